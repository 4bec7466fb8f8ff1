//! Rasterises one message read from files and writes `VoxelGrid.data`: the
//! bridge the independent-producer comparison (`tests/py/occupancy/compare.py`
//! in the chronotope repository) drives.
//!
//! ```sh
//! # Octomap fields given one by one, the stream in a file:
//! cargo run --release --example rasterize -- octomap --binary 1 --id OcTree --res 0.05 --data map.bin \
//!     --origin 0,0,0 --lattice-res 0.1 --size 32,32,16 --encoding percent --out grid.bin
//! # A whole message as CDR (what a ROS 2 subscriber receives), Octomap or PointCloud2:
//! cargo run --release --example rasterize -- octomap-cdr --msg map.cdr ... --out grid.bin
//! cargo run --release --example rasterize -- cloud-cdr --msg cloud.cdr --min-points 2 --dilate 0.05 \
//!     --fill z- --matrix r00,r01,r02,r10,r11,r12,r20,r21,r22,tx,ty,tz ... --out grid.bin
//! ```
//!
//! Prints the statistics as `key=value` words on one line. The CDR reader here
//! is a minimal one for these two messages (XCDR1, either byte order), enough
//! for a test bridge; a node decodes messages with its own codec.

use chronotope_occupancy::{
    Axis, CloudOptions, CloudRasterizer, Encoding, Fill, Lattice, OctomapMsg, OctomapOptions,
    OctomapRasterizer, PointCloud2Ref, PointField, RigidTransform, Toward, VoxelFrame,
};
use std::collections::HashMap;
use std::process::ExitCode;

/// Errors of an example program: whatever went wrong, shown by its message.
type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// A reader of one CDR-encapsulated message.
struct Cdr<'a> {
    body: &'a [u8],
    pos: usize,
    le: bool,
}

impl<'a> Cdr<'a> {
    fn new(bytes: &'a [u8]) -> Result<Self> {
        let le = match bytes.get(..4) {
            Some([0, 1, _, _]) => true,
            Some([0, 0, _, _]) => false,
            _ => return Err("not a CDR message: bad encapsulation header".into()),
        };
        Ok(Cdr {
            body: &bytes[4..],
            pos: 0,
            le,
        })
    }
    fn take(&mut self, n: usize, align: usize) -> Result<&'a [u8]> {
        self.pos = self.pos.div_ceil(align) * align;
        let s = self
            .body
            .get(self.pos..self.pos + n)
            .ok_or(format!("CDR message ends at body offset {}", self.pos))?;
        self.pos += n;
        Ok(s)
    }
    fn u8(&mut self) -> Result<u8> {
        Ok(self.take(1, 1)?[0])
    }
    fn u32(&mut self) -> Result<u32> {
        let b: [u8; 4] = self.take(4, 4)?.try_into().unwrap();
        Ok(if self.le {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        })
    }
    fn f64(&mut self) -> Result<f64> {
        let b: [u8; 8] = self.take(8, 8)?.try_into().unwrap();
        Ok(if self.le {
            f64::from_le_bytes(b)
        } else {
            f64::from_be_bytes(b)
        })
    }
    fn bytes(&mut self) -> Result<&'a [u8]> {
        let n = self.u32()? as usize;
        self.take(n, 1)
    }
    fn string(&mut self) -> Result<&'a str> {
        let b = self.bytes()?;
        let b = b.strip_suffix(&[0]).unwrap_or(b);
        Ok(std::str::from_utf8(b)?)
    }
    fn header(&mut self) -> Result<()> {
        self.u32()?; // stamp.sec
        self.u32()?; // stamp.nanosec
        self.string()?; // frame_id
        Ok(())
    }
}

fn parse_list<T: std::str::FromStr>(s: &str, n: usize, what: &str) -> Result<Vec<T>> {
    let v: Vec<T> = s
        .split(',')
        .map(|x| {
            x.trim()
                .parse()
                .map_err(|_| format!("{what}: bad number {x:?}"))
        })
        .collect::<std::result::Result<_, _>>()?;
    if v.len() != n {
        return Err(format!("{what}: want {n} numbers, got {}", v.len()).into());
    }
    Ok(v)
}

fn lattice_of(args: &HashMap<String, String>) -> Result<(Lattice, Encoding)> {
    let get = |k: &str| args.get(k).ok_or(format!("--{k} is needed"));
    let o: Vec<f64> = parse_list(get("origin")?, 3, "--origin")?;
    let s: Vec<u32> = parse_list(get("size")?, 3, "--size")?;
    let res: f64 = get("lattice-res")?
        .parse()
        .map_err(|_| "--lattice-res: bad number")?;
    let lattice = Lattice::new([o[0], o[1], o[2]], res, [s[0], s[1], s[2]])?;
    let enc = match args.get("encoding").map(String::as_str) {
        Some("percent") => Encoding::Percent,
        Some("bits") | None => Encoding::Bits,
        Some(e) => return Err(format!("--encoding {e}: bits or percent").into()),
    };
    Ok((lattice, enc))
}

fn octomap_options(args: &HashMap<String, String>) -> Result<OctomapOptions> {
    let mut opts = OctomapOptions::new()
        .unknown_occupied(args.contains_key("unknown-occupied"))
        .allow_trailing_bytes(args.contains_key("allow-trailing"));
    if let Some(t) = args.get("threshold") {
        opts = opts.threshold_log_odds(t.parse().map_err(|_| "--threshold: bad number")?);
    }
    Ok(opts)
}

fn run_octomap(msg: &OctomapMsg<'_>, args: &HashMap<String, String>) -> Result<(Vec<u8>, String)> {
    let (lattice, enc) = lattice_of(args)?;
    let mut frame = VoxelFrame::new();
    let stats =
        OctomapRasterizer::new(octomap_options(args)?).rasterize(msg, &lattice, enc, &mut frame)?;
    let line = format!(
        "nodes={} occupied_leaves={} free_leaves={} max_depth={} leaves_in_lattice={} occupied_voxels={} unknown_voxels={}",
        stats.stream.nodes,
        stats.stream.occupied_leaves,
        stats.stream.free_leaves,
        stats.stream.max_depth,
        stats.leaves_in_lattice,
        stats.occupied_voxels,
        stats.unknown_voxels
    );
    Ok((frame.take_data(), line))
}

fn cloud_options(args: &HashMap<String, String>) -> Result<CloudOptions> {
    let mut opts = CloudOptions::new();
    if let Some(n) = args.get("min-points") {
        opts = opts.min_points(n.parse().map_err(|_| "--min-points: 1..=255")?);
    }
    if let Some(d) = args.get("dilate") {
        opts = opts.dilate_m(d.parse().map_err(|_| "--dilate: bad number")?);
    }
    if let Some(f) = args.get("fill") {
        let fill = match f.as_str() {
            "none" => Fill::None,
            s if s.len() == 2 => {
                let axis = match &s[..1] {
                    "x" => Axis::X,
                    "y" => Axis::Y,
                    "z" => Axis::Z,
                    _ => {
                        return Err(format!("--fill {s}: none, or an axis and a sign as z-").into())
                    }
                };
                let toward = if &s[1..] == "-" {
                    Toward::Min
                } else {
                    Toward::Max
                };
                Fill::Columns { axis, toward }
            }
            s => return Err(format!("--fill {s}: none, or an axis and a sign as z-").into()),
        };
        opts = opts.fill(fill);
    }
    if let Some(m) = args.get("matrix") {
        let v: Vec<f64> = parse_list(m, 12, "--matrix")?;
        let r = [[v[0], v[1], v[2]], [v[3], v[4], v[5]], [v[6], v[7], v[8]]];
        opts = opts.transform(Some(RigidTransform::from_matrix(r, [v[9], v[10], v[11]])?));
    }
    Ok(opts)
}

fn run(args: &[String]) -> Result<()> {
    let (cmd, rest) = args
        .split_first()
        .ok_or("give a command: octomap, octomap-cdr or cloud-cdr")?;
    let mut kv = HashMap::new();
    let mut it = rest.iter();
    while let Some(k) = it.next() {
        let key = k
            .strip_prefix("--")
            .ok_or(format!("unexpected {k}"))?
            .to_owned();
        if matches!(key.as_str(), "unknown-occupied" | "allow-trailing") {
            kv.insert(key, String::new());
        } else {
            kv.insert(
                key.clone(),
                it.next().ok_or(format!("--{key} needs a value"))?.clone(),
            );
        }
    }
    let read = |k: &str| -> Result<Vec<u8>> {
        let p = kv.get(k).ok_or(format!("--{k} is needed"))?;
        Ok(std::fs::read(p).map_err(|e| format!("{p}: {e}"))?)
    };
    let (data, line) = match cmd.as_str() {
        "octomap" => {
            let bytes = read("data")?;
            let binary = kv
                .get("binary")
                .map(|b| b == "1" || b == "true")
                .unwrap_or(false);
            let id = kv.get("id").cloned().unwrap_or_else(|| "OcTree".into());
            let res: f64 = kv
                .get("res")
                .ok_or("--res is needed")?
                .parse()
                .map_err(|_| "--res: bad number")?;
            run_octomap(
                &OctomapMsg {
                    binary,
                    id: &id,
                    resolution: res,
                    data: &bytes,
                },
                &kv,
            )?
        }
        "octomap-cdr" => {
            let bytes = read("msg")?;
            let mut c = Cdr::new(&bytes)?;
            c.header()?;
            let binary = c.u8()? != 0;
            let id = c.string()?;
            let resolution = c.f64()?;
            let data = c.bytes()?;
            run_octomap(
                &OctomapMsg {
                    binary,
                    id,
                    resolution,
                    data,
                },
                &kv,
            )?
        }
        "cloud-cdr" => {
            let bytes = read("msg")?;
            let mut c = Cdr::new(&bytes)?;
            c.header()?;
            let height = c.u32()?;
            let width = c.u32()?;
            let n = c.u32()? as usize;
            let mut fields = Vec::new();
            for _ in 0..n.min(1024) {
                let name = c.string()?;
                let offset = c.u32()?;
                let datatype = c.u8()?;
                let count = c.u32()?;
                fields.push(PointField {
                    name,
                    offset,
                    datatype,
                    count,
                });
            }
            let is_bigendian = c.u8()? != 0;
            let point_step = c.u32()?;
            let row_step = c.u32()?;
            let data = c.bytes()?;
            let is_dense = c.u8()? != 0;
            let cloud = PointCloud2Ref {
                height,
                width,
                fields: &fields,
                is_bigendian,
                point_step,
                row_step,
                data,
                is_dense,
            };
            let (lattice, enc) = lattice_of(&kv)?;
            let mut frame = VoxelFrame::new();
            let s = CloudRasterizer::new(cloud_options(&kv)?)
                .rasterize(&cloud, &lattice, enc, &mut frame)?;
            let line = format!(
                "points={} nonfinite={} outside={} margin_points={} marked_voxels={} occupied_voxels={} trailing_bytes={}",
                s.points, s.nonfinite, s.outside, s.margin_points, s.marked_voxels, s.occupied_voxels, s.trailing_bytes
            );
            (frame.take_data(), line)
        }
        c => return Err(format!("unknown command {c}: octomap, octomap-cdr or cloud-cdr").into()),
    };
    let out = kv.get("out").ok_or("--out is needed")?;
    std::fs::write(out, data).map_err(|e| format!("{out}: {e}"))?;
    println!("{line}");
    Ok(())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
