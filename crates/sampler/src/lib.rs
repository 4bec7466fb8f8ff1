//! Stochastic sampling of implicit figures (the sampling paper, Tanaka et al.:
//! docs/methods/sampling.md): points spread uniformly over
//! `{q ∈ R^N : F^a(q) = 0, a = 1..M}` inside reflecting walls.
//!
//! - N = 3, M = 1: an implicit surface; N = 3, M = 2: the curve where two surfaces meet;
//!   N = 4, M = 2: the *space-time collision set* of two moving implicit bodies, i.e. the
//!   points `(x, y, z, t)` where the surfaces of both bodies pass at once — at each time t
//!   the curve where the two moving surfaces cross, swept over t (the sampling paper's
//!   §3.3, Fig. 3, shown there projected to YZT;
//!   docs/methods/sampling.md#the-4d-collision-set). Time is a coordinate like the others:
//!   one second weighs as one metre in the uniform measure.
//! - Figures ([`Figure`]) are built from [`Field`]s, usually scene [`Body`]s: a [`Shape`]
//!   (sphere, rounded box, torus, capsule, cone, the seed's two surfaces) moving at constant
//!   velocity. Scene files ([`scene_file`]) describe them in YAML.
//! - Three schemes ([`Scheme`]):
//!   - `Explicit`: seed eq. (2) as written, integrated by Euler-Maruyama — tangent noise,
//!     the curvature term `Tr(∂²F P)` and the constraint force `-Kα dt ∇F D^{-1} F`. With
//!     `D^{-1}` the force is a damped Newton step, `F ← (1-λ) F` with `λ = Kα dt`: stable
//!     only for `0 < λ < 2` whatever `|∇F|` is, so λ ≥ [`LAMBDA_LIMIT`] is refused
//!     ([`SamplerError::Unstable`]) or clamped to 1 ([`LambdaPolicy`]). Its density has an
//!     O(dt) bias (docs/methods/sampling.md#time-step-bias; measured in
//!     `docs/sampler-error.md`).
//!   - `Projected`: tangent noise then Newton projection along the normals (no Hessian;
//!     samples exactly on the figure; still an O(dt) bias).
//!   - `Metropolis`: the manifold MCMC of Zappa, Holmes-Cerfon & Goodman (2018): tangent
//!     proposal, projection, Metropolis-Hastings with the reverse proposal density and a
//!     reverse projection check. Unbiased for any step; the default.
//!
//! Convergence of every projection is tested with `|F|/|∇F|` (a length), never `|F|`, so
//! warped or steep functions are treated alike. Deterministic for a given seed. Pure
//! numerics: no ROS, MCAP or I/O (the CLI writes the samples).
//!
//! Adapted to the figure ([`Sampler::new`], docs/sampler.md): walkers start from points spread over
//! the figure (farthest-point choice among projected candidates); during burn-in the
//! Metropolis step is tuned to an acceptance rate and the thinning is chosen from the
//! measured autocorrelation; both are then fixed before the first sample is kept, so the
//! chain that gives the samples is an ordinary fixed-kernel chain. Every run reports its
//! [`Quality`]: effective sample size per coordinate, acceptance rate, largest residual
//! and, for the explicit scheme, how far its points lie off the figure.
//!
//! ```
//! use chronotope_sampler::{sample, Body, Figure, SamplerOptions, Shape, Wall};
//! use std::sync::Arc;
//!
//! let torus = Body::fixed(Shape::Torus { centre: [0.0; 3], axis: Default::default(), major: 1.0, minor: 0.3 });
//! let fig = Figure::new(3, vec![Arc::new(torus)]).unwrap()
//!     .wall(Wall::Box { min: [-2.0; 4], max: [2.0; 4] }).unwrap();
//! let s = sample(&fig, &SamplerOptions::default().samples(200).seed(1)).unwrap();
//! assert_eq!(s.points.len(), 200);
//! assert!(s.points.iter().all(|q| fig.residual(q) < 1e-8));
//! println!("ESS of x: {:?}, acceptance {:.2}", s.quality.ess[0], s.quality.acceptance);
//! ```
#![warn(missing_docs)]
// `!(x > 0.0)` is meant: it rejects NaN as well as non-positive values. The index loops over
// M ≤ 3 constraints mirror the formulas' indices (D^{ab}, Cholesky factors).
#![allow(
    clippy::neg_cmp_op_on_partial_ord,
    clippy::needless_range_loop,
    clippy::nonminimal_bool
)]

pub mod exact;
mod field;
mod figure;
pub mod quality;
pub mod reference;
mod rng;
pub mod scene_file;
mod walk;

pub use field::{Body, Field, Shape, ShapeAxis, Q};
pub use figure::{Figure, Wall, MAX_CONSTRAINTS};
pub use quality::{Adaptation, Quality};
pub use rng::Rng;
pub use walk::Sampler;

use std::sync::Arc;

/// λ = Kα dt at or above which the explicit scheme is unstable (F ← (1-λ) F).
pub const LAMBDA_LIMIT: f64 = 2.0;
/// Most samples one call draws (at thin 1 that is the whole step budget).
pub const MAX_SAMPLES: usize = 30_000_000;
/// Most walkers.
pub const MAX_WALKERS: usize = 100_000;
/// Most steps of one run, all walkers together: `walkers × burn_in + samples × thin`, plus
/// any extension of the burn-in's pilot ([`MAX_PILOT_STEPS`]). 3e7 steps take about 100 s
/// at the slowest rate measured, 0.3M steps/s (Metropolis with the tuned step on the 4D
/// collision set of two tori, docs/sampler-error.md; 0.5-0.7M steps/s on the 3D figures),
/// with the default 20 Newton iterations per projection.
pub const MAX_TOTAL_STEPS: u64 = 30_000_000;
/// Most samples [`sample`] collects in memory (32 bytes each: 512 MiB). Draw more with
/// [`Sampler::draw`] and write them as they come (`chronotope sample` does).
pub const MAX_COLLECTED_SAMPLES: usize = 1 << 24;
/// The time step of the explicit and projected schemes when none is given (m² with α = 1:
/// steps of ~0.045 m on a surface). Their density has an O(dt) bias, so their step is an
/// accuracy setting and is not tuned.
pub const DEFAULT_DT: f64 = 1e-3;
/// The acceptance rate the Metropolis step is tuned to during burn-in when no `dt` is given
/// (docs/sampler.md: of 0.3, 0.5 and 0.7 none was the cheapest per effective sample on
/// every benchmark figure; 0.5 was within about 25 % of the cheapest on each).
pub const DEFAULT_TARGET_ACCEPTANCE: f64 = 0.5;
/// With `thin` chosen during burn-in: the correlation of successive samples of one walker
/// aimed at (the pilot's autocorrelation at lag `thin`, every coordinate). 0.05 makes the
/// integrated autocorrelation time of the samples about (1 + 0.05)/(1 - 0.05) = 1.1, i.e.
/// an effective sample size of about 0.9 N.
pub const AUTO_THIN_CORRELATION: f64 = 0.05;
/// Largest `thin` chosen during burn-in; a walk that needs more is reported with its
/// effective sample size below N/2 ([`quality::Quality`]) instead of running for hours.
pub const MAX_AUTO_THIN: usize = 1000;
/// Most sampling steps a chosen `thin` may cost (`samples × thin`): about 30 s at the
/// slowest rate measured ([`MAX_TOTAL_STEPS`]). A walk that would need more (a figure whose parts the walk
/// crosses between only rarely, a tiny fixed step) is capped there and its shortfall
/// reported; a `thin` given by the caller is bounded by [`MAX_TOTAL_STEPS`] only.
pub const AUTO_THIN_STEPS: u64 = 10_000_000;
/// Fewest burn-in steps per walker when the step or the thinning is tuned during burn-in.
pub const MIN_ADAPT_BURN_IN: usize = 100;
/// Most steps per walker of the burn-in's pilot (the part whose autocorrelation chooses
/// `thin`), extension included. The pilot keeps the positions of at most
/// [`PILOT_CHAINS`] walkers: 16 × 16384 × 32 bytes = 8 MiB.
pub const MAX_PILOT_STEPS: usize = 1 << 14;
/// Walkers whose pilot positions are kept.
pub const PILOT_CHAINS: usize = 16;

/// Why sampling could not start.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SamplerError {
    /// The explicit scheme's `λ = Kα dt` is at or above 2: the constraint force overshoots
    /// and diverges.
    #[error("explicit scheme unstable: λ = Kαdt = {} ≥ 2 (use λ ≈ 1, a smaller K or dt, or --clamp)", chronotope_mesh::num(*lambda))]
    Unstable {
        /// The λ asked for.
        lambda: f64,
    },
    /// A parameter outside its limits.
    #[error("{name} = {}: expected {expected}", chronotope_mesh::num(*value))]
    BadParameter {
        /// Which parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// The accepted range.
        expected: &'static str,
    },
    /// The run would take more steps than [`MAX_TOTAL_STEPS`].
    #[error("walkers × burn_in + samples × thin = {walkers} × {burn_in} + {samples} × {thin} = {total} steps ({per_walker} per walker): at most {max} in one run (MAX_TOTAL_STEPS, 1-2 minutes at 0.3-0.7M steps/s); lower burn_in, thin or samples")]
    TooManySteps {
        /// Walkers.
        walkers: usize,
        /// Burn-in steps per walker.
        burn_in: usize,
        /// Samples.
        samples: usize,
        /// Steps between samples of one walker (1 when it is to be chosen: the least).
        thin: usize,
        /// Steps of the whole run.
        total: u128,
        /// Steps of the busiest walker.
        per_walker: u128,
        /// The limit.
        max: u64,
    },
    /// The figure is malformed (dimensions, walls, shapes).
    #[error("bad figure: {0}")]
    BadFigure(String),
    /// A scheme name that is none of [`Scheme::ALL`].
    #[error("unknown scheme `{0}`: expected explicit, projected or metropolis")]
    UnknownScheme(String),
    /// No walker could be put on the figure.
    #[error("cannot put walkers on the figure after {tries} tries: {why}")]
    NoStart {
        /// Start points tried.
        tries: usize,
        /// Why.
        why: String,
    },
}

/// The integration or sampling scheme.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Scheme {
    /// Seed eq. (2) by Euler-Maruyama (O(dt) bias; λ < 2 only).
    Explicit,
    /// Tangent noise and Newton projection (O(dt) bias, any stiffness).
    Projected,
    /// Manifold Metropolis with reverse check (unbiased, any stiffness).
    #[default]
    Metropolis,
}

impl std::str::FromStr for Scheme {
    type Err = SamplerError;
    fn from_str(s: &str) -> Result<Self, SamplerError> {
        match s {
            "explicit" => Ok(Self::Explicit),
            "projected" => Ok(Self::Projected),
            "metropolis" => Ok(Self::Metropolis),
            _ => Err(SamplerError::UnknownScheme(s.to_owned())),
        }
    }
}

impl Scheme {
    /// Every scheme.
    pub const ALL: [Scheme; 3] = [Scheme::Explicit, Scheme::Projected, Scheme::Metropolis];
    /// The name on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Explicit => "explicit",
            Self::Projected => "projected",
            Self::Metropolis => "metropolis",
        }
    }
}

/// What the explicit scheme does with `λ ≥ 2`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LambdaPolicy {
    /// Return [`SamplerError::Unstable`] (the default).
    #[default]
    Refuse,
    /// Use `K = 1/(α dt)` (λ = 1) instead and record the λ asked for in
    /// [`SampleStats::clamped_lambda`].
    Clamp,
}

/// Sampling options. Start from `SamplerOptions::default()` and adjust with the builders.
///
/// With the defaults nothing about the figure needs to be known: the Metropolis step is
/// tuned during burn-in to [`Self::target_acceptance`] and the thinning chosen from the
/// burn-in's measured autocorrelation, both then fixed before the first sample is kept
/// (docs/sampler.md).
#[derive(Debug, Clone, PartialEq)]
pub struct SamplerOptions {
    /// Scheme (default Metropolis).
    pub scheme: Scheme,
    /// Time step; the noise has variance `2 α dt` per coordinate, so the step length is
    /// about `sqrt(2 α dt (N - M))`. `None` (the default): the Metropolis scheme tunes it
    /// during burn-in to [`Self::target_acceptance`]; the explicit and projected schemes use
    /// [`DEFAULT_DT`]. Limits: `0 < dt ≤ 1e3`.
    pub dt: Option<f64>,
    /// Diffusion constant α > 0 (default 1).
    pub alpha: f64,
    /// Constraint strength K of the explicit scheme; `None`: from [`Self::lambda`].
    pub k: Option<f64>,
    /// λ = Kα dt when K is not given (default 1, the damped Newton step that lands on the
    /// figure in one step to first order). Must be in (0, 2).
    pub lambda: f64,
    /// What to do with λ ≥ 2.
    pub on_unstable: LambdaPolicy,
    /// Independent walkers (default 16, at most [`MAX_WALKERS`]; at most `samples` are used).
    pub walkers: usize,
    /// Steps each walker takes before its first sample (default 1000): step tuning (first
    /// 40 %, when `dt` is `None` and the scheme is Metropolis), equilibration, and the pilot
    /// whose autocorrelation chooses `thin` (last 40 %, when `thin` is `None`).
    pub burn_in: usize,
    /// Steps between two samples of one walker (≥ 1). `None` (the default): the least lag
    /// at which the burn-in pilot's autocorrelation falls to [`AUTO_THIN_CORRELATION`] in
    /// every coordinate, at most [`MAX_AUTO_THIN`].
    pub thin: Option<usize>,
    /// Samples to draw (default 10 000, 1 to [`MAX_SAMPLES`]).
    pub samples: usize,
    /// RNG seed.
    pub seed: u64,
    /// Projection tolerance on `|F|/|∇F|` (m; default 1e-10, in [1e-14, 1e-2]).
    pub tol: f64,
    /// Newton iterations per projection (default 20, 1..=1000).
    pub max_newton: usize,
    /// Guard: a step or a projection moving further than `max_jump` × the figure's scale is
    /// not taken (default 0.5).
    pub max_jump: f64,
    /// Start points (cycled over walkers); empty: spread over the figure from the start box.
    pub starts: Vec<Q>,
    /// The acceptance rate the Metropolis step is tuned to (default
    /// [`DEFAULT_TARGET_ACCEPTANCE`], in [0.05, 0.95]).
    pub target_acceptance: f64,
    /// Finish each sample with a Newton projection onto the figure (Gauss-Newton along
    /// the gradients, to `tol`); the walker itself goes on from where it was. Meant for the
    /// explicit scheme, whose samples lie off the figure by O(step).
    pub project: bool,
}

impl Default for SamplerOptions {
    fn default() -> Self {
        Self {
            scheme: Scheme::Metropolis,
            dt: None,
            alpha: 1.0,
            k: None,
            lambda: 1.0,
            on_unstable: LambdaPolicy::Refuse,
            walkers: 16,
            burn_in: 1000,
            thin: None,
            samples: 10_000,
            seed: 0,
            tol: 1e-10,
            max_newton: 20,
            max_jump: 0.5,
            starts: Vec::new(),
            target_acceptance: DEFAULT_TARGET_ACCEPTANCE,
            project: false,
        }
    }
}

macro_rules! builder {
    ($($name:ident: $ty:ty),* $(,)?) => {
        $(
            #[doc = concat!("With `", stringify!($name), "` set.")]
            pub fn $name(mut self, v: $ty) -> Self {
                self.$name = v;
                self
            }
        )*
    };
}

impl SamplerOptions {
    builder!(scheme: Scheme, alpha: f64, lambda: f64, on_unstable: LambdaPolicy,
        walkers: usize, burn_in: usize, samples: usize, seed: u64, tol: f64,
        max_newton: usize, max_jump: f64, starts: Vec<Q>, target_acceptance: f64,
        project: bool);

    /// With the explicit scheme's K set directly (λ = Kα dt).
    pub fn k(mut self, k: f64) -> Self {
        self.k = Some(k);
        self
    }

    /// With a fixed time step (no tuning).
    pub fn dt(mut self, dt: f64) -> Self {
        self.dt = Some(dt);
        self
    }

    /// With a fixed thinning (no choice from the burn-in's autocorrelation).
    pub fn thin(mut self, thin: usize) -> Self {
        self.thin = Some(thin);
        self
    }

    /// Whether the step is tuned during burn-in (Metropolis without a given `dt`).
    pub fn tunes_step(&self) -> bool {
        self.scheme == Scheme::Metropolis && self.dt.is_none()
    }

    /// Whether the thinning is chosen during burn-in (no `thin` given).
    pub fn chooses_thin(&self) -> bool {
        self.thin.is_none()
    }

    /// Checks every limit.
    ///
    /// # Errors
    /// [`SamplerError::BadParameter`] naming the first parameter out of range,
    /// [`SamplerError::TooManySteps`] for a run over [`MAX_TOTAL_STEPS`].
    pub fn validate(&self) -> Result<(), SamplerError> {
        let bad = |name, value: f64, expected| {
            Err(SamplerError::BadParameter {
                name,
                value,
                expected,
            })
        };
        if let Some(dt) = self.dt {
            if !(dt > 0.0 && dt <= 1e3) {
                return bad("dt", dt, "0 < dt ≤ 1e3");
            }
        }
        if !(self.alpha > 0.0 && self.alpha <= 1e6) {
            return bad("alpha", self.alpha, "0 < α ≤ 1e6");
        }
        if let Some(k) = self.k {
            if !(k > 0.0 && k.is_finite()) {
                return bad("K", k, "K > 0");
            }
        } else if !(self.lambda > 0.0 && self.lambda.is_finite()) {
            return bad("lambda", self.lambda, "λ > 0 (stable below 2)");
        }
        if self.samples == 0 {
            return bad("samples", 0.0, "1 ≤ samples ≤ 3e7 (MAX_SAMPLES)");
        }
        if self.samples > MAX_SAMPLES {
            return bad(
                "samples",
                self.samples as f64,
                "1 ≤ samples ≤ 3e7 (MAX_SAMPLES)",
            );
        }
        if !(1..=MAX_WALKERS).contains(&self.walkers) {
            return bad("walkers", self.walkers as f64, "1..=100000");
        }
        if let Some(t) = self.thin {
            if t == 0 || t > 1_000_000 {
                return bad(
                    "thin",
                    t as f64,
                    "1..=1000000 (or left out: chosen in burn-in)",
                );
            }
        }
        if self.burn_in > MAX_TOTAL_STEPS as usize {
            return bad("burn_in", self.burn_in as f64, "≤ 3e7 (MAX_TOTAL_STEPS)");
        }
        if (self.tunes_step() || self.chooses_thin()) && self.burn_in < MIN_ADAPT_BURN_IN {
            return bad(
                "burn_in",
                self.burn_in as f64,
                "≥ 100 while the step or the thinning is tuned during burn-in (give dt and thin to run with less)",
            );
        }
        if !(self.target_acceptance >= 0.05 && self.target_acceptance <= 0.95) {
            return bad(
                "target_acceptance",
                self.target_acceptance,
                "0.05 ≤ target acceptance ≤ 0.95",
            );
        }
        // Walkers past the samples' count would never give a sample: at most `samples` run.
        let walkers = self.walkers.min(self.samples);
        let thin = self.thin.unwrap_or(1);
        let (w, b, n, t) = (
            walkers as u128,
            self.burn_in as u128,
            self.samples as u128,
            thin as u128,
        );
        let total = w * b + n * t;
        if total > u128::from(MAX_TOTAL_STEPS) {
            return Err(SamplerError::TooManySteps {
                walkers,
                burn_in: self.burn_in,
                samples: self.samples,
                thin,
                total,
                per_walker: b + n.div_ceil(w) * t,
                max: MAX_TOTAL_STEPS,
            });
        }
        if !(self.tol >= 1e-14 && self.tol <= 1e-2) {
            return bad("tol", self.tol, "1e-14 ≤ tol ≤ 1e-2");
        }
        if !(1..=1000).contains(&self.max_newton) {
            return bad("max_newton", self.max_newton as f64, "1..=1000");
        }
        if !(self.max_jump > 0.0 && self.max_jump.is_finite()) {
            return bad("max_jump", self.max_jump, "> 0");
        }
        if self.starts.iter().flatten().any(|x| !x.is_finite()) {
            return bad("starts", f64::NAN, "finite start points");
        }
        Ok(())
    }
}

/// Counters of one sampling run.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct SampleStats {
    /// Samples drawn.
    pub samples: u64,
    /// Steps taken by all walkers (burn-in included).
    pub steps: u64,
    /// Steps taken before the first sample (tuning, equilibration, pilot).
    pub burn_in_steps: u64,
    /// Steps that moved their walker (burn-in included).
    pub accepted: u64,
    /// Evaluations of a constraint function with its gradient (all constraints, all
    /// purposes: steps, projections, curvature differences, start-up).
    pub evals: u64,
    /// Newton projections that did not converge (the step was not taken).
    pub failed_projections: u64,
    /// Proposals refused by the walls (projected, Metropolis).
    pub rejected_walls: u64,
    /// Proposals refused by the Metropolis test.
    pub rejected_metropolis: u64,
    /// Proposals refused by the reverse projection check.
    pub rejected_reverse: u64,
    /// Explicit steps reflected by a wall.
    pub reflections: u64,
    /// Steps at points where D is singular (vanishing gradient, tangent constraints).
    pub singular: u64,
    /// Explicit steps not taken because they left the finite numbers or jumped too far.
    pub guarded: u64,
    /// The λ asked for, if it was clamped to 1.
    pub clamped_lambda: Option<f64>,
    /// Largest `|F|/|∇F|` over the samples as returned (after `project`, if asked).
    pub max_residual: f64,
    /// Largest `|F|/|∇F|` of the walkers where the samples were taken (before `project`):
    /// how far the explicit scheme's points lie off the figure (m, to first order).
    pub max_off_figure: f64,
    /// Sum of the squares of those distances (m²), for their root mean square.
    pub sum_sq_off_figure: f64,
    /// Samples whose final projection (`project`) did not converge inside the walls; they
    /// are returned where the walker was.
    pub failed_final_projections: u64,
}

/// Samples and what it took to draw them.
#[derive(Debug, Clone)]
pub struct Samples {
    /// Points `(x, y, z, t)`; coordinates past N are zero.
    pub points: Vec<Q>,
    /// Counters.
    pub stats: SampleStats,
    /// Effective sample size, acceptance, residuals and the adapted settings.
    pub quality: Quality,
}

/// Draws `opts.samples` points uniformly on `fig`, collected in memory.
///
/// # Errors
/// See [`Sampler::new`]; [`SamplerError::BadParameter`] for more than
/// [`MAX_COLLECTED_SAMPLES`] samples (checked before anything is drawn or allocated).
pub fn sample(fig: &Figure, opts: &SamplerOptions) -> Result<Samples, SamplerError> {
    if opts.samples > MAX_COLLECTED_SAMPLES {
        return Err(SamplerError::BadParameter {
            name: "samples",
            value: opts.samples as f64,
            expected: "≤ 33554432 (MAX_COLLECTED_SAMPLES, 1 GiB) when collected in memory; \
                       draw more with Sampler::draw and write them as they come",
        });
    }
    let mut s = Sampler::new(fig, opts)?;
    let mut points = Vec::new();
    points
        .try_reserve_exact(opts.samples)
        .map_err(|_| SamplerError::BadParameter {
            name: "samples",
            value: opts.samples as f64,
            expected: "as many as memory holds (32 bytes each)",
        })?;
    points.extend((0..opts.samples).map(|_| s.draw()));
    Ok(Samples {
        points,
        stats: s.stats().clone(),
        quality: s.quality(),
    })
}

/// A point on a surface with its outward unit normal (`∇F/|∇F|`).
pub type Surfel = ([f64; 3], [f64; 3]);

/// `n` points spread uniformly over the surface `F = 0` of `field` in R^3, with unit normals
/// from `∇F` (outward where F < 0 inside), e.g. to seed a carving workpiece's surfels.
/// Walkers are seeded in `bounds` (a box holding the surface); the Metropolis scheme with
/// steps of `step` (m; about a tenth of the smallest feature is right) is used.
///
/// # Errors
/// [`SamplerError`] for a bad box or step, or a surface no walker reaches from the box.
pub fn surface_points(
    field: Arc<dyn Field>,
    bounds: ([f64; 3], [f64; 3]),
    n: usize,
    step: f64,
    seed: u64,
) -> Result<Vec<Surfel>, SamplerError> {
    let (lo, hi) = bounds;
    let min = [lo[0], lo[1], lo[2], 0.0];
    let max = [hi[0], hi[1], hi[2], 0.0];
    let fig = Figure::new(3, vec![field])?.seed_box(min, max)?;
    let dt = step * step / 4.0;
    let opts = SamplerOptions::default().dt(dt).samples(n).seed(seed);
    let s = sample(&fig, &opts)?;
    Ok(s.points
        .iter()
        .map(|q| {
            let (_, g) = fig.eval(q);
            let g = g[0];
            let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
            let nrm = if len > 0.0 {
                [g[0] / len, g[1] / len, g[2] / len]
            } else {
                [0.0; 3]
            };
            ([q[0], q[1], q[2]], nrm)
        })
        .collect())
}
