//! The face-normal prepass: each pixel's **triangle normal**, the facet a ray from the
//! eye through the pixel centre meets, for passes that must know which way the geometry
//! itself faces rather than how it is shaded.
//!
//! # Why
//!
//! Bevy's G-buffer holds the *shading* normal: interpolated vertex normals, bent by
//! normal maps, flipped toward the eye on double-sided materials. Ray tracing decides
//! a surface's own shadow with the triangle's plane (a ray toward the light leaves the
//! surface or enters it), and at 1080p and below a game mesh's triangles are often
//! smaller than a pixel (the Bevy terrain example asset: about 38 triangles per pixel
//! at 128 × 96), so neither the G-buffer nor the depth buffer's plane across the
//! neighbouring pixels tells which facet a pixel centre lies on. With this pass the
//! distance-field shadow mask's error over shadowed pixels on the scene corpus went
//! 0.240 → 0.088 on the terrain, 0.068 → 0.033 on the flight helmet and 0.084 → 0.023
//! on the barn lamp (`README.md`, "Facets"; `shadows` reads the target).
//!
//! # How
//!
//! A camera with [`FaceNormalPrepass`] draws every visible mesh a second time after
//! Bevy's prepass, positions only, with no culling and its own depth buffer (reverse-Z,
//! nearest wins): each fragment writes the normal of the plane its world position spans
//! across its 2 × 2 pixel quad (`cross(dpdy(p), dpdx(p))`, constant over a triangle and
//! exact for it), turned to the triangle's winding front (`front_facing`), into an
//! `Rgba16Float` target: xyz the unit normal in world space, w 1 where a triangle was
//! drawn (0: background). `ViewFaceNormalTexture` holds it in the render world.
//!
//! # Limits
//!
//! Skinned and morphed meshes are drawn in the pose the camera sees (the vertex stage
//! blends their joints and morph targets as Bevy's mesh shader does), lightmapped ones
//! with the bind group Bevy binds for them. What the G-buffer shows and this pass does
//! not, a reader must tell by depth (the target's own depth against the prepass's):
//! back faces that Bevy culls but this pass draws (an open single-sided mesh seen from
//! behind), alpha-masked cut-outs (drawn whole here), a material's own vertex shader
//! (a custom displacement this pass does not run). Alpha-blended and transmissive
//! materials are not drawn, as Bevy's G-buffer leaves them out.
//!
//! Cost: one more draw of the visible meshes, positions only, and 12 bytes a pixel
//! (the target and its depth, Bevy's `TextureCache`); on lavapipe at 480 × 270, 3.3 ms
//! in the showcase's 562 ms frame and 24.5 ms in the flight helmet's 330 ms. Nothing —
//! no phase, no texture, no draw — without the component or while no light has
//! `DistanceFieldShadows`, its only reader.

mod render;

pub use render::ViewFaceNormalTexture;

use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::extract_component::{ExtractComponent, ExtractComponentPlugin};

/// Adds [`FaceNormalPrepass`]. Part of `PenumbraPlugins` (through
/// `DistanceFieldShadowsPlugin`).
#[derive(Default)]
pub struct FaceNormalPrepassPlugin;

/// Draws the [module docs](self)' face-normal target for this 3D camera.
#[derive(Component, ExtractComponent, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Clone, Default)]
pub struct FaceNormalPrepass;

impl Plugin for FaceNormalPrepassPlugin {
    fn build(&self, app: &mut App) {
        crate::shader_library::register_shader_library(app);
        app.register_type::<FaceNormalPrepass>().add_plugins((
            ExtractComponentPlugin::<FaceNormalPrepass>::default(),
            render::phase_plugin(),
        ));
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render::build(render_app);
        }
    }

    fn finish(&self, app: &mut App) {
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render::finish(render_app);
        }
    }
}
