//! Figures whose uniform distribution is known exactly, and the statistics that compare
//! samples with them (DESIGN.md §7). Used by the tests and by `chronotope bench sampler`.

use super::field::Q;

/// Kolmogorov-Smirnov statistic `sup |F_n(x) - F(x)|` of `values` (sorted in place) against
/// the continuous CDF `cdf`. 0 for no values.
pub fn ks_statistic(values: &mut [f64], cdf: impl Fn(f64) -> f64) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len() as f64;
    values
        .iter()
        .enumerate()
        .map(|(i, &x)| {
            let c = cdf(x);
            (c - i as f64 / n).abs().max(((i + 1) as f64 / n - c).abs())
        })
        .fold(0.0, f64::max)
}

/// A torus around z with radii `major` > `minor`: the tube angle θ of a uniform point has
/// density `(R + r cos θ) / (2π R)` on (-π, π].
#[derive(Debug, Clone, Copy)]
pub struct TorusTheta {
    /// R.
    pub major: f64,
    /// r.
    pub minor: f64,
}

impl TorusTheta {
    /// θ of a point (0 on the outer equator, π/2 on top).
    pub fn theta(&self, q: &Q) -> f64 {
        let rho = (q[0] * q[0] + q[1] * q[1]).sqrt();
        q[2].atan2(rho - self.major)
    }
    /// `P(Θ ≤ θ)` = `(R(θ + π) + r sin θ) / (2π R)`.
    pub fn cdf(&self, theta: f64) -> f64 {
        (self.major * (theta + std::f64::consts::PI) + self.minor * theta.sin())
            / (2.0 * std::f64::consts::PI * self.major)
    }
    /// `E[cos θ] = r / (2R)`.
    pub fn mean_cos(&self) -> f64 {
        self.minor / (2.0 * self.major)
    }
}

/// The unit sphere given by the non-distance function `(|q|² - 1) e^{k x}` (any k): x of a
/// uniform point is uniform on [-1, 1] (Archimedes), so `E[x] = 0` and the CDF is
/// `(x + 1)/2`.
pub fn sphere_x_cdf(x: f64) -> f64 {
    ((x + 1.0) / 2.0).clamp(0.0, 1.0)
}

/// A static sphere A (centre 0, radius `ra`) and a sphere B (radius `rb`) whose centre moves
/// along x as `(speed · t, 0, 0)`. Their space-time collision set `{F_A = F_B = 0}` ⊂ R^4,
/// with F the signed distances, is at each t the circle where the spheres cross (for
/// `|ra - rb| < d(t) < ra + rb`, `d = |speed · t|`). The t-marginal of the uniform (area)
/// measure follows from the coarea formula: `f(t) ∝ ∮ dℓ / |∇_S t|`. With
/// `cos γ = n_A·n_B = (ra² + rb² - d²)/(2 ra rb)` and `β = n_B · v`, both constant on the
/// circle, `|∇_S t|² = 1 - e_t·G^T D^{-1} G e_t = sin²γ / (sin²γ + β²)` and the circle has
/// length `2π ra rb sinγ / d`, so `f(t) ∝ sqrt(sin²γ + β²) / d`.
#[derive(Debug, Clone, Copy)]
pub struct PassingSpheres {
    /// Radius of the static sphere (m).
    pub ra: f64,
    /// Radius of the moving sphere (m).
    pub rb: f64,
    /// Speed of the moving sphere along x (m/s).
    pub speed: f64,
}

impl PassingSpheres {
    /// Unnormalised t-density (0 where the spheres do not cross).
    pub fn density(&self, t: f64) -> f64 {
        let (ra, rb) = (self.ra, self.rb);
        let c = self.speed * t;
        let d = c.abs();
        if !(d > (ra - rb).abs() && d < ra + rb) {
            return 0.0;
        }
        let cos_g = (ra * ra + rb * rb - d * d) / (2.0 * ra * rb);
        let sin2 = 1.0 - cos_g * cos_g;
        // The circle lies in the plane x = x0; n_B = (p - c)/rb, so β = speed (x0 - c)/rb.
        let x0 = (ra * ra + c * c - rb * rb) / (2.0 * c);
        let beta = self.speed * (x0 - c) / rb;
        (sin2 + beta * beta).sqrt() / d
    }

    /// The CDF of the t-marginal restricted to `[t0, t1]`, tabulated by composite Simpson
    /// on `steps` intervals (2000 give ~1e-10 on smooth windows), as a closure.
    pub fn cdf_on(&self, t0: f64, t1: f64, steps: usize) -> impl Fn(f64) -> f64 {
        let steps = steps.max(2) & !1;
        let h = (t1 - t0) / steps as f64;
        let mut acc = vec![0.0; steps / 2 + 1];
        for k in 0..steps / 2 {
            let a = t0 + 2.0 * k as f64 * h;
            let s =
                h / 3.0 * (self.density(a) + 4.0 * self.density(a + h) + self.density(a + 2.0 * h));
            acc[k + 1] = acc[k] + s;
        }
        let total = acc[steps / 2];
        let me = *self;
        move |t: f64| {
            if t <= t0 {
                return 0.0;
            }
            if t >= t1 {
                return 1.0;
            }
            // Whole Simpson panels, then the remainder by Simpson on its own interval.
            let k = (((t - t0) / (2.0 * h)).floor() as usize).min(steps / 2 - 1);
            let a = t0 + 2.0 * k as f64 * h;
            let m = 0.5 * (a + t);
            let rest = (t - a) / 6.0 * (me.density(a) + 4.0 * me.density(m) + me.density(t));
            ((acc[k] + rest) / total).clamp(0.0, 1.0)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ks_of_a_perfect_grid_is_half_a_step() {
        let mut v: Vec<f64> = (0..100).map(|i| (i as f64 + 0.5) / 100.0).collect();
        let d = ks_statistic(&mut v, |x| x);
        assert!((d - 0.005).abs() < 1e-12, "{d}");
    }

    #[test]
    fn torus_cdf_spans_zero_to_one() {
        let t = TorusTheta {
            major: 1.0,
            minor: 0.4,
        };
        assert!(t.cdf(-std::f64::consts::PI).abs() < 1e-15);
        assert!((t.cdf(std::f64::consts::PI) - 1.0).abs() < 1e-15);
    }

    #[test]
    fn passing_spheres_density_matches_a_direct_quadrature() {
        // Direct: integrate 1/|∇_S t| over the circle numerically from the gradients.
        let p = PassingSpheres {
            ra: 1.0,
            rb: 0.5,
            speed: 1.3,
        };
        let t = 0.8;
        let c = p.speed * t;
        let x0 = (1.0 + c * c - 0.25) / (2.0 * c);
        let rho = (1.0 - x0 * x0).sqrt();
        let n = 720;
        let mut sum = 0.0;
        for k in 0..n {
            let phi = 2.0 * std::f64::consts::PI * k as f64 / n as f64;
            let pt = [x0, rho * phi.cos(), rho * phi.sin()];
            let na = [pt[0], pt[1], pt[2], 0.0];
            let nb3 = [(pt[0] - c) / 0.5, pt[1] / 0.5, pt[2] / 0.5];
            let nb = [nb3[0], nb3[1], nb3[2], -nb3[0] * p.speed];
            let d11 = 1.0;
            let d12: f64 = (0..4).map(|i| na[i] * nb[i]).sum();
            let d22: f64 = (0..4).map(|i| nb[i] * nb[i]).sum();
            let det = d11 * d22 - d12 * d12;
            // e_t·G^T D^{-1} G e_t with G e_t = (0, nb[3]).
            let q = nb[3] * nb[3] * d11 / det;
            sum += (2.0 * std::f64::consts::PI * rho / n as f64) / (1.0 - q).sqrt();
        }
        let ratio = sum / p.density(t);
        // Same up to the constant 2π ra rb = π.
        assert!((ratio - std::f64::consts::PI).abs() < 1e-9, "{ratio}");
        let cdf = p.cdf_on(0.6, 1.1, 2000);
        assert!(cdf(0.6) == 0.0 && (cdf(1.1) - 1.0).abs() < 1e-12);
        assert!(cdf(0.8) > 0.0 && cdf(0.8) < cdf(0.9));
    }
}
