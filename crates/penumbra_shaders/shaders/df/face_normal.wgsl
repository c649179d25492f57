// The face-normal prepass (`bevy_penumbra_df::face_normals`): every opaque mesh drawn
// again with positions only — skinned and morphed as Bevy's mesh shader poses them, so
// the triangle is the one the G-buffer shows — and each fragment writes its triangle's
// own normal: the plane its world position spans across the pixel quad, not the
// interpolated or normal-mapped normal of the G-buffer, oriented by the triangle's
// winding, and 1 in alpha. Its own depth buffer keeps the nearest triangle at each pixel
// centre, the one a ray from the eye through the pixel centre meets.
#import bevy_pbr::{
    mesh_bindings::mesh,
    mesh_functions::{get_world_from_local, mesh_position_local_to_world},
    skinning,
    view_transformations::position_world_to_clip,
}

struct Vertex {
    @builtin(instance_index) instance_index: u32,
#ifdef MORPH_TARGETS
    @builtin(vertex_index) index: u32,
#endif
    @location(0) position: vec3<f32>,
#ifdef SKINNED
    @location(1) joint_indices: vec4<u32>,
    @location(2) joint_weights: vec4<f32>,
#endif
}

struct VertexOutput {
    @builtin(position) clip_position: vec4<f32>,
    @location(0) world_position: vec3<f32>,
}

// The vertex's local position with the mesh's morph targets applied at their current
// weights (Bevy's `mesh.wgsl`, positions only).
fn morphed_position(vertex: Vertex) -> vec3<f32> {
    var position = vertex.position;
#ifdef MORPH_TARGETS
    let index = vertex.index - mesh[vertex.instance_index].first_vertex_index;
    let layers = bevy_pbr::morph::layer_count(vertex.instance_index);
    for (var i = 0u; i < layers; i++) {
        let weight = bevy_pbr::morph::weight_at(i, vertex.instance_index);
        if weight != 0.0 {
            position += weight * bevy_pbr::morph::morph_position(index, i, vertex.instance_index);
        }
    }
#endif
    return position;
}

// The mesh's world-from-local: its joints' blend where it is skinned.
fn posed_world_from_local(vertex: Vertex) -> mat4x4<f32> {
#ifdef SKINNED
    return skinning::skin_model(vertex.joint_indices, vertex.joint_weights, vertex.instance_index);
#else
    return get_world_from_local(vertex.instance_index);
#endif
}

@vertex
fn vertex(vertex: Vertex) -> VertexOutput {
    let world = mesh_position_local_to_world(
        posed_world_from_local(vertex),
        vec4(morphed_position(vertex), 1.0),
    );
    var out: VertexOutput;
    out.clip_position = position_world_to_clip(world.xyz);
    out.world_position = world.xyz;
    return out;
}

// The triangle's plane normal facing the side the eye sees (screen x right, y down:
// `dpdy × dpdx` points toward the eye), then turned to its winding's front.
fn winding_normal(world_position: vec3<f32>, front_facing: bool) -> vec3<f32> {
    let seen = cross(dpdy(world_position), dpdx(world_position));
    let len = length(seen);
    if !(len > 0.0) {
        return vec3(0.0);
    }
    return select(-seen, seen, front_facing) / len;
}

@fragment
fn fragment(in: VertexOutput, @builtin(front_facing) front_facing: bool) -> @location(0) vec4<f32> {
    return vec4(winding_normal(in.world_position, front_facing), 1.0);
}
