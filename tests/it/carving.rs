//! The carving model (crates/carving): sweeps against the exact swept solid, the workpiece's
//! invariants, stiff and extreme cases, forces, cut-outs and images. Small grids only.

use chronotope::carving::cutout::{Axis, BinaryImage, ImageError};
use chronotope::carving::exact::BoxSweep;
use chronotope::carving::{
    CarveError, Flag, ForceModel, ForceParams, ForceRenderer, Quat, Tool, ToolPose, Workpiece,
};

const H: f64 = 0.001;

fn block(n: [usize; 3]) -> Workpiece {
    Workpiece::block([0.0; 3], n.map(|v| v as f64 * H), H).unwrap()
}

fn pose(p: [f64; 3], q: Quat) -> ToolPose {
    ToolPose {
        position: p,
        rotation: q,
    }
}

/// A small deterministic generator (xorshift).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn quat(&mut self) -> Quat {
        let axis = [self.next() - 0.5, self.next() - 0.5, self.next() - 0.5];
        Quat::from_axis_angle(axis, self.next() * 3.0)
    }
}

fn half_extents(tool: &Tool) -> [f64; 3] {
    let mut e = [0.0f64; 3];
    for v in tool.vertices() {
        for a in 0..3 {
            e[a] = e[a].max(v[a].abs());
        }
    }
    e
}

fn material(w: &Workpiece) -> Vec<bool> {
    (0..w.dims().iter().product::<usize>())
        .map(|i| w.flag(i) != Flag::Outside)
        .collect()
}

#[test]
fn a_block_has_surfels_on_its_faces_only() {
    let w = block([10, 8, 6]);
    w.validate().unwrap();
    let inner = 8 * 6 * 4;
    assert_eq!(w.surfels().len(), 10 * 8 * 6 - inner);
    assert_eq!(w.material_points(), 480);
    // Face surfels lie on the true faces.
    for s in w.surfels() {
        let p = s.position.map(f64::from);
        let on_face =
            (0..3).any(|a| p[a].abs() < 1e-9 || (p[a] - [0.01, 0.008, 0.006][a]).abs() < 1e-9);
        assert!(on_face, "{p:?}");
    }
    assert!(
        Workpiece::block([0.0; 3], [1.0, 1.0, 1.0], 1e-4).is_err(),
        "too many points"
    );
    assert!(Workpiece::block([0.0; 3], [1.0, 1.0, f64::NAN], 1e-2).is_err());
    assert!(Workpiece::block([0.0; 3], [1.0, 1.0, 1.0], 0.0).is_err());
}

#[test]
fn a_translation_removes_exactly_the_points_of_the_exact_sweep() {
    let mut rng = Rng(0x9e3779b97f4a7c15);
    for case in 0..12 {
        let mut w = block([24, 24, 24]);
        let tool = Tool::knife(
            0.004 + 0.006 * rng.next(),
            0.003 + 0.004 * rng.next(),
            0.0015,
            H,
        )
        .unwrap();
        let q = rng.quat();
        let a = [
            0.004 + 0.016 * rng.next(),
            0.004 + 0.016 * rng.next(),
            0.004 + 0.016 * rng.next(),
        ];
        let b = [
            0.004 + 0.016 * rng.next(),
            0.004 + 0.016 * rng.next(),
            0.004 + 0.016 * rng.next(),
        ];
        let before = material(&w);
        let cut = w.carve(&tool, &pose(a, q), &pose(b, q)).unwrap();
        w.validate().unwrap();
        let exact = BoxSweep {
            c0: a,
            rotation: q,
            half: half_extents(&tool),
            d: [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
        };
        let after = material(&w);
        let mut expected = 0;
        for idx in 0..after.len() {
            let c = w.coords(idx);
            let p = w.point(c[0], c[1], c[2]);
            let sd = exact.signed_distance(p);
            if sd < -1e-9 {
                assert!(
                    !after[idx],
                    "case {case}: {p:?} is {sd} inside the sweep but kept"
                );
            }
            if sd > 1e-9 {
                assert_eq!(
                    after[idx], before[idx],
                    "case {case}: {p:?} is {sd} outside but removed"
                );
            }
            if before[idx] && !after[idx] {
                expected += 1;
            }
        }
        assert_eq!(cut.removed, expected);
        assert!(cut.removed > 0, "case {case} cut nothing");
    }
}

#[test]
fn a_diagonal_move_removes_the_sweep_not_the_box_around_both_poses() {
    // docs/methods/carving.md#box-between-poses: a cube moving diagonally; the box between
    // the frames would remove far more.
    let mut w = block([48, 48, 16]);
    let tool = Tool::knife(0.004, 0.004, 0.004, H).unwrap();
    // Off the lattice's diagonals, so that no sweep edge runs through grid points.
    let (a, b) = ([0.0083, 0.0081, 0.008], [0.0403, 0.0401, 0.008]);
    let cut = w
        .carve(&tool, &pose(a, Quat::IDENTITY), &pose(b, Quat::IDENTITY))
        .unwrap();
    // Sweep of a 4 mm cube along a 45° diagonal: the cube's shadow across the move
    // (4√2 x 4 mm) times the length 32√2 mm, plus the cube: 1024 + 64 = 1088 mm^3.
    let box_between = 36.0 * 36.0 * 4.0;
    assert!(
        (cut.removed as f64 - 1088.0).abs() < 60.0,
        "{}",
        cut.removed
    );
    assert!((cut.removed as f64) < box_between / 4.0);
}

#[test]
fn one_jump_of_40_spacings_equals_40_steps_of_one() {
    let tool = Tool::knife(0.006, 0.004, 0.002, H).unwrap();
    let q = Quat::from_axis_angle([1.0, 2.0, 3.0], 0.7);
    let (a, b) = ([0.005, 0.006, 0.012], [0.037, 0.030, 0.012]);
    let mut one = block([44, 36, 16]);
    one.carve(&tool, &pose(a, q), &pose(b, q)).unwrap();
    let mut many = block([44, 36, 16]);
    let mut prev = pose(a, q);
    for k in 1..=40 {
        let t = k as f64 / 40.0;
        let next = pose([0, 1, 2].map(|i| a[i] + (b[i] - a[i]) * t), q);
        many.carve(&tool, &prev, &next).unwrap();
        prev = next;
    }
    let (m1, m2) = (material(&one), material(&many));
    let differ = m1.iter().zip(&m2).filter(|(x, y)| x != y).count();
    assert!(differ <= 2, "{differ} points differ");
    one.validate().unwrap();
    many.validate().unwrap();
}

#[test]
fn a_rotating_move_skips_no_point() {
    let mut w = block([32, 32, 24]);
    let tool = Tool::knife(0.012, 0.006, 0.002, H).unwrap();
    let (qa, qb) = (Quat::IDENTITY, Quat::from_axis_angle([0.0, 0.0, 1.0], 1.5));
    let (a, b) = ([0.012, 0.014, 0.020], [0.020, 0.018, 0.018]);
    let cut = w.carve(&tool, &pose(a, qa), &pose(b, qb)).unwrap();
    assert!(cut.substeps > 10, "{}", cut.substeps);
    w.validate().unwrap();
    // Reference: 120 fine translation sweeps (each within 0.05 mm of the rotating tool).
    let half = half_extents(&tool);
    let pieces: Vec<BoxSweep> = (0..120)
        .map(|j| {
            let (s, t) = (j as f64 / 120.0, (j + 1) as f64 / 120.0);
            let p = |u: f64| [0, 1, 2].map(|i| a[i] + (b[i] - a[i]) * u);
            let (pa, pb) = (p(s), p(t));
            BoxSweep {
                c0: pa,
                rotation: qa.slerp(&qb, (s + t) / 2.0),
                half,
                d: [0, 1, 2].map(|i| pb[i] - pa[i]),
            }
        })
        .collect();
    let tol = H / 2.0 - 0.05e-3;
    let reach = tool.radius() + H;
    for idx in 0..w.dims().iter().product::<usize>() {
        let c = w.coords(idx);
        let p = w.point(c[0], c[1], c[2]);
        let near: Vec<&BoxSweep> = pieces
            .iter()
            .filter(|s| {
                (0..3).map(|i| (p[i] - s.c0[i]).powi(2)).sum::<f64>().sqrt() < reach + 0.001
            })
            .collect();
        let removed = w.flag(idx) == Flag::Outside;
        if removed {
            let close = near
                .iter()
                .any(|s| s.contains(p) || s.signed_distance(p) <= tol);
            assert!(close, "{p:?} removed but more than {tol} outside the sweep");
        } else {
            for s in near.iter().filter(|s| s.contains(p)) {
                let sd = s.signed_distance(p);
                assert!(sd >= -tol, "{p:?} is {sd} deep in the sweep but kept");
            }
        }
    }
}

#[test]
fn extreme_moves_tool_outside_and_everything_cut_away() {
    let mut w = block([16, 16, 16]);
    let tool = Tool::knife(0.004, 0.004, 0.002, H).unwrap();
    let surfels = w.surfels().len();
    let out = pose([0.1, 0.1, 0.1], Quat::IDENTITY);
    let cut = w
        .carve(&tool, &out, &pose([0.2, 0.1, 0.1], Quat::IDENTITY))
        .unwrap();
    assert_eq!(cut.removed, 0);
    assert_eq!(w.surfels().len(), surfels);
    assert_eq!(w.material_points(), 16 * 16 * 16);
    // A blade bigger than the block sweeping through it.
    let big = Tool::knife(0.05, 0.05, 0.002, H).unwrap();
    let cut = w
        .carve(
            &big,
            &pose([0.008, 0.008, -0.01], Quat::IDENTITY),
            &pose([0.008, 0.008, 0.03], Quat::IDENTITY),
        )
        .unwrap();
    assert_eq!(cut.removed, 16 * 16 * 16);
    assert_eq!(w.material_points(), 0);
    assert!(w.surfels().is_empty());
    w.validate().unwrap();
    // A half-turn in one step of a long tool: substeps bounded, or refused with a reason.
    let long = Tool::knife(5.0, 5.0, 0.002, H).unwrap();
    let e = w
        .carve(
            &long,
            &pose([0.0; 3], Quat::IDENTITY),
            &pose([0.0; 3], Quat::from_axis_angle([0.0, 0.0, 1.0], 3.0)),
        )
        .unwrap_err();
    assert!(matches!(e, CarveError::TooManySubsteps { .. }), "{e}");
}

#[test]
fn repeated_cuts_in_one_place_do_not_grow_the_surfels() {
    let mut w = block([24, 24, 16]);
    let tool = Tool::knife(0.008, 0.006, 0.002, H).unwrap();
    let q = Quat::from_axis_angle([0.0, 1.0, 0.0], std::f64::consts::FRAC_PI_2);
    let (a, b) = (
        pose([0.004, 0.012, 0.018], q),
        pose([0.020, 0.012, 0.018], q),
    );
    w.carve(&tool, &a, &b).unwrap();
    w.carve(&tool, &b, &a).unwrap();
    let (n, m) = (w.surfels().len(), w.material_points());
    for _ in 0..100 {
        w.carve(&tool, &a, &b).unwrap();
        w.carve(&tool, &b, &a).unwrap();
    }
    assert_eq!(w.surfels().len(), n);
    assert_eq!(w.material_points(), m);
    w.validate().unwrap();
    // Every surfel belongs to a distinct BOUND point.
    let bound = (0..24 * 24 * 16)
        .filter(|&i| w.flag(i) == Flag::Bound)
        .count();
    assert_eq!(bound, w.surfels().len());
}

#[test]
fn a_blade_thinner_than_the_spacing_is_thickened_and_says_so() {
    let thin = Tool::knife(0.008, 0.006, 0.0002, H).unwrap();
    assert_eq!(thin.thickened(), Some(0.0002));
    assert_eq!(thin.cut_thickness(), H);
    let thick = Tool::knife(0.008, 0.006, 0.003, H).unwrap();
    assert_eq!(thick.thickened(), None);
    // Moving within its own plane (edge first), it still cuts a kerf.
    let mut w = block([24, 24, 16]);
    let cut = w
        // The 0.2 mm blade spans z 12.1..12.3 mm, between grid layers (12.5 mm is the next).
        .carve(
            &thin,
            &pose([0.0, 0.012, 0.0122], Quat::IDENTITY),
            &pose([0.024, 0.012, 0.0122], Quat::IDENTITY),
        )
        .unwrap();
    assert!(cut.removed > 0);
    w.validate().unwrap();
}

#[test]
fn surfels_of_a_cut_lie_on_the_cut_face_and_face_away_from_the_material() {
    let mut w = block([24, 24, 16]);
    // A knife lying flat (normal z) lowered 3.4 mm into the top, then moved along x.
    let tool = Tool::knife(0.008, 0.008, 0.002, H).unwrap();
    let z = 0.016 + 0.001 - 0.0034;
    w.carve(
        &tool,
        &pose([0.006, 0.012, z], Quat::IDENTITY),
        &pose([0.018, 0.012, z], Quat::IDENTITY),
    )
    .unwrap();
    w.validate().unwrap();
    // The slab-shaped blade slices a slot: a floor at z - 1 mm facing up, a ceiling at
    // z + 1 mm facing down (the material above the blade stays).
    let (floor, ceiling) = (z - 0.001, z + 0.001);
    let (mut n, mut m) = (0, 0);
    for s in w.surfels() {
        let p = s.position.map(f64::from);
        if p[0] > 0.004
            && p[0] < 0.020
            && p[1] > 0.010
            && p[1] < 0.014
            && p[2] > 0.001
            && p[2] < 0.0155
        {
            if p[2] < z {
                assert!(
                    (p[2] - floor).abs() < 1e-6,
                    "{p:?} not on the floor at {floor}"
                );
                assert!(s.normal[2] > 0.99, "{:?}", s.normal);
                n += 1;
            } else {
                assert!(
                    (p[2] - ceiling).abs() < 1e-6,
                    "{p:?} not on the ceiling at {ceiling}"
                );
                assert!(s.normal[2] < -0.99, "{:?}", s.normal);
                m += 1;
            }
        }
    }
    assert!(m > 10, "{m} ceiling surfels");
    assert!(n > 10, "{n} floor surfels");
}

#[test]
fn the_chisel_cuts_a_v_groove_and_resamples_its_edges() {
    let mut w = block([32, 16, 12]);
    let tool = Tool::chisel(0.006, 0.003, 0.001, H).unwrap();
    // Apex 2.3 mm below the top (z = 12 mm), moving along x.
    let z = 0.012 - 0.0023;
    let mut prev = pose([0.002, 0.008, z], Quat::IDENTITY);
    let mut resampled = 0;
    let mut removed = 0;
    for k in 1..=40 {
        let next = pose([0.002 + 0.0007 * k as f64, 0.008, z], Quat::IDENTITY);
        let c = w.carve(&tool, &prev, &next).unwrap();
        resampled += c.resampled;
        removed += c.removed;
        prev = next;
    }
    w.validate().unwrap();
    assert!(removed > 50, "{removed}");
    assert!(resampled > 0, "no edge was resampled");
    // Removed points lie in the V: |y - 8 mm| <= (z - apex) * (w/2) / height, within a spacing.
    for idx in 0..32 * 16 * 12 {
        if w.flag(idx) == Flag::Outside {
            let c = w.coords(idx);
            let p = w.point(c[0], c[1], c[2]);
            assert!(p[2] >= z - 1e-9, "{p:?} below the apex");
            assert!(
                (p[1] - 0.008).abs() <= (p[2] - z) + 1e-9,
                "{p:?} outside the V"
            );
        }
    }
    // Edge surfels sit on the old top face at the groove's edge.
    let red: Vec<_> = w
        .surfels()
        .iter()
        .filter(|s| s.colour == 0xd02020)
        .collect();
    assert!(!red.is_empty());
    for s in red {
        assert!(
            (f64::from(s.position[2]) - 0.012).abs() < 1e-5,
            "{:?}",
            s.position
        );
    }
}

#[test]
fn poses_are_checked() {
    assert!(ToolPose::new([f64::NAN, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]).is_err());
    assert!(ToolPose::new([0.0, f64::INFINITY, 0.0], [0.0, 0.0, 0.0, 1.0]).is_err());
    assert!(ToolPose::new([0.0; 3], [0.0, 0.0, 0.0, 0.0]).is_err());
    assert!(ToolPose::new([0.0; 3], [f64::NAN, 0.0, 0.0, 1.0]).is_err());
    let p = ToolPose::new([0.0; 3], [0.0, 0.0, 0.0, 2.0]).unwrap();
    assert_eq!(p.rotation, Quat::IDENTITY);
    assert!("gouge".parse::<chronotope::carving::ToolKind>().is_err());
    assert!(Tool::knife(f64::NAN, 0.01, 0.0, H).is_err());
    assert!(Tool::chisel(0.01, -1.0, 0.0, H).is_err());
}

/// A steady cut's mean rendered force (N) at spacing `h` and pose period `dt`.
fn steady_force(h: f64, dt: f64, model: ForceModel) -> f64 {
    let mut w = Workpiece::block([0.0; 3], [0.04, 0.012, 0.012], h).unwrap();
    let tool = Tool::knife(0.008, 0.006, 0.002, h).unwrap();
    let mut f = ForceRenderer::new(ForceParams {
        model,
        ..ForceParams::default()
    });
    let q = Quat::from_axis_angle([0.0, 1.0, 0.0], std::f64::consts::FRAC_PI_2);
    let z = 0.012 + 0.004 - 0.003;
    let v = 0.05;
    let mut prev = pose([0.004, 0.006, z], q);
    let steps = (0.4 / dt) as usize;
    let (mut sum, mut n) = (0.0, 0);
    for k in 1..=steps {
        let next = pose([prev.position[0] + v * dt, 0.006, z], q);
        let cut = w.carve(&tool, &prev, &next).unwrap();
        let out = f.step(&cut, h, [v * dt, 0.0, 0.0], dt);
        if k * 2 > steps {
            sum += (out[0] * out[0] + out[1] * out[1] + out[2] * out[2]).sqrt();
            n += 1;
        }
        prev = next;
    }
    sum / n as f64
}

#[test]
fn the_volume_force_is_rate_and_resolution_independent_and_the_count_force_is_not() {
    for model in [ForceModel::Volume, ForceModel::Section] {
        let base = steady_force(1e-3, 1e-3, model);
        // Cross-section 3 mm x 6 mm = 18 mm^2 at 2e5 N/m^2 = 3.6 N.
        assert!((base - 3.6).abs() < 0.5, "{model:?}: {base}");
        let slow = steady_force(1e-3, 2e-3, model);
        let fine = steady_force(0.5e-3, 1e-3, model);
        assert!(
            (slow / base - 1.0).abs() < 0.1,
            "{model:?}: {slow} vs {base}"
        );
        assert!(
            (fine / base - 1.0).abs() < 0.15,
            "{model:?}: {fine} vs {base}"
        );
    }
    let c1 = steady_force(1e-3, 1e-3, ForceModel::Count);
    let c2 = steady_force(1e-3, 2e-3, ForceModel::Count);
    assert!(
        c2 / c1 > 1.6,
        "eq. 8 should double with the pose period: {c1} {c2}"
    );
}

fn pgm_circle(n: usize) -> String {
    let mut s = format!("P2\n# a disc\n{n} {n}\n255\n");
    for r in 0..n {
        for c in 0..n {
            let (x, y) = (
                c as f64 + 0.5 - n as f64 / 2.0,
                r as f64 + 0.5 - n as f64 / 2.0,
            );
            let black = x * x + y * y < (n as f64 * 0.4).powi(2);
            s.push_str(if black { "0 " } else { "255 " });
        }
        s.push('\n');
    }
    s
}

#[test]
fn a_cut_out_keeps_the_black_shape_with_side_surfels() {
    let img = BinaryImage::from_pgm(pgm_circle(40).as_bytes()).unwrap();
    assert_eq!((img.width, img.height), (40, 40));
    let mut w = block([20, 20, 10]);
    let s = w.cut_out(&img, Axis::Z);
    w.validate().unwrap();
    // A disc of radius 0.4 of the side: π 0.16 of the area kept.
    let kept = w.material_points() as f64 / (20.0 * 20.0 * 10.0);
    assert!((kept - std::f64::consts::PI * 0.16).abs() < 0.05, "{kept}");
    assert!(s.exposed > 0);
    // Side surfels face outward in the x-y plane.
    let mut sides = 0;
    for sf in w.surfels() {
        if sf.colour == 0xb89060 {
            let (x, y) = (
                f64::from(sf.position[0]) - 0.01,
                f64::from(sf.position[1]) - 0.01,
            );
            let out = x * f64::from(sf.normal[0]) + y * f64::from(sf.normal[1]);
            assert!(out > 0.0, "{:?} {:?}", sf.position, sf.normal);
            sides += 1;
        }
    }
    assert!(sides > 20);
    // A second cut-out along another axis (seed Fig. 4).
    let before = w.material_points();
    w.cut_out(&img, Axis::Y);
    w.validate().unwrap();
    assert!(w.material_points() < before);
}

#[test]
fn bad_images_are_typed_errors() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("none.pgm");
    assert!(matches!(
        BinaryImage::load(&missing),
        Err(ImageError::Io { .. })
    ));
    for (name, bytes) in [
        ("garbage.pgm", b"hello world".to_vec()),
        ("truncated.pgm", b"P5 4 4 255\n\x00\x00".to_vec()),
        ("huge.pgm", b"P2 100000 100000 255\n0".to_vec()),
        ("badmax.pgm", b"P2 1 1 0\n0".to_vec()),
        ("bad.png", b"\x89PNG\r\n\x1a\nnot really".to_vec()),
    ] {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        let e = BinaryImage::load(&p).unwrap_err();
        assert!(matches!(e, ImageError::Format { .. }), "{name}: {e}");
        assert!(e.to_string().contains(name), "{e}");
    }
    // A binary P5 reads.
    let p = dir.path().join("ok.pgm");
    std::fs::write(&p, b"P5\n2 1\n255\n\x00\xff").unwrap();
    let img = BinaryImage::load(&p).unwrap();
    assert!(img.is_black(0, 0) && !img.is_black(1, 0));
}
