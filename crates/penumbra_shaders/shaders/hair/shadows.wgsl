// Hair under distance-field-shadowed lights (`bevy_penumbra_cinematic::hair`, `shadows`
// feature): the buffer a hair entity's strips read their visibility from. A compute
// pass (`hair/df_visibility.wgsl`) writes, for every point of the strands' centre lines,
// the visibility of up to four lights through the scene's distance fields; the vertex
// shader reads its point's, the fragment shader picks a light's by matching Bevy's
// light ids (as Penumbra's lighting pass matches its masks, `lighting/masks.wgsl`).
#define_import_path penumbra::hair::shadows

// Lights one hair entity takes from the distance fields.
const MAX_HAIR_SHADOW_LIGHTS: u32 = 4u;

const HAIR_SHADOW_DIRECTIONAL: u32 = 0u;
const HAIR_SHADOW_CLUSTERED: u32 = 1u;
// A light's slot when nothing was traced (no caster in the scene): lit.
const HAIR_SHADOW_UNTRACED: u32 = 4u;

// One light whose visibility comes from the distance fields.
struct HairShadowedLight {
    // x: 0 directional, 1 point or spot; y: the clustered light id (point, spot);
    // z: the slot in each point's visibility (4: untraced, lit); w: unused.
    ids: vec4<u32>,
    // Directional lights: unit vector toward the light (matched against Bevy's list).
    direction: vec4<f32>,
}

struct HairShadows {
    // x: lights in `lights`; y: points in `points`.
    counts: vec4<u32>,
    lights: array<HairShadowedLight, 4>,
    // Per centre-line point (in the strip mesh's order, two vertices each): the
    // visibility of slots 0..3 (1 lit, 0 shadowed).
    points: array<vec4<f32>>,
}

// A slot's visibility from the point's (interpolated) visibilities.
fn slot_visibility(visibility: vec4<f32>, slot: i32) -> f32 {
    if slot >= 0 && slot < 4 {
        return visibility[slot];
    }
    return 1.0;
}
