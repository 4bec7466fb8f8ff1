//! Synthetic voxel scenes: moving bodies rasterised frame by frame into
//! `chronotope_msgs/msg/VoxelGrid` messages ([`VoxelGrid`]).
//!
//! A scene is a set of rigid bodies, each a union of implicit solids ([`Shape`]: boxes,
//! cylinders, spheres) translated over time ([`Motion`]), plus one [`VoxelLattice`] that
//! every frame of every body shares (the whole scene domain, frame id `world`). Frames are
//! generated on demand, so memory does not depend on the number of frames.
//!
//! Two scenes are built in ([`SceneName`]):
//! - `machine-tool`: the workload of the marching paper (docs/methods/marching.md#figures)
//!   (spindle, table with workpiece, fixture); see [`TOOL_FIXTURE_CONTACT_U`] for when the
//!   tool crashes into the fixture.
//! - `four-spheres`: the test scene of the interference paper
//!   (docs/methods/interference.md#the-test-scene), with exact answers in [`FOUR_SPHERES`].
//!
//! Both encodings follow docs/formats.md#input-message: BITS marks voxels whose centre is
//! inside a body; PERCENT gives the occupied volume fraction by 8×8×8 supersampling
//! ([`Rasterizer`]). Pure library code: no I/O, no ROS or MCAP.
//!
//! ```
//! use chronotope_scene::{build_scene, SceneName, SceneOptions};
//!
//! let opts = SceneOptions::for_scene(SceneName::FourSpheres).grid(16).frames(5);
//! let scene = build_scene(SceneName::FourSpheres, &opts).unwrap();
//! assert_eq!(scene.topics()[0], "/sphere_a/occupancy");
//! let frame = scene.frame(0, 2);
//! assert_eq!(frame.data.len(), 16 * 16 * 16 / 8);
//! assert_eq!(scene.stamp_ns(4) - scene.stamp_ns(0), 1_000_000_000);
//! ```
#![warn(missing_docs)]

mod body;
mod four_spheres;
mod lattice;
mod machine_tool;
mod motion;
mod periodic;
mod person;
mod raster;
mod robot_cell;
mod shape;

use std::fmt;
use std::str::FromStr;

pub use body::BodySpec;
pub use four_spheres::{FourSpheresParams, FOUR_SPHERES};
pub use lattice::VoxelLattice;
pub use machine_tool::{
    MACHINE_TOOL_DOMAIN_EDGE, MACHINE_TOOL_FRAME_PERIOD_NS, TOOL_FIXTURE_CONTACT_U,
    TOOL_WORKPIECE_CONTACT_U,
};
pub use motion::{Keyframe, Motion};
pub use periodic::{
    periodic_contacts, PERIODIC_AMPLITUDE, PERIODIC_FRAME_PERIOD_NS, PERIODIC_PERIOD_S,
    PERIODIC_RADIUS,
};
pub use person::{
    PersonCell, CAMERA_FRAME, CAMERA_PIXELS, CLOUD_TOPIC, OCTOMAP_TOPIC, PERSON_CELL_DOMAIN_EDGE,
    PERSON_CELL_FRAME_PERIOD_NS,
};
pub use raster::{rasterize, Rasterizer, PERCENT_SUBSAMPLES};
pub use robot_cell::{
    robot_cell_lattice, robot_cell_positions, robot_cell_table, robot_cell_velocities,
    ROBOT_CELL_BASE, ROBOT_CELL_DOMAIN_EDGE, ROBOT_CELL_DOMAIN_ORIGIN, ROBOT_CELL_DURATION_S,
    ROBOT_CELL_FIRST_MESSAGE_JOINTS, ROBOT_CELL_FRAME_PERIOD_NS, ROBOT_CELL_JOINTS,
    ROBOT_CELL_JOINT_PERIOD_NS, ROBOT_CELL_PLAN_SENT_U, ROBOT_CELL_PLAN_U, ROBOT_CELL_URDF,
};
pub use shape::{Aabb, Axis, Shape};

use chronotope_msg::{Header, Point, Time, VoxelEncoding, VoxelGrid};

/// Smallest accepted grid (voxels per domain edge).
pub const MIN_GRID: u32 = 4;
/// Largest accepted grid (voxels per domain edge).
pub const MAX_GRID: u32 = 2048;
/// Smallest accepted frame count.
pub const MIN_FRAMES: u32 = 1;
/// Largest accepted frame count.
pub const MAX_FRAMES: u32 = 100_000;
/// Stamp of every scene's first frame: 1 700 000 000 s after the epoch, in ns.
pub const SCENE_START_NS: i64 = 1_700_000_000 * 1_000_000_000;
/// `header.frame_id` of every frame.
pub const SCENE_FRAME_ID: &str = "world";

/// What went wrong building a scene or asking it for a frame.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SceneError {
    /// The scene name is not one of [`SceneName::ALL`].
    #[error("unknown scene `{name}`: expected `machine-tool` or `four-spheres`")]
    UnknownScene {
        /// The name given.
        name: String,
    },
    /// The grid is outside [`MIN_GRID`]..=[`MAX_GRID`].
    #[error("grid {grid} is out of range: use {MIN_GRID}..={MAX_GRID} voxels per edge")]
    GridOutOfRange {
        /// The grid given.
        grid: u32,
    },
    /// The frame count is outside [`MIN_FRAMES`]..=[`MAX_FRAMES`].
    #[error("{frames} frames is out of range: use {MIN_FRAMES}..={MAX_FRAMES}")]
    FramesOutOfRange {
        /// The frame count given.
        frames: u32,
    },
    /// A body index past the end of [`Scene::bodies`].
    #[error("no body {body}: the scene has {bodies} bodies")]
    NoSuchBody {
        /// The index given.
        body: usize,
        /// Number of bodies.
        bodies: usize,
    },
    /// A frame index past the end of the run.
    #[error("no frame {frame}: the scene has {frames} frames")]
    NoSuchFrame {
        /// The index given.
        frame: u32,
        /// Number of frames.
        frames: u32,
    },
}

/// The built-in scenes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum SceneName {
    /// `machine-tool`: spindle, table with workpiece, fixture (the marching paper's
    /// workload: docs/methods/marching.md#figures).
    MachineTool,
    /// `four-spheres`: four spheres at constant velocity (the interference paper's test
    /// scene: docs/methods/interference.md#the-test-scene).
    FourSpheres,
    /// `periodic`: two spheres meeting every two seconds, for as long as asked.
    Periodic,
}

impl SceneName {
    /// Every scene, in the order listed to users.
    pub const ALL: [SceneName; 3] = [
        SceneName::MachineTool,
        SceneName::FourSpheres,
        SceneName::Periodic,
    ];

    /// The name on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::MachineTool => "machine-tool",
            Self::FourSpheres => "four-spheres",
            Self::Periodic => "periodic",
        }
    }
}

impl fmt::Display for SceneName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for SceneName {
    type Err = SceneError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|n| n.as_str() == s)
            .ok_or_else(|| SceneError::UnknownScene { name: s.to_owned() })
    }
}

/// How to build a scene. Start from [`SceneOptions::for_scene`] and adjust with the builder
/// methods.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SceneOptions {
    /// Voxels per edge of the cubic domain.
    pub grid: u32,
    /// Number of frames per body.
    pub frames: u32,
    /// Encoding of the frames' data.
    pub encoding: VoxelEncoding,
}

impl SceneOptions {
    /// The defaults of a scene: `machine-tool` 128³ voxels × 64 frames (the marching
    /// paper's workload: docs/methods/marching.md#figures), `four-spheres` 64³ × 33 frames
    /// (one frame every 1/32 s), `periodic` 48³ × 201 frames (10 s at 20 Hz), all BITS.
    pub fn for_scene(name: SceneName) -> Self {
        match name {
            SceneName::MachineTool => Self {
                grid: 128,
                frames: 64,
                encoding: VoxelEncoding::Bits,
            },
            SceneName::FourSpheres => Self {
                grid: 64,
                frames: 33,
                encoding: VoxelEncoding::Bits,
            },
            SceneName::Periodic => Self {
                grid: 48,
                frames: 201,
                encoding: VoxelEncoding::Bits,
            },
        }
    }

    /// With `grid` voxels per domain edge.
    pub fn grid(mut self, grid: u32) -> Self {
        self.grid = grid;
        self
    }

    /// With `frames` frames.
    pub fn frames(mut self, frames: u32) -> Self {
        self.frames = frames;
        self
    }

    /// With frames in `encoding`.
    pub fn encoding(mut self, encoding: VoxelEncoding) -> Self {
        self.encoding = encoding;
        self
    }

    /// Checks the ranges.
    ///
    /// # Errors
    /// [`SceneError::GridOutOfRange`] or [`SceneError::FramesOutOfRange`].
    pub fn validate(&self) -> Result<(), SceneError> {
        if !(MIN_GRID..=MAX_GRID).contains(&self.grid) {
            return Err(SceneError::GridOutOfRange { grid: self.grid });
        }
        if !(MIN_FRAMES..=MAX_FRAMES).contains(&self.frames) {
            return Err(SceneError::FramesOutOfRange {
                frames: self.frames,
            });
        }
        Ok(())
    }
}

/// A synthetic scene: bodies, the shared lattice and the frame times. Frames are generated
/// on demand by [`Scene::frame`].
#[derive(Debug, Clone)]
pub struct Scene {
    name: SceneName,
    options: SceneOptions,
    lattice: VoxelLattice,
    bodies: Vec<BodySpec>,
    /// Time from the first to the last frame (ns).
    span_ns: i64,
}

/// Builds the scene `name` with `opts`.
///
/// # Errors
/// [`SceneError::GridOutOfRange`] or [`SceneError::FramesOutOfRange`] for options outside
/// the accepted ranges.
pub fn build_scene(name: SceneName, opts: &SceneOptions) -> Result<Scene, SceneError> {
    opts.validate()?;
    let steps = i64::from(opts.frames - 1);
    let (lattice, bodies, span_ns) = match name {
        SceneName::MachineTool => {
            let span_ns = steps * MACHINE_TOOL_FRAME_PERIOD_NS;
            let lattice = VoxelLattice::cube([0.0; 3], MACHINE_TOOL_DOMAIN_EDGE, opts.grid);
            (lattice, machine_tool::bodies(span_ns as f64 / 1e9), span_ns)
        }
        SceneName::FourSpheres => {
            let p = &FOUR_SPHERES;
            let span_ns = ((p.t_span.1 - p.t_span.0) * 1e9).round() as i64;
            let lattice = VoxelLattice::cube(p.domain_origin, p.domain_edge, opts.grid);
            (lattice, p.bodies(), if steps == 0 { 0 } else { span_ns })
        }
        SceneName::Periodic => {
            let span_ns = steps * periodic::PERIODIC_FRAME_PERIOD_NS;
            let lattice = VoxelLattice::cube([0.0; 3], periodic::PERIODIC_DOMAIN_EDGE, opts.grid);
            (lattice, periodic::bodies(span_ns as f64 / 1e9), span_ns)
        }
    };
    Ok(Scene {
        name,
        options: *opts,
        lattice,
        bodies,
        span_ns,
    })
}

impl Scene {
    /// Which scene this is.
    pub fn name(&self) -> SceneName {
        self.name
    }

    /// The options it was built with.
    pub fn options(&self) -> &SceneOptions {
        &self.options
    }

    /// The lattice every frame uses.
    pub fn lattice(&self) -> &VoxelLattice {
        &self.lattice
    }

    /// The bodies, in publishing order; body `i` is published on `topics()[i]`.
    pub fn bodies(&self) -> &[BodySpec] {
        &self.bodies
    }

    /// One topic per body, e.g. `/spindle/occupancy`.
    pub fn topics(&self) -> Vec<String> {
        self.bodies.iter().map(|b| b.topic.clone()).collect()
    }

    /// Index of the body published on `topic`.
    pub fn body_index(&self, topic: &str) -> Option<usize> {
        self.bodies.iter().position(|b| b.topic == topic)
    }

    /// Frames per body.
    pub fn frame_count(&self) -> u32 {
        self.options.frames
    }

    /// Stamp of the first frame (ns since the epoch), [`SCENE_START_NS`].
    pub fn start_ns(&self) -> i64 {
        SCENE_START_NS
    }

    /// Stamp of frame `k` (ns since the epoch): frames are spread uniformly from
    /// [`SCENE_START_NS`] over the run, rounded to the nearest nanosecond.
    pub fn stamp_ns(&self, k: u32) -> i64 {
        let steps = i128::from(self.options.frames.max(2) - 1);
        let num = i128::from(k) * i128::from(self.span_ns);
        SCENE_START_NS + ((2 * num + steps) / (2 * steps)) as i64
    }

    /// Time of frame `k` in seconds since the first frame: the time at which the bodies are
    /// posed in that frame (from its stamp, so it agrees with what a reader of the stamps sees).
    pub fn time_s(&self, k: u32) -> f64 {
        (self.stamp_ns(k) - SCENE_START_NS) as f64 / 1e9
    }

    /// Time from the first to the last frame (s).
    pub fn duration_s(&self) -> f64 {
        self.span_ns as f64 / 1e9
    }

    /// The run fraction `k / (frames - 1)` of frame `k` (0 for a single frame).
    pub fn run_fraction(&self, k: u32) -> f64 {
        if self.options.frames < 2 {
            0.0
        } else {
            f64::from(k) / f64::from(self.options.frames - 1)
        }
    }

    /// Frame `k` of body `body`, in the scene's encoding.
    ///
    /// # Panics
    /// If `body >= bodies().len()` or `k >= frame_count()`; [`Scene::try_frame`] returns
    /// an error instead.
    pub fn frame(&self, body: usize, k: u32) -> VoxelGrid {
        match self.try_frame(body, k) {
            Ok(g) => g,
            Err(e) => panic!("{e}"),
        }
    }

    /// Frame `k` of body `body`, in the scene's encoding.
    ///
    /// # Errors
    /// [`SceneError::NoSuchBody`] or [`SceneError::NoSuchFrame`].
    pub fn try_frame(&self, body: usize, k: u32) -> Result<VoxelGrid, SceneError> {
        let mut grid = VoxelGrid::default();
        self.write_frame(body, k, &mut Rasterizer::new(), &mut grid)?;
        Ok(grid)
    }

    /// Writes frame `k` of body `body` into `grid`, reusing its data buffer and the
    /// rasteriser's workspace (for streaming many frames without allocating).
    ///
    /// # Errors
    /// [`SceneError::NoSuchBody`] or [`SceneError::NoSuchFrame`]; `grid` is then unchanged.
    pub fn write_frame(
        &self,
        body: usize,
        k: u32,
        raster: &mut Rasterizer,
        grid: &mut VoxelGrid,
    ) -> Result<(), SceneError> {
        let spec = self.bodies.get(body).ok_or(SceneError::NoSuchBody {
            body,
            bodies: self.bodies.len(),
        })?;
        if k >= self.options.frames {
            return Err(SceneError::NoSuchFrame {
                frame: k,
                frames: self.options.frames,
            });
        }
        let l = &self.lattice;
        let enc = self.options.encoding;
        raster.rasterize(
            &spec.shapes,
            spec.offset_at(self.time_s(k)),
            l,
            enc,
            &mut grid.data,
        );
        grid.header = Header {
            stamp: Time::from_nanos(self.stamp_ns(k)),
            frame_id: SCENE_FRAME_ID.to_owned(),
        };
        grid.origin = Point {
            x: l.origin[0],
            y: l.origin[1],
            z: l.origin[2],
        };
        grid.resolution = l.resolution;
        [grid.size_x, grid.size_y, grid.size_z] = l.size;
        grid.encoding = enc.code();
        Ok(())
    }
}
