//! Where a body is not observed well enough for the 4D check to hold: the spans of its
//! stream in which a contact could be missed, why, and what would resolve it.
//!
//! Two bodies are called clear over a span only where both are observed there. A slab (the
//! body between two consecutive frames) is not, when:
//!
//! - **a part of the body vanishes between the frames** ([`super::vanish`]): it moves farther
//!   than its own thickness in one frame period, so nothing of it lies between its two
//!   positions in 4D; a higher frame rate resolves it;
//! - **its frames were filled in**: frames were missing, and the gap is filled with the union
//!   of the frames around it, which is safe for what stands still and says nothing of what
//!   moved in between; the missing frames resolve it;
//! - **one slab spans missing frames**: a gap too long (or too costly) to fill is bridged by
//!   one slab, with the same consequence.
//!
//! And a pair is not observed well enough over a slab when **a body moves more than
//! [`FAST_VOXELS`] voxels in it near the other** ([`Unsure::MovesFast`]): the 4D solid holds
//! the body as one frame or the other shows it, not the space it passes through in between,
//! so a contact on the way can be missed (see `docs/checker.md`).

//!
//! [`UnsureLog`] keeps a body's spans, merged where consecutive and alike, the latest
//! [`MAX_UNSURE_SPANS`] listed and the rest counted, so a stream of any length keeps bounded
//! memory.

use std::collections::VecDeque;

/// A body that moves more than this many voxels in a frame period passes, between the
/// frames, through space more than a voxel from both (on a straight path it is within half
/// its motion of one of them): beyond what the voxels themselves leave uncertain.
pub const FAST_VOXELS: u16 = 2;

/// Why a span of a body's stream is not observed well enough.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Unsure {
    /// A part of the body vanishes between the frames; `rate_factor` estimates how many times
    /// the frame rate would join it (0: not estimated).
    Vanishes {
        /// Estimated factor on the frame rate (0: unknown).
        rate_factor: f32,
    },
    /// Missing frames filled with the union of the frames around them.
    Filled,
    /// Missing frames bridged by one slab.
    Spanned,
    /// The body moves `voxels` voxels between the frames (more than [`FAST_VOXELS`]) and
    /// comes near the other body of a pair: what it passes on the way is not seen.
    MovesFast {
        /// How far it moves in the frame period (voxels; see
        /// [`super::vanish::Motion::displacement`]).
        voxels: u16,
    },
}

impl Unsure {
    /// A short code for reports (`vanishes`, `frames_filled`, `gap_spanned`, `moves_fast`).
    pub fn code(&self) -> &'static str {
        match self {
            Self::Vanishes { .. } => "vanishes",
            Self::MovesFast { .. } => "moves_fast",
            Self::Filled => "frames_filled",
            Self::Spanned => "gap_spanned",
        }
    }

    /// Why, in a user's words.
    pub fn reason(&self) -> &'static str {
        match self {
            Self::Vanishes { .. } => {
                "a part of the body moves farther than its own thickness between two frames, so \
                 it is not seen in between and a contact there can be missed"
            }
            Self::Filled => {
                "frames were missing and are filled with the union of the frames around the gap, \
                 which does not show how the body moved in between"
            }
            Self::Spanned => {
                "frames were missing and one slab bridges the gap, which does not show how the \
                 body moved in between"
            }
            Self::MovesFast { .. } => {
                "the body moves more than two voxels between two frames close to the other \
                 body, and what it passes on the way is not seen, so a contact there can be \
                 missed"
            }
        }
    }

    /// What would resolve it, given the slab's frame period (s).
    pub fn remedy(&self, period_s: f64) -> String {
        let rate = if period_s > 0.0 { 1.0 / period_s } else { 0.0 };
        match self {
            Self::Vanishes { rate_factor } if *rate_factor > 0.0 => format!(
                "a frame rate of at least {:.0} Hz for this body (now {:.3} s between frames, \
                 {rate:.1} Hz; estimated from how far the part moves against its thickness)",
                (rate * f64::from(*rate_factor)).ceil(),
                period_s
            ),
            Self::Vanishes { .. } => format!(
                "a higher frame rate for this body (now {period_s:.3} s between frames, \
                 {rate:.1} Hz)"
            ),
            Self::Filled | Self::Spanned => "the missing frames (a stream without gaps)".to_owned(),
            Self::MovesFast { voxels } => format!(
                "a frame rate of at least {:.0} Hz for this body (now {:.3} s between frames, \
                 {rate:.1} Hz, and it moves up to {voxels} voxels a frame), or keeping it \
                 farther from the other body",
                (rate * f64::from(*voxels) / f64::from(FAST_VOXELS)).ceil(),
                period_s
            ),
        }
    }

    /// The stronger of two reasons for one span: missing frames over a vanishing part over a
    /// fast motion, and the larger rate factor or motion.
    pub fn max(self, other: Self) -> Self {
        match (self, other) {
            (Self::Spanned, _) | (_, Self::Spanned) => Self::Spanned,
            (Self::Filled, _) | (_, Self::Filled) => Self::Filled,
            (Self::Vanishes { rate_factor: a }, Self::Vanishes { rate_factor: b }) => {
                Self::Vanishes {
                    rate_factor: a.max(b),
                }
            }
            (v @ Self::Vanishes { .. }, Self::MovesFast { .. })
            | (Self::MovesFast { .. }, v @ Self::Vanishes { .. }) => v,
            (Self::MovesFast { voxels: a }, Self::MovesFast { voxels: b }) => {
                Self::MovesFast { voxels: a.max(b) }
            }
        }
    }
}

/// One span of a body's stream that is not observed well enough.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnsureSpan {
    /// Start (ns).
    pub from_ns: i64,
    /// End (ns).
    pub to_ns: i64,
    /// Why.
    pub why: Unsure,
    /// The shortest frame period in it (ns), for the remedy.
    pub period_ns: i64,
}

/// Most spans a log lists; older ones are counted ([`UnsureLog::dropped`]).
pub const MAX_UNSURE_SPANS: usize = 64;

/// A body's (or a pair's) unsure spans, merged and bounded (see the module documentation).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct UnsureLog {
    spans: VecDeque<UnsureSpan>,
    /// Spans dropped from the front.
    dropped: u64,
    /// Their total length (ns).
    dropped_ns: i64,
}

impl UnsureLog {
    /// Adds a span, merged into the last one if it follows it (or overlaps it) with the same
    /// kind of reason.
    pub fn push(&mut self, span: UnsureSpan) {
        if span.to_ns < span.from_ns {
            return;
        }
        if let Some(last) = self.spans.back_mut() {
            if span.from_ns <= last.to_ns
                && span.to_ns >= last.from_ns
                && span.why.code() == last.why.code()
            {
                last.from_ns = last.from_ns.min(span.from_ns);
                last.to_ns = last.to_ns.max(span.to_ns);
                last.why = last.why.max(span.why);
                last.period_ns = last.period_ns.min(span.period_ns);
                return;
            }
        }
        self.spans.push_back(span);
        if self.spans.len() > MAX_UNSURE_SPANS {
            if let Some(old) = self.spans.pop_front() {
                self.dropped += 1;
                self.dropped_ns += old.to_ns - old.from_ns;
            }
        }
    }

    /// The spans listed, oldest first.
    pub fn spans(&self) -> impl Iterator<Item = &UnsureSpan> {
        self.spans.iter()
    }

    /// True if nothing was ever unsure.
    pub fn is_empty(&self) -> bool {
        self.spans.is_empty() && self.dropped == 0
    }

    /// Spans no longer listed, and their total length (ns).
    pub fn dropped(&self) -> (u64, i64) {
        (self.dropped, self.dropped_ns)
    }

    /// The spans of this log that overlap `[from_ns, to_ns]`, clipped to it.
    pub fn within(&self, from_ns: i64, to_ns: i64) -> impl Iterator<Item = UnsureSpan> + '_ {
        self.spans
            .iter()
            .filter(move |s| s.to_ns >= from_ns && s.from_ns <= to_ns)
            .map(move |s| UnsureSpan {
                from_ns: s.from_ns.max(from_ns),
                to_ns: s.to_ns.min(to_ns),
                ..*s
            })
    }
}

/// How far each of two bodies moves in a common slab (voxels), where one moves more than
/// [`FAST_VOXELS`] and the slabs' boxes come within both motions of each other; else 0 (a
/// body that moves at most [`FAST_VOXELS`] gives 0 too). Each body: its lattice, its slab's box on it
/// ([`super::march::TetMesh::spatial_bounds`]) and its motion ([`super::Slab::displacement`]).
///
/// What a body passes between frames is not in its slab; on a straight path it stays within
/// half its motion of one frame or the other, so a partner farther than both motions cannot
/// be met on the way. The boxes are compared in metres with half a voxel to spare: they only
/// decide whether to doubt, never whether bodies touch.
pub fn moves_fast_near(
    a: (
        &super::GridGeometry,
        Option<super::march::SpatialBounds>,
        u16,
    ),
    b: (
        &super::GridGeometry,
        Option<super::march::SpatialBounds>,
        u16,
    ),
) -> (u16, u16) {
    let ((ga, xa, da), (gb, xb, db)) = (a, b);
    if da.max(db) <= FAST_VOXELS {
        return (0, 0);
    }
    let (Some(xa), Some(xb)) = (xa, xb) else {
        return (0, 0);
    };
    let metres = |g: &super::GridGeometry, (lo, hi): super::march::SpatialBounds| {
        let (c, step) = (g.voxel0_centre(), g.step_m());
        (
            [0, 1, 2].map(|k| c[k] + f64::from(lo[k]) * step),
            [0, 1, 2].map(|k| c[k] + f64::from(hi[k]) * step),
        )
    };
    let ((alo, ahi), (blo, bhi)) = (metres(ga, xa), metres(gb, xb));
    let margin = (f64::from(da) + f64::from(db) + 0.5) * ga.resolution.max(gb.resolution);
    if !(0..3).all(|k| alo[k] - margin <= bhi[k] && blo[k] - margin <= ahi[k]) {
        return (0, 0);
    }
    let fast = |d: u16| if d > FAST_VOXELS { d } else { 0 };
    (fast(da), fast(db))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn span(a: i64, b: i64, why: Unsure) -> UnsureSpan {
        UnsureSpan {
            from_ns: a,
            to_ns: b,
            why,
            period_ns: 100,
        }
    }

    #[test]
    fn consecutive_alike_spans_merge_and_the_log_stays_bounded() {
        let mut log = UnsureLog::default();
        let v = |f| Unsure::Vanishes { rate_factor: f };
        log.push(span(0, 100, v(2.0)));
        log.push(span(100, 200, v(4.0)));
        log.push(span(200, 300, Unsure::Filled));
        let spans: Vec<_> = log.spans().copied().collect();
        assert_eq!(spans.len(), 2);
        assert_eq!((spans[0].from_ns, spans[0].to_ns), (0, 200));
        assert_eq!(spans[0].why, v(4.0));
        for k in 0..1000 {
            log.push(span(1000 + 200 * k, 1100 + 200 * k, v(2.0)));
        }
        assert_eq!(log.spans().count(), MAX_UNSURE_SPANS);
        assert_eq!(log.dropped().0, 1002 - MAX_UNSURE_SPANS as u64);
        let clipped: Vec<_> = log.within(1000 + 200 * 990 + 50, i64::MAX).collect();
        assert_eq!(clipped[0].from_ns, 1000 + 200 * 990 + 50);
    }

    #[test]
    fn remedies_say_what_to_change() {
        let r = Unsure::Vanishes { rate_factor: 5.0 }.remedy(0.1);
        assert!(r.contains("50 Hz") && r.contains("10.0 Hz"), "{r}");
        assert!(Unsure::Filled.remedy(0.1).contains("missing frames"));
    }

    #[test]
    fn a_fast_body_near_another_is_doubted_and_far_from_it_is_not() {
        let g = crate::GridGeometry {
            origin: [0.0; 3],
            resolution: 0.01,
            size: [64; 3],
            encoding: 0,
            scale: 2,
        };
        // Boxes in lattice steps (2 a voxel): a at x voxels 0..6, b from x voxel 10 on.
        let a = Some(([0, 0, 0], [12, 12, 12]));
        let b = |x: i32| Some(([2 * x, 0, 0], [2 * x + 4, 12, 12]));
        // 4 voxels apart, a moves 3 a frame, b 1: within 3 + 1 (+ half a voxel).
        assert_eq!(moves_fast_near((&g, a, 3), (&g, b(10), 1)), (3, 0));
        // 5 voxels apart: not within 4.5.
        assert_eq!(moves_fast_near((&g, a, 3), (&g, b(11), 1)), (0, 0));
        // Neither moves more than two voxels: no doubt, however near.
        assert_eq!(moves_fast_near((&g, a, 2), (&g, b(6), 2)), (0, 0));
        // Both fast.
        assert_eq!(moves_fast_near((&g, a, 3), (&g, b(10), 3)), (3, 3));
        let fast = Unsure::MovesFast { voxels: 4 };
        assert_eq!(fast.code(), "moves_fast");
        assert!(
            fast.remedy(0.1).contains("at least 20 Hz"),
            "{}",
            fast.remedy(0.1)
        );
        let v = Unsure::Vanishes { rate_factor: 2.0 };
        assert_eq!(fast.max(v), v);
        assert_eq!(Unsure::Filled.max(fast), Unsure::Filled);
        assert_eq!(
            fast.max(Unsure::MovesFast { voxels: 9 }),
            Unsure::MovesFast { voxels: 9 }
        );
    }
}
