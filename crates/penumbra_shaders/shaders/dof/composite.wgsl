// Scatter bokeh depth of field, last pass (fullscreen, view resolution): each pixel
// starts from the sharp image; behind the focal plane it blends to the resolved far
// layer (`Σ colour / Σ weight`) as its own circle of confusion grows from ½ pixel to
// `min_coc`; then the resolved near layer is laid over it with opacity `min(Σ weight, 1)`.
// A pixel under ½ pixel of blur that no near sprite reaches keeps its input exactly.
// CPU model: `penumbra_reference::bokeh::composite`.
#define_import_path penumbra::dof::composite

#import penumbra::dof::types::{BokehView, coc_of_distance, distance_from_depth}

@group(0) @binding(0) var<uniform> view: BokehView;
@group(0) @binding(1) var color_texture: texture_2d<f32>;
@group(0) @binding(2) var depth_texture: texture_depth_2d;
@group(0) @binding(3) var near_layer: texture_2d<f32>;
@group(0) @binding(4) var far_layer: texture_2d<f32>;
@group(0) @binding(5) var layer_sampler: sampler;

// Distance along the view axis of view pixel `p` (the sky at `view.max_depth`).
fn pixel_distance(p: vec2<u32>) -> f32 {
    return distance_from_depth(view, p, textureLoad(depth_texture, vec2<i32>(p), 0));
}

// The bokeh of view pixel `p` over `sharp`.
fn composite(p: vec2<u32>, sharp: vec3<f32>) -> vec3<f32> {
    let coc = coc_of_distance(view, pixel_distance(p));
    // The half-resolution texel grid: view pixel centre (p + ½) lies at (p + ½) / 2.
    let uv = (vec2<f32>(p) + 0.5) * 0.5 / vec2<f32>(view.half_size);
    var c = sharp;
    let far = textureSampleLevel(far_layer, layer_sampler, uv, 0.0);
    if coc > 0.5 && far.w > 1e-6 {
        let min_coc = max(view.min_coc, 0.5 + 1e-3);
        c = mix(sharp, far.rgb / far.w, clamp((coc - 0.5) / (min_coc - 0.5), 0.0, 1.0));
    }
    let near = textureSampleLevel(near_layer, layer_sampler, uv, 0.0);
    if near.w > 1e-6 {
        c = mix(c, near.rgb / near.w, min(near.w, 1.0));
    }
    return c;
}

@fragment
fn fragment(@builtin(position) position: vec4<f32>) -> @location(0) vec4<f32> {
    let p = vec2<u32>(position.xy);
    let sharp = textureLoad(color_texture, vec2<i32>(p), 0);
    return vec4<f32>(composite(p, sharp.rgb), sharp.a);
}
