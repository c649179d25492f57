//! A measurement, not a test (ignored; it asserts nothing about time): the wall-clock
//! time of each DFAO pass — trace, upsample, temporal — on this machine's Vulkan adapter
//! (lavapipe here) at 512², with the component's defaults (9 cones, 8 steps, divisor 4),
//! 16 cones of 16 steps at divisor 4, and 9 cones of 16 steps at half resolution, for 10,
//! 100 and 1,000 casters. Bevy's GPU time spans cannot split the passes on lavapipe (the module docs
//! of `bevy_penumbra_df::ao`), so each pass is dispatched on its own through wgpu and
//! timed from submission to the queue going idle, median of 5.
//!
//! The scene: a ground plane and spheres (radius 0.3–0.6 m) scattered over 40 × 40 m
//! around a camera 6 m up looking 14 m ahead; depth and normals are ray-cast
//! analytically. `cargo test -p bevy_penumbra_df --test dfao_pass_times -- --ignored
//! --nocapture`.

use bevy::render::render_resource::encase::internal::WriteInto;
use bevy::render::render_resource::encase::{ShaderType, UniformBuffer};
use glam::{Affine3A, Mat3, Mat4, UVec2, Vec2, Vec3, Vec4};
use penumbra_df_core::ao::{AoTemporalView, AoTrace, AoTraceView, CONE_SHAPING, trace_size};
use penumbra_df_core::clipmap::GlobalFieldView;
use penumbra_df_core::cull::CameraOrigin;
use penumbra_df_core::object::{CasterShape, ObjectDesc, ObjectRecord, encode, flags};
use penumbra_reference::shadow_mask::pack_gbuffer_normal;
use penumbra_shaders::flatten;
use penumbra_test::wgpu::{self, BufferUsages};
use penumbra_test::{GpuCompute, gpu_or_skip};
use std::time::{Duration, Instant};

const SIZE: u32 = 512;
const EYE: Vec3 = Vec3::new(0.0, 6.0, 14.0);

/// `DistanceFieldAmbientOcclusion::default()`'s trace at the dfao example's 3 m reach,
/// with `cone_count` cones of `steps_per_cone` steps.
fn trace_settings(cone_count: u32, steps_per_cone: u32) -> AoTrace {
    AoTrace {
        max_distance: 3.0,
        cone_count,
        steps_per_cone,
        bias: 0.02,
        shaping: CONE_SHAPING,
    }
}

/// A small deterministic generator (xorshift).
struct Rng(u32);

impl Rng {
    fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 17;
        self.0 ^= self.0 << 5;
        (self.0 >> 8) as f32 / (1 << 24) as f32
    }
}

/// The plane and `count − 1` spheres `(centre, radius)`.
fn spheres(count: u32) -> Vec<(Vec3, f32)> {
    let mut rng = Rng(0x9e37_79b9);
    (1..count)
        .map(|_| {
            let r = 0.3 + 0.3 * rng.next();
            let c = Vec3::new(rng.next() * 40.0 - 20.0, r, rng.next() * 40.0 - 26.0);
            (c, r)
        })
        .collect()
}

struct Inputs {
    depth: Vec<f32>,
    normals: Vec<u32>,
    view_from_clip: Mat4,
    world_from_view: Mat3,
}

/// Depth (reverse-Z) and packed normals of the plane and spheres, cast analytically.
fn cast(spheres: &[(Vec3, f32)]) -> Inputs {
    let view_from_world = Mat4::look_at_rh(EYE, Vec3::ZERO, Vec3::Y);
    let world_from_view = Mat3::from_mat4(view_from_world).transpose();
    let near = 0.1;
    let clip_from_view = Mat4::perspective_infinite_reverse_rh(0.9, 1.0, near);
    let view_from_clip = clip_from_view.inverse();
    let forward = -world_from_view.z_axis;
    let (mut depth, mut normals) = (Vec::new(), Vec::new());
    for y in 0..SIZE {
        for x in 0..SIZE {
            let uv = (Vec2::new(x as f32, y as f32) + 0.5) / SIZE as f32;
            let v = view_from_clip * Vec4::new(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, 0.5, 1.0);
            let dir = (world_from_view * (v.truncate() / v.w)).normalize();
            let mut hit = (f32::INFINITY, Vec3::ZERO);
            if dir.y < 0.0 {
                hit = (-EYE.y / dir.y, Vec3::Y);
            }
            for &(c, r) in spheres {
                let oc = EYE - c;
                let b = oc.dot(dir);
                let disc = b * b - (oc.length_squared() - r * r);
                if disc > 0.0 {
                    let t = -b - disc.sqrt();
                    if t > 0.0 && t < hit.0 {
                        hit = (t, (EYE + dir * t - c) / r);
                    }
                }
            }
            let (t, n) = hit;
            let z = t * dir.dot(forward);
            depth.push(if t.is_finite() { near / z } else { 0.0 });
            normals.push(if t.is_finite() {
                pack_gbuffer_normal(n)
            } else {
                0
            });
        }
    }
    Inputs {
        depth,
        normals,
        view_from_clip,
        world_from_view,
    }
}

/// The plane and the balls as occluding casters.
fn records(balls: &[(Vec3, f32)]) -> Vec<ObjectRecord> {
    let live = flags::LIVE | flags::CASTS_OCCLUSION | flags::VISIBLE;
    let plane = ObjectDesc {
        world_from_local: Affine3A::IDENTITY,
        shape: CasterShape::Plane,
        flags: live | flags::UNBOUNDED,
    };
    std::iter::once(plane)
        .chain(balls.iter().map(|&(c, radius)| ObjectDesc {
            world_from_local: Affine3A::from_translation(c),
            shape: CasterShape::Sphere { radius },
            flags: live,
        }))
        .map(|d| encode(&d).expect("encodes"))
        .collect()
}

/// The trace's inputs on the GPU: the object buffer, depth and G-buffer.
struct GpuInputs {
    objects: wgpu::Buffer,
    depth: wgpu::Texture,
    gbuffer: wgpu::Texture,
}

fn gpu_inputs(gpu: &GpuCompute, records: &[ObjectRecord], inputs: &Inputs) -> GpuInputs {
    let record_bytes: Vec<u8> = records.iter().flat_map(|r| r.to_bytes()).collect();
    let depth_bytes: Vec<u8> = inputs.depth.iter().flat_map(|d| d.to_le_bytes()).collect();
    let gbuffer_bytes: Vec<u8> = inputs
        .normals
        .iter()
        .flat_map(|&n| [0u32, 0, 0, n])
        .flat_map(u32::to_le_bytes)
        .collect();
    let texture = |label: &str, format, texel: u32, data: &[u8]| {
        gpu.texture(
            label,
            extent(SIZE, SIZE, 1),
            wgpu::TextureDimension::D2,
            format,
            texel,
            data,
        )
    };
    GpuInputs {
        objects: gpu.buffer("objects", &record_bytes, BufferUsages::empty()),
        depth: texture("depth", wgpu::TextureFormat::R32Float, 4, &depth_bytes),
        gbuffer: texture(
            "gbuffer",
            wgpu::TextureFormat::Rgba32Uint,
            16,
            &gbuffer_bytes,
        ),
    }
}

/// A 1-voxel atlas (analytic casters only).
/// The trace's terrain bindings without a terrain: one zeroed record and a 1 × 1
/// height texture (what the app binds then).
fn no_terrain(gpu: &GpuCompute) -> (wgpu::Buffer, wgpu::TextureView) {
    use bevy::render::render_resource::encase::StorageBuffer;
    let mut bytes = StorageBuffer::new(Vec::new());
    bytes
        .write(&vec![
            penumbra_df_core::heightfield::HeightfieldRecord::default(),
        ])
        .expect("encodes");
    let records = gpu.buffer("terrains", bytes.as_ref(), BufferUsages::empty());
    let heights = gpu
        .texture(
            "heights",
            extent(1, 1, 1),
            wgpu::TextureDimension::D2,
            wgpu::TextureFormat::R32Float,
            4,
            &[0; 4],
        )
        .create_view(&Default::default());
    (records, heights)
}

fn empty_atlas(gpu: &GpuCompute) -> wgpu::Texture {
    gpu.texture(
        "atlas",
        extent(1, 1, 1),
        wgpu::TextureDimension::D3,
        wgpu::TextureFormat::R16Float,
        2,
        &[0, 0x3c],
    )
}

/// A one-texel brick table (no volume here is bricked).
fn empty_brick_table(gpu: &GpuCompute) -> wgpu::Texture {
    gpu.texture(
        "brick_table",
        extent(1, 1, 1),
        wgpu::TextureDimension::D2,
        wgpu::TextureFormat::R32Uint,
        4,
        &[0; 4],
    )
}

fn extent(w: u32, h: u32, d: u32) -> wgpu::Extent3d {
    wgpu::Extent3d {
        width: w,
        height: h,
        depth_or_array_layers: d,
    }
}

fn entry(binding: u32, resource: wgpu::BindingResource<'_>) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry { binding, resource }
}

fn uniform<T: ShaderType + WriteInto>(gpu: &GpuCompute, label: &str, value: &T) -> wgpu::Buffer {
    let mut bytes = UniformBuffer::new(Vec::new());
    bytes.write(value).expect("encodes");
    gpu.buffer(label, bytes.as_ref(), BufferUsages::UNIFORM)
}

/// The trace's group 1: a global field's bytes, validity bits and view.
fn field_group(
    gpu: &GpuCompute,
    pipeline: &wgpu::ComputePipeline,
    field: &[u8],
    valid: &[u32],
    view: &GlobalFieldView,
) -> wgpu::BindGroup {
    let field = gpu.buffer("global_field", field, BufferUsages::empty());
    let valid: Vec<u8> = valid.iter().flat_map(|w| w.to_le_bytes()).collect();
    let valid = gpu.buffer("global_valid", &valid, BufferUsages::empty());
    let view = uniform(gpu, "global_view", view);
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

/// Median wall-clock of 5 runs of `pipeline` over `groups` workgroups, each from
/// submission until the queue is idle.
fn time(
    gpu: &GpuCompute,
    pipeline: &wgpu::ComputePipeline,
    binds: &[&wgpu::BindGroup],
    groups: UVec2,
) -> Duration {
    let wait = || {
        gpu.device
            .poll(wgpu::PollType::wait_indefinitely())
            .expect("device poll");
    };
    let mut times: Vec<Duration> = (0..5)
        .map(|_| {
            wait();
            let start = Instant::now();
            gpu.dispatch_groups(pipeline, binds, [groups.x, groups.y, 1]);
            wait();
            start.elapsed()
        })
        .collect();
    times.sort();
    times[2]
}

#[test]
#[ignore = "a measurement: run with --ignored --nocapture"]
fn dfao_pass_times_at_512() {
    if !gpu_or_skip("dfao_pass_times_at_512") {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter");
    let no_terrain = no_terrain(&gpu);
    let pipeline = |module: &str, entry: &str| {
        gpu.pipeline(
            &flatten(&format!("#import penumbra::df::{module}\n")).expect("flattens"),
            entry,
        )
    };
    let (trace, upsample, temporal) = (
        pipeline("ao_trace", "trace"),
        pipeline("ao_upsample", "upsample"),
        pipeline("ao_temporal", "temporal"),
    );
    let full = UVec2::splat(SIZE);
    let texture = |label: &str, size: UVec2, format, texel: u32, data: &[u8]| {
        gpu.texture(
            label,
            extent(size.x, size.y, 1),
            wgpu::TextureDimension::D2,
            format,
            texel,
            data,
        )
    };
    let atlas = empty_atlas(&gpu);
    let brick_table = empty_brick_table(&gpu).create_view(&Default::default());
    eprintln!(
        "| casters | cones / steps / divisor | trace | upsample | temporal |\n|---|---|---|---|---|"
    );
    // The defaults, 16 cones, and 9 at half resolution (Unreal's trace resolution).
    for (count, (cones, steps, divisor)) in [10, 100, 1000]
        .into_iter()
        .flat_map(|n| [(n, (9, 8, 4)), (n, (16, 16, 4)), (n, (9, 16, 2))])
    {
        let balls = spheres(count);
        let inputs = cast(&balls);
        let records = records(&balls);
        let GpuInputs {
            objects,
            depth,
            gbuffer,
        } = gpu_inputs(&gpu, &records, &inputs);
        let camera = CameraOrigin::at(EYE).expect("finite");
        let view = AoTraceView::new(
            &camera,
            inputs.view_from_clip,
            inputs.world_from_view,
            full,
            divisor,
            UVec2::ZERO,
            records.len() as u32,
            &trace_settings(cones, steps),
        );
        let trace_uniform = uniform(&gpu, "ao_view", &view);
        let small = trace_size(full, divisor);
        let traced = texture("traced", small, wgpu::TextureFormat::Rgba16Float, 8, &[]);
        let upsampled = texture("upsampled", full, wgpu::TextureFormat::Rgba16Float, 8, &[]);
        let value = texture("value", full, wgpu::TextureFormat::Rgba16Float, 8, &[]);
        let state = texture("state", full, wgpu::TextureFormat::Rgba16Float, 8, &[]);
        let filtered = texture("filtered", full, wgpu::TextureFormat::Rgba16Float, 8, &[]);
        let history_value = texture(
            "history_value",
            full,
            wgpu::TextureFormat::Rgba16Float,
            8,
            &[],
        );
        let history_state = texture(
            "history_state",
            full,
            wgpu::TextureFormat::Rgba16Float,
            8,
            &[],
        );
        let motion = texture("motion", full, wgpu::TextureFormat::Rgba16Float, 8, &[]);
        let v = |t: &wgpu::Texture| t.create_view(&Default::default());
        let views = [
            &atlas,
            &depth,
            &gbuffer,
            &traced,
            &upsampled,
            &value,
            &state,
            &filtered,
            &history_value,
            &history_state,
            &motion,
        ]
        .map(v);
        let tv = |i: usize| wgpu::BindingResource::TextureView(&views[i]);
        let trace_bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("ao_trace"),
            layout: &trace.get_bind_group_layout(0),
            entries: &[
                entry(0, objects.as_entire_binding()),
                entry(1, tv(0)),
                entry(2, tv(1)),
                entry(3, tv(2)),
                entry(4, trace_uniform.as_entire_binding()),
                entry(5, tv(3)),
                entry(6, no_terrain.0.as_entire_binding()),
                entry(7, wgpu::BindingResource::TextureView(&no_terrain.1)),
                entry(8, wgpu::BindingResource::TextureView(&brick_table)),
            ],
        });
        let upsample_bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("ao_upsample"),
            layout: &upsample.get_bind_group_layout(0),
            entries: &[
                entry(0, tv(3)),
                entry(1, tv(1)),
                entry(2, tv(2)),
                entry(3, trace_uniform.as_entire_binding()),
                entry(4, tv(4)),
            ],
        });
        // The first frame of the filter: no history, so every pixel takes the spatial
        // fill (its dearest case); then frames reading the previous one's output.
        let temporal_bind = |history_valid: u32, history: (usize, usize), out: (usize, usize)| {
            let t = AoTemporalView {
                view_from_clip: inputs.view_from_clip,
                world_from_view: inputs.world_from_view,
                previous_offset: Vec3::ZERO,
                history_valid,
                full_size: full,
                confidence: 1,
                spatial_fill: 1,
                origin: UVec2::ZERO,
            };
            let buffer = uniform(&gpu, "ao_temporal_view", &t);
            let bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("ao_temporal"),
                layout: &temporal.get_bind_group_layout(0),
                entries: &[
                    entry(0, tv(4)),
                    entry(1, tv(history.0)),
                    entry(2, tv(history.1)),
                    entry(3, tv(1)),
                    entry(4, tv(2)),
                    entry(5, tv(10)),
                    entry(6, buffer.as_entire_binding()),
                    entry(7, tv(out.0)),
                    entry(8, tv(out.1)),
                    entry(9, tv(7)),
                ],
            });
            (bind, buffer)
        };
        let groups = |s: UVec2| UVec2::new(s.x.div_ceil(8), s.y.div_ceil(8));
        let no_field = field_group(&gpu, &trace, &[0; 4], &[0], &GlobalFieldView::default());
        let t_trace = time(&gpu, &trace, &[&trace_bind, &no_field], groups(small));
        let t_upsample = time(&gpu, &upsample, &[&upsample_bind], groups(full));
        let (first, _keep) = temporal_bind(0, (8, 9), (5, 6));
        let t_first = time(&gpu, &temporal, &[&first], groups(full));
        // Three more frames (the confidence passes ½ after two), then the steady one.
        for (history, out) in [((5, 6), (8, 9)), ((8, 9), (5, 6)), ((5, 6), (8, 9))] {
            let (bind, _keep) = temporal_bind(1, history, out);
            gpu.dispatch(&temporal, &bind, [groups(full).x, groups(full).y, 1]);
        }
        let (steady, _keep) = temporal_bind(1, (8, 9), (5, 6));
        let t_steady = time(&gpu, &temporal, &[&steady], groups(full));
        let ms = |d: Duration| d.as_secs_f64() * 1e3;
        eprintln!(
            "| {count} | {cones} / {steps} / {divisor} | {:.1} ms | {:.1} ms | {:.1} ms ({:.1} ms on a first frame) |",
            ms(t_trace),
            ms(t_upsample),
            ms(t_steady),
            ms(t_first)
        );
    }
}

/// Ground truth: the AO at world point `p` (normal `n`) from `rays_sqrt²` stratified
/// cosine-weighted rays, each blocked when it meets the plane `y = 0` or a ball within
/// `reach` (exact intersections).
fn truth_ao(balls: &[(Vec3, f32)], p: Vec3, n: Vec3, reach: f32, rays_sqrt: u32) -> f32 {
    let near: Vec<(Vec3, f32)> = balls
        .iter()
        .copied()
        .filter(|&(c, r)| (c - p).length() < reach + r)
        .collect();
    let (t, b) = penumbra_df_core::ao::tangent_frame(n);
    let origin = p + n * 1e-3;
    let mut open = 0;
    for i in 0..rays_sqrt {
        for j in 0..rays_sqrt {
            let u = (i as f32 + 0.5) / rays_sqrt as f32;
            let phi = std::f32::consts::TAU * (j as f32 + 0.5) / rays_sqrt as f32;
            let (rho, z) = (u.sqrt(), (1.0 - u).sqrt());
            let dir = (t * (rho * phi.cos()) + b * (rho * phi.sin()) + n * z).normalize();
            let plane = dir.y < 0.0 && -origin.y / dir.y < reach;
            let ball = near.iter().any(|&(c, r)| {
                let oc = origin - c;
                let bb = oc.dot(dir);
                let disc = bb * bb - (oc.length_squared() - r * r);
                disc > 0.0 && {
                    let s = disc.sqrt();
                    let t = if -bb - s > 0.0 { -bb - s } else { -bb + s };
                    t > 0.0 && t < reach
                }
            });
            open += usize::from(!(plane || ball));
        }
    }
    open as f32 / (rays_sqrt * rays_sqrt) as f32
}

/// The global field's far field on 1,000 casters (the plane and 999 balls above), the
/// component's defaults at Unreal's 10 m reach: per configuration — objects only, and
/// the far field from a switch distance of 0.5, 1, 2, 3 and 4 m — the object distance
/// evaluations and field samples per pixel and the mean |AO − truth| (the CPU model on
/// every 16th pixel of each axis; truth: 1,024 exact rays per pixel), and the trace
/// pass's lavapipe time at 512² with divisor 4 (median of 5). The field: the default
/// clipmaps (4 × 128³) around the camera, composed by the model (equal to the GPU's:
/// `global_sdf_gpu`). `cargo test -p bevy_penumbra_df --test dfao_pass_times
/// dfao_far_field -- --ignored --nocapture`.
#[test]
#[ignore = "a measurement: run with --ignored --nocapture"]
fn dfao_far_field_figures_at_512() {
    use penumbra_df_core::clipmap::{ClipmapLayout, ClipmapState};
    use penumbra_reference::df::Atlas;
    use penumbra_reference::dfao::{FarField, pixel_ao_counted, pixel_ao_far};
    use penumbra_reference::global_sdf::{ClipmapFormat, GlobalField};
    use penumbra_reference::shadow_mask::position_from_depth;
    if !gpu_or_skip("dfao_far_field_figures_at_512") {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter");
    let no_terrain = no_terrain(&gpu);
    let trace_pipeline = gpu.pipeline(
        &flatten("#import penumbra::df::ao_trace\n").expect("flattens"),
        "trace",
    );
    let balls = spheres(1000);
    let inputs = cast(&balls);
    let records = records(&balls);
    let trace = AoTrace {
        max_distance: 10.0,
        ..trace_settings(9, 8)
    };
    let atlas = Atlas::new(glam::UVec3::ONE);
    let layout = ClipmapLayout::DEFAULT;
    let mut state = ClipmapState::new(layout);
    let mut field = GlobalField::new(layout, ClipmapFormat::Unorm8);
    let start = Instant::now();
    for job in state.update(EYE, &[], usize::MAX).jobs {
        field.compose_records(job, &records, &atlas);
    }
    eprintln!(
        "model composition of the default clipmaps: {:.1} s",
        start.elapsed().as_secs_f64()
    );
    let camera = CameraOrigin::at(EYE).expect("finite");

    // The CPU figures.
    let mut pixels = Vec::new();
    for y in (8..SIZE).step_by(16) {
        for x in (8..SIZE).step_by(16) {
            let i = (y * SIZE + x) as usize;
            let d = inputs.depth[i];
            if d <= 0.0 {
                continue;
            }
            let p = position_from_depth(
                inputs.view_from_clip,
                inputs.world_from_view,
                Vec2::splat(SIZE as f32),
                Vec2::new(x as f32, y as f32),
                d,
            );
            let world = EYE + p;
            let n = balls
                .iter()
                .find(|&&(c, r)| ((world - c).length() - r).abs() < 1e-2)
                .map_or(Vec3::Y, |&(c, _)| (world - c).normalize());
            pixels.push((p, n, truth_ao(&balls, world, n, trace.max_distance, 32)));
        }
    }
    let switches = [None, Some(0.5), Some(1.0), Some(2.0), Some(3.0), Some(4.0)];
    eprintln!(
        "\n{} casters, {} pixels, 9 cones × 8 steps, 10 m reach\n\n| trace | object evaluations / px | field samples / px | mean \\|AO − truth\\| | trace at 512², divisor 4 ({}) |\n|---|---|---|---|---|",
        records.len(),
        pixels.len(),
        penumbra_test::vulkan_adapter().unwrap_or("?")
    );
    // The GPU inputs.
    let full = UVec2::splat(SIZE);
    let texture = |label: &str, size: UVec2, format, texel: u32, data: &[u8]| {
        gpu.texture(
            label,
            extent(size.x, size.y, 1),
            wgpu::TextureDimension::D2,
            format,
            texel,
            data,
        )
    };
    let GpuInputs {
        objects,
        depth,
        gbuffer,
    } = gpu_inputs(&gpu, &records, &inputs);
    let atlas_texture = empty_atlas(&gpu);
    let brick_table = empty_brick_table(&gpu).create_view(&Default::default());
    let divisor = 4;
    let small = trace_size(full, divisor);
    let traced = texture("traced", small, wgpu::TextureFormat::Rgba16Float, 8, &[]);
    let views =
        [&atlas_texture, &depth, &gbuffer, &traced].map(|t| t.create_view(&Default::default()));
    let far_view = FarField::new(&field, &state, EYE.as_dvec3(), 1.0);
    let with_field = field_group(
        &gpu,
        &trace_pipeline,
        &field.field_bytes(),
        &far_view.valid,
        &far_view.view,
    );
    for switch in switches {
        let (mut evaluations, mut samples, mut error) = (0u64, 0u64, 0.0f64);
        for &(p, n, truth) in &pixels {
            let (ao, e, s) = match switch {
                None => {
                    let (s, e) = pixel_ao_counted(&records, &atlas, &camera, p, n, &trace);
                    (s.ao, e, 0)
                }
                Some(switch) => {
                    let far = FarField::new(&field, &state, EYE.as_dvec3(), switch);
                    let (s, e, f) = pixel_ao_far(&records, &atlas, &camera, p, n, &trace, &far);
                    (s.ao, e, f)
                }
            };
            evaluations += u64::from(e);
            samples += u64::from(s);
            error += f64::from((ao - truth).abs());
        }
        let mut view = AoTraceView::new(
            &camera,
            inputs.view_from_clip,
            inputs.world_from_view,
            full,
            divisor,
            UVec2::ZERO,
            records.len() as u32,
            &trace,
        );
        if let Some(switch) = switch {
            view = view.with_far_field(&trace, switch);
        }
        let trace_uniform = uniform(&gpu, "ao_view", &view);
        let tv = |i: usize| wgpu::BindingResource::TextureView(&views[i]);
        let bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("ao_trace"),
            layout: &trace_pipeline.get_bind_group_layout(0),
            entries: &[
                entry(0, objects.as_entire_binding()),
                entry(1, tv(0)),
                entry(2, tv(1)),
                entry(3, tv(2)),
                entry(4, trace_uniform.as_entire_binding()),
                entry(5, tv(3)),
                entry(6, no_terrain.0.as_entire_binding()),
                entry(7, wgpu::BindingResource::TextureView(&no_terrain.1)),
                entry(8, wgpu::BindingResource::TextureView(&brick_table)),
            ],
        });
        let groups = UVec2::new(small.x.div_ceil(8), small.y.div_ceil(8));
        let t = time(&gpu, &trace_pipeline, &[&bind, &with_field], groups);
        let n = pixels.len() as f64;
        eprintln!(
            "| {} | {:.1} | {:.1} | {:.4} | {:.1} ms |",
            switch.map_or("objects only".to_string(), |s| format!(
                "far field from {s} m"
            )),
            evaluations as f64 / n,
            samples as f64 / n,
            error / n,
            t.as_secs_f64() * 1e3
        );
    }
}
