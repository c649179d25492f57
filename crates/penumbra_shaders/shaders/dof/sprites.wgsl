// Scatter bokeh depth of field, first pass: one thread per 2×2 block of the
// half-resolution image (4×4 view pixels). Each of the block's half-resolution pixels
// takes the mean colour of its 2×2 view pixels and the circle of confusion of the
// nearest; the block becomes one sprite when all four are out of focus on one side of
// the focal plane and agree (the 1-or-4 rule), else each out-of-focus pixel becomes
// one. Each block writes its four slots and its sprites' count per layer
// (`sprite_layer`), which the compaction lists layer by layer.
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

// Whether the four pixels of a block may be one sprite.
fn block_agrees(b: array<HalfPixel, 4>) -> bool {
    var coc_lo = b[0].coc;
    var coc_hi = b[0].coc;
    var l_lo = luminance(b[0].color);
    var l_hi = l_lo;
    var l_mean = 0.0;
    var d_lo = b[0].distance;
    var d_hi = d_lo;
    var d_mean = 0.0;
    for (var k = 0u; k < 4u; k += 1u) {
        let l = luminance(b[k].color);
        coc_lo = min(coc_lo, b[k].coc);
        coc_hi = max(coc_hi, b[k].coc);
        l_lo = min(l_lo, l);
        l_hi = max(l_hi, l);
        l_mean += l / 4.0;
        d_lo = min(d_lo, b[k].distance);
        d_hi = max(d_hi, b[k].distance);
        d_mean += b[k].distance / 4.0;
    }
    let same_side = coc_lo > 0.0 || coc_hi < 0.0;
    let in_focus = min(abs(coc_lo), abs(coc_hi)) < max(view.min_coc, 1e-3);
    return same_side && !in_focus
        && coc_hi - coc_lo <= view.coc_tolerance
        && l_hi - l_lo <= view.color_tolerance * max(l_mean, 1e-4)
        && (d_hi - d_lo <= view.depth_tolerance * d_mean || d_lo == d_hi);
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

@compute @workgroup_size(8, 8, 1)
fn sprites_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let block = gid.xy;
    if any(2u * block >= view.half_size) {
        return;
    }
    var b: array<HalfPixel, 4>;
    var inside = true;
    for (var k = 0u; k < 4u; k += 1u) {
        let h = 2u * block + vec2<u32>(k & 1u, k >> 1u);
        inside = inside && all(h < view.half_size);
        b[k] = half_pixel(min(h, view.half_size - vec2<u32>(1u)));
    }
    let index = block.y * ((view.half_size.x + 1u) / 2u) + block.x;
    let base = 4u * index;
    var count = vec4<u32>(0u);
    if view.merge == 1u && inside && block_agrees(b) {
        let coc = (b[0].coc + b[1].coc + b[2].coc + b[3].coc) / 4.0;
        let color = b[0].color + b[1].color + b[2].color + b[3].color;
        count = write(base, 2.0 * vec2<f32>(block) + 1.0, coc, color, 4.0);
        for (var k = 1u; k < 4u; k += 1u) {
            write(base + k, vec2<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0);
        }
    } else {
        for (var k = 0u; k < 4u; k += 1u) {
            let h = 2u * block + vec2<u32>(k & 1u, k >> 1u);
            let emits = all(h < view.half_size) && abs(b[k].coc) >= max(view.min_coc, 1e-3);
            count += write(base + k, vec2<f32>(h) + 0.5, b[k].coc, b[k].color, select(0.0, 1.0, emits));
        }
    }
    block_counts[index] = count;
}
