//! CPU model of scatter bokeh depth of field (#19; Mittring and Dudash, *The Technology
//! Behind the Unreal Engine 4 Elemental Demo* / *Samaritan*, GDC 2011): every
//! out-of-focus pixel of a half-resolution copy of the image becomes a sprite, a quad
//! textured with the aperture's shape, as wide as the pixel's circle of confusion and
//! carrying the pixel's energy; sprites add into a **near** layer (in front of the focal
//! plane) and a **far** layer (behind it); each layer is resolved by dividing its colour
//! by its accumulated weight and composited over the full-resolution in-focus image.
//! Per 2×2 block of half-resolution pixels one sprite stands for all four where their
//! circles of confusion, colours and depths agree, four otherwise.
//!
//! - [`Lens`]: the thin-lens circle of confusion (Bevy's `DepthOfField` formula, focal
//!   length from the projection and the sensor height) and the world-space aperture
//!   whose pinhole views, sheared to keep the focal plane fixed, average to that blur.
//! - [`Aperture`]: the bokeh shape as a square coverage image (circle and hexagon built
//!   in, any image accepted), sampled bilinearly as the GPU's sampler does.
//! - [`scatter`]: the passes — downsample, sprites, scatter, resolve and composite.
//! - [`truth`]: the thin lens as the mean of pinhole views across the aperture, ray
//!   traced: the model's independent check.

pub mod scatter;
#[cfg(test)]
mod tests;
pub mod truth;
#[cfg(test)]
mod truth_tests;

pub use scatter::{
    BokehImage, HalfImage, Layers, Sprite, by_layer, composite, depth_of_field, downsample,
    is_quarter, layer_index, quarter_diameter, quarter_sprite_weight, scatter_fragments,
    scatter_sprites, sprite_diameter, sprite_weight, sprites,
};

pub use penumbra_cinematic_core::dof::{
    Aperture, ApertureError, HALF_RES_BLUR, Lens, NORM_TABLE_MAX, QUARTER_RES_BLUR, SpriteRule,
};
