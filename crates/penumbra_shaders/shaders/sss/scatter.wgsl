// Subsurface scattering's scatter draw (`bevy_penumbra_cinematic::sss`): on the pixels
// of scattering materials (lighting ids from `first_id` up, depth-tested against Bevy's
// lighting-id texture), gathers the split lighting pass's diffuse irradiance over a disc
// on the tangent plane, weighted by Burley's profile per channel, then applies the
// diffuse colour, adds the rest of the light and runs Bevy's post-lighting processing.
// CPU model: `penumbra_reference::sss::scatter_screen`.

#import bevy_pbr::{
    prepass_utils,
    pbr_functions,
    pbr_types,
    pbr_types::STANDARD_MATERIAL_FLAGS_UNLIT_BIT,
    pbr_deferred_functions::pbr_input_from_deferred_gbuffer,
    mesh_view_bindings::{view, deferred_prepass_texture, depth_prepass_texture},
    view_transformations::{position_ndc_to_world, uv_to_ndc, ndc_to_uv},
}
#import penumbra::sss::profile::{disc_offset, pixel_noise, tangent_frame, sample_weight}

const MAX_PROFILES: u32 = 64u;
const TAU: f32 = 6.28318530717959;

// `penumbra_cinematic_core::sss::SubsurfaceUniform`.
struct SubsurfaceUniform {
    samples: u32,
    frame: u32,
    first_id: u32,
    // 0 shading; 1 irradiance before scattering, 2 after (alpha 2 + profile).
    debug_view: u32,
    // Per profile: Burley's d per channel (metres).
    profiles: array<vec4<f32>, MAX_PROFILES>,
}

@group(2) @binding(0) var<uniform> subsurface: SubsurfaceUniform;
// The split lighting pass's targets: the light that is not scattered, and the diffuse
// irradiance (exposed, before the diffuse colour).
@group(2) @binding(1) var rest_light: texture_2d<f32>;
@group(2) @binding(2) var diffuse_irradiance: texture_2d<f32>;
#ifdef PENUMBRA_SSS_MSAA
// Deferred MSAA: Bevy's lighting pass ids and G-buffer words per sample. A pixel's id
// is the irradiance's alpha (the split lighting's first scattering sample).
@group(2) @binding(3) var msaa_lighting_ids: texture_multisampled_2d<u32>;
@group(2) @binding(4) var msaa_gbuffer: texture_multisampled_2d<u32>;
#else
// Bevy's deferred lighting pass ids (`R8Uint`): the profile is `id − first_id`.
@group(2) @binding(3) var lighting_ids: texture_2d<u32>;
#endif

struct FullscreenVertexOutput {
    @builtin(position) position: vec4<f32>,
}

// A fullscreen triangle at the depth just under the first scattering id: with the test
// `Less`, only scattering pixels are shaded.
@vertex
fn vertex(@builtin(vertex_index) vertex_index: u32) -> FullscreenVertexOutput {
    let uv = vec2<f32>(f32(vertex_index >> 1u), f32(vertex_index & 1u)) * 2.0;
    let depth = (f32(subsurface.first_id) - 0.5) / 255.0;
    return FullscreenVertexOutput(vec4(uv * vec2(2.0, -2.0) + vec2(-1.0, 1.0), depth, 1.0));
}

#ifndef PENUMBRA_SSS_MSAA
@fragment
fn scatter(in: FullscreenVertexOutput) -> @location(0) vec4<f32> {
    let pixel = vec2<i32>(in.position.xy);
    let frag_coord = vec4(in.position.xy, prepass_utils::prepass_depth(in.position, 0u), 0.0);
    let pbr_input = pbr_input_from_deferred_gbuffer(frag_coord, textureLoad(deferred_prepass_texture, pixel, 0));
    return scattered_color(pixel, pbr_input, pixel_id(pixel) - subsurface.first_id);
}

// The lighting pass id of frame-buffer pixel `j`.
fn pixel_id(j: vec2<i32>) -> u32 {
    return textureLoad(lighting_ids, j, 0).r;
}
#else
struct MsaaScatterOutput {
    @location(0) color: vec4<f32>,
    @builtin(sample_mask) mask: u32,
}

// Deferred MSAA, drawn after the lighting pass: once per pixel, from its first
// scattering sample, into the samples that hold a scattering material (the sample
// mask), replacing their unscattered shading; the other samples keep theirs.
@fragment
fn scatter_msaa(in: FullscreenVertexOutput) -> MsaaScatterOutput {
    let pixel = vec2<i32>(in.position.xy);
    var mask = 0u;
    var first = 4u;
    for (var i = 3; i >= 0; i--) {
        if textureLoad(msaa_lighting_ids, pixel, i).r >= subsurface.first_id {
            mask |= 1u << u32(i);
            first = u32(i);
        }
    }
    if mask == 0u {
        discard;
    }
    let frag_coord = vec4(in.position.xy, prepass_utils::prepass_depth(in.position, first), 0.0);
    let gbuffer = textureLoad(msaa_gbuffer, pixel, i32(first));
    let pbr_input = pbr_input_from_deferred_gbuffer(frag_coord, gbuffer);
    let profile = pixel_id(pixel) - subsurface.first_id;
    return MsaaScatterOutput(scattered_color(pixel, pbr_input, profile), mask);
}

// The scattering lighting id of frame-buffer pixel `j` (0: none), as the split
// lighting marked it.
fn pixel_id(j: vec2<i32>) -> u32 {
    return u32(textureLoad(diffuse_irradiance, j, 0).a);
}
#endif

// A scattering pixel's colour: the scattered irradiance times its diffuse colour, plus
// the light that is not scattered, post-processed (or a debug view).
fn scattered_color(pixel: vec2<i32>, pbr_input: pbr_types::PbrInput, profile: u32) -> vec4<f32> {
    let scattered = scattered_irradiance(pixel, pbr_input.world_position.xyz, pbr_input.N, profile);
    if subsurface.debug_view == 1u {
        return vec4(textureLoad(diffuse_irradiance, pixel, 0).rgb, 2.0 + f32(profile));
    }
    if subsurface.debug_view == 2u {
        return vec4(scattered, 2.0 + f32(profile));
    }
    var color = textureLoad(rest_light, pixel, 0);
    if (pbr_input.material.flags & STANDARD_MATERIAL_FLAGS_UNLIT_BIT) == 0u {
        // The albedo after the blur: the pixel's own diffuse colour (deferred materials
        // have no transmission).
        let diffuse_color = pbr_functions::calculate_diffuse_color(
            pbr_input.material.base_color.rgb, pbr_input.material.metallic, 0.0, 0.0
        );
        color = vec4(color.rgb + diffuse_color * scattered, color.a);
    }
    return pbr_functions::main_pass_post_lighting_processing(pbr_input, color);
}

// The world position of frame-buffer pixel `j`'s centre on the surface it shows (the
// view's UVs span its viewport, `view.viewport`: split screen).
fn pixel_position(j: vec2<i32>) -> vec3<f32> {
    let depth = textureLoad(depth_prepass_texture, j, 0);
    let uv = (vec2<f32>(j) + 0.5 - view.viewport.xy) / view.viewport.zw;
    return position_ndc_to_world(vec3(uv_to_ndc(uv), depth));
}

// The diffuse irradiance of pixel `pixel` (surface point `p`, unit normal `n`, profile
// `k`) scattered over its surface: `samples` disc points projected to the screen, kept
// where the pixel there has the same profile, weighted per channel and normalised.
fn scattered_irradiance(pixel: vec2<i32>, p: vec3<f32>, n: vec3<f32>, k: u32) -> vec3<f32> {
    let own = textureLoad(diffuse_irradiance, pixel, 0).rgb;
    let d = subsurface.profiles[k].xyz;
    let d_max = max(d.x, max(d.y, d.z));
    if !(d_max > 0.0) {
        return own;
    }
    let tangents = tangent_frame(n);
    // Seeded by the pixel's place in the viewport: a split screen's halves match their
    // cameras alone.
    let noise = pixel_noise(vec2<u32>(vec2<f32>(pixel) - view.viewport.xy), subsurface.frame);
    // The view's viewport in the frame buffer (the textures are the render target's).
    let origin = view.viewport.xy;
    let size = view.viewport.zw;
    let id = subsurface.first_id + k;
    var sum = vec3(0.0);
    var weights = vec3(0.0);
    for (var i = 0u; i < subsurface.samples; i += 1u) {
        let o = disc_offset(i, subsurface.samples, noise.x * TAU, noise.y, d_max);
        let clip = view.clip_from_world * vec4(p + tangents[0] * o.x + tangents[1] * o.y, 1.0);
        if !(clip.w > 0.0) {
            continue;
        }
        let local = ndc_to_uv(clip.xy / clip.w) * size;
        if any(local < vec2(0.0)) || any(local >= size) {
            continue;
        }
        let xy = origin + local;
        let j = vec2<i32>(xy);
        if pixel_id(j) != id {
            continue;
        }
        // The distance between the surface points, never under the disc radius (never 0).
        let disc = max(length(o), 1e-6 * d_max);
        let r = max(length(pixel_position(j) - p), disc);
        let w = sample_weight(r, disc, d, d_max);
        sum += w * textureLoad(diffuse_irradiance, j, 0).rgb;
        weights += w;
    }
    return select(own, sum / weights, weights > vec3(0.0));
}
