//! The plugin's own GPU object buffer (render world) equals its CPU mirror (main world)
//! after thousands of random adds, removes, moves and rescales of casters through the
//! ECS, over hundreds of frames on lavapipe.

use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::render_resource::{BufferDescriptor, BufferUsages, MapMode, PollType};
use bevy::render::renderer::{RenderDevice, RenderQueue};
use bevy_penumbra_df::scene::DistanceFieldGpu;
use bevy_penumbra_df::{
    CasterSource, DistanceFieldCaster, DistanceFieldScene, DistanceFieldScenePlugin,
    DistanceFieldUploadStats, SdfAssetPlugin,
};
use penumbra_df_core::object::{ObjectRecord, RECORD_BYTES};
use penumbra_test::{HeadlessRender, gpu_or_skip};

#[derive(Resource)]
struct Churn {
    rng: u64,
    live: Vec<Entity>,
    ops: usize,
    frames: u32,
}

impl Churn {
    fn next(&mut self) -> f32 {
        self.rng = self
            .rng
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.rng >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn churn(
    mut commands: Commands,
    mut state: ResMut<Churn>,
    mut transforms: Query<&mut Transform, With<DistanceFieldCaster>>,
) {
    state.frames += 1;
    if state.frames.is_multiple_of(9) {
        return; // a static frame now and then
    }
    for _ in 0..45 {
        state.ops += 1;
        let roll = state.next();
        if roll < 0.45 || state.live.is_empty() {
            let (x, z, r) = (
                state.next() * 40.0 - 20.0,
                state.next() * 40.0 - 20.0,
                0.2 + state.next(),
            );
            let source = if state.next() < 0.5 {
                CasterSource::Sphere { radius: r }
            } else {
                CasterSource::Capsule {
                    radius: r * 0.5,
                    half_length: r,
                }
            };
            let e = commands
                .spawn((
                    DistanceFieldCaster {
                        source,
                        ..default()
                    },
                    Transform::from_xyz(x, r, z),
                ))
                .id();
            state.live.push(e);
        } else if roll < 0.7 {
            let i = (state.next() * state.live.len() as f32) as usize % state.live.len();
            let e = state.live.swap_remove(i);
            commands.entity(e).despawn();
        } else {
            let i = (state.next() * state.live.len() as f32) as usize % state.live.len();
            let e = state.live[i];
            let (dx, s) = (state.next() - 0.5, 0.5 + state.next());
            if let Ok(mut t) = transforms.get_mut(e) {
                t.translation.x += dx;
                t.scale = Vec3::new(s, 1.0, 2.0 - s);
            }
        }
    }
}

/// Reads the render world's object buffer back.
fn read_gpu_objects(app: &mut App, slots: u32) -> Vec<ObjectRecord> {
    let render = app.sub_app(RenderApp).world();
    let gpu = render.resource::<DistanceFieldGpu>();
    let objects = gpu.objects.as_ref().expect("object buffer exists").clone();
    let device = render.resource::<RenderDevice>().clone();
    let queue = render.resource::<RenderQueue>().clone();
    let size = slots as u64 * RECORD_BYTES as u64;
    let staging = device.create_buffer(&BufferDescriptor {
        label: Some("test_readback"),
        size,
        usage: BufferUsages::MAP_READ | BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(&objects, 0, &staging, 0, size);
    queue.submit([encoder.finish()]);
    let slice = staging.slice(..);
    slice.map_async(MapMode::Read, |r| r.expect("map"));
    device.poll(PollType::wait_indefinitely()).expect("poll");
    let bytes = slice.get_mapped_range().to_vec();
    bytes
        .chunks_exact(RECORD_BYTES)
        .map(|c| ObjectRecord::from_bytes(c.try_into().expect("record")))
        .collect()
}

#[test]
fn plugin_object_buffer_equals_the_mirror_under_ecs_churn() {
    if !gpu_or_skip("plugin_object_buffer_equals_the_mirror_under_ecs_churn") {
        return;
    }
    let render = HeadlessRender::new(32, 32).frames(250).without_pipelining();
    let mut app = render.app();
    app.add_plugins((SdfAssetPlugin, DistanceFieldScenePlugin))
        .insert_resource(Churn {
            rng: 9,
            live: Vec::new(),
            ops: 0,
            frames: 0,
        })
        .add_systems(Startup, |mut commands: Commands| {
            commands.spawn((Camera3d::default(), Transform::from_xyz(0.0, 5.0, 30.0)));
        })
        .add_systems(Update, churn);
    let (_, mut app) = render.run_keeping_app(app).expect("render");
    let ops = app.world().resource::<Churn>().ops;
    let stats = app.world().resource::<DistanceFieldUploadStats>().clone();
    let mirror: Vec<ObjectRecord> = app
        .world()
        .resource::<DistanceFieldScene>()
        .records()
        .to_vec();
    println!(
        "{ops} ECS operations; {} live casters in {} slots; {} bytes uploaded in total",
        stats.objects, stats.slots, stats.total_bytes
    );
    assert!(ops >= 10_000, "{ops}");
    let gpu = read_gpu_objects(&mut app, mirror.len() as u32);
    let differing = gpu.iter().zip(&mirror).filter(|(a, b)| a != b).count();
    assert_eq!(differing, 0, "{differing} of {} slots differ", mirror.len());
}
