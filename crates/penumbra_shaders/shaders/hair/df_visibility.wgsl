// The distance-field visibility of a hair entity's strand points (compute, one thread
// per centre-line point): for each of its distance-field-shadowed lights, the march of
// Penumbra's shadow-mask pass (`penumbra::df::shadow`) from the point toward the light
// through every shadow-casting object whose bounding sphere meets the light's cone.
// Each workgroup goes through the object slots GROUP_CASTERS at a time: together its
// threads list those that can meet the cone of any of its 64 points (`group_in_cone`: a
// superset of each point's `object_in_cone`), with their bounding spheres, and each
// point marches those of them in its own cone — 1/64 of the slots' bounding spheres per
// thread. The same objects, so the same visibility (a minimum: order-free).
// Positions are relative to the hair's origin (its tile and offset), as the mask pass's
// are to the camera. No own-shadow term: a strand has no tangent plane. CPU model:
// `penumbra_reference::shadow_mask::pixel_visibility` with a zero normal, per point.
#define_import_path penumbra::hair::df_visibility

#import penumbra::df::object::DistanceFieldObject
#import penumbra::df::shadow::{
    ShadowLight, ShadowRay, bounding_sphere, casts_shadows, cull_slack, finish_visibility,
    is_directional, march_object, object_in_cone, round_cone_distance, shadow_ray,
    traces_point,
}
#import penumbra::hair::shadows::{HairShadows, MAX_HAIR_SHADOW_LIGHTS}

struct HairShadowParams {
    // Origin-relative world from hair space (the entity's transform, translation taken
    // relative to the origin).
    origin_from_local: mat4x4<f32>,
    // xyz: the origin's tile; w: unused.
    origin_tile: vec4<i32>,
    // xyz: the origin within its tile.
    origin_offset: vec4<f32>,
    point_count: u32,
    light_count: u32,
    // Slots of the object buffer to consider.
    object_count: u32,
    reserved: u32,
}

@group(0) @binding(0) var<storage, read> objects: array<DistanceFieldObject>;
@group(0) @binding(1) var atlas: texture_3d<f32>;
@group(0) @binding(6) var brick_table: texture_2d<u32>;
// The centre-line points, hair space (xyz).
@group(0) @binding(2) var<storage, read> points: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> shadows: HairShadows;
@group(0) @binding(4) var<uniform> params: HairShadowParams;
@group(0) @binding(5) var<uniform> lights: array<ShadowLight, 4>;

// Threads (points) per workgroup.
const GROUP: u32 = 64u;
// Object slots a workgroup lists from at a time (so its list never overflows).
const GROUP_CASTERS: u32 = 128u;

// The workgroup's points (w: 1 for a point, 0 past the last).
var<workgroup> group_points: array<vec4<f32>, 64>;
// This light's list from the current slots: how many, their slots and origin-relative
// bounding spheres.
var<workgroup> group_count: atomic<u32>;
var<workgroup> group_slots: array<u32, 128>;
var<workgroup> group_spheres: array<vec4<f32>, 128>;

// A sphere (centre, radius) around the workgroup's points; w < 0: it has none.
fn group_bounds() -> vec4<f32> {
    var lo = vec3(3.4e38);
    var hi = vec3(-3.4e38);
    var any = false;
    for (var k = 0u; k < GROUP; k += 1u) {
        let q = group_points[k];
        if q.w > 0.0 {
            lo = min(lo, q.xyz);
            hi = max(hi, q.xyz);
            any = true;
        }
    }
    if !any {
        return vec4(0.0, 0.0, 0.0, -1.0);
    }
    return vec4((lo + hi) * 0.5, length(hi - lo) * 0.5);
}

// Whether the object (bounding sphere `sphere`) can meet the cone toward `light` of some
// point within `bounds` (`object_in_cone` there). Toward a directional light each
// point's cone is the centre's moved by at most the bounds' radius: the centre's cone
// widened by it holds them all. Toward a point or spot light, a point's cone ends on a
// disc of radius at most the light's source radius, centred that far from the light
// (`shadow_ray`): the convex hull of the bounds and the light's ball widened √2 (1.5
// here) holds them all.
fn group_in_cone(sphere: vec4<f32>, bounds: vec4<f32>, light: ShadowLight) -> bool {
    if sphere.w < 0.0 {
        return true;
    }
    var end = light.position_or_direction.xyz;
    var end_radius = 1.5 * light.source;
    if is_directional(light) {
        let ray = shadow_ray(bounds.xyz, light);
        end = bounds.xyz + ray.dir * ray.t_max;
        end_radius = bounds.w + ray.t_max * ray.tan_half;
    }
    // Rounding never drops an object: the points' test has its own errors.
    let margin = 1e-3 * (1.0 + bounds.w) + 1e-5 * length(end - bounds.xyz);
    return round_cone_distance(sphere.xyz, bounds.xyz, end, bounds.w, end_radius)
        < sphere.w + cull_slack(sphere.w) + margin;
}

// Lists, for the workgroup, the objects of slots `base` to `base + GROUP_CASTERS` that
// can meet this light's cone (every thread, uniform control flow); returns how many.
fn list_group_casters(local: u32, bounds: vec4<f32>, light: ShadowLight, base: u32) -> u32 {
    if local == 0u {
        atomicStore(&group_count, 0u);
    }
    workgroupBarrier();
    let end = min(base + GROUP_CASTERS, params.object_count);
    if bounds.w >= 0.0 {
        for (var m = base + local; m < end; m += GROUP) {
            let o = objects[m];
            if !casts_shadows(o) {
                continue;
            }
            let sphere = bounding_sphere(o, params.origin_tile.xyz, params.origin_offset.xyz);
            if group_in_cone(sphere, bounds, light) {
                let at = atomicAdd(&group_count, 1u);
                group_slots[at] = m;
                group_spheres[at] = sphere;
            }
        }
    }
    workgroupBarrier();
    return atomicLoad(&group_count);
}

// The running minimum `v` of the light's visibility from origin-relative `p` (the mask
// pass's, without the surface's own shadow) over the workgroup's `listed` objects.
fn march_listed(p: vec3<f32>, ray: ShadowRay, light: ShadowLight, listed: u32, v: f32) -> f32 {
    var out = v;
    for (var k = 0u; k < listed; k += 1u) {
        let sphere = group_spheres[k];
        if object_in_cone(sphere, p, ray) {
            // A hair point has no surface of its own: the light's bias, no self-shadow
            // offset.
            out = min(out, march_object(
                objects[group_slots[k]], sphere, p, ray, light, light.bias,
                params.origin_tile.xyz, params.origin_offset.xyz,
                atlas, brick_table,
            ));
        }
    }
    return out;
}

// Dispatched in rows of at most 65,535 groups (`penumbra_cinematic_core::dispatch`).
@compute @workgroup_size(64)
fn hair_df_visibility(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
) {
    let i = (group.y * groups.x + group.x) * GROUP + local;
    let valid = i < params.point_count;
    var p = vec3(0.0);
    if valid {
        p = (params.origin_from_local * vec4(points[i].xyz, 1.0)).xyz;
    }
    group_points[local] = vec4(p, select(0.0, 1.0, valid));
    workgroupBarrier();
    let bounds = group_bounds();
    var out = vec4(1.0);
    for (var l = 0u; l < min(params.light_count, MAX_HAIR_SHADOW_LIGHTS); l += 1u) {
        let light = lights[l];
        let traced = valid && traces_point(light, p);
        let ray = shadow_ray(p, light);
        var v = 1.0;
        // The slots GROUP_CASTERS at a time: a list never overflows.
        for (var base = 0u; base < params.object_count; base += GROUP_CASTERS) {
            let listed = list_group_casters(local, bounds, light, base);
            if traced {
                v = march_listed(p, ray, light, listed, v);
            }
            // The next chunk's list overwrites this one.
            workgroupBarrier();
        }
        if traced {
            out[l] = finish_visibility(v, light.shaping);
        }
    }
    if valid {
        shadows.points[i] = out;
    }
}
