//! Measures the suite's CDR codec (`chronotope::msg::{encode_cdr, decode_cdr}`) against the
//! serde CDR codec RustDDS and ros2-client use (`cdr-encoding`), on the large messages the
//! suite sends: a 1.1M-surfel PointCloud2 (36 MB), a 128³ VoxelGrid in percent encoding
//! (2 MB), and a MarkerArray of 100k triangles (300k points and colours). Both must give the
//! same bytes; the figures go into ARCHITECTURE.md.
//!
//! `cargo run --release --example cdr_codec`

use std::time::Instant;

use byteorder::LittleEndian;
use chronotope::msg::{
    decode_cdr, encode_cdr, ColorRGBA, Marker, MarkerArray, Point, PointCloud2, PointField,
    VoxelGrid,
};
use serde::{de::DeserializeOwned, Serialize};

fn best_of<T>(reps: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..reps {
        let t = Instant::now();
        let v = f();
        best = best.min(t.elapsed().as_secs_f64());
        out = Some(v);
    }
    (best, out.expect("reps > 0"))
}

fn measure<T: Serialize + DeserializeOwned + PartialEq + std::fmt::Debug>(name: &str, msg: &T) {
    let reps = 5;
    let (ours_enc, ours) = best_of(reps, || encode_cdr(msg).expect("encodes"));
    let (theirs_enc, theirs) = best_of(reps, || {
        cdr_encoding::to_vec::<T, LittleEndian>(msg).expect("encodes")
    });
    // Ours carries the 4-byte encapsulation header; theirs is the body alone.
    assert_eq!(&ours[4..], &theirs[..], "{name}: the two codecs disagree");
    let (ours_dec, back) = best_of(reps, || decode_cdr::<T>(&ours).expect("decodes"));
    assert!(&back == msg, "{name}: ours does not round-trip");
    let (theirs_dec, back2) = best_of(reps, || {
        cdr_encoding::from_bytes::<T, LittleEndian>(&theirs)
            .expect("decodes")
            .0
    });
    assert!(&back2 == msg, "{name}: theirs does not round-trip");
    let mb = ours.len() as f64 / 1e6;
    println!(
        "| {name} | {mb:.1} | {:.1} | {:.1} | {:.1} | {:.1} |",
        ours_enc * 1e3,
        theirs_enc * 1e3,
        ours_dec * 1e3,
        theirs_dec * 1e3
    );
}

/// A `uint8[]` field as a code generator without serde_bytes writes it: a plain `Vec<u8>`,
/// serialised element by element.
#[derive(Debug, PartialEq, serde::Serialize, serde::Deserialize)]
struct PlainBytes {
    data: Vec<u8>,
}

/// The same field with `serde_bytes`, as the suite's message types declare `uint8[]`.
#[derive(Debug, PartialEq, serde::Serialize, serde::Deserialize)]
struct BulkBytes {
    #[serde(with = "serde_bytes")]
    data: Vec<u8>,
}

fn main() {
    let n = 1_100_000u32;
    let cloud = PointCloud2 {
        height: 1,
        width: n,
        fields: [
            "x", "y", "z", "normal_x", "normal_y", "normal_z", "rgb", "pad",
        ]
        .iter()
        .enumerate()
        .map(|(i, f)| PointField {
            name: (*f).to_owned(),
            offset: 4 * i as u32,
            datatype: 7,
            count: 1,
        })
        .collect(),
        point_step: 32,
        row_step: 32 * n,
        data: (0..32 * n as usize).map(|i| (i * 31 % 251) as u8).collect(),
        is_dense: true,
        ..PointCloud2::default()
    };
    let grid = VoxelGrid {
        resolution: 0.01,
        size_x: 128,
        size_y: 128,
        size_z: 128,
        encoding: VoxelGrid::ENCODING_PERCENT,
        data: (0..128 * 128 * 128usize).map(|i| (i % 101) as u8).collect(),
        ..VoxelGrid::default()
    };
    let tris = 100_000usize;
    let marker = Marker {
        r#type: Marker::TRIANGLE_LIST,
        points: (0..3 * tris)
            .map(|i| Point {
                x: i as f64 * 1e-3,
                y: (i % 7) as f64,
                z: -(i as f64),
            })
            .collect(),
        colors: (0..3 * tris)
            .map(|i| ColorRGBA::new((i % 3) as f32, 0.5, 0.25, 1.0))
            .collect(),
        ..Marker::default()
    };
    let markers = MarkerArray {
        markers: vec![marker],
    };
    println!("| message | MB | encode ours ms | encode cdr-encoding ms | decode ours ms | decode cdr-encoding ms |");
    println!("|---|---|---|---|---|---|");
    measure("PointCloud2, 1.1M points", &cloud);
    measure("VoxelGrid 128³ percent", &grid);
    measure("MarkerArray, 100k triangles", &markers);
    let data: Vec<u8> = cloud.data.clone();
    measure(
        "uint8[] 35 MB, serde_bytes",
        &BulkBytes { data: data.clone() },
    );
    measure("uint8[] 35 MB, plain Vec<u8>", &PlainBytes { data });
}
