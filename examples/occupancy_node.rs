//! The occupancy node's time per cloud, as a replay or a live launch runs it: a 1-million-point
//! surface cloud (x, y, z, intensity as FLOAT32, random order, the crate bench's cell) onto a
//! 256³ lattice of 4 cm, the whole `on_message` (rasterising, the frame's copy into its
//! VoxelGrid), on rayon's pool (the cloud split in halves) and on one thread.
//!
//! ```sh
//! cargo run --release --example occupancy_node
//! ```
//!
//! Prints the median and best wall time of 31 runs after a warm-up, for bits and percent,
//! plain and with a 5 cm margin and a fill to the floor.

use std::sync::Arc;
use std::time::{Duration, Instant};

use chronotope::msg::{Header, PointCloud2, PointField};
use chronotope::node::launch::LaunchConfig;
use chronotope::node::occupancy::OccupancyNode;
use chronotope::node::{Message, Node, Payload};

/// SplitMix64, so runs are comparable.
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

/// Points on the floor, walls, boxes and a post of a 10 m cell, 5 mm of noise, random order.
fn cloud(n: usize) -> PointCloud2 {
    let mut rng = Rng(7);
    let boxes = [
        ([2.0, 2.0, 0.0], [3.5, 3.0, 1.2]),
        ([6.0, 1.5, 0.0], [8.5, 2.5, 0.9]),
        ([4.0, 6.0, 0.0], [5.0, 8.0, 2.0]),
        ([7.0, 6.5, 0.0], [9.0, 9.0, 1.5]),
    ];
    let mut data = Vec::with_capacity(n * 16);
    for i in 0..n {
        let (u, v) = (rng.unit(), rng.unit());
        let p = match rng.next() % 8 {
            0 | 1 => [u * 10.0, v * 10.0, 0.0],
            2 => [0.02, u * 10.0, v * 3.0],
            3 => [9.98, u * 10.0, v * 3.0],
            4 => [u * 10.0, 0.02, v * 3.0],
            5 => [u * 10.0, 9.98, v * 3.0],
            6 => {
                let (lo, hi) = boxes[(rng.next() % 4) as usize];
                [
                    lo[0] + u * (hi[0] - lo[0]),
                    lo[1] + v * (hi[1] - lo[1]),
                    hi[2],
                ]
            }
            _ => {
                let a = u * std::f64::consts::TAU;
                [2.0 + 0.6 * a.cos(), 7.5 + 0.6 * a.sin(), v * 2.5]
            }
        };
        for c in p {
            let noisy = c + (rng.unit() - 0.5) * 0.01;
            data.extend((noisy as f32).to_le_bytes());
        }
        data.extend((i as f32).to_le_bytes());
    }
    PointCloud2 {
        header: Header::default(),
        height: 1,
        width: n as u32,
        fields: ["x", "y", "z", "intensity"]
            .iter()
            .enumerate()
            .map(|(i, f)| PointField::new(*f, 4 * i as u32, PointField::FLOAT32, 1))
            .collect(),
        is_bigendian: false,
        point_step: 16,
        row_step: 16 * n as u32,
        data,
        is_dense: true,
    }
}

fn node(extra: &str) -> OccupancyNode {
    let text = format!(
        "launch:\n- node: {{pkg: chronotope, exec: occupancy, name: cam, param: [\
         {{name: input_topic, value: /points}}, \
         {{name: input_type, value: sensor_msgs/msg/PointCloud2}}, \
         {{name: origin, value: [-0.1, -0.1, -0.1]}}, {{name: resolution, value: 0.04}}, \
         {{name: size, value: [256, 256, 256]}}{extra}]}}\n"
    );
    let c = LaunchConfig::parse(&text, "bench").expect("the bench config");
    OccupancyNode::from_spec(&c.nodes[0]).expect("the bench node")
}

fn time(name: &str, threads: usize, extra: &str, cloud: &Arc<PointCloud2>) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a pool");
    let mut n = node(extra);
    let mut stamp = 0i64;
    let mut run = || {
        stamp += 1;
        let mut c = (**cloud).clone();
        c.header.stamp = chronotope::msg::Time::from_nanos(stamp);
        let m = Message::new("/points", stamp, Payload::PointCloud2(Arc::new(c)));
        let mut out = Vec::new();
        let t = Instant::now();
        pool.install(|| n.on_message(&m, &mut out));
        let took = t.elapsed();
        assert_eq!(out.len(), 1, "{:?}", n.status().problems);
        took
    };
    run();
    let mut times: Vec<Duration> = (0..31).map(|_| run()).collect();
    times.sort();
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    println!(
        "{name:<48} {threads} thread(s): median {:>6.2} ms  best {:>6.2} ms",
        ms(times[15]),
        ms(times[0])
    );
}

fn main() {
    let c = Arc::new(cloud(1_000_000));
    for (name, extra) in [
        ("cloud 1M -> 256^3 bits", ""),
        (
            "cloud 1M -> 256^3 percent",
            ", {name: encoding, value: percent}",
        ),
        (
            "cloud 1M -> 256^3 bits, dilate 5 cm, fill to floor",
            ", {name: dilate_m, value: 0.05}, {name: fill, value: columns}",
        ),
    ] {
        for threads in [1, 2] {
            time(name, threads, extra, &c);
        }
    }
}
