// Penumbra's lighting pass: a fullscreen triangle over the deferred G-buffer (depth-id
// tested like Bevy's deferred lighting pass, which Penumbra replaces on its cameras),
// lit by Penumbra's light loop.

#import bevy_pbr::{
    prepass_utils,
    pbr_types::STANDARD_MATERIAL_FLAGS_UNLIT_BIT,
    pbr_functions,
    pbr_types,
    pbr_deferred_functions::pbr_input_from_deferred_gbuffer,
    lighting,
    mesh_view_bindings::deferred_prepass_texture,
}
#import penumbra::lighting::lights::{apply_lighting, apply_lighting_with_diffuse_color}
#import penumbra::lighting::masks::penumbra_lighting
#ifdef PENUMBRA_MSAA
#import penumbra::lighting::masks::set_shading_sample
#import penumbra::lighting::msaa_view
#endif

#ifdef SCREEN_SPACE_AMBIENT_OCCLUSION
#import bevy_pbr::mesh_view_bindings::screen_space_ambient_occlusion_texture
#import bevy_pbr::ssao_utils::ssao_multibounce
#endif

struct FullscreenVertexOutput {
    @builtin(position) position: vec4<f32>,
    @location(0) uv: vec2<f32>,
}

@vertex
fn vertex(@builtin(vertex_index) vertex_index: u32) -> FullscreenVertexOutput {
    let uv = vec2<f32>(f32(vertex_index >> 1u), f32(vertex_index & 1u)) * 2.0;
    // The lighting-id depth texture stores the material's pass id as unorm depth.
#ifdef PENUMBRA_LIGHTING_IDS_FROM
    // Every id from PENUMBRA_LIGHTING_IDS_FROM up (with the depth test `Less`).
    let depth = (f32(#{PENUMBRA_LIGHTING_IDS_FROM}) - 0.5) / 255.0;
#else
    let depth = f32(penumbra_lighting.depth_id) / 255.0;
#endif
    return FullscreenVertexOutput(vec4(uv * vec2(2.0, -2.0) + vec2(-1.0, 1.0), depth, 1.0), uv);
}

@fragment
fn fragment(in: FullscreenVertexOutput) -> @location(0) vec4<f32> {
    return shade(gbuffer_input(in.position));
}

// The G-buffer sample under a fragment (single-sample views).
fn gbuffer_input(position: vec4<f32>) -> pbr_types::PbrInput {
    var frag_coord = vec4(position.xy, 0.0, 0.0);
    let gbuffer = textureLoad(deferred_prepass_texture, vec2<i32>(frag_coord.xy), 0);
#ifdef DEPTH_PREPASS
    frag_coord.z = prepass_utils::prepass_depth(position, 0u);
#endif
    return pbr_input_from_deferred_gbuffer(frag_coord, gbuffer);
}

// Shades one G-buffer sample.
fn shade(input: pbr_types::PbrInput) -> vec4<f32> {
    let pbr_input = with_screen_space_occlusion(input);
    var color = pbr_input.material.base_color;
    if is_lit(pbr_input) {
        color = apply_lighting(pbr_input);
    }
    return pbr_functions::main_pass_post_lighting_processing(pbr_input, color);
}

fn is_lit(in: pbr_types::PbrInput) -> bool {
    return (in.material.flags & STANDARD_MATERIAL_FLAGS_UNLIT_BIT) == 0u;
}

// The sample's occlusion with Bevy's SSAO folded in (when the view has it).
fn with_screen_space_occlusion(input: pbr_types::PbrInput) -> pbr_types::PbrInput {
    var pbr_input = input;
    if is_lit(pbr_input) {
#ifdef SCREEN_SPACE_AMBIENT_OCCLUSION
        let ssao = textureLoad(screen_space_ambient_occlusion_texture, vec2<i32>(pbr_input.frag_coord.xy), 0i).r;
        pbr_input.diffuse_occlusion = min(pbr_input.diffuse_occlusion, ssao_multibounce(ssao, pbr_input.material.base_color.rgb));
        // Specular occlusion from SSAO (Lagarde and Rousiers 2014), as Bevy does.
        let NdotV = max(dot(pbr_input.N, pbr_input.V), 0.0001);
        let roughness = lighting::perceptualRoughnessToRoughness(pbr_input.material.perceptual_roughness);
        pbr_input.specular_occlusion = saturate(pow(NdotV + ssao, exp2(-16.0 * roughness - 1.0)) - 1.0 + ssao);
#endif
    }
    return pbr_input;
}

#ifdef PENUMBRA_SPLIT_DIFFUSE
// The split lighting pass (subsurface scattering: `bevy_penumbra_cinematic::sss`): each
// sample's light in two targets, before fog and tonemapping — everything that does not
// scale with the albedo (specular, emissive, the ambient's Fresnel part), and the diffuse
// irradiance (exposed, before the diffuse colour), so that a later pass can filter the
// irradiance and apply the diffuse colour after (`apply_lighting_with_diffuse_color`).
struct SplitDiffuse {
    @location(0) rest: vec4<f32>,
    @location(1) diffuse: vec4<f32>,
}

@fragment
fn split_diffuse(in: FullscreenVertexOutput) -> SplitDiffuse {
    let pbr_input = with_screen_space_occlusion(gbuffer_input(in.position));
    if !is_lit(pbr_input) {
        return SplitDiffuse(pbr_input.material.base_color, vec4(0.0, 0.0, 0.0, 1.0));
    }
    return split_lighting(pbr_input, 1.0);
}

// The two targets of a lit sample; `marker` is the irradiance's alpha.
fn split_lighting(pbr_input: pbr_types::PbrInput, marker: f32) -> SplitDiffuse {
    let rest = apply_lighting_with_diffuse_color(pbr_input, vec3(0.0));
    let white = apply_lighting_with_diffuse_color(pbr_input, vec3(1.0));
    return SplitDiffuse(rest, vec4(white.rgb - rest.rgb, marker));
}

#ifdef PENUMBRA_MSAA
// Deferred MSAA: the split lighting once per pixel that holds a scattering material,
// from its first sample that does (the shadow masks and AO per pixel). The irradiance's
// alpha is that sample's lighting id (the scatter draw's profile test: the lighting ids
// are multisampled); pixels without one are left cleared (alpha 0).
@fragment
fn split_diffuse_msaa(in: FullscreenVertexOutput) -> SplitDiffuse {
    let pixel = vec2<i32>(in.position.xy);
    var sample = 4u;
    var id = 0u;
    for (var i = 3; i >= 0; i--) {
        let sample_id = textureLoad(msaa_view::msaa_lighting_id, pixel, i).r;
        if sample_id >= #{PENUMBRA_LIGHTING_IDS_FROM} {
            sample = u32(i);
            id = sample_id;
        }
    }
    if sample == 4u {
        discard;
    }
    let frag_coord = vec4(in.position.xy, prepass_utils::prepass_depth(in.position, sample), 0.0);
    let gbuffer = textureLoad(msaa_view::msaa_gbuffer, pixel, i32(sample));
    let pbr_input = with_screen_space_occlusion(pbr_input_from_deferred_gbuffer(frag_coord, gbuffer));
    if !is_lit(pbr_input) {
        return SplitDiffuse(pbr_input.material.base_color, vec4(0.0, 0.0, 0.0, f32(id)));
    }
    return split_lighting(pbr_input, f32(id));
}
#endif
#endif

#ifdef PENUMBRA_MSAA
// Deferred 4× MSAA (`lighting/msaa_view.wgsl`): the stencil marks each pixel 1 (its
// samples agree: shaded once) or 2 (an edge: shaded per sample).

// A pixel whose samples agree, shaded once at its centre: the samples' mean NDC depth
// (exact at the centre on a plane: the pattern's centroid is the centre) and mean
// normal, sample 0's material.
@fragment
fn fragment_msaa_pixel(in: FullscreenVertexOutput) -> @location(0) vec4<f32> {
    let pixel = vec2<i32>(in.position.xy);
    var depth = 0.0;
    var normal = vec3(0.0);
    for (var i = 0u; i < 4u; i++) {
        depth += prepass_utils::prepass_depth(in.position, i);
        normal += msaa_view::msaa_sample_normal(pixel, i);
    }
    let frag_coord = vec4(in.position.xy, depth * 0.25, 0.0);
    var pbr_input = pbr_input_from_deferred_gbuffer(frag_coord, textureLoad(msaa_view::msaa_gbuffer, pixel, 0));
    let n = normalize(normal);
    pbr_input.N = n;
    pbr_input.world_normal = n;
    pbr_input.clearcoat_N = n;
    return shade(pbr_input);
}

// One sample of an edge pixel, shaded at its own position (the stencil holds only the
// samples of this pass's material: the others are left to the passes that draw them).
// No `discard`: the stencil test can run before shading.
@fragment
fn fragment_msaa_sample(
    in: FullscreenVertexOutput,
    @builtin(sample_index) sample_index: u32,
) -> @location(0) vec4<f32> {
    let pixel = vec2<i32>(in.position.xy);
    let xy = msaa_view::msaa_sample_position(pixel, sample_index);
    let frag_coord = vec4(xy, prepass_utils::prepass_depth(in.position, sample_index), 0.0);
    let gbuffer = textureLoad(msaa_view::msaa_gbuffer, pixel, i32(sample_index));
    let settings = msaa_view::penumbra_msaa;
    set_shading_sample(sample_index, settings.sample_shadows != 0u, settings.sample_ao != 0u);
    let color = shade(pbr_input_from_deferred_gbuffer(frag_coord, gbuffer));
    if msaa_view::penumbra_msaa.show_edges != 0u {
        return vec4(mix(color.rgb, vec3(1.0, 0.0, 1.0), 0.6), color.a);
    }
    return color;
}
#endif
