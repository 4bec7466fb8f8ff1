//! Resolutions per contact episode over a horizon around it, and dropping what no window
//! or horizon needs any more.

use std::collections::BTreeMap;
use std::sync::Arc;

use super::{
    add_run, check_pair, hold, BodyMesh, BodyStream, CapSide, CommonLattice, HeldSlab, PairResult,
    Resolution, RollingChecker, RollingOutput, SlabDone, TetMesh, Welder, CONTEXT_SLABS,
};
use crate::pipeline::{resolutions, suggest, Suggestions};
use crate::resolve::Metric;
use crate::rotate::RotationSpec;
use crate::{CheckError, Prepared};

impl RollingChecker {
    /// Resolves the contact episodes of the movable bodies that are complete: no contact of
    /// their pairs can join them any more (or the inputs ended).
    pub(super) fn resolve_episodes(&mut self, out: &mut Vec<RollingOutput>) {
        let movable: Vec<String> = self.resolved_until.keys().cloned().collect();
        for m in movable {
            while let Some(ep) = self.next_episode(&m) {
                let until = self.resolved_until[&m];
                self.resolve_episode(&m, ep, out);
                // Every episode moves the resolved time on; one that cannot (an empty
                // episode) ends the loop rather than repeat itself.
                if self.resolved_until[&m] <= until {
                    break;
                }
            }
        }
    }

    /// Pairs of body `m`, in the report's order.
    pub(super) fn pairs_of(&self, m: &str) -> Vec<usize> {
        (0..self.pairs.len())
            .filter(|&i| self.pairs[i].a == m || self.pairs[i].b == m)
            .collect()
    }

    /// The earliest complete episode of `m` not resolved yet: its contacts merged when
    /// closer than two horizons, cut at `max_episode_s`.
    pub(super) fn next_episode(&self, m: &str) -> Option<[f64; 2]> {
        let until = self.resolved_until[m];
        let h = self.cfg.horizon_s;
        let mut spans: Vec<[f64; 2]> = Vec::new();
        let mut decided = f64::INFINITY;
        for i in self.pairs_of(m) {
            let p = &self.pairs[i];
            let done = p
                .undecided_from()
                .map_or(f64::NEG_INFINITY, |n| self.seconds_of_stamp(n));
            if p.stopped.is_none() {
                decided = decided.min(done);
            }
            for o in p.intervals.iter().rev().chain(p.open.iter()) {
                if o.s.1 > until || (o.s.1 == until && o.s.0 > until) {
                    spans.push([o.s.0.max(until), o.s.1]);
                }
            }
        }
        if self.finishing {
            decided = f64::INFINITY;
        }
        spans.sort_by(|x, y| x[0].total_cmp(&y[0]));
        let mut first = *spans.first()?;
        for s in &spans[1..] {
            if s[0] <= first[1] + 2.0 * h {
                first[1] = first[1].max(s[1]);
            } else {
                break;
            }
        }
        if first[1] - first[0] > self.cfg.max_episode_s {
            first[1] = first[0] + self.cfg.max_episode_s;
            return (decided >= first[1] + h).then_some(first);
        }
        (decided >= first[1] + 2.0 * h).then_some(first)
    }

    /// Builds the horizon bodies of `m` and its partners around `ep`, checks them, and
    /// suggests and verifies a translation and a time scaling of `m`.
    pub(super) fn resolve_episode(&mut self, m: &str, ep: [f64; 2], out: &mut Vec<RollingOutput>) {
        self.resolved_until.insert(m.to_string(), ep[1]);
        let h = self.cfg.horizon_s;
        let origin = self.origin_ns.unwrap_or(0);
        let stamp = |s: f64| origin.saturating_add((s * 1e9).round() as i64);
        let (lo, hi) = (stamp(ep[0] - h), stamp(ep[1] + h));
        let pair_ids = self.pairs_of(m);
        let mut ids: Vec<String> = vec![m.to_string()];
        for &i in &pair_ids {
            let p = &self.pairs[i];
            ids.push(if p.a == m { p.b.clone() } else { p.a.clone() });
        }
        ids.sort();
        ids.dedup();
        // Where older slabs were dropped (max_horizon_tets), the horizon starts later.
        let cut_until = ids
            .iter()
            .filter_map(|id| self.bodies.get(id).map(|b| b.horizon_cut_until))
            .max()
            .unwrap_or(0);
        let lo_kept = lo.max(cut_until);
        let mut ep = ep;
        if lo_kept > lo {
            let from = self.seconds_of_stamp(lo_kept);
            let why = if from >= ep[1] {
                format!(
                    "{m}: the contact episode {:.3}-{:.3} s is not resolved: its slabs were \
                     dropped (resolve_max_tets {})",
                    ep[0], ep[1], self.cfg.max_horizon_tets
                )
            } else {
                format!(
                    "{m}: the contact episode {:.3}-{:.3} s is resolved over {from:.3}-{:.3} s \
                     only (older slabs were dropped: resolve_max_tets {})",
                    ep[0],
                    ep[1],
                    ep[1] + h,
                    self.cfg.max_horizon_tets
                )
            };
            self.problem(out, "resolution_horizon_cut", why);
            if from >= ep[1] {
                return;
            }
            ep[0] = ep[0].max(from);
        }
        let lo = lo_kept;
        // At most `resolve_in_flight` resolutions hold their horizon bodies at once: the
        // oldest is waited for before this one's are built.
        while self.cfg.resolve_in_flight > 0 && self.in_flight.len() >= self.cfg.resolve_in_flight {
            self.take_oldest(true, out);
        }
        let mut meshes: BTreeMap<String, BodyMesh> = BTreeMap::new();
        for id in &ids {
            if let Some(b) = self.horizon_body(id, lo, hi) {
                meshes.insert(id.clone(), b);
            }
        }
        if !meshes.contains_key(m) {
            return;
        }
        let job = ResolveJob {
            movable: m.to_string(),
            episode: ep,
            meshes,
            pairs: pair_ids
                .iter()
                .map(|&i| (self.pairs[i].a.clone(), self.pairs[i].b.clone()))
                .collect(),
            time_scale: self.plan.time_scale,
            rotation: self.plan.rotation,
            period_s: self.union.period_s(),
            origin_ns: origin,
            horizons: Arc::clone(&self.horizons),
        };
        self.submit(job, out);
    }

    /// Hands a resolution to the resolver's pool, or runs it here if none is wanted.
    fn submit(&mut self, job: ResolveJob, out: &mut Vec<RollingOutput>) {
        if self.cfg.resolve_in_flight == 0 {
            let outcome = job.run();
            self.apply(outcome, out);
            return;
        }
        if self.resolver.is_none() {
            match resolver_pool() {
                Ok(pool) => self.resolver = Some(pool),
                Err(e) => {
                    tracing::warn!("no thread pool for resolutions ({e}): they run in turn");
                    self.cfg.resolve_in_flight = 0;
                    let outcome = job.run();
                    self.apply(outcome, out);
                    return;
                }
            }
        }
        let Some(pool) = &self.resolver else { return };
        let what = format!(
            "{}: the contact episode {:.3}-{:.3} s",
            job.movable, job.episode[0], job.episode[1]
        );
        let (tx, rx) = crossbeam_channel::bounded(1);
        pool.spawn(move || {
            // The receiver is gone only if the checker was dropped: nobody to tell.
            let _ = tx.send(job.run());
        });
        self.in_flight.push_back((what, rx));
    }

    /// Takes the oldest resolution's result, waiting for it if `wait`; false if there is
    /// none, or it is not ready and `wait` is false.
    fn take_oldest(&mut self, wait: bool, out: &mut Vec<RollingOutput>) -> bool {
        let Some((_, rx)) = self.in_flight.front() else {
            return false;
        };
        let outcome = if wait {
            rx.recv().ok()
        } else {
            match rx.try_recv() {
                Ok(o) => Some(o),
                Err(crossbeam_channel::TryRecvError::Empty) => return false,
                Err(crossbeam_channel::TryRecvError::Disconnected) => None,
            }
        };
        let what = self
            .in_flight
            .pop_front()
            .map(|(w, _)| w)
            .unwrap_or_default();
        // A job that panicked dropped its sender: said, and the others go on.
        let outcome = outcome.unwrap_or_else(|| {
            ResolveOutcome::Failed(format!(
                "{what} is not resolved: its resolution stopped unexpectedly (a bug: please \
                 report it)"
            ))
        });
        self.apply(outcome, out);
        true
    }

    /// The results of the resolutions that have finished, oldest first, up to the first
    /// that has not (a live transport's clock tick calls this; a replay never does, so
    /// that its output does not depend on how fast the resolutions run).
    pub fn poll_resolutions(&mut self, out: &mut Vec<RollingOutput>) {
        while self.take_oldest(false, out) {}
    }

    /// Waits for every resolution still running and takes its results, oldest first.
    pub(super) fn join_resolutions(&mut self, out: &mut Vec<RollingOutput>) {
        while self.take_oldest(true, out) {}
    }

    /// Resolutions handed to the pool whose results are not taken yet.
    pub fn resolutions_in_flight(&self) -> usize {
        self.in_flight.len()
    }

    fn apply(&mut self, outcome: ResolveOutcome, out: &mut Vec<RollingOutput>) {
        match outcome {
            ResolveOutcome::Clear => {}
            ResolveOutcome::Failed(why) => self.problem(out, "resolution_failed", why),
            ResolveOutcome::Found(found) => {
                for r in found {
                    self.resolutions.push_back(r);
                    if self.resolutions.len() > self.cfg.max_resolutions {
                        self.resolutions.pop_front();
                        self.dropped_resolutions += 1;
                    }
                }
                out.push(RollingOutput::Resolved);
            }
        }
    }

    /// Body `id` between stamps `lo` and `hi` as a closed mesh: its kept slabs there (of
    /// one run), closed by its own caps or caps from its frames.
    pub(super) fn horizon_body(&self, id: &str, lo: i64, hi: i64) -> Option<BodyMesh> {
        let b = self.bodies.get(id)?;
        let mut slabs = b
            .slabs
            .range(lo..)
            .take_while(|(_, x)| x.hi <= hi)
            .peekable();
        let run_id = slabs.peek()?.1.run;
        let r = b.run(run_id)?;
        let mut chosen: Vec<(i64, &HeldSlab)> = Vec::new();
        for (s, x) in slabs {
            if x.run != run_id || chosen.last().is_some_and(|(_, p)| p.hi != *s) {
                break;
            }
            chosen.push((*s, x));
        }
        let (first_s, first) = *chosen.first()?;
        let last_hi = chosen.last()?.1.hi;
        let g = r.geometry;
        let shift = i64::from(g.scale) * i64::from(first.index);
        let shifted = |m: &TetMesh| -> Option<TetMesh> {
            let mut out = m.clone();
            for p in &mut out.vertices {
                p[3] = i32::try_from(i64::from(p[3]) - shift).ok()?;
            }
            Some(out)
        };
        let frame_cap = |stamp: i64, local: u32, side: CapSide| -> Option<TetMesh> {
            let f = b.frame_at(stamp, &g)?;
            let f = f.as_ref();
            let mut out = TetMesh::default();
            let at = chronotope_mesh::SlabPlacement {
                scale: g.scale,
                frame: i64::from(local),
                iso: self.opts.decode.iso_percent,
            };
            chronotope_mesh::march::march_cap(
                chronotope_mesh::table::table(),
                f,
                at,
                side,
                self.opts.max_slab_tets,
                &mut out,
            )
            .then_some(out)
        };
        let low = if r.first_stamp == first_s {
            shifted(&r.first_cap)?
        } else {
            frame_cap(first_s, 0, CapSide::Low)?
        };
        let high = match r.last_cap_at(last_hi) {
            Some(c) => shifted(c)?,
            None => frame_cap(last_hi, chosen.len() as u32, CapSide::High)?,
        };
        let mut body = BodyMesh {
            geometry: Some(g),
            ..BodyMesh::default()
        };
        let mut welder = Welder::default();
        let mut push = |part: &TetMesh, body: &mut BodyMesh| {
            body.pieces.push(body.mesh.tets.len());
            welder.append(&mut body.mesh, part);
        };
        push(&low, &mut body);
        body.stamps_ns.push(first_s);
        for (_, x) in &chosen {
            push(&shifted(&x.mesh)?, &mut body);
            body.stamps_ns.push(x.hi);
        }
        push(&high, &mut body);
        body.stats.frames = body.stamps_ns.len() as u64;
        Some(body)
    }

    /// Stamp (ns) before which nothing of body `id` is needed for resolutions: the start of
    /// a pending episode of a movable body it is paired with, less the horizon, or the
    /// horizon behind that body's decided time.
    pub(super) fn horizon_keep(&self, id: &str) -> i64 {
        let h = self.cfg.horizon_s;
        let origin = self.origin_ns.unwrap_or(0);
        let mut keep = i64::MAX;
        for (m, &until) in &self.resolved_until {
            let related = m == id
                || self
                    .pairs
                    .iter()
                    .any(|p| (p.a == *m && p.b == id) || (p.b == *m && p.a == id));
            if !related {
                continue;
            }
            let mut from = f64::INFINITY;
            for i in self.pairs_of(m) {
                let p = &self.pairs[i];
                if p.stopped.is_some() {
                    continue;
                }
                let done = p
                    .undecided_from()
                    .map_or(f64::NEG_INFINITY, |n| self.seconds_of_stamp(n));
                from = from.min(done);
                for o in p.intervals.iter().rev().chain(p.open.iter()) {
                    if o.s.1 > until {
                        from = from.min(o.s.0.max(until));
                    }
                }
            }
            if from.is_finite() {
                let s = origin.saturating_add(((from - h) * 1e9).floor() as i64);
                keep = keep.min(s);
            } else if from == f64::NEG_INFINITY {
                keep = i64::MIN;
            }
        }
        keep
    }

    /// Reports the slabs every pair has labelled, then drops the slabs and frames nothing
    /// needs any more.
    pub(super) fn prune(&mut self, out: &mut Vec<RollingOutput>) {
        let keeps: BTreeMap<String, i64> = self
            .bodies
            .keys()
            .map(|id| (id.clone(), self.horizon_keep(id)))
            .collect();
        let pairs = &self.pairs;
        let finishing = self.finishing;
        let max_frames = self.cfg.max_lead_frames + 2 * CONTEXT_SLABS + 2;
        let mut oldest_of: BTreeMap<String, i64> = BTreeMap::new();
        for (id, b) in &mut self.bodies {
            // The oldest stamp a pair of this body has not decided.
            let oldest = pairs
                .iter()
                .filter(|p| (p.a == *id || p.b == *id) && p.stopped.is_none())
                .map(|p| p.undecided_from().unwrap_or(i64::MIN))
                .min()
                .unwrap_or(i64::MAX);
            if self.cfg.slabs_done {
                for (s, sl) in b.slabs.range_mut(..oldest) {
                    if sl.worst.is_empty() {
                        continue;
                    }
                    let worst = std::mem::take(&mut sl.worst);
                    if let Some(r) = b.runs.iter().find(|r| r.id == sl.run) {
                        out.push(RollingOutput::SlabDone(SlabDone {
                            body: id.clone(),
                            index: sl.index,
                            stamps_ns: (*s, sl.hi),
                            geometry: r.geometry,
                            mesh: sl.mesh.clone(),
                            worst,
                        }));
                    }
                }
            }
            // Its prepared windows: every pair that could take one again has gone past it.
            // A body at rest keeps them, to move them for its next windows.
            if let Some(held) = self
                .prepared
                .get_mut(id)
                .filter(|held| held.iter().any(|h| h.s < oldest))
            {
                let (gone, kept): (Vec<_>, Vec<_>) =
                    std::mem::take(held).into_iter().partition(|h| h.s < oldest);
                *held = kept;
                if held.is_empty() {
                    self.prepared.remove(id);
                }
                if b.moving_for == 0 {
                    for h in gone {
                        hold(&mut self.rest, id, h);
                    }
                }
            }
            oldest_of.insert(id.clone(), oldest);
            let decided = b.slabs.range(..oldest).count();
            let horizon = keeps.get(id).copied().unwrap_or(i64::MAX);
            for _ in 0..decided.saturating_sub(CONTEXT_SLABS) {
                if b.slabs
                    .first_key_value()
                    .is_some_and(|(_, x)| x.hi >= horizon)
                {
                    break;
                }
                b.slabs.pop_first();
            }
            let keep_from = b.slabs.keys().next().copied().unwrap_or(oldest).min(oldest);
            while b
                .frames
                .first_key_value()
                .is_some_and(|(s, _)| *s < keep_from)
            {
                b.frames.pop_first();
            }
            // Frames of a stream no piece has come for yet: only the latest ones.
            while b.frames.len() > max_frames + b.slabs.len() {
                b.frames.pop_first();
            }
            // And never more than `max_frame_bytes` of decoded frames per body (the oldest
            // go first; an overlap that needed one is then not measured, and says so).
            let mut bytes: u64 = b.frames.values().map(|k| k.grid.heap_bytes()).sum();
            while bytes > self.cfg.max_frame_bytes {
                let Some((_, k)) = b.frames.pop_first() else {
                    break;
                };
                bytes -= k.grid.heap_bytes();
            }
            // Finished runs none of whose slabs are kept: their figures go to the totals
            // (once they are finished: a run ended by its cap has them finished on the pool).
            while let Some(r) = b.runs.first() {
                let last = b.runs.len() == 1;
                let in_use = b.slabs.values().any(|s| s.run == r.id);
                if !r.ended() || r.stats.is_none() || in_use || (last && !finishing) {
                    break;
                }
                let r = b.runs.remove(0);
                add_run(&mut b.totals, r);
            }
        }
        self.cut_horizon(&oldest_of);
        self.release_opening_caps();
    }

    /// A run's opening cap closes the windows and horizons that begin at its first frame,
    /// which begin at a kept slab: once its first slab has come and is no longer kept,
    /// only the cap's count of tets stays (a cap fills the body's volume: at 128³, megabytes
    /// a body for the whole run otherwise).
    fn release_opening_caps(&mut self) {
        for b in self.bodies.values_mut() {
            for r in &mut b.runs {
                let first_kept = b.slabs.get(&r.first_stamp).is_some_and(|x| x.run == r.id);
                if r.next_index > r.first_index && !first_kept && !r.first_cap.tets.is_empty() {
                    r.first_cap = Arc::default();
                }
            }
        }
    }

    /// Drops the oldest slabs kept for resolutions alone (those before what every pair
    /// still needs, less [`CONTEXT_SLABS`]) while they hold more than
    /// [`RollingConfig::max_horizon_tets`] tets.
    pub(super) fn cut_horizon(&mut self, oldest_of: &BTreeMap<String, i64>) {
        let only_horizon = |b: &BodyStream, oldest: i64| -> Vec<(i64, usize)> {
            let decided: Vec<(i64, usize)> = b
                .slabs
                .range(..oldest)
                .map(|(s, x)| (*s, x.mesh.tets.len()))
                .collect();
            let n = decided.len().saturating_sub(CONTEXT_SLABS);
            decided[..n].to_vec()
        };
        let mut kept: Vec<(i64, String, usize)> = Vec::new();
        for (id, b) in &self.bodies {
            let oldest = oldest_of.get(id).copied().unwrap_or(i64::MIN);
            kept.extend(
                only_horizon(b, oldest)
                    .into_iter()
                    .map(|(s, n)| (s, id.clone(), n)),
            );
        }
        let mut total: usize = kept.iter().map(|k| k.2).sum();
        if total <= self.cfg.max_horizon_tets {
            return;
        }
        kept.sort();
        for (s, id, n) in kept {
            if total <= self.cfg.max_horizon_tets {
                break;
            }
            if let Some(b) = self.bodies.get_mut(&id) {
                if let Some(x) = b.slabs.remove(&s) {
                    b.horizon_cut_until = b.horizon_cut_until.max(x.hi);
                }
                b.frames.remove(&s);
            }
            total -= n;
        }
    }
}

/// The resolver's pool: as many threads as rayon's, so that a resolution's long sequential
/// parts never hold up the windows' parallel work. Its threads run at a lower priority
/// ([`RESOLVER_NICE`]): contacts are the answer a cell waits for, so the windows, the
/// meshers and the transport take the cores first and a resolution the time they leave.
fn resolver_pool() -> Result<rayon::ThreadPool, rayon::ThreadPoolBuildError> {
    low_priority_pool("resolver", RESOLVER_NICE)
}

/// A pool of as many threads as rayon's, named `{name}-N`, each at `nice` more than the
/// process ([`lower_own_priority`]). A job that panics (a bug) must not abort the process,
/// rayon's default: the panic is logged (a resolution's result channel then closes and
/// the checker says so; a bookkeeping job catches its own).
pub(super) fn low_priority_pool(
    name: &'static str,
    nice: i32,
) -> Result<rayon::ThreadPool, rayon::ThreadPoolBuildError> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(rayon::current_num_threads())
        .thread_name(move |i| format!("{name}-{i}"))
        .start_handler(move |_| lower_own_priority(nice))
        .panic_handler(move |p| {
            tracing::error!("a {name} job panicked: {}", crate::panic_text(p.as_ref()));
        })
        .build()
}

/// How much the resolver's threads lower their priority: nice values added (Linux gives a
/// thread of nice +10 about a tenth of a core's time against a thread of the process's own
/// nice when both want the core). A live cell's contact events at the start of an episode
/// waited behind its resolution otherwise: docs/performance.md, "Resolutions yield to the
/// contacts".
pub const RESOLVER_NICE: i32 = 10;

/// Lowers the calling thread's scheduling priority by `by` nice values (at most to 19). On
/// Linux each thread has a nice value of its own; elsewhere, or if the system refuses, the
/// thread keeps its priority: only the order in which work gets the cores changes, never
/// what is computed. (Also the live markers part's pool: a display yields to the check.)
pub fn lower_own_priority(by: i32) {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: system calls on the calling thread's own id, with no memory passed.
        unsafe {
            let tid = libc::gettid() as libc::id_t;
            // -1 is also a valid nice value: then this lowers from -1, which is as asked.
            let now = libc::getpriority(libc::PRIO_PROCESS, tid);
            let _ = libc::setpriority(libc::PRIO_PROCESS, tid, (now + by).min(19));
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = by;
}

/// A contact episode's resolution, with everything it needs: it runs on the resolver's pool
/// while the checker goes on.
pub(super) struct ResolveJob {
    movable: String,
    episode: [f64; 2],
    /// The horizon bodies (the movable one and its partners).
    meshes: BTreeMap<String, BodyMesh>,
    /// The movable body's pairs, in the report's order.
    pairs: Vec<(String, String)>,
    time_scale: Option<f64>,
    /// The rotation asked for.
    rotation: RotationSpec,
    period_s: Option<f64>,
    origin_ns: i64,
    /// The bodies' last horizons and the movable bodies' last searches, for horizons and
    /// episodes that repeat ([`KeptHorizons`]).
    horizons: Arc<KeptHorizons>,
}

/// Each body's last horizon prepared by a resolution, and each movable body's last search.
///
/// A horizon body is built in local time (its first frame at time 0), so a body at rest, or
/// one whose motion repeats with its contacts, gives the same horizon body episode after
/// episode: the same tets on the same vertices, welded from the same pieces. Its
/// preparation (tree, adjacency, normals) depends only on that mesh, its lattice and its
/// placement on the common lattice. A horizon that equals the kept one, compared exactly
/// (every vertex, tet and piece, the lattice and the placement), has repeated: it is
/// prepared once more and that preparation is kept, and from then on it is shared. One
/// horizon per body is kept; a different one replaces it (the old one dropped before the
/// new one is prepared), and keeps only its mesh until it repeats.
///
/// The check of the horizon and the search for a translation and a time scaling depend
/// only on the prepared bodies, the pairs and the metric, and give lattice units. When every
/// horizon body of an episode shares the preparation the movable body's last search was
/// made on, with the same pairs and metric, that search's answer is the answer: only its
/// conversion to seconds, on this episode's stamps, is done again.
#[derive(Debug, Default)]
pub(super) struct KeptHorizons {
    bodies: std::sync::Mutex<BTreeMap<String, KeptHorizon>>,
    /// Entries made so far (each entry's generation).
    generations: std::sync::atomic::AtomicU64,
    searches: std::sync::Mutex<BTreeMap<String, KeptSearch>>,
}

/// A movable body's last search and what it was made on.
#[derive(Debug)]
struct KeptSearch {
    /// The horizon bodies, in the job's order, held weakly: while a weak pointer lives, its
    /// allocation is not reused, so a preparation at the same address is the same one.
    bodies: Vec<(String, std::sync::Weak<Prepared>)>,
    pairs: Vec<(String, String)>,
    metric: Metric,
    rotation: RotationSpec,
    /// What it found; `None` if nothing interferes over the horizon.
    found: Option<Suggestions>,
}

impl KeptSearch {
    /// Whether it was made on `prepared` (named `ids`), `pairs`, `metric` and `rotation`.
    fn made_on(
        &self,
        ids: &[String],
        prepared: &[Arc<Prepared>],
        pairs: &[(String, String)],
        metric: &Metric,
        rotation: &RotationSpec,
    ) -> bool {
        self.metric == *metric
            && self.rotation == *rotation
            && self.pairs == pairs
            && self.bodies.len() == prepared.len()
            && self
                .bodies
                .iter()
                .zip(ids.iter().zip(prepared))
                .all(|((kid, w), (id, p))| kid == id && std::ptr::eq(w.as_ptr(), Arc::as_ptr(p)))
    }
}

/// A body's last horizon, and its preparation once it has repeated.
#[derive(Debug)]
struct KeptHorizon {
    body: BodyMesh,
    placement: (i64, [i64; 4]),
    /// Set when the horizon came again: a horizon seen once is not worth its preparation's
    /// memory (about five times the mesh's) until it repeats.
    prepared: Option<Arc<Prepared>>,
    /// Which entry this is (entries are replaced while a preparation runs unlocked).
    generation: u64,
}

impl KeptHorizons {
    /// Body `id`'s horizon `b` prepared on `lat`: the kept preparation if `b` is the kept
    /// horizon on the same placement and has been prepared before; otherwise prepared, and
    /// kept if `b` is the kept horizon (it has repeated), or `b` kept in its place.
    ///
    /// # Errors
    /// As [`CommonLattice::prepare`].
    fn prepare(
        &self,
        lat: &CommonLattice,
        id: &str,
        b: BodyMesh,
    ) -> Result<Arc<Prepared>, CheckError> {
        let placement = lat.placement_of(&b);
        // A resolution that panicked while holding the lock left the map whole (it is only
        // read or written in one step): its poisoning is ignored.
        let lock = || self.bodies.lock().unwrap_or_else(|e| e.into_inner());
        let mut kept = lock();
        let seen = kept.get(id).filter(|k| {
            Some(k.placement) == placement
                && k.body.geometry == b.geometry
                && k.body.pieces == b.pieces
                && k.body.mesh == b.mesh
        });
        if let Some(k) = seen {
            if let Some(p) = &k.prepared {
                return Ok(Arc::clone(p));
            }
            // It has repeated: prepared, and kept from now on.
            let generation = k.generation;
            drop(kept);
            let prepared = Arc::new(lat.prepare(id, &b)?);
            if let Some(k) = lock().get_mut(id).filter(|k| k.generation == generation) {
                k.prepared = Some(Arc::clone(&prepared));
            }
            return Ok(prepared);
        }
        kept.remove(id);
        drop(kept);
        let prepared = Arc::new(lat.prepare(id, &b)?);
        if let Some(placement) = placement {
            let k = KeptHorizon {
                body: b,
                placement,
                prepared: None,
                generation: self
                    .generations
                    .fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            };
            lock().insert(id.to_string(), k);
        }
        Ok(prepared)
    }

    /// Movable body `m`'s search on the horizon bodies `prepared` (named `ids`), `pairs`,
    /// `metric` and `rotation`: its last one if that was made on them, otherwise
    /// `search()`, kept in its place.
    #[allow(clippy::too_many_arguments)]
    fn search_or(
        &self,
        m: &str,
        ids: &[String],
        prepared: &[Arc<Prepared>],
        pairs: &[(String, String)],
        metric: &Metric,
        rotation: &RotationSpec,
        search: impl FnOnce() -> Option<Suggestions>,
    ) -> Option<Suggestions> {
        let lock = || self.searches.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(k) = lock()
            .get(m)
            .filter(|k| k.made_on(ids, prepared, pairs, metric, rotation))
        {
            return k.found.clone();
        }
        let found = search();
        let k = KeptSearch {
            bodies: ids
                .iter()
                .cloned()
                .zip(prepared.iter().map(Arc::downgrade))
                .collect(),
            pairs: pairs.to_vec(),
            metric: *metric,
            rotation: *rotation,
            found: found.clone(),
        };
        lock().insert(m.to_string(), k);
        found
    }
}

/// What a resolution gave.
#[derive(Debug)]
pub(super) enum ResolveOutcome {
    /// Nothing interferes over the horizon: nothing to resolve.
    Clear,
    /// The suggestions, each verified.
    Found(Vec<Resolution>),
    /// It could not be done (why).
    Failed(String),
}

impl ResolveJob {
    /// Checks the horizon bodies, then suggests and verifies a translation, a time scaling
    /// and a rotation of the movable body.
    fn run(self) -> ResolveOutcome {
        let (m, ep) = (self.movable.as_str(), self.episode);
        let lattice = {
            let named: Vec<(&str, &BodyMesh)> =
                self.meshes.iter().map(|(k, v)| (k.as_str(), v)).collect();
            CommonLattice::of(&named)
        };
        let ids: Vec<String> = self.meshes.keys().cloned().collect();
        let result = lattice.and_then(|lat| {
            // One body at a time: preparing them side by side saved 7 % of a periodic
            // replay's time for 15 % more peak memory.
            let prepared = self
                .meshes
                .into_iter()
                .map(|(id, b)| self.horizons.prepare(&lat, &id, b))
                .collect::<Result<Vec<_>, _>>()?;
            Ok((lat, prepared))
        });
        let (lat, prepared) = match result {
            Ok(x) => x,
            Err(e) => {
                return ResolveOutcome::Failed(format!(
                    "{m}: the contact episode {:.3}-{:.3} s cannot be resolved: {e}",
                    ep[0], ep[1]
                ))
            }
        };
        let index = |id: &str| ids.iter().position(|k| k == id);
        let Some(im) = index(m) else {
            return ResolveOutcome::Clear;
        };
        let resolution = prepared[im].geometry.resolution;
        let c = self
            .time_scale
            .or_else(|| self.period_s.map(|p| resolution / p))
            .unwrap_or(resolution);
        let metric = Metric::new(&lat, c);
        let found = self.horizons.search_or(
            m,
            &ids,
            &prepared,
            &self.pairs,
            &metric,
            &self.rotation,
            || {
                search(
                    im,
                    &index,
                    &prepared,
                    &self.pairs,
                    &metric,
                    &lat,
                    &self.rotation,
                )
            },
        );
        match found {
            None => ResolveOutcome::Clear,
            Some(found) => {
                ResolveOutcome::Found(resolutions(m, &found, &lat, &metric, c, self.origin_ns, ep))
            }
        }
    }
}

/// Checks the movable body (`prepared[im]`) against its partners over the horizon, and
/// suggests and verifies a translation, a time scaling and a rotation of it; `None` if
/// nothing interferes.
fn search(
    im: usize,
    index: &dyn Fn(&str) -> Option<usize>,
    prepared: &[Arc<Prepared>],
    pairs: &[(String, String)],
    metric: &Metric,
    lat: &CommonLattice,
    rotation: &RotationSpec,
) -> Option<Suggestions> {
    let mut others = Vec::new();
    let mut rs: Vec<PairResult> = Vec::new();
    for (a, b) in pairs {
        let (Some(ia), Some(ib)) = (index(a), index(b)) else {
            continue;
        };
        let r = check_pair(&prepared[ia], &prepared[ib]);
        if ia == im {
            others.push(&*prepared[ib]);
            rs.push(r);
        } else {
            others.push(&*prepared[ia]);
            rs.push(r.swapped());
        }
    }
    if !rs.iter().any(|r| r.interfering()) {
        return None;
    }
    let rs: Vec<&PairResult> = rs.iter().collect();
    Some(suggest(&prepared[im], &others, &rs, metric, lat, rotation))
}

#[cfg(test)]
mod tests {
    use super::super::{CheckPlan, MesherOptions, RollingConfig};
    use super::*;

    /// A 6×5×4 box of voxels starting at `x0`, stepping one voxel along x per frame from
    /// frame `step_from` on, over 4 frames stamped from `t0` (ns) every 0.1 s, on a lattice
    /// whose origin is `origin_x` (m) along x.
    fn box_body(x0: usize, step_from: usize, t0: i64, origin_x: f64) -> BodyMesh {
        let stamps: Vec<i64> = (0..4).map(|k| t0 + k * 100_000_000).collect();
        chronotope_mesh::glue::test_body([16, 9, 8], [origin_x, 0.0, 0.0], &stamps, |k, p| {
            let x = x0 + k.saturating_sub(step_from);
            (x..x + 6).contains(&p[0]) && (2..7).contains(&p[1]) && (2..6).contains(&p[2])
        })
    }

    /// What a preparation is made of, to compare a shared one with a fresh one.
    fn parts(p: &Prepared) -> impl PartialEq + std::fmt::Debug + '_ {
        (
            &p.mesh,
            &*p.adjacency,
            &p.normals,
            &*p.original,
            p.factor,
            p.geometry,
            p.bvh.node_count(),
            p.bvh.aabb(),
        )
    }

    /// A horizon seen once is kept without its preparation; when it comes again, at other
    /// stamps, it is prepared and that preparation kept, and the next time it is shared.
    /// The shared preparation is the one a fresh preparation gives; a different mesh,
    /// lattice origin or first frame on the common lattice is prepared again.
    #[test]
    fn a_horizon_seen_before_shares_its_preparation() {
        let kept = KeptHorizons::default();
        let on = |bodies: &[(&str, &BodyMesh)]| CommonLattice::of(bodies).expect("one lattice");
        let partner = |t0| box_body(5, 9, t0, 0.0);
        let prepared_of = |id: &str| {
            let map = kept.bodies.lock().expect("not poisoned");
            map.get(id).and_then(|k| k.prepared.clone())
        };
        // A body at rest, then the same horizon 2 s and 4 s later.
        let (a1, b1) = (box_body(1, 9, 0, 0.0), partner(0));
        let lat1 = on(&[("a", &a1), ("b", &b1)]);
        let p1 = kept.prepare(&lat1, "a", a1.clone()).expect("prepared");
        assert!(prepared_of("a").is_none(), "seen once: not kept prepared");
        let (a2, b2) = (box_body(1, 9, 2_000_000_000, 0.0), partner(2_000_000_000));
        let lat2 = on(&[("a", &a2), ("b", &b2)]);
        let p2 = kept.prepare(&lat2, "a", a2.clone()).expect("prepared");
        assert!(!Arc::ptr_eq(&p1, &p2));
        assert!(
            prepared_of("a").is_some_and(|k| Arc::ptr_eq(&k, &p2)),
            "repeated: kept"
        );
        let (a3, b3) = (box_body(1, 9, 4_000_000_000, 0.0), partner(4_000_000_000));
        let lat3 = on(&[("a", &a3), ("b", &b3)]);
        let p3 = kept.prepare(&lat3, "a", a3.clone()).expect("prepared");
        assert!(Arc::ptr_eq(&p2, &p3), "the third time, shared");
        let fresh = lat3.prepare("a", &a3).expect("prepared");
        assert_eq!(parts(&p3), parts(&fresh));
        let pb3 = lat3.prepare("b", &b3).expect("b");
        let (shared, own) = (check_pair(&p3, &pb3), check_pair(&fresh, &pb3));
        assert!(shared.interfering());
        let answer = |r: &PairResult| {
            format!(
                "{:?} {:?} {:?} {} {}",
                r.labels_a, r.labels_b, r.intervals, r.candidate_pairs, r.interfering_pairs
            )
        };
        assert_eq!(answer(&shared), answer(&own));
        // Each of these differs from the kept horizon in one thing, and is prepared again.
        let aside = box_body(2, 9, 0, 0.0);
        let elsewhere = box_body(1, 9, 0, 0.01);
        let later = box_body(1, 9, 100_000_000, 0.0);
        let cases = [
            (
                "the same box one voxel along",
                on(&[("a", &aside), ("b", &b1)]),
                aside.clone(),
            ),
            (
                "a lattice one voxel along",
                on(&[("a", &elsewhere), ("b", &b1)]),
                elsewhere.clone(),
            ),
            (
                "a later first frame",
                on(&[("a", &later), ("b", &b1)]),
                later.clone(),
            ),
        ];
        for (what, lat, body) in cases {
            // The horizon at rest is the kept one, prepared, when each case comes.
            kept.prepare(&lat1, "a", a1.clone()).expect("prepared");
            let at_rest = kept.prepare(&lat1, "a", a1.clone()).expect("prepared");
            assert!(prepared_of("a").is_some_and(|k| Arc::ptr_eq(&k, &at_rest)));
            let p = kept.prepare(&lat, "a", body.clone()).expect("prepared");
            assert!(!Arc::ptr_eq(&p, &at_rest), "{what}: prepared again");
            assert!(
                prepared_of("a").is_none(),
                "{what}: kept in its place, unprepared"
            );
            let own = lat.prepare("a", &body).expect("a");
            assert_eq!(parts(&p), parts(&own), "{what}");
        }
        // Another body's horizon is kept beside the last one.
        kept.prepare(&lat1, "b", b1.clone()).expect("prepared");
        let map = kept.bodies.lock().expect("not poisoned");
        assert_eq!(map.len(), 2);
        assert_eq!(map["a"].body.mesh, later.mesh);
        assert_eq!(map["b"].body.mesh, b1.mesh);
    }

    /// The resolver's threads run at a lower priority than the thread that made the pool,
    /// which keeps its own.
    #[cfg(target_os = "linux")]
    #[test]
    fn the_resolver_s_threads_yield_to_the_checker_s() {
        let nice =
            || unsafe { libc::getpriority(libc::PRIO_PROCESS, libc::gettid() as libc::id_t) };
        let mine = nice();
        let pool = resolver_pool().unwrap();
        let theirs = pool.install(nice);
        assert_eq!(theirs, (mine + RESOLVER_NICE).min(19), "mine {mine}");
        assert_eq!(nice(), mine);
    }

    #[test]
    fn a_resolution_that_panics_is_said_and_the_checker_goes_on() {
        let plan = CheckPlan {
            pairs: Some(vec![("/a".into(), "/b".into())]),
            movable: vec!["/a".into()],
            time_scale: None,
            frame_ids: Default::default(),
            rotation: Default::default(),
        };
        let mut c = RollingChecker::new(plan, MesherOptions::default(), RollingConfig::default());
        let pool = resolver_pool().unwrap();
        let (tx, rx) = crossbeam_channel::bounded::<ResolveOutcome>(1);
        pool.spawn(move || {
            let _keep = tx;
            panic!("a bug");
        });
        c.in_flight
            .push_back(("/a: the contact episode 1.000-2.000 s".into(), rx));
        // The pool survives the panic and runs the next job.
        let (tx2, rx2) = crossbeam_channel::bounded(1);
        pool.spawn(move || {
            let _ = tx2.send(ResolveOutcome::Clear);
        });
        c.in_flight.push_back(("/a: the next".into(), rx2));
        let mut out = Vec::new();
        c.join_resolutions(&mut out);
        assert_eq!(c.resolutions_in_flight(), 0);
        let said: Vec<&str> = out
            .iter()
            .filter_map(|r| match r {
                RollingOutput::Problem(kind, text) => Some((*kind, text.as_str())),
                _ => None,
            })
            .map(|(k, t)| {
                assert_eq!(k, "resolution_failed");
                t
            })
            .collect();
        assert_eq!(said.len(), 1, "{said:?}");
        assert!(
            said[0].contains("1.000-2.000 s is not resolved"),
            "{}",
            said[0]
        );
    }

    /// An episode whose horizon bodies are the last one's, on the same pairs and metric,
    /// takes that episode's search, converted on its own stamps: the answer a fresh
    /// resolution gives. Another metric or another partner is searched again.
    #[test]
    fn an_episode_like_the_last_takes_its_search() {
        let horizons = Arc::new(KeptHorizons::default());
        let job = |t0: i64, partner_x: usize, time_scale: Option<f64>| {
            let meshes: BTreeMap<String, BodyMesh> = [
                ("a".to_string(), box_body(0, 1, t0, 0.0)),
                ("b".to_string(), box_body(partner_x, 9, t0, 0.0)),
            ]
            .into();
            ResolveJob {
                movable: "a".into(),
                episode: [t0 as f64 * 1e-9, t0 as f64 * 1e-9 + 0.3],
                meshes,
                pairs: vec![("a".into(), "b".into())],
                time_scale,
                rotation: RotationSpec::default(),
                period_s: Some(0.1),
                origin_ns: 0,
                horizons: Arc::clone(&horizons),
            }
        };
        // What a resolution of these horizon bodies gives with nothing kept.
        let fresh = |j: &ResolveJob| {
            let named: Vec<(&str, &BodyMesh)> =
                j.meshes.iter().map(|(k, v)| (k.as_str(), v)).collect();
            let lat = CommonLattice::of(&named).expect("one lattice");
            let (a, b) = (
                lat.prepare("a", &j.meshes["a"]).expect("a"),
                lat.prepare("b", &j.meshes["b"]).expect("b"),
            );
            let r = check_pair(&a, &b);
            assert!(r.interfering());
            let c = j.time_scale.unwrap_or(0.01 / 0.1);
            crate::pipeline::resolve(
                &a,
                &[&b],
                &[&r],
                &lat,
                c,
                &j.rotation,
                j.origin_ns,
                j.episode,
            )
        };
        let found = |o: ResolveOutcome| match o {
            ResolveOutcome::Found(f) => f,
            other => panic!("not found: {other:?}"),
        };
        let first = job(0, 7, None);
        let want = fresh(&first);
        assert_eq!(
            want.len(),
            3,
            "a translation, a time scaling and a rotation: {want:?}"
        );
        assert_eq!(found(first.run()), want);
        // The same horizon 2 s later: the kept search, on the later stamps.
        let later = job(2_000_000_000, 7, None);
        let want = fresh(&later);
        assert_eq!(found(later.run()), want);
        // The kept search is what answers: one planted in its place is taken as it is.
        {
            let mut kept = horizons.searches.lock().expect("not poisoned");
            let k = kept.get_mut("a").expect("kept");
            let Some(Suggestions {
                translation: Some(t),
                ..
            }) = &mut k.found
            else {
                panic!("a translation was kept");
            };
            t.distance_m = 123.0;
        }
        let planted = found(job(4_000_000_000, 7, None).run());
        assert!(
            matches!(planted[0], Resolution::Translate { distance, .. } if distance == 123.0),
            "{planted:?}"
        );
        // Another metric, or a partner elsewhere, is searched again.
        for (what, j) in [
            ("the partner one voxel closer", job(0, 6, None)),
            ("another time scale", job(0, 7, Some(0.2))),
        ] {
            let want = fresh(&j);
            let got = found(j.run());
            assert_eq!(got, want, "{what}");
            assert!(
                !matches!(got[0], Resolution::Translate { distance, .. } if distance == 123.0),
                "{what}"
            );
        }
    }
}
