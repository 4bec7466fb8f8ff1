//! Scene files (YAML): implicit bodies with their motions, the walls, and which boundaries
//! to sample. Examples live under `scenes/implicit/`.
//!
//! ```yaml
//! dim: 4                       # 3: space; 4: space-time (x, y, z, t)
//! bodies:
//!   - name: a
//!     shape: {kind: sphere, centre: [0, 0, 0], radius: 1.0}
//!   - name: b
//!     shape: {kind: box, centre: [-1.5, 0, 0], half: [0.4, 0.4, 0.4]}
//!     velocity: [1.0, 0, 0]    # m/s, in the given pose at t_ref (default 0)
//! sample: [a, b]               # M = 2: where both surfaces pass at once
//! walls:
//!   - {kind: box, min: [-3, -3, -3], max: [3, 3, 3]}
//! time: [0.0, 3.0]             # dim 4: the time window (reflecting walls on t)
//! sampler: {scheme: metropolis, dt: 0.001, samples: 20000}   # optional defaults
//! ```
//!
//! Shapes: `sphere`, `box` (rounded edges, see [`Shape::Box`]), `torus`, `capsule`, `cone`,
//! `seed_saddle` and `seed_holes` (the sampling paper's Figs. 1 and 2:
//! docs/methods/sampling.md#figures-of-the-paper). Any body may carry `warp: [kx, ky, kz]`,
//! multiplying its function by `exp(k·p)` (same surface, not a distance any more). Walls:
//! `box` (on x, y, z; for dim 4 the time window is added) and `shell`
//! (`inner ≤ |p - centre| ≤ outer`, the seed's Fig. 1).
//!
//! What dim 4 samples: the points (x, y, z, t) where the surfaces of the sampled bodies
//! pass at the same time — for two bodies the 2D surface swept by the curve where they
//! cross (the sampling paper's §3.3: docs/methods/sampling.md#the-4d-collision-set); its
//! YZT projection is the seed's Fig. 3. It is non-empty exactly while the bodies'
//! boundaries cross, i.e. while they interfere (a body wholly inside the other has no
//! crossing and is not seen).

use super::field::{Body, Shape, Q};
use super::figure::{Figure, Wall};
use super::{SamplerError, SamplerOptions, Scheme};
use chronotope_yaml::{number, quote};
use serde::Deserialize;
use std::sync::Arc;

/// Most bodies in one scene file.
pub const MAX_BODIES: usize = 64;
/// Largest scene file read (bytes): `config_bytes` of [`chronotope_yaml::CONFIG_LIMITS`].
pub const MAX_FILE_BYTES: u64 = chronotope_yaml::CONFIG_LIMITS.max_bytes as u64;
/// Most walls in one scene file.
pub const MAX_WALLS: usize = 64;

/// What is wrong with a scene file.
#[derive(Debug, thiserror::Error)]
pub enum SceneFileError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The file is larger than [`MAX_FILE_BYTES`].
    #[error("{path}: {bytes} bytes, more than the {MAX_FILE_BYTES} a scene file may have")]
    TooLarge {
        /// The file.
        path: String,
        /// Its size.
        bytes: u64,
    },
    /// Refused before parsing (a limit of [`chronotope_yaml::CONFIG_LIMITS`], an alias, not a
    /// regular file), or not valid YAML for a scene.
    #[error("scene file: {0}")]
    Yaml(#[from] chronotope_yaml::YamlError),
    /// Valid YAML, invalid scene.
    #[error("scene file: {0}")]
    Invalid(String),
    /// The figure could not be built.
    #[error(transparent)]
    Sampler(#[from] SamplerError),
}

/// One body of a scene file.
#[derive(Debug, Clone, Deserialize)]
#[serde(
    deny_unknown_fields,
    expecting = "a body: a mapping with name, shape, and optionally velocity, t_ref, warp"
)]
pub struct BodyEntry {
    /// Unique name.
    pub name: String,
    /// The solid, in its pose at `t_ref`.
    pub shape: Shape,
    /// Velocity (m/s).
    #[serde(default)]
    pub velocity: [f64; 3],
    /// When the body is in its given pose (s).
    #[serde(default)]
    pub t_ref: f64,
    /// Warp exponent (1/m).
    #[serde(default)]
    pub warp: [f64; 3],
}

/// A wall of a scene file.
#[derive(Debug, Clone, Deserialize)]
#[serde(
    tag = "kind",
    rename_all = "snake_case",
    deny_unknown_fields,
    expecting = "a wall: `{kind: box, min: [x, y, z], max: [x, y, z]}` or `{kind: shell, centre: [x, y, z], inner: r, outer: r}`"
)]
pub enum WallEntry {
    /// An axis-aligned box in space.
    Box {
        /// Lower corner (m).
        min: [f64; 3],
        /// Upper corner (m).
        max: [f64; 3],
    },
    /// A spherical shell.
    Shell {
        /// Centre (m).
        centre: [f64; 3],
        /// Inner radius (m).
        inner: f64,
        /// Outer radius (m).
        outer: f64,
    },
}

/// Sampler defaults a scene may carry (the command line overrides them).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(
    deny_unknown_fields,
    expecting = "sampler defaults: a mapping with scheme, dt, samples, walkers, burn_in, thin"
)]
pub struct SamplerEntry {
    /// Scheme.
    pub scheme: Option<Scheme>,
    /// Time step (left out: tuned during burn-in for Metropolis).
    pub dt: Option<f64>,
    /// Samples.
    pub samples: Option<usize>,
    /// Walkers.
    pub walkers: Option<usize>,
    /// Burn-in steps.
    pub burn_in: Option<usize>,
    /// Steps between samples (left out: chosen from the burn-in's autocorrelation).
    pub thin: Option<usize>,
}

/// A scene file as written.
#[derive(Debug, Clone, Deserialize)]
#[serde(
    deny_unknown_fields,
    expecting = "a scene: a mapping with dim, bodies, sample, and optionally walls, time, sampler"
)]
pub struct SceneFile {
    /// 3 or 4.
    pub dim: usize,
    /// The bodies.
    pub bodies: Vec<BodyEntry>,
    /// Names of the bodies whose surfaces are sampled together (M of them).
    pub sample: Vec<String>,
    /// Reflecting walls.
    #[serde(default)]
    pub walls: Vec<WallEntry>,
    /// dim 4: the time window `[t0, t1]` (s).
    #[serde(default)]
    pub time: Option<[f64; 2]>,
    /// Sampler defaults.
    #[serde(default)]
    pub sampler: SamplerEntry,
}

/// A scene ready to sample.
#[derive(Debug, Clone)]
pub struct ImplicitScene {
    /// The figure.
    pub figure: Figure,
    /// The sampled bodies, in order, with their names.
    pub bodies: Vec<(String, Body)>,
    /// The scene's sampler defaults applied to `SamplerOptions::default()`.
    pub options: SamplerOptions,
    /// dim 4: the time window.
    pub time: Option<[f64; 2]>,
}

impl SceneFile {
    /// Parses YAML text, checked against [`chronotope_yaml::CONFIG_LIMITS`] first.
    ///
    /// # Errors
    /// [`SceneFileError::Yaml`].
    pub fn parse(text: &str) -> Result<Self, SceneFileError> {
        Ok(chronotope_yaml::from_str(
            text,
            &chronotope_yaml::CONFIG_LIMITS,
        )?)
    }

    /// Reads and parses a regular file of at most [`MAX_FILE_BYTES`].
    ///
    /// # Errors
    /// [`SceneFileError::Io`], [`SceneFileError::TooLarge`], [`SceneFileError::Yaml`].
    pub fn read(path: &std::path::Path) -> Result<Self, SceneFileError> {
        use chronotope_yaml::{read_text, YamlError, CONFIG_LIMITS};
        let shown = path.display().to_string();
        let text = read_text(path, &CONFIG_LIMITS).map_err(|e| match e {
            YamlError::Io { source, .. } => SceneFileError::Io {
                path: shown.clone(),
                source,
            },
            YamlError::TooLarge { .. } => SceneFileError::TooLarge {
                path: shown.clone(),
                bytes: std::fs::metadata(path).map_or(MAX_FILE_BYTES + 1, |m| m.len()),
            },
            e => SceneFileError::Invalid(format!("{shown}: {e}")),
        })?;
        Self::parse(&text)
    }

    /// Checks everything and builds the figure.
    ///
    /// # Errors
    /// [`SceneFileError::Invalid`] naming the problem, or [`SceneFileError::Sampler`].
    pub fn build(&self) -> Result<ImplicitScene, SceneFileError> {
        let bad = |s: String| Err(SceneFileError::Invalid(s));
        if !(self.dim == 3 || self.dim == 4) {
            return bad(format!(
                "dim {}: expected 3 (space) or 4 (space-time)",
                self.dim
            ));
        }
        if self.bodies.len() > MAX_BODIES {
            return bad(format!(
                "{} bodies: at most {MAX_BODIES}",
                self.bodies.len()
            ));
        }
        if self.walls.len() > MAX_WALLS {
            return bad(format!("{} walls: at most {MAX_WALLS}", self.walls.len()));
        }
        for (i, b) in self.bodies.iter().enumerate() {
            let name = quote(&b.name);
            if self.bodies[..i].iter().any(|o| o.name == b.name) {
                return bad(format!("body {name} is defined twice"));
            }
            if let Some(p) = b.shape.problem() {
                return bad(format!("body {name}: {p}"));
            }
            for (field, values) in [
                ("velocity (m/s)", &b.velocity[..]),
                ("warp (1/m)", &b.warp[..]),
                ("t_ref (s)", std::slice::from_ref(&b.t_ref)),
            ] {
                if let Some(v) = values.iter().find(|v| !v.is_finite()) {
                    return bad(format!(
                        "body {name}: {field} is {}: it must be finite",
                        number(*v)
                    ));
                }
            }
            if self.dim == 3 && b.velocity != [0.0; 3] {
                tracing::warn!(
                    "body `{}`: velocity is ignored in a dim 3 scene (its pose at t = 0 is used)",
                    b.name
                );
            }
        }
        let mut bodies = Vec::new();
        for (i, w) in self.walls.iter().enumerate() {
            if let Some(p) = w.problem() {
                return bad(format!("wall {}: {p}", i + 1));
            }
        }
        for name in &self.sample {
            let Some(b) = self.bodies.iter().find(|b| &b.name == name) else {
                return bad(format!("sample: no body named {}", quote(name)));
            };
            let mut body = Body::fixed(b.shape).warped(b.warp);
            if self.dim == 4 {
                body = body.moving(b.velocity, b.t_ref);
            } else {
                // A dim 3 scene is the t = 0 pose.
                let off = b.velocity.map(|v| -v * b.t_ref);
                body = Body::fixed(translated(b.shape, off)).warped(b.warp);
            }
            bodies.push((name.clone(), body));
        }
        let m = bodies.len();
        if m == 0 || m >= self.dim {
            return bad(format!(
                "sample lists {m} bodies: need 1 ≤ M < dim = {} (1 or 2 in 3D; 1, 2 or 3 in 4D)",
                self.dim
            ));
        }
        let time = match (self.dim, self.time) {
            (4, Some([t0, t1])) if t0.is_finite() && t1.is_finite() && t0 < t1 => Some([t0, t1]),
            (4, Some([t0, t1])) => {
                return bad(format!(
                    "time: [{}, {}] s: dim 4 needs finite t0 < t1",
                    number(t0),
                    number(t1)
                ))
            }
            (4, _) => return bad("dim 4 needs `time: [t0, t1]` with t0 < t1".into()),
            (_, Some(_)) => return bad("`time` is only for dim 4".into()),
            _ => None,
        };
        let fields: Vec<Arc<dyn super::Field>> = bodies
            .iter()
            .map(|(_, b)| Arc::new(*b) as Arc<dyn super::Field>)
            .collect();
        let mut fig = Figure::new(self.dim, fields)?;
        let mut have_box = false;
        for w in &self.walls {
            let wall = match *w {
                WallEntry::Box { min, max } => {
                    have_box = true;
                    let (t0, t1) = time.map_or((0.0, 0.0), |[a, b]| (a, b));
                    Wall::Box {
                        min: [min[0], min[1], min[2], t0],
                        max: [max[0], max[1], max[2], t1],
                    }
                }
                WallEntry::Shell {
                    centre,
                    inner,
                    outer,
                } => Wall::Shell {
                    centre,
                    inner,
                    outer,
                },
            };
            fig = fig.wall(wall)?;
        }
        if !have_box {
            // Walkers need a box to start in: the bodies' bounds, which every bounded shape has.
            let mut lo = [f64::INFINITY; 3];
            let mut hi = [f64::NEG_INFINITY; 3];
            for (_, b) in &bodies {
                let Some((a, c)) = b.shape.bounds() else {
                    return bad("an unbounded shape (cone, seed_saddle) needs a box wall".into());
                };
                for i in 0..3 {
                    let shift = time.map_or(0.0, |[t0, t1]| {
                        (b.velocity[i] * (t0 - b.t_ref))
                            .abs()
                            .max((b.velocity[i] * (t1 - b.t_ref)).abs())
                    });
                    lo[i] = lo[i].min(a[i] - shift);
                    hi[i] = hi[i].max(c[i] + shift);
                }
            }
            let (t0, t1) = time.map_or((0.0, 0.0), |[a, b]| (a, b));
            let pad = 0.05 * (0..3).map(|i| hi[i] - lo[i]).fold(0.0, f64::max);
            let min: Q = [lo[0] - pad, lo[1] - pad, lo[2] - pad, t0];
            let max: Q = [hi[0] + pad, hi[1] + pad, hi[2] + pad, t1];
            fig = fig.seed_box(min, max)?;
            if time.is_some() {
                // The time window is a wall in any case.
                fig = fig.wall(Wall::Box {
                    min: [-1e30, -1e30, -1e30, t0],
                    max: [1e30, 1e30, 1e30, t1],
                })?;
            }
        }
        let s = &self.sampler;
        let mut o = SamplerOptions::default();
        if let Some(v) = s.scheme {
            o.scheme = v;
        }
        if let Some(v) = s.dt {
            if !(v.is_finite() && v > 0.0) {
                return bad(format!(
                    "sampler.dt is {}: a positive, finite time step is needed",
                    number(v)
                ));
            }
            o.dt = Some(v);
        }
        if let Some(v) = s.samples {
            o.samples = v;
        }
        if let Some(v) = s.walkers {
            o.walkers = v;
        }
        if let Some(v) = s.burn_in {
            o.burn_in = v;
        }
        if let Some(v) = s.thin {
            o.thin = Some(v);
        }
        o.validate()?;
        Ok(ImplicitScene {
            figure: fig,
            bodies,
            options: o,
            time,
        })
    }
}

impl WallEntry {
    /// What is wrong with the wall, if anything (finite corners with min < max; a finite
    /// centre with 0 ≤ inner < outer).
    pub fn problem(&self) -> Option<String> {
        let all_finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        match *self {
            Self::Box { min, max } => {
                if !all_finite(&min) || !all_finite(&max) {
                    return Some("box min and max must be finite (m)".into());
                }
                let axis = (0..3).find(|&i| min[i] >= max[i])?;
                Some(format!(
                    "box min {} ≥ max {} m on {}: min must be below max",
                    number(min[axis]),
                    number(max[axis]),
                    ["x", "y", "z"][axis]
                ))
            }
            Self::Shell {
                centre,
                inner,
                outer,
            } => {
                if !all_finite(&centre) || !inner.is_finite() || !outer.is_finite() {
                    return Some("shell centre, inner and outer must be finite (m)".into());
                }
                (!(0.0 <= inner && inner < outer)).then(|| {
                    format!(
                        "shell inner {} m, outer {} m: need 0 ≤ inner < outer",
                        number(inner),
                        number(outer)
                    )
                })
            }
        }
    }
}

/// The shape moved by `off`.
fn translated(s: Shape, off: [f64; 3]) -> Shape {
    let add = |p: [f64; 3]| [p[0] + off[0], p[1] + off[1], p[2] + off[2]];
    match s {
        Shape::Sphere { centre, radius } => Shape::Sphere {
            centre: add(centre),
            radius,
        },
        Shape::Box {
            centre,
            half,
            rounding,
        } => Shape::Box {
            centre: add(centre),
            half,
            rounding,
        },
        Shape::Torus {
            centre,
            axis,
            major,
            minor,
        } => Shape::Torus {
            centre: add(centre),
            axis,
            major,
            minor,
        },
        Shape::Capsule { a, b, radius } => Shape::Capsule {
            a: add(a),
            b: add(b),
            radius,
        },
        Shape::Cone {
            apex,
            axis,
            half_angle,
        } => Shape::Cone {
            apex: add(apex),
            axis,
            half_angle,
        },
        Shape::SeedSaddle { centre } => Shape::SeedSaddle {
            centre: add(centre),
        },
        Shape::SeedHoles { centre } => Shape::SeedHoles {
            centre: add(centre),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_doc_example_parses_and_builds() {
        let text = "dim: 4\nbodies:\n  - name: a\n    shape: {kind: sphere, centre: [0, 0, 0], radius: 1.0}\n  - name: b\n    shape: {kind: box, centre: [-1.5, 0, 0], half: [0.4, 0.4, 0.4]}\n    velocity: [1.0, 0, 0]\nsample: [a, b]\nwalls:\n  - {kind: box, min: [-3, -3, -3], max: [3, 3, 3]}\ntime: [0.0, 3.0]\nsampler: {scheme: metropolis, dt: 0.001, samples: 20000}\n";
        let s = SceneFile::parse(text).unwrap().build().unwrap();
        assert_eq!(s.figure.dim(), 4);
        assert_eq!(s.figure.constraints(), 2);
        assert_eq!(s.options.samples, 20000);
    }

    #[test]
    fn bad_scenes_say_what_is_wrong() {
        let e = SceneFile::parse("dim: 3\nbodies: []\nsample: [x]\n")
            .unwrap()
            .build()
            .unwrap_err();
        assert!(e.to_string().contains("no body named \"x\""), "{e}");
        let e = SceneFile::parse("dim: 3\nbodies:\n  - name: a\n    shape: {kind: sphere, centre: [0,0,0], radius: -1}\nsample: [a]\n")
            .unwrap()
            .build()
            .unwrap_err();
        assert!(e.to_string().contains("radius"), "{e}");
        assert!(SceneFile::parse(
            "dim: 3\nbodies:\n  - name: a\n    shape: {kind: blob}\nsample: [a]\n"
        )
        .is_err());
        let e = SceneFile::parse("dim: 4\nbodies:\n  - name: a\n    shape: {kind: sphere, centre: [0,0,0], radius: 1}\nsample: [a]\n")
            .unwrap()
            .build()
            .unwrap_err();
        assert!(e.to_string().contains("time"), "{e}");
    }
}
