// A one-workgroup prefix sum over 256 threads (Hillis and Steele), for the counting
// sorts of culling grids (`df/shadow_grid_build.wgsl`, `reflections/spheres.wgsl`):
// each thread sums a run of cells, the workgroup scans the runs' sums.
#define_import_path penumbra::common::scan

const SCAN_THREADS: u32 = 256u;

var<workgroup> scan_partial: array<u32, 256>;

// Thread `li`'s exclusive prefix of the workgroup's `value`s (x) and their total (y).
// Every thread of a 256-thread workgroup calls it, in uniform control flow.
fn workgroup_exclusive_scan(li: u32, value: u32) -> vec2<u32> {
    scan_partial[li] = value;
    workgroupBarrier();
    for (var step = 1u; step < SCAN_THREADS; step *= 2u) {
        var add = 0u;
        if li >= step {
            add = scan_partial[li - step];
        }
        workgroupBarrier();
        scan_partial[li] += add;
        workgroupBarrier();
    }
    let inclusive = scan_partial[li];
    let total = scan_partial[SCAN_THREADS - 1u];
    return vec2(inclusive - value, total);
}
