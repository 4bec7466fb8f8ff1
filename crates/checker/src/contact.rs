//! Where in time two crossing boundary tets meet: the t-range of their intersection
//! polygon. The polygon is τ_A's section by τ_B's hyperplane (end points of A's edges found
//! from exact signs), clipped by τ_B's four facets; coordinates are then real numbers, used
//! only to report a time, never to decide anything.

use chronotope_kernel::{orient4_i128, LatticePoint};

use chronotope_kernel::float::{cross4, det4, dot4 as dot, sub4 as sub};

type P = [f64; 4];

/// The t-range of τ_A ∩ τ_B for two tets whose boundaries cross, or `None` if the section
/// is empty (then the caller keeps the conservative range).
pub fn crossing_t_range(a: &[LatticePoint; 4], b: &[LatticePoint; 4]) -> Option<(f64, f64)> {
    // 1. τ_A ∩ H_B: vertices on H_B and edge crossings, from exact orientation signs.
    let o: [i128; 4] = a.map(|p| orient4_i128([&b[0], &b[1], &b[2], &b[3], &p]));
    let f = |p: &LatticePoint| p.map(f64::from);
    let mut pts: Vec<P> = Vec::with_capacity(6);
    for i in 0..4 {
        if o[i] == 0 {
            pts.push(f(&a[i]));
        }
        for j in i + 1..4 {
            if (o[i] > 0 && o[j] < 0) || (o[i] < 0 && o[j] > 0) {
                let l = o[i] as f64 / (o[i] - o[j]) as f64;
                let (p, q) = (f(&a[i]), f(&a[j]));
                pts.push([0, 1, 2, 3].map(|k| p[k] + l * (q[k] - p[k])));
            }
        }
    }
    if pts.is_empty() {
        return None;
    }
    // 2. Order the (convex) section around its centroid in its 2-plane.
    let n = pts.len() as f64;
    let c: P = [0, 1, 2, 3].map(|k| pts.iter().map(|p| p[k]).sum::<f64>() / n);
    let u = pts
        .iter()
        .map(|p| sub(p, &c))
        .max_by(|x, y| dot(x, x).total_cmp(&dot(y, y)))?;
    let uu = dot(&u, &u);
    if uu == 0.0 {
        return Some((c[3], c[3]));
    }
    let mut v: P = [0.0; 4];
    let mut best = 0.0;
    for p in &pts {
        let d = sub(p, &c);
        let w: P = [0, 1, 2, 3].map(|k| d[k] - dot(&d, &u) / uu * u[k]);
        if dot(&w, &w) > best {
            best = dot(&w, &w);
            v = w;
        }
    }
    let mut poly: Vec<P> = pts;
    if best > 0.0 {
        poly.sort_by(|p, q| {
            let (dp, dq) = (sub(p, &c), sub(q, &c));
            let ap = dot(&dp, &v).atan2(dot(&dp, &u));
            let aq = dot(&dq, &v).atan2(dot(&dq, &u));
            ap.total_cmp(&aq)
        });
    }
    // 3. Clip by τ_B's facets within H_B: g_i(x) = det[f1−f0, f2−f0, N, x−f0], signed so
    //    that the opposite vertex is inside.
    let bf = b.map(|p| f(&p));
    let e = [
        sub(&bf[1], &bf[0]),
        sub(&bf[2], &bf[0]),
        sub(&bf[3], &bf[0]),
    ];
    let normal: P = cross4(&e[0], &e[1], &e[2]);
    for i in 0..4 {
        let face: Vec<&P> = (0..4).filter(|&j| j != i).map(|j| &bf[j]).collect();
        let (f0, f1, f2) = (face[0], face[1], face[2]);
        let g = |x: &P| det4(&sub(f1, f0), &sub(f2, f0), &normal, &sub(x, f0));
        let s = g(&bf[i]).signum();
        if s == 0.0 {
            return None;
        }
        let inside = |x: &P| s * g(x);
        let mut out = Vec::with_capacity(poly.len() + 2);
        for k in 0..poly.len() {
            let (p, q) = (&poly[k], &poly[(k + 1) % poly.len()]);
            let (gp, gq) = (inside(p), inside(q));
            if gp >= 0.0 {
                out.push(*p);
            }
            if (gp > 0.0 && gq < 0.0) || (gp < 0.0 && gq > 0.0) {
                let l = gp / (gp - gq);
                out.push([0, 1, 2, 3].map(|m| p[m] + l * (q[m] - p[m])));
            }
        }
        poly = out;
        if poly.is_empty() {
            return None;
        }
    }
    let lo = poly.iter().map(|p| p[3]).fold(f64::INFINITY, f64::min);
    let hi = poly.iter().map(|p| p[3]).fold(f64::NEG_INFINITY, f64::max);
    Some((lo, hi))
}
