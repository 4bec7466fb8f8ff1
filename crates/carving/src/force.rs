//! The cutting force: seed eq. 8 or the cut cross-section, low-pass filtered and rendered
//! through a virtual coupling.

use super::math::{norm, scale, Vec3};
use super::{CarveError, CutStats};

/// Which cut force.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ForceModel {
    /// Seed eq. 8: `F = n · n_avg` times a gain (N per removed point). Depends on the pose
    /// rate and the grid spacing
    /// (docs/methods/carving.md#force-depends-on-rate-and-spacing: a coefficient of
    /// variation of 4.7 at 1 kHz).
    Count,
    /// The cut cross-section `A = n h^3 / |Δx|` (m^2: removed volume per distance moved,
    /// the distance being the tool origin's plus rotation angle x tool radius)
    /// times a specific cutting pressure (N/m^2), along `n_avg`: independent of the pose
    /// rate and, up to sampling, of the spacing.
    Volume,
    /// The cut cross-section read off the material in front of the tool
    /// ([`crate::Workpiece::section_ahead`]: the material in a one-spacing window
    /// half a spacing ahead of it along the move, with sub-voxel weights, divided by the
    /// window's length), times the cutting pressure, against the motion. Rate independent
    /// like [`ForceModel::Volume`], and without its stepping (points are removed a layer at
    /// a time, so the removed volume per pose comes in bursts), nor the lattice-phase jumps
    /// a plain count of the points ahead has on a cut diagonal to the grid.
    Section,
}

impl std::str::FromStr for ForceModel {
    type Err = CarveError;
    fn from_str(s: &str) -> Result<Self, CarveError> {
        match s {
            "count" => Ok(Self::Count),
            "volume" => Ok(Self::Volume),
            "section" => Ok(Self::Section),
            o => Err(CarveError::UnknownForceModel(o.to_owned())),
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

/// Shortest integration substep of the virtual coupling (s): a tenth of the 1 kHz haptic
/// period. A move `dt` after the previous one is integrated in equal substeps short
/// enough for accuracy (`ω h ≤ 0.2`, `ω = sqrt(k/m)`) and for stability (`h ≤ h*`, the
/// largest step meeting the condition of [`ForceParams::validate`]), at most
/// [`MAX_MOVE_DT_S`] / `COUPLING_STEP_S` = 1000 of them; parameters are accepted when
/// `h* ≥ COUPLING_STEP_S`, so the stable step always fits in that budget.
pub const COUPLING_STEP_S: f64 = 1e-4;

/// Most coupling substeps of one move ([`MAX_MOVE_DT_S`] / [`COUPLING_STEP_S`]).
const MAX_COUPLING_SUBSTEPS: f64 = 1000.0;

/// Longest time (s) one move integrates the filter and the coupling over: a pose after a
/// longer pause is taken as this long after the previous one, so a pause costs at most
/// `MAX_MOVE_DT_S / COUPLING_STEP_S` = 1000 substeps, whatever its length.
pub const MAX_MOVE_DT_S: f64 = 0.1;

/// The coupling is accepted while `k h²/m + 2 b h/m` at [`COUPLING_STEP_S`] stays at or
/// below this: half of the stability bound 4, for margin.
pub const COUPLING_STABILITY_MARGIN: f64 = 2.0;

impl ForceParams {
    /// The stability number of the virtual coupling's integration, `k h²/m + 2 b h/m` at
    /// `h = COUPLING_STEP_S`.
    ///
    /// The coupling is integrated by semi-implicit (symplectic) Euler:
    /// `v' = v + h (F - k x - b v)/m`, `x' = x + h v'`. Its matrix on `(v, x)` has trace
    /// `2 - h b/m - h² k/m` and determinant `1 - h b/m`; by the Jury criterion both roots
    /// lie inside the unit circle iff `0 ≤ h b/m < 2` and `h² k/m + 2 h b/m < 4` (the
    /// second implies the first for `k ≥ 0`). Outside, the proxy's displacement grows
    /// geometrically until it overflows to infinity and the rendered force to NaN.
    pub fn coupling_stability(&self) -> f64 {
        let h = COUPLING_STEP_S;
        (self.coupling_stiffness * h * h + 2.0 * self.coupling_damping * h) / self.proxy_mass
    }

    /// The largest integration step (s) with `k h²/m + 2 b h/m ≤ 2`
    /// ([`COUPLING_STABILITY_MARGIN`]), or infinity without a coupling.
    pub fn stable_step(&self) -> f64 {
        let (k, b, m) = (
            self.coupling_stiffness,
            self.coupling_damping,
            self.proxy_mass,
        );
        let c = COUPLING_STABILITY_MARGIN;
        if k > 0.0 {
            // The positive root of k h² + 2 b h - c m = 0.
            (-b + (b * b + c * k * m).sqrt()) / k
        } else if b > 0.0 {
            c * m / (2.0 * b)
        } else {
            f64::INFINITY
        }
    }

    /// Checks the parameters: every number finite and not negative, and the virtual
    /// coupling stable at its integration step with margin
    /// (`k h²/m + 2 b h/m ≤ 2` at `h = 0.1 ms`, half the bound 4 of
    /// [`ForceParams::coupling_stability`]).
    ///
    /// # Errors
    /// [`CarveError::Force`] naming the parameter and the condition.
    pub fn validate(&self) -> Result<(), CarveError> {
        for (name, v) in [
            ("newtons_per_point", self.newtons_per_point),
            ("cutting_pressure_n_per_m2", self.pressure),
            ("filter_cutoff_hz", self.cutoff_hz),
            ("coupling_stiffness_n_per_m", self.coupling_stiffness),
            ("coupling_damping_ns_per_m", self.coupling_damping),
            ("proxy_mass_kg", self.proxy_mass),
            ("max_force_n", self.max_force),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(CarveError::Force {
                    param: name,
                    reason: format!("{name} {v}: a finite number ≥ 0 is needed"),
                });
            }
        }
        if self.coupling_stiffness == 0.0 {
            return Ok(()); // no coupling: the filtered force is rendered
        }
        let s = self.coupling_stability();
        if !(self.proxy_mass > 0.0 && s <= COUPLING_STABILITY_MARGIN) {
            let h = COUPLING_STEP_S;
            let need = (self.coupling_stiffness * h * h + 2.0 * self.coupling_damping * h)
                / COUPLING_STABILITY_MARGIN;
            return Err(CarveError::Force {
                param: "proxy_mass_kg",
                reason: format!(
                    "proxy_mass_kg {} with coupling_stiffness_n_per_m {} and \
                 coupling_damping_ns_per_m {} makes the virtual coupling unstable: \
                 integrated by semi-implicit Euler in substeps down to h = {} ms (at most \
                 1000 in a move), it needs k·h²/m + 2·b·h/m ≤ {} there (stable below 4, \
                 half of it for margin), got {s:.3}; use proxy_mass_kg ≥ {need:.3e}, or a \
                 smaller stiffness or damping",
                    self.proxy_mass,
                    self.coupling_stiffness,
                    self.coupling_damping,
                    h * 1e3,
                    COUPLING_STABILITY_MARGIN,
                ),
            });
        }
        Ok(())
    }
}

/// Turns what each move removed into the force rendered on the device.
///
/// The cut force of each move (by [`ForceModel`]) goes through a first-order low-pass filter,
/// then a virtual coupling: a proxy of mass `m` pulled by the filtered force and held to the
/// device by a spring-damper `(k, b)`; the spring-damper's force is rendered. The coupling is
/// what keeps a stiff cut passive on a real device (it bounds the apparent stiffness by `k`);
/// here it acts as a second-order filter of natural frequency `sqrt(k/m)`, integrated in
/// substeps of at most [`COUPLING_STEP_S`] (stable for parameters that pass
/// [`ForceParams::validate`]). The result is clamped at `max_force`.
///
/// The rendered force is never NaN or infinite: should anything non-finite come out (a
/// parameter set that was not validated, a move whose length overflows), the filter and
/// the coupling are reset to rest, the last finite force is rendered instead, and the step
/// is counted ([`ForceRenderer::non_finite_steps`]).
#[derive(Debug, Clone)]
pub struct ForceRenderer {
    p: ForceParams,
    filtered: Vec3,
    /// Proxy displacement from the device (m) and its velocity (m/s).
    delta: Vec3,
    delta_v: Vec3,
    /// The last force rendered (finite, within `max_force`).
    last: Vec3,
    non_finite: u64,
}

impl ForceRenderer {
    /// A renderer at rest. Check the parameters first with [`ForceParams::validate`]:
    /// unstable ones are not refused here, but their forces are replaced (and counted).
    pub fn new(p: ForceParams) -> Self {
        Self {
            p,
            filtered: [0.0; 3],
            delta: [0.0; 3],
            delta_v: [0.0; 3],
            last: [0.0; 3],
            non_finite: 0,
        }
    }

    /// The parameters.
    pub fn params(&self) -> &ForceParams {
        &self.p
    }

    /// Steps whose force came out non-finite and was replaced by the last finite one.
    pub fn non_finite_steps(&self) -> u64 {
        self.non_finite
    }

    /// The unfiltered cut force of one move (N) on a grid of `spacing`.
    pub fn cut_force(&self, cut: &CutStats, spacing: f64, motion: Vec3) -> Vec3 {
        if self.p.model == ForceModel::Section {
            let len = norm(motion);
            let area = cut.ahead_area;
            if !(area > 0.0 && area.is_finite() && len > 1e-12) {
                return [0.0; 3];
            }
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
    /// one (clamped to [0, [`MAX_MOVE_DT_S`]] s: a pause costs no more than 0.1 s of
    /// integration). Finite and at most `max_force` long, always.
    pub fn step(&mut self, cut: &CutStats, spacing: f64, motion: Vec3, dt: f64) -> Vec3 {
        let f = self.cut_force(cut, spacing, motion);
        let dt = if dt.is_finite() {
            dt.clamp(0.0, MAX_MOVE_DT_S)
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
        let out = if p.coupling_stiffness > 0.0 && p.proxy_mass > 0.0 {
            // Semi-implicit Euler in equal substeps: ω h ≤ 0.2 for accuracy and h ≤ h* for
            // stability, at most MAX_COUPLING_SUBSTEPS (enough for h* for validated
            // parameters: h* ≥ COUPLING_STEP_S).
            let w = (p.coupling_stiffness / p.proxy_mass).sqrt();
            let accurate = (dt * w / 0.2).ceil();
            let stable = (dt / p.stable_step()).ceil();
            let n = accurate.max(stable);
            let n = if n.is_finite() {
                n.clamp(1.0, MAX_COUPLING_SUBSTEPS) as usize
            } else {
                MAX_COUPLING_SUBSTEPS as usize
            };
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
        if !out.iter().all(|v| v.is_finite()) {
            // Never render NaN: back to rest, the last finite force instead, counted.
            self.non_finite += 1;
            self.filtered = [0.0; 3];
            self.delta = [0.0; 3];
            self.delta_v = [0.0; 3];
            return self.last;
        }
        let m = norm(out);
        let out = if m > p.max_force {
            // `max_force` may be 0 (nothing rendered); m > 0 here.
            scale(out, p.max_force / m)
        } else {
            out
        };
        self.last = out;
        out
    }
}
