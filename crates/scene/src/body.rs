//! A body: a union of shapes moving rigidly, published on one topic.

use super::{Aabb, Motion, Shape};

/// One rigid body of a scene: the union of `shapes` (given in the rest pose), translated by
/// `motion`, published on `topic`.
#[derive(Debug, Clone, PartialEq)]
pub struct BodySpec {
    /// The topic (and body id), e.g. `/spindle/occupancy`.
    pub topic: String,
    /// What the body is, in a few words.
    pub description: String,
    /// The solids whose union is the body, in the rest pose.
    pub shapes: Vec<Shape>,
    /// Translation from the rest pose over time.
    pub motion: Motion,
}

impl BodySpec {
    /// A body on `topic` made of `shapes` moving by `motion`.
    pub fn new(
        topic: impl Into<String>,
        description: impl Into<String>,
        shapes: Vec<Shape>,
        motion: Motion,
    ) -> Self {
        Self {
            topic: topic.into(),
            description: description.into(),
            shapes,
            motion,
        }
    }

    /// The translation at `t` seconds since the scene's first frame.
    pub fn offset_at(&self, t: f64) -> [f64; 3] {
        self.motion.offset_at(t)
    }

    /// The shapes placed where they are at time `t`.
    pub fn shapes_at(&self, t: f64) -> impl Iterator<Item = Shape> + '_ {
        let offset = self.offset_at(t);
        self.shapes.iter().map(move |s| s.translated(offset))
    }

    /// Whether `p` is strictly inside the body at time `t`.
    pub fn contains(&self, p: [f64; 3], t: f64) -> bool {
        // Translate the shapes, not the point, exactly as the rasteriser does.
        self.shapes_at(t).any(|s| s.contains(p))
    }

    /// Signed distance of `p` to the body at time `t`: the minimum over its shapes. Exact
    /// outside; inside, its magnitude is a lower bound on the distance to the surface.
    pub fn signed_distance(&self, p: [f64; 3], t: f64) -> f64 {
        self.shapes_at(t)
            .map(|s| s.signed_distance(p))
            .fold(f64::INFINITY, f64::min)
    }

    /// Bounding box at time `t`, or `None` for a body without shapes.
    pub fn aabb_at(&self, t: f64) -> Option<Aabb> {
        let o = self.offset_at(t);
        self.shapes
            .iter()
            .map(|s| s.aabb())
            .reduce(|a, b| a.union(&b))
            .map(|b| b.translated(o))
    }
}
