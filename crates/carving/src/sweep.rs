//! Removing the solid a tool sweeps between two poses (seed §4.2-4.3, eqs. 2-7;
//! docs/methods/carving.md#what-the-project-does-instead).
//!
//! For a translation by `d` from `c0`, the tool's faces `n_k · x <= o_k` become, for a point
//! `p` and the sweep parameter `s ∈ [0, 1]`, `a_k(p) - s b_k <= 0` with
//! `a_k = n_k · (p - c0) - o_k` and `b_k = n_k · d`; `p` is in the swept solid iff these
//! intervals of `s` have a common point. Along a grid row `p = p0 + i h x̂` the `a_k` are
//! linear in `i`, so eliminating `s` (Fourier-Motzkin on two unknowns) gives the exact range
//! of `i` inside: each row costs a few dozen flops plus the points it removes. The same test
//! with `<= d_s` gives the seed's BOUND band (eq. 2); `f(p) = min_s max_k (a_k - s b_k)` is
//! the value of eq. 2, and the face attaining it the cutting face whose normal a newly
//! exposed point takes (§5.2).

use super::math::{add, dot, lerp, norm, scale, sub, Vec3};
use super::tool::{Tool, ToolKind};
use super::workpiece::{
    Workpiece, BOUND, COLOUR_BLOCK, COLOUR_CHISEL, COLOUR_EDGE, COLOUR_KNIFE, NO_SURFEL, OUTSIDE,
};
use super::{CarveError, CutStats, ToolPose};

/// Most rotation substeps of one move.
pub const MAX_SUBSTEPS: u64 = 4096;

/// Most grid rows the sweeps of one pose may visit: the rows crossing the bounding box of
/// each rotation substep's sweep (for the chisel, also that box two points wider, where
/// its edge band is resampled), plus the layer ahead of the tool and the `section` force's
/// window. Each row costs the
/// constraint elimination of the tool's faces: about 90 ns a row including the points it
/// removes (measured in the test profile, opt-level 2, with a 0.3 m knife turning through a
/// 64³ grid: 2040 substeps, at most 8.4M rows, 0.73 s), so 2^22 rows bound a pose to about
/// 0.4 s.
/// A 20 × 10 spacing knife moving a few spacings visits a few hundred rows.
pub const MAX_SWEEP_ROWS_PER_POSE: u64 = 1 << 22;

/// Most grid points in the bounding boxes of one pose's sweeps (the points a pose may
/// test): 2^27 ≈ 134M, eight 256³ blocks; at about a nanosecond a point (an estimate, not
/// measured alone) some 0.1 s.
pub const MAX_SWEEP_POINTS_PER_POSE: u64 = 1 << 27;

/// Index ranges `[(lo, hi); 3]` (inclusive) of the grid points in a sweep's bounding box.
type GridBox = [(usize, usize); 3];

fn box_rows(b: &GridBox) -> u64 {
    (b[1].1 - b[1].0 + 1) as u64 * (b[2].1 - b[2].0 + 1) as u64
}

fn box_points(b: &GridBox) -> u64 {
    box_rows(b) * (b[0].1 - b[0].0 + 1) as u64
}

/// A translation sweep of the tool at one orientation, in world coordinates.
#[derive(Clone, Copy)]
pub(crate) struct Sweep {
    /// `(world normal, offset at s = 0)`: `n · x <= off` at the start pose.
    faces: [(Vec3, f64); 8],
    m: usize,
    /// `n_k · d`.
    b: [f64; 8],
    /// Face `k` of the tool's face list is slanted (a chisel side).
    slanted: [bool; 8],
    d: Vec3,
    /// For a box tool (the knife): start centre, world axes and half-extents, for the exact
    /// closest point of the swept solid.
    boxed: Option<(Vec3, [Vec3; 3], Vec3)>,
}

impl Sweep {
    pub(crate) fn new(tool: &Tool, rot: &super::Quat, c0: Vec3, d: Vec3) -> Self {
        let mut faces = [([0.0; 3], 0.0); 8];
        let mut b = [0.0; 8];
        let mut slanted = [false; 8];
        let m = tool.faces().len();
        for (k, &(n, o)) in tool.faces().iter().enumerate() {
            let nw = rot.rotate(n);
            faces[k] = (nw, o + dot(nw, c0));
            b[k] = dot(nw, d);
            slanted[k] = tool.kind() == ToolKind::Chisel && n[0] == 0.0 && n[2] < 0.0;
        }
        let boxed = (tool.kind() == ToolKind::Knife).then(|| {
            let f = tool.faces();
            (
                c0,
                [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]].map(|a| rot.rotate(a)),
                [f[0].1, f[2].1, f[4].1],
            )
        });
        Self {
            faces,
            m,
            b,
            slanted,
            d,
            boxed,
        }
    }

    /// For a box tool, the closest point of the swept solid to `p` (outside it) and the
    /// distance: `min over s of dist(p - s d, box)`, convex in `s`, by golden-section search.
    fn closest_on_box_sweep(&self, p: Vec3) -> Option<(Vec3, f64)> {
        let (c0, ax, half) = self.boxed?;
        let q = sub(p, c0);
        let local = |s: f64| {
            let r = sub(q, scale(self.d, s));
            [0, 1, 2].map(|a| dot(ax[a], r))
        };
        let dist2 = |s: f64| {
            let l = local(s);
            (0..3)
                .map(|a| (l[a].abs() - half[a]).max(0.0).powi(2))
                .sum::<f64>()
        };
        let mid = golden_section_min(dist2, 48);
        let mut best = (dist2(mid), mid);
        for s in [0.0, 1.0] {
            let v = dist2(s);
            if v < best.0 {
                best = (v, s);
            }
        }
        let s = best.1;
        let l = local(s);
        let mut c = add(c0, scale(self.d, s));
        for k in 0..3 {
            c = add(c, scale(ax[k], l[k].clamp(-half[k], half[k])));
        }
        Some((c, best.0.sqrt()))
    }

    /// `f(p) = min over s in [0,1] of max_k (a_k - s b_k)`, the `s` and the face attaining it.
    pub(crate) fn value(&self, p: Vec3) -> (f64, f64, usize) {
        let mut a = [0.0; 8];
        for k in 0..self.m {
            a[k] = dot(self.faces[k].0, p) - self.faces[k].1;
        }
        let eval = |s: f64| {
            let mut best = (f64::NEG_INFINITY, 0usize);
            for k in 0..self.m {
                let v = a[k] - s * self.b[k];
                if v > best.0 {
                    best = (v, k);
                }
            }
            best
        };
        let mut best = {
            let (v, k) = eval(0.0);
            (v, 0.0, k)
        };
        let mut try_s = |s: f64| {
            let (v, k) = eval(s);
            if v < best.0 {
                best = (v, s, k);
            }
        };
        try_s(1.0);
        for k in 0..self.m {
            for l in k + 1..self.m {
                let db = self.b[k] - self.b[l];
                if db.abs() > 1e-300 {
                    let s = (a[k] - a[l]) / db;
                    if s > 0.0 && s < 1.0 {
                        try_s(s);
                    }
                }
            }
        }
        best
    }
}

/// The real range `[lo, hi]` of `i` for which some `s ∈ [0, 1]` satisfies every constraint
/// `ci · i + cs · s <= c0`, or `None`.
fn row_range(cons: &[(f64, f64, f64)]) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
    let mut bound = |ci: f64, c0: f64| -> bool {
        if ci > 0.0 {
            hi = hi.min(c0 / ci);
        } else if ci < 0.0 {
            lo = lo.max(c0 / ci);
        } else if c0 < 0.0 {
            return false;
        }
        true
    };
    for &(ci, cs, c0) in cons {
        if cs == 0.0 {
            if !bound(ci, c0) {
                return None;
            }
            continue;
        }
        if cs < 0.0 {
            continue;
        }
        // x bounds s from above; pair it with every constraint bounding s from below.
        for &(cj, csj, c0j) in cons {
            if csj < 0.0 {
                let (lp, ln) = (1.0 / cs, -1.0 / csj);
                if !bound(lp * ci + ln * cj, lp * c0 + ln * c0j) {
                    return None;
                }
            }
        }
    }
    (lo <= hi).then_some((lo, hi))
}

impl Workpiece {
    /// Removes the solid `tool` sweeps from pose `from` to pose `to`; returns what it removed.
    ///
    /// Exact for a translation; a rotation is cut in substeps, each a translation at the
    /// substep's middle orientation, so small that rotation angle x tool radius < spacing/2
    /// (no point is skipped between substeps by more than a quarter spacing). The workpiece
    /// is unchanged on error.
    ///
    /// # Errors
    /// [`CarveError::TooManySubsteps`] if the rotation would need more than 4096 substeps;
    /// [`CarveError::TooMuchWork`] if the substeps' sweeps (and the layer ahead) would visit
    /// more than [`MAX_SWEEP_ROWS_PER_POSE`] grid rows or hold more than
    /// [`MAX_SWEEP_POINTS_PER_POSE`] points in their bounding boxes — both counted before
    /// anything is cut.
    pub fn carve(
        &mut self,
        tool: &Tool,
        from: &ToolPose,
        to: &ToolPose,
    ) -> Result<CutStats, CarveError> {
        let angle = from.rotation.angle_to(&to.rotation);
        let need = (angle * tool.radius() / (self.h / 2.0)).ceil().max(1.0);
        if !(need <= MAX_SUBSTEPS as f64) {
            return Err(CarveError::TooManySubsteps {
                angle_deg: angle.to_degrees(),
                substeps: if need.is_finite() {
                    need as u64
                } else {
                    u64::MAX
                },
                max: MAX_SUBSTEPS,
            });
        }
        let n = need as u32;
        // The work of the whole pose, counted before anything is cut.
        let (mut rows, mut points) = (0u64, 0u64);
        let mut count = |b: Option<GridBox>| {
            if let Some(b) = b {
                rows = rows.saturating_add(box_rows(&b));
                points = points.saturating_add(box_points(&b));
            }
        };
        for j in 0..n {
            let (t0, t1) = (f64::from(j) / f64::from(n), f64::from(j + 1) / f64::from(n));
            let rot = from.rotation.slerp(&to.rotation, (t0 + t1) / 2.0);
            let c0 = lerp(from.position, to.position, t0);
            let c1 = lerp(from.position, to.position, t1);
            let b = self.sweep_box(tool, &rot, c0, c1);
            count(b);
            if tool.kind() == ToolKind::Chisel {
                count(b.map(|b| Self::band_box(b, self.dims)));
            }
        }
        let motion = sub(to.position, from.position);
        count(self.ahead_box(tool, to, motion));
        count(self.section_box(tool, to, motion));
        let too_much = |what, got, unit, max, limit| CarveError::TooMuchWork {
            what,
            got,
            unit,
            max,
            limit,
            travel_m: norm(motion),
            angle_deg: angle.to_degrees(),
        };
        if rows > MAX_SWEEP_ROWS_PER_POSE {
            return Err(too_much(
                "rows of",
                rows,
                "rows",
                MAX_SWEEP_ROWS_PER_POSE,
                "MAX_SWEEP_ROWS_PER_POSE",
            ));
        }
        if points > MAX_SWEEP_POINTS_PER_POSE {
            return Err(too_much(
                "points in bounding boxes of",
                points,
                "points",
                MAX_SWEEP_POINTS_PER_POSE,
                "MAX_SWEEP_POINTS_PER_POSE",
            ));
        }
        let mut stats = CutStats {
            substeps: n,
            travel: norm(sub(to.position, from.position)) + angle * tool.radius(),
            ..CutStats::default()
        };
        for j in 0..n {
            let (t0, t1) = (f64::from(j) / f64::from(n), f64::from(j + 1) / f64::from(n));
            let rot = from.rotation.slerp(&to.rotation, (t0 + t1) / 2.0);
            let c0 = lerp(from.position, to.position, t0);
            let c1 = lerp(from.position, to.position, t1);
            let sweep = Sweep::new(tool, &rot, c0, sub(c1, c0));
            self.carve_translation(tool, &rot, c0, c1, &sweep, &mut stats);
        }
        stats.ahead = self.material_ahead(tool, to, motion);
        stats.ahead_area = self.section_ahead(tool, to, motion);
        Ok(stats)
    }

    /// The grid index box holding the translation sweep of `tool` at `rot` from `c0` to
    /// `c1`, or `None` if it misses the grid (or is not finite).
    fn sweep_box(&self, tool: &Tool, rot: &super::Quat, c0: Vec3, c1: Vec3) -> Option<GridBox> {
        let h = self.h;
        let mut bmin = [f64::INFINITY; 3];
        let mut bmax = [f64::NEG_INFINITY; 3];
        for &v in tool.vertices() {
            let w = rot.rotate(v);
            for c in [c0, c1] {
                for a in 0..3 {
                    bmin[a] = bmin[a].min(c[a] + w[a]);
                    bmax[a] = bmax[a].max(c[a] + w[a]);
                }
            }
        }
        let mut range = [(0usize, 0usize); 3];
        for a in 0..3 {
            let lo = ((bmin[a] - self.origin[a]) / h).ceil().max(0.0);
            let hi = ((bmax[a] - self.origin[a]) / h)
                .floor()
                .min(self.dims[a] as f64 - 1.0);
            if !(lo <= hi) {
                return None;
            }
            range[a] = (lo as usize, hi as usize);
        }
        Some(range)
    }

    /// The sweep of the layer ahead of the tool at `pose` ([`Workpiece::material_ahead`]):
    /// its end point and index box.
    fn ahead_box(&self, tool: &Tool, pose: &ToolPose, motion: Vec3) -> Option<GridBox> {
        let len = norm(motion);
        if !(len > 1e-12) {
            return None;
        }
        let c1 = add(pose.position, scale(motion, self.h / len));
        self.sweep_box(tool, &pose.rotation, pose.position, c1)
    }

    /// The grid points of layer `k` (within `range`) inside the translation sweep, as row
    /// spans `(row start, i0, i1)`. A layer at a time, so the spans kept are at most one
    /// per row of a layer (≤ 4096).
    fn layer_spans(
        &self,
        range: &GridBox,
        k: usize,
        sweep: &Sweep,
        spans: &mut Vec<(usize, usize, usize)>,
    ) {
        spans.clear();
        for j in range[1].0..=range[1].1 {
            let Some((lo, hi)) = self.row_interval(j, k, sweep) else {
                continue;
            };
            let i0 = lo.ceil().max(range[0].0 as f64);
            let i1 = hi.floor().min(range[0].1 as f64);
            if i0 <= i1 {
                spans.push((self.index(0, j, k), i0 as usize, i1 as usize));
            }
        }
    }

    /// The real range `[lo, hi]` of `i` (in spacings along x, unclipped) for which the
    /// line through the points `(·, j, k)` is inside the translation sweep, or `None`.
    fn row_interval(&self, j: usize, k: usize, sweep: &Sweep) -> Option<(f64, f64)> {
        self.chord(self.point(0, j, k), sweep)
    }

    /// The real range `[lo, hi]` of `i` for which `p0 + i h x̂` is inside the translation
    /// sweep, or `None`.
    fn chord(&self, p0: Vec3, sweep: &Sweep) -> Option<(f64, f64)> {
        let h = self.h;
        let m = sweep.m;
        let mut cons = [(0.0, 0.0, 0.0); 10];
        cons[m] = (0.0, -1.0, 0.0); // s >= 0
        cons[m + 1] = (0.0, 1.0, 1.0); // s <= 1
        for (q, &(nw, off)) in sweep.faces[..m].iter().enumerate() {
            // a_q(i) - s b_q <= 0  with  a_q(i) = n·p0 - off + i n_x h.
            let alpha = dot(nw, p0) - off;
            // A face parallel to the move: its constraint does not involve s.
            let b = if sweep.b[q].abs() < 1e-12 * h {
                0.0
            } else {
                sweep.b[q]
            };
            cons[q] = (nw[0] * h, -b, -alpha);
        }
        row_range(&cons[..m + 2])
    }

    /// The window the `section` force reads ([`Workpiece::section_ahead`]): the tool at
    /// `pose` swept along `motion` by one and a half spacings (`A`) and by half a spacing
    /// (`B`); the window is `A \ B`. Their start, translations and `A`'s index box.
    fn section_window(
        &self,
        tool: &Tool,
        pose: &ToolPose,
        motion: Vec3,
    ) -> Option<(Vec3, Vec3, Vec3, GridBox)> {
        let len = norm(motion);
        if !(len > 1e-12) {
            return None;
        }
        let u = scale(motion, 1.0 / len);
        let c0 = pose.position;
        let (da, db) = (scale(u, 1.5 * self.h), scale(u, 0.5 * self.h));
        // The index box widened by one point: a point whose cell overlaps the window may
        // lie outside it.
        let h = self.h;
        let (lo, hi) = tool.vertices().iter().fold(
            ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
            |(mut lo, mut hi), &v| {
                let w = pose.rotation.rotate(v);
                for c in [c0, add(c0, da)] {
                    for a in 0..3 {
                        lo[a] = lo[a].min(c[a] + w[a] - h);
                        hi[a] = hi[a].max(c[a] + w[a] + h);
                    }
                }
                (lo, hi)
            },
        );
        let mut b = [(0usize, 0usize); 3];
        for a in 0..3 {
            let l = ((lo[a] - self.origin[a]) / h).ceil().max(0.0);
            let u = ((hi[a] - self.origin[a]) / h)
                .floor()
                .min(self.dims[a] as f64 - 1.0);
            if !(l <= u) {
                return None;
            }
            b[a] = (l as usize, u as usize);
        }
        Some((c0, da, db, b))
    }

    fn section_box(&self, tool: &Tool, pose: &ToolPose, motion: Vec3) -> Option<GridBox> {
        self.section_window(tool, pose, motion).map(|w| w.3)
    }

    /// Material points the tool at `pose` would meet in its next spacing of travel along
    /// `motion`: the layer in front of it. Times spacing^2 it is the cut cross-section,
    /// sampled without the stepping of the points removed per pose.
    pub fn material_ahead(&mut self, tool: &Tool, pose: &ToolPose, motion: Vec3) -> u64 {
        let Some(range) = self.ahead_box(tool, pose, motion) else {
            return 0;
        };
        let len = norm(motion);
        let c1 = add(pose.position, scale(motion, self.h / len));
        let sweep = Sweep::new(tool, &pose.rotation, pose.position, sub(c1, pose.position));
        let mut spans = std::mem::take(&mut self.spans);
        let mut n = 0u64;
        for k in range[2].0..=range[2].1 {
            self.layer_spans(&range, k, &sweep, &mut spans);
            for &(row, i0, i1) in &spans {
                n += self.flags[row + i0..=row + i1]
                    .iter()
                    .filter(|&&f| f != OUTSIDE)
                    .count() as u64;
            }
        }
        self.spans = spans;
        n
    }

    /// The cut cross-section ahead of the tool at `pose` moving along `motion` (m²), with
    /// sub-voxel weights: the material in the window from half a spacing to one and a half
    /// spacings ahead of the tool, `Σ w_p h³ / h`, where `w_p` is the length (in spacings)
    /// of the window's chords along x that falls in point `p`'s cell `[i - ½, i + ½]`,
    /// averaged over two lines through the cell (at ∓¼ spacing in y and z).
    ///
    /// Counting the points inside a one-spacing layer ([`Workpiece::material_ahead`]) is
    /// exact along a grid axis but jumps with the lattice phase on a diagonal: a point
    /// enters or leaves whole. Here each row contributes the length of its chords through
    /// the window, which move continuously with the tool. The window is the tool swept
    /// ahead by 1.5 spacings less the tool swept ahead by 0.5 (on each row, the chord of
    /// the first less that of the second); it starts half a spacing ahead so that no cell
    /// of a point the move already removed reaches into it (a removed point's cell ends at
    /// most half a spacing along x, so at most half a spacing along the motion, past the
    /// tool). Costs four chords per row of the window, where `material_ahead` costs one.
    pub fn section_ahead(&mut self, tool: &Tool, pose: &ToolPose, motion: Vec3) -> f64 {
        let Some((c0, da, db, range)) = self.section_window(tool, pose, motion) else {
            return 0.0;
        };
        let a = Sweep::new(tool, &pose.rotation, c0, da);
        let b = Sweep::new(tool, &pose.rotation, c0, db);
        let q = self.h / 4.0;
        let mut cells = 0.0f64;
        for k in range[2].0..=range[2].1 {
            for j in range[1].0..=range[1].1 {
                // The chords of two sub-rows of the row's cell, at (-h/4, -h/4) and
                // (h/4, h/4) across it in (y, z): the cell's share of the window across the
                // row, not only at its centre line.
                let base = self.point(0, j, k);
                let mut chords = [(None, None); 2];
                let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
                for (c, (dy, dz)) in [(-q, -q), (q, q)].into_iter().enumerate() {
                    let p0 = [base[0], base[1] + dy, base[2] + dz];
                    if let Some(ca) = self.chord(p0, &a) {
                        lo = lo.min(ca.0);
                        hi = hi.max(ca.1);
                        chords[c] = (Some(ca), self.chord(p0, &b));
                    }
                }
                // Points whose cells [i - 1/2, i + 1/2] overlap [lo, hi].
                let i0 = (lo + 0.5).floor().max(range[0].0 as f64);
                let i1 = (hi - 0.5).ceil().min(range[0].1 as f64);
                if !(i0 <= i1) {
                    continue;
                }
                let row = self.index(0, j, k);
                for i in i0 as usize..=i1 as usize {
                    if self.flags[row + i] == OUTSIDE {
                        continue;
                    }
                    let x = i as f64;
                    let overlap = |c: Option<(f64, f64)>| {
                        c.map_or(0.0, |(l, u)| ((x + 0.5).min(u) - (x - 0.5).max(l)).max(0.0))
                    };
                    for &(ca, cb) in &chords {
                        cells += (overlap(ca) - overlap(cb)) / 2.0;
                    }
                }
            }
        }
        cells * self.h * self.h
    }

    fn carve_translation(
        &mut self,
        tool: &Tool,
        rot: &super::Quat,
        c0: Vec3,
        c1: Vec3,
        sweep: &Sweep,
        stats: &mut CutStats,
    ) {
        self.removed.clear();
        let Some(range) = self.sweep_box(tool, rot, c0, c1) else {
            return;
        };
        let mut spans = std::mem::take(&mut self.spans);
        for k in range[2].0..=range[2].1 {
            self.layer_spans(&range, k, sweep, &mut spans);
            for &(row, i0, i1) in &spans {
                for idx in row + i0..=row + i1 {
                    if self.flags[idx] == OUTSIDE {
                        continue;
                    }
                    self.cut_point(idx, stats);
                }
            }
        }
        self.spans = spans;
        if self.removed.is_empty() {
            return;
        }
        // §5.2: material 6-neighbours of removed points are on the surface now; they lie
        // within one spacing of the swept solid (the seed's BOUND band with d_s = spacing)
        // and take the normal of the cutting face nearest to them.
        let colour = match tool.kind() {
            ToolKind::Knife => COLOUR_KNIFE,
            ToolKind::Chisel => COLOUR_CHISEL,
        };
        let removed = std::mem::take(&mut self.removed);
        for &r in &removed {
            let (nbs, n) = self.neighbours6(r as usize);
            for &nb in &nbs[..n] {
                if self.flags[nb] != OUTSIDE {
                    self.expose(nb, sweep, colour, stats);
                }
            }
        }
        self.removed = removed;
        if tool.kind() == ToolKind::Chisel {
            self.resample_band(&range, sweep, stats);
        }
    }

    /// The index box the chisel's edge band is looked for in ([`Workpiece::resample_band`]):
    /// the sweep's, two points wider each way.
    fn band_box(range: GridBox, dims: [usize; 3]) -> GridBox {
        [0, 1, 2].map(|a| {
            (
                range[a].0.saturating_sub(2),
                (range[a].1 + 2).min(dims[a] - 1),
            )
        })
    }

    /// Eq. 2's BOUND band for eq. 6: the surfels of the old surface within the band
    /// `0 < f <= 1.5 spacings` of the sweep's slanted faces that the cut did not expose
    /// (no 6-neighbour removed) are slid onto the edge too, if they are within 0.7 spacing
    /// of it (their own disc then still covers where they were: the square lattice's discs,
    /// √3/2 spacing wide, leave a hole of 0.13 spacing around a moved one). Without this
    /// only exposed points are resampled, and on a cut diagonal to the grid those are sparse
    /// along the edge (at 30°, the points within 0.37 spacing of it; at 45°, none at some
    /// offsets). Rows of the sweep's index box widened by two points, with the sweep's faces
    /// pushed out by 1.5 spacings.
    fn resample_band(&mut self, range: &GridBox, sweep: &Sweep, stats: &mut CutStats) {
        let band = Self::band_box(*range, self.dims);
        let mut grown = *sweep;
        for k in 0..grown.m {
            grown.faces[k].1 += 1.5 * self.h;
        }
        let mut spans = std::mem::take(&mut self.spans);
        for k in band[2].0..=band[2].1 {
            self.layer_spans(&band, k, &grown, &mut spans);
            for &(row, i0, i1) in &spans {
                for idx in row + i0..=row + i1 {
                    if self.flags[idx] != BOUND {
                        continue;
                    }
                    let slot = self.surfel_of[idx];
                    if slot == NO_SURFEL {
                        continue;
                    }
                    let colour = self.surfels[slot as usize].colour;
                    let c = self.coords(idx);
                    // An edge surfel stays; a chisel face's surfel is no old surface unless
                    // the point lies on the block's face ([`Workpiece::uncut_face`]).
                    let on_block_face = (0..3).any(|a| c[a] == 0 || c[a] + 1 == self.dims[a]);
                    if colour == COLOUR_EDGE || (colour == COLOUR_CHISEL && !on_block_face) {
                        continue;
                    }
                    let (f, s, k) = sweep.value(self.point(c[0], c[1], c[2]));
                    if sweep.slanted[k] && f > 0.0 {
                        self.slide_to_edge(idx, sweep, k, s, 0.7, stats);
                    }
                }
            }
        }
        self.spans = spans;
    }

    /// Eq. 6: a chisel's slanted face `k` (at sweep parameter `s`) meeting the old surface
    /// at BOUND point `idx`: slides the old surfel within its tangent plane onto the face
    /// (the groove's edge), keeping its normal, if the edge is within `reach` spacings.
    /// The old surface is the point's surfel unless the chisel put it itself (a face of an
    /// earlier pose of the stroke, often its front face meeting the point first): then it
    /// is the block's face the point lies on, if any. Returns whether the surfel is on the
    /// edge (moved there now, or already there).
    fn slide_to_edge(
        &mut self,
        idx: usize,
        sweep: &Sweep,
        k: usize,
        s: f64,
        reach: f64,
        stats: &mut CutStats,
    ) -> bool {
        let h = self.h;
        let nw = sweep.faces[k].0;
        let o = self.surfels[self.surfel_of[idx] as usize];
        let old = if o.colour == COLOUR_CHISEL {
            self.uncut_face(idx, nw)
        } else {
            Some((o.position.map(f64::from), o.normal.map(f64::from), o.colour))
        };
        let Some((xb, nb, old_colour)) = old else {
            return false;
        };
        let cos = dot(nw, nb);
        if !(cos.abs() < 0.94) {
            return false;
        }
        let v = sub(nw, scale(nb, cos));
        // Plane of face k at the sweep parameter s: n · x = off + s (n · d).
        let fb = dot(nw, xb) - sweep.faces[k].1 - s * dot(nw, sweep.d);
        if old_colour == COLOUR_EDGE && fb.abs() <= 1e-3 * h {
            // Already on this face's edge (a later pose of the same stroke exposes the
            // point again): projecting it onto the face would lose the edge.
            return true;
        }
        let nv = dot(nw, v);
        if !(nv.abs() > 1e-12) {
            return false;
        }
        let step = scale(v, fb / nv);
        if fb > 0.0 && norm(step) <= reach * h {
            self.set_surfel(idx, sub(xb, step), nb, COLOUR_EDGE);
            stats.resampled += 1;
            stats.exposed += 1;
            return true;
        }
        false
    }

    /// The surface point `idx` had before the chisel reached it, if that was one of the
    /// block's own faces: the first axis direction off the grid from it that is not within
    /// 20° of the face normal `nw`; the face half a spacing that way, facing it. (An air
    /// neighbour is no evidence: the chisel may have cut it earlier in the stroke.)
    fn uncut_face(&self, idx: usize, nw: Vec3) -> Option<(Vec3, Vec3, u32)> {
        let c = self.coords(idx);
        let p = self.point(c[0], c[1], c[2]);
        for a in 0..3 {
            for (sign, off_grid) in [(-1.0f64, c[a] == 0), (1.0, c[a] + 1 == self.dims[a])] {
                let mut dir = [0.0; 3];
                dir[a] = sign;
                if off_grid && dot(dir, nw).abs() < 0.94 {
                    return Some((add(p, scale(dir, self.h / 2.0)), dir, COLOUR_BLOCK));
                }
            }
        }
        None
    }

    /// Point `idx` (material, next to a removed point) is on the surface of the cut.
    fn expose(&mut self, idx: usize, sweep: &Sweep, colour: u32, stats: &mut CutStats) {
        let c = self.coords(idx);
        let p = self.point(c[0], c[1], c[2]);
        let (f, s, k) = sweep.value(p);
        let nw = sweep.faces[k].0;
        let h = self.h;
        let was_surface = self.flags[idx] == BOUND && self.surfel_of[idx] != NO_SURFEL;
        if sweep.slanted[k] && was_surface && self.slide_to_edge(idx, sweep, k, s, 1.0, stats) {
            return;
        }
        self.flags[idx] = BOUND;
        // The knife: the surfel at the exact closest point of the swept solid, facing it.
        if let Some((c, dist)) = sweep.closest_on_box_sweep(p) {
            if dist > 1e-12 * h && dist <= 1.5 * h {
                self.set_surfel(idx, c, scale(sub(c, p), 1.0 / dist), colour);
                stats.exposed += 1;
                return;
            }
        }
        // The surfel on the cutting face (eq. 2's plane), if the point is within the band.
        let pos = if f > 0.0 && f <= 1.5 * h {
            sub(p, scale(nw, f))
        } else {
            p
        };
        self.set_surfel(idx, pos, scale(nw, -1.0), colour);
        stats.exposed += 1;
    }
}

/// The minimiser over [0, 1] of a unimodal `f` by golden-section search, `iters` steps (each
/// shrinks the bracket by 0.618: 48 steps leave about 1e-10).
pub(crate) fn golden_section_min(f: impl Fn(f64) -> f64, iters: u32) -> f64 {
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut a, mut b) = (0.0f64, 1.0f64);
    let (mut x1, mut x2) = (b - g * (b - a), a + g * (b - a));
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..iters {
        if f1 < f2 {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - g * (b - a);
            f1 = f(x1);
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + g * (b - a);
            f2 = f(x2);
        }
    }
    (a + b) / 2.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn row_range_of_a_box_moving_along_x() {
        // Unit box [-0.5, 0.5] moving by 2 along x, row along x through its centre, h = 1.
        let d = [2.0, 0.0, 0.0];
        let faces = [([1.0, 0.0, 0.0], 0.5), ([-1.0, 0.0, 0.0], 0.5)];
        let mut cons = vec![];
        for (n, o) in faces {
            cons.push((n[0], -dot(n, d), o));
        }
        cons.push((0.0, -1.0, 0.0));
        cons.push((0.0, 1.0, 1.0));
        let (lo, hi) = row_range(&cons).unwrap();
        assert!(
            (lo + 0.5).abs() < 1e-12 && (hi - 2.5).abs() < 1e-12,
            "{lo} {hi}"
        );
    }
}
