// The face-normal prepass (`bevy_penumbra_df::face_normals`): every opaque mesh drawn
// again with positions only; each fragment writes its triangle's own normal — the plane
// its world position spans across the pixel quad, not the interpolated or
// normal-mapped normal of the G-buffer — oriented by the triangle's winding, and 1 in
// alpha. Its own depth buffer keeps the nearest triangle at each pixel centre, the one
// a ray from the eye through the pixel centre meets.
#import bevy_pbr::{
    mesh_functions::{get_world_from_local, mesh_position_local_to_world},
    view_transformations::position_world_to_clip,
}

struct Vertex {
    @builtin(instance_index) instance_index: u32,
    @location(0) position: vec3<f32>,
}

struct VertexOutput {
    @builtin(position) clip_position: vec4<f32>,
    @location(0) world_position: vec3<f32>,
}

@vertex
fn vertex(vertex: Vertex) -> VertexOutput {
    let world_from_local = get_world_from_local(vertex.instance_index);
    let world = mesh_position_local_to_world(world_from_local, vec4(vertex.position, 1.0));
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
