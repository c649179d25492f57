//! `DistanceFieldAmbientOcclusion` in a running app: a sphere caster floating over a
//! plane, seen from above. The AO debug view (linear HDR capture) equals the CPU model
//! (`penumbra_reference::dfao::pixel_ao` on the same caster) on the plane's pixels, the
//! plane is occluded under the sphere and open far from it; with shading, only the
//! indirect light darkens (a camera without the component renders the plane brighter
//! under the sphere, a direct light's contribution is the same). With a global distance
//! field the cones' far part goes through it, as the far-field model's does. A sphere's
//! volume placed as sparse bricks occludes as the same volume placed dense.

use bevy::camera::Hdr;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::pbr::DefaultOpaqueRendererMethod;
use bevy::prelude::*;
use penumbra::prelude::*;
use penumbra_df_core::ao::AoTrace;
use penumbra_df_core::cull::CameraOrigin;
use penumbra_df_core::object::{CasterShape, ObjectDesc, encode, flags};
use penumbra_reference::analytic_volume;
use penumbra_reference::df::Atlas;
use penumbra_reference::dfao::pixel_ao;
use penumbra_test::{CaptureFormat, HeadlessRender, gpu_or_skip};

const SIZE: u32 = 64;
const EYE: Vec3 = Vec3::new(0.0, 3.0, 4.0);
const FOV_DEG: f32 = 45.0;
const SPHERE: Vec3 = Vec3::new(0.3, 0.65, 0.0);
const RADIUS: f32 = 0.5;
const MAX_DISTANCE: f32 = 3.0;

#[derive(Resource, Clone)]
struct Setup {
    dfao: Option<DistanceFieldAmbientOcclusion>,
    global_field: Option<GlobalDistanceField>,
    /// A terrain with a ridge beside the sphere ([`ridge`]), seen only by the
    /// distance fields.
    terrain: bool,
    /// The sphere occludes through a volume of its exact distances placed as sparse
    /// bricks (`Some(true)`) or dense, instead of as an analytic sphere.
    sphere_volume: Option<bool>,
}

/// The ridge terrain: 17 × 17 heights over 6 × 6 m centred at [`RIDGE`], 0.5 m below
/// the plane but for a ridge along z at its centre, 0.5 m above it.
fn ridge_heights() -> Vec<f32> {
    (0..17 * 17)
        .map(|i| {
            let x = (i % 17) as f32 * 6.0 / 16.0 - 3.0;
            -0.5 + (-(x / 0.6).powi(2)).exp()
        })
        .collect()
}

const RIDGE: Vec3 = Vec3::new(-1.6, 0.0, 0.0);

fn scene(
    setup: Res<Setup>,
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut images: ResMut<Assets<Image>>,
    mut sdfs: ResMut<Assets<SdfVolumeAsset>>,
) {
    let grey = materials.add(StandardMaterial {
        base_color: Color::srgb(0.7, 0.7, 0.7),
        perceptual_roughness: 1.0,
        ..default()
    });
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(20.0, 20.0))),
        MeshMaterial3d(grey.clone()),
    ));
    commands.spawn((
        Mesh3d(meshes.add(Sphere::new(RADIUS))),
        MeshMaterial3d(grey),
        Transform::from_translation(SPHERE),
        DistanceFieldCaster {
            source: match setup.sphere_volume {
                Some(_) => CasterSource::Sdf(sdfs.add(SdfVolumeAsset {
                    volume: analytic_volume::sphere_for_bricks(RADIUS),
                })),
                None => CasterSource::Sphere { radius: RADIUS },
            },
            ..default()
        },
    ));
    commands.insert_resource(GlobalAmbientLight {
        color: Color::WHITE,
        brightness: 2000.0,
        ..default()
    });
    let mut camera = commands.spawn((
        Camera3d::default(),
        PenumbraLighting,
        Hdr,
        Tonemapping::None,
        Projection::Perspective(PerspectiveProjection {
            fov: FOV_DEG.to_radians(),
            ..default()
        }),
        Transform::from_translation(EYE).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    if let Some(dfao) = setup.dfao.clone() {
        camera.insert(dfao);
    }
    if let Some(field) = setup.global_field.clone() {
        camera.insert(field);
    }
    if setup.terrain {
        use bevy::asset::RenderAssetUsages;
        use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
        let bytes = ridge_heights()
            .iter()
            .flat_map(|h| h.to_le_bytes())
            .collect();
        let heights = images.add(Image::new(
            Extent3d {
                width: 17,
                height: 17,
                depth_or_array_layers: 1,
            },
            TextureDimension::D2,
            bytes,
            TextureFormat::R32Float,
            RenderAssetUsages::MAIN_WORLD,
        ));
        commands.spawn((
            DistanceFieldHeightfield {
                heights,
                size: Vec2::splat(6.0),
                height_scale: 1.0,
            },
            Transform::from_translation(RIDGE),
        ));
    }
}

fn ray(i: u32, j: u32) -> Vec3 {
    let forward = (Vec3::ZERO - EYE).normalize();
    let right = forward.cross(Vec3::Y).normalize();
    let up = right.cross(forward);
    let t = (FOV_DEG.to_radians() * 0.5).tan();
    let x = ((i as f32 + 0.5) / SIZE as f32 * 2.0 - 1.0) * t;
    let y = (1.0 - (j as f32 + 0.5) / SIZE as f32 * 2.0) * t;
    (forward + x * right + y * up).normalize()
}

fn render(dfao: Option<DistanceFieldAmbientOcclusion>) -> Vec<[f32; 4]> {
    let render = HeadlessRender::new(SIZE, SIZE)
        .frames(6)
        .format(CaptureFormat::LinearF16);
    render
        .run(app(&render, dfao, None))
        .expect("headless render")
        .to_linear()
}

fn app(
    render: &HeadlessRender,
    dfao: Option<DistanceFieldAmbientOcclusion>,
    global_field: Option<GlobalDistanceField>,
) -> App {
    app_with(
        render,
        Setup {
            dfao,
            global_field,
            terrain: false,
            sphere_volume: None,
        },
    )
}

/// The scene of `setup` with `PenumbraPlugins`, deferred.
fn app_with(render: &HeadlessRender, setup: Setup) -> App {
    let mut app = render.app();
    app.add_plugins(PenumbraPlugins)
        .insert_resource(DefaultOpaqueRendererMethod::deferred())
        .insert_resource(setup)
        .add_systems(Startup, scene);
    app
}

/// Two 32³ clipmaps, 0.2 and 0.4 m texels.
fn small_global_field() -> GlobalDistanceField {
    GlobalDistanceField {
        clipmap_count: 2,
        resolution: 32,
        first_extent: 6.4,
        ..default()
    }
}

/// The plane's pixels, away from the sphere's silhouette: `(index, world point)`.
fn plane_pixels() -> Vec<(usize, Vec3)> {
    let mut out = Vec::new();
    for j in 0..SIZE {
        for i in 0..SIZE {
            let d = ray(i, j);
            let to_centre = SPHERE - EYE;
            let miss = (to_centre - d * to_centre.dot(d)).length();
            if miss < RADIUS + 0.1 || d.y >= 0.0 {
                continue;
            }
            out.push(((j * SIZE + i) as usize, EYE + d * (-EYE.y / d.y)));
        }
    }
    out
}

#[test]
fn dfao_matches_the_model_and_occludes_only_indirect_light() {
    if !gpu_or_skip("dfao_matches_the_model_and_occludes_only_indirect_light") {
        return;
    }
    let settings = DistanceFieldAmbientOcclusion {
        max_occlusion_distance: MAX_DISTANCE,
        trace_resolution_divisor: 1,
        // One frame's trace, as the model computes it.
        temporal_filter: false,
        debug_view: DistanceFieldAoDebugView::AmbientOcclusion,
        ..default()
    };
    let ao = render(Some(settings.clone()));
    let record = encode(&ObjectDesc {
        world_from_local: bevy::math::Affine3A::from_translation(SPHERE),
        shape: CasterShape::Sphere { radius: RADIUS },
        flags: flags::LIVE | flags::VISIBLE | flags::CASTS_OCCLUSION | flags::CASTS_SHADOWS,
    })
    .expect("encodes");
    let camera = CameraOrigin::at(EYE).expect("finite");
    let trace = AoTrace {
        max_distance: MAX_DISTANCE,
        cone_count: settings.cone_count,
        steps_per_cone: settings.steps_per_cone,
        bias: settings.surface_bias,
        shaping: penumbra_df_core::ao::CONE_SHAPING,
    };
    let atlas = Atlas::new(UVec3::ONE);
    let (mut sum, mut worst, mut n, mut under, mut open) = (0.0f32, 0.0f32, 0, 1.0f32, 0.0f32);
    for (k, p) in plane_pixels() {
        let want = pixel_ao(&[record], &atlas, &camera, p - EYE, Vec3::Y, &trace).ao;
        let got = ao[k][0];
        let e = (got - want).abs();
        sum += e;
        worst = worst.max(e);
        n += 1;
        if (p - Vec3::new(SPHERE.x, 0.0, SPHERE.z)).length() < 0.3 {
            under = under.min(got);
        }
        if (p - Vec3::new(SPHERE.x, 0.0, SPHERE.z)).length() > 2.5 {
            open = open.max(got);
        }
    }
    let mean = sum / n as f32;
    eprintln!(
        "AO view vs model over {n} plane pixels: mean |Δ| {mean:.4}, worst {worst:.4}; under the sphere {under:.3}, far {open:.3}"
    );
    // The G-buffer's normals (octahedral, 12-bit) and f16 storage only.
    assert!(mean < 0.01 && worst < 0.05, "mean {mean} worst {worst}");
    assert!(under < 0.6 && open > 0.98, "under {under} far {open}");

    // The defaults' path (half-resolution trace, jittered, temporally filtered over the
    // 6 frames): the filtered AO the lighting reads is the same field (a history pair
    // read before it is written, or the wrong pair bound, is far off).
    let filtered = render(Some(DistanceFieldAmbientOcclusion {
        trace_resolution_divisor: 2,
        // At 64² the default would trace every pixel: keep the half-resolution path.
        min_trace_rows: 0,
        temporal_filter: true,
        ..settings.clone()
    }));
    let (mut sum, mut worst, mut n) = (0.0f32, 0.0f32, 0);
    for (k, p) in plane_pixels() {
        let want = pixel_ao(&[record], &atlas, &camera, p - EYE, Vec3::Y, &trace).ao;
        let e = (filtered[k][0] - want).abs();
        sum += e;
        worst = worst.max(e);
        n += 1;
    }
    let mean = sum / n as f32;
    eprintln!(
        "temporally filtered half-resolution AO vs model: mean |Δ| {mean:.4}, worst {worst:.4}"
    );
    assert!(
        mean < 0.01 && worst < 0.15,
        "filtered: mean {mean} worst {worst}"
    );

    // Shading: ambient light only, so the occluded plane is darker than without DFAO
    // in proportion to the AO.
    let shaded = render(Some(DistanceFieldAmbientOcclusion {
        debug_view: DistanceFieldAoDebugView::None,
        ..settings
    }));
    let plain = render(None);
    let (mut ratio_error, mut m) = (0.0f32, 0);
    for (k, _) in plane_pixels() {
        if plain[k][1] > 1e-4 {
            ratio_error += (shaded[k][1] / plain[k][1] - ao[k][1]).abs();
            m += 1;
        }
    }
    let ratio_error = ratio_error / m as f32;
    eprintln!("shaded / plain vs AO over {m} pixels: mean |Δ| {ratio_error:.4}");
    assert!(
        ratio_error < 0.01,
        "indirect light is not scaled by the AO: {ratio_error}"
    );
}

/// With a `GlobalDistanceField` on the camera (two 32³ clipmaps, 0.2 and 0.4 m texels)
/// and the switch at 0.3 m, the AO view equals the far-field model
/// (`penumbra_reference::dfao::pixel_ao_far` through the model's composition of the
/// same caster): the app composes the clipmaps on the GPU, binds them and traces the
/// cones through them. The far part matters (the sphere's bottom is 0.15 m up: most of
/// it is beyond the switch; the objects alone up to 0.3 m leave the plane far lighter),
/// and removing the component removes the render world's clipmaps.
#[test]
fn dfao_traces_the_global_field_beyond_the_switch() {
    use penumbra_df_core::clipmap::ClipmapState;
    use penumbra_reference::dfao::{FarField, pixel_ao_far};
    use penumbra_reference::global_sdf::{ClipmapFormat, GlobalField};
    if !gpu_or_skip("dfao_traces_the_global_field_beyond_the_switch") {
        return;
    }
    let settings = DistanceFieldAmbientOcclusion {
        max_occlusion_distance: MAX_DISTANCE,
        trace_resolution_divisor: 1,
        temporal_filter: false,
        global_field_start: 0.3,
        debug_view: DistanceFieldAoDebugView::AmbientOcclusion,
        ..default()
    };
    let field_settings = small_global_field();
    let render = HeadlessRender::new(SIZE, SIZE)
        .frames(6)
        .without_pipelining()
        .format(CaptureFormat::LinearF16);
    let (capture, mut kept) = render
        .run_keeping_app(app(
            &render,
            Some(settings.clone()),
            Some(field_settings.clone()),
        ))
        .expect("headless render");
    let ao = capture.to_linear();

    let record = encode(&ObjectDesc {
        world_from_local: bevy::math::Affine3A::from_translation(SPHERE),
        shape: CasterShape::Sphere { radius: RADIUS },
        flags: flags::LIVE | flags::VISIBLE | flags::CASTS_OCCLUSION | flags::CASTS_SHADOWS,
    })
    .expect("encodes");
    let atlas = Atlas::new(UVec3::ONE);
    let (layout, _, _) = field_settings.resolve();
    let mut state = ClipmapState::new(layout);
    let mut field = GlobalField::new(layout, ClipmapFormat::Unorm8);
    for job in state.update(EYE, &[], usize::MAX).jobs {
        field.compose_records(job, &[record], &atlas);
    }
    let far = FarField::new(&field, &state, EYE.as_dvec3(), settings.global_field_start);
    let camera = CameraOrigin::at(EYE).expect("finite");
    let trace = AoTrace {
        max_distance: MAX_DISTANCE,
        cone_count: settings.cone_count,
        steps_per_cone: settings.steps_per_cone,
        bias: settings.surface_bias,
        shaping: penumbra_df_core::ao::CONE_SHAPING,
    };
    let near = AoTrace {
        max_distance: settings.global_field_start,
        ..trace
    };
    let (mut sum, mut worst, mut n, mut far_matters, mut apart) = (0.0f32, 0.0f32, 0, 0, 0);
    for (k, p) in plane_pixels() {
        let (want, _, _) = pixel_ao_far(&[record], &atlas, &camera, p - EYE, Vec3::Y, &trace, &far);
        let near_only = pixel_ao(&[record], &atlas, &camera, p - EYE, Vec3::Y, &near).ao;
        far_matters += usize::from(near_only - want.ao > 0.1);
        let e = (ao[k][0] - want.ao).abs();
        sum += e;
        worst = worst.max(e);
        apart += usize::from(e > 0.02);
        n += 1;
    }
    let mean = sum / n as f32;
    eprintln!(
        "AO view with the global field vs the far-field model over {n} plane pixels: mean |Δ| {mean:.4}, worst {worst:.4}, {apart} apart by > 0.02; {far_matters} pixels darkened by the far part"
    );
    assert!(
        far_matters > 50,
        "the far part hardly matters: {far_matters}"
    );
    // The G-buffer's normals and f16 storage; a field sample on the edge of the
    // receiver-plane rule may flip a cone (one pixel in this scene).
    assert!(
        mean < 0.01 && apart * 100 <= n,
        "mean {mean}, {apart} apart"
    );

    let fields = |app: &mut App| {
        let world = app.sub_app_mut(bevy::render::RenderApp).world_mut();
        world
            .query::<&penumbra::df::global_field::ViewGlobalField>()
            .iter(world)
            .map(|f| f.backlog())
            .collect::<Vec<_>>()
    };
    assert_eq!(
        fields(&mut kept),
        [0],
        "one camera's clipmaps, all composed"
    );
    let camera = kept
        .world_mut()
        .query_filtered::<Entity, With<Camera3d>>()
        .single(kept.world())
        .unwrap();
    kept.world_mut()
        .entity_mut(camera)
        .remove::<GlobalDistanceField>();
    for _ in 0..3 {
        kept.update();
    }
    assert!(fields(&mut kept).is_empty(), "clipmaps left behind");
}

/// Removing the component stops the passes: the render-world view loses its AO input
/// (and with it the trace, the upsample and the lighting pass's occlusion); adding it
/// back restores them.
#[test]
fn removing_dfao_removes_its_passes() {
    if !gpu_or_skip("removing_dfao_removes_its_passes") {
        return;
    }
    let render = HeadlessRender::new(SIZE, SIZE)
        .frames(4)
        .without_pipelining();
    let mut app = render.app();
    app.add_plugins(PenumbraPlugins)
        .insert_resource(DefaultOpaqueRendererMethod::deferred())
        .insert_resource(Setup {
            dfao: Some(DistanceFieldAmbientOcclusion::default()),
            global_field: None,
            terrain: false,
            sphere_volume: None,
        })
        .add_systems(Startup, scene);
    let (_, mut app) = render.run_keeping_app(app).expect("headless render");
    let inputs = |app: &mut App| {
        let world = app.sub_app_mut(bevy::render::RenderApp).world_mut();
        world
            .query::<&penumbra::df::lighting::PenumbraAoInput>()
            .iter(world)
            .count()
    };
    assert_eq!(inputs(&mut app), 1, "the DFAO camera has its input");
    let camera = app
        .world_mut()
        .query_filtered::<Entity, With<Camera3d>>()
        .single(app.world())
        .unwrap();
    app.world_mut()
        .entity_mut(camera)
        .remove::<DistanceFieldAmbientOcclusion>();
    for _ in 0..3 {
        app.update();
    }
    assert_eq!(
        inputs(&mut app),
        0,
        "a camera without DFAO keeps no AO input"
    );
    app.world_mut()
        .entity_mut(camera)
        .insert(DistanceFieldAmbientOcclusion::default());
    for _ in 0..3 {
        app.update();
    }
    assert_eq!(
        inputs(&mut app),
        1,
        "the input comes back with the component"
    );
}

/// The objects-per-tile view: with a 0.5 m max distance (influence 0.78 m) the one
/// caster is kept by the tiles around it and by no tile far from it; the view shows the
/// heat ramp's colour for 1 (dark blue) and for 0 (black), and nothing else (the
/// temporal filter is on in the settings, off in this view). AO shown instead, or a count that
/// includes the plane-less background, fails it.
#[test]
fn objects_per_tile_view_shows_the_tiles_counts() {
    if !gpu_or_skip("objects_per_tile_view_shows_the_tiles_counts") {
        return;
    }
    let heat = render(Some(DistanceFieldAmbientOcclusion {
        max_occlusion_distance: 0.5,
        // 8×8-pixel tiles (at 64² a half-resolution tile is a quarter of the view).
        trace_resolution_divisor: 1,
        debug_view: DistanceFieldAoDebugView::ObjectsPerTile,
        ..default()
    }));
    // The ramp at t = log2(2) / 8: 5/8 of the way from black to blue.
    let one = [0.0, 0.0, 0.625];
    let (mut near, mut far, mut other) = (0, 0, 0);
    for (k, p) in plane_pixels() {
        let c = heat[k];
        let is = |want: [f32; 3]| (0..3).all(|a| (c[a] - want[a]).abs() < 0.02);
        let from_sphere = (p - Vec3::new(SPHERE.x, 0.0, SPHERE.z)).length();
        if from_sphere < 0.5 {
            assert!(is(one), "under the sphere {c:?}");
            near += 1;
        } else if from_sphere > 2.8 {
            assert!(
                is([0.0; 3]),
                "far from the sphere ({from_sphere:.2} m) {c:?}"
            );
            far += 1;
        } else {
            // Upsampled tile edges blend the two.
            assert!(c[0] < 0.02 && c[1] < 0.02, "not a count of 0 or 1: {c:?}");
            other += 1;
        }
    }
    eprintln!("objects per tile: {near} pixels show 1, {far} show 0, {other} between");
    assert!(near > 20 && far > 100, "near {near} far {far}");
}

/// A `DistanceFieldHeightfield` (a ridge beside the sphere, no mesh: only the distance
/// fields see it) with a `GlobalDistanceField` and the switch at 0.3 m: the AO view
/// equals the model with the terrain (`penumbra_reference::dfao::pixel_ao_with_terrain`:
/// the terrain's own cones up to the switch, the field — composed with the terrain on
/// the GPU — beyond). The terrain matters: without it the plane by the ridge is lighter.
#[test]
fn dfao_sees_terrains_near_and_through_the_global_field() {
    use penumbra_df_core::clipmap::ClipmapState;
    use penumbra_df_core::heightfield::{Heightfield, HeightfieldTexture};
    use penumbra_reference::dfao::{FarField, pixel_ao_with_terrain};
    use penumbra_reference::global_sdf::{ClipmapFormat, GlobalField};
    if !gpu_or_skip("dfao_sees_terrains_near_and_through_the_global_field") {
        return;
    }
    let settings = DistanceFieldAmbientOcclusion {
        max_occlusion_distance: MAX_DISTANCE,
        trace_resolution_divisor: 1,
        temporal_filter: false,
        global_field_start: 0.3,
        debug_view: DistanceFieldAoDebugView::AmbientOcclusion,
        ..default()
    };
    let field_settings = small_global_field();
    let render = HeadlessRender::new(SIZE, SIZE)
        .frames(6)
        .format(CaptureFormat::LinearF16);
    let mut app = app(
        &render,
        Some(settings.clone()),
        Some(field_settings.clone()),
    );
    app.insert_resource(Setup {
        dfao: Some(settings.clone()),
        global_field: Some(field_settings.clone()),
        terrain: true,
        sphere_volume: None,
    });
    let ao = render.run(app).expect("headless render").to_linear();

    let record = encode(&ObjectDesc {
        world_from_local: bevy::math::Affine3A::from_translation(SPHERE),
        shape: CasterShape::Sphere { radius: RADIUS },
        flags: flags::LIVE | flags::VISIBLE | flags::CASTS_OCCLUSION | flags::CASTS_SHADOWS,
    })
    .expect("encodes");
    let ridge = Heightfield::new(
        UVec2::splat(17),
        Vec2::new(RIDGE.x, RIDGE.z) - 3.0,
        Vec2::splat(6.0),
        ridge_heights(),
    )
    .expect("valid");
    let (terrain, _) = HeightfieldTexture::pack(&[&ridge], 4096);
    let atlas = Atlas::new(UVec3::ONE);
    let (layout, _, _) = field_settings.resolve();
    let compose = |terrain: &HeightfieldTexture| {
        let mut state = ClipmapState::new(layout);
        let mut field = GlobalField::new(layout, ClipmapFormat::Unorm8);
        for job in state.update(EYE, &[], usize::MAX).jobs {
            field.compose_records_and_terrain(job, &[record], &atlas, terrain);
        }
        (field, state)
    };
    let (field, state) = compose(&terrain);
    let none = HeightfieldTexture::default();
    let (bare_field, bare_state) = compose(&none);
    let far = FarField::new(&field, &state, EYE.as_dvec3(), settings.global_field_start);
    let bare = FarField::new(
        &bare_field,
        &bare_state,
        EYE.as_dvec3(),
        settings.global_field_start,
    );
    let camera = CameraOrigin::at(EYE).expect("finite");
    let trace = AoTrace {
        max_distance: MAX_DISTANCE,
        cone_count: settings.cone_count,
        steps_per_cone: settings.steps_per_cone,
        bias: settings.surface_bias,
        shaping: penumbra_df_core::ao::CONE_SHAPING,
    };
    let (mut sum, mut n, mut terrain_matters, mut apart) = (0.0f32, 0, 0, 0);
    for (k, p) in plane_pixels() {
        let model = |far, terrain| {
            pixel_ao_with_terrain(
                &[record],
                &atlas,
                &camera,
                p - EYE,
                Vec3::Y,
                &trace,
                Some(far),
                terrain,
            )
            .0
            .ao
        };
        let want = model(&far, &terrain);
        terrain_matters += usize::from(model(&bare, &none) - want > 0.1);
        let e = (ao[k][0] - want).abs();
        sum += e;
        apart += usize::from(e > 0.02);
        n += 1;
    }
    let mean = sum / n as f32;
    eprintln!(
        "AO view with a terrain vs the model over {n} plane pixels: mean |Δ| {mean:.4}, {apart} apart by > 0.02; {terrain_matters} pixels darkened by the terrain"
    );
    assert!(
        terrain_matters > 200,
        "the terrain hardly matters: {terrain_matters}"
    );
    assert!(mean < 0.01 && apart * 50 <= n, "mean {mean}, {apart} apart");
}

/// Skip: a DFAO camera without `GlobalDistanceField` allocates exactly what it does in an
/// app without `GlobalDistanceFieldPlugin` — buffers, bytes, textures and bind groups —
/// has no clipmaps in the render world and counts no brick; the same camera with the
/// component allocates its 8 MiB of clipmaps (so the counters see them).
#[test]
fn the_global_field_costs_nothing_without_its_component() {
    use bevy::app::PluginGroup;
    use penumbra::df::{GlobalDistanceFieldPlugin, GpuAllocationCounts, PenumbraGpuAllocations};
    if !gpu_or_skip("the_global_field_costs_nothing_without_its_component") {
        return;
    }
    let run = |plugin: bool, field: Option<GlobalDistanceField>| {
        let render = HeadlessRender::new(SIZE, SIZE)
            .frames(4)
            .without_pipelining();
        let mut app = render.app();
        let plugins = PenumbraPlugins.build();
        let plugins = if plugin {
            plugins
        } else {
            plugins.disable::<GlobalDistanceFieldPlugin>()
        };
        app.add_plugins(plugins)
            .insert_resource(DefaultOpaqueRendererMethod::deferred())
            .insert_resource(Setup {
                dfao: Some(DistanceFieldAmbientOcclusion::default()),
                global_field: field,
                terrain: false,
                sphere_volume: None,
            })
            .add_systems(Startup, scene);
        let (_, mut kept) = render.run_keeping_app(app).expect("headless render");
        let counts: GpuAllocationCounts =
            kept.world().resource::<PenumbraGpuAllocations>().counts();
        let world = kept.sub_app_mut(bevy::render::RenderApp).world_mut();
        let fields = world
            .query::<&penumbra::df::global_field::ViewGlobalField>()
            .iter(world)
            .count();
        let stats = kept
            .world()
            .get_resource::<GlobalDistanceFieldStats>()
            .copied()
            .unwrap_or_default();
        (counts, fields, stats)
    };
    let (without_plugin, _, _) = run(false, None);
    let (without_component, fields, stats) = run(true, None);
    let (with_component, with_fields, _) = run(true, Some(GlobalDistanceField::default()));
    println!(
        "allocations: no plugin {without_plugin:?}; plugin, no component {without_component:?}; \
         with the component {with_component:?}"
    );
    assert_eq!(without_component, without_plugin);
    assert_eq!((fields, stats), (0, GlobalDistanceFieldStats::default()));
    assert_eq!(with_fields, 1);
    assert!(
        with_component.buffer_bytes >= without_plugin.buffer_bytes + (8 << 20),
        "the clipmaps were not counted"
    );
}

/// The sphere as a volume placed as sparse bricks occludes the plane as the same volume
/// placed dense, by the objects alone and with the far part of the cones through the
/// global field (the AO pass and the global field's composition each bind the scene's
/// brick table and read through it).
#[test]
fn a_bricked_volume_occludes_as_a_dense_one() {
    if !gpu_or_skip("a_bricked_volume_occludes_as_a_dense_one") {
        return;
    }
    let render = HeadlessRender::new(SIZE, SIZE)
        .frames(6)
        .format(CaptureFormat::LinearF16);
    for global in [false, true] {
        check_bricked_against_dense(&render, global);
    }
}

/// [`a_bricked_volume_occludes_as_a_dense_one`], with or without the global field (two
/// 32³ clipmaps; the switch at 0.3 m: most of the sphere is beyond it).
fn check_bricked_against_dense(render: &HeadlessRender, global: bool) {
    let ao = |bricked: bool| {
        let mut app = app_with(
            render,
            Setup {
                dfao: Some(DistanceFieldAmbientOcclusion {
                    max_occlusion_distance: MAX_DISTANCE,
                    trace_resolution_divisor: 1,
                    temporal_filter: false,
                    global_field_start: 0.3,
                    debug_view: DistanceFieldAoDebugView::AmbientOcclusion,
                    ..default()
                }),
                global_field: global.then(small_global_field),
                terrain: false,
                sphere_volume: Some(bricked),
            },
        );
        app.insert_resource(DistanceFieldSceneSettings {
            sparse_min_bytes: if bricked { 0 } else { u64::MAX },
            ..default()
        });
        let (capture, app) = render.run_keeping_app(app).expect("headless render");
        let stats = app.world().resource::<DistanceFieldUploadStats>().clone();
        (
            capture.to_linear(),
            (stats.atlas_volumes, stats.atlas_bricked),
        )
    };
    let (dense, dense_counts) = ao(false);
    let (bricked, bricked_counts) = ao(true);
    assert_eq!((dense_counts, bricked_counts), ((1, 0), (1, 1)));
    let (mut sum, mut worst, mut occluded, mut apart, mut signed) = (0.0f32, 0.0f32, 0, 0, 0.0f32);
    let pixels = plane_pixels();
    for &(k, _) in &pixels {
        occluded += usize::from(dense[k][0] < 0.9);
        let e = (dense[k][0] - bricked[k][0]).abs();
        apart += usize::from(e > 0.02);
        signed += bricked[k][0] - dense[k][0];
        sum += e;
        worst = worst.max(e);
    }
    let mean = sum / pixels.len() as f32;
    eprintln!(
        "global field {global}: {} plane pixels, {occluded} under 0.9: |bricked − dense| AO \
         mean {mean:.2e}, worst {worst:.2e}, {apart} apart by > 0.02, signed mean {:.2e}",
        pixels.len(),
        signed / pixels.len() as f32
    );
    assert!(occluded > 50, "{occluded}");
    if global {
        // The composition stores the bricked sphere's lower bound beyond its band (up to
        // a voxel nearer) in 8-bit steps of the clipmaps' range: bricked reads a little
        // darker (measured: mean 3.0e-3, signed −2.9e-3, 2.7 % of pixels apart by more
        // than 0.02; with the empty table bound in the composition 3.8e-2 and 29 %).
        assert!(
            mean < 0.01 && apart * 20 <= pixels.len(),
            "mean {mean}, {apart} apart"
        );
    } else {
        assert!(mean < 2e-3 && worst < 0.05, "mean {mean}, worst {worst}");
    }
}
