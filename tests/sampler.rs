//! The stochastic sampler (issue 7): uniformity on figures with exact answers, the stiff and
//! extreme cases, the command, and an independent cross-check of the mesh + checker pipeline
//! against the sampled 4D collision set of two moving bodies.

use chronotope::checker::labels::Label;
use chronotope::checker::{check_pair, CommonLattice};
use chronotope::mesh::glue::BodyAssembler;
use chronotope::mesh::{FrameRef, MesherOptions};
use chronotope::msg::VoxelEncoding;
use chronotope::sampler::exact::{ks_statistic, sphere_x_cdf, TorusTheta};
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
        let o = SamplerOptions::default()
            .scheme(scheme)
            .dt(1e-3)
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
    ] {
        match sample(&fig, &o) {
            Err(SamplerError::BadParameter { name: n, .. }) => assert_eq!(n, name),
            other => panic!("{name}: {:?}", other.map(|s| s.stats)),
        }
    }
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
fn disconnected_components_are_each_reached_but_not_weighted_by_area() {
    let f = TwoSpheres(sphere([-1.0, 0.0, 0.0], 0.6), sphere([1.2, 0.0, 0.0], 0.3));
    let fig = boxed(vec![Arc::new(f)], 2.0);
    let s = sample(
        &fig,
        &SamplerOptions::default().samples(6400).walkers(64).seed(6),
    )
    .unwrap();
    let left = s.points.iter().filter(|q| q[0] < 0.0).count() as f64 / s.points.len() as f64;
    eprintln!("two spheres: fraction on the larger {left:.3} (by area it would be 0.8)");
    // Diffusion never crosses between components: each walker stays on the one it was
    // projected onto, so both are covered, in proportion to the walkers that landed there.
    assert!(left > 0.05 && left < 0.95, "{left}");
    for q in &s.points {
        let on_a = ((q[0] + 1.0).powi(2) + q[1] * q[1] + q[2] * q[2]).sqrt() - 0.6;
        let on_b = ((q[0] - 1.2).powi(2) + q[1] * q[1] + q[2] * q[2]).sqrt() - 0.3;
        assert!(on_a.abs() < 1e-9 || on_b.abs() < 1e-9);
    }
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
// Cross-check: the checker on voxelised bodies against the sampled 4D collision set.

const GRID: u32 = 20;
const FRAMES: u32 = 21;

struct Pair {
    a: (chronotope::scene::Shape, [f64; 3]),
    b: (chronotope::scene::Shape, [f64; 3]),
    fa: Body,
    fb: Body,
}

/// A static sphere (r 0.2 at (0.65, 0.5, 0.5)) and a box (half 0.15) crossing it along x
/// at `vx`, in the unit cube over 1 s.
fn pair(b_x0: f64, vx: f64) -> Pair {
    use chronotope::scene::Shape as S;
    let (c, r) = ([0.65, 0.5, 0.5], 0.2);
    let (bc, h) = ([b_x0, 0.5, 0.55], 0.15);
    Pair {
        a: (S::sphere(c, r), [0.0; 3]),
        b: (
            S::cuboid(bc.map(|x| x - h), bc.map(|x| x + h)),
            [vx, 0.0, 0.0],
        ),
        fa: sphere(c, r),
        fb: Body::fixed(Shape::Box {
            centre: bc,
            half: [h; 3],
            rounding: Some(0.0),
        })
        .moving([vx, 0.0, 0.0], 0.0),
    }
}

struct Checked {
    intervals_s: Vec<(f64, f64)>,
    /// World bounding boxes (x, y, z, t) of INTERFERENCE tets of both bodies.
    boxes: Vec<([f64; 4], [f64; 4])>,
    period: f64,
    voxel: f64,
}

fn check(p: &Pair) -> Checked {
    let lattice = chronotope::scene::VoxelLattice::cube([0.0; 3], 1.0, GRID);
    let mut raster = chronotope::scene::Rasterizer::new();
    let mut data = Vec::new();
    let period_ns = 1_000_000_000 / i64::from(FRAMES - 1);
    let mut meshes = Vec::new();
    for (shape, v) in [&p.a, &p.b] {
        let mut asm = BodyAssembler::new(MesherOptions::default()).unwrap();
        for k in 0..FRAMES {
            let t = f64::from(k) / f64::from(FRAMES - 1);
            raster.rasterize(
                &[*shape],
                v.map(|c| c * t),
                &lattice,
                VoxelEncoding::Bits,
                &mut data,
            );
            asm.push(&FrameRef {
                stamp_ns: i64::from(k) * period_ns,
                origin: lattice.origin,
                resolution: lattice.resolution,
                size: lattice.size,
                encoding: VoxelEncoding::Bits.code(),
                data: &data,
            })
            .unwrap();
        }
        meshes.push(asm.finish());
    }
    let named = [("a", &meshes[0]), ("b", &meshes[1])];
    let lat = CommonLattice::of(&named).unwrap();
    let pa = lat.prepare("a", &meshes[0]).unwrap();
    let pb = lat.prepare("b", &meshes[1]).unwrap();
    let r = check_pair(&pa, &pb);
    let origin = lat.stamps_ns[0];
    let per = lat.per_step() as f64;
    let world = |v: &[i32; 4]| -> [f64; 4] {
        [
            lat.voxel0_centre[0] + f64::from(v[0]) / per * lat.resolution,
            lat.voxel0_centre[1] + f64::from(v[1]) / per * lat.resolution,
            lat.voxel0_centre[2] + f64::from(v[2]) / per * lat.resolution,
            lat.time_s(f64::from(v[3]), origin),
        ]
    };
    let mut boxes = Vec::new();
    for (prep, labels) in [(&pa, &r.labels_a), (&pb, &r.labels_b)] {
        for (tet, l) in prep.mesh.tets.iter().zip(&labels.labels) {
            if *l != Label::Interference {
                continue;
            }
            let mut lo = [f64::INFINITY; 4];
            let mut hi = [f64::NEG_INFINITY; 4];
            for &vi in tet {
                let w = world(&prep.mesh.vertices[vi as usize]);
                for i in 0..4 {
                    lo[i] = lo[i].min(w[i]);
                    hi[i] = hi[i].max(w[i]);
                }
            }
            boxes.push((lo, hi));
        }
    }
    Checked {
        intervals_s: r
            .intervals
            .iter()
            .map(|&(s, e)| (lat.time_s(s, origin), lat.time_s(e, origin)))
            .collect(),
        boxes,
        period: period_ns as f64 * 1e-9,
        voxel: lattice.resolution,
    }
}

fn collision_set(p: &Pair) -> Result<Vec<Q>, SamplerError> {
    let fig = Figure::new(4, vec![Arc::new(p.fa), Arc::new(p.fb)])?.wall(Wall::Box {
        min: [0.0, 0.0, 0.0, 0.0],
        max: [1.0, 1.0, 1.0, 1.0],
    })?;
    let o = SamplerOptions::default()
        .dt(1e-4)
        .samples(3000)
        .walkers(32)
        .seed(11);
    let s = sample(&fig, &o)?;
    assert!(s.points.iter().all(|q| fig.residual(q) < 1e-9));
    Ok(s.points)
}

#[test]
fn every_sample_of_the_4d_collision_set_lies_where_the_checker_found_interference() {
    let p = pair(0.2, 0.6);
    let c = check(&p);
    let samples = collision_set(&p).unwrap();
    // The box's face reaches the sphere at t = (0.45 - 0.35)/0.6 = 0.167 s; they still cross
    // at the end of the run.
    let (tmin, tmax) = samples.iter().fold((f64::INFINITY, 0.0f64), |a, q| {
        (a.0.min(q[3]), a.1.max(q[3]))
    });
    assert!(tmin > 0.1 && tmin < 0.25 && tmax > 0.95, "{tmin} {tmax}");
    assert!(
        !c.intervals_s.is_empty(),
        "the checker found no interference"
    );
    // Tolerances: voxelisation moves each surface by up to half a voxel diagonal, so a
    // sample may sit up to one voxel diagonal from the nearest INTERFERENCE tet of the
    // voxel bodies, and the time of first contact may shift by that over the closing speed
    // (0.6 m/s), plus a frame period for the piecewise-linear time interpolation.
    let diag = 3f64.sqrt() * c.voxel;
    let t_tol = c.period + diag / 0.6;
    let mut outside = Vec::new();
    for q in &samples {
        let in_interval = c
            .intervals_s
            .iter()
            .any(|&(s, e)| q[3] >= s - t_tol && q[3] <= e + t_tol);
        assert!(
            in_interval,
            "sample at t = {} outside the checker's intervals {:?}",
            q[3], c.intervals_s
        );
        let in_box = c.boxes.iter().any(|(lo, hi)| {
            (0..3).all(|i| q[i] >= lo[i] - diag && q[i] <= hi[i] + diag)
                && q[3] >= lo[3] - t_tol
                && q[3] <= hi[3] + t_tol
        });
        if !in_box {
            outside.push(*q);
        }
    }
    assert!(
        outside.is_empty(),
        "{} of {} samples far from every INTERFERENCE tet, e.g. {:?}",
        outside.len(),
        samples.len(),
        &outside[..outside.len().min(3)]
    );
    // And the other way round: the checker's interval is covered by samples (it would also
    // fail if the checker reported interference where the bodies never cross).
    for &(s, e) in &c.intervals_s {
        assert!(
            (s - tmin).abs() < t_tol && (e - tmax).abs() < t_tol,
            "checker {s}..{e} vs samples {tmin}..{tmax}"
        );
    }
}

#[test]
fn bodies_that_never_meet_have_no_collision_set_and_no_interference() {
    // The box moves away from the sphere.
    let p = pair(0.2, -0.1);
    let c = check(&p);
    assert!(c.intervals_s.is_empty() && c.boxes.is_empty());
    assert!(matches!(
        collision_set(&p),
        Err(SamplerError::NoStart { .. })
    ));
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
    };
    run(&args).unwrap();
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
    let e = run(&SampleArgs { scene: bad, ..args }).unwrap_err();
    assert!(e.to_string().contains("nothing"), "{e}");
}
