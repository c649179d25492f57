// Bilateral upsampling of a half-resolution shadow mask: each full-resolution pixel
// blends the (up to) four half-resolution texels around it with bilinear weights, each
// scaled down as its traced pixel's distance from the camera differs from this pixel's
// (zero beyond 10 %): shadows do not bleed across depth edges. Where no texel is close
// in depth, the closest one is taken. CPU model: `penumbra_reference::shadow_mask::upsample`.
#define_import_path penumbra::df::shadow_upsample

struct ShadowUpsampleView {
    view_from_clip: mat4x4<f32>,
    // x, y: half-resolution size; z, w: full-resolution size (the viewport's).
    sizes: vec4<u32>,
    // x, y: the viewport's origin in the frame buffer (the depth texture's pixels).
    origin: vec4<u32>,
}

@group(0) @binding(0) var half_mask: texture_2d<f32>;
@group(0) @binding(1) var depth_texture: texture_2d<f32>;
@group(0) @binding(2) var<uniform> view: ShadowUpsampleView;
@group(0) @binding(3) var mask: texture_storage_2d<r32float, write>;

// Relative depth difference at which a texel's weight reaches zero.
const DEPTH_TOLERANCE: f32 = 0.1;

// Distance from the camera of the viewport's full-resolution pixel `xy` (0: background
// or invalid).
fn view_distance(xy: vec2<u32>) -> f32 {
    let depth = textureLoad(depth_texture, vec2<i32>(xy + view.origin.xy), 0).r;
    if !(depth > 0.0) {
        return 0.0;
    }
    let uv = (vec2<f32>(xy) + 0.5) / vec2<f32>(view.sizes.zw);
    let v = view.view_from_clip * vec4<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, depth, 1.0);
    let d = length(v.xyz / v.w);
    return select(0.0, d, d > 0.0 && d < 3.0e38);
}

@compute @workgroup_size(8, 8, 1)
fn upsample(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= view.sizes.z || gid.y >= view.sizes.w {
        return;
    }
    let d = view_distance(gid.xy);
    if d <= 0.0 {
        textureStore(mask, vec2<i32>(gid.xy), vec4<f32>(1.0, 0.0, 0.0, 1.0));
        return;
    }
    let h = vec2<f32>(gid.xy) * 0.5;
    let i0 = vec2<u32>(floor(h));
    let f = h - floor(h);
    let last = view.sizes.xy - vec2<u32>(1u);
    var sum = 0.0;
    var weights = 0.0;
    var nearest = 1.0;
    var nearest_error = 3.0e38;
    for (var k = 0u; k < 4u; k += 1u) {
        let o = vec2<u32>(k & 1u, k >> 1u);
        let texel = min(i0 + o, last);
        let v = textureLoad(half_mask, vec2<i32>(texel), 0).r;
        let ds = view_distance(texel * 2u);
        let error = abs(ds - d) / d;
        let wx = select(1.0 - f.x, f.x, o.x == 1u);
        let wy = select(1.0 - f.y, f.y, o.y == 1u);
        let w = wx * wy * max(0.0, 1.0 - error / DEPTH_TOLERANCE);
        sum += v * w;
        weights += w;
        if error < nearest_error {
            nearest_error = error;
            nearest = v;
        }
    }
    var out = nearest;
    if weights > 1e-4 {
        out = sum / weights;
    }
    out = clamp(out, 0.0, 1.0);
    textureStore(mask, vec2<i32>(gid.xy), vec4<f32>(select(1.0, out, out >= 0.0), 0.0, 0.0, 1.0));
}
