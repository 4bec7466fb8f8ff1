//! URDF builders shared by the tests.

use chronotope_robot::{LoadOptions, Robot};

/// A robot with one link carrying `collisions` (raw `<collision>` XML).
pub fn one_link(collisions: &str) -> String {
    format!(r#"<robot name="r"><link name="base">{collisions}</link></robot>"#)
}

/// A `<collision>` element.
pub fn collision(xyz: [f64; 3], rpy: [f64; 3], geometry: &str) -> String {
    format!(
        r#"<collision><origin xyz="{} {} {}" rpy="{} {} {}"/><geometry>{geometry}</geometry></collision>"#,
        xyz[0], xyz[1], xyz[2], rpy[0], rpy[1], rpy[2]
    )
}

/// Loads a robot from text with no package path and no environment.
pub fn robot(text: &str) -> Robot {
    Robot::from_urdf_str(text, &options()).expect("test robot loads")
}

/// Options that read no environment variable.
pub fn options() -> LoadOptions {
    LoadOptions::new().environment(Box::new(chronotope_robot::mesh::VarsEnvironment::default()))
}

/// A temporary directory removed on drop.
pub struct TempDir(pub std::path::PathBuf);

impl TempDir {
    pub fn new(tag: &str) -> TempDir {
        let dir = std::env::temp_dir().join(format!(
            "chronotope-robot-{tag}-{}-{:?}",
            std::process::id(),
            std::thread::current().id()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
