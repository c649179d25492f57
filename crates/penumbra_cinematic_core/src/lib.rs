//! The Bevy-free core of Penumbra's cinematic effects: what the WGSL shaders and the CPU
//! reference models (`penumbra_reference`) share.
//!
//! - [`dof`]: scatter bokeh depth of field — the thin lens ([`dof::Lens`]) and the
//!   passes' uniform ([`dof::BokehView`]).

pub mod dof;
