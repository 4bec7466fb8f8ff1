//! `chronotope sample SCENE.yaml --out samples.mcap [--ply samples.ply] [--scheme S]
//! [--samples N] [--seed S] [--dt DT] ...`: samples an implicit scene (see
//! [`crate::sampler::scene_file`]) and writes the points as a `sensor_msgs/PointCloud2`
//! (fields x, y, z, and t for a 4D scene, float32) on `/sampler/points`; for a 4D scene a
//! second cloud on `/sampler/yzt` holds the seed's YZT projection (x ← y, y ← z, z ← t) so
//! that rviz2 or Foxglove shows it as the seed's Fig. 3. `--ply` also writes a
//! binary_little_endian PLY (vertex x, y, z[, t] as float32).
//!
//! Samples are written as they are drawn, so memory does not grow with `--samples`: the
//! clouds go out in messages of at most [`CLOUD_POINTS`] points each (all stamped with
//! the scene's start; together they are the samples, in the order drawn), and the PLY is
//! written point by point. The run's steps are bounded by
//! [`crate::sampler::MAX_TOTAL_STEPS`].
//!
//! Every run reports its quality ([`crate::sampler::Quality`]: effective sample size per
//! coordinate, acceptance rate, largest residual, the step and thinning used and how they
//! were found, and for the explicit scheme how far its points lie off the figure): printed,
//! and written as JSON next to the bag (`--summary`, default the bag's path with the
//! extension `quality.json`).

use super::CliError;
use crate::bag::BagWriter;
use crate::msg::{Header, PointCloud2, PointField, Time};
use crate::sampler::scene_file::{SceneFile, SceneFileError};
use crate::sampler::{LambdaPolicy, Quality, SampleStats, Sampler, Scheme, Q};
use clap::Args;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Topic of the sampled points.
pub const POINTS_TOPIC: &str = "/sampler/points";
/// Topic of the YZT projection of a 4D scene's samples.
pub const YZT_TOPIC: &str = "/sampler/yzt";
/// Most points in one PointCloud2 message: 2^20, 16 MiB of float32 x, y, z, t.
pub const CLOUD_POINTS: usize = 1 << 20;
/// Stamp of the clouds (the scenes' start time, 1 700 000 000 s).
const STAMP_NS: i64 = crate::scene::SCENE_START_NS;

/// Options of `chronotope sample`.
#[derive(Debug, Clone, Args)]
pub struct SampleArgs {
    /// The scene file (YAML; examples under scenes/implicit/).
    pub scene: PathBuf,
    /// Output bag: an MCAP file, or a rosbag2 directory (with metadata.yaml) if the path
    /// ends with `/` or is a directory.
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
    /// Time step (noise variance 2·α·dt per coordinate). Default: tuned during burn-in
    /// (metropolis), 1e-3 (explicit, projected).
    #[arg(long)]
    pub dt: Option<f64>,
    /// Walkers (default 16).
    #[arg(long)]
    pub walkers: Option<usize>,
    /// Burn-in steps per walker (default 1000; the step is tuned and the thinning chosen
    /// in them).
    #[arg(long)]
    pub burn_in: Option<usize>,
    /// Steps between samples of one walker. Default: chosen from the burn-in's
    /// autocorrelation, so that the samples are close to independent.
    #[arg(long)]
    pub thin: Option<usize>,
    /// Explicit scheme: λ = Kαdt (must be < 2).
    #[arg(long)]
    pub lambda: Option<f64>,
    /// Explicit scheme: clamp λ ≥ 2 to 1 instead of refusing.
    #[arg(long)]
    pub clamp: bool,
    /// Finish each sample with a Newton projection onto the figure (the explicit scheme's
    /// points lie off it by about a step).
    #[arg(long)]
    pub project: bool,
    /// The acceptance rate the metropolis step is tuned to (default 0.5).
    #[arg(long)]
    pub target_acceptance: Option<f64>,
    /// Where to write the run's quality summary (JSON). Default: the bag's path with the
    /// extension `quality.json`.
    #[arg(long)]
    pub summary: Option<PathBuf>,
    /// Replace an output path that holds a bag this program did not derive.
    #[arg(long)]
    pub overwrite: bool,
}

/// The JSON summary of one `chronotope sample` run.
#[derive(Debug, serde::Serialize)]
pub struct SampleSummary {
    /// The scene file.
    pub scene: String,
    /// The bag written.
    pub out: String,
    /// The RNG seed.
    pub seed: u64,
    /// Wall-clock seconds of the run (start-up, burn-in, sampling and writing).
    pub seconds: f64,
    /// Effective sample size, acceptance, residuals, the adapted settings.
    pub quality: Quality,
    /// Every counter of the run.
    pub stats: SampleStats,
}

/// Where the summary of a run writing `out` goes by default: `out` with the extension
/// `quality.json` (`s.mcap` → `s.quality.json`).
pub fn default_summary_path(out: &Path) -> PathBuf {
    out.with_extension("quality.json")
}

/// Samples the scene and writes the bag (and PLY).
///
/// # Errors
/// A bad scene file or option, walkers that cannot reach the figure, or a file that cannot
/// be written.
pub fn run(a: &SampleArgs) -> Result<(), CliError> {
    use super::paths::{OutputKind, Paths};
    let summary_path = a
        .summary
        .clone()
        .unwrap_or_else(|| default_summary_path(&a.out));
    Paths::new(a.overwrite)
        .input("the scene file", &a.scene)
        .output("--out", Some(&a.out), OutputKind::Bag { derived: true })
        .output("--ply", a.ply.as_deref(), OutputKind::File)
        .output("--summary", Some(&summary_path), OutputKind::File)
        .check()?;
    let scene = SceneFile::read(&a.scene)?.build()?;
    let mut o = scene.options.clone().seed(a.seed);
    if let Some(v) = a.scheme {
        o.scheme = v;
    }
    if let Some(v) = a.samples {
        o.samples = v;
    }
    if let Some(v) = a.dt {
        o.dt = Some(v);
    }
    if let Some(v) = a.walkers {
        o.walkers = v;
    }
    if let Some(v) = a.burn_in {
        o.burn_in = v;
    }
    if let Some(v) = a.thin {
        o.thin = Some(v);
    }
    if let Some(v) = a.lambda {
        o.lambda = v;
    }
    if a.clamp {
        o.on_unstable = LambdaPolicy::Clamp;
    }
    if let Some(v) = a.target_acceptance {
        o.target_acceptance = v;
    }
    o.project = a.project;
    // Refused with the option's name before anything is written.
    o.validate().map_err(SceneFileError::from)?;
    let t0 = std::time::Instant::now();
    let fig = &scene.figure;
    let dim = fig.dim();
    let mut sampler = Sampler::new(fig, &o).map_err(SceneFileError::from)?;
    let mut w =
        BagWriter::create_with(&a.out, crate::bag::BagWriteOptions::new().derived("sample"))?;
    w.add_topic::<PointCloud2>(POINTS_TOPIC)?;
    if dim == 4 {
        w.add_topic::<PointCloud2>(YZT_TOPIC)?;
    }
    let mut ply = match &a.ply {
        Some(p) => Some(
            PlyWriter::create(p, o.samples, dim).map_err(|source| CliError::Io {
                path: p.clone(),
                source,
            })?,
        ),
        None => None,
    };
    // One chunk of samples at a time: drawn, then written to the bag and the PLY.
    let mut chunk: Vec<Q> = Vec::with_capacity(o.samples.min(CLOUD_POINTS));
    let mut drawn = 0usize;
    while drawn < o.samples {
        let n = (o.samples - drawn).min(CLOUD_POINTS);
        chunk.clear();
        chunk.extend((0..n).map(|_| sampler.draw()));
        drawn += n;
        w.write(
            POINTS_TOPIC,
            STAMP_NS as u64,
            &point_cloud(&chunk, dim, None),
        )?;
        if dim == 4 {
            let yzt = point_cloud(&chunk, 3, Some([1, 2, 3]));
            w.write(YZT_TOPIC, STAMP_NS as u64, &yzt)?;
        }
        if let (Some(f), Some(p)) = (ply.as_mut(), &a.ply) {
            f.points(&chunk).map_err(|source| CliError::Io {
                path: p.clone(),
                source,
            })?;
        }
    }
    w.finish()?;
    if let (Some(f), Some(p)) = (ply, &a.ply) {
        f.finish().map_err(|source| CliError::Io {
            path: p.clone(),
            source,
        })?;
    }
    let secs = t0.elapsed().as_secs_f64();
    let st = sampler.stats().clone();
    if let Some(l) = st.clamped_lambda {
        tracing::warn!("λ = {l} ≥ 2 clamped to 1");
    }
    let quality = sampler.quality();
    println!(
        "{drawn} samples ({} scheme, {} walkers) in {secs:.3} s: {} steps ({} in burn-in), {} function evaluations",
        o.scheme.as_str(),
        sampler.walkers(),
        st.steps,
        st.burn_in_steps,
        st.evals,
    );
    println!("{}", quality.describe());
    println!(
        "  rejected: walls {}, metropolis {}, reverse check {}; failed projections {}; singular {}; guarded {}",
        st.rejected_walls,
        st.rejected_metropolis,
        st.rejected_reverse,
        st.failed_projections,
        st.singular,
        st.guarded
    );
    let path = a
        .summary
        .clone()
        .unwrap_or_else(|| default_summary_path(&a.out));
    let summary = SampleSummary {
        scene: a.scene.display().to_string(),
        out: a.out.display().to_string(),
        seed: a.seed,
        seconds: secs,
        quality,
        stats: st,
    };
    let text = serde_json::to_string_pretty(&summary)
        .map_err(|e| CliError::Usage(format!("quality summary: {e}")))?;
    super::write_output(&path, (text + "\n").as_bytes())?;
    println!("  quality summary: {}", path.display());
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
    let mut f = PlyWriter::create(path, points.len(), dim)?;
    f.points(points)?;
    f.finish()
}

/// A binary_little_endian PLY written point by point: the count goes in the header, so it
/// is given first.
pub struct PlyWriter {
    f: std::io::BufWriter<std::fs::File>,
    /// The file, named only once complete ([`crate::fsio::NewFile`]).
    staged: crate::fsio::NewFile,
    dim: usize,
    left: usize,
}

impl PlyWriter {
    /// Creates the file and writes the header for `count` vertices of `dim` (3 or 4)
    /// float32 coordinates.
    ///
    /// # Errors
    /// The file cannot be written.
    pub fn create(path: &Path, count: usize, dim: usize) -> std::io::Result<Self> {
        std::fs::create_dir_all(crate::fsio::parent_dir(path))?;
        let mut staged = crate::fsio::NewFile::create(path)?;
        let mut f = std::io::BufWriter::new(staged.file().try_clone()?);
        write!(
            f,
            "ply\nformat binary_little_endian 1.0\ncomment chronotope sample (seed 001 stochastic sampler)\nelement vertex {count}\nproperty float x\nproperty float y\nproperty float z\n"
        )?;
        if dim == 4 {
            writeln!(f, "property float t")?;
        }
        writeln!(f, "end_header")?;
        Ok(Self {
            f,
            staged,
            dim: dim.clamp(3, 4),
            left: count,
        })
    }

    /// Appends vertices.
    ///
    /// # Errors
    /// The file cannot be written, or more points than the header's count.
    pub fn points(&mut self, points: &[Q]) -> std::io::Result<()> {
        if points.len() > self.left {
            return Err(std::io::Error::other(format!(
                "{} points given, {} left of the header's count",
                points.len(),
                self.left
            )));
        }
        self.left -= points.len();
        for q in points {
            for c in q.iter().take(self.dim) {
                self.f.write_all(&(*c as f32).to_le_bytes())?;
            }
        }
        Ok(())
    }

    /// Flushes the file and gives it its name.
    ///
    /// # Errors
    /// The file cannot be written, or fewer points than the header's count.
    pub fn finish(mut self) -> std::io::Result<()> {
        if self.left != 0 {
            return Err(std::io::Error::other(format!(
                "{} points missing from the header's count",
                self.left
            )));
        }
        self.f.flush()?;
        self.staged.commit()
    }
}
