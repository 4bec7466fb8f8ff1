//! Point clouds in every layout give the same voxels; the rules for NaN,
//! outside points, min_points, dilation, fill and transforms.

use chronotope_occupancy::{
    Axis, CloudOptions, CloudRasterizer, CloudStats, Encoding, Fill, Lattice, PointCloud2Ref,
    PointField, RigidTransform, Toward, VoxelFrame, FLOAT32, FLOAT64,
};
use proptest::prelude::*;

/// How a test cloud is laid out.
#[derive(Clone, Debug)]
pub struct Layout {
    pub f64s: [bool; 3],
    pub offsets: [u32; 3],
    pub point_step: u32,
    pub big_endian: bool,
    pub height: u32,
    pub row_pad: u32,
}

impl Layout {
    pub fn plain() -> Self {
        Layout {
            f64s: [false; 3],
            offsets: [0, 4, 8],
            point_step: 16,
            big_endian: false,
            height: 1,
            row_pad: 0,
        }
    }
}

/// An encoded cloud: its fields and data.
pub struct Encoded {
    pub fields: Vec<PointField<'static>>,
    pub data: Vec<u8>,
    pub height: u32,
    pub width: u32,
    pub point_step: u32,
    pub row_step: u32,
    pub big_endian: bool,
}

impl Encoded {
    pub fn cloud(&self) -> PointCloud2Ref<'_> {
        PointCloud2Ref {
            height: self.height,
            width: self.width,
            fields: &self.fields,
            is_bigendian: self.big_endian,
            point_step: self.point_step,
            row_step: self.row_step,
            data: &self.data,
            is_dense: false,
        }
    }
}

/// Encodes points (the count must divide by the layout's height), filling
/// other bytes with 0xAB so stray reads show.
pub fn encode(points: &[[f64; 3]], l: &Layout) -> Encoded {
    let names = ["x", "y", "z"];
    let mut fields: Vec<PointField<'static>> = (0..3)
        .map(|a| PointField {
            name: names[a],
            offset: l.offsets[a],
            datatype: if l.f64s[a] { FLOAT64 } else { FLOAT32 },
            count: 1,
        })
        .collect();
    fields.push(PointField {
        name: "intensity",
        offset: 0,
        datatype: 2,
        count: 1,
    });
    fields.rotate_left(1);
    let width = points.len() as u32 / l.height;
    let row_step = width * l.point_step + l.row_pad;
    let mut data = vec![0xABu8; (row_step * l.height) as usize];
    for (n, p) in points.iter().enumerate() {
        let (r, c) = (n as u32 / width, n as u32 % width);
        let base = (r * row_step + c * l.point_step) as usize;
        for a in 0..3 {
            let o = base + l.offsets[a] as usize;
            let bytes: Vec<u8> = match (l.f64s[a], l.big_endian) {
                (false, false) => (p[a] as f32).to_le_bytes().to_vec(),
                (false, true) => (p[a] as f32).to_be_bytes().to_vec(),
                (true, false) => p[a].to_le_bytes().to_vec(),
                (true, true) => p[a].to_be_bytes().to_vec(),
            };
            data[o..o + bytes.len()].copy_from_slice(&bytes);
        }
    }
    Encoded {
        fields,
        data,
        height: l.height,
        width,
        point_step: l.point_step,
        row_step,
        big_endian: l.big_endian,
    }
}

pub fn rasterize(
    e: &Encoded,
    lattice: &Lattice,
    enc: Encoding,
    opts: CloudOptions,
) -> (Vec<u8>, CloudStats) {
    let mut frame = VoxelFrame::new();
    let stats = CloudRasterizer::new(opts)
        .rasterize(&e.cloud(), lattice, enc, &mut frame)
        .unwrap();
    (frame.take_data(), stats)
}

fn bit(data: &[u8], n: usize) -> bool {
    data[n / 8] >> (n % 8) & 1 == 1
}

fn layouts() -> impl Strategy<Value = Layout> {
    (
        any::<[bool; 3]>(),
        any::<bool>(),
        0u32..3,
        0u32..7,
        prop::sample::select(vec![1u32, 2, 4]),
        0u32..4,
    )
        .prop_map(|(f64s, big_endian, order, pad, height, gap)| {
            // Lay x, y, z out in one of three orders with `gap` bytes between.
            let sizes = f64s.map(|d| if d { 8 } else { 4 });
            let order = [[0, 1, 2], [2, 0, 1], [1, 2, 0]][order as usize];
            let mut offsets = [0u32; 3];
            let mut at = 1 + gap; // after a 1-byte intensity
            for &a in &order {
                offsets[a] = at;
                at += sizes[a] + gap;
            }
            Layout {
                f64s,
                offsets,
                point_step: at + 3,
                big_endian,
                height,
                row_pad: pad,
            }
        })
}

fn f32_points(n: usize) -> impl Strategy<Value = Vec<[f64; 3]>> {
    let coord = prop_oneof![
        8 => (-0.3f32..1.9).prop_map(f64::from),
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
    ];
    proptest::collection::vec([coord.clone(), coord.clone(), coord], n)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn every_layout_gives_the_voxels_of_the_plain_one(points in f32_points(24), layout in layouts()) {
        let lattice = Lattice::new([-0.1, 0.0, 0.05], 0.1, [13, 9, 11]).unwrap();
        let plain = encode(&points, &Layout::plain());
        let other = encode(&points, &layout);
        for enc in [Encoding::Bits, Encoding::Percent] {
            let (a, sa) = rasterize(&plain, &lattice, enc, CloudOptions::new());
            let (b, sb) = rasterize(&other, &lattice, enc, CloudOptions::new());
            prop_assert_eq!(a, b);
            prop_assert_eq!(sa.nonfinite, sb.nonfinite);
            prop_assert_eq!(sa.outside, sb.outside);
        }
    }

    #[test]
    fn each_finite_point_marks_exactly_its_voxel(points in f32_points(40)) {
        let lattice = Lattice::new([-0.1, 0.0, 0.05], 0.1, [13, 9, 11]).unwrap();
        let (bits, stats) = rasterize(&encode(&points, &Layout::plain()), &lattice, Encoding::Bits, CloudOptions::new());
        let mut want = vec![false; 13 * 9 * 11];
        let (mut nonfinite, mut outside) = (0, 0);
        for p in &points {
            let p = p.map(|v| f64::from(v as f32));
            if p.iter().any(|v| !v.is_finite()) { nonfinite += 1; continue; }
            let o = lattice.origin();
            let u: Vec<f64> = (0..3).map(|a| ((p[a] - o[a]) * (1.0 / 0.1)).floor()).collect();
            let n = [13.0, 9.0, 11.0];
            if (0..3).all(|a| u[a] >= 0.0 && u[a] < n[a]) {
                want[u[0] as usize + 13 * (u[1] as usize + 9 * u[2] as usize)] = true;
            } else { outside += 1; }
        }
        let got: Vec<bool> = (0..want.len()).map(|n| bit(&bits, n)).collect();
        prop_assert_eq!(got, want);
        prop_assert_eq!((stats.nonfinite, stats.outside), (nonfinite, outside));
        prop_assert_eq!(stats.points, 40);
    }

    /// Dilation is conservative: every voxel whose cube comes within the margin
    /// of a point is occupied, and nothing farther than the margin from a
    /// marked voxel's cube is.
    #[test]
    fn dilation_covers_the_margin_around_each_point_and_no_more(
        p in proptest::array::uniform3(0.0f64..1.0),
        dilate in 0.0f64..0.35,
    ) {
        let res = 0.1;
        let lattice = Lattice::new([-0.5, -0.5, -0.5], res, [20, 20, 20]).unwrap();
        let e = encode(&[p], &Layout { f64s: [true; 3], offsets: [0, 8, 16], point_step: 24, ..Layout::plain() });
        let (bits, _) = rasterize(&e, &lattice, Encoding::Bits, CloudOptions::new().dilate_m(dilate));
        let v = p.map(|c| ((c + 0.5) / res).floor() as i64);
        for k in 0..20i64 {
            for j in 0..20i64 {
                for i in 0..20i64 {
                    let idx = [i, j, k];
                    // Distance from the point to voxel (i,j,k)'s cube.
                    let d2: f64 = (0..3).map(|a| {
                        let lo = -0.5 + idx[a] as f64 * res;
                        let d = (lo - p[a]).max(p[a] - (lo + res)).max(0.0);
                        d * d
                    }).sum();
                    // Distance between the marked voxel's cube and this cube, in edges.
                    let g2: f64 = (0..3).map(|a| {
                        let g = ((idx[a] - v[a]).abs() - 1).max(0) as f64;
                        g * g
                    }).sum();
                    let set = bit(&bits, (i + 20 * (j + 20 * k)) as usize);
                    if d2.sqrt() < dilate * (1.0 - 1e-9) { prop_assert!(set, "voxel {:?} within {} of the point", idx, dilate); }
                    if g2.sqrt() * res > dilate * (1.0 + 1e-6) + 1e-12 && idx != v { prop_assert!(!set, "voxel {:?} beyond the margin", idx); }
                }
            }
        }
    }

    /// Each point fills its column from its voxel to the chosen face, also
    /// when it lies beyond the opposite face (a surface above the lattice).
    #[test]
    fn column_fills_run_to_the_chosen_face(
        points in proptest::collection::vec(proptest::array::uniform3(-0.15f64..0.85), 1..6),
        axis in 0usize..3,
        to_min in any::<bool>(),
    ) {
        let lattice = Lattice::new([0.0; 3], 0.1, [6, 5, 7]).unwrap();
        let axes = [Axis::X, Axis::Y, Axis::Z];
        let toward = if to_min { Toward::Min } else { Toward::Max };
        let e = encode(&points, &Layout::plain());
        let (filled, stats) = rasterize(&e, &lattice, Encoding::Bits, CloudOptions::new().fill(Fill::Columns { axis: axes[axis], toward }));
        let n = [6i64, 5, 7];
        let cells: Vec<[i64; 3]> = points.iter().map(|p| p.map(|c| ((f64::from(c as f32)) * (1.0 / 0.1)).floor() as i64)).collect();
        let mut count = 0;
        for k in 0..7i64 { for j in 0..5i64 { for i in 0..6i64 {
            let v = [i, j, k];
            let want = cells.iter().any(|u| {
                (0..3).filter(|&b| b != axis).all(|b| u[b] == v[b])
                    && if to_min { u[axis] >= v[axis] } else { u[axis] <= v[axis] }
                    && if to_min { u[axis] >= 0 } else { u[axis] < n[axis] }
            });
            let idx = (i + 6 * (j + 5 * k)) as usize;
            prop_assert_eq!(bit(&filled, idx), want, "voxel {:?}", v);
            count += usize::from(want);
        }}}
        prop_assert_eq!(stats.occupied_voxels, count as u64);
    }
}

#[test]
fn nan_and_infinite_points_are_skipped_and_counted() {
    let pts = [
        [0.05, 0.05, 0.05],
        [f64::NAN, 0.0, 0.0],
        [0.0, f64::NEG_INFINITY, 0.0],
        [5.0, 0.0, 0.0],
    ];
    let lattice = Lattice::new([0.0; 3], 0.1, [2, 2, 2]).unwrap();
    let (bits, stats) = rasterize(
        &encode(&pts, &Layout::plain()),
        &lattice,
        Encoding::Bits,
        CloudOptions::new(),
    );
    assert_eq!(bits, vec![1]);
    assert_eq!(
        (
            stats.points,
            stats.nonfinite,
            stats.outside,
            stats.marked_voxels
        ),
        (4, 2, 1, 1)
    );
}

#[test]
fn min_points_rejects_voxels_with_fewer_points() {
    let mut pts = vec![[0.05, 0.05, 0.05]; 3];
    pts.push([0.15, 0.05, 0.05]);
    pts.extend([[0.05, 0.15, 0.05]; 2]);
    let lattice = Lattice::new([0.0; 3], 0.1, [2, 2, 1]).unwrap();
    let e = encode(&pts, &Layout::plain());
    let (bits, _) = rasterize(
        &e,
        &lattice,
        Encoding::Bits,
        CloudOptions::new().min_points(2),
    );
    assert_eq!(bits, vec![0b0101]);
    let (bits, _) = rasterize(
        &e,
        &lattice,
        Encoding::Bits,
        CloudOptions::new().min_points(3),
    );
    assert_eq!(bits, vec![0b0001]);
    let (pct, _) = rasterize(
        &e,
        &lattice,
        Encoding::Percent,
        CloudOptions::new().min_points(2),
    );
    assert_eq!(pct, vec![100, 0, 100, 0]);
}

#[test]
fn a_transformed_cloud_lands_where_its_transformed_points_do() {
    let pts = [[0.05, 0.05, 0.05], [0.25, 0.05, 0.15], [0.35, 0.15, 0.05]];
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let t = RigidTransform::from_quaternion([0.0, 0.0, h, h], [0.5, 0.0, 0.0]).unwrap();
    let moved: Vec<[f64; 3]> = pts.iter().map(|p| t.apply(*p)).collect();
    let lattice = Lattice::new([0.0; 3], 0.1, [8, 8, 4]).unwrap();
    let layout = Layout {
        f64s: [true; 3],
        offsets: [0, 8, 16],
        point_step: 24,
        ..Layout::plain()
    };
    let (a, _) = rasterize(
        &encode(&pts, &layout),
        &lattice,
        Encoding::Bits,
        CloudOptions::new().transform(Some(t)),
    );
    let (b, _) = rasterize(
        &encode(&moved, &layout),
        &lattice,
        Encoding::Bits,
        CloudOptions::new(),
    );
    assert_eq!(a, b);
    assert!(a.iter().any(|&x| x != 0));
}

#[test]
fn points_just_outside_still_reach_inside_through_the_margin() {
    let lattice = Lattice::new([0.0; 3], 0.1, [5, 5, 5]).unwrap();
    // 0.04 m beyond the x = 0 face: within a 0.05 m margin of voxel (0, 2, 2).
    let e = encode(&[[-0.04, 0.25, 0.25]], &Layout::plain());
    let (bits, stats) = rasterize(
        &e,
        &lattice,
        Encoding::Bits,
        CloudOptions::new().dilate_m(0.05),
    );
    assert_eq!(stats.margin_points, 1);
    assert!(bit(&bits, 0 + 5 * (2 + 5 * 2)));
    let (_, stats) = rasterize(
        &e,
        &lattice,
        Encoding::Bits,
        CloudOptions::new().dilate_m(0.03),
    );
    assert_eq!(
        (stats.margin_points, stats.outside, stats.occupied_voxels),
        (0, 1, 0)
    );
}

#[test]
fn a_point_above_the_top_fills_its_whole_column_down_to_the_floor() {
    let lattice = Lattice::new([0.0; 3], 0.1, [3, 3, 4]).unwrap();
    let e = encode(&[[0.15, 0.15, 2.0]], &Layout::plain());
    let (pct, stats) = rasterize(
        &e,
        &lattice,
        Encoding::Percent,
        CloudOptions::new().fill(Fill::down_to_floor()),
    );
    assert_eq!(stats.margin_points, 1);
    for k in 0..4 {
        assert_eq!(pct[4 + 9 * k], 100);
    }
    assert_eq!(stats.occupied_voxels, 4);
    // Below the floor it fills nothing.
    let e = encode(&[[0.15, 0.15, -2.0]], &Layout::plain());
    let (_, stats) = rasterize(
        &e,
        &lattice,
        Encoding::Percent,
        CloudOptions::new().fill(Fill::down_to_floor()),
    );
    assert_eq!((stats.outside, stats.occupied_voxels), (1, 0));
}

#[test]
fn one_rasteriser_serves_frames_of_changing_lattices_and_options() {
    let pts = [[0.05, 0.05, 0.05], [0.95, 0.05, 0.05]];
    let e = encode(&pts, &Layout::plain());
    let mut raster = CloudRasterizer::new(CloudOptions::new().dilate_m(0.1).min_points(1));
    let mut frame = VoxelFrame::new();
    for n in [10u32, 3, 70, 10] {
        let lattice = Lattice::new([0.0; 3], 0.1, [n, 2, 2]).unwrap();
        let stats = raster
            .rasterize(&e.cloud(), &lattice, Encoding::Bits, &mut frame)
            .unwrap();
        assert_eq!(frame.occupied(0, 1, 1), Some(true));
        assert_eq!(stats.outside, u64::from(n < 10));
        assert_eq!(frame.data().len(), (n as usize * 4).div_ceil(8));
    }
}

#[test]
fn an_empty_cloud_gives_an_empty_frame() {
    let e = encode(&[], &Layout::plain());
    let lattice = Lattice::new([0.0; 3], 0.1, [3, 3, 3]).unwrap();
    let (pct, stats) = rasterize(&e, &lattice, Encoding::Percent, CloudOptions::new());
    assert_eq!(pct, vec![0; 27]);
    assert_eq!(stats.points, 0);
}

#[test]
fn a_large_cloud_split_over_two_threads_gives_the_frame_and_counts_of_one() {
    // Three rows of a padded organised cloud: the halves split inside the middle row.
    let (height, width) = (3u32, 100_003u32);
    assert!(u64::from(height * width) >= chronotope_occupancy::cloud::PARALLEL_POINTS);
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut unit = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let points: Vec<[f64; 3]> = (0..height * width)
        .map(|i| match i % 97 {
            0 => [f64::NAN, 0.1, 0.1],
            1 => [unit() * 3.0 - 1.0, 0.2, 0.2], // often outside, some within the margin
            _ => [unit() * 0.62, unit() * 0.5, unit() * 0.35],
        })
        .collect();
    let layout = Layout {
        height,
        row_pad: 12,
        ..Layout::plain()
    };
    let e = encode(&points, &layout);
    let lattice = Lattice::new([0.0, 0.0, 0.0], 0.01, [61, 50, 33]).unwrap();
    let turn = RigidTransform::from_quaternion([0.0, 0.0, 0.0871557, 0.9961947], [0.01, 0.0, 0.0])
        .unwrap();
    for opts in [
        CloudOptions::new(),
        CloudOptions::new().dilate_m(0.02),
        CloudOptions::new().fill(Fill::down_to_floor()),
        CloudOptions::new().transform(Some(turn)),
    ] {
        for enc in [Encoding::Bits, Encoding::Percent] {
            let two = rasterize(&e, &lattice, enc, opts);
            let one = rasterize(&e, &lattice, enc, opts.parallel(false));
            assert!(two.1.nonfinite > 0 && two.1.outside > 0 && two.1.marked_voxels > 0);
            assert_eq!(two, one, "{opts:?} {enc:?}");
        }
    }
}
