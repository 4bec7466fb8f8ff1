//! The cutting force: seed eq. 8 or the cut cross-section, low-pass filtered and rendered
//! through a virtual coupling.

use super::math::{norm, scale, Vec3};
use super::CutStats;

/// Which cut force.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ForceModel {
    /// Seed eq. 8: `F = n · n_avg` times a gain (N per removed point). Depends on the pose
    /// rate and the grid spacing (DESIGN.md §8: a coefficient of variation of 4.7 at 1 kHz).
    Count,
    /// The cut cross-section `A = n h^3 / |Δx|` (m^2: removed volume per distance moved,
    /// the distance being the tool origin's plus rotation angle x tool radius)
    /// times a specific cutting pressure (N/m^2), along `n_avg`: independent of the pose
    /// rate and, up to sampling, of the spacing.
    Volume,
    /// The cut cross-section read off the material in front of the tool: `A = m h^2` for the
    /// `m` material points within one spacing ahead of it along the move
    /// ([`crate::carving::Workpiece::material_ahead`]), times the cutting pressure, against
    /// the motion. Rate independent like [`ForceModel::Volume`], and without its stepping
    /// (points are removed a layer at a time, so the removed volume per pose comes in bursts).
    Section,
}

impl std::str::FromStr for ForceModel {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "count" => Ok(Self::Count),
            "volume" => Ok(Self::Volume),
            "section" => Ok(Self::Section),
            o => Err(format!("force model {o:?}: one of count, volume, section")),
        }
    }
}

/// Parameters of [`ForceRenderer`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceParams {
    /// Which cut force.
    pub model: ForceModel,
    /// [`ForceModel::Count`]: newtons per removed point.
    pub newtons_per_point: f64,
    /// [`ForceModel::Volume`]: specific cutting pressure (N/m^2 of cross-section).
    pub pressure: f64,
    /// Cut-off of the first-order low-pass filter (Hz); 0 = no filter.
    pub cutoff_hz: f64,
    /// Virtual coupling stiffness (N/m); 0 = no coupling (the filtered force is rendered).
    pub coupling_stiffness: f64,
    /// Virtual coupling damping (N·s/m).
    pub coupling_damping: f64,
    /// Virtual coupling proxy mass (kg).
    pub proxy_mass: f64,
    /// Largest force rendered (N).
    pub max_force: f64,
}

impl Default for ForceParams {
    fn default() -> Self {
        Self {
            model: ForceModel::Section,
            newtons_per_point: 0.05,
            pressure: 2.0e5,
            cutoff_hz: 30.0,
            coupling_stiffness: 2000.0,
            coupling_damping: 8.0,
            proxy_mass: 0.02,
            max_force: 10.0,
        }
    }
}

/// Turns what each move removed into the force rendered on the device.
///
/// The cut force of each move (by [`ForceModel`]) goes through a first-order low-pass filter,
/// then a virtual coupling: a proxy of mass `m` pulled by the filtered force and held to the
/// device by a spring-damper `(k, b)`; the spring-damper's force is rendered. The coupling is
/// what keeps a stiff cut passive on a real device (it bounds the apparent stiffness by `k`);
/// here it acts as a second-order filter of natural frequency `sqrt(k/m)`. The result is
/// clamped at `max_force`.
#[derive(Debug, Clone)]
pub struct ForceRenderer {
    p: ForceParams,
    filtered: Vec3,
    /// Proxy displacement from the device (m) and its velocity (m/s).
    delta: Vec3,
    delta_v: Vec3,
}

impl ForceRenderer {
    /// A renderer at rest.
    pub fn new(p: ForceParams) -> Self {
        Self {
            p,
            filtered: [0.0; 3],
            delta: [0.0; 3],
            delta_v: [0.0; 3],
        }
    }

    /// The parameters.
    pub fn params(&self) -> &ForceParams {
        &self.p
    }

    /// The unfiltered cut force of one move (N) on a grid of `spacing`.
    pub fn cut_force(&self, cut: &CutStats, spacing: f64, motion: Vec3) -> Vec3 {
        if self.p.model == ForceModel::Section {
            let len = norm(motion);
            if cut.ahead == 0 || !(len > 1e-12) {
                return [0.0; 3];
            }
            let area = cut.ahead as f64 * spacing * spacing;
            return scale(motion, -self.p.pressure * area / len);
        }
        if cut.removed == 0 {
            return [0.0; 3];
        }
        // n_avg: the mean outward normal of the removed surface points, else against the move.
        let mut dir = cut.normal_sum;
        let mut len = norm(dir);
        if len < 1e-9 {
            dir = scale(motion, -1.0);
            len = norm(dir);
            if len < 1e-15 {
                return [0.0; 3];
            }
        }
        let unit = scale(dir, 1.0 / len);
        let magnitude = match self.p.model {
            ForceModel::Count | ForceModel::Section => {
                self.p.newtons_per_point * cut.removed as f64
            }
            ForceModel::Volume => {
                // No travel (a stroke's first pose, the tool appearing in the material): no
                // cross-section to speak of.
                if cut.travel < 1e-12 {
                    return [0.0; 3];
                }
                let area = cut.removed as f64 * spacing.powi(3) / cut.travel;
                self.p.pressure * area
            }
        };
        scale(unit, magnitude)
    }

    /// The force rendered after a move that removed `cut`, `dt` seconds after the previous
    /// one (clamped to [0, 0.1] s).
    pub fn step(&mut self, cut: &CutStats, spacing: f64, motion: Vec3, dt: f64) -> Vec3 {
        let f = self.cut_force(cut, spacing, motion);
        let dt = if dt.is_finite() {
            dt.clamp(0.0, 0.1)
        } else {
            0.0
        };
        let p = self.p;
        if p.cutoff_hz > 0.0 {
            let tau = 1.0 / (2.0 * std::f64::consts::PI * p.cutoff_hz);
            let alpha = dt / (dt + tau);
            for a in 0..3 {
                self.filtered[a] += alpha * (f[a] - self.filtered[a]);
            }
        } else {
            self.filtered = f;
        }
        let mut out = if p.coupling_stiffness > 0.0 && p.proxy_mass > 0.0 {
            // Semi-implicit Euler, substepped well inside its stability limit.
            let w = (p.coupling_stiffness / p.proxy_mass).sqrt();
            let n = ((dt * w / 0.2).ceil() as usize).clamp(1, 1000);
            let h = dt / n as f64;
            for _ in 0..n {
                for a in 0..3 {
                    let acc = (self.filtered[a]
                        - p.coupling_stiffness * self.delta[a]
                        - p.coupling_damping * self.delta_v[a])
                        / p.proxy_mass;
                    self.delta_v[a] += h * acc;
                    self.delta[a] += h * self.delta_v[a];
                }
            }
            [0, 1, 2].map(|a| {
                p.coupling_stiffness * self.delta[a] + p.coupling_damping * self.delta_v[a]
            })
        } else {
            self.filtered
        };
        let m = norm(out);
        if m > p.max_force {
            out = scale(out, p.max_force / m);
        }
        out
    }
}
