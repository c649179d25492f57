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

#[path = "stress.rs"]
mod stress;

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
            app.add_systems(PostStartup, stress::spawn_stress)
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
