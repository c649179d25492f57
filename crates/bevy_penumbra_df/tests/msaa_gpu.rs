//! Contract test of deferred MSAA's edge test and resolve on lavapipe
//! (`lighting/msaa.wgsl`, run through wgpu by a compute wrapper): every pixel of the
//! CPU model's fence scene (`penumbra_reference::msaa`: wires, bars, a ball, a tilted
//! ground against the sky, 96 × 64 × 4 samples) plus pixels with one sample nudged
//! across each threshold is classified as `penumbra_reference::msaa::is_edge` does,
//! for the default thresholds, a tighter normal cone, a looser depth rule and two
//! samples; the resolve equals the model's mean.

use bevy::render::render_resource::ShaderType;
use glam::Vec3;
use penumbra_df_core::msaa::EdgeParams;
use penumbra_reference::msaa::{
    FENCE_SIZE, GPixel, GSample, fence, fence_camera, is_edge, resolve, sample_pixel,
};
use penumbra_shaders::flatten;
use penumbra_test::wgpu::{self, BufferUsages};
use penumbra_test::{GpuCompute, gpu_or_skip, storage_bytes, uniform_bytes};

const WRAPPER: &str = "
#import penumbra::lighting::msaa::{MsaaEdgeParams, MsaaSample, msaa_is_edge, msaa_resolve}

struct Pixel {
    samples: array<MsaaSample, 4>,
    colors: array<vec4<f32>, 4>,
    z_slope: f32,
}

@group(0) @binding(0) var<storage, read> pixels: array<Pixel>;
@group(0) @binding(1) var<uniform> params: MsaaEdgeParams;
@group(0) @binding(2) var<storage, read_write> out: array<vec4<f32>>;

@compute @workgroup_size(64, 1, 1)
fn classify(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= arrayLength(&pixels) {
        return;
    }
    let p = pixels[id.x];
    var colors: array<vec3<f32>, 4>;
    for (var i = 0u; i < 4u; i++) {
        colors[i] = p.colors[i].xyz;
    }
    let edge = msaa_is_edge(p.samples, p.z_slope, params);
    out[id.x] = vec4<f32>(msaa_resolve(colors, params.sample_count), select(0.0, 1.0, edge));
}
";

#[derive(ShaderType, Clone, Copy, Default)]
struct GpuSample {
    normal: Vec3,
    view_z: f32,
    material: u32,
    covered: u32,
}

#[derive(ShaderType, Clone, Copy, Default)]
struct GpuPixel {
    samples: [GpuSample; 4],
    colors: [glam::Vec4; 4],
    z_slope: f32,
}

/// The model's pixels, then each pixel with sample 2 nudged just inside and just
/// beyond the depth and normal thresholds.
fn pixels() -> Vec<GPixel> {
    let (scene, camera, (w, h)) = (fence(), fence_camera(), FENCE_SIZE);
    let mut out: Vec<GPixel> = (0..w * h)
        .map(|i| sample_pixel(&scene, &camera, i % w, i / w).0)
        .collect();
    let d = EdgeParams::default();
    let flat = GSample {
        view_z: 8.0,
        normal: Vec3::Y,
        material: 1,
    };
    for k in [0.98f32, 1.02] {
        let allowed = d.slope_scale * 0.05 + d.relative_depth * flat.view_z;
        let angle = d.normal_cos.acos() * k;
        for other in [
            GSample {
                view_z: flat.view_z + allowed * k,
                ..flat
            },
            GSample {
                normal: Vec3::new(angle.sin(), angle.cos(), 0.0),
                ..flat
            },
        ] {
            out.push(GPixel {
                samples: [Some(flat), Some(flat), Some(other), Some(flat)],
                z_slope: 0.05,
            });
        }
    }
    out
}

fn to_gpu(p: &GPixel, i: usize) -> GpuPixel {
    GpuPixel {
        samples: p.samples.map(|s| {
            s.map_or(GpuSample::default(), |s| GpuSample {
                normal: s.normal,
                view_z: s.view_z,
                material: s.material,
                covered: 1,
            })
        }),
        colors: std::array::from_fn(|k| {
            let v = (i * 4 + k) as f32;
            glam::Vec4::new(
                v.sin().abs(),
                (0.3 * v).cos().abs(),
                0.01 * (v % 100.0),
                0.0,
            )
        }),
        z_slope: p.z_slope,
    }
}

#[test]
fn edge_test_and_resolve_match_the_model() {
    if !gpu_or_skip("edge_test_and_resolve_match_the_model") {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter");
    let pipeline = gpu.pipeline(&flatten(WRAPPER).expect("flattens"), "classify");
    let pixels = pixels();
    let gpu_pixels: Vec<GpuPixel> = pixels
        .iter()
        .enumerate()
        .map(|(i, p)| to_gpu(p, i))
        .collect();
    let input = gpu.buffer("pixels", &storage_bytes(&gpu_pixels), BufferUsages::empty());
    let out_size = pixels.len() as u64 * 16;
    let out = gpu.zeroed("out", out_size, BufferUsages::COPY_SRC);
    let d = EdgeParams::default();
    for params in [
        d,
        EdgeParams {
            normal_cos: 0.999,
            ..d
        },
        EdgeParams {
            slope_scale: 3.0,
            relative_depth: 1e-2,
            ..d
        },
        EdgeParams {
            sample_count: 2,
            ..d
        },
    ] {
        let uniform = gpu.buffer("params", &uniform_bytes(&params), BufferUsages::UNIFORM);
        let bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: input.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: uniform.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: out.as_entire_binding(),
                },
            ],
        });
        gpu.dispatch(&pipeline, &bind, [(pixels.len() as u32).div_ceil(64), 1, 1]);
        let got: Vec<f32> = gpu
            .read(&out, out_size)
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        let (mut edges, mut disagree, mut worst) = (0, 0, 0.0f32);
        for (i, (p, g)) in pixels.iter().zip(&gpu_pixels).enumerate() {
            let want = is_edge(p, &params);
            let colors: Vec<Vec3> = g.colors[..params.sample_count as usize]
                .iter()
                .map(|c| c.truncate())
                .collect();
            let r = resolve(&colors);
            edges += usize::from(want);
            disagree += usize::from(want != (got[4 * i + 3] == 1.0));
            worst = worst.max(
                (Vec3::new(got[4 * i], got[4 * i + 1], got[4 * i + 2]) - r)
                    .abs()
                    .max_element(),
            );
        }
        eprintln!(
            "{params:?}: {edges} edges of {}, {disagree} classified differently, resolve within {worst:.1e}",
            pixels.len()
        );
        assert!(disagree == 0 && worst < 1e-6 && edges > 300);
    }
}

/// Not a check: which candidate G-buffer formats the adapter can render with 4×
/// MSAA (and resolve), and which WebGPU guarantees everywhere
/// (`cargo test -p bevy_penumbra_df --test msaa_gpu formats -- --nocapture`).
#[test]
fn gbuffer_format_candidates() {
    use wgpu::{TextureFormat as F, TextureFormatFeatureFlags as Flags};
    if !gpu_or_skip("gbuffer_format_candidates") {
        return;
    }
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::VULKAN,
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let adapter = bevy::tasks::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        ..Default::default()
    }))
    .expect("adapter");
    eprintln!(
        "{:?}\n| format | bytes | 4× here | resolve here | 4× guaranteed (WebGPU) |\n|---|---|---|---|---|",
        adapter.get_info().name
    );
    for format in [
        F::Rgba32Uint,
        F::Rg32Uint,
        F::R32Uint,
        F::Rgba16Uint,
        F::Rgba16Float,
        F::Rg16Float,
        F::Rgb10a2Unorm,
        F::Rgba8Unorm,
        F::Rg11b10Ufloat,
        F::R8Uint,
        F::Depth32Float,
    ] {
        let here = adapter.get_texture_format_features(format).flags;
        let guaranteed = format
            .guaranteed_format_features(wgpu::Features::empty())
            .flags;
        eprintln!(
            "| {format:?} | {} | {} | {} | {} |",
            format.block_copy_size(None).unwrap_or(4),
            here.contains(Flags::MULTISAMPLE_X4),
            here.contains(Flags::MULTISAMPLE_RESOLVE),
            guaranteed.contains(Flags::MULTISAMPLE_X4)
        );
    }
}
