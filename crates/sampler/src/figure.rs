//! Implicit figures: M constraint functions on R^N (N ≤ 4, M < N) with reflecting walls,
//! and the local geometry every scheme needs (gradients, the Gram matrix
//! `D^{ab} = ∇F^a · ∇F^b`, orthonormal normal and tangent frames, Newton projection).

use super::field::{Field, Q};
use super::SamplerError;
use std::sync::Arc;

/// Most constraints of one figure.
pub const MAX_CONSTRAINTS: usize = 3;

/// A reflecting wall: the figure is sampled only where every wall admits the point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Wall {
    /// `min ≤ q ≤ max` on the first N coordinates (for N = 4 the last is time).
    Box {
        /// Lower corner.
        min: Q,
        /// Upper corner.
        max: Q,
    },
    /// `inner ≤ |p - centre| ≤ outer` in space (the sampling paper's Fig. 1: two concentric
    /// spheres; docs/methods/sampling.md#figures-of-the-paper).
    Shell {
        /// Centre (m).
        centre: [f64; 3],
        /// Inner radius (m), ≥ 0.
        inner: f64,
        /// Outer radius (m), > inner.
        outer: f64,
    },
}

impl Wall {
    /// Whether `q` is admitted (first `n` coordinates).
    pub fn contains(&self, q: &Q, n: usize) -> bool {
        match self {
            Self::Box { min, max } => (0..n).all(|i| q[i] >= min[i] && q[i] <= max[i]),
            Self::Shell {
                centre,
                inner,
                outer,
            } => {
                let r = dist3(q, centre);
                r >= *inner && r <= *outer
            }
        }
    }

    /// `q` mirrored back through the walls it crossed (the explicit scheme's reflection).
    fn reflect(&self, q: &mut Q, n: usize) {
        match self {
            Self::Box { min, max } => {
                for i in 0..n {
                    if q[i] < min[i] {
                        q[i] = 2.0 * min[i] - q[i];
                    } else if q[i] > max[i] {
                        q[i] = 2.0 * max[i] - q[i];
                    }
                }
            }
            Self::Shell {
                centre,
                inner,
                outer,
            } => {
                let r = dist3(q, centre);
                let target = if r > *outer {
                    2.0 * outer - r
                } else if r < *inner {
                    2.0 * inner - r
                } else {
                    return;
                };
                if r > 0.0 {
                    let s = target.max(0.0) / r;
                    for i in 0..3 {
                        q[i] = centre[i] + (q[i] - centre[i]) * s;
                    }
                }
            }
        }
    }

    fn problem(&self, n: usize) -> Option<String> {
        match self {
            Self::Box { min, max } => (0..n)
                .find(|&i| !(min[i].is_finite() && max[i].is_finite() && min[i] < max[i]))
                .map(|i| {
                    let axis = ["x", "y", "z", "t"][i];
                    let unit = if i == 3 { "s" } else { "m" };
                    format!(
                        "box wall: along {axis}, min {} {unit} and max {} {unit}: need finite min < max",
                        min[i],
                        max[i]
                    )
                }),
            Self::Shell {
                centre,
                inner,
                outer,
            } => {
                if let Some(i) = centre.iter().position(|c| !c.is_finite()) {
                    Some(format!(
                        "shell wall: centre ({}, {}, {}) m has a non-finite {} coordinate",
                        centre[0],
                        centre[1],
                        centre[2],
                        ["x", "y", "z"][i]
                    ))
                } else {
                    (!(*inner >= 0.0 && inner < outer && outer.is_finite())).then(|| {
                        format!(
                            "shell wall: inner radius {} m, outer radius {} m: need 0 ≤ inner < outer, finite",
                            *inner,
                            *outer
                        )
                    })
                }
            }
        }
    }
}

fn dist3(q: &Q, c: &[f64; 3]) -> f64 {
    ((q[0] - c[0]).powi(2) + (q[1] - c[1]).powi(2) + (q[2] - c[2]).powi(2)).sqrt()
}

pub(crate) fn dot(a: &Q, b: &Q) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]
}

pub(crate) fn axpy(y: &mut Q, a: f64, x: &Q) {
    for i in 0..4 {
        y[i] += a * x[i];
    }
}

/// An implicit figure `{q ∈ R^N : F^a(q) = 0, a = 1..M}` inside its walls.
#[derive(Debug, Clone)]
pub struct Figure {
    dim: usize,
    fields: Vec<Arc<dyn Field>>,
    walls: Vec<Wall>,
    seed_box: Option<(Q, Q)>,
}

/// Values and gradients of every constraint at one point.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Local {
    pub m: usize,
    pub f: [f64; MAX_CONSTRAINTS],
    pub g: [Q; MAX_CONSTRAINTS],
}

impl Local {
    /// `max_a |F^a| / |∇F^a|`: the first-order distance to the figure (∞ where a gradient
    /// vanishes off the figure).
    pub fn residual(&self) -> f64 {
        (0..self.m)
            .map(|a| {
                let n = norm(&self.g[a]);
                if !self.f[a].is_finite() || !n.is_finite() {
                    f64::INFINITY
                } else if self.f[a] == 0.0 {
                    0.0
                } else if n > 0.0 {
                    self.f[a].abs() / n
                } else {
                    f64::INFINITY
                }
            })
            .fold(0.0, f64::max)
    }

    /// An orthonormal basis of the span of the gradients (Gram-Schmidt), or `None` where
    /// they are (nearly) dependent: a vanishing gradient or tangent constraints.
    pub fn normals(&self) -> Option<[Q; MAX_CONSTRAINTS]> {
        let mut out = [[0.0; 4]; MAX_CONSTRAINTS];
        for a in 0..self.m {
            let len0 = norm(&self.g[a]);
            if !(len0 > 0.0 && len0.is_finite()) {
                return None;
            }
            let mut v = self.g[a].map(|x| x / len0);
            for b in 0..a {
                let c = dot(&v, &out[b]);
                axpy(&mut v, -c, &out[b]);
            }
            let len = dot(&v, &v).sqrt();
            // 1e-9: below this the normal direction is noise and D^{-1} meaningless.
            if !(len > 1e-9) || !len.is_finite() {
                return None;
            }
            out[a] = v.map(|x| x / len);
        }
        Some(out)
    }

    /// The minimum-norm correction `∇F^T D^{-1} b` (`D^{ab} = ∇F^a · ∇F^b`), computed with
    /// unit gradients so that neither huge nor tiny `|∇F|` over- or underflows:
    /// `∇F^T D^{-1} b = Σ_a c_a ĝ_a` with `ĝ_a = ∇F^a/|∇F^a|` and
    /// `c = D̂^{-1} (b_a/|∇F^a|)`. `None` if D is singular to working precision (a vanishing
    /// gradient, tangent constraints) or anything is not finite.
    pub fn correction(&self, b: [f64; MAX_CONSTRAINTS]) -> Option<Q> {
        let m = self.m;
        let mut u = [[0.0; 4]; MAX_CONSTRAINTS];
        let mut sb = [0.0; MAX_CONSTRAINTS];
        for a in 0..m {
            let n = norm(&self.g[a]);
            if !(n > 0.0 && n.is_finite()) {
                return None;
            }
            u[a] = self.g[a].map(|x| x / n);
            sb[a] = b[a] / n;
        }
        let mut d = [[0.0; MAX_CONSTRAINTS]; MAX_CONSTRAINTS];
        for a in 0..m {
            for c in 0..m {
                d[a][c] = dot(&u[a], &u[c]);
            }
        }
        let c = solve_spd(&d, m, sb)?;
        let mut out = [0.0; 4];
        for a in 0..m {
            axpy(&mut out, c[a], &u[a]);
        }
        out.iter().all(|x| x.is_finite()).then_some(out)
    }
}

/// `|v|` without overflow or underflow of the squares.
pub(crate) fn norm(v: &Q) -> f64 {
    let s = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if !(s > 0.0) || !s.is_finite() {
        return s;
    }
    s * v.iter().map(|x| (x / s) * (x / s)).sum::<f64>().sqrt()
}

/// Solves `A x = b` for a symmetric positive definite `m × m` matrix (m ≤ 3) by Cholesky;
/// `None` if a pivot falls below 1e-14 of the largest diagonal entry.
pub(crate) fn solve_spd(
    a: &[[f64; MAX_CONSTRAINTS]; MAX_CONSTRAINTS],
    m: usize,
    b: [f64; MAX_CONSTRAINTS],
) -> Option<[f64; MAX_CONSTRAINTS]> {
    let scale = (0..m).map(|i| a[i][i]).fold(0.0, f64::max);
    if !(scale > 0.0) || !scale.is_finite() {
        return None;
    }
    let mut l = [[0.0; MAX_CONSTRAINTS]; MAX_CONSTRAINTS];
    for i in 0..m {
        for j in 0..=i {
            let mut s = a[i][j];
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            if i == j {
                if !(s > 1e-14 * scale) {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    let mut y = [0.0; MAX_CONSTRAINTS];
    for i in 0..m {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i][k] * y[k];
        }
        y[i] = s / l[i][i];
    }
    let mut x = [0.0; MAX_CONSTRAINTS];
    for i in (0..m).rev() {
        let mut s = y[i];
        for k in i + 1..m {
            s -= l[k][i] * x[k];
        }
        x[i] = s / l[i][i];
    }
    Some(x)
}

/// Solves a general `m × m` system (m ≤ 3) by Gaussian elimination with partial pivoting.
fn solve_general(
    mut a: [[f64; MAX_CONSTRAINTS]; MAX_CONSTRAINTS],
    m: usize,
    mut b: [f64; MAX_CONSTRAINTS],
) -> Option<[f64; MAX_CONSTRAINTS]> {
    let scale = (0..m)
        .flat_map(|i| (0..m).map(move |j| (i, j)))
        .map(|(i, j)| a[i][j].abs())
        .fold(0.0, f64::max);
    if !(scale > 0.0) || !scale.is_finite() {
        return None;
    }
    for c in 0..m {
        let p = (c..m).fold(c, |p, r| if a[r][c].abs() > a[p][c].abs() { r } else { p });
        if !(a[p][c].abs() > 1e-13 * scale) {
            return None;
        }
        a.swap(c, p);
        b.swap(c, p);
        for r in c + 1..m {
            let f = a[r][c] / a[c][c];
            for k in c..m {
                a[r][k] -= f * a[c][k];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = [0.0; MAX_CONSTRAINTS];
    for i in (0..m).rev() {
        let mut s = b[i];
        for k in i + 1..m {
            s -= a[i][k] * x[k];
        }
        x[i] = s / a[i][i];
    }
    Some(x)
}

impl Figure {
    /// The figure `F^a = 0` for the given `fields` in R^`dim`.
    ///
    /// # Errors
    /// [`SamplerError::BadFigure`] unless `2 ≤ dim ≤ 4` and `1 ≤ M < dim`, `M ≤ 3`.
    pub fn new(dim: usize, fields: Vec<Arc<dyn Field>>) -> Result<Self, SamplerError> {
        let m = fields.len();
        if !(2..=4).contains(&dim) || m == 0 || m >= dim || m > MAX_CONSTRAINTS {
            return Err(SamplerError::BadFigure(format!(
                "{m} constraints in R^{dim}: need 2 ≤ N ≤ 4 and 1 ≤ M < N (M ≤ {MAX_CONSTRAINTS})"
            )));
        }
        Ok(Self {
            dim,
            fields,
            walls: Vec::new(),
            seed_box: None,
        })
    }

    /// With a reflecting wall added.
    ///
    /// # Errors
    /// [`SamplerError::BadFigure`] for an empty or non-finite wall.
    pub fn wall(mut self, w: Wall) -> Result<Self, SamplerError> {
        if let Some(p) = w.problem(self.dim) {
            return Err(SamplerError::BadFigure(p));
        }
        self.walls.push(w);
        Ok(self)
    }

    /// With walkers seeded (before projection) uniformly in the box `[min, max]`; without
    /// one, the first box wall is used.
    ///
    /// # Errors
    /// [`SamplerError::BadFigure`] for an empty or non-finite box.
    pub fn seed_box(mut self, min: Q, max: Q) -> Result<Self, SamplerError> {
        if let Some(p) = (Wall::Box { min, max }).problem(self.dim) {
            return Err(SamplerError::BadFigure(format!("seed {p}")));
        }
        self.seed_box = Some((min, max));
        Ok(self)
    }

    /// N, the dimension of the ambient space.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// M, the number of constraints.
    pub fn constraints(&self) -> usize {
        self.fields.len()
    }

    /// The walls.
    pub fn walls(&self) -> &[Wall] {
        &self.walls
    }

    /// The constraint functions.
    pub fn fields(&self) -> &[Arc<dyn Field>] {
        &self.fields
    }

    /// Where walkers are seeded: the seed box, else the first box wall.
    pub fn start_box(&self) -> Option<(Q, Q)> {
        self.seed_box.or_else(|| {
            self.walls.iter().find_map(|w| match w {
                Wall::Box { min, max } => Some((*min, *max)),
                Wall::Shell { .. } => None,
            })
        })
    }

    /// A length scale for guards: the diagonal of the start box, or 1.
    pub fn scale(&self) -> f64 {
        self.start_box()
            .map(|(a, b)| {
                (0..self.dim)
                    .map(|i| (b[i] - a[i]).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .unwrap_or(1.0)
    }

    /// Whether every wall admits `q`.
    pub fn admits(&self, q: &Q) -> bool {
        self.walls.iter().all(|w| w.contains(q, self.dim))
    }

    /// `q` reflected through the walls (each wall once, in order).
    pub(crate) fn reflect(&self, q: &mut Q) {
        for w in &self.walls {
            w.reflect(q, self.dim);
        }
    }

    /// Values and gradients of the constraints at `q`; adds M to `evals`.
    pub(crate) fn local(&self, q: &Q, evals: &mut u64) -> Local {
        let mut l = Local {
            m: self.fields.len(),
            ..Default::default()
        };
        for (a, f) in self.fields.iter().enumerate() {
            let (v, mut g) = f.eval(q);
            for x in g.iter_mut().skip(self.dim) {
                *x = 0.0;
            }
            l.f[a] = v;
            l.g[a] = g;
        }
        *evals += l.m as u64;
        l
    }

    /// The `F^a` values and gradients at `q` (one evaluation of each constraint).
    pub fn eval(&self, q: &Q) -> (Vec<f64>, Vec<Q>) {
        let l = self.local(q, &mut 0);
        (l.f[..l.m].to_vec(), l.g[..l.m].to_vec())
    }

    /// `max_a |F^a(q)| / |∇F^a(q)|`: how far `q` is from the figure, to first order.
    pub fn residual(&self, q: &Q) -> f64 {
        self.local(q, &mut 0).residual()
    }

    /// Newton projection of `y0` onto the figure along the span of `dirs` (the gradients at
    /// the point the move started from, as in Zappa, Holmes-Cerfon & Goodman 2018): solves
    /// `F(y0 + Σ a_b dirs_b) = 0` for `a`. `None` if it has not converged to `tol` (in
    /// `|F|/|∇F|`) after `max_iter` steps, left the finite numbers, or moved further than
    /// `max_move`.
    pub(crate) fn newton(
        &self,
        y0: &Q,
        dirs: &[Q; MAX_CONSTRAINTS],
        tol: f64,
        max_iter: usize,
        max_move: f64,
        evals: &mut u64,
    ) -> Option<(Q, Local)> {
        let m = self.fields.len();
        let mut a = [0.0; MAX_CONSTRAINTS];
        for _ in 0..=max_iter {
            let mut y = *y0;
            for b in 0..m {
                axpy(&mut y, a[b], &dirs[b]);
            }
            if !y.iter().all(|v| v.is_finite()) {
                return None;
            }
            let l = self.local(&y, evals);
            if l.residual() <= tol {
                return Some((y, l));
            }
            let mut j = [[0.0; MAX_CONSTRAINTS]; MAX_CONSTRAINTS];
            for r in 0..m {
                for c in 0..m {
                    j[r][c] = dot(&l.g[r], &dirs[c]);
                }
            }
            let delta = solve_general(j, m, l.f.map(|v| -v))?;
            for b in 0..m {
                a[b] += delta[b];
            }
            let mut moved = [0.0; 4];
            for b in 0..m {
                axpy(&mut moved, a[b], &dirs[b]);
            }
            if !(dot(&moved, &moved).sqrt() <= max_move) {
                return None;
            }
        }
        None
    }

    /// Gauss-Newton from an arbitrary point: `q ← q - ∇F^T D^{-1} F` (the minimum-norm
    /// step), each step capped at `max_step`, until `|F|/|∇F| ≤ tol`. Used to put walkers
    /// on the figure wherever they start.
    pub(crate) fn pull_onto(
        &self,
        mut q: Q,
        tol: f64,
        max_iter: usize,
        max_step: f64,
        evals: &mut u64,
    ) -> Option<Q> {
        for _ in 0..max_iter {
            let l = self.local(&q, evals);
            if l.residual() <= tol {
                return Some(q);
            }
            let step = l.correction(l.f)?.map(|x| -x);
            let len = dot(&step, &step).sqrt();
            let s = if len > max_step { max_step / len } else { 1.0 };
            axpy(&mut q, s, &step);
            if !q.iter().all(|v| v.is_finite()) {
                return None;
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spd_and_general_solvers_agree() {
        let a = [[4.0, 1.0, 0.5], [1.0, 3.0, 0.2], [0.5, 0.2, 2.0]];
        let b = [1.0, -2.0, 0.5];
        let x = solve_spd(&a, 3, b).unwrap();
        let y = solve_general(a, 3, b).unwrap();
        for i in 0..3 {
            assert!((x[i] - y[i]).abs() < 1e-12);
            let r: f64 = (0..3).map(|k| a[i][k] * x[k]).sum();
            assert!((r - b[i]).abs() < 1e-12);
        }
        assert!(solve_spd(&[[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0; 3]], 2, b).is_none());
    }
}
