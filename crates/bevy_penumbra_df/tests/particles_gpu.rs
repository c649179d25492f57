//! Contract test of the particle step on lavapipe (`df/particles.wgsl`, run through
//! wgpu directly): 256 particles dropped onto a ground slab and a ball through the
//! global field (default clipmaps, composed by the CPU model and uploaded as the GPU
//! keeps it) follow the CPU model (`penumbra_reference::particles::step_from`, the
//! same 240 steps at 60 Hz, positions relative to an origin away from the camera),
//! come to rest, and none ends more than a texel inside a surface by the exact
//! distance.

use glam::Vec3;
use penumbra_df_core::clipmap::{ClipmapLayout, ClipmapState, GlobalFieldView};
use penumbra_df_core::particles::{GpuParticle, ParticleStep};
use penumbra_reference::global_sdf::{
    AnalyticCaster, ClipmapFormat, FieldObject, GlobalField, analytic_distance,
};
use penumbra_reference::particles::{Collision, Particle, step_from};
use penumbra_shaders::flatten;
use penumbra_test::wgpu::{self, BufferUsages};
use penumbra_test::{GpuCompute, gpu_or_skip, storage_bytes, uniform_bytes};

const STEPS: usize = 240;
const DT: f32 = 1.0 / 60.0;

fn entry(binding: u32, b: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: b.as_entire_binding(),
    }
}

#[test]
fn particle_step_matches_the_model() {
    if !gpu_or_skip("particle_step_matches_the_model") {
        return;
    }
    let scene = [
        AnalyticCaster::Cuboid {
            centre: Vec3::new(0.0, -0.5, 0.0),
            half: Vec3::new(20.0, 0.5, 20.0),
        },
        AnalyticCaster::Sphere {
            centre: Vec3::new(0.0, 1.0, 0.0),
            radius: 1.0,
        },
    ];
    let layout = ClipmapLayout::DEFAULT;
    let camera = Vec3::new(0.0, 1.0, 3.0);
    let objects: Vec<FieldObject> = scene.iter().map(|c| c.field_object()).collect();
    let mut state = ClipmapState::new(layout);
    let mut field = GlobalField::new(layout, ClipmapFormat::Unorm8);
    for job in state.update(camera, &[], usize::MAX).jobs {
        field.compose(job, &objects);
    }
    let view = GlobalFieldView::new(&state, camera.as_dvec3());
    let valid = GlobalFieldView::valid_bits(&state);
    let collision = Collision {
        restitution: 0.3,
        friction: 0.2,
        radius: 0.05,
        gravity: Vec3::new(0.0, -9.81, 0.0),
    };
    // Positions relative to an origin 3 m before and 2 m above the camera's feet.
    let origin = Vec3::new(0.0, 2.0, -3.0);
    let start: Vec<Particle> = (0..256)
        .map(|i| {
            let a = i as f32 * 2.399;
            let r = 0.1 * (i as f32).sqrt();
            Particle {
                position: Vec3::new(r * a.cos(), 0.01 * i as f32, r * a.sin()),
                velocity: Vec3::new(0.3 * a.sin(), 0.0, 0.0),
            }
        })
        .collect();
    let mut model = start.clone();
    for _ in 0..STEPS {
        step_from(origin, &mut model, &field, &view, &valid, &collision, DT);
    }

    let gpu = GpuCompute::new().expect("adapter");
    let pipeline = gpu.pipeline(
        &flatten("#import penumbra::df::particles\n").expect("flattens"),
        "step_particles",
    );
    let to_gpu = |ps: &[Particle]| -> Vec<u8> {
        let gpu_particles: Vec<GpuParticle> = ps
            .iter()
            .map(|p| GpuParticle {
                position: p.position,
                age: 0.0,
                velocity: p.velocity,
                alive: 1,
            })
            .collect();
        storage_bytes(&gpu_particles)
    };
    let bytes = to_gpu(&start);
    let particles = gpu.buffer("particles", &bytes, BufferUsages::COPY_SRC);
    let params = ParticleStep {
        gravity: collision.gravity,
        dt: DT,
        origin,
        restitution: collision.restitution,
        friction: collision.friction,
        radius: collision.radius,
        count: start.len() as u32,
    };
    let params = gpu.buffer("params", &uniform_bytes(&params), BufferUsages::UNIFORM);
    let field_buffer = gpu.buffer("field", &field.field_bytes(), BufferUsages::empty());
    let valid_bytes: Vec<u8> = valid.iter().flat_map(|w| w.to_le_bytes()).collect();
    let valid_buffer = gpu.buffer("valid", &valid_bytes, BufferUsages::empty());
    let view_buffer = gpu.buffer("view", &uniform_bytes(&view), BufferUsages::UNIFORM);
    let group = |index: u32, entries: &[wgpu::BindGroupEntry]| {
        gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipeline.get_bind_group_layout(index),
            entries,
        })
    };
    let g0 = group(0, &[entry(0, &particles), entry(1, &params)]);
    let g1 = group(
        1,
        &[
            entry(0, &field_buffer),
            entry(1, &valid_buffer),
            entry(2, &view_buffer),
        ],
    );
    let groups = [start.len().div_ceil(64) as u32, 1, 1];
    let read = || -> Vec<f32> {
        gpu.read(&particles, bytes.len() as u64)
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    };
    let position = |f: &[f32], i: usize| Vec3::new(f[8 * i], f[8 * i + 1], f[8 * i + 2]);
    let velocity = |f: &[f32], i: usize| Vec3::new(f[8 * i + 4], f[8 * i + 5], f[8 * i + 6]);
    // Step by step from the model's states: the kernel is the model's step.
    let mut state = start.clone();
    let (mut step_apart, mut speed_apart) = (0.0f32, 0.0f32);
    for _ in 0..STEPS {
        gpu.queue.write_buffer(&particles, 0, &to_gpu(&state));
        gpu.dispatch_groups(&pipeline, &[&g0, &g1], groups);
        step_from(origin, &mut state, &field, &view, &valid, &collision, DT);
        let got = read();
        for (i, want) in state.iter().enumerate() {
            step_apart = step_apart.max((position(&got, i) - want.position).length());
            speed_apart = speed_apart.max((velocity(&got, i) - want.velocity).length());
        }
    }
    // Free run: the GPU's own trajectory.
    gpu.queue.write_buffer(&particles, 0, &bytes);
    for _ in 0..STEPS {
        gpu.dispatch_groups(&pipeline, &[&g0, &g1], groups);
    }
    let got = read();
    let texel = layout.texel(0);
    let (mut within, mut apart, mut deepest, mut resting) = (0, 0.0f32, f32::INFINITY, 0);
    for (i, want) in model.iter().enumerate() {
        let d = (position(&got, i) - want.position).length();
        within += usize::from(d < 1e-3);
        apart = apart.max(d);
        deepest = deepest.min(analytic_distance(
            &scene,
            camera + origin + position(&got, i),
        ));
        resting += usize::from(velocity(&got, i).length() < 0.05);
    }
    eprintln!(
        "{} particles, {STEPS} steps: one step apart by {step_apart:.2e} m and {speed_apart:.2e} m/s at most; free run: \
         {within} within 1 mm of the model (farthest {apart:.2e} m), {resting} at rest, \
         nearest {deepest:.3} m from a surface",
        model.len()
    );
    assert!(
        step_apart < 1e-5 && speed_apart < 1e-4,
        "a GPU step differs from the model's by {step_apart} m, {speed_apart} m/s"
    );
    // Bounces amplify rounding (a particle balanced on the ball's top falls either way).
    assert!(within * 100 >= model.len() * 98, "{within} within 1 mm");
    assert!(deepest > -texel, "a particle {deepest} m inside");
    assert!(resting * 100 >= model.len() * 95, "{resting} at rest");
}
