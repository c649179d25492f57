// Scatter bokeh depth of field, between the sprite and scatter passes: the blocks' sprites
// listed layer by layer (`sprite_layer`: near, far, near quarter, far quarter), in block
// order within each layer, with no gaps; each layer's first index in the list and its
// draw's instance count. An exclusive prefix sum of the blocks' counts (a vector of the
// four layers' counts) in three passes over many workgroups
// (`penumbra_cinematic_core::scan`): `reduce_main` sums each group's 1,024 blocks,
// `scan_groups_main` (one workgroup) turns the groups' sums into offsets, `compact_main`
// scans each group's blocks again from its offset and copies their sprites there.
// Deterministic: the order does not depend on which thread runs first, so neither do the
// layers' floating-point sums. CPU model: `penumbra_reference::bokeh::{sprites,
// by_layer}` (the list in the same order); the scan's:
// `penumbra_cinematic_core::scan::exclusive_scan`.
#define_import_path penumbra::dof::compact

#import penumbra::dof::types::{BokehView, DrawArgs, LayerDraws, Sprite, sprite_layer}

@group(0) @binding(0) var<uniform> view: BokehView;
// Each block's sprite count per layer (the sprite pass's).
@group(0) @binding(1) var<storage, read> block_counts: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> slots: array<Sprite>;
@group(0) @binding(3) var<storage, read_write> sprites: array<Sprite>;
@group(0) @binding(4) var<storage, read_write> args: LayerDraws;
// Each group's sums (`reduce_main`), then its first index in each layer
// (`scan_groups_main`).
@group(0) @binding(5) var<storage, read_write> group_sums: array<vec4<u32>>;

const SCAN_THREADS: u32 = 256u;
const ITEMS_PER_THREAD: u32 = 4u;
const GROUP_ITEMS: u32 = SCAN_THREADS * ITEMS_PER_THREAD;

var<workgroup> partial: array<vec4<u32>, SCAN_THREADS>;

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

fn run_sum(run: vec2<u32>) -> vec4<u32> {
    var sum = vec4<u32>(0u);
    for (var b = run.x; b < run.y; b += 1u) {
        sum += block_counts[b];
    }
    return sum;
}

// The workgroup's exclusive scan of the threads' `value`s (Hillis and Steele, in
// `partial`): this thread's offset; `partial[SCAN_THREADS - 1]` then holds the last
// thread's inclusive sum. Called by every thread of the workgroup.
fn workgroup_exclusive_scan(i: u32, value: vec4<u32>) -> vec4<u32> {
    partial[i] = value;
    workgroupBarrier();
    for (var d = 1u; d < SCAN_THREADS; d *= 2u) {
        var add = vec4<u32>(0u);
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
    var sum = vec4<u32>(0u);
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
        // Layer `l` starts after the layers before it; what passes the list's capacity
        // is not drawn.
        let totals = partial[i];
        var first = vec4<u32>(0u);
        for (var l = 1u; l < 4u; l += 1u) {
            first[l] = first[l - 1u] + totals[l - 1u];
        }
        args.first = first;
        for (var l = 0u; l < 4u; l += 1u) {
            let stored = min(first[l] + totals[l], view.capacity) - min(first[l], view.capacity);
            args.draws[l] = DrawArgs(4u, stored, 0u, 0u);
        }
    }
}

// Block `b`'s sprites, in slot order, each at its layer's next index: `offsets` (the
// block's first index within each layer) from the layers' first indices.
fn copy_block(b: u32, offsets: vec4<u32>) {
    var next = args.first + offsets;
    for (var k = 0u; k < 4u; k += 1u) {
        if 4u * b + k >= view.capacity {
            // Not stored by the sprite pass (a buffer too small): its place stays empty.
            return;
        }
        let s = slots[4u * b + k];
        if s.shape.w > 0.0 {
            let l = sprite_layer(view, s);
            if next[l] < view.capacity {
                sprites[next[l]] = s;
            }
            next[l] += 1u;
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
