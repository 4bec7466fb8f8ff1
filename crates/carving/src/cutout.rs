//! Cut-outs (seed §4.1): a binary image held against the workpiece along an axis removes the
//! material over its white pixels (eq. 1), and the material along the image's contour gets
//! side surfels facing the removed part.
//!
//! Images: PGM (`P2` text or `P5` binary, read here) and PNG (8- or 16-bit grey, grey+alpha,
//! RGB or RGBA, through the `png` crate). A pixel is black (material kept) if its grey value
//! is below half the maximum.

use std::path::{Path, PathBuf};

use super::math::{add, norm, scale, Vec3};
use super::workpiece::{Workpiece, BOUND, COLOUR_CUTOUT, OUTSIDE};
use super::{CarveError, CutStats};

/// Largest image side (pixels).
pub const MAX_IMAGE_SIDE: usize = 8192;

/// Largest image file read (bytes): 256 MiB holds an 8192² 16-bit P5 (128 MiB) or a P2
/// of one-digit pixels (128 MiB); anything larger is refused before it is read.
pub const MAX_IMAGE_FILE_BYTES: u64 = 256 << 20;

/// Why an image could not be used.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The path is not a regular file (a FIFO, a device, a directory): it is refused
    /// before it is opened, since reading a FIFO or a device may block forever.
    #[error("{path}: not a regular file ({kind}); a cut-out image must be a file")]
    NotAFile {
        /// The path.
        path: PathBuf,
        /// What it is.
        kind: &'static str,
    },
    /// The file is larger than [`MAX_IMAGE_FILE_BYTES`].
    #[error(
        "{path}: {bytes} bytes, over the {max}-byte limit of an image file (MAX_IMAGE_FILE_BYTES)"
    )]
    TooLarge {
        /// The path.
        path: PathBuf,
        /// Its size.
        bytes: u64,
        /// The limit.
        max: u64,
    },
    /// The file is not an image this reads, or is malformed.
    #[error("{path}: {reason}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        #[source]
        reason: FormatError,
    },
}

/// What is wrong with an image's bytes: not a PGM or PNG this reads, malformed, or too large.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    /// Neither PGM's magic (`P2`, `P5`) nor PNG's.
    #[error("not a PGM (magic {magic:?}; P2 or P5 expected) nor a PNG")]
    NotAnImage {
        /// The first token of the file.
        magic: String,
    },
    /// The PGM header stops before its width, height and maxval (or a P2 before its pixels).
    #[error("the PGM header ends early")]
    PgmEnds,
    /// A PGM header field or P2 pixel that is not a number.
    #[error("PGM {what} {token:?} is not a number")]
    PgmNumber {
        /// What it is (`width`, `height`, `maxval`, `pixel`).
        what: &'static str,
        /// The text found.
        token: String,
    },
    /// A PGM maxval out of 1..=65535.
    #[error("PGM maxval {0}: 1..=65535 allowed")]
    PgmMaxval(usize),
    /// P5 pixel data shorter than its header says.
    #[error("P5 data holds {held} bytes, {needed} needed")]
    P5Short {
        /// Bytes after the header.
        held: usize,
        /// Bytes the header's size asks for.
        needed: usize,
    },
    /// An empty image, or one larger than [`MAX_IMAGE_SIDE`] on a side.
    #[error("image is {width}x{height} pixels: 1..={MAX_IMAGE_SIDE} on a side allowed")]
    Size {
        /// Columns.
        width: usize,
        /// Rows.
        height: usize,
    },
    /// The PNG decoder cannot size its output buffer.
    #[error("PNG: image too large")]
    PngTooLarge,
    /// A palette image the decoder did not expand.
    #[error("PNG: indexed colour not expanded")]
    PngIndexed,
    /// The PNG ends early or cannot be read.
    #[error("PNG: truncated or unreadable ({0})")]
    PngUnreadable(std::io::Error),
    /// A chunk length, CRC or header field of the PNG is wrong.
    #[error("PNG: malformed or damaged (a chunk length, CRC or header field is wrong)")]
    PngDamaged,
    /// The PNG decoder was called wrongly.
    #[error("PNG: the decoder was misused (a bug)")]
    PngMisused,
    /// The PNG is larger than the decoder's memory limit.
    #[error("PNG: the image is larger than the decoder's memory limit")]
    PngLimits,
}

/// A binary image: `black[row * width + col]`, row 0 at the top.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BinaryImage {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Black (material kept) pixels, row-major.
    pub black: Vec<bool>,
}

impl BinaryImage {
    /// Reads a PGM or PNG file (by its magic bytes).
    ///
    /// # Errors
    /// [`ImageError::Io`] if it cannot be read, [`ImageError::NotAFile`] for anything but a
    /// regular file (checked before opening: a FIFO would block),
    /// [`ImageError::TooLarge`] above [`MAX_IMAGE_FILE_BYTES`], [`ImageError::Format`] if it
    /// is neither a well-formed PGM nor a PNG, or larger than [`MAX_IMAGE_SIDE`] on a side.
    pub fn load(path: &Path) -> Result<Self, ImageError> {
        use std::io::Read;
        let io = |source| ImageError::Io {
            path: path.to_owned(),
            source,
        };
        let meta = std::fs::metadata(path).map_err(io)?;
        check_regular(path, &meta)?;
        let file = std::fs::File::open(path).map_err(io)?;
        // The file opened may not be the one looked at (replaced in between): check again.
        let meta = file.metadata().map_err(io)?;
        check_regular(path, &meta)?;
        let mut bytes = Vec::new();
        // Read at most one byte past the limit: a file growing while read is caught too.
        file.take(MAX_IMAGE_FILE_BYTES + 1)
            .read_to_end(&mut bytes)
            .map_err(io)?;
        if bytes.len() as u64 > MAX_IMAGE_FILE_BYTES {
            return Err(ImageError::TooLarge {
                path: path.to_owned(),
                bytes: meta.len().max(bytes.len() as u64),
                max: MAX_IMAGE_FILE_BYTES,
            });
        }
        let r = if bytes.starts_with(b"\x89PNG") {
            Self::from_png(&bytes)
        } else {
            Self::from_pgm(&bytes)
        };
        r.map_err(|reason| ImageError::Format {
            path: path.to_owned(),
            reason,
        })
    }

    /// Parses a PGM (`P2` or `P5`, maxval up to 65535).
    ///
    /// # Errors
    /// What is malformed.
    pub fn from_pgm(bytes: &[u8]) -> Result<Self, FormatError> {
        let mut pos = 0usize;
        // Header tokens, skipping whitespace and comments.
        let token = |pos: &mut usize| -> Result<String, FormatError> {
            loop {
                while *pos < bytes.len() && bytes[*pos].is_ascii_whitespace() {
                    *pos += 1;
                }
                if *pos < bytes.len() && bytes[*pos] == b'#' {
                    while *pos < bytes.len() && bytes[*pos] != b'\n' {
                        *pos += 1;
                    }
                    continue;
                }
                break;
            }
            let start = *pos;
            while *pos < bytes.len() && !bytes[*pos].is_ascii_whitespace() {
                *pos += 1;
            }
            if start == *pos {
                return Err(FormatError::PgmEnds);
            }
            Ok(String::from_utf8_lossy(&bytes[start..*pos]).into_owned())
        };
        let magic = token(&mut pos)?;
        if magic != "P2" && magic != "P5" {
            return Err(FormatError::NotAnImage { magic });
        }
        let num = |token: String, what: &'static str| -> Result<usize, FormatError> {
            token
                .parse::<usize>()
                .map_err(|_| FormatError::PgmNumber { what, token })
        };
        let width = num(token(&mut pos)?, "width")?;
        let height = num(token(&mut pos)?, "height")?;
        let maxval = num(token(&mut pos)?, "maxval")?;
        check_size(width, height)?;
        if !(1..=65535).contains(&maxval) {
            return Err(FormatError::PgmMaxval(maxval));
        }
        let n = width * height;
        let mut values = Vec::with_capacity(n);
        if magic == "P5" {
            pos += 1; // the single whitespace after maxval
            let bpp = if maxval < 256 { 1 } else { 2 };
            let data = bytes
                .get(pos..pos + n * bpp)
                .ok_or_else(|| FormatError::P5Short {
                    held: bytes.len().saturating_sub(pos),
                    needed: n * bpp,
                })?;
            for px in data.chunks(bpp) {
                values.push(if bpp == 1 {
                    usize::from(px[0])
                } else {
                    usize::from(px[0]) << 8 | usize::from(px[1])
                });
            }
        } else {
            for _ in 0..n {
                let v = num(token(&mut pos)?, "pixel")?;
                values.push(v);
            }
        }
        Ok(Self {
            width,
            height,
            black: values.iter().map(|&v| 2 * v < maxval).collect(),
        })
    }

    /// Decodes a PNG.
    ///
    /// # Errors
    /// What the decoder said, or an unsupported colour type.
    pub fn from_png(bytes: &[u8]) -> Result<Self, FormatError> {
        let mut dec = png::Decoder::new(std::io::Cursor::new(bytes));
        dec.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
        let mut reader = dec.read_info().map_err(png_error)?;
        let (w, h) = {
            let info = reader.info();
            (info.width as usize, info.height as usize)
        };
        check_size(w, h)?;
        let size = reader
            .output_buffer_size()
            .ok_or(FormatError::PngTooLarge)?;
        let mut buf = vec![0u8; size];
        let info = reader.next_frame(&mut buf).map_err(png_error)?;
        let channels = match info.color_type {
            png::ColorType::Grayscale => 1,
            png::ColorType::GrayscaleAlpha => 2,
            png::ColorType::Rgb => 3,
            png::ColorType::Rgba => 4,
            png::ColorType::Indexed => return Err(FormatError::PngIndexed),
        };
        let mut black = Vec::with_capacity(w * h);
        for row in 0..h {
            let line = &buf[row * info.line_size..];
            for col in 0..w {
                let px = &line[col * channels..col * channels + channels];
                let grey = if channels >= 3 {
                    (u32::from(px[0]) + u32::from(px[1]) + u32::from(px[2])) / 3
                } else {
                    u32::from(px[0])
                };
                black.push(grey < 128);
            }
        }
        Ok(Self {
            width: w,
            height: h,
            black,
        })
    }

    /// Is pixel `(col, row)` black?
    pub fn is_black(&self, col: usize, row: usize) -> bool {
        self.black[row * self.width + col]
    }
}

/// A regular file no larger than [`MAX_IMAGE_FILE_BYTES`], or the error naming it.
fn check_regular(path: &Path, meta: &std::fs::Metadata) -> Result<(), ImageError> {
    let ft = meta.file_type();
    if !ft.is_file() {
        let kind = if ft.is_dir() {
            "a directory"
        } else {
            special_kind(&ft)
        };
        return Err(ImageError::NotAFile {
            path: path.to_owned(),
            kind,
        });
    }
    if meta.len() > MAX_IMAGE_FILE_BYTES {
        return Err(ImageError::TooLarge {
            path: path.to_owned(),
            bytes: meta.len(),
            max: MAX_IMAGE_FILE_BYTES,
        });
    }
    Ok(())
}

#[cfg(unix)]
fn special_kind(ft: &std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if ft.is_fifo() {
        "a FIFO"
    } else if ft.is_socket() {
        "a socket"
    } else if ft.is_char_device() {
        "a character device"
    } else if ft.is_block_device() {
        "a block device"
    } else {
        "not a regular file"
    }
}

#[cfg(not(unix))]
fn special_kind(_: &std::fs::FileType) -> &'static str {
    "not a regular file"
}

fn check_size(w: usize, h: usize) -> Result<(), FormatError> {
    if w == 0 || h == 0 || w > MAX_IMAGE_SIDE || h > MAX_IMAGE_SIDE {
        return Err(FormatError::Size {
            width: w,
            height: h,
        });
    }
    Ok(())
}

/// The axis an image is held along.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Axis {
    /// Along x: image columns along y, rows along z (top = +z).
    X,
    /// Along y: columns along x, rows along z (top = +z).
    Y,
    /// Along z: columns along x, rows along y (top = +y).
    Z,
}

impl std::str::FromStr for Axis {
    type Err = CarveError;
    fn from_str(s: &str) -> Result<Self, CarveError> {
        match s {
            "x" => Ok(Self::X),
            "y" => Ok(Self::Y),
            "z" => Ok(Self::Z),
            o => Err(CarveError::UnknownAxis(o.to_owned())),
        }
    }
}

impl Axis {
    /// (column axis, row axis) indices.
    fn plane(self) -> (usize, usize) {
        match self {
            Self::X => (1, 2),
            Self::Y => (0, 2),
            Self::Z => (0, 1),
        }
    }
}

impl Workpiece {
    /// Cuts the workpiece out along `axis` with `image` (seed §4.1): the image is stretched
    /// over the extent of the workpiece's surfels (eq. 1), material over white pixels is
    /// removed, and material along the contour gets side surfels, half a spacing towards the
    /// removed side (the seed's midpoints between contour pixels), facing it.
    pub fn cut_out(&mut self, image: &BinaryImage, axis: Axis) -> CutStats {
        let mut stats = CutStats::default();
        if self.surfels.is_empty() {
            return stats;
        }
        let (cu, cv) = axis.plane();
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for s in &self.surfels {
            for a in 0..3 {
                lo[a] = lo[a].min(f64::from(s.position[a]));
                hi[a] = hi[a].max(f64::from(s.position[a]));
            }
        }
        let pixel = |x: f64, a: usize, n: usize| -> usize {
            let span = (hi[a] - lo[a]).max(1e-12);
            (((x - lo[a]) * n as f64 / span).floor().max(0.0) as usize).min(n - 1)
        };
        self.removed.clear();
        for idx in 0..self.flags.len() {
            if self.flags[idx] == OUTSIDE {
                continue;
            }
            let c = self.coords(idx);
            let p = self.point(c[0], c[1], c[2]);
            let col = pixel(p[cu], cu, image.width);
            let row = image.height - 1 - pixel(p[cv], cv, image.height);
            if !image.is_black(col, row) {
                self.cut_point(idx, &mut stats);
            }
        }
        let removed = std::mem::take(&mut self.removed);
        for &r in &removed {
            let (nbs, n) = self.neighbours6(r as usize);
            for &nb in &nbs[..n] {
                if self.flags[nb] != OUTSIDE {
                    self.side_surfel(nb);
                    stats.exposed += 1;
                }
            }
        }
        self.removed = removed;
        stats
    }

    /// A surface point's surfel from its air neighbours: facing them, half a spacing out.
    fn side_surfel(&mut self, idx: usize) {
        let c = self.coords(idx);
        let stride = [1usize, self.dims[0], self.dims[0] * self.dims[1]];
        let mut dir: Vec3 = [0.0; 3];
        let mut first = None;
        for a in 0..3 {
            if c[a] == 0 || self.flags[idx - stride[a]] == OUTSIDE {
                dir[a] -= 1.0;
                first.get_or_insert((a, -1.0));
            }
            if c[a] + 1 == self.dims[a] || self.flags[idx + stride[a]] == OUTSIDE {
                dir[a] += 1.0;
                first.get_or_insert((a, 1.0));
            }
        }
        if norm(dir) == 0.0 {
            // Air on opposite sides (a one-point sliver): face the first of them.
            let Some((a, s)) = first else { return };
            dir[a] = s;
        }
        let len = norm(dir);
        let p = self.point(c[0], c[1], c[2]);
        self.flags[idx] = BOUND;
        let pos = add(p, scale(dir, self.h / 2.0 / len.max(1.0)));
        self.set_surfel(idx, pos, scale(dir, 1.0 / len), COLOUR_CUTOUT);
    }
}

/// A PNG decoding error as a [`FormatError`] in words (the png crate's own text can embed
/// a debug dump of the chunk type).
fn png_error(e: png::DecodingError) -> FormatError {
    match e {
        png::DecodingError::IoError(e) => FormatError::PngUnreadable(e),
        png::DecodingError::Format(_) => FormatError::PngDamaged,
        png::DecodingError::Parameter(_) => FormatError::PngMisused,
        png::DecodingError::LimitsExceeded => FormatError::PngLimits,
    }
}
