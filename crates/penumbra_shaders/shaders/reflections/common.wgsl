// Billboard reflections' shared declarations (`bevy_penumbra_cinematic::reflections`):
// the uniform, the billboards, images and distance-field scene, the tiles' billboard
// lists, and a G-buffer pixel's mirror ray and lobe. Used by the tile cull
// (`reflections/cull.wgsl`) and the trace (`reflections/trace.wgsl`).
#define_import_path penumbra::reflections::common

#import bevy_pbr::{
    pbr_types::STANDARD_MATERIAL_FLAGS_UNLIT_BIT,
    pbr_deferred_functions::pbr_input_from_deferred_gbuffer,
}
#ifndef PENUMBRA_PIXEL_PREPASS
#import bevy_pbr::mesh_view_bindings::{deferred_prepass_texture, depth_prepass_texture}
#endif
#import penumbra::df::object::{DistanceFieldObject, FLAG_CASTS_SHADOWS, FLAG_LIVE, TILE_SIZE}
#import penumbra::reflections::types::{GpuBillboard, ReflectionUniform}

const MAX_TAPS: u32 = 8u;
const MAX_LAYERS: u32 = 4u;
const MAX_ANISOTROPY: f32 = 0.95;
const MIN_SHADOW_STEP: f32 = 0.01;

// Trace pixels per tile side.
const TILE: u32 = 16u;

@group(2) @binding(0) var<uniform> settings: ReflectionUniform;
@group(2) @binding(1) var<storage, read> billboards: array<GpuBillboard>;
@group(2) @binding(2) var images: texture_2d_array<f32>;
@group(2) @binding(3) var images_sampler: sampler;
// The distance-field scene (reflection shadows): its objects and atlas.
@group(2) @binding(4) var<storage, read> objects: array<DistanceFieldObject>;
@group(2) @binding(5) var atlas: texture_3d<f32>;
@group(2) @binding(8) var brick_table: texture_2d<u32>;
// Per object slot, its bounding sphere relative to the camera for the shadow casters
// (w −1: unbounded), w −2 for the rest (`reflections/spheres.wgsl`, run before the cull).
@group(2) @binding(7) var<storage, read> spheres: array<vec4<f32>>;
// Per tile (from `tile_record`): the count of billboards kept, then their indices
// (`tile_capacity` slots); with caster lists, the count of shadow casters kept, then
// their object slots (`caster_capacity` slots). A count over its capacity means "every
// billboard" or "every object".
@group(2) @binding(6) var<storage, read_write> tile_lists: array<u32>;

#ifdef PENUMBRA_PIXEL_PREPASS
// Deferred MSAA: each pixel's representative depth and G-buffer texel (the samples'
// mean where they agree, the first covered sample on edges), which the classification
// writes; Bevy's prepass textures are multisampled there.
@group(3) @binding(0) var pixel_depth: texture_depth_2d;
@group(3) @binding(1) var pixel_gbuffer: texture_2d<u32>;
#endif

// Where tile `tile`'s record starts in `tile_lists`.
fn tile_record(tile: vec2<u32>) -> u32 {
    var stride = settings.tile_capacity + 1u;
    if settings.caster_capacity > 0u {
        stride += settings.caster_capacity + 1u;
    }
    return (tile.y * settings.tiles_x + tile.x) * stride;
}

// Where a tile's caster count is, from its record's start.
fn caster_record(record: u32) -> u32 {
    return record + settings.tile_capacity + 1u;
}

// Whether object `o` casts reflection shadows.
fn casts(o: u32) -> bool {
    let needed = FLAG_LIVE | FLAG_CASTS_SHADOWS;
    return (objects[o].flags & needed) == needed;
}

// The camera's world position (the distance-field scene's objects are relative to it).
fn camera_position() -> vec3<f32> {
    return vec3<f32>(settings.camera_tile) * TILE_SIZE + settings.camera_offset;
}

struct Lobe {
    dir: vec3<f32>,
    major: vec3<f32>,
    minor: vec3<f32>,
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


// A trace pixel's surface: world position and lobe; `valid` false for the sky and unlit
// materials (no reflection).
struct SurfaceSample {
    position: vec3<f32>,
    lobe: Lobe,
    valid: bool,
}

// The G-buffer under trace pixel `trace_pixel` (the top-left pixel of its 2 × 2 block at
// half resolution).
fn surface_sample(trace_pixel: vec2<i32>) -> SurfaceSample {
    var out: SurfaceSample;
    out.valid = false;
    let pixel = trace_pixel * select(1, 2, settings.half_resolution != 0u);
#ifdef PENUMBRA_PIXEL_PREPASS
    let depth = textureLoad(pixel_depth, pixel, 0);
#else
    let depth = textureLoad(depth_prepass_texture, pixel, 0);
#endif
    if depth == 0.0 {
        return out; // the sky
    }
    let frag_coord = vec4(vec2<f32>(pixel) + 0.5, depth, 0.0);
#ifdef PENUMBRA_PIXEL_PREPASS
    let gbuffer = textureLoad(pixel_gbuffer, pixel, 0);
#else
    let gbuffer = textureLoad(deferred_prepass_texture, pixel, 0);
#endif
    let in = pbr_input_from_deferred_gbuffer(frag_coord, gbuffer);
    if (in.material.flags & STANDARD_MATERIAL_FLAGS_UNLIT_BIT) != 0u {
        return out;
    }
    out.position = in.world_position.xyz;
    out.lobe = surface_lobe(in.N, in.V, in.material.perceptual_roughness);
    out.valid = true;
    return out;
}
