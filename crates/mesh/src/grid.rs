//! One occupancy frame, decoded into padded bit rows (and values for graded input).
//!
//! The grid is padded by one free voxel on every side (everything outside the grid is free),
//! so the hypercubes that close the surface at the border exist like any other.

use super::MeshError;

/// The lattice every frame of one body must share.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridGeometry {
    /// Min corner of voxel (0,0,0) (m).
    pub origin: [f64; 3],
    /// Voxel edge (m).
    pub resolution: f64,
    /// Voxels along x, y, z.
    pub size: [u32; 3],
    /// Raw encoding.
    pub encoding: u8,
    /// Lattice steps per voxel edge and per frame.
    pub scale: i32,
}

impl GridGeometry {
    /// Centre of voxel (0,0,0) (m): lattice point (0,0,0,·).
    pub fn voxel0_centre(&self) -> [f64; 3] {
        self.origin.map(|o| o + 0.5 * self.resolution)
    }
    /// Metres per lattice step.
    pub fn step_m(&self) -> f64 {
        self.resolution / f64::from(self.scale)
    }
}

/// How the voxel data of a frame is encoded (mirrors the VoxelGrid `encoding` field).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Encoding {
    /// 1 bit per voxel, LSB first, x fastest, then y, then z.
    Bits,
    /// 1 byte per voxel: 0..=100 percent occupied, 255 unknown.
    Percent,
}

impl Encoding {
    /// The raw `encoding` field's value: 0 for BITS, 1 for PERCENT.
    pub const fn code(self) -> u8 {
        match self {
            Encoding::Bits => 0,
            Encoding::Percent => 1,
        }
    }
}

/// A borrowed view of one frame of one body, as the mesher needs it (no ROS types).
#[derive(Debug, Clone, Copy)]
pub struct FrameRef<'a> {
    /// Stamp (ns).
    pub stamp_ns: i64,
    /// Min corner of voxel (0, 0, 0) (m).
    pub origin: [f64; 3],
    /// Voxel edge (m).
    pub resolution: f64,
    /// Voxels along x, y, z.
    pub size: [u32; 3],
    /// Raw `encoding` field.
    pub encoding: u8,
    /// Voxel data.
    pub data: &'a [u8],
}

/// Default of [`DecodeOptions::max_decoded_bytes`]: 512 MiB per decoded frame. A body keeps
/// at most four decoded frames at once in the mesher (first, previous, the new one, and the
/// union filling a gap), so 2 GiB per body at worst.
pub const DEFAULT_MAX_DECODED_BYTES: u64 = 512 << 20;

/// Options for decoding frames.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecodeOptions {
    /// Largest accepted voxel count per frame (refused before allocating).
    pub max_voxels: u64,
    /// Percent value at and above which a voxel counts as occupied (the iso level).
    pub iso_percent: u8,
    /// Whether unknown (255) counts as occupied (the safe side for collision).
    pub unknown_occupied: bool,
    /// Largest accepted decoded size of one frame in bytes (padded bit rows, percent
    /// values, and the marcher's edge cache): thin grids cost more per voxel than their data.
    pub max_decoded_bytes: u64,
}

impl Default for DecodeOptions {
    fn default() -> Self {
        Self {
            max_voxels: 1 << 30,
            iso_percent: 50,
            unknown_occupied: true,
            max_decoded_bytes: DEFAULT_MAX_DECODED_BYTES,
        }
    }
}

/// A decoded frame: bit rows over padded x for every padded (y, z), plus padded percent
/// values for graded input.
#[derive(Debug, Clone, PartialEq)]
pub struct OccupancyGrid {
    /// Padded sizes (original + 2).
    pub padded: [usize; 3],
    /// u64 words per bit row (with at least one spare zero word at the end).
    pub words: usize,
    /// Bit rows, row index `y + py·z` (padded), bit x (padded).
    pub bits: Vec<u64>,
    /// Percent values of graded frames, by padded row (see [`Values`]); unknown is already
    /// mapped to 100 or 0.
    pub values: Option<Values>,
    /// Number of occupied voxels.
    pub occupied: u64,
    /// PERCENT voxels whose value was outside the domain (101..=254) and was read as 100
    /// (occupied, the safe side); the stream counts and names them.
    pub clamped: u64,
}

/// The percent values of a graded frame, one padded row (`px` values) at a time: only the
/// rows holding a value above zero are stored (most of a robot's or a person's frame is
/// empty, and its empty rows are then neither written nor zeroed nor compared). Stored rows
/// come in row order, so two equal grids have equal `Values`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Values {
    /// Padded row length.
    px: usize,
    /// For each padded row `y + py·z`: 0 if all its values are 0, else 1 + its place among
    /// the stored rows.
    rows: Vec<u32>,
    /// The stored rows, `px` values each.
    data: Vec<u8>,
}

impl Values {
    /// No row stored yet, for `rows` padded rows of `px` values.
    fn empty(px: usize, rows: usize) -> Self {
        Self {
            px,
            rows: vec![0; rows],
            data: Vec::new(),
        }
    }

    /// The values of padded row `r` (`None`: all 0).
    #[inline]
    pub fn row(&self, r: usize) -> Option<&[u8]> {
        match self.rows[r] {
            0 => None,
            k => Some(&self.data[(k as usize - 1) * self.px..][..self.px]),
        }
    }

    /// Value `x` of padded row `r`.
    #[inline]
    fn get(&self, x: usize, r: usize) -> u8 {
        match self.rows[r] {
            0 => 0,
            k => self.data[(k as usize - 1) * self.px + x],
        }
    }

    /// Row `r` (rows come in order), written by `fill`, which says whether a value of it is
    /// above 0: stored if one is (`true`), else left as zeros (`false`).
    fn push_row(&mut self, r: usize, fill: impl FnOnce(&mut [u8]) -> bool) -> bool {
        let start = self.data.len();
        self.data.resize(start + self.px, 0);
        if fill(&mut self.data[start..]) {
            // A row count past u32 would need more than 16 GiB of rows; such a frame is
            // refused by its memory limit long before (and kept as zeros if not).
            if let Ok(k) = u32::try_from(start / self.px + 1) {
                self.rows[r] = k;
                return true;
            }
        }
        self.data.truncate(start);
        false
    }

    /// Heap bytes.
    fn heap_bytes(&self) -> usize {
        self.rows.len() * 4 + self.data.len()
    }
}

impl OccupancyGrid {
    /// The frame with no voxel occupied on lattice `g` (what decoding an all-zero frame of
    /// its sizes and encoding gives, at an iso level above 0), without data to decode. Its
    /// memory is that of a decoded frame of `g`: only for a lattice whose frames were
    /// decoded (checked against the limits) already.
    pub fn empty(g: &GridGeometry) -> Self {
        let [sx, sy, sz] = g.size.map(|v| v as usize);
        let padded = [sx + 2, sy + 2, sz + 2];
        let words = (sx + 2) / 64 + 2;
        Self {
            padded,
            words,
            bits: vec![0u64; words * padded[1] * padded[2]],
            values: (g.encoding == Encoding::Percent.code())
                .then(|| Values::empty(padded[0], padded[1] * padded[2])),
            occupied: 0,
            clamped: 0,
        }
    }

    /// Heap bytes the decoded frame takes.
    pub fn heap_bytes(&self) -> u64 {
        (self.bits.len() * 8 + self.values.as_ref().map_or(0, Values::heap_bytes)) as u64
    }

    /// Decodes a frame after checking its fields.
    ///
    /// # Errors
    /// [`MeshError`] naming the field: bad resolution or origin, unknown encoding, sizes
    /// whose product exceeds `opts.max_voxels` (checked before allocating), data length not
    /// matching the sizes and encoding.
    pub fn decode(f: &FrameRef<'_>, opts: &DecodeOptions) -> Result<Self, MeshError> {
        if !(super::MIN_RESOLUTION_M..=super::MAX_RESOLUTION_M).contains(&f.resolution) {
            return Err(MeshError::BadResolution {
                resolution: f.resolution,
            });
        }
        if f.origin
            .iter()
            .any(|v| !(v.is_finite() && v.abs() <= super::MAX_ORIGIN_M))
        {
            return Err(MeshError::BadOrigin { origin: f.origin });
        }
        let encoding = match f.encoding {
            0 => Encoding::Bits,
            1 => Encoding::Percent,
            other => return Err(MeshError::UnknownEncoding { encoding: other }),
        };
        let [sx, sy, sz] = f.size.map(u64::from);
        // u32^3 can exceed u64: saturate, the limit check below refuses it anyway.
        let n = sx
            .checked_mul(sy)
            .and_then(|v| v.checked_mul(sz))
            .unwrap_or(u64::MAX);
        if sx == 0 || sy == 0 || sz == 0 {
            return Err(MeshError::EmptySize { size: f.size });
        }
        if n > opts.max_voxels {
            return Err(MeshError::TooLarge {
                size: f.size,
                voxels: n,
                limit: opts.max_voxels,
            });
        }
        let bytes = decoded_bytes(f.size, encoding);
        if bytes > opts.max_decoded_bytes {
            return Err(MeshError::TooMuchMemory {
                size: f.size,
                bytes,
                limit: opts.max_decoded_bytes,
            });
        }
        let expected = match encoding {
            Encoding::Bits => n.div_ceil(8),
            Encoding::Percent => n,
        };
        if f.data.len() as u64 != expected {
            return Err(MeshError::DataLength {
                expected,
                got: f.data.len() as u64,
                encoding,
            });
        }
        let (sx, sy, sz) = (sx as usize, sy as usize, sz as usize);
        let padded = [sx + 2, sy + 2, sz + 2];
        let words = (sx + 2) / 64 + 2;
        let mut bits = vec![0u64; words * padded[1] * padded[2]];
        let mut occupied = 0u64;
        let mut clamped = 0u64;
        let mut values = None;
        match encoding {
            Encoding::Bits => {
                for z in 0..sz {
                    for y in 0..sy {
                        let row = &mut bits[words * ((y + 1) + padded[1] * (z + 1))..][..words];
                        let start = sx * (y + sy * z);
                        copy_bits(f.data, start, sx, row);
                        occupied += row.iter().map(|w| u64::from(w.count_ones())).sum::<u64>();
                    }
                }
            }
            Encoding::Percent => {
                let mut v = Values::empty(padded[0], padded[1] * padded[2]);
                let unknown = if opts.unknown_occupied { 100 } else { 0 };
                for z in 0..sz {
                    for y in 0..sy {
                        let src = &f.data[sx * (y + sy * z)..][..sx];
                        // An empty row (most of a robot's or a person's frame) leaves its
                        // values and bits zero, untouched; with an iso level of 0 every
                        // voxel is occupied, so it is read.
                        if opts.iso_percent > 0 && src.iter().fold(0u8, |a, &b| a | b) == 0 {
                            continue;
                        }
                        let r = (y + 1) + padded[1] * (z + 1);
                        let row = &mut bits[words * r..][..words];
                        let fill = |dst: &mut [u8]| {
                            let dst = &mut dst[1..1 + sx];
                            // Branch-free, so that both loops vectorise: the values
                            // (unknown as asked, above 100 clamped), then the occupancy 64
                            // voxels at a time, voxel x at bit x + 1 of the row.
                            let mut any = 0u8;
                            for (d, &raw) in dst.iter_mut().zip(src) {
                                clamped += u64::from(raw > 100 && raw != 255);
                                *d = if raw == 255 { unknown } else { raw.min(100) };
                                any |= *d;
                            }
                            for (c, chunk) in dst.chunks(64).enumerate() {
                                let mut m = 0u64;
                                for (i, &val) in chunk.iter().enumerate() {
                                    m |= u64::from(val >= opts.iso_percent) << i;
                                }
                                occupied += u64::from(m.count_ones());
                                row[c] |= m << 1;
                                row[c + 1] |= m >> 63;
                            }
                            any != 0
                        };
                        v.push_row(r, fill);
                    }
                }
                values = Some(v);
            }
        }
        Ok(Self {
            padded,
            words,
            bits,
            values,
            occupied,
            clamped,
        })
    }

    /// The voxels occupied in either frame (same lattice): bits OR-ed, percent values the
    /// maximum. `None` if the two grids have different sizes or encodings.
    pub fn union(&self, other: &OccupancyGrid) -> Option<OccupancyGrid> {
        self.combine(other, |a, b| a | b, u8::max)
    }

    /// The voxels occupied in both frames (same lattice): bits AND-ed, percent values the
    /// minimum (the occupied fraction of the intersection is at most either). `None` if
    /// the two grids have different sizes or encodings.
    pub fn intersect(&self, other: &OccupancyGrid) -> Option<OccupancyGrid> {
        self.combine(other, |a, b| a & b, u8::min)
    }

    fn combine(
        &self,
        other: &OccupancyGrid,
        bit: impl Fn(u64, u64) -> u64,
        value: impl Fn(u8, u8) -> u8,
    ) -> Option<OccupancyGrid> {
        if self.values.is_some() != other.values.is_some() {
            return None;
        }
        let mut g = self.combine_bits(other, bit)?;
        g.values = match (&self.values, &other.values) {
            (Some(a), Some(b)) => {
                let mut v = Values::empty(a.px, a.rows.len());
                let zeros = vec![0u8; a.px];
                for r in 0..a.rows.len() {
                    let (ra, rb) = (a.row(r), b.row(r));
                    if ra.is_none() && rb.is_none() {
                        continue;
                    }
                    let (ra, rb) = (ra.unwrap_or(&zeros), rb.unwrap_or(&zeros));
                    v.push_row(r, |dst| {
                        let mut any = 0u8;
                        for ((d, &x), &y) in dst.iter_mut().zip(ra).zip(rb) {
                            *d = value(x, y);
                            any |= *d;
                        }
                        any != 0
                    });
                }
                Some(v)
            }
            _ => None,
        };
        Some(g)
    }

    /// The bit rows of two grids of one size combined word by word, without values (a BITS
    /// grid whatever the two encodings). `None` if the sizes differ.
    fn combine_bits(
        &self,
        other: &OccupancyGrid,
        bit: impl Fn(u64, u64) -> u64,
    ) -> Option<OccupancyGrid> {
        if self.padded != other.padded || self.words != other.words {
            return None;
        }
        let bits: Vec<u64> = self
            .bits
            .iter()
            .zip(&other.bits)
            .map(|(a, b)| bit(*a, *b))
            .collect();
        let occupied = bits.iter().map(|w| u64::from(w.count_ones())).sum();
        Some(OccupancyGrid {
            padded: self.padded,
            words: self.words,
            bits,
            values: None,
            occupied,
            clamped: 0,
        })
    }

    /// Bit row for padded (y, z).
    #[inline]
    pub fn row(&self, y: usize, z: usize) -> &[u64] {
        &self.bits[self.words * (y + self.padded[1] * z)..][..self.words]
    }

    /// Occupancy of padded voxel (x, y, z).
    #[inline]
    pub fn get(&self, x: usize, y: usize, z: usize) -> bool {
        (self.row(y, z)[x / 64] >> (x % 64)) & 1 == 1
    }

    /// Percent value of padded voxel (x, y, z) (100/0 for binary frames).
    #[inline]
    pub fn value(&self, x: usize, y: usize, z: usize) -> u8 {
        match &self.values {
            Some(v) => v.get(x, y + self.padded[1] * z),
            None => 100 * u8::from(self.get(x, y, z)),
        }
    }
}

/// The lattice [`intersect_across`] gives two frames on `ga` and `gb`: `ga` itself when they
/// are the same (PERCENT frames then keep their values), else `ga`'s grid as BITS; `None`
/// where it gives none.
pub fn intersection_geometry(ga: &GridGeometry, gb: &GridGeometry) -> Option<GridGeometry> {
    if ga == gb {
        return Some(*ga);
    }
    across(ga, gb).map(|(g, _)| g)
}

/// For two different lattices: `ga`'s grid as BITS, and `gb`'s origin in whole voxels from
/// `ga`'s (`None` if the resolutions differ or the origins are not whole voxels apart).
fn across(ga: &GridGeometry, gb: &GridGeometry) -> Option<(GridGeometry, [i64; 3])> {
    if (ga.resolution - gb.resolution).abs() > 1e-9 * ga.resolution {
        return None;
    }
    let mut off = [0i64; 3];
    for (o, (b, a)) in off.iter_mut().zip(gb.origin.iter().zip(&ga.origin)) {
        let v = (b - a) / ga.resolution;
        let r = v.round();
        if (v - r).abs() > 1e-6 || !r.is_finite() || r.abs() > 1e9 {
            return None;
        }
        *o = r as i64;
    }
    let g = GridGeometry {
        encoding: Encoding::Bits.code(),
        scale: 2,
        ..*ga
    };
    Some((g, off))
}

/// The voxels occupied in both of two frames of bodies whose lattices differ by a whole
/// number of voxels in origin and/or by encoding (same resolution), on `ga`'s grid as a BITS
/// frame (PERCENT frames count at their iso level, as their bits say). Frames on the same
/// lattice use [`OccupancyGrid::intersect`] instead (it keeps percent values).
///
/// `None` if the resolutions differ or the origins are not a whole number of voxels apart.
pub fn intersect_across(
    a: &OccupancyGrid,
    ga: &GridGeometry,
    b: &OccupancyGrid,
    gb: &GridGeometry,
) -> Option<(OccupancyGrid, GridGeometry)> {
    if ga == gb {
        return a.intersect(b).map(|g| (g, *ga));
    }
    let (g, off) = across(ga, gb)?;
    // The same lattice in another encoding (a PERCENT robot against a BITS table): the bit
    // rows line up word for word (padding and spare words are zero in both).
    if off == [0; 3] && ga.size == gb.size {
        if let Some(grid) = a.combine_bits(b, |x, y| x & y) {
            return Some((grid, g));
        }
    }
    intersect_offset(a, ga, b, gb, off, g)
}

/// [`intersect_across`] voxel by voxel, `b`'s lattice `off` voxels from `a`'s.
fn intersect_offset(
    a: &OccupancyGrid,
    ga: &GridGeometry,
    b: &OccupancyGrid,
    gb: &GridGeometry,
    off: [i64; 3],
    g: GridGeometry,
) -> Option<(OccupancyGrid, GridGeometry)> {
    let [sx, sy, sz] = ga.size.map(|v| v as usize);
    let [bx, by, bz] = gb.size.map(|v| v as i64);
    let n = sx.checked_mul(sy)?.checked_mul(sz)?;
    let mut data = vec![0u8; n.div_ceil(8)];
    for z in 0..sz {
        let zb = z as i64 - off[2];
        if !(0..bz).contains(&zb) {
            continue;
        }
        for y in 0..sy {
            let yb = y as i64 - off[1];
            if !(0..by).contains(&yb) {
                continue;
            }
            for x in 0..sx {
                let xb = x as i64 - off[0];
                if (0..bx).contains(&xb)
                    && a.get(x + 1, y + 1, z + 1)
                    && b.get(xb as usize + 1, yb as usize + 1, zb as usize + 1)
                {
                    let i = x + sx * (y + sy * z);
                    data[i / 8] |= 1 << (i % 8);
                }
            }
        }
    }
    let f = FrameRef {
        stamp_ns: 0,
        origin: g.origin,
        resolution: g.resolution,
        size: g.size,
        encoding: 0,
        data: &data,
    };
    let opts = DecodeOptions {
        max_voxels: u64::MAX,
        max_decoded_bytes: u64::MAX,
        ..DecodeOptions::default()
    };
    OccupancyGrid::decode(&f, &opts).ok().map(|grid| (grid, g))
}

/// Bytes a decoded frame and its share of the marcher's workspace take (saturating).
pub fn decoded_bytes(size: [u32; 3], encoding: Encoding) -> u64 {
    let [px, py, pz] = size.map(|v| u64::from(v) + 2);
    let words = px / 64 + 2;
    let rows = py.saturating_mul(pz);
    let bits = rows.saturating_mul(words).saturating_mul(8);
    // At most every row stored, and each row's place.
    let values = match encoding {
        Encoding::Bits => 0,
        Encoding::Percent => px.saturating_add(4).saturating_mul(rows),
    };
    // Two z-layers of 7 edge slots of u32 in the marcher, plus the touched lists.
    let cache = px.saturating_mul(py).saturating_mul(2 * 7 * 4 * 2);
    bits.saturating_add(values).saturating_add(cache)
}

/// Copies `len` bits starting at bit `start` of `src` (LSB first) into `dst` at bit 1.
fn copy_bits(src: &[u8], start: usize, len: usize, dst: &mut [u64]) {
    let mut x = 0;
    // Bit-by-bit until the source is byte aligned, then whole words, whole bytes, bits.
    while x < len && (start + x) % 8 != 0 {
        set_from(src, start + x, x + 1, dst);
        x += 1;
    }
    while x + 64 <= len {
        let at_byte = (start + x) / 8;
        let mut le = [0u8; 8];
        le.copy_from_slice(&src[at_byte..at_byte + 8]);
        let word = u64::from_le_bytes(le);
        let at = x + 1;
        dst[at / 64] |= word << (at % 64);
        if at % 64 != 0 {
            dst[at / 64 + 1] |= word >> (64 - at % 64);
        }
        x += 64;
    }
    while x + 8 <= len {
        let byte = u64::from(src[(start + x) / 8]);
        let at = x + 1;
        dst[at / 64] |= byte << (at % 64);
        if at % 64 > 56 {
            dst[at / 64 + 1] |= byte >> (64 - at % 64);
        }
        x += 8;
    }
    while x < len {
        set_from(src, start + x, x + 1, dst);
        x += 1;
    }
}

#[inline]
fn set_from(src: &[u8], bit: usize, at: usize, dst: &mut [u64]) {
    if (src[bit / 8] >> (bit % 8)) & 1 == 1 {
        dst[at / 64] |= 1 << (at % 64);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Copying a bit row by words and bytes sets the bits one by one would: every start
    /// offset within a byte and every length across word boundaries, on random bits.
    #[test]
    fn rows_copy_as_bit_by_bit() {
        let mut rng = chronotope_kernel::intersect::test_rng::Rng(0x9e37_79b9_7f4a_7c15);
        let src: Vec<u8> = (0..64).map(|_| rng.next() as u8).collect();
        for start in 0..24 {
            for len in 0..=(src.len() * 8 - start).min(300) {
                let words = (len + 2) / 64 + 2;
                let mut fast = vec![0u64; words];
                copy_bits(&src, start, len, &mut fast);
                let mut slow = vec![0u64; words];
                for x in 0..len {
                    set_from(&src, start + x, x + 1, &mut slow);
                }
                assert_eq!(fast, slow, "start {start}, length {len}");
            }
        }
    }

    /// The empty frame of a lattice is the one decoding an all-zero frame gives, in both
    /// encodings and at sizes across a word of a row.
    #[test]
    fn an_empty_frame_is_an_all_zero_one_decoded() {
        for size in [[1u32, 1, 1], [5, 4, 3], [62, 2, 3], [63, 3, 2], [130, 2, 2]] {
            for encoding in [0u8, 1] {
                let n = size.iter().product::<u32>() as usize;
                let data = vec![0u8; if encoding == 0 { n.div_ceil(8) } else { n }];
                let f = FrameRef {
                    stamp_ns: 0,
                    origin: [0.0; 3],
                    resolution: 0.01,
                    size,
                    encoding,
                    data: &data,
                };
                let decoded = OccupancyGrid::decode(&f, &DecodeOptions::default()).unwrap();
                let g = GridGeometry {
                    origin: [0.0; 3],
                    resolution: 0.01,
                    size,
                    encoding,
                    scale: 2,
                };
                assert_eq!(OccupancyGrid::empty(&g), decoded, "{size:?} {encoding}");
            }
        }
    }

    /// A PERCENT frame of `size` voxels of 1 cm at the origin.
    fn percent_frame(size: [u32; 3], data: &[u8]) -> FrameRef<'_> {
        FrameRef {
            stamp_ns: 0,
            origin: [0.0; 3],
            resolution: 0.01,
            size,
            encoding: 1,
            data,
        }
    }

    /// PERCENT frames with empty rows decode as voxel by voxel: values (unknown and
    /// out-of-range ones mapped), bits at the iso level, counts; at iso levels 0 and 50.
    #[test]
    fn percent_frames_with_empty_rows_decode_voxel_by_voxel() {
        let mut rng = chronotope_kernel::intersect::test_rng::Rng(0x6a09_e667_f3bc_c908);
        // Rows shorter than a word, a word, across word boundaries.
        for size in [[70u32, 5, 4], [64, 3, 2], [1, 3, 2], [129, 2, 3]] {
            let [sx, sy, sz] = size.map(|v| v as usize);
            let n = sx * sy * sz;
            // Every other row empty, the rest random over 0..=255.
            let data: Vec<u8> = (0..n)
                .map(|i| {
                    if (i / sx) % 2 == 0 {
                        0
                    } else {
                        rng.next() as u8
                    }
                })
                .collect();
            for (iso, unknown_occupied) in [(50u8, false), (50, true), (0, false)] {
                let opts = DecodeOptions {
                    iso_percent: iso,
                    unknown_occupied,
                    ..DecodeOptions::default()
                };
                let g = OccupancyGrid::decode(&percent_frame(size, &data), &opts).unwrap();
                let (mut occupied, mut clamped) = (0, 0);
                for (i, &raw) in data.iter().enumerate() {
                    let (x, y, z) = (i % sx, i / sx % sy, i / (sx * sy));
                    let want = match raw {
                        255 => 100 * u8::from(unknown_occupied),
                        101..=254 => 100,
                        r => r,
                    };
                    let at = format!("voxel {i} of {size:?}, iso {iso}");
                    assert_eq!(g.value(x + 1, y + 1, z + 1), want, "{at}");
                    assert_eq!(g.get(x + 1, y + 1, z + 1), want >= iso, "{at}");
                    occupied += u64::from(want >= iso);
                    clamped += u64::from((101..=254).contains(&raw));
                }
                // The padding stays empty.
                for (x, y, z) in [(0, 1, 1), (sx + 1, 1, 1), (1, 0, 1), (1, 1, sz + 1)] {
                    assert!(!g.get(x, y, z), "padding {x} {y} {z} of {size:?}");
                }
                assert_eq!(g.occupied, occupied, "{size:?}, iso {iso}");
                assert_eq!(g.clamped, clamped, "{size:?}, iso {iso}");
            }
        }
    }

    /// Two PERCENT frames with empty rows (some only after unknown is mapped to 0): their
    /// union and intersection hold, voxel by voxel, the larger and the smaller value; a
    /// grid equals the one decoded from the same values written another way.
    #[test]
    fn percent_rows_combine_and_compare_voxel_by_voxel() {
        let mut rng = chronotope_kernel::intersect::test_rng::Rng(0x510e_527f_ade6_82d1);
        let opts = DecodeOptions {
            unknown_occupied: false,
            ..DecodeOptions::default()
        };
        for size in [[70u32, 5, 4], [1, 3, 2], [129, 2, 3]] {
            let [sx, sy, sz] = size.map(|v| v as usize);
            let n = sx * sy * sz;
            // Rows empty, unknown only, or random over 0..=100.
            let frame_data = |rng: &mut chronotope_kernel::intersect::test_rng::Rng| -> Vec<u8> {
                let kinds: Vec<u64> = (0..sy * sz).map(|_| rng.next() % 3).collect();
                (0..n)
                    .map(|i| match kinds[i / sx] {
                        0 => 0,
                        1 => 255,
                        _ => (rng.next() % 101) as u8,
                    })
                    .collect()
            };
            let decode =
                |data: &[u8]| OccupancyGrid::decode(&percent_frame(size, data), &opts).unwrap();
            for _ in 0..20 {
                let (da, db) = (frame_data(&mut rng), frame_data(&mut rng));
                let (a, b) = (decode(&da), decode(&db));
                let (u, i) = (a.union(&b).unwrap(), a.intersect(&b).unwrap());
                let mapped = |raw: u8| if raw == 255 { 0 } else { raw };
                for k in 0..n {
                    let (x, y, z) = (k % sx + 1, k / sx % sy + 1, k / (sx * sy) + 1);
                    let (va, vb) = (mapped(da[k]), mapped(db[k]));
                    assert_eq!(a.value(x, y, z), va);
                    assert_eq!(u.value(x, y, z), va.max(vb), "union, voxel {k} of {size:?}");
                    assert_eq!(i.value(x, y, z), va.min(vb), "intersection, voxel {k}");
                    assert_eq!(i.get(x, y, z), va.min(vb) >= 50, "voxel {k}");
                }
                // Unknown read as 0 is a 0 written as such.
                let zeros: Vec<u8> = da.iter().map(|&r| mapped(r)).collect();
                assert_eq!(decode(&zeros), a, "{size:?}");
                assert!(a.heap_bytes() <= super::decoded_bytes(size, Encoding::Percent));
            }
        }
    }

    /// A PERCENT frame against a BITS frame on the same lattice: the word-wise intersection
    /// is the voxel-by-voxel one, on random frames of sizes across word boundaries.
    #[test]
    fn the_same_lattice_in_two_encodings_intersects_as_voxel_by_voxel() {
        let mut rng = chronotope_kernel::intersect::test_rng::Rng(0x2545_f491_4f6c_dd1d);
        for size in [[1, 1, 1], [5, 3, 2], [63, 2, 3], [64, 4, 1], [130, 3, 2]] {
            let n = (size[0] * size[1] * size[2]) as usize;
            let percent: Vec<u8> = (0..n).map(|_| (rng.next() % 101) as u8).collect();
            let bits: Vec<u8> = (0..n.div_ceil(8)).map(|_| rng.next() as u8).collect();
            let geometry = |encoding: u8, scale: i32| super::GridGeometry {
                origin: [0.5, -1.0, 0.0],
                resolution: 0.01,
                size,
                encoding,
                scale,
            };
            let frame = |encoding: u8, data: &[u8]| {
                let f = FrameRef {
                    stamp_ns: 0,
                    origin: [0.5, -1.0, 0.0],
                    resolution: 0.01,
                    size,
                    encoding,
                    data,
                };
                OccupancyGrid::decode(&f, &DecodeOptions::default()).unwrap()
            };
            let (a, ga) = (frame(1, &percent), geometry(1, 100));
            let (b, gb) = (frame(0, &bits), geometry(0, 2));
            let (fast, g) = intersect_across(&a, &ga, &b, &gb).unwrap();
            let (slow, g2) = intersect_offset(&a, &ga, &b, &gb, [0; 3], g).unwrap();
            assert_eq!(g, g2);
            assert_eq!(fast.bits, slow.bits, "{size:?}");
            assert_eq!(fast.occupied, slow.occupied, "{size:?}");
            assert!(fast.values.is_none() && slow.values.is_none());
        }
    }
}
