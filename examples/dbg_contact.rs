use chronotope::checker::contact::crossing_t_range;
use chronotope::checker::{check_pair, CommonLattice};
use chronotope::kernel::bvh::{overlapping_pairs, TraverseWorkspace};
use chronotope::kernel::intersect::{classify, TetPairRelation};
fn main() {
    let bodies = chronotope::cli::check::load_bodies(
        std::path::Path::new("bags/four-spheres-32-percent.mcap"),
        Default::default(),
    )
    .unwrap();
    let v: Vec<_> = bodies.iter().collect();
    let named = vec![(v[0].0.as_str(), v[0].1), (v[1].0.as_str(), v[1].1)];
    let lat = CommonLattice::of(&named).unwrap();
    let a = lat.prepare(named[0].0, named[0].1).unwrap();
    let b = lat.prepare(named[1].0, named[1].1).unwrap();
    let mut ws = TraverseWorkspace::new();
    let mut mins = (f64::INFINITY, f64::INFINITY, 0, 0, 0);
    overlapping_pairs(&a.bvh, &b.bvh, &mut ws, |i, j| {
        let ta = a.mesh.tets[i as usize].map(|v| a.mesh.vertices[v as usize]);
        let tb = b.mesh.tets[j as usize].map(|v| b.mesh.vertices[v as usize]);
        match classify(&ta, &tb) {
            TetPairRelation::Crossing => {
                mins.2 += 1;
                match crossing_t_range(&ta, &tb) {
                    Some(r) => {
                        if r.0 < mins.0 {
                            mins.0 = r.0
                        }
                    }
                    None => mins.3 += 1,
                }
            }
            TetPairRelation::Coplanar { .. } => {
                mins.4 += 1;
                let t = ta.iter().map(|p| p[3]).min().unwrap() as f64;
                if t < mins.1 {
                    mins.1 = t
                }
            }
            _ => {}
        }
    });
    let r = check_pair(&a, &b);
    let o = lat.stamps_ns[0];
    println!("crossing min t {} s (n={}, none={}), coplanar min {} s (n={}); result first {:?} s; per frame {}", lat.time_s(mins.0, o), mins.2, mins.3, lat.time_s(mins.1, o), mins.4, r.first_contact().map(|t| lat.time_s(t,o)), 4*lat.scale);
    println!("counts {:?}", r.counts());
}
