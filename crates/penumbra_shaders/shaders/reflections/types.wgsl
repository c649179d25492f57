// Billboard reflections' structs shared with the Rust encoders, and the caster grid's
// layout (no bindings): used by `reflections/common.wgsl` and the caster spheres' and
// grid's passes (`reflections/spheres.wgsl`).
#define_import_path penumbra::reflections::types

// `penumbra_cinematic_core::reflections::pass::GpuBillboard`.
struct GpuBillboard {
    center: vec3<f32>,
    layer: u32,
    half_x: vec3<f32>,
    emissive: f32,
    half_y: vec3<f32>,
    // Render-layer groups (`GpuBillboard::layers`): a view reflects it where they meet
    // `ReflectionUniform::view_layers`.
    layers: u32,
}

// `penumbra_cinematic_core::reflections::pass::ReflectionUniform`.
struct ReflectionUniform {
    billboard_count: u32,
    max_layers: u32,
    max_distance: f32,
    anisotropy: f32,
    texture_size: vec2<u32>,
    mip_count: u32,
    half_resolution: u32,
    camera_tile: vec3<i32>,
    object_count: u32,
    camera_offset: vec3<f32>,
    footprint_slope: f32,
    shadow_steps: u32,
    shadow_bias: f32,
    shadow_softness: f32,
    taps: u32,
    // Tiles per row of the trace's image; billboards a tile's list holds (0: no lists,
    // the trace tests every billboard).
    tiles_x: u32,
    tile_capacity: u32,
    // The trace's image size, pixels.
    trace_size: vec2<u32>,
    // The shadow cone's half-width as a share of the footprint's long half-axis.
    shadow_cone: f32,
    // Shadow casters a tile's list holds (0: no caster lists).
    caster_capacity: u32,
    // The render-layer groups the view sees.
    view_layers: u32,
    // Where the caster grid starts in the view's list buffer, words (0: no grid).
    caster_grid: u32,
}

// The caster grid (`penumbra_cinematic_core::reflections::grid`): a loose uniform grid
// of the shadow casters' bounding-sphere centres in the view's list buffer, from word
// `caster_grid`: a header, GRID_CELLS counts, GRID_CELLS + 1 offsets, one item per
// listed caster, one per large one (`grid::grid_words`).
const GRID_DIM: u32 = 32u;
const GRID_CELLS: u32 = 32768u;
const GRID_HEADER: u32 = 16u;
// A tile listing more casters than this gathers from the grid (`grid::GRID_OVER_LIST`).
const GRID_OVER_LIST: u32 = 64u;
// Header words: order keys of the centres' box (lowest corner inverted, so that both
// grow from zero), the largest listed radius's bits, the large casters' count, and the
// frame the scan resolves from them for the trace.
const GRID_LO_KEYS: u32 = 0u;
const GRID_HI_KEYS: u32 = 3u;
const GRID_MAX_RADIUS: u32 = 6u;
const GRID_LARGE_COUNT: u32 = 7u;
const GRID_FRAME_LO: u32 = 8u;
const GRID_FRAME_CELL: u32 = 11u;
const GRID_FRAME_DIMS: u32 = 12u;

struct GridFrame {
    lo: vec3<f32>,
    cell: f32,
    // Cells per axis (zero: no listed caster).
    dims: vec3<u32>,
}

// The frame of the centres' box `lo`–`hi` (`grid::grid_frame`, same arithmetic).
fn grid_frame(lo: vec3<f32>, hi: vec3<f32>) -> GridFrame {
    let extent = max(hi - lo, vec3(0.0));
    let cell = max(max(extent.x, max(extent.y, extent.z)) / f32(GRID_DIM), 1e-4);
    // At most GRID_DIM cells (a NaN box, which no live caster gives: one), never zero.
    let q = extent / cell;
    let cells = select(vec3(0.0), min(q, vec3(f32(GRID_DIM - 1u))), q == q);
    return GridFrame(lo, cell, vec3<u32>(cells) + 1u);
}

// The cell holding camera-relative point `p`, clamped into the grid.
fn grid_cell(f: GridFrame, p: vec3<f32>) -> u32 {
    let c = min(vec3<u32>(max((p - f.lo) / f.cell, vec3(0.0))), f.dims - 1u);
    return (c.z * f.dims.y + c.y) * f.dims.x + c.x;
}

// Where the grid's parts start in the list buffer (`slots`: the object slots marched).
fn grid_counts(base: u32) -> u32 {
    return base + GRID_HEADER;
}

fn grid_offsets(base: u32) -> u32 {
    return base + GRID_HEADER + GRID_CELLS;
}

fn grid_items(base: u32) -> u32 {
    return base + GRID_HEADER + 2u * GRID_CELLS + 1u;
}

fn grid_large(base: u32, slots: u32) -> u32 {
    return grid_items(base) + slots;
}
