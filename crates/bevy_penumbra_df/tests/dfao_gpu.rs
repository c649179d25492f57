//! Contract test of the distance-field AO passes on lavapipe: the trace
//! (`df/ao_trace.wgsl`, 8×8 tiles with two depth ranges) and the upsample
//! (`df/ao_upsample.wgsl`), run through wgpu directly on a known scene and depth buffer
//! (a plane, a sphere, a box, a capsule, a baked torus that lets 40 % of the sky through,
//! far and tiny objects and one that does not occlude), equal the CPU model (`penumbra_reference::dfao::trace_view`, then
//! `upsample`) — at full resolution, and at half resolution with a jitter, near the
//! origin and 10⁵ m away; and the temporal filter (`df/ao_temporal.wgsl`) equals
//! `temporal_step` on a history with sub-pixel motion, rejected texels, leaks and
//! partial confidence, with and without its confidence and fill steps.
//!
//! The scene and its depth buffer: `support/shadow_passes.rs`.

use glam::{UVec2, Vec3, Vec4};
use penumbra_df_core::ao::{
    AoTemporalView, AoTrace, AoTraceView, CONE_SHAPING, TILE_OBJECTS_SCALE, trace_size,
};
use penumbra_df_core::clipmap::{ClipmapLayout, ClipmapState, GlobalFieldView};
use penumbra_df_core::heightfield::HeightfieldTexture;
use penumbra_reference::df::f16_to_f32;
use penumbra_reference::dfao::{
    AoHistory, AoView, FarField, TemporalFrame, TemporalSteps, temporal_step, tile_object_counts,
    trace_view, trace_view_with_terrain, upsample,
};
use penumbra_reference::global_sdf::{ClipmapFormat, GlobalField};
use penumbra_reference::shadow_mask::{
    pack_gbuffer_normal, position_from_depth, unpack_gbuffer_normal,
};
use penumbra_shaders::flatten;
use penumbra_test::wgpu::{self, BufferUsages};
use penumbra_test::{GpuCompute, gpu_or_skip};

#[path = "support/shadow_passes.rs"]
mod support;

// The temporal pass's contract test.
#[path = "dfao_gpu/temporal.rs"]
mod temporal;

use support::*;

/// The trace's settings: a bias above 1.5 voxels of the baked torus (about 4 cm), so that
/// its cones start at the fine-field bias (`ao::object_bias`) and the analytic shapes'
/// at the trace's.
fn settings() -> AoTrace {
    AoTrace {
        max_distance: 2.0,
        cone_count: 9,
        steps_per_cone: 16,
        bias: 0.08,
        shaping: CONE_SHAPING,
    }
}

struct Pipelines {
    trace: wgpu::ComputePipeline,
    upsample: wgpu::ComputePipeline,
    temporal: wgpu::ComputePipeline,
}

fn pipelines(gpu: &GpuCompute) -> Pipelines {
    Pipelines {
        trace: gpu.pipeline(
            &flatten("#import penumbra::df::ao_trace\n").expect("flattens"),
            "trace",
        ),
        upsample: gpu.pipeline(
            &flatten("#import penumbra::df::ao_upsample\n").expect("flattens"),
            "upsample",
        ),
        temporal: gpu.pipeline(
            &flatten("#import penumbra::df::ao_temporal\n").expect("flattens"),
            "temporal",
        ),
    }
}

fn extent(w: u32, h: u32, d: u32) -> wgpu::Extent3d {
    wgpu::Extent3d {
        width: w,
        height: h,
        depth_or_array_layers: d,
    }
}

fn read_rgba16(gpu: &GpuCompute, texture: &wgpu::Texture) -> Vec<Vec4> {
    gpu.read_texture_2d(texture)
        .chunks_exact(8)
        .map(|c| {
            let h = |i: usize| f16_to_f32(u16::from_le_bytes([c[2 * i], c[2 * i + 1]]));
            Vec4::new(h(0), h(1), h(2), h(3))
        })
        .collect()
}

fn entry(binding: u32, resource: wgpu::BindingResource<'_>) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry { binding, resource }
}

/// The GPU's trace (and upsample when `divisor > 1`): `(trace, full)`.
fn gpu_ao(
    gpu: &GpuCompute,
    pipelines: &Pipelines,
    scene: &Scene,
    view: &View,
    uniform: &AoTraceView,
) -> (Vec<Vec4>, Option<Vec<Vec4>>) {
    gpu_ao_far(
        gpu,
        pipelines,
        scene,
        view,
        uniform,
        &FarInput::none(),
        &HeightfieldTexture::default(),
    )
}

/// The global field group 1 binds: the field buffer's bytes, the validity bits and the
/// view (no level: never read).
struct FarInput {
    field: Vec<u8>,
    valid: Vec<u32>,
    view: GlobalFieldView,
}

impl FarInput {
    fn none() -> FarInput {
        FarInput {
            field: vec![0; 4],
            valid: vec![0],
            view: GlobalFieldView::default(),
        }
    }

    fn bind_group(&self, gpu: &GpuCompute, pipeline: &wgpu::ComputePipeline) -> wgpu::BindGroup {
        let mut bytes = bevy::render::render_resource::encase::UniformBuffer::new(Vec::new());
        bytes.write(&self.view).expect("encodes");
        let view = gpu.buffer("global_view", bytes.as_ref(), BufferUsages::UNIFORM);
        let valid: Vec<u8> = self.valid.iter().flat_map(|w| w.to_le_bytes()).collect();
        let valid = gpu.buffer("global_valid", &valid, BufferUsages::empty());
        let field = gpu.buffer("global_field", &self.field, BufferUsages::empty());
        gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("global_field"),
            layout: &pipeline.get_bind_group_layout(1),
            entries: &[
                entry(0, field.as_entire_binding()),
                entry(1, valid.as_entire_binding()),
                entry(2, view.as_entire_binding()),
            ],
        })
    }
}

/// [`gpu_ao`] with the global field `far` and the terrains `terrain` bound.
fn gpu_ao_far(
    gpu: &GpuCompute,
    pipelines: &Pipelines,
    scene: &Scene,
    view: &View,
    uniform: &AoTraceView,
    far: &FarInput,
    terrain: &HeightfieldTexture,
) -> (Vec<Vec4>, Option<Vec<Vec4>>) {
    let (terrain_records, heights) = terrain_inputs(gpu, terrain);
    let records: Vec<u8> = scene.records.iter().flat_map(|r| r.to_bytes()).collect();
    let objects = gpu.buffer("objects", &records, BufferUsages::empty());
    let mut bytes = bevy::render::render_resource::encase::UniformBuffer::new(Vec::new());
    bytes.write(uniform).expect("encodes");
    let uniform_buffer = gpu.buffer("ao_view", bytes.as_ref(), BufferUsages::UNIFORM);
    let ViewInputs {
        atlas,
        brick_table,
        depth,
        gbuffer,
    } = view_inputs(gpu, scene, view);
    let size = uniform.trace_size;
    let traced = gpu.texture(
        "ao_trace",
        extent(size.x, size.y, 1),
        wgpu::TextureDimension::D2,
        wgpu::TextureFormat::Rgba16Float,
        8,
        &[],
    );
    let view_of = |t: &wgpu::Texture| t.create_view(&Default::default());
    let (atlas_view, depth_view, gbuffer_view, traced_view, table_view) = (
        view_of(&atlas),
        view_of(&depth),
        view_of(&gbuffer),
        view_of(&traced),
        view_of(&brick_table),
    );
    let bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("ao_trace"),
        layout: &pipelines.trace.get_bind_group_layout(0),
        entries: &[
            entry(0, objects.as_entire_binding()),
            entry(1, wgpu::BindingResource::TextureView(&atlas_view)),
            entry(2, wgpu::BindingResource::TextureView(&depth_view)),
            entry(3, wgpu::BindingResource::TextureView(&gbuffer_view)),
            entry(4, uniform_buffer.as_entire_binding()),
            entry(5, wgpu::BindingResource::TextureView(&traced_view)),
            entry(6, terrain_records.as_entire_binding()),
            entry(7, wgpu::BindingResource::TextureView(&heights)),
            entry(8, wgpu::BindingResource::TextureView(&table_view)),
        ],
    });
    let far_group = far.bind_group(gpu, &pipelines.trace);
    gpu.dispatch_groups(
        &pipelines.trace,
        &[&bind, &far_group],
        [size.x.div_ceil(8), size.y.div_ceil(8), 1],
    );
    let trace = read_rgba16(gpu, &traced);
    if uniform.divisor <= 1 {
        return (trace, None);
    }
    let full = gpu.texture(
        "ao",
        extent(WIDTH, HEIGHT, 1),
        wgpu::TextureDimension::D2,
        wgpu::TextureFormat::Rgba16Float,
        8,
        &[],
    );
    let full_view = view_of(&full);
    let bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("ao_upsample"),
        layout: &pipelines.upsample.get_bind_group_layout(0),
        entries: &[
            entry(0, wgpu::BindingResource::TextureView(&traced_view)),
            entry(1, wgpu::BindingResource::TextureView(&depth_view)),
            entry(2, wgpu::BindingResource::TextureView(&gbuffer_view)),
            entry(3, uniform_buffer.as_entire_binding()),
            entry(4, wgpu::BindingResource::TextureView(&full_view)),
        ],
    });
    gpu.dispatch(
        &pipelines.upsample,
        &bind,
        [WIDTH.div_ceil(8), HEIGHT.div_ceil(8), 1],
    );
    (trace, Some(read_rgba16(gpu, &full)))
}

/// Largest and mean |Δ| of the AO, and the largest bent-normal angle (radians), over
/// texels where either side is not background.
fn compare(got: &[Vec4], want: &[Vec4]) -> (f32, f32, f32) {
    assert_eq!(got.len(), want.len());
    let (mut worst, mut sum, mut angle) = (0.0f32, 0.0f32, 0.0f32);
    for (g, w) in got.iter().zip(want) {
        let e = (g.x - w.x).abs();
        worst = worst.max(e);
        sum += e;
        let (gb, wb) = (Vec3::new(g.y, g.z, g.w), Vec3::new(w.y, w.z, w.w));
        if wb != Vec3::ZERO {
            angle = angle.max(gb.normalize_or_zero().angle_between(wb));
        }
    }
    (worst, sum / got.len() as f32, angle)
}

fn check(name: &str, offset: Vec3) {
    check_scene(name, offset, scene);
}

fn check_scene(name: &str, offset: Vec3, scene: fn(Vec3) -> Scene) {
    if !gpu_or_skip(name) {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter");
    let pipelines = pipelines(&gpu);
    let scene = scene(offset);
    let view = view(&scene, offset);
    let full_size = UVec2::new(WIDTH, HEIGHT);
    let normals: Vec<Vec3> = (0..view.normals.len()).map(|i| view.normal(i)).collect();
    let model_view = AoView {
        view_from_clip: view.view_from_clip,
        world_from_view: view.world_from_view,
        size: full_size,
        depth: &view.depth,
        normals: &normals,
    };
    let trace = settings();
    for (divisor, jitter) in [(1, UVec2::ZERO), (2, UVec2::new(1, 1))] {
        let uniform = AoTraceView::new(
            &view.camera,
            view.view_from_clip,
            view.world_from_view,
            full_size,
            divisor,
            jitter,
            scene.records.len() as u32,
            &trace,
        );
        let want = trace_view(
            &scene.records,
            &scene.atlas,
            &view.camera,
            &model_view,
            divisor,
            jitter,
            &trace,
        );
        let occluded = want.iter().filter(|v| v.x < 0.8).count();
        assert!(occluded > 200, "{name}: only {occluded} occluded texels");
        let (got, full) = gpu_ao(&gpu, &pipelines, &scene, &view, &uniform);
        let (worst, mean, angle) = compare(&got, &want);
        check_tile_counts(
            name,
            &gpu,
            &pipelines,
            (&scene, &view, &model_view),
            &uniform,
        );
        eprintln!(
            "{name}, divisor {divisor} ({} texels, {occluded} occluded): trace max |Δ| {worst:.4}, mean {mean:.5}, bent max {angle:.4} rad",
            got.len()
        );
        // f16 storage (≤ 5·10⁻⁴ near 1) and GPU trigonometry; a wrongly culled object
        // or one cone lost moves texels by > 0.05.
        assert!(
            worst < 0.02 && mean < 2e-3 && angle < 0.05,
            "{name}: trace differs"
        );
        if let Some(full) = full {
            let distance: Vec<f32> = (0..WIDTH * HEIGHT)
                .map(|i| {
                    let d = view.depth[i as usize];
                    if d <= 0.0 {
                        return 0.0;
                    }
                    let px = glam::Vec2::new((i % WIDTH) as f32, (i / WIDTH) as f32);
                    position_from_depth(
                        view.view_from_clip,
                        view.world_from_view,
                        full_size.as_vec2(),
                        px,
                        d,
                    )
                    .length()
                })
                .collect();
            // The model upsamples the GPU's own trace: this checks the upsample alone.
            let want_full = upsample(
                &got,
                trace_size(full_size, divisor),
                divisor,
                jitter,
                &distance,
                &normals,
                full_size,
            );
            let (worst, mean, angle) = compare(&full, &want_full);
            eprintln!(
                "{name}, upsample: max |Δ| {worst:.4}, mean {mean:.5}, bent max {angle:.4} rad"
            );
            assert!(
                worst < 0.02 && mean < 1e-3 && angle < 0.05,
                "{name}: upsample differs"
            );
        }
    }
}

/// The objects-per-tile debug view: the trace's counts equal the model's
/// (`tile_object_counts`) on all but a few texels (a cull test decided by rounding), by
/// at most one. Reading the other range's objects, or counting objects out of reach,
/// moves hundreds.
fn check_tile_counts(
    name: &str,
    gpu: &GpuCompute,
    pipelines: &Pipelines,
    (scene, view, model_view): (&Scene, &View, &AoView),
    uniform: &AoTraceView,
) {
    let debug = AoTraceView {
        tile_objects_debug: 1,
        ..*uniform
    };
    let want = tile_object_counts(
        &scene.records,
        &scene.atlas,
        &view.camera,
        model_view,
        uniform.divisor,
        uniform.jitter,
        &settings(),
    );
    let (got, _) = gpu_ao(gpu, pipelines, scene, view, &debug);
    let (mut differ, mut worst, mut kept) = (0, 0u32, 0u32);
    for (g, &w) in got.iter().zip(&want) {
        let g = (g.x * TILE_OBJECTS_SCALE).round() as u32;
        if w == 0 && g == TILE_OBJECTS_SCALE as u32 {
            continue; // background: AO 1
        }
        differ += usize::from(g != w);
        worst = worst.max(g.abs_diff(w));
        kept += w;
    }
    let texels = want.iter().filter(|&&w| w > 0).count();
    eprintln!(
        "{name}, objects per tile: {texels} texels, mean {:.2} objects of {}, {differ} differ, by at most {worst}",
        f64::from(kept) / texels as f64,
        scene.records.len()
    );
    assert!(
        texels > 1000 && differ * 100 <= texels && worst <= 1,
        "{name}: tile counts differ"
    );
}

/// The trace with a global distance field (`AoTraceView::with_far_field`): objects up
/// to a 0.5 m switch, the field (composed by the model: the compose pass is checked in
/// `global_sdf_gpu`) from there to 6 m, equals `trace_view_far` — and the far field
/// matters: a trace that ignored it (or stopped at the switch) differs in hundreds of
/// texels.
fn check_far(name: &str, offset: Vec3) {
    if !gpu_or_skip(name) {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter");
    let pipelines = pipelines(&gpu);
    let scene = scene(offset);
    let view = view(&scene, offset);
    let full_size = UVec2::new(WIDTH, HEIGHT);
    let normals: Vec<Vec3> = (0..view.normals.len()).map(|i| view.normal(i)).collect();
    let model_view = AoView {
        view_from_clip: view.view_from_clip,
        world_from_view: view.world_from_view,
        size: full_size,
        depth: &view.depth,
        normals: &normals,
    };
    let trace = AoTrace {
        max_distance: 6.0,
        ..settings()
    };
    let switch = 0.5;
    // The clipmaps around the camera (f64: its tile and offset).
    let camera = glam::IVec3::from_array(view.camera.tile).as_dvec3()
        * f64::from(penumbra_df_core::object::TILE_SIZE)
        + view.camera.offset.as_dvec3();
    let layout = ClipmapLayout::new(3, 32, 6.4, 2.0).0;
    let mut state = ClipmapState::new(layout);
    let mut field = GlobalField::new(layout, ClipmapFormat::Unorm8);
    let terrain = hills(offset);
    for job in state.update(camera.as_vec3(), &[], usize::MAX).jobs {
        field.compose_records_and_terrain(job, &scene.records, &scene.atlas, &terrain);
    }
    let far = FarField::new(&field, &state, camera, switch);
    let input = FarInput {
        field: field.field_bytes(),
        valid: far.valid.clone(),
        view: far.view,
    };
    let model = |far: Option<&FarField>, trace: &AoTrace, terrain: &HeightfieldTexture| {
        trace_view_with_terrain(
            &scene.records,
            &scene.atlas,
            &view.camera,
            &model_view,
            (1, UVec2::ZERO),
            trace,
            far,
            terrain,
        )
    };
    let (want, evaluations, samples) = model(Some(&far), &trace, &terrain);
    let near = AoTrace {
        max_distance: switch,
        ..trace
    };
    let (near_only, _, _) = model(None, &near, &terrain);
    let (no_terrain, _, _) = model(None, &near, &HeightfieldTexture::default());
    let terrain_matters = near_only
        .iter()
        .zip(&no_terrain)
        .filter(|(w, n)| (w.x - n.x).abs() > 0.05)
        .count();
    let far_matters = want
        .iter()
        .zip(&near_only)
        .filter(|(w, n)| (w.x - n.x).abs() > 0.05)
        .count();
    let uniform = AoTraceView::new(
        &view.camera,
        view.view_from_clip,
        view.world_from_view,
        full_size,
        1,
        UVec2::ZERO,
        scene.records.len() as u32,
        &trace,
    )
    .with_far_field(&trace, switch);
    let uniform = AoTraceView {
        heightfield_count: terrain.records.len() as u32,
        ..uniform
    };
    let (got, _) = gpu_ao_far(&gpu, &pipelines, &scene, &view, &uniform, &input, &terrain);
    let (worst, mean, angle) = compare(&got, &want);
    eprintln!(
        "{name}: {} texels, {far_matters} changed by the far field, {terrain_matters} by the terrain's near trace, {evaluations} distance evaluations and {samples} field samples; max |Δ| {worst:.4}, mean {mean:.5}, bent max {angle:.4} rad",
        got.len()
    );
    assert!(far_matters > 300, "{name}: the far field hardly matters");
    assert!(terrain_matters > 300, "{name}: the terrain hardly matters");
    assert!(
        worst < 0.02 && mean < 2e-3 && angle < 0.05,
        "{name}: trace differs"
    );
}

#[test]
fn dfao_far_field_trace_matches_the_model() {
    check_far("dfao_far_field_trace_matches_the_model", Vec3::ZERO);
}

#[test]
fn dfao_far_field_trace_matches_the_model_far_from_the_origin() {
    check_far(
        "dfao_far_field_trace_matches_the_model_far_from_the_origin",
        Vec3::new(1.0e5, 30.0, -2.0e5),
    );
}

/// G-buffer normals facing away from the eye (exported against their triangles' winding,
/// a mirrored double-sided mesh's) are turned to face it before the cones leave
/// (`shadow_mask::facing_the_eye`, as the shadow trace does): with every normal negated,
/// the GPU's trace equals the model's, and most occluded texels stay as they are.
#[test]
fn dfao_turns_normals_facing_away_from_the_eye() {
    let name = "dfao_turns_normals_facing_away_from_the_eye";
    if !gpu_or_skip(name) {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter");
    let pipelines = pipelines(&gpu);
    let scene = scene(Vec3::ZERO);
    let straight = view(&scene, Vec3::ZERO);
    let mut inverted = view(&scene, Vec3::ZERO);
    for w in &mut inverted.normals {
        *w = pack_gbuffer_normal(-unpack_gbuffer_normal(*w));
    }
    let full_size = UVec2::new(WIDTH, HEIGHT);
    let trace = settings();
    let uniform = AoTraceView::new(
        &inverted.camera,
        inverted.view_from_clip,
        inverted.world_from_view,
        full_size,
        1,
        UVec2::ZERO,
        scene.records.len() as u32,
        &trace,
    );
    let model = |v: &View| {
        let normals: Vec<Vec3> = (0..v.normals.len()).map(|i| v.normal(i)).collect();
        let model_view = AoView {
            view_from_clip: v.view_from_clip,
            world_from_view: v.world_from_view,
            size: full_size,
            depth: &v.depth,
            normals: &normals,
        };
        trace_view(
            &scene.records,
            &scene.atlas,
            &v.camera,
            &model_view,
            1,
            UVec2::ZERO,
            &trace,
        )
    };
    let (want, as_is) = (model(&inverted), model(&straight));
    let (got, _) = gpu_ao(&gpu, &pipelines, &scene, &inverted, &uniform);
    let (worst, mean, angle) = compare(&got, &want);
    let same = want
        .iter()
        .zip(&as_is)
        .filter(|(a, b)| a.x < 0.8 && (a.x - b.x).abs() < 1e-3)
        .count();
    let occluded = as_is.iter().filter(|v| v.x < 0.8).count();
    eprintln!(
        "{name}: negated vs the model: max |Δ| {worst:.4}, mean {mean:.5}, bent max {angle:.4}; \
         {same} of {occluded} occluded texels as with the normals as they are"
    );
    assert!(
        worst < 0.02 && mean < 2e-3 && angle < 0.05,
        "{name}: trace differs"
    );
    assert!(same * 10 > occluded * 7, "{same} of {occluded}");
}

#[test]
fn dfao_passes_match_the_model_near_the_origin() {
    check("dfao_passes_match_the_model_near_the_origin", Vec3::ZERO);
}

/// The torus placed as sparse bricks: the passes read its brick table and pool as the
/// model does (`penumbra_reference::df`).
#[test]
fn dfao_passes_match_the_model_with_a_bricked_torus() {
    check_scene(
        "dfao_passes_match_the_model_with_a_bricked_torus",
        Vec3::ZERO,
        bricked_scene,
    );
}

#[test]
fn dfao_passes_match_the_model_far_from_the_origin() {
    check(
        "dfao_passes_match_the_model_far_from_the_origin",
        Vec3::new(1.0e5, 30.0, -2.0e5),
    );
}
