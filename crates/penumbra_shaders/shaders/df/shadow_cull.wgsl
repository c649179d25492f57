// Light-level culling for distance-field shadows: the objects that can shadow some
// pixel of the view for one light, compacted into a list with a count. Positional
// lights keep objects within the light's range (plus the object's and the source's
// radius); directional lights keep objects whose sphere, swept back along the light
// direction by the ray length (widened by the cone), meets the view frustum.
// Conservative: the mask pass never needs a culled-away object.
#define_import_path penumbra::df::shadow_cull

#import penumbra::df::object::DistanceFieldObject
#import penumbra::df::shadow::{ShadowLight, bounding_sphere, casts_shadows, cull_slack, is_directional}

struct ShadowCullView {
    // Planes n · p + w ≥ 0 in camera-relative world space (unit n).
    planes: array<vec4<f32>, 6>,
    camera_tile: vec4<i32>,
    camera_offset: vec4<f32>,
    object_count: u32,
    groups_x: u32,
    reserved: vec2<u32>,
}

@group(0) @binding(0) var<storage, read> objects: array<DistanceFieldObject>;
@group(0) @binding(1) var<uniform> view: ShadowCullView;
@group(0) @binding(2) var<uniform> light: ShadowLight;
@group(0) @binding(3) var<storage, read_write> culled: array<u32>;
@group(0) @binding(4) var<storage, read_write> culled_count: atomic<u32>;

fn may_shadow_view(o: DistanceFieldObject) -> bool {
    if !casts_shadows(o) {
        return false;
    }
    let s = bounding_sphere(o, view.camera_tile.xyz, view.camera_offset.xyz);
    if s.w < 0.0 {
        return true;
    }
    if !is_directional(light) {
        let reach = light.range + s.w + 2.0 * light.source + cull_slack(s.w);
        return length(s.xyz - light.position_or_direction.xyz) < reach;
    }
    let back = -light.position_or_direction.xyz * light.max_distance;
    let radius = s.w + light.max_distance * light.source + cull_slack(s.w);
    // A pixel p it shadows lies within `radius` of the segment from the centre along `back`,
    // and |p| ≤ max_view_distance: that segment must come that close to the camera.
    let h = clamp(-dot(s.xyz, back) / max(dot(back, back), 1e-30), 0.0, 1.0);
    if length(s.xyz + back * h) > light.max_view_distance + radius {
        return false;
    }
    for (var i = 0u; i < 6u; i += 1u) {
        let plane = view.planes[i];
        let near = max(dot(plane.xyz, s.xyz), dot(plane.xyz, s.xyz + back)) + plane.w;
        if near < -radius {
            return false;
        }
    }
    return true;
}

@compute @workgroup_size(64)
fn cull(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x + id.y * view.groups_x * 64u;
    if i >= view.object_count {
        return;
    }
    if may_shadow_view(objects[i]) {
        culled[atomicAdd(&culled_count, 1u)] = i;
    }
}
