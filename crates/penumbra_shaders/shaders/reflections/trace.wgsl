// Billboard reflections' trace (`bevy_penumbra_cinematic::reflections`): for each
// G-buffer pixel (at full or half resolution), the mirror ray from the normal and the
// view vector is intersected with every billboard; the nearest `max_layers` hits whose
// GGX footprint overlaps the image are sampled over that footprint and composited front
// to back into premultiplied radiance (cd/m²) and coverage — the specular layer that
// Penumbra's lighting pass adds under Bevy's environment BRDF. Reflection shadows: one
// soft march along the mirror ray through the distance-field scene's objects dims each
// hit by its visibility.
// CPU model: `penumbra_cinematic_core::reflections::pass::reflect_pixel`.

#import bevy_pbr::{
    pbr_types::STANDARD_MATERIAL_FLAGS_UNLIT_BIT,
    pbr_deferred_functions::pbr_input_from_deferred_gbuffer,
    mesh_view_bindings::{deferred_prepass_texture, depth_prepass_texture},
}
#import penumbra::df::object::{DistanceFieldObject, FLAG_CASTS_SHADOWS, FLAG_LIVE, TILE_SIZE}
#import penumbra::df::distance::object_distance

const MAX_TAPS: u32 = 8u;
const MAX_LAYERS: u32 = 4u;
const MAX_ANISOTROPY: f32 = 0.95;
const MIN_SHADOW_STEP: f32 = 0.01;

// `penumbra_cinematic_core::reflections::pass::GpuBillboard`.
struct GpuBillboard {
    center: vec3<f32>,
    layer: u32,
    half_x: vec3<f32>,
    emissive: f32,
    half_y: vec3<f32>,
    reserved: u32,
}

// `penumbra_cinematic_core::reflections::pass::ReflectionUniform`.
struct ReflectionUniform {
    billboard_count: u32,
    max_layers: u32,
    max_distance: f32,
    anisotropy: f32,
    texture_size: vec2<u32>,
    mip_count: u32,
    half_resolution: u32,
    camera_tile: vec3<i32>,
    object_count: u32,
    camera_offset: vec3<f32>,
    footprint_slope: f32,
    shadow_steps: u32,
    shadow_bias: f32,
    shadow_softness: f32,
    taps: u32,
}

@group(2) @binding(0) var<uniform> settings: ReflectionUniform;
@group(2) @binding(1) var<storage, read> billboards: array<GpuBillboard>;
@group(2) @binding(2) var images: texture_2d_array<f32>;
@group(2) @binding(3) var images_sampler: sampler;
// The distance-field scene (reflection shadows): its objects and atlas.
@group(2) @binding(4) var<storage, read> objects: array<DistanceFieldObject>;
@group(2) @binding(5) var atlas: texture_3d<f32>;

struct Lobe {
    dir: vec3<f32>,
    major: vec3<f32>,
    minor: vec3<f32>,
}

struct FootprintHit {
    t: f32,
    index: u32,
    uv: vec2<f32>,
    axis_a: vec2<f32>,
    axis_b: vec2<f32>,
}

struct FullscreenVertexOutput {
    @builtin(position) position: vec4<f32>,
}

@vertex
fn vertex(@builtin(vertex_index) vertex_index: u32) -> FullscreenVertexOutput {
    let uv = vec2<f32>(f32(vertex_index >> 1u), f32(vertex_index & 1u)) * 2.0;
    return FullscreenVertexOutput(vec4(uv * vec2(2.0, -2.0) + vec2(-1.0, 1.0), 0.0, 1.0));
}

@fragment
fn fragment(in: FullscreenVertexOutput) -> @location(0) vec4<f32> {
    let pixel = vec2<i32>(in.position.xy) * select(1, 2, settings.half_resolution != 0u);
    let depth = textureLoad(depth_prepass_texture, pixel, 0);
    if depth == 0.0 {
        return vec4(0.0); // the sky
    }
    let frag_coord = vec4(vec2<f32>(pixel) + 0.5, depth, 0.0);
    let in_gbuffer = pbr_input_from_deferred_gbuffer(frag_coord, textureLoad(deferred_prepass_texture, pixel, 0));
    if (in_gbuffer.material.flags & STANDARD_MATERIAL_FLAGS_UNLIT_BIT) != 0u {
        return vec4(0.0);
    }
    let lobe = surface_lobe(in_gbuffer.N, in_gbuffer.V, in_gbuffer.material.perceptual_roughness);
    return reflect_billboards(in_gbuffer.world_position.xyz, lobe);
}

// A unit vector perpendicular to unit `n` (Duff et al.).
fn any_perpendicular(n: vec3<f32>) -> vec3<f32> {
    let sign = select(1.0, -1.0, (bitcast<u32>(n.z) >> 31u) != 0u); // copysign(1, n.z)
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    return vec3(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
}

// The mirror ray and the lobe's footprint half-axes per metre (module docs of the model).
fn surface_lobe(n: vec3<f32>, v: vec3<f32>, perceptual_roughness: f32) -> Lobe {
    let n_dot_v = max(dot(n, v), 1e-4);
    let dir = 2.0 * n_dot_v * n - v;
    let along = v - n * dot(n, v);
    var t = any_perpendicular(n);
    if dot(along, along) > 1e-8 {
        t = normalize(along);
    }
    let b = cross(n, t);
    let e1 = n_dot_v * t + dot(v, t) * n;
    let p = clamp(perceptual_roughness, 0.089, 1.0);
    let alpha = p * p;
    let a = clamp(settings.anisotropy, 0.0, MAX_ANISOTROPY);
    return Lobe(
        dir,
        e1 * (settings.footprint_slope * alpha * (1.0 + a)),
        b * (settings.footprint_slope * alpha * (1.0 - a) * n_dot_v),
    );
}

// The hit of the lobe on billboard `index`; `t = -1` when it misses.
fn footprint_hit(index: u32, origin: vec3<f32>, lobe: Lobe) -> FootprintHit {
    var hit = FootprintHit(-1.0, index, vec2(0.0), vec2(0.0), vec2(0.0));
    let b = billboards[index];
    let n = cross(b.half_x, b.half_y);
    let facing = dot(lobe.dir, n);
    if !(facing < 0.0) {
        return hit;
    }
    let t = dot(b.center - origin, n) / facing;
    if !(t > 0.0 && t <= settings.max_distance) {
        return hit;
    }
    let n2 = dot(n, n);
    let du = cross(b.half_y, n) * (0.5 / n2);
    let dv = cross(n, b.half_x) * (-0.5 / n2);
    let p = origin + lobe.dir * t - b.center;
    let uv = vec2(dot(p, du), dot(p, dv)) + 0.5;
    let oa = lobe.major * t;
    let ob = lobe.minor * t;
    let pa = oa - lobe.dir * (dot(oa, n) / facing);
    let pb = ob - lobe.dir * (dot(ob, n) / facing);
    let axis_a = vec2(dot(pa, du), dot(pa, dv));
    let axis_b = vec2(dot(pb, du), dot(pb, dv));
    let reach = abs(axis_a) + abs(axis_b);
    if all(uv >= -reach) && all(uv <= vec2(1.0) + reach) {
        hit = FootprintHit(t, index, uv, axis_a, axis_b);
    }
    return hit;
}

// The fraction of the box [c − e, c + e] inside [0, 1].
fn box_coverage(c: f32, e: f32) -> f32 {
    if e <= 1e-7 {
        return select(0.0, 1.0, c >= 0.0 && c <= 1.0);
    }
    return min((clamp(c + e, 0.0, 1.0) - clamp(c - e, 0.0, 1.0)) / (2.0 * e), 1.0);
}

// The premultiplied image over a hit's footprint: taps along its long axis, spread so
// that the result varies continuously with the footprint's shape
// (`penumbra_cinematic_core::reflections::pass::sample_footprint`).
fn sample_footprint(layer: u32, hit: FootprintHit) -> vec4<f32> {
    let size = vec2<f32>(settings.texture_size);
    let ta = hit.axis_a * size;
    let tb = hit.axis_b * size;
    var long = length(tb);
    var short = length(ta);
    var long_uv = hit.axis_b;
    var short_uv = hit.axis_a;
    if length(ta) >= length(tb) {
        long = length(ta);
        short = length(tb);
        long_uv = hit.axis_a;
        short_uv = hit.axis_b;
    }
    var taps = 1u;
    if long > short * 1.0001 {
        taps = clamp(settings.taps, 1u, MAX_TAPS);
    }
    let n = f32(taps);
    let half = max(short, long / n);
    let lod = log2(max(2.0 * half, 1.0));
    var share = 1.0;
    if long > 0.0 {
        share = half / long;
    }
    let reach = abs(short_uv) + abs(long_uv) * share;
    var sum = vec4(0.0);
    for (var k = 0u; k < taps; k += 1u) {
        var at = 0.0;
        if taps > 1u {
            at = 2.0 * f32(k) / (n - 1.0) - 1.0;
        }
        let uv = hit.uv + long_uv * ((1.0 - share) * at);
        let cover = box_coverage(uv.x, reach.x) * box_coverage(uv.y, reach.y);
        if cover > 0.0 {
            sum += textureSampleLevel(images, images_sampler, uv, layer, lod) * cover;
        }
    }
    return sum / n;
}

// The nearest hits composited front to back: premultiplied radiance and coverage.
fn reflect_billboards(origin: vec3<f32>, lobe: Lobe) -> vec4<f32> {
    let k = clamp(settings.max_layers, 1u, MAX_LAYERS);
    var hits: array<FootprintHit, MAX_LAYERS>;
    var count = 0u;
    for (var i = 0u; i < settings.billboard_count; i += 1u) {
        let hit = footprint_hit(i, origin, lobe);
        if hit.t < 0.0 {
            continue;
        }
        // Insertion into the sorted list (distance, then index).
        var at = count;
        for (var j = 0u; j < count; j += 1u) {
            if hit.t < hits[j].t || (hit.t == hits[j].t && hit.index < hits[j].index) {
                at = j;
                break;
            }
        }
        if at >= k {
            continue;
        }
        var j = min(count, k - 1u);
        while j > at {
            hits[j] = hits[j - 1u];
            j -= 1u;
        }
        hits[at] = hit;
        count = min(count + 1u, k);
    }
    let cone = max(length(lobe.major), settings.shadow_softness);
    var facing: array<f32, MAX_LAYERS>;
    for (var j = 0u; j < count; j += 1u) {
        let b = billboards[hits[j].index];
        facing[j] = abs(dot(lobe.dir, normalize(cross(b.half_x, b.half_y))));
    }
    let visibility = shadow_march(origin, lobe.dir, &hits, &facing, count, cone);
    var colour = vec3(0.0);
    var transmittance = 1.0;
    for (var j = 0u; j < count; j += 1u) {
        let b = billboards[hits[j].index];
        let texel = sample_footprint(b.layer, hits[j]);
        colour += transmittance * texel.rgb * (b.emissive * visibility[j]);
        transmittance *= 1.0 - clamp(texel.a, 0.0, 1.0);
    }
    return vec4(colour, 1.0 - transmittance);
}

// The distance (metres) from world point `p` to the nearest live shadow-casting object.
fn scene_distance(p: vec3<f32>) -> f32 {
    let camera = vec3<f32>(settings.camera_tile) * TILE_SIZE + settings.camera_offset;
    let relative = p - camera;
    var d = 3.4e38;
    for (var i = 0u; i < settings.object_count; i += 1u) {
        let o = objects[i];
        let needed = FLAG_LIVE | FLAG_CASTS_SHADOWS;
        if (o.flags & needed) != needed {
            continue;
        }
        d = min(d, object_distance(o, relative, settings.camera_tile, settings.camera_offset, atlas));
    }
    return d;
}

// Reflection shadows: each hit's visibility from one soft march along the ray, counting
// only surfaces in front of the next billboard's plane
// (`penumbra_cinematic_core::reflections::pass::shadow_march`).
fn shadow_march(
    origin: vec3<f32>,
    dir: vec3<f32>,
    hits: ptr<function, array<FootprintHit, MAX_LAYERS>>,
    facing: ptr<function, array<f32, MAX_LAYERS>>,
    count: u32,
    cone: f32,
) -> array<f32, MAX_LAYERS> {
    var out = array<f32, MAX_LAYERS>(1.0, 1.0, 1.0, 1.0);
    if settings.shadow_steps == 0u || settings.object_count == 0u {
        return out;
    }
    var t = settings.shadow_bias;
    var v = 1.0;
    var j = 0u;
    for (var step = 0u; step < settings.shadow_steps; step += 1u) {
        while j < count && t >= (*hits)[j].t {
            out[j] = v;
            j += 1u;
        }
        if j >= count || v <= 0.0 {
            break;
        }
        let d = scene_distance(origin + dir * t);
        // Only surfaces surely in front of the next billboard's plane occlude it.
        if d < ((*hits)[j].t - t) * (*facing)[j] {
            v = min(v, clamp(d / (cone * t), 0.0, 1.0));
        }
        t += max(d, MIN_SHADOW_STEP);
    }
    for (; j < count; j += 1u) {
        out[j] = v;
    }
    return out;
}
