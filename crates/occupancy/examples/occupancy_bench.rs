//! The benchmark: prints the median and best time of each case over repeated
//! runs. A cloud of at least `PARALLEL_POINTS` points is marked on two threads
//! (the caller and a scoped thread) unless a case says "one thread", and an
//! OctoMap is read on a second thread while the caller rasterises its leaves in
//! the cases that say "two threads" (the others read and rasterise on one): the
//! wall time is the figure, the calling thread's CPU time then counts its part.
//!
//! ```sh
//! cargo run --release --example bench            # all cases
//! cargo run --release --example bench -- cloud   # only cases whose name contains "cloud"
//! ```
//!
//! Cases: a 1-million-point surface cloud onto a 256³ lattice (several
//! layouts and options), and a 5 cm OctoMap of a 10 m × 10 m × 3 m cell
//! (floor, walls, boxes, free and unknown space; generated here and written by
//! the test writer in `tests/support/`) onto a 128³ lattice, parse and
//! rasterise together.

#[path = "../tests/support/octree_writer.rs"]
mod octree_writer;

use chronotope_occupancy::{
    read_leaves, CloudOptions, CloudRasterizer, Encoding, Fill, Lattice, Limits, OctomapMsg,
    OctomapOptions, OctomapRasterizer, PointCloud2Ref, PointField, RigidTransform, VoxelFrame,
    FLOAT32, FLOAT64,
};
use std::hint::black_box;
use std::time::{Duration, Instant};

/// A small deterministic generator (SplitMix64), so runs are comparable.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// CPU time of the calling thread.
fn thread_cpu() -> Duration {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec through a valid pointer.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    assert_eq!(rc, 0);
    Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32)
}

/// Runs `f` `runs` times after a warm-up; prints the median and best thread
/// CPU time, and the median wall time.
fn time(name: &str, filter: &str, runs: usize, mut f: impl FnMut()) {
    if !name.contains(filter) {
        return;
    }
    f(); // warm up: buffers allocated, caches filled
    let mut cpu = Vec::with_capacity(runs);
    let mut wall = Vec::with_capacity(runs);
    for _ in 0..runs {
        let (c, w) = (thread_cpu(), Instant::now());
        f();
        wall.push(w.elapsed());
        cpu.push(thread_cpu() - c);
    }
    cpu.sort();
    wall.sort();
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    println!(
        "{name:<62} cpu median {:>6.2} ms  best {:>6.2} ms | wall median {:>6.2} ms",
        ms(cpu[runs / 2]),
        ms(cpu[0]),
        ms(wall[runs / 2])
    );
}

/// Points on the surfaces of a 10 m cell: floor, four walls, boxes and a
/// cylinder, with 5 mm of noise, in random order or sorted like a scan.
fn cell_surface_points(n: usize, sorted: bool) -> Vec<[f64; 3]> {
    let mut rng = Rng(7);
    let boxes = [
        ([2.0, 2.0, 0.0], [3.5, 3.0, 1.2]),
        ([6.0, 1.5, 0.0], [8.5, 2.5, 0.9]),
        ([4.0, 6.0, 0.0], [5.0, 8.0, 2.0]),
        ([7.0, 6.5, 0.0], [9.0, 9.0, 1.5]),
    ];
    let mut pts = Vec::with_capacity(n);
    while pts.len() < n {
        let (u, v) = (rng.unit(), rng.unit());
        let p = match rng.next() % 8 {
            0 | 1 => [u * 10.0, v * 10.0, 0.0],
            2 => [0.02, u * 10.0, v * 3.0],
            3 => [9.98, u * 10.0, v * 3.0],
            4 => [u * 10.0, 0.02, v * 3.0],
            5 => [u * 10.0, 9.98, v * 3.0],
            6 => {
                let (lo, hi) = boxes[(rng.next() % 4) as usize];
                let face = rng.next() % 5;
                let d = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
                match face {
                    0 => [lo[0] + u * d[0], lo[1] + v * d[1], hi[2]],
                    1 => [lo[0], lo[1] + u * d[1], lo[2] + v * d[2]],
                    2 => [hi[0], lo[1] + u * d[1], lo[2] + v * d[2]],
                    3 => [lo[0] + u * d[0], lo[1], lo[2] + v * d[2]],
                    _ => [lo[0] + u * d[0], hi[1], lo[2] + v * d[2]],
                }
            }
            _ => {
                let a = u * std::f64::consts::TAU;
                [2.0 + 0.6 * a.cos(), 7.5 + 0.6 * a.sin(), v * 2.5]
            }
        };
        let noise = |r: &mut Rng| (r.unit() - 0.5) * 0.01;
        pts.push([
            p[0] + noise(&mut rng),
            p[1] + noise(&mut rng),
            p[2] + noise(&mut rng),
        ]);
    }
    if sorted {
        let key = |p: &[f64; 3]| {
            (
                (p[2] * 20.0) as i64,
                (p[1] * 20.0) as i64,
                (p[0] * 100.0) as i64,
            )
        };
        pts.sort_by_key(key);
    }
    pts
}

struct Cloud {
    fields: Vec<PointField<'static>>,
    data: Vec<u8>,
    width: u32,
    point_step: u32,
    big_endian: bool,
}

impl Cloud {
    /// x, y, z, intensity as f32 (point_step 16), little-endian: PCL's PointXYZI-like.
    fn xyzi(points: &[[f64; 3]]) -> Self {
        let mut data = Vec::with_capacity(points.len() * 16);
        for p in points {
            for v in [p[0] as f32, p[1] as f32, p[2] as f32, 1.0] {
                data.extend_from_slice(&v.to_le_bytes());
            }
        }
        let fields = ["x", "y", "z", "intensity"]
            .iter()
            .enumerate()
            .map(|(i, n)| PointField {
                name: n,
                offset: 4 * i as u32,
                datatype: FLOAT32,
                count: 1,
            })
            .collect();
        Cloud {
            fields,
            data,
            width: points.len() as u32,
            point_step: 16,
            big_endian: false,
        }
    }

    /// x, y, z as big-endian f64 after an 8-byte stamp (point_step 32).
    fn f64_be(points: &[[f64; 3]]) -> Self {
        let mut data = Vec::with_capacity(points.len() * 32);
        for p in points {
            data.extend_from_slice(&[0u8; 8]);
            for v in p {
                data.extend_from_slice(&v.to_be_bytes());
            }
        }
        let fields = ["x", "y", "z"]
            .iter()
            .enumerate()
            .map(|(i, n)| PointField {
                name: n,
                offset: 8 + 8 * i as u32,
                datatype: FLOAT64,
                count: 1,
            })
            .collect();
        Cloud {
            fields,
            data,
            width: points.len() as u32,
            point_step: 32,
            big_endian: true,
        }
    }

    fn msg(&self) -> PointCloud2Ref<'_> {
        PointCloud2Ref {
            height: 1,
            width: self.width,
            fields: &self.fields,
            is_bigendian: self.big_endian,
            point_step: self.point_step,
            row_step: self.width * self.point_step,
            data: &self.data,
            is_dense: true,
        }
    }
}

fn bench_clouds(filter: &str) {
    let runs = 31;
    let lattice = Lattice::new([-0.1, -0.1, -0.1], 0.04, [256, 256, 256]).unwrap();
    let random = cell_surface_points(1_000_000, false);
    let sorted = cell_surface_points(1_000_000, true);
    let cases: Vec<(&str, Cloud, CloudOptions, Encoding)> = vec![
        (
            "cloud 1M xyzi f32, random order -> 256^3 bits",
            Cloud::xyzi(&random),
            CloudOptions::new(),
            Encoding::Bits,
        ),
        (
            "cloud 1M xyzi f32, random order -> 256^3 bits, one thread",
            Cloud::xyzi(&random),
            CloudOptions::new().parallel(false),
            Encoding::Bits,
        ),
        (
            "cloud 1M xyzi f32, scan order -> 256^3 bits",
            Cloud::xyzi(&sorted),
            CloudOptions::new(),
            Encoding::Bits,
        ),
        (
            "cloud 1M f64 big-endian, random order -> 256^3 bits",
            Cloud::f64_be(&random),
            CloudOptions::new(),
            Encoding::Bits,
        ),
        (
            "cloud 1M xyzi, random -> 256^3 percent",
            Cloud::xyzi(&random),
            CloudOptions::new(),
            Encoding::Percent,
        ),
        (
            "cloud 1M xyzi, random, transform -> bits",
            Cloud::xyzi(&random),
            CloudOptions::new().transform(Some(
                RigidTransform::from_quaternion(
                    [0.0, 0.0, 0.0871557, 0.9961947],
                    [0.2, -0.1, 0.05],
                )
                .unwrap(),
            )),
            Encoding::Bits,
        ),
        (
            "cloud 1M xyzi, random, min_points 2 -> bits",
            Cloud::xyzi(&random),
            CloudOptions::new().min_points(2),
            Encoding::Bits,
        ),
        (
            "cloud 1M xyzi, random, dilate 5 cm -> bits",
            Cloud::xyzi(&random),
            CloudOptions::new().dilate_m(0.05),
            Encoding::Bits,
        ),
        (
            "cloud 1M xyzi, random, fill down -> bits",
            Cloud::xyzi(&random),
            CloudOptions::new().fill(Fill::down_to_floor()),
            Encoding::Bits,
        ),
    ];
    let mut frame = VoxelFrame::new();
    for (name, cloud, opts, enc) in &cases {
        let mut raster = CloudRasterizer::new(*opts);
        let msg = cloud.msg();
        time(name, filter, runs, || {
            black_box(raster.rasterize(&msg, &lattice, *enc, &mut frame).unwrap());
        });
    }
    {
        let stats = CloudRasterizer::new(CloudOptions::new())
            .rasterize(&cases[0].1.msg(), &lattice, Encoding::Bits, &mut frame)
            .unwrap();
        println!(
            "  (cloud: {} points, {} voxels marked, {} outside)",
            stats.points, stats.marked_voxels, stats.outside
        );
    }
}

/// The cell at 5 cm: what each depth-16 cell holds (log-odds, or unknown).
fn cell_map(max_likelihood: bool) -> Option<octree_writer::Tree> {
    const K: u32 = 32768;
    let (nx, ny, nz) = (200u32, 200u32, 60u32);
    let boxes: [([u32; 3], [u32; 3]); 5] = [
        ([40, 40, 1], [70, 60, 24]),
        ([120, 30, 1], [170, 50, 18]),
        ([80, 120, 1], [100, 160, 40]),
        ([140, 130, 1], [180, 180, 30]),
        ([30, 150, 1], [55, 170, 12]),
    ];
    let hash = |x: u32, y: u32, z: u32| {
        let mut h = (u64::from(x) * 0x9e37_79b9)
            ^ (u64::from(y) * 0x85eb_ca6b)
            ^ (u64::from(z) * 0xc2b2_ae35);
        h ^= h >> 15;
        h = h.wrapping_mul(0x2545_f491_4f6c_dd1d);
        h ^ (h >> 29)
    };
    let cell = move |key: [u32; 3]| -> Option<f32> {
        let (x, y, z) = (key[0] - K, key[1] - K, key[2] - K);
        let occupied = if max_likelihood {
            3.5
        } else {
            3.5 - (hash(x, y, z) % 4) as f32 * 0.7
        };
        // Floor and walls.
        if z == 0 || x == 0 || y == 0 || x == nx - 1 || y == ny - 1 {
            return Some(occupied);
        }
        // Boxes: shell occupied, inside unknown; the space behind each box
        // (toward +x, a shadow from a sensor at the cell's -x side) unknown up to its height.
        for (lo, hi) in &boxes {
            let inside = (lo[0]..hi[0]).contains(&x)
                && (lo[1]..hi[1]).contains(&y)
                && (lo[2]..hi[2]).contains(&z);
            if inside {
                let shell =
                    x == lo[0] || x == hi[0] - 1 || y == lo[1] || y == hi[1] - 1 || z == hi[2] - 1;
                return if shell { Some(occupied) } else { None };
            }
            if (hi[0]..hi[0] + 25).contains(&x) && (lo[1]..hi[1]).contains(&y) && z < hi[2] {
                return None;
            }
        }
        // Never seen: above 2.5 m.
        if z >= 50 {
            return None;
        }
        let h = hash(x, y, z);
        // Sensor noise: a few stray hits in free space.
        if h % 2000 == 0 {
            return Some(if max_likelihood { 3.5 } else { 0.85 });
        }
        if max_likelihood {
            return Some(-2.0);
        }
        // Free space: clamped far from surfaces, graded near them (not prunable).
        let near = z < 4
            || x < 4
            || y < 4
            || x > nx - 5
            || y > ny - 5
            || boxes.iter().any(|(lo, hi)| {
                (0..3).all(|a| [x, y, z][a] + 3 >= lo[a] && [x, y, z][a] < hi[a] + 3)
            });
        Some(if near {
            -0.4 * (1 + h % 4) as f32
        } else {
            -2.0
        })
    };
    octree_writer::from_cells([K, K, K], [K + nx, K + ny, K + nz], &cell)
}

fn bench_octomap(filter: &str) {
    let runs = 31;
    let res = 0.05;
    let full_tree = cell_map(false);
    let ml_tree = cell_map(true);
    let full = octree_writer::full(&full_tree, &[]);
    let binary = octree_writer::binary(&ml_tree, 0.0);
    let full_ml = octree_writer::full(&ml_tree, &[]);
    for (name, data, is_binary) in [
        ("full", &full, false),
        ("binary (max-likelihood, pruned)", &binary, true),
        ("full (max-likelihood, pruned)", &full_ml, false),
    ] {
        let msg = OctomapMsg {
            binary: is_binary,
            id: "OcTree",
            resolution: res,
            data,
        };
        let s = read_leaves(&msg, &OctomapOptions::new(), &Limits::default(), |_| {}).unwrap();
        println!(
            "  (octomap {name}: {:.2} MB, {} nodes, {} occupied + {} free leaves)",
            data.len() as f64 / 1e6,
            s.nodes,
            s.occupied_leaves,
            s.free_leaves
        );
    }
    // 128³ over the cell: 7.8125 cm voxels (not aligned with 5 cm leaves), and
    // 10 cm voxels (aligned: two leaves a side).
    let unaligned = Lattice::new([0.0, 0.0, -0.5], 10.0 / 128.0, [128, 128, 128]).unwrap();
    let aligned = Lattice::new([-1.4, -1.4, -0.5], 0.1, [128, 128, 128]).unwrap();
    let mut frame = VoxelFrame::new();
    for (lname, lattice) in [("7.8 cm", &unaligned), ("10 cm aligned", &aligned)] {
        for (sname, data, is_binary) in [("full", &full, false), ("binary", &binary, true)] {
            let msg = OctomapMsg {
                binary: is_binary,
                id: "OcTree",
                resolution: res,
                data,
            };
            for (oname, opts, enc) in [
                ("bits", OctomapOptions::new(), Encoding::Bits),
                (
                    "bits unknown-occupied",
                    OctomapOptions::new().unknown_occupied(true).parallel(false),
                    Encoding::Bits,
                ),
                (
                    "percent",
                    OctomapOptions::new().parallel(false),
                    Encoding::Percent,
                ),
                (
                    "percent two threads",
                    OctomapOptions::new(),
                    Encoding::Percent,
                ),
            ] {
                let mut raster = OctomapRasterizer::new(opts);
                let name = format!("octomap 5 cm {sname} -> 128^3 {lname} {oname}");
                time(&name, filter, runs, || {
                    black_box(raster.rasterize(&msg, lattice, enc, &mut frame).unwrap());
                });
            }
        }
    }
    let msg = OctomapMsg {
        binary: false,
        id: "OcTree",
        resolution: res,
        data: &full,
    };
    time(
        "octomap 5 cm full, parse only (no lattice)",
        filter,
        runs,
        || {
            black_box(read_leaves(
                &msg,
                &OctomapOptions::new(),
                &Limits::default(),
                |l| {
                    black_box(l);
                },
            ))
            .unwrap();
        },
    );
    let msg = OctomapMsg {
        binary: true,
        id: "OcTree",
        resolution: res,
        data: &binary,
    };
    time(
        "octomap 5 cm binary, parse only (no lattice)",
        filter,
        runs,
        || {
            black_box(read_leaves(
                &msg,
                &OctomapOptions::new(),
                &Limits::default(),
                |l| {
                    black_box(l);
                },
            ))
            .unwrap();
        },
    );
}

fn main() {
    let filter = std::env::args().nth(1).unwrap_or_default();
    println!("chronotope-occupancy benchmark: 31 runs per case after a warm-up");
    // Each family's data is made only when a case of it is asked for.
    if filter.is_empty() || filter.contains("cloud") {
        bench_clouds(&filter);
    }
    if filter.is_empty() || filter.contains("octomap") {
        bench_octomap(&filter);
    }
}
