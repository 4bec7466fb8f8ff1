//! `chronotope scene NAME --out FILE.mcap [--grid N] [--frames F] [--encoding bits|percent]`.

use super::CliError;
use super::EncodingArg;
use crate::bag::BagWriter;
use crate::msg::VoxelGrid;
use crate::scene::{build_scene, Rasterizer, SceneName, SceneOptions};
use clap::Args;
use std::path::PathBuf;

/// Options of `chronotope scene`.
#[derive(Debug, Clone, Args)]
pub struct SceneArgs {
    /// `machine-tool`, `four-spheres`, or `carving-session` (haptic tool poses and a fixture).
    pub name: String,
    /// Output bag.
    #[arg(long)]
    pub out: PathBuf,
    /// Voxels per edge of the cubic domain (default: the scene's).
    #[arg(long)]
    pub grid: Option<u32>,
    /// Frames per body (default: the scene's).
    #[arg(long)]
    pub frames: Option<u32>,
    /// Voxel encoding.
    #[arg(long, value_enum, default_value_t = EncodingArg::Bits)]
    pub encoding: EncodingArg,
}

/// Writes the scene bag: frames in time order, bodies interleaved, log time = stamp.
///
/// # Errors
/// Bad options or a bag that cannot be written.
pub fn run(a: &SceneArgs) -> Result<(), CliError> {
    if a.name == "carving-session" {
        return carving_session(&a.out);
    }
    let name: SceneName = a.name.parse()?;
    let mut opts = SceneOptions::for_scene(name).encoding(a.encoding.into());
    if let Some(g) = a.grid {
        opts = opts.grid(g);
    }
    if let Some(f) = a.frames {
        opts = opts.frames(f);
    }
    let scene = build_scene(name, &opts)?;
    let mut w = BagWriter::create(&a.out)?;
    let topics = scene.topics();
    for t in &topics {
        w.add_topic::<VoxelGrid>(t)?;
    }
    let mut raster = Rasterizer::new();
    let mut grid = VoxelGrid::default();
    for k in 0..scene.frame_count() {
        for (b, t) in topics.iter().enumerate() {
            scene.write_frame(b, k, &mut raster, &mut grid)?;
            w.write(t, scene.stamp_ns(k) as u64, &grid)?;
        }
    }
    w.finish()?;
    tracing::info!(
        "wrote {} ({} bodies x {} frames, {}^3 voxels, {:?})",
        a.out.display(),
        topics.len(),
        scene.frame_count(),
        opts.grid,
        opts.encoding
    );
    Ok(())
}

/// Start of the carving session (ns since the epoch).
const CARVING_T0_NS: i64 = 1_700_000_000_000_000_000;
/// Pose period: 500 Hz.
const POSE_PERIOD_NS: i64 = 2_000_000;
/// Fixture frame period (the carving node's `occupancy_period_s`).
const FIXTURE_PERIOD_NS: i64 = 100_000_000;

/// A recorded haptic carving session: `/haptic/pose` (PoseStamped, 500 Hz, 2 s) of a ball tool
/// plunging into the block of `launch_configs/carving_session.yaml`, cutting a groove along x,
/// lifting and cutting a second groove along y; with the faults a device produces (a NaN pose,
/// a zero quaternion, a stamp going backwards, a pose in another frame); and
/// `/fixture/occupancy`, a clamp one voxel off the block's -x face, on the block's lattice and
/// frame times.
fn carving_session(out: &std::path::Path) -> Result<(), CliError> {
    use crate::msg::{Header, Point, Pose, PoseStamped, Quaternion, Time};
    let mut w = BagWriter::create(out)?;
    w.add_topic::<PoseStamped>("/haptic/pose")?;
    w.add_topic::<VoxelGrid>("/fixture/occupancy")?;
    let n = 1000i64;
    let path = |k: i64| -> [f64; 3] {
        let s = k as f64 / n as f64; // 0..1
        let depth = 0.03 - 0.002; // 2 mm into the 30 mm block
        if s < 0.1 {
            [0.01, 0.02, 0.04 - (0.04 - depth) * s / 0.1]
        } else if s < 0.45 {
            [0.01 + 0.04 * (s - 0.1) / 0.35, 0.02, depth]
        } else if s < 0.55 {
            [
                0.05 - 0.02 * (s - 0.45) / 0.1,
                0.02 + 0.01 * (s - 0.45) / 0.1,
                0.04,
            ]
        } else if s < 0.6 {
            [
                0.03,
                0.03,
                0.04 - (0.04 - depth + 0.001) * (s - 0.55) / 0.05,
            ]
        } else {
            [0.03, 0.03 + 0.025 * (s - 0.6) / 0.4, depth - 0.001]
        }
    };
    let mut fixture_k = 0i64;
    let mut fixture = |w: &mut BagWriter, upto: i64| -> Result<(), CliError> {
        while CARVING_T0_NS + fixture_k * FIXTURE_PERIOD_NS <= upto {
            let stamp = CARVING_T0_NS + fixture_k * FIXTURE_PERIOD_NS;
            // 4 x 30 x 15 voxels of 2 mm at x in [-10, -2) mm: the clamp, one voxel off the block.
            let size = [4u32, 30, 15];
            let voxels = (size[0] * size[1] * size[2]) as usize;
            let mut data = vec![0u8; voxels.div_ceil(8)];
            for i in 0..voxels {
                data[i / 8] |= 1 << (i % 8);
            }
            let g = VoxelGrid {
                header: Header {
                    stamp: Time::from_nanos(stamp),
                    frame_id: "world".into(),
                },
                origin: Point {
                    x: -0.010,
                    y: 0.0,
                    z: 0.0,
                },
                resolution: 0.002,
                size_x: size[0],
                size_y: size[1],
                size_z: size[2],
                encoding: VoxelGrid::ENCODING_BITS,
                data,
            };
            w.write("/fixture/occupancy", stamp as u64, &g)?;
            fixture_k += 1;
        }
        Ok(())
    };
    for k in 0..n {
        let mut stamp = CARVING_T0_NS + k * POSE_PERIOD_NS;
        let p = path(k);
        let mut pose = PoseStamped {
            header: Header {
                stamp: Time::from_nanos(stamp),
                frame_id: "world".into(),
            },
            pose: Pose {
                position: Point {
                    x: p[0],
                    y: p[1],
                    z: p[2],
                },
                orientation: Quaternion::IDENTITY,
            },
        };
        match k {
            200 => pose.pose.position.y = f64::NAN,
            300 => {
                pose.pose.orientation = Quaternion {
                    x: 0.0,
                    y: 0.0,
                    z: 0.0,
                    w: 0.0,
                }
            }
            400 => {
                stamp -= 10 * POSE_PERIOD_NS;
                pose.header.stamp = Time::from_nanos(stamp);
            }
            500 => pose.header.frame_id = "tool0".into(),
            600 => {
                pose.pose.orientation = Quaternion {
                    x: 0.0,
                    y: 0.0,
                    z: 0.0,
                    w: 2.0,
                }
            }
            _ => {}
        }
        fixture(&mut w, stamp)?;
        w.write("/haptic/pose", stamp as u64, &pose)?;
    }
    // The carving node publishes its last frame on the next period after the last pose.
    fixture(
        &mut w,
        CARVING_T0_NS + n * POSE_PERIOD_NS + FIXTURE_PERIOD_NS - 1,
    )?;
    w.finish()?;
    tracing::info!("wrote {}", out.display());
    Ok(())
}
