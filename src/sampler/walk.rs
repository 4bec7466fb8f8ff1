//! The walkers and the three schemes: one step of each, and the driver that seeds walkers,
//! burns them in and draws samples round-robin.

use super::field::Q;
use super::figure::{axpy, dot, Figure, MAX_CONSTRAINTS};
use super::rng::Rng;
use super::{LambdaPolicy, SampleStats, SamplerError, SamplerOptions, Scheme};

/// Attempts per walker to find a starting point that projects onto the figure.
const START_TRIES: usize = 200;

#[derive(Debug, Clone)]
struct Walker {
    q: Q,
    rng: Rng,
}

/// A set of walkers on one figure, ready to draw samples. [`super::sample`] is the one-call
/// form; this type lets a benchmark draw a few samples at a time and time them.
#[derive(Debug)]
pub struct Sampler<'a> {
    fig: &'a Figure,
    opts: SamplerOptions,
    /// The constraint strength actually used (after a clamp).
    k: f64,
    walkers: Vec<Walker>,
    next: usize,
    stats: SampleStats,
    scale: f64,
}

impl<'a> Sampler<'a> {
    /// Checks the options, puts every walker on the figure and burns it in.
    ///
    /// # Errors
    /// [`SamplerError::BadParameter`] for options outside their limits,
    /// [`SamplerError::Unstable`] for `λ = Kαdt ≥ 2` with the explicit scheme under
    /// [`LambdaPolicy::Refuse`], [`SamplerError::NoStart`] if a walker cannot be put on the
    /// figure.
    pub fn new(fig: &'a Figure, opts: &SamplerOptions) -> Result<Self, SamplerError> {
        opts.validate()?;
        let mut stats = SampleStats::default();
        let mut k = opts.k.unwrap_or(opts.lambda / (opts.alpha * opts.dt));
        if opts.scheme == Scheme::Explicit {
            let lambda = k * opts.alpha * opts.dt;
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
                        k = 1.0 / (opts.alpha * opts.dt);
                    }
                }
            }
        }
        let scale = fig.scale();
        let mut s = Self {
            fig,
            opts: opts.clone(),
            k,
            walkers: Vec::with_capacity(opts.walkers),
            next: 0,
            stats,
            scale,
        };
        for w in 0..opts.walkers {
            let mut rng = Rng::new(opts.seed, w as u64);
            let q = s.start(w, &mut rng)?;
            s.walkers.push(Walker { q, rng });
        }
        for w in 0..s.walkers.len() {
            for _ in 0..opts.burn_in {
                s.step(w);
            }
        }
        Ok(s)
    }

    /// Where walker `w` starts: the given start point (cycled), else a uniform point of the
    /// start box, pulled onto the figure by Gauss-Newton; retried from fresh points.
    fn start(&mut self, w: usize, rng: &mut Rng) -> Result<Q, SamplerError> {
        let n = self.fig.dim();
        let max_step = 0.25 * self.scale;
        let mut best = f64::INFINITY;
        for attempt in 0..START_TRIES {
            let q0 = if !self.opts.starts.is_empty() && attempt == 0 {
                self.opts.starts[w % self.opts.starts.len()]
            } else if let Some((lo, hi)) = self.fig.start_box() {
                let mut q = [0.0; 4];
                for i in 0..n {
                    q[i] = lo[i] + (hi[i] - lo[i]) * rng.uniform();
                }
                q
            } else if !self.opts.starts.is_empty() {
                // Jitter around the given start.
                let mut q = self.opts.starts[w % self.opts.starts.len()];
                for x in q.iter_mut().take(n) {
                    *x += 0.1 * rng.normal();
                }
                q
            } else {
                return Err(SamplerError::NoStart {
                    tries: 0,
                    why: "no start points and no box to seed walkers in (give a box wall or a seed box)".into(),
                });
            };
            let got = self.fig.pull_onto(
                q0,
                self.opts.tol,
                (self.opts.max_newton * 100).max(2000),
                max_step,
                &mut self.stats.evals,
            );
            if let Some(q) = got {
                // The Newton schemes need a tangent space to start from (not a cone apex).
                if self.fig.admits(&q)
                    && (self.opts.scheme == Scheme::Explicit
                        || self
                            .fig
                            .local(&q, &mut self.stats.evals)
                            .normals()
                            .is_some())
                {
                    return Ok(q);
                }
            } else {
                best = best.min(self.fig.residual(&q0));
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

    /// Draws one sample: the next walker (round-robin) moves `thin` steps and its position
    /// is returned.
    pub fn draw(&mut self) -> Q {
        let w = self.next;
        self.next = (self.next + 1) % self.walkers.len();
        for _ in 0..self.opts.thin {
            self.step(w);
        }
        self.stats.samples += 1;
        let q = self.walkers[w].q;
        let r = self.fig.residual(&q);
        if r > self.stats.max_residual {
            self.stats.max_residual = r;
        }
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

    fn step(&mut self, w: usize) {
        self.stats.steps += 1;
        match self.opts.scheme {
            Scheme::Explicit => self.step_explicit(w),
            Scheme::Projected => self.step_projected(w),
            Scheme::Metropolis => self.step_metropolis(w),
        }
    }

    /// Full-space Gaussian noise of variance `2 α dt` per coordinate.
    fn noise(&mut self, w: usize) -> Q {
        let sd = (2.0 * self.opts.alpha * self.opts.dt).sqrt();
        let n = self.fig.dim();
        let rng = &mut self.walkers[w].rng;
        let mut v = [0.0; 4];
        for x in v.iter_mut().take(n) {
            *x = sd * rng.normal();
        }
        v
    }

    /// Seed 001 eq. (2) by Euler-Maruyama:
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
        axpy(&mut dq, -self.opts.alpha * self.opts.dt, &corr);
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
        let var = 2.0 * self.opts.alpha * self.opts.dt;
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
