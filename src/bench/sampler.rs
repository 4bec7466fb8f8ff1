//! `chronotope bench sampler`: how close the sampler's output comes to independent uniform
//! samples, and at what cost.
//!
//! 1. **Default settings** (are N samples close to N independent ones?): on spheres, a
//!    torus, the seed's figures and 4D collision sets, N samples at the default options
//!    (step tuned and thinning chosen in burn-in) and at the defaults before adaptation
//!    (dt 1e-3, 500 burn-in steps, thin 5 and thin 50). For each: the Kolmogorov-Smirnov
//!    distance of each coordinate's marginal to its exact distribution (Archimedes for
//!    spheres, [`TorusTheta`] for the torus, the quadrature of [`crate::sampler::reference`]
//!    for the seed's Figs. 1 and 2, [`PassingSpheres`] for the 4D t), the effective sample
//!    size, and the cost per effective sample. Repeated over seeds for pass rates.
//! 2. **The reference quadrature checked** against the exact marginals of a sphere and a
//!    torus, and against itself at half the spacing on the seed's figures.
//! 3. **Error against run time** for each scheme and step (as before): the torus tube
//!    angle θ (density ∝ R + r cos θ), the unit sphere given by the non-distance function
//!    (|q|² - 1) e^x (x uniform on [-1, 1]), and the t-marginal of the 4D collision set of a
//!    static sphere and a passing one. For each scheme and step, one run draws samples in
//!    growing checkpoints; at each the KS statistic of everything drawn so far is computed
//!    (outside the clock). Each run now also gives its effective sample size and cost per
//!    effective sample. The long-run error of a mean (`E[cos θ]`, `E[x]`, `E[t]`) with its
//!    standard error over walkers separates the bias floor from the mixing noise.

use super::BenchError;
use crate::sampler::exact::{
    ks_statistic, sphere_coordinate_cdf, sphere_x_cdf, PassingSpheres, TorusTheta,
};
use crate::sampler::quality::ess;
use crate::sampler::reference::surface_marginals;
use crate::sampler::{
    Body, Field, Figure, Sampler, SamplerOptions, Scheme, Shape, ShapeAxis, Wall, Q,
};
use std::fmt::Write as _;
use std::sync::Arc;
use std::time::Instant;

/// `(|q|² - 1) e^x`: the unit sphere, not a distance (|∇F| from 2/e to 2e on it).
#[derive(Debug)]
struct ExpSphere;

impl Field for ExpSphere {
    fn eval(&self, q: &Q) -> (f64, Q) {
        let r2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
        let e = q[0].exp();
        let f = (r2 - 1.0) * e;
        (f, [2.0 * q[0] * e + f, 2.0 * q[1] * e, 2.0 * q[2] * e, 0.0])
    }
}

/// A case: its figure, the statistic of a sample, its exact CDF and the exact mean.
struct Case {
    name: &'static str,
    what: &'static str,
    fig: Figure,
    stat: Box<dyn Fn(&Q) -> f64>,
    cdf: Box<dyn Fn(f64) -> f64>,
    mean_stat: Box<dyn Fn(&Q) -> f64>,
    mean_exact: f64,
}

const TORUS: TorusTheta = TorusTheta {
    major: 1.0,
    minor: 0.4,
};
const PASS: PassingSpheres = PassingSpheres {
    ra: 1.0,
    rb: 0.5,
    speed: 1.0,
};
const T_WINDOW: (f64, f64) = (0.6, 1.4);

fn cases() -> Result<Vec<Case>, crate::sampler::SamplerError> {
    let big = Wall::Box {
        min: [-2.0; 4],
        max: [2.0; 4],
    };
    let torus = Body::fixed(Shape::Torus {
        centre: [0.0; 3],
        axis: ShapeAxis::Z,
        major: TORUS.major,
        minor: TORUS.minor,
    });
    let (a, b, window) = passing_spheres();
    let t_cdf = PASS.cdf_on(T_WINDOW.0, T_WINDOW.1, 4000);
    // E[t] by the same Simpson rule.
    let n = 4000;
    let h = (T_WINDOW.1 - T_WINDOW.0) / n as f64;
    let (mut m0, mut m1) = (0.0, 0.0);
    for k in 0..=n {
        let t = T_WINDOW.0 + k as f64 * h;
        let w = if k == 0 || k == n {
            1.0
        } else if k % 2 == 1 {
            4.0
        } else {
            2.0
        };
        m0 += w * PASS.density(t);
        m1 += w * t * PASS.density(t);
    }
    Ok(vec![
        Case {
            name: "torus",
            what: "torus R = 1, r = 0.4: tube angle θ",
            fig: Figure::new(3, vec![Arc::new(torus)])?.wall(big)?,
            stat: Box::new(|q| TORUS.theta(q)),
            cdf: Box::new(|t| TORUS.cdf(t)),
            mean_stat: Box::new(|q| TORUS.theta(q).cos()),
            mean_exact: TORUS.mean_cos(),
        },
        Case {
            name: "exp-sphere",
            what: "unit sphere as (|q|²-1)e^x: x",
            fig: Figure::new(3, vec![Arc::new(ExpSphere)])?.wall(big)?,
            stat: Box::new(|q| q[0]),
            cdf: Box::new(sphere_x_cdf),
            mean_stat: Box::new(|q| q[0]),
            mean_exact: 0.0,
        },
        Case {
            name: "4d-spheres",
            what: "4D collision set, static sphere r 1 vs sphere r 0.5 passing at 1 m/s, t ∈ [0.6, 1.4]: t",
            fig: Figure::new(4, vec![Arc::new(a), Arc::new(b)])?.wall(window)?,
            stat: Box::new(|q| q[3]),
            cdf: Box::new(t_cdf),
            mean_stat: Box::new(|q| q[3]),
            mean_exact: m1 / m0,
        },
    ])
}

/// One checkpoint of one run.
#[derive(Debug, Clone)]
struct Point {
    samples: usize,
    secs: f64,
    evals: u64,
    ks: f64,
}

struct Run {
    case: &'static str,
    scheme: Scheme,
    /// The step given, or `None` for the step tuned in burn-in.
    dt: Option<f64>,
    /// The step used.
    dt_used: f64,
    points: Vec<Point>,
    mean_err: f64,
    mean_se: f64,
    accept: f64,
    /// The sampler's own smallest ESS over the coordinates, and whether it is an upper bound.
    ess: Option<(f64, bool)>,
}

impl Run {
    fn dt_label(&self) -> String {
        match self.dt {
            Some(d) => format!("{d}"),
            None => format!("auto ({:.2e})", self.dt_used),
        }
    }
}

/// Options of the benchmark.
#[derive(Debug, Clone)]
pub struct BenchSamplerOptions {
    /// Steps of the error-against-time runs.
    pub dts: Vec<f64>,
    /// Samples of the longest error-against-time run.
    pub max_samples: usize,
    /// KS level at which samples per second are compared.
    pub target: f64,
    /// Samples of each default-settings run (N).
    pub n: usize,
    /// Seeds of the default-settings pass rates.
    pub seeds: u64,
    /// Skip the error-against-time runs.
    pub no_sweep: bool,
}

/// Runs the benchmark and writes the Markdown report (and an SVG plot).
///
/// # Errors
/// A report file that cannot be written, or a figure the benchmark cannot build.
pub fn bench_sampler(
    o: &BenchSamplerOptions,
    out: Option<&std::path::Path>,
    svg: Option<&std::path::Path>,
) -> Result<(), BenchError> {
    let usage = |e: crate::sampler::SamplerError| BenchError::Usage(e.to_string());
    let command = format!(
        "chronotope bench sampler --n {} --seeds {} --samples {} --target {}{} --out docs/sampler-error.md --svg docs/sampler-error.svg",
        o.n,
        o.seeds,
        o.max_samples,
        o.target,
        if o.no_sweep { " --no-sweep" } else { "" }
    );
    let mut md = String::new();
    let _ = writeln!(
        md,
        "# Sampler: uniformity, effective sample size and cost\n"
    );
    let _ = writeln!(
        md,
        "Command: `{command}` (release build). Date: {}. Machine: {} core(s) (`nproc`), {} (`lscpu` model name).\n",
        today(),
        std::thread::available_parallelism().map_or(0, |n| n.get()),
        cpu_model()
    );
    let _ = writeln!(md, "Written by `chronotope bench sampler`; how the sampler adapts and what it reports: [sampler.md](sampler.md).\n");
    let t0 = Instant::now();
    let (refs_md, refs) = references().map_err(usage)?;
    eprintln!("reference quadratures: {:.1} s", t0.elapsed().as_secs_f64());
    let figures = default_figures(refs).map_err(usage)?;
    md.push_str(&defaults_section(&figures, o.n, o.seeds));
    md.push_str(&refs_md);
    let mut runs = Vec::new();
    let mut checkpoints = Vec::new();
    let cases = cases().map_err(usage)?;
    if !o.no_sweep {
        let mut n = 1000;
        while n < o.max_samples {
            checkpoints.push(n);
            n *= 2;
        }
        checkpoints.push(o.max_samples);
        runs = sweep(&cases, &o.dts, &checkpoints);
        md.push_str(&report(&cases, &runs, &checkpoints, o.target));
    }
    print!("{md}");
    if let Some(p) = out {
        crate::fsio::write_atomic(p, md.as_bytes()).map_err(|source| BenchError::Io {
            path: p.to_owned(),
            source,
        })?;
    }
    if let (Some(p), false) = (svg, o.no_sweep) {
        crate::fsio::write_atomic(p, plot(&cases, &runs).as_bytes()).map_err(|source| {
            BenchError::Io {
                path: p.to_owned(),
                source,
            }
        })?;
    }
    Ok(())
}

/// Today's date (UTC) as YYYY-MM-DD, from the system clock (civil-from-days, H. Hinnant).
fn today() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs()) as i64;
    let z = secs.div_euclid(86_400) + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}")
}

/// The CPU's model name as `lscpu` shows it (from /proc/cpuinfo), or "unknown".
fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_owned())
        })
        .unwrap_or_else(|| "unknown".into())
}

// ---------------------------------------------------------------------------------------
// Default settings.

type Cdf = Arc<dyn Fn(f64) -> f64 + Send + Sync>;

/// A figure of the default-settings table: per coordinate its exact or reference CDF.
struct Figured {
    name: &'static str,
    what: &'static str,
    fig: Figure,
    cdfs: Vec<Option<Cdf>>,
    reference: &'static str,
}

/// The reference marginals of the seed's Figs. 1 and 2 (x, y, z each), and the Markdown
/// section that checks the quadrature.
struct References {
    fig1: [Cdf; 3],
    fig2: [Cdf; 3],
}

fn sphere_figure() -> Result<Figure, crate::sampler::SamplerError> {
    let b = Body::fixed(Shape::Sphere {
        centre: SPHERE_C,
        radius: SPHERE_R,
    });
    Figure::new(3, vec![Arc::new(b)])?.wall(Wall::Box {
        min: [-2.0; 4],
        max: [2.0; 4],
    })
}

fn torus_figure() -> Result<Figure, crate::sampler::SamplerError> {
    let t = Body::fixed(Shape::Torus {
        centre: [0.0; 3],
        axis: ShapeAxis::Z,
        major: TORUS.major,
        minor: TORUS.minor,
    });
    Figure::new(3, vec![Arc::new(t)])?.wall(Wall::Box {
        min: [-2.0; 4],
        max: [2.0; 4],
    })
}

/// Seed Fig. 1: the saddle between the spheres of radius 0.5 and 1.5 (scenes/implicit/seed_fig1.yaml).
fn fig1() -> Result<Figure, crate::sampler::SamplerError> {
    Figure::new(
        3,
        vec![Arc::new(Body::fixed(Shape::SeedSaddle {
            centre: [0.0; 3],
        }))],
    )?
    .wall(Wall::Box {
        min: [-1.5, -1.5, -1.5, 0.0],
        max: [1.5, 1.5, 1.5, 0.0],
    })?
    .wall(Wall::Shell {
        centre: [0.0; 3],
        inner: 0.5,
        outer: 1.5,
    })
}

/// Seed Fig. 2: the surface with holes (scenes/implicit/seed_fig2_holes.yaml).
fn fig2() -> Result<Figure, crate::sampler::SamplerError> {
    Figure::new(
        3,
        vec![Arc::new(Body::fixed(Shape::SeedHoles { centre: [0.0; 3] }))],
    )?
    .wall(Wall::Box {
        min: [-4.0, -4.0, -4.0, 0.0],
        max: [4.0, 4.0, 4.0, 0.0],
    })
}

const SPHERE_C: [f64; 3] = [0.3, -0.2, 0.1];
const SPHERE_R: f64 = 0.7;
const REF_BINS: usize = 16384;

/// Reference quadratures: checked on the sphere and torus, then run on the seed's figures
/// at spacings h and h/2 (the finer is the reference).
fn references() -> Result<(String, References), crate::sampler::SamplerError> {
    let mut md = String::new();
    let _ = writeln!(md, "\n## Reference marginals of the seed's figures\n");
    let _ = writeln!(md, "The seed's Figs. 1 and 2 have no closed-form marginals. Their reference is a quadrature that owes nothing to the walk (`crates/sampler/src/reference.rs`): marching tetrahedra on a grid of spacing h with edge roots on the surface, each triangle cut into 16 with the new vertices projected onto the surface, pieces straddling a wall cut by subdivision, and each flat piece's exact marginal added into {REF_BINS} bins per axis (linear interpolation between bin edges; at a square-root edge of a CDF, such as the torus's z at ±r, that interpolation alone is off by up to ~0.1·sqrt(bin/r)). Checked here against exact marginals, and against itself at twice the spacing. The largest CDF difference bounds what the reference adds to a KS distance.\n");
    let _ = writeln!(
        md,
        "| figure | spacing h (m) | triangles | area (m²) | max CDF difference x, y, z | against |"
    );
    let _ = writeln!(md, "|---|---|---|---|---|---|");
    let row = |md: &mut String,
               name: &str,
               h: f64,
               m: &crate::sampler::reference::SurfaceMarginals,
               d: [f64; 3],
               against: &str| {
        let _ = writeln!(
            md,
            "| {name} | {h} | {} | {:.4} | {:.1e}, {:.1e}, {:.1e} | {against} |",
            m.triangles, m.area, d[0], d[1], d[2]
        );
    };
    // Checks against exact answers, at the spacing used for Fig. 2 relative to the feature.
    let sphere = sphere_figure()?;
    let lo = SPHERE_C.map(|c| c - SPHERE_R - 0.1);
    let hi = SPHERE_C.map(|c| c + SPHERE_R + 0.1);
    {
        let h = 0.04;
        let m = surface_marginals(&sphere, lo, hi, h, REF_BINS)?;
        let d: [f64; 3] = std::array::from_fn(|i| {
            m.cdf[i].max_difference(sphere_coordinate_cdf(SPHERE_C[i], SPHERE_R), 4000)
        });
        row(
            &mut md,
            &format!("sphere r {SPHERE_R}"),
            h,
            &m,
            d,
            "Archimedes (exact)",
        );
    }
    let torus = torus_figure()?;
    let across = TORUS.across_cdf(4000);
    {
        let h = 0.04;
        let m = surface_marginals(&torus, [-1.5, -1.5, -0.5], [1.5, 1.5, 0.5], h, REF_BINS)?;
        let d = [
            m.cdf[0].max_difference(|x| across.eval(x), 4000),
            m.cdf[1].max_difference(|x| across.eval(x), 4000),
            m.cdf[2].max_difference(|z| TORUS.axial_cdf(z), 4000),
        ];
        row(&mut md, "torus R 1, r 0.4", h, &m, d, "exact marginals");
    }
    let mut out = Vec::new();
    for (name, fig, lo, hi, h) in [
        (
            "seed Fig. 1 (saddle in shell)",
            fig1()?,
            [-1.5; 3],
            [1.5; 3],
            0.04,
        ),
        ("seed Fig. 2 (holes)", fig2()?, [-4.0; 3], [4.0; 3], 0.08),
    ] {
        let coarse = surface_marginals(&fig, lo, hi, h, REF_BINS)?;
        let fine = surface_marginals(&fig, lo, hi, h / 2.0, REF_BINS)?;
        let d: [f64; 3] =
            std::array::from_fn(|i| coarse.cdf[i].max_difference(|x| fine.cdf[i].eval(x), 4000));
        row(
            &mut md,
            name,
            h,
            &coarse,
            d,
            &format!("itself at h = {}", h / 2.0),
        );
        let d0 = [0.0; 3];
        row(&mut md, name, h / 2.0, &fine, d0, "(the reference)");
        out.push(fine.cdf.map(|c| Arc::new(move |x: f64| c.eval(x)) as Cdf));
    }
    let fig2 = out.pop().expect("two figures");
    let fig1 = out.pop().expect("two figures");
    Ok((md, References { fig1, fig2 }))
}

fn default_figures(r: References) -> Result<Vec<Figured>, crate::sampler::SamplerError> {
    let exp_sphere =
        Figure::new(3, vec![Arc::new(ExpSphere) as Arc<dyn Field>])?.wall(Wall::Box {
            min: [-2.0; 4],
            max: [2.0; 4],
        })?;
    let across = TORUS.across_cdf(4000);
    let across = Arc::new(move |x: f64| across.eval(x)) as Cdf;
    let sphere_cdfs: Vec<Option<Cdf>> = (0..3)
        .map(|i| Some(Arc::new(sphere_coordinate_cdf(SPHERE_C[i], SPHERE_R)) as Cdf))
        .collect();
    let unit: Vec<Option<Cdf>> = (0..3)
        .map(|_| Some(Arc::new(sphere_coordinate_cdf(0.0, 1.0)) as Cdf))
        .collect();
    let (a, b, window) = passing_spheres();
    let t_cdf = PASS.cdf_on(T_WINDOW.0, T_WINDOW.1, 4000);
    let tori = {
        let still = Body::fixed(Shape::Torus {
            centre: [0.0; 3],
            axis: ShapeAxis::Z,
            major: 1.0,
            minor: 0.3,
        });
        let moving = Body::fixed(Shape::Torus {
            centre: [0.0, -1.0, 0.0],
            axis: ShapeAxis::X,
            major: 1.0,
            minor: 0.3,
        })
        .moving([0.0, 1.0, 0.0], 0.0);
        Figure::new(4, vec![Arc::new(still), Arc::new(moving)])?.wall(Wall::Box {
            min: [-2.5, -2.5, -2.5, 0.0],
            max: [2.5, 2.5, 2.5, 2.0],
        })?
    };
    let [f1x, f1y, f1z] = r.fig1;
    let [f2x, f2y, f2z] = r.fig2;
    Ok(vec![
        Figured {
            name: "sphere",
            what: "sphere r 0.7 about (0.3, -0.2, 0.1) (a new user's first try)",
            fig: sphere_figure()?,
            cdfs: sphere_cdfs,
            reference: "exact (Archimedes)",
        },
        Figured {
            name: "exp-sphere",
            what: "unit sphere as (|q|²-1)e^x, not a distance",
            fig: exp_sphere,
            cdfs: unit,
            reference: "exact (Archimedes)",
        },
        Figured {
            name: "torus",
            what: "torus R 1, r 0.4 around z",
            fig: torus_figure()?,
            cdfs: vec![
                Some(across.clone()),
                Some(across),
                Some(Arc::new(|z| TORUS.axial_cdf(z)) as Cdf),
            ],
            reference: "exact (x, y: quadrature over θ; z: arcsine)",
        },
        Figured {
            name: "seed-fig1",
            what: "seed Fig. 1: z = x² + xy - (xy)²/2 - 1/4 between spheres r 0.5 and 1.5",
            fig: fig1()?,
            cdfs: vec![Some(f1x), Some(f1y), Some(f1z)],
            reference: "quadrature (h 0.02)",
        },
        Figured {
            name: "seed-fig2",
            what: "seed Fig. 2: (9/2)sin²x + 9cos y cos z + |q|² = 6",
            fig: fig2()?,
            cdfs: vec![Some(f2x), Some(f2y), Some(f2z)],
            reference: "quadrature (h 0.04)",
        },
        Figured {
            name: "4d-spheres",
            what: "4D collision set, static sphere r 1 vs sphere r 0.5 passing at 1 m/s, t ∈ [0.6, 1.4]",
            fig: Figure::new(4, vec![Arc::new(a), Arc::new(b)])?.wall(window)?,
            cdfs: vec![None, None, None, Some(Arc::new(t_cdf) as Cdf)],
            reference: "t exact (coarea formula); x, y, z none",
        },
        Figured {
            name: "seed-fig3",
            what: "seed Fig. 3 (scenes/implicit/seed_fig3_tori.yaml): 4D collision set of a torus passing through another, t ∈ [0, 2]",
            fig: tori,
            cdfs: vec![None; 4],
            reference: "none (ESS only)",
        },
    ])
}

/// One default-settings run.
struct DefaultRun {
    label: &'static str,
    secs: f64,
    evals: u64,
    steps: u64,
    dt: f64,
    step_m: f64,
    thin: usize,
    acceptance: f64,
    /// KS per coordinate (None without a reference).
    ks: Vec<Option<f64>>,
    /// ESS per coordinate over every lag (in memory).
    ess_full: Vec<Option<f64>>,
    /// The sampler's own smallest ESS (running estimate) and whether it is an upper bound.
    ess_own: Option<(f64, bool)>,
}

impl DefaultRun {
    fn min_ess(&self) -> Option<f64> {
        self.ess_full
            .iter()
            .flatten()
            .fold(None, |m: Option<f64>, &e| Some(m.map_or(e, |m| m.min(e))))
    }
}

fn run_default(f: &Figured, label: &'static str, o: &SamplerOptions) -> Option<DefaultRun> {
    let t0 = Instant::now();
    let mut s = match Sampler::new(&f.fig, o) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("{} {label}: {e}", f.name);
            return None;
        }
    };
    let points: Vec<Q> = (0..o.samples).map(|_| s.draw()).collect();
    let secs = t0.elapsed().as_secs_f64();
    let q = s.quality();
    let dim = f.fig.dim();
    let walkers = s.walkers();
    let ks = (0..dim)
        .map(|i| {
            f.cdfs[i].as_ref().map(|cdf| {
                let mut v: Vec<f64> = points.iter().map(|p| p[i]).collect();
                ks_statistic(&mut v, |x| cdf(x))
            })
        })
        .collect();
    let ess_full = (0..dim)
        .map(|i| {
            let chains: Vec<Vec<f64>> = (0..walkers)
                .map(|w| {
                    points
                        .iter()
                        .skip(w)
                        .step_by(walkers)
                        .map(|p| p[i])
                        .collect()
                })
                .collect();
            let refs: Vec<&[f64]> = chains.iter().map(|c| &c[..]).collect();
            ess(&refs).map(|e| e.value)
        })
        .collect();
    let ess_own = q.min_ess.map(|e| {
        let upper =
            (0..dim).any(|i| q.ess_upper_bound[i] && q.ess[i].is_some_and(|x| x <= e * 1.0001));
        (e, upper)
    });
    Some(DefaultRun {
        label,
        secs,
        evals: q.evals,
        steps: q.steps,
        dt: q.adaptation.dt,
        step_m: q.adaptation.step_m,
        thin: q.adaptation.thin,
        acceptance: q.acceptance,
        ks,
        ess_full,
        ess_own,
    })
}

fn defaults_section(figures: &[Figured], n: usize, seeds: u64) -> String {
    let mut md = String::new();
    let bound = 1.5 / (n as f64).sqrt();
    let _ = writeln!(md, "## At default settings, N = {n}\n");
    let _ = writeln!(md, "`SamplerOptions::default()` (what `chronotope sample` does with no options): Metropolis, 16 walkers, 1000 burn-in steps in which the step is tuned to acceptance 0.5 and the thinning chosen from the measured autocorrelation, seed 42. Against the defaults before adaptation: dt 1e-3 (steps of ~0.045 m), 500 burn-in steps, thin 5 (the old default) and thin 50. KS: Kolmogorov-Smirnov distance of each coordinate's marginal to its exact (or reference) distribution; bound 1.5/√N = {bound:.4} (independent samples exceed it with probability 0.022 per coordinate; samples worth N/2 with probability 0.21). ESS: effective sample size from the autocorrelation over every lag (`quality::ess`, walkers as chains), smallest over the coordinates; \"own\": the sampler's running estimate that `chronotope sample` reports (at most 128 lags of samples; ≤: the autocorrelation had not died out, an upper bound). Time and evaluations include start-up and burn-in. Cost per effective sample: time / smallest ESS, and evaluations / smallest ESS.\n");
    for f in figures {
        let _ = writeln!(
            md,
            "- **{}**: {}; reference: {}",
            f.name, f.what, f.reference
        );
    }
    let _ = writeln!(md, "\n| figure | settings | dt (step m) | thin | accepted | KS x | KS y | KS z | KS t | ESS/N | own ESS/N | time (s) | evals | µs per ESS | evals per ESS | cost vs old thin 50 |");
    let _ = writeln!(
        md,
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    let old = |thin: usize| {
        SamplerOptions::default()
            .dt(1e-3)
            .burn_in(500)
            .thin(thin)
            .samples(n)
            .seed(42)
    };
    for f in figures {
        let runs: Vec<DefaultRun> = [
            ("default", SamplerOptions::default().samples(n).seed(42)),
            ("old, thin 5", old(5)),
            ("old, thin 50", old(50)),
        ]
        .iter()
        .filter_map(|(label, o)| run_default(f, label, o))
        .collect();
        let old50 = runs.iter().find(|r| r.label == "old, thin 50");
        let per_ess = |r: &DefaultRun| r.min_ess().map(|e| r.secs / e);
        for r in &runs {
            let ks: Vec<String> = (0..4)
                .map(|i| match r.ks.get(i).copied().flatten() {
                    Some(k) if k <= bound => format!("{k:.4}"),
                    Some(k) => format!("**{k:.4}**"),
                    None => "–".into(),
                })
                .collect();
            let e = r.min_ess();
            let cost = match (per_ess(r), old50.and_then(per_ess)) {
                (Some(a), Some(b)) if r.label != "old, thin 50" => format!("{:.2}x time", a / b),
                _ => "–".into(),
            };
            let _ = writeln!(
                md,
                "| {} | {} | {:.2e} ({:.3}) | {} | {:.3} | {} | {} | {} | {} | {} | {} | {:.3} | {:.2e} | {} | {} | {cost} |",
                f.name,
                r.label,
                r.dt,
                r.step_m,
                r.thin,
                r.acceptance,
                ks[0],
                ks[1],
                ks[2],
                ks[3],
                e.map_or("–".into(), |e| {
                    let x = e / n as f64;
                    if x < 0.5 { format!("**{x:.2}**") } else { format!("{x:.2}") }
                }),
                r.ess_own.map_or("–".into(), |(e, up)| format!(
                    "{}{:.2}",
                    if up { "≤ " } else { "" },
                    e / n as f64
                )),
                r.secs,
                r.evals as f64,
                e.map_or("–".into(), |e| format!("{:.1}", 1e6 * r.secs / e)),
                e.map_or("–".into(), |e| format!("{:.0}", r.evals as f64 / e)),
            );
            eprintln!(
                "{:>11} {:>13}: dt {:.2e} thin {:>4} acc {:.3} KS {:?} ESS/N {:?} {:.3} s {} steps",
                f.name,
                r.label,
                r.dt,
                r.thin,
                r.acceptance,
                r.ks,
                e.map(|e| e / n as f64),
                r.secs,
                r.steps
            );
        }
    }
    // Pass rates over seeds at the default settings.
    let _ = writeln!(
        md,
        "\n### Over {seeds} seeds (1..={seeds}), default settings, N = {n}\n"
    );
    let _ = writeln!(md, "Pass: KS ≤ 1.5/√N for a (seed, coordinate), ESS ≥ 0.5 N for a seed (smallest over the coordinates, every lag). For truly independent samples about 2 % of (seed, coordinate) pairs exceed the KS bound.\n");
    let _ = writeln!(md, "| figure | KS ≤ 1.5/√N | largest KS | ESS ≥ 0.5 N | ESS/N min, median | thin (min-max) | dt (min-max) | mean time (s) | mean µs per ESS |");
    let _ = writeln!(md, "|---|---|---|---|---|---|---|---|---|");
    for f in figures {
        let runs: Vec<DefaultRun> = (1..=seeds)
            .filter_map(|seed| {
                run_default(
                    f,
                    "default",
                    &SamplerOptions::default().samples(n).seed(seed),
                )
            })
            .collect();
        if runs.is_empty() {
            continue;
        }
        let ks: Vec<f64> = runs
            .iter()
            .flat_map(|r| r.ks.iter().flatten().copied())
            .collect();
        let ks_pass = ks.iter().filter(|&&k| k <= bound).count();
        let mut fr: Vec<f64> = runs
            .iter()
            .filter_map(|r| r.min_ess())
            .map(|e| e / n as f64)
            .collect();
        fr.sort_by(f64::total_cmp);
        let ess_pass = fr.iter().filter(|&&x| x >= 0.5).count();
        let thin = runs.iter().map(|r| r.thin);
        let (tmin, tmax) = (thin.clone().min().unwrap_or(0), thin.max().unwrap_or(0));
        let dts = runs.iter().map(|r| r.dt);
        let (dmin, dmax) = dts.fold((f64::INFINITY, 0.0f64), |a, d| (a.0.min(d), a.1.max(d)));
        let secs = runs.iter().map(|r| r.secs).sum::<f64>() / runs.len() as f64;
        let us = runs
            .iter()
            .filter_map(|r| r.min_ess().map(|e| 1e6 * r.secs / e))
            .sum::<f64>()
            / runs.len() as f64;
        let _ = writeln!(
            md,
            "| {} | {} | {} | {}/{} | {}, {} | {tmin}-{tmax} | {dmin:.2e}-{dmax:.2e} | {secs:.3} | {us:.1} |",
            f.name,
            if ks.is_empty() { "–".into() } else { format!("{ks_pass}/{}", ks.len()) },
            ks.iter().copied().fold(None, |m: Option<f64>, k| Some(m.map_or(k, |m| m.max(k)))).map_or("–".into(), |k| format!("{k:.4}")),
            ess_pass,
            fr.len(),
            fr.first().map_or("–".into(), |x| format!("{x:.2}")),
            fr.get(fr.len() / 2).map_or("–".into(), |x| format!("{x:.2}")),
        );
        eprintln!(
            "{:>11} over seeds: KS pass {ks_pass}/{}, ESS pass {ess_pass}/{}",
            f.name,
            ks.len(),
            fr.len()
        );
    }
    md
}

// ---------------------------------------------------------------------------------------
// Error against run time.

fn passing_spheres() -> (Body, Body, Wall) {
    let a = Body::fixed(Shape::Sphere {
        centre: [0.0; 3],
        radius: PASS.ra,
    });
    let b = Body::fixed(Shape::Sphere {
        centre: [0.0; 3],
        radius: PASS.rb,
    })
    .moving([PASS.speed, 0.0, 0.0], 0.0);
    let window = Wall::Box {
        min: [-2.0, -2.0, -2.0, T_WINDOW.0],
        max: [2.0, 2.0, 2.0, T_WINDOW.1],
    };
    (a, b, window)
}

fn sweep(cases: &[Case], dts: &[f64], checkpoints: &[usize]) -> Vec<Run> {
    let walkers = 32;
    let max_samples = checkpoints.last().copied().unwrap_or(1000);
    let mut runs = Vec::new();
    for case in cases {
        for scheme in Scheme::ALL {
            let mut steps: Vec<Option<f64>> = dts.iter().map(|&d| Some(d)).collect();
            if scheme == Scheme::Metropolis {
                steps.push(None);
            }
            for dt in steps {
                let mut opts = SamplerOptions::default()
                    .scheme(scheme)
                    .walkers(walkers)
                    .thin(2)
                    .samples(max_samples)
                    .seed(42);
                opts = match dt {
                    Some(d) => opts.dt(d).burn_in(200),
                    None => opts,
                };
                let t0 = Instant::now();
                let mut s = match Sampler::new(&case.fig, &opts) {
                    Ok(s) => s,
                    Err(e) => {
                        eprintln!("{} {} dt {dt:?}: {e}", case.name, scheme.as_str());
                        continue;
                    }
                };
                let mut secs = t0.elapsed().as_secs_f64();
                let mut stats = Vec::with_capacity(max_samples);
                let mut per_walker = vec![(0.0f64, 0usize); walkers];
                let mut points = Vec::new();
                for &c in checkpoints {
                    let t1 = Instant::now();
                    let mut drawn = Vec::with_capacity(c - stats.len());
                    while stats.len() + drawn.len() < c {
                        drawn.push(s.draw());
                    }
                    secs += t1.elapsed().as_secs_f64();
                    for q in &drawn {
                        let k = stats.len() % walkers;
                        per_walker[k].0 += (case.mean_stat)(q);
                        per_walker[k].1 += 1;
                        stats.push((case.stat)(q));
                    }
                    let mut v = stats.clone();
                    let ks = ks_statistic(&mut v, &case.cdf);
                    points.push(Point {
                        samples: c,
                        secs,
                        evals: s.stats().evals,
                        ks,
                    });
                }
                let means: Vec<f64> = per_walker
                    .iter()
                    .map(|(s, n)| s / (*n).max(1) as f64)
                    .collect();
                let mean = means.iter().sum::<f64>() / walkers as f64;
                let var =
                    means.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / (walkers - 1) as f64;
                let q = s.quality();
                let ess = q.min_ess.map(|e| {
                    let upper = (0..q.dim).any(|i| q.ess_upper_bound[i]);
                    (e, upper)
                });
                let run = Run {
                    case: case.name,
                    scheme,
                    dt,
                    dt_used: q.adaptation.dt,
                    points,
                    mean_err: mean - case.mean_exact,
                    mean_se: (var / walkers as f64).sqrt(),
                    accept: q.acceptance,
                    ess,
                };
                if let Some(p) = run.points.last() {
                    eprintln!(
                        "{:>10} {:>10} dt {:<18} {:>8} samples {:>7.3} s {:>10} evals KS {:.4} mean err {:+.4} ± {:.4} ESS {:?}",
                        case.name,
                        scheme.as_str(),
                        run.dt_label(),
                        p.samples,
                        p.secs,
                        p.evals,
                        p.ks,
                        run.mean_err,
                        run.mean_se,
                        run.ess
                    );
                }
                runs.push(run);
            }
        }
    }
    runs
}

fn report(cases: &[Case], runs: &[Run], checkpoints: &[usize], target: f64) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "\n## Error against run time, per scheme and step\n");
    let _ = writeln!(
        s,
        "32 walkers, a sample every 2 steps, seed 42; the noise has variance 2·dt per coordinate (α = 1), explicit scheme at λ = Kαdt = 1. Given steps: 200 burn-in steps; \"auto\": the Metropolis step tuned in the default 1000 burn-in steps (thin still 2, to compare like with like). KS: Kolmogorov-Smirnov statistic of all samples drawn so far against the exact CDF (its noise floor for N independent samples is about 0.87/√N: 0.0019 at 200 000). Time and function evaluations (value + gradient of one constraint) include walker start-up and burn-in.\n"
    );
    for c in cases {
        let _ = writeln!(s, "- **{}**: {}", c.name, c.what);
    }
    let _ = writeln!(s, "\n### KS statistic against run time and evaluations\n");
    let _ = write!(s, "| case | scheme | dt | accepted |");
    for c in checkpoints {
        let _ = write!(s, " KS @{c} (s, evals) |");
    }
    let _ = writeln!(s);
    let _ = write!(s, "|---|---|---|---|");
    for _ in checkpoints {
        let _ = write!(s, "---|");
    }
    let _ = writeln!(s);
    for r in runs {
        let _ = write!(
            s,
            "| {} | {} | {} | {:.3} |",
            r.case,
            r.scheme.as_str(),
            r.dt_label(),
            r.accept
        );
        for p in &r.points {
            let _ = write!(
                s,
                " {:.4} ({:.3} s, {:.2e}) |",
                p.ks, p.secs, p.evals as f64
            );
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(
        s,
        "\n### Cost per effective sample at the end of each run\n"
    );
    let _ = writeln!(s, "ESS: the sampler's running estimate (smallest over the coordinates; ≤ marks an upper bound: the autocorrelation of the samples had not died out within 128 lags, so the cost is at least the figure shown).\n");
    let _ = writeln!(
        s,
        "| case | scheme | dt | samples | ESS | ESS/N | time (s) | µs per ESS | evals per ESS |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|");
    for r in runs {
        let Some(p) = r.points.last() else { continue };
        let (ess, bound) = match r.ess {
            Some((e, up)) => (e, up),
            None => continue,
        };
        let (le, ge) = if bound { ("≤ ", "≥ ") } else { ("", "") };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {le}{:.0} | {le}{:.3} | {:.3} | {ge}{:.2} | {ge}{:.1} |",
            r.case,
            r.scheme.as_str(),
            r.dt_label(),
            p.samples,
            ess,
            ess / p.samples as f64,
            p.secs,
            1e6 * p.secs / ess,
            p.evals as f64 / ess
        );
    }
    let _ = writeln!(
        s,
        "\n### Bias floor: error of a mean after the longest run\n"
    );
    let _ = writeln!(s, "Mean statistic: E[cos θ] = r/2R for the torus, E[x] = 0 for the sphere, E[t] for the 4D set. ± is one standard error over the 32 walkers' means; an error beyond ~3 standard errors is bias, not mixing.\n");
    let _ = writeln!(
        s,
        "| case | scheme | dt | error of mean | standard error | error / SE | verdict |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for r in runs {
        let z = r.mean_err / r.mean_se.max(1e-300);
        let verdict = if z.abs() > 3.0 {
            "biased"
        } else {
            "no bias resolved"
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:+.5} | {:.5} | {:+.1} | {verdict} |",
            r.case,
            r.scheme.as_str(),
            r.dt_label(),
            r.mean_err,
            r.mean_se,
            z
        );
    }
    let _ = writeln!(s, "\n### Samples per second at KS ≤ {target}\n");
    let _ = writeln!(s, "For each case and scheme, over the steps tried, the checkpoint from which KS stays ≤ {target} to the end of the run, reached in the least time; samples/s = samples drawn / time to that point (start-up and burn-in included). \"not reached\": no step size stays there (a bias floor above the target, or mixing too slow for the run).\n");
    let _ = writeln!(
        s,
        "| case | scheme | best dt | samples | time (s) | evals | samples/s |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for c in cases {
        for scheme in Scheme::ALL {
            let best = runs
                .iter()
                .filter(|r| r.case == c.name && r.scheme == scheme)
                .filter_map(|r| {
                    // The first checkpoint from which KS stays at or below the target to
                    // the end of the run (a single lucky crossing does not count).
                    let from = r
                        .points
                        .iter()
                        .rposition(|p| p.ks > target)
                        .map_or(0, |i| i + 1);
                    r.points.get(from).map(|p| (r, p))
                })
                .min_by(|a, b| a.1.secs.total_cmp(&b.1.secs));
            match best {
                Some((r, p)) => {
                    let _ = writeln!(
                        s,
                        "| {} | {} | {} | {} | {:.3} | {:.2e} | {:.0} |",
                        c.name,
                        scheme.as_str(),
                        r.dt_label(),
                        p.samples,
                        p.secs,
                        p.evals as f64,
                        p.samples as f64 / p.secs
                    );
                }
                None => {
                    let _ = writeln!(
                        s,
                        "| {} | {} | – | – | – | – | not reached |",
                        c.name,
                        scheme.as_str()
                    );
                }
            }
        }
    }
    s
}

/// A log-log plot of KS against time, one panel per case, by hand (no plotting crate).
fn plot(cases: &[Case], runs: &[Run]) -> String {
    let (pw, ph, m) = (360.0, 300.0, 50.0);
    let w = cases.len() as f64 * (pw + m) + m;
    let h = ph + 2.0 * m + 60.0;
    let mut s = format!("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"11\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n");
    let colours = ["#d62728", "#1f77b4", "#2ca02c"];
    let dash = ["", "6,3", "2,2", "8,2,2,2"];
    let all: Vec<&Point> = runs.iter().flat_map(|r| &r.points).collect();
    let (tmin, tmax) = all.iter().fold((f64::INFINITY, 0.0f64), |a, p| {
        (a.0.min(p.secs), a.1.max(p.secs))
    });
    let (kmin, kmax) = all.iter().fold((f64::INFINITY, 0.0f64), |a, p| {
        (a.0.min(p.ks), a.1.max(p.ks))
    });
    let (lt0, lt1) = (tmin.max(1e-6).log10().floor(), tmax.log10().ceil());
    let (lk0, lk1) = (kmin.max(1e-6).log10().floor(), kmax.log10().ceil());
    // Given steps from the largest, then "auto" (the tuned step differs by case).
    let mut dts: Vec<Option<f64>> = runs.iter().map(|r| r.dt).collect();
    dts.sort_by(|a, b| match (a, b) {
        (Some(a), Some(b)) => b.total_cmp(a),
        (Some(_), None) => std::cmp::Ordering::Less,
        (None, Some(_)) => std::cmp::Ordering::Greater,
        (None, None) => std::cmp::Ordering::Equal,
    });
    dts.dedup();
    for (ci, c) in cases.iter().enumerate() {
        let x0 = m + ci as f64 * (pw + m);
        let y0 = m;
        let _ = writeln!(s, "<rect x=\"{x0}\" y=\"{y0}\" width=\"{pw}\" height=\"{ph}\" fill=\"none\" stroke=\"black\"/>");
        let _ = writeln!(
            s,
            "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}: KS vs run time (s), log-log</text>",
            x0 + pw / 2.0,
            y0 - 8.0,
            c.name
        );
        let px = |t: f64| x0 + (t.max(1e-6).log10() - lt0) / (lt1 - lt0) * pw;
        let py = |k: f64| y0 + ph - (k.max(1e-6).log10() - lk0) / (lk1 - lk0) * ph;
        let mut e = lt0;
        while e <= lt1 {
            let _ = writeln!(
                s,
                "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">1e{e}</text>",
                px(10f64.powf(e)),
                y0 + ph + 14.0
            );
            e += 1.0;
        }
        let mut e = lk0;
        while e <= lk1 {
            let _ = writeln!(
                s,
                "<text x=\"{}\" y=\"{}\" text-anchor=\"end\">1e{e}</text>",
                x0 - 3.0,
                py(10f64.powf(e)) + 4.0
            );
            e += 1.0;
        }
        for r in runs.iter().filter(|r| r.case == c.name) {
            let si = Scheme::ALL.iter().position(|x| *x == r.scheme).unwrap_or(0);
            let di = dts.iter().position(|d| *d == r.dt).unwrap_or(0) % dash.len();
            let pts: Vec<String> = r
                .points
                .iter()
                .map(|p| format!("{:.1},{:.1}", px(p.secs), py(p.ks)))
                .collect();
            let _ = writeln!(s, "<polyline fill=\"none\" stroke=\"{}\" stroke-dasharray=\"{}\" stroke-width=\"1.5\" points=\"{}\"/>", colours[si], dash[di], pts.join(" "));
        }
    }
    let mut y = h - 40.0;
    for (si, sc) in Scheme::ALL.iter().enumerate() {
        let _ = writeln!(s, "<line x1=\"{m}\" y1=\"{y}\" x2=\"{}\" y2=\"{y}\" stroke=\"{}\" stroke-width=\"2\"/><text x=\"{}\" y=\"{}\">{}</text>", m + 30.0, colours[si], m + 35.0, y + 4.0, sc.as_str());
        y += 14.0;
    }
    let mut x = m + 200.0;
    for (di, d) in dts.iter().enumerate() {
        let d = d.map_or("auto".to_owned(), |d| d.to_string());
        let _ = writeln!(s, "<line x1=\"{x}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"black\" stroke-dasharray=\"{}\"/><text x=\"{}\" y=\"{}\">dt {d}</text>", h - 40.0, x + 30.0, h - 40.0, dash[di % dash.len()], x + 35.0, h - 36.0);
        x += 110.0;
    }
    s.push_str("</svg>\n");
    s
}
