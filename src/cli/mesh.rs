//! `chronotope mesh BAG [--stats FILE.json] [--slice AXIS=VALUE ... --ply-dir DIR]`.
//!
//! The bag is read once, in file order; each body's frames go to its own worker thread
//! through a small bounded queue, so bodies mesh in parallel and memory stays bounded by a
//! few frames and one slab per body, whatever the bag's length. A frame that cannot be
//! decoded or meshed is logged with its topic, stamp and reason, counted, and skipped.

use super::BagFrames;
use super::CliError;
use crate::mesh::slice::{PlaneValue, Slicer, TriMesh};
use crate::mesh::stats::{BodyStats, StatsAccumulator};
use crate::mesh::stream::BodyStream;
use crate::mesh::{CapSide, GridGeometry, MeshError, Mesher, MesherOptions, Slab, TetMesh};
use crate::msg::VoxelGrid;
use clap::Args;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{sync_channel, Receiver};
use std::time::Instant;

/// Options of `chronotope mesh`.
#[derive(Debug, Clone, Args)]
pub struct MeshArgs {
    /// Input bag: a rosbag2 directory, or an MCAP or SQLite (.db3) file, zstd-compressed or not.
    pub bag: PathBuf,
    /// Write statistics as JSON (format: docs/formats.md#mesh-statistics).
    #[arg(long)]
    pub stats: Option<PathBuf>,
    /// Cut every body's 4D mesh by an axis hyperplane, e.g. `t=1.5` (seconds after the
    /// body's first frame) or `x=0.64` (metres); repeatable. Written as PLY into
    /// `--ply-dir`; a PLY's time axis is seconds after the body's first frame.
    #[arg(long = "slice", value_parser = parse_slice)]
    pub slices: Vec<SliceSpec>,
    /// Directory for the slice PLY files.
    #[arg(long, default_value = ".")]
    pub ply_dir: PathBuf,
    /// Mesher options.
    #[command(flatten)]
    pub mesher: MesherArgs,
    /// Replace an output path that holds a bag. Inputs are never replaced.
    #[arg(long)]
    pub overwrite: bool,
}

/// Mesher options on the command line.
#[derive(Debug, Clone, Args)]
pub struct MesherArgs {
    /// Lattice steps per voxel edge for PERCENT frames (power of two).
    #[arg(long, default_value_t = 64)]
    pub percent_scale: i32,
    /// Percent at and above which a voxel counts as occupied.
    #[arg(long, default_value_t = 50)]
    pub iso_percent: u8,
    /// Count unknown (255) voxels as free instead of occupied.
    #[arg(long)]
    pub unknown_free: bool,
}

/// An axis hyperplane in metres / seconds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SliceSpec {
    /// 0..4 = x, y, z, t.
    pub axis: usize,
    /// Metres for x, y, z; seconds since the bag's first frame for t.
    pub value: f64,
}

/// Why a `--slice` value is refused (clap shows it after the value).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SliceError {
    /// No `=` between axis and value.
    #[error("slice {0:?}: expected AXIS=VALUE, e.g. t=1.5")]
    NoEquals(String),
    /// An axis other than x, y, z or t.
    #[error("slice axis {0:?}: expected x, y, z or t")]
    Axis(String),
    /// A value that is not a number.
    #[error("slice value {value:?}: {reason}")]
    Value {
        /// The value as given.
        value: String,
        /// Why it does not parse.
        reason: std::num::ParseFloatError,
    },
    /// A value that is infinite or NaN.
    #[error("slice value {0:?} is not finite")]
    NotFinite(String),
}

fn parse_slice(s: &str) -> Result<SliceSpec, SliceError> {
    let (a, v) = s
        .split_once('=')
        .ok_or_else(|| SliceError::NoEquals(s.to_owned()))?;
    let axis = match a.trim() {
        "x" => 0,
        "y" => 1,
        "z" => 2,
        "t" => 3,
        other => return Err(SliceError::Axis(other.to_owned())),
    };
    let value: f64 = v.trim().parse().map_err(|reason| SliceError::Value {
        value: v.to_owned(),
        reason,
    })?;
    if !value.is_finite() {
        return Err(SliceError::NotFinite(v.to_owned()));
    }
    Ok(SliceSpec { axis, value })
}

/// Per-body result of a mesh run.
#[derive(Debug, Clone)]
pub struct BodyResult {
    /// Topic name.
    pub id: String,
    /// Statistics.
    pub stats: BodyStats,
    /// Frames skipped (decode or mesher errors).
    pub skipped: u64,
    /// The lattice, once known.
    pub geometry: Option<GridGeometry>,
    /// Slices, with their spec.
    pub slices: Vec<(SliceSpec, TriMesh)>,
    /// Stamps of the accepted frames (ns).
    pub stamps_ns: Vec<i64>,
}

/// The result of meshing a bag.
#[derive(Debug, Clone)]
pub struct MeshRun {
    /// Bodies by topic, sorted.
    pub bodies: Vec<BodyResult>,
    /// Wall-clock seconds.
    pub seconds_total: f64,
    /// Peak RSS (MB).
    pub peak_rss_mb: f64,
    /// Problems with the bag itself (corrupt chunks, truncation), in reading order.
    pub bag_errors: Vec<String>,
}

/// Mesher options from the command line.
pub fn mesher_options_from(a: &MesherArgs) -> MesherOptions {
    let mut o = MesherOptions {
        percent_scale: a.percent_scale,
        ..MesherOptions::default()
    };
    o.decode.iso_percent = a.iso_percent;
    o.decode.unknown_occupied = !a.unknown_free;
    o
}

enum Job {
    Frame(Box<VoxelGrid>),
    Undecodable,
}

/// Meshes every VoxelGrid topic of a bag.
///
/// # Errors
/// The bag cannot be opened, is empty, has no VoxelGrid topic, or the options are bad.
/// Per-frame problems are logged and counted instead.
pub fn mesh_bag(
    path: &Path,
    opts: MesherOptions,
    slices: &[SliceSpec],
) -> Result<MeshRun, CliError> {
    let start = Instant::now();
    Mesher::new(opts)?; // refuse bad options before reading anything
    let mut frames = BagFrames::open(path)?;
    let mut bag_errors = Vec::new();
    let bodies = std::thread::scope(|scope| {
        let mut senders = BTreeMap::new();
        let mut handles = Vec::new();
        let mut refused = std::collections::BTreeSet::new();
        for (topic, grid) in frames.by_ref() {
            let job = match grid {
                Some(grid) => Job::Frame(Box::new(grid)),
                None => Job::Undecodable,
            };
            if !senders.contains_key(&topic) {
                if refused.contains(&topic) {
                    continue;
                }
                let (tx, rx) = sync_channel::<Job>(2);
                let name = topic.clone();
                let spawned = std::thread::Builder::new()
                    .name(format!("mesh {topic}"))
                    .spawn_scoped(scope, move || body_worker(name, rx, opts, slices))
                    .map(|h| {
                        handles.push(h);
                        tx
                    })
                    .map_err(|e| format!("cannot start a worker: {e}"));
                match spawned {
                    Ok(tx) => {
                        senders.insert(topic.clone(), tx);
                    }
                    Err(why) => {
                        tracing::error!(topic = %topic, "not meshed: {why}");
                        bag_errors.push(format!("{topic}: not meshed: {why}"));
                        refused.insert(topic);
                        continue;
                    }
                }
            }
            let tx = &senders[&topic];
            // Fails only if the worker panicked, which the join below reports.
            let _ = tx.send(job);
        }
        drop(senders);
        let mut bodies: Vec<BodyResult> = handles
            .into_iter()
            .map(|h| h.join().expect("body worker panicked"))
            .collect();
        bodies.sort_by(|a, b| a.id.cmp(&b.id));
        bodies
    });
    // Bag problems first (in reading order), then refused topics.
    let mut errors = frames.errors;
    errors.extend(bag_errors);
    Ok(MeshRun {
        bodies,
        seconds_total: start.elapsed().as_secs_f64(),
        peak_rss_mb: crate::bench::peak_rss_mb(),
        bag_errors: errors,
    })
}

/// One requested slice of one body: the two rule variants, created once the plane is known.
struct SliceState {
    spec: SliceSpec,
    pair: Option<(Slicer, Slicer)>,
}

impl SliceState {
    fn add(&mut self, c: PlaneValue, mesh: &TetMesh) {
        let (plus, minus) = self.pair.get_or_insert_with(|| {
            (
                Slicer::new(self.spec.axis, c),
                Slicer::new(self.spec.axis, c).on_plane_below(),
            )
        });
        plus.add(mesh);
        minus.add(mesh);
    }

    fn finish(self) -> (SliceSpec, TriMesh) {
        let mesh = match self.pair {
            None => TriMesh::default(),
            Some((plus, minus)) => {
                let p = plus.finish();
                if p.triangles.is_empty() {
                    minus.finish()
                } else {
                    p
                }
            }
        };
        (self.spec, mesh)
    }
}

fn body_worker(
    topic: String,
    rx: Receiver<Job>,
    opts: MesherOptions,
    slices: &[SliceSpec],
) -> BodyResult {
    let mut stream = BodyStream::new(opts).expect("options checked before spawning");
    let mut acc = StatsAccumulator::new();
    let mut first_cap: Option<TetMesh> = None;
    let mut frame_id = String::new();
    let mut states: Vec<SliceState> = slices
        .iter()
        .map(|&spec| SliceState { spec, pair: None })
        .collect();
    let mut stamps_ns: Vec<i64> = Vec::new();
    for job in rx {
        let grid = match job {
            Job::Frame(g) => g,
            Job::Undecodable => {
                stream.refuse(None, &MeshError::Undecodable);
                continue;
            }
        };
        let f = grid.frame_ref();
        // The same rules as the mesher node and `check` (mesh::stream).
        if let Err(e) = grid.message_check(&frame_id) {
            tracing::warn!(topic = %topic, stamp_ns = f.stamp_ns, "skipping frame: {e}");
            stream.refuse(Some(f.stamp_ns), &e);
            continue;
        }
        let t0 = Instant::now();
        let accepted = match stream.push(&f) {
            Ok(a) => a,
            Err(e) => {
                tracing::warn!(topic = %topic, stamp_ns = f.stamp_ns, "skipping frame: {e}");
                continue;
            }
        };
        if frame_id.is_empty() {
            frame_id = grid.header.frame_id.clone();
        }
        if accepted.clamped > 0 {
            tracing::warn!(topic = %topic, stamp_ns = f.stamp_ns, "{}", MeshError::PercentOutOfRange { voxels: accepted.clamped });
        }
        if let Some(g) = &accepted.gap {
            tracing::warn!(topic = %topic, "frames missing from {} to {} ns: {}", g.from_ns, g.to_ns, g.reason);
        }
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        for (stamp, slab) in accepted.frames {
            stamps_ns.push(stamp);
            let Some(slab) = slab else {
                continue;
            };
            acc.record_time(ms);
            let mesher = stream.mesher();
            let first_stamp = mesher
                .first_frame()
                .map_or(slab.stamp_lo_ns, |k| k.stamp_ns);
            if first_cap.is_none() {
                first_cap = mesher
                    .first_frame()
                    .and_then(|k| mesher.cap(k, CapSide::Low));
            }
            acc.add_slab(&slab, first_cap.as_ref());
            for st in &mut states {
                let g = &slab.geometry;
                if st.spec.axis < 3 {
                    let c = spatial_plane(&st.spec, g);
                    if st.pair.is_none() {
                        if let Some(cap) = &first_cap {
                            st.add(c, cap);
                        }
                    }
                    st.add(c, &slab.mesh);
                } else if let Some(c) = time_plane(st.spec.value, g, &slab, first_stamp) {
                    st.add(c, &slab.mesh);
                }
            }
        }
    }
    let mesher = stream.mesher();
    let has_slabs = mesher.frames() >= 2;
    let last_cap = if has_slabs {
        mesher
            .last_frame()
            .and_then(|k| mesher.cap(k, CapSide::High))
    } else {
        None
    };
    if let (Some(cap), Some(g)) = (&last_cap, mesher.geometry()) {
        for st in states.iter_mut().filter(|s| s.spec.axis < 3) {
            st.add(spatial_plane(&st.spec, g), cap);
        }
    }
    let occ_first = mesher.first_frame().map_or(0, |f| f.grid.occupied);
    let occ_last = mesher.last_frame().map_or(0, |f| f.grid.occupied);
    let stats = acc.finish(
        mesher.frames(),
        first_cap.as_ref().map(|c| (c.tets.len() as u64, occ_first)),
        last_cap.as_ref().map(|c| (c, occ_last)),
    );
    BodyResult {
        id: topic,
        stats,
        skipped: stream.losses().refused_frames,
        geometry: mesher.geometry().copied(),
        slices: states.into_iter().map(SliceState::finish).collect(),
        stamps_ns,
    }
}

/// Lattice coordinate of a spatial plane given in metres.
fn spatial_plane(spec: &SliceSpec, g: &GridGeometry) -> PlaneValue {
    let c = g.voxel0_centre()[spec.axis];
    PlaneValue::approx((spec.value - c) / g.step_m())
}

/// Lattice time of `t` seconds after the body's first frame, if it falls in the slab.
fn time_plane(t: f64, g: &GridGeometry, slab: &Slab, first_stamp: i64) -> Option<PlaneValue> {
    // Integer nanoseconds: absolute stamps (~1.7e18) lose 256 ns as f64.
    let ns = first_stamp.checked_add((t * 1e9).round() as i64)?;
    let (lo, hi) = (slab.stamp_lo_ns, slab.stamp_hi_ns);
    if !(lo..=hi).contains(&ns) {
        return None;
    }
    let s = i64::from(g.scale);
    let base = s * slab.index as i64;
    Some(if ns == lo {
        PlaneValue::lattice(base)
    } else if ns == hi {
        PlaneValue::lattice(base + s)
    } else {
        PlaneValue::approx(base as f64 + (ns - lo) as f64 / (hi - lo) as f64 * s as f64)
    })
}

/// One body in the `--stats` JSON (docs/formats.md#mesh-statistics), with extra fields
/// after the contract's.
#[derive(Debug, Serialize)]
struct BodyJson<'a> {
    id: &'a str,
    frames: u64,
    tets: u64,
    vertices: u64,
    closed: bool,
    hypervolume_m3s: f64,
    slab_ms_median: f64,
    slab_ms_p99: f64,
    slabs: u64,
    skipped_frames: u64,
    unpaired_triangles: u64,
    misoriented_triangles: u64,
    vanishing_slabs: u64,
}

/// The `--stats` JSON (docs/formats.md#mesh-statistics).
#[derive(Debug, Serialize)]
struct StatsJson<'a> {
    bodies: Vec<BodyJson<'a>>,
    seconds_total: f64,
    peak_rss_mb: f64,
    bag_errors: &'a [String],
}

/// The `--stats` JSON text of a run.
pub fn stats_json(r: &MeshRun) -> String {
    let bodies = r
        .bodies
        .iter()
        .map(|b| BodyJson {
            id: &b.id,
            frames: b.stats.frames,
            tets: b.stats.tets,
            vertices: b.stats.vertices,
            closed: b.stats.closed.is_closed(),
            hypervolume_m3s: b.stats.hypervolume_m3s,
            slab_ms_median: b.stats.slab_ms_median(),
            slab_ms_p99: b.stats.slab_ms_p99(),
            slabs: b.stats.slabs,
            skipped_frames: b.skipped,
            unpaired_triangles: b.stats.closed.unpaired + b.stats.closed.overshared,
            misoriented_triangles: b.stats.closed.misoriented,
            vanishing_slabs: b.stats.vanishing_slabs,
        })
        .collect();
    let j = StatsJson {
        bodies,
        seconds_total: r.seconds_total,
        peak_rss_mb: r.peak_rss_mb,
        bag_errors: &r.bag_errors,
    };
    serde_json::to_string_pretty(&j).expect("plain data serialises")
}

fn file_safe(topic: &str) -> String {
    let s: String = topic
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    s.trim_matches('_').to_owned()
}

/// Runs `chronotope mesh`.
///
/// # Errors
/// See [`mesh_bag`]; also a stats or PLY file that cannot be written.
pub fn run(a: &MeshArgs) -> Result<(), CliError> {
    use super::paths::{OutputKind, Paths};
    Paths::new(a.overwrite)
        .bag(&a.bag)
        .output("--stats", a.stats.as_deref(), OutputKind::File)
        .output(
            "--ply-dir",
            (!a.slices.is_empty()).then_some(a.ply_dir.as_path()),
            OutputKind::Dir,
        )
        .check()?;
    let r = mesh_bag(&a.bag, mesher_options_from(&a.mesher), &a.slices)?;
    println!(
        "{:<28} {:>6} {:>11} {:>11} {:>7} {:>14} {:>9} {:>9} {:>7}",
        "body",
        "frames",
        "tets",
        "vertices",
        "closed",
        "hypervol m3s",
        "slab p50",
        "slab p99",
        "skipped"
    );
    for b in &r.bodies {
        let s = &b.stats;
        println!(
            "{:<28} {:>6} {:>11} {:>11} {:>7} {:>14.6e} {:>7.2}ms {:>7.2}ms {:>7}",
            b.id,
            s.frames,
            s.tets,
            s.vertices,
            s.closed.is_closed(),
            s.hypervolume_m3s,
            s.slab_ms_median(),
            s.slab_ms_p99(),
            b.skipped
        );
        if s.vanishing_slabs > 0 {
            tracing::warn!(
                topic = %b.id,
                "{} of {} slabs: consecutive frames share no occupied voxel: the body moves more than its own \
                 thickness per frame, vanishes between frames in 4D, and contacts there can be missed; raise the frame rate",
                s.vanishing_slabs,
                s.slabs
            );
        }
        if s.frames == 1 {
            tracing::warn!(topic = %b.id, "only one frame: a 4D mesh needs at least two frames");
        }
    }
    println!(
        "total {:.3} s, peak RSS {:.1} MB",
        r.seconds_total, r.peak_rss_mb
    );
    if let Some(p) = &a.stats {
        super::write_output(p, stats_json(&r).as_bytes())?;
    }
    if !a.slices.is_empty() {
        std::fs::create_dir_all(&a.ply_dir).map_err(|source| CliError::Io {
            path: a.ply_dir.clone(),
            source,
        })?;
    }
    for b in &r.bodies {
        let Some(g) = b.geometry else { continue };
        for (spec, mesh) in &b.slices {
            let axis = ["x", "y", "z", "t"][spec.axis];
            let path = a
                .ply_dir
                .join(format!("{}_{axis}{}.ply", file_safe(&b.id), spec.value));
            let io = |source| CliError::Io {
                path: path.clone(),
                source,
            };
            // Named once complete; a link at the path is replaced, not followed.
            let mut file = crate::fsio::NewFile::create(&path).map_err(io)?;
            let to_world = slice_to_world(spec.axis, &g, b);
            crate::mesh::slice::write_ply(mesh, std::io::BufWriter::new(file.file()), to_world)
                .map_err(io)?;
            file.commit().map_err(io)?;
            tracing::info!("{}: {} triangles", path.display(), mesh.triangles.len());
        }
    }
    Ok(())
}

/// Maps slice coordinates (lattice units of the three remaining axes) to metres and, for
/// time, seconds since the body's first frame (piecewise linear between its frame stamps).
fn slice_to_world(axis: usize, g: &GridGeometry, b: &BodyResult) -> impl Fn(&[f64; 3]) -> [f64; 3] {
    let c = g.voxel0_centre();
    let step = g.step_m();
    let s = f64::from(g.scale);
    let stamps = b.stamps_ns.clone();
    let keep: Vec<usize> = (0..4).filter(|&k| k != axis).collect();
    move |p: &[f64; 3]| {
        let mut out = [0.0; 3];
        for (m, &k) in keep.iter().enumerate() {
            out[m] = if k < 3 {
                c[k] + p[m] * step
            } else {
                crate::kernel::stamp_time_s(&stamps, s, p[m], stamps.first().copied().unwrap_or(0))
            };
        }
        out
    }
}
