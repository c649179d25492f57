//! Scatter bokeh depth of field (#19): the thin lens, the aperture's shape, the sprite
//! rule and the uniform of the passes (`shaders/dof/`), shared by the Bevy plugin
//! (`bevy_penumbra_cinematic::dof`), the shaders (by `encase`) and the CPU model
//! (`penumbra_reference::bokeh`).

mod aperture;

pub use aperture::{Aperture, ApertureError, NORM_INTERVALS, NORM_TABLE_MAX, NORM_TABLE_STEPS};
use encase::ShaderType;
use glam::{Mat4, UVec2};

/// A thin lens focused at `focal_distance`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lens {
    /// Distance to the plane in focus, metres.
    pub focal_distance: f32,
    /// Aperture as an f-number (focal length / aperture diameter).
    pub f_stops: f32,
    /// Height of the sensor, metres (Bevy's default 18.66 mm, Super 35).
    pub sensor_height: f32,
    /// Vertical field of view of the projection, radians.
    pub fov_y: f32,
    /// Largest circle of confusion, full-resolution pixels (diameter).
    pub max_coc: f32,
    /// Distances beyond this count as this far (the sky), metres.
    pub max_depth: f32,
}

impl Lens {
    /// The focal length that maps the sensor onto the field of view, metres.
    pub fn focal_length(&self) -> f32 {
        0.5 * self.sensor_height / (0.5 * self.fov_y).tan()
    }

    /// The signed diameter of the circle of confusion, in pixels of an image `height`
    /// pixels high, of a point `distance` metres along the view axis: negative in front
    /// of the focal plane, positive behind, clamped to `±max_coc`. Bevy's formula:
    /// `f² (z − s) / (N z (s − f))` over the sensor height.
    ///
    /// At infinity (the sky, unless `max_depth` is finite) it is the limit
    /// `f² / (N (s − f))`; a distance that is NaN or not positive counts as in focus.
    pub fn coc(&self, distance: f32, height: u32) -> f32 {
        if distance.is_nan() || distance <= 0.0 {
            return 0.0;
        }
        let z = distance.min(self.max_depth);
        // (z − s) / z, written so that z = ∞ gives its limit 1.
        let behind = 1.0 - self.focal_distance / z;
        (self.coc_scale(height) * behind).clamp(-self.max_coc, self.max_coc)
    }

    /// The circle of confusion at infinity, pixels of an image `height` high, before
    /// clamping: `f² / (N (s − f))` over the sensor height. `coc(z)` is this times
    /// `1 − s / z`.
    pub fn coc_scale(&self, height: u32) -> f32 {
        let f = self.focal_length();
        let s = self.focal_distance;
        f * f / (self.f_stops * (s - f)) / self.sensor_height * height as f32
    }

    /// The diameter, metres, of the disc of pinhole positions (views sheared so that the
    /// focal plane stays put) whose average image has this lens's blur: a point at `z`
    /// moves on the focal plane by `p (z − s) / z` for a pinhole moved by `p`, so the
    /// disc is `f s / (N (s − f))` wide.
    pub fn aperture_diameter(&self) -> f32 {
        let f = self.focal_length();
        let s = self.focal_distance;
        f * s / (self.f_stops * (s - f))
    }
}

/// Which pixels become sprites, and when one sprite stands for a 2×2 block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpriteRule {
    /// Circles of confusion below this (full-resolution pixels) make no sprite: the
    /// composite shows the sharp image there, blending to the layers up to this size.
    pub min_coc: f32,
    /// Whether agreeing blocks make one sprite (Samaritan's 1-or-4 rule).
    pub merge: bool,
    /// With `merge`, whether a 2×2 group of blocks (4×4 texels) that agrees as a whole
    /// makes one sprite drawn at half resolution: a sixteenth of the fragments and
    /// blends of its texels' sprites, sixteen aperture samples per fragment.
    pub merge_groups: bool,
    /// Largest spread of the block's circles of confusion, full-resolution pixels.
    pub coc_tolerance: f32,
    /// Largest spread of the block's luminance relative to its mean.
    pub color_tolerance: f32,
    /// Largest spread of the block's distances relative to its mean.
    pub depth_tolerance: f32,
    /// Circles of confusion from this size (full-resolution pixels) are scattered into
    /// quarter-resolution layers: a quarter of the fragments (and blends) per sprite, one
    /// aperture sample per fragment. At least 16 (smaller values act as 16);
    /// `f32::INFINITY`: every sprite at half resolution.
    pub quarter_coc: f32,
}

impl SpriteRule {
    /// The sprite diameter (half-resolution pixels) from which a sprite is drawn at
    /// quarter resolution: `quarter_coc / 2` (sprites of 16 px and more are `coc / 2`
    /// wide), `f32::MAX` for never.
    pub fn quarter_diameter(&self) -> f32 {
        if self.quarter_coc.is_finite() {
            0.5 * self.quarter_coc.max(16.0)
        } else {
            f32::MAX
        }
    }
}

impl Default for SpriteRule {
    fn default() -> Self {
        SpriteRule {
            min_coc: 2.0,
            merge: true,
            merge_groups: true,
            coc_tolerance: 2.0,
            color_tolerance: 0.1,
            depth_tolerance: 0.05,
            quarter_coc: 32.0,
        }
    }
}

/// The blur the half-resolution round trip adds, as the squared diameter of a disc of
/// the same variance (full-resolution px²): the 2×2 box of the downsample (⅓ px²) and
/// the bilinear upsample (⅔ px²) make 1 px², and a disc of diameter `D` has `D² / 16`.
/// Sprites under 16 px are shrunk by it (`bokeh::sprite_diameter` in the CPU model).
pub const HALF_RES_BLUR: f32 = 16.0;

/// The extra blur of the quarter-resolution round trip over the half-resolution one, as
/// a disc's squared diameter in **half-resolution** pixels: the quarter round trip's
/// `4 × HALF_RES_BLUR` view px² less the `HALF_RES_BLUR` that half-resolution sprites of
/// that size keep, over 4. Quarter-resolution sprites are shrunk by it
/// (`bokeh::quarter_diameter` in the CPU model).
pub const QUARTER_RES_BLUR: f32 = 0.75 * HALF_RES_BLUR;

/// The bokeh passes' view uniform (`penumbra::dof::types::BokehView`).
#[derive(ShaderType, Clone, Copy, Debug, PartialEq)]
pub struct BokehView {
    /// Inverse projection (reverse-Z clip to view space): the depth buffer to distances
    /// along the view axis.
    pub view_from_clip: Mat4,
    /// The view's size, pixels.
    pub full_size: UVec2,
    /// The half-resolution size, `ceil(full / 2)`.
    pub half_size: UVec2,
    /// The quarter-resolution size, `ceil(half / 2)`.
    pub quarter_size: UVec2,
    /// [`Lens::coc_scale`] at the view's height.
    pub coc_scale: f32,
    /// [`Lens::focal_distance`].
    pub focal_distance: f32,
    /// [`Lens::max_coc`].
    pub max_coc: f32,
    /// [`Lens::max_depth`] (`f32::MAX` for none: WGSL has no infinity).
    pub max_depth: f32,
    /// [`SpriteRule::min_coc`].
    pub min_coc: f32,
    /// [`SpriteRule::coc_tolerance`].
    pub coc_tolerance: f32,
    /// [`SpriteRule::color_tolerance`].
    pub color_tolerance: f32,
    /// [`SpriteRule::depth_tolerance`].
    pub depth_tolerance: f32,
    /// 1 when [`SpriteRule::merge`].
    pub merge: u32,
    /// 1 when [`SpriteRule::merge`] and [`SpriteRule::merge_groups`].
    pub merge_groups: u32,
    /// Sprite slots the sprite buffer holds, 4 per 2×2 block of half-resolution pixels
    /// ([`sprite_slots`]); sprites past it are dropped.
    pub capacity: u32,
    /// [`SpriteRule::quarter_diameter`]: sprites at least this wide (half-resolution
    /// pixels) are drawn into the quarter-resolution layers.
    pub quarter_diameter: f32,
    /// The view's top-left pixel in the frame buffer (its viewport's origin; 0 for a
    /// whole target): the passes read the frame-buffer textures from there, and the
    /// composite leaves the pixels outside the viewport as they are (split screen).
    pub origin: UVec2,
}

/// The sprite slots a view of `full_size` pixels needs: 4 per 2×2 block of its
/// half-resolution image (block `b`, row-major, owns slots `4b..4b + 4`).
pub fn sprite_slots(full_size: UVec2) -> u32 {
    let half = (full_size + UVec2::ONE) / 2;
    let blocks = (half + UVec2::ONE) / 2;
    4 * blocks.x * blocks.y
}

impl BokehView {
    /// The uniform of a `full_size` view.
    pub fn new(
        lens: &Lens,
        rule: &SpriteRule,
        view_from_clip: Mat4,
        full_size: UVec2,
        capacity: u32,
    ) -> Self {
        let half_size = (full_size + UVec2::ONE) / 2;
        BokehView {
            view_from_clip,
            full_size,
            half_size,
            quarter_size: (half_size + UVec2::ONE) / 2,
            coc_scale: lens.coc_scale(full_size.y),
            focal_distance: lens.focal_distance,
            max_coc: lens.max_coc,
            max_depth: lens.max_depth.min(f32::MAX),
            min_coc: rule.min_coc,
            coc_tolerance: rule.coc_tolerance,
            color_tolerance: rule.color_tolerance,
            depth_tolerance: rule.depth_tolerance,
            merge: u32::from(rule.merge),
            merge_groups: u32::from(rule.merge && rule.merge_groups),
            capacity,
            quarter_diameter: rule.quarter_diameter(),
            origin: UVec2::ZERO,
        }
    }

    /// The uniform of a view whose viewport starts at `origin` in the frame buffer.
    pub fn at(self, origin: UVec2) -> Self {
        BokehView { origin, ..self }
    }
}
