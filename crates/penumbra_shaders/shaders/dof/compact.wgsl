// Scatter bokeh depth of field, between the sprite and scatter passes: the blocks' sprites
// listed in block order, with no gaps, and the draw's instance count. An exclusive prefix
// sum of the blocks' counts in three passes over many workgroups
// (`penumbra_cinematic_core::scan`): `reduce_main` sums each group's 1,024 blocks,
// `scan_groups_main` (one workgroup) turns the groups' sums into offsets, `compact_main`
// scans each group's blocks again from its offset and copies their sprites there.
// Deterministic: the order does not depend on which thread runs first, so neither do the
// layers' floating-point sums. CPU model: `penumbra_reference::bokeh::sprites` (the list
// in the same order); the scan's: `penumbra_cinematic_core::scan::exclusive_scan`.
#define_import_path penumbra::dof::compact

#import penumbra::dof::types::{BokehView, Sprite}

// `draw_indirect`'s arguments.
struct DrawArgs {
    vertex_count: u32,
    instance_count: u32,
    first_vertex: u32,
    first_instance: u32,
}

@group(0) @binding(0) var<uniform> view: BokehView;
// Each block's sprite count (the sprite pass's).
@group(0) @binding(1) var<storage, read> block_counts: array<u32>;
@group(0) @binding(2) var<storage, read> slots: array<Sprite>;
@group(0) @binding(3) var<storage, read_write> sprites: array<Sprite>;
@group(0) @binding(4) var<storage, read_write> args: DrawArgs;
// Each group's sum (`reduce_main`), then its first index in the list (`scan_groups_main`).
@group(0) @binding(5) var<storage, read_write> group_sums: array<u32>;

const SCAN_THREADS: u32 = 256u;
const ITEMS_PER_THREAD: u32 = 4u;
const GROUP_ITEMS: u32 = SCAN_THREADS * ITEMS_PER_THREAD;

var<workgroup> partial: array<u32, SCAN_THREADS>;

// Blocks of the half-resolution image (2×2 pixels each).
fn block_total() -> u32 {
    let blocks = (view.half_size + vec2<u32>(1u)) / 2u;
    return blocks.x * blocks.y;
}

// Thread `i` of group `g`'s blocks (reduce and place passes).
fn thread_blocks(g: u32, i: u32) -> vec2<u32> {
    let n = block_total();
    let first = min(g * GROUP_ITEMS + i * ITEMS_PER_THREAD, n);
    return vec2(first, min(first + ITEMS_PER_THREAD, n));
}

fn run_sum(run: vec2<u32>) -> u32 {
    var sum = 0u;
    for (var b = run.x; b < run.y; b += 1u) {
        sum += block_counts[b];
    }
    return sum;
}

// The workgroup's exclusive scan of the threads' `value`s (Hillis and Steele, in
// `partial`): this thread's offset; `partial[SCAN_THREADS - 1]` then holds the last
// thread's inclusive sum. Called by every thread of the workgroup.
fn workgroup_exclusive_scan(i: u32, value: u32) -> u32 {
    partial[i] = value;
    workgroupBarrier();
    for (var d = 1u; d < SCAN_THREADS; d *= 2u) {
        var add = 0u;
        if i >= d {
            add = partial[i - d];
        }
        workgroupBarrier();
        partial[i] += add;
        workgroupBarrier();
    }
    return partial[i] - value;
}

// Pass 1, one workgroup per 1,024 blocks: the group's sum.
@compute @workgroup_size(SCAN_THREADS, 1, 1)
fn reduce_main(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(local_invocation_index) i: u32,
) {
    let sum = run_sum(thread_blocks(group.x, i));
    workgroup_exclusive_scan(i, sum);
    if i == SCAN_THREADS - 1u {
        group_sums[group.x] = partial[i];
    }
}

// Pass 2, one workgroup: each group's sum becomes its first offset; the draw's count.
@compute @workgroup_size(SCAN_THREADS, 1, 1)
fn scan_groups_main(@builtin(local_invocation_index) i: u32) {
    let groups = (block_total() + GROUP_ITEMS - 1u) / GROUP_ITEMS;
    let run = (groups + SCAN_THREADS - 1u) / SCAN_THREADS;
    let first = min(i * run, groups);
    let end = min(first + run, groups);
    var sum = 0u;
    for (var g = first; g < end; g += 1u) {
        sum += group_sums[g];
    }
    var offset = workgroup_exclusive_scan(i, sum);
    for (var g = first; g < end; g += 1u) {
        let c = group_sums[g];
        group_sums[g] = offset;
        offset += c;
    }
    if i == SCAN_THREADS - 1u {
        args = DrawArgs(6u, min(partial[i], view.capacity), 0u, 0u);
    }
}

// Block `b`'s sprites, in slot order, from `first` on.
fn copy_block(b: u32, first: u32) {
    var j = first;
    for (var k = 0u; k < 4u; k += 1u) {
        if 4u * b + k >= view.capacity {
            // Not stored by the sprite pass (a buffer too small): its place stays empty.
            return;
        }
        let s = slots[4u * b + k];
        if s.shape.w > 0.0 {
            if j < view.capacity {
                sprites[j] = s;
            }
            j += 1u;
        }
    }
}

// Pass 3, the reduce's workgroups: each thread's blocks, from its group's offset plus the
// workgroup's scan.
@compute @workgroup_size(SCAN_THREADS, 1, 1)
fn compact_main(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(local_invocation_index) i: u32,
) {
    let run = thread_blocks(group.x, i);
    var offset = group_sums[group.x] + workgroup_exclusive_scan(i, run_sum(run));
    for (var b = run.x; b < run.y; b += 1u) {
        copy_block(b, offset);
        offset += block_counts[b];
    }
}
