//! The marching-hypercubes table, generated at build time by [`super::table_gen`].

use std::sync::OnceLock;

static TABLE_BYTES: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/mc4_table.bin"));

/// Lateral tets for each of the 2^16 hypercube cases and cap tets for each of the 2^8 cube
/// cases. Lateral tets are edge ids (0..32, see [`super::table_gen::edge4`]) oriented
/// outward of the occupied region; cap tets are cube point ids (corners 0..8, then
/// 8 + edge) with positive 3D orientation.
#[derive(Debug)]
pub struct Table {
    lateral_offsets: Vec<u32>,
    lateral: Vec<[u8; 4]>,
    cap_offsets: Vec<u32>,
    cap: Vec<[u8; 4]>,
}

impl Table {
    /// Lateral tets of a hypercube case (bit c set = corner c occupied).
    #[inline]
    pub fn lateral(&self, case: u16) -> &[[u8; 4]] {
        let c = usize::from(case);
        &self.lateral[self.lateral_offsets[c] as usize..self.lateral_offsets[c + 1] as usize]
    }

    /// Cap tets of a cube case (bit c set = corner c occupied).
    #[inline]
    pub fn cap(&self, case: u8) -> &[[u8; 4]] {
        let c = usize::from(case);
        &self.cap[self.cap_offsets[c] as usize..self.cap_offsets[c + 1] as usize]
    }

    /// Total number of lateral tets over all cases.
    pub fn lateral_total(&self) -> usize {
        self.lateral.len()
    }

    /// Largest number of lateral tets in one case.
    pub fn lateral_max(&self) -> usize {
        self.lateral_offsets
            .windows(2)
            .map(|w| (w[1] - w[0]) as usize)
            .max()
            .unwrap_or(0)
    }
}

fn parse(bytes: &[u8]) -> Table {
    // The bytes are our own build output; a malformed table is a build bug, not input.
    let magic = super::table_gen::TABLE_MAGIC;
    assert_eq!(&bytes[..magic.len()], magic, "marching table magic");
    let mut pos = magic.len();
    let u32s = |n: usize, pos: &mut usize| -> Vec<u32> {
        let v = bytes[*pos..*pos + 4 * n]
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        *pos += 4 * n;
        v
    };
    let lateral_offsets = u32s(65537, &mut pos);
    let n = *lateral_offsets.last().expect("offsets") as usize;
    let lateral = bytes[pos..pos + 4 * n]
        .chunks_exact(4)
        .map(|c| [c[0], c[1], c[2], c[3]])
        .collect();
    pos += 4 * n;
    let cap_offsets = u32s(257, &mut pos);
    let m = *cap_offsets.last().expect("offsets") as usize;
    let cap = bytes[pos..pos + 4 * m]
        .chunks_exact(4)
        .map(|c| [c[0], c[1], c[2], c[3]])
        .collect();
    Table {
        lateral_offsets,
        lateral,
        cap_offsets,
        cap,
    }
}

/// The table (parsed once, on first use).
pub fn table() -> &'static Table {
    static T: OnceLock<Table> = OnceLock::new();
    T.get_or_init(|| parse(TABLE_BYTES))
}
