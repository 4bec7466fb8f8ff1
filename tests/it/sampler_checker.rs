//! The checker cross-checked by the sampler
//! (docs/sampler.md#the-checker-cross-checked-by-the-sampler): two bodies are rasterised,
//! meshed in 4D and checked; the same bodies, as exact implicit figures, are given to
//! `chronotope sample`, whose 4D collision set (the points where both surfaces pass at
//! once) gives times. Every sampled time must lie in one of the checker's contact intervals
//! widened by the checker's own stated error bound at each end
//! (`checker::bounds::contact_time_bound`, the report's `interval_error_bounds_s`:
//! Δt·(1/2 + 1/v') with v' the closing speed in voxels per frame period), and the samples
//! must reach each end of every interval within that bound. docs/sampler.md derives the
//! bound and says why it is the right one.
//!
//! Two scenes, small grids (20³ voxels, 21 frames over 1 s) so that the test runs in
//! seconds: a box sliding into a sphere (first contact only; still overlapping when the
//! recording ends), and two spheres passing through each other off-centre (contact begins
//! and ends inside the recording). A third, where the bodies never meet, has neither
//! interference nor a collision set.

use chronotope::bag::BagReader;
use chronotope::checker::bounds::contact_time_bound;
use chronotope::checker::labels::Label;
use chronotope::checker::{check_pair, CommonLattice};
use chronotope::cli::sample::{run, SampleArgs, POINTS_TOPIC};
use chronotope::mesh::glue::BodyAssembler;
use chronotope::mesh::{FrameRef, MesherOptions};
use chronotope::msg::{decode_cdr, PointCloud2, VoxelEncoding};
use chronotope::scene::Shape as Solid;

const GRID: u32 = 20;
const FRAMES: u32 = 21;
/// Samples of the collision set per scene.
const SAMPLES: usize = 3000;
/// How near the samples must come to an interval's end beyond the checker's bound: the
/// sampled set's t-density is finite and non-zero at first and last contact (coarea formula,
/// `sampler::exact::PassingSpheres`), so 3000 samples come close to both ends (measured:
/// within 0.0013 s of the exact contact times).
const SAMPLING_GAP_S: f64 = 0.02;

/// One body: its rasterised solid and velocity, and the same body as a scene-file entry.
struct BodySpec {
    solid: Solid,
    velocity: [f64; 3],
    yaml: String,
}

fn sphere(c: [f64; 3], r: f64, v: [f64; 3]) -> BodySpec {
    BodySpec {
        solid: Solid::sphere(c, r),
        velocity: v,
        yaml: format!(
            "shape: {{kind: sphere, centre: [{}, {}, {}], radius: {r}}}\n    velocity: [{}, {}, {}]",
            c[0], c[1], c[2], v[0], v[1], v[2]
        ),
    }
}

/// The exact box (no rounding), as the rasteriser's cuboid.
fn cuboid(c: [f64; 3], h: f64, v: [f64; 3]) -> BodySpec {
    BodySpec {
        solid: Solid::cuboid(c.map(|x| x - h), c.map(|x| x + h)),
        velocity: v,
        yaml: format!(
            "shape: {{kind: box, centre: [{}, {}, {}], half: [{h}, {h}, {h}], rounding: 0.0}}\n    velocity: [{}, {}, {}]",
            c[0], c[1], c[2], v[0], v[1], v[2]
        ),
    }
}

fn scene_yaml(a: &BodySpec, b: &BodySpec) -> String {
    format!(
        "dim: 4\nbodies:\n  - name: a\n    {}\n  - name: b\n    {}\nsample: [a, b]\nwalls:\n  - {{kind: box, min: [0, 0, 0], max: [1, 1, 1]}}\ntime: [0.0, 1.0]\n",
        a.yaml, b.yaml
    )
}

/// A contact interval (s) and the error bound (s) the checker states at each end (`None`:
/// it states none, e.g. for a grazing contact).
type Contact = ((f64, f64), (Option<f64>, Option<f64>));

/// What the checker says about the rasterised pair.
struct Checked {
    /// Contact intervals with their bounds.
    intervals: Vec<Contact>,
    /// World bounding boxes (x, y, z, t) of the INTERFERENCE tets of both bodies.
    boxes: Vec<([f64; 4], [f64; 4])>,
    voxel: f64,
    period: f64,
    /// Closing speeds the checker states at the interval ends inside the recording (m/s).
    speeds_mps: Vec<f64>,
    start_s: f64,
    end_s: f64,
}

fn check(a: &BodySpec, b: &BodySpec) -> Checked {
    let lattice = chronotope::scene::VoxelLattice::cube([0.0; 3], 1.0, GRID);
    let mut raster = chronotope::scene::Rasterizer::new();
    let mut data = Vec::new();
    let period_ns = 1_000_000_000 / i64::from(FRAMES - 1);
    let mut meshes = Vec::new();
    for body in [a, b] {
        let mut asm = BodyAssembler::new(MesherOptions::default()).unwrap();
        for k in 0..FRAMES {
            let t = f64::from(k) / f64::from(FRAMES - 1);
            raster.rasterize(
                &[body.solid],
                body.velocity.map(|c| c * t),
                &lattice,
                VoxelEncoding::Bits,
                &mut data,
            );
            asm.push(&FrameRef {
                stamp_ns: i64::from(k) * period_ns,
                origin: lattice.origin,
                resolution: lattice.resolution,
                size: lattice.size,
                encoding: VoxelEncoding::Bits.code(),
                data: &data,
            })
            .unwrap();
        }
        meshes.push(asm.finish());
    }
    let named = [("a", &meshes[0]), ("b", &meshes[1])];
    let lat = CommonLattice::of(&named).unwrap();
    let pa = lat.prepare("a", &meshes[0]).unwrap();
    let pb = lat.prepare("b", &meshes[1]).unwrap();
    let r = check_pair(&pa, &pb);
    let origin = lat.stamps_ns[0];
    let period = period_ns as f64 * 1e-9;
    let per = lat.per_step() as f64;
    let world = |v: &[i32; 4]| -> [f64; 4] {
        [
            lat.voxel0_centre[0] + f64::from(v[0]) / per * lat.resolution,
            lat.voxel0_centre[1] + f64::from(v[1]) / per * lat.resolution,
            lat.voxel0_centre[2] + f64::from(v[2]) / per * lat.resolution,
            lat.time_s(f64::from(v[3]), origin),
        ]
    };
    let mut boxes = Vec::new();
    for (prep, labels) in [(&pa, &r.labels_a), (&pb, &r.labels_b)] {
        for (tet, l) in prep.mesh.tets.iter().zip(&labels.labels) {
            if *l != Label::Interference {
                continue;
            }
            let mut lo = [f64::INFINITY; 4];
            let mut hi = [f64::NEG_INFINITY; 4];
            for &vi in tet {
                let w = world(&prep.mesh.vertices[vi as usize]);
                for i in 0..4 {
                    lo[i] = lo[i].min(w[i]);
                    hi[i] = hi[i].max(w[i]);
                }
            }
            boxes.push((lo, hi));
        }
    }
    let intervals = r
        .intervals
        .iter()
        .zip(&r.interval_speeds)
        .map(|(&(s, e), &(vs, ve))| {
            (
                (lat.time_s(s, origin), lat.time_s(e, origin)),
                (
                    contact_time_bound(period, vs),
                    contact_time_bound(period, ve),
                ),
            )
        })
        .collect();
    let speeds_mps = r
        .interval_speeds
        .iter()
        .flat_map(|&(a, b)| [a, b])
        .flatten()
        .map(|v| v * lattice.resolution / period)
        .collect();
    Checked {
        intervals,
        boxes,
        voxel: lattice.resolution,
        period,
        speeds_mps,
        start_s: 0.0,
        end_s: f64::from(FRAMES - 1) * period,
    }
}

/// `chronotope sample` on the scene: the sampled points (x, y, z, t) read back from the bag.
fn sample(yaml: &str, seed: u64) -> Result<Vec<[f64; 4]>, String> {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.yaml");
    std::fs::write(&scene, yaml).unwrap();
    let out = dir.path().join("s.mcap");
    run(&SampleArgs {
        overwrite: false,
        scene,
        out: out.clone(),
        ply: None,
        scheme: None,
        samples: Some(SAMPLES),
        seed,
        dt: None,
        walkers: None,
        burn_in: None,
        thin: None,
        lambda: None,
        clamp: false,
        project: false,
        target_acceptance: None,
        summary: None,
    })
    .map_err(|e| e.to_string())?;
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("s.quality.json")).unwrap())
            .unwrap();
    let frac = summary["quality"]["ess_fraction"].as_f64().unwrap();
    eprintln!(
        "  sampled: ESS/N {frac:.2}, acceptance {:.2}, thin {}",
        summary["quality"]["acceptance"], summary["quality"]["adaptation"]["thin"]
    );
    let mut points = Vec::new();
    for m in BagReader::open(&out).unwrap() {
        let m = m.unwrap();
        if m.topic != POINTS_TOPIC {
            continue;
        }
        let c: PointCloud2 = decode_cdr(&m.data).unwrap();
        assert_eq!(c.point_step, 16);
        for p in c.data.chunks_exact(16) {
            let f =
                |i: usize| f64::from(f32::from_le_bytes(p[4 * i..4 * i + 4].try_into().unwrap()));
            points.push([f(0), f(1), f(2), f(3)]);
        }
    }
    assert_eq!(points.len(), SAMPLES);
    Ok(points)
}

/// The cross-check of one scene; `exact` is the analytic contact interval of the exact
/// bodies (clipped to the recording), a check that the scene is what it claims to be.
fn cross_check(name: &str, a: &BodySpec, b: &BodySpec, exact: (f64, f64)) {
    eprintln!("{name}:");
    let c = check(a, b);
    assert!(
        !c.intervals.is_empty(),
        "{name}: the checker found no contact"
    );
    let samples = sample(&scene_yaml(a, b), 11).unwrap();
    let (tmin, tmax) = samples
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |m, q| {
            (m.0.min(q[3]), m.1.max(q[3]))
        });
    eprintln!(
        "  exact contact {:.4}..{:.4} s; sampled {tmin:.4}..{tmax:.4} s; checker {:?}",
        exact.0, exact.1, c.intervals
    );
    assert!(
        (tmin - exact.0).abs() < SAMPLING_GAP_S && (tmax - exact.1).abs() < SAMPLING_GAP_S,
        "{name}: the sampled set does not span the exact contact"
    );
    // Each end of an interval inside the recording carries the checker's bound; an end at
    // the recording's start or end is where the recording cut the contact, like the time
    // wall cuts the sampled set, and needs none.
    let at_edge = |t: f64| (t - c.start_s).abs() < 1e-9 || (t - c.end_s).abs() < 1e-9;
    let widened: Vec<(f64, f64)> = c
        .intervals
        .iter()
        .map(|&((s, e), (bs, be))| {
            let bs = if at_edge(s) {
                0.0
            } else {
                bs.unwrap_or_else(|| panic!("{name}: no bound stated at {s} s"))
            };
            let be = if at_edge(e) {
                0.0
            } else {
                be.unwrap_or_else(|| panic!("{name}: no bound stated at {e} s"))
            };
            eprintln!("  checker interval {s:.4}..{e:.4} s, bounds ±{bs:.4} / ±{be:.4} s");
            // The checker's own claim about the exact contact, seen from the exact answer.
            assert!(
                (s - exact.0).abs() <= bs + 1e-9 || at_edge(s),
                "{name}: start {s} vs {}",
                exact.0
            );
            assert!(
                (e - exact.1).abs() <= be + 1e-9 || at_edge(e),
                "{name}: end {e} vs {}",
                exact.1
            );
            (s - bs, e + be)
        })
        .collect();
    // 1. Every sampled time lies in a widened interval.
    for q in &samples {
        assert!(
            widened.iter().any(|&(s, e)| q[3] >= s && q[3] <= e),
            "{name}: sample at t = {} outside the checker's intervals widened by their bounds {widened:?}",
            q[3]
        );
    }
    // 2. The samples reach each end of the union of the intervals within its bound (and the
    //    sampling gap): the checker reports no contact the exact bodies do not have.
    let first = c.intervals.first().unwrap();
    let last = c.intervals.last().unwrap();
    let (bs, be) = (first.1 .0.unwrap_or(0.0), last.1 .1.unwrap_or(0.0));
    assert!(
        tmin <= first.0 .0 + bs + SAMPLING_GAP_S,
        "{name}: the checker's contact starts at {} but samples only from {tmin}",
        first.0 .0
    );
    assert!(
        tmax >= last.0 .1 - be - SAMPLING_GAP_S,
        "{name}: the checker's contact ends at {} but samples go to {tmax}",
        last.0 .1
    );
    // 3. Where, not only when: every sample lies near the bounding box of an INTERFERENCE
    //    tet. A contact *time* is off by at most the stated Δt/2 + h/v, but the *place*
    //    where two meshes cross moves further than their surfaces where they cross at a
    //    shallow angle (the box's edges), so this allows a voxel diagonal in space and a
    //    frame period plus a voxel diagonal over the slowest closing speed the checker
    //    states in time.
    let diag = 3f64.sqrt() * c.voxel;
    let t_tol = c
        .speeds_mps
        .iter()
        .map(|v| c.period + diag / v)
        .fold(0.0, f64::max);
    let far: Vec<&[f64; 4]> = samples
        .iter()
        .filter(|q| {
            !c.boxes.iter().any(|(lo, hi)| {
                (0..3).all(|i| q[i] >= lo[i] - diag && q[i] <= hi[i] + diag)
                    && q[3] >= lo[3] - t_tol
                    && q[3] <= hi[3] + t_tol
            })
        })
        .collect();
    assert!(
        far.is_empty(),
        "{name}: {} of {} samples far from every INTERFERENCE tet, e.g. {:?}",
        far.len(),
        samples.len(),
        &far[..far.len().min(3)]
    );
}

#[test]
fn a_box_sliding_into_a_sphere() {
    // Sphere r 0.2 at (0.65, 0.5, 0.5); box of half-edge 0.15 from (0.2, 0.5, 0.55) at
    // 0.6 m/s along x: its face x = 0.35 + 0.6 t reaches the sphere's leftmost point
    // (0.45, 0.5, 0.5), inside the face, at t = 1/6 s; they still cross at the end.
    let a = sphere([0.65, 0.5, 0.5], 0.2, [0.0; 3]);
    let b = cuboid([0.2, 0.5, 0.55], 0.15, [0.6, 0.0, 0.0]);
    cross_check("box into sphere", &a, &b, (1.0 / 6.0, 1.0));
}

#[test]
fn two_spheres_passing_through_each_other() {
    // Spheres r 0.15 at (0.5, 0.5, 0.5) and (0.1 + 0.8 t, 0.58, 0.5): their centres are
    // 0.3 apart when (0.4 - 0.8 t)² + 0.08² = 0.09, at t = (0.4 ∓ 0.28914)/0.8; never closer
    // than 0.08, so neither ever holds the other and their surfaces cross throughout.
    let a = sphere([0.5, 0.5, 0.5], 0.15, [0.0; 3]);
    let b = sphere([0.1, 0.58, 0.5], 0.15, [0.8, 0.0, 0.0]);
    let root = (0.09f64 - 0.08 * 0.08).sqrt();
    cross_check(
        "spheres passing",
        &a,
        &b,
        ((0.4 - root) / 0.8, (0.4 + root) / 0.8),
    );
}

#[test]
fn bodies_that_never_meet_have_no_collision_set_and_no_interference() {
    // The box moves away from the sphere.
    let a = sphere([0.65, 0.5, 0.5], 0.2, [0.0; 3]);
    let b = cuboid([0.2, 0.5, 0.55], 0.15, [-0.1, 0.0, 0.0]);
    let c = check(&a, &b);
    assert!(c.intervals.is_empty() && c.boxes.is_empty());
    let e = sample(&scene_yaml(&a, &b), 11).unwrap_err();
    assert!(e.contains("cannot put walkers on the figure"), "{e}");
}
