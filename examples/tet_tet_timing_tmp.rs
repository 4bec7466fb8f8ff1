//! Temporary timing (deleted after measuring).
use chronotope::kernel::intersect::{classify, tets_cross, LatticeTet};
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

fn time(v: &[(LatticeTet, LatticeTet)], f: impl Fn(&LatticeTet, &LatticeTet) -> bool) -> (f64, f64) {
    let mut best = f64::MAX;
    let mut c = 0;
    for _ in 0..9 {
        c = 0;
        let t = Instant::now();
        for (a, b) in v {
            c += f(black_box(a), black_box(b)) as usize;
        }
        best = best.min(t.elapsed().as_nanos() as f64 / v.len() as f64);
    }
    (best, 100.0 * c as f64 / v.len() as f64)
}

fn main() {
    let mut rng = Rng(7);
    let n = 100_000;
    for (name, lo, hi) in [("[0,4]", 0, 4), ("[-60,60] near", -60, 60), ("2^25 (i128)", -(1 << 25), 1 << 25), ("2^31 (i256)", -(1 << 30), 1 << 30)] {
        let mut v = Vec::with_capacity(n);
        for _ in 0..n {
            let a: LatticeTet = [0; 4].map(|_| [0; 4].map(|_| rng.range(lo, hi)));
            let c = a[0];
            let b: LatticeTet = [0; 4].map(|_| [0, 1, 2, 3].map(|k| c[k] / 2 + rng.range(lo, hi) / 2));
            v.push((a, b));
        }
        let (t1, p1) = time(&v, tets_cross);
        let (t2, p2) = time(&v, |a, b| matches!(classify(a, b), chronotope::kernel::intersect::TetPairRelation::Disjoint));
        println!("{name:>14}: tets_cross {t1:6.1} ns ({p1:.0}% crossing)   classify {t2:6.1} ns ({p2:.0}% disjoint)");
    }
}
