// Billboard reflections' caster spheres (`bevy_penumbra_cinematic::reflections`): once
// per frame and view, before the tile cull, each object slot's bounding sphere relative
// to the camera (`penumbra::df::shadow::bounding_sphere`; w −1: unbounded) for the live
// shadow casters, w −2 for every other slot — so that the tile cull and each pixel's
// shadow march test 16 bytes per object, not its record and transform.

#import penumbra::reflections::types::ReflectionUniform
#import penumbra::df::object::{DistanceFieldObject, FLAG_CASTS_SHADOWS, FLAG_LIVE}
#import penumbra::df::shadow::bounding_sphere

@group(0) @binding(0) var<uniform> settings: ReflectionUniform;
@group(0) @binding(1) var<storage, read> objects: array<DistanceFieldObject>;
@group(0) @binding(2) var<storage, read_write> spheres: array<vec4<f32>>;

// A slot that casts no reflection shadow.
const NOT_CASTING: f32 = -2.0;

@compute @workgroup_size(64)
fn spheres_main(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    // Rows of at most 65,535 workgroups.
    let i = id.x + id.y * groups.x * 64u;
    if i >= settings.object_count {
        return;
    }
    let needed = FLAG_LIVE | FLAG_CASTS_SHADOWS;
    var sphere = vec4<f32>(0.0, 0.0, 0.0, NOT_CASTING);
    if (objects[i].flags & needed) == needed {
        sphere = bounding_sphere(objects[i], settings.camera_tile, settings.camera_offset);
    }
    spheres[i] = sphere;
}
