//! `DistanceFieldParticles` in a running app (60 Hz steps for 2 s): a burst of 256
//! particles emitted 1.5 m over a ground
//! plane and a ball (analytic casters) fall, collide with the camera's global distance
//! field on the GPU and come to rest on the casters — none more than a texel inside
//! them (by the exact distance), nearly all in contact; without the field camera they
//! fall through. Read back with Bevy's `Readback`.

use bevy::prelude::*;
use bevy::render::gpu_readback::{Readback, ReadbackComplete};
use bevy::time::TimeUpdateStrategy;
use penumbra::df::DistanceFieldParticlesState;
use penumbra::prelude::*;
use penumbra_test::{HeadlessRender, gpu_or_skip};

const BALL: Vec3 = Vec3::new(0.3, 0.4, 0.0);
const BALL_RADIUS: f32 = 0.4;
const EMITTER: Vec3 = Vec3::new(0.0, 1.5, 0.0);

#[derive(Resource, Clone, Copy)]
struct WithField(bool);

#[derive(Resource, Default)]
struct Back(Option<Vec<f32>>);

fn scene(mut commands: Commands, with_field: Res<WithField>) {
    commands.spawn((
        DistanceFieldCaster {
            source: CasterSource::Plane,
            ..default()
        },
        Transform::default(),
    ));
    commands.spawn((
        DistanceFieldCaster {
            source: CasterSource::Sphere {
                radius: BALL_RADIUS,
            },
            ..default()
        },
        Transform::from_translation(BALL),
    ));
    let mut camera = commands.spawn((
        Camera3d::default(),
        // Over the scene, so that every particle stays in the first clipmap (0.1 m
        // texels, x −3.2..3.2, y −0.8..5.6, z −2.4..4.0): beyond the clipmaps they
        // fly free.
        Transform::from_xyz(0.0, 2.0, 1.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    if with_field.0 {
        camera.insert(GlobalDistanceField {
            clipmap_count: 2,
            resolution: 64,
            first_extent: 6.4,
            ..default()
        });
    }
    commands.spawn((
        DistanceFieldParticles {
            capacity: 256,
            rate: 4000.0,
            max_emitted: Some(256),
            spawn_half_extents: Vec3::new(0.6, 0.1, 0.3),
            velocity_jitter: 0.2,
            ..default()
        },
        Transform::from_translation(EMITTER),
    ));
}

/// The particles' world positions and speeds after `frames` frames.
fn run(with_field: bool, frames: u32) -> Vec<(Vec3, f32)> {
    let render = HeadlessRender::new(64, 64).frames(frames);
    let mut app = render.app();
    app.add_plugins(PenumbraPlugins)
        // 60 Hz steps whatever the machine's frame time.
        .insert_resource(TimeUpdateStrategy::ManualDuration(
            std::time::Duration::from_secs_f64(1.0 / 60.0),
        ))
        .insert_resource(WithField(with_field))
        .init_resource::<Back>()
        .add_systems(Startup, scene);
    let (_, mut app) = render.run_keeping_app(app).expect("headless render");
    let (buffer, origin) = {
        let world = app.world_mut();
        let mut q = world.query::<&DistanceFieldParticlesState>();
        let state = q.single(world).expect("one emitter");
        (state.buffer.clone(), state.origin)
    };

    app.world_mut().spawn(Readback::buffer(buffer)).observe(
        |event: On<ReadbackComplete>, mut back: ResMut<Back>| {
            let floats: Vec<f32> = event
                .data
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect();
            back.0.get_or_insert(floats);
        },
    );
    for _ in 0..4 {
        app.update();
    }
    let floats = app
        .world_mut()
        .resource_mut::<Back>()
        .0
        .take()
        .expect("read back");
    floats
        .chunks_exact(8)
        .filter(|p| p[7].to_bits() != 0)
        .map(|p| {
            (
                origin + Vec3::new(p[0], p[1], p[2]),
                Vec3::new(p[4], p[5], p[6]).length(),
            )
        })
        .collect()
}

fn distance(p: Vec3) -> f32 {
    p.y.min((p - BALL).length() - BALL_RADIUS)
}

#[test]
fn particles_rest_on_the_casters() {
    if !gpu_or_skip("particles_rest_on_the_casters") {
        return;
    }
    let texel = 0.1;
    let radius = DistanceFieldParticles::default().radius;
    let particles = run(true, 120);
    let deepest = particles
        .iter()
        .map(|(p, _)| distance(*p))
        .fold(f32::INFINITY, f32::min);
    let resting = particles
        .iter()
        .filter(|(p, v)| distance(*p) < radius + texel && *v < 0.2)
        .count();
    println!(
        "{} particles: nearest {deepest:.3} m from a surface, {resting} resting on one",
        particles.len()
    );
    assert_eq!(particles.len(), 256);
    assert!(deepest > -texel, "a particle {deepest} m inside");
    assert!(resting * 10 >= particles.len() * 9, "{resting} resting");

    // Without a field camera nothing stops them.
    let falling = run(false, 120);
    let below = falling.iter().filter(|(p, _)| p.y < -1.0).count();
    println!("without the field: {below} of {} below −1 m", falling.len());
    assert!(below * 10 >= falling.len() * 9, "{below} fell");
}
