// Penumbra's per-view lighting inputs (group 2 of the lighting pass): which lights
// take their visibility from a Penumbra shadow mask, and the masks.

#define_import_path penumbra::lighting::masks

#import penumbra::lighting::msaa::msaa_sample_texel

// One light whose visibility comes from a mask.
struct PenumbraShadowedLight {
    // x: 0 directional, 1 point or spot; y: the clustered light id (point, spot);
    // z: mask layer; w: unused.
    ids: vec4<u32>,
    // Directional lights: unit vector toward the light (matched against Bevy's list).
    direction: vec4<f32>,
}

struct PenumbraLightingUniform {
    // Bevy's deferred lighting pass id (the G-buffer's material depth id).
    depth_id: u32,
    shadowed_light_count: u32,
    // Distance-field AO: 1 when `ambient_occlusion` holds it; specular occlusion mode
    // (0 none, 1 non-directional, 2 cone–cone); tint (linear rgb, `AmbientLight` units);
    // contrast and min occlusion; debug view (0 none, 1 AO, 2 bent normal,
    // 3 objects per tile).
    ao_enabled: u32,
    ao_specular_occlusion: u32,
    ao_tint: vec4<f32>,
    ao_contrast: f32,
    ao_min_occlusion: f32,
    ao_debug_view: u32,
    // A specular layer (`PenumbraSpecularLayer`): 0 none, 1 full resolution, 2 half;
    // +4: show it instead of the lighting.
    specular_layer: u32,
    // Deferred MSAA also shades lighting ids from this one up (`MsaaShadedLightingIds`).
    msaa_shaded_ids_from: u32,
}

const SHADOWED_DIRECTIONAL: u32 = 0u;
const SHADOWED_CLUSTERED: u32 = 1u;

@group(2) @binding(0) var<uniform> penumbra_lighting: PenumbraLightingUniform;
@group(2) @binding(1) var<storage, read> shadowed_lights: array<PenumbraShadowedLight>;
@group(2) @binding(2) var shadow_masks: texture_2d_array<f32>;
// Distance-field AO at the view's size: AO, then the world-space bent normal.
@group(2) @binding(3) var ambient_occlusion: texture_2d<f32>;

// The specular layer: premultiplied reflected radiance (before exposure) and coverage.
#ifdef PENUMBRA_MSAA
@group(2) @binding(10) var specular_layer: texture_2d<f32>;
#else
@group(2) @binding(4) var specular_layer: texture_2d<f32>;
#endif

#ifdef PENUMBRA_MSAA
// Deferred MSAA: the masks and the AO of edge pixels per sample (twice the view's size,
// `msaa_sample_texel`), 1-texel placeholders where they are not traced.
@group(2) @binding(8) var sample_shadow_masks: texture_2d_array<f32>;
@group(2) @binding(9) var sample_ambient_occlusion: texture_2d<f32>;

// The sample being shaded when the masks and the AO hold it per sample (-1: read them
// per pixel). Set by the per-sample lighting entry (`set_shading_sample`).
var<private> shadow_sample: i32 = -1;
var<private> ao_sample: i32 = -1;

// Per-sample shading of sample `i`: whether the view traced its masks and its AO per
// sample.
fn set_shading_sample(i: u32, shadows: bool, ao: bool) {
    shadow_sample = select(-1, i32(i), shadows);
    ao_sample = select(-1, i32(i), ao);
}
#endif

// The mask layer of clustered light `light_id`, or -1.
fn clustered_light_mask(light_id: u32) -> i32 {
    for (var i = 0u; i < penumbra_lighting.shadowed_light_count; i += 1u) {
        let ids = shadowed_lights[i].ids;
        if ids.x == SHADOWED_CLUSTERED && ids.y == light_id {
            return i32(ids.z);
        }
    }
    return -1;
}

// The mask layer of the directional light shining from `direction_to_light`, or -1.
fn directional_light_mask(direction_to_light: vec3<f32>) -> i32 {
    for (var i = 0u; i < penumbra_lighting.shadowed_light_count; i += 1u) {
        let light = shadowed_lights[i];
        if light.ids.x == SHADOWED_DIRECTIONAL && dot(light.direction.xyz, direction_to_light) > 0.99999 {
            return i32(light.ids.z);
        }
    }
    return -1;
}

fn mask_visibility(layer: i32, frag_xy: vec2<f32>) -> f32 {
#ifdef PENUMBRA_MSAA
    if shadow_sample >= 0 {
        let texel = msaa_sample_texel(vec2<i32>(frag_xy), u32(shadow_sample));
        return textureLoad(sample_shadow_masks, texel, layer, 0).r;
    }
#endif
    return textureLoad(shadow_masks, vec2<i32>(frag_xy), layer, 0).r;
}

// The view's AO texel at `frag_xy` (AO, bent normal): the shaded sample's where it is
// traced per sample.
fn ao_texel(frag_xy: vec2<f32>) -> vec4<f32> {
#ifdef PENUMBRA_MSAA
    if ao_sample >= 0 {
        return textureLoad(sample_ambient_occlusion, msaa_sample_texel(vec2<i32>(frag_xy), u32(ao_sample)), 0);
    }
#endif
    return textureLoad(ambient_occlusion, vec2<i32>(frag_xy), 0);
}
