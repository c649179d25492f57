// Scatter bokeh depth of field, second pass: one instanced quad per sprite of the
// compacted list (`draw_indirect` with its layer's count), drawn in list order with
// additive blending into one layer per draw — near (`NEAR_LAYER`) or far, at half
// resolution or, for sprites at least `view.quarter_diameter` wide, at quarter
// resolution (`QUARTER_LAYER`) — each texel `(Σ colour · v, Σ v)`. The list holds each
// layer's sprites together (`compact.wgsl`): each draw runs its own sprites' four
// vertices (a triangle strip) and each fragment blends one target. A fragment adds the
// aperture image around the sprite's pixel, or around each of a block's four or a
// group's sixteen, normalised by what the aperture sums to over the texels it
// covers, so each pixel spreads unit weight; near sprites read the aperture
// point-reflected. A quarter texel adds what the sprite (its aperture shrunk by
// `quarter_diameter`) adds at its four half-resolution texel centres: a quarter of the
// fragments and blends of a half-resolution sprite, the same samples.
// CPU model: `penumbra_reference::bokeh::scatter_sprites`.
#define_import_path penumbra::dof::scatter

#import penumbra::dof::types::{BokehView, LayerDraws, Sprite, quarter_diameter}

@group(0) @binding(0) var<uniform> view: BokehView;
@group(0) @binding(1) var<storage, read> sprites: array<Sprite>;
@group(0) @binding(2) var aperture: texture_2d<f32>;
@group(0) @binding(3) var aperture_sampler: sampler;
// The aperture's mean transmission (its area as a fraction of the square), then per
// interval of its normalisation table (`Aperture::norm_words`): the lattice sum at the
// start, its continuous part at the end, the jump and the diameter it comes past.
@group(0) @binding(4) var<storage, read> aperture_norm: array<f32>;
// Where each layer's sprites start in `sprites` (the compaction's).
@group(0) @binding(5) var<storage, read> layer_draws: LayerDraws;

// This draw's layer (`sprite_layer`'s order).
#ifdef NEAR_LAYER
const LAYER_SIDE: u32 = 0u;
#else
const LAYER_SIDE: u32 = 1u;
#endif
#ifdef QUARTER_LAYER
const LAYER_RESOLUTION: u32 = 2u;
#else
const LAYER_RESOLUTION: u32 = 0u;
#endif
const LAYER: u32 = LAYER_SIDE + LAYER_RESOLUTION;

// `penumbra_cinematic_core::dof::{NORM_TABLE_MAX, NORM_TABLE_STEPS, NORM_INTERVALS}`.
const NORM_TABLE_MAX: f32 = 64.0;
const NORM_TABLE_STEPS: f32 = 128.0;
const NORM_INTERVALS: u32 = 768u;

struct VertexOutput {
    @builtin(position) position: vec4<f32>,
    // The sprite: centre, aperture diameter, weight; colour per pixel, side.
    @location(0) @interpolate(flat) shape: vec4<f32>,
    @location(1) @interpolate(flat) color: vec4<f32>,
    // What the sprite's aperture sums to over the texels it covers.
    @location(2) @interpolate(flat) norm: f32,
}

@vertex
fn vertex(@builtin(vertex_index) vertex_index: u32, @builtin(instance_index) instance: u32) -> VertexOutput {
    var out: VertexOutput;
    let index = layer_draws.first[LAYER] + instance;
    if index >= view.capacity {
        out.position = vec4<f32>(2.0, 2.0, 2.0, 1.0);
        return out;
    }
    let s = sprites[index];
    if s.shape.w == 0.0 {
        // A place left empty (buffers too small for the view): nothing to draw.
        out.position = vec4<f32>(2.0, 2.0, 2.0, 1.0);
        return out;
    }
    // A triangle strip: (0, 0) (1, 0) (0, 1) (1, 1).
    let corners = array(vec2<f32>(0.0, 0.0), vec2<f32>(1.0, 0.0), vec2<f32>(0.0, 1.0),
        vec2<f32>(1.0, 1.0));
    let spread = f32(side(s.shape.w) - 1u);
    var shape = s.shape;
#ifdef QUARTER_LAYER
    // The half-resolution quad (one pixel wider for a block) halved, and half a quarter
    // texel more for the samples around each texel centre.
    shape.z = quarter_diameter(s.shape.z);
    let center = 0.5 * s.shape.xy;
    let extent = 0.5 * (shape.z + spread) + 0.5;
    let size = vec2<f32>(view.quarter_size);
#else
    let center = s.shape.xy;
    let extent = s.shape.z + spread;
    let size = vec2<f32>(view.half_size);
#endif
    let p = center + (corners[vertex_index % 4u] - 0.5) * extent;
    let ndc = p / size * 2.0 - 1.0;
    out.position = vec4<f32>(ndc.x, -ndc.y, 0.0, 1.0);
    out.shape = shape;
    out.color = vec4<f32>(s.color.rgb / s.shape.w, s.color.a);
    out.norm = normalisation(shape.z);
    return out;
}

// What a sprite of diameter `d` (half-resolution pixels) sums to over the texel centres
// it covers, far or near (the covered offsets are symmetric): the table under
// NORM_TABLE_MAX, the analytic area above (`Aperture::normalisation`).
fn normalisation(diameter: f32) -> f32 {
    let d = max(diameter, 1.0);
    let area = aperture_norm[0] * d * d;
    if d >= NORM_TABLE_MAX {
        return area;
    }
    let t = log2(d) * NORM_TABLE_STEPS;
    let k = min(u32(t), NORM_INTERVALS - 1u);
    let f = t - f32(k);
    let i = 1u + 4u * k;
    var sum = aperture_norm[i] * (1.0 - f) + aperture_norm[i + 1u] * f;
    if d > aperture_norm[i + 3u] {
        sum += aperture_norm[i + 2u];
    }
    return max(sum, area / 16.0);
}

// The aperture around `center`, seen from half-resolution point `p`: 0 unless the
// offset is strictly within half the diameter on each axis (`Aperture::sprite_sample`).
fn aperture_at(p: vec2<f32>, center: vec2<f32>, diameter: f32, near: bool) -> f32 {
    let o = p - center;
    if any(abs(o) >= vec2<f32>(0.5 * diameter)) {
        return 0.0;
    }
    var uv = o / diameter + 0.5;
    if near {
        uv = 1.0 - uv;
    }
    return textureSampleLevel(aperture, aperture_sampler, uv, 0.0).r;
}

// Texels across the square a sprite of `weight` stands for: 1, 2 for a block, 4 for a
// group (`Sprite::side`).
fn side(weight: f32) -> u32 {
    if weight > 4.0 {
        return 4u;
    }
    return select(1u, 2u, weight > 1.0);
}

// What the sprite adds at `p`, before normalisation: the aperture around each texel
// centre of its square (`bokeh::sprite_weight`).
fn sprite_weight(p: vec2<f32>, shape: vec4<f32>, near: bool) -> f32 {
    let n = side(shape.w);
    let half = 0.5 * f32(n - 1u);
    var sum = 0.0;
    for (var y = 0u; y < n; y += 1u) {
        for (var x = 0u; x < n; x += 1u) {
            sum += aperture_at(p, shape.xy + (vec2<f32>(f32(x), f32(y)) - half), shape.z, near);
        }
    }
    return sum;
}

@fragment
fn fragment(in: VertexOutput) -> @location(0) vec4<f32> {
    let near = in.color.a > 0.5;
#ifdef QUARTER_LAYER
    // The quarter texel's four half-resolution texel centres (`quarter_sprite_weight`).
    var v = 0.0;
    for (var k = 0u; k < 4u; k += 1u) {
        let o = vec2<f32>(f32(k & 1u), f32(k >> 1u)) - 0.5;
        v += sprite_weight(2.0 * in.position.xy + o, in.shape, near) / in.norm;
    }
#else
    let v = sprite_weight(in.position.xy, in.shape, near) / in.norm;
#endif
    if v == 0.0 {
        // Outside the aperture (the quad's corners, a hexagon's sides): adding nothing,
        // it skips the blend, the pass's bottleneck where raster output is scarce.
        discard;
    }
    return vec4<f32>(in.color.rgb * v, v);
}
