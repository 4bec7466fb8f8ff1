//! The checker as a library: two bodies' voxel sequences in, their contacts out.
//!
//! A cube slides along x, a voxel a frame, into a still post over 16 frames at 10 Hz on a 32³ lattice of 1 cm
//! voxels. Each body's frames are meshed into a closed 4D mesh (`BodyAssembler`), the pair is
//! checked exactly (`check_bodies`), and the verdict, contact intervals, first contact and
//! the verified resolutions are printed.
//!
//! It needs only this crate and the mesher's (no ROS, DDS, bags or tokio):
//!
//! ```sh
//! cargo run --release -p chronotope-checker --example check_two_bodies
//! ```

use std::collections::BTreeMap;

use chronotope_checker::pipeline::{check_bodies, CheckPlan};
use chronotope_mesh::glue::BodyAssembler;
use chronotope_mesh::{Encoding, FrameRef, MesherOptions};

const N: usize = 32;

/// BITS data (LSB first, x fastest) of the voxels `occupied` says are in.
fn bits(occupied: impl Fn(usize, usize, usize) -> bool) -> Vec<u8> {
    let mut d = vec![0u8; (N * N * N).div_ceil(8)];
    for z in 0..N {
        for y in 0..N {
            for x in 0..N {
                if occupied(x, y, z) {
                    let i = x + N * (y + N * z);
                    d[i / 8] |= 1 << (i % 8);
                }
            }
        }
    }
    d
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let opts = MesherOptions::default();
    let mut cube = BodyAssembler::new(opts)?;
    let mut post = BodyAssembler::new(opts)?;
    for k in 0..16usize {
        let stamp_ns = k as i64 * 100_000_000;
        // The cube spans x 2 + k .. 8 + k voxels; the post stands at x 20..24.
        let cube_bits = bits(|x, y, z| {
            (2 + k..8 + k).contains(&x) && (12..18).contains(&y) && (12..18).contains(&z)
        });
        let post_bits =
            bits(|x, y, z| (20..24).contains(&x) && (10..20).contains(&y) && (8..24).contains(&z));
        for (body, data) in [(&mut cube, &cube_bits), (&mut post, &post_bits)] {
            body.push(&FrameRef {
                stamp_ns,
                origin: [0.0; 3],
                resolution: 0.01,
                size: [N as u32; 3],
                encoding: Encoding::Bits.code(),
                data,
            })?;
        }
    }
    let bodies = BTreeMap::from([
        ("/cube".to_owned(), cube.finish()),
        ("/post".to_owned(), post.finish()),
    ]);
    // Every pair; resolutions suggested for the body whose id sorts first (the cube).
    let plan = CheckPlan::all_pairs_first_movable(&["/cube", "/post"], None);
    let outcome = check_bodies(&bodies, &plan, opts)?;
    for p in &outcome.report.pairs {
        println!("{} x {}: {}", p.a, p.b, p.verdict.as_str());
        for [from, to] in &p.intervals_s {
            println!("  in contact {from:.3}-{to:.3} s");
        }
        if let (Some(t), Some(e)) = (p.first_contact_s, p.first_contact_error_bound_s) {
            println!("  first contact {t:.3} s (± {e:.3} s)");
        }
    }
    for r in &outcome.report.resolutions {
        println!("  {}", serde_json::to_string(r)?);
    }
    Ok(())
}
