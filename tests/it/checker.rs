//! The checker on scenes with known answers, and the stiff cases.

use crate::common;

use chronotope::checker::labels::LabelCounts;
use chronotope::checker::{check_pair, check_pair_walked, CommonLattice, PairResult, StreamWalk};
use chronotope::mesh::glue::{BodyAssembler, BodyMesh};
use chronotope::mesh::MesherOptions;
use chronotope::msg::VoxelEncoding;
use chronotope::scene::{build_scene, SceneName, SceneOptions, FOUR_SPHERES};
use common::{bits_data, frame_ref as test_frame_ref, TestFrame};

fn assemble(frames: &[TestFrame], size: [u32; 3]) -> BodyMesh {
    let mut a = BodyAssembler::new(MesherOptions::default()).unwrap();
    for f in frames {
        a.push(&test_frame_ref(f, size, 0.1)).unwrap();
    }
    a.finish()
}

fn check(a: &BodyMesh, b: &BodyMesh) -> (PairResult, CommonLattice) {
    let lat = CommonLattice::of(&[("a", a), ("b", b)]).unwrap();
    let (pa, pb) = (lat.prepare("a", a).unwrap(), lat.prepare("b", b).unwrap());
    (check_pair(&pa, &pb), lat)
}

fn static_body(
    size: [u32; 3],
    frames: usize,
    occ: impl Fn(usize, usize, usize) -> bool + Copy,
) -> BodyMesh {
    body_over(size, 0..frames, occ)
}

fn in_box(lo: [usize; 3], hi: [usize; 3]) -> impl Fn(usize, usize, usize) -> bool + Copy {
    move |x, y, z| {
        (lo[0]..=hi[0]).contains(&x) && (lo[1]..=hi[1]).contains(&y) && (lo[2]..=hi[2]).contains(&z)
    }
}

fn no_interference(c: &LabelCounts) -> bool {
    c.interference == 0 && c.inside == 0
}

#[test]
fn disjoint_bodies_are_all_outside() {
    let size = [8, 6, 6];
    let a = static_body(size, 3, in_box([1, 1, 1], [2, 4, 4]));
    let b = static_body(size, 3, in_box([5, 1, 1], [6, 4, 4]));
    let (r, _) = check(&a, &b);
    assert!(!r.interfering());
    let (ca, cb) = r.counts();
    assert!(no_interference(&ca) && no_interference(&cb));
    assert_eq!(ca.outside as usize, a.mesh.tets.len());
    assert!(r.intervals.is_empty());
}

fn body_over(
    size: [u32; 3],
    frames: std::ops::Range<usize>,
    occ: impl Fn(usize, usize, usize) -> bool + Copy,
) -> BodyMesh {
    let f: Vec<TestFrame> = frames
        .map(|k| TestFrame {
            stamp_ns: 1_000_000 * k as i64,
            encoding: 0,
            data: bits_data(size, occ),
        })
        .collect();
    assemble(&f, size)
}

#[test]
fn a_body_inside_the_other_without_crossing_is_all_inside() {
    // The small body exists for frames 1..=3, the big one for 0..=4: in 4D the small one
    // is strictly inside, no boundary crosses, there is no INTERFERENCE tet at all.
    let size = [9, 9, 9];
    let big = body_over(size, 0..5, in_box([1, 1, 1], [7, 7, 7]));
    let small = body_over(size, 1..4, in_box([3, 3, 3], [5, 5, 5]));
    let (r, lat) = check(&small, &big);
    let (cs, cb) = r.counts();
    assert_eq!(cs.interference, 0, "{cs:?}");
    assert_eq!(cs.inside as usize, small.mesh.tets.len(), "{cs:?}");
    assert_eq!(cb.inside, 0);
    assert_eq!(cb.outside as usize, big.mesh.tets.len());
    assert!(r.interfering());
    // Overlap over the small body's whole span, frames 1 to 3.
    assert_eq!(r.intervals.len(), 1);
    let origin = lat.stamps_ns[0];
    assert!((lat.time_s(r.intervals[0].0, origin) - 0.001).abs() < 1e-12);
    assert!((lat.time_s(r.intervals[0].1, origin) - 0.003).abs() < 1e-12);
}

#[test]
fn shared_start_and_end_times_make_the_caps_interfere() {
    // Same time span: the small body's caps lie in the big body's cap hyperplanes and face
    // the same way, so the interiors overlap right there: INTERFERENCE on the caps (the
    // coplanar clause of the touching rule), INSIDE elsewhere.
    let size = [9, 9, 9];
    let big = body_over(size, 0..3, in_box([1, 1, 1], [7, 7, 7]));
    let small = body_over(size, 0..3, in_box([3, 3, 3], [5, 5, 5]));
    let (r, _) = check(&small, &big);
    let (cs, _) = r.counts();
    assert!(
        cs.interference > 0 && cs.inside > 0 && cs.outside == 0,
        "{cs:?}"
    );
}

#[test]
fn bodies_face_to_face_in_adjacent_voxels_only_touch() {
    let size = [8, 6, 6];
    let a = static_body(size, 3, in_box([1, 1, 1], [3, 4, 4]));
    let b = static_body(size, 3, in_box([4, 1, 1], [6, 4, 4]));
    let (r, _) = check(&a, &b);
    assert!(!r.interfering(), "{:?}", r.counts());
}

#[test]
fn identical_bodies_interfere_everywhere() {
    let size = [6, 6, 6];
    let a = static_body(size, 3, in_box([1, 1, 1], [3, 4, 2]));
    let (r, _) = check(&a, &a.clone());
    assert!(r.interfering());
    let (ca, cb) = r.counts();
    assert_eq!(ca.interference as usize, a.mesh.tets.len(), "{ca:?}");
    assert_eq!(cb.interference as usize, a.mesh.tets.len());
}

fn spheres(grid: u32, frames: u32) -> (Vec<String>, Vec<BodyMesh>) {
    let opts = SceneOptions::for_scene(SceneName::FourSpheres)
        .grid(grid)
        .frames(frames)
        .encoding(VoxelEncoding::Bits);
    let scene = build_scene(SceneName::FourSpheres, &opts).unwrap();
    let bodies = (0..scene.topics().len())
        .map(|b| {
            let mut asm = BodyAssembler::new(MesherOptions::default()).unwrap();
            for k in 0..scene.frame_count() {
                asm.push(&scene.frame(b, k).frame_ref()).unwrap();
            }
            asm.finish()
        })
        .collect();
    (scene.topics(), bodies)
}

#[test]
fn four_spheres_interfere_as_the_exact_answer_says() {
    let (topics, bodies) = spheres(20, 21);
    let named: Vec<(&str, &BodyMesh)> = topics
        .iter()
        .map(|t| t.as_str())
        .zip(bodies.iter())
        .collect();
    let lat = CommonLattice::of(&named).unwrap();
    let prepared: Vec<_> = named
        .iter()
        .map(|(id, b)| lat.prepare(id, b).unwrap())
        .collect();
    let origin = lat.stamps_ns[0];
    let period = 1.0 / 20.0;
    for i in 0..4 {
        for j in i + 1..4 {
            let r = check_pair(&prepared[i], &prepared[j]);
            let exact = FOUR_SPHERES.overlap_interval(i, j);
            assert_eq!(
                r.interfering(),
                exact.is_some(),
                "pair {i}-{j}: {:?}",
                r.counts()
            );
            if let Some((t0, t1)) = exact {
                assert_eq!(r.intervals.len(), 1, "pair {i}-{j}: {:?}", r.intervals);
                let (s, e) = (
                    lat.time_s(r.intervals[0].0, origin),
                    lat.time_s(r.intervals[0].1, origin),
                );
                // Voxelisation moves surfaces by up to half a voxel (0.025 m at grid 20);
                // at closing speeds of 0.5-0.72 m/s that is about a frame period.
                assert!(
                    (s - t0).abs() < 2.0 * period,
                    "pair {i}-{j}: start {s} vs exact {t0}"
                );
                assert!(
                    (e - t1).abs() < 2.0 * period,
                    "pair {i}-{j}: end {e} vs exact {t1}"
                );
                // Symmetric.
                let rev = check_pair(&prepared[j], &prepared[i]);
                assert_eq!(rev.counts(), (r.counts().1, r.counts().0));
                assert_eq!(rev.intervals, r.intervals);
            }
        }
    }
}

#[test]
fn translating_both_bodies_by_a_lattice_vector_changes_no_label() {
    let size = [10, 8, 8];
    let a = static_body(size, 3, in_box([1, 1, 1], [4, 5, 5]));
    let b = static_body(size, 3, in_box([3, 3, 2], [6, 6, 6]));
    let (r, _) = check(&a, &b);
    assert!(r.interfering());
    let shift = |m: &BodyMesh| {
        let mut m = m.clone();
        m.mesh.translate([6, -4, 2, 8]);
        m
    };
    let (r2, _) = check(&shift(&a), &shift(&b));
    assert_eq!(r.labels_a.labels, r2.labels_a.labels);
    assert_eq!(r.labels_b.labels, r2.labels_b.labels);
}

mod resolution {
    use super::*;
    use chronotope::checker::resolve::{suggest_time_scaling, suggest_translation, Metric};

    fn prepare2(
        a: &BodyMesh,
        b: &BodyMesh,
    ) -> (
        chronotope::checker::Prepared,
        chronotope::checker::Prepared,
        CommonLattice,
    ) {
        let lat = CommonLattice::of(&[("a", a), ("b", b)]).unwrap();
        (
            lat.prepare("a", a).unwrap(),
            lat.prepare("b", b).unwrap(),
            lat,
        )
    }

    #[test]
    fn overlapping_boxes_are_pushed_apart_along_the_overlap_by_its_depth() {
        // Same y/z extent, overlapping by 2 voxels in x (marching-cubes solids [0.5, 4.5] and
        // [2.5, 6.5] in voxel units): the shortest way out is 2 voxels along −x.
        let size = [9, 6, 6];
        let a = static_body(size, 3, in_box([1, 1, 1], [4, 4, 4]));
        let b = static_body(size, 3, in_box([3, 1, 1], [6, 4, 4]));
        let (pa, pb, lat) = prepare2(&a, &b);
        let r = check_pair(&pa, &pb);
        assert!(r.interfering());
        let m = Metric::new(&lat, 0.1 / 0.001);
        let t = suggest_translation(&pa, &[&pb], &[&r], &m).expect("a translation");
        assert!(t.verified_clear, "{t:?}");
        assert_eq!(t.direction, "gradient");
        let per = lat.per_step();
        assert!(t.lattice[0] < 0, "{t:?}");
        assert!(
            t.lattice[1].abs() + t.lattice[2].abs() + t.lattice[3].abs() <= per / 4,
            "{t:?}"
        );
        let exact = 2.0 * 0.1;
        assert!(
            t.distance_m >= exact * 0.99 && t.distance_m <= exact * 1.1,
            "{} vs {exact}",
            t.distance_m
        );
    }

    #[test]
    fn a_symmetric_overlap_with_zero_gradient_falls_back_without_nan() {
        // The small body is strictly inside the big one: its whole boundary is INSIDE, so
        // the outward normals sum to zero.
        let size = [9, 9, 9];
        let big = body_over(size, 0..5, in_box([1, 1, 1], [7, 7, 7]));
        let small = body_over(size, 1..4, in_box([3, 3, 3], [5, 5, 5]));
        let (ps, pb, lat) = prepare2(&small, &big);
        let r = check_pair(&ps, &pb);
        let m = Metric::new(&lat, 0.1 / 0.001);
        let t = suggest_translation(&ps, &[&pb], &[&r], &m).expect("a translation");
        assert_eq!(t.direction, "axis fallback");
        assert!(t.distance_m.is_finite() && t.distance_m > 0.0);
        assert!(t.verified_clear, "{t:?}");
        // Along time the small body leaves the big one by shifting past its end: a scaling
        // about an end of its span cannot do that, and the report says so honestly.
        if let Some(ts) = suggest_time_scaling(&ps, &[&pb], &[&r]) {
            assert!(ts.scale.is_finite() && ts.scale > 0.0);
        }
    }
}

mod stiff {
    use super::*;

    fn frames_of(
        size: [u32; 3],
        stamps: &[i64],
        occ: &dyn Fn(usize, usize, usize, usize) -> bool,
    ) -> Vec<TestFrame> {
        stamps
            .iter()
            .enumerate()
            .map(|(k, &s)| TestFrame {
                stamp_ns: s,
                encoding: 0,
                data: bits_data(size, |x, y, z| occ(k, x, y, z)),
            })
            .collect()
    }

    #[test]
    fn bodies_disjoint_in_time_do_not_interfere() {
        // Same place, frames 0-2 for one and 3-5 for the other.
        let size = [6, 6, 6];
        let occ = |_: usize, x: usize, y: usize, z: usize| {
            (1..4).contains(&x) && (1..4).contains(&y) && (1..4).contains(&z)
        };
        let a = assemble(&frames_of(size, &[0, 10, 20], &occ), size);
        let b = assemble(&frames_of(size, &[30, 40, 50], &occ), size);
        let (r, _) = check(&a, &b);
        assert!(!r.interfering(), "{:?}", r.counts());
    }

    #[test]
    fn a_single_voxel_body_is_found_inside_a_big_one() {
        let size = [7, 7, 7];
        let big = body_over(size, 0..5, in_box([1, 1, 1], [5, 5, 5]));
        let dot = body_over(size, 1..4, in_box([3, 3, 3], [3, 3, 3]));
        let (r, _) = check(&dot, &big);
        let (cd, _) = r.counts();
        assert_eq!(cd.inside as usize, dot.mesh.tets.len());
        assert!(r.interfering());
    }

    fn moving_pair(origin: [f64; 3], period_ns: i64) -> (PairResult, CommonLattice, i64) {
        // A box moving +x one voxel per frame towards a static box: they meet.
        let size = [12u32, 5, 5];
        let stamps: Vec<i64> = (0..6).map(|k| 7_000_000_000 + k * period_ns).collect();
        let mover = |k: usize, x: usize, y: usize, z: usize| {
            (k..k + 2).contains(&x) && (1..4).contains(&y) && (1..4).contains(&z)
        };
        let wall = |_: usize, x: usize, y: usize, z: usize| {
            (6..8).contains(&x) && (1..4).contains(&y) && (1..4).contains(&z)
        };
        let asm = |occ: &dyn Fn(usize, usize, usize, usize) -> bool| {
            let fr = frames_of(size, &stamps, occ);
            let mut a = BodyAssembler::new(MesherOptions::default()).unwrap();
            for f in &fr {
                let mut r = test_frame_ref(f, size, 0.05);
                r.origin = origin;
                a.push(&r).unwrap();
            }
            a.finish()
        };
        let (a, b) = (asm(&mover), asm(&wall));
        let (r, lat) = check(&a, &b);
        (r, lat, stamps[0])
    }

    #[test]
    fn far_origins_and_extreme_frame_periods_change_nothing_but_units() {
        let (base, lat0, s0) = moving_pair([0.0; 3], 100_000_000);
        assert!(base.interfering());
        let first = |r: &PairResult, lat: &CommonLattice, s: i64, period: f64| {
            lat.time_s(r.first_contact().unwrap(), s) / period
        };
        let f0 = first(&base, &lat0, s0, 0.1);
        for (origin, period_ns) in [
            ([1e5, -1e5, 1e5], 100_000_000i64),
            ([0.0; 3], 100_000),
            ([0.0; 3], 1_000_000_000_000),
        ] {
            let (r, lat, s) = moving_pair(origin, period_ns);
            assert_eq!(
                r.counts(),
                base.counts(),
                "origin {origin:?}, period {period_ns} ns"
            );
            let f = first(&r, &lat, s, period_ns as f64 * 1e-9);
            assert!(
                (f - f0).abs() < 1e-6,
                "first contact in frames: {f} vs {f0}"
            );
        }
    }

    #[test]
    fn a_body_faster_than_its_thickness_per_frame_is_flagged() {
        // A one-voxel-thick plate jumping 3 voxels per frame: consecutive frames share no
        // voxel, so in 4D it vanishes between frames.
        let size = [16u32, 4, 4];
        let plate = |k: usize, x: usize, _: usize, _: usize| x == 1 + 3 * k;
        let body = assemble(&frames_of(size, &[0, 10, 20, 30], &plate), size);
        assert_eq!(body.stats.vanishing_slabs, 3);
        let slow = |k: usize, x: usize, _: usize, _: usize| x == 1 + k || x == 2 + k;
        let body = assemble(&frames_of(size, &[0, 10, 20, 30], &slow), size);
        assert_eq!(body.stats.vanishing_slabs, 0);
    }
}

#[test]
fn bodies_too_far_apart_for_one_lattice_are_refused_not_wrapped() {
    let size = [4, 4, 4];
    let a = static_body(size, 3, in_box([1, 1, 1], [2, 2, 2]));
    let mut b = a.clone();
    // 1e8 voxels away: on the ×8 checker lattice that exceeds i32.
    let g = b.geometry.as_mut().unwrap();
    g.origin[0] += 1e8 * g.resolution;
    let lat = CommonLattice::of(&[("a", &a), ("b", &b)]).unwrap();
    assert!(lat.prepare("a", &a).is_ok());
    assert!(matches!(
        lat.prepare("b", &b),
        Err(chronotope::checker::CheckError::LatticeMismatch { .. })
    ));
}

mod properties {
    use super::*;
    use proptest::prelude::*;

    const SIZE: [u32; 3] = [5, 5, 4];

    /// A random moving body: occupancy bits per frame.
    fn moving_body() -> impl Strategy<Value = Vec<Vec<bool>>> {
        let n = (SIZE[0] * SIZE[1] * SIZE[2]) as usize;
        prop::collection::vec(prop::collection::vec(prop::bool::weighted(0.35), n), 3)
    }

    fn body_of(frames: &[Vec<bool>]) -> BodyMesh {
        let idx = |x: usize, y: usize, z: usize| x + SIZE[0] as usize * (y + SIZE[1] as usize * z);
        let f: Vec<TestFrame> = frames
            .iter()
            .enumerate()
            .map(|(k, occ)| TestFrame {
                stamp_ns: 1_000_000 * k as i64,
                encoding: 0,
                data: bits_data(SIZE, |x, y, z| occ[idx(x, y, z)]),
            })
            .collect();
        assemble(&f, SIZE)
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

        /// Checking (a, b) and (b, a) gives the same answer, the same intervals and each
        /// body the same labels.
        #[test]
        fn interference_is_symmetric(a in moving_body(), b in moving_body()) {
            let (a, b) = (body_of(&a), body_of(&b));
            prop_assume!(a.stamps_ns.len() >= 2 && b.stamps_ns.len() >= 2);
            let (ab, _) = check(&a, &b);
            let (ba, _) = check(&b, &a);
            prop_assert_eq!(ab.interfering(), ba.interfering());
            prop_assert_eq!(&ab.labels_a.labels, &ba.labels_b.labels);
            prop_assert_eq!(&ab.labels_b.labels, &ba.labels_a.labels);
            prop_assert_eq!(&ab.intervals, &ba.intervals);
            prop_assert_eq!(ab.interfering_pairs, ba.interfering_pairs);
        }

        /// Translating both bodies by one lattice vector changes no label.
        #[test]
        fn a_common_lattice_translation_changes_no_label(
            a in moving_body(),
            b in moving_body(),
            v in prop::array::uniform4(-40i32..40),
        ) {
            let (a, b) = (body_of(&a), body_of(&b));
            prop_assume!(a.stamps_ns.len() >= 2 && b.stamps_ns.len() >= 2);
            let shift = |m: &BodyMesh| {
                let mut m = m.clone();
                m.mesh.translate(v);
                m
            };
            let (r, _) = check(&a, &b);
            let (r2, _) = check(&shift(&a), &shift(&b));
            prop_assert_eq!(&r.labels_a.labels, &r2.labels_a.labels);
            prop_assert_eq!(&r.labels_b.labels, &r2.labels_b.labels);
        }

        /// An independent answer for static bodies: their marching-cubes solids overlap
        /// exactly when the voxel sets share a voxel (bodies in neighbouring voxels meet
        /// only at the midpoint between them: contact, not interference).
        #[test]
        fn static_bodies_interfere_exactly_when_they_share_a_voxel(
            a in moving_body(),
            b in moving_body(),
        ) {
            let (fa, fb) = (vec![a[0].clone(); 2], vec![b[0].clone(); 2]);
            let (ba, bb) = (body_of(&fa), body_of(&fb));
            prop_assume!(ba.mesh.tets.len() > 0 && bb.mesh.tets.len() > 0);
            let shared = a[0].iter().zip(&b[0]).any(|(x, y)| *x && *y);
            let (r, _) = check(&ba, &bb);
            prop_assert_eq!(r.interfering(), shared);
            prop_assert_eq!(r.labels_a.undecided_regions + r.labels_b.undecided_regions, 0);
        }
    }
}

/// Labels of a pair result in each body's own tet order, as bytes.
fn labels_in_body_order(
    r: &PairResult,
    pa: &chronotope::checker::Prepared,
    pb: &chronotope::checker::Prepared,
) -> (Vec<u8>, Vec<u8>) {
    let raw = |l: &chronotope::checker::labels::Labeling| -> Vec<u8> {
        l.labels.iter().map(|&x| x as u8).collect()
    };
    (
        pa.in_original_order(&raw(&r.labels_a)),
        pb.in_original_order(&raw(&r.labels_b)),
    )
}

#[test]
fn preparing_slab_by_slab_as_the_stream_arrives_changes_no_result() {
    use chronotope::checker::prep::BodyPrep;
    // Four spheres meshed frame by frame, each body prepared three ways: fed to a
    // `BodyPrep` after every frame with every pair walked as the pieces come (as the
    // checker node does), from the recorded pieces at once, and as one piece (one tree
    // over the whole body). Every pair must come out the same: interference, intervals,
    // candidate pairs, labels tet by tet.
    let opts = SceneOptions::for_scene(SceneName::FourSpheres)
        .grid(14)
        .frames(15)
        .encoding(VoxelEncoding::Bits);
    let scene = build_scene(SceneName::FourSpheres, &opts).unwrap();
    let topics = scene.topics();
    // Frame k of every body, then frame k + 1, ...; every pair walked as pieces come.
    let n = topics.len();
    let mut asms: Vec<BodyAssembler> = (0..n)
        .map(|_| BodyAssembler::new(MesherOptions::default()).unwrap())
        .collect();
    let mut streamed: Vec<BodyPrep> = (0..n).map(|_| BodyPrep::new()).collect();
    let mut walks: Vec<Vec<StreamWalk>> = (0..n)
        .map(|_| (0..n).map(|_| StreamWalk::new()).collect())
        .collect();
    let advance = |walks: &mut Vec<Vec<StreamWalk>>, preps: &[BodyPrep]| {
        for i in 0..n {
            for j in i + 1..n {
                walks[i][j].advance(&preps[i], &preps[j]);
            }
        }
    };
    for k in 0..scene.frame_count() {
        for b in 0..n {
            asms[b].push(&scene.frame(b, k).frame_ref()).unwrap();
            streamed[b].add(asms[b].mesh()).unwrap();
        }
        advance(&mut walks, &streamed);
    }
    let bodies: Vec<BodyMesh> = asms.into_iter().map(|a| a.finish()).collect();
    for (p, body) in streamed.iter_mut().zip(&bodies) {
        // The last cap arrives at `finish`.
        p.add(&body.mesh).unwrap();
        assert_eq!(p.len(), body.mesh.tets.len());
        assert!(p.pieces() + 1 >= scene.frame_count() as usize);
    }
    advance(&mut walks, &streamed);
    let named: Vec<(&str, &BodyMesh)> = topics.iter().map(|t| t.as_str()).zip(&bodies).collect();
    let lat = CommonLattice::of(&named).unwrap();
    let ways: Vec<Vec<chronotope::checker::Prepared>> = vec![
        streamed
            .into_iter()
            .zip(&named)
            .map(|(p, (id, b))| lat.place_prep(id, b, p).unwrap())
            .collect(),
        named
            .iter()
            .map(|(id, b)| lat.prepare(id, b).unwrap())
            .collect(),
        named
            .iter()
            .map(|(id, b)| {
                lat.place(id, b, BodyPrep::of(&b.mesh, &[]).unwrap())
                    .unwrap()
            })
            .collect(),
    ];
    assert!(named.iter().all(|(_, b)| lat.places_as_is(b)));
    let mut interfering = 0;
    for i in 0..4 {
        for j in i + 1..4 {
            let w = std::mem::take(&mut walks[i][j]);
            // Every tet of both bodies was walked while streaming (no fallback below).
            assert_eq!(
                w.tets(),
                (bodies[i].mesh.tets.len(), bodies[j].mesh.tets.len())
            );
            let mut walked = Some(w);
            let results: Vec<_> = ways
                .iter()
                .map(|p| {
                    // The first way (prepared as streamed) also uses the streamed walk.
                    let r = match walked.take() {
                        Some(w) => check_pair_walked(&p[i], &p[j], w),
                        None => check_pair(&p[i], &p[j]),
                    };
                    let labels = labels_in_body_order(&r, &p[i], &p[j]);
                    (
                        r.interfering(),
                        r.intervals,
                        r.candidate_pairs,
                        r.interfering_pairs,
                        labels,
                    )
                })
                .collect();
            interfering += usize::from(results[0].0);
            assert!(
                results[1..].iter().all(|r| *r == results[0]),
                "pair {i}-{j}"
            );
        }
    }
    assert_eq!(interfering, 3, "A meets B, C and D");
}

#[test]
fn a_body_on_a_shifted_lattice_is_placed_without_changing_its_result() {
    use chronotope::checker::prep::BodyPrep;
    // The same two bodies, once on one grid and once with B on a grid whose origin is 3
    // voxels off and whose frames start 2 periods later (B's occupancy shifted to match):
    // B is then placed by an axis map, and nothing may change.
    let size = [10, 8, 8];
    let a = body_over(size, 0..6, in_box([1, 1, 1], [5, 5, 5]));
    let b = body_over(size, 2..6, in_box([4, 2, 2], [8, 6, 6]));
    let (r, _) = check(&a, &b);
    assert!(r.interfering());
    let shifted = {
        let f: Vec<TestFrame> = (2..6)
            .map(|k| TestFrame {
                stamp_ns: 1_000_000 * k as i64,
                encoding: 0,
                data: bits_data(size, in_box([1, 2, 2], [5, 6, 6])),
            })
            .collect();
        let mut asm = BodyAssembler::new(MesherOptions::default()).unwrap();
        for x in &f {
            let mut fr = test_frame_ref(x, size, 0.1);
            fr.origin[0] += 0.3;
            asm.push(&fr).unwrap();
        }
        asm.finish()
    };
    let lat = CommonLattice::of(&[("a", &a), ("b", &shifted)]).unwrap();
    let pa = lat.prepare("a", &a).unwrap();
    let pb = lat
        .place(
            "b",
            &shifted,
            BodyPrep::of(&shifted.mesh, &shifted.pieces).unwrap(),
        )
        .unwrap();
    let s = check_pair(&pa, &pb);
    assert_eq!(s.intervals, r.intervals);
    assert_eq!(s.counts(), r.counts());
    assert_eq!(s.candidate_pairs, r.candidate_pairs);
}
