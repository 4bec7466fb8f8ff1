//! Preparing one body for checking piece by piece, as its mesh arrives: each piece (a cap
//! or a slab, welded onto the body's mesh) gets its subtree, its tets in that subtree's
//! leaf order with their vertices numbered by first use, its tet normals, and its face
//! adjacency (with the faces left open by the pieces before) when it comes. What is left
//! when the stream ends is the top of the tree (one node per piece) and putting the body
//! on the common lattice of the bodies it is checked against ([`CommonLattice::place`]),
//! which is a no-op when every body shares its lattice and time origin.
//!
//! Everything is in the body's own lattice × [`CHECKER_FACTOR`]: the common lattice
//! (finer for a mix of encodings, shifted for other origins or later starts) is known only
//! once every body's stream has begun, and mapping onto it is an increasing axis map, which
//! keeps the tree valid (see [`Placement`](super::Placement)).
//!
//! [`CommonLattice::place`]: super::CommonLattice::place

use super::adjacency::AdjacencyBuilder;
use super::{tet_normal, CHECKER_FACTOR, NO_NORMAL};
use chronotope_kernel::bvh::{Aabb4, BvhError, Forest};
use chronotope_kernel::LatticePoint;
use chronotope_mesh::TetMesh;
use rayon::prelude::*;

/// Why a body's mesh cannot be prepared.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PrepError {
    /// The tree cannot hold the tets, or a tet names a vertex that does not exist.
    #[error(transparent)]
    Tree(#[from] BvhError),
    /// A coordinate × [`CHECKER_FACTOR`] leaves ±2^30 (the exact predicates' far points
    /// must fit `i32`).
    #[error("lattice coordinate {value} is too large for the checker lattice (×{CHECKER_FACTOR} must stay within ±2^30)")]
    Overflow {
        /// The body's lattice coordinate.
        value: i32,
    },
}

/// A body being prepared piece by piece; see the module documentation.
#[derive(Debug, Default)]
pub struct BodyPrep {
    forest: Forest,
    adjacency: AdjacencyBuilder,
    /// The body mesh's vertex → prepared vertex ([`UNSEEN`] until a tet uses it).
    new_of: Vec<u32>,
    /// Tets in leaf order over vertices numbered by first use, × [`CHECKER_FACTOR`].
    mesh: TetMesh,
    normals: Vec<[i32; 4]>,
    original: Vec<u32>,
    /// The first error; the body cannot be checked after it.
    error: Option<PrepError>,
}

/// A prepared vertex not assigned yet.
const UNSEEN: u32 = u32::MAX;

/// Pieces of at least this many tets get their normals and adjacency at once, on the pool.
const PARALLEL_PIECE_TETS: usize = 16_384;
/// Tets per chunk of normals on the pool.
const NORMAL_CHUNK: usize = 4096;

/// The coordinates, tree and topology [`BodyPrep::finish`] hands over.
#[derive(Debug)]
pub struct LocalPrep {
    /// Tets in leaf order over vertices numbered by first use, × [`CHECKER_FACTOR`].
    pub mesh: TetMesh,
    /// Tree over `mesh.tets` (item `i` is tet `i`).
    pub bvh: chronotope_kernel::Bvh,
    /// Face neighbours of each tet.
    pub adjacency: Vec<[u32; 4]>,
    /// Hyperplane normal of each tet (see [`Prepared::normals`](super::Prepared::normals)).
    pub normals: Vec<[i32; 4]>,
    /// Each tet's index in the body's mesh.
    pub original: Vec<u32>,
}

impl BodyPrep {
    /// Nothing prepared yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Prepares the tets of `mesh` not seen by earlier calls (`mesh` grows between calls,
    /// as [`BodyGluer`](chronotope_mesh::glue::BodyGluer) welds pieces onto it) as one piece.
    ///
    /// # Errors
    /// A tet names a missing vertex, a coordinate is too large, or there are too many
    /// tets; the error stays, and every later call and [`finish`](Self::finish) return it.
    pub fn add(&mut self, mesh: &TetMesh) -> Result<(), PrepError> {
        // A mesh shorter than what was seen is not the one this body was fed with.
        let new = mesh.tets.get(self.original.len()..).unwrap_or(&[]);
        self.add_tets(&mesh.vertices, new)
    }

    /// [`add`](Self::add) with the new tets given.
    fn add_tets(&mut self, vertices: &[LatticePoint], new: &[[u32; 4]]) -> Result<(), PrepError> {
        if let Some(e) = &self.error {
            return Err(e.clone());
        }
        if new.is_empty() {
            return Ok(());
        }
        let result = self.add_piece(vertices, new);
        if let Err(e) = &result {
            self.error = Some(e.clone());
        }
        result
    }

    fn add_piece(&mut self, vertices: &[LatticePoint], new: &[[u32; 4]]) -> Result<(), PrepError> {
        let done = self.original.len();
        let nv = vertices.len();
        if let Some((t, &v)) = new
            .iter()
            .enumerate()
            .find_map(|(t, tet)| tet.iter().find(|&&v| v as usize >= nv).map(|v| (t, v)))
        {
            return Err(BvhError::VertexOutOfRange {
                tet: done + t,
                vertex: v,
                vertices: nv,
            }
            .into());
        }
        const LIMIT: i32 = (1 << 30) / CHECKER_FACTOR;
        if let Some(&c) = new
            .iter()
            .flat_map(|tet| tet.iter().flat_map(|&v| &vertices[v as usize]))
            .find(|c| c.unsigned_abs() >= LIMIT as u32)
        {
            return Err(PrepError::Overflow { value: c });
        }
        // Each tet's box, on the checker lattice, asked for by the tree's build: four
        // vertices read again beat 32 bytes a tet held (a cap's piece fills its body).
        let box_of = |i: usize| {
            let tet = new[i];
            let mut b = Aabb4::from_point(vertices[tet[0] as usize]);
            for &v in &tet[1..] {
                b.grow(&vertices[v as usize]);
            }
            Aabb4::new(
                b.min.map(|c| c * CHECKER_FACTOR),
                b.max.map(|c| c * CHECKER_FACTOR),
            )
        };
        let order = self.forest.add_with(new.len(), box_of)?;
        self.new_of.resize(nv, UNSEEN);
        let first = self.mesh.tets.len();
        for &local in order {
            let tet = new[local as usize].map(|v| {
                let slot = &mut self.new_of[v as usize];
                if *slot == UNSEEN {
                    *slot = self.mesh.vertices.len() as u32;
                    self.mesh
                        .vertices
                        .push(vertices[v as usize].map(|c| c * CHECKER_FACTOR));
                }
                *slot
            });
            self.mesh.tets.push(tet);
            self.original.push((done + local as usize) as u32);
        }
        // The normals and the face adjacency read the renumbered tets and nothing else of
        // each other: a big piece gets both at once, its normals in chunks on the pool,
        // written in place (the result is the same). A window prepared alone (the other
        // bodies' windows moved or cached) no longer leaves a core idle for it.
        let (mesh, normals, adjacency) = (&self.mesh, &mut self.normals, &mut self.adjacency);
        let tets = &mesh.tets[first..];
        let normal = |t: &[u32; 4]| tet_normal(t.map(|v| mesh.vertices[v as usize]));
        if tets.len() < PARALLEL_PIECE_TETS {
            normals.extend(tets.iter().map(normal));
            adjacency.add(tets, mesh.vertices.len());
        } else {
            let from = normals.len();
            normals.resize(from + tets.len(), NO_NORMAL);
            let fresh = &mut normals[from..];
            rayon::join(
                || {
                    fresh
                        .par_chunks_mut(NORMAL_CHUNK)
                        .zip(tets.par_chunks(NORMAL_CHUNK))
                        .for_each(|(out, ts)| {
                            for (n, t) in out.iter_mut().zip(ts) {
                                *n = normal(t);
                            }
                        });
                },
                || adjacency.add(tets, mesh.vertices.len()),
            );
        }
        Ok(())
    }

    /// Tets prepared so far.
    pub fn len(&self) -> usize {
        self.mesh.tets.len()
    }

    /// Whether no tet was prepared.
    pub fn is_empty(&self) -> bool {
        self.mesh.tets.is_empty()
    }

    /// The tets prepared so far, in their final order and coordinates (the body's own
    /// lattice × [`CHECKER_FACTOR`]).
    pub fn mesh(&self) -> &TetMesh {
        &self.mesh
    }

    /// The normals of [`mesh`](Self::mesh)'s tets.
    pub fn normals(&self) -> &[[i32; 4]] {
        &self.normals
    }

    /// The pieces' subtrees so far.
    pub fn forest(&self) -> &Forest {
        &self.forest
    }

    /// Prepares the body mesh's tets from those seen so far up to `end` as one piece (a
    /// recorded piece of [`BodyMesh::pieces`](chronotope_mesh::glue::BodyMesh::pieces)).
    ///
    /// # Errors
    /// As [`add`](Self::add).
    pub fn add_up_to(&mut self, mesh: &TetMesh, end: usize) -> Result<(), PrepError> {
        let lo = self.original.len().min(mesh.tets.len());
        let hi = end.clamp(lo, mesh.tets.len());
        self.add_tets(&mesh.vertices, &mesh.tets[lo..hi])
    }

    /// Pieces prepared so far (those with at least one tet).
    pub fn pieces(&self) -> usize {
        self.forest.pieces()
    }

    /// The prepared body (the tree's top is built here).
    ///
    /// # Errors
    /// The first error of [`add`](Self::add).
    pub fn finish(self) -> Result<LocalPrep, PrepError> {
        if let Some(e) = self.error {
            return Err(e);
        }
        Ok(LocalPrep {
            mesh: self.mesh,
            bvh: self.forest.finish(),
            adjacency: self.adjacency.finish(),
            normals: self.normals,
            original: self.original,
        })
    }

    /// A body's whole mesh prepared at once, one piece per range starting at each of
    /// `pieces` (tet offsets, increasing; none: the whole mesh as one piece).
    ///
    /// # Errors
    /// As [`add`](Self::add).
    pub fn of(mesh: &TetMesh, pieces: &[usize]) -> Result<LocalPrep, PrepError> {
        let n = mesh.tets.len();
        // Sized once: grown piece by piece, each buffer would end up to twice its size
        // (and be copied on the way), in the largest buffers a window check holds.
        let mut p = Self::new();
        p.new_of.reserve_exact(mesh.vertices.len());
        p.mesh.vertices.reserve_exact(mesh.vertices.len());
        p.mesh.tets.reserve_exact(n);
        p.normals.reserve_exact(n);
        p.original.reserve_exact(n);
        p.forest.reserve_items(n);
        p.adjacency.reserve_tets(n);
        let mut lo = 0;
        for hi in pieces.iter().copied().chain([n]) {
            let hi = hi.clamp(lo, n);
            p.add_tets(&mesh.vertices, &mesh.tets[lo..hi])?;
            lo = hi;
        }
        p.finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tet_mesh(vertices: Vec<LatticePoint>, tets: Vec<[u32; 4]>) -> TetMesh {
        TetMesh { vertices, tets }
    }

    /// A piece big enough for its normals to be computed on the pool, next to small ones:
    /// every tet's normal is its own, in the prepared order, whichever path made it.
    #[test]
    fn normals_match_their_tets_in_big_and_small_pieces() {
        let mut rng = chronotope_kernel::intersect::test_rng::Rng(0x5DEE_CE66_D1CE_4E5B);
        let vertices: Vec<LatticePoint> = (0..5000)
            .map(|_| [0; 4].map(|_| (rng.next() % 200) as i32 - 100))
            .collect();
        let tets: Vec<[u32; 4]> = (0..PARALLEL_PIECE_TETS * 2 + 77)
            .map(|_| [0; 4].map(|_| (rng.next() % vertices.len() as u64) as u32))
            .collect();
        let m = tet_mesh(vertices, tets);
        for pieces in [vec![], vec![100, 200], vec![PARALLEL_PIECE_TETS + 5]] {
            let l = BodyPrep::of(&m, &pieces).unwrap();
            assert_eq!(l.normals.len(), l.mesh.tets.len());
            for (t, n) in l.mesh.tets.iter().zip(&l.normals) {
                assert_eq!(*n, tet_normal(t.map(|v| l.mesh.vertices[v as usize])));
            }
            // And each prepared tet is its original one, moved onto the checker lattice.
            for (t, &o) in l.mesh.tets.iter().zip(&l.original) {
                let p = t.map(|v| l.mesh.vertices[v as usize]);
                let q =
                    m.tets[o as usize].map(|v| m.vertices[v as usize].map(|c| c * CHECKER_FACTOR));
                assert_eq!(p, q);
            }
        }
    }

    #[test]
    fn a_missing_vertex_is_a_typed_error_that_stays() {
        let mut p = BodyPrep::new();
        let good = tet_mesh(
            vec![[0, 0, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 1]],
            vec![[0, 1, 2, 3]],
        );
        p.add(&good).unwrap();
        let mut bad = good.clone();
        bad.tets.push([0, 1, 2, 7]);
        let e = p.add(&bad).unwrap_err();
        assert_eq!(
            e,
            PrepError::Tree(BvhError::VertexOutOfRange {
                tet: 1,
                vertex: 7,
                vertices: 4
            })
        );
        // Nothing of the bad piece was taken, and the error stays.
        assert_eq!(p.len(), 1);
        bad.tets.push([0, 1, 2, 3]);
        assert_eq!(p.add(&bad), Err(e.clone()));
        assert_eq!(p.finish().unwrap_err(), e);
    }

    #[test]
    fn coordinates_too_large_for_the_checker_lattice_are_refused() {
        let big = (1 << 30) / CHECKER_FACTOR;
        let m = tet_mesh(
            vec![[0, 0, 0, 0], [big, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 1]],
            vec![[0, 1, 2, 3]],
        );
        assert_eq!(
            BodyPrep::of(&m, &[]).unwrap_err(),
            PrepError::Overflow { value: big }
        );
        let m = tet_mesh(
            vec![[0, 0, 0, 0], [big - 1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 1]],
            vec![[0, 1, 2, 3]],
        );
        assert!(BodyPrep::of(&m, &[]).is_ok());
    }

    #[test]
    fn vertices_are_numbered_by_first_use_and_tets_remember_their_place() {
        // Two pieces sharing vertices 1..=3; an unused vertex 9 is left out.
        let mut vertices: Vec<LatticePoint> =
            (0..10).map(|i| [i, i * i % 7, i % 3, i / 4]).collect();
        vertices[4] = [5, 5, 5, 2];
        let m = tet_mesh(
            vertices.clone(),
            vec![[0, 1, 2, 3], [4, 1, 2, 3], [5, 6, 7, 8]],
        );
        let l = BodyPrep::of(&m, &[0, 1]).unwrap();
        assert_eq!(l.mesh.tets.len(), 3);
        assert_eq!(l.mesh.vertices.len(), 9);
        let mut seen = 0;
        for (t, &o) in l.mesh.tets.iter().zip(&l.original) {
            for (&v, &w) in t.iter().zip(&m.tets[o as usize]) {
                assert_eq!(
                    l.mesh.vertices[v as usize],
                    vertices[w as usize].map(|c| c * CHECKER_FACTOR)
                );
                assert!(v <= seen, "vertex {v} used before {seen}");
                seen = seen.max(v + 1);
            }
        }
        // Tets 0 and 1 share face (1, 2, 3), across the two pieces.
        let at = |o: u32| l.original.iter().position(|&x| x == o).unwrap() as u32;
        assert!(l.adjacency[at(0) as usize].contains(&at(1)));
        assert_eq!(l.bvh.len(), 3);
    }
}
