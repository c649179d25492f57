//! Split screen: two `PenumbraLighting` cameras side by side on one render target (the
//! `df_shadows` example's scene, its sun, lamp and small lamps shadowed by distance
//! fields, with distance-field AO on both cameras). Each half equals that camera
//! rendered alone at half the width: the passes read the prepass textures (the target's
//! size) at the viewport's origin, compute positions in the viewport, and the lighting
//! pass reads the viewport-sized masks and AO at the fragment's viewport coordinates.
//! Before, the right-hand camera read the left camera's pixels and rendered almost black.
//! The same holds with subsurface scattering (`subsurface` example), billboard
//! reflections (`reflections` example) and scatter bokeh (`df_shadows` with
//! `BokehDepthOfField` on both cameras).

// Both examples include their shared `common/cli.rs` and `common/controls.rs`.
#![allow(
    clippy::duplicate_mod,
    reason = "two examples' scenes in one test binary"
)]

#[path = "../examples/df_shadows.rs"]
#[allow(dead_code, reason = "the example's main is not used here")]
mod df_shadows;

#[path = "../examples/subsurface.rs"]
#[allow(dead_code, reason = "the example's main is not used here")]
mod subsurface;

#[path = "../examples/reflections.rs"]
#[allow(dead_code, reason = "the example's main is not used here")]
mod reflections;

use bevy::camera::{Exposure, Viewport};
use bevy::core_pipeline::tonemapping::DebandDither;
use bevy::prelude::*;
use penumbra::prelude::*;
use penumbra_test::{
    HeadlessRender, Tolerance, assert_images_match, compare_rgba8, gpu_or_skip, image,
};

/// One half: the size each camera renders.
const HALF: UVec2 = UVec2::new(96, 96);

/// An example's scene.
#[derive(Clone, Copy)]
enum Scene {
    /// `df_shadows`, with DFAO added.
    Shadows,
    /// `subsurface`: a face under DF-shadowed lights with subsurface scattering.
    Subsurface,
    /// `reflections`: a wet street with billboard reflections.
    Reflections,
    /// `df_shadows` with DFAO and scatter bokeh.
    Bokeh,
}

/// What the copy of a scene's camera takes from it.
type CameraItem = (
    Entity,
    &'static Transform,
    &'static Projection,
    Option<&'static SubsurfaceScattering>,
    Option<&'static BillboardReflections>,
    Option<&'static Exposure>,
);

/// The scene's camera, alone at `HALF` (`split: false`) or beside a copy of itself on a
/// target twice as wide (`split: true`: viewports left and right).
fn render(scene: Scene, split: bool) -> image::RgbaImage {
    let width = if split { 2 * HALF.x } else { HALF.x };
    let harness = HeadlessRender::new(width, HALF.y).frames(12);
    let (harness, add_scene): (HeadlessRender, fn(&mut App)) = match scene {
        Scene::Shadows | Scene::Bokeh => (
            harness.warm_up(df_shadows::casters_ready),
            df_shadows::add_scene,
        ),
        Scene::Subsurface => (
            harness.warm_up(subsurface::casters_ready),
            subsurface::add_scene,
        ),
        Scene::Reflections => (
            harness.warm_up(reflections::casters_ready),
            reflections::add_scene,
        ),
    };
    let bokeh = matches!(scene, Scene::Bokeh).then(|| BokehDepthOfField {
        // Near the camera, wide open: the scene beyond blurs by up to ~20 px.
        focal_distance: 2.0,
        aperture_f_stops: 0.05,
        ..default()
    });
    let mut app = harness.app();
    add_scene(&mut app);
    app.add_systems(
        PostStartup,
        move |mut commands: Commands, cameras: Query<CameraItem, With<Camera3d>>| {
            let viewport = |x: u32| Viewport {
                physical_position: UVec2::new(x, 0),
                physical_size: HALF,
                ..default()
            };
            for (entity, transform, projection, sss, billboards, exposure) in &cameras {
                let mut camera = commands.entity(entity);
                // Bevy's debanding dither follows the frame buffer's coordinates (1/255
                // apart between the halves): off, so the halves can match exactly.
                camera.insert((
                    DistanceFieldAmbientOcclusion::default(),
                    DebandDither::Disabled,
                ));
                if let Some(bokeh) = &bokeh {
                    camera.insert(bokeh.clone());
                }
                if !split {
                    continue;
                }
                camera.insert(Camera {
                    viewport: Some(viewport(0)),
                    ..default()
                });
                let mut copy = commands.spawn((
                    Camera3d::default(),
                    Camera {
                        order: 1,
                        viewport: Some(viewport(HALF.x)),
                        // The first camera cleared the whole target.
                        clear_color: ClearColorConfig::None,
                        ..default()
                    },
                    PenumbraLighting,
                    Msaa::Off,
                    *transform,
                    projection.clone(),
                    DistanceFieldAmbientOcclusion::default(),
                    DebandDither::Disabled,
                ));
                if let Some(sss) = sss {
                    copy.insert(sss.clone());
                }
                if let Some(billboards) = billboards {
                    copy.insert(billboards.clone());
                }
                if let Some(exposure) = exposure {
                    copy.insert(*exposure);
                }
                if let Some(bokeh) = &bokeh {
                    copy.insert(bokeh.clone());
                }
            }
        },
    );
    harness.run(app).expect("renders").to_rgba8()
}

#[test]
fn each_half_of_a_split_screen_is_its_camera_alone() {
    if !gpu_or_skip("each_half_of_a_split_screen_is_its_camera_alone") {
        return;
    }
    halves_match(Scene::Shadows, "split_screen");
}

/// The same with subsurface scattering (its samples mapped into the viewport, its noise
/// seeded by the pixel's place in it) on the `subsurface` example's face.
#[test]
fn each_half_of_a_split_screen_scatters_as_its_camera_alone() {
    if !gpu_or_skip("each_half_of_a_split_screen_scatters_as_its_camera_alone") {
        return;
    }
    halves_match(Scene::Subsurface, "split_screen_sss");
}

/// The same with billboard reflections (the `reflections` example's wet street).
#[test]
fn each_half_of_a_split_screen_reflects_as_its_camera_alone() {
    if !gpu_or_skip("each_half_of_a_split_screen_reflects_as_its_camera_alone") {
        return;
    }
    halves_match(Scene::Reflections, "split_screen_reflections");
}

/// The same with scatter bokeh on both cameras (each blurs its own viewport only).
#[test]
fn each_half_of_a_split_screen_blurs_as_its_camera_alone() {
    if !gpu_or_skip("each_half_of_a_split_screen_blurs_as_its_camera_alone") {
        return;
    }
    halves_match(Scene::Bokeh, "split_screen_bokeh");
    // And the lens blurs something: the camera alone differs from the sharp scene.
    let cmp = compare_rgba8(
        &render(Scene::Bokeh, false),
        &render(Scene::Shadows, false),
        &Tolerance::GOLDEN,
    );
    assert!(!cmp.passed, "the bokeh blurs nothing: {cmp}");
}

fn halves_match(scene: Scene, name: &str) {
    let alone = render(scene, false);
    let split = render(scene, true);
    for (side, x) in [("left", 0), ("right", HALF.x)] {
        let half = image::imageops::crop_imm(&split, x, 0, HALF.x, HALF.y).to_image();
        let cmp = assert_images_match(&format!("{name}_{side}"), &half, &alone, &Tolerance::GOLDEN);
        println!("{name}: {side} half against the camera alone: {cmp}");
    }
}
