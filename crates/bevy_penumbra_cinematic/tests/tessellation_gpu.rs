//! Compute tessellation on lavapipe: a displaced PN-AEN rock (UV seam, split normals at
//! its rim) seen by a perspective camera.
//!
//! - **Contract.** The output pools read back from the GPU equal the CPU reference
//!   (`penumbra_cinematic_core::tessellation::tessellate` for the frame the plugin
//!   tessellated for): the same levels and bias, every patch at the same place (the
//!   output order is the patches'), every vertex's position, normal and UV.
//! - **Crack-free on the GPU.** The GPU's triangles, welded by position bits, have as
//!   many boundary edges as the input (none: the rock is closed), also in a pool too
//!   small for any halving of the factors (every patch its input triangle, no holes).
//! - **Drawn.** The entity draws its output mesh through `StandardMaterial`; removing
//!   `Tessellated` restores the source mesh.

use bevy::prelude::*;
use bevy::render::gpu_readback::{Readback, ReadbackComplete};
use bevy_penumbra_cinematic::tessellation::TessellationState;
use bevy_penumbra_cinematic::{
    Tessellated, TessellationMode, TessellationPartitioning, TessellationPlugin,
};
use penumbra_cinematic_core::tessellation::preprocess::boundary_edge_count;
use penumbra_cinematic_core::tessellation::reference::Frame;
use penumbra_cinematic_core::tessellation::shapes::rock;
use penumbra_cinematic_core::tessellation::{Partitioning, Settings, SurfaceMode, tessellate};
use penumbra_test::{HeadlessRender, gpu_or_skip};

mod tessellation_scene;
use tessellation_scene::{camera, height_image, mesh_of};

const SIZE: u32 = 96;

/// The configuration under test: mode, partitioning, the rock's segments and rings, the
/// pool's most triangles.
#[derive(Resource, Clone, Copy)]
struct Config(TessellationMode, TessellationPartitioning, (u32, u32), u32);

fn tessellated(map: Handle<Image>, config: Config) -> Tessellated {
    Tessellated {
        pixels_per_triangle: 6.0,
        max_level: 4,
        displacement: Some(map),
        displacement_scale: 0.15,
        mode: config.0,
        partitioning: config.1,
        max_triangles: config.3,
        ..default()
    }
}

#[derive(Resource)]
struct Rock(Entity);

/// The four read-back buffers: vertices, indices, patch states, totals.
#[derive(Resource, Default)]
struct ReadBack([Option<Vec<u8>>; 4]);

fn scene(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut images: ResMut<Assets<Image>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    config: Res<Config>,
) {
    let map = images.add(height_image(64));
    let rock = commands
        .spawn((
            Mesh3d(meshes.add(mesh_of(&rock(config.2.0, config.2.1), true, true))),
            MeshMaterial3d(materials.add(StandardMaterial::default())),
            tessellated(map, *config),
        ))
        .id();
    commands.insert_resource(Rock(rock));
    commands.spawn((
        DirectionalLight::default(),
        Transform::from_xyz(1.0, 2.0, 1.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    commands.spawn(camera(2.6));
}

/// Starts the read-backs once the state exists.
fn read_back(
    mut commands: Commands,
    rock: Option<Res<Rock>>,
    states: Query<&TessellationState>,
    mut started: Local<bool>,
) {
    let Some(rock) = rock else { return };
    let Ok(state) = states.get(rock.0) else {
        return;
    };
    if *started {
        return;
    }
    *started = true;
    for (k, buffer) in state.buffers().into_iter().enumerate() {
        commands.spawn(Readback::buffer(buffer.clone())).observe(
            move |event: On<ReadbackComplete>, mut read: ResMut<ReadBack>| {
                read.0[k] = Some(event.data.clone());
            },
        );
    }
}

fn words(bytes: &[u8]) -> Vec<u32> {
    bytes
        .chunks_exact(4)
        .map(|b| u32::from_le_bytes(b.try_into().unwrap()))
        .collect()
}

#[test]
fn gpu_tessellation_is_the_reference() {
    if !gpu_or_skip("gpu_tessellation_is_the_reference") {
        return;
    }
    let max = Tessellated::default().max_triangles;
    contract(Config(
        TessellationMode::PnAen,
        TessellationPartitioning::Integer,
        (16, 6),
        max,
    ));
    contract(Config(
        TessellationMode::Flat,
        TessellationPartitioning::Fractional,
        (16, 6),
        max,
    ));
    // Over 1,024 patches: the allocation's scan spans several workgroups; a pool so
    // small that the factors are halved.
    contract(Config(
        TessellationMode::PnAen,
        TessellationPartitioning::Fractional,
        (64, 24),
        6_000,
    ));
    // A pool of the input's own size (`max_triangles` below it is raised to it): the
    // factors halved three times still ask for more, so every patch is drawn as its
    // input triangle (before, the patches past the pool were left out: holes).
    contract(Config(
        TessellationMode::PnAen,
        TessellationPartitioning::Integer,
        (64, 24),
        10,
    ));
}

fn contract(config: Config) {
    let harness = HeadlessRender::new(SIZE, SIZE).frames(3).warm_up(|world| {
        let read = &world.resource::<ReadBack>().0;
        read.iter().all(Option::is_some) && words(read[3].as_ref().unwrap())[3] > 0
    });
    let mut app = harness.app();
    app.add_plugins(TessellationPlugin)
        .insert_resource(config)
        .init_resource::<ReadBack>()
        .add_systems(Startup, scene)
        .add_systems(Update, read_back);
    let (capture, mut app) = harness.run_keeping_app(app).expect("renders");
    let world = app.world();
    let entity = world.resource::<Rock>().0;
    let state = world
        .get::<TessellationState>(entity)
        .expect("tessellated")
        .clone();
    assert_eq!(world.get::<Mesh3d>(entity).unwrap().0, *state.output());
    let read = world.resource::<ReadBack>().0.clone().map(Option::unwrap);
    let uniform = *state.uniform().expect("a uniform");
    let frame = Frame {
        view: uniform.view,
        world_from_local: uniform.world_from_local,
    };
    let settings = Settings {
        pixels_per_triangle: 6.0,
        max_level: 4,
        mode: match config.0 {
            TessellationMode::Flat => SurfaceMode::Flat,
            TessellationMode::PnAen => SurfaceMode::PnAen,
        },
        partitioning: match config.1 {
            TessellationPartitioning::Integer => Partitioning::Integer,
            TessellationPartitioning::Fractional => Partitioning::Fractional,
        },
        displacement_scale: 0.15,
        displacement_midlevel: 0.5,
        crack_fixes: true,
    };
    let (vertex_budget, index_budget) = state.budget();
    let cpu = tessellate(
        state.input(),
        &frame,
        &settings,
        state.map().map(|m| &**m),
        vertex_budget.into(),
        index_budget.into(),
    );
    let totals = words(&read[3]);
    println!(
        "GPU totals: bias {}, {} vertices, {} indices, {} patches; CPU: bias {}, {} vertices, {} indices",
        totals[0],
        totals[1],
        totals[2],
        totals[3],
        cpu.bias,
        cpu.positions.len(),
        cpu.indices.len()
    );
    assert_eq!(totals[0], cpu.bias);
    // Patch placement and levels.
    let states = words(&read[2]);
    let mut level_mismatches = 0;
    for (p, &(base, first, lod)) in cpu.patches.iter().enumerate() {
        let s = &states[8 * p..8 * p + 8];
        if s[6] != lod.counts.inside {
            level_mismatches += 1;
        }
        assert_eq!((s[4], s[5]), (base, first), "patch {p}");
    }
    assert_eq!(level_mismatches, 0);
    assert_eq!(
        (totals[1] as usize, totals[2] as usize),
        (cpu.positions.len(), cpu.indices.len())
    );
    // Every vertex.
    let floats: Vec<f32> = read[0]
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
        .collect();
    let (mut position, mut normal, mut uv) = (0.0f32, 0.0f32, 0.0f32);
    let mut gpu_positions = Vec::with_capacity(cpu.positions.len());
    for v in 0..cpu.positions.len() {
        let f = &floats[8 * v..8 * v + 8];
        let p = Vec3::new(f[0], f[1], f[2]);
        gpu_positions.push(p);
        position = position.max((p - cpu.positions[v]).length());
        normal = normal.max((Vec3::new(f[3], f[4], f[5]) - cpu.normals[v]).length());
        uv = uv.max((Vec2::new(f[6], f[7]) - cpu.uvs[v]).length());
    }
    let indices = words(&read[1]);
    assert_eq!(&indices[..cpu.indices.len()], &cpu.indices[..]);
    assert!(
        indices[cpu.indices.len()..].iter().all(|&i| i == 0),
        "the pool's tail is degenerate"
    );
    let cracks = boundary_edge_count(&gpu_positions, &indices[..cpu.indices.len()]);
    println!(
        "{:?}: {} vertices, {} triangles: |gpu − cpu| max position {position:.2e} (rock radius 1), normal {normal:.2e}, uv {uv:.2e}; GPU boundary edges after welding: {cracks}",
        (config.0, config.1),
        cpu.positions.len(),
        cpu.indices.len() / 3
    );
    assert!(position < 1e-4 && normal < 1e-3 && uv < 1e-5);
    assert_eq!(cracks, 0);
    // The rock is drawn: most of the frame's centre is lit.
    let image = capture.to_rgba8();
    let lit = (SIZE / 4..3 * SIZE / 4)
        .flat_map(|y| (SIZE / 4..3 * SIZE / 4).map(move |x| (x, y)))
        .filter(|&(x, y)| image.get_pixel(x, y)[1] > 120)
        .count();
    assert!(
        lit > (SIZE * SIZE / 4) as usize * 8 / 10,
        "{lit} lit pixels"
    );
    // Removing the component restores the source mesh.
    app.world_mut().entity_mut(entity).remove::<Tessellated>();
    app.update();
    assert_eq!(
        app.world().get::<Mesh3d>(entity).unwrap().0,
        *state.source()
    );
}
