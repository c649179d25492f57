// Deferred 4× MSAA's classification (`penumbra::lighting::msaa_view::msaa_pixel_class`),
// drawn fullscreen with the lighting pass's vertex shader:
// - `classify`, once per pixel, to single-sample targets: the class (0 nothing of this
//   pass's material, 1 shaded once, 2 shaded per sample) and, for the distance-field
//   passes that trace per pixel, a representative G-buffer texel and depth — the
//   samples' mean depth where they agree, else the first covered sample's;
// - `mark_pixels` and `mark_edges`, into the multisampled stencil the lighting draws
//   test: they keep only the pixels of their class (the stencil reference does the
//   rest), `mark_edges` only their covered samples.
#import bevy_pbr::prepass_utils::prepass_depth
#import penumbra::lighting::msaa_view::{
    keep_class, msaa_gbuffer, msaa_pixel_class, msaa_sample_covered,
}

struct FullscreenVertexOutput {
    @builtin(position) position: vec4<f32>,
    @location(0) uv: vec2<f32>,
}

struct ClassifyOutput {
    @location(0) pixel_class: u32,
    @location(1) gbuffer: vec4<u32>,
    @builtin(frag_depth) depth: f32,
}

// The first sample of `pixel` holding this pass's material (0 when none does).
fn first_covered_sample(pixel: vec2<i32>) -> u32 {
    for (var i = 0u; i < 4u; i++) {
        if msaa_sample_covered(pixel, i) {
            return i;
        }
    }
    return 0u;
}

@fragment
fn classify(in: FullscreenVertexOutput) -> ClassifyOutput {
    let pixel = vec2<i32>(in.position.xy);
    let pixel_class = msaa_pixel_class(pixel);
    let first = first_covered_sample(pixel);
    var depth = prepass_depth(in.position, first);
    if pixel_class == 1u {
        depth = 0.0;
        for (var i = 0u; i < 4u; i++) {
            depth += prepass_depth(in.position, i);
        }
        depth *= 0.25;
    }
    var gbuffer = vec4(0u);
    if pixel_class != 0u {
        gbuffer = textureLoad(msaa_gbuffer, pixel, i32(first));
    }
    return ClassifyOutput(pixel_class, gbuffer, depth);
}

@fragment
fn mark_pixels(in: FullscreenVertexOutput) -> @location(0) vec4<f32> {
    keep_class(vec2<i32>(in.position.xy), 1u);
    return vec4(0.0);
}

struct MarkOutput {
    @location(0) color: vec4<f32>,
    @builtin(sample_mask) mask: u32,
}

// Marks only the samples holding this pass's material: the per-sample lighting then
// needs no `discard`, and the stencil test can reject before shading.
@fragment
fn mark_edges(in: FullscreenVertexOutput) -> MarkOutput {
    let pixel = vec2<i32>(in.position.xy);
    keep_class(pixel, 2u);
    var mask = 0u;
    for (var i = 0u; i < 4u; i++) {
        mask |= select(0u, 1u << i, msaa_sample_covered(pixel, i));
    }
    return MarkOutput(vec4(0.0), mask);
}
