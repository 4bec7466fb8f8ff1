//! CDR (OMG Common Data Representation) with the 4-byte encapsulation header, as ROS 2 sends
//! messages on the wire and stores them in rosbag2 files.
//!
//! A serialised message is `[0x00, kind, options_hi, options_lo]` followed by the body, where
//! `kind` is `0x01` for little endian (`CDR_LE`) and `0x00` for big endian (`CDR_BE`). The body
//! is plain (XCDR1, "final") CDR, the encoding every ROS 2 middleware uses for messages:
//!
//! - primitives are aligned to their own size (1, 2, 4 or 8 bytes) relative to the start of the
//!   body; padding bytes are zero;
//! - `string` is a `u32` length that counts a terminating NUL, the bytes, and the NUL;
//! - `T[]` (unbounded or bounded sequence) is a `u32` element count followed by the elements;
//!   `T[N]` (fixed array, a Rust tuple or array) is the N elements alone;
//! - a struct is its fields in order, with no alignment of its own;
//! - enums (not used by ROS messages) are a `u32` variant index, options a `u32` 0/1 tag.
//!
//! The serde data model is mapped accordingly; `#[serde(with = "serde_bytes")]` on a `uint8[]`
//! field gives a single bulk copy each way.
//!
//! The codec is written here rather than taken from `cdr-encoding` 0.10: that version writes
//! `serialize_bytes` without the `u32` length prefix (so a `serde_bytes` `uint8[]` field comes
//! out unreadable for every other ROS 2 implementation) and can only be called with a
//! `byteorder` type parameter. The byte layout is the same as `cdr-encoding`'s for everything
//! else, which the tests check byte by byte.
//!
//! Decoding never panics and never allocates more than the input can fill: every length read
//! from the data is checked against the bytes that remain before anything is read, and a
//! sequence may not declare more elements than there are bytes left, so a bogus `u32` length
//! prefix ends in [`CdrError::Truncated`] rather than in a giant allocation or a long loop.

use serde::de::{self, DeserializeOwned, DeserializeSeed, IntoDeserializer, Visitor};
use serde::ser::{self, Serialize};

/// Encapsulation identifier of plain CDR, big endian.
const CDR_BE: [u8; 2] = [0x00, 0x00];
/// Encapsulation identifier of plain CDR, little endian.
const CDR_LE: [u8; 2] = [0x00, 0x01];
/// The magic number that opens a zstd frame (a compressed message is told by it).
const ZSTD_MAGIC: [u8; 4] = [0x28, 0xB5, 0x2F, 0xFD];

/// Length of the encapsulation header (identifier and options).
const HEADER_LEN: usize = 4;
/// Writers may pad the body to a multiple of 4 bytes (rmw_fastrtps does, and records the count
/// in the options field); up to this many bytes after the last field are accepted.
const MAX_PADDING: usize = 3;

/// Byte order of a CDR body, from its encapsulation header.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CdrEndianness {
    /// `00 01`, `CDR_LE`: what ROS 2 writes on every common platform.
    Little,
    /// `00 00`, `CDR_BE`.
    Big,
}

/// What was wrong with a CDR message, or why a value could not be serialised.
///
/// Offsets are byte positions in the body, i.e. after the 4-byte encapsulation header.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CdrError {
    /// Fewer bytes than the encapsulation header.
    #[error(
        "CDR data is {len} bytes long, shorter than the 4-byte encapsulation header \
         (00 01 00 00 for little endian)"
    )]
    TooShort {
        /// Length of the data.
        len: usize,
    },
    /// The data is a zstd frame, not CDR: a message stored compressed (rosbag2's
    /// per-message compression) read without decompressing it.
    #[error(
        "the data starts with the zstd magic 28 b5 2f fd, not a CDR encapsulation header: the \
         message is stored compressed (rosbag2 per-message compression); read the bag through \
         its rosbag2 directory, whose metadata.yaml says how it is compressed"
    )]
    Compressed,
    /// The encapsulation identifier names something other than plain CDR.
    #[error(
        "unsupported CDR encapsulation {:02x} {:02x}: only plain CDR is read, 00 01 (little \
         endian) or 00 00 (big endian); parameter lists and XCDR2 are not",
        found[0],
        found[1]
    )]
    UnsupportedEncapsulation {
        /// The first two bytes of the data.
        found: [u8; 2],
    },
    /// The body ended before the value was complete: the data is truncated, a length prefix
    /// claims more than there is, or the data is of another message type.
    #[error(
        "CDR body ends early: {needed} more bytes needed at body offset {offset}, but the body \
         is {body_len} bytes (truncated data, a bogus length prefix, or another message type)"
    )]
    Truncated {
        /// Bytes the decoder needed to read.
        needed: u64,
        /// Where it needed them.
        offset: usize,
        /// Length of the body.
        body_len: usize,
    },
    /// A `bool` byte other than 0 or 1.
    #[error("invalid bool {value:#04x} at body offset {offset} (only 0 and 1 are allowed)")]
    InvalidBool {
        /// The byte found.
        value: u8,
        /// Where.
        offset: usize,
    },
    /// A string that is not UTF-8.
    #[error("string at body offset {offset} is not valid UTF-8")]
    InvalidUtf8 {
        /// Where the string's bytes start.
        offset: usize,
    },
    /// A `char` code that is not a Unicode scalar value.
    #[error("invalid char code {value:#x} at body offset {offset}")]
    InvalidChar {
        /// The code found.
        value: u32,
        /// Where.
        offset: usize,
    },
    /// An option tag other than 0 or 1.
    #[error("invalid option tag {value} at body offset {offset} (only 0 and 1 are allowed)")]
    InvalidOptionTag {
        /// The tag found.
        value: u32,
        /// Where.
        offset: usize,
    },
    /// The decoded data does not fit the Rust type (for example an unknown enum variant).
    #[error("invalid value near body offset {offset}: {message}")]
    Invalid {
        /// What serde reported.
        message: String,
        /// Where the decoder was.
        offset: usize,
    },
    /// More bytes followed the value than alignment padding explains.
    #[error(
        "{trailing} bytes are left after the message ({body_len} body bytes); at most 3 bytes \
         of padding are expected, so the data is probably of another message type"
    )]
    TrailingBytes {
        /// Bytes left after the last field.
        trailing: usize,
        /// Length of the body.
        body_len: usize,
    },
    /// The type uses something CDR cannot express (self-describing input, 128-bit integers,
    /// a sequence whose length is not known up front, ...).
    #[error("CDR cannot express {what}")]
    Unsupported {
        /// What was asked for.
        what: &'static str,
    },
    /// A sequence, string or map too long for CDR's `u32` length.
    #[error("a sequence, string or map of {len} elements does not fit CDR's u32 length")]
    LengthOverflow {
        /// The length.
        len: usize,
    },
    /// A serialisation failure reported by the value's `Serialize` impl.
    #[error("cannot serialise the value: {message}")]
    Serialize {
        /// What the impl reported.
        message: String,
    },
}

impl ser::Error for CdrError {
    fn custom<T: std::fmt::Display>(msg: T) -> Self {
        CdrError::Serialize {
            message: msg.to_string(),
        }
    }
}

impl de::Error for CdrError {
    fn custom<T: std::fmt::Display>(msg: T) -> Self {
        // The offset is filled in by `decode_cdr`, which knows where the decoder stopped.
        CdrError::Invalid {
            message: msg.to_string(),
            offset: 0,
        }
    }
}

/// Serialises `msg` as CDR little endian behind the encapsulation header `00 01 00 00`.
///
/// ```
/// use chronotope_msg::{decode_cdr, encode_cdr, Time};
/// let stamp = Time { sec: 1, nanosec: 2 };
/// let bytes = encode_cdr(&stamp).unwrap();
/// assert_eq!(bytes, [0, 1, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0]);
/// assert_eq!(decode_cdr::<Time>(&bytes).unwrap(), stamp);
/// ```
///
/// # Errors
///
/// [`CdrError::Unsupported`] or [`CdrError::LengthOverflow`] if the value uses something CDR
/// cannot express (a sequence of unknown length, a 128-bit integer, more than `u32::MAX`
/// elements), [`CdrError::Serialize`] if its `Serialize` impl fails. Message structs never do.
pub fn encode_cdr<T: Serialize>(msg: &T) -> Result<Vec<u8>, CdrError> {
    let mut out = Vec::with_capacity(64);
    encode_cdr_into(msg, &mut out)?;
    Ok(out)
}

/// [`encode_cdr`] into `out` (cleared first): a writer of many messages keeps one buffer,
/// grown to the largest, rather than growing a new one by doubling for each.
///
/// # Errors
///
/// As [`encode_cdr`]; `out` then holds a part of the message.
pub fn encode_cdr_into<T: Serialize>(msg: &T, out: &mut Vec<u8>) -> Result<(), CdrError> {
    out.clear();
    let mut writer = CdrWriter {
        out: std::mem::take(out),
    };
    writer.out.extend_from_slice(&CDR_LE);
    writer.out.extend_from_slice(&[0x00, 0x00]);
    let done = msg.serialize(&mut writer);
    *out = writer.out;
    done
}

/// Decodes a message serialised with its encapsulation header (either byte order).
///
/// # Errors
///
/// A [`CdrError`] saying what is wrong: too short for the header, an encapsulation other than
/// plain CDR, a body that ends early, an invalid value, or more than 3 bytes left over after
/// the value. Any input gives a value or an error; none panics.
pub fn decode_cdr<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, CdrError> {
    let endianness = encapsulation(bytes)?;
    let body = bytes.get(HEADER_LEN..).unwrap_or_default();
    let mut reader = CdrReader {
        body,
        pos: 0,
        big_endian: endianness == CdrEndianness::Big,
    };
    let value = T::deserialize(&mut reader).map_err(|err| match err {
        CdrError::Invalid { message, .. } => CdrError::Invalid {
            message,
            offset: reader.pos,
        },
        other => other,
    })?;
    let trailing = body.len() - reader.pos;
    if trailing > MAX_PADDING {
        return Err(CdrError::TrailingBytes {
            trailing,
            body_len: body.len(),
        });
    }
    Ok(value)
}

/// Checks the encapsulation header of a serialised message and returns its byte order.
///
/// # Errors
///
/// [`CdrError::TooShort`] below 4 bytes, [`CdrError::UnsupportedEncapsulation`] for anything
/// but `00 01` and `00 00`. The options bytes (2 and 3) are not checked: writers use them for
/// the padding count.
pub fn encapsulation(bytes: &[u8]) -> Result<CdrEndianness, CdrError> {
    let Some(header) = bytes.first_chunk::<HEADER_LEN>() else {
        return Err(CdrError::TooShort { len: bytes.len() });
    };
    match [header[0], header[1]] {
        CDR_LE => Ok(CdrEndianness::Little),
        CDR_BE => Ok(CdrEndianness::Big),
        _ if header == &ZSTD_MAGIC => Err(CdrError::Compressed),
        found => Err(CdrError::UnsupportedEncapsulation { found }),
    }
}

// ---------------------------------------------------------------------------------------------
// Serialisation (always little endian)

/// Appends CDR little endian to a buffer whose first 4 bytes are the encapsulation header.
struct CdrWriter {
    out: Vec<u8>,
}

impl CdrWriter {
    /// Zero-pads so that the body length is a multiple of `n`.
    fn align(&mut self, n: usize) {
        let pos = self.out.len() - HEADER_LEN;
        let pad = (n - pos % n) % n;
        self.out.resize(self.out.len() + pad, 0);
    }

    /// Writes a primitive's bytes, aligned to its size.
    fn put<const N: usize>(&mut self, bytes: [u8; N]) {
        self.align(N);
        self.out.extend_from_slice(&bytes);
    }

    /// Writes a `u32` length, refusing lengths CDR cannot carry.
    fn put_len(&mut self, len: usize) -> Result<(), CdrError> {
        let len32 = u32::try_from(len).map_err(|_| CdrError::LengthOverflow { len })?;
        self.put(len32.to_le_bytes());
        Ok(())
    }
}

impl ser::Serializer for &mut CdrWriter {
    type Ok = ();
    type Error = CdrError;
    type SerializeSeq = Self;
    type SerializeTuple = Self;
    type SerializeTupleStruct = Self;
    type SerializeTupleVariant = Self;
    type SerializeMap = Self;
    type SerializeStruct = Self;
    type SerializeStructVariant = Self;

    fn is_human_readable(&self) -> bool {
        false
    }

    fn serialize_bool(self, v: bool) -> Result<(), CdrError> {
        self.put([u8::from(v)]);
        Ok(())
    }
    fn serialize_i8(self, v: i8) -> Result<(), CdrError> {
        self.put(v.to_le_bytes());
        Ok(())
    }
    fn serialize_i16(self, v: i16) -> Result<(), CdrError> {
        self.put(v.to_le_bytes());
        Ok(())
    }
    fn serialize_i32(self, v: i32) -> Result<(), CdrError> {
        self.put(v.to_le_bytes());
        Ok(())
    }
    fn serialize_i64(self, v: i64) -> Result<(), CdrError> {
        self.put(v.to_le_bytes());
        Ok(())
    }
    fn serialize_u8(self, v: u8) -> Result<(), CdrError> {
        self.put([v]);
        Ok(())
    }
    fn serialize_u16(self, v: u16) -> Result<(), CdrError> {
        self.put(v.to_le_bytes());
        Ok(())
    }
    fn serialize_u32(self, v: u32) -> Result<(), CdrError> {
        self.put(v.to_le_bytes());
        Ok(())
    }
    fn serialize_u64(self, v: u64) -> Result<(), CdrError> {
        self.put(v.to_le_bytes());
        Ok(())
    }
    fn serialize_f32(self, v: f32) -> Result<(), CdrError> {
        self.put(v.to_le_bytes());
        Ok(())
    }
    fn serialize_f64(self, v: f64) -> Result<(), CdrError> {
        self.put(v.to_le_bytes());
        Ok(())
    }
    fn serialize_char(self, v: char) -> Result<(), CdrError> {
        // As cdr-encoding does: the Unicode scalar value as a u32.
        self.put(u32::from(v).to_le_bytes());
        Ok(())
    }
    fn serialize_str(self, v: &str) -> Result<(), CdrError> {
        self.put_len(v.len() + 1)?;
        self.out.extend_from_slice(v.as_bytes());
        self.out.push(0);
        Ok(())
    }
    fn serialize_bytes(self, v: &[u8]) -> Result<(), CdrError> {
        self.put_len(v.len())?;
        self.out.extend_from_slice(v);
        Ok(())
    }
    fn serialize_none(self) -> Result<(), CdrError> {
        self.put(0u32.to_le_bytes());
        Ok(())
    }
    fn serialize_some<T: ?Sized + Serialize>(self, value: &T) -> Result<(), CdrError> {
        self.put(1u32.to_le_bytes());
        value.serialize(self)
    }
    fn serialize_unit(self) -> Result<(), CdrError> {
        Ok(())
    }
    fn serialize_unit_struct(self, _name: &'static str) -> Result<(), CdrError> {
        Ok(())
    }
    fn serialize_unit_variant(
        self,
        _name: &'static str,
        variant_index: u32,
        _variant: &'static str,
    ) -> Result<(), CdrError> {
        self.serialize_u32(variant_index)
    }
    fn serialize_newtype_struct<T: ?Sized + Serialize>(
        self,
        _name: &'static str,
        value: &T,
    ) -> Result<(), CdrError> {
        value.serialize(self)
    }
    fn serialize_newtype_variant<T: ?Sized + Serialize>(
        self,
        _name: &'static str,
        variant_index: u32,
        _variant: &'static str,
        value: &T,
    ) -> Result<(), CdrError> {
        self.put(variant_index.to_le_bytes());
        value.serialize(self)
    }
    fn serialize_seq(self, len: Option<usize>) -> Result<Self, CdrError> {
        let len = len.ok_or(CdrError::Unsupported {
            what: "a sequence whose length is not known before its elements",
        })?;
        self.put_len(len)?;
        Ok(self)
    }
    fn serialize_tuple(self, _len: usize) -> Result<Self, CdrError> {
        Ok(self)
    }
    fn serialize_tuple_struct(self, _name: &'static str, _len: usize) -> Result<Self, CdrError> {
        Ok(self)
    }
    fn serialize_tuple_variant(
        self,
        _name: &'static str,
        variant_index: u32,
        _variant: &'static str,
        _len: usize,
    ) -> Result<Self, CdrError> {
        self.put(variant_index.to_le_bytes());
        Ok(self)
    }
    fn serialize_map(self, len: Option<usize>) -> Result<Self, CdrError> {
        let len = len.ok_or(CdrError::Unsupported {
            what: "a map whose length is not known before its entries",
        })?;
        self.put_len(len)?;
        Ok(self)
    }
    fn serialize_struct(self, _name: &'static str, _len: usize) -> Result<Self, CdrError> {
        Ok(self)
    }
    fn serialize_struct_variant(
        self,
        _name: &'static str,
        variant_index: u32,
        _variant: &'static str,
        _len: usize,
    ) -> Result<Self, CdrError> {
        self.put(variant_index.to_le_bytes());
        Ok(self)
    }
}

/// Implements the compound-serialisation traits: elements follow one another, nothing else.
macro_rules! sequential_compound {
    ($($tr:ident :: $method:ident),*) => {$(
        impl ser::$tr for &mut CdrWriter {
            type Ok = ();
            type Error = CdrError;
            fn $method<T: ?Sized + Serialize>(&mut self, value: &T) -> Result<(), CdrError> {
                value.serialize(&mut **self)
            }
            fn end(self) -> Result<(), CdrError> {
                Ok(())
            }
        }
    )*};
}
sequential_compound!(
    SerializeSeq::serialize_element,
    SerializeTuple::serialize_element,
    SerializeTupleStruct::serialize_field,
    SerializeTupleVariant::serialize_field
);

impl ser::SerializeMap for &mut CdrWriter {
    type Ok = ();
    type Error = CdrError;
    fn serialize_key<T: ?Sized + Serialize>(&mut self, key: &T) -> Result<(), CdrError> {
        key.serialize(&mut **self)
    }
    fn serialize_value<T: ?Sized + Serialize>(&mut self, value: &T) -> Result<(), CdrError> {
        value.serialize(&mut **self)
    }
    fn end(self) -> Result<(), CdrError> {
        Ok(())
    }
}

impl ser::SerializeStruct for &mut CdrWriter {
    type Ok = ();
    type Error = CdrError;
    fn serialize_field<T: ?Sized + Serialize>(
        &mut self,
        _key: &'static str,
        value: &T,
    ) -> Result<(), CdrError> {
        value.serialize(&mut **self)
    }
    fn end(self) -> Result<(), CdrError> {
        Ok(())
    }
}

impl ser::SerializeStructVariant for &mut CdrWriter {
    type Ok = ();
    type Error = CdrError;
    fn serialize_field<T: ?Sized + Serialize>(
        &mut self,
        _key: &'static str,
        value: &T,
    ) -> Result<(), CdrError> {
        value.serialize(&mut **self)
    }
    fn end(self) -> Result<(), CdrError> {
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// Deserialisation (either byte order)

/// Reads CDR from a body slice; `pos` is the next byte to read.
struct CdrReader<'de> {
    body: &'de [u8],
    pos: usize,
    big_endian: bool,
}

impl<'de> CdrReader<'de> {
    /// Takes the next `n` bytes, or fails without moving if there are fewer.
    fn take(&mut self, n: usize) -> Result<&'de [u8], CdrError> {
        let body = self.body;
        match self
            .pos
            .checked_add(n)
            .and_then(|end| body.get(self.pos..end))
        {
            Some(bytes) => {
                self.pos += n;
                Ok(bytes)
            }
            None => Err(self.truncated(n as u64)),
        }
    }

    fn truncated(&self, needed: u64) -> CdrError {
        CdrError::Truncated {
            needed,
            offset: self.pos,
            body_len: self.body.len(),
        }
    }

    fn remaining(&self) -> usize {
        self.body.len() - self.pos
    }

    /// Reads an `N`-byte primitive, skipping the padding before it.
    fn get<const N: usize>(&mut self) -> Result<[u8; N], CdrError> {
        let pad = (N - self.pos % N) % N;
        self.take(pad)?;
        let bytes = self.take(N)?;
        let mut out = [0u8; N];
        out.copy_from_slice(bytes);
        if self.big_endian {
            out.reverse();
        }
        // `out` is now little endian whatever the input was.
        Ok(out)
    }

    fn get_u32(&mut self) -> Result<u32, CdrError> {
        Ok(u32::from_le_bytes(self.get()?))
    }

    /// Reads a sequence or map length and checks that the elements can be there at all: each
    /// element of a ROS message takes at least one byte, so more elements than bytes left means
    /// a bogus length, and refusing it bounds both allocation and work by the input size.
    fn get_count(&mut self) -> Result<usize, CdrError> {
        let count = self.get_u32()?;
        let count_usize = usize::try_from(count).unwrap_or(usize::MAX);
        if count_usize > self.remaining() {
            return Err(self.truncated(u64::from(count)));
        }
        Ok(count_usize)
    }

    /// Reads a `u32` length and that many bytes.
    fn get_bytes(&mut self) -> Result<&'de [u8], CdrError> {
        let len = self.get_u32()?;
        let len = usize::try_from(len).map_err(|_| self.truncated(u64::from(len)))?;
        self.take(len)
    }

    /// Reads a string (length with NUL, bytes, NUL) and returns it without the NUL.
    fn get_str(&mut self) -> Result<&'de str, CdrError> {
        let bytes = self.get_bytes()?;
        let offset = self.pos - bytes.len();
        // The length counts the terminating NUL; be lenient with writers that leave it out.
        let text = bytes.strip_suffix(&[0]).unwrap_or(bytes);
        std::str::from_utf8(text).map_err(|_| CdrError::InvalidUtf8 { offset })
    }
}

macro_rules! deserialize_number {
    ($($method:ident => $visit:ident : $ty:ty),* $(,)?) => {$(
        fn $method<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, CdrError> {
            visitor.$visit(<$ty>::from_le_bytes(self.get()?))
        }
    )*};
}

impl<'de> de::Deserializer<'de> for &mut CdrReader<'de> {
    type Error = CdrError;

    fn is_human_readable(&self) -> bool {
        false
    }

    fn deserialize_any<V: Visitor<'de>>(self, _visitor: V) -> Result<V::Value, CdrError> {
        Err(CdrError::Unsupported {
            what: "self-described data: CDR carries no type information, so the Rust type must \
                   say what to read",
        })
    }

    fn deserialize_bool<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, CdrError> {
        let offset = self.pos;
        match self.get::<1>()?[0] {
            0 => visitor.visit_bool(false),
            1 => visitor.visit_bool(true),
            value => Err(CdrError::InvalidBool { value, offset }),
        }
    }

    deserialize_number!(
        deserialize_i8 => visit_i8: i8,
        deserialize_i16 => visit_i16: i16,
        deserialize_i32 => visit_i32: i32,
        deserialize_i64 => visit_i64: i64,
        deserialize_u8 => visit_u8: u8,
        deserialize_u16 => visit_u16: u16,
        deserialize_u32 => visit_u32: u32,
        deserialize_u64 => visit_u64: u64,
        deserialize_f32 => visit_f32: f32,
        deserialize_f64 => visit_f64: f64,
    );

    fn deserialize_char<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, CdrError> {
        let offset = self.pos;
        let value = self.get_u32()?;
        match char::from_u32(value) {
            Some(c) => visitor.visit_char(c),
            None => Err(CdrError::InvalidChar { value, offset }),
        }
    }

    fn deserialize_str<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, CdrError> {
        visitor.visit_borrowed_str(self.get_str()?)
    }

    fn deserialize_string<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, CdrError> {
        visitor.visit_borrowed_str(self.get_str()?)
    }

    fn deserialize_bytes<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, CdrError> {
        visitor.visit_borrowed_bytes(self.get_bytes()?)
    }

    fn deserialize_byte_buf<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, CdrError> {
        visitor.visit_borrowed_bytes(self.get_bytes()?)
    }

    fn deserialize_option<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, CdrError> {
        let offset = self.pos;
        match self.get_u32()? {
            0 => visitor.visit_none(),
            1 => visitor.visit_some(self),
            value => Err(CdrError::InvalidOptionTag { value, offset }),
        }
    }

    fn deserialize_unit<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, CdrError> {
        visitor.visit_unit()
    }

    fn deserialize_unit_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        visitor: V,
    ) -> Result<V::Value, CdrError> {
        visitor.visit_unit()
    }

    fn deserialize_newtype_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        visitor: V,
    ) -> Result<V::Value, CdrError> {
        visitor.visit_newtype_struct(self)
    }

    fn deserialize_seq<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, CdrError> {
        let count = self.get_count()?;
        visitor.visit_seq(Elements {
            reader: self,
            left: count,
        })
    }

    fn deserialize_tuple<V: Visitor<'de>>(
        self,
        len: usize,
        visitor: V,
    ) -> Result<V::Value, CdrError> {
        visitor.visit_seq(Elements {
            reader: self,
            left: len,
        })
    }

    fn deserialize_tuple_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        len: usize,
        visitor: V,
    ) -> Result<V::Value, CdrError> {
        self.deserialize_tuple(len, visitor)
    }

    fn deserialize_map<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, CdrError> {
        let count = self.get_count()?;
        visitor.visit_map(Elements {
            reader: self,
            left: count,
        })
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        fields: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, CdrError> {
        self.deserialize_tuple(fields.len(), visitor)
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _name: &'static str,
        _variants: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, CdrError> {
        visitor.visit_enum(self)
    }

    fn deserialize_identifier<V: Visitor<'de>>(self, _visitor: V) -> Result<V::Value, CdrError> {
        Err(CdrError::Unsupported {
            what: "field or variant names: CDR identifies them by position",
        })
    }

    fn deserialize_ignored_any<V: Visitor<'de>>(self, _visitor: V) -> Result<V::Value, CdrError> {
        Err(CdrError::Unsupported {
            what: "skipping a value of unknown type",
        })
    }
}

/// Gives a visitor a known number of elements (or map entries) read one after the other.
struct Elements<'r, 'de> {
    reader: &'r mut CdrReader<'de>,
    left: usize,
}

impl<'de> de::SeqAccess<'de> for Elements<'_, 'de> {
    type Error = CdrError;

    fn next_element_seed<T: DeserializeSeed<'de>>(
        &mut self,
        seed: T,
    ) -> Result<Option<T::Value>, CdrError> {
        if self.left == 0 {
            return Ok(None);
        }
        self.left -= 1;
        seed.deserialize(&mut *self.reader).map(Some)
    }

    fn size_hint(&self) -> Option<usize> {
        // Never more than the bytes left (see `get_count`); serde caps it further.
        Some(self.left.min(self.reader.remaining()))
    }
}

impl<'de> de::MapAccess<'de> for Elements<'_, 'de> {
    type Error = CdrError;

    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, CdrError> {
        if self.left == 0 {
            return Ok(None);
        }
        self.left -= 1;
        seed.deserialize(&mut *self.reader).map(Some)
    }

    fn next_value_seed<V: DeserializeSeed<'de>>(&mut self, seed: V) -> Result<V::Value, CdrError> {
        seed.deserialize(&mut *self.reader)
    }

    fn size_hint(&self) -> Option<usize> {
        Some(self.left.min(self.reader.remaining()))
    }
}

impl<'de> de::EnumAccess<'de> for &mut CdrReader<'de> {
    type Error = CdrError;
    type Variant = Self;

    fn variant_seed<V: DeserializeSeed<'de>>(self, seed: V) -> Result<(V::Value, Self), CdrError> {
        let index = self.get_u32()?;
        let value = seed.deserialize(IntoDeserializer::<CdrError>::into_deserializer(index))?;
        Ok((value, self))
    }
}

impl<'de> de::VariantAccess<'de> for &mut CdrReader<'de> {
    type Error = CdrError;

    fn unit_variant(self) -> Result<(), CdrError> {
        Ok(())
    }

    fn newtype_variant_seed<T: DeserializeSeed<'de>>(self, seed: T) -> Result<T::Value, CdrError> {
        seed.deserialize(self)
    }

    fn tuple_variant<V: Visitor<'de>>(self, len: usize, visitor: V) -> Result<V::Value, CdrError> {
        de::Deserializer::deserialize_tuple(self, len, visitor)
    }

    fn struct_variant<V: Visitor<'de>>(
        self,
        fields: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, CdrError> {
        de::Deserializer::deserialize_tuple(self, fields.len(), visitor)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::{Deserialize, Serialize};

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    struct Mixed {
        a: u8,
        b: u64,
        s: String,
        c: u16,
        v: Vec<i32>,
        #[serde(with = "serde_bytes")]
        bytes: Vec<u8>,
        fixed: [f32; 3],
        flag: bool,
        e: Kind,
        o: Option<u8>,
    }

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    enum Kind {
        A,
        B(u16),
    }

    fn mixed() -> Mixed {
        Mixed {
            a: 7,
            b: 0x0102_0304_0506_0708,
            s: "hi".into(),
            c: 9,
            v: vec![-1, 2],
            bytes: vec![1, 2, 3],
            fixed: [1.0, 2.0, 3.0],
            flag: true,
            e: Kind::B(5),
            o: Some(4),
        }
    }

    #[test]
    fn layout_matches_plain_cdr() {
        let bytes = encode_cdr(&mixed()).unwrap();
        #[rustfmt::skip]
        let expected: Vec<u8> = vec![
            0, 1, 0, 0,                     // CDR_LE
            7, 0, 0, 0, 0, 0, 0, 0,         // a, pad to 8
            8, 7, 6, 5, 4, 3, 2, 1,         // b
            3, 0, 0, 0, b'h', b'i', 0,      // s: len 3 incl NUL
            0,                              // pad to 2
            9, 0,                           // c
            0, 0,                           // pad to 4
            2, 0, 0, 0, 255, 255, 255, 255, 2, 0, 0, 0, // v
            3, 0, 0, 0, 1, 2, 3,            // bytes with u32 length
            0,                              // pad to 4
            0, 0, 0x80, 0x3f, 0, 0, 0, 0x40, 0, 0, 0x40, 0x40, // fixed: no length
            1,                              // flag
            0, 0, 0,                        // pad to 4
            1, 0, 0, 0, 5, 0,               // e: variant 1, u16
            0, 0,                           // pad to 4
            1, 0, 0, 0, 4,                  // o: Some(4)
        ];
        assert_eq!(bytes, expected);
        assert_eq!(decode_cdr::<Mixed>(&bytes).unwrap(), mixed());
    }

    /// Into a buffer that held a longer message, the same bytes as a fresh encoding (its
    /// alignment counted from the new header, nothing of the old one left).
    #[test]
    fn encoding_into_a_used_buffer_gives_the_fresh_bytes() {
        let mut buf = vec![0xAB; 3];
        let long = Mixed {
            s: "a longer string".into(),
            v: (0..50).collect(),
            ..mixed()
        };
        encode_cdr_into(&long, &mut buf).unwrap();
        assert_eq!(buf, encode_cdr(&long).unwrap());
        let room = buf.capacity();
        encode_cdr_into(&mixed(), &mut buf).unwrap();
        assert_eq!(buf, encode_cdr(&mixed()).unwrap());
        assert_eq!(buf.capacity(), room);
    }

    #[test]
    fn big_endian_body_decodes() {
        // Time { sec: 1, nanosec: 2 } in CDR_BE.
        let bytes = [0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 2];
        let t: crate::Time = decode_cdr(&bytes).unwrap();
        assert_eq!((t.sec, t.nanosec), (1, 2));
    }

    #[test]
    fn padding_is_accepted_but_not_more() {
        let mut bytes = encode_cdr(&7u8).unwrap();
        bytes.extend_from_slice(&[0, 0, 0]);
        assert_eq!(decode_cdr::<u8>(&bytes).unwrap(), 7);
        bytes.push(0);
        assert!(matches!(
            decode_cdr::<u8>(&bytes),
            Err(CdrError::TrailingBytes { trailing: 4, .. })
        ));
    }

    #[test]
    fn bogus_lengths_are_truncation_errors() {
        // A sequence claiming u32::MAX elements in an 8-byte body.
        let bytes = [0, 1, 0, 0, 0xff, 0xff, 0xff, 0xff, 1, 2, 3, 4];
        assert!(matches!(
            decode_cdr::<Vec<u8>>(&bytes),
            Err(CdrError::Truncated {
                needed: 0xffff_ffff,
                offset: 4,
                body_len: 8
            })
        ));
        assert!(matches!(
            decode_cdr::<serde_bytes::ByteBuf>(&bytes),
            Err(CdrError::Truncated { .. })
        ));
        assert!(matches!(
            decode_cdr::<String>(&bytes),
            Err(CdrError::Truncated { .. })
        ));
        assert!(matches!(
            decode_cdr::<Vec<()>>(&bytes),
            Err(CdrError::Truncated { .. })
        ));
    }

    #[test]
    fn invalid_values_are_reported_with_offsets() {
        assert_eq!(
            decode_cdr::<bool>(&[0, 1, 0, 0, 2]),
            Err(CdrError::InvalidBool {
                value: 2,
                offset: 0
            })
        );
        assert_eq!(
            decode_cdr::<String>(&[0, 1, 0, 0, 2, 0, 0, 0, 0xff, 0]),
            Err(CdrError::InvalidUtf8 { offset: 4 })
        );
        assert!(matches!(
            decode_cdr::<Kind>(&[0, 1, 0, 0, 9, 0, 0, 0]),
            Err(CdrError::Invalid { offset: 4, .. })
        ));
    }
}
