//! The carving tools: convex prisms given by their faces (half-spaces) in the tool frame.

use super::math::{dot, norm, Vec3};
use super::CarveError;

/// Which tool.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ToolKind {
    /// The knife of seed §4.2: a rectangle (length along the tool's x, width along y),
    /// centred on the tool origin, its face normal the tool's z.
    Knife,
    /// The triangular chisel of seed §4.3: an isosceles triangle in the tool's y-z plane,
    /// apex at the tool origin, opening towards +z (width at the top, height along z); it
    /// cuts moving along the tool's x, sweeping a triangular prism.
    Chisel,
}

impl std::str::FromStr for ToolKind {
    type Err = CarveError;
    fn from_str(s: &str) -> Result<Self, CarveError> {
        match s {
            "knife" => Ok(Self::Knife),
            "chisel" => Ok(Self::Chisel),
            other => Err(CarveError::UnknownTool(other.to_owned())),
        }
    }
}

impl ToolKind {
    /// The name a launch config uses.
    pub fn name(self) -> &'static str {
        match self {
            Self::Knife => "knife",
            Self::Chisel => "chisel",
        }
    }
}

/// A tool: a convex polytope `{x : n_k · x <= o_k for all k}` in the tool frame.
///
/// The seed's tools are flat (a rectangle, a triangle); they are given a thickness along
/// their face normal so that the solid swept by a move within the blade's plane has volume.
/// A blade thinner than the grid spacing would remove almost nothing on a point grid
/// (docs/methods/carving.md#thin-blades: at thickness / spacing = 0.2, 81% of cuts remove
/// nothing), so it is cut as one spacing thick and [`Tool::thickened`] says so: never a
/// silent miss.
#[derive(Debug, Clone, PartialEq)]
pub struct Tool {
    kind: ToolKind,
    faces: Vec<(Vec3, f64)>,
    vertices: Vec<Vec3>,
    radius: f64,
    thickness: f64,
    asked_thickness: f64,
}

fn positive(what: &str, v: f64) -> Result<f64, CarveError> {
    if v.is_finite() && v > 0.0 && v <= 10.0 {
        Ok(v)
    } else {
        Err(CarveError::Tool(format!(
            "{what} = {v}: a finite length in (0, 10] m"
        )))
    }
}

impl Tool {
    /// The knife: a `length` x `width` rectangle of `thickness` (m), cut on a grid of
    /// `spacing` (a thickness below `spacing` is cut as `spacing`).
    ///
    /// # Errors
    /// [`CarveError::Tool`] for a dimension that is not finite and in (0, 10] m
    /// (`thickness` may be 0: a flat blade).
    pub fn knife(
        length: f64,
        width: f64,
        thickness: f64,
        spacing: f64,
    ) -> Result<Self, CarveError> {
        let l = positive("knife length", length)? / 2.0;
        let w = positive("knife width", width)? / 2.0;
        let t = Self::thickness(thickness, spacing)?;
        let h = t / 2.0;
        let faces = vec![
            ([1.0, 0.0, 0.0], l),
            ([-1.0, 0.0, 0.0], l),
            ([0.0, 1.0, 0.0], w),
            ([0.0, -1.0, 0.0], w),
            ([0.0, 0.0, 1.0], h),
            ([0.0, 0.0, -1.0], h),
        ];
        let mut vertices = Vec::with_capacity(8);
        for sx in [-l, l] {
            for sy in [-w, w] {
                for sz in [-h, h] {
                    vertices.push([sx, sy, sz]);
                }
            }
        }
        Ok(Self::build(ToolKind::Knife, faces, vertices, t, thickness))
    }

    /// The triangular chisel: an isosceles triangle `width` wide at the top and `height`
    /// high (apex at the origin), `thickness` along the cutting direction (the tool's x).
    ///
    /// # Errors
    /// [`CarveError::Tool`] for a dimension that is not finite and in (0, 10] m.
    pub fn chisel(
        width: f64,
        height: f64,
        thickness: f64,
        spacing: f64,
    ) -> Result<Self, CarveError> {
        let w = positive("chisel width", width)? / 2.0;
        let hgt = positive("chisel height", height)?;
        let t = Self::thickness(thickness, spacing)?;
        let h = t / 2.0;
        // Slanted sides through the apex and (y = ±w, z = hgt); outward normals.
        let side = |s: f64| {
            let n = [0.0, s * hgt, -w];
            let l = norm(n);
            ([0.0, n[1] / l, n[2] / l], 0.0)
        };
        let faces = vec![
            ([1.0, 0.0, 0.0], h),
            ([-1.0, 0.0, 0.0], h),
            ([0.0, 0.0, 1.0], hgt),
            side(1.0),
            side(-1.0),
        ];
        let mut vertices = Vec::with_capacity(6);
        for sx in [-h, h] {
            vertices.push([sx, 0.0, 0.0]);
            vertices.push([sx, -w, hgt]);
            vertices.push([sx, w, hgt]);
        }
        Ok(Self::build(ToolKind::Chisel, faces, vertices, t, thickness))
    }

    fn thickness(t: f64, spacing: f64) -> Result<f64, CarveError> {
        if !(t.is_finite() && (0.0..=10.0).contains(&t)) {
            return Err(CarveError::Tool(format!(
                "thickness = {t}: a finite length in [0, 10] m"
            )));
        }
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(CarveError::Tool(format!(
                "grid spacing {spacing} is not positive"
            )));
        }
        Ok(t.max(spacing))
    }

    fn build(
        kind: ToolKind,
        faces: Vec<(Vec3, f64)>,
        vertices: Vec<Vec3>,
        thickness: f64,
        asked_thickness: f64,
    ) -> Self {
        let radius = vertices.iter().map(|&v| norm(v)).fold(0.0, f64::max);
        debug_assert!(vertices
            .iter()
            .all(|&v| faces.iter().all(|&(n, o)| dot(n, v) <= o + 1e-12)));
        Self {
            kind,
            faces,
            vertices,
            radius,
            thickness,
            asked_thickness,
        }
    }

    /// Which tool.
    pub fn kind(&self) -> ToolKind {
        self.kind
    }

    /// Faces `(outward unit normal, offset)` in the tool frame.
    pub fn faces(&self) -> &[(Vec3, f64)] {
        &self.faces
    }

    /// Corners in the tool frame.
    pub fn vertices(&self) -> &[Vec3] {
        &self.vertices
    }

    /// Largest distance of a corner from the tool origin (m).
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// The thickness cut (m): the one asked for, or the grid spacing if that was thinner.
    pub fn cut_thickness(&self) -> f64 {
        self.thickness
    }

    /// `Some(asked thickness)` if the blade was thinner than the grid spacing and is cut as
    /// one spacing thick.
    pub fn thickened(&self) -> Option<f64> {
        (self.asked_thickness < self.thickness).then_some(self.asked_thickness)
    }

    /// Is the tool-frame point `p` inside (within `tol`)?
    pub fn contains(&self, p: Vec3, tol: f64) -> bool {
        self.faces.iter().all(|&(n, o)| dot(n, p) <= o + tol)
    }
}
