// Hair strips in Bevy's prepasses and shadow passes: the same camera-facing strip (facing
// the light in a shadow view) and the same coverage as the main pass (`hair/draw.wgsl`),
// so the depth of the samples the main pass colours is written first; normals face the
// viewer across the strand, motion vectors follow the centre line.

#import bevy_pbr::{
    mesh_view_bindings::view,
    prepass_bindings,
}
#import penumbra::hair::common::{HairVertex, HairVaryings, hair_vertex, hair_coverage}

@vertex
fn vertex(vertex: HairVertex) -> HairVaryings {
    return hair_vertex(vertex);
}

struct HairPrepassOutput {
#ifdef NORMAL_PREPASS
    @location(0) normal: vec4<f32>,
#endif
#ifdef MOTION_VECTOR_PREPASS
    @location(1) motion_vector: vec2<f32>,
#endif
#ifdef UNCLIPPED_DEPTH_ORTHO_EMULATION
    @builtin(frag_depth) frag_depth: f32,
#endif
    @builtin(sample_mask) mask: u32,
}

@fragment
fn fragment(in: HairVaryings) -> HairPrepassOutput {
    var out: HairPrepassOutput;
    out.mask = hair_coverage(in);
#ifdef NORMAL_PREPASS
    let to_eye = select(
        view.world_position - in.world_position.xyz,
        view.world_from_view[2].xyz,
        view.clip_from_view[3].w == 1.0,
    );
    let n = to_eye - in.world_tangent * dot(in.world_tangent, to_eye);
    let normal = select(vec3(0.0, 0.0, 1.0), normalize(n), dot(n, n) > 1e-12);
    out.normal = vec4(normal * 0.5 + vec3(0.5), 1.0);
#endif
#ifdef UNCLIPPED_DEPTH_ORTHO_EMULATION
    out.frag_depth = in.unclipped_depth;
#endif
#ifdef MOTION_VECTOR_PREPASS
    let clip_t = view.unjittered_clip_from_world * in.world_position;
    let previous_t = prepass_bindings::previous_view_uniforms.clip_from_world * in.previous_world_position;
    out.motion_vector = (clip_t.xy / clip_t.w - previous_t.xy / previous_t.w) * vec2(0.5, -0.5);
#endif
    return out;
}
