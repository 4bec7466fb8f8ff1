//! The synthetic scene generator: encodings, determinism, and the geometry each scene is
//! meant to have (who touches whom, and when). Small grids only.

use chronotope::msg::{VoxelEncoding, VoxelGrid};
use chronotope::scene::{
    build_scene, rasterize, Scene, SceneError, SceneName, SceneOptions, Shape, VoxelLattice,
    FOUR_SPHERES, MAX_GRID, SCENE_START_NS, TOOL_FIXTURE_CONTACT_U, TOOL_WORKPIECE_CONTACT_U,
};

fn scene(name: SceneName, grid: u32, frames: u32, encoding: VoxelEncoding) -> Scene {
    let opts = SceneOptions::for_scene(name)
        .grid(grid)
        .frames(frames)
        .encoding(encoding);
    build_scene(name, &opts).expect("valid options")
}

fn bit(data: &[u8], idx: usize) -> bool {
    data[idx >> 3] >> (idx & 7) & 1 == 1
}

fn occupied(g: &VoxelGrid) -> Vec<bool> {
    (0..g.voxel_count() as usize)
        .map(|i| bit(&g.data, i))
        .collect()
}

fn shared_voxels(a: &VoxelGrid, b: &VoxelGrid) -> usize {
    a.data
        .iter()
        .zip(&b.data)
        .map(|(x, y)| (x & y).count_ones() as usize)
        .sum()
}

#[test]
fn scene_names_round_trip() {
    for name in SceneName::ALL {
        assert_eq!(name.to_string().parse::<SceneName>(), Ok(name));
    }
    assert_eq!("machine-tool".parse(), Ok(SceneName::MachineTool));
    assert_eq!("four-spheres".parse(), Ok(SceneName::FourSpheres));
    assert_eq!(
        "three-cubes".parse::<SceneName>(),
        Err(SceneError::UnknownScene {
            name: "three-cubes".into()
        })
    );
}

#[test]
fn bad_options_are_errors() {
    let base = SceneOptions::for_scene(SceneName::FourSpheres);
    for (opts, err) in [
        (base.grid(3), SceneError::GridOutOfRange { grid: 3 }),
        (
            base.grid(MAX_GRID + 1),
            SceneError::GridOutOfRange { grid: MAX_GRID + 1 },
        ),
        (base.frames(0), SceneError::FramesOutOfRange { frames: 0 }),
        (
            base.frames(100_001),
            SceneError::FramesOutOfRange { frames: 100_001 },
        ),
    ] {
        for name in SceneName::ALL {
            assert_eq!(build_scene(name, &opts).unwrap_err(), err);
        }
    }
    assert!(build_scene(SceneName::FourSpheres, &base.grid(4).frames(1)).is_ok());
    let s = scene(SceneName::FourSpheres, 8, 3, VoxelEncoding::Bits);
    assert_eq!(
        s.try_frame(4, 0).unwrap_err(),
        SceneError::NoSuchBody { body: 4, bodies: 4 }
    );
    assert_eq!(
        s.try_frame(0, 3).unwrap_err(),
        SceneError::NoSuchFrame {
            frame: 3,
            frames: 3
        }
    );
}

#[test]
fn defaults_match_the_seeds() {
    let mt = SceneOptions::for_scene(SceneName::MachineTool);
    assert_eq!(
        (mt.grid, mt.frames, mt.encoding),
        (128, 64, VoxelEncoding::Bits)
    );
    let fs = SceneOptions::for_scene(SceneName::FourSpheres);
    assert_eq!(
        (fs.grid, fs.frames, fs.encoding),
        (64, 33, VoxelEncoding::Bits)
    );
}

#[test]
fn frames_share_one_lattice_and_carry_stamps() {
    for (name, period_ns) in [
        (SceneName::MachineTool, 100_000_000),
        (SceneName::FourSpheres, 250_000_000),
    ] {
        for enc in [VoxelEncoding::Bits, VoxelEncoding::Percent] {
            let s = scene(name, 12, 5, enc);
            assert_eq!(s.name(), name);
            assert_eq!(s.frame_count(), 5);
            assert_eq!(s.topics().len(), s.bodies().len());
            let first = s.frame(0, 0);
            for body in 0..s.bodies().len() {
                for k in 0..5 {
                    let g = s.frame(body, k);
                    assert_eq!(g.header.frame_id, "world");
                    assert_eq!(
                        g.header.stamp.as_nanos(),
                        SCENE_START_NS + i64::from(k) * period_ns
                    );
                    assert_eq!(g.header.stamp.as_nanos(), s.stamp_ns(k));
                    assert_eq!((g.origin, g.resolution), (first.origin, first.resolution));
                    assert_eq!((g.size_x, g.size_y, g.size_z), (12, 12, 12));
                    assert_eq!(g.encoding, enc.code());
                    assert_eq!(g.data.len() as u64, g.expected_data_len().unwrap());
                }
            }
        }
    }
    let mt = scene(SceneName::MachineTool, 16, 3, VoxelEncoding::Bits);
    assert_eq!(
        mt.topics(),
        [
            "/spindle/occupancy",
            "/table/occupancy",
            "/fixture/occupancy"
        ]
    );
    assert_eq!(mt.frame(0, 0).resolution, 0.08);
    let fs = scene(SceneName::FourSpheres, 16, 33, VoxelEncoding::Bits);
    assert_eq!(fs.topics(), FOUR_SPHERES.topics);
    assert_eq!(fs.stamp_ns(1) - fs.stamp_ns(0), 31_250_000);
    assert_eq!(fs.time_s(32), 1.0);
    // Frame times are rounded to the nanosecond when the period is not a whole number of them.
    let odd = scene(SceneName::FourSpheres, 8, 4, VoxelEncoding::Bits);
    assert_eq!(odd.stamp_ns(1) - SCENE_START_NS, 333_333_333);
    assert_eq!(odd.stamp_ns(2) - SCENE_START_NS, 666_666_667);
    assert_eq!(odd.stamp_ns(3) - SCENE_START_NS, 1_000_000_000);
}

#[test]
fn frames_are_deterministic() {
    for name in SceneName::ALL {
        for enc in [VoxelEncoding::Bits, VoxelEncoding::Percent] {
            let (a, b) = (scene(name, 20, 7, enc), scene(name, 20, 7, enc));
            for body in 0..a.bodies().len() {
                for k in [0, 3, 6] {
                    let fa = a.frame(body, k);
                    assert_eq!(fa, b.frame(body, k));
                    assert!(
                        fa.data.iter().any(|&v| v != 0),
                        "{name} body {body} frame {k} is empty"
                    );
                }
            }
        }
    }
}

#[test]
fn write_frame_reuses_buffers_and_agrees_with_frame() {
    let s = scene(SceneName::MachineTool, 16, 4, VoxelEncoding::Percent);
    let mut raster = chronotope::scene::Rasterizer::new();
    let mut grid = VoxelGrid::default();
    for body in 0..3 {
        for k in 0..4 {
            s.write_frame(body, k, &mut raster, &mut grid).unwrap();
            assert_eq!(grid, s.frame(body, k));
        }
    }
}

#[test]
fn bits_are_lsb_first_x_fastest() {
    // 5 x 4 x 3 voxels of 1 m from the origin: 60 voxels, 8 bytes.
    let lattice = VoxelLattice {
        origin: [0.0; 3],
        resolution: 1.0,
        size: [5, 4, 3],
    };
    // A small box around the centre of voxel (2, 1, 2): linear index 2 + 5 (1 + 4 * 2) = 47.
    let one = [Shape::cuboid([2.4, 1.4, 2.4], [2.6, 1.6, 2.6])];
    let data = rasterize(&one, [0.0; 3], &lattice, VoxelEncoding::Bits);
    assert_eq!(data, vec![0, 0, 0, 0, 0, 0x80, 0, 0]);
    // The same box moved by (-2, -1, -2) marks voxel 0: bit 0 of byte 0.
    let data = rasterize(&one, [-2.0, -1.0, -2.0], &lattice, VoxelEncoding::Bits);
    assert_eq!(data, vec![1, 0, 0, 0, 0, 0, 0, 0]);
    // A rod along x through the centres of row (j, k) = (3, 0) covers voxels 15..=19.
    let rod = [Shape::cuboid([-1.0, 3.4, 0.4], [9.0, 3.6, 0.6])];
    let data = rasterize(&rod, [0.0; 3], &lattice, VoxelEncoding::Bits);
    assert_eq!(data, vec![0, 0x80, 0x0f, 0, 0, 0, 0, 0]);
    // A box whose faces lie halfway between centres covers exactly the voxels it encloses.
    let block = [Shape::cuboid([1.0, 0.0, 1.0], [3.0, 2.0, 2.0])];
    let data = rasterize(&block, [0.0; 3], &lattice, VoxelEncoding::Bits);
    let expected: Vec<usize> = [(1, 0, 1), (2, 0, 1), (1, 1, 1), (2, 1, 1)]
        .map(|(i, j, k)| i + 5 * (j + 4 * k))
        .into();
    let got: Vec<usize> = (0..60).filter(|&i| bit(&data, i)).collect();
    assert_eq!(got, expected);
    // PERCENT of the same box: 100 in those voxels, 0 elsewhere, one byte per voxel.
    let data = rasterize(&block, [0.0; 3], &lattice, VoxelEncoding::Percent);
    assert_eq!(data.len(), 60);
    for (i, v) in data.iter().enumerate() {
        assert_eq!(*v, if expected.contains(&i) { 100 } else { 0 }, "voxel {i}");
    }
    // Half a voxel: a box covering x in [0, 0.5] of voxel (0, 0, 0).
    let half = [Shape::cuboid([0.0, 0.0, 0.0], [0.5, 1.0, 1.0])];
    assert_eq!(
        rasterize(&half, [0.0; 3], &lattice, VoxelEncoding::Percent)[0],
        50
    );
    // Shapes outside the lattice leave it empty.
    let away = [Shape::sphere([50.0, 0.0, 0.0], 2.0)];
    assert!(rasterize(&away, [0.0; 3], &lattice, VoxelEncoding::Bits)
        .iter()
        .all(|&b| b == 0));
}

/// Every BITS voxel is set iff its centre is inside the body at the frame's time.
#[test]
fn bits_mark_exactly_the_voxel_centres_inside() {
    for name in SceneName::ALL {
        let s = scene(name, 24, 6, VoxelEncoding::Bits);
        let l = *s.lattice();
        for (b, body) in s.bodies().iter().enumerate() {
            for k in [0, 2, 5] {
                let g = s.frame(b, k);
                let t = s.time_s(k);
                let occ = occupied(&g);
                for kz in 0..24 {
                    for j in 0..24 {
                        for i in 0..24 {
                            let inside = body.contains(l.voxel_centre(i, j, kz), t);
                            assert_eq!(
                                occ[l.index(i, j, kz)],
                                inside,
                                "{name} body {b} frame {k} voxel {i},{j},{kz}"
                            );
                        }
                    }
                }
            }
        }
    }
}

/// PERCENT equals brute-force 8x8x8 midpoint supersampling of the body, voxel by voxel.
#[test]
fn percent_is_exact_supersampling() {
    for name in SceneName::ALL {
        let n = 10;
        let s = scene(name, n, 5, VoxelEncoding::Percent);
        let l = *s.lattice();
        for (b, body) in s.bodies().iter().enumerate() {
            for k in [1, 3] {
                let g = s.frame(b, k);
                let t = s.time_s(k);
                for kz in 0..n {
                    for j in 0..n {
                        for i in 0..n {
                            let mut count = 0u32;
                            for c in 0..8 {
                                for bb in 0..8 {
                                    for a in 0..8 {
                                        let p = [
                                            l.sample(0, u64::from(i) * 8 + a, 8),
                                            l.sample(1, u64::from(j) * 8 + bb, 8),
                                            l.sample(2, u64::from(kz) * 8 + c, 8),
                                        ];
                                        count += u32::from(body.contains(p, t));
                                    }
                                }
                            }
                            let want = ((count * 100 + 256) / 512) as u8;
                            assert_eq!(
                                g.data[l.index(i, j, kz)],
                                want,
                                "{name} body {b} frame {k} voxel {i},{j},{kz}"
                            );
                        }
                    }
                }
            }
        }
    }
}

/// PERCENT is 0..=100, 100 deep inside, 0 far outside, and agrees with BITS near the surface.
#[test]
fn percent_is_consistent_with_bits() {
    for name in SceneName::ALL {
        let bits = scene(name, 32, 5, VoxelEncoding::Bits);
        let pct = scene(name, 32, 5, VoxelEncoding::Percent);
        let l = *bits.lattice();
        let half_diagonal = l.resolution * 3f64.sqrt() / 2.0;
        for (b, body) in bits.bodies().iter().enumerate() {
            for k in [0, 2, 4] {
                let (gb, gp) = (bits.frame(b, k), pct.frame(b, k));
                let t = bits.time_s(k);
                let occ = occupied(&gb);
                for kz in 0..32 {
                    for j in 0..32 {
                        for i in 0..32 {
                            let idx = l.index(i, j, kz);
                            let v = gp.data[idx];
                            assert!(v <= 100);
                            let sd = body.signed_distance(l.voxel_centre(i, j, kz), t);
                            if sd <= -half_diagonal {
                                assert_eq!(v, 100, "{name} body {b} frame {k} voxel {i},{j},{kz}");
                            } else if sd >= half_diagonal {
                                assert_eq!(v, 0, "{name} body {b} frame {k} voxel {i},{j},{kz}");
                            } else if sd.abs() > 0.25 * l.resolution {
                                // A quarter voxel or more from the surface, the centre's side mostly
                                // wins (a box corner keeps (3/4)³ = 42 %; concave joints of a union
                                // may add a little on the outside).
                                if occ[idx] {
                                    assert!(v >= 40, "{name} body {b} frame {k} voxel {i},{j},{kz}: {v}% but centre inside");
                                } else {
                                    assert!(v <= 60, "{name} body {b} frame {k} voxel {i},{j},{kz}: {v}% but centre outside");
                                }
                            }
                        }
                    }
                }
            }
        }
    }
}

#[test]
fn percent_volume_of_a_sphere() {
    let s = scene(SceneName::FourSpheres, 32, 33, VoxelEncoding::Percent);
    let r = FOUR_SPHERES.radius;
    let exact = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
    let cell = s.lattice().resolution.powi(3);
    for body in 0..4 {
        for k in [0, 7, 16, 32] {
            let g = s.frame(body, k);
            let volume = g.data.iter().map(|&v| f64::from(v)).sum::<f64>() / 100.0 * cell;
            let err = (volume - exact).abs() / exact;
            assert!(err < 0.01, "body {body} frame {k}: {volume} vs {exact}");
        }
    }
}

#[test]
fn four_spheres_exact_intervals() {
    let p = FOUR_SPHERES;
    let root3 = 3f64.sqrt();
    let close =
        |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).abs() < 1e-12 && (a.1 - b.1).abs() < 1e-12;
    let ab = p.overlap_interval(0, 1).unwrap();
    assert!(
        close(ab, (0.5 - 1.0 / 13f64.sqrt(), 0.5 + 1.0 / 13f64.sqrt())),
        "{ab:?}"
    );
    let ac = p.overlap_interval(0, 2).unwrap();
    assert!(
        close(ac, ((4.0 - 2.0 * root3) / 15.0, (4.0 + 2.0 * root3) / 15.0)),
        "{ac:?}"
    );
    let ad = p.overlap_interval(0, 3).unwrap();
    assert!(
        close(
            ad,
            ((11.0 - 2.0 * root3) / 15.0, (11.0 + 2.0 * root3) / 15.0)
        ),
        "{ad:?}"
    );
    assert!(ac.1 < ad.0, "A–C ends before A–D starts");
    assert_eq!(p.overlap_interval(1, 0), Some(ab));
    // Deepest overlaps.
    let (d, t) = p.closest_approach(0, 1);
    assert!((d - 0.15).abs() < 1e-12 && (t - 0.5).abs() < 1e-12);
    assert!((p.closest_approach(0, 2).1 - 4.0 / 15.0).abs() < 1e-12);
    assert!((p.closest_approach(0, 3).1 - 11.0 / 15.0).abs() < 1e-12);
    // B, C, D never meet: at least 5 cm between their surfaces.
    for (i, j) in [(1, 2), (1, 3), (2, 3)] {
        assert_eq!(p.overlap_interval(i, j), None);
        assert!(
            p.closest_approach(i, j).0 > 2.0 * p.radius + 0.05,
            "{i} {j}"
        );
    }
    // Every sphere stays inside the domain with a margin at both ends of the run.
    for i in 0..4 {
        for t in [p.t_span.0, p.t_span.1] {
            for c in p.centre(i, t) {
                assert!(
                    c - p.radius >= 0.07 && c + p.radius <= p.domain_edge - 0.07,
                    "sphere {i} at {t}"
                );
            }
        }
    }
    // Overlap hypervolumes (docs/methods/interference.md#exact-answers-for-moving-spheres),
    // against 200-point Gauss-Legendre in numpy.
    for (i, j, v) in [
        (0, 1, 4.769062246541e-4),
        (0, 2, 2.062369697711e-4),
        (0, 3, 2.062369697711e-4),
    ] {
        let got = p.overlap_hypervolume(i, j);
        assert!((got - v).abs() < 1e-9 * v, "{i}{j}: {got} vs {v}");
    }
    assert_eq!(p.overlap_hypervolume(1, 2), 0.0);
    assert!(
        (p.lens_volume(0.0) - 4.0 / 3.0 * std::f64::consts::PI * p.radius.powi(3)).abs() < 1e-15
    );
    // The exact intervals agree with the centre distances.
    for (i, j) in [(0, 1), (0, 2), (0, 3)] {
        let (t0, t1) = p.overlap_interval(i, j).unwrap();
        assert!((p.centre_distance(i, j, t0) - 2.0 * p.radius).abs() < 1e-12);
        assert!((p.centre_distance(i, j, t1) - 2.0 * p.radius).abs() < 1e-12);
        assert!(p.depth(i, j, (t0 + t1) / 2.0) > 0.0);
    }
}

/// BITS of two spheres share voxels when the exact overlap is at least a voxel diagonal deep
/// (the lens then holds a ball of radius half a diagonal, which holds a voxel centre), and
/// never when the spheres are apart (disjoint open sets share no centre).
#[test]
fn four_spheres_bits_overlap_follows_exact_intervals() {
    let p = FOUR_SPHERES;
    for grid in [16, 32] {
        let s = scene(SceneName::FourSpheres, grid, 33, VoxelEncoding::Bits);
        let diag = s.lattice().resolution * 3f64.sqrt();
        let frames: Vec<Vec<VoxelGrid>> = (0..4)
            .map(|b| (0..33).map(|k| s.frame(b, k)).collect())
            .collect();
        let mut overlapping_frames = [0; 4];
        for i in 0..4 {
            for j in i + 1..4 {
                let interval = p.overlap_interval(i, j);
                for k in 0..33 {
                    let t = s.time_s(k);
                    let shared = shared_voxels(&frames[i][k as usize], &frames[j][k as usize]);
                    let inside = interval.is_some_and(|(t0, t1)| t0 < t && t < t1);
                    if !inside {
                        assert_eq!(shared, 0, "grid {grid} pair {i}{j} at t = {t}");
                    } else if p.depth(i, j, t) >= diag {
                        assert!(shared > 0, "grid {grid} pair {i}{j} at t = {t}");
                        overlapping_frames[j] += 1;
                    }
                }
            }
        }
        if grid == 32 {
            // A meets B, C and D in several frames each.
            assert!(
                overlapping_frames[1..].iter().all(|&n| n >= 5),
                "{overlapping_frames:?}"
            );
        }
    }
}

#[test]
fn machine_tool_bodies_meet_when_designed() {
    let frames = 21;
    let s = scene(SceneName::MachineTool, 32, frames, VoxelEncoding::Bits);
    let [spindle, table, fixture] =
        [0, 1, 2].map(|b| (0..frames).map(|k| s.frame(b, k)).collect::<Vec<_>>());
    let margin = 0.03;
    let (mut tool_fixture, mut tool_work) = (0, 0);
    for k in 0..frames as usize {
        let u = s.run_fraction(k as u32);
        for ((a, b), (u0, u1), hits) in [
            (
                (&spindle, &fixture),
                TOOL_FIXTURE_CONTACT_U,
                &mut tool_fixture,
            ),
            ((&spindle, &table), TOOL_WORKPIECE_CONTACT_U, &mut tool_work),
        ] {
            let shared = shared_voxels(&a[k], &b[k]);
            if u < u0 || u > u1 {
                assert_eq!(
                    shared, 0,
                    "frame {k} (u = {u}) outside contact ({u0}, {u1})"
                );
            } else if u0 + margin < u && u < u1 - margin {
                assert!(
                    shared >= 9,
                    "frame {k} (u = {u}): only {shared} shared voxels"
                );
                *hits += 1;
            }
        }
        // The fixture stands on the table: touching, never overlapping.
        assert_eq!(shared_voxels(&table[k], &fixture[k]), 0, "frame {k}");
    }
    assert!(
        tool_fixture >= 3 && tool_work >= 5,
        "{tool_fixture} {tool_work}"
    );
    // Contact runs over roughly 38 %..61 % of the run (tool and fixture), 12 %..45 % (workpiece).
    assert!(
        (TOOL_FIXTURE_CONTACT_U.0 - 0.38).abs() < 1e-9
            && (TOOL_FIXTURE_CONTACT_U.1 - 0.61333).abs() < 1e-5
    );
}

#[test]
fn machine_tool_stays_inside_and_survives_coarse_grids() {
    let s = scene(SceneName::MachineTool, 32, 64, VoxelEncoding::Bits);
    let edge = s.lattice().resolution * 32.0;
    let res = s.lattice().resolution;
    for body in s.bodies() {
        for k in 0..64 {
            let bb = body.aabb_at(s.time_s(k)).unwrap();
            for a in 0..3 {
                assert!(
                    bb.min[a] >= 2.0 * res && bb.max[a] <= edge - 2.0 * res,
                    "{} frame {k}: {bb:?}",
                    body.topic
                );
            }
        }
        // Every shape alone keeps most of its volume at grid 32.
        for shape in &body.shapes {
            let data = rasterize(
                std::slice::from_ref(shape),
                [0.0; 3],
                s.lattice(),
                VoxelEncoding::Bits,
            );
            let voxels: u32 = data.iter().map(|b| b.count_ones()).sum();
            let expected = shape.volume() / res.powi(3);
            assert!(
                f64::from(voxels) > 0.5 * expected,
                "{}: {voxels} voxels for {expected}",
                body.topic
            );
        }
    }
}
