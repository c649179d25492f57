//! The temporal filter (`df/ao_temporal.wgsl`) against `temporal_step` (part of
//! `dfao_gpu.rs`, which holds the pipelines and helpers it uses).

use super::*;

/// An `Rgba32Float` texture of the view's size holding `values`.
fn float_texture(gpu: &GpuCompute, label: &str, values: &[Vec4]) -> wgpu::Texture {
    let bytes: Vec<u8> = values
        .iter()
        .flat_map(|v| v.to_array())
        .flat_map(f32::to_le_bytes)
        .collect();
    gpu.texture(
        label,
        extent(WIDTH, HEIGHT, 1),
        wgpu::TextureDimension::D2,
        wgpu::TextureFormat::Rgba32Float,
        16,
        &bytes,
    )
}

/// The GPU's temporal pass: `(value, state, filtered)`.
#[allow(clippy::too_many_arguments, reason = "the pass's inputs")]
fn gpu_temporal(
    gpu: &GpuCompute,
    pipelines: &Pipelines,
    scene: &Scene,
    view: &View,
    uniform: &AoTemporalView,
    current: &[Vec4],
    history: &AoHistory,
    motion: &[glam::Vec2],
) -> (Vec<Vec4>, Vec<Vec4>, Vec<Vec4>) {
    let mut bytes = bevy::render::render_resource::encase::UniformBuffer::new(Vec::new());
    bytes.write(uniform).expect("encodes");
    let uniform_buffer = gpu.buffer("ao_temporal_view", bytes.as_ref(), BufferUsages::UNIFORM);
    let ViewInputs { depth, gbuffer, .. } = view_inputs(gpu, scene, view);
    let motion: Vec<Vec4> = motion.iter().map(|m| m.extend(0.0).extend(0.0)).collect();
    let inputs = [
        float_texture(gpu, "current", current),
        float_texture(gpu, "history_value", &history.value),
        float_texture(gpu, "history_state", &history.state),
        depth,
        gbuffer,
        float_texture(gpu, "motion", &motion),
    ];
    let output = |label| {
        gpu.texture(
            label,
            extent(WIDTH, HEIGHT, 1),
            wgpu::TextureDimension::D2,
            wgpu::TextureFormat::Rgba16Float,
            8,
            &[],
        )
    };
    let outputs = [output("value"), output("state"), output("filtered")];
    let views: Vec<wgpu::TextureView> = inputs
        .iter()
        .chain(&outputs)
        .map(|t| t.create_view(&Default::default()))
        .collect();
    let texture = |i: usize| wgpu::BindingResource::TextureView(&views[i]);
    let bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("ao_temporal"),
        layout: &pipelines.temporal.get_bind_group_layout(0),
        entries: &[
            entry(0, texture(0)),
            entry(1, texture(1)),
            entry(2, texture(2)),
            entry(3, texture(3)),
            entry(4, texture(4)),
            entry(5, texture(5)),
            entry(6, uniform_buffer.as_entire_binding()),
            entry(7, texture(6)),
            entry(8, texture(7)),
            entry(9, texture(8)),
        ],
    });
    gpu.dispatch(
        &pipelines.temporal,
        &bind,
        [WIDTH.div_ceil(8), HEIGHT.div_ceil(8), 1],
    );
    (
        read_rgba16(gpu, &outputs[0]),
        read_rgba16(gpu, &outputs[1]),
        read_rgba16(gpu, &outputs[2]),
    )
}

/// The temporal pass equals the model. The history is the model's first step on this
/// view, then disturbed: texels whose stored distance belongs to another surface (every
/// 7th), confidences from 0 to 1, and AO offsets of up to ±0.15 (leaks either way); the
/// motion is sub-pixel and varies over the view (some pixels reproject outside it); the
/// camera moved 6 cm.
#[test]
fn dfao_temporal_pass_matches_the_model() {
    let name = "dfao_temporal_pass_matches_the_model";
    if !gpu_or_skip(name) {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter");
    let pipelines = pipelines(&gpu);
    let scene = scene(Vec3::ZERO);
    let view = view(&scene, Vec3::ZERO);
    let full_size = UVec2::new(WIDTH, HEIGHT);
    let n = (WIDTH * HEIGHT) as usize;
    let normals: Vec<Vec3> = (0..n).map(|i| view.normal(i)).collect();
    let positions: Vec<Vec3> = (0..n)
        .map(|i| {
            let d = view.depth[i];
            if d <= 0.0 {
                return Vec3::NAN;
            }
            let px = glam::Vec2::new((i as u32 % WIDTH) as f32, (i as u32 / WIDTH) as f32);
            position_from_depth(
                view.view_from_clip,
                view.world_from_view,
                full_size.as_vec2(),
                px,
                d,
            )
        })
        .collect();
    let model_view = AoView {
        view_from_clip: view.view_from_clip,
        world_from_view: view.world_from_view,
        size: full_size,
        depth: &view.depth,
        normals: &normals,
    };
    let traced = trace_view(
        &scene.records,
        &scene.atlas,
        &view.camera,
        &model_view,
        1,
        UVec2::ZERO,
        &settings(),
    );
    let wave = |i: usize, k: f32| (i as f32 * k).sin();
    let current: Vec<Vec4> = traced
        .iter()
        .enumerate()
        .map(|(i, v)| Vec4::new((v.x + 0.08 * wave(i, 0.37)).clamp(0.0, 1.0), v.y, v.z, v.w))
        .collect();
    let still = vec![glam::Vec2::ZERO; n];
    let previous_offset = Vec3::new(0.05, 0.0, -0.03);
    let first = TemporalFrame {
        size: full_size,
        current: &traced,
        positions: &positions,
        normals: &normals,
        motion: &still,
        previous_offset,
    };
    let mut history = temporal_step(&first, None, TemporalSteps::ALL);
    for (i, (v, s)) in history.value.iter_mut().zip(&mut history.state).enumerate() {
        v.x = (v.x + 0.15 * wave(i, 0.11)).clamp(0.0, 1.0);
        s.y = 0.5 + 0.5 * wave(i, 0.23);
        if i % 7 == 0 {
            s.x *= 1.2;
        }
    }
    let motion: Vec<glam::Vec2> = (0..n)
        .map(|i| {
            glam::Vec2::new(
                (1.3 + 0.8 * wave(i / WIDTH as usize, 0.2)) / WIDTH as f32,
                (-0.7 + 0.5 * wave(i % WIDTH as usize, 0.3)) / HEIGHT as f32,
            )
        })
        .collect();
    let frame = TemporalFrame {
        motion: &motion,
        current: &current,
        ..first
    };
    for steps in [TemporalSteps::ALL, TemporalSteps::PLAIN] {
        let want = temporal_step(&frame, Some(&history), steps);
        let uniform = AoTemporalView {
            view_from_clip: view.view_from_clip,
            world_from_view: view.world_from_view,
            previous_offset,
            history_valid: 1,
            full_size,
            confidence: u32::from(steps.confidence),
            spatial_fill: u32::from(steps.spatial_fill),
            origin: UVec2::ZERO,
        };
        let (value, state, filtered) = gpu_temporal(
            &gpu, &pipelines, &scene, &view, &uniform, &current, &history, &motion,
        );
        // The history the next frame reads, and what the lighting pass reads (the fill
        // in place of the pixel's own value where it applies).
        let (worst, mean, angle) = compare(&value, &want.value);
        let (shown_worst, shown_mean, shown_angle) = compare(&filtered, &want.filtered);
        let filled = want
            .value
            .iter()
            .zip(&want.filtered)
            .filter(|(v, f)| (v.x - f.x).abs() > 0.02)
            .count();
        let confidence = state
            .iter()
            .zip(&want.state)
            .map(|(g, w)| (g.y - w.y).abs())
            .fold(0.0f32, f32::max);
        let distance = state
            .iter()
            .zip(&want.state)
            .filter(|(_, w)| w.x > 0.0)
            .map(|(g, w)| (g.x - w.x).abs() / w.x)
            .fold(0.0f32, f32::max);
        let rejected = want
            .state
            .iter()
            .filter(|s| s.x > 0.0 && s.y == 0.0)
            .count();
        let blended = want
            .value
            .iter()
            .zip(&current)
            .filter(|(w, c)| (w.x - c.x).abs() > 0.02)
            .count();
        eprintln!(
            "temporal {steps:?}: max |Δ| {worst:.4}, mean {mean:.5}, bent max {angle:.4} rad, \
             shown max |Δ| {shown_worst:.4}, mean {shown_mean:.5}, bent max \
             {shown_angle:.4} rad, confidence max |Δ| {confidence:.4}, distance max rel \
             {distance:.5}; {rejected} pixels without history, {blended} moved by it, \
             {filled} shown filled"
        );
        assert!(
            rejected > 100 && blended > 500 && (filled > 100) == steps.spatial_fill,
            "the case does not exercise the pass"
        );
        assert!(
            shown_worst < 0.02 && shown_mean < 1e-3 && shown_angle < 0.05,
            "the filtered output differs"
        );
        // f16 output; a lost step (no rejection, no leak test, no fill, motion ignored)
        // moves pixels by > 0.05.
        assert!(
            worst < 0.02 && mean < 1e-3 && angle < 0.05 && confidence < 0.01 && distance < 2e-3,
            "temporal pass differs"
        );
    }
}
