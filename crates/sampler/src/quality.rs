//! How good a run's samples are: the effective sample size (ESS) of each coordinate from
//! its autocorrelation, the acceptance rate, the largest residual, and how far the
//! explicit scheme's points lie off the figure.
//!
//! The ESS is the multi-chain estimate of Vehtari, Gelman, Simpson, Carpenter & Bürkner
//! (2021, "Rank-normalization, folding, and localization", without the rank
//! normalisation): each walker is a chain; the autocorrelation at lag k is
//! `ρ_k = 1 - (W - mean_c γ_c(k)) / var⁺`, with `γ_c` the autocovariance of chain c, `W` the
//! mean within-chain variance and `var⁺ = (n-1)/n W + B/n` (B the between-chain variance of
//! the means, so walkers stuck in different places lower the ESS). The integrated time
//! `τ = -1 + 2 Σ_m P_m`, `P_m = ρ_{2m} + ρ_{2m+1}`, is summed while `P_m > 0` and made
//! monotone (Geyer 1992, initial monotone sequence); `ESS = N / τ`.
//!
//! During sampling the estimate is kept as the samples go (`EssTracker`), so its memory is
//! bounded whatever the number of samples: at most [`ESS_CHAINS`] walkers are followed, each
//! with its last and first [`ESS_LAGS`] values and its lagged sums. A walk whose
//! autocorrelation has not died out within [`ESS_LAGS`] lags of samples gets an ESS marked
//! as an upper bound (`ess_upper_bound`). [`ess`] is the same estimate on chains held in
//! memory, with every lag it needs (benchmarks and tests).

use super::field::Q;
use super::Scheme;

/// Lags of samples (not steps) the running estimate looks at.
pub const ESS_LAGS: usize = 128;
/// Walkers the running estimate follows (the first ones; the others are alike).
pub const ESS_CHAINS: usize = 64;
/// R-hat above which the walkers are said to disagree.
pub const RHAT_WARNING: f64 = 1.05;

/// The step and thinning a run uses, and how they were found.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct Adaptation {
    /// The time step in use.
    pub dt: f64,
    /// The step length it gives, `sqrt(2 α dt (N - M))` (m).
    pub step_m: f64,
    /// Whether `dt` was tuned during burn-in.
    pub dt_tuned: bool,
    /// Whether `dt` was given (otherwise tuned, or the explicit and projected schemes'
    /// default [`DEFAULT_DT`](super::DEFAULT_DT)).
    pub dt_given: bool,
    /// The acceptance rate it was tuned to.
    pub target_acceptance: f64,
    /// The acceptance over the last half of the tuning rounds (NaN when not tuned).
    pub tuning_acceptance: f64,
    /// Steps between two samples of one walker.
    pub thin: usize,
    /// Whether `thin` was chosen from the burn-in pilot's autocorrelation.
    pub thin_chosen: bool,
    /// The thinning the pilot asked for, before any cap. It errs high: over a pilot of n
    /// steps the walkers' means differ by chance, which adds about 2τ/n to the
    /// multi-walker autocorrelation at long lags (τ the walk's correlation time).
    pub thin_wanted: usize,
    /// Whether `thin` was capped ([`MAX_AUTO_THIN`](super::MAX_AUTO_THIN) or the step budget) below that.
    pub thin_capped: bool,
    /// Whether the lag was extrapolated from the decay seen in the pilot rather than seen.
    pub thin_extrapolated: bool,
    /// Pilot steps per walker.
    pub pilot_steps: usize,
    /// The pilot's autocorrelation at lag `thin`, largest over the coordinates.
    pub pilot_correlation: f64,
    /// Start points found on the figure, among which the walkers were spread.
    pub start_candidates: usize,
}

/// The quality of one run, printed by `chronotope sample` and written to its JSON summary.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Quality {
    /// The scheme.
    pub scheme: Scheme,
    /// Samples drawn.
    pub samples: u64,
    /// Walkers used.
    pub walkers: usize,
    /// Dimension N of the figure's space (coordinates x, y, z, t in that order).
    pub dim: usize,
    /// Effective sample size of each coordinate (`None` past N, for a coordinate that does
    /// not vary on the figure, or with fewer than 4 samples per walker).
    pub ess: [Option<f64>; 4],
    /// Per coordinate: the autocorrelation had not died out within [`ESS_LAGS`] lags, so the
    /// ESS is an upper bound (the walk is slower than the estimate can see).
    pub ess_upper_bound: [bool; 4],
    /// R-hat of each coordinate, `sqrt(var⁺/W)` over the followed walkers: near 1 when
    /// they agree; above [`RHAT_WARNING`], walkers sample different parts of the figure
    /// (parts the walk cannot cross between, or a walk too slow for the run).
    pub rhat: [Option<f64>; 4],
    /// The smallest ESS over the coordinates.
    pub min_ess: Option<f64>,
    /// `min_ess / samples`: 1 for independent samples; the defaults aim at about 0.9 and
    /// promise at least 0.5 where the walk can reach it (docs/sampler.md).
    pub ess_fraction: Option<f64>,
    /// Fraction of the sampling steps (burn-in excluded) that moved their walker.
    pub acceptance: f64,
    /// Largest `|F|/|∇F|` of the samples as returned (m, to first order).
    pub max_residual: f64,
    /// Largest `|F|/|∇F|` where the walkers were when sampled (before `project`): how far
    /// the explicit scheme's points lie off the figure (m).
    pub off_figure_max: f64,
    /// Root mean square of the same (m).
    pub off_figure_rms: f64,
    /// Samples whose final projection (`project`) failed (returned unprojected).
    pub failed_final_projections: u64,
    /// Whether each sample was finished by a Newton projection.
    pub projected: bool,
    /// Steps before the first sample, all walkers.
    pub burn_in_steps: u64,
    /// Steps in all.
    pub steps: u64,
    /// Constraint evaluations in all.
    pub evals: u64,
    /// The step and thinning in use, and how they were found.
    pub adaptation: Adaptation,
}

impl Quality {
    /// One line per fact, for the terminal.
    pub fn describe(&self) -> String {
        let names = ["x", "y", "z", "t"];
        let mut ess = Vec::new();
        for i in 0..self.dim.min(4) {
            match self.ess[i] {
                Some(e) => ess.push(format!(
                    "{} {}{:.0} ({:.2} N)",
                    names[i],
                    if self.ess_upper_bound[i] { "≤ " } else { "" },
                    e,
                    e / self.samples.max(1) as f64
                )),
                None => ess.push(format!("{} –", names[i])),
            }
        }
        let a = &self.adaptation;
        let step = if a.dt_tuned {
            format!(
                "dt {:.3e} (steps of {:.3e} m), tuned in burn-in to acceptance {:.2}",
                a.dt, a.step_m, a.target_acceptance
            )
        } else if a.dt_given {
            format!("dt {:.3e} (steps of {:.3e} m), as given", a.dt, a.step_m)
        } else {
            format!(
                "dt {:.3e} (steps of {:.3e} m), the {} scheme's default (not tuned: its O(dt) bias makes the step an accuracy setting)",
                a.dt,
                a.step_m,
                self.scheme.as_str()
            )
        };
        let thin = if a.thin_chosen {
            format!(
                "thin {} chosen from the burn-in's autocorrelation ({:.3} at that lag{}{})",
                a.thin,
                a.pilot_correlation,
                if a.thin_extrapolated {
                    ", extrapolated"
                } else {
                    ""
                },
                if a.thin_capped {
                    format!(
                        "; capped at {}: the pilot asked for {}",
                        a.thin, a.thin_wanted
                    )
                } else {
                    String::new()
                }
            )
        } else {
            format!("thin {}, as given", a.thin)
        };
        let mut s = format!(
            "  step: {step}; {thin}\n  effective sample size: {}; acceptance {:.3}; max |F|/|∇F| {:.2e} m",
            ess.join(", "),
            self.acceptance,
            self.max_residual
        );
        if let Some(f) = self.ess_fraction {
            if f < 0.5 {
                s.push_str(&format!(
                    "\n  warning: the samples are worth {f:.2} N independent ones (below 0.5 N); {}",
                    if a.thin_chosen {
                        "the walk mixes too slowly for the thinning allowed, or its walkers sample different parts of the figure (see R-hat)"
                    } else {
                        "raise --thin or leave it out to have it chosen"
                    }
                ));
            }
        }
        let worst = (0..self.dim.min(4))
            .filter_map(|i| self.rhat[i].map(|r| (i, r)))
            .fold(None, |m: Option<(usize, f64)>, (i, r)| match m {
                Some((_, b)) if b >= r => m,
                _ => Some((i, r)),
            });
        if let Some((i, r)) = worst.filter(|w| w.1 > RHAT_WARNING) {
            s.push_str(&format!(
                "\n  warning: the walkers disagree on {} (R-hat {r:.2}): they sample different parts of the figure, which the walk does not cross between in this run; parts the walk cannot reach from each other are weighted by where walkers started, not by their size (docs/sampler.md)",
                names[i]
            ));
        }
        if self.scheme == Scheme::Explicit || self.off_figure_max > 10.0 * self.max_residual {
            s.push_str(&format!(
                "\n  off the figure (seed eq. 2 leaves the walkers off it): max {:.2e} m, rms {:.2e} m{}",
                self.off_figure_max,
                self.off_figure_rms,
                if self.projected {
                    format!(
                        "; each sample finished by a Newton projection ({} failed)",
                        self.failed_final_projections
                    )
                } else {
                    "; --project finishes each sample with a Newton projection".into()
                }
            ));
        }
        s
    }
}

/// What the running estimate gives per coordinate.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Estimate {
    /// Effective sample size.
    pub ess: [Option<f64>; 4],
    /// Whether it is an upper bound.
    pub upper: [bool; 4],
    /// R-hat.
    pub rhat: [Option<f64>; 4],
}

/// The running ESS estimate of [`ESS_CHAINS`] walkers over [`ESS_LAGS`] lags.
#[derive(Debug, Clone)]
pub(crate) struct EssTracker {
    dim: usize,
    chains: usize,
    /// Subtracted from every value (the first sample) so that the sums do not cancel.
    shift: Option<Q>,
    /// Per chain: its last `ESS_LAGS` values (a ring) and its first `ESS_LAGS` values.
    ring: Vec<Q>,
    head: Vec<Q>,
    n: Vec<u64>,
    sum: Vec<Q>,
    /// Per chain and lag k = 0..=ESS_LAGS: Σ_t x_t x_{t-k}.
    lag_sum: Vec<Q>,
}

impl EssTracker {
    /// Follows the first `min(walkers, ESS_CHAINS)` walkers of a figure in R^`dim`.
    pub fn new(dim: usize, walkers: usize) -> Self {
        let chains = walkers.clamp(1, ESS_CHAINS);
        Self {
            dim: dim.min(4),
            chains,
            shift: None,
            ring: vec![[0.0; 4]; chains * ESS_LAGS],
            head: vec![[0.0; 4]; chains * ESS_LAGS],
            n: vec![0; chains],
            sum: vec![[0.0; 4]; chains],
            lag_sum: vec![[0.0; 4]; chains * (ESS_LAGS + 1)],
        }
    }

    /// Adds the next sample of walker `chain` (ignored past the followed walkers).
    pub fn push(&mut self, chain: usize, q: &Q) {
        if chain >= self.chains {
            return;
        }
        let shift = *self.shift.get_or_insert(*q);
        let mut x = [0.0; 4];
        for i in 0..self.dim {
            x[i] = q[i] - shift[i];
        }
        let n = self.n[chain] as usize;
        let ring = &mut self.ring[chain * ESS_LAGS..(chain + 1) * ESS_LAGS];
        let lags = &mut self.lag_sum[chain * (ESS_LAGS + 1)..(chain + 1) * (ESS_LAGS + 1)];
        for i in 0..self.dim {
            lags[0][i] += x[i] * x[i];
        }
        for k in 1..=n.min(ESS_LAGS) {
            let y = ring[(n - k) % ESS_LAGS];
            for i in 0..self.dim {
                lags[k][i] += x[i] * y[i];
            }
        }
        ring[n % ESS_LAGS] = x;
        if n < ESS_LAGS {
            self.head[chain * ESS_LAGS + n] = x;
        }
        for i in 0..self.dim {
            self.sum[chain][i] += x[i];
        }
        self.n[chain] += 1;
    }

    /// The ESS of each coordinate for `total` samples drawn by all walkers alike, whether
    /// it is only an upper bound, and R-hat.
    pub fn estimate(&self, total: u64) -> Estimate {
        let mut ess = [None; 4];
        let mut upper = [false; 4];
        let mut rhat = [None; 4];
        let used: Vec<usize> = (0..self.chains).filter(|&c| self.n[c] >= 4).collect();
        if used.is_empty() {
            return Estimate { ess, upper, rhat };
        }
        for d in 0..self.dim {
            let means: Vec<f64> = used
                .iter()
                .map(|&c| self.sum[c][d] / self.n[c] as f64)
                .collect();
            // Autocovariance of chain c at lag k (divided by n, as in the references):
            // Σ_{t≥k} (x_t - m)(x_{t-k} - m) = S(k) - m (A + B) + (n - k) m², with A the sum
            // of x_t for t ≥ k (all but the first k) and B for t < n - k (all but the last k).
            let acov = |k: usize| -> f64 {
                let mut s = 0.0;
                for (j, &c) in used.iter().enumerate() {
                    let n = self.n[c] as usize;
                    let m = means[j];
                    if k >= n {
                        continue;
                    }
                    let first: f64 = (0..k).map(|t| self.head[c * ESS_LAGS + t][d]).sum();
                    let last: f64 = (1..=k)
                        .map(|j| self.ring[c * ESS_LAGS + (n - j) % ESS_LAGS][d])
                        .sum();
                    let total = self.sum[c][d];
                    let a = total - first;
                    let b = total - last;
                    let lag = self.lag_sum[c * (ESS_LAGS + 1) + k][d];
                    s += (lag - m * (a + b) + (n - k) as f64 * m * m) / n as f64;
                }
                s / used.len() as f64
            };
            let n_mean = used.iter().map(|&c| self.n[c] as f64).sum::<f64>() / used.len() as f64;
            let max_lag = ESS_LAGS.min(n_mean as usize - 1);
            if let Some(t) = tau_of(acov, &means, n_mean, max_lag, total) {
                ess[d] = Some(total as f64 / t.tau);
                upper[d] = t.truncated;
                rhat[d] = Some(t.rhat);
            }
        }
        Estimate { ess, upper, rhat }
    }
}

/// What [`tau_of`] finds for one coordinate.
#[derive(Debug, Clone, Copy)]
struct Tau {
    /// Integrated autocorrelation time.
    tau: f64,
    /// The sum ran out of lags (τ is a lower bound, the ESS an upper bound).
    truncated: bool,
    /// `sqrt(var⁺ / W)`: 1 when the walkers agree.
    rhat: f64,
}

/// The integrated autocorrelation time from the mean autocovariance `acov(k)` of the chains
/// (biased, divided by n), their means and length, looking at lags up to `max_lag`;
/// `None` for a coordinate that does not vary.
fn tau_of(
    acov: impl Fn(usize) -> f64,
    means: &[f64],
    n: f64,
    max_lag: usize,
    total: u64,
) -> Option<Tau> {
    if n < 4.0 {
        return None;
    }
    let g0 = acov(0);
    let w = g0 * n / (n - 1.0);
    let c = means.len();
    let b_over_n = if c > 1 {
        let mm = means.iter().sum::<f64>() / c as f64;
        means.iter().map(|m| (m - mm).powi(2)).sum::<f64>() / (c - 1) as f64
    } else {
        0.0
    };
    let var_plus = g0 + b_over_n;
    let scale = means.iter().fold(0.0f64, |a, m| a.max(m.abs()));
    // A coordinate that does not vary (a figure in a plane, t of a 3D figure).
    if !(var_plus > 1e-24 * (1.0 + scale * scale)) || !var_plus.is_finite() {
        return None;
    }
    let rho = |k: usize| {
        if k == 0 {
            1.0
        } else {
            1.0 - (w - acov(k)) / var_plus
        }
    };
    let mut sum = 0.0;
    let mut prev = f64::INFINITY;
    let mut truncated = false;
    let mut m = 0;
    loop {
        if 2 * m + 1 > max_lag {
            truncated = true;
            break;
        }
        let p = rho(2 * m) + rho(2 * m + 1);
        if !(p > 0.0) {
            break;
        }
        let p = p.min(prev);
        prev = p;
        sum += p;
        m += 1;
    }
    let tau = -1.0 + 2.0 * sum;
    // As in the references: an ESS above N log10 N is not believed (antithetic chains).
    let floor = 1.0 / (total.max(10) as f64).log10();
    Some(Tau {
        tau: tau.max(floor),
        truncated,
        rhat: if w > 0.0 {
            (var_plus / w).sqrt()
        } else {
            f64::INFINITY
        },
    })
}

/// An effective sample size and whether it is only an upper bound.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ess {
    /// ESS of all the chains' values together.
    pub value: f64,
    /// The autocorrelation had not died out at the longest lag looked at (`n/2`).
    pub upper_bound: bool,
    /// R-hat, `sqrt(var⁺/W)`: near 1 when the chains agree; well above (1.05 and more)
    /// when they sample different parts, e.g. components of a figure the walk cannot cross
    /// between.
    pub rhat: f64,
}

/// The ESS of one statistic over `chains` (one slice per walker, in order), by the same
/// estimate as the running one but with every lag it needs up to half a chain. Chains are
/// cut to the shortest. `None` for fewer than 4 values per chain or a constant statistic.
pub fn ess(chains: &[&[f64]]) -> Option<Ess> {
    let n = chains.iter().map(|c| c.len()).min()?;
    if n < 4 {
        return None;
    }
    let means: Vec<f64> = chains
        .iter()
        .map(|c| c[..n].iter().sum::<f64>() / n as f64)
        .collect();
    let acov = |k: usize| -> f64 {
        chains
            .iter()
            .zip(&means)
            .map(|(c, m)| (k..n).map(|t| (c[t] - m) * (c[t - k] - m)).sum::<f64>() / n as f64)
            .sum::<f64>()
            / chains.len() as f64
    };
    let total = (n * chains.len()) as u64;
    tau_of(acov, &means, n as f64, n / 2, total).map(|t| Ess {
        value: total as f64 / t.tau,
        upper_bound: t.truncated,
        rhat: t.rhat,
    })
}

/// The within-walker autocorrelation of coordinate `d` of `chains` (equal lengths) at lag
/// `k`: `mean_c γ_c(k) / mean_c γ_c(0)`, each chain about its own mean. It is what thinning
/// can change: walkers that sample different parts of a figure (components the walk cannot
/// cross between) disagree by the same amount whatever the thinning, and that shows in
/// R-hat and the multi-chain ESS instead. `None` if the coordinate does not vary within the
/// walkers or `k ≥ n`.
pub(crate) fn within_rho(chains: &[Vec<Q>], d: usize, k: usize) -> Option<f64> {
    let n = chains.iter().map(|c| c.len()).min()?;
    if n < 4 || k >= n {
        return None;
    }
    let (mut g0, mut gk, mut scale) = (0.0, 0.0, 0.0f64);
    for c in chains {
        let m = c[..n].iter().map(|q| q[d]).sum::<f64>() / n as f64;
        scale = scale.max(m.abs());
        g0 += c[..n].iter().map(|q| (q[d] - m).powi(2)).sum::<f64>();
        gk += (k..n)
            .map(|t| (c[t][d] - m) * (c[t - k][d] - m))
            .sum::<f64>();
    }
    let var = g0 / (n * chains.len()) as f64;
    if !(var > 1e-24 * (1.0 + scale * scale)) || !var.is_finite() {
        return None;
    }
    Some(gk / g0)
}

/// The multi-chain autocorrelation `ρ_k` of coordinate `d` of `chains` (equal lengths) at
/// lag `k`, as in the ESS estimate (walkers that disagree keep it high at every lag);
/// `None` if the coordinate does not vary or `k ≥ n`.
pub(crate) fn chains_rho(chains: &[Vec<Q>], d: usize, k: usize) -> Option<f64> {
    let n = chains.iter().map(|c| c.len()).min()?;
    if n < 4 || k >= n {
        return None;
    }
    let means: Vec<f64> = chains
        .iter()
        .map(|c| c[..n].iter().map(|q| q[d]).sum::<f64>() / n as f64)
        .collect();
    let acov = |k: usize| -> f64 {
        chains
            .iter()
            .zip(&means)
            .map(|(c, m)| {
                (k..n)
                    .map(|t| (c[t][d] - m) * (c[t - k][d] - m))
                    .sum::<f64>()
                    / n as f64
            })
            .sum::<f64>()
            / chains.len() as f64
    };
    let nf = n as f64;
    let g0 = acov(0);
    let w = g0 * nf / (nf - 1.0);
    let c = means.len();
    let b_over_n = if c > 1 {
        let mm = means.iter().sum::<f64>() / c as f64;
        means.iter().map(|m| (m - mm).powi(2)).sum::<f64>() / (c - 1) as f64
    } else {
        0.0
    };
    let var_plus = g0 + b_over_n;
    let scale = means.iter().fold(0.0f64, |a, m| a.max(m.abs()));
    if !(var_plus > 1e-24 * (1.0 + scale * scale)) || !var_plus.is_finite() {
        return None;
    }
    Some(1.0 - (w - acov(k)) / var_plus)
}

/// Whether each walker's coordinate `d` looks stationary over its pilot: the mean variance
/// of the walkers over the whole pilot, against the mean over its two halves (each about its
/// own mean). A walk that has mixed gives about 1 (1 + τ/n for a correlation time τ); a
/// walk still wandering, whose positions over the pilot are a random-walk segment, about 2
/// (the variance of a segment grows with its length). The ratio, or `None` if the
/// coordinate does not vary.
pub(crate) fn variance_growth(chains: &[Vec<Q>], d: usize) -> Option<f64> {
    let n = chains.iter().map(|c| c.len()).min()?;
    if n < 8 {
        return None;
    }
    let var = |v: &[Q]| -> f64 {
        let m = v.iter().map(|q| q[d]).sum::<f64>() / v.len() as f64;
        v.iter().map(|q| (q[d] - m).powi(2)).sum::<f64>() / v.len() as f64
    };
    let (mut whole, mut halves) = (0.0, 0.0);
    for c in chains {
        whole += var(&c[..n]);
        halves += 0.5 * (var(&c[..n / 2]) + var(&c[n / 2..n]));
    }
    (halves > 0.0 && halves.is_finite()).then(|| whole / halves)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Rng;

    /// AR(1) chains x_t = φ x_{t-1} + sqrt(1-φ²) ε: τ = (1 + φ)/(1 - φ).
    fn ar1(phi: f64, chains: usize, n: usize, seed: u64) -> Vec<Vec<f64>> {
        (0..chains)
            .map(|c| {
                let mut r = Rng::new(seed, c as u64);
                let mut x = r.normal();
                (0..n)
                    .map(|_| {
                        x = phi * x + (1.0 - phi * phi).sqrt() * r.normal();
                        x
                    })
                    .collect()
            })
            .collect()
    }

    #[test]
    fn ess_of_ar1_chains_matches_the_formula() {
        for phi in [0.0, 0.5, 0.9] {
            let tau = (1.0 + phi) / (1.0 - phi);
            let c = ar1(phi, 16, 4000, 7);
            let refs: Vec<&[f64]> = c.iter().map(|v| &v[..]).collect();
            let e = ess(&refs).unwrap();
            let want = 64_000.0 / tau;
            assert!(
                (e.value / want - 1.0).abs() < 0.15 && !e.upper_bound,
                "φ {phi}: ESS {} vs {want}",
                e.value
            );
            // The running estimate agrees with the one in memory.
            let mut t = EssTracker::new(1, 16);
            for i in 0..4000 {
                for (w, chain) in c.iter().enumerate() {
                    t.push(w, &[chain[i], 0.0, 0.0, 0.0]);
                }
            }
            let est = t.estimate(64_000);
            let r = est.ess[0].unwrap();
            assert!(
                (r / e.value - 1.0).abs() < 1e-6,
                "φ {phi}: {r} vs {}",
                e.value
            );
            assert!(!est.upper[0]);
            assert!((est.rhat[0].unwrap() - e.rhat).abs() < 1e-9 && e.rhat < 1.01);
        }
    }

    #[test]
    fn chains_stuck_apart_have_a_small_ess() {
        // Independent values, but half the chains around 0 and half around 5: the
        // between-chain variance makes ρ large at every lag.
        let c: Vec<Vec<f64>> = ar1(0.0, 8, 1000, 3)
            .into_iter()
            .enumerate()
            .map(|(i, v)| v.into_iter().map(|x| x + 5.0 * (i % 2) as f64).collect())
            .collect();
        let refs: Vec<&[f64]> = c.iter().map(|v| &v[..]).collect();
        let e = ess(&refs).unwrap();
        assert!(e.value < 800.0 && e.rhat > 1.5, "{e:?}");
        // The within-walker autocorrelation does not see it (thinning cannot help), each
        // walker is stationary, and the multi-walker autocorrelation stays high.
        let q: Vec<Vec<Q>> = c
            .iter()
            .map(|v| v.iter().map(|&x| [x, 0.0, 0.0, 0.0]).collect())
            .collect();
        assert!(within_rho(&q, 0, 1).unwrap().abs() < 0.1);
        assert!(chains_rho(&q, 0, 100).unwrap() > 0.5);
        assert!(variance_growth(&q, 0).unwrap() < 1.1);
        // A random walk is not stationary: its variance grows with the window.
        let walk: Vec<Vec<Q>> = ar1(0.0, 8, 1000, 4)
            .into_iter()
            .map(|v| {
                let mut x = 0.0;
                v.into_iter()
                    .map(|e| {
                        x += e;
                        [x, 0.0, 0.0, 0.0]
                    })
                    .collect()
            })
            .collect();
        assert!(variance_growth(&walk, 0).unwrap() > 1.6);
    }

    #[test]
    fn a_slow_walk_is_flagged_as_an_upper_bound() {
        let c = ar1(0.999, 4, 2000, 1);
        let mut t = EssTracker::new(1, 4);
        for i in 0..2000 {
            for (w, chain) in c.iter().enumerate() {
                t.push(w, &[chain[i], 0.0, 0.0, 0.0]);
            }
        }
        let e = t.estimate(8000);
        assert!(e.upper[0]);
        // A constant coordinate has no ESS.
        assert!(e.ess[1].is_none() && e.rhat[1].is_none());
    }
}
