// Hair strips' main pass (forward, into the camera's MSAA colour and depth): the
// per-sample coverage of `penumbra::hair::common` written as the fragment's sample mask,
// shaded once per pixel with Kajiya-Kay's strand model (diffuse ∝ sin(T, L); the
// specular of Scheuermann's two tangent-shifted lobes, the second tinted by the hair)
// under Bevy's lights, each dimmed by its shadow map — or, for a distance-field-shadowed
// light, by the strand's visibility through the distance fields
// (`penumbra::hair::shadows`, interpolated along the strand from its points).
// Evaluated on the strand's centre line; ambient from Bevy's ambient light; fog and
// in-shader tonemapping as Bevy's forward materials do them.

#import bevy_pbr::{
    mesh_bindings::mesh,
    mesh_view_bindings as view_bindings,
    mesh_view_types,
    clustered_forward as clustering,
    lighting,
    shadows,
    pbr_types,
    pbr_functions,
}
#import penumbra::hair::common::{
    HairVertex, HairVaryings, hair, hair_vertex, hair_coverage, atlas_alpha, atlas_coordinates,
    ALPHA_CUTOFF,
    hair_atlas, hair_sampler, sample_thresholds, HAIR_FLAG_ATLAS, HAIR_FLAG_DEBUG_COVERAGE,
}
#import penumbra::hair::shadows::{
    HairShadows, HAIR_SHADOW_CLUSTERED, HAIR_SHADOW_DIRECTIONAL, MAX_HAIR_SHADOW_LIGHTS,
    slot_visibility,
}

// The strands' distance-field visibility (a placeholder with no light where the scene
// has no distance-field-shadowed light).
@group(#{MATERIAL_BIND_GROUP}) @binding(3) var<storage, read> hair_shadows: HairShadows;

const PI: f32 = 3.141592653589793;

@vertex
fn vertex(vertex: HairVertex) -> HairVaryings {
    var out = hair_vertex(vertex);
    out.df_visibility = point_df_visibility(vertex);
    return out;
}

// The visibility of the vertex's centre-line point (1 where it has none).
fn point_df_visibility(vertex: HairVertex) -> vec4<f32> {
    let point = (vertex.vertex_index - mesh[vertex.instance_index].first_vertex_index) / 2u;
    if hair_shadows.counts.x == 0u || point >= hair_shadows.counts.y {
        return vec4(1.0);
    }
    return hair_shadows.points[point];
}

// The distance-field slot of clustered light `light_id`, or -1.
fn clustered_slot(light_id: u32) -> i32 {
    for (var i = 0u; i < min(hair_shadows.counts.x, MAX_HAIR_SHADOW_LIGHTS); i += 1u) {
        let ids = hair_shadows.lights[i].ids;
        if ids.x == HAIR_SHADOW_CLUSTERED && ids.y == light_id {
            return i32(ids.z);
        }
    }
    return -1;
}

// The distance-field slot of the directional light shining from `direction_to_light`,
// or -1 (matched by direction, as Penumbra's lighting pass does).
fn directional_slot(direction_to_light: vec3<f32>) -> i32 {
    for (var i = 0u; i < min(hair_shadows.counts.x, MAX_HAIR_SHADOW_LIGHTS); i += 1u) {
        let light = hair_shadows.lights[i];
        if light.ids.x == HAIR_SHADOW_DIRECTIONAL && dot(light.direction.xyz, direction_to_light) > 0.99999 {
            return i32(light.ids.z);
        }
    }
    return -1;
}

struct HairOutput {
    @location(0) color: vec4<f32>,
    @builtin(sample_mask) mask: u32,
}

// The normalised Kajiya-Kay lobe of a tangent: (n + 2) / 2π · sin(T, H)ⁿ, faded as the
// half vector turns behind the strand (Scheuermann).
fn strand_lobe(T: vec3<f32>, H: vec3<f32>, exponent: f32) -> f32 {
    let t = dot(T, H);
    let sin_th = sqrt(max(1.0 - t * t, 0.0));
    return (exponent + 2.0) / (2.0 * PI) * pow(sin_th, exponent) * smoothstep(-1.0, 0.0, t);
}

// The strand's response to a light from direction `L` (per unit radiance, cosine
// included): the diffuse sin(T, L) / π times the colour, plus the two lobes.
fn strand_brdf(T: vec3<f32>, N: vec3<f32>, V: vec3<f32>, L: vec3<f32>, color: vec3<f32>) -> vec3<f32> {
    let tl = dot(T, L);
    let diffuse = color * sqrt(max(1.0 - tl * tl, 0.0)) / PI;
    let H = normalize(L + V);
    let t1 = normalize(T + hair.primary_shift * N);
    let t2 = normalize(T + hair.secondary_shift * N);
    let primary = hair.specular.x * strand_lobe(t1, H, hair.specular.y);
    let secondary = hair.specular.z * strand_lobe(t2, H, hair.specular.w);
    return diffuse + vec3(primary) + color * secondary;
}

struct StrandPoint {
    P: vec4<f32>,
    T: vec3<f32>,
    // Across the strip, towards the viewer.
    N: vec3<f32>,
    V: vec3<f32>,
    frag_coord: vec4<f32>,
    // Visibility of the distance-field-shadowed lights' slots.
    df_visibility: vec4<f32>,
}

// The normal the shadow maps' bias uses: across the strand, towards the light.
fn shadow_normal(p: StrandPoint, L: vec3<f32>) -> vec3<f32> {
    let n = L - p.T * dot(p.T, L);
    return select(p.N, normalize(n), dot(n, n) > 1e-8);
}

fn clustered_light(p: StrandPoint, light_id: u32, spot: bool, color: vec3<f32>) -> vec3<f32> {
    let light = &view_bindings::clustered_lights.data[light_id];
    let to_light = (*light).position_radius.xyz - p.P.xyz;
    let distance_square = dot(to_light, to_light);
    let L = to_light * inverseSqrt(distance_square);
    var radiance = (*light).color_inverse_square_range.rgb
        * lighting::getDistanceAttenuation(distance_square, (*light).color_inverse_square_range.w);
    if spot {
        var spot_dir = vec3((*light).light_custom_data.x, 0.0, (*light).light_custom_data.y);
        spot_dir.y = sqrt(max(0.0, 1.0 - spot_dir.x * spot_dir.x - spot_dir.z * spot_dir.z));
        if ((*light).flags & mesh_view_types::POINT_LIGHT_FLAGS_SPOT_LIGHT_Y_NEGATIVE) != 0u {
            spot_dir.y = -spot_dir.y;
        }
        let a = saturate(dot(-spot_dir, L) * (*light).light_custom_data.z + (*light).light_custom_data.w);
        radiance *= a * a;
    }
    if all(radiance <= vec3(0.0)) {
        return vec3(0.0);
    }
    var visibility = 1.0;
    let slot = clustered_slot(light_id);
    if slot >= 0 {
        visibility = slot_visibility(p.df_visibility, slot);
    } else if ((*light).flags & mesh_view_types::POINT_LIGHT_FLAGS_SHADOWS_ENABLED_BIT) != 0u {
        let n = shadow_normal(p, L);
        if spot {
            visibility = shadows::fetch_spot_shadow(light_id, p.P, n, (*light).shadow_map_near_z, p.frag_coord.xy);
        } else {
            visibility = shadows::fetch_point_shadow(light_id, p.P, n, p.frag_coord.xy);
        }
    }
    return radiance * visibility * strand_brdf(p.T, p.N, p.V, L, color);
}

fn directional_light(p: StrandPoint, i: u32, view_z: f32, color: vec3<f32>) -> vec3<f32> {
    let light = &view_bindings::lights.directional_lights[i];
    let L = (*light).direction_to_light;
    var visibility = 1.0;
    let slot = directional_slot(L);
    if slot >= 0 {
        visibility = slot_visibility(p.df_visibility, slot);
    } else if ((*light).flags & mesh_view_types::DIRECTIONAL_LIGHT_FLAGS_SHADOWS_ENABLED_BIT) != 0u {
        visibility = shadows::fetch_directional_shadow(i, p.P, shadow_normal(p, L), view_z, p.frag_coord.xy);
    }
    return (*light).color.rgb * visibility * strand_brdf(p.T, p.N, p.V, L, color);
}

// Every light of the view on the strand point: clustered point and spot lights,
// directional lights, ambient; exposure applied.
fn hair_lighting(p: StrandPoint, color: vec3<f32>) -> vec3<f32> {
    let view = view_bindings::view;
    let view_z = dot(vec4(view.view_from_world[0].z, view.view_from_world[1].z,
        view.view_from_world[2].z, view.view_from_world[3].z), p.P);
    let is_orthographic = view.clip_from_view[3].w == 1.0;
    let cluster_index = clustering::view_fragment_cluster_index(p.frag_coord.xy, view_z, is_orthographic);
    let ranges = clustering::unpack_clusterable_object_index_ranges(cluster_index);
    var direct = vec3(0.0);
    for (var i = ranges.first_point_light_index_offset; i < ranges.first_spot_light_index_offset; i += 1u) {
        direct += clustered_light(p, clustering::get_clusterable_object_id(i), false, color);
    }
    for (var i = ranges.first_spot_light_index_offset; i < ranges.first_reflection_probe_index_offset; i += 1u) {
        direct += clustered_light(p, clustering::get_clusterable_object_id(i), true, color);
    }
    for (var i = 0u; i < view_bindings::lights.n_directional_lights; i += 1u) {
        direct += directional_light(p, i, view_z, color);
    }
    let ambient = view_bindings::lights.ambient_color.rgb * color;
    return view.exposure * (direct + ambient);
}

fn strand_point(in: HairVaryings) -> StrandPoint {
    var p: StrandPoint;
    p.P = in.world_position;
    p.T = in.world_tangent;
    let to_eye = select(
        view_bindings::view.world_position - in.world_position.xyz,
        // Orthographic: towards the view, along its z axis.
        view_bindings::view.world_from_view[2].xyz,
        view_bindings::view.clip_from_view[3].w == 1.0,
    );
    p.V = normalize(to_eye);
    let n = p.V - p.T * dot(p.T, p.V);
    p.N = select(p.V, normalize(n), dot(n, n) > 1e-8);
    p.frag_coord = in.position;
    p.df_visibility = in.df_visibility;
    return p;
}

// The hair's colour at a strip point: the root-to-tip gradient times the atlas's colour.
fn hair_color(in: HairVaryings) -> vec3<f32> {
    var color = mix(hair.root_color.rgb, hair.tip_color.rgb, saturate(in.uv.x));
    if (hair.flags & HAIR_FLAG_ATLAS) != 0u {
        color *= textureSample(hair_atlas, hair_sampler, atlas_coordinates(in.uv, in.slot)).rgb;
    }
    return color;
}

fn shade(in: HairVaryings) -> vec4<f32> {
    if (hair.flags & HAIR_FLAG_DEBUG_COVERAGE) != 0u {
        return vec4(1.0);
    }
    let color = hair_lighting(strand_point(in), hair_color(in));
    var pbr_input = pbr_types::pbr_input_new();
    pbr_input.frag_coord = in.position;
    pbr_input.world_position = in.world_position;
    pbr_input.material.flags = pbr_types::STANDARD_MATERIAL_FLAGS_FOG_ENABLED_BIT;
    return pbr_functions::main_pass_post_lighting_processing(pbr_input, vec4(color, 1.0));
}

// Per-sample alpha test (4× MSAA), or the per-pixel test (MSAA off, or the comparison).
@fragment
fn fragment(in: HairVaryings) -> HairOutput {
    var out: HairOutput;
    out.mask = hair_coverage(in);
    out.color = shade(in);
    return out;
}

// Alpha-to-coverage (the comparison): the pixel centre's alpha, turned into samples by
// the pipeline.
@fragment
fn fragment_alpha_to_coverage(in: HairVaryings) -> @location(0) vec4<f32> {
    let ddx = dpdx(in.uv);
    let ddy = dpdy(in.uv);
    let alpha = atlas_alpha(clamp(in.uv, vec2(0.0), vec2(1.0)), in.slot, ddx, ddy) * in.fade;
    return vec4(shade(in).rgb, alpha);
}

// Shading per sample (the comparison): `uv` is interpolated at each sample
// (`HAIR_SAMPLE_SHADING`), tested against that sample's threshold and discarded.
@fragment
fn fragment_sample_shading(in: HairVaryings, @builtin(sample_index) sample_index: u32) -> @location(0) vec4<f32> {
    let color = shade(in);
    var thresholds = sample_thresholds(vec2<i32>(floor(in.position.xy)));
    let alpha = atlas_alpha(in.uv, in.slot, vec2(0.0), vec2(0.0));
    if alpha < ALPHA_CUTOFF || in.fade < thresholds[min(sample_index, 7u)] {
        discard;
    }
    return color;
}
