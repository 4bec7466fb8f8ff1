//! The stochastic sampler: uniformity on figures with exact answers, the stiff and extreme
//! cases, the adaptation of the default settings and the quality they report, and the
//! command. (The cross-check of the checker by the sampler is in tests/it/sampler_checker.rs.)

use chronotope::sampler::exact::{ks_statistic, sphere_coordinate_cdf, sphere_x_cdf, TorusTheta};
use chronotope::sampler::quality::ess;
use chronotope::sampler::{
    sample, surface_points, Body, Field, Figure, LambdaPolicy, SamplerError, SamplerOptions,
    Scheme, Shape, ShapeAxis, Wall, Q,
};
use std::sync::Arc;

/// The figure of `fields` in R^3 inside the box [−e, e]^4.
fn boxed(fields: Vec<Arc<dyn Field>>, e: f64) -> Figure {
    Figure::new(3, fields)
        .unwrap()
        .wall(Wall::Box {
            min: [-e; 4],
            max: [e; 4],
        })
        .unwrap()
}

fn torus(major: f64, minor: f64) -> Arc<dyn Field> {
    Arc::new(Body::fixed(Shape::Torus {
        centre: [0.0; 3],
        axis: ShapeAxis::Z,
        major,
        minor,
    }))
}

fn sphere(centre: [f64; 3], radius: f64) -> Body {
    Body::fixed(Shape::Sphere { centre, radius })
}

/// The largest distance (m) of a point from the unit sphere about the origin.
fn off_unit_sphere(points: &[Q]) -> f64 {
    points
        .iter()
        .map(|q| ((q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt() - 1.0).abs())
        .fold(0.0, f64::max)
}

fn all_finite(p: &[Q]) -> bool {
    p.iter().flatten().all(|x| x.is_finite())
}

fn torus_ks(points: &[Q], major: f64, minor: f64) -> f64 {
    let t = TorusTheta { major, minor };
    let mut th: Vec<f64> = points.iter().map(|q| t.theta(q)).collect();
    ks_statistic(&mut th, |x| t.cdf(x))
}

#[test]
fn every_scheme_is_uniform_on_the_torus_and_metropolis_is_exactly_so() {
    let fig = boxed(vec![torus(1.0, 0.4)], 2.0);
    // KS of 40 000 correlated samples from 32 walkers is 0.01-0.03 (mixing); a sampler that
    // ignores the curvature (uniform in θ) scores r/(2πR) = 0.064 whatever the run length.
    for scheme in Scheme::ALL {
        // The old defaults (dt 1e-3, thin 5): what these fixed-step checks were written for.
        let o = SamplerOptions::default()
            .scheme(scheme)
            .dt(1e-3)
            .thin(5)
            .samples(40_000)
            .walkers(32)
            .seed(3);
        let s = sample(&fig, &o).unwrap();
        assert!(all_finite(&s.points));
        let ks = torus_ks(&s.points, 1.0, 0.4);
        assert!(ks < 0.04, "{scheme:?}: KS {ks}");
        if scheme != Scheme::Explicit {
            assert!(
                s.stats.max_residual < 1e-9,
                "{scheme:?}: {}",
                s.stats.max_residual
            );
        }
    }
    // Uniform in θ would fail the same test: the test can fail.
    let fake: Vec<Q> = (0..20_000)
        .map(|i| {
            let th =
                -std::f64::consts::PI + 2.0 * std::f64::consts::PI * (i as f64 + 0.5) / 20_000.0;
            [1.0 + 0.4 * th.cos(), 0.0, 0.4 * th.sin(), 0.0]
        })
        .collect();
    assert!(torus_ks(&fake, 1.0, 0.4) > 0.06); // r/(2πR) = 0.064
}

#[test]
fn samples_are_deterministic_for_a_seed() {
    let fig = boxed(vec![torus(1.0, 0.4)], 2.0);
    let o = SamplerOptions::default().samples(300).seed(9);
    let a = sample(&fig, &o).unwrap().points;
    let b = sample(&fig, &o).unwrap().points;
    let c = sample(&fig, &o.clone().seed(10)).unwrap().points;
    assert_eq!(a, b);
    assert_ne!(a, c);
}

/// `(|q|² - 1) e^{k x}`: the unit sphere, not a distance.
#[derive(Debug)]
struct ExpSphere(f64);

impl Field for ExpSphere {
    fn eval(&self, q: &Q) -> (f64, Q) {
        let r2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
        let e = (self.0 * q[0]).exp();
        let f = (r2 - 1.0) * e;
        (
            f,
            [
                2.0 * q[0] * e + self.0 * f,
                2.0 * q[1] * e,
                2.0 * q[2] * e,
                0.0,
            ],
        )
    }
}

fn x_ks(points: &[Q]) -> f64 {
    let mut x: Vec<f64> = points.iter().map(|q| q[0]).collect();
    ks_statistic(&mut x, sphere_x_cdf)
}

#[test]
fn gradient_varying_a_thousandfold_changes_nothing() {
    // k = ln(1000)/2: |∇F| = 2e^{kx} runs from 2/31.6 to 2·31.6 over the sphere.
    let k = 1000f64.ln() / 2.0;
    let fig = boxed(vec![Arc::new(ExpSphere(k))], 2.0);
    let (lo, hi) = (
        ExpSphere(k).eval(&[-1.0, 0.0, 0.0, 0.0]).1[0].abs(),
        ExpSphere(k).eval(&[1.0, 0.0, 0.0, 0.0]).1[0],
    );
    assert!(hi / lo > 999.0, "{}", hi / lo);
    for scheme in Scheme::ALL {
        let o = SamplerOptions::default()
            .scheme(scheme)
            .dt(1e-3)
            .thin(5)
            .samples(40_000)
            .walkers(32)
            .seed(5);
        let s = sample(&fig, &o).unwrap();
        assert!(all_finite(&s.points), "{scheme:?}");
        let ks = x_ks(&s.points);
        assert!(ks < 0.04, "{scheme:?}: KS of x {ks}");
        // Distance to the sphere, not |F|: the test is in metres whatever |∇F| is.
        let worst = off_unit_sphere(&s.points);
        let bound = if scheme == Scheme::Explicit {
            0.05
        } else {
            1e-9
        };
        assert!(worst < bound, "{scheme:?}: {worst}");
    }
}

#[test]
fn explicit_lambda_near_two_is_stable_above_two_refused_or_clamped() {
    let fig = boxed(vec![torus(1.0, 0.4)], 2.0);
    let base = SamplerOptions::default()
        .scheme(Scheme::Explicit)
        .dt(1e-3)
        .thin(5)
        .samples(2000)
        .burn_in(200)
        .seed(1);
    for lambda in [1.9, 1.99] {
        let s = sample(&fig, &base.clone().lambda(lambda)).unwrap();
        assert!(all_finite(&s.points), "λ {lambda}");
        assert_eq!(s.stats.clamped_lambda, None);
        // F ← (1-λ)F oscillates but decays: the walkers stay within a few step lengths.
        assert!(
            s.stats.max_residual < 0.3,
            "λ {lambda}: {}",
            s.stats.max_residual
        );
    }
    match sample(&fig, &base.clone().lambda(2.01)) {
        Err(SamplerError::Unstable { lambda }) => assert!((lambda - 2.01).abs() < 1e-12),
        other => panic!("λ 2.01 not refused: {:?}", other.map(|s| s.stats)),
    }
    // K given directly is checked the same way.
    assert!(matches!(
        sample(&fig, &base.clone().k(2010.0)),
        Err(SamplerError::Unstable { .. })
    ));
    let s = sample(
        &fig,
        &base.clone().lambda(2.01).on_unstable(LambdaPolicy::Clamp),
    )
    .unwrap();
    assert_eq!(s.stats.clamped_lambda, Some(2.01));
    assert!(all_finite(&s.points));
    assert!(s.stats.max_residual < 0.1);
    // The other schemes have no λ.
    assert!(sample(&fig, &base.clone().lambda(2.01).scheme(Scheme::Metropolis)).is_ok());
}

#[test]
fn bad_options_are_refused_with_their_name() {
    let fig = boxed(vec![torus(1.0, 0.4)], 2.0);
    for (o, name) in [
        (SamplerOptions::default().dt(f64::NAN), "dt"),
        (SamplerOptions::default().dt(-1.0), "dt"),
        (SamplerOptions::default().walkers(0), "walkers"),
        (SamplerOptions::default().thin(0), "thin"),
        (SamplerOptions::default().tol(0.0), "tol"),
        (SamplerOptions::default().samples(usize::MAX), "samples"),
        (SamplerOptions::default().samples(0), "samples"),
        // The step and thinning are tuned in burn-in: too short a burn-in is refused...
        (SamplerOptions::default().burn_in(10), "burn_in"),
        (
            SamplerOptions::default().target_acceptance(1.0),
            "target_acceptance",
        ),
        (
            SamplerOptions::default().target_acceptance(f64::NAN),
            "target_acceptance",
        ),
    ] {
        match sample(&fig, &o) {
            Err(SamplerError::BadParameter { name: n, .. }) => assert_eq!(n, name),
            other => panic!("{name}: {:?}", other.map(|s| s.stats)),
        }
    }
    // ... but not when nothing is tuned.
    assert!(sample(
        &fig,
        &SamplerOptions::default()
            .dt(1e-3)
            .thin(1)
            .burn_in(0)
            .samples(10)
    )
    .is_ok());
    let e = SamplerOptions::default().samples(0).validate().unwrap_err();
    assert!(e.to_string().contains("samples = 0"), "{e}");
    assert!(matches!(
        Figure::new(3, vec![torus(1.0, 0.4); 3]),
        Err(SamplerError::BadFigure(_))
    ));
    assert!(matches!(
        Figure::new(5, vec![torus(1.0, 0.4)]),
        Err(SamplerError::BadFigure(_))
    ));
}

#[test]
fn cone_apex_where_the_gradient_vanishes() {
    // x² + y² = (z tan a)² between z = ±1: area density of |z| ∝ |z|, so P(|z| ≤ s) = s².
    let cone: Arc<dyn Field> = Arc::new(Body::fixed(Shape::Cone {
        apex: [0.0; 3],
        axis: ShapeAxis::Z,
        half_angle: 0.5,
    }));
    let fig = Figure::new(3, vec![cone])
        .unwrap()
        .wall(Wall::Box {
            min: [-2.0, -2.0, -1.0, 0.0],
            max: [2.0, 2.0, 1.0, 0.0],
        })
        .unwrap();
    for scheme in Scheme::ALL {
        // Every walker starts exactly at the apex, where ∇F = 0 and D is singular.
        let o = SamplerOptions::default()
            .scheme(scheme)
            .dt(1e-3)
            .thin(5)
            .burn_in(2000)
            .samples(8000)
            .walkers(32)
            .starts(vec![[0.0; 4]])
            .seed(2);
        let s = sample(&fig, &o).unwrap();
        assert!(all_finite(&s.points), "{scheme:?}");
        let mut az: Vec<f64> = s.points.iter().map(|q| q[2].abs()).collect();
        let ks = ks_statistic(&mut az, |z| (z * z).clamp(0.0, 1.0));
        let upper = s.points.iter().filter(|q| q[2] > 0.0).count() as f64 / s.points.len() as f64;
        eprintln!(
            "cone {scheme:?}: KS of |z| {ks:.4}, upper nappe {upper:.2}, singular steps {}",
            s.stats.singular
        );
        assert!(ks < 0.08, "{scheme:?}: KS {ks}");
        // Both nappes are reached (they meet only at the apex; walkers restart elsewhere).
        assert!(
            upper > 0.1 && upper < 0.9,
            "{scheme:?}: upper fraction {upper}"
        );
    }
}

#[test]
fn nearly_tangent_spheres_give_a_small_circle_and_exact_tangency_is_refused() {
    // Two unit spheres 2 - ε apart meet in a circle of radius ~sqrt(ε): det D ~ ε.
    let eps = 1e-3;
    let a = sphere([0.0; 3], 1.0);
    let b = sphere([2.0 - eps, 0.0, 0.0], 1.0);
    let fig = Figure::new(3, vec![Arc::new(a), Arc::new(b)])
        .unwrap()
        .wall(Wall::Box {
            min: [0.5, -0.5, -0.5, 0.0],
            max: [1.5, 0.5, 0.5, 0.0],
        })
        .unwrap();
    let x0 = (2.0 - eps) / 2.0;
    let rho = (1.0 - x0 * x0).sqrt();
    for scheme in [Scheme::Projected, Scheme::Metropolis, Scheme::Explicit] {
        let o = SamplerOptions::default()
            .scheme(scheme)
            .dt(1e-4)
            .samples(4000)
            .walkers(16)
            .thin(10)
            .seed(4);
        let s = sample(&fig, &o).unwrap();
        assert!(all_finite(&s.points), "{scheme:?}");
        // On the circle (explicit: near it) and uniform in its angle.
        // The explicit scheme's D^{-1} amplifies the curvature drift as det D → 0: its
        // samples stray up to about the circle's radius from it.
        let tol = if scheme == Scheme::Explicit {
            1.0 * rho
        } else {
            1e-6
        };
        let mut phi = Vec::new();
        for q in &s.points {
            let r = (q[1] * q[1] + q[2] * q[2]).sqrt();
            assert!(
                (q[0] - x0).abs() < tol && (r - rho).abs() < tol,
                "{scheme:?}: {q:?}"
            );
            phi.push(q[2].atan2(q[1]));
        }
        let ks = ks_statistic(&mut phi, |p| {
            (p + std::f64::consts::PI) / (2.0 * std::f64::consts::PI)
        });
        assert!(ks < 0.1, "{scheme:?}: KS of the angle {ks}");
    }
    // Exactly tangent: the figure is the single point (1, 0, 0), where D is singular. Either
    // no walker gets on (refused) or every sample sits at that point; never NaN.
    let b = sphere([2.0, 0.0, 0.0], 1.0);
    let fig = boxed(vec![Arc::new(a), Arc::new(b)], 3.0);
    match sample(&fig, &SamplerOptions::default().samples(10).walkers(2)) {
        Err(SamplerError::NoStart { .. }) => {}
        Ok(s) => assert!(
            s.points
                .iter()
                .all(|q| ((q[0] - 1.0).powi(2) + q[1] * q[1] + q[2] * q[2]).sqrt() < 1e-4),
            "{:?}",
            s.points
        ),
        Err(e) => panic!("{e}"),
    }
}

#[test]
fn thin_torus() {
    let (major, minor) = (1.0, 0.01);
    let fig = boxed(vec![torus(major, minor)], 2.0);
    for scheme in Scheme::ALL {
        // Steps must be small against the tube: dt = 1e-6 gives ~0.002.
        let o = SamplerOptions::default()
            .scheme(scheme)
            .dt(1e-6)
            .samples(10_000)
            .walkers(32)
            .seed(8)
            .thin(20);
        let s = sample(&fig, &o).unwrap();
        assert!(all_finite(&s.points), "{scheme:?}");
        let ks = torus_ks(&s.points, major, minor);
        eprintln!(
            "thin torus {scheme:?}: KS {ks:.4}, max residual {:.2e}",
            s.stats.max_residual
        );
        assert!(ks < 0.06, "{scheme:?}: KS {ks}");
        assert!(s.stats.max_residual < 0.2 * minor, "{scheme:?}");
    }
}

/// The union of two spheres as one function (min of distances): two components.
#[derive(Debug)]
struct TwoSpheres(Body, Body);

impl Field for TwoSpheres {
    fn eval(&self, q: &Q) -> (f64, Q) {
        let (a, b) = (self.0.eval(q), self.1.eval(q));
        if a.0 <= b.0 {
            a
        } else {
            b
        }
    }
}

#[test]
fn disconnected_components_small_steps_stay_large_steps_jump() {
    let f = TwoSpheres(sphere([-1.0, 0.0, 0.0], 0.6), sphere([1.2, 0.0, 0.0], 0.3));
    let fig = boxed(vec![Arc::new(f)], 2.0);
    let on_figure = |q: &Q| {
        let on_a = ((q[0] + 1.0).powi(2) + q[1] * q[1] + q[2] * q[2]).sqrt() - 0.6;
        let on_b = ((q[0] - 1.2).powi(2) + q[1] * q[1] + q[2] * q[2]).sqrt() - 0.3;
        on_a.abs() < 1e-9 || on_b.abs() < 1e-9
    };
    let left = |p: &[Q]| p.iter().filter(|q| q[0] < 0.0).count() as f64 / p.len() as f64;
    // Small fixed steps (0.045 m) never cross the 1.3 m gap: each walker stays on the
    // sphere it was put on, so the spheres are weighted by the walkers that landed there,
    // not by area, and the run says so (R-hat of x).
    let small = sample(
        &fig,
        &SamplerOptions::default()
            .dt(1e-3)
            .thin(5)
            .samples(6400)
            .walkers(64)
            .seed(6),
    )
    .unwrap();
    assert!(small.points.iter().all(on_figure));
    let rhat = small.quality.rhat[0].unwrap();
    eprintln!(
        "two spheres, small steps: fraction on the larger {:.3} (by area 0.8), R-hat of x {rhat:.2}",
        left(&small.points)
    );
    assert!(rhat > chronotope::sampler::quality::RHAT_WARNING, "{rhat}");
    assert!(small.quality.describe().contains("walkers disagree on x"));
    assert!(left(&small.points) > 0.05 && left(&small.points) < 0.95);
    // The tuned steps are as large as the spheres: a proposal projected onto the other
    // sphere and passing the reverse check is a reversible jump, so the walkers cross and
    // the spheres are weighted by area (0.36 : 0.09).
    let tuned = sample(
        &fig,
        &SamplerOptions::default().samples(3200).walkers(32).seed(6),
    )
    .unwrap();
    assert!(tuned.points.iter().all(on_figure));
    let rhat = tuned.quality.rhat[0].unwrap();
    eprintln!(
        "two spheres, tuned steps: fraction on the larger {:.3} (by area 0.8), R-hat of x {rhat:.3}",
        left(&tuned.points)
    );
    assert!(
        (left(&tuned.points) - 0.8).abs() < 0.05,
        "{}",
        left(&tuned.points)
    );
    assert!(rhat < chronotope::sampler::quality::RHAT_WARNING, "{rhat}");
    eprintln!("  thin {}", tuned.quality.adaptation.thin);
}

#[test]
fn walkers_started_far_away_reach_the_figure() {
    let far = vec![[300.0, -200.0, 100.0, 0.0], [-400.0, 0.0, 0.0, 0.0]];
    for field in [
        Arc::new(sphere([0.0; 3], 1.0)) as Arc<dyn Field>,
        Arc::new(ExpSphere(0.0)),
    ] {
        let fig = boxed(vec![field], 500.0);
        for scheme in Scheme::ALL {
            let o = SamplerOptions::default()
                .scheme(scheme)
                .samples(8000)
                .walkers(16)
                .starts(far.clone())
                .seed(7)
                .dt(1e-2)
                .thin(10);
            // All walkers start from two points: a long burn-in (steps of 0.14 on a unit
            // sphere) lets them spread; KS noise at this effective size is ~0.03.
            let o = o.burn_in(2000);
            let s = sample(&fig, &o).unwrap();
            assert!(all_finite(&s.points));
            let worst = off_unit_sphere(&s.points);
            // The explicit scheme's samples are off the sphere by O(step) (0.14 here).
            let bound = if scheme == Scheme::Explicit {
                0.3
            } else {
                1e-9
            };
            assert!(worst < bound, "{scheme:?}: {worst}");
            assert!(
                x_ks(&s.points) < 0.06,
                "{scheme:?}: {} {:?}",
                x_ks(&s.points),
                s.stats
            );
        }
    }
    // (|q|² - 1) e^x also tends to 0 as x → -∞: from far away Gauss-Newton follows the
    // exponential down to that zero at infinity instead of the sphere. Refused, not NaN.
    let fig = boxed(vec![Arc::new(ExpSphere(1.0))], 500.0);
    let o = SamplerOptions::default().samples(10).walkers(1).starts(far);
    assert!(matches!(
        sample(&fig, &o),
        Err(SamplerError::NoStart { .. })
    ));
}

#[test]
fn seed_surfaces_with_the_fig1_shell_walls() {
    // Fig. 1: the open saddle between two concentric spheres; the curve where it meets the
    // outer sphere (N = 3, M = 2).
    let saddle = Body::fixed(Shape::SeedSaddle { centre: [0.0; 3] });
    let shell = Wall::Shell {
        centre: [0.0; 3],
        inner: 0.5,
        outer: 1.5,
    };
    let fig = Figure::new(3, vec![Arc::new(saddle)])
        .unwrap()
        .wall(shell)
        .unwrap()
        .seed_box([-1.5; 4], [1.5; 4])
        .unwrap();
    let s = sample(&fig, &SamplerOptions::default().samples(2000).seed(1)).unwrap();
    for q in &s.points {
        let r = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
        assert!((0.5..=1.5).contains(&r), "{q:?}");
        assert!(saddle.eval(q).0.abs() < 1e-9);
    }
    let rim = boxed(vec![Arc::new(saddle), Arc::new(sphere([0.0; 3], 1.5))], 2.0);
    let s = sample(&rim, &SamplerOptions::default().samples(500).seed(1)).unwrap();
    assert!(s.points.iter().all(|q| rim.residual(q) < 1e-9));
    // Fig. 2: the surface with holes.
    let holes = boxed(
        vec![Arc::new(Body::fixed(Shape::SeedHoles { centre: [0.0; 3] }))],
        4.0,
    );
    let s = sample(&holes, &SamplerOptions::default().samples(1000).seed(1)).unwrap();
    assert!(s.points.iter().all(|q| holes.residual(q) < 1e-9));
}

#[test]
fn surface_points_give_outward_normals() {
    let b = Body::fixed(Shape::Box {
        centre: [0.1, 0.2, 0.3],
        half: [0.3, 0.2, 0.1],
        rounding: Some(0.02),
    });
    let pts = surface_points(
        Arc::new(b),
        ([-0.5, -0.3, -0.1], [0.7, 0.7, 0.7]),
        500,
        0.02,
        1,
    )
    .unwrap();
    assert_eq!(pts.len(), 500);
    for (p, n) in &pts {
        assert!(b.eval(&[p[0], p[1], p[2], 0.0]).0.abs() < 1e-9);
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-9);
        // Outward: a small step along the normal leaves the box.
        let q = [
            p[0] + 1e-3 * n[0],
            p[1] + 1e-3 * n[1],
            p[2] + 1e-3 * n[2],
            0.0,
        ];
        assert!(b.eval(&q).0 > 0.0);
    }
    // Faces are reached in proportion to their area: the two largest (0.6 × 0.4, normal ±z)
    // hold about 0.24·2/(2·(0.24 + 0.12 + 0.08)) = 0.55 of the points (less the rounding).
    let z = pts.iter().filter(|(_, n)| n[2].abs() > 0.99).count() as f64 / 500.0;
    assert!((0.4..0.65).contains(&z), "{z}");
}

// ---------------------------------------------------------------------------------------
// The command.

#[test]
fn sample_command_writes_point_clouds_and_ply() {
    use chronotope::bag::BagReader;
    use chronotope::cli::sample::{run, SampleArgs};
    use chronotope::msg::{decode_cdr, PointCloud2};
    let dir = tempfile::tempdir().unwrap();
    let scene =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/implicit/sphere_box_4d.yaml");
    let out = dir.path().join("s.mcap");
    let ply = dir.path().join("s.ply");
    let args = SampleArgs {
        overwrite: false,
        scene,
        out: out.clone(),
        ply: Some(ply.clone()),
        scheme: Some(Scheme::Metropolis),
        samples: Some(500),
        seed: 1,
        dt: None,
        walkers: Some(8),
        burn_in: Some(100),
        thin: None,
        lambda: None,
        clamp: false,
        project: false,
        target_acceptance: None,
        summary: None,
    };
    run(&args).unwrap();
    // The quality summary goes next to the bag.
    let summary = dir.path().join("s.quality.json");
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    let q = &j["quality"];
    assert_eq!(q["samples"], 500);
    assert_eq!(q["dim"], 4);
    for i in 0..4 {
        assert!(q["ess"][i].as_f64().unwrap() > 0.0, "{q}");
    }
    assert!(q["acceptance"].as_f64().unwrap() > 0.05);
    assert!(q["max_residual"].as_f64().unwrap() < 1e-9);
    assert_eq!(q["adaptation"]["dt_tuned"], true);
    assert_eq!(q["adaptation"]["thin_chosen"], true);
    let msgs: Vec<_> = BagReader::open(&out).unwrap().map(|m| m.unwrap()).collect();
    assert_eq!(msgs.len(), 2);
    for m in &msgs {
        let c: PointCloud2 = decode_cdr(&m.data).unwrap();
        assert_eq!(c.width, 500);
        assert_eq!(c.data.len(), (c.point_step * c.width) as usize);
        let names: Vec<&str> = c.fields.iter().map(|f| f.name.as_str()).collect();
        match m.topic.as_str() {
            "/sampler/points" => assert_eq!(names, ["x", "y", "z", "t"]),
            "/sampler/yzt" => assert_eq!(names, ["x", "y", "z"]),
            t => panic!("unexpected topic {t}"),
        }
    }
    let bytes = std::fs::read(&ply).unwrap();
    let head = b"end_header\n";
    let at = bytes.windows(head.len()).position(|w| w == head).unwrap() + head.len();
    assert!(String::from_utf8_lossy(&bytes[..at]).contains("element vertex 500\n"));
    assert_eq!(bytes.len() - at, 500 * 16);
    // A bad scene is an error that names the problem.
    let bad = dir.path().join("bad.yaml");
    std::fs::write(&bad, "dim: 3\nbodies: []\nsample: [nothing]\n").unwrap();
    let e = run(&SampleArgs {
        overwrite: false,
        scene: bad,
        ..args.clone()
    })
    .unwrap_err();
    assert!(e.to_string().contains("nothing"), "{e}");
    // Bad options are refused with the option and the reason, before anything is written.
    for (patch, want) in [
        (
            SampleArgs {
                overwrite: false,
                samples: Some(0),
                ..args.clone()
            },
            "samples = 0",
        ),
        (
            SampleArgs {
                overwrite: false,
                walkers: Some(0),
                ..args.clone()
            },
            "walkers = 0",
        ),
        (
            SampleArgs {
                overwrite: false,
                thin: Some(0),
                ..args.clone()
            },
            "thin = 0",
        ),
        (
            SampleArgs {
                overwrite: false,
                burn_in: Some(5),
                ..args.clone()
            },
            "burn_in = 5",
        ),
        (
            SampleArgs {
                overwrite: false,
                dt: Some(f64::NAN),
                ..args.clone()
            },
            "dt = NaN",
        ),
        (
            SampleArgs {
                overwrite: false,
                target_acceptance: Some(0.0),
                ..args.clone()
            },
            "target_acceptance = 0",
        ),
    ] {
        let fresh = dir.path().join("refused.mcap");
        let e = run(&SampleArgs {
            overwrite: false,
            out: fresh.clone(),
            ..patch
        })
        .unwrap_err()
        .to_string();
        assert!(e.contains(want), "{want}: {e}");
        assert!(!fresh.exists(), "{want}: nothing written");
    }
}

// ---------------------------------------------------------------------------------------
// Adaptation and quality.

fn sphere_07() -> Figure {
    Figure::new(
        3,
        vec![Arc::new(sphere([0.3, -0.2, 0.1], 0.7)) as Arc<dyn Field>],
    )
    .unwrap()
    .wall(Wall::Box {
        min: [-2.0; 4],
        max: [2.0; 4],
    })
    .unwrap()
}

/// ESS of coordinate `i` over every lag, walkers as chains (samples are drawn round-robin).
fn full_ess(points: &[Q], walkers: usize, i: usize) -> f64 {
    let chains: Vec<Vec<f64>> = (0..walkers)
        .map(|w| {
            points
                .iter()
                .skip(w)
                .step_by(walkers)
                .map(|p| p[i])
                .collect()
        })
        .collect();
    let refs: Vec<&[f64]> = chains.iter().map(|c| &c[..]).collect();
    ess(&refs).unwrap().value
}

#[test]
fn default_settings_give_nearly_independent_samples() {
    // A new user's first try: a sphere of radius 0.7 off the origin, 20 000 samples at the
    // defaults. Before adaptation (dt 1e-3, thin 5) the azimuth's KS distance was 0.059 and
    // the ESS about N/100.
    let fig = sphere_07();
    let n = 20_000;
    let s = sample(&fig, &SamplerOptions::default().samples(n).seed(1)).unwrap();
    let q = &s.quality;
    assert!(q.adaptation.dt_tuned && q.adaptation.thin_chosen, "{q:?}");
    assert!(
        (q.acceptance - 0.5).abs() < 0.1,
        "acceptance {}",
        q.acceptance
    );
    let c = [0.3, -0.2, 0.1];
    for i in 0..3 {
        let e = full_ess(&s.points, q.walkers, i);
        let own = q.ess[i].unwrap();
        assert!(e >= 0.5 * n as f64, "coordinate {i}: ESS {e}");
        // The sampler's running estimate agrees with the one over every lag.
        assert!((own / e - 1.0).abs() < 0.1, "coordinate {i}: {own} vs {e}");
        let mut v: Vec<f64> = s.points.iter().map(|p| p[i]).collect();
        let ks = ks_statistic(&mut v, sphere_coordinate_cdf(c[i], 0.7));
        // 2.5/√N: exceeded with probability ~1e-4 by N/2 independent samples.
        assert!(ks < 2.5 / (n as f64).sqrt(), "coordinate {i}: KS {ks}");
    }
    let az = |p: &Q| (p[1] - c[1]).atan2(p[0] - c[0]);
    let mut a: Vec<f64> = s.points.iter().map(az).collect();
    let ks = ks_statistic(&mut a, |x| {
        (x + std::f64::consts::PI) / (2.0 * std::f64::consts::PI)
    });
    assert!(ks < 2.5 / (n as f64).sqrt(), "azimuth KS {ks}");
    // The same checks fail for the old defaults: the test can fail.
    let old = sample(
        &fig,
        &SamplerOptions::default()
            .dt(1e-3)
            .burn_in(500)
            .thin(5)
            .samples(n)
            .seed(1),
    )
    .unwrap();
    let e = full_ess(&old.points, old.quality.walkers, 0);
    assert!(e < 0.1 * n as f64, "old defaults: ESS {e}");
    let mut a: Vec<f64> = old.points.iter().map(az).collect();
    let ks_old = ks_statistic(&mut a, |x| {
        (x + std::f64::consts::PI) / (2.0 * std::f64::consts::PI)
    });
    assert!(
        ks_old > 2.5 / (n as f64).sqrt(),
        "old defaults: azimuth KS {ks_old}"
    );
    eprintln!(
        "sphere r 0.7: tuned dt {:.3e} (step {:.3} m), thin {}, ESS/N {:.2}; old defaults: ESS/N {:.3}, azimuth KS {ks_old:.4}",
        q.adaptation.dt,
        q.adaptation.step_m,
        q.adaptation.thin,
        q.ess_fraction.unwrap(),
        e / n as f64
    );
}

#[test]
fn adaptation_is_deterministic_and_stops_before_the_first_sample() {
    let fig = boxed(vec![torus(1.0, 0.4)], 2.0);
    let o = SamplerOptions::default().samples(2000).seed(4);
    let mut a = chronotope::sampler::Sampler::new(&fig, &o).unwrap();
    let mut b = chronotope::sampler::Sampler::new(&fig, &o).unwrap();
    let before = a.adaptation().clone();
    assert_eq!(&before, b.adaptation());
    assert!(before.dt_tuned && before.thin_chosen && before.thin >= 1);
    let burn = a.stats().burn_in_steps;
    assert_eq!(
        burn,
        a.stats().steps,
        "nothing but burn-in before the first draw"
    );
    let pa: Vec<Q> = (0..2000).map(|_| a.draw()).collect();
    let pb: Vec<Q> = (0..2000).map(|_| b.draw()).collect();
    assert_eq!(pa, pb);
    // Fixed from the first sample on: the same step and thinning, the burn-in unchanged,
    // and exactly thin steps per sample.
    assert_eq!(a.adaptation(), &before);
    assert_eq!(a.stats().burn_in_steps, burn);
    assert_eq!(
        a.stats().steps - burn,
        2000 * before.thin as u64,
        "sampling steps"
    );
    // A different seed adapts to about the same step.
    let c = chronotope::sampler::Sampler::new(&fig, &o.clone().seed(5)).unwrap();
    let r = c.adaptation().dt / before.dt;
    assert!(
        r > 0.7 && r < 1.4,
        "tuned steps {} and {}",
        before.dt,
        c.adaptation().dt
    );
    // A given step and thinning are kept as given.
    let d = chronotope::sampler::Sampler::new(&fig, &o.clone().dt(1e-3).thin(3)).unwrap();
    assert!(!d.adaptation().dt_tuned && !d.adaptation().thin_chosen);
    assert_eq!((d.adaptation().dt, d.adaptation().thin), (1e-3, 3));
}

#[test]
fn the_explicit_scheme_reports_its_distance_off_the_figure_and_project_removes_it() {
    let fig = sphere_07();
    let o = SamplerOptions::default()
        .scheme(Scheme::Explicit)
        .thin(10)
        .samples(3000)
        .seed(2);
    let raw = sample(&fig, &o).unwrap();
    let off = |p: &Q| {
        (((p[0] - 0.3).powi(2) + (p[1] + 0.2).powi(2) + (p[2] - 0.1).powi(2)).sqrt() - 0.7).abs()
    };
    let worst = raw.points.iter().map(off).fold(0.0, f64::max);
    // Seed eq. (2) leaves the walkers off the sphere by O(step), and the run says how far.
    assert!(worst > 1e-4, "{worst}");
    assert!((raw.quality.off_figure_max / worst - 1.0).abs() < 1e-6);
    assert!(raw.quality.off_figure_rms > 0.0 && raw.quality.off_figure_rms <= worst);
    assert!(raw.quality.describe().contains("off the figure"));
    let proj = sample(&fig, &o.clone().project(true)).unwrap();
    assert!(proj.points.iter().all(|p| off(p) < 1e-9));
    assert!(proj.quality.max_residual < 1e-9 && proj.quality.projected);
    // The walk itself is untouched: the same distances off the figure before projection,
    // and each sample is the nearest point of the sphere to the walker's.
    assert_eq!(proj.quality.off_figure_max, raw.quality.off_figure_max);
    for (a, b) in raw.points.iter().zip(&proj.points) {
        let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
        assert!((d - off(a)).abs() < 1e-9, "{a:?} → {b:?}");
    }
}

/// The KS distance of samples worth N_eff independent ones is about 0.869/√N_eff on
/// average (the mean of Kolmogorov's distribution). Over 60 seeds of the sphere of radius
/// 0.7 off the origin at the defaults, KS·√ESS must average that: a bias would raise it, an
/// ESS estimate too high as well. 30 s in a test build, so not in CI:
/// `cargo test --test it sampler:: -- --ignored ks_of_default_samples`.
#[test]
#[ignore]
fn ks_of_default_samples_is_that_of_independent_ones() {
    let fig = sphere_07();
    let c = [0.3, -0.2, 0.1];
    let n = 20_000;
    let (mut sum, mut over, mut runs) = (0.0, 0, 0);
    for seed in 100..160 {
        let s = sample(&fig, &SamplerOptions::default().samples(n).seed(seed)).unwrap();
        for i in 0..3 {
            let mut v: Vec<f64> = s.points.iter().map(|p| p[i]).collect();
            let ks = ks_statistic(&mut v, sphere_coordinate_cdf(c[i], 0.7));
            sum += ks * full_ess(&s.points, s.quality.walkers, i).sqrt();
            over += usize::from(ks > 1.5 / (n as f64).sqrt());
            runs += 1;
        }
    }
    let mean = sum / runs as f64;
    eprintln!(
        "mean KS·√ESS {mean:.3} (independent samples: 0.869); KS > 1.5/√N in {over} of {runs}"
    );
    // The mean of 180 values with a standard deviation of about 0.26: ±0.06 is 3 SE.
    assert!((mean - 0.869).abs() < 0.06, "{mean}");
}
