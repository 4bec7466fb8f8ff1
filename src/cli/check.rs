//! `chronotope check BAG [--report FILE.json]`: mesh every body, check every pair, suggest
//! resolutions for the body whose id sorts first (a translation, a time scaling and a
//! rotation, each verified against every other body), and write the report of
//! docs/formats.md#report
//! (`chronotope.report/1`).

use super::mesh::{mesher_options_from, MesherArgs};
use super::{BagFrames, CliError};
use crate::checker::pipeline::{check_bodies, CheckPlan};
use crate::checker::report::Report;
use crate::checker::rotate::RotationSpec;
use crate::mesh::glue::{BodyAssembler, BodyMesh};
use crate::mesh::MesherOptions;
use clap::Args;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `chronotope check`.
#[derive(Debug, Clone, Args)]
pub struct CheckArgs {
    /// Input bag: a rosbag2 directory, or an MCAP or SQLite (.db3) file, zstd-compressed or not.
    pub bag: PathBuf,
    /// Write the report (docs/formats.md#report, schema chronotope.report/1).
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Time scale c (m/s) of the 4D metric |(dx, dy, dz, c·dt)| (default: one voxel per
    /// frame period).
    #[arg(long)]
    pub time_scale: Option<f64>,
    /// Axis the movable body is turned about, as X,Y,Z (default: vertical, 0,0,1).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub rotation_axis: Option<Vec<f64>>,
    /// A point on that axis in metres, as X,Y,Z (default: the body's centroid at its first
    /// contact).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub rotation_point: Option<Vec<f64>>,
    /// Largest turn tried in either sense (rad, at most π; 0: no rotation suggested).
    #[arg(long)]
    pub rotation_max_rad: Option<f64>,
    /// Mesher options.
    #[command(flatten)]
    pub mesher: MesherArgs,
    /// Replace a report path that holds a bag. Inputs are never replaced.
    #[arg(long)]
    pub overwrite: bool,
}

/// Meshes every VoxelGrid topic of a bag into whole-body meshes (frames kept).
///
/// # Errors
/// The bag cannot be read or has no VoxelGrid topic.
pub fn load_bodies(
    path: &Path,
    opts: MesherOptions,
) -> Result<BTreeMap<String, BodyMesh>, CliError> {
    Ok(load_bodies_with_frames(path, opts)?.bodies)
}

/// A bag's bodies with what `check` needs besides their meshes.
#[derive(Debug)]
pub struct LoadedBag {
    /// Whole-body meshes, by id.
    pub bodies: BTreeMap<String, BodyMesh>,
    /// Each body's `header.frame_id` (of its first accepted frame).
    pub frame_ids: BTreeMap<String, String>,
    /// What was read from the bag.
    pub input: crate::cli::InputCounts,
}

/// [`load_bodies`], with each body's frame and what was read from the bag.
///
/// # Errors
/// The bag cannot be read or has no VoxelGrid topic.
pub fn load_bodies_with_frames(path: &Path, opts: MesherOptions) -> Result<LoadedBag, CliError> {
    let mut asm: BTreeMap<String, (BodyAssembler, String)> = BTreeMap::new();
    let mut frames_in = BagFrames::open(path)?;
    for (topic, grid) in frames_in.by_ref() {
        let (a, frame_id) = match asm.entry(topic.clone()) {
            std::collections::btree_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::btree_map::Entry::Vacant(e) => {
                e.insert((BodyAssembler::new(opts)?.keep_frames(true), String::new()))
            }
        };
        let Some(grid) = grid else {
            a.refuse(None, &crate::mesh::MeshError::Undecodable);
            continue;
        };
        let stamp = grid.header.stamp.as_nanos();
        if let Err(e) = grid.message_check(frame_id) {
            tracing::warn!(topic = %topic, "skipping frame: {e}");
            a.refuse(Some(stamp), &e);
            continue;
        }
        match a.push(&grid.frame_ref()) {
            Err(e) => tracing::warn!(topic = %topic, stamp_ns = stamp, "skipping frame: {e}"),
            Ok(pushed) => {
                if frame_id.is_empty() {
                    *frame_id = grid.header.frame_id.clone();
                }
                if pushed.clamped > 0 {
                    tracing::warn!(topic = %topic, stamp_ns = stamp, "{}", crate::mesh::MeshError::PercentOutOfRange { voxels: pushed.clamped });
                }
                if let Some(g) = pushed.gap {
                    tracing::warn!(topic = %topic, "frames missing from {} to {} ns: {}", g.from_ns, g.to_ns, g.reason);
                }
            }
        }
    }
    let mut frames = BTreeMap::new();
    let bodies = asm
        .into_iter()
        .map(|(k, (a, frame_id))| {
            frames.insert(k.clone(), frame_id);
            (k, a.finish())
        })
        .collect();
    Ok(LoadedBag {
        bodies,
        frame_ids: frames,
        input: frames_in.input(),
    })
}

/// The report of `chronotope check`: the fields of docs/formats.md#report, then what was
/// read from the bag (extra field `input`).
#[derive(Debug, Clone, serde::Serialize)]
pub struct CheckReport {
    /// The check's report.
    #[serde(flatten)]
    pub report: Report,
    /// What was read from the bag.
    pub input: super::InputCounts,
}

impl std::ops::Deref for CheckReport {
    type Target = Report;
    fn deref(&self) -> &Report {
        &self.report
    }
}

/// Checks every pair of bodies of a bag; resolutions for the body whose id sorts first.
///
/// # Errors
/// The bag cannot be read, or its bodies are not on one lattice.
pub fn check_bag(
    path: &Path,
    opts: MesherOptions,
    time_scale: Option<f64>,
) -> Result<CheckReport, CliError> {
    check_bag_with(path, opts, time_scale, RotationSpec::default())
}

/// [`check_bag`] with the rotation asked for.
///
/// # Errors
/// As [`check_bag`].
pub fn check_bag_with(
    path: &Path,
    opts: MesherOptions,
    time_scale: Option<f64>,
    rotation: RotationSpec,
) -> Result<CheckReport, CliError> {
    let start = Instant::now();
    let LoadedBag {
        bodies,
        frame_ids,
        input,
    } = load_bodies_with_frames(path, opts)?;
    let t_mesh = start.elapsed();
    let ids: Vec<&str> = bodies
        .iter()
        .filter(|(_, b)| b.stamps_ns.len() >= 2)
        .map(|(k, _)| k.as_str())
        .collect();
    let mut plan = CheckPlan::all_pairs_first_movable(&ids, time_scale);
    plan.frame_ids = frame_ids;
    plan.rotation = rotation;
    let mut report = check_bodies(&bodies, &plan, opts)?.report;
    report.timings_ms.mesh = t_mesh.as_secs_f64() * 1e3;
    report.timings_ms.total = start.elapsed().as_secs_f64() * 1e3;
    Ok(CheckReport { report, input })
}

/// The rotation `a` asks for.
fn rotation_spec(a: &CheckArgs) -> Result<RotationSpec, CliError> {
    let mut spec = RotationSpec::default();
    let three = |flag: &str, v: &[f64]| -> Result<[f64; 3], CliError> {
        match <[f64; 3]>::try_from(v) {
            Ok(x) if x.iter().all(|c| c.is_finite()) => Ok(x),
            _ => Err(CliError::Usage(format!(
                "{flag}: three finite numbers X,Y,Z are needed"
            ))),
        }
    };
    if let Some(v) = &a.rotation_axis {
        spec.axis = three("--rotation-axis", v)?;
        if spec.axis.iter().all(|&c| c == 0.0) {
            return Err(CliError::Usage(
                "--rotation-axis 0,0,0: the axis needs a direction".into(),
            ));
        }
    }
    if let Some(v) = &a.rotation_point {
        spec.point_m = Some(three("--rotation-point", v)?);
    }
    if let Some(r) = a.rotation_max_rad {
        if !(0.0..=std::f64::consts::PI).contains(&r) {
            return Err(CliError::Usage(format!(
                "--rotation-max-rad {r}: must be within [0, π]"
            )));
        }
        spec.max_rad = r;
    }
    Ok(spec)
}

/// Runs `chronotope check`.
///
/// # Errors
/// See [`check_bag`]; also a report file that cannot be written.
pub fn run(a: &CheckArgs) -> Result<(), CliError> {
    if let Some(c) = a.time_scale {
        if !(c.is_finite() && c > 0.0) {
            return Err(CliError::Usage(format!(
                "--time-scale {c}: must be a positive number of m/s"
            )));
        }
    }
    let rotation = rotation_spec(a)?;
    super::paths::Paths::new(a.overwrite)
        .bag(&a.bag)
        .output(
            "--report",
            a.report.as_deref(),
            super::paths::OutputKind::File,
        )
        .check()?;
    let r = check_bag_with(
        &a.bag,
        mesher_options_from(&a.mesher),
        a.time_scale,
        rotation,
    )?;
    for b in &r.bodies {
        println!(
            "{:<24} {:>4} frames {:>10} tets  closed {}",
            b.id, b.frames, b.tets, b.closed
        );
        if b.vanishing_slabs > 0 {
            println!(
                "WARNING {}: in {} frame periods it moves more than its own thickness and vanishes between \
                 frames; contacts there can be missed. Raise the frame rate.",
                b.id, b.vanishing_slabs
            );
        }
    }
    for p in &r.pairs {
        if p.interfering {
            let spans: Vec<String> = p
                .intervals_s
                .iter()
                .map(|[s, e]| format!("{s:.3}-{e:.3} s"))
                .collect();
            println!(
                "COLLIDE {} x {}: first contact {:.3} s (frame period {:.3} s), during {}; overlap {:.4e} m3s",
                p.a,
                p.b,
                p.first_contact_s.unwrap_or(f64::NAN),
                p.frame_period_s.unwrap_or(f64::NAN),
                spans.join(", "),
                p.overlap_hypervolume_m3s.unwrap_or(f64::NAN)
            );
        } else if p.verdict == crate::checker::report::Verdict::Unsure {
            println!(
                "UNSURE  {} x {}: no contact found, but cannot be called clear during {}",
                p.a,
                p.b,
                p.unsure_line()
            );
        } else {
            println!("clear   {} x {}", p.a, p.b);
        }
        if p.interfering && !p.unsure_spans_s.is_empty() {
            println!(
                "        and where it is not observed well enough: {}",
                p.unsure_line()
            );
        }
    }
    for s in &r.resolutions {
        println!(
            "resolve {}",
            serde_json::to_string(s).expect("plain data serialises")
        );
    }
    print!("{}", super::replay::fix_lines(&r.resolutions));
    println!(
        "mesh {:.0} ms, check {:.0} ms, resolve {:.0} ms, total {:.0} ms",
        r.timings_ms.mesh, r.timings_ms.check, r.timings_ms.resolve, r.timings_ms.total
    );
    if let Some(line) = super::integrity_note(r.input.recovery.as_ref()) {
        println!("{line}");
    }
    if let Some(p) = &a.report {
        let text = serde_json::to_string_pretty(&r).expect("plain data serialises");
        super::write_output(p, text.as_bytes())?;
    }
    Ok(())
}
