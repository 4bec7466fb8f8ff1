//! `chronotope scene NAME --out FILE.mcap [--grid N] [--frames F] [--encoding bits|percent]`.

use super::CliError;
use super::EncodingArg;
use crate::bag::{BagWriteOptions, BagWriter};
use crate::msg::VoxelGrid;
use crate::scene::{build_scene, Rasterizer, SceneName, SceneOptions};
use clap::Args;
use std::path::PathBuf;

/// Options of `chronotope scene`.
#[derive(Debug, Clone, Args)]
pub struct SceneArgs {
    /// `machine-tool`, `four-spheres`, `periodic` (two spheres meeting every 2 s, 20 Hz, for
    /// as long as asked), `carving-session` (haptic tool poses and a fixture), or
    /// `robot-cell` (a six-axis arm's description, joint states and /tf_static beside a
    /// machine-tool table's frames), `person-cell` (a person reaching into the machine-tool
    /// cell, seen by a depth camera as a point cloud and mapped as an OctoMap).
    pub name: String,
    /// Output bag: an MCAP file, or a rosbag2 directory (with metadata.yaml) if the path
    /// ends with `/` or is a directory.
    #[arg(long)]
    pub out: PathBuf,
    /// Voxels per edge of the cubic domain (default: the scene's).
    #[arg(long)]
    pub grid: Option<u32>,
    /// Frames per body (default: the scene's).
    #[arg(long, conflicts_with = "duration")]
    pub frames: Option<u32>,
    /// Seconds of recording (`periodic` only: 20 frames per second, plus the first).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Voxel encoding.
    #[arg(long, value_enum, default_value_t = EncodingArg::Bits)]
    pub encoding: EncodingArg,
    /// Replace an output path that holds a bag this program did not derive (a recording, a
    /// bag of another program).
    #[arg(long)]
    pub overwrite: bool,
    /// `robot-cell` only: the arm's dip as a plan (`/arm_controller/joint_trajectory`, sent
    /// before it starts) instead of joint states, which then stop when the plan is sent.
    #[arg(long)]
    pub plan: bool,
    /// `robot-cell` and `person-cell`: the cell's frames per second (default 10). The motion
    /// keeps its length in frames, so `robot-cell` at 30 Hz is 4 s of 121 frames and
    /// `person-cell --frames 150 --frame-hz 30` is 5 s.
    #[arg(long)]
    pub frame_hz: Option<f64>,
    /// `robot-cell` only: joint states per second, each instant in two partial messages
    /// (default 200).
    #[arg(long)]
    pub joint_hz: Option<f64>,
    /// `person-cell` only: the depth camera's pixels, WIDTHxHEIGHT (default 48x36; 640x480 is
    /// a 307 200-point organised cloud, NaN where a ray misses the person).
    #[arg(long)]
    pub camera: Option<String>,
}

/// A rate option as a period in whole nanoseconds: 0.1 to 10 000 per second.
fn period_ns(option: &str, hz: Option<f64>, default_ns: i64) -> Result<i64, CliError> {
    match hz {
        None => Ok(default_ns),
        Some(hz) if hz.is_finite() && (0.1..=10_000.0).contains(&hz) => {
            Ok((1e9 / hz).round() as i64)
        }
        Some(hz) => Err(CliError::Usage(format!(
            "{option} {hz}: use 0.1..=10000 per second"
        ))),
    }
}

/// The cut-out images the carving session writes next to its bag.
const CARVING_IMAGES: [&str; 2] = ["carving-outline-z.pgm", "carving-outline-y.pgm"];

/// Writes the scene bag: frames in time order, bodies interleaved, log time = stamp.
///
/// # Errors
/// Bad options or a bag that cannot be written.
pub fn run(a: &SceneArgs) -> Result<(), CliError> {
    use super::paths::{OutputKind, Paths};
    let mut paths =
        Paths::new(a.overwrite).output("--out", Some(&a.out), OutputKind::Bag { derived: true });
    if a.name == "carving-session" {
        let dir = crate::fsio::parent_dir(&a.out);
        for name in CARVING_IMAGES {
            paths = paths.output(
                "the cut-out image beside --out",
                Some(&dir.join(name)),
                OutputKind::File,
            );
        }
        paths.check()?;
        return carving_session(&a.out);
    }
    paths.check()?;
    if a.camera.is_some() && a.name != "person-cell" {
        return Err(CliError::Usage(
            "--camera is for the person-cell scene".into(),
        ));
    }
    if a.frame_hz.is_some() && !matches!(a.name.as_str(), "robot-cell" | "person-cell") {
        return Err(CliError::Usage(
            "--frame-hz is for the robot-cell and person-cell scenes".into(),
        ));
    }
    if a.name == "robot-cell" {
        if a.frames.is_some() || a.duration.is_some() {
            return Err(CliError::Usage(
                "robot-cell has a fixed length (4 s): no --frames or --duration (--frame-hz and \
                 --joint-hz set its rates)"
                    .into(),
            ));
        }
        let timing = super::scene_robot::RobotCellTiming {
            frame_period_ns: period_ns(
                "--frame-hz",
                a.frame_hz,
                crate::scene::ROBOT_CELL_FRAME_PERIOD_NS,
            )?,
            joint_period_ns: period_ns(
                "--joint-hz",
                a.joint_hz,
                crate::scene::ROBOT_CELL_JOINT_PERIOD_NS,
            )?,
        };
        return super::scene_robot::robot_cell(
            &a.out,
            a.grid.unwrap_or(32),
            a.encoding.into(),
            a.plan,
            timing,
        );
    }
    if a.plan {
        return Err(CliError::Usage("--plan is for the robot-cell scene".into()));
    }
    if a.joint_hz.is_some() {
        return Err(CliError::Usage(
            "--joint-hz is for the robot-cell scene".into(),
        ));
    }
    if a.name == "person-cell" {
        return person_cell(a);
    }
    let name: SceneName = a.name.parse()?;
    let mut opts = SceneOptions::for_scene(name).encoding(a.encoding.into());
    if let Some(g) = a.grid {
        opts = opts.grid(g);
    }
    if let Some(f) = a.frames {
        opts = opts.frames(f);
    }
    if let Some(d) = a.duration {
        if name != SceneName::Periodic {
            return Err(CliError::Usage(format!(
                "--duration is for the periodic scene; {name} takes --frames"
            )));
        }
        let period_s = crate::scene::PERIODIC_FRAME_PERIOD_NS as f64 / 1e9;
        let frames = (d / period_s).round() + 1.0;
        if !(d.is_finite() && d >= 0.0 && frames <= f64::from(crate::scene::MAX_FRAMES)) {
            return Err(CliError::Usage(format!(
                "--duration {d}: use 0..={} s",
                f64::from(crate::scene::MAX_FRAMES - 1) * period_s
            )));
        }
        opts = opts.frames(frames as u32);
    }
    let scene = build_scene(name, &opts)?;
    let mut w = BagWriter::create_with(&a.out, BagWriteOptions::new().derived("scene"))?;
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

/// Poses of the carving session (3 s at 500 Hz).
const CARVING_POSES: i64 = 1500;

/// The cut-out images of the carving session, written next to its bag: the outline seen from
/// above (cut along z) and the profile seen from the side (cut along y), black = material.
fn carving_outlines(dir: &std::path::Path) -> Result<(), CliError> {
    let write = |name: &str, w: usize, h: usize, black: &dyn Fn(f64, f64) -> bool| {
        // P2 text: small, diffable, one row per line; (u, v) in [0, 1]^2, v up.
        let mut t = format!("P2\n# chronotope scene carving-session: {name}\n{w} {h}\n1\n");
        for row in 0..h {
            let v = 1.0 - (row as f64 + 0.5) / h as f64;
            let line: Vec<&str> = (0..w)
                .map(|col| {
                    let u = (col as f64 + 0.5) / w as f64;
                    if black(u, v) {
                        "0"
                    } else {
                        "1"
                    }
                })
                .collect();
            t.push_str(&line.join(" "));
            t.push('\n');
        }
        super::write_output(&dir.join(name), t.as_bytes())
    };
    // From above (x right, y up): a body (ellipse) and a head (disc) towards +x.
    write(CARVING_IMAGES[0], 60, 60, &|u, v| {
        let body = ((u - 0.45) / 0.4).powi(2) + ((v - 0.5) / 0.3).powi(2) < 1.0;
        let head = (u - 0.8).powi(2) + (v - 0.5).powi(2) < 0.15f64.powi(2);
        body || head
    })?;
    // From the side (x right, z up): a back rounded down towards both ends.
    write(CARVING_IMAGES[1], 60, 30, &|u, v| {
        v < 1.0 - 0.5 * ((u - 0.5) / 0.5).powi(2)
    })
}

/// A recorded haptic carving session: `/haptic/pose` (PoseStamped, 500 Hz, 3 s) on the block
/// of `launch_configs/carving_session.yaml` (cut out beforehand by the two images this also
/// writes next to the bag): a knife stroke planing a groove along x while turning 30° about
/// z, a lift, then (the launch config's `tool_schedule` switches to the chisel at 1.5 s) a
/// chisel V-groove along y; with the faults a device produces (a NaN pose, a zero
/// quaternion, a stamp going backwards, a pose in another frame, a non-unit quaternion); and
/// `/fixture/occupancy`, a clamp one voxel off the block's -x face, on the block's lattice and
/// frame times.
fn carving_session(out: &std::path::Path) -> Result<(), CliError> {
    use crate::carving::Quat as Q;
    use crate::msg::{Header, Point, Pose, PoseStamped, Quaternion, Time};
    let dir = out
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(std::path::Path::new("."));
    carving_outlines(dir)?;
    let mut w = BagWriter::create_with(out, BagWriteOptions::new().derived("scene"))?;
    w.add_topic::<PoseStamped>("/haptic/pose")?;
    w.add_topic::<VoxelGrid>("/fixture/occupancy")?;
    let n = CARVING_POSES;
    // The knife's blade faces +x (tool z → x, its length along -z), turned about z.
    let facing_x = Q::from_axis_angle([0.0, 1.0, 0.0], std::f64::consts::FRAC_PI_2);
    let knife =
        |turn_deg: f64| Q::from_axis_angle([0.0, 0.0, 1.0], turn_deg.to_radians()).mul(&facing_x);
    // The chisel cuts along its x: turned to cut along y, its V opening up.
    let chisel = Q::from_axis_angle([0.0, 0.0, 1.0], std::f64::consts::FRAC_PI_2);
    let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
    // The knife (16 mm long) centred 4 mm below the block's 30 mm top + 8 mm.
    let kz = 0.030 + 0.008 - 0.004;
    let path = |k: i64| -> ([f64; 3], Q) {
        let s = k as f64 / n as f64; // 0..1 over 3 s
        if s < 0.1 {
            ([0.012, 0.030, lerp(0.045, kz, s / 0.1)], knife(0.0))
        } else if s < 0.45 {
            let t = (s - 0.1) / 0.35;
            ([lerp(0.012, 0.048, t), 0.030, kz], knife(30.0 * t))
        } else if s < 0.5 {
            let t = (s - 0.45) / 0.05;
            (
                [lerp(0.048, 0.030, t), lerp(0.030, 0.006, t), 0.045],
                knife(30.0),
            )
        } else if s < 0.55 {
            // The chisel (from 1.5 s) descends: apex 3 mm below the top.
            ([0.030, 0.006, lerp(0.045, 0.027, (s - 0.5) / 0.05)], chisel)
        } else {
            (
                [0.030, lerp(0.006, 0.054, (s - 0.55) / 0.45), 0.027],
                chisel,
            )
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
        let (p, q) = path(k);
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
                orientation: Quaternion {
                    x: q.x,
                    y: q.y,
                    z: q.z,
                    w: q.w,
                },
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
            // The same rotation, twice the norm: normalised by the node.
            600 => {
                pose.pose.orientation = Quaternion {
                    x: 2.0 * q.x,
                    y: 2.0 * q.y,
                    z: 2.0 * q.z,
                    w: 2.0 * q.w,
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

/// The `person-cell` scene (`crate::scene::PersonCell`): the machine-tool cell's bodies as
/// VoxelGrid frames at 10 Hz, the depth camera's cloud of the person (`/camera/points`, 10 Hz,
/// 33 ms after each cell frame, in `camera_optical`), the map built from it
/// (`/octomap_binary`, 5 Hz) and `/tf_static` placing the camera; log time = stamp.
fn person_cell(a: &SceneArgs) -> Result<(), CliError> {
    use crate::msg::{Octomap, PointCloud2, TFMessage};
    use crate::scene::{PersonCell, CLOUD_TOPIC, OCTOMAP_TOPIC};
    if a.duration.is_some() {
        return Err(CliError::Usage(
            "--duration is for the periodic scene; person-cell takes --frames".into(),
        ));
    }
    let grid = a.grid.unwrap_or(64);
    let frames = a.frames.unwrap_or(16);
    if !(crate::scene::MIN_GRID..=512).contains(&grid) || !(2..=10_000).contains(&frames) {
        return Err(CliError::Usage(format!(
            "person-cell takes --grid {}..=512 and --frames 2..=10000",
            crate::scene::MIN_GRID
        )));
    }
    let period = period_ns(
        "--frame-hz",
        a.frame_hz,
        crate::scene::PERSON_CELL_FRAME_PERIOD_NS,
    )?;
    let pixels = match &a.camera {
        None => crate::scene::CAMERA_PIXELS,
        Some(c) => {
            let parsed = c
                .split_once('x')
                .and_then(|(w, h)| Some([w.parse::<u32>().ok()?, h.parse::<u32>().ok()?]));
            match parsed {
                Some([w, h]) if (1..=4096).contains(&w) && (1..=4096).contains(&h) => [w, h],
                _ => {
                    return Err(CliError::Usage(format!(
                        "--camera {c:?}: WIDTHxHEIGHT, each 1..=4096 pixels"
                    )))
                }
            }
        }
    };
    let scene = PersonCell::with_timing(grid, frames, period, pixels);
    let mut w = BagWriter::create_with(&a.out, BagWriteOptions::new().derived("scene"))?;
    w.add_topic::<TFMessage>("/tf_static")?;
    let topics: Vec<String> = scene
        .cell_bodies()
        .iter()
        .map(|b| b.topic.clone())
        .collect();
    for t in &topics {
        w.add_topic::<VoxelGrid>(t)?;
    }
    w.add_topic::<PointCloud2>(CLOUD_TOPIC)?;
    w.add_topic::<Octomap>(OCTOMAP_TOPIC)?;
    w.write("/tf_static", scene.stamp_ns(0) as u64, &scene.tf_static())?;
    let mut raster = Rasterizer::new();
    for k in 0..scene.frame_count() {
        for (b, t) in topics.iter().enumerate() {
            let g = scene.cell_frame(b, k, &mut raster);
            w.write(t, scene.stamp_ns(k) as u64, &g)?;
        }
        let c = scene.cloud(k);
        w.write(CLOUD_TOPIC, c.header.stamp.as_nanos() as u64, &c)?;
        if k % 2 == 0 {
            let m = scene.octomap(k);
            w.write(OCTOMAP_TOPIC, m.header.stamp.as_nanos() as u64, &m)?;
        }
    }
    w.finish()?;
    tracing::info!(
        "wrote {} (3 bodies x {frames} frames on {grid}^3 voxels, a cloud per frame, a map every other frame)",
        a.out.display()
    );
    Ok(())
}
