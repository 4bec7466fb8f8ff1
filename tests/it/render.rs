//! `chronotope render`: the checker's labelled slices of a replay's output bag drawn to a PNG,
//! with the interfering parts in red.

use std::process::Command;

#[test]
fn a_replay_renders_with_its_interference_in_red() {
    let root = env!("CARGO_MANIFEST_DIR");
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("replay.mcap");
    let st = Command::new(env!("CARGO_BIN_EXE_chronotope"))
        .args([
            "replay",
            &format!("{root}/bags/machine-tool-32-bits.mcap"),
            "--launch",
        ])
        .arg(format!("{root}/launch_configs/machine_tool.yaml"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let png = d.path().join("slice.png");
    let st = Command::new(env!("CARGO_BIN_EXE_chronotope"))
        .arg("render")
        .arg(&out)
        .arg("--out")
        .arg(&png)
        .args(["--size", "300"])
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&png).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (300, 300));
    let px: Vec<&[u8]> = buf[..info.buffer_size()].chunks(3).collect();
    let red = px
        .iter()
        .filter(|p| p[0] > 150 && p[1] < 40 && p[2] < 40)
        .count();
    let background = px.iter().filter(|p| **p == [255u8, 255, 255]).count();
    assert!(red > 20, "{red} red pixels");
    assert!(
        background > 300 * 300 / 10 && background < 300 * 300 * 9 / 10,
        "{background}"
    );
    // A bag without markers is refused by name.
    let st = Command::new(env!("CARGO_BIN_EXE_chronotope"))
        .arg("render")
        .arg(format!("{root}/bags/four-spheres-32-bits.mcap"))
        .arg("--out")
        .arg(d.path().join("none.png"))
        .output()
        .unwrap();
    assert!(!st.status.success());
    assert!(String::from_utf8_lossy(&st.stderr).contains("no TRIANGLE_LIST markers"));
}
