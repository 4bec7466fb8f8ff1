use chronotope::kernel::intersect::{classify, relative_interiors_meet, tets_cross, LatticeTet};
use std::hint::black_box;
use std::time::Instant;

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn range(&mut self, lo: i32, hi: i32) -> i32 {
        lo + (self.next() % (hi - lo + 1) as u64) as i32
    }
}

fn main() {
    let mut rng = Rng(7);
    let n = 200_000;
    let mut sets: Vec<(&str, Vec<(LatticeTet, LatticeTet)>)> = Vec::new();
    for (name, lo, hi) in [
        ("small [0,4]", 0, 4),
        ("[-60,60] near", -60, 60),
        ("big 2^20", -(1 << 20), 1 << 20),
        ("2^25 (i128)", -(1 << 25), 1 << 25),
    ] {
        let mut v = Vec::with_capacity(n);
        for _ in 0..n {
            let a: LatticeTet = [0; 4].map(|_| [0; 4].map(|_| rng.range(lo, hi)));
            let c = a[0];
            let b: LatticeTet =
                [0; 4].map(|_| [0, 1, 2, 3].map(|k| c[k] / 2 + rng.range(lo, hi) / 2));
            v.push((a, b));
        }
        sets.push((name, v));
    }
    for (name, v) in &sets {
        for (fname, f) in [
            (
                "tets_cross",
                tets_cross as fn(&LatticeTet, &LatticeTet) -> bool,
            ),
            ("strict SAT", relative_interiors_meet),
        ] {
            let t = Instant::now();
            let mut c = 0usize;
            for _ in 0..3 {
                for (a, b) in v {
                    c += f(black_box(a), black_box(b)) as usize;
                }
            }
            let ns = t.elapsed().as_nanos() as f64 / (3 * v.len()) as f64;
            println!(
                "{name:>16} {fname:>12}: {ns:7.1} ns/call  crossing {:.1}%",
                100.0 * c as f64 / (3 * v.len()) as f64
            );
        }
        let t = Instant::now();
        let mut c = 0usize;
        for (a, b) in v {
            c += matches!(
                classify(black_box(a), black_box(b)),
                chronotope::kernel::intersect::TetPairRelation::Disjoint
            ) as usize;
        }
        println!(
            "{name:>16} {:>12}: {:7.1} ns/call  disjoint {:.1}%",
            "classify",
            t.elapsed().as_nanos() as f64 / v.len() as f64,
            100.0 * c as f64 / v.len() as f64
        );
        // Only straddling pairs (those that reach the vertex tests).
    }
}
