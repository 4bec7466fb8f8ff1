//! `chronotope sample SCENE.yaml --out samples.mcap [--ply samples.ply] [--scheme S]
//! [--samples N] [--seed S] [--dt DT] ...`: samples an implicit scene (see
//! [`crate::sampler::scene_file`]) and writes the points as a `sensor_msgs/PointCloud2`
//! (fields x, y, z, and t for a 4D scene, float32) on `/sampler/points`; for a 4D scene a
//! second cloud on `/sampler/yzt` holds the seed's YZT projection (x ← y, y ← z, z ← t) so
//! that rviz2 or Foxglove shows it as the seed's Fig. 3. `--ply` also writes a
//! binary_little_endian PLY (vertex x, y, z[, t] as float32).

use super::CliError;
use crate::bag::BagWriter;
use crate::msg::{Header, PointCloud2, PointField, Time};
use crate::sampler::scene_file::{SceneFile, SceneFileError};
use crate::sampler::{sample, LambdaPolicy, Scheme, Q};
use clap::Args;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Topic of the sampled points.
pub const POINTS_TOPIC: &str = "/sampler/points";
/// Topic of the YZT projection of a 4D scene's samples.
pub const YZT_TOPIC: &str = "/sampler/yzt";
/// Stamp of the clouds (the scenes' start time, 1 700 000 000 s).
const STAMP_NS: i64 = crate::scene::SCENE_START_NS;

/// Options of `chronotope sample`.
#[derive(Debug, Clone, Args)]
pub struct SampleArgs {
    /// The scene file (YAML; examples under scenes/implicit/).
    pub scene: PathBuf,
    /// Output bag (MCAP).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the samples as a PLY file.
    #[arg(long)]
    pub ply: Option<PathBuf>,
    /// explicit (seed eq. 2, Euler-Maruyama), projected (Newton) or metropolis (unbiased).
    #[arg(long)]
    pub scheme: Option<Scheme>,
    /// Samples to write (default: the scene's, else 10000).
    #[arg(long)]
    pub samples: Option<usize>,
    /// RNG seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Time step (noise variance 2·α·dt per coordinate).
    #[arg(long)]
    pub dt: Option<f64>,
    /// Walkers.
    #[arg(long)]
    pub walkers: Option<usize>,
    /// Burn-in steps per walker.
    #[arg(long)]
    pub burn_in: Option<usize>,
    /// Steps between samples of one walker.
    #[arg(long)]
    pub thin: Option<usize>,
    /// Explicit scheme: λ = Kαdt (must be < 2).
    #[arg(long)]
    pub lambda: Option<f64>,
    /// Explicit scheme: clamp λ ≥ 2 to 1 instead of refusing.
    #[arg(long)]
    pub clamp: bool,
}

/// Samples the scene and writes the bag (and PLY).
///
/// # Errors
/// A bad scene file or option, walkers that cannot reach the figure, or a file that cannot
/// be written.
pub fn run(a: &SampleArgs) -> Result<(), CliError> {
    let scene = SceneFile::read(&a.scene)?.build()?;
    let mut o = scene.options.clone().seed(a.seed);
    if let Some(v) = a.scheme {
        o.scheme = v;
    }
    if let Some(v) = a.samples {
        o.samples = v;
    }
    if let Some(v) = a.dt {
        o.dt = v;
    }
    if let Some(v) = a.walkers {
        o.walkers = v;
    }
    if let Some(v) = a.burn_in {
        o.burn_in = v;
    }
    if let Some(v) = a.thin {
        o.thin = v;
    }
    if let Some(v) = a.lambda {
        o.lambda = v;
    }
    if a.clamp {
        o.on_unstable = LambdaPolicy::Clamp;
    }
    let t0 = std::time::Instant::now();
    let s = sample(&scene.figure, &o).map_err(SceneFileError::from)?;
    let secs = t0.elapsed().as_secs_f64();
    let dim = scene.figure.dim();
    let st = &s.stats;
    if let Some(l) = st.clamped_lambda {
        tracing::warn!("λ = {l} ≥ 2 clamped to 1");
    }
    println!(
        "{} samples ({} scheme, dt {}, {} walkers) in {secs:.3} s: {} steps, {} function evaluations, max |F|/|∇F| {:.2e}",
        s.points.len(),
        o.scheme.as_str(),
        o.dt,
        o.walkers,
        st.steps,
        st.evals,
        st.max_residual
    );
    println!(
        "  rejected: walls {}, metropolis {}, reverse check {}; failed projections {}; singular {}; guarded {}",
        st.rejected_walls,
        st.rejected_metropolis,
        st.rejected_reverse,
        st.failed_projections,
        st.singular,
        st.guarded
    );
    let mut w = BagWriter::create(&a.out)?;
    w.add_topic::<PointCloud2>(POINTS_TOPIC)?;
    let cloud = point_cloud(&s.points, dim, None);
    w.write(POINTS_TOPIC, STAMP_NS as u64, &cloud)?;
    if dim == 4 {
        w.add_topic::<PointCloud2>(YZT_TOPIC)?;
        let yzt = point_cloud(&s.points, 3, Some([1, 2, 3]));
        w.write(YZT_TOPIC, STAMP_NS as u64, &yzt)?;
    }
    w.finish()?;
    if let Some(p) = &a.ply {
        write_ply(p, &s.points, dim).map_err(|source| CliError::Io {
            path: p.clone(),
            source,
        })?;
    }
    Ok(())
}

/// A PointCloud2 of `points` with `dim` float32 fields named x, y, z, t; `pick` chooses
/// which coordinates fill the three fields x, y, z (the YZT projection is `[1, 2, 3]`).
pub fn point_cloud(points: &[Q], dim: usize, pick: Option<[usize; 3]>) -> PointCloud2 {
    let names = ["x", "y", "z", "t"];
    let dim = dim.min(4);
    let fields = (0..dim)
        .map(|i| PointField::new(names[i], 4 * i as u32, PointField::FLOAT32, 1))
        .collect();
    let step = 4 * dim;
    let mut data = Vec::with_capacity(points.len() * step);
    for q in points {
        for i in 0..dim {
            let c = pick.map_or(i, |p| p[i]);
            data.extend_from_slice(&(q[c] as f32).to_le_bytes());
        }
    }
    PointCloud2 {
        header: Header {
            stamp: Time::from_nanos(STAMP_NS),
            frame_id: crate::scene::SCENE_FRAME_ID.to_owned(),
        },
        height: 1,
        width: points.len() as u32,
        fields,
        is_bigendian: false,
        point_step: step as u32,
        row_step: (step * points.len()) as u32,
        data,
        is_dense: true,
    }
}

/// Writes a binary_little_endian PLY with float32 vertex properties x, y, z (and t).
///
/// # Errors
/// The file cannot be written.
pub fn write_ply(path: &Path, points: &[Q], dim: usize) -> std::io::Result<()> {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
    write!(
        f,
        "ply\nformat binary_little_endian 1.0\ncomment chronotope sample (seed 001 stochastic sampler)\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n",
        points.len()
    )?;
    if dim == 4 {
        writeln!(f, "property float t")?;
    }
    writeln!(f, "end_header")?;
    for q in points {
        for c in q.iter().take(dim.clamp(3, 4)) {
            f.write_all(&(*c as f32).to_le_bytes())?;
        }
    }
    f.flush()
}
