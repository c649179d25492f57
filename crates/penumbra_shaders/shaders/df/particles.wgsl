// GPU particles colliding with the global distance field: one invocation per particle
// integrates gravity, then, where the particle's centre is nearer a surface than its
// radius, pushes it out along the field's gradient (central differences of half a
// texel in the level it was read from) and reflects its velocity: the normal part
// reversed times the restitution, the tangential part kept times 1 − friction. Where
// no clipmap level can be read the particle flies free. Group 1 is the field
// (`global_field.wgsl`). CPU model: `penumbra_reference::particles::step_from`; the
// layouts: `penumbra_df_core::particles`.
#define_import_path penumbra::df::particles

#import penumbra::df::global_field::field_normal

struct DistanceFieldParticle {
    position: vec3<f32>,
    age: f32,
    velocity: vec3<f32>,
    alive: u32,
}

struct ParticleStep {
    gravity: vec3<f32>,
    dt: f32,
    origin: vec3<f32>,
    restitution: f32,
    friction: f32,
    radius: f32,
    count: u32,
}

@group(0) @binding(0) var<storage, read_write> particles: array<DistanceFieldParticle>;
@group(0) @binding(1) var<uniform> params: ParticleStep;

@compute @workgroup_size(64, 1, 1)
fn step_particles(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.count {
        return;
    }
    var q = particles[gid.x];
    if q.alive == 0u {
        return;
    }
    q.velocity += params.gravity * params.dt;
    q.position += q.velocity * params.dt;
    q.age += params.dt;
    let f = field_normal(params.origin + q.position);
    if f.ok && f.distance < params.radius {
        q.position += f.normal * (params.radius - f.distance);
        let vn = dot(q.velocity, f.normal);
        if vn < 0.0 {
            let tangential = q.velocity - f.normal * vn;
            q.velocity = tangential * (1.0 - params.friction) - f.normal * vn * params.restitution;
        }
    }
    particles[gid.x] = q;
}
