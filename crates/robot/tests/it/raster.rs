//! Rasterisation: percent against exact volumes, bits conservative (and tight) on random
//! poses, unions, bodies, open meshes and the VoxelGrid layout.

use super::common::{collision, one_link, robot};
use chronotope_robot::raster::{bit_at, MARGIN};
use chronotope_robot::{BasePose, Encoding, Lattice, LinkPoses, RasterOptions, Rasterizer, Robot};
use nalgebra::{Matrix3, Vector3};
use proptest::prelude::*;

const H: f64 = 0.05;

fn lattice() -> Lattice {
    Lattice::new([-0.5, -0.5, -0.5], H, [20, 20, 20]).unwrap()
}

fn frame(robot: &Robot, lattice: Lattice, encoding: Encoding, k: u32, base: BasePose) -> Vec<u8> {
    let mut poses = LinkPoses::new();
    let q = vec![0.0; robot.kinematics().dof()];
    robot.kinematics().forward(&q, &base, &mut poses);
    let mut r = Rasterizer::new(lattice, encoding, RasterOptions::default().subsamples(k));
    r.rasterize(robot, &robot.whole_body(), &poses);
    r.data().to_vec()
}

fn volume(percent: &[u8], h: f64) -> f64 {
    percent.iter().map(|&p| f64::from(p)).sum::<f64>() / 100.0 * h * h * h
}

fn overlap(a0: f64, a1: f64, b0: f64, b1: f64) -> f64 {
    (a1.min(b1) - a0.max(b0)).max(0.0)
}

/// Exact per-voxel percent of an axis-aligned box, and how many of its y and z faces cross
/// the voxel's yz square (each costs at most 1/K of the voxel: K sub-squares of 1/K²).
fn aligned_box_check(centre: [f64; 3], size: [f64; 3], k: u32) {
    let r = robot(&one_link(&collision(
        centre,
        [0.0; 3],
        &format!(r#"<box size="{} {} {}"/>"#, size[0], size[1], size[2]),
    )));
    let l = lattice();
    let data = frame(&r, l, Encoding::Percent, k, BasePose::IDENTITY);
    let lo: Vec<f64> = (0..3).map(|a| centre[a] - size[a] / 2.0).collect();
    let hi: Vec<f64> = (0..3).map(|a| centre[a] + size[a] / 2.0).collect();
    let o = l.origin();
    let mut worst = 0.0f64;
    for kz in 0..20u32 {
        for j in 0..20u32 {
            for i in 0..20u32 {
                let c0 = [i, j, kz].map(|v| f64::from(v) * H);
                let mut frac = 1.0;
                let mut faces = 0;
                for a in 0..3 {
                    let (v0, v1) = (o[a] + c0[a], o[a] + c0[a] + H);
                    frac *= overlap(v0, v1, lo[a], hi[a]) / H;
                    if a > 0 {
                        faces += [lo[a], hi[a]].iter().filter(|&&f| f > v0 && f < v1).count();
                    }
                }
                let got = f64::from(data[l.index(i, j, kz)]);
                let bound = 100.0 * faces as f64 / f64::from(k) + 0.5 + 1e-3;
                let err = (got - 100.0 * frac).abs();
                worst = worst.max(err - bound);
                assert!(
                    err <= bound,
                    "voxel ({i},{j},{kz}): {got} vs {} (bound {bound})",
                    100.0 * frac
                );
            }
        }
    }
    let _ = worst;
}

#[test]
fn an_aligned_box_is_exact_when_its_faces_fall_between_sub_rows() {
    // K = 4 sub-rows at 1/8, 3/8, 5/8, 7/8 of a voxel: faces at quarter voxels fall between.
    let q = H / 4.0;
    aligned_box_check([0.013, 2.0 * q, -q], [0.2, 12.0 * q, 14.0 * q], 4);
}

#[test]
fn an_aligned_box_is_within_its_bound_anywhere() {
    aligned_box_check([0.0123, -0.0371, 0.0519], [0.31, 0.173, 0.2281], 4);
    aligned_box_check([0.0123, -0.0371, 0.0519], [0.31, 0.173, 0.2281], 16);
}

/// (solid as URDF geometry, exact volume)
fn solids() -> Vec<(String, f64)> {
    let pi = std::f64::consts::PI;
    vec![
        (r#"<box size="0.31 0.17 0.23"/>"#.into(), 0.31 * 0.17 * 0.23),
        (
            r#"<sphere radius="0.17"/>"#.into(),
            4.0 / 3.0 * pi * 0.17f64.powi(3),
        ),
        (
            r#"<cylinder radius="0.12" length="0.33"/>"#.into(),
            pi * 0.12 * 0.12 * 0.33,
        ),
    ]
}

#[test]
fn rotated_solids_have_their_exact_volume_within_half_a_percent() {
    // (Axis-aligned faces are checked voxel by voxel above: the midpoint rule across y and z
    // can shift such a face by up to half a sub-row, which no rotation averages out.)
    for (geometry, exact) in solids() {
        for (xyz, rpy) in [
            ([0.01, -0.02, 0.03], [0.3, -0.5, 0.9]),
            ([0.0; 3], [0.2, 0.1, 0.4]),
            ([-0.07, 0.05, 0.011], [1.2, 0.7, -2.0]),
        ] {
            let r = robot(&one_link(&collision(xyz, rpy, &geometry)));
            let v = volume(
                &frame(&r, lattice(), Encoding::Percent, 4, BasePose::IDENTITY),
                H,
            );
            let rel = (v - exact).abs() / exact;
            assert!(
                rel < 0.005,
                "{geometry} at {xyz:?} {rpy:?}: {v} vs {exact} ({rel:.4})"
            );
        }
    }
}

#[test]
fn overlapping_solids_count_once() {
    let geometry = format!(
        "{}{}",
        collision([0.0; 3], [0.0; 3], r#"<box size="0.3 0.3 0.3"/>"#),
        collision([0.1, 0.0, 0.0], [0.0; 3], r#"<box size="0.3 0.3 0.3"/>"#)
    );
    let r = robot(&one_link(&geometry));
    let v = volume(
        &frame(&r, lattice(), Encoding::Percent, 4, BasePose::IDENTITY),
        H,
    );
    let exact = 0.4 * 0.3 * 0.3;
    assert!((v - exact).abs() / exact < 1e-3, "{v} vs {exact}");
}

#[test]
fn the_data_follow_voxelgrid_layout() {
    let l = Lattice::new([0.0; 3], 1.0, [5, 4, 3]).unwrap();
    let r = robot(&one_link(&collision(
        [3.5, 1.5, 2.5],
        [0.0; 3],
        r#"<sphere radius="0.2"/>"#,
    )));
    let bits = frame(&r, l, Encoding::Bits, 4, BasePose::IDENTITY);
    assert_eq!(bits.len(), 60usize.div_ceil(8));
    let index = 3 + 5 * (1 + 4 * 2);
    assert_eq!(l.index(3, 1, 2), index);
    for v in 0..60 {
        assert_eq!(bit_at(&bits, v), v == index, "voxel {v}");
    }
    assert_eq!(bits[index / 8], 1 << (index % 8));
    let percent = frame(&r, l, Encoding::Percent, 16, BasePose::IDENTITY);
    assert_eq!(percent.len(), 60);
    let exact = 4.0 / 3.0 * std::f64::consts::PI * 0.008 * 100.0;
    assert!(
        (f64::from(percent[index]) - exact).abs() <= 1.0,
        "{} vs {exact}",
        percent[index]
    );
    assert_eq!(percent.iter().filter(|&&p| p > 0).count(), 1);
    // A voxel wholly inside reads exactly 100.
    let r = robot(&one_link(&collision(
        [2.5, 2.0, 1.5],
        [0.1, 0.2, 0.3],
        r#"<sphere radius="1.4"/>"#,
    )));
    assert_eq!(
        frame(&r, l, Encoding::Percent, 4, BasePose::IDENTITY)[l.index(2, 1, 1)],
        100
    );
}

/// Rotation of a base pose, written out.
fn rot(b: &BasePose) -> Matrix3<f64> {
    let (sr, cr) = b.roll.sin_cos();
    let (sp, cp) = b.pitch.sin_cos();
    let (sy, cy) = b.yaw.sin_cos();
    Matrix3::new(cy, -sy, 0.0, sy, cy, 0.0, 0.0, 0.0, 1.0)
        * Matrix3::new(cp, 0.0, sp, 0.0, 1.0, 0.0, -sp, 0.0, cp)
        * Matrix3::new(1.0, 0.0, 0.0, 0.0, cr, -sr, 0.0, sr, cr)
}

/// Points of the solid (in its frame): inside and on its surface.
fn solid_points(kind: usize, dims: [f64; 3], u: &[[f64; 3]]) -> Vec<Vector3<f64>> {
    u.iter()
        .enumerate()
        .map(|(n, s)| {
            let on_surface = n % 2 == 0;
            match kind {
                0 => {
                    let mut p = Vector3::new(
                        (s[0] - 0.5) * dims[0],
                        (s[1] - 0.5) * dims[1],
                        (s[2] - 0.5) * dims[2],
                    );
                    if on_surface {
                        let a = n / 2 % 3;
                        p[a] = if s[a] < 0.5 {
                            -0.5 * dims[a]
                        } else {
                            0.5 * dims[a]
                        };
                    }
                    p
                }
                1 => {
                    let dir = Vector3::new(s[0] - 0.5, s[1] - 0.5, s[2] - 0.5 + 1e-9).normalize();
                    dir * dims[0] * if on_surface { 1.0 } else { s[0].cbrt() }
                }
                _ => {
                    let a = 2.0 * std::f64::consts::PI * s[0];
                    let rr = dims[0]
                        * if on_surface && n % 4 == 0 {
                            1.0
                        } else {
                            s[1].sqrt()
                        };
                    let z = if on_surface && n % 4 == 2 {
                        (s[2].round() - 0.5) * dims[1]
                    } else {
                        (s[2] - 0.5) * dims[1]
                    };
                    Vector3::new(rr * a.cos(), rr * a.sin(), z)
                }
            }
        })
        .collect()
}

fn geometry_of(kind: usize, dims: [f64; 3]) -> String {
    match kind {
        0 => format!(r#"<box size="{} {} {}"/>"#, dims[0], dims[1], dims[2]),
        1 => format!(r#"<sphere radius="{}"/>"#, dims[0]),
        _ => format!(r#"<cylinder radius="{}" length="{}"/>"#, dims[0], dims[1]),
    }
}

/// Whether the closed voxel cube (lattice frame) meets the solid, exactly, for a box
/// (separating axes) or a sphere; grown by `grow` metres.
fn cube_meets(
    kind: usize,
    dims: [f64; 3],
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
    lo: Vector3<f64>,
    grow: f64,
) -> bool {
    let c = lo + Vector3::repeat(H / 2.0);
    let e = Vector3::repeat(H / 2.0);
    if kind == 1 {
        let d = (t - c).abs() - e;
        let d = Vector3::new(d.x.max(0.0), d.y.max(0.0), d.z.max(0.0));
        return d.norm() <= dims[0] + grow;
    }
    let half = Vector3::new(dims[0], dims[1], dims[2]) / 2.0;
    let mut axes: Vec<Vector3<f64>> = (0..3).map(|i| Vector3::ith(i, 1.0)).collect();
    axes.extend((0..3).map(|i| r.column(i).into_owned()));
    for i in 0..3 {
        for j in 0..3 {
            let a = Vector3::<f64>::ith(i, 1.0).cross(&r.column(j));
            if a.norm() > 1e-9 {
                axes.push(a.normalize());
            }
        }
    }
    axes.iter().all(|a| {
        let ra = e.x * a.x.abs() + e.y * a.y.abs() + e.z * a.z.abs();
        let rb: f64 = (0..3).map(|k| half[k] * a.dot(&r.column(k)).abs()).sum();
        (a.dot(&(t - c))).abs() <= ra + rb + grow * (a.x.abs() + a.y.abs() + a.z.abs()).max(1.0)
    })
}

fn arb_pose() -> impl Strategy<Value = BasePose> {
    (
        -0.2..0.2f64,
        -0.2..0.2f64,
        -0.2..0.2f64,
        -3.2..3.2f64,
        -1.6..1.6f64,
        -3.2..3.2f64,
    )
        .prop_map(|(x, y, z, roll, pitch, yaw)| BasePose {
            x,
            y,
            z,
            roll,
            pitch,
            yaw,
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn bits_are_conservative_and_tight_for_primitives(
        kind in 0usize..3,
        dims in (0.01..0.4f64, 0.01..0.4f64, 0.01..0.4f64),
        base in arb_pose(),
        u in prop::collection::vec((0.0..1.0f64, 0.0..1.0f64, 0.0..1.0f64), 400),
    ) {
        let dims = [dims.0, dims.1, dims.2];
        let r = robot(&one_link(&collision([0.0; 3], [0.0; 3], &geometry_of(kind, dims))));
        let l = lattice();
        let bits = frame(&r, l, Encoding::Bits, 4, base);
        let percent = frame(&r, l, Encoding::Percent, 4, base);
        let rm = rot(&base);
        let t = Vector3::new(base.x, base.y, base.z);
        let u: Vec<[f64; 3]> = u.iter().map(|&(a, b, c)| [a, b, c]).collect();
        for p in solid_points(kind, dims, &u) {
            let w = rm * p + t;
            let ijk = (w - Vector3::from(l.origin())) / H;
            let (i, j, k) = (ijk.x.floor(), ijk.y.floor(), ijk.z.floor());
            if i < 0.0 || j < 0.0 || k < 0.0 || i >= 20.0 || j >= 20.0 || k >= 20.0 {
                continue;
            }
            let v = l.index(i as u32, j as u32, k as u32);
            prop_assert!(bit_at(&bits, v), "point {w:?} of the solid lies in empty voxel ({i},{j},{k})");
        }
        for (v, &p) in percent.iter().enumerate() {
            if p > 0 {
                prop_assert!(bit_at(&bits, v), "percent {} where bits is 0", p);
            }
            if kind != 2 && bit_at(&bits, v) {
                let (i, j, k) = (v % 20, v / 20 % 20, v / 400);
                let lo = Vector3::from(l.origin()) + Vector3::new(i as f64, j as f64, k as f64) * H;
                prop_assert!(cube_meets(kind, dims, &rm, &t, lo, 2.0 * MARGIN * H), "voxel ({i},{j},{k}) set but apart from the solid");
            }
        }
    }
}

#[test]
fn bodies_rasterise_their_links_and_bits_of_a_union_are_the_or() {
    let text = r#"<robot name="r">
  <link name="arm"><collision><origin xyz="0.1 0 0"/><geometry><box size="0.3 0.1 0.1"/></geometry></collision></link>
  <link name="tool"><collision><geometry><cylinder radius="0.05" length="0.2"/></geometry></collision></link>
  <joint name="j" type="revolute"><parent link="arm"/><child link="tool"/><origin xyz="0.25 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
</robot>"#;
    let r = robot(text);
    let mut poses = LinkPoses::new();
    r.kinematics()
        .forward(&[0.7], &BasePose::IDENTITY, &mut poses);
    let mut raster = Rasterizer::new(lattice(), Encoding::Bits, RasterOptions::default());
    let mut run = |links: &[&str]| {
        raster.rasterize(&r, &r.body(links).unwrap(), &poses);
        raster.data().to_vec()
    };
    let (arm, tool, both) = (run(&["arm"]), run(&["tool"]), run(&["arm", "tool"]));
    assert!(arm.iter().any(|&b| b != 0) && tool.iter().any(|&b| b != 0));
    let or: Vec<u8> = arm.iter().zip(&tool).map(|(a, b)| a | b).collect();
    assert_eq!(both, or);
    assert!(
        matches!(r.body(&["gripper"]), Err(chronotope_robot::RobotError::UnknownLink(ref n)) if n == "gripper")
    );
}

#[test]
fn an_open_mesh_gives_its_surface_only() {
    let dir = super::common::TempDir::new("open-raster");
    // A 0.4 m cube without its +x face, as a binary STL.
    let v = |i: usize| {
        [
            (i & 1) as f32 * 0.4 - 0.2,
            ((i >> 1) & 1) as f32 * 0.4 - 0.2,
            ((i >> 2) & 1) as f32 * 0.4 - 0.2,
        ]
    };
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
    ];
    let mut b = vec![0u8; 80];
    b.extend_from_slice(&10u32.to_le_bytes());
    for q in quads {
        for t in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
            b.extend_from_slice(&[0u8; 12]);
            for i in t {
                for c in v(i) {
                    b.extend_from_slice(&c.to_le_bytes());
                }
            }
            b.extend_from_slice(&[0, 0]);
        }
    }
    std::fs::write(dir.0.join("open.stl"), b).unwrap();
    let text = one_link(&collision(
        [0.01, 0.01, 0.01],
        [0.0; 3],
        r#"<mesh filename="open.stl"/>"#,
    ));
    let r = Robot::from_urdf_str(&text, &super::common::options().base_dir(&dir.0)).unwrap();
    let l = lattice();
    let bits = frame(&r, l, Encoding::Bits, 4, BasePose::IDENTITY);
    // The centre voxel is inside the box but not on its surface: empty.
    assert!(!bit_at(&bits, l.index(10, 10, 10)));
    assert!(bit_at(&bits, l.index(10, 10, 6)), "the -z face is there");
    let percent = frame(&r, l, Encoding::Percent, 4, BasePose::IDENTITY);
    assert!(percent.iter().all(|&p| p == 0));
}

#[test]
fn a_mesh_box_and_a_primitive_box_agree() {
    let dir = super::common::TempDir::new("mesh-box");
    let m = chronotope_robot::mesh::TriMesh::cuboid([1.0, 1.0, 1.0]);
    let mut s = String::from("solid b\n");
    for t in &m.triangles {
        s.push_str("facet normal 0 0 0\nouter loop\n");
        for &i in t {
            let p = m.vertices[i as usize];
            s.push_str(&format!("vertex {} {} {}\n", p[0], p[1], p[2]));
        }
        s.push_str("endloop\nendfacet\n");
    }
    s.push_str("endsolid b\n");
    std::fs::write(dir.0.join("b.stl"), s).unwrap();
    let (xyz, rpy) = ([0.013, -0.021, 0.03], [0.4, 0.3, -0.8]);
    let mesh = Robot::from_urdf_str(
        &one_link(&collision(
            xyz,
            rpy,
            r#"<mesh filename="b.stl" scale="0.25 0.125 0.375"/>"#,
        )),
        &super::common::options().base_dir(&dir.0),
    )
    .unwrap();
    let prim = robot(&one_link(&collision(
        xyz,
        rpy,
        r#"<box size="0.25 0.125 0.375"/>"#,
    )));
    let l = lattice();
    for enc in [Encoding::Bits, Encoding::Percent] {
        let (a, b) = (
            frame(&mesh, l, enc, 4, BasePose::IDENTITY),
            frame(&prim, l, enc, 4, BasePose::IDENTITY),
        );
        let worst = a
            .iter()
            .zip(&b)
            .map(|(x, y)| (i16::from(*x) - i16::from(*y)).abs())
            .max()
            .unwrap();
        assert!(
            worst <= if enc == Encoding::Bits { 0 } else { 1 },
            "{enc:?}: {worst}"
        );
    }
}

/// Two overlapping boxes (sizes `a`, `b`; `b` moved by `shift`) as one STL of two closed
/// shells; with `flip` one triangle of each is reversed (closed, not oriented: parity).
fn two_box_stl(a: [f64; 3], b: [f64; 3], shift: [f64; 3], flip: bool) -> String {
    let mut s = String::from("solid two\n");
    for (size, off) in [(a, [0.0; 3]), (b, shift)] {
        let m = chronotope_robot::mesh::TriMesh::cuboid(size);
        for (n, t) in m.triangles.iter().enumerate() {
            let t = if flip && n == 3 {
                [t[0], t[2], t[1]]
            } else {
                *t
            };
            s.push_str("facet normal 0 0 0\nouter loop\n");
            for i in t {
                let p = m.vertices[i as usize];
                s.push_str(&format!(
                    "vertex {} {} {}\n",
                    p[0] + off[0],
                    p[1] + off[1],
                    p[2] + off[2]
                ));
            }
            s.push_str("endloop\nendfacet\n");
        }
    }
    s.push_str("endsolid two\n");
    s
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    #[test]
    fn bits_are_conservative_and_tight_for_meshes_of_overlapping_shells(
        a in (0.02..0.3f64, 0.02..0.3f64, 0.02..0.3f64),
        b in (0.02..0.3f64, 0.02..0.3f64, 0.02..0.3f64),
        shift in (-0.1..0.1f64, -0.1..0.1f64, -0.1..0.1f64),
        flip in any::<bool>(),
        base in arb_pose(),
        u in prop::collection::vec((0.0..1.0f64, 0.0..1.0f64, 0.0..1.0f64), 300),
    ) {
        let (a, b, shift) = ([a.0, a.1, a.2], [b.0, b.1, b.2], [shift.0, shift.1, shift.2]);
        let dir = super::common::TempDir::new("two-box");
        std::fs::write(dir.0.join("m.stl"), two_box_stl(a, b, shift, flip)).unwrap();
        let r = Robot::from_urdf_str(
            &one_link(&collision([0.0; 3], [0.0; 3], r#"<mesh filename="m.stl"/>"#)),
            &super::common::options().base_dir(&dir.0),
        ).unwrap();
        // A reversed triangle is turned back: the mesh is oriented again.
        prop_assert_eq!(r.load_report().meshes[0].closure, chronotope_robot::mesh::Closure::Oriented);
        let l = lattice();
        let bits = frame(&r, l, Encoding::Bits, 4, base);
        let rm = rot(&base);
        let t = Vector3::new(base.x, base.y, base.z);
        let u: Vec<[f64; 3]> = u.iter().map(|&(x, y, z)| [x, y, z]).collect();
        let pts_a = solid_points(0, a, &u);
        let pts_b = solid_points(0, b, &u).into_iter().map(|p| p + Vector3::from(shift));
        for p in pts_a.into_iter().chain(pts_b) {
            let ijk = (rm * p + t - Vector3::from(l.origin())) / H;
            let (i, j, k) = (ijk.x.floor(), ijk.y.floor(), ijk.z.floor());
            if i < 0.0 || j < 0.0 || k < 0.0 || i >= 20.0 || j >= 20.0 || k >= 20.0 {
                continue;
            }
            prop_assert!(bit_at(&bits, l.index(i as u32, j as u32, k as u32)), "point {p:?} in an empty voxel");
        }
        let tb = t + rm * Vector3::from(shift);
        for v in (0..l.voxels()).filter(|&v| bit_at(&bits, v)) {
            let (i, j, k) = (v % 20, v / 20 % 20, v / 400);
            let lo = Vector3::from(l.origin()) + Vector3::new(i as f64, j as f64, k as f64) * H;
            let grow = 2.0 * MARGIN * H;
            prop_assert!(cube_meets(0, a, &rm, &t, lo, grow) || cube_meets(0, b, &rm, &tb, lo, grow), "voxel ({i},{j},{k}) set but apart");
        }
    }
}

#[test]
fn lattices_with_very_many_rows_give_the_same_frames() {
    // 2050² rows is over the counting sort's 2²² counters: the comparison sort is used.
    let r = robot(&one_link(&collision(
        [0.011, 0.052, 0.073],
        [0.3, 0.2, 0.1],
        r#"<box size="0.05 0.07 0.09"/>"#,
    )));
    let (small, large) = (
        Lattice::new([0.0; 3], 0.004, [4, 60, 60]).unwrap(),
        Lattice::new([0.0; 3], 0.004, [4, 2050, 2050]).unwrap(),
    );
    for enc in [Encoding::Bits, Encoding::Percent] {
        let (a, b) = (
            frame(&r, small, enc, 4, BasePose::IDENTITY),
            frame(&r, large, enc, 4, BasePose::IDENTITY),
        );
        let mut occupied = 0;
        for k in 0..60 {
            for j in 0..60 {
                for i in 0..4 {
                    let (va, vb) = (small.index(i, j, k), large.index(i, j, k));
                    let (x, y) = match enc {
                        Encoding::Bits => (u8::from(bit_at(&a, va)), u8::from(bit_at(&b, vb))),
                        Encoding::Percent => (a[va], b[vb]),
                    };
                    assert_eq!(x, y, "{enc:?} ({i},{j},{k})");
                    occupied += usize::from(x > 0);
                }
            }
        }
        assert!(occupied > 100);
    }
}

#[test]
fn bad_lattices_and_poses_are_values_not_panics() {
    use chronotope_robot::LatticeError;
    assert_eq!(
        Lattice::new([0.0; 3], 0.0, [1, 1, 1]),
        Err(LatticeError::BadResolution(0.0))
    );
    assert!(matches!(
        Lattice::new([0.0; 3], f64::NAN, [1, 1, 1]),
        Err(LatticeError::BadResolution(_))
    ));
    assert!(matches!(
        Lattice::new([f64::INFINITY, 0.0, 0.0], 1.0, [1, 1, 1]),
        Err(LatticeError::BadOrigin(_))
    ));
    assert_eq!(
        Lattice::new([0.0; 3], 1.0, [4, 0, 4]),
        Err(LatticeError::Empty([4, 0, 4]))
    );
    let e = Lattice::new([0.0; 3], 1.0, [2048, 2048, 2048]).unwrap_err();
    assert!(e.to_string().contains("MAX_VOXELS"), "{e}");
    // VoxelGrid's ENCODING_BITS = 0 and ENCODING_PERCENT = 1.
    assert_eq!(
        (Encoding::Bits.wire_value(), Encoding::Percent.wire_value()),
        (0, 1)
    );
    // A non-finite base pose places nothing (the geometry is skipped and counted).
    let r = robot(&one_link(&format!(
        "{}{}",
        collision([0.0; 3], [0.0; 3], r#"<box size="0.1 0.1 0.1"/>"#),
        collision([0.0; 3], [0.0; 3], r#"<sphere radius="0.1"/>"#)
    )));
    let mut poses = LinkPoses::new();
    let base = BasePose {
        x: f64::NAN,
        ..BasePose::IDENTITY
    };
    assert!(!base.is_finite());
    r.kinematics().forward(&[], &base, &mut poses);
    for enc in [Encoding::Bits, Encoding::Percent] {
        let mut raster = Rasterizer::new(lattice(), enc, RasterOptions::default());
        let stats = raster.rasterize(&r, &r.whole_body(), &poses);
        assert!(
            stats.skipped_far >= 1 && stats.occupied == 0,
            "{enc:?}: {stats:?}"
        );
    }
}

#[test]
fn a_frame_copied_into_the_last_frames_buffer_equals_the_frame() {
    let r = robot(&one_link(&collision(
        [0.0; 3],
        [0.3, -0.2, 0.5],
        r#"<cylinder radius="0.08" length="0.3"/>"#,
    )));
    for encoding in [Encoding::Percent, Encoding::Bits] {
        let mut raster = Rasterizer::new(lattice(), encoding, RasterOptions::default());
        let (mut out, mut written) = (Vec::new(), Vec::new());
        let mut poses = LinkPoses::new();
        // The body moves across the lattice and out of it, then back: every voxel a frame
        // wrote must be cleared in the next copy unless that frame covers it again.
        for step in [0.0, 0.1, 0.25, 0.6, 2.0, 0.05, -0.2] {
            let base = BasePose::from_array([step, -step / 2.0, 0.0, 0.0, 0.0, step]);
            r.kinematics().forward(&[], &base, &mut poses);
            raster.rasterize(&r, &r.whole_body(), &poses);
            raster.copy_into(&mut out, &mut written);
            assert_eq!(out, raster.data(), "{encoding:?} at step {step}");
        }
    }
}
