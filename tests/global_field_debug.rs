//! The global field's debug views in a running app (lavapipe): a plane, a sphere and a
//! ball under a `GlobalDistanceField` camera with a `DistanceFieldDebugView` in
//! `GlobalField` and `ClipmapLevels` mode equal the CPU model
//! (`penumbra_reference::field_debug`) over the model's own composition of the same
//! casters; in `GlobalFieldUpdates` mode a still scene shows no update and the frame a
//! ball moves shows its bricks; without a `GlobalDistanceField` the modes leave the
//! image as it is.

use bevy::camera::Hdr;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::prelude::*;
use bevy::render::gpu_readback::{Readback, ReadbackComplete};
use penumbra::prelude::*;
use penumbra_df_core::clipmap::debug::FieldDebugMode;
use penumbra_df_core::clipmap::{ClipmapState, GlobalFieldView};
use penumbra_df_core::object::{CasterShape, ObjectDesc, encode, flags};
use penumbra_reference::df::Atlas;
use penumbra_reference::field_debug::{FieldDebugScene, field_debug_pixel};
use penumbra_reference::global_sdf::{ClipmapFormat, GlobalField};
use penumbra_test::harness::HarnessTarget;
use penumbra_test::{CaptureFormat, HeadlessRender, gpu_or_skip};

const SIZE: u32 = 64;
const EYE: Vec3 = Vec3::new(0.6, 2.4, 5.0);
const LOOK: Vec3 = Vec3::new(0.0, 0.5, 0.0);
const FOV: f32 = 0.9;
const SPHERE: (Vec3, f32) = (Vec3::new(-1.0, 1.0, -1.0), 1.0);
const BALL: (Vec3, f32) = (Vec3::new(1.2, 0.4, 0.5), 0.4);

fn field_settings() -> GlobalDistanceField {
    GlobalDistanceField {
        clipmap_count: 3,
        resolution: 64,
        first_extent: 12.8,
        ..default()
    }
}

#[derive(Resource, Clone)]
struct Setup {
    mode: Option<DistanceFieldDebugMode>,
    field: bool,
}

#[derive(Component)]
struct Ball;

fn scene(setup: Res<Setup>, mut commands: Commands) {
    let caster = |source| DistanceFieldCaster {
        source,
        ..default()
    };
    commands.spawn((caster(CasterSource::Plane), Transform::default()));
    commands.spawn((
        caster(CasterSource::Sphere { radius: SPHERE.1 }),
        Transform::from_translation(SPHERE.0),
    ));
    commands.spawn((
        Ball,
        caster(CasterSource::Sphere { radius: BALL.1 }),
        Transform::from_translation(BALL.0),
    ));
    let mut camera = commands.spawn((
        Camera3d::default(),
        Hdr,
        Tonemapping::None,
        Projection::Perspective(PerspectiveProjection {
            fov: FOV,
            ..default()
        }),
        Transform::from_translation(EYE).looking_at(LOOK, Vec3::Y),
    ));
    if let Some(mode) = setup.mode {
        camera.insert(DistanceFieldDebugView {
            mode,
            max_steps: 128,
            max_distance: 40.0,
        });
    }
    if setup.field {
        camera.insert(field_settings());
    }
}

fn app(render: &HeadlessRender, setup: Setup) -> App {
    let mut app = render.app();
    app.add_plugins(PenumbraPlugins)
        .insert_resource(setup)
        .add_systems(Startup, scene);
    app
}

fn render(setup: Setup) -> Vec<[f32; 4]> {
    let render = HeadlessRender::new(SIZE, SIZE)
        .frames(6)
        .format(CaptureFormat::LinearF16);
    render
        .run(app(&render, setup))
        .expect("headless render")
        .to_linear()
}

/// The model's image of the still scene (nothing composed this frame).
fn model(mode: FieldDebugMode) -> Vec<Vec3> {
    let record = |shape, at: Vec3| {
        encode(&ObjectDesc {
            world_from_local: bevy::math::Affine3A::from_translation(at),
            shape,
            flags: flags::LIVE | flags::VISIBLE | flags::CASTS_OCCLUSION | flags::CASTS_SHADOWS,
        })
        .expect("encodes")
    };
    let records = [
        record(CasterShape::Plane, Vec3::ZERO),
        record(CasterShape::Sphere { radius: SPHERE.1 }, SPHERE.0),
        record(CasterShape::Sphere { radius: BALL.1 }, BALL.0),
    ];
    let atlas = Atlas::new(UVec3::ONE);
    let (layout, _, _) = field_settings().resolve();
    let mut state = ClipmapState::new(layout);
    let mut field = GlobalField::new(layout, ClipmapFormat::Unorm8);
    for job in state.update(EYE, &[], usize::MAX).jobs {
        field.compose_records(job, &records, &atlas);
    }
    let view = GlobalFieldView::new(&state, EYE.as_dvec3());
    let valid = GlobalFieldView::valid_bits(&state);
    let updated = vec![0; valid.len()];
    let rotation = Transform::from_translation(EYE)
        .looking_at(LOOK, Vec3::Y)
        .rotation;
    let proj = Mat4::perspective_infinite_reverse_rh(FOV, 1.0, 0.1);
    let scene = FieldDebugScene {
        field: &field,
        view: &view,
        valid: &valid,
        updated: &updated,
        relative_from_clip: (proj * Mat4::from_quat(rotation.inverse())).inverse(),
        max_steps: 128,
        max_distance: 40.0,
    };
    (0..SIZE * SIZE)
        .map(|i| {
            let uv = Vec2::new((i % SIZE) as f32 + 0.5, (i / SIZE) as f32 + 0.5) / SIZE as f32;
            field_debug_pixel(&scene, mode, uv)
        })
        .collect()
}

fn orange(p: &[f32; 4]) -> bool {
    p[0] > 2.0 * p[2]
}

#[test]
fn global_field_views_match_the_model() {
    if !gpu_or_skip("global_field_views_match_the_model") {
        return;
    }
    for (mode, model_mode) in [
        (DistanceFieldDebugMode::GlobalField, FieldDebugMode::Shaded),
        (
            DistanceFieldDebugMode::ClipmapLevels,
            FieldDebugMode::Levels,
        ),
    ] {
        let got = render(Setup {
            mode: Some(mode),
            field: true,
        });
        let want = model(model_mode);
        let (mut sum, mut apart) = (0.0f32, 0);
        for (g, w) in got.iter().zip(&want) {
            let d = (Vec3::new(g[0], g[1], g[2]) - *w).abs().max_element();
            sum += d;
            apart += usize::from(d > 0.05);
        }
        let mean = sum / want.len() as f32;
        let colours = want
            .iter()
            .map(|w| (w.normalize_or_zero() * 8.0).round().as_ivec3().to_array())
            .collect::<std::collections::BTreeSet<_>>()
            .len();
        eprintln!(
            "{mode:?}: mean |Δ| {mean:.4} against the model, {apart} of {} pixels apart by \
             > 0.05 ({colours} hues)",
            want.len()
        );
        assert!(mean < 0.005 && apart * 100 <= want.len(), "{mean} {apart}");
    }
}

#[test]
fn the_update_view_shows_the_bricks_composed_this_frame() {
    if !gpu_or_skip("the_update_view_shows_the_bricks_composed_this_frame") {
        return;
    }
    let render = HeadlessRender::new(SIZE, SIZE)
        .frames(6)
        .without_pipelining()
        .format(CaptureFormat::LinearF16);
    let setup = Setup {
        mode: Some(DistanceFieldDebugMode::GlobalFieldUpdates),
        field: true,
    };
    let (capture, mut app) = render
        .run_keeping_app(app(&render, setup))
        .expect("headless render");
    let still = capture.to_linear().iter().filter(|p| orange(p)).count();

    #[derive(Resource, Default)]
    struct Back(Option<Vec<u8>>);
    let target = app.world().resource::<HarnessTarget>().0.clone();
    let mut ball = app
        .world_mut()
        .query_filtered::<&mut Transform, With<Ball>>();
    ball.single_mut(app.world_mut())
        .expect("one ball")
        .translation
        .z -= 1.0;
    app.init_resource::<Back>();
    app.world_mut().spawn(Readback::texture(target)).observe(
        |event: On<ReadbackComplete>, mut back: ResMut<Back>| {
            back.0.get_or_insert(event.data.clone());
        },
    );
    for _ in 0..3 {
        app.update();
    }
    let bytes = app
        .world_mut()
        .resource_mut::<Back>()
        .0
        .take()
        .expect("read back");
    let moved = bytes
        .chunks_exact(8)
        .map(|p| std::array::from_fn(|i| half_to_f32(u16::from_le_bytes([p[2 * i], p[2 * i + 1]]))))
        .filter(orange)
        .count();
    eprintln!("orange pixels: {still} in a still frame, {moved} the frame the ball moved");
    assert_eq!(still, 0, "nothing is composed in a still scene");
    assert!(moved > 200, "the moved ball's bricks: {moved}");
}

fn half_to_f32(h: u16) -> f32 {
    let sign = if h >> 15 == 1 { -1.0 } else { 1.0 };
    let exponent = i32::from((h >> 10) & 0x1f);
    let mantissa = f32::from(h & 0x3ff);
    sign * match exponent {
        0 => mantissa * 2f32.powi(-24),
        31 => f32::INFINITY,
        e => (1.0 + mantissa / 1024.0) * 2f32.powi(e - 15),
    }
}

#[test]
fn without_a_global_field_the_modes_leave_the_image_alone() {
    if !gpu_or_skip("without_a_global_field_the_modes_leave_the_image_alone") {
        return;
    }
    let plain = render(Setup {
        mode: None,
        field: false,
    });
    let debug = render(Setup {
        mode: Some(DistanceFieldDebugMode::ClipmapLevels),
        field: false,
    });
    assert!(plain == debug, "the image changed");
}
