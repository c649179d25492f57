// Heightfields (terrain) as distance-field casters: a record per terrain and an
// `R32Float` texture of heights and per-tile slope bounds, read with exact loads. The
// distance is a conservative lower bound (the vertical gap over the local slope bound,
// capped by a slope tile's reach, never below the gap over the terrain's steepest slope;
// beyond the rectangle at least the horizontal distance to it).
// CPU reference: `penumbra_df_core::heightfield::HeightfieldTexture::distance` (the GPU's
// arithmetic), equal to `Heightfield::distance`.
#define_import_path penumbra::df::heightfield

#import penumbra::df::object::TILE_SIZE

const SLOPE_TILE: f32 = 8.0;

struct HeightfieldRecord {
    tile: vec3<i32>,
    row: u32,
    origin: vec2<f32>,
    extent: vec2<f32>,
    size: vec2<u32>,
    tiles: vec2<u32>,
    // Steepest slope bound, a slope tile's reach (m), lowest and highest height.
    bounds: vec4<f32>,
}

// Position `p`, relative to tile `tile`, relative to `h`'s tile.
fn heightfield_local(h: HeightfieldRecord, tile: vec3<i32>, p: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(tile - h.tile) * TILE_SIZE + p;
}

// Whether `h`'s surface box grown by `reach` meets the box [lo, hi] (both in `h`'s frame).
fn heightfield_reaches(h: HeightfieldRecord, lo: vec3<f32>, hi: vec3<f32>, reach: f32) -> bool {
    let box_lo = vec3<f32>(h.origin.x, h.bounds.z, h.origin.y) - vec3<f32>(reach);
    let box_hi = vec3<f32>(h.origin.x + h.extent.x, h.bounds.w, h.origin.y + h.extent.y)
        + vec3<f32>(reach);
    return all(box_lo <= hi) && all(box_hi >= lo);
}

// The bilinear surface height at `xz` (clamped to the edge beyond the rectangle).
fn heightfield_height(h: HeightfieldRecord, heights: texture_2d<f32>, xz: vec2<f32>) -> f32 {
    let cells = vec2<f32>(h.size - vec2<u32>(1u));
    let g = clamp((xz - h.origin) / h.extent * cells, vec2<f32>(0.0), cells);
    let i0 = min(floor(g), cells - vec2<f32>(1.0));
    let f = g - i0;
    let base = vec2<i32>(i0) + vec2<i32>(0, i32(h.row));
    let a = textureLoad(heights, base, 0).r;
    let b = textureLoad(heights, base + vec2<i32>(1, 0), 0).r;
    let c = textureLoad(heights, base + vec2<i32>(0, 1), 0).r;
    let d = textureLoad(heights, base + vec2<i32>(1, 1), 0).r;
    let x0 = a + (b - a) * f.x;
    let x1 = c + (d - c) * f.x;
    return x0 + (x1 - x0) * f.y;
}

// A lower bound of the signed distance from `p` (in `h`'s frame) to the terrain,
// negative below it, metres.
fn heightfield_distance(h: HeightfieldRecord, heights: texture_2d<f32>, p: vec3<f32>) -> f32 {
    let xz = p.xz;
    let cells = vec2<f32>(h.size - vec2<u32>(1u));
    let g = (xz - h.origin) / h.extent * cells;
    let slope_tile = floor(clamp(g, vec2<f32>(0.0), cells - vec2<f32>(1e-3)) / SLOPE_TILE);
    let k = textureLoad(heights, vec2<i32>(slope_tile) + vec2<i32>(0, i32(h.row + h.size.y)), 0).r;
    let gap = p.y - heightfield_height(h, heights, xz);
    let bound = max(min(abs(gap) / k, h.bounds.y), abs(gap) / h.bounds.x);
    let vertical = select(bound, -bound, gap < 0.0);
    let outside = max(max(h.origin - xz, xz - h.origin - h.extent), vec2<f32>(0.0));
    if all(outside == vec2<f32>(0.0)) {
        return vertical;
    }
    let above = max(p.y - h.bounds.w, 0.0);
    return max(vertical, sqrt(dot(outside, outside) + above * above));
}
