//! `sensor_msgs/PointCloud2` onto a lattice: any field layout, either byte
//! order, organised or not, padded rows.
//!
//! Each finite point (after the optional rigid transform) marks the voxel it
//! falls in, `floor((p - origin) · (1 / resolution))` per axis in `f64`. Then,
//! in this order: `min_points` keeps the voxels with at least that many points;
//! `dilate_m` adds every voxel whose cube comes within that distance of a kept
//! voxel's cube (a superset of "within that distance of a point"); `fill`
//! extends each occupied voxel's column to a lattice face.
//!
//! A cloud says where surfaces are, not where space is free: `Percent` frames
//! hold 100 or 0, never 255.
//!
//! Relies on [`crate::lattice`], the padded bit rows (`rows.rs`) and [`crate::transform`].

mod layout;
mod morph;
mod points;

pub use layout::{FLOAT32, FLOAT64};

use crate::lattice::{Encoding, Lattice, LatticeError, Limits, VoxelFrame};
use crate::rows::BitRows;
use crate::transform::RigidTransform;
use layout::xyz_layout;
use points::{Marker, Reach};
use thiserror::Error;

/// One `sensor_msgs/PointField`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PointField<'a> {
    /// `name`; x, y and z are found by it.
    pub name: &'a str,
    /// `offset`: byte offset in a point.
    pub offset: u32,
    /// `datatype`: x, y and z must be [`FLOAT32`] (7) or [`FLOAT64`] (8).
    pub datatype: u8,
    /// `count`: elements; the first is read.
    pub count: u32,
}

/// The fields of one `sensor_msgs/msg/PointCloud2` message (the header aside).
#[derive(Clone, Copy, Debug)]
pub struct PointCloud2Ref<'a> {
    /// `height`: rows (1 for an unorganised cloud).
    pub height: u32,
    /// `width`: points per row.
    pub width: u32,
    /// `fields`.
    pub fields: &'a [PointField<'a>],
    /// `is_bigendian`: byte order of the values in `data`.
    pub is_bigendian: bool,
    /// `point_step`: bytes per point.
    pub point_step: u32,
    /// `row_step`: bytes per row (at least `width · point_step`; the rest of a
    /// row is padding).
    pub row_step: u32,
    /// `data`: at least `height · row_step` bytes; bytes past that are ignored
    /// (counted in [`CloudStats::trailing_bytes`]).
    pub data: &'a [u8],
    /// `is_dense`: not trusted; every point is checked.
    pub is_dense: bool,
}

/// A lattice axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    /// x.
    X,
    /// y.
    Y,
    /// z.
    Z,
}

/// Which lattice face a column fill runs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Toward {
    /// The face at index 0 (for z: the floor).
    Min,
    /// The face at the last index (for z: the top).
    Max,
}

/// How marked voxels are extended into solids.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Fill {
    /// Only the voxels the points (and the margin) mark: a surface cloud stays
    /// a shell one or two voxels thick.
    #[default]
    None,
    /// Every occupied voxel's column along `axis`, to the face `toward`: a
    /// top-view shell becomes a solid down to the floor.
    Columns {
        /// The column axis.
        axis: Axis,
        /// The face the columns run to.
        toward: Toward,
    },
}

impl Fill {
    /// Columns along z down to the lattice's floor.
    pub fn down_to_floor() -> Self {
        Fill::Columns {
            axis: Axis::Z,
            toward: Toward::Min,
        }
    }
}

/// How a cloud is turned into voxels. Built with [`CloudOptions::new`] and its setters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CloudOptions {
    min_points: u8,
    dilate_m: f64,
    fill: Fill,
    transform: Option<RigidTransform>,
    parallel: bool,
}

impl Default for CloudOptions {
    fn default() -> Self {
        CloudOptions {
            min_points: 1,
            dilate_m: 0.0,
            fill: Fill::None,
            transform: None,
            parallel: true,
        }
    }
}

impl CloudOptions {
    /// One point marks a voxel; no margin, no fill, no transform.
    pub fn new() -> Self {
        Self::default()
    }

    /// A voxel needs at least `n` points (1..=255; 0 is taken as 1) to be
    /// marked: rejects isolated noise.
    pub fn min_points(mut self, n: u8) -> Self {
        self.min_points = n.max(1);
        self
    }

    /// Safety margin in metres (finite, ≥ 0): every voxel whose cube comes
    /// within `metres` of a marked voxel's cube is occupied too.
    pub fn dilate_m(mut self, metres: f64) -> Self {
        self.dilate_m = metres;
        self
    }

    /// Column fill.
    pub fn fill(mut self, fill: Fill) -> Self {
        self.fill = fill;
        self
    }

    /// Transform applied to every point first (cloud frame → lattice frame).
    pub fn transform(mut self, transform: Option<RigidTransform>) -> Self {
        self.transform = transform;
        self
    }

    /// Whether a cloud of at least [`PARALLEL_POINTS`] points is split in two halves marked
    /// at once, on the calling thread and a scoped thread (on by default on a machine of
    /// more than one core; the frame is the same either way).
    /// Not with `min_points` above 1, whose counts are kept in one array.
    pub fn parallel(mut self, on: bool) -> Self {
        self.parallel = on;
        self
    }
}

/// The least points of a cloud split over two threads: below it, the second thread's
/// frame (cleared, then OR-ed in: two passes over the lattice's bits) costs more than it
/// saves.
pub const PARALLEL_POINTS: u64 = 1 << 17;

/// What one cloud held and gave.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CloudStats {
    /// `width · height`.
    pub points: u64,
    /// Points with a NaN or infinite coordinate, skipped.
    pub nonfinite: u64,
    /// Finite points outside the lattice, skipped.
    pub outside: u64,
    /// Points outside the lattice kept by the margin or column rule (they mark
    /// the nearest voxel, or their column's end voxel).
    pub margin_points: u64,
    /// Voxels marked by points (after `min_points`, before dilation and fill).
    pub marked_voxels: u64,
    /// Voxels occupied in the frame.
    pub occupied_voxels: u64,
    /// Bytes of `data` past `height · row_step`, ignored.
    pub trailing_bytes: u64,
}

/// What is wrong with a cloud or the options.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum CloudError {
    /// The lattice is invalid or passes a limit.
    #[error(transparent)]
    Lattice(#[from] LatticeError),
    /// No field of that name.
    #[error("PointCloud2 has no field \"{name}\"")]
    MissingField {
        /// `x`, `y` or `z`.
        name: &'static str,
    },
    /// Two fields of that name.
    #[error("PointCloud2 has two fields named \"{name}\"")]
    DuplicateField {
        /// `x`, `y` or `z`.
        name: &'static str,
    },
    /// A coordinate of another datatype than FLOAT32 or FLOAT64.
    #[error("PointCloud2 field \"{name}\" has datatype {datatype} ({type_name}): x, y and z must be FLOAT32 (7) or FLOAT64 (8)")]
    FieldDatatype {
        /// `x`, `y` or `z`.
        name: &'static str,
        /// The datatype given.
        datatype: u8,
        /// Its name.
        type_name: &'static str,
    },
    /// A coordinate field with count 0.
    #[error("PointCloud2 field \"{name}\" has count 0: it holds no value")]
    FieldCount {
        /// `x`, `y` or `z`.
        name: &'static str,
    },
    /// A coordinate field reaching past `point_step`.
    #[error("PointCloud2 field \"{name}\" at offset {offset} with {size} bytes ends past point_step {point_step}")]
    FieldOutsidePoint {
        /// `x`, `y` or `z`.
        name: &'static str,
        /// Its offset.
        offset: u32,
        /// Its size in bytes.
        size: u32,
        /// `point_step`.
        point_step: u32,
    },
    /// Two coordinate fields share bytes.
    #[error("PointCloud2 fields \"{a}\" and \"{b}\" overlap")]
    FieldsOverlap {
        /// One field.
        a: &'static str,
        /// The other.
        b: &'static str,
    },
    /// `point_step` is 0.
    #[error("PointCloud2 point_step is 0")]
    ZeroPointStep,
    /// `width · height` beyond [`Limits::max_points`].
    #[error(
        "PointCloud2 has {points} points (width·height), more than the limit max_points = {limit}"
    )]
    TooManyPoints {
        /// `width · height`.
        points: u64,
        /// The limit.
        limit: u64,
    },
    /// `row_step < width · point_step`.
    #[error(
        "PointCloud2 row_step {row_step} is less than width {width} · point_step {point_step}"
    )]
    RowStepTooSmall {
        /// `row_step`.
        row_step: u32,
        /// `width`.
        width: u32,
        /// `point_step`.
        point_step: u32,
    },
    /// `data` shorter than `height · row_step`.
    #[error("PointCloud2 data has {len} bytes, less than height {height} · row_step {row_step} = {needed}")]
    DataTooShort {
        /// Bytes given.
        len: u64,
        /// Bytes needed.
        needed: u64,
        /// `height`.
        height: u32,
        /// `row_step`.
        row_step: u32,
    },
    /// `dilate_m` negative or not finite.
    #[error("dilate_m is {value}: it must be finite and at least 0")]
    Dilate {
        /// The value given.
        value: f64,
    },
    /// `dilate_m` beyond [`Limits::max_dilate_voxels`] voxels.
    #[error("dilate_m is {voxels} voxels of this lattice, more than the limit max_dilate_voxels = {limit}")]
    DilateTooLarge {
        /// The radius in voxels, rounded up.
        voxels: u64,
        /// The limit.
        limit: u32,
    },
}

/// Turns `PointCloud2` messages into frames, reusing its working buffers.
///
/// ```
/// use chronotope_occupancy::{CloudOptions, CloudRasterizer, Encoding, Lattice, PointCloud2Ref, PointField, VoxelFrame, FLOAT32};
/// let fields = [
///     PointField { name: "x", offset: 0, datatype: FLOAT32, count: 1 },
///     PointField { name: "y", offset: 4, datatype: FLOAT32, count: 1 },
///     PointField { name: "z", offset: 8, datatype: FLOAT32, count: 1 },
/// ];
/// let mut data = Vec::new();
/// for p in [[0.15f32, 0.05, 0.05], [f32::NAN, 0.0, 0.0], [9.0, 9.0, 9.0]] {
///     data.extend(p.iter().flat_map(|v| v.to_le_bytes()));
/// }
/// let cloud = PointCloud2Ref {
///     height: 1, width: 3, fields: &fields, is_bigendian: false,
///     point_step: 12, row_step: 36, data: &data, is_dense: false,
/// };
/// let lattice = Lattice::new([0.0; 3], 0.1, [4, 1, 1]).unwrap();
/// let mut raster = CloudRasterizer::new(CloudOptions::new());
/// let mut frame = VoxelFrame::new();
/// let stats = raster.rasterize(&cloud, &lattice, Encoding::Bits, &mut frame).unwrap();
/// assert_eq!(frame.data(), &[0b0010]);
/// assert_eq!((stats.nonfinite, stats.outside), (1, 1));
/// ```
#[derive(Debug, Default)]
pub struct CloudRasterizer {
    options: CloudOptions,
    limits: Limits,
    rows: BitRows,
    spare: BitRows,
    /// The second half's marks of a cloud split over two threads.
    half: BitRows,
    counts: Vec<u8>,
    scratch: Vec<u64>,
}

impl CloudRasterizer {
    /// A rasteriser with the default [`Limits`].
    pub fn new(options: CloudOptions) -> Self {
        Self::with_limits(options, Limits::default())
    }

    /// A rasteriser with the given limits.
    pub fn with_limits(options: CloudOptions, limits: Limits) -> Self {
        CloudRasterizer {
            options,
            limits,
            ..Default::default()
        }
    }

    /// The options.
    pub fn options(&self) -> &CloudOptions {
        &self.options
    }

    /// Rasterises `cloud` onto `lattice` into `out` (overwritten; its allocation kept).
    ///
    /// # Errors
    /// [`CloudError`] naming the field, size or option at fault; `out` is then
    /// left as it was.
    pub fn rasterize(
        &mut self,
        cloud: &PointCloud2Ref<'_>,
        lattice: &Lattice,
        encoding: Encoding,
        out: &mut VoxelFrame,
    ) -> Result<CloudStats, CloudError> {
        let opts = self.options;
        if !opts.dilate_m.is_finite() || opts.dilate_m < 0.0 {
            return Err(CloudError::Dilate {
                value: opts.dilate_m,
            });
        }
        let radius = opts.dilate_m / lattice.resolution();
        if radius.floor() > f64::from(self.limits.max_dilate_voxels) {
            return Err(CloudError::DilateTooLarge {
                voxels: radius.ceil() as u64,
                limit: self.limits.max_dilate_voxels,
            });
        }
        let layout = xyz_layout(cloud, &self.limits)?;
        let voxels = lattice.voxel_count();
        let counting = opts.min_points > 1;
        let mut work = lattice.row_bytes();
        if counting {
            work = work.saturating_add(voxels);
        }
        if radius > 0.0 {
            work = work.saturating_add(lattice.row_bytes());
        }
        let parallel = opts.parallel
            && !counting
            && layout.points >= PARALLEL_POINTS
            && crate::several_cores();
        if parallel {
            work = work.saturating_add(lattice.row_bytes());
        }
        lattice.check(&self.limits, encoding, work)?;

        self.rows.reset(lattice.size());
        if counting {
            self.counts.clear();
            self.counts.resize(voxels as usize, 0);
        }
        let reach = Reach {
            dilate2: if radius > 0.0 {
                let r = radius * (1.0 + 1e-9);
                r * r
            } else {
                0.0
            },
            fill: opts.fill,
        };
        let marker = |rows, counts| Marker {
            origin: lattice.origin(),
            inv_res: 1.0 / lattice.resolution(),
            n: lattice.size().map(|n| n as usize),
            rows,
            counts,
            min_points: opts.min_points,
            transform: opts.transform,
            reach,
            stats: CloudStats::default(),
        };
        let all = layout.points as usize;
        let counted = if parallel {
            self.half.reset(lattice.size());
            let (mut a, mut b) = (marker(&mut self.rows, None), marker(&mut self.half, None));
            let mid = all / 2;
            // The second half on a thread of its own, the first on the caller's: a node's
            // frame never queues behind other work on a shared pool.
            // A thread that cannot be started (the process's limit) leaves its half to the
            // caller, after the first.
            let spawned = std::thread::scope(|scope| {
                let second = std::thread::Builder::new()
                    .name("cloud half".into())
                    .spawn_scoped(scope, || b.run(&layout, cloud.data, mid..all));
                a.run(&layout, cloud.data, 0..mid);
                second.is_ok()
            });
            if !spawned {
                b.run(&layout, cloud.data, mid..all);
            }
            let (sa, sb) = (a.stats, b.stats);
            self.rows.or_from(&self.half);
            [
                sa.nonfinite + sb.nonfinite,
                sa.outside + sb.outside,
                sa.margin_points + sb.margin_points,
            ]
        } else {
            let counts = if counting {
                Some(&mut self.counts[..])
            } else {
                None
            };
            let mut m = marker(&mut self.rows, counts);
            m.run(&layout, cloud.data, 0..all);
            [m.stats.nonfinite, m.stats.outside, m.stats.margin_points]
        };
        let mut stats = CloudStats {
            points: layout.points,
            trailing_bytes: layout.trailing,
            nonfinite: counted[0],
            outside: counted[1],
            margin_points: counted[2],
            ..Default::default()
        };
        stats.marked_voxels = self.rows.count_ones();

        if radius > 0.0 {
            let elem = morph::element(radius);
            morph::dilate(&self.rows, &mut self.spare, &elem, &mut self.scratch);
            std::mem::swap(&mut self.rows, &mut self.spare);
        }
        if let Fill::Columns { axis, toward } = opts.fill {
            morph::fill_columns(&mut self.rows, axis, toward);
        }
        stats.occupied_voxels = if radius > 0.0 || opts.fill != Fill::None {
            self.rows.count_ones()
        } else {
            stats.marked_voxels
        };
        let data = out.begin(*lattice, encoding);
        match encoding {
            Encoding::Bits => self.rows.pack_bits(data),
            Encoding::Percent => self.rows.pack_bytes(100, 0, data),
        }
        Ok(stats)
    }
}
