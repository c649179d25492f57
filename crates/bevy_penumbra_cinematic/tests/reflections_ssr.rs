//! Billboard reflections beside Bevy's screen-space reflections (a comparison, not a
//! contract): a smooth floor (perceptual roughness 0.15, fully in SSR's range) under two
//! lit signs, one in view and one above the frame. The light each adds to the floor,
//! against the same camera without signs: Penumbra's billboards reflect both; SSR, which
//! marches the screen, reflects only the sign it can see.
//!
//! `cargo test -p bevy_penumbra_cinematic --test reflections_ssr -- --nocapture`

use bevy::asset::RenderAssetUsages;
use bevy::camera::{Exposure, Hdr};
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::pbr::{DefaultOpaqueRendererMethod, ScreenSpaceReflections};
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use bevy_penumbra_cinematic::{
    BillboardReflections, BillboardReflectionsPlugin, ReflectionBillboard,
};
use bevy_penumbra_df::{PenumbraLighting, PenumbraLightingPlugin};
use penumbra_test::{CaptureFormat, HeadlessRender, gpu_or_skip};

const WIDTH: u32 = 128;
const HEIGHT: u32 = 96;
/// Sign luminance, cd/m² (exposure 1/1.2 below).
const LUMINANCE: f32 = 2.0;

#[derive(Clone, Copy, PartialEq, Debug)]
enum Reflections {
    Penumbra,
    Ssr,
}

#[derive(Clone, Copy, PartialEq, Debug)]
enum Signs {
    None,
    InView,
    AboveTheFrame,
}

fn sign_image() -> Image {
    Image::new_fill(
        Extent3d {
            width: 8,
            height: 4,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        &[255, 200, 80, 255],
        TextureFormat::Rgba8UnormSrgb,
        RenderAssetUsages::default(),
    )
}

#[allow(clippy::type_complexity, reason = "a Bevy system's parameters")]
fn scene(
    reflections: Reflections,
    signs: Signs,
) -> impl Fn(Commands, ResMut<Assets<Mesh>>, ResMut<Assets<StandardMaterial>>, ResMut<Assets<Image>>)
{
    move |mut commands, mut meshes, mut materials, mut images| {
        commands.spawn((
            Mesh3d(meshes.add(Plane3d::default().mesh().size(40.0, 40.0))),
            MeshMaterial3d(materials.add(StandardMaterial {
                base_color: Color::linear_rgb(0.05, 0.05, 0.05),
                perceptual_roughness: 0.15,
                ..default()
            })),
        ));
        let image = images.add(sign_image());
        let at = match signs {
            Signs::None => None,
            Signs::InView => Some(Vec3::new(0.0, 1.0, -6.0)),
            // 15° and more above the camera's horizon; the frame's top is at 11°.
            Signs::AboveTheFrame => Some(Vec3::new(0.0, 5.0, -8.0)),
        };
        if let Some(at) = at {
            // Bevy's deferred G-buffer keeps emissive unexposed: the visible quad carries
            // the exposed luminance (what both reflections see on screen).
            let shown = LUMINANCE / 1.2;
            commands.spawn((
                ReflectionBillboard {
                    image: image.clone(),
                    size: Vec2::new(3.0, 1.5),
                    emissive: LUMINANCE,
                },
                Mesh3d(meshes.add(Rectangle::new(3.0, 1.5))),
                MeshMaterial3d(materials.add(StandardMaterial {
                    base_color: Color::BLACK,
                    emissive: LinearRgba::rgb(shown, shown, shown),
                    emissive_texture: Some(image),
                    ..default()
                })),
                Transform::from_translation(at),
            ));
        }
        let mut camera = commands.spawn((
            Camera3d::default(),
            Hdr,
            Tonemapping::None,
            Msaa::Off,
            Exposure { ev100: 0.0 },
            Transform::from_xyz(0.0, 1.2, 3.0).looking_at(Vec3::new(0.0, 0.2, -2.0), Vec3::Y),
        ));
        match reflections {
            Reflections::Penumbra => {
                camera.insert((PenumbraLighting, BillboardReflections::default()));
            }
            Reflections::Ssr => {
                camera.insert(ScreenSpaceReflections::default());
            }
        }
    }
}

/// The floor's summed light (linear, below the horizon's row) of one render.
fn floor_light(reflections: Reflections, signs: Signs) -> (f32, Vec<[f32; 4]>) {
    let harness = HeadlessRender::new(WIDTH, HEIGHT)
        .format(CaptureFormat::LinearF16)
        .frames(6);
    let mut app = harness.app();
    app.add_plugins((
        PenumbraLightingPlugin::default(),
        BillboardReflectionsPlugin,
    ))
    .insert_resource(DefaultOpaqueRendererMethod::deferred())
    .insert_resource(GlobalAmbientLight {
        brightness: 0.0,
        ..default()
    })
    .add_systems(Startup, scene(reflections, signs));
    let (capture, _app) = harness.run_keeping_app(app).expect("renders");
    let image = capture.to_linear();
    // The floor below the in-view sign's bottom edge (rows from 60 % of the height).
    let sum = image[(WIDTH * HEIGHT * 6 / 10) as usize..]
        .iter()
        .map(|p| p[0] + p[1] + p[2])
        .sum();
    (sum, image)
}

#[test]
fn billboards_reflect_what_the_screen_does_not_show() {
    if !gpu_or_skip("billboards_reflect_what_the_screen_does_not_show") {
        return;
    }
    let mut added = Vec::new();
    for reflections in [Reflections::Penumbra, Reflections::Ssr] {
        let (base, _) = floor_light(reflections, Signs::None);
        for signs in [Signs::InView, Signs::AboveTheFrame] {
            let (light, _) = floor_light(reflections, signs);
            println!(
                "{reflections:?}, sign {signs:?}: the floor gains {:.2} (of {base:.2})",
                light - base
            );
            added.push(((reflections, signs), light - base));
        }
    }
    let gain = |r, s| {
        added
            .iter()
            .find(|(k, _)| *k == (r, s))
            .expect("measured")
            .1
    };
    // Both reflect the sign in view; only the billboards reflect the one above.
    assert!(gain(Reflections::Penumbra, Signs::InView) > 1.0);
    assert!(gain(Reflections::Ssr, Signs::InView) > 1.0);
    assert!(gain(Reflections::Penumbra, Signs::AboveTheFrame) > 1.0);
    assert!(
        gain(Reflections::Ssr, Signs::AboveTheFrame).abs()
            < 0.05 * gain(Reflections::Penumbra, Signs::AboveTheFrame),
        "SSR reflected a sign it cannot see"
    );
}
