//! Property tests of every settings component's `resolve`: thousands of settings drawn
//! with NaN, infinities, zeros, negatives, subnormals and huge values in every field
//! (`penumbra_testkit::Awkward`). For each: resolving never panics; what it returns has
//! no NaN or infinity; resolving the result again changes nothing and says nothing
//! (idempotent); and it says something exactly when it changed something (no silent
//! fix, no false alarm).

use bevy::color::{Alpha, Color};
use bevy::math::Vec3;
use bevy_penumbra_df::{
    DistanceFieldAmbientOcclusion, DistanceFieldParticles, DistanceFieldShadows,
    GlobalDistanceField,
};
use penumbra_testkit::{Awkward, assert_finite, has_non_finite};

const DRAWS: u32 = 4000;

fn vec3(a: &mut Awkward) -> Vec3 {
    Vec3::new(a.f32(), a.f32(), a.f32())
}

fn color(a: &mut Awkward) -> Color {
    Color::linear_rgba(a.f32(), a.f32(), a.f32(), a.f32())
}

/// The checks for settings whose `resolve` returns the settings themselves.
fn check_settings<T: PartialEq + std::fmt::Debug + Clone>(
    what: &str,
    input: &T,
    resolve: impl Fn(&T) -> (T, Vec<String>),
) {
    let (fixed, notes) = resolve(input);
    assert_finite(what, &fixed, input);
    let (again, more) = resolve(&fixed);
    assert_eq!(again, fixed, "{what}: not idempotent");
    assert!(
        more.is_empty(),
        "{what}: the resolved settings still draw notes: {more:?}"
    );
    // `!=` rather than `==`: a NaN field never equals itself, so it must be changed.
    let changed = fixed != *input;
    assert_eq!(
        changed,
        !notes.is_empty(),
        "{what}: changed {changed} but notes {notes:?}\n  from {input:?}\n  to {fixed:?}"
    );
}

#[test]
fn particle_settings_resolve_to_finite_settings_with_a_note_per_change() {
    let mut a = Awkward::new(11);
    for _ in 0..DRAWS {
        let input = DistanceFieldParticles {
            capacity: a.u32(),
            rate: a.f32(),
            max_emitted: a.bool().then(|| a.u32()),
            spawn_half_extents: vec3(&mut a),
            velocity: vec3(&mut a),
            velocity_jitter: a.f32(),
            radius: a.f32(),
            restitution: a.f32(),
            friction: a.f32(),
            gravity: vec3(&mut a),
            color: color(&mut a),
            seed: a.bool().then(|| u64::from(a.u32())),
        };
        check_settings(
            "DistanceFieldParticles",
            &input,
            DistanceFieldParticles::resolve,
        );
    }
}

#[test]
fn shadow_settings_resolve_to_finite_settings_with_a_note_per_change() {
    let mut a = Awkward::new(12);
    for _ in 0..DRAWS {
        let input = DistanceFieldShadows {
            angular_diameter: a.f32(),
            max_distance: a.f32(),
            max_view_distance: a.f32(),
            max_steps: a.u32(),
            bias: a.f32(),
            shaping: a.f32(),
            half_resolution: a.bool(),
        };
        check_settings(
            "DistanceFieldShadows",
            &input,
            DistanceFieldShadows::resolve,
        );
    }
}

#[test]
fn global_field_settings_resolve_to_a_finite_layout() {
    let mut a = Awkward::new(13);
    for _ in 0..DRAWS {
        let input = GlobalDistanceField {
            clipmap_count: a.u32(),
            resolution: a.u32(),
            first_extent: a.f32(),
            growth: a.f32(),
            brick_budget: a.u32(),
        };
        let (layout, budget, problems) = input.resolve();
        assert_finite("GlobalDistanceField", &layout, &input);
        assert!(budget >= 1);
        let in_range = problems.is_empty();
        if in_range {
            assert_eq!(
                (layout.levels, layout.resolution),
                (input.clipmap_count, input.resolution),
                "no problem reported, yet the layout differs from {input:?}"
            );
        }
    }
}

#[test]
fn ao_settings_report_every_value_out_of_range() {
    let mut a = Awkward::new(14);
    let defaults = DistanceFieldAmbientOcclusion::default();
    assert!(defaults.problems().is_empty());
    for _ in 0..DRAWS {
        let mut input = defaults.clone();
        // One field at a time, so each problem is its own.
        match a.below(9) {
            0 => input.max_occlusion_distance = a.f32(),
            1 => input.occlusion_contrast = a.f32(),
            2 => input.min_occlusion = a.f32(),
            // Its alpha is not used.
            3 => input.occlusion_tint = color(&mut a).with_alpha(1.0),
            4 => input.cone_count = a.u32(),
            5 => input.steps_per_cone = a.u32(),
            6 => input.trace_resolution_divisor = a.u32(),
            7 => input.surface_bias = a.f32(),
            _ => input.global_field_start = a.f32(),
        }
        let text = format!("{input:?}");
        let problems = input.problems();
        if has_non_finite(&text) {
            assert!(
                !problems.is_empty(),
                "a non-finite setting drew no problem: {input:?}"
            );
        }
    }
}

/// Heightfield images of every format, size class and data length
/// (`penumbra_test::awkward_images`): one finite height per texel, or refused with a
/// reason; never a panic.
#[test]
fn height_images_of_every_format_and_size_are_read_or_refused() {
    penumbra_test::awkward_images::check_image_reader(
        "height images",
        31,
        |image| bevy_penumbra_df::scene::image_heights(image, 2.0),
        |(size, heights)| {
            assert_eq!(
                heights.len(),
                (size.x * size.y) as usize,
                "one height per texel"
            );
            (Some(*size), heights.clone())
        },
    );
}
