//! Figures whose uniform distribution is known exactly, and the statistics that compare
//! samples with them (docs/methods/sampling.md#test-cases-with-exact-answers). Used by the
//! tests and by `chronotope bench sampler`.

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

    /// The CDF of the axial coordinate (z for a torus around z, relative to its centre):
    /// `z = r sin θ`, and the two branches of θ weigh `(R ± r cos θ)/(r |cos θ|)`, which sum
    /// to `2R/(r cos θ)`: the arcsine law `1/2 + asin(z/r)/π`.
    pub fn axial_cdf(&self, z: f64) -> f64 {
        0.5 + (z / self.minor).clamp(-1.0, 1.0).asin() / std::f64::consts::PI
    }

    /// The CDF of a coordinate across the axis (x or y for a torus around z, relative to
    /// its centre), tabulated at `points + 1` values: for a tube angle θ the point lies on a
    /// circle of radius `ρ = R + r cos θ` with a uniform azimuth φ, so
    /// `P(X ≤ s) = ∫ (ρ/(2πR)) (1 - acos(s/ρ)/π) dθ` (Simpson on 4096 intervals of θ).
    pub fn across_cdf(&self, points: usize) -> TabulatedCdf {
        let (big, r) = (self.major, self.minor);
        let (lo, hi) = (-(big + r), big + r);
        let pi = std::f64::consts::PI;
        let values = (0..=points)
            .map(|i| {
                let s = lo + (hi - lo) * i as f64 / points.max(1) as f64;
                let f = |th: f64| {
                    let rho = big + r * th.cos();
                    rho / (2.0 * pi * big) * (1.0 - (s / rho).clamp(-1.0, 1.0).acos() / pi)
                };
                simpson(f, -pi, pi, 4096).clamp(0.0, 1.0)
            })
            .collect();
        TabulatedCdf { lo, hi, values }
    }
}

/// A CDF tabulated at equally spaced points of `[lo, hi]` and interpolated linearly
/// (0 below, 1 above).
#[derive(Debug, Clone, PartialEq)]
pub struct TabulatedCdf {
    /// The first point.
    pub lo: f64,
    /// The last point.
    pub hi: f64,
    /// The CDF at `lo + i (hi - lo)/(len - 1)`, non-decreasing from 0 to 1.
    pub values: Vec<f64>,
}

impl TabulatedCdf {
    /// The CDF at `x`.
    pub fn eval(&self, x: f64) -> f64 {
        let n = self.values.len();
        if n < 2 || !(x > self.lo) {
            return if x >= self.hi { 1.0 } else { 0.0 };
        }
        if x >= self.hi {
            return 1.0;
        }
        let u = (x - self.lo) / (self.hi - self.lo) * (n - 1) as f64;
        let i = (u.floor() as usize).min(n - 2);
        let f = u - i as f64;
        self.values[i] + f * (self.values[i + 1] - self.values[i])
    }

    /// The largest difference from another CDF at `points` evenly spread over `[lo, hi]`.
    pub fn max_difference(&self, other: impl Fn(f64) -> f64, points: usize) -> f64 {
        (0..=points)
            .map(|i| {
                let x = self.lo + (self.hi - self.lo) * i as f64 / points.max(1) as f64;
                (self.eval(x) - other(x)).abs()
            })
            .fold(0.0, f64::max)
    }
}

/// Composite Simpson rule of `f` on `[a, b]` with `n` (made even) intervals.
fn simpson(f: impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> f64 {
    let n = n.max(2) & !1;
    let h = (b - a) / n as f64;
    let mut s = f(a) + f(b);
    for k in 1..n {
        s += f(a + k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
    }
    s * h / 3.0
}

/// Each coordinate of a uniform point on a sphere of radius `radius` about `centre_i` (in
/// that coordinate) is uniform on `[centre_i - radius, centre_i + radius]` (Archimedes).
pub fn sphere_coordinate_cdf(centre_i: f64, radius: f64) -> impl Fn(f64) -> f64 {
    move |x| ((x - centre_i + radius) / (2.0 * radius)).clamp(0.0, 1.0)
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
    fn torus_coordinate_marginals_match_a_direct_count() {
        // Area-weighted grid over (θ, φ): the fraction of the area with x ≤ s and z ≤ s.
        let t = TorusTheta {
            major: 1.0,
            minor: 0.4,
        };
        let across = t.across_cdf(2000);
        let n = 1000;
        let mut pts = Vec::new();
        let mut total = 0.0;
        for i in 0..n {
            let th =
                -std::f64::consts::PI + 2.0 * std::f64::consts::PI * (i as f64 + 0.5) / n as f64;
            for j in 0..n {
                let ph = 2.0 * std::f64::consts::PI * (j as f64 + 0.5) / n as f64;
                let w = 1.0 + 0.4 * th.cos();
                pts.push(((1.0 + 0.4 * th.cos()) * ph.cos(), 0.4 * th.sin(), w));
                total += w;
            }
        }
        for s in [-1.2, -0.7, -0.3, 0.0, 0.45, 0.9, 1.3] {
            let x: f64 = pts.iter().filter(|p| p.0 <= s).map(|p| p.2).sum::<f64>() / total;
            assert!(
                (x - across.eval(s)).abs() < 2e-3,
                "x ≤ {s}: {x} vs {}",
                across.eval(s)
            );
        }
        for s in [-0.35, -0.1, 0.0, 0.2, 0.39] {
            let z: f64 = pts.iter().filter(|p| p.1 <= s).map(|p| p.2).sum::<f64>() / total;
            assert!(
                (z - t.axial_cdf(s)).abs() < 2e-3,
                "z ≤ {s}: {z} vs {}",
                t.axial_cdf(s)
            );
        }
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
