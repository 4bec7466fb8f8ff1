//! One body's stream of frames: which frames are accepted, where frames are missing or were
//! refused, and how a gap between two accepted frames is filled. Shared by the mesher node
//! (live and replay) and by `chronotope check`, so both accept the same frames.
//!
//! The rules:
//! - A refused frame changes no mesh state. Its stamp (when it increases) only feeds the
//!   estimate of the body's frame period, so that frames refused in a row are seen as missing
//!   once an accepted frame follows.
//! - A gap is filled only between two accepted frames: when the next accepted frame comes
//!   a whole number (2..=1024) of periods after the last one, the frames in between are the
//!   union of those two (where the body may have been: the safe side for collision), and the
//!   span is reported as filled. Nothing is ever extended past the last accepted frame.
//!   The filled frames' slabs after the first repeat one slab moved in time, so a long fill
//!   costs a copy per frame, not a march; all of them together may hold at most
//!   `max_fill_tets` tets (known from the second slab on, before the rest exist): a longer
//!   fill is undone and one slab spans the gap, and the reason says so.
//! - The fill and the frame after it are one step: if the frame is then refused (its slab
//!   over `max_slab_tets`), the fill is undone.
//! - What was lost is kept as spans (the latest [`MAX_LOSS_SPANS`], with totals for all).

use std::collections::VecDeque;

use serde::Serialize;

use super::grid::{FrameRef, OccupancyGrid};
use super::mesher::{Mesher, MesherOptions, Slab};
use super::unsure::Unsure;
use super::MeshError;

/// A frame period longer than this many times the body's median period is frames missing.
pub const GAP_FACTOR: f64 = 1.5;
/// The median period is taken over this many latest periods.
pub const PERIOD_WINDOW: usize = 64;
/// Most frames one gap is filled with (a longer gap is spanned by one slab instead).
pub const MAX_FILL_FRAMES: i64 = 1024;
/// Loss spans kept per body (the latest; totals count every one).
pub const MAX_LOSS_SPANS: usize = 64;

/// `from_ns`/`to_ns` of a refusal whose frame's stamp is not known (it did not decode).
pub const UNKNOWN_STAMP: i64 = i64::MIN;

/// What happened over a span of a body's stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LossKind {
    /// Frames refused (the span runs from the first to the last refused stamp).
    Refused,
    /// Frames missing between two accepted frames, filled with their union.
    Filled,
    /// Frames missing between two accepted frames, not a whole number of periods (or too
    /// many): one slab spans the gap.
    Spanned,
    /// A frame accepted with PERCENT values outside the domain (101..=254) read as 100.
    Clamped,
}

/// A span of a body's stream where frames were refused or missing.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct LossSpan {
    /// What happened.
    pub kind: LossKind,
    /// First stamp of the span (ns): the refused frame, or the accepted frame before the gap;
    /// [`UNKNOWN_STAMP`] for frames that did not decode.
    pub from_ns: i64,
    /// Last stamp of the span (ns): the refused frame, or the accepted frame after the gap.
    pub to_ns: i64,
    /// Frames refused, filled or missing in the span.
    pub frames: u64,
    /// Why (the refusal's code, e.g. `lattice_changed`, or `frames_missing`).
    pub code: &'static str,
    /// The first refusal's reason, in words.
    pub reason: String,
}

/// Everything a body lost, bounded.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct LossLog {
    /// Frames refused in all.
    pub refused_frames: u64,
    /// Frames filled in all.
    pub filled_frames: u64,
    /// Gaps spanned by one slab.
    pub spanned_gaps: u64,
    /// Frames accepted with PERCENT values outside the domain read as 100.
    pub clamped_frames: u64,
    /// The latest spans.
    pub spans: VecDeque<LossSpan>,
    /// Older spans dropped to keep [`MAX_LOSS_SPANS`].
    pub spans_dropped: u64,
}

impl LossLog {
    fn push(&mut self, span: LossSpan) {
        if self.spans.len() == MAX_LOSS_SPANS {
            self.spans.pop_front();
            self.spans_dropped += 1;
        }
        self.spans.push_back(span);
    }

    fn refused(&mut self, stamp_ns: Option<i64>, e: &MeshError, run_open: bool) {
        self.refused_frames += 1;
        let code = e.code();
        if let Some(last) = self.spans.back_mut() {
            if run_open && last.kind == LossKind::Refused && last.code == code {
                last.frames += 1;
                if let Some(t) = stamp_ns {
                    if last.from_ns == UNKNOWN_STAMP {
                        last.from_ns = t;
                    }
                    last.from_ns = last.from_ns.min(t);
                    last.to_ns = last.to_ns.max(t);
                }
                return;
            }
        }
        let t = stamp_ns.unwrap_or(UNKNOWN_STAMP);
        self.push(LossSpan {
            kind: LossKind::Refused,
            from_ns: t,
            to_ns: t,
            frames: 1,
            code,
            reason: e.to_string(),
        });
    }
}

/// What an accepted frame produced.
#[derive(Debug, Default)]
pub struct Accepted {
    /// The slabs completed, in order, each with the stamp of the frame that completed it;
    /// `None` for a frame that completes no slab (the first). Filled frames come first.
    pub frames: Vec<(i64, Option<Slab>)>,
    /// The gap before this frame, if there was one.
    pub gap: Option<LossSpan>,
    /// The frame the filled frames of `gap` are (the union of the two around it).
    pub fill: Option<OccupancyGrid>,
    /// PERCENT voxels of this frame outside the domain, read as 100.
    pub clamped: u64,
}

/// One body's stream: a [`Mesher`] plus the rules of the module doc.
#[derive(Debug)]
pub struct BodyStream {
    mesher: Mesher,
    periods_ns: VecDeque<i64>,
    last_seen_ns: Option<i64>,
    /// A refused frame was the last thing seen (consecutive refusals merge into one span).
    refusing: bool,
    /// The last accepted frame had clamped values (consecutive ones merge into one span).
    last_accept_clamped: bool,
    losses: LossLog,
}

impl BodyStream {
    /// An empty stream.
    ///
    /// # Errors
    /// Bad mesher options.
    pub fn new(opts: MesherOptions) -> Result<Self, MeshError> {
        Ok(Self {
            mesher: Mesher::new(opts)?,
            periods_ns: VecDeque::new(),
            last_seen_ns: None,
            refusing: false,
            last_accept_clamped: false,
            losses: LossLog::default(),
        })
    }

    /// A new stream of the same body after this one ended (an idle close): empty, with the
    /// same options, and this one's losses carried on.
    ///
    /// # Errors
    /// Bad mesher options (not after a successful [`Self::new`]).
    pub fn restarted(&self) -> Result<Self, MeshError> {
        let mut s = Self::new(*self.mesher.options())?;
        s.losses = self.losses.clone();
        Ok(s)
    }

    /// The mesher (the accepted frames' state).
    pub fn mesher(&self) -> &Mesher {
        &self.mesher
    }

    /// What was lost so far.
    pub fn losses(&self) -> &LossLog {
        &self.losses
    }

    /// The body's frame period: the median of the latest periods between frames seen.
    pub fn period_ns(&self) -> Option<i64> {
        if self.periods_ns.is_empty() {
            return None;
        }
        let mut s: Vec<i64> = self.periods_ns.iter().copied().collect();
        s.sort_unstable();
        Some(s[s.len() / 2])
    }

    fn saw(&mut self, stamp_ns: i64) {
        match self.last_seen_ns {
            Some(last) if stamp_ns <= last => {}
            Some(last) => {
                if self.periods_ns.len() == PERIOD_WINDOW {
                    self.periods_ns.pop_front();
                }
                self.periods_ns.push_back(stamp_ns - last);
                self.last_seen_ns = Some(stamp_ns);
            }
            None => self.last_seen_ns = Some(stamp_ns),
        }
    }

    /// Records a frame the caller refused before it reached the mesher (e.g. a message that
    /// did not decode, or a stamp out of its domain): counted, its stamp (if known and valid)
    /// feeds the period estimate only.
    pub fn refuse(&mut self, stamp_ns: Option<i64>, e: &MeshError) {
        // A stamp out of its domain is no time.
        let stamp_ns = stamp_ns.filter(|_| !matches!(e, MeshError::BadStamp { .. }));
        self.losses.refused(stamp_ns, e, self.refusing);
        self.refusing = true;
        // A stamp that does not increase is no new instant of the stream: no period from it.
        if let Some(t) = stamp_ns.filter(|_| !matches!(e, MeshError::StampNotIncreasing { .. })) {
            self.saw(t);
        }
    }

    /// Feeds a frame derived from other streams' accepted frames (e.g. the intersection of
    /// two bodies' frames), with none of the stream rules: no gap is filled.
    ///
    /// # Errors
    /// The mesher's stream checks (lattice, stamp order, slab size).
    pub fn push_derived(
        &mut self,
        stamp_ns: i64,
        geometry: super::grid::GridGeometry,
        grid: OccupancyGrid,
    ) -> Result<Option<Slab>, MeshError> {
        self.mesher.push_decoded(stamp_ns, geometry, grid)
    }

    /// Feeds one frame.
    ///
    /// # Errors
    /// Why the frame was refused; the mesh state is then unchanged.
    pub fn push(&mut self, f: &FrameRef<'_>) -> Result<Accepted, MeshError> {
        let prepared = match self.mesher.prepare(f) {
            Ok(p) => p,
            Err(e) => {
                self.refuse(Some(f.stamp_ns), &e);
                return Err(e);
            }
        };
        let mut out = Accepted::default();
        let clamped = prepared.grid.clamped;
        let last = self.mesher.last_frame().map(|k| k.stamp_ns);
        let gap = match (last, self.period_ns()) {
            (Some(prev), Some(period)) if period > 0 => {
                let dt = f.stamp_ns - prev;
                (dt as f64 > GAP_FACTOR * period as f64).then_some((prev, dt, period))
            }
            _ => None,
        };
        let snapshot = gap.map(|_| self.mesher.snapshot());
        if let Some((prev, dt, period)) = gap {
            let ratio = dt as f64 / period as f64;
            let periods = ratio.round() as i64;
            let whole =
                (ratio - periods as f64).abs() < 0.05 && (2..=MAX_FILL_FRAMES).contains(&periods);
            let union = self
                .mesher
                .last_frame()
                .and_then(|k| k.grid.union(&prepared.grid));
            let mut filled = 0;
            // Tets of the whole fill, once known to be over `max_fill_tets`.
            let mut over = None;
            if let (true, Some(both)) = (whole, union) {
                out.fill = Some(both.clone());
                let max = self.mesher.options().max_fill_tets as u64;
                let mut tets = 0u64;
                for j in 1..periods {
                    // In i128: dt · j can exceed i64 for stamps years apart.
                    let t = prev + (i128::from(dt) * i128::from(j) / i128::from(periods)) as i64;
                    // From the second filled frame on, the fill repeats one grid: the
                    // mesher moves its rest slab in time rather than marching each one.
                    let pushed = self.mesher.push_decoded(t, prepared.geometry, both.clone());
                    match pushed {
                        Ok(slab) => {
                            let n = slab.as_ref().map_or(0, |s| s.mesh.tets.len() as u64);
                            // Known from the second slab on: the rest repeat it.
                            let whole_fill = match j {
                                2 => tets + n * (periods - 2) as u64,
                                _ => tets + n,
                            };
                            if whole_fill > max {
                                over = Some(whole_fill);
                                break;
                            }
                            tets += n;
                            out.frames.push((t, slab));
                            filled += 1;
                        }
                        Err(_) => break,
                    }
                }
            }
            let complete = filled == periods - 1 && filled > 0;
            out.gap = Some(LossSpan {
                kind: if complete {
                    LossKind::Filled
                } else {
                    LossKind::Spanned
                },
                from_ns: prev,
                to_ns: f.stamp_ns,
                frames: (periods - 1).max(1) as u64,
                code: "frames_missing",
                reason: format!(
                    "{:.3} s between accepted frames, about {} frame period(s) of {:.3} s{}",
                    dt as f64 * 1e-9,
                    periods,
                    period as f64 * 1e-9,
                    over.map_or(String::new(), |n| format!(
                        "; filling it would take {n} tets, over max_fill_tets ({})",
                        self.mesher.options().max_fill_tets
                    ))
                ),
            });
            if !complete && (filled > 0 || over.is_some()) {
                // A partial fill would leave uneven frame times: span the gap instead.
                if let Some(s) = snapshot.clone() {
                    self.mesher.restore(s);
                }
                out.frames.clear();
                out.fill = None;
            }
        }
        let stamp = prepared.stamp_ns;
        match self.mesher.push_prepared(prepared) {
            Ok(slab) => out.frames.push((stamp, slab)),
            Err(e) => {
                if let Some(s) = snapshot {
                    self.mesher.restore(s);
                }
                // `restore` put the skip count back; count this frame once.
                self.refuse(Some(f.stamp_ns), &e);
                return Err(e);
            }
        }
        if let Some(g) = &out.gap {
            match g.kind {
                LossKind::Filled => self.losses.filled_frames += g.frames,
                _ => self.losses.spanned_gaps += 1,
            }
            // Every slab of the gap shows frames that were not observed.
            let why = match g.kind {
                LossKind::Filled => Unsure::Filled,
                _ => Unsure::Spanned,
            };
            for (_, slab) in &mut out.frames {
                if let Some(slab) = slab {
                    slab.unsure = Some(slab.unsure.map_or(why, |u| u.max(why)));
                }
            }
            self.losses.push(g.clone());
        }
        if clamped > 0 {
            self.losses.clamped_frames += 1;
            let e = MeshError::PercentOutOfRange { voxels: clamped };
            let previous_clamped = self.last_accept_clamped;
            let merge = self
                .losses
                .spans
                .back_mut()
                .filter(|s| s.kind == LossKind::Clamped && previous_clamped);
            match merge {
                Some(s) => {
                    s.to_ns = f.stamp_ns;
                    s.frames += 1;
                }
                None => self.losses.push(LossSpan {
                    kind: LossKind::Clamped,
                    from_ns: f.stamp_ns,
                    to_ns: f.stamp_ns,
                    frames: 1,
                    code: e.code(),
                    reason: e.to_string(),
                }),
            }
        }
        self.last_accept_clamped = clamped > 0;
        out.clamped = clamped;
        self.refusing = false;
        self.saw(f.stamp_ns);
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    /// A 2x2x2 bits frame at `stamp_ns`.
    fn frame(stamp_ns: i64, data: &[u8]) -> FrameRef<'_> {
        sized(stamp_ns, [2, 2, 2], data)
    }

    /// A bits frame of `size` voxels at `stamp_ns`.
    fn sized(stamp_ns: i64, size: [u32; 3], data: &[u8]) -> FrameRef<'_> {
        FrameRef {
            stamp_ns,
            origin: [0.0; 3],
            resolution: 0.01,
            size,
            encoding: 0,
            data,
        }
    }

    #[test]
    fn a_long_gap_years_into_the_stamps_is_filled_without_overflow() {
        let data = [0b0000_0001u8];
        let mut s = BodyStream::new(MesherOptions::default()).unwrap();
        let p = 10_000_000_000_000i64; // 2.8 h between frames
        s.push(&frame(0, &data)).unwrap();
        s.push(&frame(p, &data)).unwrap();
        // 1000 periods later: 999 frames filled, at exact multiples of the period.
        let a = s.push(&frame(1001 * p, &data)).unwrap();
        assert_eq!(a.frames.len(), 1000);
        assert_eq!(a.frames[998].0, 1000 * p);
        assert_eq!(s.losses().filled_frames, 999);
    }

    #[test]
    fn a_refused_frame_changes_nothing_and_a_gap_after_it_is_filled_between_accepted_ones() {
        let data = [0b0000_0001u8];
        let mut s = BodyStream::new(MesherOptions::default()).unwrap();
        s.push(&frame(0, &data)).unwrap();
        s.push(&frame(10, &data)).unwrap();
        // Frame 20 on another resolution: refused; its stamp only feeds the period.
        let mut other = frame(20, &data);
        other.resolution = 0.02;
        assert!(s.push(&other).is_err());
        assert_eq!(s.mesher().frames(), 2);
        assert_eq!(s.mesher().last_frame().unwrap().stamp_ns, 10);
        let a = s.push(&frame(30, &data)).unwrap();
        let stamps: Vec<i64> = a.frames.iter().map(|f| f.0).collect();
        assert_eq!(stamps, [20, 30]);
        let kinds: Vec<LossKind> = s.losses().spans.iter().map(|s| s.kind).collect();
        assert_eq!(kinds, [LossKind::Refused, LossKind::Filled]);
    }

    /// A 6x5x4 bits frame at `stamp_ns` (120 bits in 15 bytes).
    fn frame654(stamp_ns: i64, data: &[u8]) -> FrameRef<'_> {
        sized(stamp_ns, [6, 5, 4], data)
    }

    /// The slabs of 6x5x4 frames `a` at 0 and 10, then `b` after `periods` periods, with
    /// the given fill budget.
    fn fill(a: &[u8], b: &[u8], periods: i64, max_fill_tets: usize) -> (Accepted, BodyStream) {
        let opts = MesherOptions {
            max_fill_tets,
            ..MesherOptions::default()
        };
        let mut s = BodyStream::new(opts).unwrap();
        s.push(&frame654(0, a)).unwrap();
        s.push(&frame654(10, a)).unwrap();
        let got = s.push(&frame654(10 + 10 * periods, b)).unwrap();
        (got, s)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]

        /// A filled frame's slab moved in time is the slab marching would give, exactly.
        #[test]
        fn filled_slabs_equal_marched_ones(
            a in prop::collection::vec(any::<u8>(), 15),
            b in prop::collection::vec(any::<u8>(), 15),
            periods in 2i64..7,
        ) {
            let (got, s) = fill(&a, &b, periods, usize::MAX);
            prop_assert_eq!(got.frames.len() as i64, periods);
            prop_assert_eq!(s.losses().filled_frames as i64, periods - 1);
            // The same frames, each pushed by hand (marched).
            let both = got.fill.clone().unwrap();
            let mut m = Mesher::new(MesherOptions::default()).unwrap();
            let g = *s.mesher().geometry().unwrap();
            let first = m.push(&frame654(0, &a)).unwrap();
            prop_assert!(first.is_none());
            m.push(&frame654(10, &a)).unwrap();
            for (j, (t, slab)) in got.frames.iter().enumerate().take(periods as usize - 1) {
                prop_assert_eq!(*t, 10 + 10 * (j as i64 + 1));
                let mut marched = m.push_decoded(*t, g, both.clone()).unwrap();
                // Filled slabs are marked as such (the frames were not observed).
                let unsure = slab.as_ref().and_then(|s| s.unsure);
                prop_assert_eq!(unsure, Some(crate::unsure::Unsure::Filled));
                if let Some(m) = &mut marched {
                    m.unsure = unsure;
                }
                prop_assert_eq!(slab, &marched);
            }
        }
    }

    #[test]
    fn a_fill_over_its_budget_is_refused_before_the_repeats_exist_and_spans_the_gap() {
        // Two occupied voxels apart, so every slab has tets.
        let mut a = [0u8; 15];
        a[0] = 1;
        let mut b = [0u8; 15];
        b[14] = 0b1000_0000;
        let (all, _) = fill(&a, &b, 40, usize::MAX);
        let per_repeat = all.frames[1].1.as_ref().unwrap().mesh.tets.len();
        let whole: usize = all.frames[..39]
            .iter()
            .map(|f| f.1.as_ref().unwrap().mesh.tets.len())
            .sum();
        assert!(per_repeat > 0);
        // Exactly the whole fill: filled.
        let (got, s) = fill(&a, &b, 40, whole);
        assert_eq!(got.frames.len(), 40);
        assert_eq!(s.losses().filled_frames, 39);
        // One tet less: refused as a whole, the gap spanned by one slab, and said.
        let (got, s) = fill(&a, &b, 40, whole - 1);
        assert_eq!(got.frames.len(), 1);
        assert!(got.fill.is_none());
        assert_eq!(s.losses().filled_frames, 0);
        assert_eq!(s.losses().spanned_gaps, 1);
        let span = s.losses().spans.back().unwrap();
        assert_eq!(span.kind, LossKind::Spanned);
        assert!(
            span.reason.contains(&format!(
                "filling it would take {whole} tets, over max_fill_tets"
            )),
            "{}",
            span.reason
        );
        // The stream goes on from the frame after the gap.
        assert_eq!(s.mesher().last_frame().unwrap().stamp_ns, 410);
        assert_eq!(s.mesher().frames(), 3);
    }
}
