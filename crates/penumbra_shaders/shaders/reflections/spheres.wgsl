// Billboard reflections' caster spheres and grid (`bevy_penumbra_cinematic::reflections`):
// once per frame and view, before the tile cull, each object slot's bounding sphere
// relative to the camera (`penumbra::df::shadow::bounding_sphere`; w −1: unbounded) for
// the live shadow casters, w −2 for every other slot — so that the tile cull and each
// pixel's shadow march test 16 bytes per object, not its record and transform.
//
// With a caster grid (`settings.caster_grid` ≠ 0: more casters than a tile's list
// holds), a counting sort of the spheres' centres into it follows, on a list buffer
// whose header and counts are zero: `spheres_main` (the spheres and their centres'
// box), `grid_count`, `grid_scan` (one workgroup), `grid_fill`. Model:
// `penumbra_cinematic_core::reflections::grid::CasterGrid`.

#import penumbra::reflections::types::{
    GRID_CELLS, GRID_FRAME_CELL, GRID_FRAME_DIMS, GRID_FRAME_LO, GRID_HI_KEYS,
    GRID_LARGE_COUNT, GRID_LO_KEYS, GRID_MAX_RADIUS, GridFrame, ReflectionUniform, grid_cell,
    grid_counts, grid_frame, grid_items, grid_large, grid_offsets,
}
#import penumbra::df::object::{DistanceFieldObject, FLAG_CASTS_SHADOWS, FLAG_LIVE}
#import penumbra::df::shadow::bounding_sphere
#import penumbra::df::shadow_grid::{from_order_key, order_key}
#import penumbra::common::scan::workgroup_exclusive_scan

@group(0) @binding(0) var<uniform> settings: ReflectionUniform;
@group(0) @binding(1) var<storage, read> objects: array<DistanceFieldObject>;
@group(0) @binding(2) var<storage, read_write> spheres: array<vec4<f32>>;
// The view's tile lists, the caster grid after them (`settings.caster_grid`).
@group(0) @binding(3) var<storage, read_write> lists: array<atomic<u32>>;

// A slot that casts no reflection shadow.
const NOT_CASTING: f32 = -2.0;

// Rows of at most 65,535 workgroups of 64.
fn slot_index(id: vec3<u32>, groups: vec3<u32>) -> u32 {
    return id.x + id.y * groups.x * 64u;
}

@compute @workgroup_size(64)
fn spheres_main(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let i = slot_index(id, groups);
    if i >= settings.object_count {
        return;
    }
    let needed = FLAG_LIVE | FLAG_CASTS_SHADOWS;
    var sphere = vec4<f32>(0.0, 0.0, 0.0, NOT_CASTING);
    if (objects[i].flags & needed) == needed {
        sphere = bounding_sphere(objects[i], settings.camera_tile, settings.camera_offset);
    }
    spheres[i] = sphere;
    if settings.caster_grid != 0u && sphere.w >= 0.0 {
        grow_bounds(sphere.xyz);
    }
}

// The centres' box: the lowest corner as inverted order keys, so that both corners
// grow from the zeroed header with atomicMax.
fn grow_bounds(c: vec3<f32>) {
    let g = settings.caster_grid;
    for (var k = 0u; k < 3u; k += 1u) {
        atomicMax(&lists[g + GRID_LO_KEYS + k], ~order_key(c[k]));
        atomicMax(&lists[g + GRID_HI_KEYS + k], order_key(c[k]));
    }
}

// The grid's frame from its box; no cells while no bounded caster grew it.
fn frame_from_keys() -> GridFrame {
    let g = settings.caster_grid;
    var lo: vec3<f32>;
    var hi: vec3<f32>;
    for (var k = 0u; k < 3u; k += 1u) {
        lo[k] = from_order_key(~atomicLoad(&lists[g + GRID_LO_KEYS + k]));
        hi[k] = from_order_key(atomicLoad(&lists[g + GRID_HI_KEYS + k]));
    }
    var f = grid_frame(lo, hi);
    if atomicLoad(&lists[g + GRID_LO_KEYS]) == 0u {
        f.dims = vec3(0u);
    }
    return f;
}

// Whether a caster is listed in a cell (else large: unbounded, or wider than a cell).
fn listed(sphere: vec4<f32>, f: GridFrame) -> bool {
    return sphere.w >= 0.0 && sphere.w <= f.cell && f.dims.x > 0u;
}

// Invocation `id`'s caster: its slot, sphere and the grid's frame; `valid` false past
// the slots and for slots that cast no shadow.
struct GridSlot {
    index: u32,
    sphere: vec4<f32>,
    frame: GridFrame,
    valid: bool,
}

fn grid_slot(id: vec3<u32>, groups: vec3<u32>) -> GridSlot {
    var s: GridSlot;
    s.index = slot_index(id, groups);
    s.valid = s.index < settings.object_count;
    if s.valid {
        s.sphere = spheres[s.index];
        s.valid = s.sphere.w >= -1.5;
        s.frame = frame_from_keys();
    }
    return s;
}

@compute @workgroup_size(64)
fn grid_count(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let s = grid_slot(id, groups);
    if !s.valid {
        return;
    }
    let g = settings.caster_grid;
    if listed(s.sphere, s.frame) {
        atomicAdd(&lists[grid_counts(g) + grid_cell(s.frame, s.sphere.xyz)], 1u);
        atomicMax(&lists[g + GRID_MAX_RADIUS], bitcast<u32>(s.sphere.w));
    } else {
        let at = atomicAdd(&lists[g + GRID_LARGE_COUNT], 1u);
        atomicStore(&lists[grid_large(g, settings.object_count) + at], s.index);
    }
}

// The scan's 256 threads each sum a run of cells.
const CELLS_PER_THREAD: u32 = GRID_CELLS / 256u;

// Exclusive prefix sums of the cells' counts into their offsets, the counts zeroed
// (the fill's cursors), and the frame written for the trace (one workgroup).
@compute @workgroup_size(256)
fn grid_scan(@builtin(local_invocation_index) li: u32) {
    let g = settings.caster_grid;
    let first = li * CELLS_PER_THREAD;
    var sum = 0u;
    for (var k = 0u; k < CELLS_PER_THREAD; k += 1u) {
        sum += atomicLoad(&lists[grid_counts(g) + first + k]);
    }
    let scan = workgroup_exclusive_scan(li, sum);
    var at = scan.x;
    for (var k = 0u; k < CELLS_PER_THREAD; k += 1u) {
        let cell = first + k;
        atomicStore(&lists[grid_offsets(g) + cell], at);
        at += atomicExchange(&lists[grid_counts(g) + cell], 0u);
    }
    if li == 255u {
        atomicStore(&lists[grid_offsets(g) + GRID_CELLS], scan.y);
        let f = frame_from_keys();
        for (var k = 0u; k < 3u; k += 1u) {
            atomicStore(&lists[g + GRID_FRAME_LO + k], bitcast<u32>(f.lo[k]));
            atomicStore(&lists[g + GRID_FRAME_DIMS + k], f.dims[k]);
        }
        atomicStore(&lists[g + GRID_FRAME_CELL], bitcast<u32>(f.cell));
    }
}

@compute @workgroup_size(64)
fn grid_fill(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let s = grid_slot(id, groups);
    if !s.valid || !listed(s.sphere, s.frame) {
        return;
    }
    let g = settings.caster_grid;
    let cell = grid_cell(s.frame, s.sphere.xyz);
    let at = atomicLoad(&lists[grid_offsets(g) + cell]) + atomicAdd(&lists[grid_counts(g) + cell], 1u);
    atomicStore(&lists[grid_items(g) + at], s.index);
}
