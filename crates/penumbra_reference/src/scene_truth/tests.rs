//! The scene truth against analytic answers: a square's shadow and its penumbra, AO under
//! an infinite ceiling, culled and double-sided faces.

use super::*;
use glam::Vec3;

/// A square of half-size `h` at height `y`, normal up (counter-clockwise seen from above).
fn square(center: Vec3, h: f32) -> [[Vec3; 3]; 2] {
    let p = |x: f32, z: f32| center + Vec3::new(x, 0.0, z);
    [
        [p(-h, -h), p(-h, h), p(h, h)],
        [p(-h, -h), p(h, h), p(h, -h)],
    ]
}

fn flipped(t: [[Vec3; 3]; 2]) -> [[Vec3; 3]; 2] {
    t.map(|[a, b, c]| [a, c, b])
}

/// A floor of half-size 50 at y = 0 and, if given, more triangles.
fn scene(extra: &[[Vec3; 3]], extra_double_sided: bool) -> SceneTriangles {
    let mut tris: Vec<[Vec3; 3]> = square(Vec3::ZERO, 50.0).to_vec();
    let mut sides = vec![false; 2];
    tris.extend_from_slice(extra);
    sides.extend(std::iter::repeat_n(extra_double_sided, extra.len()));
    SceneTriangles::new(tris, sides)
}

/// A camera looking straight down from height `y` (tiny image), a little off the
/// squares' diagonals (a ray exactly through the edge two triangles share can slip
/// between them: Möller–Trumbore is not watertight).
fn top_camera(y: f32, size: u32, fov_deg: f32) -> PerspectiveCamera {
    let off = Vec3::new(0.013, 0.0, 0.031);
    PerspectiveCamera::looking_at(
        Vec3::new(0.0, y, 1e-3) + off,
        off,
        fov_deg.to_radians(),
        size,
        size,
    )
}

/// A floor point facing up.
fn at(position: Vec3) -> Option<SurfaceHit> {
    Some(SurfaceHit {
        depth: 0.0,
        position,
        normal: Vec3::Y,
        shadow_normal: Vec3::Y,
        back: false,
    })
}

#[test]
fn a_square_casts_its_shadow_and_half_the_sun_reaches_its_edge() {
    // A one-sided square 1 m above the floor, facing down (so a raster camera above sees
    // through it), shadowing the floor under a sun straight overhead.
    let roof = flipped(square(Vec3::Y, 0.5));
    let s = scene(&roof, false);
    let angle = 3f32.to_radians();
    let probe = |p: Vec3| {
        let hits = vec![at(p)];
        sun_visibility(&s, &hits, -Vec3::Y, angle, 256)[0]
    };
    assert_eq!(probe(Vec3::ZERO), 0.0, "under the square's centre");
    assert_eq!(probe(Vec3::new(2.0, 0.0, 0.0)), 1.0, "far from it");
    // Under the edge half the disc is hidden (straight edge through its centre).
    let edge = probe(Vec3::new(0.5, 0.0, 0.0));
    assert!((edge - 0.5).abs() < 0.03, "edge {edge}");
    // At x = 0.5 + d, the disc of radius R = tan(1.5°) · 1 m is cut by a chord d from its
    // centre: the uncovered fraction is 1 − (acos(d/R) − (d/R)·√(1 − (d/R)²)) / π.
    let r = (angle * 0.5).tan();
    let d = 0.5 * r;
    let k = d / r;
    let expected = 1.0 - ((k).acos() - k * (1.0 - k * k).sqrt()) / std::f32::consts::PI;
    let got = probe(Vec3::new(0.5 + d, 0.0, 0.0));
    assert!(
        (got - expected).abs() < 0.03,
        "penumbra {got} vs {expected}"
    );
    // A surface facing away from the sun is unlit whatever occludes it.
    let hits = vec![Some(SurfaceHit {
        depth: 0.0,
        position: Vec3::new(3.0, 0.0, 0.0),
        normal: -Vec3::Y,
        shadow_normal: -Vec3::Y,
        back: false,
    })];
    assert_eq!(sun_visibility(&s, &hits, -Vec3::Y, angle, 64)[0], 0.0);
}

#[test]
fn ao_under_an_infinite_ceiling_is_the_square_of_its_height_over_the_reach() {
    // Cosine-weighted rays from the floor reach a ceiling at height H within M when
    // cos θ > H / M, which happens with probability 1 − (H/M)²: AO = (H/M)².
    let ceiling = flipped(square(Vec3::new(0.0, 0.5, 0.0), 50.0));
    let s = scene(&ceiling, false);
    let hits = vec![at(Vec3::ZERO)];
    for (reach, expected) in [(1.0, 0.25), (2.0, 0.0625), (0.4, 1.0)] {
        let ao = ambient_occlusion(&s, &hits, reach, 1024)[0];
        assert!(
            (ao - expected).abs() < 0.02,
            "reach {reach}: {ao} vs {expected}"
        );
    }
    // With nothing above, every ray escapes.
    let open = scene(&[], false);
    assert_eq!(ambient_occlusion(&open, &hits, 10.0, 64)[0], 1.0);
}

#[test]
fn the_raster_camera_sees_past_culled_back_faces_and_turns_double_sided_ones() {
    let camera = top_camera(5.0, 8, 20.0);
    let centre = |facing, double_sided| {
        let roof = flipped(square(Vec3::Y, 2.0));
        let s = scene(&roof, double_sided);
        let hits = primary_hits(&s, &camera, facing);
        assert_eq!(hits.len(), 64);
        assert!(hits.iter().all(Option::is_some));
        hits[4 * 8 + 4].unwrap()
    };
    // A single-sided square facing away from the camera: culled, the floor shows.
    let hit = centre(Facing::Raster, false);
    assert!((hit.depth - 5.0).abs() < 1e-2, "{hit:?}");
    assert_eq!(hit.shadow_normal, Vec3::Y);
    assert!(!hit.back, "the floor's front");
    // Double-sided: seen, its normal turned to the camera for shading and shadows, and
    // known to be its back.
    let hit = centre(Facing::Raster, true);
    assert!((hit.depth - 4.0).abs() < 1e-2, "{hit:?}");
    assert!(hit.normal.abs_diff_eq(Vec3::Y, 1e-5) && hit.shadow_normal == hit.normal);
    assert!(hit.back);
    // The oracles' convention: every face is seen; shadows test the face's own normal.
    let hit = centre(Facing::AllFaces, false);
    assert!((hit.depth - 4.0).abs() < 1e-2, "{hit:?}");
    assert!(hit.normal.abs_diff_eq(Vec3::Y, 1e-5));
    assert!(hit.shadow_normal.abs_diff_eq(-Vec3::Y, 1e-5));
    // So a sun overhead lights the double-sided square's top in raster, not in AllFaces.
    let roof = flipped(square(Vec3::Y, 2.0));
    let s = scene(&roof, true);
    let lit = |facing| {
        let hits = primary_hits(&s, &camera, facing);
        sun_visibility(&s, &hits, -Vec3::Y, 0.01, 16)[4 * 8 + 4]
    };
    assert_eq!((lit(Facing::Raster), lit(Facing::AllFaces)), (1.0, 0.0));
}

#[test]
fn the_truth_is_deterministic_and_nan_on_background() {
    let roof = square(Vec3::Y, 0.5);
    let s = scene(&roof, false);
    let camera = PerspectiveCamera::looking_at(
        Vec3::new(0.0, 3.0, 3.0),
        Vec3::ZERO,
        60f32.to_radians(),
        16,
        12,
    );
    let hits = primary_hits(&s, &camera, Facing::Raster);
    let sun = Vec3::new(-1.0, -0.6, -0.5);
    let a = sun_visibility(&s, &hits, sun, 0.05, 32);
    let b = sun_visibility(&s, &hits, sun, 0.05, 32);
    assert_eq!(a.len(), 16 * 12);
    assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let c = pool.install(|| sun_visibility(&s, &hits, sun, 0.05, 32));
    assert!(a.iter().zip(&c).all(|(x, y)| x.to_bits() == y.to_bits()));
    // A camera looking up sees only sky.
    let sky = PerspectiveCamera::looking_at(Vec3::Y, Vec3::new(0.0, 5.0, -1.0), 1.0, 4, 4);
    let hits = primary_hits(&s, &sky, Facing::Raster);
    assert!(hits.iter().all(Option::is_none));
    assert!(
        ambient_occlusion(&s, &hits, 1.0, 8)
            .iter()
            .all(|v| v.is_nan())
    );
    // Shadowed-pixel error counts pixels either side calls shadowed.
    let e = compare(&[1.0, 0.5, 0.0, 0.7], &[1.0, 1.0, 0.0, f32::NAN], &[1.0; 4]);
    assert_eq!((e.pixels, e.shadowed_pixels), (3, 2));
    assert!((e.all - 0.5 / 3.0).abs() < 1e-9 && (e.shadowed - 0.25).abs() < 1e-9);
}

/// The share of the shadowed-pixel error on chosen pixels: the same pixels and errors as
/// `compare` (lit-lit pixels and pixels without truth left out).
#[test]
fn the_shadowed_error_share_counts_the_pixels_compare_counts() {
    let ours = [0.0, 1.0, 0.5, 0.2, f32::NAN];
    let truth = [1.0, 1.0, 0.0, f32::NAN, 0.0];
    let depth = [1.0; 5];
    let e = compare(&ours, &truth, &depth);
    // Pixel 4: ours NaN counts as 1 (error 1); pixel 3 has no truth.
    assert_eq!(e.shadowed_pixels, 3);
    assert!((e.shadowed - 2.5 / 3.0).abs() < 1e-12);
    let share = |keep: &[usize]| shadowed_error_share(&ours, &truth, &depth, |i| keep.contains(&i));
    assert!((share(&[0]) - 1.0 / 2.5).abs() < 1e-12);
    assert!((share(&[0, 2, 4]) - 1.0).abs() < 1e-12);
    assert_eq!(share(&[1, 3]), 0.0);
    assert_eq!(shadowed_error_share(&[1.0], &[1.0], &[1.0], |_| true), 0.0);
}
