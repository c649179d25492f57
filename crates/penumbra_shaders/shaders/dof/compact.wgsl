// Scatter bokeh depth of field, between the sprite and scatter passes: the blocks' sprites
// listed in block order, with no gaps — an exclusive prefix sum of the blocks' counts
// (`scan_main`, one workgroup), then each block copies its sprites to its offset
// (`compact_main`) — and the draw's instance count. Deterministic: the order does not
// depend on which thread runs first, so neither do the layers' floating-point sums. CPU
// model: `penumbra_reference::bokeh::sprites` (the list in the same order).
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
// In: each block's sprite count; out (`scan_main`): its first index in the list.
@group(0) @binding(1) var<storage, read_write> block_counts: array<u32>;
@group(0) @binding(2) var<storage, read> slots: array<Sprite>;
@group(0) @binding(3) var<storage, read_write> sprites: array<Sprite>;
@group(0) @binding(4) var<storage, read_write> args: DrawArgs;

const SCAN_THREADS: u32 = 256u;

var<workgroup> partial: array<u32, 256>;

// Blocks of the half-resolution image (2×2 pixels each).
fn block_total() -> u32 {
    let blocks = (view.half_size + vec2<u32>(1u)) / 2u;
    return blocks.x * blocks.y;
}

// Each thread sums a run of blocks; the runs' sums are scanned; each thread rewrites its
// run's counts as offsets.
@compute @workgroup_size(256, 1, 1)
fn scan_main(@builtin(local_invocation_index) i: u32) {
    let n = block_total();
    let run = (n + SCAN_THREADS - 1u) / SCAN_THREADS;
    let start = min(i * run, n);
    let end = min(start + run, n);
    var sum = 0u;
    for (var b = start; b < end; b += 1u) {
        sum += block_counts[b];
    }
    partial[i] = sum;
    workgroupBarrier();
    if i == 0u {
        var total = 0u;
        for (var k = 0u; k < SCAN_THREADS; k += 1u) {
            let c = partial[k];
            partial[k] = total;
            total += c;
        }
        args = DrawArgs(6u, min(total, view.capacity), 0u, 0u);
    }
    workgroupBarrier();
    var offset = partial[i];
    for (var b = start; b < end; b += 1u) {
        let c = block_counts[b];
        block_counts[b] = offset;
        offset += c;
    }
}

// One thread per block: its sprites, in slot order, from its offset on.
@compute @workgroup_size(64, 1, 1)
fn compact_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let b = gid.x;
    if b >= block_total() {
        return;
    }
    var j = block_counts[b];
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
