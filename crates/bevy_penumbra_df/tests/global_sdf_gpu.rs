//! Contract test of the global distance field's compose pass on lavapipe
//! (`df/global_compose.wgsl`, run through wgpu directly): on the shadow passes' scene (a
//! plane, a sphere, a rotated and scaled box, a capsule, a baked torus that lets AO
//! through — so it stays out of the field —, a tiny sphere, far objects, one that does
//! not occlude), the clipmaps composed on the GPU equal the CPU model
//! (`penumbra_reference::global_sdf::GlobalField::compose_records`) within one step of
//! the 8-bit storage, and identical but for one texel in a thousand at most (FMA
//! contraction may round a position differently; on lavapipe none differs; a shader
//! that forgets the conservative quantum differs in 3 texels of 4) — composed whole,
//! then after the camera moves and a caster moves
//! (only the bricks the update hands out are recomposed on both sides), near the origin
//! and 10⁵ m away.

use glam::{IVec3, Vec3};
use penumbra_df_core::clipmap::{
    BrickJob, ClipmapLayout, ClipmapState, ComposeJob, ComposeParams, field_words,
    record_dirty_box, texel_byte,
};
use penumbra_df_core::object::{CasterShape, ObjectDesc, encode, flags};
use penumbra_reference::global_sdf::{ClipmapFormat, GlobalField};
use penumbra_shaders::flatten;
use penumbra_test::wgpu::{self, BufferUsages};
use penumbra_test::{GpuCompute, gpu_or_skip};

#[path = "support/shadow_passes.rs"]
mod support;

use support::{Scene, scene};

/// The GPU side: pipeline, atlas and the field buffer, kept across updates.
struct Gpu {
    gpu: GpuCompute,
    pipeline: wgpu::ComputePipeline,
    atlas: wgpu::TextureView,
    field: wgpu::Buffer,
}

impl Gpu {
    fn new(gpu: GpuCompute, scene: &Scene, layout: &ClipmapLayout) -> Gpu {
        let pipeline = gpu.pipeline(
            &flatten("#import penumbra::df::global_compose\n").expect("flattens"),
            "compose",
        );
        let bytes: Vec<u8> = scene
            .atlas_bits
            .iter()
            .flat_map(|b| b.to_le_bytes())
            .collect();
        let s = scene.atlas_size;
        let atlas = gpu
            .texture(
                "atlas",
                wgpu::Extent3d {
                    width: s.x,
                    height: s.y,
                    depth_or_array_layers: s.z,
                },
                wgpu::TextureDimension::D3,
                wgpu::TextureFormat::R16Float,
                2,
                &bytes,
            )
            .create_view(&Default::default());
        let field = gpu.zeroed("field", field_words(layout) * 4, BufferUsages::empty());
        Gpu {
            gpu,
            pipeline,
            atlas,
            field,
        }
    }

    fn compose(&self, layout: &ClipmapLayout, scene: &Scene, jobs: &[BrickJob]) {
        if jobs.is_empty() {
            return;
        }
        let gpu = &self.gpu;
        let records: Vec<u8> = scene.records.iter().flat_map(|r| r.to_bytes()).collect();
        let objects = gpu.buffer("objects", &records, BufferUsages::empty());
        let mut job_bytes = bevy::render::render_resource::encase::StorageBuffer::new(Vec::new());
        let compose_jobs: Vec<ComposeJob> =
            jobs.iter().map(|&j| ComposeJob::new(layout, j)).collect();
        job_bytes.write(&compose_jobs).expect("encodes");
        let job_buffer = gpu.buffer("jobs", job_bytes.as_ref(), BufferUsages::empty());
        let params = ComposeParams::new(layout, scene.records.len() as u32, jobs.len() as u32);
        let mut param_bytes = bevy::render::render_resource::encase::UniformBuffer::new(Vec::new());
        param_bytes.write(&params).expect("encodes");
        let uniform = gpu.buffer("params", param_bytes.as_ref(), BufferUsages::UNIFORM);
        let bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("global_compose"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: objects.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&self.atlas),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: job_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: uniform.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: self.field.as_entire_binding(),
                },
            ],
        });
        gpu.dispatch(&self.pipeline, &bind, [jobs.len() as u32, 1, 1]);
    }

    fn bytes(&self, layout: &ClipmapLayout) -> Vec<u8> {
        self.gpu.read(&self.field, field_words(layout) * 4)
    }
}

/// Every texel of every valid brick: (largest |GPU − model| in storage steps, texels
/// that differ, texels compared).
fn compare(
    layout: &ClipmapLayout,
    state: &ClipmapState,
    model: &GlobalField,
    bytes: &[u8],
) -> (f32, usize, usize) {
    let (mut worst, mut apart, mut count) = (0.0f32, 0, 0);
    let b = 8;
    for level in 0..layout.levels {
        let band = layout.band(level);
        let step = 2.0 * band / 255.0;
        let window = state.window(level).expect("composed");
        for brick in window.iter().filter(|&br| state.is_valid(level, br)) {
            for i in 0..b * b * b {
                let w = brick * b + IVec3::new(i % b, (i / b) % b, i / (b * b));
                let (word, byte) = texel_byte(layout, level, w);
                let q = bytes[(4 * word + byte) as usize];
                let gpu = (f32::from(q) / 255.0 - 0.5) * 2.0 * band;
                let steps = (gpu - model.texel(level, w)).abs() / step;
                worst = worst.max(steps);
                apart += usize::from(steps > 0.01);
                count += 1;
            }
        }
    }
    (worst, apart, count)
}

fn check(name: &str, offset: Vec3) {
    if !gpu_or_skip(name) {
        return;
    }
    let mut scene = scene(offset);
    // Two levels of 32³ (64 bricks each), 0.2 and 0.4 m texels.
    let layout = ClipmapLayout::new(2, 32, 6.4, 2.0).0;
    let gpu = Gpu::new(GpuCompute::new().expect("adapter"), &scene, &layout);
    let mut state = ClipmapState::new(layout);
    let mut model = GlobalField::new(layout, ClipmapFormat::Unorm8);
    let compose = |model: &mut GlobalField, scene: &Scene, jobs: &[BrickJob]| {
        for &j in jobs {
            model.compose_records(j, &scene.records, &scene.atlas);
        }
        gpu.compose(&layout, scene, jobs);
    };
    let mut camera = offset + Vec3::new(0.3, 1.5, 0.2);
    let jobs = state.update(camera, &[], usize::MAX).jobs;
    compose(&mut model, &scene, &jobs);
    let (worst, apart, count) = compare(&layout, &state, &model, &gpu.bytes(&layout));
    eprintln!("{name}, whole: {count} texels, worst {worst:.2} steps, {apart} differ");
    assert!(
        count == 2 * 64 * 512 && worst <= 1.01 && apart * 1000 <= count,
        "{worst} {apart}"
    );
    // Some texels see each kind of object: not a field of bands.
    assert!(model.texels.iter().flatten().filter(|v| **v < 0.0).count() > 1000);

    // The camera moves two bricks; the sphere (record 1) moves 1 m.
    camera += Vec3::new(3.2, 0.0, -1.6);
    let old = record_dirty_box(&scene.records[1]).expect("composes");
    scene.records[1] = encode(&ObjectDesc {
        world_from_local: glam::Affine3A::from_translation(offset + Vec3::new(-0.3, 0.6, -0.4)),
        shape: CasterShape::Sphere { radius: 0.6 },
        flags: flags::LIVE | flags::CASTS_SHADOWS | flags::CASTS_OCCLUSION | flags::VISIBLE,
    })
    .expect("encodes");
    let new = record_dirty_box(&scene.records[1]).expect("composes");
    let update = state.update(camera, &[old, new], usize::MAX);
    assert!(update.scrolled > 0 && update.dirtied > 0);
    compose(&mut model, &scene, &update.jobs);
    let (worst, apart, count) = compare(&layout, &state, &model, &gpu.bytes(&layout));
    eprintln!(
        "{name}, after an update of {} bricks: worst {worst:.2} steps, {apart} differ",
        update.jobs.len()
    );
    assert!(
        count == 2 * 64 * 512 && worst <= 1.01 && apart * 1000 <= count,
        "{worst} {apart}"
    );
}

#[test]
fn compose_pass_matches_the_model() {
    check("global_sdf_gpu", Vec3::ZERO);
}

#[test]
fn compose_pass_matches_the_model_far_from_the_origin() {
    check("global_sdf_gpu_far", Vec3::new(1.0e5, 0.0, -1.0e5));
}
