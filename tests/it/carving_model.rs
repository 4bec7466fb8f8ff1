//! The carving model's open pieces: the section force on a cut diagonal to the grid, the
//! seed's eq. 7 edge polygons, and the seed's tool surfels (eqs. 3-5) against the grid.

use chronotope::carving::edge::EdgePolygon;
use chronotope::carving::exact::{BoxSweep, SweptSolid};
use chronotope::carving::toolsurfel::{sweep_surfels, ToolClass, MAX_TOOL_SURFELS};
use chronotope::carving::{
    CarveError, ForceModel, ForceParams, ForceRenderer, Quat, Tool, ToolPose, Vec3, Workpiece,
};

/// The knife facing +x (tool z → world x, its length down along -z).
fn facing_x() -> Quat {
    Quat::from_axis_angle([0.0, 1.0, 0.0], std::f64::consts::FRAC_PI_2)
}

fn rz(deg: f64) -> Quat {
    Quat::from_axis_angle([0.0, 0.0, 1.0], deg.to_radians())
}

fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Raw section force over a steady knife cut (3 mm deep, 6 mm wide, 50 mm/s at 1 kHz) at
/// `deg` to the x axis, 1 mm spacing: (CV of |F| with the model's sub-voxel section, CV with
/// the layer ahead counted whole, mean |F| of the model's).
fn section_cv(deg: f64) -> (f64, f64, f64) {
    let h = 1e-3;
    let mut work = Workpiece::block([0.0, 0.0, 0.01], [0.035, 0.03, 0.02], h).unwrap();
    let tool = Tool::knife(0.008, 0.006, 0.002, h).unwrap();
    let raw = ForceParams {
        model: ForceModel::Section,
        cutoff_hz: 0.0,
        coupling_stiffness: 0.0,
        max_force: f64::INFINITY,
        ..ForceParams::default()
    };
    let (mut sub_voxel, mut counted) = (ForceRenderer::new(raw), ForceRenderer::new(raw));
    let rot = rz(deg).mul(&facing_x());
    let (s, c) = deg.to_radians().sin_cos();
    let step = [5e-5 * c, 5e-5 * s, 0.0];
    let mut prev = ToolPose {
        position: [0.008, 0.008, 0.021],
        rotation: rot,
    };
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for k in 0..400 {
        let next = ToolPose {
            position: [0, 1, 2].map(|i| prev.position[i] + step[i]),
            rotation: rot,
        };
        let cut = work.carve(&tool, &prev, &next).unwrap();
        let f = sub_voxel.step(&cut, h, step, 1e-3);
        let mut whole = cut;
        whole.ahead_area = cut.ahead as f64 * h * h;
        let g = counted.step(&whole, h, step, 1e-3);
        if k >= 100 {
            a.push(dot(f, f).sqrt());
            b.push(dot(g, g).sqrt());
        }
        prev = next;
    }
    let stats = |v: &[f64]| {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / v.len() as f64;
        (var.sqrt() / m, m)
    };
    let (cv_a, mean) = stats(&a);
    let (cv_b, _) = stats(&b);
    (cv_a, cv_b, mean)
}

#[test]
fn the_section_force_holds_steady_on_a_diagonal_cut() {
    // Cross-section 3 mm x 6 mm at 2e5 N/m^2: 3.6 N.
    for deg in [0.0, 30.0, 45.0] {
        let (cv, counted, mean) = section_cv(deg);
        assert!((mean - 3.6).abs() < 0.1, "{deg}°: mean {mean}");
        assert!(cv < 0.02, "{deg}°: sub-voxel CV {cv} (count {counted})");
        if deg > 0.0 {
            // Counting whole points jumps with the lattice phase; the sub-voxel estimate
            // must do clearly better.
            assert!(
                counted > 3.0 * cv && counted > 0.02,
                "{deg}°: count CV {counted}, sub-voxel {cv}"
            );
        }
    }
}

#[test]
fn the_sub_voxel_section_equals_the_count_along_a_grid_axis() {
    let h = 1e-3;
    let mut work = Workpiece::block([0.0; 3], [0.03, 0.02, 0.02], h).unwrap();
    let tool = Tool::knife(0.008, 0.006, 0.002, h).unwrap();
    let a = ToolPose {
        position: [0.005, 0.01, 0.021],
        rotation: facing_x(),
    };
    let b = ToolPose {
        position: [0.0103, 0.01, 0.021],
        rotation: facing_x(),
    };
    work.carve(&tool, &a, &a).unwrap();
    let cut = work.carve(&tool, &a, &b).unwrap();
    // 3 layers deep x 6 wide: 18 points, 18 mm^2.
    assert_eq!(cut.ahead, 18);
    assert!((cut.ahead_area - 18e-6).abs() < 1e-12, "{}", cut.ahead_area);
    // No motion: no section.
    let still = work.carve(&tool, &b, &b).unwrap();
    assert_eq!(still.ahead_area, 0.0);
    // In the air: none either.
    let up = |p: &ToolPose| ToolPose {
        position: [p.position[0], p.position[1], 0.05],
        rotation: p.rotation,
    };
    let air = work.carve(&tool, &up(&a), &up(&b)).unwrap();
    assert_eq!(air.ahead_area, 0.0);
}

/// A 45° chisel groove (3 mm wide, 1.5 mm high, apex 1 mm below the top) 12 mm long at
/// `deg` to x in a 24 x 20 x 6 mm block at spacing `h`; the workpiece and the true edges'
/// `(point at the stroke's start, direction)`, and the top's height.
fn grooved(h: f64, deg: f64) -> (Workpiece, [(Vec3, Vec3); 2], f64, f64) {
    let mut w = Workpiece::block([0.0; 3], [0.024, 0.02, 0.006], h).unwrap();
    let tool = Tool::chisel(0.003, 0.0015, 0.001, h).unwrap();
    let rot = rz(deg);
    let (s, c) = deg.to_radians().sin_cos();
    let start = [0.006, 0.007, 0.005];
    let len = 0.012;
    let moves = (len / (h / 2.0)).ceil() as usize;
    let at = |t: f64| ToolPose {
        position: [start[0] + t * c, start[1] + t * s, start[2]],
        rotation: rot,
    };
    let mut prev = at(0.0);
    w.carve(&tool, &prev, &prev).unwrap();
    for k in 1..=moves {
        let next = at(len * k as f64 / moves as f64);
        w.carve(&tool, &prev, &next).unwrap();
        prev = next;
    }
    w.validate().unwrap();
    // Sides at 45°: the edges 1 mm either side of the stroke's line on the top.
    let edges = [-1.0, 1.0].map(|side| {
        let q = rot.rotate([0.0, side * 0.001, 0.001]);
        ([0, 1, 2].map(|a| start[a] + q[a]), [c, s, 0.0])
    });
    (w, edges, 0.006, len)
}

/// Distance from `p` to the line `(a, u)` and the position along it.
fn to_line(p: Vec3, (a, u): (Vec3, Vec3)) -> (f64, f64) {
    let r = sub(p, a);
    let t = dot(r, u);
    let q = sub(r, [u[0] * t, u[1] * t, u[2] * t]);
    (dot(q, q).sqrt(), t)
}

fn segment_distance(p: Vec3, a: Vec3, b: Vec3) -> f64 {
    let ab = sub(b, a);
    let l2 = dot(ab, ab);
    let t = if l2 > 0.0 {
        (dot(sub(p, a), ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let q = sub(sub(p, a), [ab[0] * t, ab[1] * t, ab[2] * t]);
    dot(q, q).sqrt()
}

#[test]
fn eq7_polygons_line_the_chisel_edges_without_gaps() {
    for (h, deg) in [
        (0.5e-3, 0.0),
        (0.5e-3, 30.0),
        (0.25e-3, 45.0),
        (0.5e-3, 45.0),
    ] {
        let (w, edges, top, len) = grooved(h, deg);
        let mut polys: Vec<EdgePolygon> = Vec::new();
        let r = w.edge_polygons(0.5 * h, &mut polys).unwrap();
        assert!(r.edge_surfels > 0, "{h} {deg}: no edge surfels");
        assert_eq!(r.polygons, polys.len());
        assert_eq!(r.polygons + r.unmatched, r.edge_surfels, "{r:?}");
        // Most edge surfels find their face: at most the stroke's ends lack one.
        assert!(r.unmatched * 10 <= r.edge_surfels, "{h} {deg}: {r:?}");
        let mut interior = 0;
        for p in &polys {
            let v = p.vertices.map(|q| q.map(f64::from));
            let (d1, t1) = edges
                .iter()
                .map(|&e| to_line(v[0], e))
                .fold((f64::INFINITY, 0.0), |a, b| if b.0 < a.0 { b } else { a });
            let (d2, _) = edges
                .iter()
                .map(|&e| to_line(v[1], e))
                .fold((f64::INFINITY, 0.0), |a, b| if b.0 < a.0 { b } else { a });
            if t1 < 2.0 * h || t1 > len - 2.0 * h {
                continue; // the stroke's ends
            }
            interior += 1;
            // P1, P2 on the true edge (f32 positions), P3 on the old top face, P4 below it.
            assert!(
                d1 < 1e-5 && d2 < 1e-5,
                "{h} {deg}: P1 {d1} P2 {d2} off the edge"
            );
            assert!((v[2][2] - top).abs() < 1e-5, "{h} {deg}: P3 {:?}", v[2]);
            assert!(
                v[3][2] < top - 0.2 * h,
                "{h} {deg}: P4 {:?} not on the wall",
                v[3]
            );
            // Each side half a spacing wide.
            let mid = [0, 1, 2].map(|a| (v[0][a] + v[1][a]) / 2.0);
            for q in [v[2], v[3]] {
                let d = sub(q, mid);
                assert!((dot(d, d).sqrt() - 0.5 * h).abs() < 1e-5, "{h} {deg}");
            }
            // Triangles face out of the material: up on the top, into the groove on the wall.
            let [t1, t2] = p.triangles().map(|t| t.map(|q| q.map(f64::from)));
            let n1 = cross(sub(t1[1], t1[0]), sub(t1[2], t1[0]));
            assert!(n1[2] > 0.0, "{h} {deg}: top triangle faces {n1:?}");
            let n2 = cross(sub(t2[1], t2[0]), sub(t2[2], t2[0]));
            // The wall's outward side faces up and towards the stroke's line.
            let (_, tl) = to_line(mid, edges[0]);
            let axis =
                [0, 1, 2].map(|a| (edges[0].0[a] + edges[1].0[a]) / 2.0 + edges[0].1[a] * tl);
            let towards = sub(axis, mid);
            assert!(
                n2[2] > 0.0 && dot([n2[0], n2[1], 0.0], towards) > 0.0,
                "{h} {deg}: wall triangle faces {n2:?}"
            );
        }
        assert!(interior > 10, "{h} {deg}: {interior} interior polygons");
        // Along the edges' interior: the share of samples within 0.05 spacing of the strip
        // and of an edge surfel's centre.
        let red: Vec<Vec3> = w
            .surfels()
            .iter()
            .filter(|s| s.colour == 0xd02020)
            .map(|s| s.position.map(f64::from))
            .collect();
        let (mut strip, mut centres, mut n) = (0usize, 0usize, 0usize);
        for &e in &edges {
            for k in 0..=200 {
                let t = 2.5 * h + (len - 5.0 * h) * f64::from(k) / 200.0;
                let q = [0, 1, 2].map(|a| e.0[a] + e.1[a] * t);
                let gap = polys
                    .iter()
                    .map(|p| {
                        segment_distance(
                            q,
                            p.vertices[0].map(f64::from),
                            p.vertices[1].map(f64::from),
                        )
                    })
                    .fold(f64::INFINITY, f64::min);
                let centre = red
                    .iter()
                    .map(|&c| dot(sub(c, q), sub(c, q)).sqrt())
                    .fold(f64::INFINITY, f64::min);
                n += 1;
                strip += usize::from(gap < 0.05 * h);
                centres += usize::from(centre < 0.05 * h);
            }
        }
        // The strip lines the whole edge; the discs' centres only dot it.
        assert_eq!(
            strip, n,
            "{h} {deg}: {strip} of {n} edge samples on the strip"
        );
        assert!(centres * 4 < n, "{h} {deg}: centres {centres} of {n}");
    }
}

#[test]
fn eq7_polygons_follow_the_surfels_and_refuse_bad_widths() {
    let h = 0.5e-3;
    let (mut w, _, _, _) = grooved(h, 0.0);
    let mut polys = Vec::new();
    for bad in [0.0, -1e-3, f64::NAN, 2.5 * h] {
        assert!(
            matches!(
                w.edge_polygons(bad, &mut polys),
                Err(CarveError::Workpiece(_))
            ),
            "{bad}"
        );
    }
    let before = w.edge_polygons(0.5 * h, &mut polys).unwrap();
    // Plane the top away below the groove: no edge surfel, no polygon is left.
    let tool = Tool::knife(0.03, 0.03, 0.004, h).unwrap();
    let plane = |x: f64| ToolPose {
        position: [x, 0.01, 0.006],
        rotation: facing_x(),
    };
    w.carve(&tool, &plane(-0.02), &plane(0.05)).unwrap();
    w.validate().unwrap();
    let after = w.edge_polygons(0.5 * h, &mut polys).unwrap();
    assert!(before.polygons > 0);
    assert_eq!(after.edge_surfels, 0, "{after:?}");
    assert!(polys.is_empty());
    // A plain block has no edges.
    let block = Workpiece::block([0.0; 3], [0.01; 3], h).unwrap();
    let r = block.edge_polygons(0.5 * h, &mut polys).unwrap();
    assert_eq!((r.edge_surfels, polys.len()), (0, 0));
}

/// The tool surfels of one knife move across a 6 mm wide, 3 mm deep slot (or the plain
/// block), classified by eqs. 3-5 and by the grid: the share of those farther than a
/// spacing from the exact surface that each classifies right (material or air).
fn tool_surfel_agreement(slot: bool) -> (f64, f64, usize) {
    let h = 1e-3;
    let (lo, hi) = ([0.0; 3], [0.04, 0.03, 0.02]);
    let mut w = Workpiece::block(lo, hi, h).unwrap();
    let tool = Tool::knife(0.008, 0.006, 0.002, h).unwrap();
    let z = 0.021;
    let mut solid = SweptSolid::default();
    if slot {
        let a = ToolPose {
            position: [0.005, 0.015, z],
            rotation: facing_x(),
        };
        let b = ToolPose {
            position: [0.035, 0.015, z],
            rotation: facing_x(),
        };
        w.carve(&tool, &a, &a).unwrap();
        w.carve(&tool, &a, &b).unwrap();
        solid.pieces.push(BoxSweep {
            c0: a.position,
            rotation: a.rotation,
            half: [0.004, 0.003, 0.001],
            d: [0.03, 0.0, 0.0],
        });
    }
    let rot = rz(90.0).mul(&facing_x());
    let from = ToolPose {
        position: [0.02, 0.004, z - 0.001],
        rotation: rot,
    };
    let to = ToolPose {
        position: [0.02, 0.026, z - 0.001],
        rotation: rot,
    };
    let surfels = sweep_surfels(&tool, &from, &to, h).unwrap();
    let (mut n, mut eq3, mut grid) = (0usize, 0usize, 0usize);
    for s in &surfels {
        let sd = solid.carved_block_distance(lo, hi, s.position);
        if sd.abs() <= h {
            continue;
        }
        n += 1;
        let air = sd > 0.0;
        eq3 += usize::from((w.classify_eq3(s.position, h) == ToolClass::Outside) == air);
        grid += usize::from((w.classify_grid(s.position, h) == ToolClass::Outside) == air);
    }
    (eq3 as f64 / n as f64, grid as f64 / n as f64, n)
}

#[test]
fn eq3_holds_on_a_convex_block_and_fails_beside_a_slot_where_the_grid_does_not() {
    let (eq3, grid, n) = tool_surfel_agreement(false);
    assert!(n > 200, "{n}");
    assert_eq!((eq3, grid), (1.0, 1.0), "plain block, {n} tool surfels");
    let (eq3, grid, n) = tool_surfel_agreement(true);
    assert!(n > 200, "{n}");
    assert_eq!(grid, 1.0, "the grid beside a slot, {n} tool surfels");
    assert!(eq3 < 0.95, "eq. 3 beside a slot agrees on {eq3} of {n}");
}

#[test]
fn tool_surfels_lie_on_the_swept_solid_and_are_bounded() {
    let h = 1e-3;
    let tool = Tool::knife(0.008, 0.006, 0.002, h).unwrap();
    let from = ToolPose {
        position: [0.0, 0.0, 0.0],
        rotation: facing_x(),
    };
    let to = ToolPose {
        position: [0.004, 0.003, 0.0],
        rotation: facing_x(),
    };
    let s = sweep_surfels(&tool, &from, &to, h).unwrap();
    assert!(!s.is_empty());
    let sweep = BoxSweep {
        c0: from.position,
        rotation: from.rotation,
        half: [0.004, 0.003, 0.001],
        d: to.position,
    };
    for t in &s {
        let d = sweep.signed_distance(t.position);
        assert!(
            d.abs() < 1e-9,
            "{:?} at {d} from the sweep's boundary",
            t.position
        );
        // Its normal points out of the swept solid.
        let out = [0, 1, 2].map(|a| t.position[a] + 1e-5 * t.normal[a]);
        assert!(sweep.signed_distance(out) > 0.0);
    }
    let far = ToolPose {
        position: [10.0, 0.0, 0.0],
        rotation: facing_x(),
    };
    let e = sweep_surfels(&tool, &from, &far, 1e-5).unwrap_err();
    assert!(e.to_string().contains("MAX_TOOL_SURFELS"), "{e}");
    let _ = MAX_TOOL_SURFELS;
    assert!(sweep_surfels(&tool, &from, &to, 0.0).is_err());
}
