//! Contract tests of deferred MSAA's per-sample passes on lavapipe, each fed a 4×
//! multisampled depth buffer and G-buffer filled sample by sample and a class texture:
//!
//! - the per-sample AO upsample (`upsample_samples` in `df/ao_upsample.wgsl`, built
//!   with `PENUMBRA_SAMPLE_UPSAMPLE`): from a half-resolution trace and a representative
//!   depth and G-buffer, on samples that straddle slanted slats in front of a tilted
//!   wall and the sky, it writes for every sample of the pixels classed per sample, and
//!   no other texel, what `penumbra_reference::dfao::upsample_samples` computes at the
//!   sample's own position, depth and normal;
//! - the per-sample shadow trace (`df/shadow_trace.wgsl` built with
//!   `PENUMBRA_SAMPLE_TRACE`): on the shadow contract test's scene, each sample
//!   sphere-traced at its own position, every light's visibility at every sample of
//!   those pixels equals `pixel_visibility_with_terrain` at that sample's point and
//!   normal, and no other texel is written.

use glam::{Mat3, Mat4, UVec2, Vec2, Vec3, Vec4};
use penumbra_df_core::ao::{AoTrace, AoTraceView, CONE_SHAPING, trace_size};
use penumbra_df_core::cull::CameraOrigin;
use penumbra_reference::df::f16_to_f32;
use penumbra_reference::dfao::{TraceSource, upsample_samples};
use penumbra_reference::msaa::SAMPLE_POSITIONS_4X;
use penumbra_reference::shadow_mask::{
    pack_gbuffer_normal, position_from_depth, unpack_gbuffer_normal,
};
use penumbra_shaders::flatten_with_defs;
use penumbra_test::multisample::{MsSample, multisampled_gbuffer};
use penumbra_test::wgpu;
use penumbra_test::{GpuCompute, gpu_or_skip, uniform_bytes};

#[path = "support/shadow_passes.rs"]
mod support;

const WIDTH: u32 = 48;
const HEIGHT: u32 = 32;
use support::UNWRITTEN;

/// What the sample at frame-buffer point `p` sees: view distance along the axis and
/// unit normal, or `None` (sky above y = 3.5).
fn surface(p: Vec2) -> Option<(f32, Vec3)> {
    if p.y < 3.5 {
        return None;
    }
    if ((p.x + 0.4 * p.y) / 7.3).fract() < 0.35 {
        Some((1.2 + 0.004 * p.x, Vec3::new(0.3, 0.0, 1.0).normalize()))
    } else {
        Some((2.0 + 0.02 * p.y, Vec3::new(0.0, 0.4, 1.0).normalize()))
    }
}

/// `v` (exactly representable: k / 1024 with |k| ≤ 1024) as f16 bits.
fn f16_bits(v: f32) -> u16 {
    if v == 0.0 {
        return 0;
    }
    let b = v.to_bits();
    let exponent = ((b >> 23) & 0xff) as i32 - 127 + 15;
    (((b >> 16) & 0x8000) | ((exponent as u32) << 10) | ((b >> 13) & 0x3ff)) as u16
}

/// A deterministic hash in `0..n`.
fn hash(i: u32, salt: u32, n: u32) -> u32 {
    let mut h = i.wrapping_mul(0x9e37_79b9) ^ salt.wrapping_mul(0x85eb_ca6b);
    h ^= h >> 15;
    h = h.wrapping_mul(0x2c1b_3c6d);
    h ^= h >> 12;
    h % n
}

struct Inputs {
    samples: Vec<MsSample>,
    /// Representative depth and normal word per pixel (first covered sample).
    depth: Vec<f32>,
    normals: Vec<u32>,
    class: Vec<u8>,
    trace: Vec<Vec4>,
}

fn inputs(trace_size: UVec2) -> Inputs {
    let near = 0.1;
    let mut samples = Vec::new();
    let (mut depth, mut normals, mut class) = (Vec::new(), Vec::new(), Vec::new());
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            let seen = SAMPLE_POSITIONS_4X.map(|s| surface(Vec2::new(x as f32, y as f32) + s));
            let first = seen.iter().flatten().next().copied();
            for s in seen {
                samples.push(MsSample {
                    depth: s.map_or(0.0, |(z, _)| near / z),
                    gbuffer: [0, 0, 0, s.map_or(0, |(_, n)| pack_gbuffer_normal(n))],
                });
            }
            depth.push(first.map_or(0.0, |(z, _)| near / z));
            normals.push(first.map_or(0, |(_, n)| pack_gbuffer_normal(n)));
            // Another surface (or the sky) in the pixel: beyond the wall's own slope.
            let differ = seen.iter().any(|s| match (s, seen[0]) {
                (Some((a, _)), Some((b, _))) => (a - b).abs() > 0.05 * b,
                (a, b) => a.is_some() != b.is_some(),
            });
            let extra = hash(y * WIDTH + x, 7, 11) == 0;
            class.push(match first {
                _ if differ || extra => 2,
                None => 0,
                Some(_) => 1,
            });
        }
    }
    let q = |i: u32, salt: u32, lo: i32| (hash(i, salt, 1025) as i32 + lo) as f32 / 1024.0;
    let trace = (0..trace_size.x * trace_size.y)
        .map(|i| Vec4::new(q(i, 1, 0), q(i, 2, -512), q(i, 3, -512), 1.0))
        .collect();
    Inputs {
        samples,
        depth,
        normals,
        class,
        trace,
    }
}

fn texture(
    gpu: &GpuCompute,
    label: &str,
    size: UVec2,
    format: wgpu::TextureFormat,
    bytes: &[u8],
) -> wgpu::Texture {
    let texel = format.block_copy_size(None).expect("uncompressed");
    gpu.texture(
        label,
        wgpu::Extent3d {
            width: size.x,
            height: size.y,
            depth_or_array_layers: 1,
        },
        wgpu::TextureDimension::D2,
        format,
        texel,
        bytes,
    )
}

fn halves(v: Vec4) -> [u8; 8] {
    let mut out = [0; 8];
    for (i, c) in v.to_array().into_iter().enumerate() {
        out[2 * i..2 * i + 2].copy_from_slice(&f16_bits(c).to_le_bytes());
    }
    out
}

#[test]
fn per_sample_ao_upsample_matches_the_model() {
    if !gpu_or_skip("per_sample_ao_upsample_matches_the_model") {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter");
    let full = UVec2::new(WIDTH, HEIGHT);
    let (divisor, jitter) = (2, UVec2::new(1, 0));
    let trace_size = trace_size(full, divisor);
    let inputs = inputs(trace_size);
    let per_sample = inputs.class.iter().filter(|&&c| c == 2).count();
    let straddling = (0..(WIDTH * HEIGHT) as usize)
        .filter(|&p| {
            let d = &inputs.samples[4 * p..4 * p + 4];
            d.iter()
                .any(|s| (s.depth - d[0].depth).abs() > 0.05 * d[0].depth)
        })
        .count();
    assert!(
        per_sample > 150 && straddling > 100,
        "{per_sample} {straddling}"
    );

    let clip_from_view =
        Mat4::perspective_infinite_reverse_rh(1.0, WIDTH as f32 / HEIGHT as f32, 0.1);
    let view_from_clip = clip_from_view.inverse();
    let world_from_view = Mat3::IDENTITY;
    let camera = CameraOrigin::at(Vec3::ZERO).expect("finite");
    let settings = AoTrace {
        max_distance: 2.0,
        cone_count: 9,
        steps_per_cone: 16,
        bias: 0.02,
        shaping: CONE_SHAPING,
    };
    let uniform = AoTraceView::new(
        &camera,
        view_from_clip,
        world_from_view,
        full,
        divisor,
        jitter,
        0,
        &settings,
    );

    // The model, from the same values.
    let distance_at = |screen: Vec2, depth: f32| {
        if depth <= 0.0 {
            return 0.0;
        }
        let p = position_from_depth(
            view_from_clip,
            world_from_view,
            full.as_vec2(),
            screen - 0.5,
            depth,
        );
        p.length()
    };
    let distance: Vec<f32> = (0..WIDTH * HEIGHT)
        .map(|i| {
            let pixel = Vec2::new((i % WIDTH) as f32, (i / WIDTH) as f32);
            distance_at(pixel + 0.5, inputs.depth[i as usize])
        })
        .collect();
    let normals: Vec<Vec3> = inputs
        .normals
        .iter()
        .map(|&w| unpack_gbuffer_normal(w))
        .collect();
    let (mut sample_distance, mut sample_normals) = (Vec::new(), Vec::new());
    for (i, s) in inputs.samples.iter().enumerate() {
        let p = i / 4;
        let pixel = Vec2::new((p as u32 % WIDTH) as f32, (p as u32 / WIDTH) as f32);
        sample_distance.push(distance_at(pixel + SAMPLE_POSITIONS_4X[i % 4], s.depth));
        sample_normals.push(unpack_gbuffer_normal(s.gbuffer[3]));
    }
    let classed: Vec<bool> = inputs.class.iter().map(|&c| c == 2).collect();
    let source = TraceSource {
        trace: &inputs.trace,
        size: trace_size,
        divisor,
        jitter,
        distance: &distance,
        normals: &normals,
        full_size: full,
    };
    let want = upsample_samples(&source, &sample_distance, &sample_normals, &classed);

    // The pass.
    let source = flatten_with_defs(
        "#import penumbra::df::ao_upsample\n",
        &["PENUMBRA_SAMPLE_UPSAMPLE"],
    )
    .expect("flattens");
    let pipeline = gpu.pipeline(&source, "upsample_samples");
    let ms = multisampled_gbuffer(&gpu, WIDTH, HEIGHT, &inputs.samples);
    let bytes = |words: &mut dyn Iterator<Item = u32>| -> Vec<u8> {
        words.flat_map(u32::to_le_bytes).collect()
    };
    let trace_bytes: Vec<u8> = inputs.trace.iter().flat_map(|&v| halves(v)).collect();
    let trace = texture(
        &gpu,
        "trace",
        trace_size,
        wgpu::TextureFormat::Rgba16Float,
        &trace_bytes,
    );
    let depth = texture(
        &gpu,
        "depth",
        full,
        wgpu::TextureFormat::R32Float,
        &bytes(&mut inputs.depth.iter().map(|d| d.to_bits())),
    );
    let gbuffer = texture(
        &gpu,
        "gbuffer",
        full,
        wgpu::TextureFormat::Rgba32Uint,
        &bytes(&mut inputs.normals.iter().flat_map(|&n| [0, 0, 0, n])),
    );
    let class = texture(
        &gpu,
        "class",
        full,
        wgpu::TextureFormat::R8Uint,
        &inputs.class,
    );
    let sentinel: Vec<u8> = (0..4 * WIDTH * HEIGHT)
        .flat_map(|_| halves(Vec4::splat(UNWRITTEN)))
        .collect();
    let output = texture(
        &gpu,
        "output",
        2 * full,
        wgpu::TextureFormat::Rgba16Float,
        &sentinel,
    );
    let uniform_buffer = gpu.buffer(
        "view",
        &uniform_bytes(&uniform),
        wgpu::BufferUsages::UNIFORM,
    );
    let view = |t: &wgpu::Texture| t.create_view(&Default::default());
    let views = [
        view(&trace),
        view(&depth),
        view(&gbuffer),
        view(&output),
        view(&ms.depth),
        view(&ms.gbuffer),
        view(&class),
    ];
    let texture_entry = |binding, v| wgpu::BindGroupEntry {
        binding,
        resource: wgpu::BindingResource::TextureView(v),
    };
    let bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("ao_upsample_samples"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            texture_entry(0, &views[0]),
            texture_entry(1, &views[1]),
            texture_entry(2, &views[2]),
            wgpu::BindGroupEntry {
                binding: 3,
                resource: uniform_buffer.as_entire_binding(),
            },
            texture_entry(4, &views[3]),
            texture_entry(5, &views[4]),
            texture_entry(6, &views[5]),
            texture_entry(7, &views[6]),
        ],
    });
    gpu.dispatch(
        &pipeline,
        &bind,
        [(2 * WIDTH).div_ceil(8), (2 * HEIGHT).div_ceil(8), 1],
    );
    let got: Vec<Vec4> = gpu
        .read_texture_2d(&output)
        .chunks_exact(8)
        .map(|c| {
            let h = |i: usize| f16_to_f32(u16::from_le_bytes([c[2 * i], c[2 * i + 1]]));
            Vec4::new(h(0), h(1), h(2), h(3))
        })
        .collect();

    let (mut worst, mut sum, mut angle, mut written) = (0.0f32, 0.0f32, 0.0f32, 0);
    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
        let Some(w) = w else {
            assert_eq!(*g, Vec4::splat(UNWRITTEN), "texel {i} written");
            continue;
        };
        assert_ne!(*g, Vec4::splat(UNWRITTEN), "texel {i} not written");
        written += 1;
        let e = (g.x - w.x).abs();
        worst = worst.max(e);
        sum += e;
        let (gb, wb) = (Vec3::new(g.y, g.z, g.w), Vec3::new(w.y, w.z, w.w));
        if wb != Vec3::ZERO {
            angle = angle.max(gb.normalize_or_zero().angle_between(wb));
        }
    }
    let mean = sum / written as f32;
    eprintln!(
        "{per_sample} pixels per sample ({straddling} straddling an edge), {written} samples: \
         AO max |Δ| {worst:.5}, mean {mean:.6}, bent max {angle:.4} rad"
    );
    assert_eq!(written, 4 * per_sample);
    // f16 storage (≤ 5·10⁻⁴ near 1); a sample blended at its pixel's centre or from its
    // neighbour's depth moves texels by > 0.1.
    assert!(
        worst < 0.01 && mean < 1e-3 && angle < 0.02,
        "per-sample upsample differs"
    );
}

/// Every sample of the shadow contract scene's view, sphere-traced at its own position,
/// and the classes: per sample (2) where the samples' depths differ by over 5 % or
/// coverage differs, and on a few interior pixels; 1 or 0 (background) elsewhere.
fn shadow_samples(scene: &support::Scene, view: &support::View) -> (Vec<MsSample>, Vec<u8>) {
    let (w, h) = (support::WIDTH, support::HEIGHT);
    let (mut samples, mut class) = (Vec::new(), Vec::new());
    for y in 0..h {
        for x in 0..w {
            let seen = SAMPLE_POSITIONS_4X.map(|s| {
                let screen = Vec2::new(x as f32, y as f32) + s;
                support::march(
                    scene,
                    &view.camera,
                    view.clip_from_view,
                    view.world_from_view,
                    screen,
                )
            });
            let d0 = seen[0].0;
            let differ = seen
                .iter()
                .any(|&(d, _)| (d > 0.0) != (d0 > 0.0) || (d - d0).abs() > 0.05 * d0);
            class.push(if differ || hash(y * w + x, 5, 23) == 0 {
                2
            } else {
                u8::from(d0 > 0.0)
            });
            samples.extend(seen.map(|(depth, n)| MsSample {
                depth,
                gbuffer: [0, 0, 0, n],
            }));
        }
    }
    (samples, class)
}

#[test]
fn per_sample_shadow_trace_matches_the_model() {
    if !gpu_or_skip("per_sample_shadow_trace_matches_the_model") {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter");
    let passes = support::passes(&gpu);
    let scene = support::scene(Vec3::ZERO);
    let view = support::view(&scene, Vec3::ZERO);
    let (w, h) = (support::WIDTH, support::HEIGHT);
    let (samples, class) = shadow_samples(&scene, &view);
    let per_sample = class.iter().filter(|&&c| c == 2).count();
    assert!(per_sample > 300, "only {per_sample} pixels per sample");
    let traced = support::sample_trace(&gpu, &samples, &class);
    let size = Vec2::new(w as f32, h as f32);
    for (light_name, light) in support::lights(Vec3::ZERO, support::EYE) {
        let options = support::MaskOptions {
            samples: Some(&traced),
            ..Default::default()
        };
        let got = support::gpu_mask_at(&gpu, &passes, &scene, &view, &light, options).values;
        let (mut diffs, mut shadowed, mut split) = (Vec::new(), 0, 0);
        for pixel in 0..(w * h) as usize {
            let (x, y) = ((pixel as u32 % w), (pixel as u32 / w));
            let texel =
                |s: usize| ((2 * y + (s as u32 >> 1)) * 2 * w + 2 * x + (s as u32 & 1)) as usize;
            if class[pixel] != 2 {
                for s in 0..4 {
                    assert_eq!(
                        got[texel(s)],
                        UNWRITTEN,
                        "{light_name}: pixel {pixel} written"
                    );
                }
                continue;
            }
            let want: Vec<f32> = (0..4)
                .map(|s| {
                    let sample = samples[4 * pixel + s];
                    if sample.depth <= 0.0 {
                        // The sky: lit.
                        return 1.0;
                    }
                    let screen = Vec2::new(x as f32, y as f32) + SAMPLE_POSITIONS_4X[s];
                    let p = position_from_depth(
                        view.view_from_clip,
                        view.world_from_view,
                        size,
                        screen - 0.5,
                        sample.depth,
                    );
                    let n = unpack_gbuffer_normal(sample.gbuffer[3]);
                    penumbra_reference::shadow_mask::pixel_visibility_with_terrain(
                        &scene.records,
                        &scene.atlas,
                        &view.camera,
                        p,
                        n,
                        &light,
                        &scene.terrain,
                    )
                    .0
                })
                .collect();
            shadowed += want.iter().filter(|&&v| v < 0.5).count();
            split += usize::from(want.iter().any(|&v| (v - want[0]).abs() > 0.2));
            diffs.extend((0..4).map(|s| (got[texel(s)] - want[s]).abs()));
        }
        let mean = diffs.iter().sum::<f32>() / diffs.len() as f32;
        let max = diffs.iter().copied().fold(0.0, f32::max);
        eprintln!(
            "{light_name}: {per_sample} pixels per sample, {shadowed} samples shadowed, \
             {split} pixels whose samples' visibility differs by > 0.2; |gpu − cpu| mean \
             {mean:.6}, max {max:.4}"
        );
        assert!(
            shadowed > 100 && split > 20,
            "{light_name}: too little shadow on the edges"
        );
        // As the per-pixel pass (measured equal): a sample traced at its pixel's centre
        // or with its neighbour's depth moves some samples by up to 1.
        assert!(
            mean < 1e-4 && max < 0.05,
            "{light_name}: mean {mean}, max {max}"
        );
    }
}
