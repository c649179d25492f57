// Penumbra's light loop: Bevy's `StandardMaterial` lighting of a deferred G-buffer
// sample, where each light's visibility comes either from Bevy's shadow maps or from a
// Penumbra shadow mask (distance-field shadows). Written against Bevy 0.19's
// `bevy_pbr::lighting` BRDF functions; it covers what Bevy's deferred G-buffer can hold
// (no transmission, anisotropy or lightmaps: the deferred pipeline never defines them).
//
// Bindings used: Bevy's view bind groups (0, 1); Penumbra's masks (group 2, in
// `penumbra::lighting::masks`).

#define_import_path penumbra::lighting::lights

#import bevy_pbr::{
    pbr_types,
    mesh_view_bindings as view_bindings,
    mesh_view_types,
    lighting,
    lighting::{LAYER_BASE, LAYER_CLEARCOAT},
    clustered_forward as clustering,
    shadows,
    ambient,
    pbr_functions,
    mesh_types::MESH_FLAGS_SHADOW_RECEIVER_BIT,
}
#import penumbra::lighting::masks::{
    clustered_light_mask, directional_light_mask, mask_visibility, penumbra_lighting,
    specular_layer,
}
#import bevy_pbr::view_transformations::depth_ndc_to_view_z
#import penumbra::lighting::ao::{penumbra_ao, penumbra_ao_specular, penumbra_ao_tile_heat}

#ifdef IRRADIANCE_VOLUME
#import bevy_pbr::irradiance_volume
#endif

#ifdef ENVIRONMENT_MAP
#import bevy_pbr::environment_map
#endif

// The BRDF inputs of one G-buffer sample (Bevy's `LightingInput`), with clearcoat.
fn lighting_input(in: pbr_types::PbrInput) -> lighting::LightingInput {
    let base_color = in.material.base_color.rgb;
    let perceptual_roughness = in.material.perceptual_roughness;
    var input: lighting::LightingInput;
    input.layers[LAYER_BASE].NdotV = max(dot(in.N, in.V), 0.0001);
    input.layers[LAYER_BASE].N = in.N;
    input.layers[LAYER_BASE].R = reflect(-in.V, in.N);
    input.layers[LAYER_BASE].perceptual_roughness = perceptual_roughness;
    input.layers[LAYER_BASE].roughness = lighting::perceptualRoughnessToRoughness(perceptual_roughness);
    input.P = in.world_position.xyz;
    input.V = in.V;
    input.diffuse_color = pbr_functions::calculate_diffuse_color(
        base_color,
        in.material.metallic,
        in.material.specular_transmission,
        in.material.diffuse_transmission,
    );
    input.metallic = in.material.metallic;
    input.F0_dielectric = pbr_functions::calculate_F0_dielectric(in.material.reflectance);
    input.F0_metallic = base_color;
    input.F_ab = lighting::F_AB(perceptual_roughness, input.layers[LAYER_BASE].NdotV);
#ifdef STANDARD_MATERIAL_CLEARCOAT
    let cc_roughness = in.material.clearcoat_perceptual_roughness;
    input.layers[LAYER_CLEARCOAT].NdotV = max(dot(in.clearcoat_N, in.V), 0.0001);
    input.layers[LAYER_CLEARCOAT].N = in.clearcoat_N;
    input.layers[LAYER_CLEARCOAT].R = reflect(-in.V, in.clearcoat_N);
    input.layers[LAYER_CLEARCOAT].perceptual_roughness = cc_roughness;
    input.layers[LAYER_CLEARCOAT].roughness = lighting::perceptualRoughnessToRoughness(cc_roughness);
    input.clearcoat_strength = in.material.clearcoat;
#endif
    return input;
}

fn receives_shadows(in: pbr_types::PbrInput) -> bool {
    return (in.flags & MESH_FLAGS_SHADOW_RECEIVER_BIT) != 0u;
}

// Frame-buffer point `frag_xy` in the view's viewport: Penumbra's masks and AO are the
// viewport's size, the frame buffer the render target's (split screen).
fn viewport_xy(frag_xy: vec2<f32>) -> vec2<f32> {
    return frag_xy - view_bindings::view.viewport.xy;
}

// Visibility of clustered light `light_id` (a point light, or a spot light when
// `spot`): Penumbra's mask when the light has one, else Bevy's shadow map.
fn clustered_visibility(in: pbr_types::PbrInput, light_id: u32, spot: bool) -> f32 {
    let mask = clustered_light_mask(light_id);
    if mask >= 0 {
        return mask_visibility(mask, viewport_xy(in.frag_coord.xy));
    }
    let light = &view_bindings::clustered_lights.data[light_id];
    if !receives_shadows(in)
            || ((*light).flags & mesh_view_types::POINT_LIGHT_FLAGS_SHADOWS_ENABLED_BIT) == 0u {
        return 1.0;
    }
    var shadow: f32;
    if spot {
        shadow = shadows::fetch_spot_shadow(
            light_id, in.world_position, in.world_normal, (*light).shadow_map_near_z, in.frag_coord.xy
        );
    } else {
        shadow = shadows::fetch_point_shadow(light_id, in.world_position, in.world_normal, in.frag_coord.xy);
    }
#ifdef CONTACT_SHADOWS
#ifdef DEPTH_PREPASS
    if view_bindings::contact_shadows_settings.linear_steps > 0u && shadow > 0.0
            && ((*light).flags & mesh_view_types::POINT_LIGHT_FLAGS_CONTACT_SHADOWS_ENABLED_BIT) != 0u {
        let L = normalize((*light).position_radius.xyz - in.world_position.xyz);
        shadow *= pbr_functions::calculate_contact_shadow(
            in.world_position.xyz, in.frag_coord.xy, L, view_bindings::contact_shadows_settings.linear_steps
        );
    }
#endif
#endif
    return shadow;
}

fn directional_visibility(in: pbr_types::PbrInput, i: u32, view_z: f32) -> f32 {
    let light = &view_bindings::lights.directional_lights[i];
    let mask = directional_light_mask((*light).direction_to_light);
    if mask >= 0 {
        return mask_visibility(mask, viewport_xy(in.frag_coord.xy));
    }
    if !receives_shadows(in)
            || ((*light).flags & mesh_view_types::DIRECTIONAL_LIGHT_FLAGS_SHADOWS_ENABLED_BIT) == 0u {
        return 1.0;
    }
    var shadow = shadows::fetch_directional_shadow(i, in.world_position, in.world_normal, view_z, in.frag_coord.xy);
#ifdef CONTACT_SHADOWS
#ifdef DEPTH_PREPASS
    if view_bindings::contact_shadows_settings.linear_steps > 0u && shadow > 0.0
            && ((*light).flags & mesh_view_types::DIRECTIONAL_LIGHT_FLAGS_CONTACT_SHADOWS_ENABLED_BIT) != 0u {
        shadow *= pbr_functions::calculate_contact_shadow(
            in.world_position.xyz, in.frag_coord.xy, (*light).direction_to_light,
            view_bindings::contact_shadows_settings.linear_steps
        );
    }
#endif
#endif
    return shadow;
}

// Direct and indirect lighting of a lit G-buffer sample, exposure applied, emissive
// added: what `bevy_pbr::pbr_functions::apply_pbr_lighting` returns for it.
fn apply_lighting(in: pbr_types::PbrInput) -> vec4<f32> {
    return apply_lighting_with_input(in, lighting_input(in));
}

// `apply_lighting` with the diffuse colour (Bevy's albedo × (1 − metallic)) replaced.
// Every term is affine in it, so shading with 0 and with 1 splits a sample into what
// does not scale with the albedo (specular, emissive, the ambient's Fresnel part) and
// the diffuse irradiance: `apply_lighting = f(0) + diffuse_color · (f(1) − f(0))`
// (`split_diffuse` in `lighting/pass.wgsl`, for subsurface scattering).
fn apply_lighting_with_diffuse_color(in: pbr_types::PbrInput, diffuse_color: vec3<f32>) -> vec4<f32> {
    var input = lighting_input(in);
    input.diffuse_color = diffuse_color;
    return apply_lighting_with_input(in, input);
}

// `apply_lighting` with the BRDF inputs given.
fn apply_lighting_with_input(in: pbr_types::PbrInput, brdf_input: lighting::LightingInput) -> vec4<f32> {
    var input = brdf_input;
    let view_z = dot(vec4<f32>(
        view_bindings::view.view_from_world[0].z,
        view_bindings::view.view_from_world[1].z,
        view_bindings::view.view_from_world[2].z,
        view_bindings::view.view_from_world[3].z
    ), in.world_position);
    let cluster_index = clustering::view_fragment_cluster_index(in.frag_coord.xy, view_z, in.is_orthographic);
    var ranges = clustering::unpack_clusterable_object_index_ranges(cluster_index);

    var direct = vec3(0.0);
    for (var i = ranges.first_point_light_index_offset; i < ranges.first_spot_light_index_offset; i += 1u) {
        let light_id = clustering::get_clusterable_object_id(i);
        let visibility = clustered_visibility(in, light_id, false);
        if visibility > 0.0 {
            direct += lighting::point_light(light_id, &input, true, true) * visibility;
        }
    }
    for (var i = ranges.first_spot_light_index_offset; i < ranges.first_reflection_probe_index_offset; i += 1u) {
        let light_id = clustering::get_clusterable_object_id(i);
        let visibility = clustered_visibility(in, light_id, true);
        if visibility > 0.0 {
            direct += lighting::spot_light(light_id, &input, true) * visibility;
        }
    }
    for (var i = 0u; i < view_bindings::lights.n_directional_lights; i += 1u) {
        let visibility = directional_visibility(in, i, view_z);
        if visibility > 0.0 {
            direct += lighting::directional_light(i, &input, true) * visibility;
        }
    }
#ifdef AREA_LIGHT_LUTS
    for (var i = 0u; i < view_bindings::lights.n_rect_lights; i += 1u) {
        direct += lighting::rect_light(i, &input, true);
    }
#endif

    // Indirect: irradiance volume, else the environment map's diffuse part; the
    // environment's specular unless SSR takes it; ambient. With distance-field AO: the
    // diffuse parts are sampled along the bent normal, and each term takes the smaller
    // of its SSAO and DFAO occlusion.
    let dfao = penumbra_ao(viewport_xy(in.frag_coord.xy), in.N);
    let diffuse_occlusion = min(in.diffuse_occlusion, vec3(dfao.ao));
    let specular_occlusion = min(
        in.specular_occlusion,
        penumbra_ao_specular(dfao, in.N, in.V, input.layers[LAYER_BASE].roughness),
    );
    let layer = specular_layer_at(vec2<i32>(in.frag_coord.xy), view_z);
    var indirect_input = input;
    indirect_input.layers[LAYER_BASE].N = dfao.bent_normal;
    var indirect = vec3(0.0);
    var found_diffuse_indirect = false;
#ifdef IRRADIANCE_VOLUME
    indirect += irradiance_volume::irradiance_volume_light(in.world_position.xyz, dfao.bent_normal, &ranges)
        * input.diffuse_color * diffuse_occlusion;
    found_diffuse_indirect = true;
#endif
#ifdef ENVIRONMENT_MAP
#ifdef SCREEN_SPACE_REFLECTIONS
    let use_ssr = in.material.perceptual_roughness <= view_bindings::ssr_settings.max_perceptual_roughness
        && in.material.perceptual_roughness >= view_bindings::ssr_settings.min_perceptual_roughness;
#else
    let use_ssr = false;
#endif
    let environment = environment_map::environment_map_light(&indirect_input, &ranges, found_diffuse_indirect);
    indirect += environment.diffuse * diffuse_occlusion;
    if !use_ssr {
        // What a specular layer covers, it replaces.
        indirect += environment.specular * specular_occlusion * (1.0 - layer.a);
    }
#endif
    // The specular layer (billboard reflections): its radiance under the environment
    // BRDF (Bevy's single-scattering `FssEss`), its own occlusion already applied.
    indirect += layer.rgb * environment_brdf(&input);
    if (penumbra_lighting.specular_layer & 4u) != 0u {
        return layer;
    }
    let NdotV = input.layers[LAYER_BASE].NdotV;
    let F0 = pbr_functions::calculate_F0(in.material.base_color.rgb, in.material.metallic, in.material.reflectance);
    indirect += ambient::ambient_light(
        in.world_position, in.N, in.V, NdotV, input.diffuse_color, F0,
        in.material.perceptual_roughness, diffuse_occlusion
    );
    if penumbra_lighting.ao_enabled != 0u {
        // The occlusion tint fills the occluded part of the diffuse indirect light.
        indirect += input.diffuse_color * penumbra_lighting.ao_tint.rgb * (1.0 - dfao.ao);
        if penumbra_lighting.ao_debug_view == 1u {
            return vec4(vec3(dfao.ao), 1.0);
        }
        if penumbra_lighting.ao_debug_view == 2u {
            return vec4(dfao.bent_normal * 0.5 + 0.5, 1.0);
        }
        if penumbra_lighting.ao_debug_view == 3u {
            return vec4(penumbra_ao_tile_heat(viewport_xy(in.frag_coord.xy)), 1.0);
        }
    }

    // Emissive, under the clearcoat's Fresnel, exposed as the material asks.
    let emissive = in.material.emissive;
    var emissive_light = emissive.rgb * in.material.base_color.a;
#ifdef STANDARD_MATERIAL_CLEARCOAT
    let clearcoat_fresnel = lighting::F_Schlick(0.04, 1.0, input.layers[LAYER_CLEARCOAT].NdotV);
    emissive_light *= 1.0 - in.material.clearcoat * clearcoat_fresnel;
#endif
    emissive_light *= mix(1.0, view_bindings::view.exposure, emissive.a);

    return vec4(view_bindings::view.exposure * (direct + indirect) + emissive_light, in.material.base_color.a);
}

// Bevy's environment BRDF of a sample (`compute_multiscatter`'s `FssEss`, dielectric
// and metallic mixed by metallic, with the same pre-baked specular occlusion).
fn environment_brdf(input: ptr<function, lighting::LightingInput>) -> vec3<f32> {
    let F_ab = (*input).F_ab;
    let F0_dielectric = (*input).F0_dielectric;
    let F0_metallic = (*input).F0_metallic;
    let occlusion = saturate(dot(mix(F0_dielectric, F0_metallic, (*input).metallic), vec3(50.0 * 0.33)));
    let dielectric = F0_dielectric * F_ab.x + F_ab.y;
    let metallic = F0_metallic * F_ab.x + F_ab.y;
    return mix(dielectric, metallic, (*input).metallic) * occlusion;
}

// The specular layer at a pixel of view depth `view_z` (0 where there is none). At half
// resolution, texel `i` holds full-resolution pixel `2i`: a pixel reads the (up to) four
// texels around it, bilinearly weighted, keeping those whose depth is within 10 % of its
// own (the nearest in depth when none is). CPU model:
// `penumbra_cinematic_core::reflections::pass::upsample_half`.
fn specular_layer_at(pixel: vec2<i32>, view_z: f32) -> vec4<f32> {
    let mode = penumbra_lighting.specular_layer & 3u;
    if mode == 0u {
        return vec4(0.0);
    }
    if mode == 1u {
        return textureLoad(specular_layer, pixel, 0);
    }
    let base = pixel / 2;
    let odd = vec2<f32>(pixel - base * 2) * 0.5;
    let size = vec2<i32>(textureDimensions(specular_layer)) - 1;
    var sum = vec4(0.0);
    var weight = 0.0;
    var nearest = vec4(0.0);
    var nearest_gap = 3.4e38;
    for (var k = 0; k < 4; k += 1) {
        let offset = vec2<i32>(k & 1, k >> 1);
        let texel = min(base + offset, size);
        let bilinear = mix(1.0 - odd.x, odd.x, f32(offset.x)) * mix(1.0 - odd.y, odd.y, f32(offset.y));
        if bilinear == 0.0 {
            continue;
        }
        let value = textureLoad(specular_layer, texel, 0);
        let gap = abs(layer_view_z(texel * 2) - view_z);
        if gap <= 0.1 * abs(view_z) {
            sum += value * bilinear;
            weight += bilinear;
        }
        if gap < nearest_gap {
            nearest_gap = gap;
            nearest = value;
        }
    }
    if weight > 0.0 {
        return sum / weight;
    }
    return nearest;
}

// The view depth of full-resolution pixel `pixel` (the depth prepass).
fn layer_view_z(pixel: vec2<i32>) -> f32 {
#ifdef DEPTH_PREPASS
    return depth_ndc_to_view_z(textureLoad(view_bindings::depth_prepass_texture, pixel, 0));
#else
    return 0.0;
#endif
}
