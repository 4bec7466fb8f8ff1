//! `chronotope render BAG --out FILE.png [--time S]`: a picture of the checker's answer. The
//! checker publishes, per body and frame period, the body's boundary at that instant (its
//! 4D mesh sliced at a time plane) as a triangle list coloured by label: red where the tet
//! interferes with another body, orange where it lies inside one, the body's own colour where
//! it is clear (`/checker/markers`). This command takes those markers from an output bag
//! (`replay --out`), picks one instant, and draws every body's slice in an oblique view with
//! a depth buffer and simple shading, to a PNG. It shows what rviz2 or Foxglove show for that
//! instant, without either.

use std::collections::BTreeMap;
use std::path::PathBuf;

use clap::{Args, ValueEnum};

use super::CliError;
use crate::bag::BagReader;
use crate::msg::{decode_cdr, Marker, MarkerArray, RosMessage};

/// Largest image side accepted (pixels).
pub const MAX_IMAGE_SIDE: u32 = 8192;

/// Most triangles drawn (the rest of a huge slice is refused by name).
pub const MAX_TRIANGLES: usize = 1 << 24;

/// The direction the picture is seen from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum View {
    /// From in front, to the right and above (35° elevation).
    Oblique,
    /// From above (+z), x to the right.
    Top,
    /// From the front (−y), z up.
    Front,
}

/// Options of `chronotope render`.
#[derive(Debug, Clone, Args)]
pub struct RenderArgs {
    /// An output bag holding the checker's markers (`replay --out`, `record`).
    pub bag: PathBuf,
    /// The PNG to write.
    #[arg(long)]
    pub out: PathBuf,
    /// Seconds since the first marker's stamp; the frame period whose marker stamp is
    /// nearest is drawn (default: the period with the most interfering triangles).
    #[arg(long)]
    pub time: Option<f64>,
    /// The MarkerArray topic.
    #[arg(long, default_value = "/checker/markers")]
    pub topic: String,
    /// Image width and height (pixels).
    #[arg(long, default_value_t = 900)]
    pub size: u32,
    /// Where it is seen from.
    #[arg(long, value_enum, default_value_t = View::Oblique)]
    pub view: View,
    /// Replace an output path that holds a bag. Inputs are never replaced.
    #[arg(long)]
    pub overwrite: bool,
}

/// One triangle to draw: corners (m), colour, and whether it is a label overlay (ids 1 and
/// 2), drawn over the body's own triangles it lies on.
#[derive(Clone, Copy)]
struct Tri {
    p: [[f64; 3]; 3],
    rgb: [f64; 3],
    overlay: bool,
}

/// The colour of point `k` of a marker: its own, or the marker's.
fn color_at(m: &Marker, k: usize) -> crate::msg::ColorRGBA {
    m.colors.get(k).copied().unwrap_or(m.color)
}

fn is_red(m: &Marker, k: usize) -> bool {
    let c = color_at(m, k);
    c.r > 0.8 && c.g < 0.2 && c.b < 0.2
}

/// Calls `each` for every TRIANGLE_LIST marker (ADD or DELETE) on the topic, in bag order.
fn scan(a: &RenderArgs, mut each: impl FnMut(i64, &Marker)) -> Result<(), CliError> {
    for item in BagReader::open(&a.bag)? {
        let m = match item {
            Ok(m) => m,
            Err(e) if e.is_fatal() => return Err(e.into()),
            Err(e) => {
                tracing::warn!("{e}");
                continue;
            }
        };
        if m.topic != a.topic || m.schema_name != MarkerArray::TYPE_NAME {
            continue;
        }
        let Ok(arr) = decode_cdr::<MarkerArray>(&m.data) else {
            tracing::warn!("a MarkerArray on {} does not decode; skipped", a.topic);
            continue;
        };
        for mk in &arr.markers {
            if mk.r#type != Marker::TRIANGLE_LIST
                || (mk.action != Marker::ADD && mk.action != Marker::DELETE)
            {
                continue;
            }
            each(mk.header.stamp.as_nanos(), mk);
        }
    }
    Ok(())
}

/// Writes the picture; the stamp drawn and the triangles drawn.
///
/// Markers are kept until replaced or deleted (a body at rest is drawn once and stays, as
/// rviz2 and Foxglove keep it): the picture at a stamp is every marker's latest state at or
/// before that stamp, by namespace and id.
///
/// # Errors
/// The bag cannot be read, holds no markers on the topic, the options are out of range, or
/// the PNG cannot be written.
pub fn render(a: &RenderArgs) -> Result<(i64, usize), CliError> {
    if a.size < 16 || a.size > MAX_IMAGE_SIDE {
        return Err(CliError::Usage(format!(
            "--size {}: must be between 16 and MAX_IMAGE_SIDE = {MAX_IMAGE_SIDE} pixels",
            a.size
        )));
    }
    if let Some(t) = a.time.filter(|t| !t.is_finite() || *t < 0.0) {
        return Err(CliError::Usage(format!(
            "--time {t}: must be a non-negative number of seconds"
        )));
    }
    // Per stamp, the interfering triangles shown once the markers up to it are applied.
    let mut red_of: BTreeMap<(String, i32), u64> = BTreeMap::new();
    let mut red: BTreeMap<i64, u64> = BTreeMap::new();
    scan(a, |stamp, mk| {
        let n = if mk.action == Marker::ADD {
            (0..mk.points.len() / 3)
                .filter(|&t| is_red(mk, 3 * t))
                .count() as u64
        } else {
            0
        };
        red_of.insert((mk.ns.clone(), mk.id), n);
        red.insert(stamp, red_of.values().sum());
    })?;
    let Some(&first) = red.keys().next() else {
        return Err(CliError::Usage(format!(
            "{}: no TRIANGLE_LIST markers on {} (replay a bag with a checker and --out first)",
            a.bag.display(),
            a.topic
        )));
    };
    let stamp = match a.time {
        // The stamp nearest the time asked (markers are stamped mid-period).
        Some(t) => {
            let want = first + (t * 1e9) as i64;
            let mut best = first;
            for &s in red.keys() {
                if (s - want).abs() < (best - want).abs() {
                    best = s;
                }
            }
            best
        }
        None => red
            .iter()
            .max_by_key(|(s, n)| (**n, std::cmp::Reverse(**s)))
            .map_or(first, |(s, _)| *s),
    };
    // Each marker's latest state at the stamp drawn.
    let mut state: BTreeMap<(String, i32), Vec<Tri>> = BTreeMap::new();
    let mut over = false;
    scan(a, |s, mk| {
        if s > stamp {
            return;
        }
        let key = (mk.ns.clone(), mk.id);
        if mk.action == Marker::DELETE {
            state.remove(&key);
            return;
        }
        let mut tris = Vec::with_capacity(mk.points.len() / 3);
        for t in 0..mk.points.len() / 3 {
            if tris.len() >= MAX_TRIANGLES {
                over = true;
                break;
            }
            let p = [0, 1, 2].map(|k| {
                let q = &mk.points[3 * t + k];
                [q.x, q.y, q.z]
            });
            let c = color_at(mk, 3 * t);
            tris.push(Tri {
                p,
                rgb: [f64::from(c.r), f64::from(c.g), f64::from(c.b)],
                overlay: mk.id != 0,
            });
        }
        state.insert(key, tris);
    })?;
    // Drawn in namespace and id order, so the label overlays (ids 1, 2) cover the body.
    let mut tris: Vec<Tri> = Vec::new();
    for t in state.into_values().flatten() {
        if tris.len() >= MAX_TRIANGLES {
            over = true;
            break;
        }
        tris.push(t);
    }
    if over {
        tracing::warn!(
            "more than MAX_TRIANGLES = {MAX_TRIANGLES} triangles: the rest is not drawn"
        );
    }
    let img = rasterise(&tris, a.size, a.view);
    write_png(&a.out, a.size, &img)?;
    Ok((stamp, tris.len()))
}

/// The view's rotation: rows are the screen's right, up and towards-the-viewer axes.
fn view_basis(view: View) -> [[f64; 3]; 3] {
    match view {
        View::Top => [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        View::Front => [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]],
        View::Oblique => {
            // Towards the viewer: in front (−y), to the right (+x) and above.
            let (phi, el) = ((-50f64).to_radians(), 35f64.to_radians());
            let toward = [el.cos() * phi.cos(), el.cos() * phi.sin(), el.sin()];
            let right = [-phi.sin(), phi.cos(), 0.0];
            // up = toward × right, so that right × up = toward.
            let up = [
                toward[1] * right[2] - toward[2] * right[1],
                toward[2] * right[0] - toward[0] * right[2],
                toward[0] * right[1] - toward[1] * right[0],
            ];
            [right, up, toward]
        }
    }
}

fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Draws the triangles (orthographic, depth-buffered, shaded by the angle to the viewer) on a
/// white square of `size` pixels; RGB bytes.
fn rasterise(tris: &[Tri], size: u32, view: View) -> Vec<u8> {
    let n = size as usize;
    let mut rgb = vec![255u8; n * n * 3];
    let mut depth = vec![f64::NEG_INFINITY; n * n];
    let basis = view_basis(view);
    let proj: Vec<[[f64; 3]; 3]> = tris
        .iter()
        .map(|t| {
            t.p.map(|p| [dot(&basis[0], &p), dot(&basis[1], &p), dot(&basis[2], &p)])
        })
        .collect();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for q in proj.iter().flatten() {
        for k in 0..2 {
            lo[k] = lo[k].min(q[k]);
            hi[k] = hi[k].max(q[k]);
        }
    }
    if proj.is_empty() {
        return rgb;
    }
    let margin = 0.05 * n as f64;
    let span = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-12);
    let s = (n as f64 - 2.0 * margin) / span;
    // A label overlay lies on the body's triangles, triangulated otherwise (its flat faces
    // merged apart): its depths, interpolated over other triangles, differ from theirs in
    // the last bits. Brought this much nearer the viewer, it covers them everywhere instead
    // of in specks (a micrometre on a metre-wide scene, far below a pixel).
    let overlay_bias = 1e-6 * span;
    let off = [
        margin + 0.5 * ((n as f64 - 2.0 * margin) - s * (hi[0] - lo[0])),
        margin + 0.5 * ((n as f64 - 2.0 * margin) - s * (hi[1] - lo[1])),
    ];
    for (t, q) in tris.iter().zip(&proj) {
        // Screen coordinates (y down).
        let v = q.map(|p| {
            [
                off[0] + s * (p[0] - lo[0]),
                n as f64 - (off[1] + s * (p[1] - lo[1])),
                p[2],
            ]
        });
        let e1 = [v[1][0] - v[0][0], v[1][1] - v[0][1]];
        let e2 = [v[2][0] - v[0][0], v[2][1] - v[0][1]];
        let area = e1[0] * e2[1] - e1[1] * e2[0];
        if area.abs() < 1e-12 {
            continue;
        }
        // Shade: |cos| of the angle between the triangle's normal and the view direction.
        let a3 = [q[1][0] - q[0][0], q[1][1] - q[0][1], q[1][2] - q[0][2]];
        let b3 = [q[2][0] - q[0][0], q[2][1] - q[0][1], q[2][2] - q[0][2]];
        let normal = [
            a3[1] * b3[2] - a3[2] * b3[1],
            a3[2] * b3[0] - a3[0] * b3[2],
            a3[0] * b3[1] - a3[1] * b3[0],
        ];
        let nl = dot(&normal, &normal).sqrt().max(1e-300);
        let shade = 0.35 + 0.65 * (normal[2] / nl).abs();
        let colour = t
            .rgb
            .map(|c| ((c * shade).clamp(0.0, 1.0) * 255.0).round() as u8);
        let x0 = v
            .iter()
            .map(|p| p[0])
            .fold(f64::INFINITY, f64::min)
            .floor()
            .max(0.0) as usize;
        let x1 = v
            .iter()
            .map(|p| p[0])
            .fold(f64::NEG_INFINITY, f64::max)
            .ceil()
            .min(n as f64 - 1.0) as usize;
        let y0 = v
            .iter()
            .map(|p| p[1])
            .fold(f64::INFINITY, f64::min)
            .floor()
            .max(0.0) as usize;
        let y1 = v
            .iter()
            .map(|p| p[1])
            .fold(f64::NEG_INFINITY, f64::max)
            .ceil()
            .min(n as f64 - 1.0) as usize;
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                let w1 = ((px - v[0][0]) * e2[1] - (py - v[0][1]) * e2[0]) / area;
                let w2 = (e1[0] * (py - v[0][1]) - e1[1] * (px - v[0][0])) / area;
                let w0 = 1.0 - w1 - w2;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let z = w0 * v[0][2]
                    + w1 * v[1][2]
                    + w2 * v[2][2]
                    + if t.overlay { overlay_bias } else { 0.0 };
                let i = y * n + x;
                // Ties go to the later triangle: label overlays are drawn over the body they lie on.
                if z >= depth[i] {
                    depth[i] = z;
                    rgb[3 * i..3 * i + 3].copy_from_slice(&colour);
                }
            }
        }
    }
    rgb
}

fn write_png(path: &std::path::Path, size: u32, rgb: &[u8]) -> Result<(), CliError> {
    let png_err = |e: png::EncodingError| CliError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::other(format!("cannot write the PNG: {e}")),
    };
    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, size, size);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().map_err(png_err)?;
        w.write_image_data(rgb).map_err(png_err)?;
        w.finish().map_err(png_err)?;
    }
    super::write_output(path, &bytes)
}

/// `chronotope render`.
///
/// # Errors
/// See [`render`].
pub fn run(a: &RenderArgs) -> Result<(), CliError> {
    super::paths::Paths::new(a.overwrite)
        .bag(&a.bag)
        .output("--out", Some(&a.out), super::paths::OutputKind::File)
        .check()?;
    let (stamp, n) = render(a)?;
    println!(
        "{}: {n} triangles of the slice stamped {:.3} s, seen {:?}",
        a.out.display(),
        stamp as f64 * 1e-9,
        a.view
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_triangle_is_drawn_in_its_colour_and_the_nearer_one_wins() {
        let far = Tri {
            p: [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            rgb: [0.0, 0.0, 1.0],
            overlay: false,
        };
        let near = Tri {
            p: [[0.0, 0.0, 0.5], [0.5, 0.0, 0.5], [0.0, 0.5, 0.5]],
            rgb: [1.0, 0.0, 0.0],
            overlay: false,
        };
        let img = rasterise(&[far, near], 64, View::Top);
        let px = |x: usize, y: usize| &img[3 * (y * 64 + x)..3 * (y * 64 + x) + 3];
        // Near the origin corner (bottom left): the near, red one.
        assert!(px(6, 57)[0] > 200 && px(6, 57)[2] < 50, "{:?}", px(6, 57));
        // Further along x, only the far, blue one.
        assert!(
            px(45, 57)[2] > 200 && px(45, 57)[0] < 50,
            "{:?}",
            px(45, 57)
        );
        // Beyond the hypotenuse: background.
        assert_eq!(px(60, 4), &[255, 255, 255]);
    }

    /// A label overlay covers the body's face it lies on at every pixel, though the two are
    /// triangulated apart (a tilted square split along one diagonal, and along the other).
    #[test]
    fn a_label_overlay_covers_the_face_it_lies_on_without_specks() {
        let z = |x: f64, y: f64| 0.3 * x + 0.2 * y + 0.1;
        let at = |x: f64, y: f64| [x, y, z(x, y)];
        let (a, b, c, d) = (at(0.0, 0.0), at(1.0, 0.0), at(1.0, 1.0), at(0.0, 1.0));
        let tri = |p, rgb, overlay| Tri { p, rgb, overlay };
        let (green, red) = ([0.0, 1.0, 0.0], [1.0, 0.0, 0.0]);
        let tris = [
            tri([a, b, c], green, false),
            tri([a, c, d], green, false),
            tri([a, b, d], red, true),
            tri([b, c, d], red, true),
        ];
        let n = 128;
        let img = rasterise(&tris, n as u32, View::Oblique);
        let (mut red_px, mut green_px) = (0, 0);
        for px in img.chunks_exact(3) {
            if px[1] > 0 && px[0] == 0 {
                green_px += 1;
            }
            if px[0] > 0 && px[1] == 0 {
                red_px += 1;
            }
        }
        assert!(red_px > n * n / 8, "{red_px} red pixels");
        assert_eq!(green_px, 0, "the body shows through its overlay");
    }
}
