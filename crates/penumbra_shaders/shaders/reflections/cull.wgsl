// Billboard reflections' tile cull (`bevy_penumbra_cinematic::reflections`): one
// fragment per tile of the trace's image bounds its pixels — a sphere around their
// positions, a cone around their mirror directions, their largest footprint spread —
// and lists the billboards some ray from those bounds could meet. Conservative: the
// trace's result is the same as testing every billboard. With reflection shadows it also
// lists the shadow casters some pixel's march could gather (`cull::tile_casters`).
// CPU model: `penumbra_cinematic_core::reflections::cull`.

#import penumbra::reflections::common::{
    TILE, billboards, camera_position, caster_record, settings, spheres, surface_sample,
    tile_lists, tile_record,
}
#import penumbra::reflections::types::GpuBillboard

struct FullscreenVertexOutput {
    @builtin(position) position: vec4<f32>,
}

@vertex
fn vertex(@builtin(vertex_index) vertex_index: u32) -> FullscreenVertexOutput {
    let uv = vec2<f32>(f32(vertex_index >> 1u), f32(vertex_index & 1u)) * 2.0;
    return FullscreenVertexOutput(vec4(uv * vec2(2.0, -2.0) + vec2(-1.0, 1.0), 0.0, 1.0));
}

// `penumbra_cinematic_core::reflections::cull::TileBounds`.
struct TileBounds {
    center: vec3<f32>,
    radius: f32,
    axis: vec3<f32>,
    cos_angle: f32,
    spread: f32,
    valid: bool,
}

@fragment
fn cull(in: FullscreenVertexOutput) -> @location(0) vec4<f32> {
    let tile = vec2<u32>(in.position.xy);
    let base = tile_record(tile);
    let bounds = tile_bounds(tile);
    var count = 0u;
    // The farthest any pixel meets a kept billboard (`cull::tile_march_length`).
    var march_length = 0.0;
    if bounds.valid {
        for (var i = 0u; i < settings.billboard_count; i += 1u) {
            let reach = tile_reach(bounds, billboards[i]);
            if reach < 0.0 || (billboards[i].layers & settings.view_layers) == 0u {
                continue;
            }
            march_length = max(march_length, reach);
            if count < settings.tile_capacity {
                tile_lists[base + 1u + count] = i;
            }
            count += 1u;
        }
    }
    // Over the capacity: the trace tests every billboard.
    tile_lists[base] = count;
    if settings.caster_capacity > 0u {
        list_casters(bounds, caster_record(base), march_length * (1.0 + 1e-3));
    }
    return vec4(0.0);
}

// The shadow casters some pixel's march of at most `march_length` could gather
// (`cull::tile_casters`), written at `at`: their count, then their object slots.
fn list_casters(b: TileBounds, at: u32, march_length: f32) {
    var n = 0u;
    if b.valid && march_length > 0.0 {
        let cone = max(b.spread * settings.shadow_cone, settings.shadow_softness);
        let center = b.center - camera_position();
        for (var i = 0u; i < settings.object_count; i += 1u) {
            let sphere = spheres[i];
            if sphere.w < -1.5 {
                continue; // not a live shadow caster
            }
            if !tile_keeps_caster(b, center, sphere, march_length, cone) {
                continue;
            }
            if n < settings.caster_capacity {
                tile_lists[at + 1u + n] = i;
            }
            n += 1u;
        }
    }
    // Over the capacity: the trace's pixels gather from every object.
    tile_lists[at] = n;
}

// Whether the object bounded by `sphere` (camera-relative; w < 0: unbounded) may come
// within reach of a march of a pixel of the tile (`cull::tile_keeps_caster`); `center`
// the tile's centre, camera-relative.
fn tile_keeps_caster(
    b: TileBounds,
    center: vec3<f32>,
    sphere: vec4<f32>,
    march_length: f32,
    cone: f32,
) -> bool {
    if sphere.w < 0.0 {
        return true;
    }
    var reach = sphere.w + cone * march_length + b.radius;
    reach += reach * 1e-3 + 1e-3;
    let v = sphere.xyz - center;
    let dist = length(v);
    if dist <= reach {
        return true;
    }
    if dist > march_length + reach {
        return false;
    }
    if b.cos_angle <= -1.0 {
        return true;
    }
    let sin_angle = sqrt(max(1.0 - b.cos_angle * b.cos_angle, 0.0));
    let cos_to = dot(b.axis, v) / dist;
    let sin_ball = reach / dist;
    let cos_ball = sqrt(max(1.0 - sin_ball * sin_ball, 0.0));
    let cos_sum = b.cos_angle * cos_ball - sin_angle * sin_ball;
    let sum_past_pi = b.cos_angle < 0.0 && cos_ball < 0.0;
    return sum_past_pi || cos_to >= cos_sum - 1e-5;
}

// The bounds of a tile's pixels (`TileBounds::from_pixels`).
fn tile_bounds(tile: vec2<u32>) -> TileBounds {
    var out: TileBounds;
    var lo = vec3(3.4e38);
    var hi = vec3(-3.4e38);
    var sum = vec3(0.0);
    var spread = 0.0;
    out.valid = false;
    let size = settings.trace_size;
    for (var k = 0u; k < TILE * TILE; k += 1u) {
        let p = tile * TILE + vec2(k % TILE, k / TILE);
        if any(p >= size) {
            continue;
        }
        let s = surface_sample(vec2<i32>(p));
        if !s.valid {
            continue;
        }
        lo = min(lo, s.position);
        hi = max(hi, s.position);
        sum += s.lobe.dir;
        spread = max(spread, length(s.lobe.major) + length(s.lobe.minor));
        out.valid = true;
    }
    if !out.valid {
        return out;
    }
    let length_sum = length(sum);
    var cos_angle = -1.0;
    out.axis = vec3(0.0, 0.0, 1.0);
    if length_sum > 1e-3 {
        out.axis = sum / length_sum;
        cos_angle = 1.0;
        for (var k = 0u; k < TILE * TILE; k += 1u) {
            let p = tile * TILE + vec2(k % TILE, k / TILE);
            if any(p >= size) {
                continue;
            }
            let s = surface_sample(vec2<i32>(p));
            if s.valid {
                cos_angle = min(cos_angle, dot(out.axis, s.lobe.dir));
            }
        }
    }
    out.center = (lo + hi) * 0.5;
    out.radius = length(hi - lo) * 0.5;
    out.cos_angle = max(cos_angle - 1e-4, -1.0);
    out.spread = spread;
    return out;
}

// How far along its ray some pixel of the bounds could meet billboard `b`; −1 when
// none can (`cull::tile_reach`).
fn tile_reach(b: TileBounds, billboard: GpuBillboard) -> f32 {
    let cross_axes = cross(billboard.half_x, billboard.half_y);
    let area = length(cross_axes);
    if !(area > 0.0) {
        return -1.0;
    }
    let n = cross_axes / area;
    let plane = dot(b.center - billboard.center, n);
    if plane + b.radius <= 0.0 {
        return -1.0;
    }
    if plane - b.radius > settings.max_distance {
        return -1.0;
    }
    let sin_angle = sqrt(max(1.0 - b.cos_angle * b.cos_angle, 0.0));
    let toward = -dot(b.axis, n);
    let toward_sin = sqrt(max(1.0 - toward * toward, 0.0));
    var max_facing = 1.0;
    var min_facing = -1.0;
    if b.cos_angle > -1.0 {
        let widest = toward * b.cos_angle + toward_sin * sin_angle;
        min_facing = toward * b.cos_angle - toward_sin * sin_angle;
        max_facing = select(widest, 1.0, toward >= b.cos_angle);
    }
    if max_facing <= 0.0 {
        return -1.0;
    }
    if min_facing <= 1e-3 || b.cos_angle <= -1.0 {
        return settings.max_distance;
    }
    let hx = length(billboard.half_x);
    let hy = length(billboard.half_y);
    let sin_phi = area / (hx * hy);
    let t_max = min(max(plane + b.radius, 0.0) / min_facing, settings.max_distance);
    let reach = 2.0 * 1.41421356 * b.spread * t_max / (min_facing * max(sin_phi, 1e-6));
    let ball = hx + hy + reach + b.radius;
    let v = billboard.center - b.center;
    let dist = length(v);
    let farthest = min(t_max, dist + ball);
    if dist <= ball {
        return farthest;
    }
    let cos_to = dot(b.axis, v) / dist;
    let sin_ball = ball / dist;
    let cos_ball = sqrt(max(1.0 - sin_ball * sin_ball, 0.0));
    let cos_sum = b.cos_angle * cos_ball - sin_angle * sin_ball;
    let sum_past_pi = b.cos_angle < 0.0 && cos_ball < 0.0;
    return select(-1.0, farthest, sum_past_pi || cos_to >= cos_sum - 1e-5);
}
