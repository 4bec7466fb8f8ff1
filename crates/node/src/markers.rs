//! visualization_msgs/Marker helpers: t-slices of 4D meshes as coloured triangle lists.

use chronotope_mesh::slice::{PlaneValue, TriMesh};
use chronotope_mesh::GridGeometry;
use chronotope_msg::{ColorRGBA, Header, Marker, Point, Vector3};

/// A colour for body `id`, the same on every run (hue from a hash of the name).
pub fn body_color(id: &str) -> ColorRGBA {
    let h = id.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3)
    });
    let hue = (h % 360) as f32;
    let (r, g, b) = hsv(hue, 0.55, 0.9);
    ColorRGBA::new(r, g, b, 0.8)
}

fn hsv(h: f32, s: f32, v: f32) -> (f32, f32, f32) {
    let c = v * s;
    let x = c * (1.0 - ((h / 60.0) % 2.0 - 1.0).abs());
    let m = v - c;
    let (r, g, b) = match (h / 60.0) as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    (r + m, g + m, b + m)
}

/// The time plane of slab `index`'s later frame (lattice units of `scale` per frame): what
/// the markers draw of a slab is the body at that frame, the newest the slab knows. Sliced
/// there, a slab gives the faces of its tets that lie in the plane, which are the frame's
/// own surface (its 3D marching; the slice of a frame time reproduces the frame,
/// `tests/it/mesh_closed.rs`); no tet is cut, so the slice has no points of its own and
/// about a quarter of the triangles a plane through the slab's middle gives.
pub fn slab_end_plane(index: u64, scale: i32) -> PlaneValue {
    PlaneValue::lattice(i64::from(scale).saturating_mul((index as i64).saturating_add(1)))
}

/// Lattice units of `g` (x, y, z of a slice) to metres.
pub fn to_world(g: &GridGeometry, p: &[f64; 3]) -> Point {
    let c = g.voxel0_centre();
    let step = g.step_m();
    Point {
        x: c[0] + p[0] * step,
        y: c[1] + p[1] * step,
        z: c[2] + p[2] * step,
    }
}

/// A TRIANGLE_LIST marker of the triangles `tris` (vertex ids of `mesh`, lattice units of
/// `g`), all of one colour (the marker's `color`; `colors` left empty, which rviz2 and
/// Foxglove read as that colour for every point): 72 bytes a triangle instead of 120 with a
/// colour per point. With no triangle, a DELETE of that marker.
pub fn triangle_list_of(
    header: Header,
    ns: &str,
    id: i32,
    g: &GridGeometry,
    mesh: &TriMesh,
    tris: &[[u32; 3]],
    color: ColorRGBA,
) -> Marker {
    let mut points = Vec::with_capacity(3 * tris.len());
    for t in tris {
        for &v in t {
            points.push(to_world(g, &mesh.vertices[v as usize]));
        }
    }
    Marker {
        header,
        ns: ns.to_owned(),
        id,
        r#type: Marker::TRIANGLE_LIST,
        action: if points.is_empty() {
            Marker::DELETE
        } else {
            Marker::ADD
        },
        scale: Vector3::new(1.0, 1.0, 1.0),
        color,
        points,
        ..Marker::default()
    }
}

/// A TRIANGLE_LIST marker of `mesh` (lattice units of `g`), one colour per triangle.
pub fn triangle_list(
    header: Header,
    ns: &str,
    id: i32,
    g: &GridGeometry,
    mesh: &TriMesh,
    color_of: impl Fn(usize) -> ColorRGBA,
) -> Marker {
    let mut points = Vec::with_capacity(mesh.triangles.len() * 3);
    let mut colors = Vec::with_capacity(mesh.triangles.len() * 3);
    for (i, t) in mesh.triangles.iter().enumerate() {
        let c = color_of(i);
        for &v in t {
            points.push(to_world(g, &mesh.vertices[v as usize]));
            colors.push(c);
        }
    }
    Marker {
        header,
        ns: ns.to_owned(),
        id,
        r#type: Marker::TRIANGLE_LIST,
        action: if points.is_empty() {
            Marker::DELETE
        } else {
            Marker::ADD
        },
        scale: Vector3::new(1.0, 1.0, 1.0),
        color: ColorRGBA::new(1.0, 1.0, 1.0, 1.0),
        points,
        colors,
        ..Marker::default()
    }
}
