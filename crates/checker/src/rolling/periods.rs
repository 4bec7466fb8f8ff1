//! Deciding a pair's frame period: which slabs make its window, checking it, folding what
//! it gives into the pair's running answer (labels, intervals, contact events, closing
//! speeds), and the overlap measure.

use std::collections::VecDeque;
use std::sync::Arc;

use super::{
    add_normals, bounds, check_window, closing_sums, hold, on_pair_lattice, origin_offset,
    prepare_window,
    report::{pair_overlap_as, run_overlap},
    speed, time_at, union_bounds, CapSide, ContactPhase, ContactUpdate, Crossing, FramesAround,
    GridGeometry, HeldSlab, HeldWindow, HeldWindows, Interval, KeptWindow, Label, LabelCounts,
    Mesher, MesherOptions, OccupancyGrid, OpenUnsure, Overlap, Partner, PendingPeriod, PoolJob,
    PreparedWindow, Record, RollingChecker, RollingOutput, SlabLabels, SpatialBounds, SpatialBox,
    StatsAccumulator, TakenLabels, TetMesh, UnsureSpan, UnsureUpdate, WindowBody, WindowResult,
    CHECKER_FACTOR, CONTEXT_SLABS, REBASE_FRAMES,
};

impl RollingChecker {
    pub(super) fn seconds_of_stamp(&self, s: i64) -> f64 {
        (s - self.origin_ns.unwrap_or(s)) as f64 * 1e-9
    }

    /// The slab of `body` at `s` is decided for pair `i` without the other body: OUTSIDE.
    pub(super) fn alone(&mut self, i: usize, body: &str, s: i64, out: &mut Vec<RollingOutput>) {
        let (hi, index, run, lateral) = {
            let sl = &self.bodies[body].slabs[&s];
            (sl.hi, sl.index, sl.run, sl.mesh.tets.len())
        };
        if self.cfg.labels {
            let b = &self.bodies[body];
            let r = b.run(run);
            let cap_start = r
                .filter(|r| r.first_stamp == s)
                .map(|r| r.first_cap_tets as usize);
            let cap_end = r.and_then(|r| r.last_cap_at(hi)).map(|c| c.tets.len());
            let n = cap_start.unwrap_or(0) + lateral + cap_end.unwrap_or(0);
            let p = &self.pairs[i];
            let other = if p.a == body { &p.b } else { &p.a };
            out.push(RollingOutput::Labels(SlabLabels {
                body: body.to_string(),
                other: other.clone(),
                index,
                stamps_ns: (s, hi),
                with_cap_start: cap_start.is_some(),
                with_cap_end: cap_end.is_some(),
                labels: vec![Label::Outside as u8; n],
                counts: LabelCounts {
                    outside: n as u64,
                    ..LabelCounts::default()
                },
            }));
        }
        let k = self.period_index(i, s);
        self.advance(i, s, hi, k, out);
    }

    /// Moves pair `i` past the period [s, hi] of common index `k`.
    pub(super) fn advance(
        &mut self,
        i: usize,
        s: i64,
        hi: i64,
        k: i64,
        out: &mut Vec<RollingOutput>,
    ) {
        let p = &mut self.pairs[i];
        p.stamps.insert(k, s);
        p.stamps.insert(k + 1, hi);
        p.next = Some(hi);
        p.index = k + 1;
        while p
            .stamps
            .first_key_value()
            .is_some_and(|(j, _)| *j < k - CONTEXT_SLABS as i64)
        {
            p.stamps.pop_first();
        }
        // Nothing later can start before the end of this period, and nothing goes on past
        // it where either body's stream ends there.
        let hi_t = ((k + 1 - p.base) * p.per) as f64;
        let before_end = p.open.as_ref().is_some_and(|o| o.t.1 < hi_t);
        if before_end {
            self.close_open(i, out);
        }
        self.end_streams(i, s, hi, out);
        self.finish_speeds(i, false);
    }

    /// Where either body's stream ends at `hi` (its run closed by a cap there), pair `i`'s
    /// contact and unsure span going on end with it.
    pub(super) fn end_streams(&mut self, i: usize, s: i64, hi: i64, out: &mut Vec<RollingOutput>) {
        let (a, b) = (self.pairs[i].a.clone(), self.pairs[i].b.clone());
        let ends_here = |id: &str| {
            let body = &self.bodies[id];
            body.slabs
                .get(&s)
                .and_then(|x| body.run(x.run))
                .is_some_and(|r| r.last_cap_at(hi).is_some())
        };
        if ends_here(&a) || ends_here(&b) {
            self.close_open(i, out);
            // An unsure span goes on no further than a stream: its end is said when the
            // stream ends, not when the node does.
            self.close_unsure(i, out);
        }
    }

    /// What one body's window is made of (owned, so that the pair can be changed while it
    /// is checked).
    pub(super) fn window_spec(
        &self,
        me: &str,
        other: &str,
        s: i64,
        k: i64,
        (base, per): (i64, i64),
        (shift, ratio): ([i64; 3], i64),
    ) -> Option<WindowSpec> {
        let body = &self.bodies[me];
        let centre_slab = body.slabs.get(&s)?;
        let r = body.run(centre_slab.run)?;
        let o = self.bodies[other].run(self.bodies[other].slabs.get(&s)?.run)?;
        let hi = centre_slab.hi;
        let prev = |stamp: i64| {
            body.slabs
                .range(..stamp)
                .next_back()
                .filter(|(_, x)| x.hi == stamp && x.run == r.id)
                .map(|(key, x)| (*key, x))
        };
        let mut slabs: VecDeque<(i64, &HeldSlab)> = VecDeque::from([(s, centre_slab)]);
        let mut centre = 0;
        let mut lo_stamp = s;
        let mut hi_stamp = hi;
        // The other body's real cap in an end plane: reach one slab further.
        if o.first_stamp == s {
            if let Some(x) = prev(s) {
                slabs.push_front(x);
                centre += 1;
                lo_stamp = x.0;
            }
        }
        if o.last_cap_at(hi).is_some() {
            if let Some(x) = body.slabs.get(&hi).filter(|x| x.run == r.id) {
                slabs.push_back((hi, x));
                hi_stamp = x.hi;
            }
        }
        let low = (r.first_stamp == lo_stamp).then(|| r.first_cap.clone());
        let high = r.last_cap_at(hi_stamp).cloned();
        let lo_common = k - centre as i64;
        let bounds = slabs
            .iter()
            .map(|(_, x)| x.bounds)
            .chain(
                [&low, &high]
                    .into_iter()
                    .flatten()
                    .map(|m| m.spatial_bounds()),
            )
            .fold(None, union_bounds);
        Some(WindowSpec {
            bounds,
            geometry: r.geometry,
            lo: slabs[0].1.index,
            slabs: slabs.iter().map(|(_, x)| x.mesh.clone()).collect(),
            centre,
            low,
            high,
            mul: ratio,
            add: [
                shift[0] * per,
                shift[1] * per,
                shift[2] * per,
                (lo_common - base) * per,
            ],
            first_tet: if r.first_stamp == s {
                0
            } else {
                centre_slab.first_tet
            },
        })
    }

    /// Checks the period of pair `i` starting at `s` where both bodies have a slab; `false`
    /// if it must wait for a frame.
    pub(super) fn window(&mut self, i: usize, s: i64, out: &mut Vec<RollingOutput>) -> bool {
        let (a, b) = (self.pairs[i].a.clone(), self.pairs[i].b.clone());
        let (hi, hb) = (self.bodies[&a].slabs[&s].hi, self.bodies[&b].slabs[&s].hi);
        if hi != hb {
            let why = format!(
                "pair {a} x {b}: frames at different times (the periods from {:.3} s end at \
                 {:.3} s and {:.3} s); the pair is not checked from there on",
                self.seconds_of_stamp(s),
                self.seconds_of_stamp(hi),
                self.seconds_of_stamp(hb)
            );
            self.pairs[i].stopped = Some(why.clone());
            self.problem(out, "time_mismatch", why);
            return false;
        }
        // What follows each slab, the next slab or the end of its stream, need not be known:
        // if it is not, the period is checked now as though both streams go on, and settled
        // once it is (see `PendingPeriod`).
        self.close_stalled(&a, &b, s, out);
        if !self.period_ready(&a, &b, s, hi) {
            return false;
        }
        let speculative = !self.follows_known(&a, s, hi) || !self.follows_known(&b, s, hi);
        let geometry = |id: &str| {
            let body = &self.bodies[id];
            body.run(body.slabs[&s].run).map(|r| r.geometry)
        };
        let (Some(ga), Some(gb)) = (geometry(&a), geometry(&b)) else {
            return false;
        };
        let (fa, fb) = (&self.bodies[&a].frame_id, &self.bodies[&b].frame_id);
        if fa != fb {
            let why = format!(
                "pair {a} x {b}: not checked: {a} is in frame {fa:?} and {b} in frame {fb:?}: \
                 bodies in different frames are not compared (publish them in one frame)"
            );
            self.pairs[i].stopped = Some(why.clone());
            self.problem(out, "frame_mismatch", why);
            return false;
        }
        let lattice = match pair_lattice(&ga, &gb) {
            Ok(l) => l,
            Err(reason) => {
                let why = format!(
                    "pair {a} x {b}: not on one lattice ({reason}); the pair is not checked from \
                     there on"
                );
                self.pairs[i].stopped = Some(why.clone());
                self.problem(out, "lattice_mismatch", why);
                return false;
            }
        };
        let k = self.period_index(i, s);
        let per = i64::from(lattice.scale) * i64::from(CHECKER_FACTOR);
        let base = {
            let p = &self.pairs[i];
            if k - p.base > REBASE_FRAMES {
                k - CONTEXT_SLABS as i64
            } else {
                p.base
            }
        };
        let specs = self.window_specs(i, s, k, (base, per), &lattice);
        self.rebase(i, base, per);
        let (Some(wa), Some(wb)) = specs else {
            // A frame for a cap has not come (yet).
            let behind = self.lead(&a, s).max(self.lead(&b, s)) > self.cfg.max_lead_frames;
            if !self.finishing && !behind {
                return false;
            }
            let why = format!(
                "pair {a} x {b}: no frame to close the period {:.3}-{:.3} s (a frame the mesher \
                 filled in, or one that never came); that period is not checked",
                self.seconds_of_stamp(s),
                self.seconds_of_stamp(hi)
            );
            self.problem(out, "period_unchecked", why);
            self.settle_overlap(i);
            self.pairs[i].overlap.unknown = true;
            self.advance(i, s, hi, k, out);
            return true;
        };
        let fast = self.fast_near(&a, &b, s);
        let repeated = (!apart(&wa, &wb))
            .then(|| {
                self.repeated(i, k, &wa, &wb)
                    .map(|(w, dt)| w.result.moved_in_time(dt))
            })
            .flatten();
        let checked = match repeated {
            Some(r) => {
                self.pairs[i].taken_moved += 1;
                Ok(r)
            }
            None => {
                let ahead = self
                    .prefetched
                    .iter()
                    .position(|x| {
                        x.pair == i && x.s == s && x.specs.0.same_as(&wa) && x.specs.1.same_as(&wb)
                    })
                    .map(|n| self.prefetched.swap_remove(n).result);
                self.check_windows((&a, &wa), (&b, &wb), s, ahead)
            }
        };
        let r = match checked {
            Ok(r) => {
                self.keep_window(i, k, &wa, &wb, &r);
                r
            }
            Err(e) => {
                let why = format!(
                    "pair {a} x {b}: the period {:.3}-{:.3} s cannot be checked: {e}",
                    self.seconds_of_stamp(s),
                    self.seconds_of_stamp(hi)
                );
                self.problem(out, "period_unchecked", why);
                self.advance(i, s, hi, k, out);
                if speculative {
                    // The ends are still said where a stream turns out to end at `hi`.
                    self.pairs[i].pending = Some(PendingPeriod {
                        s,
                        hi,
                        k,
                        result: None,
                        labels: Vec::new(),
                    });
                }
                return true;
            }
        };
        self.overlap_push(i, s, hi, no_overlap(&r));
        {
            let p = &mut self.pairs[i];
            p.stamps.insert(k, s);
            p.stamps.insert(k + 1, hi);
        }
        let starts = (wa.first_tet, wb.first_tet);
        if speculative {
            let mut labels = Vec::new();
            self.fold_counts(i, &r, starts);
            self.fold_labels(i, s, hi, &r, &mut labels);
            self.fold_ranges(i, r.ranges.clone(), hi, out);
            self.note_unsure(i, s, hi, fast, out);
            self.advance(i, s, hi, k, out);
            self.pairs[i].pending = Some(PendingPeriod {
                s,
                hi,
                k,
                result: Some(r),
                labels,
            });
            return true;
        }
        self.fold(i, s, hi, &r, starts, out);
        self.note_unsure(i, s, hi, fast, out);
        self.advance(i, s, hi, k, out);
        true
    }

    /// Whether the period of bodies `a` and `b` from `s` to `hi` (both slabs in) can be
    /// checked: what follows both slabs is known, or, checked before it is, both bodies'
    /// frames at `hi` are in. The overlap is measured from the frames at the period's
    /// stamps, and a frame comes on its own topic: live, a slab can come before the frame
    /// at its later stamp. The period then waits for that frame (or, if it never comes,
    /// for what follows the slabs).
    pub(super) fn period_ready(&self, a: &str, b: &str, s: i64, hi: i64) -> bool {
        let known = self.follows_known(a, s, hi) && self.follows_known(b, s, hi);
        known
            || [a, b]
                .iter()
                .all(|id| self.bodies[*id].frames.contains_key(&hi))
    }

    /// Whether what follows `id`'s slab at `s` (ending at `hi`) is known: its next slab, or
    /// the end of its stream.
    /// (A slab no longer held has nothing left to wait for.)
    fn follows_known(&self, id: &str, s: i64, hi: i64) -> bool {
        let body = &self.bodies[id];
        let Some(slab) = body.slabs.get(&s) else {
            return true;
        };
        body.slabs.contains_key(&hi) || body.run(slab.run).is_some_and(|r| r.ended())
    }

    /// Where nothing follows a body's slab at `s` while the other body runs far ahead, the
    /// stream stalled (a lost piece or cap): its run is closed there, so that the pair goes
    /// on and the other body's slabs do not pile up.
    fn close_stalled(&mut self, a: &str, b: &str, s: i64, out: &mut Vec<RollingOutput>) {
        if self.lead(a, s).max(self.lead(b, s)) <= self.cfg.max_lead_frames {
            return;
        }
        for id in [a, b] {
            let Some(hi) = self.bodies[id].slabs.get(&s).map(|x| x.hi) else {
                continue;
            };
            if self.follows_known(id, s, hi) {
                continue;
            }
            let why = format!(
                "{id}: nothing follows its slab at {:.3} s while its partner is more than {} \
                 slabs ahead (a lost piece or cap); its stream is taken as ended there",
                self.seconds_of_stamp(s),
                self.cfg.max_lead_frames
            );
            self.settle_stats(id);
            let body = self.bodies.get_mut(id).expect("a paired body");
            let run = body.slabs.get(&s).map(|x| x.run);
            if let Some(r) = body.runs.iter_mut().find(|r| Some(r.id) == run) {
                r.close(None);
            }
            self.problem(out, "stream_stalled", why);
        }
    }

    /// Settles pair `i`'s period checked before what follows its slabs was known, once that
    /// is known (`false` while it is not): its labels as they were where neither stream
    /// ends at the period's later frame; else the window with the caps there checked, what
    /// it adds folded in (the caps' labels, their crossings, the overlap they give in that
    /// time plane) and the streams' ends said, so that the pair's answer is the one the
    /// full window would have given.
    pub(super) fn settle_pending(&mut self, i: usize, out: &mut Vec<RollingOutput>) -> bool {
        let Some((s, hi)) = self.pairs[i].pending.as_ref().map(|x| (x.s, x.hi)) else {
            return true;
        };
        let (a, b) = (self.pairs[i].a.clone(), self.pairs[i].b.clone());
        self.close_stalled(&a, &b, s, out);
        if !self.follows_known(&a, s, hi) || !self.follows_known(&b, s, hi) {
            return false;
        }
        let Some(pending) = self.pairs[i].pending.take() else {
            return true;
        };
        let capped = |me: &Self, id: &str| {
            let body = &me.bodies[id];
            body.slabs
                .get(&s)
                .and_then(|x| body.run(x.run))
                .is_some_and(|r| r.last_cap_at(hi).is_some())
        };
        if !capped(self, &a) && !capped(self, &b) {
            out.extend(pending.labels);
            return true;
        }
        let Some(taken) = &pending.result else {
            // The period could not be checked (said then): the streams' ends alone.
            self.end_streams(i, s, hi, out);
            self.finish_speeds(i, false);
            return true;
        };
        match self.capped_window(i, &pending) {
            Ok((full, starts)) => {
                self.fold_added(i, hi, taken, &full, starts, out);
                self.fold_labels(i, s, hi, &full, out);
            }
            Err(e) => {
                let why = format!(
                    "pair {a} x {b}: the caps that close a stream at {:.3} s cannot be checked: \
                     {e}; their tets are not labelled (the period's slabs are)",
                    self.seconds_of_stamp(hi)
                );
                self.problem(out, "period_unchecked", why);
                out.extend(pending.labels);
            }
        }
        self.end_streams(i, s, hi, out);
        self.finish_speeds(i, false);
        true
    }

    /// The full window of a pending period, with the caps at its later frame, checked: its
    /// result and the positions of the two bodies' first taken tets.
    fn capped_window(
        &mut self,
        i: usize,
        pending: &PendingPeriod,
    ) -> Result<(WindowResult, (u64, u64)), CapsUnchecked> {
        let s = pending.s;
        let (a, b) = (self.pairs[i].a.clone(), self.pairs[i].b.clone());
        let geometry = |id: &str| {
            let body = &self.bodies[id];
            body.run(body.slabs.get(&s)?.run).map(|r| r.geometry)
        };
        let (Some(ga), Some(gb)) = (geometry(&a), geometry(&b)) else {
            return Err(CapsUnchecked::Gone);
        };
        let lattice = pair_lattice(&ga, &gb)?;
        let (base, per) = (self.pairs[i].base, self.pairs[i].per);
        let (Some(wa), Some(wb)) = self.window_specs(i, s, pending.k, (base, per), &lattice) else {
            return Err(CapsUnchecked::Gone);
        };
        let r = self.check_windows((&a, &wa), (&b, &wb), s, None)?;
        Ok((r, (wa.first_tet, wb.first_tet)))
    }

    /// Both bodies' windows of pair `i`'s period at `s` (common index `k`) on their pair
    /// lattice (see [`Self::window_spec`]).
    pub(super) fn window_specs(
        &self,
        i: usize,
        s: i64,
        k: i64,
        (base, per): (i64, i64),
        lattice: &PairLattice,
    ) -> (Option<WindowSpec>, Option<WindowSpec>) {
        let (a, b) = (&self.pairs[i].a, &self.pairs[i].b);
        let spec = |me: &str, other: &str, shift, ratio| {
            self.window_spec(me, other, s, k, (base, per), (shift, ratio))
        };
        (
            spec(a, b, lattice.shift_a, lattice.ratio_a),
            spec(b, a, lattice.shift_b, lattice.ratio_b),
        )
    }

    /// The window pair `i` kept of which its windows `wa` and `wb` of its period `k` are both
    /// the moved copies by one vector, if one is, with that vector's time (see
    /// [`KeptWindow`]): the result is then the kept one moved by it.
    pub(super) fn repeated(
        &self,
        i: usize,
        k: i64,
        wa: &WindowSpec,
        wb: &WindowSpec,
    ) -> Option<(&KeptWindow, i64)> {
        let most = self.cfg.kept_windows as i64;
        self.pairs[i]
            .kept
            .iter()
            .rev()
            .take_while(|w| k - w.k <= most)
            .find_map(|w| {
                let d = wa.moved_copy_of(&w.specs.0)?;
                (wb.moved_copy_of(&w.specs.1)? == d).then_some((w, d[3]))
            })
    }

    /// Keeps pair `i`'s windows `wa` and `wb` of its period `k` with their result `r` for the
    /// periods after, if the result moves exactly (see [`KeptWindow`]); lets go of those too
    /// old to serve the next period.
    fn keep_window(
        &mut self,
        i: usize,
        k: i64,
        wa: &WindowSpec,
        wb: &WindowSpec,
        r: &WindowResult,
    ) {
        let most = self.cfg.kept_windows as i64;
        let kept = &mut self.pairs[i].kept;
        kept.retain(|w| k - w.k < most);
        // Only a result that moves exactly (no crossing, nothing undecided, no real cap), of
        // windows that were walked (those apart in space cost nothing to answer again).
        let plain = |w: &WindowSpec| w.low.is_none() && w.high.is_none();
        if most == 0
            || !r.crossings.is_empty()
            || r.undecided > 0
            || !plain(wa)
            || !plain(wb)
            || apart(wa, wb)
        {
            return;
        }
        kept.push_back(KeptWindow {
            k,
            specs: (wa.clone(), wb.clone()),
            result: r.clone(),
        });
    }

    /// Checks two bodies' windows of the period at `s`, or takes the result checked ahead
    /// (`ahead`), and keeps both preparations for the next windows. Windows whose boxes are
    /// apart in space are not walked: no tet meets the other body, every one is outside.
    fn check_windows(
        &mut self,
        (a, wa): (&str, &WindowSpec),
        (b, wb): (&str, &WindowSpec),
        s: i64,
        ahead: Option<WindowChecked>,
    ) -> Result<WindowResult, crate::period::WindowError> {
        if apart(wa, wb) {
            return Ok(WindowResult {
                labels: [wa.all_outside(), wb.all_outside()],
                ..WindowResult::default()
            });
        }
        let result = ahead.unwrap_or_else(|| {
            check_specs((a, wa), (b, wb), |id, w, partner| {
                cached(&self.prepared, id, w, partner).or_else(|| self.moved(id, w, partner))
            })
        });
        let (r, prepared) = result?;
        if let Some([pa, pb]) = prepared {
            let held = |partner: &str, spec: &WindowSpec, window| HeldWindow {
                partner: partner.to_owned(),
                spec: spec.clone(),
                window,
                s,
            };
            hold(&mut self.prepared, a, held(b, wa, pa));
            hold(&mut self.prepared, b, held(a, wb, pb));
        }
        Ok(r)
    }

    /// How far each body of a pair moves in the period from `s` (voxels), where one moves
    /// fast near the other ([`chronotope_mesh::unsure::moves_fast_near`], as `check`
    /// decides it); else 0.
    pub(super) fn fast_near(&self, a: &str, b: &str, s: i64) -> (u16, u16) {
        let slab = |id: &str| {
            let body = self.bodies.get(id)?;
            let x = body.slabs.get(&s)?;
            Some((body.run(x.run)?.geometry, x.bounds, x.displacement))
        };
        let (Some((ga, xa, da)), Some((gb, xb, db))) = (slab(a), slab(b)) else {
            return (0, 0);
        };
        chronotope_mesh::unsure::moves_fast_near((&ga, xa, da), (&gb, xb, db))
    }

    /// Moves pair `i`'s checker-time origin to common frame `base` (the crossings and the
    /// open interval kept shift with it) and sets its lattice step.
    pub(super) fn rebase(&mut self, i: usize, base: i64, per: i64) {
        let p = &mut self.pairs[i];
        if base != p.base {
            let d = ((base - p.base) * p.per) as f64;
            for r in &mut p.records {
                r.t = (r.t.0 - d, r.t.1 - d);
            }
            if let Some(o) = &mut p.open {
                o.t = (o.t.0 - d, o.t.1 - d);
            }
            for o in &mut p.intervals {
                o.t = (o.t.0 - d, o.t.1 - d);
            }
            p.base = base;
        }
        p.per = per;
    }

    /// Folds a window's result into pair `i`'s answer.
    pub(super) fn fold(
        &mut self,
        i: usize,
        s: i64,
        hi: i64,
        r: &WindowResult,
        starts: (u64, u64),
        out: &mut Vec<RollingOutput>,
    ) {
        self.fold_counts(i, r, starts);
        self.fold_labels(i, s, hi, r, out);
        self.fold_ranges(i, r.ranges.clone(), hi, out);
    }

    /// A window's counts and crossings into pair `i`'s figures.
    pub(super) fn fold_counts(&mut self, i: usize, r: &WindowResult, starts: (u64, u64)) {
        let p = &mut self.pairs[i];
        p.checked = true;
        p.partner_absent = false;
        p.candidates += r.candidate_pairs;
        p.crossings += r.crossings.len() as u64;
        p.undecided += u64::from(r.undecided);
        for (c, l) in [
            (&mut p.counts.0, &r.labels[0]),
            (&mut p.counts.1, &r.labels[1]),
        ] {
            c.interference += l.counts.interference;
            c.inside += l.counts.inside;
        }
        for c in &r.crossings {
            p.records.push_back(record(c, starts));
        }
    }

    /// What the full window of a pending period (`full`, with the caps at its later frame)
    /// adds to the window without them (`taken`, folded already): the caps' counts, the
    /// crossings and overlap ranges in that time plane. The slabs' tets get the same labels
    /// and crossings in both (see `PendingPeriod`); what `full` has beyond `taken` is found
    /// as a difference of multisets, so nothing is counted twice.
    fn fold_added(
        &mut self,
        i: usize,
        hi: i64,
        taken: &WindowResult,
        full: &WindowResult,
        starts: (u64, u64),
        out: &mut Vec<RollingOutput>,
    ) {
        {
            let p = &mut self.pairs[i];
            p.candidates += full.candidate_pairs.saturating_sub(taken.candidate_pairs);
            p.undecided += u64::from(full.undecided.saturating_sub(taken.undecided));
            for (c, (f, t)) in [
                (&mut p.counts.0, (&full.labels[0], &taken.labels[0])),
                (&mut p.counts.1, (&full.labels[1], &taken.labels[1])),
            ] {
                c.interference += f.counts.interference.saturating_sub(t.counts.interference);
                c.inside += f.counts.inside.saturating_sub(t.counts.inside);
            }
            let key = |c: &Crossing| (c.tets, c.t.0.to_bits(), c.t.1.to_bits());
            for c in beyond(&taken.crossings, &full.crossings, key) {
                p.crossings += 1;
                p.records.push_back(record(c, starts));
            }
        }
        let key = |r: &(f64, f64)| (r.0.to_bits(), r.1.to_bits());
        let added = beyond(&taken.ranges, &full.ranges, key)
            .into_iter()
            .copied()
            .collect();
        self.fold_ranges(i, added, hi, out);
    }

    /// A window's labels published (if asked for) and the worst label of each slab tet
    /// kept for the markers.
    pub(super) fn fold_labels(
        &mut self,
        i: usize,
        s: i64,
        hi: i64,
        r: &WindowResult,
        out: &mut Vec<RollingOutput>,
    ) {
        let (a, b) = (self.pairs[i].a.clone(), self.pairs[i].b.clone());
        for (k, (me, other)) in [(&a, &b), (&b, &a)].into_iter().enumerate() {
            let l = &r.labels[k];
            if self.cfg.labels {
                let index = self.bodies[me].slabs[&s].index;
                out.push(RollingOutput::Labels(SlabLabels {
                    body: me.clone(),
                    other: other.clone(),
                    index,
                    stamps_ns: (s, hi),
                    with_cap_start: l.pieces[0] > 0,
                    with_cap_end: l.pieces[2] > 0,
                    labels: l.labels.clone(),
                    counts: l.counts,
                }));
            }
            if self.cfg.slabs_done {
                let lateral = &l.labels[l.pieces[0]..l.pieces[0] + l.pieces[1]];
                if let Some(sl) = self
                    .bodies
                    .get_mut(me.as_str())
                    .and_then(|b| b.slabs.get_mut(&s))
                {
                    for (w, &x) in sl.worst.iter_mut().zip(lateral) {
                        *w = (*w).max(x);
                    }
                }
            }
        }
    }

    /// A window's overlap ranges (checker time) into pair `i`'s contact intervals, with
    /// the events they give, stamped `hi`.
    pub(super) fn fold_ranges(
        &mut self,
        i: usize,
        mut ranges: Vec<(f64, f64)>,
        hi: i64,
        out: &mut Vec<RollingOutput>,
    ) {
        // The window's ranges merged (so that a contact begins with all this period gives
        // it, whatever order the walk found them in), then in order: merged into the open
        // interval, or closing it and opening another.
        ranges.sort_unstable_by(|x, y| x.0.total_cmp(&y.0).then(x.1.total_cmp(&y.1)));
        let mut merged: Vec<(f64, f64)> = Vec::new();
        for (t0, t1) in ranges {
            match merged.last_mut() {
                Some(m) if t0 <= m.1 => m.1 = m.1.max(t1),
                _ => merged.push((t0, t1)),
            }
        }
        for (t0, t1) in merged {
            let merges = self.pairs[i].open.as_ref().is_some_and(|o| t0 <= o.t.1);
            if merges {
                let mut extended = false;
                if let Some(o) = &mut self.pairs[i].open {
                    if t1 > o.t.1 {
                        o.t.1 = t1;
                        extended = true;
                    }
                }
                if extended {
                    self.convert_open(i);
                    out.extend(self.update(i, ContactPhase::Ongoing, hi));
                }
                continue;
            }
            self.close_open(i, out);
            let p = &mut self.pairs[i];
            let index = p.contacts;
            p.contacts += 1;
            p.open = Some(Interval {
                t: (t0, t1),
                s: (0.0, 0.0),
                speeds: (None, None),
                periods: (0.0, 0.0),
                index,
            });
            self.convert_open(i);
            out.extend(self.update(i, ContactPhase::Begin, hi));
        }
    }

    /// Records in pair `i` whether either body's slab of the period `s..hi` is unsure, and
    /// says when an unsure span of the pair begins or ends.
    pub(super) fn note_unsure(
        &mut self,
        i: usize,
        s: i64,
        hi: i64,
        (fast_a, fast_b): (u16, u16),
        out: &mut Vec<RollingOutput>,
    ) {
        let (a, b) = (self.pairs[i].a.clone(), self.pairs[i].b.clone());
        let why = |id: &str, fast: u16| {
            let slab = self.bodies.get(id)?.slabs.get(&s)?.unsure;
            let moves =
                (fast > 0).then_some(chronotope_mesh::unsure::Unsure::MovesFast { voxels: fast });
            match (slab, moves) {
                (Some(x), Some(y)) => Some(x.max(y)),
                (x, y) => x.or(y),
            }
        };
        let (ua, ub) = (why(&a, fast_a), why(&b, fast_b));
        let period_ns = hi - s;
        let p = &mut self.pairs[i];
        for (log, u) in [(&mut p.unsure.0, ua), (&mut p.unsure.1, ub)] {
            if let Some(why) = u {
                log.push(UnsureSpan {
                    from_ns: s,
                    to_ns: hi,
                    why,
                    period_ns,
                });
            }
        }
        let now = match (ua, ub) {
            (Some(w), _) => Some((a.clone(), w)),
            (None, Some(w)) => Some((b.clone(), w)),
            (None, None) => None,
        };
        match (&mut p.unsure_open, now) {
            (Some(o), Some((_, w))) if o.to_ns >= s => {
                o.to_ns = hi;
                o.why = o.why.max(w);
                o.period_ns = o.period_ns.min(period_ns);
            }
            (_, now) => {
                // Said at the period that found the span over, like a contact's end: the
                // event's stamp is this period's later frame, not the span's last one.
                if let Some(o) = self.pairs[i].unsure_open.take() {
                    out.push(self.unsure_update(i, &o, true, hi));
                }
                if let Some((body, why)) = now {
                    let p = &mut self.pairs[i];
                    let open = OpenUnsure {
                        index: p.unsure_count,
                        body,
                        from_ns: s,
                        to_ns: hi,
                        why,
                        period_ns,
                    };
                    p.unsure_count += 1;
                    p.unsure_open = Some(open.clone());
                    out.push(self.unsure_update(i, &open, false, hi));
                }
            }
        }
    }

    /// Ends pair `i`'s unsure span going on, if any.
    pub(super) fn close_unsure(&mut self, i: usize, out: &mut Vec<RollingOutput>) {
        if let Some(o) = self.pairs[i].unsure_open.take() {
            out.push(self.unsure_update(i, &o, true, o.to_ns));
        }
    }

    fn unsure_update(&self, i: usize, o: &OpenUnsure, ended: bool, stamp_ns: i64) -> RollingOutput {
        let p = &self.pairs[i];
        let span = UnsureSpan {
            from_ns: o.from_ns,
            to_ns: o.to_ns,
            why: o.why,
            period_ns: o.period_ns,
        };
        RollingOutput::Unsure(UnsureUpdate {
            a: p.a.clone(),
            b: p.b.clone(),
            ended,
            index: o.index,
            span: crate::report::UnsureSpanReport::of(&o.body, &span, self.origin_ns.unwrap_or(0)),
            stamp_ns,
        })
    }

    /// Seconds and periods of the open interval's ends (the start once, when it opens).
    pub(super) fn convert_open(&mut self, i: usize) {
        let origin = self.origin_ns.unwrap_or(0);
        let p = &mut self.pairs[i];
        let Some(mut o) = p.open.take() else { return };
        if o.periods.0 == 0.0 {
            if let Some(x) = time_at(p, o.t.0, origin) {
                o.s.0 = x.0;
                o.periods.0 = x.1;
            }
        }
        if let Some(y) = time_at(p, o.t.1, origin) {
            o.s.1 = y.0;
            o.periods.1 = y.1;
        }
        p.open = Some(o);
    }

    pub(super) fn update(
        &self,
        i: usize,
        phase: ContactPhase,
        stamp_ns: i64,
    ) -> Option<RollingOutput> {
        let p = &self.pairs[i];
        let o = match phase {
            ContactPhase::End => p.intervals.back()?,
            _ => p.open.as_ref()?,
        };
        let bound = |speed: Option<Option<f64>>, period: f64| {
            bounds::contact_time_bound(period, speed.flatten())
        };
        Some(RollingOutput::Contact(ContactUpdate {
            a: p.a.clone(),
            b: p.b.clone(),
            phase,
            index: o.index,
            start_s: o.s.0,
            end_s: o.s.1,
            start_bound_s: bound(o.speeds.0, o.periods.0),
            end_bound_s: bound(o.speeds.1, o.periods.1),
            stamp_ns,
        }))
    }

    /// Closes pair `i`'s open interval (its end speed from the crossings near its end).
    pub(super) fn close_open(&mut self, i: usize, out: &mut Vec<RollingOutput>) {
        let p = &mut self.pairs[i];
        let Some(mut o) = p.open.take() else { return };
        let per = p.per as f64;
        let end = o.t.1;
        o.speeds.1 = Some(
            speed(
                p.records
                    .iter()
                    .filter(|r| r.t.1 <= end && r.t.1 >= end - per),
            )
            .map(|v| -v),
        );
        let stamp = p.next.unwrap_or(0);
        p.intervals.push_back(o);
        if p.intervals.len() > self.cfg.max_intervals {
            p.intervals.pop_front();
            p.dropped_intervals += 1;
        }
        out.extend(self.update(i, ContactPhase::End, stamp));
    }

    /// Start speeds that can be decided: no crossing can start before the start plus one
    /// frame period any more (or the pair is done); crossings nothing needs are dropped.
    pub(super) fn finish_speeds(&mut self, i: usize, all: bool) {
        let p = &mut self.pairs[i];
        let per = p.per as f64;
        let done_t = ((p.index - p.base) * p.per) as f64;
        let records = &p.records;
        let decide = |o: &mut Interval| {
            if o.speeds.0.is_none() && (all || o.t.0 + per < done_t) {
                o.speeds.0 = Some(speed(
                    records
                        .iter()
                        .filter(|r| r.t.0 >= o.t.0 && r.t.0 <= o.t.0 + per),
                ));
            }
        };
        for o in p.intervals.iter_mut().rev().take(4) {
            decide(o);
        }
        if let Some(o) = &mut p.open {
            decide(o);
        }
        let keep = done_t - 3.0 * per;
        let pending = p
            .intervals
            .iter()
            .rev()
            .take(4)
            .chain(p.open.iter())
            .filter(|o| o.speeds.0.is_none())
            .map(|o| o.t.0)
            .fold(f64::INFINITY, f64::min);
        while p
            .records
            .front()
            .is_some_and(|r| r.t.1 < keep && r.t.0 < pending)
        {
            p.records.pop_front();
        }
    }

    /// Feeds the intersection of the two bodies' frames at `s` and `hi` to the pair's
    /// overlap mesher. The frames are found, decoded, intersected and meshed by the
    /// bookkeeping, while the checker goes on ([`Self::settle_overlap`] takes the overlap
    /// back, before anything reads it or feeds it again). A period whose check found no
    /// overlap (`none`, see [`no_overlap`]) feeds empty intersections where they are BITS,
    /// its frames neither decoded nor intersected.
    pub(super) fn overlap_push(&mut self, i: usize, s: i64, hi: i64, none: bool) {
        self.settle_overlap(i);
        let (a, b) = (self.pairs[i].a.clone(), self.pairs[i].b.clone());
        let opts = self.opts;
        let geometry = |id: &str| {
            let body = &self.bodies[id];
            body.run(body.slabs[&s].run).map(|r| r.geometry)
        };
        let (ga, gb) = (geometry(&a), geometry(&b));
        // Periods left out since the last one (a partner absent or stopped): the intersection
        // stream has a gap there. Its run so far is closed and counted, and a new one starts.
        let gap = {
            let ov = &self.pairs[i].overlap;
            !ov.unknown && ov.last_pushed.is_some_and(|l| l != s)
        };
        if gap {
            let ov = &mut self.pairs[i].overlap;
            match run_overlap(ov) {
                Some((hv, b)) => {
                    ov.closed.0 += hv;
                    ov.closed.1 += b;
                    ov.mesher = None;
                    ov.acc = StatsAccumulator::default();
                    ov.sums = (0.0, 0.0);
                    ov.closed_sums = None;
                    ov.last_pushed = None;
                    ov.stamps = (0, 0, 0);
                }
                None => ov.unknown = true,
            }
        }
        let mut frames = Vec::with_capacity(2);
        for stamp in [s, hi] {
            let ov = &self.pairs[i].overlap;
            if ov.unknown || ov.last_pushed.is_some_and(|l| l >= stamp) {
                continue;
            }
            let both = ga.zip(gb).map(|(ga, gb)| {
                // Only where the intersection is BITS: a PERCENT one keeps the values below
                // the iso level, which place the next slab's vertices, and only decoding
                // finds them.
                let bits = chronotope_mesh::grid::intersection_geometry(&ga, &gb)
                    .is_some_and(|g| g.encoding == chronotope_mesh::Encoding::Bits.code());
                if none && bits {
                    return OverlapFrames::Empty { ga, gb };
                }
                OverlapFrames::Found {
                    fa: self.bodies[&a].frames_around(stamp),
                    ga,
                    fb: self.bodies[&b].frames_around(stamp),
                    gb,
                }
            });
            frames.push((stamp, both));
        }
        // What the contact events of this period say: the overlap through its start (its
        // bound too while reports are read; else not known here, where working it out would
        // hold up the check).
        self.pairs[i].overlap_known = pair_overlap_as(&self.pairs[i], self.cfg.reports);
        if frames.is_empty() {
            return;
        }
        let closing = self.pairs[i].interfering() && self.cfg.reports;
        let mut ov = std::mem::take(&mut self.pairs[i].overlap);
        self.pairs[i].overlap_job = Some(PoolJob::spawn(&self.bookkeeping, move || {
            feed_overlap(&mut ov, opts, frames, closing);
            ov
        }));
    }
}

/// Two bodies' frames at one stamp, each with its lattice: to be found among those around
/// it, or known to share no occupied voxel (their intersection is empty).
enum OverlapFrames {
    Found {
        fa: FramesAround,
        ga: GridGeometry,
        fb: FramesAround,
        gb: GridGeometry,
    },
    Empty {
        ga: GridGeometry,
        gb: GridGeometry,
    },
}

/// Whether a period's check says the two bodies do not overlap in it: no range of overlap,
/// no crossing, nothing undecided, and every taken tet of both OUTSIDE. Then neither of its
/// two frames has a voxel both bodies occupy: an occupied voxel's centre lies strictly
/// inside its body (no mesh vertex sits on a sample point), so a shared one would have the
/// bodies overlap around it, within the period.
fn no_overlap(r: &WindowResult) -> bool {
    r.ranges.is_empty()
        && r.crossings.is_empty()
        && r.undecided == 0
        && r.labels
            .iter()
            .all(|l| l.counts.inside == 0 && l.counts.interference == 0)
}

/// The intersection of two empty frames on lattices `ga` and `gb`, as
/// [`chronotope_mesh::grid::intersect_across`] gives it, kept with the overlap for its next
/// period apart.
fn empty_intersection(
    ov: &mut Overlap,
    ga: GridGeometry,
    gb: GridGeometry,
) -> Option<(OccupancyGrid, GridGeometry)> {
    if let Some((a, b, e)) = &ov.empty {
        if (*a, *b) == (ga, gb) {
            return e.clone();
        }
    }
    let e = chronotope_mesh::grid::intersect_across(
        &OccupancyGrid::empty(&ga),
        &ga,
        &OccupancyGrid::empty(&gb),
        &gb,
    );
    ov.empty = Some((ga, gb, e.clone()));
    e
}

/// Feeds `ov` the intersection of each stamp's frames, in order (`None`: a frame or a
/// geometry missing, so the overlap is not measurable); with `closing`, works out the
/// normals of the run closed at its last frame too (see `Overlap::closed_sums`).
fn feed_overlap(
    ov: &mut Overlap,
    opts: MesherOptions,
    frames: Vec<(i64, Option<OverlapFrames>)>,
    closing: bool,
) {
    for (stamp, both) in frames {
        if ov.unknown || ov.last_pushed.is_some_and(|l| l >= stamp) {
            continue;
        }
        let intersection = match both {
            None => None,
            Some(OverlapFrames::Found { fa, ga, fb, gb }) => fa.frame(&ga).and_then(|fa| {
                let fb = fb.frame(&gb)?;
                chronotope_mesh::grid::intersect_across(&fa, &ga, &fb, &gb)
            }),
            Some(OverlapFrames::Empty { ga, gb }) => empty_intersection(ov, ga, gb),
        };
        let Some((both, ga)) = intersection else {
            ov.unknown = true;
            continue;
        };
        if ov.geometry.is_some_and(|g| g != ga) {
            ov.unknown = true;
            continue;
        }
        if ov.mesher.is_none() {
            match Mesher::new(opts) {
                Ok(m) => ov.mesher = Some(m),
                Err(_) => {
                    ov.unknown = true;
                    continue;
                }
            }
        }
        let m = ov.mesher.as_mut().expect("set above");
        ov.geometry = Some(ga);
        match m.push_decoded(stamp, ga, both) {
            Ok(slab) => {
                ov.last_pushed = Some(stamp);
                ov.stamps = if ov.stamps.2 == 0 {
                    (stamp, stamp, 1)
                } else {
                    (ov.stamps.0, stamp, ov.stamps.2 + 1)
                };
                if let Some(slab) = slab {
                    // The intersection's cap at the run's first frame: checked with its
                    // first slab, counted in its normals, and not kept.
                    let first_cap = (slab.index == 0)
                        .then(|| m.first_frame().and_then(|k| m.cap(k, CapSide::Low)))
                        .flatten();
                    if let Some(cap) = &first_cap {
                        ov.sums = add_normals(ov.sums, cap);
                    }
                    ov.acc.add_lateral(slab.lateral_ref(), first_cap.as_ref());
                    ov.sums = add_normals(ov.sums, &slab.mesh);
                }
                // The run as it would close now, at this frame.
                ov.closed_sums = None;
                if closing && ov.stamps.2 >= 2 {
                    ov.closed_sums = closing_sums(ov);
                }
            }
            Err(_) => ov.unknown = true,
        }
    }
}

/// What one body's window is made of (see [`WindowBody`]).
#[derive(Debug, Clone)]
pub(super) struct WindowSpec {
    pub(super) geometry: GridGeometry,
    pub(super) lo: u32,
    pub(super) slabs: Vec<Arc<TetMesh>>,
    pub(super) centre: usize,
    pub(super) low: Option<Arc<TetMesh>>,
    pub(super) high: Option<Arc<TetMesh>>,
    pub(super) mul: i64,
    pub(super) add: [i64; 4],
    /// Run number of the first taken tet.
    pub(super) first_tet: u64,
    /// The box of its parts' vertices on the body's lattice (from each slab's, kept with
    /// it, and the caps').
    pub(super) bounds: Option<SpatialBounds>,
}

/// Whether two windows' boxes are apart (a gap on some spatial axis) on the pair's
/// lattice: then no tet of one meets the other body, nor lies inside it.
pub(super) fn apart(a: &WindowSpec, b: &WindowSpec) -> bool {
    let (Some(x), Some(y)) = (a.spatial_box(), b.spatial_box()) else {
        return true;
    };
    (0..3).any(|k| x.1[k] < y.0[k] || y.1[k] < x.0[k])
}

/// How two windows whose boxes meet are checked.
pub(super) enum Approach {
    /// One of them has no tet near the other's box (see [`WindowBody::kept_tets`]): every
    /// tet of both OUTSIDE, as for windows apart; neither is prepared. A robot's arm
    /// reaching over a table has a box that meets the table's long before a tet of the
    /// arm comes near it.
    Separated(Box<WindowResult>),
    /// Both are prepared, first the one with fewer tets near the other's box
    /// (`a_first`: the pair's first body's), then the other near the tets that one kept
    /// (see [`crate::period::Clip`]).
    Near { a_first: bool },
}

/// How windows `wa` and `wb` (boxes not apart) are checked: the tets each keeps near the
/// other's box are counted, on two threads.
pub(super) fn approach(wa: &WindowSpec, wb: &WindowSpec) -> Approach {
    let near = |w: &WindowSpec, o: &WindowSpec| {
        w.body("", o.spatial_box().map(Partner::whole)).kept_tets()
    };
    match rayon::join(|| near(wa, wb), || near(wb, wa)) {
        (0, _) | (_, 0) => Approach::Separated(Box::new(WindowResult {
            labels: [wa.all_outside(), wb.all_outside()],
            ..WindowResult::default()
        })),
        (na, nb) => Approach::Near { a_first: na <= nb },
    }
}

/// Prepares and checks the two bodies' windows of a pair (`(id, window)` each), as their
/// [`approach`] says.
///
/// A body's window already prepared (for another pair's period: `ready` gives it, when it
/// is the same window and holds every tet its partner needs) is not prepared again; one
/// prepared here holds only the tets its partner needs. The two prepared windows are
/// returned with the result, for the cache.
pub(super) fn check_specs(
    (a, wa): (&str, &WindowSpec),
    (b, wb): (&str, &WindowSpec),
    ready: impl Fn(&str, &WindowSpec, &Partner) -> Option<Arc<PreparedWindow>> + Sync,
) -> WindowChecked {
    match approach(wa, wb) {
        Approach::Separated(r) => Ok((*r, None)),
        // On rayon's pool, like the windows' other work: a node's own thread only waits.
        Approach::Near { a_first } => {
            rayon::scope(|_| check_near((a, wa), (b, wb), a_first, &ready))
        }
    }
}

/// [`check_specs`] of two windows whose [`approach`] is [`Approach::Near`]: the first
/// (`a_first`: `wa`) is prepared near the other's box, the other then near the tets it
/// kept (see [`crate::period::Clip`]).
pub(super) fn check_near(
    (a, wa): (&str, &WindowSpec),
    (b, wb): (&str, &WindowSpec),
    a_first: bool,
    ready: impl Fn(&str, &WindowSpec, &Partner) -> Option<Arc<PreparedWindow>> + Sync,
) -> WindowChecked {
    let prepared = |id: &str, w: &WindowSpec, partner: Option<Partner>| {
        let Some(partner) = partner else {
            return prepare_spec(id, w, None);
        };
        match ready(id, w, &partner) {
            Some(p) => Ok(p),
            None => prepare_spec(id, w, Some(partner)),
        }
    };
    let (ba, bb) = (wa.spatial_box(), wb.spatial_box());
    let ((f, wf, bo), (o, wo, bf)) = if a_first {
        ((a, wa, bb), (b, wb, ba))
    } else {
        ((b, wb, ba), (a, wa, bb))
    };
    let pf = prepared(f, wf, bo.map(Partner::whole))?;
    let po = prepared(o, wo, bf.map(|whole| Partner::prepared(whole, &pf)))?;
    let (pa, pb) = if a_first { (pf, po) } else { (po, pf) };
    Ok((check_window(&pa, &pb), Some([pa, pb])))
}

impl RollingChecker {
    /// Body `id`'s window `w` as a window prepared before (for an earlier period, kept in
    /// the cache or for a body at rest) moved, if `w` is that window's moved copy
    /// ([`WindowSpec::moved_copy_of`]) and, moved, it serves a partner in box `partner`.
    pub(super) fn moved(
        &self,
        id: &str,
        w: &WindowSpec,
        partner: &Partner,
    ) -> Option<Arc<PreparedWindow>> {
        [self.prepared.get(id), self.rest.get(id)]
            .into_iter()
            .flatten()
            .flatten()
            .find_map(|h| {
                let d = w.moved_copy_of(&h.spec)?;
                h.window
                    .serves_moved(d, partner)
                    .then(|| h.window.moved_by(d).map(Arc::new))
                    .flatten()
            })
    }
}

/// Prepares body `id`'s window, only the tets partners `clip` need if given.
pub(super) fn prepare_spec(
    id: &str,
    w: &WindowSpec,
    clip: Option<Partner>,
) -> Result<Arc<PreparedWindow>, crate::period::WindowError> {
    prepare_window(&w.body(id, clip)).map(Arc::new)
}

/// The window prepared for body `id` in `cache`, if it is the same window as `w` and
/// serves `partner`.
pub(super) fn cached(
    cache: &HeldWindows,
    id: &str,
    w: &WindowSpec,
    partner: &Partner,
) -> Option<Arc<PreparedWindow>> {
    cache
        .get(id)?
        .iter()
        .find(|h| h.spec.same_as(w) && h.window.serves(partner))
        .map(|h| h.window.clone())
}

/// A window's result, with the two bodies' prepared windows (`None`: not prepared, see
/// [`Approach::Separated`]).
pub(super) type WindowChecked =
    Result<(WindowResult, Option<[Arc<PreparedWindow>; 2]>), crate::period::WindowError>;

impl WindowSpec {
    /// The same window: the same pieces (by identity), placement and numbering.
    pub(super) fn same_as(&self, o: &WindowSpec) -> bool {
        let same = |x: &Arc<TetMesh>, y: &Arc<TetMesh>| Arc::ptr_eq(x, y);
        let same_opt = |x: &Option<Arc<TetMesh>>, y: &Option<Arc<TetMesh>>| match (x, y) {
            (Some(x), Some(y)) => same(x, y),
            (None, None) => true,
            _ => false,
        };
        self.geometry == o.geometry
            && self.lo == o.lo
            && self.slabs.len() == o.slabs.len()
            && self.slabs.iter().zip(&o.slabs).all(|(x, y)| same(x, y))
            && self.centre == o.centre
            && same_opt(&self.low, &o.low)
            && same_opt(&self.high, &o.high)
            && self.mul == o.mul
            && self.add == o.add
            && self.first_tet == o.first_tet
    }

    /// If this window is `earlier` one or more frame periods on, moved (the same lattice
    /// and placement, no cap, each slab an exact copy of `earlier`'s moved by one lattice
    /// vector: a body at rest, or one that stepped by whole voxels), that move in checker
    /// coordinates: its prepared window is then `earlier`'s moved by it. Compares the
    /// slabs exactly ([`TetMesh::is_moved_copy_of`]).
    pub(super) fn moved_copy_of(&self, earlier: &WindowSpec) -> Option<[i64; 4]> {
        let plain = |w: &WindowSpec| w.low.is_none() && w.high.is_none();
        if self.geometry != earlier.geometry
            || self.mul != earlier.mul
            || self.add[..3] != earlier.add[..3]
            || self.centre != earlier.centre
            || self.slabs.len() != earlier.slabs.len()
            || self.lo <= earlier.lo
            || !plain(self)
            || !plain(earlier)
        {
            return None;
        }
        let frames = i64::from(self.lo - earlier.lo);
        let dt = i32::try_from(i64::from(self.geometry.scale) * frames).ok()?;
        // The move of the first vertex of the first slab with vertices (each slab spans one
        // period, so its move in time is `dt`); every vertex of every slab must make it.
        let firsts = self
            .slabs
            .iter()
            .zip(&earlier.slabs)
            .find_map(|(x, y)| Some((x.vertices.first()?, y.vertices.first()?)));
        let d = match firsts {
            Some((p, q)) => {
                let mut d = [0; 4];
                for k in 0..4 {
                    d[k] = p[k].checked_sub(q[k])?;
                }
                d
            }
            None => [0, 0, 0, dt],
        };
        if d[3] != dt
            || !self
                .slabs
                .iter()
                .zip(&earlier.slabs)
                .all(|(x, y)| x.is_moved_copy_of(y, d))
        {
            return None;
        }
        // A lattice vector d moves the window's checker coordinates (c·factor·mul + add,
        // time counted from the window's first frame) by d·factor·mul in space, and by the
        // change of `add` in time.
        let f = i64::from(CHECKER_FACTOR) * self.mul;
        Some([
            i64::from(d[0]) * f,
            i64::from(d[1]) * f,
            i64::from(d[2]) * f,
            self.add[3] - earlier.add[3],
        ])
    }

    /// The box of every vertex of the window on the pair's lattice, spatial axes only
    /// (`None` for a window without vertices).
    pub(super) fn spatial_box(&self) -> Option<SpatialBox> {
        debug_assert_eq!(
            self.bounds.map(|b| on_pair_lattice(b, self.mul, &self.add)),
            self.body("", None).spatial_box()
        );
        self.bounds.map(|b| on_pair_lattice(b, self.mul, &self.add))
    }

    /// Every taken tet OUTSIDE.
    fn all_outside(&self) -> TakenLabels {
        let n = self.slabs.len();
        let pieces = [
            if self.centre == 0 {
                self.low.as_ref().map_or(0, |m| m.tets.len())
            } else {
                0
            },
            self.slabs[self.centre].tets.len(),
            if self.centre + 1 == n {
                self.high.as_ref().map_or(0, |m| m.tets.len())
            } else {
                0
            },
        ];
        let total: usize = pieces.iter().sum();
        TakenLabels {
            labels: vec![Label::Outside as u8; total],
            counts: LabelCounts {
                outside: total as u64,
                ..LabelCounts::default()
            },
            pieces,
        }
    }

    fn body<'a>(&'a self, id: &'a str, clip: Option<Partner>) -> WindowBody<'a> {
        WindowBody {
            id,
            geometry: self.geometry,
            lo: self.lo,
            slabs: self.slabs.iter().map(|m| m.as_ref()).collect(),
            centre: self.centre,
            low: self.low.as_deref(),
            high: self.high.as_deref(),
            mul: self.mul,
            add: self.add,
            clip,
        }
    }
}

/// The map of two bodies onto their pair's lattice.
pub(super) struct PairLattice {
    pub(super) scale: i32,
    pub(super) ratio_a: i64,
    pub(super) ratio_b: i64,
    pub(super) shift_a: [i64; 3],
    pub(super) shift_b: [i64; 3],
}

pub(super) fn pair_lattice(
    ga: &GridGeometry,
    gb: &GridGeometry,
) -> Result<PairLattice, crate::LatticeMismatch> {
    if (ga.resolution - gb.resolution).abs() > 1e-9 * ga.resolution {
        return Err(crate::LatticeMismatch::Resolution {
            a: ga.resolution,
            b: gb.resolution,
        });
    }
    let off = origin_offset(&ga.origin, &gb.origin, ga.resolution)?;
    let scale = ga.scale.max(gb.scale).max(2);
    Ok(PairLattice {
        scale,
        ratio_a: i64::from(scale / ga.scale.max(1)).max(1),
        ratio_b: i64::from(scale / gb.scale.max(1)).max(1),
        shift_a: [0; 3],
        shift_b: off,
    })
}

#[cfg(test)]
mod tests {
    use super::super::{CheckPlan, Piece, PieceKind, RollingConfig};
    use super::*;
    use chronotope_kernel::LatticePoint;

    /// A body's slabs, frame by frame: a box and a ball at rest (frames 0-2), stepped one
    /// voxel along +x (frame 3) and at rest there (3-5), on a 10³ lattice.
    fn slabs() -> (Vec<Arc<TetMesh>>, GridGeometry) {
        let (_, slabs) = chronotope_mesh::mesher::test_stream([10; 3], 6, |k, x, y, z| {
            let x = x - i32::from(k >= 3);
            let ball = (x - 3).pow(2) + (y - 4).pow(2) + (z - 5).pow(2) <= 5;
            ball || ((1..3).contains(&x) && (6..9).contains(&y) && (2..4).contains(&z))
        });
        let geometry = slabs[0].geometry;
        (
            slabs.into_iter().map(|s| Arc::new(s.mesh)).collect(),
            geometry,
        )
    }

    /// A rolling checker of the pair `/a`, `/b` with the default options.
    fn checker_of_a_and_b() -> RollingChecker {
        checker_of_a_and_b_with(RollingConfig::default())
    }

    /// A rolling checker of the pair `/a`, `/b` with `cfg`.
    fn checker_of_a_and_b_with(cfg: RollingConfig) -> RollingChecker {
        let plan = CheckPlan {
            pairs: Some(vec![("/a".into(), "/b".into())]),
            movable: Vec::new(),
            time_scale: None,
            frame_ids: Default::default(),
            rotation: Default::default(),
        };
        RollingChecker::new(plan, MesherOptions::default(), cfg)
    }

    fn spec(
        (slabs, geometry): &(Vec<Arc<TetMesh>>, GridGeometry),
        lo: u32,
        mul: i64,
        add: [i64; 4],
    ) -> WindowSpec {
        let geometry = *geometry;
        WindowSpec {
            geometry,
            lo,
            slabs: vec![slabs[lo as usize].clone()],
            centre: 0,
            low: None,
            high: None,
            mul,
            add,
            first_tet: 0,
            bounds: slabs[lo as usize].spatial_bounds(),
        }
    }

    /// A run lets its opening cap go once its first slab is no longer kept, keeping only
    /// the cap's count of tets; the run's figures at its end are still those of its whole
    /// mesh welded in one piece (`BodyGluer`).
    #[test]
    fn a_run_lets_its_opening_cap_go_with_its_first_slab() {
        let ball = |cx: i32| moving_ball(cx, 4);
        let mut c = checker_of_a_and_b();
        let frames = 12;
        let mut glued = Vec::new();
        let mut pieces: Vec<Vec<Piece>> = Vec::new();
        for (body, cx) in [("/a", 3), ("/b", 14)] {
            let ps = pieces_of(body, [20, 9, 9], frames, ball(cx));
            let (cap, end) = (&ps[0], &ps[ps.len() - 1]);
            // The ball's frames all hold as many voxels.
            assert_eq!(cap.occupied, end.occupied);
            let mut g = chronotope_mesh::glue::BodyGluer::new();
            g.first_cap(&cap.mesh, cap.occupied);
            for p in &ps[1..ps.len() - 1] {
                let lateral = chronotope_mesh::stats::LateralRef {
                    index: u64::from(p.index),
                    stamps_ns: p.stamps_ns,
                    geometry: &p.geometry,
                    mesh: &p.mesh,
                    unsure: p.unsure,
                    displacement: p.displacement,
                };
                g.lateral(lateral, None);
            }
            g.last_cap(&end.mesh, end.occupied);
            glued.push((
                cap.mesh.tets.len(),
                g.finish(u64::from(frames), Vec::new(), None),
            ));
            pieces.push(ps);
        }
        let mut out = Vec::new();
        for j in 0..pieces[0].len() {
            for ps in &pieces {
                c.on_piece(ps[j].clone(), &mut out);
            }
            if j == pieces[0].len() - 2 {
                // Every slab in: the first ones are decided and gone.
                c.settle_all_stats();
                for (body, (cap_tets, _)) in ["/a", "/b"].into_iter().zip(&glued) {
                    let b = &c.bodies[body];
                    let r = &b.runs[0];
                    assert!(!b.slabs.contains_key(&r.first_stamp), "{body}");
                    assert!(
                        r.first_cap.tets.is_empty(),
                        "{body}: its opening cap let go"
                    );
                    assert_eq!(r.first_cap_tets, *cap_tets as u64, "{body}");
                }
            }
        }
        c.finish(&mut out);
        for (body, (_, whole)) in ["/a", "/b"].into_iter().zip(&glued) {
            let b = &c.bodies[body];
            let st = b.runs.iter().find_map(|r| r.stats.as_ref());
            let (tets, closed) = match st {
                Some(st) => (st.tets, st.closed.is_closed()),
                None => (b.totals.tets, b.totals.closed),
            };
            assert!(whole.stats.closed.is_closed());
            assert_eq!((tets, closed), (whole.stats.tets, true), "{body}");
        }
    }

    /// With the bookkeeping held up (a pool whose only thread is busy), a body's pieces
    /// queue behind the one being added: the checker takes in up to `STATS_QUEUED` of them
    /// without adding any itself, then brings the statistics up to date; a report adds
    /// what is queued. Every figure is the one a checker whose bookkeeping keeps up gives.
    #[test]
    fn statistics_queue_behind_a_busy_bookkeeping_and_add_up_the_same() {
        let ball = |cx: i32| moving_ball(cx, 3);
        let frames = 12;
        let pieces: Vec<Vec<Piece>> = [("/a", 3), ("/b", 12)]
            .into_iter()
            .map(|(body, cx)| pieces_of(body, [20, 9, 9], frames, ball(cx)))
            .collect();
        let (held, release) = super::super::bookkeeping::held_pool();
        let mut busy = checker_of_a_and_b();
        busy.set_bookkeeping_pool(held);
        let mut keeping_up = checker_of_a_and_b();
        keeping_up.set_bookkeeping_pool(None);
        let (mut out, mut out_keeping_up) = (Vec::new(), Vec::new());
        let mut most_queued = 0;
        for j in 0..pieces[0].len() {
            for ps in &pieces {
                busy.on_piece(ps[j].clone(), &mut out);
                keeping_up.on_piece(ps[j].clone(), &mut out_keeping_up);
                keeping_up.settle_all_stats();
                let b = &busy.bodies[&ps[j].body];
                most_queued = most_queued.max(b.stats_queue.len());
                assert!(
                    b.stats_queue.len() <= super::super::STATS_QUEUED,
                    "piece {j}"
                );
                if (1..=super::super::STATS_QUEUED + 1).contains(&j) {
                    // The first slab's job (never run by the held pool) and the slabs
                    // queued behind it: nothing added yet.
                    assert_eq!(b.stats_queue.len(), j - 1, "piece {j}");
                    assert!(b.stats_job.as_ref().is_some_and(|j| !j.job.finished()));
                    assert!(busy.statistics_pending());
                }
            }
            if j == 8 {
                // A report brings everything up to date, and agrees.
                let (r, k) = (busy.report(), keeping_up.report());
                assert!(!busy.statistics_pending());
                assert_eq!(bodies_of(&r), bodies_of(&k));
            }
        }
        assert_eq!(most_queued, super::super::STATS_QUEUED);
        busy.finish(&mut out);
        keeping_up.finish(&mut out_keeping_up);
        let (r, k) = (busy.report(), keeping_up.report());
        assert_eq!(bodies_of(&r), bodies_of(&k));
        assert!(bodies_of(&r).iter().all(|b| b.3), "{:?}", bodies_of(&r));
        drop(release);
    }

    /// A report as it stands computes nothing of the bookkeeping's: with the bookkeeping
    /// held up after a few pieces, its bodies count every frame and tet accepted, their
    /// hypervolume is the one before the pieces still out (the statistics taken out for the
    /// first of them, read as they were), and everything stays pending; once the pool runs,
    /// it comes to the complete report without a report that waits.
    #[test]
    fn a_report_as_it_stands_waits_for_nothing_and_comes_to_the_complete_one() {
        let frames = 12;
        let pieces: Vec<Vec<Piece>> = [("/a", 3), ("/b", 12)]
            .into_iter()
            .map(|(body, cx)| pieces_of(body, [20, 9, 9], frames, moving_ball(cx, 3)))
            .collect();
        let mut busy = checker_of_a_and_b();
        busy.set_bookkeeping_pool(None);
        let mut keeping_up = checker_of_a_and_b();
        keeping_up.set_bookkeeping_pool(None);
        let (mut out, mut out_keeping_up) = (Vec::new(), Vec::new());
        let (held, release) = super::super::bookkeeping::held_pool();
        let mut before_held = Vec::new();
        let mut held = Some(held);
        for j in 0..=8 {
            if j == 6 {
                // Everything added so far; the pieces from here wait for a held pool.
                busy.settle_all_stats();
                before_held = bodies_of(&busy.report());
                busy.set_bookkeeping_pool(held.take().expect("once"));
            }
            for ps in &pieces {
                busy.on_piece(ps[j].clone(), &mut out);
                keeping_up.on_piece(ps[j].clone(), &mut out_keeping_up);
                keeping_up.settle_all_stats();
            }
        }
        let complete = bodies_of(&keeping_up.report());
        let stands = bodies_of(&busy.report_as_it_stands());
        assert!(
            busy.statistics_pending(),
            "nothing of the pool's computed here"
        );
        for ((s, c), b) in stands.iter().zip(&complete).zip(&before_held) {
            // Frames and tets as accepted, the hypervolume before the held pieces, open.
            assert_eq!(
                (&s.0, s.1, s.2, s.3),
                (&c.0, c.1, c.2, false),
                "{s:?} {c:?}"
            );
            assert_eq!(s.4, b.4, "{s:?}, before the held pieces {b:?}");
            assert!(f64::from_bits(s.4) > 0.0 && s.4 != c.4, "{s:?} {c:?}");
        }
        drop(release);
        let start = std::time::Instant::now();
        let stands = loop {
            let r = busy.report_as_it_stands();
            if !busy.statistics_pending() {
                break bodies_of(&r);
            }
            assert!(start.elapsed().as_secs() < 60, "the pool never finished");
            std::thread::sleep(std::time::Duration::from_millis(5));
        };
        assert_eq!(stands, complete);
    }

    /// A ball of radius √6 voxels centred at (cx, 4, 4) in frame 0, one voxel on along x
    /// every `every` frames.
    fn moving_ball(cx: i32, every: u32) -> impl Fn(u32, i32, i32, i32) -> bool {
        move |k, x, y, z| {
            let x = x - cx - (k / every) as i32;
            x * x + (y - 4).pow(2) + (z - 4).pow(2) <= 6
        }
    }

    /// A report's body figures: id, frames, tets, closed, hypervolume's bits.
    fn bodies_of(r: &crate::report::Report) -> Vec<(String, u64, u64, bool, u64)> {
        r.bodies
            .iter()
            .map(|b| {
                (
                    b.id.clone(),
                    b.frames,
                    b.tets,
                    b.closed,
                    b.hypervolume_m3s.to_bits(),
                )
            })
            .collect()
    }

    /// A piece whose tet names a vertex past its vertex table is refused by name (the tet
    /// said), and nothing of it is kept; the same piece with its tets in range is taken.
    #[test]
    fn a_piece_naming_a_vertex_past_its_table_is_refused() {
        let (slabs, geometry) = slabs();
        let mut c = checker_of_a_and_b();
        let piece = |mesh: TetMesh| Piece {
            body: "/a".into(),
            kind: PieceKind::CapStart,
            index: 0,
            stamps_ns: (0, 0),
            geometry,
            occupied: 1,
            unsure: None,
            displacement: 0,
            mesh: Arc::new(mesh),
            frame_id: String::new(),
        };
        let mut bad = (*slabs[0]).clone();
        let past = bad.vertices.len() as u32;
        let at = bad.tets.len() / 2;
        bad.tets[at][2] = past;
        let mut out = Vec::new();
        c.on_piece(piece(bad), &mut out);
        let problems: Vec<String> = out
            .iter()
            .filter_map(|o| match o {
                RollingOutput::Problem(kind, text) => Some(format!("{kind}: {text}")),
                _ => None,
            })
            .collect();
        assert_eq!(
            problems,
            [format!(
                "bad_piece: /a: tet {at} of a piece names a vertex past its {past}; ignored"
            )]
        );
        assert!(c.bodies["/a"].runs.is_empty());
        let mut out = Vec::new();
        c.on_piece(piece((*slabs[0]).clone()), &mut out);
        assert!(!out.iter().any(|o| matches!(o, RollingOutput::Problem(..))));
        assert_eq!(c.bodies["/a"].runs.len(), 1);
    }

    /// Asserts that `part` gives every label, count, crossing, range and undecided tet
    /// `full` gives (`at`: the case, for the message).
    fn assert_same_answer(part: &WindowResult, full: &WindowResult, at: &str) {
        for k in 0..2 {
            assert_eq!(
                part.labels[k].labels, full.labels[k].labels,
                "{at} body {k}"
            );
            assert_eq!(
                part.labels[k].counts, full.labels[k].counts,
                "{at} body {k}"
            );
            assert_eq!(
                part.labels[k].pieces, full.labels[k].pieces,
                "{at} body {k}"
            );
        }
        assert_eq!(part.crossings, full.crossings, "{at}");
        let sorted = |r: &[(f64, f64)]| {
            let mut r = r.to_vec();
            r.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.total_cmp(&y.1)));
            r
        };
        assert_eq!(sorted(&part.ranges), sorted(&full.ranges), "{at}");
        assert_eq!(part.undecided, full.undecided, "{at}");
    }

    /// Two windows checked with each prepared only near the other (and inclusion tests
    /// towards far points on the side its clip chose) give every label, count, crossing
    /// and range the full windows give: a small body moved all around and through a
    /// bigger one (apart, touching, crossing, nested, and at the bigger one's hollow).
    /// So do they with either prepared first and the other near the tets it kept, and
    /// as [`check_specs`] chooses.
    #[test]
    fn windows_prepared_near_their_partner_answer_as_whole_ones() {
        let big = chronotope_mesh::mesher::test_stream([12; 3], 3, |k, x, y, z| {
            let x = x - i32::from(k >= 2);
            let shell = (2..10).contains(&x) && (2..9).contains(&y) && (3..8).contains(&z);
            let hollow = (4..7).contains(&x) && (4..7).contains(&y) && (5..7).contains(&z);
            shell && !hollow
        })
        .1;
        let small = chronotope_mesh::mesher::test_stream([12; 3], 3, |k, x, y, z| {
            (x - 3 - i32::from(k >= 1)).pow(2) + (y - 3).pow(2) + (z - 3).pow(2) <= 2
        })
        .1;
        let geometry = big[0].geometry;
        let (big, small): (Vec<Arc<TetMesh>>, Vec<Arc<TetMesh>>) = (
            big.into_iter().map(|s| Arc::new(s.mesh)).collect(),
            small.into_iter().map(|s| Arc::new(s.mesh)).collect(),
        );
        let f = i64::from(CHECKER_FACTOR) * i64::from(geometry.scale);
        let (mut clipped, mut inside, mut crossing) = (0, 0, 0);
        for lo in 0..2u32 {
            let t = i64::from(lo) * f;
            let wa = spec(&(big.clone(), geometry), lo, 1, [0, 0, 0, t]);
            for d in 0..5i64.pow(3) {
                let d = [d % 5, d / 5 % 5, d / 25].map(|v| (2 * v - 2) * f);
                let wb = spec(&(small.clone(), geometry), lo, 1, [d[0], d[1], d[2], t]);
                if apart(&wa, &wb) {
                    continue;
                }
                let at = format!("{lo} {d:?}");
                let whole = |id: &str, w: &WindowSpec| prepare_spec(id, w, None).unwrap();
                let near = |id: &str, w: &WindowSpec, o: &WindowSpec| {
                    prepare_spec(id, w, o.spatial_box().map(Partner::whole)).unwrap()
                };
                let full = check_window(&whole("/a", &wa), &whole("/b", &wb));
                let (pa, pb) = (near("/a", &wa, &wb), near("/b", &wb, &wa));
                clipped +=
                    usize::from(pa.body.mesh.tets.len() < whole("/a", &wa).body.mesh.tets.len());
                assert_same_answer(&check_window(&pa, &pb), &full, &at);
                assert_either_first_answers_as_whole(("/a", &wa), ("/b", &wb), &full, &at);
                let (r, _) = check_specs(("/a", &wa), ("/b", &wb), |_, _, _| None).unwrap();
                assert_same_answer(&r, &full, &at);
                for k in 0..2 {
                    inside += full.labels[k].counts.inside as usize;
                }
                crossing += usize::from(!full.crossings.is_empty());
            }
        }
        assert!(
            clipped > 20 && inside > 0 && crossing > 20,
            "{clipped} {inside} {crossing}"
        );
    }

    /// Asserts that windows `wa` and `wb` checked with either prepared first (the other
    /// near the tets it kept) answer as `full`, and that the second never keeps more tets
    /// than near the first's whole box; how many times it kept fewer.
    fn assert_either_first_answers_as_whole(
        (a, wa): (&str, &WindowSpec),
        (b, wb): (&str, &WindowSpec),
        full: &WindowResult,
        at: &str,
    ) -> usize {
        let near = |id: &str, w: &WindowSpec, o: &WindowSpec| {
            prepare_spec(id, w, o.spatial_box().map(Partner::whole)).unwrap()
        };
        let mut fewer = 0;
        for a_first in [true, false] {
            let (r, p) = check_near((a, wa), (b, wb), a_first, |_, _, _| None).unwrap();
            assert_same_answer(&r, full, &format!("{at}, {a} first: {a_first}"));
            let [pa, pb] = p.unwrap();
            let (second, whole_box) = if a_first {
                (pb, near(b, wb, wa))
            } else {
                (pa, near(a, wa, wb))
            };
            let (n, m) = (second.body.mesh.tets.len(), whole_box.body.mesh.tets.len());
            assert!(n <= m, "{at}: {n} > {m}");
            fewer += usize::from(n < m);
        }
        fewer
    }

    /// Windows whose boxes meet but one of which has no tet near the other's box (an arm
    /// arching over a table: a post beside it, a bar above it) are answered without being
    /// prepared, exactly as the whole windows' check answers them; the same placements
    /// nearer, where the bar reaches the table, are checked as before.
    #[test]
    fn windows_with_no_tet_near_each_other_answer_as_whole_ones() {
        let slabs = |f: &dyn Fn(u32, i32, i32, i32) -> bool| {
            let s = chronotope_mesh::mesher::test_stream([16; 3], 3, f).1;
            let geometry = s[0].geometry;
            let meshes: Vec<Arc<TetMesh>> = s.into_iter().map(|x| Arc::new(x.mesh)).collect();
            (meshes, geometry)
        };
        let table = slabs(&|_, x, y, z| {
            (6..15).contains(&x) && (1..15).contains(&y) && (1..7).contains(&z)
        });
        // The arm's post stands on the floor beside the table; its bar comes down `dz`
        // voxels over it (one more in the last frame), from a voxel above the table's top
        // to through it.
        let arm = |dz: i32| {
            slabs(&move |k, x, y, z| {
                let z = z + dz + i32::from(k >= 2);
                let post = (1..3).contains(&x) && (1 + dz..14 + dz).contains(&z);
                let bar = (1..13).contains(&x) && (12..14).contains(&z);
                (post || bar) && (5..8).contains(&y)
            })
        };
        let geometry = table.1;
        let f = i64::from(CHECKER_FACTOR) * i64::from(geometry.scale);
        let (mut skipped, mut checked, mut crossing, mut inside, mut fewer) = (0, 0, 0, 0, 0);
        for lo in 0..2u32 {
            let t = i64::from(lo) * f;
            let wt = spec(&table, lo, 1, [0, 0, 0, t]);
            for d in 0..5i64 * 7 {
                let (dx, dz) = (d % 5 - 2, d / 5);
                let wa = spec(&arm(dz as i32), lo, 1, [dx * f, 0, 0, t]);
                if apart(&wa, &wt) {
                    continue;
                }
                let at = format!("{lo} {dx} {dz}");
                let whole = |id: &str, w: &WindowSpec| prepare_spec(id, w, None).unwrap();
                let full = check_window(&whole("/a", &wa), &whole("/b", &wt));
                let (r, prepared) = check_specs(("/a", &wa), ("/b", &wt), |_, _, _| None).unwrap();
                assert_same_answer(&r, &full, &at);
                match approach(&wa, &wt) {
                    Approach::Separated(r) => {
                        assert!(prepared.is_none(), "{at}");
                        assert!(full.crossings.is_empty() && full.ranges.is_empty(), "{at}");
                        assert_same_answer(&r, &full, &at);
                        skipped += 1;
                    }
                    Approach::Near { .. } => {
                        assert!(prepared.is_some(), "{at}");
                        checked += 1;
                        crossing += usize::from(!full.crossings.is_empty());
                        inside += full.labels.iter().map(|l| l.counts.inside).sum::<u64>();
                        fewer += assert_either_first_answers_as_whole(
                            ("/a", &wa),
                            ("/b", &wt),
                            &full,
                            &at,
                        );
                    }
                }
            }
        }
        assert!(
            skipped > 5 && checked > 5 && crossing > 2 && inside > 0 && fewer > 5,
            "{skipped} {checked} {crossing} {inside} {fewer}"
        );
    }

    /// Each tet of a prepared window by its four corners (sorted): the window as a set,
    /// whatever its leaf order.
    fn corners(p: &PreparedWindow) -> Vec<[LatticePoint; 4]> {
        let m = &p.body.mesh;
        let mut all: Vec<[LatticePoint; 4]> = m
            .tets
            .iter()
            .map(|t| {
                let mut c = t.map(|v| m.vertices[v as usize]);
                c.sort_unstable();
                c
            })
            .collect();
        all.sort_unstable();
        all
    }

    /// A window whose slab is an earlier one moved (in time only, or one voxel in space
    /// too) is found to be that window moved, and the moved prepared window has exactly the
    /// tets, normals' hyperplanes and band a fresh preparation gives; any other is not.
    #[test]
    fn a_window_of_a_moved_copy_is_the_earlier_one_moved() {
        let slabs = slabs();
        assert_eq!(slabs.0.len(), 5);
        let scale = i64::from(slabs.1.scale);
        let f = i64::from(CHECKER_FACTOR);
        for mul in [1i64, 2] {
            let per = scale * f * mul;
            let at = |lo: u32| spec(&slabs, lo, mul, [3 * f, 0, 0, i64::from(lo) * per + 5]);
            // Rest (0 -> 1), a step (2 is the moving slab; 3 is 1 moved one voxel), rest
            // again (3 -> 4), and two windows apart (0 -> 4).
            let cases = [
                (0, 1, Some([0, 0, 0, per])),
                (1, 2, None),
                (2, 3, None),
                (1, 3, Some([scale * f * mul, 0, 0, 2 * per])),
                (3, 4, Some([0, 0, 0, per])),
                (0, 4, Some([scale * f * mul, 0, 0, 4 * per])),
                (1, 0, None),
            ];
            for (a, b, want) in cases {
                let (wa, wb) = (at(a), at(b));
                assert_eq!(wb.moved_copy_of(&wa), want, "mul {mul}: {a} -> {b}");
                let Some(d) = want else { continue };
                let moved = prepare_spec("/x", &wa, None).unwrap().moved_by(d).unwrap();
                let fresh = prepare_spec("/x", &wb, None).unwrap();
                assert_eq!(corners(&moved), corners(&fresh), "mul {mul}: {a} -> {b}");
                assert_eq!(moved.band, fresh.band);
                assert_eq!(moved.taken, fresh.taken);
                // The normals are those of the same hyperplanes, tet by tet.
                let normal_of = |p: &PreparedWindow| {
                    let mut n: Vec<([LatticePoint; 4], [i32; 4])> = p
                        .body
                        .mesh
                        .tets
                        .iter()
                        .zip(&p.body.normals)
                        .map(|(t, n)| {
                            let mut c = t.map(|v| p.body.mesh.vertices[v as usize]);
                            c.sort_unstable();
                            (c, *n)
                        })
                        .collect();
                    n.sort_unstable();
                    n.into_iter().map(|x| x.1).collect::<Vec<_>>()
                };
                assert_eq!(normal_of(&moved), normal_of(&fresh));
            }
            // A placement that differs in space is no copy.
            let mut other = at(1);
            other.add[1] += 1;
            assert_eq!(other.moved_copy_of(&at(0)), None);
        }
    }

    /// The pieces of body `body` over `frames` frames of a `size` lattice (voxels where
    /// `occ(k, x, y, z)`): first cap, slabs (each with the last frame's voxel count), last
    /// cap.
    fn pieces_of(
        body: &str,
        size: [u32; 3],
        frames: u32,
        occ: impl Fn(u32, i32, i32, i32) -> bool,
    ) -> Vec<Piece> {
        let (m, slabs) = chronotope_mesh::mesher::test_stream(size, frames, occ);
        let (first, last) = (m.first_frame().unwrap(), m.last_frame().unwrap());
        let geometry = slabs[0].geometry;
        let piece = |kind, index, stamps_ns, occupied, mesh: TetMesh| Piece {
            body: body.into(),
            kind,
            index,
            stamps_ns,
            geometry,
            occupied,
            unsure: None,
            displacement: 0,
            mesh: Arc::new(mesh),
            frame_id: String::new(),
        };
        let mut out = vec![piece(
            PieceKind::CapStart,
            0,
            (first.stamp_ns, first.stamp_ns),
            first.grid.occupied,
            m.cap(first, CapSide::Low).unwrap(),
        )];
        for s in slabs {
            out.push(piece(
                PieceKind::Lateral,
                s.index as u32,
                (s.stamp_lo_ns, s.stamp_hi_ns),
                last.grid.occupied,
                s.mesh,
            ));
        }
        out.push(piece(
            PieceKind::CapEnd,
            last.index as u32,
            (last.stamp_ns, last.stamp_ns),
            last.grid.occupied,
            m.cap(last, CapSide::High).unwrap(),
        ));
        out
    }

    /// Two bodies at rest, one inside the other (its tets INSIDE, no crossing), then both
    /// one voxel on and at rest there; the inner one jumps out (apart for a period) and back
    /// to where it was, and rests there. The periods at rest are taken from the windows
    /// kept before them, moved (the rests at the second place from the first, the last ones
    /// from before the jump), and everything the checker says is what it says when it
    /// checks every window: labels, contacts (the second starts at the jump back) and the
    /// report.
    #[test]
    fn periods_at_rest_are_taken_moved_and_answer_as_checked_ones() {
        let step = |k: u32| i32::from(k >= 4);
        let inner = move |k: u32, x: i32, y: i32, z: i32| {
            let x = x - step(k) - if (8..10).contains(&k) { 6 } else { 0 };
            (4..6).contains(&x) && (4..6).contains(&y) && (4..6).contains(&z)
        };
        let outer = move |k: u32, x: i32, y: i32, z: i32| {
            let x = x - step(k);
            (2..8).contains(&x) && (2..8).contains(&y) && (2..8).contains(&z)
        };
        let frames = 14;
        let (a, b) = (
            pieces_of("/a", [14, 10, 10], frames, inner),
            pieces_of("/b", [14, 10, 10], frames, outer),
        );
        let run = |kept_windows: usize| {
            let mut c = checker_of_a_and_b_with(RollingConfig {
                kept_windows,
                ..RollingConfig::default()
            });
            let mut out = Vec::new();
            for (x, y) in a.iter().zip(&b) {
                c.on_piece(x.clone(), &mut out);
                c.on_piece(y.clone(), &mut out);
            }
            c.finish(&mut out);
            let moved = c.taken_moved()[0].2;
            let r = c.report();
            let p = &r.pairs[0];
            // The inner body INSIDE the outer from the start, and again after the jump.
            assert!(p.labels.a.inside > 0 && p.labels.a.interference > 0);
            assert_eq!(p.intervals_s.len(), 2);
            assert_eq!(p.intervals_s[0][0], 0.0);
            (format!("{out:?}\n{:?}\n{:?}", r.pairs, r.bodies), moved)
        };
        let (checked, none) = run(0);
        let (taken, moved) = run(4);
        assert_eq!(none, 0);
        // Period 2 (from 1; period 0's window holds the opening cap, so it is not kept),
        // 4-6 (at rest after the step, the first from period 2 moved one voxel) and 10-11
        // (back after the jump: from period 6); period 12's window holds the closing cap.
        assert_eq!(moved, 6);
        assert_eq!(taken, checked);
    }

    /// A table at rest between two partners whose slabs change every period (a notch runs
    /// along each) within the same box: the table's windows of its rest are kept one for
    /// each partner, so that neither pair's preparation takes the other's place (with one
    /// window a body, only the last pair's is kept); face to face, every tet is OUTSIDE.
    #[test]
    fn a_body_at_rest_keeps_a_window_for_each_partner() {
        let table = |_k: u32, x: i32, y: i32, z: i32| {
            (1..13).contains(&x) && (2..8).contains(&y) && (4..6).contains(&z)
        };
        // On the table (z 6..8) and under it (z 2..4), each with a notch moving along x.
        let partner = |z0: i32| {
            move |k: u32, x: i32, y: i32, z: i32| {
                let notch = x == 3 + k as i32 && y == 4 && z == z0 + 1;
                (2..12).contains(&x) && (3..7).contains(&y) && (z0..z0 + 2).contains(&z) && !notch
            }
        };
        let frames = 8;
        let pieces = [
            pieces_of("/t", [14, 10, 10], frames, table),
            pieces_of("/a", [14, 10, 10], frames, partner(6)),
            pieces_of("/b", [14, 10, 10], frames, partner(2)),
        ];
        let plan = CheckPlan {
            pairs: Some(vec![("/a".into(), "/t".into()), ("/b".into(), "/t".into())]),
            movable: Vec::new(),
            time_scale: None,
            frame_ids: Default::default(),
            rotation: Default::default(),
        };
        let mut c = RollingChecker::new(plan, MesherOptions::default(), RollingConfig::default());
        let mut out = Vec::new();
        for k in 0..pieces[0].len() {
            for p in &pieces {
                c.on_piece(p[k].clone(), &mut out);
            }
            if k == pieces[0].len() - 2 {
                // Before the closing caps: the table's windows of its rest, one per partner.
                let mut partners: Vec<&str> = c
                    .rest
                    .get("/t")
                    .into_iter()
                    .flatten()
                    .map(|h| h.partner.as_str())
                    .collect();
                partners.sort();
                assert_eq!(partners, ["/a", "/b"]);
            }
        }
        c.finish(&mut out);
        let r = c.report();
        for p in &r.pairs {
            // Face to face, never crossing: all OUTSIDE.
            assert_eq!(p.labels.a.inside + p.labels.a.interference, 0, "{p:?}");
            assert_eq!(p.labels.b.inside + p.labels.b.interference, 0, "{p:?}");
            assert!(p.labels.b.outside > 0);
        }
    }
}

/// The items of `full` beyond those of `taken`, as multisets by `key` (an item of `full`
/// is matched with one of `taken` at most once), in `full`'s order.
fn beyond<'a, T, K: Ord>(taken: &[T], full: &'a [T], key: impl Fn(&T) -> K) -> Vec<&'a T> {
    let mut had: Vec<K> = taken.iter().map(&key).collect();
    had.sort_unstable();
    let mut used = vec![false; had.len()];
    full.iter()
        .filter(|x| {
            let k = key(x);
            let from = had.partition_point(|h| *h < k);
            let seen = (from..had.len())
                .take_while(|&n| had[n] == k)
                .find(|&n| !used[n]);
            match seen {
                Some(n) => {
                    used[n] = true;
                    false
                }
                None => true,
            }
        })
        .collect()
}

/// Why the caps that close a pending period could not be checked.
#[derive(Debug, thiserror::Error)]
pub(super) enum CapsUnchecked {
    /// The period's slabs or runs are no longer held.
    #[error("its slabs are no longer held")]
    Gone,
    /// The two bodies' lattices cannot be compared.
    #[error(transparent)]
    Lattice(#[from] crate::LatticeMismatch),
    /// The window could not be prepared.
    #[error(transparent)]
    Window(#[from] crate::period::WindowError),
}

/// A crossing as pair `i` keeps it, its tets numbered from the windows' first taken tets.
fn record(c: &Crossing, starts: (u64, u64)) -> Record {
    Record {
        t: c.t,
        tets: (
            starts.0 + u64::from(c.tets.0),
            starts.1 + u64::from(c.tets.1),
        ),
        normals: c.normals,
    }
}
