// Penumbra's per-view lighting inputs (group 2 of the lighting pass): which lights
// take their visibility from a Penumbra shadow mask, and the masks.

#define_import_path penumbra::lighting::masks

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
    reserved: u32,
}

const SHADOWED_DIRECTIONAL: u32 = 0u;
const SHADOWED_CLUSTERED: u32 = 1u;

@group(2) @binding(0) var<uniform> penumbra_lighting: PenumbraLightingUniform;
@group(2) @binding(1) var<storage, read> shadowed_lights: array<PenumbraShadowedLight>;
@group(2) @binding(2) var shadow_masks: texture_2d_array<f32>;
// Distance-field AO at the view's size: AO, then the world-space bent normal.
@group(2) @binding(3) var ambient_occlusion: texture_2d<f32>;

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
    return textureLoad(shadow_masks, vec2<i32>(frag_xy), layer, 0).r;
}
