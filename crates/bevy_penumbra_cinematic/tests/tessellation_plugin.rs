//! `TessellationPlugin` as a Bevy citizen, on lavapipe:
//!
//! - **Opt-in.** Without `Tessellated` nothing is made: no state, no buffer, no GPU
//!   allocation, the mesh untouched.
//! - **Bad input.** A line list, a mesh with a non-finite position and a skinned mesh are
//!   drawn untessellated; a mesh without normals is tessellated with computed normals; a
//!   mesh without UVs, or a displacement image of an unsupported format, is tessellated
//!   without displacement; `pixels_per_triangle ≤ 0` falls back to 16 and `max_level`
//!   above 6 is clamped.
//! - **Budget and pooling.** A pool too small for the view gets coarser factors (the
//!   GPU's bias read back, its output within the pool), and while the camera moves every
//!   frame — a new tessellation each frame — no Penumbra buffer, texture or bind group is
//!   created.
//! - **The LOD camera.** The factors follow a camera that draws the entity's
//!   `RenderLayers`, not a higher-order camera that does not.
//! - **A still scene is free.** Once the latest tessellation's totals are back, nothing is
//!   read back until the view changes again; one camera step is read back until its own
//!   totals are in.

use bevy::asset::RenderAssetUsages;
use bevy::image::Image;
use bevy::mesh::PrimitiveTopology;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::prelude::*;
use bevy::render::gpu_readback::{Readback, ReadbackComplete};
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use bevy::render::storage::ShaderBuffer;
use bevy_penumbra_cinematic::tessellation::TessellationState;
use bevy_penumbra_cinematic::{Tessellated, TessellationPlugin};
use bevy_penumbra_df::{GpuAllocationCounts, PenumbraGpuAllocations};
use penumbra_cinematic_core::tessellation::shapes::{height_map, rock};
use penumbra_cinematic_core::tessellation::uniform::TessellationUniform;
use penumbra_test::{HeadlessRender, gpu_or_skip};

mod tessellation_scene;
use tessellation_scene::{Totals, camera, mesh_of, read_totals};

fn heights(format: TextureFormat) -> Image {
    let bytes: Vec<u8> = height_map(16).iter().map(|h| (h * 127.0) as u8).collect();
    Image::new(
        Extent3d {
            width: 16,
            height: 16,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        bytes,
        format,
        RenderAssetUsages::default(),
    )
}

#[test]
fn without_the_component_nothing_is_made() {
    if !gpu_or_skip("without_the_component_nothing_is_made") {
        return;
    }
    let harness = HeadlessRender::new(32, 32).frames(3);
    let mut app = harness.app();
    app.add_plugins(TessellationPlugin).add_systems(
        Startup,
        |mut commands: Commands,
         mut meshes: ResMut<Assets<Mesh>>,
         mut materials: ResMut<Assets<StandardMaterial>>| {
            commands.spawn((
                Mesh3d(meshes.add(mesh_of(&rock(8, 3), true, true))),
                MeshMaterial3d(materials.add(StandardMaterial::default())),
            ));
            commands.spawn(camera(3.0));
        },
    );
    let (_, mut app) = harness.run_keeping_app(app).expect("renders");
    let world = app.world_mut();
    assert_eq!(world.query::<&TessellationState>().iter(world).count(), 0);
    assert_eq!(world.resource::<Assets<ShaderBuffer>>().len(), 0);
    assert_eq!(
        world.resource::<PenumbraGpuAllocations>().counts(),
        GpuAllocationCounts::default()
    );
}

#[derive(Resource)]
struct Cases(Vec<(&'static str, Entity, Handle<Mesh>)>);

#[test]
fn bad_input_is_skipped_or_repaired() {
    if !gpu_or_skip("bad_input_is_skipped_or_repaired") {
        return;
    }
    // Until the five that can be tessellated are (the three others never are).
    let harness = HeadlessRender::new(32, 32).frames(3).warm_up(|world| {
        world
            .query::<&TessellationState>()
            .iter(world)
            .filter(|s| s.latest_totals().is_some())
            .count()
            == 5
    });
    let mut app = harness.app();
    app.add_plugins(TessellationPlugin).add_systems(
        Startup,
        |mut commands: Commands,
         mut meshes: ResMut<Assets<Mesh>>,
         mut images: ResMut<Assets<Image>>,
         mut materials: ResMut<Assets<StandardMaterial>>,
         mut bindposes: ResMut<Assets<SkinnedMeshInverseBindposes>>| {
            let shape = rock(8, 3);
            let material = materials.add(StandardMaterial::default());
            let good = heights(TextureFormat::R8Unorm);
            let mut nan = shape.clone();
            nan.positions[3].x = f32::NAN;
            let mut lines = mesh_of(&shape, true, true);
            lines = Mesh::new(PrimitiveTopology::LineList, RenderAssetUsages::default())
                .with_inserted_attribute(
                    Mesh::ATTRIBUTE_POSITION,
                    lines.attribute(Mesh::ATTRIBUTE_POSITION).unwrap().clone(),
                );
            let skinned = mesh_of(&shape, true, true)
                .with_inserted_attribute(
                    Mesh::ATTRIBUTE_JOINT_INDEX,
                    bevy::mesh::VertexAttributeValues::Uint16x4(vec![
                        [0; 4];
                        shape.positions.len()
                    ]),
                )
                .with_inserted_attribute(
                    Mesh::ATTRIBUTE_JOINT_WEIGHT,
                    vec![[1.0f32, 0.0, 0.0, 0.0]; shape.positions.len()],
                );
            let map = images.add(good);
            let snorm = images.add(heights(TextureFormat::R8Snorm));
            let cases: Vec<(&'static str, Mesh, Tessellated)> = vec![
                ("lines", lines, Tessellated::default()),
                ("nan", mesh_of(&nan, true, true), Tessellated::default()),
                ("skinned", skinned, Tessellated::default()),
                (
                    "no normals",
                    mesh_of(&shape, false, true),
                    Tessellated::default(),
                ),
                (
                    "no uvs",
                    mesh_of(&shape, true, false),
                    Tessellated {
                        displacement: Some(map.clone()),
                        ..default()
                    },
                ),
                (
                    "snorm map",
                    mesh_of(&shape, true, true),
                    Tessellated {
                        displacement: Some(snorm),
                        ..default()
                    },
                ),
                (
                    "bad settings",
                    mesh_of(&shape, true, true),
                    Tessellated {
                        pixels_per_triangle: -1.0,
                        max_level: 9,
                        ..default()
                    },
                ),
                (
                    "good map",
                    mesh_of(&shape, true, true),
                    Tessellated {
                        displacement: Some(map),
                        ..default()
                    },
                ),
            ];
            let mut spawned = Vec::new();
            let joint = commands.spawn(Transform::default()).id();
            let skin = SkinnedMesh {
                inverse_bindposes: bindposes
                    .add(SkinnedMeshInverseBindposes::from(vec![Mat4::IDENTITY])),
                joints: vec![joint],
            };
            for (name, mesh, tessellated) in cases {
                let handle = meshes.add(mesh);
                let mut entity = commands.spawn((
                    Mesh3d(handle.clone()),
                    MeshMaterial3d(material.clone()),
                    tessellated,
                ));
                if name == "skinned" {
                    entity.insert(skin.clone());
                }
                spawned.push((name, entity.id(), handle));
            }
            commands.insert_resource(Cases(spawned));
            commands.spawn(camera(3.0));
        },
    );
    let (_, app) = harness.run_keeping_app(app).expect("renders");
    let world = app.world();
    for (name, entity, source) in &world.resource::<Cases>().0 {
        let state = world.get::<TessellationState>(*entity);
        let mesh = &world.get::<Mesh3d>(*entity).unwrap().0;
        match *name {
            "lines" | "nan" | "skinned" => {
                assert!(state.is_none(), "{name}: tessellated");
                assert_eq!(mesh, source, "{name}: its mesh was replaced");
            }
            _ => {
                let state = state.unwrap_or_else(|| panic!("{name}: not tessellated"));
                assert_eq!(mesh, state.output(), "{name}");
                let uniform = state.uniform().expect("a uniform");
                match *name {
                    "no normals" => assert!(state.input().computed_normals),
                    "no uvs" | "snorm map" => {
                        assert!(state.map().is_none() && uniform.map_levels == 0, "{name}");
                    }
                    "bad settings" => {
                        assert_eq!((uniform.pixels_per_triangle, uniform.max_level), (16.0, 6));
                    }
                    "good map" => assert_eq!(uniform.map_levels, 5),
                    _ => unreachable!(),
                }
            }
        }
    }
}

#[derive(Resource, Default)]
struct Log(Vec<GpuAllocationCounts>);

fn record(allocations: Res<PenumbraGpuAllocations>, mut log: ResMut<Log>) {
    log.0.push(allocations.counts());
}

/// The camera circles a step per frame: a new tessellation every frame.
fn circle(mut cameras: Query<&mut Transform, With<Camera3d>>, mut frame: Local<u32>) {
    *frame += 1;
    let angle = *frame as f32 * 0.05;
    for mut t in &mut cameras {
        *t = Transform::from_xyz(1.4 * angle.cos(), 1.0, 1.4 * angle.sin())
            .looking_at(Vec3::new(0.0, 0.3, 0.0), Vec3::Y);
    }
}

#[test]
fn an_over_budget_view_is_coarsened_and_moving_allocates_nothing() {
    if !gpu_or_skip("an_over_budget_view_is_coarsened_and_moving_allocates_nothing") {
        return;
    }
    const FRAMES: u32 = 10;
    let harness = HeadlessRender::new(256, 256)
        .frames(FRAMES)
        .warm_up(|world| {
            world
                .resource::<Totals>()
                .0
                .as_ref()
                .is_some_and(|t| t[3] > 0)
        });
    let mut app = harness.app();
    app.add_plugins(TessellationPlugin)
        .init_resource::<Totals>()
        .init_resource::<Log>()
        .add_systems(
            Startup,
            |mut commands: Commands,
             mut meshes: ResMut<Assets<Mesh>>,
             mut materials: ResMut<Assets<StandardMaterial>>| {
                commands.spawn((
                    Mesh3d(meshes.add(mesh_of(&rock(16, 6), true, true))),
                    MeshMaterial3d(materials.add(StandardMaterial::default())),
                    // Below the input's 192 triangles: raised to them.
                    Tessellated {
                        pixels_per_triangle: 2.0,
                        max_triangles: 10,
                        ..default()
                    },
                ));
                commands.spawn(camera(1.4));
            },
        )
        .add_systems(Update, (circle, read_totals))
        .add_systems(Last, record);
    let (_, mut app) = harness.run_keeping_app(app).expect("renders");
    let world = app.world();
    let totals = world.resource::<Totals>().0.clone().expect("read back");
    let mut states = world.try_query::<&TessellationState>().unwrap();
    let state = states.iter(world).next().expect("tessellated");
    let (vertex_budget, index_budget) = state.budget();
    println!(
        "pool: {vertex_budget} vertices, {index_budget} indices; GPU bias {}, output {} vertices, {} indices",
        totals[0], totals[1], totals[2]
    );
    assert_eq!(
        index_budget,
        3 * 192,
        "the budget is raised to the input's triangles"
    );
    assert!(totals[0] > 0, "not coarsened");
    assert!(totals[1] <= vertex_budget && totals[2] <= index_budget);
    let log = &world.resource::<Log>().0;
    let steady = &log[log.len() - FRAMES as usize + 3..];
    assert_eq!(
        *steady.last().unwrap() - steady[0],
        GpuAllocationCounts::default(),
        "{steady:?}"
    );
    // Despawning the entity stops the plugin's read-back of its totals (the test's own
    // stays).
    let world = app.world_mut();
    let readbacks = |world: &mut World| {
        world
            .query_filtered::<(), With<Readback>>()
            .iter(world)
            .count()
    };
    let before = readbacks(world);
    let rock = world
        .query_filtered::<Entity, With<Tessellated>>()
        .single(world)
        .unwrap();
    world.despawn(rock);
    app.update();
    assert_eq!(readbacks(app.world_mut()), before - 1);
}

/// Which camera draws the rock.
#[derive(Resource, Clone, Copy, PartialEq)]
struct Path {
    deferred: bool,
    tessellated: bool,
}

/// The rock's silhouette (pixels not the clear colour) as one camera draws it.
fn silhouette(path: Path) -> Vec<bool> {
    const SIZE: u32 = 64;
    let harness = HeadlessRender::new(SIZE, SIZE)
        .format(penumbra_test::CaptureFormat::LinearF16)
        .frames(4)
        .warm_up(tessellation_scene::all_tessellated);
    let mut app = harness.app();
    if path.deferred {
        app.insert_resource(bevy::pbr::DefaultOpaqueRendererMethod::deferred());
    }
    app.add_plugins((
        TessellationPlugin,
        bevy_penumbra_df::PenumbraLightingPlugin::default(),
    ))
    .insert_resource(path)
    .insert_resource(ClearColor(Color::BLACK))
    .add_systems(
        Startup,
        |mut commands: Commands,
         path: Res<Path>,
         mut meshes: ResMut<Assets<Mesh>>,
         mut images: ResMut<Assets<Image>>,
         mut materials: ResMut<Assets<StandardMaterial>>| {
            let mut rock = commands.spawn((
                Mesh3d(meshes.add(mesh_of(&rock(16, 6), true, true))),
                MeshMaterial3d(materials.add(StandardMaterial::default())),
            ));
            if path.tessellated {
                rock.insert(Tessellated {
                    displacement: Some(images.add(tessellation_scene::height_image(64))),
                    displacement_scale: 0.3,
                    pixels_per_triangle: 4.0,
                    ..default()
                });
            }
            commands.spawn((
                DirectionalLight::default(),
                Transform::from_xyz(1.0, 2.0, 1.0).looking_at(Vec3::ZERO, Vec3::Y),
            ));
            let mut camera = commands.spawn((camera(2.2), Msaa::Off));
            if path.deferred {
                camera.insert(bevy_penumbra_df::PenumbraLighting);
            }
        },
    );
    let capture = harness.run(app).expect("renders");
    capture
        .to_linear()
        .iter()
        .map(|p| p[0] + p[1] + p[2] > 1e-3)
        .collect()
}

#[test]
fn forward_and_deferred_cameras_draw_the_tessellated_mesh() {
    if !gpu_or_skip("forward_and_deferred_cameras_draw_the_tessellated_mesh") {
        return;
    }
    let [forward, deferred, plain] =
        [(false, true), (true, true), (false, false)].map(|(deferred, tessellated)| {
            silhouette(Path {
                deferred,
                tessellated,
            })
        });
    let differ = |a: &[bool], b: &[bool]| a.iter().zip(b).filter(|(x, y)| x != y).count();
    let covered = forward.iter().filter(|&&x| x).count();
    println!(
        "silhouette: {covered} pixels; forward vs Penumbra's deferred lighting differ in {}, tessellated vs not in {}",
        differ(&forward, &deferred),
        differ(&forward, &plain)
    );
    assert!(covered > 500, "{covered}");
    // The same triangles in the G-buffer as in the forward pass.
    assert!(
        differ(&forward, &deferred) <= 2,
        "{}",
        differ(&forward, &deferred)
    );
    // And they are the tessellated, displaced ones.
    assert!(
        differ(&forward, &plain) > 50,
        "{}",
        differ(&forward, &plain)
    );
}

#[test]
fn the_pool_grows_to_the_view() {
    if !gpu_or_skip("the_pool_grows_to_the_view") {
        return;
    }
    // Until the GPU needed no bias.
    let harness = HeadlessRender::new(256, 256).frames(2).warm_up(|world| {
        world
            .query::<&TessellationState>()
            .iter(world)
            .next()
            .and_then(TessellationState::latest_totals)
            .is_some_and(|t| t[0] == 0 && t[3] > 0)
    });
    let mut app = harness.app();
    app.add_plugins(TessellationPlugin).add_systems(
        Startup,
        |mut commands: Commands,
         mut meshes: ResMut<Assets<Mesh>>,
         mut materials: ResMut<Assets<StandardMaterial>>| {
            commands.spawn((
                Mesh3d(meshes.add(mesh_of(&rock(16, 6), true, true))),
                MeshMaterial3d(materials.add(StandardMaterial::default())),
                Tessellated {
                    pixels_per_triangle: 2.0,
                    ..default()
                },
            ));
            commands.spawn(camera(1.4));
        },
    );
    let (_, mut app) = harness.run_keeping_app(app).expect("renders");
    let world = app.world_mut();
    let (state, mesh) = world
        .query::<(&TessellationState, &Mesh3d)>()
        .single(world)
        .unwrap();
    let totals = state.latest_totals().unwrap();
    println!(
        "pool {:?}, output {} triangles",
        state.budget(),
        totals[2] / 3
    );
    assert!(state.budget().1 > 3 * 65_536, "the pool did not grow");
    assert!(totals[2] / 3 > 65_536);
    assert_eq!(mesh.0, *state.output());
}

#[derive(Resource)]
struct Pair {
    seen: Entity,
    behind: Entity,
    first: Option<(TessellationUniform, TessellationUniform)>,
}

/// The camera dollies toward the rock in front of it, a little every frame.
fn dolly(mut cameras: Query<&mut Transform, With<Camera3d>>) {
    for mut t in &mut cameras {
        let forward = t.forward();
        t.translation += forward * 0.01;
    }
}

/// Keeps the two rocks' first uniforms.
fn keep_first(mut pair: ResMut<Pair>, states: Query<&TessellationState>) {
    if pair.first.is_none()
        && let (Ok(a), Ok(b)) = (states.get(pair.seen), states.get(pair.behind))
        && let (Some(a), Some(b)) = (a.uniform(), b.uniform())
    {
        pair.first = Some((*a, *b));
    }
}

#[test]
fn a_rock_no_view_sees_keeps_its_tessellation() {
    if !gpu_or_skip("a_rock_no_view_sees_keeps_its_tessellation") {
        return;
    }
    let harness = HeadlessRender::new(64, 64).frames(6);
    let mut app = harness.app();
    app.add_plugins(TessellationPlugin)
        .add_systems(
            Startup,
            |mut commands: Commands,
             mut meshes: ResMut<Assets<Mesh>>,
             mut materials: ResMut<Assets<StandardMaterial>>| {
                let mesh = meshes.add(mesh_of(&rock(8, 3), true, true));
                let material = materials.add(StandardMaterial::default());
                let mut rock_at = |z: f32| {
                    commands
                        .spawn((
                            Mesh3d(mesh.clone()),
                            MeshMaterial3d(material.clone()),
                            Tessellated::default(),
                            Transform::from_xyz(0.0, 0.0, z),
                        ))
                        .id()
                };
                let (seen, behind) = (rock_at(0.0), rock_at(8.0));
                commands.insert_resource(Pair {
                    seen,
                    behind,
                    first: None,
                });
                // At z = 4 looking toward −z: the second rock is behind the camera.
                commands.spawn((Camera3d::default(), Transform::from_xyz(0.0, 0.5, 4.0)));
            },
        )
        .add_systems(Update, (dolly, keep_first));
    let (_, app) = harness.run_keeping_app(app).expect("renders");
    let world = app.world();
    let pair = world.resource::<Pair>();
    let (seen, behind) = pair.first.expect("both tessellated once");
    let now = |e: Entity| {
        *world
            .get::<TessellationState>(e)
            .unwrap()
            .uniform()
            .unwrap()
    };
    assert_ne!(
        now(pair.seen).view,
        seen.view,
        "the rock in view follows the camera"
    );
    assert_eq!(
        now(pair.behind).view,
        behind.view,
        "the rock behind was tessellated again"
    );
}

/// The factors follow a camera that draws the entity: a second camera of higher order
/// on another `RenderLayers` (a minimap, a mirror) does not steer them; with no such
/// camera, the highest order still does; a `TessellationCamera` always does.
#[test]
fn the_factors_follow_a_camera_that_draws_the_entity() {
    if !gpu_or_skip("the_factors_follow_a_camera_that_draws_the_entity") {
        return;
    }
    use bevy::camera::visibility::RenderLayers;
    use bevy_penumbra_cinematic::tessellation::TessellationCamera;
    // (the far camera's layers, whether the near camera is marked): the camera whose
    // position the factors are computed from (true: the near one).
    for (far_layers, near_marked, want_near) in [
        (RenderLayers::layer(1), false, true),
        (RenderLayers::layer(0), false, false),
        (RenderLayers::layer(0), true, true),
    ] {
        let harness = HeadlessRender::new(32, 32).frames(3);
        let mut app = harness.app();
        let near = Vec3::new(0.0, 0.5, 4.0);
        let far = Vec3::new(0.0, 0.5, 40.0);
        let layers = far_layers.clone();
        app.add_plugins(TessellationPlugin).add_systems(
            Startup,
            move |mut commands: Commands,
                  mut meshes: ResMut<Assets<Mesh>>,
                  mut materials: ResMut<Assets<StandardMaterial>>| {
                commands.spawn((
                    Mesh3d(meshes.add(mesh_of(&rock(8, 3), true, true))),
                    MeshMaterial3d(materials.add(StandardMaterial::default())),
                    Tessellated::default(),
                ));
                let mut main = commands.spawn((
                    Camera3d::default(),
                    Transform::from_translation(near).looking_at(Vec3::ZERO, Vec3::Y),
                ));
                if near_marked {
                    main.insert(TessellationCamera);
                }
                commands.spawn((
                    Camera3d::default(),
                    Camera {
                        order: 1,
                        ..default()
                    },
                    layers.clone(),
                    Transform::from_translation(far).looking_at(Vec3::ZERO, Vec3::Y),
                ));
            },
        );
        let (_, mut app) = harness.run_keeping_app(app).expect("renders");
        let world = app.world_mut();
        let uniform = *world
            .query::<&TessellationState>()
            .single(world)
            .expect("one tessellated rock")
            .uniform()
            .expect("tessellated");
        let from = uniform.view.position;
        let want = if want_near { near } else { far };
        assert!(
            from.distance(want) < 1e-3,
            "far camera on {far_layers:?}, near marked {near_marked}: factors from {from}, want {want}"
        );
    }
}

/// GPU read-backs completed (any entity's).
#[derive(Resource, Default)]
struct Reads(u32);

fn count_reads(_: On<ReadbackComplete>, mut reads: ResMut<Reads>) {
    reads.0 += 1;
}

#[test]
fn a_still_scene_reads_nothing_back() {
    if !gpu_or_skip("a_still_scene_reads_nothing_back") {
        return;
    }
    const FRAMES: u32 = 10;
    let harness = HeadlessRender::new(64, 64)
        .frames(4)
        .warm_up(tessellation_scene::all_tessellated);
    let mut app = harness.app();
    app.add_plugins(TessellationPlugin)
        .init_resource::<Reads>()
        .add_observer(count_reads)
        .add_systems(
            Startup,
            |mut commands: Commands,
             mut meshes: ResMut<Assets<Mesh>>,
             mut materials: ResMut<Assets<StandardMaterial>>| {
                commands.spawn((
                    Mesh3d(meshes.add(mesh_of(&rock(8, 3), true, true))),
                    MeshMaterial3d(materials.add(StandardMaterial::default())),
                    Tessellated::default(),
                ));
                commands.spawn(camera(3.0));
            },
        );
    let (_, mut app) = harness.run_keeping_app(app).expect("renders");
    // `FRAMES` frames: the read-backs completed, the most `Readback` entities seen.
    let run = |app: &mut App| {
        app.world_mut().resource_mut::<Reads>().0 = 0;
        let mut most = 0;
        for _ in 0..FRAMES {
            app.update();
            let world = app.world_mut();
            most = most.max(
                world
                    .query_filtered::<(), With<Readback>>()
                    .iter(world)
                    .count(),
            );
        }
        (app.world().resource::<Reads>().0, most)
    };
    let uniform = |app: &mut App| {
        let world = app.world_mut();
        *world
            .query::<&TessellationState>()
            .single(world)
            .unwrap()
            .uniform()
            .unwrap()
    };
    // The harness's capture and the last tessellation's totals land.
    run(&mut app);
    let still = run(&mut app);
    let first = uniform(&mut app);
    // The camera steps once: one tessellation, read back until its totals are in.
    let world = app.world_mut();
    world
        .query_filtered::<&mut Transform, With<Camera3d>>()
        .single_mut(world)
        .unwrap()
        .translation *= 0.9;
    let moved = run(&mut app);
    let second = uniform(&mut app);
    let still_again = run(&mut app);
    println!(
        "{FRAMES} frames each (read-backs completed, most `Readback` entities): still {still:?}, \
         after one camera step {moved:?}, still again {still_again:?}"
    );
    assert_eq!(still, (0, 0), "a still scene is read back");
    assert_ne!(first.view, second.view, "the step was not tessellated");
    assert!(moved.0 >= 1 && moved.1 == 1, "the step's totals: {moved:?}");
    assert_eq!(still_again, (0, 0), "the read-back did not stop again");
}
