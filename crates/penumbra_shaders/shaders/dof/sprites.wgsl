// Scatter bokeh depth of field, first pass: one thread per 2×2 block of the
// half-resolution image (4×4 view pixels). Each of the block's half-resolution pixels
// takes the mean colour of its 2×2 view pixels and the circle of confusion of the
// nearest; the block becomes one sprite when all four are out of focus on one side of
// the focal plane and agree (the 1-or-4 rule), else each out-of-focus pixel becomes
// one. A 2×2 group of blocks (whole within each 8×8 workgroup, shared through
// workgroup memory) that agrees as a whole, with a sprite drawn at half resolution,
// becomes one sprite, in its first block's first slot. Each block writes its four
// slots and its sprites' count per layer (`sprite_layer`), which the compaction lists
// layer by layer.
// CPU model: `penumbra_reference::bokeh::{downsample, sprites}`.
#define_import_path penumbra::dof::sprites

#import penumbra::dof::types::{
    BokehView, Sprite, coc_of_distance, distance_from_depth, scene_color, sprite_diameter,
    sprite_layer,
}

@group(0) @binding(0) var<uniform> view: BokehView;
@group(0) @binding(1) var color_texture: texture_2d<f32>;
// A view with MSAA (`MULTISAMPLED` defined) reads its first sample's depth, as Bevy's
// `DepthOfField` reads it.
#ifdef MULTISAMPLED
@group(0) @binding(2) var depth_texture: texture_depth_multisampled_2d;
#else
@group(0) @binding(2) var depth_texture: texture_depth_2d;
#endif
// Per block, its sprites (0 to 4) in each layer: the compaction's input.
@group(0) @binding(3) var<storage, read_write> block_counts: array<vec4<u32>>;
@group(0) @binding(4) var<storage, read_write> slots: array<Sprite>;

// A half-resolution pixel: mean colour, circle of confusion, distance.
struct HalfPixel {
    color: vec3<f32>,
    coc: f32,
    distance: f32,
}

// Distance along the view axis of view pixel `p` (`f32::MAX`-capped; the sky at
// `view.max_depth`).
fn pixel_distance(p: vec2<u32>) -> f32 {
    return distance_from_depth(view, p, textureLoad(depth_texture, vec2<i32>(p + view.origin), 0));
}

fn half_pixel(h: vec2<u32>) -> HalfPixel {
    var color = vec3<f32>(0.0);
    var nearest = 3.4e38;
    for (var k = 0u; k < 4u; k += 1u) {
        let p = min(2u * h + vec2<u32>(k & 1u, k >> 1u), view.full_size - vec2<u32>(1u));
        color += scene_color(textureLoad(color_texture, vec2<i32>(p + view.origin), 0).rgb);
        nearest = min(nearest, pixel_distance(p));
    }
    return HalfPixel(color / 4.0, coc_of_distance(view, nearest), nearest);
}

fn luminance(c: vec3<f32>) -> f32 {
    return dot(c, vec3<f32>(0.2126, 0.7152, 0.0722));
}

// What the 1-or-4 rule reads of a block, or of a 2×2 group of blocks, summed in the
// model's order (`bokeh::scatter::GroupStats`).
struct Stats {
    coc_lo: f32,
    coc_hi: f32,
    coc_sum: f32,
    l_lo: f32,
    l_hi: f32,
    // Σ (l / n) and Σ (distance / n): four `f32::MAX` skies do not overflow.
    l_mean: f32,
    d_lo: f32,
    d_hi: f32,
    d_mean: f32,
    color: vec3<f32>,
    // All its texels lie in the image (and, for a block, it is one).
    inside: u32,
}

// Each block of the workgroup (8×8 blocks: whole 2×2 groups) as its group's others see it.
var<workgroup> block_stats: array<Stats, 64>;

fn stats_of_block(b: array<HalfPixel, 4>, inside: bool) -> Stats {
    let l0 = luminance(b[0].color);
    var s = Stats(b[0].coc, b[0].coc, 0.0, l0, l0, 0.0, b[0].distance, b[0].distance, 0.0,
        vec3<f32>(0.0), select(0u, 1u, inside));
    for (var k = 0u; k < 4u; k += 1u) {
        let l = luminance(b[k].color);
        s.coc_lo = min(s.coc_lo, b[k].coc);
        s.coc_hi = max(s.coc_hi, b[k].coc);
        s.coc_sum += b[k].coc;
        s.l_lo = min(s.l_lo, l);
        s.l_hi = max(s.l_hi, l);
        s.l_mean += l / 4.0;
        s.d_lo = min(s.d_lo, b[k].distance);
        s.d_hi = max(s.d_hi, b[k].distance);
        s.d_mean += b[k].distance / 4.0;
        s.color += b[k].color;
    }
    return s;
}

// The group of four blocks whose first (top-left) sits at local index `first`.
fn stats_of_group(first: u32) -> Stats {
    var s = block_stats[first];
    s.coc_sum = 0.0;
    s.l_mean = 0.0;
    s.d_mean = 0.0;
    s.color = vec3<f32>(0.0);
    for (var k = 0u; k < 4u; k += 1u) {
        let b = block_stats[first + (k & 1u) + 8u * (k >> 1u)];
        s.coc_lo = min(s.coc_lo, b.coc_lo);
        s.coc_hi = max(s.coc_hi, b.coc_hi);
        s.coc_sum += b.coc_sum;
        s.l_lo = min(s.l_lo, b.l_lo);
        s.l_hi = max(s.l_hi, b.l_hi);
        s.l_mean += b.l_mean / 4.0;
        s.d_lo = min(s.d_lo, b.d_lo);
        s.d_hi = max(s.d_hi, b.d_hi);
        s.d_mean += b.d_mean / 4.0;
        s.color += b.color;
        s.inside = s.inside & b.inside;
    }
    return s;
}

// Whether the texels of `s` may be one sprite.
fn agrees(s: Stats) -> bool {
    let same_side = s.coc_lo > 0.0 || s.coc_hi < 0.0;
    let in_focus = min(abs(s.coc_lo), abs(s.coc_hi)) < max(view.min_coc, 1e-3);
    return same_side && !in_focus
        && s.coc_hi - s.coc_lo <= view.coc_tolerance
        && s.l_hi - s.l_lo <= view.color_tolerance * max(s.l_mean, 1e-4)
        && (s.d_hi - s.d_lo <= view.depth_tolerance * s.d_mean || s.d_lo == s.d_hi);
}

// Slot `slot` holds a sprite, or nothing when `weight` is 0; what it adds to the
// block's counts per layer.
fn write(slot: u32, center: vec2<f32>, coc: f32, color: vec3<f32>, weight: f32) -> vec4<u32> {
    var sprite = Sprite(vec4<f32>(0.0), vec4<f32>(0.0));
    var count = vec4<u32>(0u);
    if weight > 0.0 {
        sprite = Sprite(
            vec4<f32>(center, sprite_diameter(coc), weight),
            vec4<f32>(color, select(0.0, 1.0, coc < 0.0)),
        );
        count[sprite_layer(view, sprite)] = 1u;
    }
    if slot < view.capacity {
        slots[slot] = sprite;
    }
    return count;
}

// Block `block`'s four slots: one sprite in the first (nothing for weight 0), the
// others empty; its counts per layer.
fn write_one(base: u32, center: vec2<f32>, coc: f32, color: vec3<f32>, weight: f32) -> vec4<u32> {
    let count = write(base, center, coc, color, weight);
    for (var k = 1u; k < 4u; k += 1u) {
        write(base + k, vec2<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0);
    }
    return count;
}

// A group that agrees and whose sprite is drawn at half resolution: one sprite for its
// sixteen texels.
fn group_merges(group: Stats) -> bool {
    let diameter = sprite_diameter(group.coc_sum / 16.0);
    return view.merge_groups == 1u && group.inside == 1u && agrees(group)
        && diameter < view.quarter_diameter;
}

@compute @workgroup_size(8, 8, 1)
fn sprites_main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
) {
    let block = gid.xy;
    let valid = all(2u * block < view.half_size);
    var b: array<HalfPixel, 4>;
    var inside = valid;
    for (var k = 0u; k < 4u; k += 1u) {
        let h = 2u * block + vec2<u32>(k & 1u, k >> 1u);
        inside = inside && all(h < view.half_size);
        b[k] = half_pixel(min(h, view.half_size - vec2<u32>(1u)));
    }
    let stats = stats_of_block(b, inside);
    block_stats[lid.y * 8u + lid.x] = stats;
    workgroupBarrier();
    if !valid {
        return;
    }
    let index = block.y * ((view.half_size.x + 1u) / 2u) + block.x;
    let base = 4u * index;
    // Every block of a group reads the same four records and decides alike.
    let first = (lid.y & ~1u) * 8u + (lid.x & ~1u);
    let group = stats_of_group(first);
    var count = vec4<u32>(0u);
    if group_merges(group) {
        // The group's sprite in its first block's first slot; nothing in the others'.
        let leads = all((lid.xy & vec2<u32>(1u)) == vec2<u32>(0u));
        let center = 2.0 * vec2<f32>(block & vec2<u32>(~1u)) + 2.0;
        count = write_one(base, center, group.coc_sum / 16.0, group.color, select(0.0, 16.0, leads));
    } else if view.merge == 1u && inside && agrees(stats) {
        count = write_one(base, 2.0 * vec2<f32>(block) + 1.0, stats.coc_sum / 4.0, stats.color, 4.0);
    } else {
        for (var k = 0u; k < 4u; k += 1u) {
            let h = 2u * block + vec2<u32>(k & 1u, k >> 1u);
            let emits = all(h < view.half_size) && abs(b[k].coc) >= max(view.min_coc, 1e-3);
            count += write(base + k, vec2<f32>(h) + 0.5, b[k].coc, b[k].color, select(0.0, 1.0, emits));
        }
    }
    block_counts[index] = count;
}
