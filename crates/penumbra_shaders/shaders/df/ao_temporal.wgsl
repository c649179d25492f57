// The DFAO temporal filter at full resolution: reprojection of the previous frame's
// blend with Bevy's motion vectors, depth rejection, a confidence that flushes
// ghosting, and the blend; low-confidence pixels show a spatial fill, which the history
// does not keep. Writes the blend and (distance from the camera, confidence) for the
// next frame and the filtered (AO, bent normal) the lighting pass reads. CPU model:
// `penumbra_reference::dfao::temporal_step`.
#define_import_path penumbra::df::ao_temporal

#import penumbra::df::shadow::gbuffer_normal

const HISTORY_WEIGHT: f32 = 0.85;
const HISTORY_DEPTH_TOLERANCE: f32 = 0.05;
const CONFIDENCE_GAIN: f32 = 0.25;
const LEAK_TOLERANCE: f32 = 0.05;
const FILL_CONFIDENCE: f32 = 0.5;
const FILL_RADIUS: i32 = 2;
const UPSAMPLE_DEPTH_TOLERANCE: f32 = 0.1;

struct AoTemporalView {
    view_from_clip: mat4x4<f32>,
    world_from_view: mat3x3<f32>,
    previous_offset: vec3<f32>,
    history_valid: u32,
    full_size: vec2<u32>,
    confidence: u32,
    spatial_fill: u32,
    // The viewport's origin in the frame buffer (where the prepass textures are read).
    origin: vec2<u32>,
}

// This frame's upsampled trace (AO, bent normal).
@group(0) @binding(0) var current_texture: texture_2d<f32>;
// The previous frame's blend and (distance, confidence).
@group(0) @binding(1) var history_value: texture_2d<f32>;
@group(0) @binding(2) var history_state: texture_2d<f32>;
@group(0) @binding(3) var depth_texture: texture_2d<f32>;
@group(0) @binding(4) var gbuffer: texture_2d<u32>;
// Bevy's motion vectors: this frame's UV minus the previous frame's.
#ifdef MULTISAMPLED_MOTION
// Deferred MSAA: multisampled; sample 0 is read (a pixel's samples of one surface move
// alike, and an edge pixel's history is rejected by depth where they do not).
@group(0) @binding(5) var motion_vectors: texture_multisampled_2d<f32>;
#else
@group(0) @binding(5) var motion_vectors: texture_2d<f32>;
#endif
@group(0) @binding(6) var<uniform> view: AoTemporalView;
@group(0) @binding(7) var out_value: texture_storage_2d<rgba16float, write>;
@group(0) @binding(8) var out_state: texture_storage_2d<rgba16float, write>;
// What the lighting pass reads (the blend, with the fill where it applies), in a
// texture that stays the same across frames.
@group(0) @binding(9) var out_filtered: texture_storage_2d<rgba16float, write>;

// Camera-relative world position of pixel `xy` (w = 0: background).
fn pixel_position(xy: vec2<i32>) -> vec4<f32> {
    let depth = textureLoad(depth_texture, xy + vec2<i32>(view.origin), 0).r;
    if !(depth > 0.0) {
        return vec4<f32>(0.0);
    }
    let uv = (vec2<f32>(xy) + 0.5) / vec2<f32>(view.full_size);
    let v = view.view_from_clip * vec4<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, depth, 1.0);
    let p = view.world_from_view * (v.xyz / v.w);
    let d = length(p);
    return select(vec4<f32>(0.0), vec4<f32>(p, 1.0), d > 0.0 && d < 3.0e38);
}

fn pixel_normal(xy: vec2<i32>) -> vec3<f32> {
    return gbuffer_normal(textureLoad(gbuffer, xy + vec2<i32>(view.origin), 0).a);
}

struct Reprojected {
    value: vec4<f32>,
    confidence: f32,
    found: bool,
}

// The history at pixel `xy`'s previous position, from the texels holding the same
// surface (stored distance within tolerance of `expected`).
fn reproject(xy: vec2<i32>, expected: f32) -> Reprojected {
    var r = Reprojected(vec4<f32>(0.0), 0.0, false);
    let size = vec2<f32>(view.full_size);
    let uv = (vec2<f32>(xy) + 0.5) / size - textureLoad(motion_vectors, xy + vec2<i32>(view.origin), 0).xy;
    if !(uv.x >= 0.0 && uv.x <= 1.0 && uv.y >= 0.0 && uv.y <= 1.0) {
        return r;
    }
    let h = uv * size - 0.5;
    let i0 = floor(h);
    let f = h - i0;
    var weights = 0.0;
    for (var k = 0u; k < 4u; k += 1u) {
        let o = vec2<f32>(f32(k & 1u), f32(k >> 1u));
        let texel = i0 + o;
        if texel.x < 0.0 || texel.y < 0.0 || texel.x >= size.x || texel.y >= size.y {
            continue;
        }
        let s = textureLoad(history_state, vec2<i32>(texel), 0);
        if !(s.x > 0.0 && abs(s.x - expected) < HISTORY_DEPTH_TOLERANCE * expected) {
            continue;
        }
        let wx = select(1.0 - f.x, f.x, o.x == 1.0);
        let wy = select(1.0 - f.y, f.y, o.y == 1.0);
        let w = wx * wy;
        r.value += textureLoad(history_value, vec2<i32>(texel), 0) * w;
        r.confidence += s.y * w;
        weights += w;
    }
    if weights > 1e-3 {
        r.value /= weights;
        r.confidence /= weights;
        r.found = true;
    }
    return r;
}

// The current frame's depth- and normal-weighted mean around `xy` (distance `d`).
fn spatial_fill(xy: vec2<i32>, d: f32, n: vec3<f32>) -> vec4<f32> {
    var sum = vec4<f32>(0.0);
    var weights = 0.0;
    let size = vec2<i32>(view.full_size);
    for (var dy = -FILL_RADIUS; dy <= FILL_RADIUS; dy += 1) {
        for (var dx = -FILL_RADIUS; dx <= FILL_RADIUS; dx += 1) {
            let q = xy + vec2<i32>(dx, dy);
            if q.x < 0 || q.y < 0 || q.x >= size.x || q.y >= size.y {
                continue;
            }
            let pq = pixel_position(q);
            if pq.w == 0.0 {
                continue;
            }
            let error = abs(length(pq.xyz) - d) / d;
            let similar = pow(max(dot(n, pixel_normal(q)), 0.0), 8.0);
            let w = max(1.0 - error / UPSAMPLE_DEPTH_TOLERANCE, 0.0) * similar;
            sum += textureLoad(current_texture, q, 0) * w;
            weights += w;
        }
    }
    return sum / weights;
}

// `current` blended toward the history `h` by `weight`, its bent normal renormalised
// (the receiver's normal `n` where it vanishes), the AO clamped to [0, 1].
fn blend(current: vec4<f32>, h: vec4<f32>, weight: f32, n: vec3<f32>) -> vec4<f32> {
    let v = current + (h - current) * weight;
    let len = length(v.yzw);
    let bent = select(n, v.yzw / len, len > 1e-6);
    return vec4<f32>(clamp(v.x, 0.0, 1.0), bent);
}

@compute @workgroup_size(8, 8, 1)
fn temporal(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= view.full_size.x || gid.y >= view.full_size.y {
        return;
    }
    let xy = vec2<i32>(gid.xy);
    let p = pixel_position(xy);
    if p.w == 0.0 {
        textureStore(out_value, xy, vec4<f32>(1.0, 0.0, 0.0, 0.0));
        textureStore(out_filtered, xy, vec4<f32>(1.0, 0.0, 0.0, 0.0));
        textureStore(out_state, xy, vec4<f32>(0.0));
        return;
    }
    let d = length(p.xyz);
    let c = textureLoad(current_texture, xy, 0);
    var r = Reprojected(vec4<f32>(0.0), 0.0, false);
    if view.history_valid != 0u {
        r = reproject(xy, length(p.xyz - view.previous_offset));
    }
    var weight = 0.0;
    var confidence = 0.0;
    if r.found {
        if view.confidence != 0u {
            let leak = clamp((abs(c.x - r.value.x) - LEAK_TOLERANCE) / LEAK_TOLERANCE, 0.0, 1.0);
            let trust = r.confidence * (1.0 - leak);
            weight = HISTORY_WEIGHT * trust;
            confidence = min(trust + CONFIDENCE_GAIN, 1.0);
        } else {
            weight = HISTORY_WEIGHT;
            confidence = min(r.confidence + CONFIDENCE_GAIN, 1.0);
        }
    }
    let n = pixel_normal(xy);
    // The history keeps the pixel's own value: a stored fill would be compared with the
    // pixel's own trace next frame and, on a contact pixel, flushed for ever.
    let value = blend(c, select(c, r.value, r.found), weight, n);
    var filtered = value;
    if view.spatial_fill != 0u && confidence < FILL_CONFIDENCE {
        let fill = spatial_fill(xy, d, n);
        filtered = blend(fill, select(fill, r.value, r.found), weight, n);
    }
    textureStore(out_value, xy, value);
    textureStore(out_filtered, xy, filtered);
    textureStore(out_state, xy, vec4<f32>(d, confidence, 0.0, 0.0));
}
