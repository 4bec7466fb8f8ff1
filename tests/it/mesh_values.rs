//! Hypervolumes against exact values, edge-case inputs, and bad input.

use crate::common;

use chronotope::mesh::validate::{check_closed, hypervolume24};
use chronotope::mesh::{FrameRef, MeshError, Mesher, MesherOptions};
use common::*;

/// 3D volume (voxel units) of the solid marching cubes makes of an a×b×c block of voxels:
/// the block with chamfered edges and corners (midpoint vertices).
fn block_volume(a: f64, b: f64, c: f64) -> f64 {
    let (a, b, c) = (a - 1.0, b - 1.0, c - 1.0);
    a * b * c + (a * b + b * c + a * c) + (a + b + c) / 2.0 + 1.0 / 6.0
}

fn static_frames(
    frames: usize,
    period_ns: i64,
    encoding: u8,
    size: [u32; 3],
    occ: impl Fn(usize, usize, usize) -> bool + Copy,
) -> Vec<TestFrame> {
    (0..frames)
        .map(|k| TestFrame {
            stamp_ns: 5_000_000_000 + k as i64 * period_ns,
            encoding,
            data: if encoding == 0 {
                bits_data(size, occ)
            } else {
                percent_data(size, |x, y, z| if occ(x, y, z) { 100 } else { 0 })
            },
        })
        .collect()
}

#[test]
fn box_hypervolume_is_exact() {
    for encoding in [0u8, 1] {
        for (size, lo, hi) in [
            ([6u32, 5, 7], [1usize, 1, 2], [4usize, 3, 5]),
            ([4, 4, 4], [0, 0, 0], [3, 3, 3]), // touches every border: the whole grid
            ([3, 3, 3], [1, 1, 1], [1, 1, 1]), // a single voxel
        ] {
            let inside = |x: usize, y: usize, z: usize| {
                (lo[0]..=hi[0]).contains(&x)
                    && (lo[1]..=hi[1]).contains(&y)
                    && (lo[2]..=hi[2]).contains(&z)
            };
            let frames = static_frames(4, 250_000_000, encoding, size, inside);
            let h = 0.05;
            let r = run(&frames, size, h);
            let dims = [0, 1, 2].map(|k| (hi[k] - lo[k] + 1) as f64);
            let exact = block_volume(dims[0], dims[1], dims[2]) * h * h * h * 0.75;
            let got = r.stats.hypervolume_m3s;
            assert!(
                (got - exact).abs() <= 1e-12 * exact,
                "encoding {encoding}, block {dims:?}: {got} vs {exact}"
            );
            assert!(check_closed(&glued(&r)).is_closed());
            assert_eq!(
                hypervolume24(&glued(&r)) as f64 / 24.0,
                r.stats.hypervolume_lattice
            );
        }
    }
}

/// Frames of a sphere of radius `rad` [m] moving from `c0` with velocity `v` [m/s] in the
/// unit cube at grid n; `frames` frames over [0, 1] s. PERCENT values by 6^3 supersampling.
fn sphere_frames(
    n: u32,
    frames: usize,
    rad: f64,
    c0: [f64; 3],
    v: [f64; 3],
    encoding: u8,
) -> Vec<TestFrame> {
    let h = 1.0 / f64::from(n);
    let size = [n; 3];
    (0..frames)
        .map(|k| {
            let t = k as f64 / (frames - 1) as f64;
            let c = [0, 1, 2].map(|i| c0[i] + v[i] * t);
            let inside =
                |p: [f64; 3]| (0..3).map(|i| (p[i] - c[i]).powi(2)).sum::<f64>() <= rad * rad;
            let centre = |x: usize, y: usize, z: usize| {
                [
                    (x as f64 + 0.5) * h,
                    (y as f64 + 0.5) * h,
                    (z as f64 + 0.5) * h,
                ]
            };
            let data = if encoding == 0 {
                bits_data(size, |x, y, z| inside(centre(x, y, z)))
            } else {
                percent_data(size, |x, y, z| {
                    let p = centre(x, y, z);
                    let d = (0..3).map(|i| (p[i] - c[i]).powi(2)).sum::<f64>().sqrt() - rad;
                    if d < -h {
                        100
                    } else if d > h {
                        0
                    } else {
                        let m = 6;
                        let mut count = 0;
                        for i in 0..m {
                            for j in 0..m {
                                for l in 0..m {
                                    let q = [
                                        p[0] + ((i as f64 + 0.5) / m as f64 - 0.5) * h,
                                        p[1] + ((j as f64 + 0.5) / m as f64 - 0.5) * h,
                                        p[2] + ((l as f64 + 0.5) / m as f64 - 0.5) * h,
                                    ];
                                    count += usize::from(inside(q));
                                }
                            }
                        }
                        ((100 * count) as f64 / (m * m * m) as f64).round() as u8
                    }
                })
            };
            TestFrame {
                stamp_ns: (t * 1e9).round() as i64,
                encoding,
                data,
            }
        })
        .collect()
}

#[test]
fn moving_sphere_hypervolume_converges() {
    let rad = 0.3;
    let exact = 4.0 / 3.0 * std::f64::consts::PI * rad * rad * rad * 1.0;
    for encoding in [0u8, 1] {
        let mut errors = Vec::new();
        for n in [12u32, 24, 48] {
            // Half a voxel per frame, so the time discretisation refines with the grid.
            let frames = (0.2 * f64::from(n) / 0.5).round() as usize + 1;
            let f = sphere_frames(n, frames, rad, [0.4, 0.5, 0.5], [0.2, 0.0, 0.0], encoding);
            let r = run(&f, [n; 3], 1.0 / f64::from(n));
            assert!(r.stats.closed.is_closed());
            errors.push((r.stats.hypervolume_m3s - exact).abs() / exact);
        }
        assert!(
            errors[2] < errors[0],
            "encoding {encoding}: errors {errors:?} do not shrink"
        );
        let bound = if encoding == 0 { 0.05 } else { 0.01 };
        assert!(
            errors[2] < bound,
            "encoding {encoding}: error at 48 is {}",
            errors[2]
        );
    }
}

#[test]
fn empty_frames_give_an_empty_closed_mesh() {
    let size = [4, 3, 2];
    let r = run(&static_frames(3, 1000, 0, size, |_, _, _| false), size, 0.1);
    assert_eq!(r.slabs.len(), 2);
    assert_eq!(r.stats.tets, 0);
    assert_eq!(r.stats.vertices, 0);
    assert!(r.stats.closed.is_closed());
    assert_eq!(r.stats.hypervolume_m3s, 0.0);
}

#[test]
fn one_frame_gives_no_slab_and_no_volume() {
    let size = [3, 3, 3];
    let r = run(
        &static_frames(1, 1000, 0, size, |x, _, _| x == 1),
        size,
        0.1,
    );
    assert!(r.slabs.is_empty());
    assert_eq!(r.stats.frames, 1);
    assert_eq!(r.stats.tets, 0);
    assert_eq!(r.stats.hypervolume_m3s, 0.0);
}

#[test]
fn occupancy_exactly_at_the_iso_level_counts_as_occupied() {
    let size = [5, 5, 5];
    let frames: Vec<TestFrame> = (0..3)
        .map(|k| TestFrame {
            stamp_ns: k * 100,
            encoding: 1,
            data: percent_data(size, |x, y, z| {
                if (1..4).contains(&x) && (1..4).contains(&y) && (1..4).contains(&z) {
                    50
                } else {
                    0
                }
            }),
        })
        .collect();
    let r = run(&frames, size, 1.0);
    assert!(r.stats.closed.is_closed());
    assert!(r.stats.hypervolume_m3s > 0.0);
    // Surface vertices are pushed one sub-lattice step off the samples (never on them).
    let scale = r.slabs[0].geometry.scale;
    for p in &r.slabs[0].mesh.vertices {
        let off: Vec<i32> = p[..3]
            .iter()
            .map(|c| c.rem_euclid(scale))
            .filter(|&m| m != 0)
            .collect();
        assert_eq!(off.len(), 1, "vertex {p:?}");
        assert!(off[0] == 1 || off[0] == scale - 1, "vertex {p:?}");
    }
}

fn frame<'a>(
    stamp_ns: i64,
    size: [u32; 3],
    resolution: f64,
    encoding: u8,
    data: &'a [u8],
) -> FrameRef<'a> {
    FrameRef {
        stamp_ns,
        origin: [0.0; 3],
        resolution,
        size,
        encoding,
        data,
    }
}

#[test]
fn bad_frames_are_refused_with_a_reason_and_nothing_else_is_lost() {
    let size = [4u32, 4, 4];
    let good = bits_data(size, |x, y, z| x == 1 && y == 2 && z < 3);
    let mut m = Mesher::new(MesherOptions::default()).unwrap();
    assert!(m.push(&frame(0, size, 0.1, 0, &good)).unwrap().is_none());

    let short = &good[..good.len() - 1];
    assert!(matches!(
        m.push(&frame(1, size, 0.1, 0, short)),
        Err(MeshError::DataLength {
            expected: 8,
            got: 7,
            ..
        })
    ));
    for res in [0.0, -0.1, f64::NAN, f64::INFINITY] {
        assert!(
            matches!(
                m.push(&frame(1, size, res, 0, &good)),
                Err(MeshError::BadResolution { .. })
            ),
            "{res}"
        );
    }
    assert!(matches!(
        m.push(&frame(1, size, 0.1, 7, &good)),
        Err(MeshError::UnknownEncoding { encoding: 7 })
    ));
    // Sizes whose product would not fit: refused before any allocation.
    let huge = [u32::MAX, u32::MAX, u32::MAX];
    assert!(matches!(
        m.push(&frame(1, huge, 0.1, 0, &good)),
        Err(MeshError::TooLarge {
            voxels: u64::MAX,
            ..
        })
    ));
    assert!(matches!(
        m.push(&frame(1, [100_000, 100_000, 1000], 0.1, 1, &good)),
        Err(MeshError::TooLarge { .. })
    ));
    assert!(matches!(
        m.push(&frame(1, [0, 4, 4], 0.1, 0, &[])),
        Err(MeshError::EmptySize { .. })
    ));
    // A thin grid whose decoded rows would cost far more than its data (2^30 rows of one
    // voxel): refused before allocating.
    let thin = vec![0u8; 1 << 27];
    assert!(matches!(
        m.push(&frame(1, [1, 1 << 15, 1 << 15], 0.1, 0, &thin)),
        Err(MeshError::TooMuchMemory { .. })
    ));
    // An axis so long that lattice coordinates would overflow i32 (at PERCENT's scale 64).
    assert!(matches!(
        m.push(&frame(1, [40_000_000, 1, 1], 0.1, 1, &good)),
        Err(MeshError::LatticeOverflow { scale: 64, .. })
    ));
    // Another lattice than the first frame's.
    let other = bits_data([4, 4, 5], |_, _, _| false);
    assert!(matches!(
        m.push(&frame(1, [4, 4, 5], 0.1, 0, &other)),
        Err(MeshError::LatticeMismatch { .. })
    ));
    assert!(matches!(
        m.push(&frame(1, size, 0.2, 0, &good)),
        Err(MeshError::LatticeMismatch { .. })
    ));
    assert!(matches!(
        m.push(&frame(1, size, 0.1, 1, &[0u8; 64])),
        Err(MeshError::LatticeMismatch { .. })
    ));
    // A stamp that does not increase.
    assert!(matches!(
        m.push(&frame(0, size, 0.1, 0, &good)),
        Err(MeshError::StampNotIncreasing {
            previous_ns: 0,
            got_ns: 0
        })
    ));
    assert!(matches!(
        m.push(&frame(-5, size, 0.1, 0, &good)),
        Err(MeshError::StampNotIncreasing { .. })
    ));
    let mut nan_origin = frame(1, size, 0.1, 0, &good);
    nan_origin.origin[1] = f64::NAN;
    assert!(matches!(
        m.push(&nan_origin),
        Err(MeshError::BadOrigin { .. })
    ));
    assert_eq!(m.skipped(), 17);
    assert_eq!(m.frames(), 1);

    // The stream goes on as if the bad frames had never come.
    let slab = m
        .push(&frame(10, size, 0.1, 0, &good))
        .unwrap()
        .expect("slab");
    let mut clean = Mesher::new(MesherOptions::default()).unwrap();
    clean.push(&frame(0, size, 0.1, 0, &good)).unwrap();
    let want = clean
        .push(&frame(10, size, 0.1, 0, &good))
        .unwrap()
        .unwrap();
    assert_eq!(slab, want);
}

#[test]
fn errors_name_what_was_wrong() {
    let e = MeshError::DataLength {
        expected: 8,
        got: 7,
        encoding: chronotope::mesh::Encoding::Bits,
    };
    assert_eq!(
        e.to_string(),
        "data is 7 bytes but sizes and encoding Bits need 8"
    );
    let e = MeshError::StampNotIncreasing {
        previous_ns: 5,
        got_ns: 3,
    };
    assert!(e.to_string().contains("does not increase"));
}

#[test]
fn bad_options_are_refused() {
    let o = MesherOptions {
        percent_scale: 3,
        ..MesherOptions::default()
    };
    assert!(matches!(
        Mesher::new(o),
        Err(MeshError::BadOption {
            name: "percent_scale",
            ..
        })
    ));
    let mut o = MesherOptions::default();
    o.decode.iso_percent = 0;
    assert!(Mesher::new(o).is_err());
}

#[test]
fn blocks_ending_in_the_last_column_are_exact_at_word_boundaries() {
    // x sizes around 64 and 128 exercise the bit copy straddling words and the carry from
    // the next word in the marcher.
    for encoding in [0u8, 1] {
        for sx in [1u32, 2, 61, 62, 63, 64, 65, 66, 126, 127, 128, 129, 130] {
            let size = [sx, 3, 3];
            let lo = sx.saturating_sub(3) as usize;
            let inside = |x: usize, y: usize, z: usize| x >= lo && y == 1 && z >= 1;
            let frames = static_frames(3, 100_000_000, encoding, size, inside);
            let r = run(&frames, size, 0.01);
            let dims = [(sx as usize - lo) as f64, 1.0, 2.0];
            let exact = block_volume(dims[0], dims[1], dims[2]) * 1e-6 * 0.2;
            assert!(
                r.stats.closed.is_closed(),
                "x size {sx}, encoding {encoding}"
            );
            assert!(
                (r.stats.hypervolume_m3s - exact).abs() <= 1e-12 * exact,
                "x size {sx}, encoding {encoding}: {} vs {exact}",
                r.stats.hypervolume_m3s
            );
        }
    }
}

#[test]
fn uneven_frame_periods_give_the_exact_hypervolume() {
    let size = [5u32, 5, 5];
    let inside =
        |x: usize, y: usize, z: usize| (1..4).contains(&x) && (1..3).contains(&y) && z == 2;
    let stamps = [0i64, 100_000_000, 700_000_000, 750_000_000];
    let frames: Vec<TestFrame> = stamps
        .iter()
        .map(|&s| TestFrame {
            stamp_ns: s,
            encoding: 0,
            data: bits_data(size, inside),
        })
        .collect();
    let r = run(&frames, size, 0.02);
    let exact = block_volume(3.0, 2.0, 1.0) * 0.02f64.powi(3) * 0.75;
    assert!(
        (r.stats.hypervolume_m3s - exact).abs() <= 1e-12 * exact,
        "{} vs {exact}",
        r.stats.hypervolume_m3s
    );
}

#[test]
fn noise_frames_beyond_the_slab_budget_are_refused_not_meshed() {
    let size = [16u32, 16, 16];
    let noise = |k: u64| {
        bits_data(size, move |x, y, z| {
            ((x * 7 + y * 13 + z * 29) as u64 ^ k).count_ones() % 2 == 1
        })
    };
    let opts = MesherOptions {
        max_slab_tets: 5_000,
        ..MesherOptions::default()
    };
    let mut m = Mesher::new(opts).unwrap();
    let (a, b) = (noise(1), noise(2));
    m.push(&frame(0, size, 0.1, 0, &a)).unwrap();
    assert!(matches!(
        m.push(&frame(1, size, 0.1, 0, &b)),
        Err(MeshError::SlabTooComplex { limit: 5_000 })
    ));
    assert_eq!((m.frames(), m.skipped()), (1, 1));
    // The state is unchanged: a simple frame after it meshes from the first frame.
    let empty = bits_data(size, |_, _, _| false);
    let slab = m.push(&frame(2, size, 0.1, 0, &empty));
    assert!(matches!(slab, Err(MeshError::SlabTooComplex { .. })) || slab.unwrap().is_some());
}
