//! Where x, y and z sit in a `PointCloud2`'s points, checked once per cloud
//! against every size field before a byte is read.

use super::{CloudError, PointCloud2Ref};
use crate::lattice::Limits;

/// `sensor_msgs/PointField` datatype `FLOAT32`.
pub const FLOAT32: u8 = 7;
/// `sensor_msgs/PointField` datatype `FLOAT64`.
pub const FLOAT64: u8 = 8;

/// Name of a `PointField` datatype, for messages.
pub(crate) fn datatype_name(datatype: u8) -> &'static str {
    match datatype {
        1 => "INT8",
        2 => "UINT8",
        3 => "INT16",
        4 => "UINT16",
        5 => "INT32",
        6 => "UINT32",
        7 => "FLOAT32",
        8 => "FLOAT64",
        _ => "no PointField datatype",
    }
}

/// A coordinate's storage.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Scalar {
    F32,
    F64,
}

impl Scalar {
    pub(crate) fn size(self) -> usize {
        match self {
            Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
}

/// The checked layout of one cloud.
#[derive(Clone, Copy, Debug)]
pub(crate) struct XyzLayout {
    pub offsets: [usize; 3],
    pub scalars: [Scalar; 3],
    pub big_endian: bool,
    pub point_step: usize,
    pub row_step: usize,
    pub width: usize,
    pub height: usize,
    pub points: u64,
    /// Bytes of `data` past `height · row_step`, which are ignored.
    pub trailing: u64,
}

const NAMES: [&str; 3] = ["x", "y", "z"];

/// Checks the cloud's fields and sizes.
pub(crate) fn xyz_layout(
    cloud: &PointCloud2Ref<'_>,
    limits: &Limits,
) -> Result<XyzLayout, CloudError> {
    if cloud.point_step == 0 {
        return Err(CloudError::ZeroPointStep);
    }
    let point_step = u64::from(cloud.point_step);
    let mut offsets = [0usize; 3];
    let mut scalars = [Scalar::F32; 3];
    let mut spans = [(0u64, 0u64); 3];
    for (a, name) in NAMES.iter().enumerate() {
        let mut found = cloud.fields.iter().filter(|f| f.name == *name);
        let field = found.next().ok_or(CloudError::MissingField { name })?;
        if found.next().is_some() {
            return Err(CloudError::DuplicateField { name });
        }
        let scalar = match field.datatype {
            FLOAT32 => Scalar::F32,
            FLOAT64 => Scalar::F64,
            d => {
                return Err(CloudError::FieldDatatype {
                    name,
                    datatype: d,
                    type_name: datatype_name(d),
                })
            }
        };
        if field.count == 0 {
            return Err(CloudError::FieldCount { name });
        }
        let start = u64::from(field.offset);
        let end = start + scalar.size() as u64;
        if end > point_step {
            return Err(CloudError::FieldOutsidePoint {
                name,
                offset: field.offset,
                size: scalar.size() as u32,
                point_step: cloud.point_step,
            });
        }
        offsets[a] = field.offset as usize;
        scalars[a] = scalar;
        spans[a] = (start, end);
    }
    for a in 0..3 {
        for b in a + 1..3 {
            if spans[a].0 < spans[b].1 && spans[b].0 < spans[a].1 {
                return Err(CloudError::FieldsOverlap {
                    a: NAMES[a],
                    b: NAMES[b],
                });
            }
        }
    }
    let (width, height) = (u64::from(cloud.width), u64::from(cloud.height));
    let points = width * height;
    if points > limits.max_points {
        return Err(CloudError::TooManyPoints {
            points,
            limit: limits.max_points,
        });
    }
    let row_step = u64::from(cloud.row_step);
    let row_bytes = width * point_step;
    if points > 0 && row_step < row_bytes {
        return Err(CloudError::RowStepTooSmall {
            row_step: cloud.row_step,
            width: cloud.width,
            point_step: cloud.point_step,
        });
    }
    let needed = if points == 0 { 0 } else { height * row_step };
    let len = cloud.data.len() as u64;
    if len < needed {
        return Err(CloudError::DataTooShort {
            len,
            needed,
            height: cloud.height,
            row_step: cloud.row_step,
        });
    }
    Ok(XyzLayout {
        offsets,
        scalars,
        big_endian: cloud.is_bigendian,
        point_step: cloud.point_step as usize,
        row_step: cloud.row_step as usize,
        width: cloud.width as usize,
        height: cloud.height as usize,
        points,
        trailing: len - needed,
    })
}
