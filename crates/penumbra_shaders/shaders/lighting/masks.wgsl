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
    // Unused (16-byte uniform).
    reserved: vec2<u32>,
}

const SHADOWED_DIRECTIONAL: u32 = 0u;
const SHADOWED_CLUSTERED: u32 = 1u;

@group(2) @binding(0) var<uniform> penumbra_lighting: PenumbraLightingUniform;
@group(2) @binding(1) var<storage, read> shadowed_lights: array<PenumbraShadowedLight>;
@group(2) @binding(2) var shadow_masks: texture_2d_array<f32>;

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
