//! The Bevy-free core of Penumbra's cinematic effects: what the WGSL shaders and the CPU
//! reference models (`penumbra_reference`) share.
//!
//! - [`dof`]: scatter bokeh depth of field — the thin lens ([`dof::Lens`]), the aperture's
//!   shape ([`dof::Aperture`]) and the passes' uniform ([`dof::BokehView`]).
//! - [`sss`]: screen-space subsurface scattering — Burley's normalized diffusion profile,
//!   its importance sampling and the scatter draw's uniform.
//! - [`reflections`]: billboard reflections — the quads, their exact ray intersection,
//!   the images' mip chains, the per-pixel pass and the tile cull.
//! - [`tessellation`]: compute tessellation — the per-mesh preprocessing (12-index
//!   patches, dominant vertices), the factors, PN-AEN and displacement, and a CPU
//!   reference tessellator.
//! - [`dispatch`]: compute dispatches past 65,535 workgroups (two-dimensional).
//! - [`scan`]: prefix sums over many items in three passes of many workgroups (bokeh
//!   compaction, tessellation allocation).
//! - [`hair`]: hair strips (started) — a strip's 4× MSAA coverage with an alpha test per
//!   sample, and its exact area.

pub mod dispatch;
pub mod dof;
pub mod hair;
pub mod reflections;
pub mod scan;
pub mod sss;
pub mod tessellation;
