//! Dilation by a safety margin and column fills, on padded bit rows.
//!
//! Dilation: a voxel is added when its cube comes within `r` voxel edges of a
//! marked voxel's cube, i.e. for offsets `(dx, dy, dz)` with
//! `Σ max(0, |d| - 1)² ≤ r²`. Since every point lies in its marked voxel's
//! cube, this contains every voxel whose cube comes within `r` of a point: it
//! errs toward occupied by at most one voxel's diagonal. Done row by row: each
//! non-empty source row is widened along x once per reach needed and OR-ed
//! into the rows of every `(dy, dz)` in the element.

use super::{Axis, Toward};
use crate::rows::BitRows;

/// One `(dy, dz)` of the structuring element and its x half-width.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct ElementRow {
    pub dy: i64,
    pub dz: i64,
    pub hx: usize,
}

/// Rows of the element for radius `r` voxel edges (> 0). Slightly generous
/// (`r · (1 + 1e-9)`) so that a radius that is a whole number of voxels in
/// decimal but not in binary is not cut short.
pub(crate) fn element(r: f64) -> Vec<ElementRow> {
    let r = r * (1.0 + 1e-9) + 1e-12;
    let r2 = r * r;
    let reach = r.floor() as i64 + 1;
    let mut rows = Vec::new();
    for dz in -reach..=reach {
        for dy in -reach..=reach {
            let gy = (dy.abs() - 1).max(0) as f64;
            let gz = (dz.abs() - 1).max(0) as f64;
            let rest = r2 - gy * gy - gz * gz;
            if rest < 0.0 {
                continue;
            }
            rows.push(ElementRow {
                dy,
                dz,
                hx: rest.sqrt().floor() as usize + 1,
            });
        }
    }
    rows
}

/// Widens `row` by one voxel each way, in place, through `tmp`.
fn widen_by_one(row: &mut [u64], tmp: &mut [u64], last_mask: u64) {
    tmp.copy_from_slice(row);
    let n = row.len();
    for w in 0..n {
        let left = (tmp[w] << 1) | if w > 0 { tmp[w - 1] >> 63 } else { 0 };
        let right = (tmp[w] >> 1) | if w + 1 < n { tmp[w + 1] << 63 } else { 0 };
        row[w] = tmp[w] | left | right;
    }
    row[n - 1] &= last_mask;
}

/// `dst = src` dilated by `elem`; `scratch` is reused.
pub(crate) fn dilate(
    src: &BitRows,
    dst: &mut BitRows,
    elem: &[ElementRow],
    scratch: &mut Vec<u64>,
) {
    let [nx, ny, nz] = src.size();
    dst.reset([nx as u32, ny as u32, nz as u32]);
    let wpr = src.words_per_row();
    let hmax = elem.iter().map(|e| e.hx).max().unwrap_or(0);
    // scratch: widened copies for h = 0..=hmax, then one temporary row.
    scratch.clear();
    scratch.resize((hmax + 2) * wpr, 0);
    let mask = src.last_word_mask();
    let (ny, nz) = (ny as i64, nz as i64);
    for z in 0..nz {
        for y in 0..ny {
            let start = src.row_start(y as usize, z as usize);
            let row = &src.words()[start..start + wpr];
            if row.iter().all(|&w| w == 0) {
                continue;
            }
            scratch[..wpr].copy_from_slice(row);
            for h in 1..=hmax {
                let (done, rest) = scratch.split_at_mut(h * wpr);
                let (cur, tmp) = rest.split_at_mut(wpr);
                cur.copy_from_slice(&done[(h - 1) * wpr..]);
                widen_by_one(cur, &mut tmp[..wpr], mask);
            }
            for e in elem {
                let (ty, tz) = (y + e.dy, z + e.dz);
                if ty < 0 || ty >= ny || tz < 0 || tz >= nz {
                    continue;
                }
                let t = dst.row_start(ty as usize, tz as usize);
                let widened = &scratch[e.hx * wpr..(e.hx + 1) * wpr];
                for (d, s) in dst.words_mut()[t..t + wpr].iter_mut().zip(widened) {
                    *d |= s;
                }
            }
        }
    }
}

/// Fills each occupied voxel's column along `axis` up to the lattice face
/// `toward` (`Min`: index 0, the floor for z).
pub(crate) fn fill_columns(rows: &mut BitRows, axis: Axis, toward: Toward) {
    let [_, ny, nz] = rows.size();
    let wpr = rows.words_per_row();
    let mask = rows.last_word_mask();
    let words = rows.words_mut();
    match axis {
        Axis::Z => {
            let plane = wpr * ny;
            match toward {
                Toward::Min => {
                    for z in (0..nz.saturating_sub(1)).rev() {
                        let (lo, hi) = words.split_at_mut((z + 1) * plane);
                        or_into(&mut lo[z * plane..], &hi[..plane]);
                    }
                }
                Toward::Max => {
                    for z in 1..nz {
                        let (lo, hi) = words.split_at_mut(z * plane);
                        or_into(&mut hi[..plane], &lo[(z - 1) * plane..]);
                    }
                }
            }
        }
        Axis::Y => {
            for plane in words.chunks_exact_mut(wpr * ny) {
                match toward {
                    Toward::Min => {
                        for y in (0..ny.saturating_sub(1)).rev() {
                            let (lo, hi) = plane.split_at_mut((y + 1) * wpr);
                            or_into(&mut lo[y * wpr..], &hi[..wpr]);
                        }
                    }
                    Toward::Max => {
                        for y in 1..ny {
                            let (lo, hi) = plane.split_at_mut(y * wpr);
                            or_into(&mut hi[..wpr], &lo[(y - 1) * wpr..]);
                        }
                    }
                }
            }
        }
        Axis::X => {
            for row in words.chunks_exact_mut(wpr) {
                let Some(top) = row.iter().rposition(|&w| w != 0) else {
                    continue;
                };
                match toward {
                    Toward::Min => {
                        // Set everything from bit 0 to the highest set bit.
                        let high = 63 - row[top].leading_zeros();
                        for w in &mut row[..top] {
                            *w = !0;
                        }
                        row[top] |= !0u64 >> (63 - high);
                    }
                    Toward::Max => {
                        let first = row.iter().position(|&w| w != 0).expect("a set word");
                        let low = row[first].trailing_zeros();
                        row[first] |= !0u64 << low;
                        for w in &mut row[first + 1..] {
                            *w = !0;
                        }
                    }
                }
                let last = row.len() - 1;
                row[last] &= mask;
            }
        }
    }
}

fn or_into(dst: &mut [u64], src: &[u64]) {
    for (d, s) in dst.iter_mut().zip(src) {
        *d |= s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_small_radius_reaches_all_26_neighbours_and_no_further() {
        let e = element(0.1);
        assert_eq!(e.len(), 9);
        assert!(e
            .iter()
            .all(|r| r.hx == 1 && r.dy.abs() <= 1 && r.dz.abs() <= 1));
    }

    #[test]
    fn radius_two_reaches_three_voxels_along_an_axis() {
        // Cube gap along x for dx = 3 is 2 edges: within a radius of 2.
        let e = element(2.0);
        let centre = e.iter().find(|r| r.dy == 0 && r.dz == 0).unwrap();
        assert_eq!(centre.hx, 3);
        assert!(e.iter().any(|r| r.dy == 3 && r.dz == 0));
        assert!(!e.iter().any(|r| r.dy == 3 && r.dz == 3));
    }
}
