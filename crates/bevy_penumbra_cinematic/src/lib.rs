//! Penumbra's cinematic effects for Bevy, after Epic's Samaritan demo (Mittring and
//! Dudash, GDC 2011). Each effect is opt-in per camera: a camera without its component
//! renders exactly as before, and no pass, texture or buffer exists for it.
//!
//! - [`dof`]: scatter bokeh depth of field ([`BokehDepthOfField`]).
//! - [`sss`]: screen-space subsurface scattering ([`SubsurfaceScattering`], profiles in
//!   [`SubsurfaceProfiles`]).
//! - [`reflections`]: billboard reflections ([`BillboardReflections`] on cameras,
//!   [`ReflectionBillboard`] on quads).
//! - [`hair`]: hair and beards as camera-facing strips with an alpha test per MSAA
//!   sample ([`Hair`] on entities, strands in [`HairStrands`]).
//! - [`tessellation`]: compute tessellation with PN-AEN and crack-free displacement
//!   ([`Tessellated`] on mesh entities).
//!
//! The algorithms and their shared GPU layouts live in the Bevy-free
//! `penumbra_cinematic_core`; their CPU reference models in `penumbra_reference`.

pub mod dof;
pub mod hair;
mod image_data;
pub mod reflections;
pub mod sss;
pub mod tessellation;

pub use dof::{BokehAperture, BokehDepthOfField, BokehDepthOfFieldPlugin};
pub use hair::{Hair, HairCoverage, HairPlugin, HairStrands};
pub use reflections::{
    BillboardReflections, BillboardReflectionsPlugin, ReflectionBillboard, ReflectionDebugView,
};
pub use sss::{
    ScatteringMaterial, ScatteringMaterialPlugin, SubsurfaceDebugView, SubsurfaceProfile,
    SubsurfaceProfileId, SubsurfaceProfiles, SubsurfaceScattering, SubsurfaceScatteringPlugin,
};
pub use tessellation::{
    Tessellated, TessellationCamera, TessellationMode, TessellationPartitioning, TessellationPlugin,
};
