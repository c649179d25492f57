// Scatter bokeh depth of field, last pass (fullscreen, view resolution): each pixel
// starts from the sharp image; behind the focal plane it blends to the resolved far
// layer (`Σ colour / Σ weight`, the half-resolution layer's sums plus a quarter of the
// quarter-resolution one's) as its own circle of confusion grows from ½ pixel to
// `min_coc`; then the resolved near layer is laid over it with opacity `min(Σ weight, 1)`.
// A pixel under ½ pixel of blur that no near sprite reaches keeps its input exactly.
// CPU model: `penumbra_reference::bokeh::composite`.
#define_import_path penumbra::dof::composite

#import penumbra::dof::types::{BokehView, coc_of_distance, distance_from_depth, scene_color}

@group(0) @binding(0) var<uniform> view: BokehView;
@group(0) @binding(1) var color_texture: texture_2d<f32>;
// A view with MSAA (`MULTISAMPLED` defined) reads its first sample's depth, as Bevy's
// `DepthOfField` reads it.
#ifdef MULTISAMPLED
@group(0) @binding(2) var depth_texture: texture_depth_multisampled_2d;
#else
@group(0) @binding(2) var depth_texture: texture_depth_2d;
#endif
// The layers: `Rgba32Float` where the device blends it, else `Rgba16Float`; read
// bilinearly by hand (32-bit floats need not be filterable).
@group(0) @binding(3) var near_layer: texture_2d<f32>;
@group(0) @binding(4) var far_layer: texture_2d<f32>;
@group(0) @binding(5) var near_quarter: texture_2d<f32>;
@group(0) @binding(6) var far_quarter: texture_2d<f32>;

// Distance along the view axis of view pixel `p` (the sky at `view.max_depth`).
fn pixel_distance(p: vec2<u32>) -> f32 {
    return distance_from_depth(view, p, textureLoad(depth_texture, vec2<i32>(p + view.origin), 0));
}

// Bilinear read of `layer` (`size` texels, each `scale` view pixels wide) at view
// pixel `p`'s centre, edges clamped, as a linear, clamp-to-edge sampler reads it.
fn layer_bilinear(layer: texture_2d<f32>, size: vec2<u32>, scale: f32, p: vec2<u32>) -> vec4<f32> {
    let last = vec2<i32>(size) - 1;
    let t = (vec2<f32>(p) + 0.5) / scale - 0.5;
    let t0 = floor(t);
    let f = t - t0;
    let i0 = clamp(vec2<i32>(t0), vec2<i32>(0), last);
    let i1 = clamp(vec2<i32>(t0) + 1, vec2<i32>(0), last);
    let top = mix(textureLoad(layer, i0, 0), textureLoad(layer, vec2<i32>(i1.x, i0.y), 0), f.x);
    let bottom = mix(textureLoad(layer, vec2<i32>(i0.x, i1.y), 0), textureLoad(layer, i1, 0), f.x);
    return mix(top, bottom, f.y);
}

// A layer's sums at view pixel `p`: the half-resolution layer's plus a quarter of the
// quarter-resolution one's (a quarter texel covers four half texels).
fn layers_at(half: texture_2d<f32>, quarter: texture_2d<f32>, p: vec2<u32>) -> vec4<f32> {
    return layer_bilinear(half, view.half_size, 2.0, p)
        + layer_bilinear(quarter, view.quarter_size, 4.0, p) * 0.25;
}

// The bokeh of view pixel `p` over `sharp`.
fn composite(p: vec2<u32>, sharp: vec3<f32>) -> vec3<f32> {
    let coc = coc_of_distance(view, pixel_distance(p));
    var c = sharp;
    let far = layers_at(far_layer, far_quarter, p);
    if coc > 0.5 && far.w > 1e-6 {
        let min_coc = max(view.min_coc, 0.5 + 1e-3);
        c = mix(sharp, far.rgb / far.w, clamp((coc - 0.5) / (min_coc - 0.5), 0.0, 1.0));
    }
    let near = layers_at(near_layer, near_quarter, p);
    if near.w > 1e-6 {
        c = mix(c, near.rgb / near.w, min(near.w, 1.0));
    }
    return c;
}

// Over the whole frame buffer: the view's viewport gets its bokeh, the pixels outside
// it (another camera's, on a split screen) are copied as they are.
@fragment
fn fragment(@builtin(position) position: vec4<f32>) -> @location(0) vec4<f32> {
    let frame = vec2<u32>(position.xy);
    let sharp = textureLoad(color_texture, vec2<i32>(frame), 0);
    if any(frame < view.origin) || any(frame - view.origin >= view.full_size) {
        return sharp;
    }
    return vec4<f32>(composite(frame - view.origin, scene_color(sharp.rgb)), sharp.a);
}
