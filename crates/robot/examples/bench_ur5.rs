//! Times frames of the UR5 of example-robot-data (its STL collision meshes), one core:
//! 128³ and 256³ lattices over 2 m around the base, `bits` and `percent`, each frame at a
//! new joint configuration. Prints the median, 90th percentile and max per frame.
//!
//! ```text
//! python3 -m venv /tmp/robot-venv && /tmp/robot-venv/bin/pip install example-robot-data
//! cargo run --release --example bench_ur5 -- \
//!   /tmp/robot-venv/lib/python3.*/site-packages/cmeel.prefix/share
//! ```
//!
//! The argument is the directory holding `example-robot-data/` (the package).

use chronotope_robot::{
    BasePose, Encoding, Lattice, LinkPoses, LoadOptions, RasterOptions, Rasterizer, Robot,
};
use std::path::PathBuf;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let share = PathBuf::from(
        std::env::args()
            .nth(1)
            .ok_or("usage: bench_ur5 SHARE_DIR")?,
    );
    let frames: usize = std::env::args()
        .nth(2)
        .and_then(|s| s.parse().ok())
        .unwrap_or(200);
    // Optional filter, e.g. `128-bits`: only that lattice and encoding (for profiling).
    let only = std::env::args().nth(3);
    let urdf = share.join("example-robot-data/robots/ur_description/urdf/ur5_robot.urdf");
    let t = Instant::now();
    let robot = Robot::from_urdf_file(&urdf, LoadOptions::new().package_path(vec![share.clone()]))?;
    println!(
        "loaded {} ({} triangles, {} links) in {:.1} ms",
        urdf.display(),
        robot.load_report().triangles,
        robot.model().links.len(),
        t.elapsed().as_secs_f64() * 1e3
    );
    let kin = robot.kinematics();
    let body = robot.whole_body();
    // A fixed pseudo-random walk through the joint space: reproducible configurations.
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let configs: Vec<Vec<f64>> = (0..frames)
        .map(|_| {
            (0..kin.dof())
                .map(|_| (next() * 2.0 - 1.0) * std::f64::consts::PI)
                .collect()
        })
        .collect();
    let mut poses = LinkPoses::new();
    println!("| lattice | encoding | min ms | median ms | p90 ms | max ms | occupied (mean) | crossings (mean) |");
    println!("|---|---|---|---|---|---|---|---|");
    for n in [128u32, 256] {
        let lattice = Lattice::cube([-1.0, -1.0, -1.0], 2.0, n)?;
        for encoding in [Encoding::Bits, Encoding::Percent] {
            let tag = format!(
                "{n}-{}",
                if encoding == Encoding::Bits {
                    "bits"
                } else {
                    "percent"
                }
            );
            if only.as_ref().is_some_and(|o| *o != tag) {
                continue;
            }
            let mut raster = Rasterizer::new(lattice, encoding, RasterOptions::default());
            // Warm-up: grow the buffers.
            kin.forward(&configs[0], &BasePose::IDENTITY, &mut poses);
            raster.rasterize(&robot, &body, &poses);
            let mut times = Vec::with_capacity(frames);
            let (mut occupied, mut events) = (0, 0);
            for q in &configs {
                let t = Instant::now();
                kin.forward(q, &BasePose::IDENTITY, &mut poses);
                let stats = raster.rasterize(&robot, &body, &poses);
                times.push(t.elapsed().as_secs_f64() * 1e3);
                occupied += stats.occupied;
                events += stats.events;
            }
            times.sort_by(f64::total_cmp);
            println!(
                "| {n}³ over 2 m | {:?} | {:.3} | {:.3} | {:.3} | {:.3} | {} | {} |",
                encoding,
                times[0],
                times[times.len() / 2],
                times[times.len() * 9 / 10],
                times[times.len() - 1],
                occupied / frames,
                events / frames
            );
        }
    }
    Ok(())
}
