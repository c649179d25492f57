//! Property tests of the cinematic effects' settings (`resolve`), as
//! `bevy_penumbra_df/tests/settings_properties.rs` does for the distance-field ones:
//! settings drawn with NaN, infinities, zeros, negatives, subnormals and huge values
//! (`penumbra_testkit::Awkward`) never panic, resolve to finite values, resolve
//! idempotently, and draw a note whenever a value was changed or was not finite.

use bevy::color::Color;
use bevy_penumbra_cinematic::{
    BillboardReflections, BokehAperture, BokehDepthOfField, ReflectionDebugView, SubsurfaceProfile,
    SubsurfaceScattering,
};
use penumbra_testkit::{Awkward, assert_finite, has_non_finite};

const DRAWS: u32 = 4000;

#[test]
fn reflection_settings_resolve_to_finite_settings_with_a_note_per_change() {
    let mut a = Awkward::new(21);
    for _ in 0..DRAWS {
        let input = BillboardReflections {
            max_layers: a.u32(),
            max_distance: a.f32(),
            half_resolution: a.bool(),
            anisotropy: a.f32(),
            reflection_shadows: a.bool(),
            shadow_steps: a.u32(),
            shadow_softness: a.f32(),
            tile_culling: a.bool(),
            debug_view: if a.bool() {
                ReflectionDebugView::None
            } else {
                ReflectionDebugView::Layer
            },
        };
        let (fixed, notes) = input.resolve();
        assert_finite("BillboardReflections", &fixed, &input);
        let (again, more) = fixed.resolve();
        // Compared by their debug form (no `PartialEq`; `assert_finite` rules out NaN).
        let (fixed_text, input_text) = (format!("{fixed:?}"), format!("{input:?}"));
        assert_eq!(format!("{again:?}"), fixed_text, "not idempotent");
        assert!(
            more.is_empty(),
            "resolved settings still draw notes: {more:?}"
        );
        assert_eq!(
            fixed_text != input_text,
            !notes.is_empty(),
            "{input_text} → {fixed_text}: {notes:?}"
        );
    }
}

#[test]
fn depth_of_field_settings_resolve_to_a_finite_lens() {
    let mut a = Awkward::new(22);
    for _ in 0..DRAWS {
        let aperture = match a.below(3) {
            0 => BokehAperture::Hexagon,
            1 => BokehAperture::Circle,
            _ => BokehAperture::Polygon {
                sides: a.u32(),
                rotation: a.f32(),
            },
        };
        let input = BokehDepthOfField {
            focal_distance: a.f32(),
            aperture_f_stops: a.f32(),
            sensor_height: a.f32(),
            aperture,
            max_circle_of_confusion_diameter: a.f32(),
            max_depth: a.f32(),
            min_circle_of_confusion: a.f32(),
            merge_blocks: a.bool(),
            merge_groups: a.bool(),
            merge_coc_tolerance: a.f32(),
            merge_color_tolerance: a.f32(),
            merge_depth_tolerance: a.f32(),
            quarter_resolution_coc: a.f32(),
        };
        // The camera's field of view is Bevy's, not a setting: an ordinary one.
        let fov_y = 0.2 + 2.0 * (a.below(1000) as f32 / 1000.0);
        let (mut lens, rule, problems) = input.resolve(fov_y);
        // An unbounded depth range is documented (`max_depth` ≤ 0: infinity).
        assert!(lens.max_depth > 0.0, "{input:?}");
        lens.max_depth = 1.0;
        assert_finite("BokehDepthOfField lens", &lens, &input);
        // As is `quarter_resolution_coc = ∞` (every sprite at half resolution).
        let rule = format!("{rule:?}");
        let rule = if input.quarter_resolution_coc == f32::INFINITY {
            rule.replace("quarter_coc: inf", "quarter_coc: ∞")
        } else {
            rule
        };
        assert_finite("BokehDepthOfField sprite rule", &rule, &input);
        let mut quiet = input.clone();
        quiet.max_depth = if input.max_depth == f32::INFINITY {
            1.0
        } else {
            quiet.max_depth
        };
        if quiet.quarter_resolution_coc == f32::INFINITY {
            quiet.quarter_resolution_coc = 32.0;
        }
        if has_non_finite(&format!("{quiet:?}")) {
            assert!(
                !problems.is_empty(),
                "a non-finite setting drew no problem: {input:?}"
            );
        }
    }
}

#[test]
fn scattering_settings_resolve_to_finite_profiles() {
    let mut a = Awkward::new(23);
    for _ in 0..DRAWS {
        let input = SubsurfaceScattering {
            samples: a.u32(),
            ..Default::default()
        };
        let (samples, problem) = input.resolve();
        assert!((1..=SubsurfaceScattering::MAX_SAMPLES).contains(&samples));
        assert_eq!(problem.is_some(), samples != input.samples);

        let input = SubsurfaceProfile {
            scatter_color: Color::linear_rgb(a.f32(), a.f32(), a.f32()),
            radius: a.f32(),
        };
        let (profile, problems) = input.resolve();
        assert_finite("SubsurfaceProfile", &profile, &input);
        if has_non_finite(&format!("{input:?}")) {
            assert!(
                !problems.is_empty(),
                "a non-finite setting drew no problem: {input:?}"
            );
        }
    }
}

/// Aperture images of every format, size class and data length: read or refused with a
/// reason; never a panic, never a non-finite weight.
#[test]
fn aperture_images_of_every_format_and_size_are_read_or_refused() {
    penumbra_test::awkward_images::check_image_reader(
        "aperture images",
        32,
        bevy_penumbra_cinematic::dof::aperture_from_image,
        |aperture| {
            (
                None,
                [aperture.mean()]
                    .into_iter()
                    .chain(aperture.weights().iter().copied())
                    .collect(),
            )
        },
    );
}
