// The standard MSAA sample patterns (Vulkan's and Direct3D's) and the per-pixel alpha
// thresholds of hair strips' samples, for 2×, 4× and 8× MSAA. CPU model:
// `penumbra_cinematic_core::hair::{sample_positions, sample_thresholds_for}`.
#define_import_path penumbra::hair::samples

// Sample positions relative to the pixel's centre (`hair::SAMPLE_POSITIONS_*` − ½).
const HAIR_SAMPLE_OFFSETS_2X: array<vec2<f32>, 2> = array<vec2<f32>, 2>(
    vec2<f32>(0.25, 0.25),
    vec2<f32>(-0.25, -0.25),
);
const HAIR_SAMPLE_OFFSETS_4X: array<vec2<f32>, 4> = array<vec2<f32>, 4>(
    vec2<f32>(-0.125, -0.375),
    vec2<f32>(0.375, -0.125),
    vec2<f32>(-0.375, 0.125),
    vec2<f32>(0.125, 0.375),
);
const HAIR_SAMPLE_OFFSETS_8X: array<vec2<f32>, 8> = array<vec2<f32>, 8>(
    vec2<f32>(0.0625, -0.1875),
    vec2<f32>(-0.0625, 0.1875),
    vec2<f32>(0.3125, 0.0625),
    vec2<f32>(-0.1875, -0.3125),
    vec2<f32>(-0.3125, 0.3125),
    vec2<f32>(-0.4375, -0.0625),
    vec2<f32>(0.1875, 0.4375),
    vec2<f32>(0.4375, -0.4375),
);

// Sample `i` of the `count`-sample pattern (2, 4 or 8; another count: the 4× one),
// relative to the pixel's centre.
fn hair_sample_offset(i: u32, count: u32) -> vec2<f32> {
    if count == 2u {
        return HAIR_SAMPLE_OFFSETS_2X[min(i, 1u)];
    }
    if count == 8u {
        return HAIR_SAMPLE_OFFSETS_8X[min(i, 7u)];
    }
    return HAIR_SAMPLE_OFFSETS_4X[min(i, 3u)];
}

// The `count` samples' alpha thresholds at a pixel (1 ≤ count ≤ 8; the rest 1): the
// steps (k + ½) / count permuted per pixel by a hash (Lehmer code of h mod count!).
fn hair_sample_thresholds(pixel: vec2<i32>, count: u32) -> array<f32, 8> {
    let n = clamp(count, 1u, 8u);
    var h = (bitcast<u32>(pixel.x) * 0x8da6b343u) ^ (bitcast<u32>(pixel.y) * 0xd8163841u);
    h ^= h >> 13u;
    h *= 0x2c1b3c6du;
    h ^= h >> 16u;
    var permutations = 1u;
    for (var k = 2u; k <= n; k += 1u) {
        permutations *= k;
    }
    var order = array<u32, 8>(0u, 1u, 2u, 3u, 4u, 5u, 6u, 7u);
    var code = h % permutations;
    for (var i = 0u; i + 1u < n; i += 1u) {
        let j = i + code % (n - i);
        code /= n - i;
        let t = order[i];
        order[i] = order[j];
        order[j] = t;
    }
    var thresholds = array<f32, 8>(1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0);
    for (var i = 0u; i < n; i += 1u) {
        thresholds[i] = (f32(order[i]) + 0.5) / f32(n);
    }
    return thresholds;
}
