//! Our CDR codec (`chronotope::msg::{encode_cdr, decode_cdr}`) against the serde CDR codec
//! RustDDS uses (`cdr-encoding`), on random messages: both must write the same bytes (ours
//! after its 4-byte encapsulation header), and ours must read what the other writes, little
//! and big endian. ARCHITECTURE.md says why ours is kept; this is what keeps it honest.

use byteorder::{BigEndian, LittleEndian};
use chronotope::msg::{
    decode_cdr, encode_cdr, ColorRGBA, ContactEvent, Header, Marker, MarkerArray, Point,
    PointCloud2, PointField, PoseStamped, Time, VoxelGrid, WrenchStamped,
};
use proptest::prelude::*;
use serde::{de::DeserializeOwned, Deserialize, Serialize};

/// Every kind of field the serde data model maps for ROS messages.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct AllKinds {
    b: bool,
    i8_: i8,
    u8_: u8,
    i16_: i16,
    u16_: u16,
    i32_: i32,
    u32_: u32,
    i64_: i64,
    u64_: u64,
    f32_: f32,
    f64_: f64,
    s: String,
    fixed: [f64; 9],
    small: [u8; 3],
    strings: Vec<String>,
    points: Vec<(u8, f64, String)>,
    #[serde(with = "serde_bytes")]
    bytes: Vec<u8>,
    words: Vec<u16>,
}

/// Ours and theirs give the same bytes; each reads the other's; big-endian bytes written by
/// theirs read back to the same message with ours. Compared as bytes, so NaN fields count.
fn agree<T: Serialize + DeserializeOwned>(msg: &T) -> Result<(), TestCaseError> {
    let ours = encode_cdr(msg).map_err(|e| TestCaseError::fail(e.to_string()))?;
    prop_assert_eq!(&ours[..4], &[0u8, 1, 0, 0][..]);
    let theirs = cdr_encoding::to_vec::<T, LittleEndian>(msg)
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
    prop_assert_eq!(&ours[4..], &theirs[..], "little-endian bodies differ");
    // Ours reads theirs (with a header), theirs reads ours.
    let mut framed = vec![0u8, 1, 0, 0];
    framed.extend_from_slice(&theirs);
    let back: T = decode_cdr(&framed).map_err(|e| TestCaseError::fail(e.to_string()))?;
    prop_assert_eq!(encode_cdr(&back).unwrap(), ours.clone());
    let (back2, used) = cdr_encoding::from_bytes::<T, LittleEndian>(&ours[4..])
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
    prop_assert_eq!(used, ours.len() - 4);
    prop_assert_eq!(encode_cdr(&back2).unwrap(), ours.clone());
    // Big endian, written by theirs, read by ours.
    let be = cdr_encoding::to_vec::<T, BigEndian>(msg)
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
    let mut framed = vec![0u8, 0, 0, 0];
    framed.extend_from_slice(&be);
    let back3: T = decode_cdr(&framed).map_err(|e| TestCaseError::fail(e.to_string()))?;
    prop_assert_eq!(encode_cdr(&back3).unwrap(), ours);
    Ok(())
}

fn text() -> impl Strategy<Value = String> {
    // ROS strings carry no NUL; any other character, any length up to 40.
    "[^\u{0}]{0,40}"
}

fn header() -> impl Strategy<Value = Header> {
    (any::<i32>(), 0u32..1_000_000_000, text()).prop_map(|(sec, nanosec, frame_id)| Header {
        stamp: Time { sec, nanosec },
        frame_id,
    })
}

fn point() -> impl Strategy<Value = Point> {
    (any::<f64>(), any::<f64>(), any::<f64>()).prop_map(|(x, y, z)| Point { x, y, z })
}

fn color() -> impl Strategy<Value = ColorRGBA> {
    (any::<f32>(), any::<f32>(), any::<f32>(), any::<f32>())
        .prop_map(|(r, g, b, a)| ColorRGBA::new(r, g, b, a))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    #[test]
    fn every_field_kind(
        b in any::<bool>(), i8_ in any::<i8>(), u8_ in any::<u8>(), i16_ in any::<i16>(),
        u16_ in any::<u16>(), i32_ in any::<i32>(), u32_ in any::<u32>(), i64_ in any::<i64>(),
        u64_ in any::<u64>(), f32_ in any::<f32>(), f64_ in any::<f64>(), s in text(),
        fixed in any::<[f64; 9]>(), small in any::<[u8; 3]>(),
        strings in prop::collection::vec(text(), 0..5),
        points in prop::collection::vec((any::<u8>(), any::<f64>(), text()), 0..5),
        bytes in prop::collection::vec(any::<u8>(), 0..64),
        words in prop::collection::vec(any::<u16>(), 0..9),
    ) {
        agree(&AllKinds {
            b, i8_, u8_, i16_, u16_, i32_, u32_, i64_, u64_, f32_, f64_, s, fixed, small,
            strings, points, bytes, words,
        })?;
    }

    #[test]
    fn voxel_grids(h in header(), origin in point(), resolution in any::<f64>(),
                   size in any::<[u32; 3]>(), encoding in any::<u8>(),
                   data in prop::collection::vec(any::<u8>(), 0..300)) {
        agree(&VoxelGrid {
            header: h, origin, resolution, size_x: size[0], size_y: size[1], size_z: size[2],
            encoding, data,
        })?;
    }

    #[test]
    fn point_clouds(h in header(), height in any::<u32>(), width in any::<u32>(),
                    fields in prop::collection::vec((text(), any::<u32>(), any::<u8>(), any::<u32>()), 0..6),
                    big in any::<bool>(), step in any::<u32>(), row in any::<u32>(),
                    data in prop::collection::vec(any::<u8>(), 0..300), dense in any::<bool>()) {
        agree(&PointCloud2 {
            header: h, height, width,
            fields: fields.into_iter().map(|(name, offset, datatype, count)| PointField {
                name, offset, datatype, count,
            }).collect(),
            is_bigendian: big, point_step: step, row_step: row, data, is_dense: dense,
        })?;
    }

    #[test]
    fn marker_arrays(markers in prop::collection::vec(
        (header(), text(), any::<i32>(), any::<i32>(), prop::collection::vec(point(), 0..7),
         prop::collection::vec(color(), 0..7), text()), 0..3)) {
        agree(&MarkerArray {
            markers: markers.into_iter().map(|(header, ns, id, ty, points, colors, t)| Marker {
                header, ns, id, r#type: ty, points, colors, text: t, ..Marker::default()
            }).collect(),
        })?;
    }

    #[test]
    fn poses_wrenches_and_contacts(h in header(), p in point(), q in any::<[f64; 4]>(),
                                   f in any::<[f64; 6]>(), a in text(), b in text(),
                                   ev in any::<u8>(), idx in any::<u64>(), v in any::<[f64; 7]>()) {
        let mut pose = PoseStamped { header: h.clone(), ..PoseStamped::default() };
        pose.pose.position = p;
        pose.pose.orientation.x = q[0];
        pose.pose.orientation.y = q[1];
        pose.pose.orientation.z = q[2];
        pose.pose.orientation.w = q[3];
        agree(&pose)?;
        let mut w = WrenchStamped { header: h.clone(), ..WrenchStamped::default() };
        w.wrench.force.x = f[0];
        w.wrench.force.y = f[1];
        w.wrench.force.z = f[2];
        w.wrench.torque.x = f[3];
        w.wrench.torque.y = f[4];
        w.wrench.torque.z = f[5];
        agree(&w)?;
        agree(&ContactEvent {
            header: h, body_a: a, body_b: b, event: ev, contact_index: idx,
            time_origin: Time { sec: 7, nanosec: 9 },
            start_s: v[0], end_s: v[1], start_error_bound_s: v[2], end_error_bound_s: v[3],
            first_contact_s: v[4], overlap_hypervolume_m3s: v[5],
            unsure_reason: format!("{ev} unsure"),
        })?;
    }
}
