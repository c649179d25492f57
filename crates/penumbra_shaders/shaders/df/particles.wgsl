// GPU particles colliding with the global distance field: one invocation per particle
// integrates gravity, then, where the particle's centre is nearer a surface than its
// radius, pushes it out along the field's gradient (central differences of half a
// texel in the level it was read from) and reflects its velocity: the normal part
// reversed times the restitution, the tangential part kept times 1 − friction. Where
// no clipmap level can be read the particle flies free. Group 1 is the field
// (`global_field.wgsl`). CPU model: `penumbra_reference::particles::step_from`; the
// layouts: `penumbra_df_core::particles`.
#define_import_path penumbra::df::particles

#import penumbra::df::global_field::{global_view, sample_field}

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

// The surface distance at camera-relative `p` (the stored value plus its level's
// dilation) in `w` and the field's unit gradient in `xyz`; `ok` false where the field
// cannot be read or has no gradient (`particles::field_normal`).
struct FieldNormal {
    normal: vec3<f32>,
    distance: f32,
    ok: bool,
}

fn field_normal(p: vec3<f32>) -> FieldNormal {
    let s = sample_field(p, 0u);
    if s.z == 0.0 {
        return FieldNormal(vec3<f32>(0.0), 0.0, false);
    }
    let level = u32(s.y);
    let l = global_view.levels[level];
    let h = 0.5 * l.texel;
    var at: array<f32, 6>;
    for (var i = 0u; i < 6u; i++) {
        var o = vec3<f32>(0.0);
        o[i / 2u] = select(h, -h, (i % 2u) == 1u);
        let q = sample_field(p + o, level);
        at[i] = select(s.x, q.x, q.z > 0.0);
    }
    let g = vec3<f32>(at[0] - at[1], at[2] - at[3], at[4] - at[5]);
    let len = length(g);
    if !(len > 0.0) {
        return FieldNormal(vec3<f32>(0.0), 0.0, false);
    }
    return FieldNormal(g / len, s.x + l.dilation, true);
}

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
