//! Penumbra's scene viewer: any glTF 2.0 scene with distance-field lighting on.
//!
//! ```text
//! cargo run --release --example viewer -- SCENE.glb|.gltf       # a window, an egui panel
//! cargo run --release --example viewer                          # the showcase room
//! cargo run --release --example viewer -- SCENE.glb --headless --size 512x512 \
//!     --frames 10 --out shot.png --eye 0,2,6 --target 0,1,0 --fov 45 \
//!     --sun=-0.4,-1,-0.3 --angle 0.533 --point 1,3,0 --radius 0.1 \
//!     --ao-max-distance 2 --dump dump/
//! ```
//!
//! The scene's meshes become distance-field casters (`DistanceFieldSceneCasters` on its
//! root: skinned meshes cast through capsules fitted to their joints, double-sided and
//! alpha-masked materials two-sided; `--skinned`, `--animation N --time T` to pose them,
//! a ground under them unless `--no-ground`, `--ground` for any scene); the
//! camera is framed on the scene's bounds (or `--eye/--target/--fov`); a sun (`--sun`,
//! `--angle`), `--point` lights and the scene's own `KHR_lights_punctual` lights (unless
//! `--no-scene-lights`) get `DistanceFieldShadows`; `--ao-max-distance M` puts
//! `DistanceFieldAmbientOcclusion` (max occlusion distance M, defaults otherwise) on the
//! camera, `--bokeh N` scatter bokeh depth of field at f/N focused on the framed scene's
//! centre (`BokehDepthOfField`). The shadow settings given in metres
//! (ray length, view distance, bias) are scaled with the scene's size when it is larger
//! than 10 m, so scenes in centimetres or millimetres work as they are.
//!
//! Windowed: drag with the left button to orbit, the right to pan, scroll to zoom, `F`
//! for a fly camera (WASD, Q/E, right button to look); the panel edits every Penumbra
//! setting live, switches Penumbra off (plain Bevy, shadow maps) and shows Penumbra's
//! diagnostics and GPU pass times.
//!
//! Headless (`--headless`, or no display): renders `--frames` frames after every caster
//! is baked, writes `--out`, prints the mean frame time and Penumbra's pass times, and
//! with `--dump DIR` the view's buffers (`penumbra::df::buffer_dump`: `depth`, `normal`,
//! `visibility_<light>`, with DFAO `ao` and `bent_normal`) as float32 `.npy` arrays with
//! `DIR/meta.json`, for `../shared/tools/shadow_truth.py` and `ao_truth.py`. Bad flags exit with status 2 naming the flag; a
//! scene that cannot be loaded exits with status 1 and one error.

use bevy::camera::primitives::Aabb;
use bevy::camera::{Exposure, ShadowLodOrigin};
use bevy::diagnostic::DiagnosticsStore;
use bevy::light::GlobalAmbientLight;
use bevy::pbr::DefaultOpaqueRendererMethod;
use bevy::prelude::*;
use bevy::render::diagnostic::RenderDiagnosticsPlugin;
use bevy::world_serialization::WorldAssetRoot;
use penumbra::df::{
    DistanceFieldSceneCasters, PenumbraBufferDump, PenumbraBuffers, SceneCasterCounts,
    SdfBakeFailed, SdfBaked,
};
use penumbra::prelude::*;
use std::path::PathBuf;
use std::process::ExitCode;

#[path = "viewer/camera.rs"]
pub mod camera;
#[path = "viewer/cli.rs"]
pub mod cli;
#[path = "viewer/dump.rs"]
pub mod dump;
#[path = "viewer/fallback.rs"]
pub mod fallback;
#[path = "viewer/input.rs"]
pub mod input;
#[path = "viewer/lights.rs"]
pub mod lights;
#[path = "viewer/panel.rs"]
pub mod panel;
#[path = "viewer/pose.rs"]
pub mod pose;
#[allow(dead_code, reason = "only the showcase's scene is used")]
#[path = "showcase.rs"]
mod showcase;

use cli::Args;
use lights::{fit_shadow_bias, shadow_scene_lights, spawn_lights};

fn main() -> ExitCode {
    let args = match Args::parse_from_args(std::env::args_os()) {
        Ok(a) => a,
        Err(e) => {
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { 2 } else { 0 });
        }
    };
    if let Some(scene) = &args.scene
        && let Err(e) = input::check_scene(scene)
    {
        eprintln!("viewer: {e}");
        return ExitCode::from(1);
    }
    let display = ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|s| !s.is_empty()));
    let result = if args.headless || !display {
        run_headless(&args)
    } else {
        run_windowed(&args)
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("viewer: {e}");
            ExitCode::FAILURE
        }
    }
}

/// The command line, as a resource.
#[derive(Resource, Clone)]
pub struct ViewerArgs(pub Args);

/// The scene's root entity.
#[derive(Component)]
pub struct ViewerScene;

/// The viewer's camera.
#[derive(Component)]
pub struct ViewerCamera;

/// Where the viewer stands: the framing, once the scene is in.
#[derive(Resource, Clone, Copy, Debug)]
pub struct Framing {
    /// The scene's bounding box centre.
    pub center: Vec3,
    /// Half its diagonal.
    pub radius: f32,
    /// The camera's position.
    pub eye: Vec3,
    /// The point it looks at.
    pub target: Vec3,
    /// Vertical field of view, degrees.
    pub fov_deg: f32,
}

impl Framing {
    /// Metre-based settings are scaled by this (1 up to a 10 m scene).
    pub fn scale(&self) -> f32 {
        (self.radius / 10.0).max(1.0)
    }
}

/// When the app started, and how long until every caster had its SDF (bakes, or reads
/// of the disk cache, included).
#[derive(Resource)]
pub struct BakeClock(std::time::Instant, Option<std::time::Duration>);

/// A fatal error found while running (e.g. the scene failed to load).
#[derive(Resource, Default)]
pub struct ViewerError(pub Option<String>);

/// The app: Penumbra, the scene, lights and camera (headless and windowed alike).
fn add_viewer(app: &mut App, args: &Args) {
    app.add_plugins((
        PenumbraPlugins,
        penumbra::df::PenumbraDiagnosticsPlugin,
        RenderDiagnosticsPlugin,
    ))
    // Penumbra's lighting pass shades deferred materials (Bevy's switch, app-wide).
    .insert_resource(DefaultOpaqueRendererMethod::deferred())
    .insert_resource(ViewerArgs(args.clone()))
    // Room for scenes of many large meshes (a 256³ volume is 32 MiB) without the
    // atlas halving their resolution.
    .insert_resource(DistanceFieldSceneSettings {
        atlas_budget_bytes: 256 << 20,
        sparse_min_bytes: if args.dense {
            u64::MAX
        } else {
            DistanceFieldSceneSettings::default().sparse_min_bytes
        },
        ..default()
    })
    .init_resource::<ViewerError>()
    .insert_resource(BakeClock(std::time::Instant::now(), None))
    .add_systems(Startup, (spawn_scene, spawn_camera))
    .add_systems(
        Update,
        (
            watch_load,
            pose::pose_scene.run_if(|args: Res<ViewerArgs>| args.0.animation.is_some()),
            frame_scene.run_if(not(resource_exists::<Framing>)),
            shadow_scene_lights.run_if(resource_exists::<Framing>),
            fit_shadow_bias.run_if(resource_exists::<Framing>),
        )
            .chain(),
    );
    if let Some(resolution) = args.rebake {
        // Every skinned mesh re-baked on the GPU from its pose.
        app.add_systems(
            Update,
            move |mut commands: Commands,
                  skinned: Query<
                Entity,
                (
                    With<bevy::mesh::skinning::SkinnedMesh>,
                    Without<DistanceFieldRebake>,
                ),
            >| {
                for entity in &skinned {
                    commands.entity(entity).insert(DistanceFieldRebake {
                        resolution,
                        ..default()
                    });
                }
            },
        );
    }
    if args.scene.is_none() {
        app.add_plugins(showcase::ShowcaseScenePlugin)
            .add_systems(PostStartup, adopt_showcase);
    } else {
        app.insert_resource(ClearColor(Color::srgb(0.55, 0.7, 0.9)))
            .insert_resource(GlobalAmbientLight {
                color: Color::srgb(0.7, 0.8, 1.0),
                brightness: 120.0,
                ..default()
            });
    }
}

/// The asset root and file name of the scene.
fn scene_location(args: &Args) -> Option<(PathBuf, String)> {
    let path = args.scene.as_ref()?;
    let path = std::fs::canonicalize(path).unwrap_or_else(|_| path.clone());
    let dir = path.parent()?.to_path_buf();
    let file = path.file_name()?.to_string_lossy().into_owned();
    Some((dir, file))
}

fn spawn_scene(mut commands: Commands, args: Res<ViewerArgs>, assets: Res<AssetServer>) {
    let mut root = commands.spawn((
        ViewerScene,
        Name::new("scene"),
        Transform::default(),
        Visibility::default(),
    ));
    // Plain Bevy: no casters, no bakes, no atlas (the panel can add them later).
    if !args.0.plain {
        root.insert(DistanceFieldSceneCasters {
            two_sided: args.0.two_sided,
            skinned: if args.0.rebake.is_some() {
                SkinnedCasters::Skip
            } else {
                args.0.skinned
            },
            capsules: penumbra::df::SkinCapsuleFit {
                coverage: args
                    .0
                    .capsule_coverage
                    .unwrap_or(penumbra::df::SkinCapsuleFit::default().coverage),
                ..default()
            },
            caster: DistanceFieldCaster {
                resolution_scale: args.0.resolution_scale,
                ..default()
            },
            ..default()
        });
    }
    if let Some((_, file)) = scene_location(&args.0) {
        root.insert(WorldAssetRoot(
            assets.load(GltfAssetLabel::Scene(0).from_asset(file)),
        ));
    }
}

/// The showcase room: its meshes and lights go under the scene root, its camera is
/// replaced.
#[allow(clippy::type_complexity, reason = "a Bevy system")]
fn adopt_showcase(
    mut commands: Commands,
    root: Single<Entity, With<ViewerScene>>,
    meshes: Query<
        Entity,
        (
            Or<(
                With<Mesh3d>,
                With<DirectionalLight>,
                With<PointLight>,
                With<SpotLight>,
            )>,
            Without<ChildOf>,
        ),
    >,
    cameras: Query<Entity, (With<Camera3d>, Without<ViewerCamera>)>,
) {
    for mesh in &meshes {
        commands.entity(mesh).insert(ChildOf(*root));
    }
    for camera in &cameras {
        commands.entity(camera).despawn();
    }
}

/// A scene that fails to load is fatal (headless: exit 1; windowed: exit). A dependency
/// that fails (a texture in a format Bevy cannot decode, a missing image file) is not:
/// one warning, and the scene is drawn without it, as Bevy draws a material whose
/// texture is missing. A GLB whose embedded image fails fails whole in Bevy's loader:
/// it is loaded again without its textures, with one warning (`fallback`).
#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
fn watch_load(
    mut commands: Commands,
    root: Single<(Entity, &WorldAssetRoot), With<ViewerScene>>,
    assets: Res<AssetServer>,
    args: Res<ViewerArgs>,
    registry: Res<bevy::asset::io::embedded::EmbeddedAssetRegistry>,
    mut error: ResMut<ViewerError>,
    mut exit: MessageWriter<AppExit>,
    mut warned: Local<bool>,
    mut reloaded: Local<bool>,
) {
    if error.0.is_some() {
        return;
    }
    use bevy::asset::{LoadState, RecursiveDependencyLoadState};
    let (entity, root) = *root;
    let id = root.0.id();
    if let Some(LoadState::Failed(e)) = assets.get_load_state(id) {
        let message = e.to_string();
        if !*reloaded && fallback::is_image_error(&message) {
            *reloaded = true;
            let path = args.0.scene.clone().unwrap_or_default();
            match fallback::reload_untextured(&mut commands, entity, &path, &registry, &assets) {
                Ok(()) => {
                    warn!(
                        "viewer: an image embedded in the scene failed to decode ({message}): \
                         drawing the scene without its textures"
                    );
                    return;
                }
                Err(why) => {
                    error.0 = Some(format!("the scene failed to load: {message} ({why})"));
                    exit.write(AppExit::error());
                    return;
                }
            }
        }
        error.0 = Some(format!("the scene failed to load: {message}"));
        exit.write(AppExit::error());
    } else if let Some(RecursiveDependencyLoadState::Failed(_)) =
        assets.get_recursive_dependency_load_state(id)
        && !*warned
    {
        // Bevy's asset server has logged which file and why.
        *warned = true;
        warn!(
            "viewer: a texture or other part of the scene failed to load (see above): drawn without it"
        );
    }
}

/// Whether the scene and every dependency that could load have loaded (a failed texture
/// does not hold the scene back).
fn scene_loaded(assets: &AssetServer, id: impl Into<bevy::asset::UntypedAssetId>) -> bool {
    use bevy::asset::{LoadState, RecursiveDependencyLoadState};
    let id = id.into();
    matches!(assets.get_load_state(id), Some(LoadState::Loaded))
        && matches!(
            assets.get_recursive_dependency_load_state(id),
            Some(RecursiveDependencyLoadState::Loaded | RecursiveDependencyLoadState::Failed(_))
        )
}

/// The scene root: its glTF scene (none for the showcase) and what was tagged.
type RootQuery = (
    Entity,
    Option<&'static WorldAssetRoot>,
    Option<&'static SceneCasterCounts>,
);

/// Once the scene is spawned: its bounds, the camera, the sun and the `--point` lights.
#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
fn frame_scene(
    mut commands: Commands,
    args: Res<ViewerArgs>,
    root: Single<RootQuery, With<ViewerScene>>,
    children: Query<&Children>,
    meshes: Query<(&GlobalTransform, &Aabb), With<Mesh3d>>,
    skinned: Query<(), With<bevy::mesh::skinning::SkinnedMesh>>,
    assets: Res<AssetServer>,
    camera: Single<
        (
            Entity,
            &mut Transform,
            &mut Projection,
            &mut camera::CameraRig,
        ),
        With<ViewerCamera>,
    >,
    mut waited: Local<u32>,
    mut meshes_assets: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    let (root, handle, counts) = *root;
    let loaded = handle.is_none_or(|h| scene_loaded(&assets, h.0.id()));
    let boxes: Vec<(Vec3, Vec3)> = children
        .iter_descendants(root)
        .filter_map(|e| meshes.get(e).ok())
        .map(|(transform, aabb)| world_box(transform, aabb))
        .collect();
    let tagged = counts.is_some() || args.0.plain;
    if !loaded || (boxes.is_empty() || !tagged) && *waited < 30 {
        if loaded {
            *waited += 1;
        }
        return;
    }
    let (lo, hi) = if boxes.is_empty() {
        warn!("viewer: the scene has no meshes: rendering an empty frame");
        (Vec3::splat(-1.0), Vec3::splat(1.0))
    } else {
        boxes
            .iter()
            .fold((Vec3::MAX, Vec3::MIN), |(lo, hi), (a, b)| {
                (lo.min(*a), hi.max(*b))
            })
    };
    let args = &args.0;
    let center = (lo + hi) * 0.5;
    let radius = ((hi - lo).length() * 0.5).max(1e-3);
    let fov_deg = args.fov;
    let distance = radius / (fov_deg.to_radians() * 0.5).sin() * 1.05;
    let target = args.target.unwrap_or(center);
    let eye = args
        .eye
        .unwrap_or(target + Vec3::new(0.0, 0.35, 1.0).normalize() * distance);
    let framing = Framing {
        center,
        radius,
        eye,
        target,
        fov_deg,
    };
    commands.insert_resource(framing);
    let (camera, mut transform, mut projection, mut rig) = camera.into_inner();
    *transform = Transform::from_translation(framing.eye).looking_at(framing.target, Vec3::Y);
    *projection = Projection::Perspective(PerspectiveProjection {
        fov: framing.fov_deg.to_radians(),
        near: (framing.radius * 1e-3).min(0.1),
        ..default()
    });
    *rig = camera::CameraRig::new(framing.eye, framing.target);
    if args.ssao {
        commands
            .entity(camera)
            .insert(bevy::pbr::ScreenSpaceAmbientOcclusion::default());
    }
    if let Some(aperture_f_stops) = args.bokeh {
        commands.entity(camera).insert(BokehDepthOfField {
            focal_distance: framing.eye.distance(framing.target),
            aperture_f_stops,
            ..default()
        });
    }
    if !args.plain {
        commands.entity(camera).insert(PenumbraLighting);
        if let Some(max_occlusion_distance) = args.ao_max_distance {
            commands
                .entity(camera)
                .insert(DistanceFieldAmbientOcclusion {
                    max_occlusion_distance,
                    surface_bias: DistanceFieldAmbientOcclusion::default().surface_bias
                        * framing.scale(),
                    ..default()
                });
        }
    }
    spawn_lights(&mut commands, args, &framing);
    let character = children.iter_descendants(root).any(|e| skinned.contains(e));
    if args.ground || (character && !args.no_ground) {
        let ground = ViewerGround {
            center: Vec3::new(center.x, lo.y, center.z),
            half_size: 2.0 * radius,
        };
        commands.insert_resource(ground);
        commands.spawn((
            Name::new("viewer ground"),
            Mesh3d(meshes_assets.add(Plane3d::new(Vec3::Y, Vec2::splat(ground.half_size)))),
            MeshMaterial3d(materials.add(StandardMaterial {
                base_color: Color::srgb(0.6, 0.6, 0.6),
                perceptual_roughness: 0.9,
                ..default()
            })),
            Transform::from_translation(ground.center),
            DistanceFieldCaster {
                source: CasterSource::Plane,
                ..default()
            },
        ));
    }
}

/// `--ground`: the square under the scene (its centre on the bounds' bottom, half its
/// side).
#[derive(Resource, Clone, Copy, Debug)]
pub struct ViewerGround {
    /// Centre of the square, world space.
    pub center: Vec3,
    /// Half its side.
    pub half_size: f32,
}

/// The world-space box of a local box.
fn world_box(transform: &GlobalTransform, aabb: &Aabb) -> (Vec3, Vec3) {
    let affine = transform.affine();
    let center = affine.transform_point3(Vec3::from(aabb.center));
    let half = Mat3::from(affine.matrix3).abs() * Vec3::from(aabb.half_extents);
    (center - half, center + half)
}

/// The camera, from the start (a camera spawned later is not retargeted in time by the
/// headless harness); framed, and given Penumbra, once the scene is in.
fn spawn_camera(mut commands: Commands) {
    commands.spawn((
        ViewerCamera,
        Camera3d::default(),
        Projection::default(),
        // Bevy's deferred renderer (the app's default method) needs its prepasses; the
        // lighting pass is Bevy's own until the camera gets `PenumbraLighting`.
        bevy::core_pipeline::prepass::DepthPrepass,
        bevy::core_pipeline::prepass::DeferredPrepass,
        Msaa::Off,
        Exposure::default(),
        ShadowLodOrigin,
        Transform::default(),
        camera::CameraRig::new(Vec3::Z, Vec3::ZERO),
    ));
}

/// Whether the scene is framed and every caster has its SDF (or failed for good).
fn scene_ready(world: &mut World) -> bool {
    // A fatal error (the scene failed to load) ends the wait: `run_headless` reports it.
    if world.resource::<ViewerError>().0.is_some() {
        return true;
    }
    if !world.contains_resource::<Framing>() {
        return false;
    }
    // Mesh casters wait for their bake; a skinned mesh for its capsules' fit.
    let pending = world
        .query_filtered::<&DistanceFieldCaster, (Without<SdfBaked>, Without<SdfBakeFailed>)>()
        .iter(world)
        .filter(|c| c.source == CasterSource::Mesh)
        .count();
    let fitting = world
        .query::<&SceneCasterCounts>()
        .iter(world)
        .filter(|c| c.capsule_meshes > 0 && c.capsules == 0)
        .count();
    pending == 0 && fitting == 0
}

/// Renders headless (see the module docs); the error says why not.
pub fn run_headless(args: &Args) -> Result<(), String> {
    use penumbra_test::{HeadlessRender, vulkan_adapter};
    let Some(adapter) = vulkan_adapter() else {
        return Err(
            "no Vulkan adapter found. Install Mesa's software Vulkan driver, Debian \
                    package `mesa-vulkan-drivers`"
                .into(),
        );
    };
    let size = args.size.unwrap_or(UVec2::splat(512));
    let frames = args.frames.unwrap_or(10);
    let out = args.out.clone().unwrap_or_else(|| "viewer.png".into());
    let mut render = HeadlessRender::new(size.x, size.y).frames(frames);
    render.warm_up = Some(scene_ready);
    render.asset_root = scene_location(args).map(|(dir, _)| dir);
    let mut app = render.app();
    add_viewer(&mut app, args);
    let bake_start = std::time::Instant::now();
    let (capture, mut app) = render.run_keeping_app(app).map_err(|e| e.to_string())?;
    if let Some(e) = app.world_mut().resource_mut::<ViewerError>().0.take() {
        return Err(e);
    }
    // `--out` into a folder that does not exist yet makes it (as `--dump` does).
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    }
    capture
        .to_rgba8()
        .save(&out)
        .map_err(|e| format!("writing {}: {e}", out.display()))?;
    report(
        &mut app,
        args,
        &capture.frame_times,
        bake_start.elapsed(),
        adapter,
        size,
    );
    if let Some(dir) = &args.dump {
        let bytes = dump_buffers(&mut app, args, dir)?;
        println!("viewer: dump: {bytes} bytes in {}", dir.display());
    }
    println!("viewer: wrote {}", out.display());
    Ok(())
}

/// What `DistanceFieldSceneCasters` did to the scene.
fn scene_counts(world: &mut World) -> SceneCasterCounts {
    world
        .query::<&SceneCasterCounts>()
        .iter(world)
        .next()
        .copied()
        .unwrap_or_default()
}

/// What a headless run prints: frame time, casters, bakes, Penumbra's pass times.
fn report(
    app: &mut App,
    args: &Args,
    frame_times: &[std::time::Duration],
    total: std::time::Duration,
    adapter: &str,
    size: UVec2,
) {
    let steady = &frame_times[frame_times.len().min(1)..];
    let mean =
        steady.iter().map(|d| d.as_secs_f64()).sum::<f64>() * 1e3 / steady.len().max(1) as f64;
    let scene = args
        .scene
        .as_ref()
        .map_or("showcase room".into(), |p| p.display().to_string());
    println!(
        "viewer: {scene}: {} frames at {}x{} on {adapter}, Penumbra {}: mean frame time after \
         the first {mean:.1} ms (startup, bakes and frames {:.1} s)",
        frame_times.len(),
        size.x,
        size.y,
        if args.plain { "off" } else { "on" },
        total.as_secs_f64()
    );
    let world = app.world_mut();
    let counts = scene_counts(world);
    println!("viewer: casters {counts:?}");
    if let Some(baked) = world.resource::<BakeClock>().1 {
        println!(
            "viewer: every caster had its SDF {:.2} s after startup",
            baked.as_secs_f64()
        );
    }
    if let Some(stats) = world.get_resource::<penumbra::df::SdfBakeStats>() {
        println!("viewer: bakes {stats:?}");
    }
    if let Some(store) = world.get_resource::<DiagnosticsStore>() {
        for d in store.iter() {
            let path = d.path().as_str();
            // Pass times: the mean over the frames; counts: this frame's.
            let value = if path.starts_with("render/") {
                d.average()
            } else {
                d.value()
            };
            if (path.contains("penumbra") || path == "render/ssao/elapsed_gpu")
                && let Some(v) = value
            {
                println!("viewer: diagnostic {path} = {v:.3}{}", d.suffix);
            }
        }
    }
}

/// Asks the camera for its buffers, waits for them, writes them to `dir`.
fn dump_buffers(app: &mut App, args: &Args, dir: &std::path::Path) -> Result<u64, String> {
    let camera = {
        let world = app.world_mut();
        world
            .query_filtered::<Entity, With<ViewerCamera>>()
            .single(world)
            .map_err(|e| format!("no camera to dump: {e}"))?
    };
    app.world_mut()
        .entity_mut(camera)
        .insert(PenumbraBufferDump);
    let mut buffers = None;
    for _ in 0..60 {
        app.update();
        if let Some(b) = app.world_mut().entity_mut(camera).take::<PenumbraBuffers>() {
            buffers = Some(b);
            break;
        }
    }
    let buffers = buffers.ok_or("the buffer dump did not arrive in 60 frames (is Penumbra on?)")?;
    let framing = *app.world().resource::<Framing>();
    let world = app.world_mut();
    let mut lights = dump::light_summaries(world);
    // Without casters no mask is traced (nothing shadows): no buffer for the light.
    for light in &mut lights {
        if let Some(name) = light["buffer"].as_str()
            && buffers.get(name).is_none()
        {
            light["buffer"] = serde_json::Value::Null;
        }
    }
    let app_camera_ao = world.get::<DistanceFieldAmbientOcclusion>(camera).cloned();
    let atlas_used_bytes = world.get_resource::<DiagnosticsStore>().and_then(|store| {
        store
            .get(&penumbra::df::diagnostics::ATLAS_USED_BYTES)?
            .value()
    });
    let counts = scene_counts(world);
    let (baked, failed) = {
        let mut q = world
            .query_filtered::<(Has<SdfBaked>, Has<SdfBakeFailed>), With<DistanceFieldCaster>>();
        q.iter(world).fold((0, 0), |(b, f), (ok, bad)| {
            (b + u32::from(ok), f + u32::from(bad))
        })
    };
    let meta = dump::DumpMeta {
        scene: args
            .scene
            .as_ref()
            .map_or("showcase".into(), |p| p.display().to_string()),
        eye: framing.eye,
        target: framing.target,
        fov_deg: framing.fov_deg,
        lights,
        settings: serde_json::json!({
            "ground": world.get_resource::<ViewerGround>().map(|g| serde_json::json!({
                "center": g.center.to_array(),
                "half_size": g.half_size,
            })),
            "pose": args.animation.map(|animation| serde_json::json!({
                "animation": animation,
                "time": args.time.unwrap_or(0.0),
            })),
            "casters": {
                "casters": counts.casters,
                "two_sided": counts.two_sided,
                "ground": counts.ground,
                "solid_double_sided": counts.solid_double_sided,
                "shaded_apart": counts.shaded_apart,
                "merged_primitives": counts.merged,
                "capsule_meshes": counts.capsule_meshes,
                "capsules": counts.capsules,
                "skipped_skinned": counts.skinned,
                "rebaked": world
                    .query_filtered::<(), With<penumbra::df::RebakedFrom>>()
                    .iter(world)
                    .count(),
                "skipped_small": counts.small,
                "skipped_blended": counts.blended,
                "skipped_other": counts.unsupported,
            },
            "baked": baked,
            "failed_bakes": failed,
            "atlas_used_bytes": atlas_used_bytes,
            "metre_settings_scale": framing.scale(),
            "penumbra": !args.plain,
            "ambient_occlusion": dump::ao_summary(app_camera_ao.as_ref()),
        }),
    };
    dump::write_dump(dir, &buffers, &meta)
}

fn run_windowed(args: &Args) -> Result<(), String> {
    let size = args.size.unwrap_or(UVec2::new(1280, 720));
    let mut app = App::new();
    let mut assets = AssetPlugin::default();
    if let Some((dir, _)) = scene_location(args) {
        assets.file_path = dir.to_string_lossy().into_owned();
    }
    app.add_plugins(
        DefaultPlugins
            .set(WindowPlugin {
                primary_window: Some(Window {
                    title: "Penumbra viewer".into(),
                    resolution: bevy::window::WindowResolution::new(size.x, size.y),
                    ..default()
                }),
                ..default()
            })
            .set(assets),
    );
    add_viewer(&mut app, args);
    camera::add_camera_controls(&mut app);
    panel::add_panel(&mut app);
    if let Some(frames) = args.frames {
        app.add_systems(
            Update,
            move |mut n: Local<u32>, mut exit: MessageWriter<AppExit>| {
                *n += 1;
                if *n >= frames {
                    exit.write(AppExit::Success);
                }
            },
        );
    }
    let exit = app.run();
    if let Some(e) = app.world_mut().resource_mut::<ViewerError>().0.take() {
        return Err(e);
    }
    match exit {
        AppExit::Success => Ok(()),
        AppExit::Error(code) => Err(format!("exited with {code}")),
    }
}
