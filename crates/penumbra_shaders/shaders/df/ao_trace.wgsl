// The distance-field AO trace: per 8×8 tile of trace texels, the pixels are split into
// two ranges of distance from the camera (either side of the tile's middle), each bounded
// by a ball; every occluding object is kept for a range when its ball grown by the
// influence distance meets the range's ball and one distance sample at the range's
// centre, less its radius, is within the influence distance (64 objects at a time in
// workgroup memory). Each pixel then marches its range's objects with every cone and
// writes (AO, bent normal). Texel (i, j) traces full-resolution pixel
// (i, j) · divisor + jitter; background texels get (1, 0, 0, 0). The objects-per-tile
// debug view writes the count of objects kept for the texel's range, over
// TILE_OBJECTS_SCALE, in place of the AO (`dfao::tile_object_counts`). With a global
// distance field (`far_distance` > `max_distance`, group 1 bound to its clipmaps) each
// cone goes on through the field from the switch distance (`max_distance`) to
// `far_distance`; otherwise group 1 is an empty field that is never read. Terrains
// (`heightfield_count` records, `df/heightfield.wgsl`) are marched by every cone up to
// `max_distance`, each skipped where its box is beyond the influence of the pixel
// (`dfao::texture_visibilities`).
// CPU model: `penumbra_reference::dfao::trace_view` (`trace_view_far` with the field).
#define_import_path penumbra::df::ao_trace

#import penumbra::df::object::{DistanceFieldObject, TILE_SIZE}
#import penumbra::df::distance::object_distance
#import penumbra::df::shadow::{bounding_sphere, cull_slack, facing_the_eye, gbuffer_normal}
#import penumbra::df::shadow_grid::{from_order_key, order_key}
#import penumbra::df::ao::{
    AoTraceView, MAX_CONES, MIN_STEP_FRACTION, TILE_OBJECTS_SCALE, casts_occlusion, combine, cone_direction,
    march_cone, tangent_frame,
}
#import penumbra::df::global_field::{FarCone, march_field}
#import penumbra::df::heightfield::{HeightfieldRecord, heightfield_distance}

@group(0) @binding(0) var<storage, read> objects: array<DistanceFieldObject>;
@group(0) @binding(1) var atlas: texture_3d<f32>;
@group(0) @binding(8) var brick_table: texture_2d<u32>;
// Reverse-Z prepass depth, as an unfilterable float texture.
@group(0) @binding(2) var depth_texture: texture_2d<f32>;
// Bevy's deferred G-buffer (Rgba32Uint; the octahedral normal in `.a`).
@group(0) @binding(3) var gbuffer: texture_2d<u32>;
@group(0) @binding(4) var<uniform> view: AoTraceView;
@group(0) @binding(5) var output: texture_storage_2d<rgba16float, write>;
@group(0) @binding(6) var<storage, read> heightfields: array<HeightfieldRecord>;
@group(0) @binding(7) var heights: texture_2d<f32>;

const TILE_PIXELS: u32 = 64u;

// Distance range keys (min, max) and, per range, box keys (min xyz, max xyz).
var<workgroup> range_keys: array<atomic<u32>, 2>;
var<workgroup> box_keys: array<atomic<u32>, 12>;
var<workgroup> tile_slots: array<u32, 64>;
var<workgroup> tile_spheres: array<vec4<f32>, 64>;
var<workgroup> tile_masks: array<u32, 64>;
var<workgroup> tile_count: atomic<u32>;
var<workgroup> tile_n: u32;

// Camera-relative world position of full-resolution pixel `xy` at reverse-Z `depth`.
fn position_from_depth(xy: vec2<u32>, depth: f32) -> vec3<f32> {
    let uv = (vec2<f32>(xy) + 0.5) / vec2<f32>(view.full_size);
    let v = view.view_from_clip * vec4<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, depth, 1.0);
    return view.world_from_view * (v.xyz / v.w);
}

// Range `r`'s ball (xyz centre, w radius; w < 0: the range has no pixel).
fn range_ball(r: u32) -> vec4<f32> {
    let base = r * 6u;
    let lo = vec3<f32>(
        from_order_key(atomicLoad(&box_keys[base])),
        from_order_key(atomicLoad(&box_keys[base + 1u])),
        from_order_key(atomicLoad(&box_keys[base + 2u])),
    );
    let hi = vec3<f32>(
        from_order_key(atomicLoad(&box_keys[base + 3u])),
        from_order_key(atomicLoad(&box_keys[base + 4u])),
        from_order_key(atomicLoad(&box_keys[base + 5u])),
    );
    if atomicLoad(&box_keys[base]) > atomicLoad(&box_keys[base + 3u]) {
        return vec4<f32>(0.0, 0.0, 0.0, -1.0);
    }
    return vec4<f32>((lo + hi) * 0.5, length(hi - lo) * 0.5);
}

// Whether object `o` (ball `sphere`) may occlude a pixel in `ball` (`dfao::tile_keeps`).
fn tile_keeps(o: DistanceFieldObject, sphere: vec4<f32>, ball: vec4<f32>) -> bool {
    if ball.w < 0.0 {
        return false;
    }
    if sphere.w >= 0.0 {
        let reach = sphere.w + ball.w + view.influence;
        if length(sphere.xyz - ball.xyz) >= reach + cull_slack(reach) {
            return false;
        }
    }
    let d = object_distance(o, ball.xyz, view.camera_tile, view.camera_offset, atlas, brick_table);
    return d - ball.w < view.influence + cull_slack(ball.w + view.influence);
}

// Whether an object (ball `sphere`) is within reach of pixel `p` (`dfao::in_reach`).
fn in_reach(sphere: vec4<f32>, p: vec3<f32>) -> bool {
    return sphere.w < 0.0
        || length(sphere.xyz - p) - sphere.w < view.influence + cull_slack(sphere.w + view.influence);
}

// One cone's visibility through the global field from the switch distance (the
// objects' max distance) to the far distance (`dfao::far::pixel_ao_far`).
fn far_cone(o: vec3<f32>, axis: vec3<f32>, rise: f32) -> f32 {
    return march_field(FarCone(
        o, axis, rise, view.tan_half, view.bias, view.far_distance, view.steps_per_cone,
        view.shaping, view.max_distance, 0u,
    ));
}

// One cone's shaped visibility through terrain `h` from `o` (in its frame)
// (`dfao::march_terrain`).
fn terrain_cone(h: HeightfieldRecord, o: vec3<f32>, axis: vec3<f32>, rise: f32) -> f32 {
    var s = view.bias;
    var v = 1.0;
    for (var i = 0u; i < view.steps_per_cone; i += 1u) {
        if s >= view.max_distance {
            break;
        }
        let d = heightfield_distance(h, heights, o + axis * s);
        let cone = max(s * view.tan_half, 1e-6);
        if d <= 0.0 {
            v = 0.0;
            break;
        }
        let open = max(min(cone, view.bias + s * rise), 1e-6);
        v = min(v, d / open);
        s += max(d, cone * MIN_STEP_FRACTION);
    }
    return pow(clamp(v, 0.0, 1.0), view.shaping);
}

// Every cone's visibility lowered by the terrains within reach of `p` (camera-relative,
// unit normal `n`).
fn terrain_cones(
    visibility: ptr<function, array<f32, MAX_CONES>>,
    p: vec3<f32>,
    n: vec3<f32>,
    frame: mat2x3<f32>,
    count: u32,
) {
    for (var t = 0u; t < view.heightfield_count; t += 1u) {
        let h = heightfields[t];
        let local = vec3<f32>(view.camera_tile - h.tile) * TILE_SIZE + view.camera_offset + p;
        let lo = vec3<f32>(h.origin.x, h.bounds.z, h.origin.y);
        let hi = vec3<f32>(h.origin.x + h.extent.x, h.bounds.w, h.origin.y + h.extent.y);
        if length(max(max(lo - local, local - hi), vec3<f32>(0.0))) >= view.influence {
            continue;
        }
        let o = local + n * view.bias;
        for (var k = 0u; k < count; k += 1u) {
            let a = cone_direction(k, count);
            let axis = frame[0] * a.x + frame[1] * a.y + n * a.z;
            (*visibility)[k] = min((*visibility)[k], terrain_cone(h, o, axis, a.z));
        }
    }
}

@compute @workgroup_size(8, 8, 1)
fn trace(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
) {
    // Every workgroup variable is written before it is read (Bevy does not zero them).
    if li == 0u {
        atomicStore(&range_keys[0], 0xffffffffu);
        atomicStore(&range_keys[1], 0u);
        for (var i = 0u; i < 2u; i += 1u) {
            for (var a = 0u; a < 3u; a += 1u) {
                atomicStore(&box_keys[i * 6u + a], 0xffffffffu);
                atomicStore(&box_keys[i * 6u + 3u + a], 0u);
            }
        }
        atomicStore(&tile_count, 0u);
    }
    workgroupBarrier();

    let inside = gid.x < view.trace_size.x && gid.y < view.trace_size.y;
    let pixel = min(gid.xy * max(view.divisor, 1u) + view.jitter, view.full_size - vec2<u32>(1u));
    var depth = 0.0;
    if inside {
        depth = textureLoad(depth_texture, vec2<i32>(pixel + view.origin), 0).r;
    }
    let surface = inside && depth > 0.0;
    var p = vec3<f32>(0.0);
    var n = vec3<f32>(0.0, 0.0, 1.0);
    var distance = 0.0;
    if surface {
        p = position_from_depth(pixel, depth);
        // Turned to face the eye: an inverted normal (exported against its triangles'
        // winding, or a mirrored double-sided mesh's) would start the cones inside the
        // receiver's own caster.
        n = facing_the_eye(gbuffer_normal(textureLoad(gbuffer, vec2<i32>(pixel + view.origin), 0).a), p);
        distance = length(p);
        atomicMin(&range_keys[0], order_key(distance));
        atomicMax(&range_keys[1], order_key(distance));
    }
    workgroupBarrier();
    let split = 0.5 * (from_order_key(atomicLoad(&range_keys[0])) + from_order_key(atomicLoad(&range_keys[1])));
    let range = select(0u, 1u, distance > split);
    if surface {
        for (var a = 0u; a < 3u; a += 1u) {
            atomicMin(&box_keys[range * 6u + a], order_key(p[a]));
            atomicMax(&box_keys[range * 6u + 3u + a], order_key(p[a]));
        }
    }
    workgroupBarrier();
    let balls = array<vec4<f32>, 2>(range_ball(0u), range_ball(1u));
    let any_surface = balls[0].w >= 0.0 || balls[1].w >= 0.0;

    let count = clamp(view.cone_count, 1u, MAX_CONES);
    let frame = tangent_frame(n);
    let o = p + n * view.bias;
    var visibility: array<f32, MAX_CONES>;
    for (var k = 0u; k < MAX_CONES; k += 1u) {
        visibility[k] = 1.0;
    }
    var kept_objects = 0u;
    let total = select(0u, view.slot_count, any_surface);
    for (var base = 0u; base < total; base += TILE_PIXELS) {
        let slot = base + li;
        if slot < total {
            let obj = objects[slot];
            if casts_occlusion(obj) {
                let sphere = bounding_sphere(obj, view.camera_tile, view.camera_offset);
                var mask = 0u;
                for (var r = 0u; r < 2u; r += 1u) {
                    if tile_keeps(obj, sphere, balls[r]) {
                        mask |= 1u << r;
                    }
                }
                if mask != 0u {
                    let i = atomicAdd(&tile_count, 1u);
                    tile_slots[i] = slot;
                    tile_spheres[i] = sphere;
                    tile_masks[i] = mask;
                }
            }
        }
        workgroupBarrier();
        if li == 0u {
            tile_n = atomicLoad(&tile_count);
            atomicStore(&tile_count, 0u);
        }
        let kept = workgroupUniformLoad(&tile_n);
        if surface {
            for (var i = 0u; i < kept; i += 1u) {
                let sphere = tile_spheres[i];
                if (tile_masks[i] & (1u << range)) == 0u {
                    continue;
                }
                kept_objects += 1u;
                if !in_reach(sphere, p) {
                    continue;
                }
                let obj = objects[tile_slots[i]];
                for (var k = 0u; k < count; k += 1u) {
                    let a = cone_direction(k, count);
                    let axis = frame[0] * a.x + frame[1] * a.y + n * a.z;
                    visibility[k] = min(visibility[k], march_cone(obj, sphere, p, n, axis, a.z, view, atlas, brick_table));
                }
            }
        }
        workgroupBarrier();
    }
    if surface {
        terrain_cones(&visibility, p, n, frame, count);
    }
    if surface && view.far_distance > view.max_distance {
        for (var k = 0u; k < count; k += 1u) {
            let a = cone_direction(k, count);
            let axis = frame[0] * a.x + frame[1] * a.y + n * a.z;
            visibility[k] = min(visibility[k], far_cone(o, axis, a.z));
        }
    }
    if inside {
        var out = vec4<f32>(1.0, 0.0, 0.0, 0.0);
        if surface {
            out = combine(visibility, count, n);
            if view.tile_objects_debug != 0u {
                out.x = min(f32(kept_objects) / TILE_OBJECTS_SCALE, 1.0);
            }
        }
        textureStore(output, vec2<i32>(gid.xy), out);
    }
}
