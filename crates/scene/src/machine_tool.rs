//! The `machine-tool` scene (the marching paper's workload:
//! docs/methods/marching.md#figures): a spindle with a tool, a moving table with a
//! workpiece, and a fixture clamped on the table.
//!
//! Sizes are in metres in a 1.28 m cube and do not depend on the grid (every dimension is a
//! multiple of 0.04 m, one voxel at grid 32, so at grids that are multiples of 32 the
//! axis-aligned faces of the rest pose lie on voxel boundaries). Motion is given against the
//! *run fraction* `u = k / (frames - 1)`, so the same choreography plays whatever the frame
//! count; frames are 0.1 s apart. Layout, motion and contact intervals: `docs/scenes.md`.

use super::{Axis, BodySpec, Keyframe, Motion, Shape};

/// Edge of the cubic domain (m); the domain is `[0, 1.28]³`.
pub const MACHINE_TOOL_DOMAIN_EDGE: f64 = 1.28;

/// Time between frames (ns).
pub const MACHINE_TOOL_FRAME_PERIOD_NS: i64 = 100_000_000;

/// Run fractions `u` during which the tool overlaps the fixture (exact, from the layout):
/// during the feed, `0.464 + 1.2 (u - 0.2)` is the tool axis x in table coordinates, and
/// contact lasts while it is within 0.08 m (the tool radius) of the fixture block
/// `x ∈ [0.76, 0.88]`: `u ∈ (0.38, 0.6133)`.
pub const TOOL_FIXTURE_CONTACT_U: (f64, f64) = (0.2 + 0.216 / 1.2, 0.2 + 0.496 / 1.2);

/// Run fractions `u` during which the tool overlaps the workpiece: from when the tool tip
/// passes the workpiece top (z = 0.44 m) during the plunge until the tool leaves the
/// workpiece's far face `x = 0.68` m: `u ∈ (0.12, 0.4467)`.
pub const TOOL_WORKPIECE_CONTACT_U: (f64, f64) = (0.12, 0.2 + 0.296 / 1.2);

/// Tool axis (x, y) and tool tip height at rest (m).
const TOOL_AXIS: [f64; 2] = [0.44, 0.64];
const TOOL_TIP_Z: f64 = 0.56;
const TOOL_RADIUS: f64 = 0.08;
const TOOL_LENGTH: f64 = 0.24;

/// The three bodies at rest, with their motion over a run of `duration` seconds.
pub(crate) fn bodies(duration: f64) -> Vec<BodySpec> {
    let key = |u: f64, offset: [f64; 3]| Keyframe {
        t: u * duration,
        offset,
    };
    let [ax, ay] = TOOL_AXIS;
    let tip = TOOL_TIP_Z;

    // Spindle: tool (Ø 0.16 m, 0.24 m long) under a nose (Ø 0.24 m) under a head box.
    let spindle = BodySpec::new(
        "/spindle/occupancy",
        "spindle head, nose and a cylindrical tool pointing down; plunges, feeds along +x \
         through the workpiece and the fixture, retracts, then moves along -y",
        vec![
            Shape::cylinder(Axis::Z, [ax, ay, tip], TOOL_LENGTH, TOOL_RADIUS),
            Shape::cylinder(Axis::Z, [ax, ay, tip + TOOL_LENGTH], 0.08, 0.12),
            Shape::cuboid(
                [ax - 0.14, ay - 0.14, tip + 0.32],
                [ax + 0.14, ay + 0.14, tip + 0.60],
            ),
        ],
        Motion::keyframes(vec![
            key(0.0, [0.0, 0.0, 0.0]),
            key(0.2, [0.0, 0.0, -0.20]),
            key(0.7, [0.54, 0.0, -0.20]),
            key(0.85, [0.54, 0.0, 0.0]),
            key(1.0, [0.54, -0.24, 0.0]),
        ]),
    );

    // The table and the fixture travel together, 0.12 m along -x over the run.
    let table_motion = Motion::keyframes(vec![key(0.0, [0.0; 3]), key(1.0, [-0.12, 0.0, 0.0])]);
    let table = BodySpec::new(
        "/table/occupancy",
        "machine table (0.80 x 0.64 x 0.12 m) with a workpiece block (0.32 x 0.32 x 0.20 m) on it; \
         moves along -x",
        vec![
            Shape::cuboid([0.24, 0.32, 0.12], [1.04, 0.96, 0.24]),
            Shape::cuboid([0.36, 0.48, 0.24], [0.68, 0.80, 0.44]),
        ],
        table_motion.clone(),
    );
    let fixture = BodySpec::new(
        "/fixture/occupancy",
        "clamp block (0.12 x 0.24 x 0.24 m) standing on the table next to the workpiece, with a \
         clamp bar (cylinder along y, Ø 0.12 m) on top; moves with the table",
        vec![
            Shape::cuboid([0.76, 0.52, 0.24], [0.88, 0.76, 0.48]),
            Shape::cylinder(Axis::Y, [0.82, 0.48, 0.48], 0.32, 0.06),
        ],
        table_motion,
    );
    vec![spindle, table, fixture]
}
