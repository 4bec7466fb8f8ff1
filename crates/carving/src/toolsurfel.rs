//! The seed's tool surfels (§4.2.2, eqs. 3-5), kept as a cross-check of the analytic
//! classification the model uses.
//!
//! The seed samples the faces of the solid a tool sweeps between two frames with surfels and
//! classifies each tool surfel `x_t` against the workpiece's BOUND surfels `(x_b, n_b)`:
//!
//! - eq. 3: INSIDE the workpiece iff `n_b · (x_b - x_t) > 0` for every BOUND surfel;
//! - eq. 4: `d_t = min |x_b - x_t|` over them (the seed prints `|x_b - n_b|`, a typo: a
//!   distance between a position and a normal means nothing);
//! - eq. 5: an INSIDE tool surfel with `0 < d_t < d_s` is BOUND (on the new surface's rim).
//!
//! The tool surfels inside the workpiece are the seed's new cut surface. The model instead
//! classifies the workpiece's grid points against the tool's swept solid exactly (eq. 2 with
//! the exact translation sweep, [`Workpiece::carve`]) and puts the cut surface's surfels on
//! the swept solid at the exposed points: the same surface (the tool's boundary inside the
//! material), sampled where the material is rather than where the tool is. This module
//! computes the seed's way so that the two can be compared ([`sweep_surfels`],
//! [`Workpiece::classify_eq3`], and the model's view [`Workpiece::classify_grid`]);
//! `chronotope bench carve --accuracy` prints the agreement of each with the exact answer
//! and their cost. Eq. 3 as written holds only for a convex workpiece: every BOUND surfel's
//! plane must have the whole workpiece behind it, which a groove breaks (material beside a
//! groove lies in front of the far wall's surfels). Its cost is one dot product per BOUND
//! surfel per tool surfel, where the grid costs one lookup.

use super::math::{add, cross, dot, norm, scale, sub, Vec3};
use super::sweep::Sweep;
use super::tool::Tool;
use super::workpiece::{Workpiece, OUTSIDE};
use super::{CarveError, ToolPose};

/// Most tool surfels [`sweep_surfels`] builds for one move (a cross-check, not a runtime
/// path): 2^20 of 48 bytes, 48 MiB.
pub const MAX_TOOL_SURFELS: usize = 1 << 20;

/// A tool surfel: a sample of the swept solid's boundary (m) and its outward normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolSurfel {
    /// Position (m).
    pub position: Vec3,
    /// Outward unit normal of the swept solid there.
    pub normal: Vec3,
}

/// A tool surfel's class against the workpiece (seed eqs. 3-5).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ToolClass {
    /// In the air: not part of the cut.
    Outside,
    /// Inside the material within `d_s` of its surface: the rim of the cut.
    Bound,
    /// Inside the material.
    Inside,
}

/// Surfels on the boundary of the solid `tool` sweeps translating from `from` to `to` (at
/// `from`'s orientation), about `spacing` apart: each face of the tool sampled every
/// `spacing` at sweep parameters `s = 0, spacing/|d|, ..., 1`, kept where it lies on the
/// swept solid's boundary (within 1e-9 spacing).
///
/// # Errors
/// [`CarveError::Workpiece`] for a spacing that is not positive, or a sampling that would
/// exceed [`MAX_TOOL_SURFELS`] (counted before sampling).
pub fn sweep_surfels(
    tool: &Tool,
    from: &ToolPose,
    to: &ToolPose,
    spacing: f64,
) -> Result<Vec<ToolSurfel>, CarveError> {
    if !(spacing.is_finite() && spacing > 0.0) {
        return Err(CarveError::Workpiece(format!(
            "tool surfel spacing {spacing} is not a positive length"
        )));
    }
    let rot = from.rotation;
    let d = sub(to.position, from.position);
    let steps = (norm(d) / spacing).ceil().max(1.0);
    let sweep = Sweep::new(tool, &rot, from.position, d);
    // Each face: an in-plane basis and the extent of its corners in it.
    let mut plans = Vec::new();
    let mut total = 0f64;
    for &(n, o) in tool.faces() {
        let corners: Vec<Vec3> = tool
            .vertices()
            .iter()
            .copied()
            .filter(|&v| (dot(n, v) - o).abs() < 1e-9)
            .collect();
        let helper = if n[0].abs() < 0.9 {
            [1.0, 0.0, 0.0]
        } else {
            [0.0, 1.0, 0.0]
        };
        let u = {
            let c = cross(n, helper);
            scale(c, 1.0 / norm(c))
        };
        let v = cross(n, u);
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for c in &corners {
            for (a, b) in [u, v].iter().enumerate() {
                lo[a] = lo[a].min(dot(*c, *b));
                hi[a] = hi[a].max(dot(*c, *b));
            }
        }
        let cells = [0, 1].map(|a| ((hi[a] - lo[a]) / spacing).floor() + 1.0);
        total += cells[0] * cells[1] * (steps + 1.0);
        plans.push((n, o, u, v, lo, cells));
    }
    if !(total <= MAX_TOOL_SURFELS as f64) {
        return Err(CarveError::Workpiece(format!(
            "{total:.0} tool surfel samples for one move: at most {MAX_TOOL_SURFELS} \
             (MAX_TOOL_SURFELS); use a coarser spacing or a shorter move"
        )));
    }
    let mut out = Vec::new();
    for (n, o, u, v, lo, cells) in plans {
        let nw = rot.rotate(n);
        for a in 0..cells[0] as usize {
            for b in 0..cells[1] as usize {
                let q = add(
                    scale(n, o),
                    add(
                        scale(u, lo[0] + (a as f64 + 0.5) * spacing),
                        scale(v, lo[1] + (b as f64 + 0.5) * spacing),
                    ),
                );
                if !tool.contains(q, 1e-12) {
                    continue;
                }
                let w = rot.rotate(q);
                for j in 0..=steps as usize {
                    let x = add(add(from.position, w), scale(d, j as f64 / steps));
                    if sweep.value(x).0 >= -1e-9 * spacing {
                        out.push(ToolSurfel {
                            position: x,
                            normal: nw,
                        });
                    }
                }
            }
        }
    }
    Ok(out)
}

impl Workpiece {
    /// Seed eqs. 3-5 as written: `x` is INSIDE iff `n_b · (x_b - x) > 0` for every surfel
    /// of the workpiece, BOUND if moreover the nearest surfel is closer than `d_s`. One pass
    /// over all the surfels.
    pub fn classify_eq3(&self, x: Vec3, d_s: f64) -> ToolClass {
        let mut inside = true;
        let mut d_t = f64::INFINITY;
        for s in &self.surfels {
            let xb = s.position.map(f64::from);
            let nb = s.normal.map(f64::from);
            let r = sub(xb, x);
            if dot(nb, r) <= 0.0 {
                inside = false;
                break;
            }
            d_t = d_t.min(norm(r));
        }
        match (inside, d_t < d_s) {
            (false, _) => ToolClass::Outside,
            (true, true) => ToolClass::Bound,
            (true, false) => ToolClass::Inside,
        }
    }

    /// The model's view of `x`: the flag of the grid point nearest to it (material or
    /// not; off the grid is air), BOUND if a surfel of the points within two spacings is
    /// closer than `d_s`. A handful of lookups.
    pub fn classify_grid(&self, x: Vec3, d_s: f64) -> ToolClass {
        let mut c = [0usize; 3];
        for a in 0..3 {
            let i = ((x[a] - self.origin[a]) / self.h).round();
            if !(i >= 0.0 && i < self.dims[a] as f64) {
                return ToolClass::Outside;
            }
            c[a] = i as usize;
        }
        if self.flags[self.index(c[0], c[1], c[2])] == OUTSIDE {
            return ToolClass::Outside;
        }
        let mut near = false;
        self.around(c, 2, |slot| {
            let p = self.surfels[slot].position.map(f64::from);
            near |= norm(sub(p, x)) < d_s;
        });
        if near {
            ToolClass::Bound
        } else {
            ToolClass::Inside
        }
    }
}
