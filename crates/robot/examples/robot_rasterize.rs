//! Rasterises one posed robot from a JSON request and writes the raw VoxelGrid `data`
//! bytes; prints the link poses, the frame's statistics and its time as JSON on stdout.
//! The accuracy script `tests/py/robot/compare.py` drives it.
//!
//! ```text
//! cargo run --release --example rasterize -- request.json
//! ```
//!
//! Request fields: `urdf` (path), `package_path` (list of directories), `base_pose`
//! (`[x, y, z, roll, pitch, yaw]`), `joints` (name → position; others 0), `links` (optional
//! list: the body; default every link), `lattice` (`origin`, `resolution`, `size`),
//! `encoding` (`"bits"` or `"percent"`), `subsamples` (K for percent), `out` (data file),
//! `repeat` (frames timed; the median is printed).

use chronotope_robot::{
    BasePose, Encoding, Lattice, LinkPoses, LoadOptions, RasterOptions, Rasterizer, Robot,
};
use serde_json::{json, Value};
use std::path::PathBuf;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .ok_or("usage: rasterize REQUEST.json")?;
    let req: Value = serde_json::from_str(&std::fs::read_to_string(path)?)?;
    let f64s = |v: &Value| -> Vec<f64> {
        v.as_array()
            .map(|a| a.iter().filter_map(Value::as_f64).collect())
            .unwrap_or_default()
    };
    let package_path: Vec<PathBuf> = req["package_path"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|v| v.as_str().map(PathBuf::from))
                .collect()
        })
        .unwrap_or_default();
    let urdf = req["urdf"].as_str().ok_or("request has no `urdf`")?;
    let robot =
        Robot::from_urdf_file(urdf.as_ref(), LoadOptions::new().package_path(package_path))?;
    let kin = robot.kinematics();
    let mut q = vec![0.0; kin.dof()];
    if let Some(joints) = req["joints"].as_object() {
        for (name, v) in joints {
            if let (Some(i), Some(x)) = (kin.joint_index(name), v.as_f64()) {
                q[i] = x;
            }
        }
    }
    let base = {
        let b = f64s(&req["base_pose"]);
        if b.len() == 6 {
            BasePose::from_array([b[0], b[1], b[2], b[3], b[4], b[5]])
        } else {
            BasePose::IDENTITY
        }
    };
    let body = match req["links"].as_array() {
        Some(names) => {
            let names: Vec<&str> = names.iter().filter_map(Value::as_str).collect();
            robot.body(&names)?
        }
        None => robot.whole_body(),
    };
    let lat = &req["lattice"];
    let o = f64s(&lat["origin"]);
    let s = f64s(&lat["size"]);
    let lattice = Lattice::new(
        [o[0], o[1], o[2]],
        lat["resolution"]
            .as_f64()
            .ok_or("lattice has no resolution")?,
        [s[0] as u32, s[1] as u32, s[2] as u32],
    )?;
    let encoding = match req["encoding"].as_str() {
        Some("percent") => Encoding::Percent,
        _ => Encoding::Bits,
    };
    let k = req["subsamples"].as_u64().unwrap_or(4) as u32;
    let mut raster = Rasterizer::new(lattice, encoding, RasterOptions::default().subsamples(k));
    let mut poses = LinkPoses::new();
    let repeat = req["repeat"].as_u64().unwrap_or(1).max(1);
    let mut times = Vec::new();
    let mut stats = Default::default();
    for _ in 0..repeat {
        let t = Instant::now();
        kin.forward(&q, &base, &mut poses);
        stats = raster.rasterize(&robot, &body, &poses);
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    if let Some(out) = req["out"].as_str() {
        std::fs::write(out, raster.data())?;
    }
    let mut pose_json = serde_json::Map::new();
    for (i, link) in robot.model().links.iter().enumerate() {
        let m = poses.get(i).to_homogeneous();
        let rows: Vec<f64> = (0..4)
            .flat_map(|r| (0..4).map(move |c| m[(r, c)]))
            .collect();
        pose_json.insert(link.name.clone(), json!(rows));
    }
    let report = robot.load_report();
    let answer = json!({
        "poses": pose_json,
        "frame_ms_median": times[times.len() / 2],
        "frame_ms_min": times[0],
        "stats": {
            "geometries": stats.geometries,
            "triangles": stats.triangles,
            "events": stats.events,
            "open_meshes": stats.open_meshes,
            "occupied": stats.occupied,
        },
        "robot_triangles": report.triangles,
        "open_meshes": report.open_meshes().map(|m| m.uri.clone()).collect::<Vec<_>>(),
        "encoding": encoding.wire_value(),
        "data_len": raster.data().len(),
    });
    println!("{answer}");
    Ok(())
}
