//! CPU model of GPU particles colliding with the global distance field (#17): each
//! step integrates gravity, then a particle whose centre is nearer a surface than its
//! radius is pushed out along the field's gradient (the collision plane's normal) and
//! its velocity reflected: the normal part reversed times the restitution, the
//! tangential part kept times `1 − friction`. Positions are camera-relative; the field
//! is read as the GPU reads it ([`GlobalField::sample_view`]), from the finest valid
//! level; where no level is valid a particle flies free.

use crate::global_sdf::GlobalField;
use glam::Vec3;
use penumbra_df_core::clipmap::GlobalFieldView;

/// Collision settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Collision {
    /// Fraction of the normal speed kept on a bounce, 0–1.
    pub restitution: f32,
    /// Fraction of the tangential speed lost per contact, 0–1.
    pub friction: f32,
    /// Particle radius, metres.
    pub radius: f32,
    /// Acceleration, m/s².
    pub gravity: Vec3,
}

/// One particle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Particle {
    /// Camera-relative position, metres.
    pub position: Vec3,
    /// Velocity, m/s.
    pub velocity: Vec3,
}

/// The distance at `p` (the stored value plus the level's dilation: the surface
/// itself) and the field's gradient there by central differences of half a texel of
/// that level, normalised; `None` where the field cannot be read.
pub fn field_normal(
    field: &GlobalField,
    view: &GlobalFieldView,
    valid: &[u32],
    p: Vec3,
) -> Option<(f32, Vec3)> {
    let (d, level) = field.sample_view(view, valid, p, 0)?;
    let h = 0.5 * view.levels[level as usize].texel;
    let at = |o: Vec3| {
        field
            .sample_view(view, valid, p + o, level)
            .map_or(d, |(v, _)| v)
    };
    let g = Vec3::new(
        at(Vec3::X * h) - at(-Vec3::X * h),
        at(Vec3::Y * h) - at(-Vec3::Y * h),
        at(Vec3::Z * h) - at(-Vec3::Z * h),
    );
    Some((d + view.levels[level as usize].dilation, g.try_normalize()?))
}

/// Advances `particles` (camera-relative) by `dt` seconds.
pub fn step(
    particles: &mut [Particle],
    field: &GlobalField,
    view: &GlobalFieldView,
    valid: &[u32],
    collision: &Collision,
    dt: f32,
) {
    step_from(Vec3::ZERO, particles, field, view, valid, collision, dt);
}

/// [`step`] for particles whose positions are relative to `origin` (camera-relative),
/// as the GPU step keeps them (`shaders/df/particles.wgsl`).
pub fn step_from(
    origin: Vec3,
    particles: &mut [Particle],
    field: &GlobalField,
    view: &GlobalFieldView,
    valid: &[u32],
    collision: &Collision,
    dt: f32,
) {
    for p in particles {
        p.velocity += collision.gravity * dt;
        p.position += p.velocity * dt;
        let Some((d, n)) = field_normal(field, view, valid, origin + p.position) else {
            continue;
        };
        if d >= collision.radius {
            continue;
        }
        p.position += n * (collision.radius - d);
        let vn = p.velocity.dot(n);
        if vn < 0.0 {
            let tangential = p.velocity - n * vn;
            p.velocity = tangential * (1.0 - collision.friction) - n * vn * collision.restitution;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::global_sdf::{AnalyticCaster, ClipmapFormat, FieldObject, analytic_distance};
    use penumbra_df_core::clipmap::{ClipmapLayout, ClipmapState};

    /// Particles dropped from 1–3 m onto a ground slab and a ball of radius 1 m: after
    /// 4 s (240 steps) every one has settled (below 0.05 m/s), none is more than a
    /// texel inside a surface nor a quarter texel above its resting contact (by the
    /// exact distance); without collisions they fall through the floor.
    #[test]
    fn dropped_particles_rest_on_the_plane_and_the_ball() {
        let scene = [
            AnalyticCaster::Cuboid {
                centre: Vec3::new(0.0, -0.5, 0.0),
                half: Vec3::new(20.0, 0.5, 20.0),
            },
            AnalyticCaster::Sphere {
                centre: Vec3::new(0.0, 1.0, 0.0),
                radius: 1.0,
            },
        ];
        let layout = ClipmapLayout::DEFAULT;
        let camera = Vec3::new(0.0, 1.0, 3.0);
        let objects: Vec<FieldObject> = scene.iter().map(|c| c.field_object()).collect();
        let mut state = ClipmapState::new(layout);
        let mut field = GlobalField::new(layout, ClipmapFormat::Unorm8);
        for job in state.update(camera, &[], usize::MAX).jobs {
            field.compose(job, &objects);
        }
        let view = GlobalFieldView::new(&state, camera.as_dvec3());
        let valid = GlobalFieldView::valid_bits(&state);
        let collision = Collision {
            restitution: 0.3,
            friction: 0.2,
            radius: 0.05,
            gravity: Vec3::new(0.0, -9.81, 0.0),
        };
        let start: Vec<Particle> = (0..100)
            .map(|i| {
                let a = i as f32 * 2.399;
                let r = 0.15 * (i as f32).sqrt();
                Particle {
                    position: Vec3::new(r * a.cos(), 1.0 + 0.02 * i as f32 + 2.0, r * a.sin())
                        - camera,
                    velocity: Vec3::ZERO,
                }
            })
            .collect();
        let mut particles = start.clone();
        for _ in 0..240 {
            step(
                &mut particles,
                &field,
                &view,
                &valid,
                &collision,
                1.0 / 60.0,
            );
        }
        let texel = layout.texel(0);
        let (mut worst, mut fastest) = (f32::INFINITY, 0.0f32);
        for p in &particles {
            let d = analytic_distance(&scene, p.position + camera);
            worst = worst.min(d);
            fastest = fastest.max(p.velocity.length());
        }
        eprintln!("nearest {worst:.3} m, fastest {fastest:.3} m/s");
        let highest = particles
            .iter()
            .map(|p| analytic_distance(&scene, p.position + camera))
            .fold(f32::NEG_INFINITY, f32::max);
        assert!(
            worst > -texel && highest < collision.radius + 0.25 * texel && fastest < 0.05,
            "{worst} {highest} {fastest}"
        );
        // Without collisions: through the floor.
        let mut free = start;
        let off = Collision {
            radius: -1e9,
            ..collision
        };
        for _ in 0..240 {
            step(&mut free, &field, &view, &valid, &off, 1.0 / 60.0);
        }
        assert!(free.iter().all(|p| p.position.y + camera.y < -1.0));
    }
}
