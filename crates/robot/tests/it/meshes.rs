//! Mesh files (STL binary and ASCII, OBJ, COLLADA), URIs and the package search path,
//! limits, and open meshes.

use super::common::{options, TempDir};
use chronotope_robot::limits::Limits;
use chronotope_robot::mesh::{load_mesh, Closure, MeshError, PackageResolver, VarsEnvironment};
use chronotope_robot::{LoadOptions, Robot, RobotError};
use std::ffi::OsString;
use std::path::{Path, PathBuf};

/// The 12 outward triangles of the cube [0, 1]³.
fn cube() -> Vec<[[f32; 3]; 3]> {
    let v = |i: usize| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32];
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    quads
        .iter()
        .flat_map(|q| [[v(q[0]), v(q[1]), v(q[2])], [v(q[0]), v(q[2]), v(q[3])]])
        .collect()
}

fn binary_stl(tris: &[[[f32; 3]; 3]]) -> Vec<u8> {
    let mut b = vec![0u8; 80];
    b.extend_from_slice(&(tris.len() as u32).to_le_bytes());
    for t in tris {
        b.extend_from_slice(&[0u8; 12]);
        for p in t {
            for c in p {
                b.extend_from_slice(&c.to_le_bytes());
            }
        }
        b.extend_from_slice(&[0, 0]);
    }
    b
}

fn ascii_stl(tris: &[[[f32; 3]; 3]]) -> String {
    let mut s = String::from("solid cube\n");
    for t in tris {
        s.push_str("facet normal 0 0 0\nouter loop\n");
        for p in t {
            s.push_str(&format!("vertex {} {} {}\n", p[0], p[1], p[2]));
        }
        s.push_str("endloop\nendfacet\n");
    }
    s.push_str("endsolid cube\n");
    s
}

fn obj(tris: &[[[f32; 3]; 3]]) -> String {
    let mut s = String::from("mtllib missing.mtl\n");
    for t in tris {
        for p in t {
            s.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
        }
    }
    for i in 0..tris.len() {
        s.push_str(&format!("f {} {} {}\n", 3 * i + 1, 3 * i + 2, 3 * i + 3));
    }
    s
}

/// A COLLADA cube in centimetres (`unit meter="0.01"`), 100 units a side, moved by its
/// node 100 units along x.
fn collada() -> String {
    let tris = cube();
    let mut pos = String::new();
    for t in &tris {
        for p in t {
            pos.push_str(&format!(
                "{} {} {} ",
                p[0] * 100.0,
                p[1] * 100.0,
                p[2] * 100.0
            ));
        }
    }
    let idx: Vec<String> = (0..tris.len() * 3).map(|i| i.to_string()).collect();
    format!(
        r##"<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="centimeter" meter="0.01"/><up_axis>Z_UP</up_axis></asset>
  <library_geometries>
    <geometry id="cube-mesh" name="cube">
      <mesh>
        <source id="cube-pos">
          <float_array id="cube-pos-array" count="{n}">{pos}</float_array>
          <technique_common><accessor source="#cube-pos-array" count="{v}" stride="3">
            <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
          </accessor></technique_common>
        </source>
        <vertices id="cube-vtx"><input semantic="POSITION" source="#cube-pos"/></vertices>
        <triangles count="{t}"><input semantic="VERTEX" source="#cube-vtx" offset="0"/><p>{p}</p></triangles>
      </mesh>
    </geometry>
  </library_geometries>
  <library_visual_scenes>
    <visual_scene id="scene">
      <node id="cube-node"><translate>100 0 0</translate><instance_geometry url="#cube-mesh"/></node>
    </visual_scene>
  </library_visual_scenes>
  <scene><instance_visual_scene url="#scene"/></scene>
</COLLADA>"##,
        n = tris.len() * 9,
        v = tris.len() * 3,
        t = tris.len(),
        p = idx.join(" ")
    )
}

fn bounds(vs: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for v in vs {
        for a in 0..3 {
            lo[a] = lo[a].min(v[a]);
            hi[a] = hi[a].max(v[a]);
        }
    }
    (lo, hi)
}

#[test]
fn every_format_loads_closed_and_scaled() {
    let dir = TempDir::new("formats");
    std::fs::write(dir.0.join("b.stl"), binary_stl(&cube())).unwrap();
    std::fs::write(dir.0.join("a.stl"), ascii_stl(&cube())).unwrap();
    std::fs::write(dir.0.join("c.obj"), obj(&cube())).unwrap();
    std::fs::write(dir.0.join("d.dae"), collada()).unwrap();
    for name in ["b.stl", "a.stl", "c.obj"] {
        let m = load_mesh(&dir.0.join(name), [1.0, 2.0, 3.0], &Limits::default()).unwrap();
        assert_eq!(m.closure, Closure::Oriented, "{name}");
        assert_eq!(
            (m.vertices.len(), m.triangles.len()),
            (8, 12),
            "{name}: welded"
        );
        assert_eq!(bounds(&m.vertices), ([0.0; 3], [1.0, 2.0, 3.0]), "{name}");
    }
    // COLLADA: unit and node transform as the loader applies them. mesh-loader 0.1
    // scales the geometry by the unit but applies the node's translation unscaled (100 m
    // here, where the COLLADA specification would give 1 m); this test notices if that
    // changes.
    let m = load_mesh(&dir.0.join("d.dae"), [1.0; 3], &Limits::default()).unwrap();
    assert_eq!(m.closure, Closure::Oriented);
    let (lo, hi) = bounds(&m.vertices);
    for (got, want) in lo.iter().chain(&hi).zip([100.0, 0.0, 0.0, 101.0, 1.0, 1.0]) {
        assert!((got - want).abs() < 1e-6, "{lo:?} {hi:?}");
    }
}

#[test]
fn an_open_mesh_is_classified_and_reported() {
    let dir = TempDir::new("open");
    let mut tris = cube();
    tris.truncate(10); // the +x face is missing
    std::fs::write(dir.0.join("open.stl"), binary_stl(&tris)).unwrap();
    let text = super::common::one_link(
        r#"<collision><geometry><mesh filename="open.stl"/></geometry></collision>"#,
    );
    let robot = Robot::from_urdf_str(&text, &options().base_dir(&dir.0)).unwrap();
    let open: Vec<_> = robot.load_report().open_meshes().collect();
    assert_eq!(open.len(), 1);
    assert_eq!(open[0].boundary_edges, 4);
    // A reversed triangle is turned back; a cube given inside out is turned outwards.
    let mut tris = cube();
    tris[0].swap(1, 2);
    std::fs::write(dir.0.join("flip.stl"), binary_stl(&tris)).unwrap();
    let m = load_mesh(&dir.0.join("flip.stl"), [1.0; 3], &Limits::default()).unwrap();
    assert_eq!((m.closure, m.flipped_triangles), (Closure::Oriented, 1));
    let inside_out: Vec<_> = cube()
        .into_iter()
        .map(|mut t| {
            t.swap(1, 2);
            t
        })
        .collect();
    std::fs::write(dir.0.join("inv.stl"), binary_stl(&inside_out)).unwrap();
    let m = load_mesh(&dir.0.join("inv.stl"), [1.0; 3], &Limits::default()).unwrap();
    assert_eq!((m.closure, m.flipped_triangles), (Closure::Oriented, 12));
    // Two cubes sharing an edge (non-manifold, even): closed; each is oriented.
    let mut two = cube();
    two.extend(
        cube()
            .into_iter()
            .map(|t| t.map(|p| [p[0] + 1.0, p[1] + 1.0, p[2]])),
    );
    std::fs::write(dir.0.join("two.stl"), binary_stl(&two)).unwrap();
    let m = load_mesh(&dir.0.join("two.stl"), [1.0; 3], &Limits::default()).unwrap();
    assert_eq!(m.closure, Closure::Oriented);
}

fn env(vars: &[(&str, &Path)]) -> VarsEnvironment {
    VarsEnvironment(
        vars.iter()
            .map(|(k, v)| (k.to_string(), OsString::from(v.as_os_str())))
            .collect(),
    )
}

fn make_file(path: &Path) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, binary_stl(&cube())).unwrap();
}

#[test]
fn package_uris_follow_the_documented_search_path() {
    let dir = TempDir::new("packages");
    let d = &dir.0;
    // 1a. a package_path entry that is the package itself (named by its package.xml).
    make_file(&d.join("explicit/pkg_src/meshes/a.stl"));
    std::fs::write(
        d.join("explicit/pkg_src/package.xml"),
        "<package><name>pkg_a</name></package>",
    )
    .unwrap();
    // 1b. a package_path entry whose child is the package.
    make_file(&d.join("parent/pkg_b/meshes/b.stl"));
    // 2. AMENT_PREFIX_PATH.
    make_file(&d.join("install/share/pkg_c/meshes/c.stl"));
    // 3. ROS_PACKAGE_PATH, a few levels down, directory name unlike the package's.
    make_file(&d.join("ws/src/group/some_dir/meshes/d.stl"));
    std::fs::write(
        d.join("ws/src/group/some_dir/package.xml"),
        "<package format=\"3\">\n <name> pkg_d </name></package>",
    )
    .unwrap();
    let e = env(&[
        ("AMENT_PREFIX_PATH", &d.join("install")),
        ("ROS_PACKAGE_PATH", &d.join("ws")),
    ]);
    let mut r = PackageResolver::new(vec![d.join("explicit/pkg_src"), d.join("parent")], &e);
    let ok = |r: &mut PackageResolver, uri: &str, want: PathBuf| {
        assert_eq!(r.resolve(uri, None).unwrap(), want, "{uri}")
    };
    ok(
        &mut r,
        "package://pkg_a/meshes/a.stl",
        d.join("explicit/pkg_src/meshes/a.stl"),
    );
    ok(
        &mut r,
        "package://pkg_b/meshes/b.stl",
        d.join("parent/pkg_b/meshes/b.stl"),
    );
    ok(
        &mut r,
        "package://pkg_c/meshes/c.stl",
        d.join("install/share/pkg_c/meshes/c.stl"),
    );
    ok(
        &mut r,
        "package://pkg_d/meshes/d.stl",
        d.join("ws/src/group/some_dir/meshes/d.stl"),
    );
    // Not found: the error names the URI and every path tried, in order.
    let e = r.resolve("package://pkg_x/m.stl", None).unwrap_err();
    let text = e.to_string();
    assert!(
        matches!(e, MeshError::NotFound { ref tried, .. } if tried.len() == 4),
        "{e:?}"
    );
    for part in [
        "package://pkg_x/m.stl",
        "parent/pkg_x/m.stl",
        "install/share/pkg_x/m.stl",
        "ws",
    ] {
        assert!(text.contains(part), "{part} missing in {text}");
    }
}

#[test]
fn file_uris_and_relative_paths_resolve() {
    let dir = TempDir::new("paths");
    make_file(&dir.0.join("sub/m.stl"));
    let mut r = PackageResolver::new(vec![], &VarsEnvironment::default());
    let abs = dir.0.join("sub/m.stl");
    assert_eq!(
        r.resolve(&format!("file://{}", abs.display()), None)
            .unwrap(),
        abs
    );
    assert_eq!(
        r.resolve("sub/m.stl", Some(&dir.0)).unwrap(),
        dir.0.join("sub/m.stl")
    );
    let e = r.resolve("sub/m.stl", None).unwrap_err();
    assert!(matches!(e, MeshError::RelativeWithoutBase { .. }), "{e:?}");
    let e = r.resolve("https://example.com/m.stl", None).unwrap_err();
    assert!(matches!(e, MeshError::UnsupportedUri { .. }), "{e:?}");
    let e = r.resolve("package://nopath", None).unwrap_err();
    assert!(matches!(e, MeshError::MalformedUri { .. }), "{e:?}");
    let e = r.resolve("sub/missing.stl", Some(&dir.0)).unwrap_err();
    assert!(e.to_string().contains("missing.stl"), "{e}");
}

#[test]
fn mesh_limits_refuse_by_name_and_value() {
    let dir = TempDir::new("limits");
    let path = dir.0.join("m.stl");
    std::fs::write(&path, binary_stl(&cube())).unwrap();
    let small = |l: Limits| load_mesh(&path, [1.0; 3], &l).unwrap_err().to_string();
    let t = small(Limits {
        mesh_file_bytes: 100,
        ..Limits::default()
    });
    assert!(
        t.contains("MAX_MESH_FILE_BYTES = 100") && t.contains("m.stl"),
        "{t}"
    );
    let t = small(Limits {
        mesh_triangles: 11,
        ..Limits::default()
    });
    assert!(
        t.contains("12 triangles") && t.contains("MAX_MESH_TRIANGLES = 11"),
        "{t}"
    );
    // The robot's total counts each distinct (file, scale) once.
    let text = super::common::one_link(
        r#"<collision><geometry><mesh filename="m.stl"/></geometry></collision>
           <collision><geometry><mesh filename="m.stl"/></geometry></collision>
           <collision><geometry><mesh filename="m.stl" scale="2 2 2"/></geometry></collision>"#,
    );
    let opts = |n| {
        options().base_dir(&dir.0).limits(Limits {
            robot_triangles: n,
            ..Limits::default()
        })
    };
    assert_eq!(
        Robot::from_urdf_str(&text, &opts(24))
            .unwrap()
            .load_report()
            .triangles,
        24
    );
    let e = Robot::from_urdf_str(&text, &opts(23)).unwrap_err();
    assert!(
        matches!(e, RobotError::Mesh { ref link, .. } if link == "base"),
        "{e:?}"
    );
    assert!(e.to_string().contains("MAX_ROBOT_TRIANGLES = 23"), "{e}");
}

#[test]
fn a_missing_mesh_names_its_link() {
    let text = super::common::one_link(
        r#"<collision><geometry><mesh filename="package://nope/m.stl"/></geometry></collision>"#,
    );
    let e = Robot::from_urdf_str(
        &text,
        &LoadOptions::new().environment(Box::new(VarsEnvironment::default())),
    )
    .unwrap_err();
    let t = e.to_string();
    assert!(
        t.contains("link `base`") && t.contains("package://nope/m.stl"),
        "{t}"
    );
}

#[test]
fn garbage_files_are_refused_as_unparsable() {
    let dir = TempDir::new("garbage");
    std::fs::write(dir.0.join("g.stl"), b"solid x\nfacet nonsense\n").unwrap();
    let e = load_mesh(&dir.0.join("g.stl"), [1.0; 3], &Limits::default()).unwrap_err();
    assert!(
        matches!(e, MeshError::Parse { .. } | MeshError::Invalid { .. }),
        "{e:?}"
    );
}
