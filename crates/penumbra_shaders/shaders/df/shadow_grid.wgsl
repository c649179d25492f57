// The light-space grid of a directional light's casters: after the light cull, each
// caster's bounding sphere is projected along the light onto a plane perpendicular to it
// (a disc) and listed in the cells of a 32 × 32 grid it overlaps; casters covering more
// than MAX_CELLS cells, and unbounded ones, go to a separate "large" list. The mask pass
// then gives each 8×8 pixel tile only the casters listed in the cells its own shadow
// disc (its pixels' cones, projected the same way) overlaps, plus the large ones.
//
// Passes, one workgroup size each: `grid_bounds` (the discs' extent), `grid_count`,
// `grid_scan` (one workgroup), `grid_fill`. Culling only: results are those of the full
// list (the contract test compares with the CPU model, which has no grid).
#define_import_path penumbra::df::shadow_grid

#import penumbra::df::object::DistanceFieldObject
#import penumbra::df::shadow::{ShadowLight, bounding_sphere, casts_shadows, cull_slack}

const GRID_SIZE: u32 = 32u;
const GRID_CELLS: u32 = 1024u;
// Casters overlapping more cells than this are listed once, as large.
const MAX_CELLS: u32 = 64u;

struct ShadowGridView {
    camera_tile: vec4<i32>,
    camera_offset: vec4<f32>,
    // Light-space axes: unit, perpendicular to each other and to the light direction.
    u: vec4<f32>,
    v: vec4<f32>,
}

// The light direction of the grid's axes.
fn grid_light(view: ShadowGridView) -> vec3<f32> {
    return cross(view.u.xyz, view.v.xyz);
}

// The grid's state. `bounds`: order keys of min u, min v, max u, max v. `large_count`
// and the large list; per cell: count, then (after the scan) first item; a fill cursor.
struct ShadowGrid {
    bounds: array<atomic<u32>, 4>,
    large_count: atomic<u32>,
    item_count: u32,
    // Order key of the highest point of any bounded caster along the light direction
    // (0: none): the tiles' cones need not reach beyond it (unbounded casters are kept
    // whatever the cone).
    height: atomic<u32>,
    reserved: u32,
    counts: array<atomic<u32>, 1024>,
    offsets: array<u32, 1025>,
}

// `ShadowGrid` as the mask pass reads it (same layout, no atomics).
struct ShadowGridRead {
    bounds: array<u32, 4>,
    large_count: u32,
    item_count: u32,
    height: u32,
    reserved: u32,
    counts: array<u32, 1024>,
    offsets: array<u32, 1025>,
}

// Order-preserving map of f32 to u32 (for atomic min / max).
fn order_key(f: f32) -> u32 {
    let b = bitcast<u32>(f);
    return select(b | 0x80000000u, ~b, (b & 0x80000000u) != 0u);
}

fn from_order_key(k: u32) -> f32 {
    return bitcast<f32>(select(~k, k & 0x7fffffffu, (k & 0x80000000u) != 0u));
}

// A disc in light space: centre (u, v) and radius; radius < 0: unbounded.
fn light_space_disc(o: DistanceFieldObject, view: ShadowGridView) -> vec3<f32> {
    let s = bounding_sphere(o, view.camera_tile.xyz, view.camera_offset.xyz);
    if s.w < 0.0 {
        return vec3<f32>(0.0, 0.0, -1.0);
    }
    return vec3<f32>(dot(s.xyz, view.u.xyz), dot(s.xyz, view.v.xyz), s.w + cull_slack(s.w));
}

struct GridFrame {
    origin: vec2<f32>,
    cell: vec2<f32>,
}

// The grid's placement from its bounds (cells at least 1 mm).
fn grid_frame(lo: vec2<f32>, hi: vec2<f32>) -> GridFrame {
    let extent = max(hi - lo, vec2<f32>(1e-3 * f32(GRID_SIZE)));
    return GridFrame(lo, extent / f32(GRID_SIZE));
}

// The inclusive cell range a disc overlaps (x0, y0, x1, y1), clamped to the grid; empty
// (x0 > x1) when it misses it.
fn cell_range(frame: GridFrame, center: vec2<f32>, radius: f32) -> vec4<i32> {
    let lo = floor((center - radius - frame.origin) / frame.cell);
    let hi = floor((center + radius - frame.origin) / frame.cell);
    let last = f32(GRID_SIZE - 1u);
    if any(hi < vec2<f32>(0.0)) || any(lo > vec2<f32>(last)) || any(lo != lo) || any(hi != hi) {
        return vec4<i32>(1, 1, 0, 0);
    }
    let a = vec2<i32>(clamp(lo, vec2<f32>(0.0), vec2<f32>(last)));
    let b = vec2<i32>(clamp(hi, vec2<f32>(0.0), vec2<f32>(last)));
    return vec4<i32>(a, b);
}

fn range_cells(r: vec4<i32>) -> u32 {
    if r.x > r.z || r.y > r.w {
        return 0u;
    }
    return u32(r.z - r.x + 1) * u32(r.w - r.y + 1);
}
