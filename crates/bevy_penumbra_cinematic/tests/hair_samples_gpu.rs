//! Hair strips under 2×, 4× and 8× MSAA test each count's own sample pattern with that
//! count's alpha thresholds (`hair/samples.wgsl`, which `hair/common.wgsl` uses with the
//! view's sample count). lavapipe draws 1× and 4× only, so the strips' 2× and 8× draws
//! cannot be read back here: the shader's pattern and thresholds are dispatched as a
//! compute contract instead, equal to the model (`penumbra_cinematic_core::hair::
//! {sample_positions, sample_thresholds_for}`) bit for bit; the model's coverage for each
//! count is checked against the exact area in that crate.

use penumbra_cinematic_core::hair::{sample_positions, sample_thresholds_for};
use penumbra_shaders::flatten;
use penumbra_test::wgpu::BufferUsages;
use penumbra_test::{GpuCompute, gpu_or_skip};

use bevy::math::IVec2;

const WRAPPER: &str = "
#import penumbra::hair::samples::{hair_sample_offset, hair_sample_thresholds}

@group(0) @binding(0) var<storage, read_write> out: array<f32>;

// Thread p: pixel (p % 16 − 3, p / 16 − 5); for each count 1..=8 its 8 thresholds, at
// (p · 8 + count − 1) · 8. Thread 0 also writes the offsets of 2, 4 and 8 samples after
// the 256 pixels' thresholds.
@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= 256u {
        return;
    }
    let pixel = vec2<i32>(i32(id.x % 16u) - 3, i32(id.x / 16u) - 5);
    for (var count = 1u; count <= 8u; count += 1u) {
        var t = hair_sample_thresholds(pixel, count);
        for (var k = 0u; k < 8u; k += 1u) {
            out[(id.x * 8u + count - 1u) * 8u + k] = t[k];
        }
    }
    if id.x == 0u {
        var at = 256u * 64u;
        for (var c = 1u; c <= 3u; c += 1u) {
            let count = 1u << c;
            for (var i = 0u; i < count; i += 1u) {
                let o = hair_sample_offset(i, count);
                out[at] = o.x;
                out[at + 1u] = o.y;
                at += 2u;
            }
        }
    }
}
";

#[test]
fn the_shaders_sample_patterns_and_thresholds_are_the_models() {
    if !gpu_or_skip("the_shaders_sample_patterns_and_thresholds_are_the_models") {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter");
    let pipeline = gpu.pipeline(&flatten(WRAPPER).expect("flattens"), "main");
    let words = 256 * 64 + 2 * (2 + 4 + 8);
    let size = 4 * words as u64;
    let out = gpu.zeroed("out", size, BufferUsages::COPY_SRC);
    let bind = gpu.bind(&pipeline, &[(0, &out)]);
    gpu.dispatch(&pipeline, &bind, [4, 1, 1]);
    let got: Vec<f32> = gpu
        .read(&out, size)
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    let mut differ = Vec::new();
    for p in 0..256 {
        let pixel = IVec2::new(p % 16 - 3, p / 16 - 5);
        for count in 1..=8u32 {
            let at = ((p as usize * 8) + count as usize - 1) * 8;
            let want = sample_thresholds_for(pixel, count);
            if got[at..at + 8] != want[..] {
                differ.push(format!(
                    "{pixel} × {count}: {:?} vs {want:?}",
                    &got[at..at + 8]
                ));
            }
        }
    }
    let mut at = 256 * 64;
    for count in [2u32, 4, 8] {
        for (i, p) in sample_positions(count).iter().enumerate() {
            let want = [p.x - 0.5, p.y - 0.5];
            if got[at..at + 2] != want {
                differ.push(format!(
                    "offset {i} of {count}: {:?} vs {want:?}",
                    &got[at..at + 2]
                ));
            }
            at += 2;
        }
    }
    assert!(
        differ.is_empty(),
        "{} differ:\n{}",
        differ.len(),
        differ.join("\n")
    );
}
