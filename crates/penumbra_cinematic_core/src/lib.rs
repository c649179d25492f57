//! The Bevy-free core of Penumbra's cinematic effects: what the WGSL shaders and the CPU
//! reference models (`penumbra_reference`) share.
//!
//! - [`dof`]: scatter bokeh depth of field — the thin lens ([`dof::Lens`]), the aperture's
//!   shape ([`dof::Aperture`]) and the passes' uniform ([`dof::BokehView`]).
//! - [`sss`]: screen-space subsurface scattering — Burley's normalized diffusion profile,
//!   its importance sampling and the scatter draw's uniform.
//! - [`reflections`]: billboard reflections — the quads, their exact ray intersection,
//!   the nearest hits and the front-to-back composite (started).

pub mod dof;
pub mod reflections;
pub mod sss;
