//! The walkers and the three schemes: one step of each, and the driver that spreads the
//! walkers over the figure, burns them in (tuning the step and choosing the thinning), and
//! draws samples round-robin.
//!
//! Burn-in, per walker (`burn_in` steps, docs/sampler.md):
//! 1. **Step tuning** (first 40 %, Metropolis without a given `dt`): rounds of
//!    [`TUNE_ROUND`] steps of every walker; after each, the log of the step length moves by
//!    `γ_r (a_r - a*)` (a Robbins-Monro recursion: `a_r` the round's acceptance, `a*` the
//!    target, `γ_r = 2/√(1+r)`); the step kept is the mean log step of the last half of the
//!    rounds.
//! 2. **Equilibration** at the fixed step (the rest).
//! 3. **Pilot** (last 40 %, when `thin` is not given): the positions of up to
//!    [`PILOT_CHAINS`] walkers are kept at every step; their multi-walker autocorrelation
//!    (as in the ESS; largest over the coordinates) is searched up to a quarter of the
//!    pilot, and `thin` is the larger of the least lag where it falls to
//!    [`AUTO_THIN_CORRELATION`] and the lag where it falls to 0.3 extrapolated to that level
//!    as an exponential decay (less noisy). If the walkers disagree at every lag while each
//!    is stationary (its variance no longer grows with the pilot) over a pilot of at least
//!    16 of their own lags, they sample parts of the figure the walk does not cross
//!    between, which no thinning changes: the lag is then taken from the within-walker
//!    autocorrelation, and R-hat reports the disagreement. Not found: the pilot is doubled
//!    (to at most [`MAX_PILOT_STEPS`] steps per walker and a quarter of
//!    [`MAX_TOTAL_STEPS`]), then the decay seen is extrapolated; `thin` is capped at
//!    [`MAX_AUTO_THIN`], at `AUTO_THIN_STEPS / samples` and by what the step budget leaves.
//!
//! Nothing is adapted after the first sample is kept: the samples come from one
//! fixed-kernel chain per walker, which the adaptation only chose.

use super::field::Q;
use super::figure::{axpy, dot, Figure, MAX_CONSTRAINTS};
use super::quality::{chains_rho, variance_growth, within_rho, Adaptation, EssTracker, Quality};
use super::rng::Rng;
use super::{
    LambdaPolicy, SampleStats, SamplerError, SamplerOptions, Scheme, AUTO_THIN_CORRELATION,
    AUTO_THIN_STEPS, DEFAULT_DT, MAX_AUTO_THIN, MAX_PILOT_STEPS, MAX_TOTAL_STEPS, PILOT_CHAINS,
};

/// Attempts per walker to find a starting point that projects onto the figure.
const START_TRIES: usize = 200;
/// Candidate start points per walker among which the walkers are spread (farthest-point
/// choice), for up to [`FARTHEST_POINT_WALKERS`] walkers.
const CANDIDATES_PER_WALKER: usize = 4;
/// Most walkers spread by farthest-point choice (its cost is candidates × walkers); more
/// take the candidates as they come.
const FARTHEST_POINT_WALKERS: usize = 1024;
/// Steps of every walker between two adjustments of the step while tuning.
pub const TUNE_ROUND: usize = 10;
/// Largest growth of the walkers' variance from half the pilot to all of it
/// ([`super::quality::variance_growth`]: about 1 + τ/n when mixed, 2 when still wandering)
/// at which walkers that disagree are taken to sample separate parts of the figure.
const STATIONARY_GROWTH: f64 = 1.2;
/// Pilot steps per within-walker lag before walkers that disagree are taken to sample
/// separate parts of the figure (shorter pilots are extended first).
const STATIONARY_SPAN: usize = 16;
/// The autocorrelation level whose lag is extrapolated to [`AUTO_THIN_CORRELATION`]:
/// estimated from a few thousand pilot positions, ρ has a standard error of a few
/// hundredths, comparable to the target, so the lag where it first dips to 0.05 can come
/// early by chance; the lag where it dips to 0.3 is seen well above the noise.
const FIT_CORRELATION: f64 = 0.3;

#[derive(Debug, Clone)]
struct Walker {
    q: Q,
    rng: Rng,
}

/// A set of walkers on one figure, ready to draw samples. [`super::sample`] is the one-call
/// form; this type lets a caller draw samples as it writes them, or time them.
#[derive(Debug)]
pub struct Sampler<'a> {
    fig: &'a Figure,
    opts: SamplerOptions,
    /// The constraint strength actually used (after a clamp).
    k: f64,
    /// The time step in use.
    dt: f64,
    /// Steps between two samples of one walker.
    thin: usize,
    walkers: Vec<Walker>,
    next: usize,
    stats: SampleStats,
    scale: f64,
    adaptation: Adaptation,
    tracker: EssTracker,
    accepted_at_burn_in: u64,
}

impl<'a> Sampler<'a> {
    /// Checks the options, spreads the walkers over the figure, burns them in (tuning the
    /// step and choosing the thinning as the options ask) and fixes both.
    ///
    /// # Errors
    /// [`SamplerError::BadParameter`] for options outside their limits,
    /// [`SamplerError::Unstable`] for `λ = Kαdt ≥ 2` with the explicit scheme under
    /// [`LambdaPolicy::Refuse`], [`SamplerError::NoStart`] if no walker can be put on the
    /// figure.
    pub fn new(fig: &'a Figure, opts: &SamplerOptions) -> Result<Self, SamplerError> {
        opts.validate()?;
        let mut stats = SampleStats::default();
        let dt = opts.dt.unwrap_or(DEFAULT_DT);
        let mut k = opts.k.unwrap_or(opts.lambda / (opts.alpha * dt));
        if opts.scheme == Scheme::Explicit {
            let lambda = k * opts.alpha * dt;
            if !(lambda > 0.0 && lambda.is_finite()) {
                return Err(SamplerError::BadParameter {
                    name: "lambda",
                    value: lambda,
                    expected: "K α dt > 0",
                });
            }
            if lambda >= super::LAMBDA_LIMIT {
                match opts.on_unstable {
                    LambdaPolicy::Refuse => return Err(SamplerError::Unstable { lambda }),
                    LambdaPolicy::Clamp => {
                        stats.clamped_lambda = Some(lambda);
                        k = 1.0 / (opts.alpha * dt);
                    }
                }
            }
        }
        let walkers = opts.walkers.min(opts.samples);
        let scale = fig.scale();
        let mut s = Self {
            fig,
            opts: opts.clone(),
            k,
            dt,
            thin: opts.thin.unwrap_or(1),
            walkers: Vec::with_capacity(walkers),
            next: 0,
            stats,
            scale,
            adaptation: Adaptation {
                dt_given: opts.dt.is_some(),
                target_acceptance: opts.target_acceptance,
                tuning_acceptance: f64::NAN,
                pilot_correlation: f64::NAN,
                ..Default::default()
            },
            tracker: EssTracker::new(fig.dim(), walkers),
            accepted_at_burn_in: 0,
        };
        let starts = s.starts(walkers)?;
        for (w, q) in starts.into_iter().enumerate() {
            s.walkers.push(Walker {
                q,
                rng: Rng::new(opts.seed, w as u64),
            });
        }
        s.burn_in();
        Ok(s)
    }

    /// The walkers' start points. Given start points are used in turn; otherwise candidate
    /// points, uniform in the start box and pulled onto the figure by Gauss-Newton, are
    /// gathered ([`CANDIDATES_PER_WALKER`] per walker) and the walkers put on the ones
    /// farthest from each other, so that they begin spread over the figure.
    fn starts(&mut self, walkers: usize) -> Result<Vec<Q>, SamplerError> {
        let mut rng = Rng::new(self.opts.seed, u64::MAX);
        if !self.opts.starts.is_empty() {
            let mut out = Vec::with_capacity(walkers);
            for w in 0..walkers {
                out.push(self.start_near(w, &mut rng)?);
            }
            self.adaptation.start_candidates = out.len();
            return Ok(out);
        }
        let Some((lo, hi)) = self.fig.start_box() else {
            return Err(SamplerError::NoStart {
                tries: 0,
                why:
                    "no start points and no box to seed walkers in (give a box wall or a seed box)"
                        .into(),
            });
        };
        let n = self.fig.dim();
        let wanted = if walkers <= FARTHEST_POINT_WALKERS {
            CANDIDATES_PER_WALKER * walkers
        } else {
            walkers
        };
        let max_tries = START_TRIES * walkers;
        let mut found: Vec<Q> = Vec::with_capacity(wanted);
        let mut best = f64::INFINITY;
        let mut tries = 0;
        while found.len() < wanted && tries < max_tries {
            // A figure no start point reaches is refused after START_TRIES attempts.
            if found.is_empty() && tries >= START_TRIES {
                break;
            }
            tries += 1;
            let mut q0 = [0.0; 4];
            for i in 0..n {
                q0[i] = lo[i] + (hi[i] - lo[i]) * rng.uniform();
            }
            match self.pull(q0) {
                Some(q) => found.push(q),
                None => best = best.min(self.fig.residual(&q0)),
            }
        }
        if found.is_empty() {
            return Err(SamplerError::NoStart {
                tries,
                why: format!(
                    "no start point reached |F|/|∇F| ≤ {} inside the walls (closest start residual {best:.3e})",
                    self.opts.tol
                ),
            });
        }
        self.adaptation.start_candidates = found.len();
        if found.len() <= walkers {
            // Fewer than asked for: walkers share the points found (burn-in spreads them).
            return Ok((0..walkers).map(|w| found[w % found.len()]).collect());
        }
        if walkers > FARTHEST_POINT_WALKERS {
            found.truncate(walkers);
            return Ok(found);
        }
        // Farthest-point choice: each next walker goes to the candidate farthest from the
        // walkers placed so far (distance in all N coordinates: time weighs as space).
        let d2 = |a: &Q, b: &Q| (0..n).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>();
        let mut nearest: Vec<f64> = found.iter().map(|q| d2(q, &found[0])).collect();
        let mut out = vec![found[0]];
        while out.len() < walkers {
            let (i, _) =
                nearest
                    .iter()
                    .enumerate()
                    .fold((0, -1.0), |b, (i, &d)| if d > b.1 { (i, d) } else { b });
            let q = found[i];
            out.push(q);
            for (j, c) in found.iter().enumerate() {
                nearest[j] = nearest[j].min(d2(c, &q));
            }
        }
        Ok(out)
    }

    /// A given start point (walker `w`'s, cycled) pulled onto the figure; retried from
    /// jittered copies of it, or from points of the start box when there is one.
    fn start_near(&mut self, w: usize, rng: &mut Rng) -> Result<Q, SamplerError> {
        let n = self.fig.dim();
        let given = self.opts.starts[w % self.opts.starts.len()];
        let mut best = f64::INFINITY;
        for attempt in 0..START_TRIES {
            let q0 = if attempt == 0 {
                given
            } else if let Some((lo, hi)) = self.fig.start_box() {
                let mut q = [0.0; 4];
                for i in 0..n {
                    q[i] = lo[i] + (hi[i] - lo[i]) * rng.uniform();
                }
                q
            } else {
                let mut q = given;
                for x in q.iter_mut().take(n) {
                    *x += 0.1 * rng.normal();
                }
                q
            };
            match self.pull(q0) {
                Some(q) => return Ok(q),
                None => best = best.min(self.fig.residual(&q0)),
            }
        }
        Err(SamplerError::NoStart {
            tries: START_TRIES,
            why: format!(
                "no start point reached |F|/|∇F| ≤ {} inside the walls (closest start residual {best:.3e})",
                self.opts.tol
            ),
        })
    }

    /// `q0` pulled onto the figure, if it gets there inside the walls at a point where the
    /// Newton schemes have a tangent space (not a cone apex).
    fn pull(&mut self, q0: Q) -> Option<Q> {
        let q = self.fig.pull_onto(
            q0,
            self.opts.tol,
            (self.opts.max_newton * 100).max(2000),
            0.25 * self.scale,
            &mut self.stats.evals,
        )?;
        let ok = self.fig.admits(&q)
            && (self.opts.scheme == Scheme::Explicit
                || self
                    .fig
                    .local(&q, &mut self.stats.evals)
                    .normals()
                    .is_some());
        ok.then_some(q)
    }

    /// The three phases of burn-in (module doc).
    fn burn_in(&mut self) {
        let b = self.opts.burn_in;
        let tune = if self.opts.tunes_step() { b * 2 / 5 } else { 0 };
        let pilot = if self.opts.chooses_thin() {
            (b * 2 / 5).min(MAX_PILOT_STEPS)
        } else {
            0
        };
        if tune > 0 {
            self.tune_step(tune);
        }
        self.set_dt(self.dt);
        self.run_all(b - tune - pilot);
        if pilot > 0 {
            self.choose_thin(pilot);
        } else {
            self.adaptation.thin = self.thin;
            self.adaptation.thin_wanted = self.thin;
        }
        self.stats.burn_in_steps = self.stats.steps;
        self.accepted_at_burn_in = self.stats.accepted;
    }

    /// Every walker takes `n` steps.
    fn run_all(&mut self, n: usize) {
        for _ in 0..n {
            for w in 0..self.walkers.len() {
                self.step(w);
            }
        }
    }

    /// `N - M`, the dimension of the figure.
    fn free_dims(&self) -> f64 {
        (self.fig.dim() - self.fig.constraints()).max(1) as f64
    }

    /// Uses `dt` from now on and records it.
    fn set_dt(&mut self, dt: f64) {
        self.dt = dt;
        self.adaptation.dt = dt;
        self.adaptation.step_m = (2.0 * self.opts.alpha * dt * self.free_dims()).sqrt();
    }

    /// Robbins-Monro on the log step length toward the target acceptance (module doc).
    fn tune_step(&mut self, steps: usize) {
        let n = self.fig.dim();
        // Start from a twentieth of the walkers' spread over the figure.
        let mut c = [0.0; 4];
        for w in &self.walkers {
            axpy(&mut c, 1.0 / self.walkers.len() as f64, &w.q);
        }
        let spread = (self
            .walkers
            .iter()
            .map(|w| (0..n).map(|i| (w.q[i] - c[i]).powi(2)).sum::<f64>())
            .sum::<f64>()
            / self.walkers.len() as f64)
            .sqrt();
        let spread = if spread > 1e-9 * self.scale {
            spread
        } else {
            0.2 * self.scale
        };
        let to_dt = |len: f64, s: &Self| len * len / (2.0 * s.opts.alpha * s.free_dims());
        let (lo, hi) = (
            (1e-9 * self.scale).ln(),
            (self.opts.max_jump * self.scale).ln(),
        );
        let mut log_len = (0.05 * spread).ln().clamp(lo, hi);
        let round = TUNE_ROUND.min(steps).max(1);
        let rounds = steps / round;
        let (mut kept, mut kept_n) = (0.0, 0usize);
        let (mut acc_sum, mut acc_n) = (0u64, 0u64);
        for r in 0..rounds {
            self.dt = to_dt(log_len.exp(), self);
            let (a0, s0) = (self.stats.accepted, self.stats.steps);
            self.run_all(round);
            let (da, ds) = (self.stats.accepted - a0, self.stats.steps - s0);
            let acc = da as f64 / ds.max(1) as f64;
            if 2 * r >= rounds {
                acc_sum += da;
                acc_n += ds;
            }
            let gain = 2.0 / ((1 + r) as f64).sqrt();
            log_len = (log_len + gain * (acc - self.opts.target_acceptance)).clamp(lo, hi);
            if 2 * (r + 1) > rounds {
                kept += log_len;
                kept_n += 1;
            }
        }
        if kept_n > 0 {
            log_len = kept / kept_n as f64;
        }
        self.set_dt(to_dt(log_len.exp(), self));
        self.adaptation.dt_tuned = true;
        self.adaptation.tuning_acceptance = acc_sum as f64 / acc_n.max(1) as f64;
        self.run_all(steps - rounds * round);
    }

    /// Runs the pilot and chooses `thin` from its autocorrelation (module doc).
    fn choose_thin(&mut self, pilot: usize) {
        let dim = self.fig.dim();
        let chains = self.walkers.len().min(PILOT_CHAINS);
        let walkers = self.walkers.len() as u64;
        let samples = self.opts.samples as u64;
        let mut rec: Vec<Vec<Q>> = vec![Vec::with_capacity(pilot); chains];
        let mut len = 0;
        let mut target = pilot;
        let extension_budget = MAX_TOTAL_STEPS / 4;
        let mut extended = 0u64;
        let largest = |it: &mut dyn Iterator<Item = f64>| -> Option<f64> {
            it.fold(None, |m: Option<f64>, r| Some(m.map_or(r, |m| m.max(r))))
        };
        // The largest multi-walker autocorrelation over the coordinates that vary, at lag k.
        let rho = |rec: &[Vec<Q>], k: usize| -> Option<f64> {
            largest(&mut (0..dim).filter_map(|d| chains_rho(rec, d, k)))
        };
        // The same within each walker, and how much each walker's variance still grows.
        let rho_within = |rec: &[Vec<Q>], k: usize| -> Option<f64> {
            largest(&mut (0..dim).filter_map(|d| within_rho(rec, d, k)))
        };
        let growth =
            |rec: &[Vec<Q>]| largest(&mut (0..dim).filter_map(|d| variance_growth(rec, d)));
        let (wanted, corr, extrapolated) = loop {
            for _ in len..target {
                for w in 0..self.walkers.len() {
                    self.step(w);
                    if w < chains {
                        rec[w].push(self.walkers[w].q);
                    }
                }
            }
            len = target;
            let max_k = (len / 4).max(1);
            if rho(&rec, 1).is_none() {
                // Nothing varies (a figure that is a point): any thinning will do.
                break (1, 0.0, false);
            }
            if let Some((k, r)) = thinning_lag(|k| rho(&rec, k), max_k) {
                break (k, r, false);
            }
            // The walkers disagree at every lag. If each of them is stationary and the pilot
            // is long against their own correlation, they sample different parts of the
            // figure that the walk does not cross between: thinning cannot change that
            // (R-hat reports it), so the lag is taken within walkers.
            if growth(&rec).is_some_and(|g| g <= STATIONARY_GROWTH) {
                if let Some((k, r)) = thinning_lag(|k| rho_within(&rec, k), max_k) {
                    if len >= STATIONARY_SPAN * k {
                        break (k, r, false);
                    }
                }
            }
            let next = 2 * len;
            let more = (next - len) as u64 * walkers;
            let left = MAX_TOTAL_STEPS.saturating_sub(self.stats.steps + samples);
            if next <= MAX_PILOT_STEPS && extended + more <= extension_budget && more <= left {
                extended += more;
                target = next;
                continue;
            }
            // Extrapolate the decay seen at the longest lag looked at: ρ(k) ≈ ρ(K)^(k/K).
            let rk = rho(&rec, max_k).unwrap_or(1.0);
            let k = if rk > 0.0 && rk < 0.98 {
                (max_k as f64 * AUTO_THIN_CORRELATION.ln() / rk.ln()).ceil()
            } else {
                f64::INFINITY
            };
            let k = if k.is_finite() && k < 1e9 {
                k as usize
            } else {
                1_000_000_000
            };
            break (k.max(max_k + 1), rk, true);
        };
        // What the step budgets leave for sampling: the run's, and the automatic choice's.
        let left = MAX_TOTAL_STEPS.saturating_sub(self.stats.steps) / samples.max(1);
        let auto = AUTO_THIN_STEPS / samples.max(1);
        let cap = MAX_AUTO_THIN.min(left.min(auto).max(1) as usize);
        let thin = wanted.clamp(1, cap);
        let a = &mut self.adaptation;
        a.thin = thin;
        a.thin_wanted = wanted;
        a.thin_chosen = true;
        a.thin_capped = thin < wanted;
        a.thin_extrapolated = extrapolated;
        a.pilot_steps = len;
        // `corr` is the pilot's correlation at the longest lag looked at (extrapolated) or
        // at the lag asked for; carried to the lag used along an exponential decay.
        let at = if extrapolated {
            (len / 4).max(1)
        } else {
            wanted
        };
        a.pilot_correlation = if thin != at && corr > 0.0 {
            corr.powf(thin as f64 / at as f64)
        } else {
            corr
        };
        self.thin = thin;
    }

    /// Draws one sample: the next walker (round-robin) moves `thin` steps and its position
    /// is returned (finished by a Newton projection with `project`).
    pub fn draw(&mut self) -> Q {
        let w = self.next;
        self.next = (self.next + 1) % self.walkers.len();
        for _ in 0..self.thin {
            self.step(w);
        }
        self.stats.samples += 1;
        let mut q = self.walkers[w].q;
        let off = self.fig.residual(&q);
        self.stats.max_off_figure = self.stats.max_off_figure.max(off);
        self.stats.sum_sq_off_figure += off * off;
        let mut r = off;
        if self.opts.project {
            match self.fig.pull_onto(
                q,
                self.opts.tol,
                self.opts.max_newton,
                0.25 * self.scale,
                &mut self.stats.evals,
            ) {
                Some(p) if self.fig.admits(&p) => {
                    q = p;
                    r = self.fig.residual(&q);
                }
                _ => self.stats.failed_final_projections += 1,
            }
        }
        if r > self.stats.max_residual || r.is_nan() {
            self.stats.max_residual = r;
        }
        self.tracker.push(w, &q);
        q
    }

    /// What happened so far.
    pub fn stats(&self) -> &SampleStats {
        &self.stats
    }

    /// The constraint strength in use (after a clamp).
    pub fn k(&self) -> f64 {
        self.k
    }

    /// The step and thinning in use.
    pub fn adaptation(&self) -> &Adaptation {
        &self.adaptation
    }

    /// Walkers in use (at most the number of samples).
    pub fn walkers(&self) -> usize {
        self.walkers.len()
    }

    /// The quality of the samples drawn so far: effective sample size per coordinate (from
    /// the running autocorrelation of [`super::quality::ESS_CHAINS`] walkers), acceptance
    /// over the sampling steps, residuals, and the adapted settings.
    pub fn quality(&self) -> Quality {
        let st = &self.stats;
        let dim = self.fig.dim();
        let est = self.tracker.estimate(st.samples);
        let (ess, ess_upper_bound) = (est.ess, est.upper);
        let min_ess = (0..dim)
            .filter_map(|i| ess[i])
            .fold(None, |m: Option<f64>, e| Some(m.map_or(e, |m| m.min(e))));
        let steps = st.steps - st.burn_in_steps;
        Quality {
            scheme: self.opts.scheme,
            samples: st.samples,
            walkers: self.walkers.len(),
            dim,
            ess,
            ess_upper_bound,
            rhat: est.rhat,
            min_ess,
            ess_fraction: min_ess.map(|e| e / st.samples.max(1) as f64),
            acceptance: if steps > 0 {
                (st.accepted - self.accepted_at_burn_in) as f64 / steps as f64
            } else {
                f64::NAN
            },
            max_residual: st.max_residual,
            off_figure_max: st.max_off_figure,
            off_figure_rms: (st.sum_sq_off_figure / st.samples.max(1) as f64).sqrt(),
            failed_final_projections: st.failed_final_projections,
            projected: self.opts.project,
            burn_in_steps: st.burn_in_steps,
            steps: st.steps,
            evals: st.evals,
            adaptation: self.adaptation.clone(),
        }
    }

    fn step(&mut self, w: usize) {
        self.stats.steps += 1;
        let before = self.walkers[w].q;
        match self.opts.scheme {
            Scheme::Explicit => self.step_explicit(w),
            Scheme::Projected => self.step_projected(w),
            Scheme::Metropolis => self.step_metropolis(w),
        }
        if self.walkers[w].q != before {
            self.stats.accepted += 1;
        }
    }

    /// Full-space Gaussian noise of variance `2 α dt` per coordinate.
    fn noise(&mut self, w: usize) -> Q {
        let sd = (2.0 * self.opts.alpha * self.dt).sqrt();
        let n = self.fig.dim();
        let rng = &mut self.walkers[w].rng;
        let mut v = [0.0; 4];
        for x in v.iter_mut().take(n) {
            *x = sd * rng.normal();
        }
        v
    }

    /// docs/methods/sampling.md, eq. (2), by Euler-Maruyama:
    /// `dq = P dw - α dt ∇F^a (D^{-1})^{ab} [Tr(∂²F^b P) + K F^b]`.
    /// The trace is `Σ_k u_k·∂²F^b u_k` over an orthonormal tangent frame `u_k`, each term a
    /// central difference of the analytic gradient along `u_k` (2(N-M) gradient calls).
    fn step_explicit(&mut self, w: usize) {
        let fig = self.fig;
        let q = self.walkers[w].q;
        let dw = self.noise(w);
        let l = fig.local(&q, &mut self.stats.evals);
        let Some(nrm) = l.normals() else {
            // ∇F vanishes or the constraints are tangent here: D^{-1} does not exist.
            // Diffuse in full space for this step; the constraint force pulls back later.
            self.stats.singular += 1;
            self.finish_explicit(w, q, dw);
            return;
        };
        let tangent = tangent_frame(&nrm, l.m, fig.dim());
        let h = 1e-5 * self.scale.max(1e-3);
        let mut trace = [0.0; MAX_CONSTRAINTS];
        for u in &tangent[..fig.dim() - l.m] {
            let mut a = q;
            let mut b = q;
            axpy(&mut a, h, u);
            axpy(&mut b, -h, u);
            let la = fig.local(&a, &mut self.stats.evals);
            let lb = fig.local(&b, &mut self.stats.evals);
            for c in 0..l.m {
                trace[c] += (dot(&la.g[c], u) - dot(&lb.g[c], u)) / (2.0 * h);
            }
        }
        let rhs: [f64; MAX_CONSTRAINTS] = std::array::from_fn(|c| trace[c] + self.k * l.f[c]);
        let Some(corr) = l.correction(rhs) else {
            self.stats.singular += 1;
            self.finish_explicit(w, q, dw);
            return;
        };
        let mut dq = tangent_part(&dw, &nrm, l.m);
        axpy(&mut dq, -self.opts.alpha * self.dt, &corr);
        self.finish_explicit(w, q, dq);
    }

    fn finish_explicit(&mut self, w: usize, q: Q, dq: Q) {
        let mut y = q;
        axpy(&mut y, 1.0, &dq);
        if !self.fig.admits(&y) {
            self.fig.reflect(&mut y);
            self.stats.reflections += 1;
        }
        // The guard that keeps NaN and runaways out of the samples: a step that leaves the
        // finite numbers or jumps further than the guard length is not taken.
        let len = dot(&dq, &dq).sqrt();
        if !y.iter().all(|v| v.is_finite()) || !(len <= self.opts.max_jump * self.scale) {
            self.stats.guarded += 1;
            return;
        }
        self.walkers[w].q = y;
    }

    /// Tangent noise, then Newton projection along the normals at the start point.
    fn step_projected(&mut self, w: usize) {
        let fig = self.fig;
        let q = self.walkers[w].q;
        let dw = self.noise(w);
        let l = fig.local(&q, &mut self.stats.evals);
        let Some(nrm) = l.normals() else {
            self.stats.singular += 1;
            return;
        };
        let mut y0 = q;
        axpy(&mut y0, 1.0, &tangent_part(&dw, &nrm, l.m));
        match fig.newton(
            &y0,
            &l.g,
            self.opts.tol,
            self.opts.max_newton,
            self.opts.max_jump * self.scale,
            &mut self.stats.evals,
        ) {
            Some((y, _)) if fig.admits(&y) => self.walkers[w].q = y,
            Some(_) => self.stats.rejected_walls += 1,
            None => self.stats.failed_projections += 1,
        }
    }

    /// Zappa, Holmes-Cerfon & Goodman (2018): tangent Gaussian proposal, Newton projection
    /// along the normals at x, Metropolis-Hastings with the reverse move's density, and the
    /// reverse projection check that keeps the chain reversible (hence unbiased).
    fn step_metropolis(&mut self, w: usize) {
        let fig = self.fig;
        let x = self.walkers[w].q;
        let dw = self.noise(w);
        let lx = fig.local(&x, &mut self.stats.evals);
        let Some(nx) = lx.normals() else {
            self.stats.singular += 1;
            return;
        };
        let v = tangent_part(&dw, &nx, lx.m);
        let mut y0 = x;
        axpy(&mut y0, 1.0, &v);
        let max_move = self.opts.max_jump * self.scale;
        let Some((y, ly)) = fig.newton(
            &y0,
            &lx.g,
            self.opts.tol,
            self.opts.max_newton,
            max_move,
            &mut self.stats.evals,
        ) else {
            self.stats.failed_projections += 1;
            return;
        };
        if !fig.admits(&y) {
            self.stats.rejected_walls += 1;
            return;
        }
        let Some(ny) = ly.normals() else {
            self.stats.singular += 1;
            return;
        };
        let mut xy = x;
        axpy(&mut xy, -1.0, &y);
        let vr = tangent_part(&xy, &ny, ly.m);
        let var = 2.0 * self.opts.alpha * self.dt;
        let log_acc = (dot(&v, &v) - dot(&vr, &vr)) / (2.0 * var);
        if log_acc < 0.0 && self.walkers[w].rng.uniform() >= log_acc.exp() {
            self.stats.rejected_metropolis += 1;
            return;
        }
        let mut x0 = y;
        axpy(&mut x0, 1.0, &vr);
        let back = fig.newton(
            &x0,
            &ly.g,
            self.opts.tol,
            self.opts.max_newton,
            max_move,
            &mut self.stats.evals,
        );
        let ok = back.is_some_and(|(xb, _)| {
            let mut d = xb;
            axpy(&mut d, -1.0, &x);
            dot(&d, &d).sqrt() <= 1e3 * self.opts.tol.max(1e-12 * self.scale)
        });
        if !ok {
            self.stats.rejected_reverse += 1;
            return;
        }
        self.walkers[w].q = y;
    }
}

/// The thinning for an autocorrelation function `rho` of the pilot, looked at up to lag
/// `max_k`, and the correlation expected at it: the larger of the least lag where `rho`
/// falls to [`AUTO_THIN_CORRELATION`] and the lag where it falls to [`FIT_CORRELATION`]
/// carried to that level as an exponential decay (`k ln(0.05)/ln ρ(k)`, 2.5 times the lag
/// for ρ = 0.3). `None` if `rho` stays above the target up to `max_k`.
fn thinning_lag(rho: impl Fn(usize) -> Option<f64>, max_k: usize) -> Option<(usize, f64)> {
    let (k_direct, r_direct) = first_lag_below(&rho, max_k, AUTO_THIN_CORRELATION)?;
    let (k_fit, r_fit) = first_lag_below(&rho, max_k, FIT_CORRELATION)?;
    if r_fit > AUTO_THIN_CORRELATION && r_fit < 1.0 {
        let k = (k_fit as f64 * AUTO_THIN_CORRELATION.ln() / r_fit.ln()).ceil() as usize;
        if k > k_direct {
            // The correlation expected there on the decay fitted.
            return Some((k, r_fit.powf(k as f64 / k_fit as f64)));
        }
    }
    Some((k_direct, r_direct))
}

/// The least lag `k ≤ max_k` with `rho(k) ≤ level` and that value: lags 1, 2, 4, … until
/// one is at or below, then bisection between it and the previous (the autocorrelation of a
/// reversible walk decays, so the first crossing is bracketed).
fn first_lag_below(
    rho: impl Fn(usize) -> Option<f64>,
    max_k: usize,
    level: f64,
) -> Option<(usize, f64)> {
    let below = |k: usize| rho(k).filter(|r| *r <= level);
    let mut lo = 0;
    let mut k = 1;
    let (mut hi, mut at) = loop {
        if let Some(r) = below(k) {
            break (k, r);
        }
        if k >= max_k {
            return None;
        }
        lo = k;
        k = (2 * k).min(max_k);
    };
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        match below(mid) {
            Some(r) => {
                hi = mid;
                at = r;
            }
            None => lo = mid,
        }
    }
    Some((hi, at))
}

/// `v` minus its components along the orthonormal normals.
fn tangent_part(v: &Q, nrm: &[Q; MAX_CONSTRAINTS], m: usize) -> Q {
    let mut t = *v;
    for n in &nrm[..m] {
        let c = dot(&t, n);
        axpy(&mut t, -c, n);
    }
    t
}

/// An orthonormal frame of the tangent space (the first `dim - m` entries): the normals
/// completed by Gram-Schmidt, each round with the coordinate axis that keeps most of its
/// length (at least 1/2: the squared residual lengths of the N
/// axes sum to N - k ≥ 1, so the largest is at least 1/N ≥ 1/4).
fn tangent_frame(nrm: &[Q; MAX_CONSTRAINTS], m: usize, dim: usize) -> [Q; 4] {
    let mut basis = [[0.0; 4]; 4];
    basis[..m].copy_from_slice(&nrm[..m]);
    for k in m..dim {
        let mut best = ([0.0; 4], 0.0);
        for i in 0..dim {
            let mut e = [0.0; 4];
            e[i] = 1.0;
            for b in &basis[..k] {
                let c = dot(&e, b);
                axpy(&mut e, -c, b);
            }
            let len = dot(&e, &e).sqrt();
            if len > best.1 {
                best = (e, len);
            }
        }
        basis[k] = best.0.map(|x| x / best.1);
    }
    let mut out = [[0.0; 4]; 4];
    out[..dim - m].copy_from_slice(&basis[m..dim]);
    out
}
