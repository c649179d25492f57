// The distance-field debug view: sphere-traces each pixel's camera ray through the
// view's culled objects. Modes: step-count heat map (black → red → yellow → white as
// steps grow), shaded surfaces. CPU reference: `penumbra_reference::df::debug_pixel`.
#define_import_path penumbra::df::debug_view

#import penumbra::df::object::DistanceFieldObject
#import penumbra::df::distance::object_distance

struct DebugView {
    // Camera-relative world position of a point on a pixel's ray from clip space.
    relative_from_clip: mat4x4<f32>,
    camera_tile: vec4<i32>,
    camera_offset: vec4<f32>,
    mode: u32,
    max_steps: u32,
    max_distance: f32,
    _pad: u32,
}

@group(0) @binding(0) var<storage, read> objects: array<DistanceFieldObject>;
@group(0) @binding(1) var<storage, read> culled: array<u32>;
@group(0) @binding(2) var<storage, read> culled_count: array<u32>;
@group(0) @binding(3) var atlas: texture_3d<f32>;
@group(0) @binding(5) var brick_table: texture_2d<u32>;
@group(0) @binding(4) var<uniform> view: DebugView;

// What Bevy's fullscreen vertex shader (`FullscreenShader`) outputs: uv (0, 0) at the
// top-left corner.
struct FullscreenInput {
    @builtin(position) position: vec4<f32>,
    @location(0) uv: vec2<f32>,
}

const MODE_STEPS: u32 = 0u;
const MODE_SHADED: u32 = 1u;

fn scene_distance(p: vec3<f32>) -> f32 {
    var d = view.max_distance;
    let count = culled_count[0];
    for (var i = 0u; i < count; i += 1u) {
        d = min(d, object_distance(objects[culled[i]], p, view.camera_tile.xyz, view.camera_offset.xyz, atlas, brick_table));
    }
    return d;
}

fn heat(v: f32) -> vec3<f32> {
    return clamp(vec3<f32>(3.0 * v, 3.0 * v - 1.0, 3.0 * v - 2.0), vec3<f32>(0.0), vec3<f32>(1.0));
}

@fragment
fn debug_view(in: FullscreenInput) -> @location(0) vec4<f32> {
    let ndc = vec2<f32>(in.uv.x * 2.0 - 1.0, 1.0 - in.uv.y * 2.0);
    let on_ray = view.relative_from_clip * vec4<f32>(ndc, 0.5, 1.0);
    let dir = normalize(on_ray.xyz / on_ray.w);
    var t = 0.0;
    var steps = 0u;
    var hit = false;
    loop {
        if steps >= view.max_steps || t >= view.max_distance {
            break;
        }
        let d = scene_distance(dir * t);
        steps += 1u;
        if d < 1e-3 + 5e-4 * t {
            hit = true;
            break;
        }
        t += d;
    }
    if view.mode == MODE_STEPS {
        return vec4<f32>(heat(f32(steps) / f32(view.max_steps)), 1.0);
    }
    if !hit {
        return vec4<f32>(0.05, 0.05, 0.08, 1.0);
    }
    let p = dir * t;
    let e = 1e-3 * max(1.0, t);
    let n = normalize(vec3<f32>(
        scene_distance(p + vec3<f32>(e, 0.0, 0.0)) - scene_distance(p - vec3<f32>(e, 0.0, 0.0)),
        scene_distance(p + vec3<f32>(0.0, e, 0.0)) - scene_distance(p - vec3<f32>(0.0, e, 0.0)),
        scene_distance(p + vec3<f32>(0.0, 0.0, e)) - scene_distance(p - vec3<f32>(0.0, 0.0, e)),
    ));
    let light = normalize(vec3<f32>(0.4, 0.8, 0.3));
    let c = 0.8 * (0.15 + 0.85 * max(dot(n, light), 0.0));
    return vec4<f32>(vec3<f32>(c), 1.0);
}
