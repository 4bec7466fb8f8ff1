//! `chronotope check BAG [--report FILE.json]`: mesh every body, check every pair, suggest
//! resolutions for the body whose id sorts first (a translation and a time scaling, each
//! verified against every other body), and write the CONTRACT.md report
//! (`chronotope.report/1`).

use super::mesh::{mesher_options_from, MesherArgs};
use super::{frame_ref, BagFrames, CliError};
use crate::checker::bounds;
use crate::checker::labels::LabelCounts;
use crate::checker::resolve::{suggest_time_scaling, suggest_translation, Metric};
use crate::checker::{check_pair, CommonLattice, PairResult};
use crate::mesh::glue::{BodyAssembler, BodyMesh};
use crate::mesh::MesherOptions;
use clap::Args;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `chronotope check`.
#[derive(Debug, Clone, Args)]
pub struct CheckArgs {
    /// Input rosbag2 MCAP bag.
    pub bag: PathBuf,
    /// Write the report (CONTRACT.md, schema chronotope.report/1).
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Time scale c (m/s) of the 4D metric |(dx, dy, dz, c·dt)| (default: one voxel per
    /// frame period).
    #[arg(long)]
    pub time_scale: Option<f64>,
    /// Mesher options.
    #[command(flatten)]
    pub mesher: MesherArgs,
}

/// One body in the report.
#[derive(Debug, Clone, Serialize)]
pub struct BodyReport {
    /// Topic.
    pub id: String,
    /// Frames accepted.
    pub frames: u64,
    /// Tets of the closed mesh.
    pub tets: u64,
    /// Vertices of the closed mesh.
    pub vertices: u64,
    /// Closed and consistently oriented.
    pub closed: bool,
    /// Hypervolume (m³·s).
    pub hypervolume_m3s: f64,
    /// Frames refused (extra field).
    pub skipped_frames: u64,
    /// Slabs in which the body vanishes between its frames: the frame rate is too low for
    /// its motion and contacts there can be missed (extra field).
    pub vanishing_slabs: u64,
}

/// Label counts of both bodies of a pair.
#[derive(Debug, Clone, Serialize)]
pub struct PairLabels {
    /// First body.
    pub a: LabelCounts,
    /// Second body.
    pub b: LabelCounts,
}

/// One pair in the report.
#[derive(Debug, Clone, Serialize)]
pub struct PairReport {
    /// First body.
    pub a: String,
    /// Second body.
    pub b: String,
    /// The interiors overlap somewhere in space-time.
    pub interfering: bool,
    /// Time intervals of overlap (s since `time_origin_ns`).
    pub intervals_s: Vec<[f64; 2]>,
    /// Earliest time of overlap, or null.
    pub first_contact_s: Option<f64>,
    /// 4D measure of the overlap (m³·s), or null when the bodies' frames are not on one grid.
    pub overlap_hypervolume_m3s: Option<f64>,
    /// Label counts.
    pub labels: PairLabels,
    /// The frame period at the first contact (s), the time resolution of the input (extra
    /// field).
    pub frame_period_s: Option<f64>,
    /// Voxel edge (m), the space resolution of the input (extra field).
    pub voxel_size_m: f64,
    /// Bound on the error of `first_contact_s` (s): Δt/2 + h/v at closing speed v; null
    /// for a grazing contact or one not made by crossing boundaries (extra field; README,
    /// "Error bounds").
    pub first_contact_error_bound_s: Option<f64>,
    /// The closing speed v of the two boundaries at the first contact (m/s, extra field).
    pub closing_speed_mps: Option<f64>,
    /// Bounds on the errors of each interval's start and end (s; null as above; extra
    /// field).
    pub interval_error_bounds_s: Vec<[Option<f64>; 2]>,
    /// Bound on the error of `overlap_hypervolume_m3s` (m³·s, extra field).
    pub overlap_hypervolume_error_bound_m3s: Option<f64>,
    /// Candidate tet pairs from the trees (extra field).
    pub candidate_pairs: u64,
    /// Tet pairs whose boundaries cross (extra field).
    pub crossing_pairs: u64,
}

/// Timings (ms).
#[derive(Debug, Clone, Default, Serialize)]
pub struct Timings {
    /// Reading and meshing.
    pub mesh: f64,
    /// Detection and labels (trees, exact tests, inclusion).
    pub check: f64,
    /// Resolution suggestions.
    pub resolve: f64,
    /// Everything.
    pub total: f64,
}

/// The report (CONTRACT.md).
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// `chronotope.report/1`.
    pub schema: &'static str,
    /// Earliest frame stamp in the bag (ns); report times are seconds since it.
    pub time_origin_ns: i64,
    /// c (m/s) of the 4D metric.
    pub time_scale_m_per_s: f64,
    /// Bodies, sorted by id.
    pub bodies: Vec<BodyReport>,
    /// Every pair (a < b).
    pub pairs: Vec<PairReport>,
    /// Resolve suggestions for the body whose id sorts first.
    pub resolutions: Vec<serde_json::Value>,
    /// Timings.
    pub timings_ms: Timings,
}

/// Meshes every VoxelGrid topic of a bag into whole-body meshes (frames kept).
///
/// # Errors
/// The bag cannot be read or has no VoxelGrid topic.
pub fn load_bodies(
    path: &Path,
    opts: MesherOptions,
) -> Result<BTreeMap<String, BodyMesh>, CliError> {
    let mut asm: BTreeMap<String, (BodyAssembler, u64)> = BTreeMap::new();
    for (topic, grid) in BagFrames::open(path)? {
        let (a, undecodable) = match asm.entry(topic.clone()) {
            std::collections::btree_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::btree_map::Entry::Vacant(e) => {
                e.insert((BodyAssembler::new(opts)?.keep_frames(true), 0))
            }
        };
        let Some(grid) = grid else {
            *undecodable += 1;
            continue;
        };
        if let Err(e) = a.push(&frame_ref(&grid)) {
            tracing::warn!(topic = %topic, stamp_ns = grid.header.stamp.as_nanos(), "skipping frame: {e}");
        }
    }
    Ok(asm
        .into_iter()
        .map(|(k, (a, undecodable))| {
            let mut body = a.finish();
            body.skipped += undecodable;
            (k, body)
        })
        .collect())
}

/// Overlap hypervolume (m³·s) from the intersection of the two bodies' frames, meshed
/// like a body, with its error bound (see `checker::bounds`).
pub fn overlap_hypervolume(a: &BodyMesh, b: &BodyMesh, opts: MesherOptions) -> Option<(f64, f64)> {
    let (ga, gb) = (a.geometry?, b.geometry?);
    if ga != gb {
        return None;
    }
    let mut asm = BodyAssembler::new(opts).ok()?;
    let mut j = 0;
    for (i, &s) in a.stamps_ns.iter().enumerate() {
        while j < b.stamps_ns.len() && b.stamps_ns[j] < s {
            j += 1;
        }
        if j < b.stamps_ns.len() && b.stamps_ns[j] == s {
            let both = a.frames.get(i)?.intersect(b.frames.get(j)?)?;
            asm.push_decoded(s, ga, both).ok()?;
        }
    }
    let body = asm.finish();
    let n = body.stamps_ns.len();
    let period = if n >= 2 {
        (body.stamps_ns[n - 1] - body.stamps_ns[0]) as f64 * 1e-9 / (n - 1) as f64
    } else {
        0.0
    };
    let bound = bounds::hypervolume_bound(&body.mesh, &ga, period);
    Some((body.stats.hypervolume_m3s, bound))
}

/// Checks every pair of bodies of a bag.
///
/// # Errors
/// The bag cannot be read, or its bodies are not on one lattice.
pub fn check_bag(
    path: &Path,
    opts: MesherOptions,
    time_scale: Option<f64>,
) -> Result<Report, CliError> {
    let start = Instant::now();
    let bodies = load_bodies(path, opts)?;
    let t_mesh = start.elapsed();
    let named: Vec<(&str, &BodyMesh)> = bodies
        .iter()
        .filter(|(_, b)| b.stamps_ns.len() >= 2)
        .map(|(k, b)| (k.as_str(), b))
        .collect();
    for (id, b) in &bodies {
        if b.stamps_ns.len() < 2 {
            tracing::warn!(topic = %id, "fewer than two frames: no 4D mesh, not checked");
        }
    }
    let time_origin_ns = bodies
        .values()
        .filter_map(|b| b.stamps_ns.first().copied())
        .min()
        .unwrap_or(0);
    let mut pairs = Vec::new();
    let mut resolutions = Vec::new();
    let mut t_resolve = std::time::Duration::ZERO;
    let mut c = time_scale.unwrap_or(0.0);
    if !named.is_empty() {
        let lat = CommonLattice::of(&named)?;
        let span = (lat.stamps_ns[lat.stamps_ns.len() - 1] - lat.stamps_ns[0]) as f64 * 1e-9;
        let period = span / (lat.stamps_ns.len() - 1) as f64;
        if time_scale.is_none() {
            c = lat.resolution / period;
        }
        // Bodies are prepared, and pairs checked, on all cores: they are independent.
        let prepared: Vec<_> = par_map(named.len(), |i| lat.prepare(named[i].0, named[i].1))
            .into_iter()
            .collect::<Result<_, _>>()?;
        let jobs: Vec<(usize, usize)> = (0..prepared.len())
            .flat_map(|i| (i + 1..prepared.len()).map(move |j| (i, j)))
            .collect();
        let results = par_map(jobs.len(), |k| {
            let (i, j) = jobs[k];
            let r = check_pair(&prepared[i], &prepared[j]);
            let hv = if r.interfering() {
                overlap_hypervolume(named[i].1, named[j].1, opts)
            } else {
                Some((0.0, 0.0))
            };
            (r, hv)
        });
        let mut first_results = Vec::new();
        for (&(i, j), (r, hv)) in jobs.iter().zip(results) {
            pairs.push(pair_report(
                named[i].0,
                named[j].0,
                &r,
                hv,
                &lat,
                time_origin_ns,
            ));
            if i == 0 {
                first_results.push(r);
            }
        }
        let t0 = Instant::now();
        if first_results.iter().any(PairResult::interfering) {
            resolutions = resolve_first(&prepared, &first_results, &lat, c, time_origin_ns);
        }
        t_resolve = t0.elapsed();
    }
    let t_check = start.elapsed() - t_mesh - t_resolve;
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
    Ok(Report {
        schema: "chronotope.report/1",
        time_origin_ns,
        time_scale_m_per_s: c,
        bodies: bodies
            .iter()
            .map(|(id, b)| BodyReport {
                id: id.clone(),
                frames: b.stats.frames,
                tets: b.mesh.tets.len() as u64,
                vertices: b.mesh.vertices.len() as u64,
                closed: b.stats.closed.is_closed(),
                hypervolume_m3s: b.stats.hypervolume_m3s,
                skipped_frames: b.skipped,
                vanishing_slabs: b.stats.vanishing_slabs,
            })
            .collect(),
        pairs,
        resolutions,
        timings_ms: Timings {
            mesh: ms(t_mesh),
            check: ms(t_check),
            resolve: ms(t_resolve),
            total: ms(start.elapsed()),
        },
    })
}

/// `f(0..n)` computed on all available cores, results in index order.
pub fn par_map<T: Send>(n: usize, f: impl Fn(usize) -> T + Sync) -> Vec<T> {
    let threads = std::thread::available_parallelism()
        .map_or(1, |t| t.get())
        .min(n.max(1));
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut out: Vec<Option<T>> = (0..n).map(|_| None).collect();
    let done: Vec<Vec<(usize, T)>> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                s.spawn(|| {
                    let mut mine = Vec::new();
                    loop {
                        let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        if k >= n {
                            break mine;
                        }
                        mine.push((k, f(k)));
                    }
                })
            })
            .collect();
        workers
            .into_iter()
            .map(|w| w.join().expect("worker panicked"))
            .collect()
    });
    for (k, v) in done.into_iter().flatten() {
        out[k] = Some(v);
    }
    out.into_iter()
        .map(|v| v.expect("every index computed"))
        .collect()
}

/// Translation and time scaling of the first body against all the others.
fn resolve_first(
    prepared: &[crate::checker::Prepared],
    results: &[PairResult],
    lat: &CommonLattice,
    c: f64,
    origin: i64,
) -> Vec<serde_json::Value> {
    let a = &prepared[0];
    let others: Vec<&crate::checker::Prepared> = prepared[1..].iter().collect();
    let rs: Vec<&PairResult> = results.iter().collect();
    let m = Metric::new(lat, c);
    let mut out = Vec::new();
    if let Some(t) = suggest_translation(a, &others, &rs, &m) {
        let v: Vec<f64> = (0..4)
            .map(|k| {
                if k < 3 {
                    t.lattice[k] as f64 * m.sigma[k]
                } else {
                    t.lattice[k] as f64 * m.sigma[3] / c
                }
            })
            .collect();
        let snap = m.sigma.iter().map(|s| s * s).sum::<f64>().sqrt();
        let period = m.sigma[3] * lat.per_step() as f64 / c;
        out.push(serde_json::json!({
            "body": a.id, "kind": "translate", "vector": v, "distance": t.distance_m,
            "verified_clear": t.verified_clear, "direction": t.direction,
            "distance_error_bound_m": bounds::translation_bound(lat.resolution, period, c, snap),
        }));
    } else {
        tracing::warn!(body = %a.id, "no translation found (no interior point of the body lies inside another)");
    }
    if let Some(ts) = suggest_time_scaling(a, &others, &rs) {
        out.push(serde_json::json!({
            "body": a.id, "kind": "time_scale", "t0_s": lat.time_s(ts.t0 as f64, origin), "scale": ts.scale,
            "verified_clear": ts.verified_clear,
        }));
    }
    out
}

fn pair_report(
    a: &str,
    b: &str,
    r: &PairResult,
    hv: Option<(f64, f64)>,
    lat: &CommonLattice,
    origin: i64,
) -> PairReport {
    let (ca, cb) = r.counts();
    let first = r.first_contact();
    let bound = |t: f64, speed: Option<f64>| bounds::contact_time_bound(lat.period_s(t), speed);
    PairReport {
        a: a.to_owned(),
        b: b.to_owned(),
        interfering: r.interfering(),
        intervals_s: r
            .intervals
            .iter()
            .map(|&(s, e)| [lat.time_s(s, origin), lat.time_s(e, origin)])
            .collect(),
        first_contact_s: first.map(|t| lat.time_s(t, origin)),
        overlap_hypervolume_m3s: hv.map(|h| h.0),
        labels: PairLabels { a: ca, b: cb },
        frame_period_s: first.map(|t| lat.period_s(t)),
        voxel_size_m: lat.resolution,
        first_contact_error_bound_s: first
            .and_then(|t| bound(t, r.interval_speeds.first().and_then(|s| s.0))),
        closing_speed_mps: first.and_then(|t| {
            r.interval_speeds
                .first()
                .and_then(|s| s.0)
                .map(|v| v * lat.resolution / lat.period_s(t))
        }),
        interval_error_bounds_s: r
            .intervals
            .iter()
            .zip(&r.interval_speeds)
            .map(|(&(s, e), &(vs, ve))| [bound(s, vs), bound(e, ve)])
            .collect(),
        overlap_hypervolume_error_bound_m3s: hv.map(|h| h.1),
        candidate_pairs: r.candidate_pairs,
        crossing_pairs: r.interfering_pairs,
    }
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
    let r = check_bag(&a.bag, mesher_options_from(&a.mesher), a.time_scale)?;
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
        } else {
            println!("clear   {} x {}", p.a, p.b);
        }
    }
    for s in &r.resolutions {
        println!("resolve {}", s);
    }
    println!(
        "mesh {:.0} ms, check {:.0} ms, resolve {:.0} ms, total {:.0} ms",
        r.timings_ms.mesh, r.timings_ms.check, r.timings_ms.resolve, r.timings_ms.total
    );
    if let Some(p) = &a.report {
        if let Some(dir) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|source| CliError::Io {
                path: dir.to_path_buf(),
                source,
            })?;
        }
        let text = serde_json::to_string_pretty(&r).expect("plain data serialises");
        std::fs::write(p, text).map_err(|source| CliError::Io {
            path: p.clone(),
            source,
        })?;
    }
    Ok(())
}
