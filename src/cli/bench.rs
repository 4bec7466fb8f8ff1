//! `chronotope bench mesh`: meshing throughput on a synthetic scene held in memory.
//!
//! Frames are generated before the clock starts, so the figure is the mesher alone (decode,
//! march, and the streaming validation timed separately); `chronotope mesh BAG --stats`
//! measures the end-to-end run from a bag.

use super::CliError;
use super::{frame_ref, EncodingArg};
use crate::mesh::stats::{percentile, StatsAccumulator};
use crate::mesh::{CapSide, Mesher, MesherOptions};
use crate::msg::VoxelGrid;
use crate::scene::{build_scene, Rasterizer, SceneName, SceneOptions};
use clap::{Args, Subcommand};
use std::time::Instant;

/// Options of `chronotope bench`.
#[derive(Debug, Clone, Args)]
pub struct BenchArgs {
    /// Which benchmark.
    #[command(subcommand)]
    pub which: BenchWhich,
}

/// The benchmarks.
#[derive(Debug, Clone, Subcommand)]
pub enum BenchWhich {
    /// Mesh a synthetic scene (default: machine-tool 128^3 x 64, BITS) body by body.
    Mesh {
        /// Scene name.
        #[arg(default_value = "machine-tool")]
        scene: SceneName,
        /// Voxels per edge.
        #[arg(long)]
        grid: Option<u32>,
        /// Frames.
        #[arg(long)]
        frames: Option<u32>,
        /// Encoding.
        #[arg(long, value_enum, default_value_t = EncodingArg::Bits)]
        encoding: EncodingArg,
        /// Also validate (closedness, hypervolume) every slab.
        #[arg(long)]
        validate: bool,
    },
}

/// Runs a benchmark and prints its figures.
///
/// # Errors
/// Bad scene options.
pub fn run(a: &BenchArgs) -> Result<(), CliError> {
    match &a.which {
        BenchWhich::Mesh {
            scene,
            grid,
            frames,
            encoding,
            validate,
        } => {
            let mut o = SceneOptions::for_scene(*scene).encoding((*encoding).into());
            if let Some(g) = grid {
                o = o.grid(*g);
            }
            if let Some(f) = frames {
                o = o.frames(*f);
            }
            bench_mesh(*scene, &o, *validate)
        }
    }
}

fn bench_mesh(name: SceneName, o: &SceneOptions, validate: bool) -> Result<(), CliError> {
    let scene = build_scene(name, o)?;
    println!(
        "scene {name}: {}^3 voxels x {} frames, {:?}, {} bodies",
        o.grid,
        o.frames,
        o.encoding,
        scene.topics().len()
    );
    let mut raster = Rasterizer::new();
    let mut all_slab_ms = Vec::new();
    let (mut tets, mut lateral_vertices, mut total_s, mut validate_s) =
        (0u64, 0u64, 0.0f64, 0.0f64);
    for (b, topic) in scene.topics().iter().enumerate() {
        let frames: Vec<VoxelGrid> = (0..scene.frame_count())
            .map(|k| {
                let mut g = VoxelGrid::default();
                scene.write_frame(b, k, &mut raster, &mut g).map(|_| g)
            })
            .collect::<Result<_, _>>()?;
        let mut m = Mesher::new(MesherOptions::default())?;
        let mut acc = StatsAccumulator::new();
        let mut first_cap = None;
        let mut slab_ms = Vec::new();
        let start = Instant::now();
        let mut body_tets = 0u64;
        for f in &frames {
            let t0 = Instant::now();
            let slab = m.push(&frame_ref(f))?;
            let ms = t0.elapsed().as_secs_f64() * 1e3;
            if let Some(slab) = slab {
                slab_ms.push(ms);
                body_tets += slab.mesh.tets.len() as u64;
                lateral_vertices += slab.mesh.vertices.len() as u64;
                if validate {
                    let v0 = Instant::now();
                    if first_cap.is_none() {
                        first_cap = m.first_frame().and_then(|k| m.cap(k, CapSide::Low));
                    }
                    acc.add_slab(&slab, first_cap.as_ref());
                    validate_s += v0.elapsed().as_secs_f64();
                }
            }
        }
        let body_s = start.elapsed().as_secs_f64();
        total_s += body_s;
        tets += body_tets;
        println!(
            "  {topic:<24} lateral tets {body_tets:>10}  {body_s:>7.3} s  slab p50 {:>6.2} ms  p99 {:>6.2} ms",
            percentile(&slab_ms, 0.5),
            percentile(&slab_ms, 0.99)
        );
        all_slab_ms.extend(slab_ms);
    }
    println!(
        "total {:.3} s on one core ({} lateral tets, {} lateral vertices before welding frames); slab p50 {:.2} ms, p99 {:.2} ms{}",
        total_s,
        tets,
        lateral_vertices,
        percentile(&all_slab_ms, 0.5),
        percentile(&all_slab_ms, 0.99),
        if validate { format!("; streaming validation {validate_s:.3} s") } else { String::new() }
    );
    println!(
        "peak RSS {:.1} MB (frames held in memory for the benchmark)",
        super::peak_rss_mb()
    );
    Ok(())
}
