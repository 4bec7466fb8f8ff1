//! Every refusal of a PointCloud2 or of cloud options: its variant, and a
//! message naming the culprit.

use super::cloud::{encode, Layout};
use chronotope_occupancy::{
    CloudError, CloudOptions, CloudRasterizer, Encoding, Lattice, LatticeError, Limits,
    PointCloud2Ref, PointField, VoxelFrame, FLOAT32,
};

fn lattice() -> Lattice {
    Lattice::new([0.0; 3], 0.1, [4, 4, 4]).unwrap()
}

fn try_cloud(cloud: &PointCloud2Ref<'_>) -> Result<(), CloudError> {
    try_with(cloud, CloudOptions::new(), Limits::default())
}

fn try_with(
    cloud: &PointCloud2Ref<'_>,
    opts: CloudOptions,
    limits: Limits,
) -> Result<(), CloudError> {
    let mut frame = VoxelFrame::new();
    let r = CloudRasterizer::with_limits(opts, limits)
        .rasterize(cloud, &lattice(), Encoding::Bits, &mut frame)
        .map(|_| ());
    if r.is_err() {
        assert!(frame.data().is_empty(), "the frame is left as it was");
    }
    r
}

fn xyz(offsets: [u32; 3], types: [u8; 3]) -> Vec<PointField<'static>> {
    ["x", "y", "z"]
        .iter()
        .enumerate()
        .map(|(a, n)| PointField {
            name: n,
            offset: offsets[a],
            datatype: types[a],
            count: 1,
        })
        .collect()
}

fn base<'a>(fields: &'a [PointField<'a>], data: &'a [u8]) -> PointCloud2Ref<'a> {
    PointCloud2Ref {
        height: 1,
        width: 2,
        fields,
        is_bigendian: false,
        point_step: 12,
        row_step: 24,
        data,
        is_dense: true,
    }
}

#[test]
fn a_missing_or_doubled_field_is_named() {
    let data = vec![0u8; 24];
    let fields: Vec<_> = xyz([0, 4, 8], [FLOAT32; 3])
        .into_iter()
        .filter(|f| f.name != "y")
        .collect();
    let err = try_cloud(&base(&fields, &data)).unwrap_err();
    assert_eq!(err, CloudError::MissingField { name: "y" });
    assert!(err.to_string().contains("\"y\""));
    let mut fields = xyz([0, 4, 8], [FLOAT32; 3]);
    fields.push(PointField {
        name: "z",
        offset: 8,
        datatype: FLOAT32,
        count: 1,
    });
    let err = try_cloud(&base(&fields, &data)).unwrap_err();
    assert_eq!(err, CloudError::DuplicateField { name: "z" });
}

#[test]
fn coordinates_of_another_datatype_are_refused_with_the_type_named() {
    let data = vec![0u8; 24];
    let fields = xyz([0, 4, 8], [FLOAT32, 5, FLOAT32]);
    let err = try_cloud(&base(&fields, &data)).unwrap_err();
    assert_eq!(
        err,
        CloudError::FieldDatatype {
            name: "y",
            datatype: 5,
            type_name: "INT32"
        }
    );
    assert!(
        err.to_string().contains("\"y\"") && err.to_string().contains("INT32"),
        "{err}"
    );
    let fields = xyz([0, 4, 8], [FLOAT32, FLOAT32, 42]);
    assert!(matches!(
        try_cloud(&base(&fields, &data)),
        Err(CloudError::FieldDatatype {
            name: "z",
            datatype: 42,
            ..
        })
    ));
}

#[test]
fn a_field_with_count_zero_is_refused() {
    let data = vec![0u8; 24];
    let mut fields = xyz([0, 4, 8], [FLOAT32; 3]);
    fields[0].count = 0;
    assert_eq!(
        try_cloud(&base(&fields, &data)).unwrap_err(),
        CloudError::FieldCount { name: "x" }
    );
}

#[test]
fn fields_past_the_point_step_or_overlapping_are_refused() {
    let data = vec![0u8; 24];
    let fields = xyz([0, 4, 9], [FLOAT32; 3]);
    let err = try_cloud(&base(&fields, &data)).unwrap_err();
    assert_eq!(
        err,
        CloudError::FieldOutsidePoint {
            name: "z",
            offset: 9,
            size: 4,
            point_step: 12
        }
    );
    assert!(err.to_string().contains("point_step 12"), "{err}");
    let fields = xyz([0, 2, 8], [FLOAT32; 3]);
    let err = try_cloud(&base(&fields, &data)).unwrap_err();
    assert_eq!(err, CloudError::FieldsOverlap { a: "x", b: "y" });
    assert!(err.to_string().contains("\"x\" and \"y\" overlap"));
}

#[test]
fn a_zero_point_step_is_refused() {
    let data = vec![0u8; 24];
    let fields = xyz([0, 4, 8], [FLOAT32; 3]);
    let cloud = PointCloud2Ref {
        point_step: 0,
        ..base(&fields, &data)
    };
    assert_eq!(try_cloud(&cloud).unwrap_err(), CloudError::ZeroPointStep);
}

#[test]
fn a_short_row_step_or_short_data_is_refused_and_extra_bytes_are_counted() {
    let data = vec![0u8; 24];
    let fields = xyz([0, 4, 8], [FLOAT32; 3]);
    let cloud = PointCloud2Ref {
        row_step: 23,
        ..base(&fields, &data)
    };
    let err = try_cloud(&cloud).unwrap_err();
    assert_eq!(
        err,
        CloudError::RowStepTooSmall {
            row_step: 23,
            width: 2,
            point_step: 12
        }
    );
    assert!(err.to_string().contains("row_step 23"));
    let cloud = PointCloud2Ref {
        data: &data[..23],
        ..base(&fields, &data)
    };
    let err = try_cloud(&cloud).unwrap_err();
    assert_eq!(
        err,
        CloudError::DataTooShort {
            len: 23,
            needed: 24,
            height: 1,
            row_step: 24
        }
    );
    // Rows with padding: height 2, row_step 30, the last row's padding missing.
    let cloud = PointCloud2Ref {
        height: 2,
        row_step: 30,
        data: &[0u8; 54],
        ..base(&fields, &data)
    };
    assert!(matches!(
        try_cloud(&cloud),
        Err(CloudError::DataTooShort { needed: 60, .. })
    ));
    // Extra bytes are ignored and counted.
    let long = vec![0u8; 31];
    let cloud = PointCloud2Ref {
        data: &long,
        ..base(&fields, &long)
    };
    let stats = CloudRasterizer::new(CloudOptions::new())
        .rasterize(&cloud, &lattice(), Encoding::Bits, &mut VoxelFrame::new())
        .unwrap();
    assert_eq!(stats.trailing_bytes, 7);
}

#[test]
fn clouds_past_the_point_limit_are_refused_without_reading_data() {
    let fields = xyz([0, 4, 8], [FLOAT32; 3]);
    // 4 billion points claimed over 24 bytes: refused by the limit, not by allocation.
    let cloud = PointCloud2Ref {
        height: 65536,
        width: 65536,
        row_step: 12 * 65536,
        ..base(&fields, &[])
    };
    let err = try_cloud(&cloud).unwrap_err();
    assert_eq!(
        err,
        CloudError::TooManyPoints {
            points: 1 << 32,
            limit: 1 << 25
        }
    );
    assert!(err.to_string().contains("max_points"));
    // Within the limit, but the data is not there.
    let cloud = PointCloud2Ref {
        height: 1000,
        width: 1000,
        row_step: 12_000,
        ..base(&fields, &[])
    };
    assert!(matches!(
        try_cloud(&cloud),
        Err(CloudError::DataTooShort {
            needed: 12_000_000,
            ..
        })
    ));
}

#[test]
fn bad_margins_are_refused() {
    let e = encode(&[[0.05, 0.05, 0.05]], &Layout::plain());
    for d in [-0.1, f64::NAN, f64::INFINITY] {
        let err = try_with(
            &e.cloud(),
            CloudOptions::new().dilate_m(d),
            Limits::default(),
        )
        .unwrap_err();
        assert!(matches!(err, CloudError::Dilate { .. }), "{err:?}");
        assert!(err.to_string().contains("dilate_m"));
    }
    let err = try_with(
        &e.cloud(),
        CloudOptions::new().dilate_m(10.0),
        Limits::default(),
    )
    .unwrap_err();
    assert_eq!(
        err,
        CloudError::DilateTooLarge {
            voxels: 100,
            limit: 64
        }
    );
    assert!(err.to_string().contains("max_dilate_voxels"));
}

#[test]
fn lattices_past_the_limits_are_refused_before_allocating() {
    let e = encode(&[[0.05, 0.05, 0.05]], &Layout::plain());
    let limits = Limits {
        max_decoded_bytes: 1000,
        ..Limits::default()
    };
    let mut frame = VoxelFrame::new();
    let big = Lattice::new([0.0; 3], 0.1, [64, 64, 64]).unwrap();
    let err = CloudRasterizer::with_limits(CloudOptions::new(), limits)
        .rasterize(&e.cloud(), &big, Encoding::Bits, &mut frame)
        .unwrap_err();
    assert!(
        matches!(err, CloudError::Lattice(LatticeError::TooManyBytes { .. })),
        "{err:?}"
    );
    let limits = Limits {
        max_voxels: 1000,
        ..Limits::default()
    };
    let err = CloudRasterizer::with_limits(CloudOptions::new(), limits)
        .rasterize(&e.cloud(), &big, Encoding::Bits, &mut frame)
        .unwrap_err();
    assert_eq!(
        err,
        CloudError::Lattice(LatticeError::TooManyVoxels {
            voxels: 64 * 64 * 64,
            limit: 1000
        })
    );
}
