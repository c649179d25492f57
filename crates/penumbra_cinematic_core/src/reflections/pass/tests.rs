//! Tests of the reflection pass model.

use super::*;
use glam::Mat4;

fn surface(view: Vec3, perceptual_roughness: f32) -> Surface {
    Surface {
        position: Vec3::ZERO,
        normal: Vec3::Y,
        view: view.normalize(),
        perceptual_roughness,
    }
}

#[test]
fn the_lobe_stretches_toward_grazing() {
    // 60° from the normal: the in-plane half-width is 1/cos 60° = 2× the other.
    let s = surface(Vec3::new(0.0, 0.5, 3f32.sqrt() / 2.0), 0.5);
    let l = lobe(&s, 0.0, FOOTPRINT_SLOPE);
    assert!((l.dir - Vec3::new(0.0, 0.5, -(3f32.sqrt()) / 2.0)).length() < 1e-6);
    assert!(l.major.dot(l.dir).abs() < 1e-6 && l.minor.dot(l.dir).abs() < 1e-6);
    assert!((l.major.length() / l.minor.length() - 2.0).abs() < 1e-5);
    assert!((l.major.length() - FOOTPRINT_SLOPE * 0.25).abs() < 1e-6);
    // Anisotropy widens the in-plane axis and narrows the other.
    let a = lobe(&s, 0.5, FOOTPRINT_SLOPE);
    assert!((a.major.length() / l.major.length() - 1.5).abs() < 1e-5);
    assert!((a.minor.length() / l.minor.length() - 0.5).abs() < 1e-5);
    // Straight down the normal: round.
    let top = lobe(&surface(Vec3::Y, 0.5), 0.0, FOOTPRINT_SLOPE);
    assert!((top.major.length() - top.minor.length()).abs() < 1e-6);
}

#[test]
fn coverage_of_a_box() {
    assert_eq!(box_coverage(0.5, 0.1), 1.0);
    assert!((box_coverage(0.0, 0.1) - 0.5).abs() < 1e-6);
    assert!((box_coverage(1.05, 0.1) - 0.25).abs() < 1e-6);
    assert_eq!(box_coverage(-0.2, 0.1), 0.0);
    assert_eq!(box_coverage(0.3, 0.0), 1.0);
    assert_eq!(box_coverage(1.3, 0.0), 0.0);
    assert!((box_coverage(0.5, 1.0) - 0.5).abs() < 1e-6);
}

/// A smooth floor under a billboard: the mirror hit reads the texel the reflected
/// ray meets; rougher floors spread the same texel over more of the image.
#[test]
fn a_mirror_reads_the_texel_it_meets() {
    // 8×8 image: a white texel at (5, 2) on transparent black.
    let mut texels = vec![Vec4::ZERO; 64];
    texels[2 * 8 + 5] = Vec4::ONE;
    let image = MipChain::from_straight_alpha(8, 8, &texels);
    // The quad 2 m ahead (−Z), 2 m across, facing +Z, centred 1 m up.
    let quad = Billboard::from_transform(
        Mat4::from_translation(Vec3::new(0.0, 1.0, -2.0)),
        Vec2::splat(2.0),
    )
    .unwrap();
    let gpu = GpuBillboard::new(&quad, 0, 3.0);
    let settings = ReflectionUniform::new(1, UVec2::splat(8), 4);
    // The texel's centre: u = 5.5/8, v = 2.5/8 → x = −1 + 2u, y = 2 − 2v.
    let target = Vec3::new(-1.0 + 2.0 * 5.5 / 8.0, 2.0 - 2.0 * 2.5 / 8.0, -2.0);
    // The eye at the mirror image of a ray from the floor point (0, 0, −1): the
    // reflected ray from there goes to the target.
    let p = Vec3::new(0.0, 0.0, -1.0);
    let mirrored_target = target * Vec3::new(1.0, -1.0, 1.0);
    let view = (p - mirrored_target).normalize();
    let mut s = surface(view, 0.0);
    s.position = p;
    let sharp = reflect_pixel(&s, &[gpu], std::slice::from_ref(&image), &settings);
    // Perceptual roughness is clamped to 0.089: a slight blur, most light kept.
    assert!(sharp.x > 1.5 && sharp.w > 0.5, "{sharp}");
    s.perceptual_roughness = 0.6;
    let rough = reflect_pixel(&s, &[gpu], std::slice::from_ref(&image), &settings);
    assert!(
        rough.x < 0.5 * sharp.x && rough.x > 0.0,
        "{rough} vs {sharp}"
    );
    // An emissive beyond the layer's f16 range stays finite (it stored infinity,
    // then NaN in the composite).
    s.perceptual_roughness = 0.0;
    let blinding = GpuBillboard::new(&quad, 0, 1e9);
    let layer = reflect_pixel(&s, &[blinding], std::slice::from_ref(&image), &settings);
    assert!(
        layer.is_finite() && layer.max_element() <= MAX_REFLECTED_RADIANCE,
        "{layer}"
    );
    assert!(
        layer
            .to_array()
            .iter()
            .all(|&c| half::f16::from_f32(c).is_finite())
    );
    // From behind the quad: nothing.
    s.position = Vec3::new(0.0, 0.0, -3.0);
    s.view = (s.position - mirrored_target).normalize();
    assert_eq!(reflect_pixel(&s, &[gpu], &[], &settings), Vec4::ZERO);
}

/// The march evaluates only the objects near its ray: a wall across a mirror ray and
/// 400 boxes off to the side cost the wall's evaluations alone (before the cull: 401
/// per step), with the same visibility as marching everything; past
/// [`MAX_SHADOW_CASTERS`] near the ray it marches them all.
#[test]
fn the_shadow_march_skips_objects_off_its_ray() {
    use std::cell::Cell;
    let cuboid = |p: Vec3, c: Vec3, h: Vec3| {
        let q = (p - c).abs() - h;
        q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
    };
    // Box 0: a wall between a floor point and a sign 4 m up its mirror ray; boxes
    // 1..: a field 6 m or more to the side.
    let mut boxes = vec![(Vec3::new(0.0, 2.0, -2.0), Vec3::new(2.0, 0.5, 0.1))];
    for i in 0..400 {
        let (x, z) = ((i % 20) as f32, (i / 20) as f32);
        boxes.push((Vec3::new(6.0 + x, 0.5, -10.0 + z), Vec3::splat(0.3)));
    }
    let spheres: Vec<_> = boxes.iter().map(|&(c, h)| Some((c, h.length()))).collect();
    let evaluations = Cell::new(0usize);
    let casters = ShadowCasters {
        spheres: &spheres,
        distance: |i: usize, p: Vec3| {
            evaluations.set(evaluations.get() + 1);
            cuboid(p, boxes[i].0, boxes[i].1)
        },
    };
    // The floor at the origin, looking along -z and down: the mirror ray rises
    // toward -z, through the wall, to a sign facing +z at z = -4.
    let sign = Billboard::from_transform(
        Mat4::from_translation(Vec3::new(0.0, 4.0, -4.0)),
        Vec2::splat(3.0),
    )
    .expect("a quad");
    let gpu = GpuBillboard::new(&sign, 0, 1.0);
    let images = [MipChain::from_straight_alpha(1, 1, &[Vec4::ONE])];
    let mut settings = ReflectionUniform::new(1, UVec2::ONE, 1);
    settings.shadow_steps = 32;
    settings.object_count = boxes.len() as u32;
    let s = Surface {
        position: Vec3::ZERO,
        normal: Vec3::Y,
        view: Vec3::new(0.0, 1.0, 1.0).normalize(),
        perceptual_roughness: 0.2,
    };
    let culled = reflect_pixel_shadowed(&s, &[gpu], &images, &settings, &casters);
    let work = evaluations.replace(0);
    // Everything, as before the cull: a pixel's march through all 401 boxes.
    let all = shadow_march(
        s.position,
        (-s.view).reflect(s.normal),
        &[ShadowTarget {
            t: 4.0 / (0.5f32).sqrt(),
            facing: (0.5f32).sqrt(),
        }],
        (lobe(&s, 0.0, settings.footprint_slope).major.length() * settings.shadow_cone)
            .max(settings.shadow_softness),
        &settings,
        |p| {
            (0..boxes.len())
                .map(|i| (casters.distance)(i, p))
                .fold(f32::MAX, f32::min)
        },
    );
    let unculled = evaluations.replace(0);
    println!("reflection shadow march: {work} evaluations culled, {unculled} unculled");
    assert!(culled.w > 0.1, "the sign is reflected: {culled}");
    assert!(
        culled.x < 0.05 && all[0] < 0.05,
        "the wall hides it: {culled} {all:?}"
    );
    assert!(unculled >= 400 * 4, "{unculled}");
    assert!(
        work <= 2 * 32,
        "{work} evaluations: objects off the ray were marched"
    );
    // Crowded: 40 boxes along the ray, more than the cap: all are marched.
    let spheres: Vec<_> = (0..40)
        .map(|i| Some((Vec3::new(0.0, 0.1 * i as f32, -0.1 * i as f32), 0.01)))
        .collect();
    let near = ShadowCasters {
        spheres: &spheres,
        distance: |_: usize, _: Vec3| {
            evaluations.set(evaluations.get() + 1);
            f32::MAX
        },
    };
    reflect_pixel_shadowed(&s, &[gpu], &images, &settings, &near);
    assert!(evaluations.get() >= 40, "{}", evaluations.get());
    assert_eq!(
        shadow_casters(&spheres, None, Vec3::ZERO, Vec3::Z, 0.0, 1.0, 0.0),
        Some(vec![0]),
        "beside the ray"
    );
    assert_eq!(
        segment_ends(2.0),
        [0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0]
    );
}

/// A wall across the ray hides the hits behind it, not those before it; beside the
/// ray it dims them by `d / (cone t)`; with no steps nothing is shadowed.
#[test]
fn the_shadow_march_sees_walls() {
    let mut settings = ReflectionUniform::new(1, UVec2::ONE, 1);
    settings.shadow_steps = 64;
    settings.object_count = 1;
    // A box wall at z ∈ [1.9, 2.1], x ∈ [x0, x1], tall.
    let wall = |x0: f32, x1: f32| {
        move |p: Vec3| {
            let c = Vec3::new(0.5 * (x0 + x1), 0.0, 2.0);
            let h = Vec3::new(0.5 * (x1 - x0), 10.0, 0.1);
            let q = (p - c).abs() - h;
            q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
        }
    };
    let march = |cone: f32, scene: &dyn Fn(Vec3) -> f32, settings: &ReflectionUniform| {
        let targets = [1.0, 4.0].map(|t| ShadowTarget { t, facing: 1.0 });
        shadow_march(Vec3::ZERO, Vec3::Z, &targets, cone, settings, scene)
    };
    let across = wall(-1.0, 1.0);
    let v = march(0.05, &across, &settings);
    assert_eq!(&v[..2], &[1.0, 0.0], "{v:?}");
    // Beside the ray, 0.3 m off at 2 m: visibility 0.3 / (cone · ~2).
    let beside = wall(0.3, 2.0);
    let v = march(0.3, &beside, &settings);
    assert_eq!(v[0], 1.0);
    assert!((v[1] - 0.3 / (0.3 * 1.9)).abs() < 0.05, "{v:?}");
    assert_eq!(
        march(0.05, &beside, &settings)[1],
        1.0,
        "a narrow cone passes"
    );
    settings.shadow_steps = 0;
    assert_eq!(
        march(0.05, &across, &settings),
        [1.0; crate::reflections::MAX_LAYERS]
    );
}
