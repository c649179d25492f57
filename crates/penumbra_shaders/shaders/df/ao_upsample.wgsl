// Geometry-aware upsample of the reduced-resolution AO trace: each pixel blends the
// four trace texels around it with bilinear weights scaled by depth similarity (zero
// beyond 10 % of the pixel's distance) and normal similarity (max(n · n_s, 0)⁸); where
// every weight is zero, the texel closest in depth wins. Background pixels get
// (1, 0, 0, 0). CPU model: `penumbra_reference::dfao::upsample`.
#define_import_path penumbra::df::ao_upsample

#import penumbra::df::shadow::gbuffer_normal
#import penumbra::df::ao::AoTraceView
#import penumbra::lighting::msaa::MSAA_SAMPLE_POSITIONS

@group(0) @binding(0) var trace_texture: texture_2d<f32>;
@group(0) @binding(1) var depth_texture: texture_2d<f32>;
@group(0) @binding(2) var gbuffer: texture_2d<u32>;
@group(0) @binding(3) var<uniform> view: AoTraceView;
@group(0) @binding(4) var output: texture_storage_2d<rgba16float, write>;
#ifdef PENUMBRA_SAMPLE_UPSAMPLE
// Deferred MSAA's per-sample upsample: the multisampled depth and G-buffer of the
// samples written (those of the pixels shaded per sample, class 2), into `output` at
// twice the view's size (`msaa_sample_texel`); the trace's texels are still described
// by the representative `depth_texture` and `gbuffer`.
@group(0) @binding(5) var sample_depth: texture_depth_multisampled_2d;
@group(0) @binding(6) var sample_gbuffer: texture_multisampled_2d<u32>;
@group(0) @binding(7) var pixel_class: texture_2d<u32>;
#endif

const DEPTH_TOLERANCE: f32 = 0.1;

// Distance from the camera of frame-buffer point `screen` at reverse-Z `depth` (0:
// background).
fn distance_at(screen: vec2<f32>, depth: f32) -> f32 {
    if !(depth > 0.0) {
        return 0.0;
    }
    let uv = screen / vec2<f32>(view.full_size);
    let v = view.view_from_clip * vec4<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, depth, 1.0);
    let d = length(view.world_from_view * (v.xyz / v.w));
    return select(0.0, d, d > 0.0 && d < 3.0e38);
}

// Distance from the camera of pixel `xy` (0: background).
fn pixel_distance(xy: vec2<u32>) -> f32 {
    return distance_at(vec2<f32>(xy) + 0.5, textureLoad(depth_texture, vec2<i32>(xy + view.origin), 0).r);
}

fn pixel_normal(xy: vec2<u32>) -> vec3<f32> {
    return gbuffer_normal(textureLoad(gbuffer, vec2<i32>(xy + view.origin), 0).a);
}

@compute @workgroup_size(8, 8, 1)
fn upsample(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= view.full_size.x || gid.y >= view.full_size.y {
        return;
    }
    let d = pixel_distance(gid.xy);
    if d <= 0.0 {
        textureStore(output, vec2<i32>(gid.xy), vec4<f32>(1.0, 0.0, 0.0, 0.0));
        return;
    }
    textureStore(output, vec2<i32>(gid.xy), blend(vec2<f32>(gid.xy) + 0.5, d, pixel_normal(gid.xy)));
}

// The AO texel (AO, unit bent normal) of the surface at frame-buffer point `screen`,
// distance `d` from the camera, normal `n`: the trace texels around it, weighted.
fn blend(screen: vec2<f32>, d: f32, n: vec3<f32>) -> vec4<f32> {
    let divisor = max(view.divisor, 1u);
    let h = max((screen - 0.5 - vec2<f32>(view.jitter)) / f32(divisor), vec2<f32>(0.0));
    let i0 = vec2<u32>(floor(h));
    let f = h - floor(h);
    let last = view.trace_size - vec2<u32>(1u);
    var sum = vec4<f32>(0.0);
    var weights = 0.0;
    var nearest = vec4<f32>(1.0, n);
    var nearest_error = 3.0e38;
    for (var k = 0u; k < 4u; k += 1u) {
        let o = vec2<u32>(k & 1u, k >> 1u);
        let texel = min(i0 + o, last);
        let v = textureLoad(trace_texture, vec2<i32>(texel), 0);
        let source = min(texel * divisor + view.jitter, view.full_size - vec2<u32>(1u));
        let error = abs(pixel_distance(source) - d) / d;
        let wx = select(1.0 - f.x, f.x, o.x == 1u);
        let wy = select(1.0 - f.y, f.y, o.y == 1u);
        let similar = pow(max(dot(n, pixel_normal(source)), 0.0), 8.0);
        let w = wx * wy * max(0.0, 1.0 - error / DEPTH_TOLERANCE) * similar;
        sum += v * w;
        weights += w;
        if error < nearest_error {
            nearest_error = error;
            nearest = v;
        }
    }
    var v = nearest;
    if weights > 1e-4 {
        v = sum / weights;
    }
    let len = length(v.yzw);
    let bent = select(n, v.yzw / len, len > 1e-6);
    return vec4<f32>(clamp(v.x, 0.0, 1.0), bent);
}

#ifdef PENUMBRA_SAMPLE_UPSAMPLE
// Sample `(gid.x & 1) | (gid.y & 1) << 1` of pixel `gid / 2`, where the pixel is shaded
// per sample: the trace blended for the sample's own surface.
@compute @workgroup_size(8, 8, 1)
fn upsample_samples(@builtin(global_invocation_id) gid: vec3<u32>) {
    let local = vec2<i32>(gid.xy / 2u);
    let pixel = local + vec2<i32>(view.origin);
    if any(gid.xy / 2u >= view.full_size) || textureLoad(pixel_class, pixel, 0).r != 2u {
        return;
    }
    let i = (gid.x & 1u) | ((gid.y & 1u) << 1u);
    let screen = vec2<f32>(local) + MSAA_SAMPLE_POSITIONS[i];
    let d = distance_at(screen, textureLoad(sample_depth, pixel, i32(i)));
    if d <= 0.0 {
        textureStore(output, vec2<i32>(gid.xy), vec4<f32>(1.0, 0.0, 0.0, 0.0));
        return;
    }
    let n = gbuffer_normal(textureLoad(sample_gbuffer, pixel, i32(i)).a);
    textureStore(output, vec2<i32>(gid.xy), blend(screen, d, n));
}
#endif
