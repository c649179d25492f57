//! GPU particles colliding with the global distance field: the particle buffer's
//! element and the step's uniform (`shaders/df/particles.wgsl`), laid out by `encase`.
//! The step itself — gravity, then a push out along the field's gradient and a bounce
//! with restitution and friction — is `penumbra_reference::particles::step`.

use encase::ShaderType;
use glam::Vec3;

/// One particle (32 bytes).
#[derive(ShaderType, Clone, Copy, Debug, Default, PartialEq)]
pub struct GpuParticle {
    /// Position relative to the step's origin, metres.
    pub position: Vec3,
    /// Seconds since the particle was emitted (not used by the step).
    pub age: f32,
    /// Velocity, m/s.
    pub velocity: Vec3,
    /// 1 while the particle lives; 0: skipped.
    pub alive: u32,
}

/// One step's uniform.
#[derive(ShaderType, Clone, Copy, Debug, Default, PartialEq)]
pub struct ParticleStep {
    /// Acceleration, m/s².
    pub gravity: Vec3,
    /// Seconds.
    pub dt: f32,
    /// The particles' origin relative to the camera the field is centred on, metres
    /// (computed in f64 on the CPU): a particle at `position` is at camera-relative
    /// `origin + position`.
    pub origin: Vec3,
    /// Fraction of the normal speed kept on a bounce, 0–1.
    pub restitution: f32,
    /// Fraction of the tangential speed lost per contact, 0–1.
    pub friction: f32,
    /// Particle radius, metres.
    pub radius: f32,
    /// Particles in the buffer.
    pub count: u32,
}
