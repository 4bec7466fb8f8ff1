//! `chronotope bench rotation`: the rotation suggestion against the exact smallest angle on
//! a scene where it is known in closed form, a bar turning away from a post.
//!
//! The bar (0.96 × 0.16 × 0.16 m, along x) pivots about the vertical axis through the
//! middle of its end face; a vertical cylinder (radius ρ = 0.08 m) stands at L = 0.64 m
//! along it and c = 0.04 m to its side, through its upper half. Turning away from the post
//! (clockwise seen from above), the bar's face at half-width w clears the cylinder once
//! the cylinder's axis is w + ρ from the bar's centre line: the exact smallest angle is
//! asin((w + ρ)/√(L² + c²)) − atan2(c, L). The other sense needs asin(…) + atan2(c, L).
//! Both bodies stand still over three frames; every size is a multiple of 0.04 m, so at
//! grids that are multiples of 32 the bar's faces and the pivot lie on voxel boundaries.
//!
//! Besides the ideal shapes' angle, the exact smallest angle for the bodies *as meshed* is
//! computed from the post's mesh: the bar's face is the plane at w exactly, and the post
//! clears it once every vertex of its section (r, α from the pivot) has turned past it,
//! φ = max asin(w/r) − α. A verified suggestion can never be below that angle; it exceeds
//! it by at most the search's bracket. The meshed boundaries lie within h/2 of the true
//! ones, so the meshed angle is within asin((w + ρ + h)/D) − asin((w + ρ)/D) of the ideal
//! one (D = √(L² + c²)).

use super::BenchError;
use crate::checker::rotate::{suggest_rotation, RotationSpec};
use crate::checker::{check_pair, CommonLattice, Prepared};
use crate::mesh::glue::{BodyAssembler, BodyMesh};
use crate::mesh::grid::FrameRef;
use crate::mesh::MesherOptions;
use crate::msg::VoxelEncoding;
use crate::scene::{Axis, Rasterizer, Shape, VoxelLattice};
use std::time::Instant;

/// Edge of the cubic domain (m).
const DOMAIN: f64 = 1.28;
/// The pivot: the middle of the bar's end face (m).
const PIVOT: [f64; 3] = [0.16, 0.64, 0.64];
/// The bar's half-width (m).
const HALF_WIDTH: f64 = 0.08;
/// The post's radius, distance along the bar and offset to its side (m).
const POST: (f64, f64, f64) = (0.08, 0.64, 0.04);

/// The shapes of the bar and of the post.
fn shapes() -> (Vec<Shape>, Vec<Shape>) {
    let [px, py, pz] = PIVOT;
    let bar = Shape::cuboid(
        [px, py - HALF_WIDTH, pz - HALF_WIDTH],
        [px + 0.96, py + HALF_WIDTH, pz + HALF_WIDTH],
    );
    let (rho, l, c) = POST;
    let post = Shape::cylinder(Axis::Z, [px + l, py + c, pz - 0.16], 0.32, rho);
    (vec![bar], vec![post])
}

/// The exact smallest clockwise turn for the ideal shapes (rad).
pub fn exact_ideal() -> f64 {
    let (rho, l, c) = POST;
    ((HALF_WIDTH + rho) / l.hypot(c)).asin() - c.atan2(l)
}

/// A body of `shapes` at rest over three frames, rasterised at `grid` in `encoding`.
fn body(shapes: &[Shape], grid: u32, encoding: VoxelEncoding) -> Result<BodyMesh, BenchError> {
    let lattice = VoxelLattice::cube([0.0; 3], DOMAIN, grid);
    let mut raster = Rasterizer::new();
    let mut data = Vec::new();
    let mut asm = BodyAssembler::new(MesherOptions::default())?;
    raster.rasterize(shapes, [0.0; 3], &lattice, encoding, &mut data);
    for k in 0..3 {
        asm.push(&FrameRef {
            stamp_ns: k * 100_000_000,
            origin: lattice.origin,
            resolution: lattice.resolution,
            size: lattice.size,
            encoding: encoding.code(),
            data: &data,
        })?;
    }
    Ok(asm.finish())
}

/// The exact smallest clockwise turn for the post as meshed, in radians (see the module
/// documentation), from its checker coordinates on `lat`.
fn exact_meshed(post: &Prepared, lat: &CommonLattice) -> f64 {
    let per_step = lat.per_step() as f64;
    let metres = |k: usize, c: i32| lat.voxel0_centre[k] + f64::from(c) / per_step * lat.resolution;
    post.mesh
        .vertices
        .iter()
        .filter(|v| (metres(2, v[2]) - PIVOT[2]).abs() < HALF_WIDTH)
        .map(|v| {
            let (x, y) = (metres(0, v[0]) - PIVOT[0], metres(1, v[1]) - PIVOT[1]);
            (HALF_WIDTH / x.hypot(y)).asin() - y.atan2(x)
        })
        .fold(f64::NEG_INFINITY, f64::max)
}

/// Runs the benchmark: one row per grid and encoding.
///
/// # Errors
/// A grid out of range, or bodies that cannot be checked.
pub fn bench_rotation(grids: &[u32], encodings: &[VoxelEncoding]) -> Result<(), BenchError> {
    let (bar_shapes, post_shapes) = shapes();
    let ideal = exact_ideal();
    let (rho, l, c) = POST;
    let d = l.hypot(c);
    println!(
        "bar turning away from a post: half-width {HALF_WIDTH} m, post radius {rho} m at {l} m \
         along and {c} m aside; exact smallest turn for the ideal shapes {ideal:.5} rad \
         ({:.3}°), clockwise",
        ideal.to_degrees()
    );
    println!();
    println!(
        "| grid | encoding | tets (bar + post) | found (rad) | exact, as meshed | found − meshed | \
         exact, ideal | found − ideal | voxel bound | bracket | n | angles / in full | time |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for &grid in grids {
        if !(8..=1024).contains(&grid) {
            return Err(BenchError::Usage(format!(
                "grid {grid}: must be within 8..=1024"
            )));
        }
        for &encoding in encodings {
            let bar = body(&bar_shapes, grid, encoding)?;
            let post = body(&post_shapes, grid, encoding)?;
            let lat = CommonLattice::of(&[("bar", &bar), ("post", &post)])?;
            let a = lat.prepare("bar", &bar)?;
            let b = lat.prepare("post", &post)?;
            let r = check_pair(&a, &b);
            let spec = RotationSpec {
                point_m: Some(PIVOT),
                ..RotationSpec::default()
            };
            let t = Instant::now();
            let rot = suggest_rotation(&a, &[&b], &[&r], &lat, &spec);
            let secs = t.elapsed().as_secs_f64();
            let meshed = exact_meshed(&b, &lat);
            let h = lat.resolution;
            let bound = ((HALF_WIDTH + rho + h) / d).asin() - ((HALF_WIDTH + rho) / d).asin();
            let Some(rot) = rot else {
                println!("| {grid} | {encoding:?} | no interference: nothing to turn |");
                continue;
            };
            let found = -rot.angle_rad;
            let bracket = rot.failing_rad.map_or(f64::NAN, |f| found + f);
            println!(
                "| {grid} | {encoding:?} | {} + {} | {found:.5}{} | {meshed:.5} | {:+.5} | \
                 {ideal:.5} | {:+.5} | {bound:.5} | {bracket:.5} | {} | {} / {} | {:.0} ms |",
                a.mesh.tets.len(),
                b.mesh.tets.len(),
                if rot.verified_clear {
                    ""
                } else {
                    " (not clear)"
                },
                found - meshed,
                found - ideal,
                rot.n,
                rot.tried.0,
                rot.tried.1,
                secs * 1e3
            );
        }
    }
    Ok(())
}
