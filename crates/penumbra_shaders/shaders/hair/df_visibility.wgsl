// The distance-field visibility of a hair entity's strand points (compute, one thread
// per centre-line point): for each of its distance-field-shadowed lights, the march of
// Penumbra's shadow-mask pass (`penumbra::df::shadow`) from the point toward the light
// through every shadow-casting object whose bounding sphere meets the light's cone.
// Positions are relative to the hair's origin (its tile and offset), as the mask pass's
// are to the camera. No own-shadow term: a strand has no tangent plane. CPU model:
// `penumbra_reference::shadow_mask::pixel_visibility` with a zero normal, per point.
#define_import_path penumbra::hair::df_visibility

#import penumbra::df::object::DistanceFieldObject
#import penumbra::df::shadow::{
    ShadowLight, bounding_sphere, casts_shadows, finish_visibility, march_object,
    object_in_cone, shadow_ray, traces_point,
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

// The light's visibility from origin-relative `p` (the mask pass's, without the
// surface's own shadow).
fn point_visibility(p: vec3<f32>, light: ShadowLight) -> f32 {
    if !traces_point(light, p) {
        return 1.0;
    }
    let ray = shadow_ray(p, light);
    var v = 1.0;
    for (var i = 0u; i < params.object_count; i += 1u) {
        let o = objects[i];
        if !casts_shadows(o) {
            continue;
        }
        let sphere = bounding_sphere(o, params.origin_tile.xyz, params.origin_offset.xyz);
        if object_in_cone(sphere, p, ray) {
            // A hair point has no surface of its own: the light's bias, no self-shadow
            // offset.
            v = min(v, march_object(
                o, sphere, p, ray, light, light.bias, params.origin_tile.xyz,
                params.origin_offset.xyz,
                atlas, brick_table,
            ));
        }
    }
    return finish_visibility(v, light.shaping);
}

// Dispatched in rows of at most 65,535 groups (`penumbra_cinematic_core::dispatch`).
@compute @workgroup_size(64)
fn hair_df_visibility(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
) {
    let i = (group.y * groups.x + group.x) * 64u + local;
    if i >= params.point_count {
        return;
    }
    let p = (params.origin_from_local * vec4(points[i].xyz, 1.0)).xyz;
    var out = vec4(1.0);
    for (var l = 0u; l < min(params.light_count, MAX_HAIR_SHADOW_LIGHTS); l += 1u) {
        out[l] = point_visibility(p, lights[l]);
    }
    shadows.points[i] = out;
}
