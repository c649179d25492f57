// Scatter bokeh depth of field: the passes' uniform (`penumbra_cinematic_core::dof::
// BokehView`), the sprite record and the lens functions they share. CPU model: `penumbra_reference::bokeh`.
#define_import_path penumbra::dof::types

// The half-resolution round trip's blur as a disc's squared diameter, view pixels²
// (`penumbra_cinematic_core::dof::HALF_RES_BLUR`).
const HALF_RES_BLUR: f32 = 16.0;

// The quarter-resolution round trip's extra blur over the half-resolution one, half
// pixels² (`penumbra_cinematic_core::dof::QUARTER_RES_BLUR`).
const QUARTER_RES_BLUR: f32 = 12.0;

struct BokehView {
    view_from_clip: mat4x4<f32>,
    full_size: vec2<u32>,
    half_size: vec2<u32>,
    quarter_size: vec2<u32>,
    coc_scale: f32,
    focal_distance: f32,
    max_coc: f32,
    max_depth: f32,
    min_coc: f32,
    coc_tolerance: f32,
    color_tolerance: f32,
    depth_tolerance: f32,
    merge: u32,
    // 1: a 2×2 group of blocks that agrees is one sprite (`SpriteRule::merge_groups`).
    merge_groups: u32,
    capacity: u32,
    // Sprites at least this wide (half-resolution pixels) are drawn at quarter resolution.
    quarter_diameter: f32,
    // The view's viewport origin in the frame buffer: view pixel `p` is frame-buffer
    // pixel `p + origin`.
    origin: vec2<u32>,
}

// One sprite: `shape` = (centre in half-resolution pixels, aperture diameter, weight:
// 1 or 4 for a block, 0 for an empty slot); `color` = (the summed colour, 1 when in front
// of the focal plane). In the sprite pass's slots block `b` (row-major) owns `4b` to
// `4b + 3`; the compacted list has no gaps.
struct Sprite {
    shape: vec4<f32>,
    color: vec4<f32>,
}

// `draw_indirect`'s arguments.
struct DrawArgs {
    vertex_count: u32,
    instance_count: u32,
    first_vertex: u32,
    first_instance: u32,
}

// The scatter pass's four draws (one per layer, `sprite_layer`'s order) and each layer's
// first index in the sprite list, written by the compaction.
struct LayerDraws {
    draws: array<DrawArgs, 4>,
    first: vec4<u32>,
}

// Distance along the view axis of view pixel `p` whose reverse-Z depth is `depth`
// (the sky, depth 0, at `view.max_depth`).
fn distance_from_depth(view: BokehView, p: vec2<u32>, depth: f32) -> f32 {
    if !(depth > 0.0) {
        return view.max_depth;
    }
    let uv = (vec2<f32>(p) + 0.5) / vec2<f32>(view.full_size);
    let v = view.view_from_clip * vec4<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, depth, 1.0);
    return min(-v.z / v.w, view.max_depth);
}

// Signed circle of confusion, view pixels, of a point `distance` along the view axis
// (`Lens::coc`).
fn coc_of_distance(view: BokehView, distance: f32) -> f32 {
    if !(distance > 0.0) {
        return 0.0;
    }
    let z = min(distance, view.max_depth);
    return clamp(view.coc_scale * (1.0 - view.focal_distance / z), -view.max_coc, view.max_coc);
}

// The aperture's diameter in half-resolution pixels for a circle of confusion of `coc`
// view pixels, less the half-resolution round trip's own blur under 16 px
// (`bokeh::sprite_diameter`).
fn sprite_diameter(coc: f32) -> f32 {
    let d = abs(coc);
    let fade = clamp((16.0 - d) / 8.0, 0.0, 1.0);
    return max(0.5 * sqrt(max(d * d - HALF_RES_BLUR * fade, 0.0)), 1.0);
}

// The aperture diameter, half-resolution pixels, a sprite `diameter` wide is drawn with at
// quarter resolution (`bokeh::quarter_diameter`).
fn quarter_diameter(diameter: f32) -> f32 {
    return sqrt(max(diameter * diameter - QUARTER_RES_BLUR, 1.0));
}

// The layer a sprite is drawn into, in the scatter pass's order: 0 near and 1 far at
// half resolution, 2 near and 3 far at quarter resolution (sprites at least
// `view.quarter_diameter` wide) (`bokeh::layer_index`).
fn sprite_layer(view: BokehView, s: Sprite) -> u32 {
    return select(1u, 0u, s.color.a > 0.5) + select(0u, 2u, s.shape.z >= view.quarter_diameter);
}

// A pixel of the HDR target as the sprites and the composite take it: at most the
// largest f16 per channel, NaN as 0 (one +Inf pixel made its sprite, and the square it
// covers, NaN). CPU model: `bokeh::scatter::scene_color`.
fn scene_color(c: vec3<f32>) -> vec3<f32> {
    return select(vec3<f32>(0.0), min(c, vec3<f32>(65504.0)), c == c);
}
