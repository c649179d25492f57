// Deferred MSAA's edge test and resolve (Samaritan; Lauritzen 2010): a pixel is an
// edge — shaded per sample — when any of its first `sample_count` samples differs from
// sample 0 in material, in view depth beyond `slope_scale` × the pixel's depth slope
// plus `relative_depth` × its depth, in normal beyond `normal_cos`, or in coverage (one
// sees the sky, another geometry). The resolve is the mean of the samples' colours.
// CPU model: `penumbra_reference::msaa::{is_edge, resolve}`; the thresholds:
// `penumbra_df_core::msaa::EdgeParams`.
#define_import_path penumbra::lighting::msaa

struct MsaaEdgeParams {
    slope_scale: f32,
    relative_depth: f32,
    normal_cos: f32,
    sample_count: u32,
}

// Vulkan's (and D3D's, Metal's) standard 4× sample positions, from the pixel's corner.
const MSAA_SAMPLE_POSITIONS: array<vec2<f32>, 4> = array(
    vec2(0.375, 0.125), vec2(0.875, 0.375), vec2(0.125, 0.625), vec2(0.625, 0.875),
);

// The texel of sample `i` of `pixel` in a per-sample texture (twice the view's size:
// each pixel's samples in a 2×2 block, sample i at (i & 1, i >> 1)).
fn msaa_sample_texel(pixel: vec2<i32>, i: u32) -> vec2<i32> {
    return 2 * pixel + vec2<i32>(i32(i & 1u), i32(i >> 1u));
}

// One G-buffer sample as the classifier reads it.
struct MsaaSample {
    normal: vec3<f32>,
    // View depth, metres.
    view_z: f32,
    material: u32,
    // 0: nothing drawn (the sky).
    covered: u32,
}

fn msaa_samples_differ(a: MsaaSample, b: MsaaSample, allowed_dz: f32, normal_cos: f32) -> bool {
    if a.covered != b.covered {
        return true;
    }
    if a.covered == 0u {
        return false;
    }
    return a.material != b.material
        || abs(a.view_z - b.view_z) > allowed_dz
        || dot(a.normal, b.normal) < normal_cos;
}

// Whether the pixel of `samples` (depth slope `z_slope`, metres per pixel) is an edge.
fn msaa_is_edge(samples: array<MsaaSample, 4>, z_slope: f32, params: MsaaEdgeParams) -> bool {
    let first = samples[0];
    let allowed = params.slope_scale * z_slope + params.relative_depth * first.view_z;
    let count = clamp(params.sample_count, 1u, 4u);
    for (var i = 1u; i < count; i++) {
        if msaa_samples_differ(samples[i], first, allowed, params.normal_cos) {
            return true;
        }
    }
    return false;
}

// The box resolve of `count` sample colours.
fn msaa_resolve(colors: array<vec3<f32>, 4>, count: u32) -> vec3<f32> {
    let n = clamp(count, 1u, 4u);
    var sum = vec3<f32>(0.0);
    for (var i = 0u; i < n; i++) {
        sum += colors[i];
    }
    return sum / f32(n);
}
