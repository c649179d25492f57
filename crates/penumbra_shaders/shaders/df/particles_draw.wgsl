// Draws `DistanceFieldParticles` as camera-facing discs: quad q of the emitter's mesh is
// particle q of its buffer (`df/particles.wgsl`'s layout; the vertex position holds
// (q, corner), not `vertex_index`, which Bevy's mesh allocator offsets), placed at the
// emitter's origin plus the particle's position, its corners spread along the view's
// right and up axes by the radius; dead particles collapse to a point. Unlit,
// alpha-blended edges.
#import bevy_pbr::mesh_view_bindings::view

struct DistanceFieldParticle {
    position: vec3<f32>,
    age: f32,
    velocity: vec3<f32>,
    alive: u32,
}

struct ParticleDrawParams {
    color: vec4<f32>,
    origin: vec3<f32>,
    radius: f32,
}

@group(#{MATERIAL_BIND_GROUP}) @binding(0) var<storage, read> particles: array<DistanceFieldParticle>;
@group(#{MATERIAL_BIND_GROUP}) @binding(1) var<uniform> params: ParticleDrawParams;

struct Vertex {
    // (particle index, corner x, corner y), corners ±1.
    @location(0) slot: vec3<f32>,
}

struct VertexOutput {
    @builtin(position) clip: vec4<f32>,
    @location(0) corner: vec2<f32>,
}

@vertex
fn vertex(v: Vertex) -> VertexOutput {
    let q = particles[u32(v.slot.x)];
    let corner = v.slot.yz;
    let right = view.world_from_view[0].xyz;
    let up = view.world_from_view[1].xyz;
    let radius = select(0.0, params.radius, q.alive != 0u);
    let world = params.origin + q.position + (right * corner.x + up * corner.y) * radius;
    var out: VertexOutput;
    out.clip = view.clip_from_world * vec4<f32>(world, 1.0);
    out.corner = corner;
    return out;
}

@fragment
fn fragment(in: VertexOutput) -> @location(0) vec4<f32> {
    let r = length(in.corner);
    let alpha = clamp((1.0 - r) * 8.0, 0.0, 1.0);
    if alpha <= 0.0 {
        discard;
    }
    return vec4<f32>(params.color.rgb, params.color.a * alpha);
}
