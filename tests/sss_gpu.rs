//! Contract test of screen-space subsurface scattering's WGSL profile functions
//! (`shaders/sss/profile.wgsl`) on lavapipe: Burley's profile, its CDF, the inverse CDF
//! and the disc's sample offsets equal `penumbra_cinematic_core::sss` and
//! `penumbra_reference::sss::disc_samples` (which are checked against quadrature).
//!
//! `cargo test -p penumbra --test sss_gpu -- --nocapture`

use bevy::math::{Vec2, Vec3};
use penumbra_reference::sss::{ScatterProfile, cdf, disc_samples, profile, sample_radius};
use penumbra_shaders::flatten;
use penumbra_test::wgpu;
use penumbra_test::{GpuCompute, gpu_or_skip};

const SHADER: &str = "#import penumbra::sss::profile::{burley_cdf, burley_profile, burley_sample_radius, disc_offset}

@group(0) @binding(0) var<storage, read> inputs: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read_write> outputs: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> disc: array<vec2<f32>>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i < arrayLength(&inputs) {
        let v = inputs[i];
        outputs[i] = vec4<f32>(burley_profile(v.x, v.y), burley_cdf(v.x, v.y), burley_sample_radius(v.z, v.y), 0.0);
    }
    if i < 16u {
        disc[i] = disc_offset(i, 16u, 1.3, 0.37, 0.003);
    }
}
";

#[test]
fn profile_functions_match_the_core() {
    if !gpu_or_skip("profile_functions_match_the_core") {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter");
    // (r, d, u): radii from 10 µm to 3 cm, shape distances 0.5 to 5 mm, CDF fractions.
    let mut inputs = Vec::new();
    for (k, r) in [1e-5f32, 1e-4, 5e-4, 1e-3, 3e-3, 0.01, 0.03]
        .into_iter()
        .enumerate()
    {
        for d in [5e-4f32, 1.2e-3, 3e-3, 5e-3] {
            let u = (k as f32 + 0.5) / 7.0 * 0.998;
            inputs.push([r, d, u, 0.0]);
        }
    }
    inputs.push([0.001, 0.0, 0.5, 0.0]); // no scattering
    let bytes: Vec<u8> = inputs
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let input = gpu.buffer("inputs", &bytes, wgpu::BufferUsages::empty());
    let output = gpu.zeroed(
        "outputs",
        (inputs.len() * 16) as u64,
        wgpu::BufferUsages::empty(),
    );
    let disc = gpu.zeroed("disc", 16 * 8, wgpu::BufferUsages::empty());
    let pipeline = gpu.pipeline(&flatten(SHADER).expect("flattens"), "main");
    let entry = |binding, resource| wgpu::BindGroupEntry { binding, resource };
    let bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("sss_profile"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            entry(0, input.as_entire_binding()),
            entry(1, output.as_entire_binding()),
            entry(2, disc.as_entire_binding()),
        ],
    });
    gpu.dispatch(&pipeline, &bind, [(inputs.len() as u32).div_ceil(64), 1, 1]);
    let floats = |bytes: Vec<u8>| -> Vec<f32> {
        bytes
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    };
    let got = floats(gpu.read(&output, (inputs.len() * 16) as u64));
    let rel = |a: f32, b: f32| (a - b).abs() / b.abs().max(1e-12);
    let mut worst = [0.0f32; 3];
    for (i, v) in inputs.iter().enumerate() {
        let [r, d, u, _] = *v;
        let want = [profile(r, d), cdf(r, d), sample_radius(u, d)];
        for c in 0..3 {
            let g = got[4 * i + c];
            let e = if want[c] == 0.0 {
                g.abs()
            } else {
                rel(g, want[c])
            };
            worst[c] = worst[c].max(e);
        }
    }
    eprintln!(
        "{} inputs; worst relative difference: profile {:.1e}, CDF {:.1e}, inverse CDF {:.1e}",
        inputs.len(),
        worst[0],
        worst[1],
        worst[2]
    );
    // f32 transcendental functions (exp, log) of a GPU against the CPU's.
    assert!(worst.iter().all(|&w| w < 1e-4), "{worst:?}");
    let got_disc = floats(gpu.read(&disc, 16 * 8));
    let want_disc = disc_samples(&ScatterProfile::new(Vec3::ONE, 0.003), 16, 1.3, 0.37);
    let mut worst_disc = 0.0f32;
    for (k, w) in want_disc.iter().enumerate() {
        let g = Vec2::new(got_disc[2 * k], got_disc[2 * k + 1]);
        worst_disc = worst_disc.max((g - *w).length() / w.length().max(1e-9));
    }
    eprintln!("disc offsets: worst relative difference {worst_disc:.1e}");
    assert!(worst_disc < 1e-4, "{worst_disc}");
}

const FRAME_SHADER: &str = "#import penumbra::sss::profile::{pixel_noise, tangent_frame}

@group(0) @binding(0) var<storage, read> normals: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read_write> frames: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> noise: array<vec2<f32>>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i < arrayLength(&normals) {
        let t = tangent_frame(normals[i].xyz);
        frames[2u * i] = vec4<f32>(t[0], 0.0);
        frames[2u * i + 1u] = vec4<f32>(t[1], 0.0);
    }
    if i < 64u {
        noise[i] = pixel_noise(vec2<u32>(i * 37u, i * 11u + 5u), i / 8u);
    }
}
";

/// The per-pixel hash and the tangent frame (both signs of `n.z`, −0 included) equal
/// `penumbra_reference::sss::screen`'s — the scene-level contract test's plane faces the
/// camera, so it never takes the negative branch.
#[test]
fn noise_and_tangent_frames_match_the_model() {
    use penumbra_reference::sss::screen::{pixel_noise, tangents};
    if !gpu_or_skip("noise_and_tangent_frames_match_the_model") {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter");
    let normals: Vec<Vec3> = [
        Vec3::Z,
        Vec3::NEG_Z,
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.6, 0.8, -0.0),
        Vec3::new(0.3, -0.5, -0.81),
        Vec3::new(-0.6, 0.2, 0.77),
        Vec3::new(0.1, 0.99, -0.05),
    ]
    .into_iter()
    .map(|n| {
        if n == Vec3::new(0.0, 1.0, -0.0) {
            n
        } else {
            n.normalize()
        }
    })
    .collect();
    let bytes: Vec<u8> = normals
        .iter()
        .flat_map(|n| [n.x, n.y, n.z, 0.0])
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let input = gpu.buffer("normals", &bytes, wgpu::BufferUsages::empty());
    let frames = gpu.zeroed(
        "frames",
        (normals.len() * 32) as u64,
        wgpu::BufferUsages::empty(),
    );
    let noise = gpu.zeroed("noise", 64 * 8, wgpu::BufferUsages::empty());
    let pipeline = gpu.pipeline(&flatten(FRAME_SHADER).expect("flattens"), "main");
    let entry = |binding, resource| wgpu::BindGroupEntry { binding, resource };
    let bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("sss_frames"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            entry(0, input.as_entire_binding()),
            entry(1, frames.as_entire_binding()),
            entry(2, noise.as_entire_binding()),
        ],
    });
    gpu.dispatch(&pipeline, &bind, [1, 1, 1]);
    let floats = |bytes: Vec<u8>| -> Vec<f32> {
        bytes
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    };
    let got = floats(gpu.read(&frames, (normals.len() * 32) as u64));
    let mut worst = 0.0f32;
    for (i, n) in normals.iter().enumerate() {
        let (t, b) = tangents(*n);
        let g = |k: usize| Vec3::from_slice(&got[8 * i + 4 * k..8 * i + 4 * k + 3]);
        worst = worst.max((g(0) - t).length()).max((g(1) - b).length());
    }
    let got_noise = floats(gpu.read(&noise, 64 * 8));
    for i in 0..64u32 {
        let want = pixel_noise(i * 37, i * 11 + 5, i / 8);
        assert_eq!(
            (got_noise[2 * i as usize], got_noise[2 * i as usize + 1]),
            want,
            "pixel noise {i}"
        );
    }
    eprintln!("tangent frames: worst difference {worst:.1e}; pixel noise equal for 64 pixels");
    assert!(worst < 1e-6, "{worst}");
}
