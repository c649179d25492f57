// The global distance field's debug views: each pixel's camera ray is sphere-traced
// through the clipmaps (the finest valid level; the surface distance is the stored
// value plus the level's dilation; a hit is under a quarter of that level's texel),
// Lambert-shaded by the field's gradient; tinted by the answering level (mode 1) or,
// where its storage brick was composed this frame, orange (mode 2). Group 1 is the
// field (`global_field.wgsl`). CPU model: `penumbra_reference::field_debug`; layouts:
// `penumbra_df_core::clipmap::debug`.
#define_import_path penumbra::df::global_field_debug

#import penumbra::df::global_field::{global_view, sample_field, field_normal, BRICK}

struct FieldDebugParams {
    relative_from_clip: mat4x4<f32>,
    mode: u32,
    max_steps: u32,
    max_distance: f32,
}

@group(0) @binding(0) var<uniform> debug_params: FieldDebugParams;
// Bits of the storage bricks composed this frame, laid out as the validity bits.
@group(0) @binding(1) var<storage, read> debug_updated: array<u32>;

const MODE_LEVELS: u32 = 1u;
const MODE_UPDATES: u32 = 2u;
const MISS: vec3<f32> = vec3<f32>(0.05, 0.05, 0.08);
const UPDATED: vec3<f32> = vec3<f32>(1.0, 0.45, 0.1);

// `clipmap::debug::LEVEL_COLORS`.
fn level_color(level: u32) -> vec3<f32> {
    var colors = array<vec3<f32>, 8>(
        vec3<f32>(1.0, 0.25, 0.2),
        vec3<f32>(1.0, 0.6, 0.1),
        vec3<f32>(0.95, 0.95, 0.2),
        vec3<f32>(0.3, 0.9, 0.3),
        vec3<f32>(0.2, 0.85, 0.9),
        vec3<f32>(0.25, 0.4, 1.0),
        vec3<f32>(0.6, 0.3, 1.0),
        vec3<f32>(1.0, 0.3, 0.85),
    );
    return colors[min(level, 7u)];
}

fn debug_ray(uv: vec2<f32>) -> vec3<f32> {
    let ndc = vec2<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
    let on_ray = debug_params.relative_from_clip * vec4<f32>(ndc, 0.5, 1.0);
    return normalize(on_ray.xyz / on_ray.w);
}

// Sphere tracing from the camera: (t, level, 1) at a hit, else w = 0.
fn trace_field(dir: vec3<f32>) -> vec3<f32> {
    var t = 0.0;
    for (var step = 0u; step < debug_params.max_steps; step++) {
        if t >= debug_params.max_distance {
            break;
        }
        let s = sample_field(dir * t, 0u);
        if s.z == 0.0 {
            break;
        }
        let l = global_view.levels[u32(s.y)];
        let d = s.x + l.dilation;
        if d < 0.25 * l.texel {
            return vec3<f32>(t, s.y, 1.0);
        }
        t += d;
    }
    return vec3<f32>(0.0);
}

// Whether the storage brick holding camera-relative `p` in `level` was composed this
// frame.
fn updated_at(level: u32, p: vec3<f32>) -> bool {
    let l = global_view.levels[level];
    let n = i32(global_view.resolution);
    let w = vec3<i32>(floor((p + l.camera) / l.texel));
    let s = ((l.origin_mod + w) % n + n) % n;
    let b = s / i32(BRICK);
    let nb = i32(global_view.bricks_per_side);
    let bit = u32(b.x + nb * (b.y + nb * b.z));
    return ((debug_updated[level * global_view.valid_words + bit / 32u] >> (bit % 32u)) & 1u) == 1u;
}

// Linear RGB of the view at `uv` ((0, 0): the top-left corner).
fn field_debug_color(uv: vec2<f32>) -> vec3<f32> {
    let dir = debug_ray(uv);
    let hit = trace_field(dir);
    if hit.z == 0.0 {
        return MISS;
    }
    let level = u32(hit.y);
    let p = dir * hit.x;
    let f = field_normal(p);
    let n = select(-dir, f.normal, f.ok);
    let light = normalize(vec3<f32>(0.4, 0.8, 0.3));
    let c = 0.8 * (0.15 + 0.85 * max(dot(n, light), 0.0));
    if debug_params.mode == MODE_LEVELS {
        return c * level_color(level);
    }
    if debug_params.mode == MODE_UPDATES && updated_at(level, p) {
        return c * UPDATED;
    }
    return vec3<f32>(c);
}

struct FullscreenInput {
    @builtin(position) position: vec4<f32>,
    @location(0) uv: vec2<f32>,
}

@fragment
fn global_field_debug(in: FullscreenInput) -> @location(0) vec4<f32> {
    return vec4<f32>(field_debug_color(in.uv), 1.0);
}
