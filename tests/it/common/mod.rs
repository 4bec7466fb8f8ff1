//! Helpers shared by the mesh tests: frames from closures, running the mesher, gluing.
#![allow(dead_code)]

use chronotope::mesh::march::CapSide;
use chronotope::mesh::stats::{BodyStats, StatsAccumulator};
use chronotope::mesh::{FrameRef, Mesher, MesherOptions, Slab, TetMesh};

/// BITS data for a grid, LSB first, x fastest.
pub fn bits_data(size: [u32; 3], occ: impl Fn(usize, usize, usize) -> bool) -> Vec<u8> {
    let [sx, sy, sz] = size.map(|v| v as usize);
    let mut d = vec![0u8; (sx * sy * sz).div_ceil(8)];
    for z in 0..sz {
        for y in 0..sy {
            for x in 0..sx {
                if occ(x, y, z) {
                    let i = x + sx * (y + sy * z);
                    d[i / 8] |= 1 << (i % 8);
                }
            }
        }
    }
    d
}

/// PERCENT data for a grid.
pub fn percent_data(size: [u32; 3], val: impl Fn(usize, usize, usize) -> u8) -> Vec<u8> {
    let [sx, sy, sz] = size.map(|v| v as usize);
    let mut d = vec![0u8; sx * sy * sz];
    for z in 0..sz {
        for y in 0..sy {
            for x in 0..sx {
                d[x + sx * (y + sy * z)] = val(x, y, z);
            }
        }
    }
    d
}

/// One frame to feed.
pub struct TestFrame {
    pub stamp_ns: i64,
    pub encoding: u8,
    pub data: Vec<u8>,
}

pub fn frame_ref<'a>(f: &'a TestFrame, size: [u32; 3], resolution: f64) -> FrameRef<'a> {
    FrameRef {
        stamp_ns: f.stamp_ns,
        origin: [0.0; 3],
        resolution,
        size,
        encoding: f.encoding,
        data: &f.data,
    }
}

/// Everything a run produced.
pub struct Run {
    pub slabs: Vec<Slab>,
    pub first_cap: Option<TetMesh>,
    pub last_cap: Option<TetMesh>,
    pub stats: BodyStats,
    pub mesher: Mesher,
}

pub fn run(frames: &[TestFrame], size: [u32; 3], resolution: f64) -> Run {
    run_with(frames, size, resolution, MesherOptions::default())
}

pub fn run_with(frames: &[TestFrame], size: [u32; 3], resolution: f64, opts: MesherOptions) -> Run {
    let mut m = Mesher::new(opts).expect("options");
    let mut acc = StatsAccumulator::new();
    let mut slabs = Vec::new();
    let mut first_cap = None;
    for f in frames {
        if let Some(slab) = m
            .push(&frame_ref(f, size, resolution))
            .expect("frame accepted")
        {
            if first_cap.is_none() {
                first_cap = m.cap(m.first_frame().unwrap(), CapSide::Low);
            }
            acc.add_slab(&slab, first_cap.as_ref());
            slabs.push(slab);
        }
    }
    let last_cap = if slabs.is_empty() {
        None
    } else {
        m.cap(m.last_frame().unwrap(), CapSide::High)
    };
    let occ_first = m.first_frame().map(|f| f.grid.occupied).unwrap_or(0);
    let occ_last = m.last_frame().map(|f| f.grid.occupied).unwrap_or(0);
    let stats = acc.finish(
        m.frames(),
        first_cap.as_ref().map(|c| (c.tets.len() as u64, occ_first)),
        last_cap.as_ref().map(|c| (c, occ_last)),
    );
    Run {
        slabs,
        first_cap,
        last_cap,
        stats,
        mesher: m,
    }
}

/// The glued mesh: first cap, every slab's lateral tets, last cap, welded.
pub fn glued(r: &Run) -> TetMesh {
    let mut g = TetMesh::default();
    if let Some(c) = &r.first_cap {
        g.append_welded(c);
    }
    for s in &r.slabs {
        g.append_welded(&s.mesh);
    }
    if let Some(c) = &r.last_cap {
        g.append_welded(c);
    }
    g
}

/// Slab k closed by its own two caps.
pub fn closed_slab(r: &Run, k: usize, frame_grids: &[chronotope::mesh::OccupancyGrid]) -> TetMesh {
    use chronotope::mesh::march::march_cap;
    use chronotope::mesh::table::table;
    let s = &r.slabs[k];
    let at = |f: i64| chronotope::mesh::SlabPlacement {
        scale: s.geometry.scale,
        frame: f,
        iso: 50,
    };
    let mut lo = TetMesh::default();
    let mut hi = TetMesh::default();
    march_cap(
        table(),
        &frame_grids[k],
        at(k as i64),
        CapSide::Low,
        usize::MAX,
        &mut lo,
    );
    march_cap(
        table(),
        &frame_grids[k + 1],
        at(k as i64 + 1),
        CapSide::High,
        usize::MAX,
        &mut hi,
    );
    let mut m = s.mesh.clone();
    m.append_welded(&lo);
    m.append_welded(&hi);
    m
}

/// A 3×4×4-voxel box in a 12³ BITS frame at 1 cm voxels, its x range starting at voxel
/// `x0 + k` (a body moving +x one voxel per frame), stamped `t0_ns + k · 0.1 s`.
pub fn moving_box(x0: u32, k: u32, t0_ns: i64) -> chronotope::msg::VoxelGrid {
    box_frame(x0, 1, 4, k, t0_ns)
}

/// Frame `k` of a 3×4×4-voxel box in a 12³ BITS frame at 1 cm voxels (frame "world"): x from
/// `x0 + k·vx`, y from `y0`, z 4..8, stamped `t0_ns + k · 0.1 s`.
pub fn box_frame(x0: u32, vx: u32, y0: u32, k: u32, t0_ns: i64) -> chronotope::msg::VoxelGrid {
    let data = bits_data([12; 3], |x, y, z| {
        (4..8).contains(&z)
            && (y0..y0 + 4).contains(&(y as u32))
            && (x0 + k * vx..x0 + k * vx + 3).contains(&(x as u32))
    });
    cube_grid(12, t0_ns + i64::from(k) * 100_000_000, data)
}

/// A `size`³ BITS frame at 1 cm voxels from the origin (frame "world"), stamped `stamp_ns`.
pub fn cube_grid(size: u32, stamp_ns: i64, data: Vec<u8>) -> chronotope::msg::VoxelGrid {
    use chronotope::msg::{Header, Point, Time, VoxelGrid};
    VoxelGrid {
        header: Header {
            stamp: Time::from_nanos(stamp_ns),
            frame_id: "world".into(),
        },
        origin: Point::default(),
        resolution: 0.01,
        size_x: size,
        size_y: size,
        size_z: size,
        encoding: VoxelGrid::ENCODING_BITS,
        data,
    }
}

/// Writes scene `name` at `grid`³ with `frames` frames.
pub fn scene_bag(
    dir: &std::path::Path,
    name: chronotope::scene::SceneName,
    grid: u32,
    frames: u32,
) -> std::path::PathBuf {
    let path = dir.join(format!("{name}-{grid}-{frames}.mcap"));
    let opts = chronotope::scene::SceneOptions::for_scene(name)
        .grid(grid)
        .frames(frames);
    let scene = chronotope::scene::build_scene(name, &opts).unwrap();
    let mut w = chronotope::bag::BagWriter::create(&path).unwrap();
    let topics = scene.topics();
    for t in &topics {
        w.add_topic::<chronotope::msg::VoxelGrid>(t).unwrap();
    }
    let mut raster = chronotope::scene::Rasterizer::new();
    let mut g = chronotope::msg::VoxelGrid::default();
    for k in 0..scene.frame_count() {
        for (b, t) in topics.iter().enumerate() {
            scene.write_frame(b, k, &mut raster, &mut g).unwrap();
            w.write(t, scene.stamp_ns(k) as u64, &g).unwrap();
        }
    }
    w.finish().unwrap();
    path
}
