// Hair strips (`bevy_penumbra_cinematic::hair`): what the main pass (`hair/draw.wgsl`)
// and the prepass / shadow pass (`hair/prepass.wgsl`) share — the material's bindings,
// the camera-facing expansion of a strand's centre line in screen space, the minimum
// width with its alpha fade, and the coverage of a pixel's 2, 4 or 8 samples with an
// alpha test at each. The CPU model is `penumbra_cinematic_core::hair` (same sample
// positions, same thresholds, same strip coordinates).

#define_import_path penumbra::hair::common

#import bevy_pbr::{
    mesh_functions,
    skinning,
    mesh_view_bindings::view,
    view_transformations::position_world_to_clip,
}
#import penumbra::hair::samples::{hair_sample_offset, hair_sample_thresholds}

struct HairParams {
    // Linear RGB at the root and at the tip (alpha unused).
    root_color: vec4<f32>,
    tip_color: vec4<f32>,
    // Primary lobe: strength, exponent; secondary lobe (tinted by the hair): strength, exponent.
    specular: vec4<f32>,
    // Tangent shifts of the two lobes (Scheuermann), and the width scale.
    primary_shift: f32,
    secondary_shift: f32,
    width_scale: f32,
    atlas_slots: u32,
    flags: u32,
}

const HAIR_FLAG_ATLAS: u32 = 1u;
const HAIR_FLAG_DEBUG_COVERAGE: u32 = 2u;

@group(#{MATERIAL_BIND_GROUP}) @binding(0) var<uniform> hair: HairParams;
@group(#{MATERIAL_BIND_GROUP}) @binding(1) var hair_atlas: texture_2d<f32>;
@group(#{MATERIAL_BIND_GROUP}) @binding(2) var hair_sampler: sampler;

// The narrowest strand drawn, pixels (`hair::MIN_WIDTH_PX`).
const MIN_WIDTH_PX: f32 = 0.5;

// The MSAA sample count the strips are drawn with (`HAIR_SAMPLES_2`, `HAIR_SAMPLES_8`;
// otherwise 4, also the pattern of the fade's thresholds without MSAA).
#ifdef HAIR_SAMPLES_8
const HAIR_SAMPLES: u32 = 8u;
#else
#ifdef HAIR_SAMPLES_2
const HAIR_SAMPLES: u32 = 2u;
#else
const HAIR_SAMPLES: u32 = 4u;
#endif
#endif

struct HairVertex {
    @builtin(instance_index) instance_index: u32,
    // Two vertices per centre-line point (`hair::strip_mesh`): the point is
    // `(vertex_index − first_vertex_index) / 2`.
    @builtin(vertex_index) vertex_index: u32,
    // A point of the strand's centre line, hair space.
    @location(0) position: vec3<f32>,
    // The strand's direction there.
    @location(1) tangent: vec3<f32>,
    // Side (−1, +1), u along the strand (0 root, 1 tip), width (metres), atlas slot.
    @location(2) strip: vec4<f32>,
#ifdef SKINNED
    @location(3) joint_indices: vec4<u32>,
    @location(4) joint_weights: vec4<f32>,
#endif
}

struct HairVaryings {
    @builtin(position) position: vec4<f32>,
    // The centre line's point (lighting and shadows are evaluated on it).
    @location(0) world_position: vec4<f32>,
    @location(1) world_tangent: vec3<f32>,
    // u along the strand, v across (0 and 1 at the edges).
#ifdef HAIR_SAMPLE_SHADING
    @location(2) @interpolate(perspective, sample) uv: vec2<f32>,
#else
    @location(2) uv: vec2<f32>,
#endif
    // The alpha fade of strands narrower than the minimum width.
    @location(3) fade: f32,
    @location(4) @interpolate(flat) slot: u32,
#ifdef UNCLIPPED_DEPTH_ORTHO_EMULATION
    @location(5) unclipped_depth: f32,
#endif
#ifdef MOTION_VECTOR_PREPASS
    @location(6) previous_world_position: vec4<f32>,
#endif
#ifndef PREPASS_PIPELINE
    // The centre line's visibility of up to four distance-field-shadowed lights
    // (`penumbra::hair::shadows`; 1 without).
    @location(7) df_visibility: vec4<f32>,
#endif
}

fn hair_world_from_local(vertex: HairVertex) -> mat4x4<f32> {
#ifdef SKINNED
    return skinning::skin_model(vertex.joint_indices, vertex.joint_weights, vertex.instance_index);
#else
    return mesh_functions::get_world_from_local(vertex.instance_index);
#endif
}

// A strand's drawn width (pixels) and alpha fade (`hair::clamp_width`).
fn clamp_width(width_px: f32) -> vec2<f32> {
    if !(width_px > 0.0) {
        return vec2(MIN_WIDTH_PX, 0.0);
    }
    if width_px < MIN_WIDTH_PX {
        return vec2(MIN_WIDTH_PX, width_px / MIN_WIDTH_PX);
    }
    return vec2(width_px, 1.0);
}

// The strand's direction on screen at a clip-space point (pixels, y down): the
// derivative of the projected point along the world tangent.
fn screen_direction(clip: vec4<f32>, world_tangent: vec3<f32>, half_size: vec2<f32>) -> vec2<f32> {
    let clip_t = view.clip_from_world * vec4(world_tangent, 0.0);
    let along = (clip_t.xy * clip.w - clip.xy * clip_t.w) * half_size * vec2(1.0, -1.0);
    if !(dot(along, along) > 0.0) {
        return vec2(1.0, 0.0);
    }
    return normalize(along);
}

// The vertex on the strip's edge: the centre line's point moved across the strand's
// screen direction by half the drawn width (pixels), so the strip faces the camera.
fn hair_vertex(vertex: HairVertex) -> HairVaryings {
    var out: HairVaryings;
    let world_from_local = hair_world_from_local(vertex);
    out.world_position = world_from_local * vec4(vertex.position, 1.0);
    let tangent = (world_from_local * vec4(vertex.tangent, 0.0)).xyz;
    out.world_tangent = tangent / max(length(tangent), 1e-20);
    // Widths scale with the transform (uniform scale assumed: its x axis).
    let scale = length(world_from_local[0].xyz);
    let clip = position_world_to_clip(out.world_position.xyz);
    let half_size = 0.5 * view.viewport.zw;
    let width_px = vertex.strip.z * hair.width_scale * scale * view.clip_from_view[1][1] * half_size.y / clip.w;
    let drawn = clamp_width(width_px);
    let d = screen_direction(clip, out.world_tangent, half_size);
    let offset_px = vec2(-d.y, d.x) * (0.5 * drawn.x * vertex.strip.x);
    out.position = clip + vec4(offset_px / half_size * vec2(1.0, -1.0) * clip.w, 0.0, 0.0);
    out.uv = vec2(vertex.strip.y, 0.5 + 0.5 * vertex.strip.x);
    out.fade = drawn.y;
    out.slot = u32(max(vertex.strip.w, 0.0));
#ifdef UNCLIPPED_DEPTH_ORTHO_EMULATION
    out.unclipped_depth = out.position.z;
    out.position.z = min(out.position.z, 1.0);
#endif
#ifdef MOTION_VECTOR_PREPASS
    out.previous_world_position = mesh_functions::get_previous_world_from_local(vertex.instance_index)
        * vec4(vertex.position, 1.0);
#endif
    return out;
}

// The atlas texel of a strip point: slot `slot`'s column, across the hair (v) along x,
// along it (u) down y.
fn atlas_coordinates(uv: vec2<f32>, slot: u32) -> vec2<f32> {
    return vec2((f32(slot) + clamp(uv.y, 0.0, 1.0)) / f32(max(hair.atlas_slots, 1u)), uv.x);
}

// The alpha test's cutoff (`hair::ALPHA_CUTOFF`).
const ALPHA_CUTOFF: f32 = 0.5;

// The atlas's alpha at strip point `uv` (1 without an atlas).
fn atlas_alpha(uv: vec2<f32>, slot: u32, ddx: vec2<f32>, ddy: vec2<f32>) -> f32 {
    if (hair.flags & HAIR_FLAG_ATLAS) == 0u {
        return 1.0;
    }
    let s = vec2(1.0 / f32(max(hair.atlas_slots, 1u)), 1.0);
    return textureSampleGrad(
        hair_atlas, hair_sampler, atlas_coordinates(uv, slot), ddx.yx * s, ddy.yx * s
    ).a;
}

// The samples' alpha thresholds at a pixel (`hair::sample_thresholds_for`): the steps
// (k + ½) / HAIR_SAMPLES permuted per pixel by a hash.
fn sample_thresholds(pixel: vec2<i32>) -> array<f32, 8> {
    return hair_sample_thresholds(pixel, HAIR_SAMPLES);
}

// The coverage mask of a fragment (bit i for sample i; the rasterizer keeps only the
// samples inside the strip): sample i passes where the atlas's alpha reaches the cutoff
// and the width fade reaches its threshold (`hair::coverage_mask_for`). Under MSAA
// (2×, 4×, 8×: the standard patterns) the alpha is tested at each sample, its strip coordinates extrapolated from the pixel
// centre's by the derivatives (exact: they are affine in the pixel); otherwise
// (`Msaa::Off`, or the per-pixel comparison) once at the centre, with the pixel's first
// threshold.
fn hair_coverage(in: HairVaryings) -> u32 {
    let ddx = dpdx(in.uv);
    let ddy = dpdy(in.uv);
    var thresholds = sample_thresholds(vec2<i32>(floor(in.position.xy)));
#ifdef HAIR_PER_SAMPLE
    var mask = 0u;
    for (var i = 0u; i < HAIR_SAMPLES; i += 1u) {
        let o = hair_sample_offset(i, HAIR_SAMPLES);
        let alpha = atlas_alpha(in.uv + ddx * o.x + ddy * o.y, in.slot, ddx, ddy);
        if alpha >= ALPHA_CUTOFF && in.fade >= thresholds[i] {
            mask |= 1u << i;
        }
    }
    return mask;
#else
    let alpha = atlas_alpha(clamp(in.uv, vec2(0.0), vec2(1.0)), in.slot, ddx, ddy);
    return select(0u, 0xffffffffu, alpha >= ALPHA_CUTOFF && in.fade >= thresholds[0]);
#endif
}
