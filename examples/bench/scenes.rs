//! The benchmark's scenes and the variants each is rendered in.
//!
//! A run is one scene in one variant: a fresh app, the scene, a camera with the
//! variant's components. Variants are Bevy's features or Penumbra's, one against the
//! other on the same scene: `bevy` (no Penumbra plugins: Bevy's deferred renderer with
//! shadow maps), `bevy-no-shadows` (the same without shadows), `penumbra-off` (Penumbra's plugins, no Penumbra component),
//! `penumbra` (the scene's Penumbra effects), and the counterparts `bevy-ssao`,
//! `forward-msaa4` / `deferred-msaa4`, `bevy-dof` / `scatter-bokeh`, `bevy-ssr`.

use super::samaritan::SamaritanScenePlugin;
use super::showcase::{ShowcaseCaster, ShowcaseScenePlugin};
use bevy::camera::primitives::Aabb;
use bevy::camera::{Exposure, Hdr, ShadowLodOrigin};
use bevy::core_pipeline::prepass::{DeferredPrepass, DepthPrepass};
use bevy::pbr::{DefaultOpaqueRendererMethod, ScreenSpaceAmbientOcclusion, ScreenSpaceReflections};
use bevy::post_process::dof::{DepthOfField, DepthOfFieldMode};
use bevy::prelude::*;

use bevy::world_serialization::WorldAssetRoot;
use penumbra::cinematic::hair::Strand;
use penumbra::cinematic::tessellation::shape_mesh;
use penumbra::prelude::*;
use penumbra_cinematic_core::tessellation::shapes;
use std::path::{Path, PathBuf};

/// A benchmark scene.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum SceneKind {
    /// The showcase room (built in code): 5 casters, a sun, a point and a spot light.
    Showcase,
    /// `CornellBox.glb`.
    Cornell,
    /// `DepthOfFieldExample.glb`, with Bevy's depth-of-field example's lens.
    Dof,
    /// `FlightHelmet/FlightHelmet.gltf`.
    Helmet,
    /// 1,000 mesh casters, 8 shadowed lights, DFAO with the global field, 100
    /// billboards, a head of hair and a tessellated rock.
    Stress,
    /// The flagship scene (`examples/samaritan.rs`, built in code): every Penumbra
    /// feature on one deferred 4× MSAA camera.
    Samaritan,
    /// `--characters N` walking Foxes (`Fox.glb`) on a ground: capsules or re-bakes
    /// (`bench/characters.rs`).
    Characters,
}

impl SceneKind {
    /// Every scene, in report order.
    pub const ALL: [SceneKind; 7] = [
        SceneKind::Showcase,
        SceneKind::Cornell,
        SceneKind::Dof,
        SceneKind::Helmet,
        SceneKind::Stress,
        SceneKind::Samaritan,
        SceneKind::Characters,
    ];

    /// The name on the command line and in the report.
    pub fn name(self) -> &'static str {
        match self {
            SceneKind::Showcase => "showcase",
            SceneKind::Cornell => "cornell",
            SceneKind::Dof => "dof",
            SceneKind::Helmet => "helmet",
            SceneKind::Stress => "stress",
            SceneKind::Samaritan => "samaritan",
            SceneKind::Characters => "characters",
        }
    }

    /// The glTF file under the scenes folder, if the scene is one.
    pub fn file(self) -> Option<&'static str> {
        match self {
            SceneKind::Cornell => Some("CornellBox.glb"),
            SceneKind::Dof => Some("DepthOfFieldExample.glb"),
            SceneKind::Helmet => Some("FlightHelmet/FlightHelmet.gltf"),
            SceneKind::Characters => Some(super::characters::FILE),
            SceneKind::Showcase | SceneKind::Stress | SceneKind::Samaritan => None,
        }
    }

    /// The variants this scene is rendered in.
    pub fn variants(self) -> &'static [Variant] {
        use Variant::*;
        match self {
            SceneKind::Showcase => &[
                Bevy,
                BevyNoShadows,
                PenumbraOff,
                Penumbra,
                BevySsao,
                ForwardMsaa4,
                DeferredMsaa4,
            ],
            SceneKind::Cornell | SceneKind::Helmet => &[Bevy, BevyNoShadows, Penumbra, BevySsao],
            SceneKind::Dof => &[Bevy, BevyDof, ScatterBokeh, ScatterBokehHalf],
            SceneKind::Stress => &[Bevy, BevyNoShadows, Penumbra, BevySsr],
            // Its own camera and lights: every feature, or none of Penumbra's.
            SceneKind::Samaritan => &[PenumbraOff, Penumbra],
            SceneKind::Characters => &[
                Bevy,
                BevyNoShadows,
                PenumbraSkip,
                PenumbraBindPose,
                Penumbra,
                PenumbraRebake,
            ],
        }
    }
}

/// How a scene is rendered in one run.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Variant {
    /// Plain Bevy: no Penumbra plugins; deferred, shadow maps.
    Bevy,
    /// Plain Bevy with no light casting shadows (the shadow maps' cost is `bevy` less
    /// this: Bevy's shadow passes record no GPU span).
    BevyNoShadows,
    /// Penumbra's plugins added, no Penumbra component anywhere.
    PenumbraOff,
    /// The scene's Penumbra effects: distance-field shadows on every light, DFAO
    /// (the stress scene: with the global field, billboard reflections, hair,
    /// tessellation; the characters: cast by fitted capsules).
    Penumbra,
    /// `penumbra` with every skinned mesh's field re-baked on the GPU from its pose
    /// (`DistanceFieldRebake`), the characters scene's.
    PenumbraRebake,
    /// `penumbra` with every skinned mesh's field baked once in its bind pose
    /// (`SkinnedCasters::BindPose`), the characters scene's: what a static field costs
    /// (and misses) on a moving character.
    PenumbraBindPose,
    /// `penumbra` with skinned meshes not cast at all (`SkinnedCasters::Skip`), the
    /// characters scene's: the floor of the other methods' cost.
    PenumbraSkip,
    /// Plain Bevy with its SSAO.
    BevySsao,
    /// Bevy's forward renderer with 4× MSAA.
    ForwardMsaa4,
    /// Penumbra's deferred lighting with 4× MSAA (`DeferredMsaa`), shadow maps.
    DeferredMsaa4,
    /// Plain Bevy with its bokeh `DepthOfField`.
    BevyDof,
    /// Plain Bevy's renderer with Penumbra's scatter bokeh (`BokehDepthOfField`).
    ScatterBokeh,
    /// Scatter bokeh with every sprite at half resolution (`quarter_resolution_coc`
    /// at infinity): what the quarter-resolution layers save.
    ScatterBokehHalf,
    /// Plain Bevy with its screen-space reflections.
    BevySsr,
}

impl Variant {
    /// The name on the command line and in the report.
    pub fn name(self) -> &'static str {
        match self {
            Variant::Bevy => "bevy",
            Variant::BevyNoShadows => "bevy-no-shadows",
            Variant::PenumbraOff => "penumbra-off",
            Variant::Penumbra => "penumbra",
            Variant::PenumbraRebake => "penumbra-rebake",
            Variant::PenumbraBindPose => "penumbra-bind-pose",
            Variant::PenumbraSkip => "penumbra-skip",
            Variant::BevySsao => "bevy-ssao",
            Variant::ForwardMsaa4 => "forward-msaa4",
            Variant::DeferredMsaa4 => "deferred-msaa4",
            Variant::BevyDof => "bevy-dof",
            Variant::ScatterBokeh => "scatter-bokeh",
            Variant::ScatterBokehHalf => "scatter-bokeh-half",
            Variant::BevySsr => "bevy-ssr",
        }
    }

    /// Whether the app has Penumbra's plugins.
    pub fn penumbra_plugins(self) -> bool {
        matches!(
            self,
            Variant::PenumbraOff
                | Variant::Penumbra
                | Variant::PenumbraRebake
                | Variant::PenumbraBindPose
                | Variant::PenumbraSkip
                | Variant::DeferredMsaa4
                | Variant::ScatterBokeh
                | Variant::ScatterBokehHalf
        )
    }

    /// Whether lights get `DistanceFieldShadows` and meshes become casters.
    pub fn distance_fields(self) -> bool {
        matches!(
            self,
            Variant::Penumbra
                | Variant::PenumbraRebake
                | Variant::PenumbraBindPose
                | Variant::PenumbraSkip
        )
    }
}

/// What one run renders.
#[derive(Resource, Clone, Debug)]
pub struct Run {
    /// The scene.
    pub scene: SceneKind,
    /// The variant.
    pub variant: Variant,
    /// The characters scene's count.
    pub characters: u32,
    /// Where the glTF scenes are.
    pub scenes_dir: PathBuf,
}

/// The benchmark's camera.
#[derive(Component)]
pub struct BenchCamera;

/// The glTF scene's root.
#[derive(Component)]
struct SceneRoot;

/// Inserted once the camera is placed and the scene's lights configured.
#[derive(Resource, Clone, Copy, Debug)]
pub struct Framed {
    /// Metre settings are scaled by this (1 up to a 10 m scene).
    pub scale: f32,
    /// The camera's distance to the scene's far side.
    pub reach: f32,
}

/// Turns about its vertical axis every update (the stress scene's moving things).
#[derive(Component)]
struct Spin;

/// 0.02 rad per update, so runs are alike whatever the frame rate.
fn spin(mut spinning: Query<&mut Transform, With<Spin>>) {
    for mut t in &mut spinning {
        t.rotate_y(0.02);
    }
}

/// A light already given the variant's shadows.
#[derive(Component)]
struct Configured;

/// Adds `run`'s scene in `run`'s variant to `app` (built by the headless harness),
/// reading glTF scenes from the app's asset folder; `Err` when a scene's file cannot be
/// read.
pub fn add_scene(app: &mut App, run: &Run) -> Result<(), String> {
    if run.variant.penumbra_plugins() {
        // Penumbra's defaults, as a user gets them (the atlas budget included).
        app.add_plugins(PenumbraPlugins);
    }
    if run.variant != Variant::ForwardMsaa4 {
        app.insert_resource(DefaultOpaqueRendererMethod::deferred());
    }
    app.insert_resource(run.clone())
        .insert_resource(ClearColor(Color::srgb(0.55, 0.7, 0.9)))
        .add_systems(Startup, spawn_camera)
        .add_systems(
            Update,
            (
                frame_gltf.run_if(not(resource_exists::<Framed>)),
                configure_lights.run_if(resource_exists::<Framed>),
            )
                .chain(),
        );
    match run.scene {
        SceneKind::Showcase => {
            app.add_plugins(ShowcaseScenePlugin)
                .add_systems(PostStartup, adopt_showcase);
        }
        SceneKind::Stress => {
            app.add_systems(PostStartup, spawn_stress)
                .add_systems(Update, spin);
        }
        SceneKind::Samaritan => {
            app.add_plugins(SamaritanScenePlugin)
                .add_systems(PostStartup, adopt_samaritan);
        }
        SceneKind::Characters => super::characters::add(app, run, &run.scenes_dir)?,
        _ => {
            app.add_systems(Startup, spawn_gltf);
        }
    }
    Ok(())
}

/// Casters not yet in the distance-field scene (analytic ones enter at once, mesh
/// ones once baked) and not failed for good.
fn pending_casters(world: &mut World) -> usize {
    let casters: Vec<Entity> = world
        .query_filtered::<Entity, (With<DistanceFieldCaster>, Without<SdfBakeFailed>)>()
        .iter(world)
        .collect();
    // A glTF root under `DistanceFieldSceneCasters` whose meshes have not been judged yet
    // (its counts are all zero until they are), or whose skinned meshes' capsules are
    // not fitted yet.
    let roots = world
        .query_filtered::<Option<&SceneCasterCounts>, With<DistanceFieldSceneCasters>>()
        .iter(world)
        .filter(|c| {
            c.is_none_or(|c| {
                *c == SceneCasterCounts::default() || (c.capsule_meshes > 0 && c.capsules == 0)
            })
        })
        .count();
    // A re-baked mesh whose field's caster is not made yet (at its first bake).
    let rebakes = world
        .query_filtered::<(), (
            With<DistanceFieldRebake>,
            Without<penumbra::df::RebakeCaster>,
        )>()
        .iter(world)
        .count();
    let Some(scene) = world.get_resource::<DistanceFieldScene>() else {
        return casters.len() + roots + rebakes;
    };
    casters.iter().filter(|&&e| scene.slot(e).is_none()).count() + roots + rebakes
}

/// Whether the scene is framed and every caster is in the distance-field scene (or
/// failed for good).
pub fn scene_ready(world: &mut World) -> bool {
    world.contains_resource::<Framed>() && pending_casters(world) == 0
}

/// What [`scene_ready`] waits for, in words.
pub fn waiting_for(world: &mut World) -> String {
    if !world.contains_resource::<Framed>() {
        return "the scene to load".into();
    }
    format!("{} distance-field casters", pending_casters(world))
}

/// The camera: the variant's components, placed by the scene.
fn spawn_camera(mut commands: Commands, run: Res<Run>) {
    let mut camera = commands.spawn((
        BenchCamera,
        Camera3d::default(),
        Hdr,
        Exposure::default(),
        ShadowLodOrigin,
        Transform::from_xyz(0.0, 4.5, 8.25).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    let deferred = (DepthPrepass, DeferredPrepass);
    match run.variant {
        Variant::ForwardMsaa4 => {
            camera.insert(Msaa::Sample4);
        }
        Variant::DeferredMsaa4 => {
            camera.insert((
                Msaa::Sample4,
                deferred,
                PenumbraLighting,
                DeferredMsaa::default(),
            ));
        }
        v => {
            camera.insert((Msaa::Off, deferred));
            if v.distance_fields() {
                camera.insert((
                    PenumbraLighting,
                    DistanceFieldAmbientOcclusion {
                        max_occlusion_distance: 3.0,
                        ..default()
                    },
                ));
                if run.scene == SceneKind::Stress {
                    camera.insert((
                        GlobalDistanceField::default(),
                        BillboardReflections::default(),
                    ));
                }
            }
        }
    }
    // The depth-of-field example's lens.
    let (focal_distance, aperture_f_stops, max_depth) = (7.0, 1.0 / 8.0, 14.0);
    match run.variant {
        Variant::BevySsao => {
            camera.insert(ScreenSpaceAmbientOcclusion::default());
        }
        Variant::BevyDof => {
            camera.insert(DepthOfField {
                mode: DepthOfFieldMode::Bokeh,
                focal_distance,
                aperture_f_stops,
                max_depth,
                ..default()
            });
        }
        Variant::ScatterBokeh | Variant::ScatterBokehHalf => {
            let quarter_resolution_coc = if run.variant == Variant::ScatterBokehHalf {
                f32::INFINITY
            } else {
                BokehDepthOfField::default().quarter_resolution_coc
            };
            camera.insert(BokehDepthOfField {
                focal_distance,
                aperture_f_stops,
                max_depth,
                quarter_resolution_coc,
                ..default()
            });
        }
        Variant::BevySsr => {
            camera.insert(ScreenSpaceReflections::default());
        }
        _ => {}
    }
}

/// The showcase room under its own lights; its camera's place is taken by the bench's.
#[allow(clippy::type_complexity, reason = "a Bevy system")]
fn adopt_showcase(
    mut commands: Commands,
    run: Res<Run>,
    casters: Query<(Entity, &ShowcaseCaster)>,
    theirs: Query<(Entity, &Transform), (With<Camera3d>, Without<BenchCamera>)>,
    mut ours: Single<&mut Transform, With<BenchCamera>>,
) {
    for (entity, transform) in &theirs {
        **ours = *transform;
        commands.entity(entity).despawn();
    }
    if run.variant.distance_fields() {
        for (entity, ShowcaseCaster(source)) in &casters {
            commands.entity(entity).insert(DistanceFieldCaster {
                source: source.clone(),
                ..default()
            });
        }
    }
    commands.insert_resource(Framed {
        scale: 1.0,
        reach: 15.0,
    });
}

/// The flagship scene keeps its own camera (every feature on it) in place of the
/// bench's; `penumbra-off` takes Penumbra's components off it and its lights.
#[allow(clippy::type_complexity, reason = "a Bevy system")]
fn adopt_samaritan(
    mut commands: Commands,
    run: Res<Run>,
    theirs: Single<Entity, (With<Camera3d>, Without<BenchCamera>)>,
    ours: Single<Entity, With<BenchCamera>>,
    lights: Query<Entity, With<DistanceFieldShadows>>,
) {
    commands.entity(*ours).despawn();
    let mut camera = commands.entity(*theirs);
    camera.insert((BenchCamera, ShadowLodOrigin));
    if run.variant != Variant::Penumbra {
        camera
            .remove::<(
                PenumbraLighting,
                DeferredMsaa,
                DistanceFieldAmbientOcclusion,
                GlobalDistanceField,
                SubsurfaceScattering,
                BillboardReflections,
                BokehDepthOfField,
            )>()
            .insert(Msaa::Off);
        for light in &lights {
            commands.entity(light).remove::<DistanceFieldShadows>();
        }
    }
    commands.insert_resource(Framed {
        scale: 1.0,
        reach: 40.0,
    });
}

fn spawn_gltf(mut commands: Commands, run: Res<Run>, assets: Res<AssetServer>) {
    let file = run.scene.file().expect("a glTF scene");
    let mut root = commands.spawn((
        SceneRoot,
        Transform::default(),
        Visibility::default(),
        WorldAssetRoot(assets.load(GltfAssetLabel::Scene(0).from_asset(file))),
    ));
    if run.variant.distance_fields() {
        root.insert(DistanceFieldSceneCasters::default());
    }
    commands.insert_resource(GlobalAmbientLight {
        color: Color::srgb(0.7, 0.8, 1.0),
        brightness: 120.0,
        ..default()
    });
}

/// Once the glTF scene is in: the camera framed on its bounds (the depth-of-field scene
/// keeps its example's camera) and a sun.
#[allow(
    clippy::type_complexity,
    clippy::too_many_arguments,
    reason = "a Bevy system"
)]
fn frame_gltf(
    mut commands: Commands,
    run: Res<Run>,
    root: Option<Single<(Entity, &WorldAssetRoot), With<SceneRoot>>>,
    children: Query<&Children>,
    meshes: Query<(&GlobalTransform, &Aabb), With<Mesh3d>>,
    assets: Res<AssetServer>,
    mut camera: Single<&mut Transform, With<BenchCamera>>,
    mut waited: Local<u32>,
) {
    let Some(root) = root else {
        return;
    };
    let (root, handle) = *root;
    if !assets.is_loaded_with_dependencies(handle.0.id()) {
        if let Some(bevy::asset::RecursiveDependencyLoadState::Failed(e)) =
            assets.get_recursive_dependency_load_state(handle.0.id())
        {
            error!("penumbra-bench: {:?} failed to load: {e}", run.scene.file());
            commands.insert_resource(Framed {
                scale: 1.0,
                reach: 10.0,
            });
        }
        return;
    }
    let boxes: Vec<(Vec3, Vec3)> = children
        .iter_descendants(root)
        .filter_map(|e| meshes.get(e).ok())
        .map(|(t, aabb)| {
            let a = t.affine();
            let c = a.transform_point3(Vec3::from(aabb.center));
            let h = Mat3::from(a.matrix3).abs() * Vec3::from(aabb.half_extents);
            (c - h, c + h)
        })
        .collect();
    // Bounds are computed a frame or two after the meshes appear.
    if boxes.is_empty() && *waited < 30 {
        *waited += 1;
        return;
    }
    let (lo, hi) = boxes.iter().fold(
        (Vec3::splat(-1e-3), Vec3::splat(1e-3)),
        |(lo, hi), (a, b)| (lo.min(*a), hi.max(*b)),
    );
    let center = (lo + hi) * 0.5;
    let radius = ((hi - lo).length() * 0.5).max(1e-3);
    let mut reach = 2.0 * radius;
    if run.scene != SceneKind::Dof {
        let fov = PerspectiveProjection::default().fov;
        let distance = radius / (fov * 0.5).sin() * 1.05;
        let eye = center + Vec3::new(0.0, 0.35, 1.0).normalize() * distance;
        **camera = Transform::from_translation(eye).looking_at(center, Vec3::Y);
        reach += distance;
    } else {
        reach += camera.translation.distance(center);
    }
    commands.spawn(sun());
    commands.insert_resource(Framed {
        scale: (radius / 10.0).max(1.0),
        reach,
    });
}

/// The glTF scenes' and the characters' sun (its shadows are set by the variant).
pub fn sun() -> impl Bundle {
    (
        Name::new("sun"),
        DirectionalLight {
            illuminance: 8_000.0,
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::default().looking_to(Vec3::new(-0.4, -1.0, -0.3), Vec3::Y),
    )
}

/// Every light casts shadows (none in `bevy-no-shadows`): shadow maps, or
/// distance-field shadows in the `penumbra` variant (its settings scaled with the scene as the scene viewer's).
#[allow(clippy::type_complexity, reason = "a Bevy system")]
fn configure_lights(
    mut commands: Commands,
    run: Res<Run>,
    framed: Res<Framed>,
    mut lights: Query<
        (
            Entity,
            Option<&mut DirectionalLight>,
            Option<&mut PointLight>,
            Option<&mut SpotLight>,
        ),
        (
            Or<(With<DirectionalLight>, With<PointLight>, With<SpotLight>)>,
            Without<Configured>,
        ),
    >,
) {
    let shadows = run.variant != Variant::BevyNoShadows;
    for (entity, directional, point, spot) in &mut lights {
        let mut angle = 0.0;
        if let Some(mut l) = directional {
            l.shadow_maps_enabled = shadows;
            angle = 0.533f32.to_radians();
        }
        if let Some(mut l) = point {
            l.shadow_maps_enabled = shadows;
        }
        if let Some(mut l) = spot {
            l.shadow_maps_enabled = shadows;
        }
        let mut e = commands.entity(entity);
        e.insert(Configured);
        if run.variant.distance_fields() {
            let d = DistanceFieldShadows::default();
            e.insert(DistanceFieldShadows {
                angular_diameter: angle.max(d.angular_diameter),
                max_distance: d.max_distance * framed.scale,
                max_view_distance: (d.max_view_distance * framed.scale).max(framed.reach),
                bias: d.bias * framed.scale,
                ..d
            });
        }
    }
}

/// The stress scene: a 40 × 25 field of 1,000 mesh casters (five shapes, scaled and
/// turned) on a glossy ground, a sun and seven point lights, 100 emissive signs that are
/// reflection billboards, a head of hair and a tessellated rock near the camera. The
/// hair, the rock and ten casters turn every frame, so the per-frame work of a game
/// (object deltas, hair visibility, re-tessellation) is measured, not a still frame's.
#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
fn spawn_stress(
    mut commands: Commands,
    run: Res<Run>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut images: ResMut<Assets<Image>>,
    strands: Option<ResMut<Assets<HairStrands>>>,
    mut camera: Single<&mut Transform, With<BenchCamera>>,
) {
    let penumbra = run.variant.penumbra_plugins();
    let df = run.variant.distance_fields();
    **camera = Transform::from_xyz(0.0, 7.0, 38.0).looking_at(Vec3::new(0.0, 0.5, 0.0), Vec3::Y);
    let hash = |i: u32, salt: u32| {
        let mut x = i.wrapping_mul(0x9E37_79B9) ^ salt.wrapping_mul(0x85EB_CA6B);
        x ^= x >> 15;
        x = x.wrapping_mul(0x2C1B_3C6D);
        x ^= x >> 12;
        (x & 0xFFFF) as f32 / 65536.0
    };
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::new(Vec3::Y, Vec2::new(50.0, 40.0)))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.3, 0.3, 0.32),
            perceptual_roughness: 0.25,
            ..default()
        })),
        Transform::default(),
    ));
    let shapes_: [Mesh; 5] = [
        Cuboid::new(1.0, 1.0, 1.0).into(),
        Sphere::new(0.5).mesh().uv(32, 16),
        Torus::new(0.25, 0.5).into(),
        Cylinder::new(0.3, 1.2).into(),
        Capsule3d::new(0.3, 0.6).into(),
    ];
    let shape_handles: Vec<Handle<Mesh>> = shapes_.into_iter().map(|m| meshes.add(m)).collect();
    let palette: Vec<Handle<StandardMaterial>> = (0..8)
        .map(|i| {
            materials.add(StandardMaterial {
                base_color: Color::hsl(i as f32 * 45.0, 0.5, 0.55),
                perceptual_roughness: 0.6,
                ..default()
            })
        })
        .collect();
    for i in 0..1_000u32 {
        let (col, row) = (i % 40, i / 40);
        let at = Vec3::new(
            -39.0 + 2.0 * col as f32 + 0.6 * (hash(i, 1) - 0.5),
            0.6,
            -24.0 + 2.0 * row as f32 + 0.6 * (hash(i, 2) - 0.5),
        );
        let mut object = commands.spawn((
            Mesh3d(shape_handles[(i % 5) as usize].clone()),
            MeshMaterial3d(palette[(i % 8) as usize].clone()),
            Transform::from_translation(at)
                .with_rotation(Quat::from_rotation_y(std::f32::consts::TAU * hash(i, 3)))
                .with_scale(Vec3::splat(0.7 + 0.6 * hash(i, 4))),
        ));
        if df {
            object.insert(DistanceFieldCaster::default());
        }
        // A row near the camera turns: the object buffer takes deltas every frame.
        if row == 24 && col % 4 == 0 {
            object.insert(Spin);
        }
    }
    commands.spawn((
        DirectionalLight {
            illuminance: 6_000.0,
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::default().looking_to(Vec3::new(-0.4, -1.0, -0.5), Vec3::Y),
    ));
    for i in 0..7 {
        let x = -30.0 + 10.0 * i as f32;
        commands.spawn((
            PointLight {
                color: Color::hsl(i as f32 * 50.0, 0.6, 0.7),
                intensity: 200_000.0,
                range: 14.0,
                radius: 0.1,
                shadow_maps_enabled: true,
                ..default()
            },
            Transform::from_xyz(x, 4.0, 4.0 * ((i % 3) as f32 - 1.0)),
        ));
    }
    // 100 signs along the back and the sides, one image size for the billboard array.
    let sign_images: Vec<Handle<Image>> = (0..4).map(|i| images.add(sign_image(i))).collect();
    let quad = meshes.add(Rectangle::new(2.0, 1.0));
    for i in 0..100u32 {
        let (at, facing) = if i < 60 {
            (Vec3::new(-44.0 + 1.5 * i as f32, 2.0, -27.0), Vec3::Z)
        } else {
            let side = if i < 80 { -1.0 } else { 1.0 };
            let k = (i - 60) % 20;
            (
                Vec3::new(side * 44.0, 2.0, -24.0 + 2.5 * k as f32),
                Vec3::X * -side,
            )
        };
        let glow = 4.0;
        let mut sign = commands.spawn((
            Mesh3d(quad.clone()),
            MeshMaterial3d(materials.add(StandardMaterial {
                base_color: Color::BLACK,
                emissive: LinearRgba::rgb(glow, glow * 0.5, glow * 0.8),
                ..default()
            })),
            Transform::from_translation(at).looking_to(-facing, Vec3::Y),
        ));
        if penumbra {
            sign.insert(ReflectionBillboard {
                image: sign_images[(i % 4) as usize].clone(),
                size: Vec2::new(2.0, 1.0),
                emissive: glow,
            });
        }
    }
    if let (true, Some(mut strands)) = (penumbra, strands) {
        let skin = materials.add(StandardMaterial {
            base_color: Color::srgb(0.72, 0.5, 0.4),
            perceptual_roughness: 0.55,
            ..default()
        });
        let head = Vec3::new(-1.0, 1.6, 30.0);
        commands.spawn((
            Mesh3d(meshes.add(Sphere::new(1.0).mesh().uv(48, 32))),
            MeshMaterial3d(skin),
            Transform::from_translation(head).with_scale(HEAD),
        ));
        commands.spawn((
            Hair {
                strands: strands.add(HairStrands::new(head_strands(HEAD))),
                ..default()
            },
            Transform::from_translation(head),
            Spin,
        ));
        commands.spawn((
            Mesh3d(meshes.add(shape_mesh(&shapes::rock(32, 8)))),
            MeshMaterial3d(materials.add(StandardMaterial {
                base_color: Color::srgb(0.62, 0.58, 0.52),
                perceptual_roughness: 0.85,
                ..default()
            })),
            Transform::from_xyz(2.5, 0.8, 28.0),
            Tessellated::default(),
            Spin,
        ));
    }
    commands.insert_resource(Framed {
        scale: 1.0,
        reach: 80.0,
    });
}

/// The stress scene's head: an ellipsoid's semi-axes, metres.
const HEAD: Vec3 = Vec3::new(0.078, 0.105, 0.092);

/// 9,000 short strands (4 segments, 4–6 cm) over the head's upper two thirds, combed
/// back and down: as many points as the hair example's head.
fn head_strands(head: Vec3) -> Vec<Strand> {
    let n = 9_000u32;
    (0..n)
        .filter_map(|i| {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            if y < -0.3 {
                return None;
            }
            let r = (1.0 - y * y).max(0.0).sqrt();
            let phi = i as f32 * 2.399_963;
            let d = Vec3::new(r * phi.cos(), y, r * phi.sin());
            let normal = (d / head).normalize();
            let comb = Vec3::new(0.0, -0.8, -0.6).normalize();
            let along = (comb - normal * normal.dot(comb)).normalize_or(comb);
            let length = 0.04 + 0.02 * ((i * 7919) % 100) as f32 / 100.0;
            let root = d * head;
            let points = (0..=4)
                .map(|k| {
                    let s = k as f32 / 4.0;
                    root + (normal * 0.3 + along).normalize() * length * s + normal * 0.002 * s
                })
                .collect();
            Some(Strand {
                points,
                width: 0.0015,
                slot: i % 4,
            })
        })
        .collect()
}

/// A 64 × 32 sign: bars of one of four colours.
fn sign_image(i: u32) -> Image {
    use bevy::asset::RenderAssetUsages;
    use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
    let colour = [
        [255, 60, 90],
        [60, 200, 255],
        [255, 200, 60],
        [120, 255, 120],
    ][i as usize % 4];
    let mut data = Vec::with_capacity(64 * 32 * 4);
    for y in 0..32 {
        for x in 0..64 {
            let on = (x / 8 + y / 8 + i).is_multiple_of(2);
            let c = if on { colour } else { [20, 20, 24] };
            data.extend([c[0], c[1], c[2], 255]);
        }
    }
    Image::new(
        Extent3d {
            width: 64,
            height: 32,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        data,
        TextureFormat::Rgba8UnormSrgb,
        RenderAssetUsages::default(),
    )
}

/// The scenes folder: `--scenes DIR`, else `scenes/` beside the executable (the packed
/// benchmark), else `../shared/scenes` beside the checkout.
pub fn scenes_dir(flag: Option<&Path>) -> PathBuf {
    if let Some(dir) = flag {
        return dir.to_path_buf();
    }
    if let Some(beside) = std::env::current_exe()
        .ok()
        .and_then(|exe| Some(exe.parent()?.join("scenes")))
        .filter(|d| d.is_dir())
    {
        return beside;
    }
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes")
}
