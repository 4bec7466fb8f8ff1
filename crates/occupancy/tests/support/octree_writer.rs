//! A small octree writer for tests and the benchmark, written from OctoMap's
//! stream description independently of the crate's reader: a boxed tree built
//! from leaves (or from a dense function, pruned), serialised in the binary
//! stream (`writeBinaryData`) and the full stream (`writeData`).
#![allow(dead_code)]

/// A node: a leaf with its log-odds, or an inner node with up to 8 children
/// (child `i`: x half by bit 0, y by bit 1, z by bit 2).
#[derive(Clone, Debug, PartialEq)]
pub enum Tree {
    Leaf(f32),
    Inner(Box<[Option<Tree>; 8]>),
}

pub const DEPTH: u32 = 16;

fn empty_children() -> Box<[Option<Tree>; 8]> {
    Box::new([None, None, None, None, None, None, None, None])
}

/// Inserts a leaf of `depth` whose min key is `key` (must be aligned to its size).
/// Replaces whatever was there.
pub fn insert(root: &mut Option<Tree>, key: [u32; 3], depth: u32, value: f32) {
    assert!(depth <= DEPTH);
    let size = 1u32 << (DEPTH - depth);
    assert!(
        key.iter().all(|k| k % size == 0 && *k < 1 << 16),
        "unaligned key"
    );
    let mut node = root;
    for d in 0..depth {
        let bit = DEPTH - 1 - d;
        let child = ((key[0] >> bit) & 1) | ((key[1] >> bit) & 1) << 1 | ((key[2] >> bit) & 1) << 2;
        if !matches!(node, Some(Tree::Inner(_))) {
            *node = Some(Tree::Inner(empty_children()));
        }
        let Some(Tree::Inner(children)) = node else {
            unreachable!()
        };
        node = &mut children[child as usize];
    }
    *node = Some(Tree::Leaf(value));
}

/// A tree over the key box `lo..hi` (depth-16 cells), `cell` giving each
/// cell's log-odds or `None` for unknown; 8 equal leaves merge into one, as
/// OctoMap prunes.
pub fn from_cells(
    lo: [u32; 3],
    hi: [u32; 3],
    cell: &dyn Fn([u32; 3]) -> Option<f32>,
) -> Option<Tree> {
    fn rec(
        key: [u32; 3],
        depth: u32,
        lo: [u32; 3],
        hi: [u32; 3],
        cell: &dyn Fn([u32; 3]) -> Option<f32>,
    ) -> Option<Tree> {
        let size = 1u32 << (DEPTH - depth);
        if (0..3).any(|a| key[a] + size <= lo[a] || key[a] >= hi[a]) {
            return None;
        }
        if depth == DEPTH {
            return cell(key).map(Tree::Leaf);
        }
        let half = size / 2;
        let mut children = empty_children();
        for (i, c) in children.iter_mut().enumerate() {
            let i = i as u32;
            let k = [
                key[0] + (i & 1) * half,
                key[1] + (i >> 1 & 1) * half,
                key[2] + (i >> 2 & 1) * half,
            ];
            *c = rec(k, depth + 1, lo, hi, cell);
        }
        if children.iter().all(Option::is_none) {
            return None;
        }
        if let Some(Tree::Leaf(v)) = &children[0] {
            let v = *v;
            if children
                .iter()
                .all(|c| matches!(c, Some(Tree::Leaf(w)) if w.to_bits() == v.to_bits()))
            {
                return Some(Tree::Leaf(v));
            }
        }
        Some(Tree::Inner(children))
    }
    rec([0; 3], 0, lo, hi, cell)
}

/// Every leaf: (min key, depth, log-odds).
pub fn leaves(root: &Option<Tree>) -> Vec<([u32; 3], u32, f32)> {
    fn rec(t: &Tree, key: [u32; 3], depth: u32, out: &mut Vec<([u32; 3], u32, f32)>) {
        match t {
            Tree::Leaf(v) => out.push((key, depth, *v)),
            Tree::Inner(ch) => {
                let half = 1u32 << (DEPTH - depth - 1);
                for (i, c) in ch.iter().enumerate() {
                    if let Some(c) = c {
                        let i = i as u32;
                        let k = [
                            key[0] + (i & 1) * half,
                            key[1] + (i >> 1 & 1) * half,
                            key[2] + (i >> 2 & 1) * half,
                        ];
                        rec(c, k, depth + 1, out);
                    }
                }
            }
        }
    }
    let mut out = Vec::new();
    if let Some(t) = root {
        rec(t, [0; 3], 0, &mut out);
    }
    out
}

/// The binary stream: per inner node 2 bytes, child `i`'s 2 bits at bits
/// `2(i % 4)` of byte `i / 4`: 01 free leaf, 10 occupied leaf, 11 inner, 00
/// unknown; then the inner children in order. A root leaf writes `00 00`, as
/// OctoMap's writer does.
pub fn binary(root: &Option<Tree>, threshold: f32) -> Vec<u8> {
    fn rec(children: &[Option<Tree>; 8], threshold: f32, out: &mut Vec<u8>) {
        let mut codes = [0u8; 2];
        for (i, c) in children.iter().enumerate() {
            let code = match c {
                None => 0,
                Some(Tree::Leaf(v)) if *v >= threshold => 2,
                Some(Tree::Leaf(_)) => 1,
                Some(Tree::Inner(_)) => 3,
            };
            codes[i / 4] |= code << (2 * (i % 4));
        }
        out.extend_from_slice(&codes);
        for c in children.iter().flatten() {
            if let Tree::Inner(ch) = c {
                rec(ch, threshold, out);
            }
        }
    }
    let mut out = Vec::new();
    match root {
        None => {}
        Some(Tree::Leaf(_)) => out.extend_from_slice(&[0, 0]),
        Some(Tree::Inner(ch)) => rec(ch, threshold, &mut out),
    }
    out
}

/// The full stream: per node its log-odds (little-endian f32; inner nodes the
/// max of their children), `extra` bytes, a child bit mask, then the children.
pub fn full(root: &Option<Tree>, extra: &[u8]) -> Vec<u8> {
    fn value(t: &Tree) -> f32 {
        match t {
            Tree::Leaf(v) => *v,
            Tree::Inner(ch) => ch
                .iter()
                .flatten()
                .map(value)
                .fold(f32::NEG_INFINITY, f32::max),
        }
    }
    fn rec(t: &Tree, extra: &[u8], out: &mut Vec<u8>) {
        out.extend_from_slice(&value(t).to_le_bytes());
        out.extend_from_slice(extra);
        match t {
            Tree::Leaf(_) => out.push(0),
            Tree::Inner(ch) => {
                let mut mask = 0u8;
                for (i, c) in ch.iter().enumerate() {
                    if c.is_some() {
                        mask |= 1 << i;
                    }
                }
                out.push(mask);
                for c in ch.iter().flatten() {
                    rec(c, extra, out);
                }
            }
        }
    }
    let mut out = Vec::new();
    if let Some(t) = root {
        rec(t, extra, &mut out);
    }
    out
}

/// Key of the cell containing coordinate `x` (metres) for `resolution`.
pub fn key_of(x: f64, resolution: f64) -> u32 {
    ((x / resolution).floor() as i64 + 32768) as u32
}
