// Deferred MSAA's view of the multisampled G-buffer (group 2 of the lighting pass's
// MSAA variants): the samples as the edge test reads them, and the pixel's depth slope.
// The test itself: `penumbra::lighting::msaa` (CPU model `penumbra_reference::msaa`).
#define_import_path penumbra::lighting::msaa_view

#import bevy_pbr::{
    mesh_view_bindings::view,
    pbr_deferred_types,
    prepass_utils::prepass_depth,
    utils::octahedral_decode,
    view_transformations::{depth_ndc_to_view_z, position_ndc_to_view, frag_coord_to_ndc},
}
#import penumbra::lighting::masks::penumbra_lighting
#import penumbra::lighting::msaa::{MSAA_SAMPLE_POSITIONS, MsaaEdgeParams, MsaaSample, msaa_is_edge}

struct PenumbraMsaaUniform {
    edge: MsaaEdgeParams,
    // 1: every covered pixel is shaded per sample (the reference the classifier is
    // measured against).
    per_sample_everywhere: u32,
    // 1: per-sample pixels are tinted (the debug view of the per-sample mask).
    show_edges: u32,
    // 1: the view's distance-field shadow masks, and its AO, are traced per sample on
    // edge pixels (`masks::set_shading_sample`).
    sample_shadows: u32,
    sample_ao: u32,
}

@group(2) @binding(4) var<uniform> penumbra_msaa: PenumbraMsaaUniform;
// Bevy's G-buffer words, per sample.
@group(2) @binding(5) var msaa_gbuffer: texture_multisampled_2d<u32>;
// Bevy's deferred lighting pass id, per sample (0: nothing deferred drawn there).
@group(2) @binding(6) var msaa_lighting_id: texture_multisampled_2d<u32>;
// The pixels' classes (`msaa_pixel_class`), written by the classification pass (a
// 1-texel placeholder while it runs).
@group(2) @binding(7) var msaa_class: texture_2d<u32>;

// The frame-buffer position of sample `i` of `pixel`.
fn msaa_sample_position(pixel: vec2<i32>, i: u32) -> vec2<f32> {
    return vec2<f32>(pixel) + MSAA_SAMPLE_POSITIONS[i];
}

// Whether lighting pass id `id` is this pass's: the default PBR one, or one it shades
// as such (`MsaaShadedLightingIds`: subsurface profiles).
fn msaa_shades_id(id: u32) -> bool {
    return id == penumbra_lighting.depth_id || id >= penumbra_lighting.msaa_shaded_ids_from;
}

// Whether sample `i` of `pixel` holds this pass's deferred material.
fn msaa_sample_covered(pixel: vec2<i32>, i: u32) -> bool {
    return msaa_shades_id(textureLoad(msaa_lighting_id, pixel, i32(i)).r);
}

// The world normal stored for sample `i` of `pixel`.
fn msaa_sample_normal(pixel: vec2<i32>, i: u32) -> vec3<f32> {
    let packed = textureLoad(msaa_gbuffer, pixel, i32(i)).a;
    return octahedral_decode(pbr_deferred_types::unpack_24bit_normal(packed));
}

// Sample `i` of `pixel` as the edge test reads it. Its "material" is the lighting
// pass id and the unlit flag: textures vary inside a surface, so base colours are no
// edge signal (texture aliasing is left to mipmaps, as in forward MSAA).
fn msaa_sample(pixel: vec2<i32>, i: u32) -> MsaaSample {
    let id = textureLoad(msaa_lighting_id, pixel, i32(i)).r;
    let packed = textureLoad(msaa_gbuffer, pixel, i32(i)).a;
    let flags = pbr_deferred_types::unpack_flags(packed);
    let depth = prepass_depth(vec4(vec2<f32>(pixel), 0.0, 0.0), i);
    return MsaaSample(
        octahedral_decode(pbr_deferred_types::unpack_24bit_normal(packed)),
        -depth_ndc_to_view_z(depth),
        id * 2u + (flags & pbr_deferred_types::DEFERRED_FLAGS_UNLIT_BIT),
        u32(msaa_shades_id(id)),
    );
}

// The view position of frame-buffer point `xy` at NDC depth `depth`.
fn msaa_view_position(xy: vec2<f32>, depth: f32) -> vec3<f32> {
    return position_ndc_to_view(frag_coord_to_ndc(vec4(xy, depth, 1.0)));
}

// The view depth, across the plane through `p` (view space) with view normal `n`, of
// the camera ray through frame-buffer point `xy` (a huge value when the ray runs along
// the plane).
fn msaa_plane_depth(xy: vec2<f32>, p: vec3<f32>, n: vec3<f32>) -> f32 {
    // Two points of the ray: the near plane (NDC depth 1, reversed Z) and NDC 0.5.
    let a = msaa_view_position(xy, 1.0);
    let b = msaa_view_position(xy, 0.5);
    let denom = dot(n, b - a);
    if abs(denom) < 1e-12 {
        return 1e30;
    }
    let t = dot(n, p - a) / denom;
    return -(a.z + t * (b.z - a.z));
}

// `|∂z/∂x| + |∂z/∂y|` of sample 0's tangent plane (metres per pixel): how far view
// depth may change across the pixel on one flat surface.
fn msaa_depth_slope(pixel: vec2<i32>, first: MsaaSample) -> f32 {
    let xy = msaa_sample_position(pixel, 0u);
    let depth = prepass_depth(vec4(vec2<f32>(pixel), 0.0, 0.0), 0u);
    let p = msaa_view_position(xy, depth);
    let n = normalize((view.view_from_world * vec4(first.normal, 0.0)).xyz);
    let dx = abs(msaa_plane_depth(xy + vec2(1.0, 0.0), p, n) - first.view_z);
    let dy = abs(msaa_plane_depth(xy + vec2(0.0, 1.0), p, n) - first.view_z);
    return min(dx + dy, 1e30);
}

// How `pixel` is shaded: 0 not at all (no sample holds this pass's material), 1 once,
// 2 per sample.
fn msaa_pixel_class(pixel: vec2<i32>) -> u32 {
    let samples = array(
        msaa_sample(pixel, 0u), msaa_sample(pixel, 1u), msaa_sample(pixel, 2u), msaa_sample(pixel, 3u),
    );
    let count = clamp(penumbra_msaa.edge.sample_count, 1u, 4u);
    var covered = 0u;
    for (var i = 0u; i < count; i++) {
        covered += samples[i].covered;
    }
    if covered == 0u {
        return 0u;
    }
    if penumbra_msaa.per_sample_everywhere != 0u {
        return 2u;
    }
    var z_slope = 0.0;
    if samples[0].covered != 0u {
        z_slope = msaa_depth_slope(pixel, samples[0]);
    }
    return select(1u, 2u, msaa_is_edge(samples, z_slope, penumbra_msaa.edge));
}

// Discards the fragment unless `pixel` is of class `class_id`.
fn keep_class(pixel: vec2<i32>, class_id: u32) {
    if textureLoad(msaa_class, pixel, 0).r != class_id {
        discard;
    }
}
