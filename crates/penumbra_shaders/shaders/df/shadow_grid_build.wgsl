// Building the light-space grid (`penumbra::df::shadow_grid`) of a directional light's
// culled casters: `grid_bounds`, `grid_count`, `grid_scan`, `grid_fill`, in that order,
// on a zeroed grid (bounds at their sentinels: `grid_reset`).
#define_import_path penumbra::df::shadow_grid_build

#import penumbra::df::object::DistanceFieldObject
#import penumbra::df::shadow_grid::{
    GRID_CELLS, GRID_SIZE, MAX_CELLS, ShadowGrid, ShadowGridView, cell_range, from_order_key,
    grid_frame, grid_light, light_space_disc, order_key, range_cells,
}
#import penumbra::df::shadow::bounding_sphere
#import penumbra::common::scan::workgroup_exclusive_scan

@group(0) @binding(0) var<storage, read> objects: array<DistanceFieldObject>;
@group(0) @binding(1) var<storage, read> light_objects: array<u32>;
@group(0) @binding(2) var<storage, read> light_object_count: array<u32>;
@group(0) @binding(3) var<uniform> view: ShadowGridView;
@group(0) @binding(4) var<storage, read_write> grid: ShadowGrid;
@group(0) @binding(5) var<storage, read_write> items: array<u32>;
@group(0) @binding(6) var<storage, read_write> large: array<u32>;
@group(0) @binding(7) var<storage, read_write> cursors: array<atomic<u32>, 1024>;

fn frame() -> vec4<f32> {
    let lo = vec2<f32>(from_order_key(atomicLoad(&grid.bounds[0])), from_order_key(atomicLoad(&grid.bounds[1])));
    let hi = vec2<f32>(from_order_key(atomicLoad(&grid.bounds[2])), from_order_key(atomicLoad(&grid.bounds[3])));
    return vec4<f32>(lo, hi);
}

@compute @workgroup_size(1)
fn grid_reset() {
    atomicStore(&grid.bounds[0], 0xffffffffu);
    atomicStore(&grid.bounds[1], 0xffffffffu);
    atomicStore(&grid.bounds[2], 0u);
    atomicStore(&grid.bounds[3], 0u);
    atomicStore(&grid.height, 0u);
}

@compute @workgroup_size(64)
fn grid_bounds(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= light_object_count[0] {
        return;
    }
    let o = objects[light_objects[id.x]];
    let disc = light_space_disc(o, view);
    if disc.z < 0.0 {
        return; // unbounded: always kept, whatever the cone's length
    }
    let s = bounding_sphere(o, view.camera_tile.xyz, view.camera_offset.xyz);
    atomicMax(&grid.height, order_key(dot(s.xyz, grid_light(view)) + disc.z));
    atomicMin(&grid.bounds[0], order_key(disc.x - disc.z));
    atomicMin(&grid.bounds[1], order_key(disc.y - disc.z));
    atomicMax(&grid.bounds[2], order_key(disc.x + disc.z));
    atomicMax(&grid.bounds[3], order_key(disc.y + disc.z));
}

// The caster's cell range, or an empty one when it goes to the large list.
fn classify(slot: u32) -> vec4<i32> {
    let disc = light_space_disc(objects[slot], view);
    let b = frame();
    if disc.z < 0.0 || b.x > b.z {
        return vec4<i32>(1, 1, 0, 0);
    }
    let r = cell_range(grid_frame(b.xy, b.zw), disc.xy, disc.z);
    if range_cells(r) > MAX_CELLS {
        return vec4<i32>(1, 1, 0, 0);
    }
    return r;
}

@compute @workgroup_size(64)
fn grid_count(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= light_object_count[0] {
        return;
    }
    let slot = light_objects[id.x];
    let r = classify(slot);
    if range_cells(r) == 0u {
        large[atomicAdd(&grid.large_count, 1u)] = slot;
        return;
    }
    for (var y = r.y; y <= r.w; y += 1) {
        for (var x = r.x; x <= r.z; x += 1) {
            atomicAdd(&grid.counts[u32(y) * GRID_SIZE + u32(x)], 1u);
        }
    }
}

// Exclusive prefix sums of the 1024 cell counts into `offsets` (one workgroup).
@compute @workgroup_size(256)
fn grid_scan(@builtin(local_invocation_index) li: u32) {
    var local: array<u32, 4>;
    var sum = 0u;
    for (var k = 0u; k < 4u; k += 1u) {
        local[k] = sum;
        sum += atomicLoad(&grid.counts[li * 4u + k]);
    }
    let scan = workgroup_exclusive_scan(li, sum);
    for (var k = 0u; k < 4u; k += 1u) {
        grid.offsets[li * 4u + k] = scan.x + local[k];
    }
    if li == 255u {
        grid.offsets[GRID_CELLS] = scan.y;
        grid.item_count = scan.y;
    }
}

@compute @workgroup_size(64)
fn grid_fill(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= light_object_count[0] {
        return;
    }
    let slot = light_objects[id.x];
    let r = classify(slot);
    for (var y = r.y; y <= r.w; y += 1) {
        for (var x = r.x; x <= r.z; x += 1) {
            let cell = u32(y) * GRID_SIZE + u32(x);
            items[grid.offsets[cell] + atomicAdd(&cursors[cell], 1u)] = slot;
        }
    }
}
