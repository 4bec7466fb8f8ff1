//! `chronotope bench …`: the arguments of the benchmarks, and the calls into
//! [`crate::bench`], where the programs are.

use super::CliError;
use super::EncodingArg;
use crate::bench;
use crate::msg::VoxelEncoding;
use crate::scene::{SceneName, SceneOptions};
use clap::{Args, Subcommand};

/// Options of `chronotope bench`.
#[derive(Debug, Clone, Args)]
pub struct BenchArgs {
    /// Which benchmark.
    #[command(subcommand)]
    pub which: BenchWhich,
    /// Threads of the rayon pool the benchmark runs in (default: RAYON_NUM_THREADS, or
    /// one per core).
    #[arg(long, global = true)]
    pub threads: Option<usize>,
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
        /// Then play the frames, in time order, through the nodes of this launch config in
        /// one process (as a live launch does, without the transport) and print the work
        /// per input frame by body, and each node's time.
        #[arg(long)]
        launch: Option<std::path::PathBuf>,
    },
    /// Error against run time on four-spheres: the checker's intervals, first contacts,
    /// overlap hypervolumes and translations against the exact answers.
    Accuracy {
        /// Grids (frames = grid + 1 over 1 s, so c = 1 m/s at every grid).
        #[arg(long, value_delimiter = ',', default_value = "32,64,128")]
        grids: Vec<u32>,
        /// Encodings.
        #[arg(
            long,
            value_delimiter = ',',
            value_enum,
            default_value = "bits,percent"
        )]
        encodings: Vec<EncodingArg>,
        /// Also write a log-log plot of the errors against the run time (SVG).
        #[arg(long)]
        svg: Option<std::path::PathBuf>,
    },
    /// The robot node: with --accuracy, the robot cell's first contact and interval against
    /// the exact contact times per grid and encoding; else the UR5 of example-robot-data in
    /// a robot node, joint states at 500 Hz, frames at 30 Hz: frame time and memory.
    Robot {
        /// The directory holding `example-robot-data/` (its `share` directory).
        #[arg(long)]
        share: Option<std::path::PathBuf>,
        /// Voxels per edge of the 2 m lattice (speed), or of the cell (accuracy).
        #[arg(long, value_delimiter = ',', default_value = "128,256")]
        grids: Vec<u32>,
        /// Encodings.
        #[arg(
            long,
            value_delimiter = ',',
            value_enum,
            default_value = "bits,percent"
        )]
        encodings: Vec<EncodingArg>,
        /// Seconds of joint-state stream (speed).
        #[arg(long, default_value_t = 60.0)]
        seconds: f64,
        /// The accuracy table instead of the speed.
        #[arg(long)]
        accuracy: bool,
    },
    /// Two spheres at the seed's scale (~1.5M tets each at grid 88): detection plus labels
    /// and resolution timed, next to per-frame 3D checks with parry3d, and what each misses.
    Check {
        /// Voxels per edge (frames = grid + 1 over 1 s).
        #[arg(long, default_value_t = 88)]
        grid: u32,
        /// Encoding.
        #[arg(long, value_enum, default_value_t = EncodingArg::Bits)]
        encoding: EncodingArg,
        /// Timed repetitions of detection plus labels and of resolution (medians printed).
        #[arg(long, default_value_t = 3)]
        reps: usize,
        /// Frame counts of the what-each-misses sweep.
        #[arg(long, value_delimiter = ',', default_value = "3,5,9,17,33")]
        sweep: Vec<u32>,
        /// Skip the sweep.
        #[arg(long)]
        no_sweep: bool,
    },
    /// The rotation suggestion against the exact smallest angle: a bar turning away from a
    /// post about its end, at several grids.
    Rotation {
        /// Grids (the domain is 1.28 m; multiples of 32 put the bar's faces on voxel
        /// boundaries).
        #[arg(long, value_delimiter = ',', default_value = "32,64,128")]
        grids: Vec<u32>,
        /// Encodings.
        #[arg(
            long,
            value_delimiter = ',',
            value_enum,
            default_value = "bits,percent"
        )]
        encodings: Vec<EncodingArg>,
    },
    /// The stochastic sampler: at default settings, KS of each coordinate and effective
    /// sample size on spheres, a torus, the seed's figures and 4D sets, with the cost per
    /// effective sample; then uniformity error (KS) against run time and evaluations per
    /// scheme and step on three figures with exact answers.
    Sampler {
        /// Time steps (noise variance 2·dt per coordinate).
        #[arg(long, value_delimiter = ',', default_value = "0.01,0.003,0.001")]
        dts: Vec<f64>,
        /// Samples of the longest error-against-time run.
        #[arg(long, default_value_t = 256_000)]
        samples: usize,
        /// The KS level at which samples per second are compared.
        #[arg(long, default_value_t = 0.01)]
        target: f64,
        /// Samples of each default-settings run (N).
        #[arg(long, default_value_t = 20_000)]
        n: usize,
        /// Seeds over which the default-settings pass rates are counted.
        #[arg(long, default_value_t = 10)]
        seeds: u64,
        /// Only the default-settings section (no error-against-time runs).
        #[arg(long)]
        no_sweep: bool,
        /// Write the Markdown report here (e.g. docs/sampler-error.md).
        #[arg(long)]
        out: Option<std::path::PathBuf>,
        /// Write an SVG plot here.
        #[arg(long)]
        svg: Option<std::path::PathBuf>,
    },
    /// Carving: per-pose update time of a knife stroke (256^3 grid, ~1M surfels, tool sizes);
    /// with --accuracy, error against the exact swept solid and the force's variation.
    Carve {
        /// Poses per stroke (speed).
        #[arg(long, default_value_t = 2000)]
        poses: usize,
        /// Run the accuracy benchmark instead.
        #[arg(long)]
        accuracy: bool,
        /// Grid spacings of the accuracy benchmark (mm).
        #[arg(long, value_delimiter = ',', default_value = "1,0.5,0.25")]
        spacings: Vec<f64>,
        /// Write the accuracy tables here (Markdown), e.g. docs/carving-accuracy.md.
        #[arg(long)]
        out: Option<std::path::PathBuf>,
    },
}

/// Runs a benchmark and prints its figures.
///
/// # Errors
/// Bad scene options.
pub fn run(a: &BenchArgs) -> Result<(), CliError> {
    match a.threads {
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n.clamp(1, 1024))
            .build()
            .map_err(|e| CliError::Usage(format!("--threads {n}: {e}")))?
            .install(|| run_in_pool(a)),
        None => run_in_pool(a),
    }
}

fn run_in_pool(a: &BenchArgs) -> Result<(), CliError> {
    println!("rayon pool: {} thread(s)", rayon::current_num_threads());
    match &a.which {
        BenchWhich::Mesh {
            scene,
            grid,
            frames,
            encoding,
            validate,
            launch,
        } => {
            let mut o = SceneOptions::for_scene(*scene).encoding((*encoding).into());
            if let Some(g) = grid {
                o = o.grid(*g);
            }
            if let Some(f) = frames {
                o = o.frames(*f);
            }
            bench::mesh::bench_mesh(*scene, &o, *validate)?;
            let build = |c: &crate::node::launch::LaunchConfig, topics: &[String]| {
                crate::node::factory::build_nodes(c, topics, false).map(|(nodes, _)| nodes)
            };
            match launch {
                Some(l) => Ok(bench::mesh::bench_nodes(*scene, &o, l, &build)?),
                None => Ok(()),
            }
        }
        BenchWhich::Accuracy {
            grids,
            encodings,
            svg,
        } => {
            let encodings: Vec<VoxelEncoding> = encodings.iter().map(|e| (*e).into()).collect();
            Ok(bench::mesh::bench_accuracy(
                grids,
                &encodings,
                svg.as_deref(),
            )?)
        }
        BenchWhich::Robot {
            share,
            grids,
            encodings,
            seconds,
            accuracy,
        } => {
            let encodings: Vec<VoxelEncoding> = encodings.iter().map(|e| (*e).into()).collect();
            if *accuracy {
                return Ok(bench::robot::accuracy(grids, &encodings)?);
            }
            let Some(share) = share else {
                return Err(CliError::Usage(
                    "--share DIR: the directory holding example-robot-data/ (python -c \"import \
                     example_robot_data, os; print(os.path.dirname(os.path.dirname(\
                     example_robot_data.getModelPath('ur5_robot.urdf'))))\")"
                        .into(),
                ));
            };
            for &g in grids {
                for &e in &encodings {
                    bench::robot::speed(share, g, e, *seconds)?;
                }
            }
            Ok(())
        }
        BenchWhich::Check {
            grid,
            encoding,
            reps,
            sweep,
            no_sweep,
        } => Ok(bench::check::bench_check(
            *grid,
            (*encoding).into(),
            *reps,
            if *no_sweep { &[] } else { sweep },
        )?),
        BenchWhich::Rotation { grids, encodings } => {
            let encodings: Vec<VoxelEncoding> = encodings.iter().map(|e| (*e).into()).collect();
            Ok(bench::rotate::bench_rotation(grids, &encodings)?)
        }
        BenchWhich::Sampler {
            dts,
            samples,
            target,
            n,
            seeds,
            no_sweep,
            out,
            svg,
        } => Ok(bench::sampler::bench_sampler(
            &bench::sampler::BenchSamplerOptions {
                dts: dts.clone(),
                max_samples: (*samples).clamp(1000, crate::sampler::MAX_SAMPLES / 2),
                target: *target,
                n: (*n).clamp(100, 1_000_000),
                seeds: (*seeds).clamp(1, 1000),
                no_sweep: *no_sweep,
            },
            out.as_deref(),
            svg.as_deref(),
        )?),
        BenchWhich::Carve {
            poses,
            accuracy,
            spacings,
            out,
        } => {
            if *accuracy {
                Ok(bench::carve::bench_carve_accuracy(
                    spacings,
                    out.as_deref(),
                )?)
            } else {
                Ok(bench::carve::bench_carve(*poses)?)
            }
        }
    }
}
