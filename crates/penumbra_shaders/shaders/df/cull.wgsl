// Frustum culling of the object buffer into a compact list of slots, a count, and
// indirect dispatch arguments (one 64-wide workgroup per 64 survivors) for the passes
// that walk the list. The CPU reference is `penumbra_df_core::cull`.
#define_import_path penumbra::df::cull

#import penumbra::df::object::{
    DistanceFieldObject, FLAG_LIVE, FLAG_UNBOUNDED, FLAG_VISIBLE, camera_relative,
    rows_column, shape_bounds, transform_rows,
}

struct CullView {
    // Planes n · p + w ≥ 0 in camera-relative world space (unit n).
    planes: array<vec4<f32>, 6>,
    camera_tile: vec4<i32>,
    // xyz: camera position within its tile.
    camera_offset: vec4<f32>,
    object_count: u32,
    groups_x: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<storage, read> objects: array<DistanceFieldObject>;
@group(0) @binding(1) var<uniform> view: CullView;
@group(0) @binding(2) var<storage, read_write> culled: array<u32>;
@group(0) @binding(3) var<storage, read_write> culled_count: atomic<u32>;
// x, y, z workgroup counts for `dispatch_workgroups_indirect`.
@group(0) @binding(4) var<storage, read_write> indirect: array<u32, 3>;

fn is_visible(o: DistanceFieldObject) -> bool {
    if (o.flags & FLAG_LIVE) == 0u || (o.flags & FLAG_VISIBLE) == 0u {
        return false;
    }
    let b = shape_bounds(o);
    if !b.bounded {
        return (o.flags & FLAG_UNBOUNDED) != 0u;
    }
    let half = (b.max - b.min) * 0.5;
    let center_tile = transform_rows(o.world_from_shape, (b.min + b.max) * 0.5);
    let center = camera_relative(o.tile, center_tile, view.camera_tile.xyz, view.camera_offset.xyz);
    let ax = rows_column(o.world_from_shape, 0u) * half.x;
    let ay = rows_column(o.world_from_shape, 1u) * half.y;
    let az = rows_column(o.world_from_shape, 2u) * half.z;
    for (var i = 0u; i < 6u; i += 1u) {
        let p = view.planes[i];
        let radius = abs(dot(p.xyz, ax)) + abs(dot(p.xyz, ay)) + abs(dot(p.xyz, az));
        if dot(p.xyz, center) + p.w < -radius {
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
    if is_visible(objects[i]) {
        culled[atomicAdd(&culled_count, 1u)] = i;
    }
}

@compute @workgroup_size(1)
fn write_indirect() {
    let count = atomicLoad(&culled_count);
    indirect[0] = (count + 63u) / 64u;
    indirect[1] = 1u;
    indirect[2] = 1u;
}
