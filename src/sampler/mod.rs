//! Stochastic sampling of implicit figures (seed 001, Tanaka et al.): points spread
//! uniformly over `{q ∈ R^N : F^a(q) = 0, a = 1..M}` inside reflecting walls.
//!
//! - N = 3, M = 1: an implicit surface; N = 3, M = 2: the curve where two surfaces meet;
//!   N = 4, M = 2: the *space-time collision set* of two moving implicit bodies, i.e. the
//!   points `(x, y, z, t)` where the surfaces of both bodies pass at once — at each time t
//!   the curve where the two moving surfaces cross, swept over t (seed 001 §3.3, Fig. 3,
//!   shown there projected to YZT). Time is a coordinate like the others: one second
//!   weighs as one metre in the uniform measure.
//! - Figures ([`Figure`]) are built from [`Field`]s, usually scene [`Body`]s: a [`Shape`]
//!   (sphere, rounded box, torus, capsule, cone, the seed's two surfaces) moving at constant
//!   velocity. Scene files ([`scene_file`]) describe them in YAML.
//! - Three schemes ([`Scheme`]):
//!   - `Explicit`: seed eq. (2) as written, integrated by Euler-Maruyama — tangent noise,
//!     the curvature term `Tr(∂²F P)` and the constraint force `-Kα dt ∇F D^{-1} F`. With
//!     `D^{-1}` the force is a damped Newton step, `F ← (1-λ) F` with `λ = Kα dt`: stable
//!     only for `0 < λ < 2` whatever `|∇F|` is, so λ ≥ [`LAMBDA_LIMIT`] is refused
//!     ([`SamplerError::Unstable`]) or clamped to 1 ([`LambdaPolicy`]). Its density has an
//!     O(dt) bias (DESIGN.md §7; measured in `docs/sampler-error.md`).
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
//! ```
//! use chronotope::sampler::{sample, Body, Figure, SamplerOptions, Shape, Wall};
//! use std::sync::Arc;
//!
//! let torus = Body::fixed(Shape::Torus { centre: [0.0; 3], axis: Default::default(), major: 1.0, minor: 0.3 });
//! let fig = Figure::new(3, vec![Arc::new(torus)]).unwrap()
//!     .wall(Wall::Box { min: [-2.0; 4], max: [2.0; 4] }).unwrap();
//! let s = sample(&fig, &SamplerOptions::default().samples(200).seed(1)).unwrap();
//! assert_eq!(s.points.len(), 200);
//! assert!(s.points.iter().all(|q| fig.residual(q) < 1e-8));
//! ```

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
mod rng;
pub mod scene_file;
mod walk;

pub use field::{Body, Field, Shape, ShapeAxis, Q};
pub use figure::{Figure, Wall, MAX_CONSTRAINTS};
pub use rng::Rng;
pub use walk::Sampler;

use std::sync::Arc;

/// λ = Kα dt at or above which the explicit scheme is unstable (F ← (1-λ) F).
pub const LAMBDA_LIMIT: f64 = 2.0;
/// Most samples one call draws (at thin 1 that is the whole step budget).
pub const MAX_SAMPLES: usize = 30_000_000;
/// Most walkers.
pub const MAX_WALKERS: usize = 100_000;
/// Most steps of one run, all walkers together: `walkers × burn_in + samples × thin`.
/// 3e7 steps take about a minute at the slowest rate measured, 0.5M steps/s (Metropolis
/// on the torus, docs/sampler-error.md: 128 000 samples × 2 steps + 32 × 200 burn-in steps
/// in 0.499 s, release build, one core of a 2-core AMD EPYC), with the default 20 Newton
/// iterations per projection.
pub const MAX_TOTAL_STEPS: u64 = 30_000_000;
/// Most samples [`sample`] collects in memory (32 bytes each: 512 MiB). Draw more with
/// [`Sampler::draw`] and write them as they come (`chronotope sample` does).
pub const MAX_COLLECTED_SAMPLES: usize = 1 << 24;

/// Why sampling could not start.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SamplerError {
    /// The explicit scheme's `λ = Kα dt` is at or above 2: the constraint force overshoots
    /// and diverges.
    #[error("explicit scheme unstable: λ = Kαdt = {} ≥ 2 (use λ ≈ 1, a smaller K or dt, or --clamp)", crate::mesh::num(*lambda))]
    Unstable {
        /// The λ asked for.
        lambda: f64,
    },
    /// A parameter outside its limits.
    #[error("{name} = {}: expected {expected}", crate::mesh::num(*value))]
    BadParameter {
        /// Which parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// The accepted range.
        expected: &'static str,
    },
    /// The run would take more steps than [`MAX_TOTAL_STEPS`].
    #[error("walkers × burn_in + samples × thin = {walkers} × {burn_in} + {samples} × {thin} = {total} steps ({per_walker} per walker): at most {max} in one run (MAX_TOTAL_STEPS, about a minute at 0.5M steps/s); lower burn_in, thin or samples")]
    TooManySteps {
        /// Walkers.
        walkers: usize,
        /// Burn-in steps per walker.
        burn_in: usize,
        /// Samples.
        samples: usize,
        /// Steps between samples of one walker.
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
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "explicit" => Ok(Self::Explicit),
            "projected" => Ok(Self::Projected),
            "metropolis" => Ok(Self::Metropolis),
            _ => Err(format!(
                "unknown scheme `{s}`: expected explicit, projected or metropolis"
            )),
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
#[derive(Debug, Clone, PartialEq)]
pub struct SamplerOptions {
    /// Scheme (default Metropolis).
    pub scheme: Scheme,
    /// Time step; the noise has variance `2 α dt` per coordinate, so the step length is
    /// about `sqrt(2 α dt (N - M))`. Default 1e-3 (m² with α = 1): steps of ~0.045 m on a
    /// surface, suited to features of ~0.1-10 m. Limits: `0 < dt ≤ 1e3`.
    pub dt: f64,
    /// Diffusion constant α > 0 (default 1).
    pub alpha: f64,
    /// Constraint strength K of the explicit scheme; `None`: from [`Self::lambda`].
    pub k: Option<f64>,
    /// λ = Kα dt when K is not given (default 1, the damped Newton step that lands on the
    /// figure in one step to first order). Must be in (0, 2).
    pub lambda: f64,
    /// What to do with λ ≥ 2.
    pub on_unstable: LambdaPolicy,
    /// Independent walkers (default 16, at most [`MAX_WALKERS`]).
    pub walkers: usize,
    /// Steps each walker takes before its first sample (default 500).
    pub burn_in: usize,
    /// Steps between two samples of one walker (default 5, ≥ 1).
    pub thin: usize,
    /// Samples to draw (default 10 000, at most [`MAX_SAMPLES`]).
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
    /// Start points (cycled over walkers); empty: uniform in the figure's start box.
    pub starts: Vec<Q>,
}

impl Default for SamplerOptions {
    fn default() -> Self {
        Self {
            scheme: Scheme::Metropolis,
            dt: 1e-3,
            alpha: 1.0,
            k: None,
            lambda: 1.0,
            on_unstable: LambdaPolicy::Refuse,
            walkers: 16,
            burn_in: 500,
            thin: 5,
            samples: 10_000,
            seed: 0,
            tol: 1e-10,
            max_newton: 20,
            max_jump: 0.5,
            starts: Vec::new(),
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
    builder!(scheme: Scheme, dt: f64, alpha: f64, lambda: f64, on_unstable: LambdaPolicy,
        walkers: usize, burn_in: usize, thin: usize, samples: usize, seed: u64, tol: f64,
        max_newton: usize, max_jump: f64, starts: Vec<Q>);

    /// With the explicit scheme's K set directly (λ = Kα dt).
    pub fn k(mut self, k: f64) -> Self {
        self.k = Some(k);
        self
    }

    /// Checks every limit.
    ///
    /// # Errors
    /// [`SamplerError::BadParameter`] naming the first parameter out of range.
    pub fn validate(&self) -> Result<(), SamplerError> {
        let bad = |name, value: f64, expected| {
            Err(SamplerError::BadParameter {
                name,
                value,
                expected,
            })
        };
        if !(self.dt > 0.0 && self.dt <= 1e3) {
            return bad("dt", self.dt, "0 < dt ≤ 1e3");
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
        if !(1..=MAX_WALKERS).contains(&self.walkers) {
            return bad("walkers", self.walkers as f64, "1..=100000");
        }
        if self.thin == 0 || self.thin > 1_000_000 {
            return bad("thin", self.thin as f64, "1..=1000000");
        }
        if self.burn_in > MAX_TOTAL_STEPS as usize {
            return bad("burn_in", self.burn_in as f64, "≤ 3e7 (MAX_TOTAL_STEPS)");
        }
        if self.samples > MAX_SAMPLES {
            return bad("samples", self.samples as f64, "≤ 3e7 (MAX_SAMPLES)");
        }
        let (w, b, n, t) = (
            self.walkers as u128,
            self.burn_in as u128,
            self.samples as u128,
            self.thin as u128,
        );
        let total = w * b + n * t;
        if total > u128::from(MAX_TOTAL_STEPS) {
            return Err(SamplerError::TooManySteps {
                walkers: self.walkers,
                burn_in: self.burn_in,
                samples: self.samples,
                thin: self.thin,
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
    /// Largest `|F|/|∇F|` over the samples.
    pub max_residual: f64,
}

/// Samples and what it took to draw them.
#[derive(Debug, Clone)]
pub struct Samples {
    /// Points `(x, y, z, t)`; coordinates past N are zero.
    pub points: Vec<Q>,
    /// Counters.
    pub stats: SampleStats,
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
