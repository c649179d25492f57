//! Contract test of the global field's debug views on lavapipe
//! (`df/global_field_debug.wgsl`, run through wgpu directly by a compute wrapper that
//! calls its `field_debug_color` per pixel): a plane, a sphere and a ball that has just
//! moved, composed by the CPU model and uploaded as the GPU keeps them; every mode
//! equals `penumbra_reference::field_debug::field_debug_pixel`, near the origin and
//! 10⁵ m out.

use glam::{Mat3, Mat4, Vec2, Vec3};
use penumbra_df_core::clipmap::debug::{FieldDebugMode, FieldDebugParams, composed_bits};
use penumbra_df_core::clipmap::{ClipmapLayout, ClipmapState, ComposeJob, GlobalFieldView};
use penumbra_reference::field_debug::{FieldDebugScene, field_debug_pixel};
use penumbra_reference::global_sdf::{AnalyticCaster, ClipmapFormat, FieldObject, GlobalField};
use penumbra_shaders::flatten;
use penumbra_test::wgpu::{self, BufferUsages};
use penumbra_test::{GpuCompute, gpu_or_skip, uniform_bytes};

const SIZE: u32 = 64;

const WRAPPER: &str = "
#import penumbra::df::global_field_debug::field_debug_color

@group(2) @binding(0) var<storage, read_write> pixels: array<vec4<f32>>;

@compute @workgroup_size(8, 8, 1)
fn debug_pixels(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = 64u;
    if id.x >= size || id.y >= size {
        return;
    }
    let uv = (vec2<f32>(id.xy) + 0.5) / f32(size);
    pixels[id.y * size + id.x] = vec4<f32>(field_debug_color(uv), 0.0);
}
";

fn scene(offset: Vec3, ball: Vec3) -> Vec<AnalyticCaster> {
    vec![
        AnalyticCaster::Cuboid {
            centre: offset + Vec3::new(0.0, -0.5, 0.0),
            half: Vec3::new(30.0, 0.5, 30.0),
        },
        AnalyticCaster::Sphere {
            centre: offset + Vec3::new(-1.0, 1.0, -1.0),
            radius: 1.0,
        },
        AnalyticCaster::Sphere {
            centre: offset + ball,
            radius: 0.4,
        },
    ]
}

fn bytes(words: &[u32]) -> Vec<u8> {
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}

/// (mean |Δ|, pixels off by more than 0.01, pixels with orange) for one mode at one
/// place.
fn compare(gpu: &GpuCompute, offset: Vec3, mode: FieldDebugMode) -> (f32, usize, usize) {
    let (layout, _) = ClipmapLayout::new(3, 64, 12.8, 2.0);
    let camera = offset + Vec3::new(0.6, 2.4, 5.0);
    let (from, to) = (Vec3::new(1.2, 0.4, 0.5), Vec3::new(1.2, 0.4, -0.5));
    let before = scene(offset, from);
    let after = scene(offset, to);
    let mut state = ClipmapState::new(layout);
    let mut field = GlobalField::new(layout, ClipmapFormat::Unorm8);
    let objects: Vec<FieldObject> = before.iter().map(|c| c.field_object()).collect();
    for job in state.update(camera, &[], usize::MAX).jobs {
        field.compose(job, &objects);
    }
    let objects: Vec<FieldObject> = after.iter().map(|c| c.field_object()).collect();
    let update = state.update(camera, &[before[2].dirty(), after[2].dirty()], usize::MAX);
    let jobs: Vec<ComposeJob> = update
        .jobs
        .iter()
        .map(|j| ComposeJob::new(&layout, *j))
        .collect();
    for job in &update.jobs {
        field.compose(*job, &objects);
    }
    let view = GlobalFieldView::new(&state, camera.as_dvec3());
    let valid = GlobalFieldView::valid_bits(&state);
    let updated = composed_bits(&layout, &jobs);
    let look = Mat4::look_at_rh(camera, offset + Vec3::new(0.0, 0.5, 0.0), Vec3::Y);
    let proj = Mat4::perspective_infinite_reverse_rh(0.9, 1.0, 0.1);
    let relative_from_clip = (proj * Mat4::from_mat3(Mat3::from_mat4(look))).inverse();
    let params = FieldDebugParams {
        relative_from_clip,
        mode: mode as u32,
        max_steps: 128,
        max_distance: 40.0,
    };
    let model = FieldDebugScene {
        field: &field,
        view: &view,
        valid: &valid,
        updated: &updated,
        relative_from_clip,
        max_steps: params.max_steps,
        max_distance: params.max_distance,
    };

    let pipeline = gpu.pipeline(&flatten(WRAPPER).expect("flattens"), "debug_pixels");
    let uniform = gpu.buffer("params", &uniform_bytes(&params), BufferUsages::UNIFORM);
    let updated_buffer = gpu.buffer("updated", &bytes(&updated), BufferUsages::empty());
    let field_buffer = gpu.buffer("field", &field.field_bytes(), BufferUsages::empty());
    let valid_buffer = gpu.buffer("valid", &bytes(&valid), BufferUsages::empty());
    let view_buffer = gpu.buffer("view", &uniform_bytes(&view), BufferUsages::UNIFORM);
    let out_size = u64::from(SIZE * SIZE) * 16;
    let out = gpu.buffer(
        "pixels",
        &vec![0u8; out_size as usize],
        BufferUsages::COPY_SRC,
    );
    let group = |index: u32, buffers: &[&wgpu::Buffer]| {
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipeline.get_bind_group_layout(index),
            entries: &entries,
        })
    };
    let groups = [
        group(0, &[&uniform, &updated_buffer]),
        group(1, &[&field_buffer, &valid_buffer, &view_buffer]),
        group(2, &[&out]),
    ];
    gpu.dispatch_groups(
        &pipeline,
        &[&groups[0], &groups[1], &groups[2]],
        [SIZE / 8, SIZE / 8, 1],
    );
    let got: Vec<f32> = gpu
        .read(&out, out_size)
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    let (mut sum, mut off, mut orange) = (0.0f32, 0, 0);
    for i in 0..(SIZE * SIZE) as usize {
        let uv = Vec2::new(
            (i as u32 % SIZE) as f32 + 0.5,
            (i as u32 / SIZE) as f32 + 0.5,
        ) / SIZE as f32;
        let want = field_debug_pixel(&model, mode, uv);
        let px = Vec3::new(got[4 * i], got[4 * i + 1], got[4 * i + 2]);
        let d = (px - want).abs().max_element();
        sum += d;
        off += usize::from(d > 0.01);
        orange += usize::from(px.x > 2.0 * px.z);
    }
    (sum / (SIZE * SIZE) as f32, off, orange)
}

#[test]
fn field_debug_views_match_the_model() {
    if !gpu_or_skip("field_debug_views_match_the_model") {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter");
    for offset in [Vec3::ZERO, Vec3::new(1e5, 30.0, -1e5)] {
        for mode in [
            FieldDebugMode::Shaded,
            FieldDebugMode::Levels,
            FieldDebugMode::Updates,
        ] {
            let (mean, off, orange) = compare(&gpu, offset, mode);
            eprintln!(
                "{mode:?} at {offset}: mean |Δ| {mean:.2e}, {off} of {} pixels off by > 0.01, \
                 {orange} orange",
                SIZE * SIZE
            );
            assert!(mean < 1e-3 && off * 200 < (SIZE * SIZE) as usize);
            if mode == FieldDebugMode::Updates {
                assert!(orange > 50, "the moved ball's bricks are orange");
            }
        }
    }
}
