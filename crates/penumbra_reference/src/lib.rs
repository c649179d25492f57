//! CPU reference models and ground truth for Penumbra's GPU algorithms.
//!
//! Every GPU algorithm in Penumbra has a model here, written for clarity rather than
//! speed, in `f32`/`f64` Rust with no Bevy dependency, so that:
//! - the model itself can be checked against exact ground truth (analytic geometry,
//!   triangle ray tracing, brute-force `f64` distance) in fast unit tests, and
//! - the GPU output, read back from lavapipe by `penumbra_test`, can be compared with it.
//!
//! # Coordinate conventions
//! Bevy's: right-handed, +Y up, the camera looks down its local −Z. World units are metres.
//! Image pixel `(x, y)` has its origin at the top-left corner, +y down, and its centre at
//! `(x + 0.5, y + 0.5)`; normalized device coordinates have +y up.
//!
//! # Modules
//! - [`bokeh`]: scatter bokeh depth of field — thin-lens circles of confusion, aperture
//!   shapes, half-resolution sprites (1 or 4 per block), near/far layers, composite.
//! - [`pbr`]: Bevy 0.19's `StandardMaterial` shading (Burley diffuse, GGX specular with
//!   Bevy's multiscatter compensation, ambient light, exposure, sRGB output).
//! - [`camera`]: perspective camera rays matching Bevy's `PerspectiveProjection`.
//! - [`analytic_volume`]: volumes of exact analytic distances (test casters, no bake).
//! - [`df`]: distance-field passes — object distances (atlas volumes and analytic
//!   shapes) and the debug view's sphere tracing.
//! - [`df_shadow`]: distance-field soft shadows (the march) and Monte Carlo area-light
//!   ground truth.
//! - [`dfao`]: distance-field ambient occlusion — the cone trace with its tiles, the
//!   upsample, specular occlusion — and cosine-weighted Monte Carlo truth on triangles.
//! - [`global_sdf`]: the global distance field's clipmap composition (brick jobs from
//!   `penumbra_df_core::clipmap`), conservative storage and sampling.
//! - [`particles`]: particles colliding with the global field (restitution, friction).
//! - [`shadow_mask`]: the distance-field shadow-mask pass — per pixel, the march over the
//!   GPU object records with its per-object cone culling.
//! - [`scene_truth`]: ray-traced truth for a whole glTF scene through a camera — sun
//!   visibility and ambient occlusion per pixel, as the scene viewer's `--dump` shows them.
//! - [`posed_gltf`]: a glTF scene's triangles in an animation's pose (skinned meshes
//!   deformed by their joints on the CPU) — the truth for characters.
//! - [`rebake`]: the GPU re-bake of a posed mesh — exact distances to its triangles,
//!   signed by their winding number — on `penumbra_df_core::rebake`'s grid.
//! - [`npy`]: float32 `.npy` files (the viewer's dumps, the truth written beside them).
//! - [`scene`]: an analytic ray-traced scene (spheres, planes, directional lights with hard
//!   shadows) shaded with [`pbr`], the expected image of simple GPU render tests.

pub mod analytic_volume;
pub mod bokeh;
pub mod camera;
pub mod df;
pub mod df_shadow;
pub mod dfao;
pub mod field_debug;
pub mod global_sdf;
pub mod msaa;
pub mod npy;
pub mod particles;
pub mod pbr;
pub mod posed_gltf;
pub mod rebake;
pub mod reflections;
pub mod scene;
pub mod scene_truth;
pub mod shadow_mask;
pub mod sss;
#[cfg(test)]
mod test_terrain;
