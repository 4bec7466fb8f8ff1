//! The sampler's limits hold for the whole run: total steps are bounded by name before any
//! step is taken, samples collected in memory are bounded, the CLI streams its output, and
//! bad shapes and walls are named with the field and its value.

use chronotope::bag::BagReader;
use chronotope::cli::sample::{run, SampleArgs, POINTS_TOPIC};
use chronotope::node::Payload;
use chronotope::sampler::scene_file::SceneFile;
use chronotope::sampler::{
    sample, Body, Figure, SamplerError, SamplerOptions, Shape, Wall, MAX_COLLECTED_SAMPLES,
    MAX_SAMPLES, MAX_TOTAL_STEPS,
};
use std::sync::Arc;

fn torus() -> Figure {
    let t = Body::fixed(Shape::Torus {
        centre: [0.0; 3],
        axis: Default::default(),
        major: 1.0,
        minor: 0.4,
    });
    Figure::new(3, vec![Arc::new(t)])
        .unwrap()
        .wall(Wall::Box {
            min: [-2.0; 4],
            max: [2.0; 4],
        })
        .unwrap()
}

#[test]
fn total_steps_are_limited_by_name_before_any_step() {
    let fig = torus();
    // With the thinning to be chosen in burn-in, the least it can be (1) is counted.
    for (o, total) in [
        // --burn-in 2e6 with the default 16 walkers.
        (
            SamplerOptions::default().burn_in(2_000_000),
            16 * 2_000_000u128 + 10_000,
        ),
        // --thin 1e6 with the default 10 000 samples.
        (
            SamplerOptions::default().thin(1_000_000),
            16 * 1000 + 10_000 * 1_000_000u128,
        ),
        // --samples 3e7 (the maximum) with the default burn-in.
        (
            SamplerOptions::default().samples(MAX_SAMPLES),
            16 * 1000 + MAX_SAMPLES as u128,
        ),
        // --samples 1e7 at thin 5.
        (
            SamplerOptions::default().samples(10_000_000).thin(5),
            16 * 1000 + 5 * 10_000_000u128,
        ),
    ] {
        let t = std::time::Instant::now();
        let e = o.validate().unwrap_err();
        match &e {
            SamplerError::TooManySteps {
                total: got, max, ..
            } => {
                assert_eq!(*got, total);
                assert_eq!(*max, MAX_TOTAL_STEPS);
            }
            other => panic!("{other}"),
        }
        let text = e.to_string();
        assert!(
            text.contains("MAX_TOTAL_STEPS") && text.contains("burn_in"),
            "{text}"
        );
        // The sampler refuses it before putting a walker down.
        assert!(chronotope::sampler::Sampler::new(&fig, &o).is_err());
        assert!(t.elapsed().as_millis() < 100);
    }
    // The maximum of samples runs at a given step, thin 1, without burn-in.
    SamplerOptions::default()
        .samples(MAX_SAMPLES)
        .dt(1e-3)
        .thin(1)
        .burn_in(0)
        .validate()
        .unwrap();
}

#[test]
fn a_chosen_thinning_stays_within_the_step_budget() {
    // 1e7 samples leave 2 steps per sample after burn-in: the thinning chosen is capped
    // there (and said), however slowly the walk mixes. Checked on the options' arithmetic
    // only: the run itself would take half a minute.
    let o = SamplerOptions::default().samples(10_000_000);
    o.validate().unwrap();
    // A slow walk (tiny fixed step) on a small run: the pilot extends, then the thinning is
    // capped at MAX_AUTO_THIN and the shortfall reported.
    let fig = torus();
    let s = chronotope::sampler::Sampler::new(
        &fig,
        &SamplerOptions::default().dt(1e-7).samples(100).walkers(4),
    )
    .unwrap();
    let a = s.adaptation();
    assert!(a.thin_chosen && a.thin_capped, "{a:?}");
    assert_eq!(a.thin, chronotope::sampler::MAX_AUTO_THIN);
    assert!(a.thin_wanted > a.thin);
    assert!(a.pilot_steps <= chronotope::sampler::MAX_PILOT_STEPS);
    assert!(s.stats().steps <= MAX_TOTAL_STEPS);
    // With more samples the automatic choice's own step budget caps it first (the burn-in
    // alone is run here: no sample is drawn).
    let s = chronotope::sampler::Sampler::new(
        &fig,
        &SamplerOptions::default()
            .dt(1e-7)
            .samples(20_000)
            .walkers(4),
    )
    .unwrap();
    let budget = chronotope::sampler::AUTO_THIN_STEPS as usize / 20_000;
    assert_eq!(s.adaptation().thin, budget);
    assert!(s.adaptation().thin_capped);
}

#[test]
fn samples_collected_in_memory_are_limited() {
    let fig = torus();
    let o = SamplerOptions::default()
        .samples(MAX_COLLECTED_SAMPLES + 1)
        .thin(1);
    o.validate().unwrap();
    let t = std::time::Instant::now();
    let e = sample(&fig, &o).unwrap_err().to_string();
    assert!(e.contains("MAX_COLLECTED_SAMPLES"), "{e}");
    assert!(t.elapsed().as_millis() < 100, "refused before drawing");
}

#[test]
fn the_cli_streams_the_same_samples_to_the_bag_and_the_ply() {
    let dir = tempfile::tempdir().unwrap();
    let scene = std::path::PathBuf::from("scenes/implicit/torus.yaml");
    let out = dir.path().join("s.mcap");
    let ply = dir.path().join("s.ply");
    let n = 3000;
    run(&SampleArgs {
        overwrite: false,
        scene: scene.clone(),
        out: out.clone(),
        ply: Some(ply.clone()),
        scheme: None,
        samples: Some(n),
        seed: 7,
        dt: None,
        walkers: None,
        burn_in: None,
        thin: None,
        lambda: None,
        clamp: false,
        project: false,
        target_acceptance: None,
        summary: Some(dir.path().join("q.json")),
    })
    .unwrap();
    assert!(dir.path().join("q.json").exists());
    // The reference: the same options, collected in memory.
    let s = SceneFile::read(&scene).unwrap().build().unwrap();
    let want = sample(&s.figure, &s.options.clone().seed(7).samples(n)).unwrap();
    let want_bytes: Vec<u8> = want
        .points
        .iter()
        .flat_map(|q| q[..3].iter().flat_map(|c| (*c as f32).to_le_bytes()))
        .collect();
    let mut got = Vec::new();
    for m in BagReader::open(&out).unwrap() {
        let m = m.unwrap();
        assert_eq!(m.topic, POINTS_TOPIC);
        match Payload::decode(&m.schema_name, &m.data).unwrap() {
            Payload::PointCloud2(c) => {
                assert_eq!(c.data.len(), c.width as usize * 12);
                got.extend_from_slice(&c.data);
            }
            _ => panic!("not a cloud"),
        }
    }
    assert_eq!(got.len(), n * 12);
    assert!(got == want_bytes, "the bag holds the samples in order");
    let file = std::fs::read(&ply).unwrap();
    let header = b"end_header\n";
    let at = file
        .windows(header.len())
        .position(|w| w == header)
        .unwrap()
        + header.len();
    assert!(String::from_utf8_lossy(&file[..at]).contains(&format!("element vertex {n}\n")));
    assert!(
        file[at..] == want_bytes[..],
        "the PLY holds the samples in order"
    );
}

#[test]
fn bad_shapes_and_walls_are_named_with_the_field_and_value() {
    let p = Shape::Sphere {
        centre: [1.0, f64::NAN, 2.0],
        radius: 1.0,
    }
    .problem()
    .unwrap();
    assert!(
        p.contains("centre") && p.contains("NaN") && p.contains(" y "),
        "{p}"
    );
    assert!(!p.contains("got 1"), "{p}");
    let p = Shape::Sphere {
        centre: [0.0; 3],
        radius: -2.0,
    }
    .problem()
    .unwrap();
    assert!(p.contains("radius -2 m"), "{p}");
    let p = Shape::Box {
        centre: [0.0; 3],
        half: [1.0, f64::INFINITY, 1.0],
        rounding: None,
    }
    .problem()
    .unwrap();
    assert!(p.contains("half[y] = inf"), "{p}");
    let p = Shape::Capsule {
        a: [0.0; 3],
        b: [0.0, 0.0, f64::NAN],
        radius: 0.1,
    }
    .problem()
    .unwrap();
    assert!(p.contains("capsule: b") && p.contains(" z "), "{p}");
    let p = Body::fixed(Shape::Sphere {
        centre: [0.0; 3],
        radius: 1.0,
    })
    .moving([0.0, f64::NAN, 0.0], 0.0)
    .problem()
    .unwrap();
    assert!(p.contains("velocity") && p.contains("m/s"), "{p}");
    let e = Figure::new(
        3,
        vec![Arc::new(Body::fixed(Shape::Sphere {
            centre: [0.0; 3],
            radius: 1.0,
        }))],
    )
    .unwrap()
    .wall(Wall::Box {
        min: [-1.0, 2.0, -1.0, 0.0],
        max: [1.0, 1.0, 1.0, 0.0],
    })
    .unwrap_err()
    .to_string();
    assert!(e.contains("along y, min 2 m and max 1 m"), "{e}");
    let e = Figure::new(
        3,
        vec![Arc::new(Body::fixed(Shape::Sphere {
            centre: [0.0; 3],
            radius: 1.0,
        }))],
    )
    .unwrap()
    .wall(Wall::Shell {
        centre: [0.0; 3],
        inner: 2.0,
        outer: 1.0,
    })
    .unwrap_err()
    .to_string();
    assert!(e.contains("inner radius 2 m, outer radius 1 m"), "{e}");
}
