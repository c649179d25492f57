//! Cameras come and go with Penumbra's features on them: on the `df_shadows` example's
//! scene (distance-field shadows from a sun, a lamp and two small lamps), a
//! render-to-texture camera with DFAO, bokeh depth of field and billboard reflections is
//! spawned late, its image resized, then despawned; a second camera on the main target
//! with a viewport is spawned, turned off and despawned; a camera with those features
//! renders into a minimized (0×0) window that is restored and minimized again, then
//! both go; the main camera's viewport comes and goes. No panic and no wgpu error (the
//! harness fails a run on any); after the churn the main camera's image equals the same scene rendered without it, and
//! steady frames create no GPU resource.

#[path = "../examples/df_shadows.rs"]
#[allow(dead_code, reason = "the example's main is not used here")]
mod df_shadows;

use bevy::camera::{ImageRenderTarget, RenderTarget, Viewport};
use bevy::core_pipeline::tonemapping::DebandDither;
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureFormat, TextureUsages};
use penumbra::df::PenumbraGpuAllocations;
use penumbra::prelude::*;
use penumbra_test::{HeadlessRender, Tolerance, assert_images_match, gpu_or_skip};

const SIZE: UVec2 = UVec2::new(96, 96);
/// Frames the churn takes; both runs render this many plus a few steady ones.
const CHURN_FRAMES: u32 = 14;

#[derive(Component)]
struct Extra;

#[derive(Resource)]
struct Texture(Handle<Image>);

/// A window that is minimized (0×0, as winit reports a minimized window on Windows and
/// Bevy writes into `Window::resolution`), restored and minimized again, and the camera
/// with Penumbra's features that renders into it. No display here: the window has no
/// surface, so what is checked is everything up to presenting (the main world's and
/// the render world's handling of a camera whose target has no pixels, and of its
/// target growing and shrinking).
#[derive(Component)]
struct Minimized;

fn set_physical_size(window: &mut Window, size: UVec2) {
    window.resolution.set_physical_resolution(size.x, size.y);
}

/// Penumbra's camera features, on the extra cameras.
fn features() -> impl Bundle {
    (
        DistanceFieldAmbientOcclusion::default(),
        BokehDepthOfField::default(),
        BillboardReflections::default(),
        DebandDither::Disabled,
    )
}

/// The minimized window's life (see [`Minimized`]), frame by frame.
#[allow(clippy::type_complexity, reason = "a Bevy system's parameters")]
fn minimize(
    mut frame: Local<u32>,
    mut commands: Commands,
    transforms: Query<&Transform, (With<Camera3d>, Without<Extra>, Without<Minimized>)>,
    mut minimized: Query<(Entity, Option<&mut Window>, Option<&Camera>), With<Minimized>>,
    mut resized: MessageWriter<bevy::window::WindowResized>,
) {
    *frame += 1;
    let Ok(transform) = transforms.single().copied() else {
        return;
    };
    // The minimized window: 0×0 at 3, restored to 64×48 at 5, 0×0 again at 7, gone
    // with its camera at 10 (each resize told as winit tells it: `WindowResized`).
    let mut resize_window = |size: UVec2| {
        for (entity, window, _) in &mut minimized {
            if let Some(mut window) = window {
                set_physical_size(&mut window, size);
                resized.write(bevy::window::WindowResized {
                    window: entity,
                    width: window.width(),
                    height: window.height(),
                });
            }
        }
    };
    match *frame {
        3 => {
            let mut window = Window::default();
            set_physical_size(&mut window, UVec2::ZERO);
            let window = commands.spawn((Minimized, window)).id();
            commands.spawn((
                Minimized,
                Camera3d::default(),
                Camera {
                    order: 3,
                    ..default()
                },
                RenderTarget::Window(bevy::window::WindowRef::Entity(window)),
                PenumbraLighting,
                Msaa::Off,
                transform,
                features(),
            ));
        }
        5 => resize_window(UVec2::new(64, 48)),
        7 => resize_window(UVec2::ZERO),
        4 | 6 | 8 => {
            // The camera sees its window's size (nothing to render while minimized).
            let size = minimized
                .iter()
                .find_map(|(_, _, camera)| camera.map(Camera::physical_target_size));
            let expected = if *frame == 6 {
                Some(UVec2::new(64, 48))
            } else {
                Some(UVec2::ZERO)
            };
            assert_eq!(size, Some(expected), "frame {}", *frame);
        }
        10 => {
            for (entity, ..) in &minimized {
                commands.entity(entity).despawn();
            }
        }
        _ => {}
    }
}

#[allow(clippy::type_complexity, reason = "a Bevy system's parameters")]
fn churn(
    mut frame: Local<u32>,
    mut commands: Commands,
    mut images: ResMut<Assets<Image>>,
    texture: Option<Res<Texture>>,
    mut main: Query<&mut Camera, (With<Camera3d>, Without<Extra>, Without<Minimized>)>,
    mut extra: Query<(Entity, &mut Camera), With<Extra>>,
    transforms: Query<&Transform, (With<Camera3d>, Without<Extra>, Without<Minimized>)>,
) {
    *frame += 1;
    let Ok(transform) = transforms.single().copied() else {
        return;
    };
    match *frame {
        2 => {
            let mut image = Image::new_target_texture(64, 48, TextureFormat::Rgba16Float, None);
            image.texture_descriptor.usage |= TextureUsages::COPY_SRC;
            let handle = images.add(image);
            commands.insert_resource(Texture(handle.clone()));
            commands.spawn((
                Extra,
                Camera3d::default(),
                Camera {
                    order: -1,
                    ..default()
                },
                RenderTarget::Image(ImageRenderTarget::from(handle)),
                PenumbraLighting,
                Msaa::Off,
                transform,
                features(),
            ));
        }
        4 => {
            if let Some(mut image) = texture.and_then(|t| images.get_mut(&t.0)) {
                image.resize(Extent3d {
                    width: 80,
                    height: 40,
                    depth_or_array_layers: 1,
                });
            }
        }
        6 => {
            commands.spawn((
                Extra,
                Camera3d::default(),
                Camera {
                    order: 2,
                    viewport: Some(Viewport {
                        physical_position: UVec2::ZERO,
                        physical_size: SIZE / 2,
                        ..default()
                    }),
                    clear_color: ClearColorConfig::None,
                    ..default()
                },
                PenumbraLighting,
                Msaa::Off,
                transform,
                features(),
            ));
        }
        8 => {
            // The render-to-texture camera (the one without a viewport) goes.
            for (entity, camera) in &extra {
                if camera.viewport.is_none() {
                    commands.entity(entity).despawn();
                }
            }
        }
        9 => {
            for (_, mut camera) in &mut extra {
                camera.is_active = false;
            }
        }
        10 => {
            for (entity, _) in &extra {
                commands.entity(entity).despawn();
            }
        }
        11 => {
            for mut camera in &mut main {
                camera.viewport = Some(Viewport {
                    physical_position: UVec2::new(8, 8),
                    physical_size: UVec2::new(40, 32),
                    ..default()
                });
            }
        }
        12 => {
            for mut camera in &mut main {
                camera.viewport = None;
            }
        }
        _ => {}
    }
}

fn render(with_churn: bool) -> (penumbra_test::image::RgbaImage, penumbra_test::KeptApp) {
    let harness = HeadlessRender::new(SIZE.x, SIZE.y)
        .frames(CHURN_FRAMES + 6)
        .warm_up(df_shadows::casters_ready);
    let mut app = harness.app();
    df_shadows::add_scene(&mut app);
    app.add_systems(
        PostStartup,
        |mut commands: Commands, cameras: Query<Entity, With<Camera3d>>| {
            for camera in &cameras {
                commands.entity(camera).insert((
                    BokehDepthOfField::default(),
                    BillboardReflections::default(),
                    DebandDither::Disabled,
                ));
            }
        },
    );
    if with_churn {
        app.add_systems(Update, (churn, minimize));
    }
    let (capture, app) = harness.run_keeping_app(app).expect("renders");
    (capture.to_rgba8(), app)
}

#[test]
fn cameras_spawned_resized_and_despawned_leave_the_main_view_as_it_was() {
    if !gpu_or_skip("cameras_spawned_resized_and_despawned_leave_the_main_view_as_it_was") {
        return;
    }
    let (still, app) = render(false);
    drop(app);
    let (churned, mut app) = render(true);
    let cmp = assert_images_match("camera_life", &churned, &still, &Tolerance::GOLDEN);
    println!("main camera after the churn against no churn: {cmp}");
    let allocations = app.world().resource::<PenumbraGpuAllocations>().clone();
    let before = allocations.counts();
    for _ in 0..3 {
        app.update();
    }
    assert_eq!(
        allocations.counts(),
        before,
        "steady frames after the churn allocated"
    );
}
