//! Scatter bokeh depth of field: put [`BokehDepthOfField`] on a 3D camera and every
//! out-of-focus highlight spreads into the aperture's shape — a hexagon, a circle or any
//! square image — with the sharp-edged, energy-conserving discs of a real lens, where a
//! gather blur spreads a highlight into a soft smear.
//!
//! # The technique
//!
//! Samaritan's scatter bokeh (Mittring and Dudash, "The Technology Behind the Unreal
//! Engine 4 Elemental Demo" / "Samaritan", GDC 2011), with the sprites built in compute
//! and drawn indirectly as instanced quads, as Blender EEVEE's scatter pass and the Xbox
//! ATG Bokeh sample do (wgpu has no geometry shaders), the list compacted in a fixed
//! order rather than appended:
//!
//! 1. **Sprites** (compute, one thread per 2×2 block of the half-resolution image): each
//!    half-resolution pixel takes the mean colour of its 2×2 view pixels and the circle of
//!    confusion of the nearest, `c = f² (z − s) / (N z (s − f))` over the sensor height
//!    (Bevy's `DepthOfField` formula: focal length `f` from the projection's field of view
//!    and the sensor height, f-number `N`, focal distance `s`), signed: negative in front
//!    of the focal plane. A block whose four pixels are out of focus on one side of the
//!    focal plane and agree in circle of confusion, luminance and depth becomes **one** sprite, otherwise
//!    each out-of-focus pixel becomes one (the 1-or-4 rule). A 2×2 **group** of blocks
//!    (8×8 view pixels) whose sixteen pixels agree the same way, with a sprite drawn at
//!    half resolution, becomes one sprite too (the blocks see each other through
//!    workgroup memory). Each block writes its own
//!    four slots and its count per layer (below); an exclusive prefix sum of the counts
//!    and a copy list the sprites layer by layer, in block order within each, with no
//!    gaps, and set each layer's indirect draw. The order — and the layers' floating-point sums — never
//!    depend on which thread ran first: the output is the same bit for bit on every run
//!    (appending through an atomic counter made 261 of 12,065 pixels differ between two
//!    runs on lavapipe).
//! 2. **Scatter** (render, half resolution): one quad per sprite, as wide as its circle of confusion and
//!    textured with the aperture, adds `(colour · w, w)` into a **near** or a **far**
//!    layer (additive blending), `w` normalised by what the aperture sums to over the
//!    texels the sprite covers (tabulated per aperture), so a pixel spreads unit weight
//!    at any size; near sprites show the aperture point-reflected. A block's or a
//!    group's quad (one or three texels wider) adds the aperture around each of its
//!    4 or 16 pixel centres: exactly the sprites it replaces, with their mean colour,
//!    for a quarter or a sixteenth of their fragments and blends. Fragments outside
//!    the aperture are discarded rather than blended as zero. Sprites whose
//!    circle of confusion reaches `quarter_resolution_coc` (32 px) go to a near and a
//!    far layer at **quarter** resolution instead: each quarter texel adds what the
//!    sprite adds at its four half-resolution texel centres (the half-resolution layer
//!    summed 2×2, the aperture shrunk by the quarter round trip's extra blur), a quarter
//!    of the fragments and blends for the same samples. One draw per layer over its own
//!    part of the list (four vertices per sprite, a triangle strip), so each fragment
//!    blends one float4 target and no vertex runs for another layer's sprite.
//! 3. **Composite** (fullscreen, view resolution): each pixel starts from the sharp image,
//!    blends to the resolved far layer (`Σ colour w / Σ w`, the half-resolution layer
//!    plus a quarter of the quarter-resolution one, both read bilinearly) as its own
//!    circle of confusion grows from ½ pixel to `min_circle_of_confusion`, then the
//!    resolved near layer is laid over it with opacity `min(Σ w, 1)`. Pixels under ½ pixel of blur that no near sprite reaches
//!    are the input, bit for bit.
//!
//! The passes run in `Core3d`'s post-processing, before tonemapping, on the linear HDR
//! image (bloom added first when Bevy's `Bloom` is on).
//!
//! Every pass has a CPU model in `penumbra_reference::bokeh`, equal to the shaders on
//! lavapipe (`tests/bokeh_gpu.rs`); the model is checked against a ray-traced thin lens
//! (the mean of pinhole views across the aperture).
//!
//! # Limits
//!
//! - One depth per pixel: what a near blur uncovers behind a foreground edge is the
//!   background's sharp pixel there, not the hidden surface (as in every post-process
//!   DOF). The far layer is normalised per pixel, so a far blur does not darken where it
//!   meets a sharp foreground and a sharp foreground does not bleed into it; but where
//!   fewer background sprites overlap (beside a sharp object) a far highlight gets a
//!   larger share: +0.9 % of a highlight's energy with a sharp square within its blur in
//!   the plugin's test scene.
//! - Half resolution: circles of confusion under `min_circle_of_confusion` (2 px) keep the
//!   sharp image; the half-resolution round trip's own blur is taken off sprites under
//!   16 px. Small blurs are where a full-resolution gather does better: against a
//!   thin-lens truth on Bevy's depth-of-field scene (`tests/bokeh_truth.rs`) Bevy's
//!   Gaussian `DepthOfField` has 0.129 relative error where the blur is 3–6 px, this
//!   0.175 (fine textures alias through the half-resolution image); this wins on
//!   occlusion borders (0.097 against 0.127) and on the bokeh's shape.
//! - Cost grows with the out-of-focus area times the squared circle of confusion (every
//!   sprite's quad is rasterised): a fully blurred view at the 64 px default fills about
//!   `(w h / 4) · 32² / 16` fragments at quarter resolution (four times that with
//!   `quarter_resolution_coc` at infinity) before the 1-or-4 rule merges agreeing blocks
//!   (about a quarter of the sprites on smooth regions) and groups (a sixteenth).
//!   On Bevy's depth-of-field scene at 1920×1080 with the bench's lens (f/0.125;
//!   `tests/bokeh_truth.rs`, `merge_rule_error_against_work`: the CPU model, equal to
//!   the passes, on the rendered image) the scatter shades 33.2 M fragments unmerged,
//!   10.8 M with blocks and 4.46 M with blocks and groups, each at 0.035 mean error
//!   against the thin lens (the groups' error equal to the blocks' to 10⁻⁴ in every
//!   mask). A group's fragment takes sixteen aperture samples where a block's takes
//!   four, so the saving is the blending's: where sampling bounds the pass it is
//!   smaller (lavapipe's pass at 1920×1080: 300 → 283 ms). Against the ray-traced thin
//!   lens (`penumbra_reference::bokeh` truth tests, 256 × 160, blur up to 64 px) the
//!   32 px default draws 0.68 of the fragments of half resolution everywhere at the same
//!   error (0.0122 mean display error); from 24 px, 0.63 at the same error; from 16 px,
//!   0.27 but 0.0080 against 0.0042 in out-of-focus interiors. An isolated 48 px
//!   highlight covers its aperture's shape with overlap 0.94–0.95 at quarter resolution,
//!   0.96 at half.
//! - No opt-out per material: everything drawn before post-processing is blurred
//!   (a second main pass after the effect would be needed; not offered).
//! - With MSAA the depth is the first sample's, as Bevy's `DepthOfField` reads it.
//! - Perspective cameras only (one warning, then nothing, on an orthographic one).
//! - A camera with a viewport (split screen) blurs its viewport only: sprites come from
//!   its pixels and the composite leaves the rest of the target as it is.
//! - Not with Bevy's `DepthOfField` on the same camera (two lens blurs): Penumbra's is
//!   off while Bevy's is there (one warning).
//!
//! Cost: nothing without the component. Per camera: two half-resolution and two
//! quarter-resolution layers (`Rgba32Float`, 40 bytes per half pixel for all four;
//! `Rgba16Float`, 20, on devices that cannot blend 32-bit floats), the sprites' slots and their compacted list (32 bytes
//! each per half pixel) and a count per block: 54 MB at 1080p. The passes: the sprite
//! pass, the scan (three passes over workgroups of 1,024 blocks: `penumbra_cinematic_core::scan`), the copy,
//! one quad per sprite (a draw per layer), the composite. On lavapipe at 384 × 288 (`tests/bokeh_truth.rs`,
//! f/0.05) frames take 41–46 ms with it, 31–34 ms with Bevy's Gaussian `DepthOfField`,
//! 35–37 ms with its bokeh and 24–31 ms with none (3 runs). On an NVIDIA H200 at
//! 1920×1080 on Bevy's depth-of-field scene: 10.9 ms, against about 3.0 ms for Bevy's
//! bokeh `DepthOfField` (`BENCHMARKS.md`, before the layers were listed apart and the
//! quarter-resolution layers; not measured on a GPU since) — over #44's 1 ms budget.
//! Profiled on lavapipe at 1920×1080 (`penumbra-bench --scenes dof`): the far layer's
//! draw shaded 24.2 M fragments, the near one's 0.14 M; with every layer's draw running
//! every sprite's six vertices, vertex work was about 100 ms of lavapipe's time per
//! draw, which listing the layers apart and four-vertex strips removed (the pass 757 →
//! 544 ms). That scene's blur stays under the 32 px of the quarter-resolution layers
//! (their draws shaded no fragment), so they save nothing there; groups cut its
//! fragments to 0.41 of the blocks' (above; not measured on a GPU yet). Diagnostics: the time span `penumbra_bokeh_dof`.

mod pipelines;
mod render;

use bevy::asset::AssetEvent;
use bevy::camera::{Camera3d, PhysicalCameraParameters, Projection};
use bevy::platform::collections::{HashMap, HashSet};
use bevy::post_process::dof::DepthOfField;
use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::render_resource::TextureUsages;
use bevy_penumbra_df::system_times::timed;
use penumbra_cinematic_core::dof::{Aperture, Lens, SpriteRule};
use std::sync::Arc;

/// Adds [`BokehDepthOfField`]. Part of `PenumbraPlugins`.
#[derive(Default)]
pub struct BokehDepthOfFieldPlugin;

/// The shape an out-of-focus highlight takes: the lens's aperture.
#[derive(Reflect, Clone, Debug, Default, PartialEq)]
#[reflect(Clone, Default)]
pub enum BokehAperture {
    /// A regular hexagon with a vertex up (six aperture blades). The default.
    #[default]
    Hexagon,
    /// A circle (a wide-open lens).
    Circle,
    /// A regular polygon of `sides` sides (3 to [`MAX_APERTURE_SIDES`]; others are
    /// clamped with a warning), a vertex at `rotation` radians from +x,
    /// counter-clockwise (taken to 1/256 of the turn between two vertices: an animated
    /// rotation makes at most 256 shapes per side count).
    Polygon {
        /// Blades of the aperture.
        sides: u32,
        /// Where the first vertex points, radians counter-clockwise from +x.
        rotation: f32,
    },
    /// Any shape, as a square image (rows from the top, as it looks from behind the
    /// camera: far highlights show it upright, near ones point-reflected). Transmission
    /// is the pixel's linear luminance times its alpha, so a white shape on black and
    /// an opaque shape on transparency both work. The image needs its CPU copy (Bevy
    /// keeps it for loaded images; `RenderAssetUsages::MAIN_WORLD`) and a format
    /// `Image::get_color_at` reads (not compressed). An empty, non-square, blank,
    /// unreadable or larger than 1024² image is rejected with one warning and the
    /// circle is used; while it loads, the circle is used too.
    Image(Handle<Image>),
}

/// Put on a 3D camera: scatter bokeh depth of field (module docs). A camera without it
/// renders as before and pays nothing.
#[derive(Component, Reflect, Clone, Debug, PartialEq)]
#[reflect(Component, Clone, Default)]
#[require(Camera3d)]
pub struct BokehDepthOfField {
    /// Distance to the plane in focus, metres along the view axis. Default 10 (Bevy's).
    /// Must be finite and beyond the focal length: otherwise 10 (or twice the focal
    /// length when it is that short), with a warning. No cost.
    pub focal_distance: f32,
    /// The aperture as an f-number (focal length / aperture diameter): smaller is
    /// blurrier. Default 1 (Bevy's `PhysicalCameraParameters`). Must be positive and
    /// finite: otherwise the default, with a warning; below [`MIN_F_STOPS`] (0.01): that, with a
    /// warning. Cost: blurrier views draw larger
    /// sprites.
    pub aperture_f_stops: f32,
    /// Height of the sensor, metres; with the projection's vertical field of view it gives
    /// the focal length, as for Bevy's `DepthOfField`. Default 0.01866 (Super 35). Must be
    /// positive and finite: otherwise the default, with a warning; above
    /// [`MAX_SENSOR_HEIGHT`] (1 m): that, with a warning.
    pub sensor_height: f32,
    /// The bokeh shape. Default [`BokehAperture::Hexagon`]. No cost.
    pub aperture: BokehAperture,
    /// The largest circle of confusion, view pixels (diameter). Default 64 (Bevy's).
    /// Cost: the fill rate grows with its square where the view is that blurred. Clamped
    /// to `1..=256` with a warning.
    pub max_circle_of_confusion_diameter: f32,
    /// Distances beyond this count as this far, metres: the sky and background, which
    /// Bevy puts at infinity, get this blur. Default infinity. Must be positive (NaN or
    /// ≤ 0: infinity, with a warning). No cost.
    pub max_depth: f32,
    /// Circles of confusion below this make no sprite, view pixels: the sharp image is
    /// kept there, blending to the blurred layers up to this size. Default 2. Cost: lower
    /// values turn more nearly sharp pixels into sprites. Clamped to
    /// `0..=max_circle_of_confusion_diameter` with a warning.
    pub min_circle_of_confusion: f32,
    /// Samaritan's 1-or-4 rule: a 2×2 block of half-resolution pixels that agree (below)
    /// is drawn as one sprite instead of four. Default on. Off: four times the sprites on
    /// smooth regions (sixteen with `merge_groups`), with no visible gain (the rule's
    /// error is 10⁻⁴ in the unit tests).
    pub merge_blocks: bool,
    /// With `merge_blocks`: a 2×2 group of blocks (8×8 view pixels) whose sixteen
    /// half-resolution pixels agree, and whose blur is drawn at half resolution, is one
    /// sprite: a sixteenth of their fragments and blends (the scatter pass's
    /// bottleneck on GPUs short of raster output), sixteen aperture samples per
    /// fragment. Default on. Off: a quarter of the fragments at most (blocks only).
    pub merge_groups: bool,
    /// The 1-or-4 rule: largest spread of a block's circles of confusion, view pixels.
    /// Default 2. Must be ≥ 0 (default otherwise, with a warning).
    pub merge_coc_tolerance: f32,
    /// The 1-or-4 rule: largest spread of a block's luminance relative to its mean.
    /// Default 0.1. Must be ≥ 0 (default otherwise, with a warning).
    pub merge_color_tolerance: f32,
    /// The 1-or-4 rule: largest spread of a block's distances relative to its mean.
    /// Default 0.05. Must be ≥ 0 (default otherwise, with a warning).
    pub merge_depth_tolerance: f32,
    /// Circles of confusion from this size, view pixels, are scattered at quarter
    /// resolution: a quarter of the fragments and blends per sprite (the scatter pass's
    /// cost grows with the square of the blur), aperture edges about one view pixel
    /// softer. Default 32, where a bokeh's edges are as sharp relative to its size as
    /// those of a 16 px bokeh at half resolution (module docs: the error against the thin
    /// lens is unchanged). At least 16 (smaller values are clamped, with a warning; NaN
    /// gives the default); `f32::INFINITY` keeps every sprite at half resolution.
    pub quarter_resolution_coc: f32,
}

impl Default for BokehDepthOfField {
    fn default() -> Self {
        let physical = PhysicalCameraParameters::default();
        let rule = SpriteRule::default();
        Self {
            focal_distance: 10.0,
            aperture_f_stops: physical.aperture_f_stops,
            sensor_height: physical.sensor_height,
            aperture: BokehAperture::Hexagon,
            max_circle_of_confusion_diameter: 64.0,
            max_depth: f32::INFINITY,
            min_circle_of_confusion: rule.min_coc,
            merge_blocks: rule.merge,
            merge_groups: rule.merge_groups,
            merge_coc_tolerance: rule.coc_tolerance,
            merge_color_tolerance: rule.color_tolerance,
            merge_depth_tolerance: rule.depth_tolerance,
            quarter_resolution_coc: rule.quarter_coc,
        }
    }
}

/// The smallest [`BokehDepthOfField::aperture_f_stops`] used (f/0.01: a hundred times
/// the widest real lens; smaller ones make the aperture overflow).
pub const MIN_F_STOPS: f32 = 0.01;
/// The largest [`BokehDepthOfField::sensor_height`] used, metres (five times the
/// largest film format; larger ones make the focal length overflow).
pub const MAX_SENSOR_HEIGHT: f32 = 1.0;

impl BokehDepthOfField {
    /// The settings as the passes use them, for a projection with vertical field of view
    /// `fov_y` (radians), and what was out of range (one message per setting, naming the
    /// value used instead).
    pub fn resolve(&self, fov_y: f32) -> (Lens, SpriteRule, Vec<String>) {
        let defaults = Self::default();
        let mut problems = Vec::new();
        let mut positive = |name: &str, v: f32, fallback: f32| {
            if v.is_finite() && v > 0.0 {
                v
            } else {
                problems.push(format!("{name} = {v} (must be positive; using {fallback})"));
                fallback
            }
        };
        let f_stops = positive(
            "aperture_f_stops",
            self.aperture_f_stops,
            defaults.aperture_f_stops,
        );
        let sensor_height = positive("sensor_height", self.sensor_height, defaults.sensor_height);
        // Bounds that keep the lens finite: the aperture (focal length / f-stops) and
        // the focal length (sensor / field of view) would overflow at the extremes.
        let f_stops = if f_stops < MIN_F_STOPS {
            problems.push(format!(
                "aperture_f_stops = {f_stops} (at least {MIN_F_STOPS}; using it)"
            ));
            MIN_F_STOPS
        } else {
            f_stops
        };
        let sensor_height = if sensor_height > MAX_SENSOR_HEIGHT {
            problems.push(format!(
                "sensor_height = {sensor_height} m (at most {MAX_SENSOR_HEIGHT} m; using it)"
            ));
            MAX_SENSOR_HEIGHT
        } else {
            sensor_height
        };
        let max_depth = if self.max_depth > 0.0 {
            self.max_depth
        } else {
            problems.push(format!(
                "max_depth = {} (must be positive; using infinity)",
                self.max_depth
            ));
            f32::INFINITY
        };
        let mut lens = Lens {
            focal_distance: self.focal_distance,
            f_stops,
            sensor_height,
            fov_y,
            max_coc: 64.0,
            max_depth,
        };
        let focal_length = lens.focal_length();
        if !(self.focal_distance.is_finite() && self.focal_distance > focal_length) {
            let fallback = if focal_length < 5.0 {
                defaults.focal_distance.max(2.0 * focal_length)
            } else {
                2.0 * focal_length
            };
            problems.push(format!(
                "focal_distance = {} (must be finite and beyond the focal length {focal_length} \
                 m; using {fallback})",
                self.focal_distance
            ));
            lens.focal_distance = fallback;
        }
        let max_coc = self.max_circle_of_confusion_diameter;
        lens.max_coc = if (1.0..=256.0).contains(&max_coc) {
            max_coc
        } else {
            let c = if max_coc.is_nan() {
                64.0
            } else {
                max_coc.clamp(1.0, 256.0)
            };
            problems.push(format!(
                "max_circle_of_confusion_diameter = {max_coc} (must be in [1, 256]; using {c})"
            ));
            c
        };
        let min_coc = self.min_circle_of_confusion;
        let min_coc = if (0.0..=lens.max_coc).contains(&min_coc) {
            min_coc
        } else {
            let c = if min_coc.is_nan() {
                defaults.min_circle_of_confusion.min(lens.max_coc)
            } else {
                min_coc.clamp(0.0, lens.max_coc)
            };
            problems.push(format!(
                "min_circle_of_confusion = {min_coc} (must be in [0, {}]; using {c})",
                lens.max_coc
            ));
            c
        };
        let mut tolerance = |name: &str, v: f32, fallback: f32| {
            if v.is_finite() && v >= 0.0 {
                v
            } else {
                problems.push(format!("{name} = {v} (must be ≥ 0; using {fallback})"));
                fallback
            }
        };
        let mut rule = SpriteRule {
            min_coc,
            merge: self.merge_blocks,
            merge_groups: self.merge_groups,
            coc_tolerance: tolerance(
                "merge_coc_tolerance",
                self.merge_coc_tolerance,
                defaults.merge_coc_tolerance,
            ),
            color_tolerance: tolerance(
                "merge_color_tolerance",
                self.merge_color_tolerance,
                defaults.merge_color_tolerance,
            ),
            depth_tolerance: tolerance(
                "merge_depth_tolerance",
                self.merge_depth_tolerance,
                defaults.merge_depth_tolerance,
            ),
            quarter_coc: self.quarter_resolution_coc,
        };
        let q = self.quarter_resolution_coc;
        if q.is_nan() || q < 16.0 {
            let c = if q.is_nan() {
                defaults.quarter_resolution_coc
            } else {
                16.0
            };
            problems.push(format!(
                "quarter_resolution_coc = {q} (must be at least 16; using {c})"
            ));
            rule.quarter_coc = c;
        }
        if let BokehAperture::Polygon { sides, rotation } = self.aperture {
            if sides < 3 {
                problems.push(format!("aperture sides = {sides} (must be ≥ 3; using 3)"));
            } else if sides > MAX_APERTURE_SIDES {
                problems.push(format!(
                    "aperture sides = {sides} (at most {MAX_APERTURE_SIDES}; using \
                     {MAX_APERTURE_SIDES})"
                ));
            }
            if !rotation.is_finite() {
                problems.push(format!("aperture rotation = {rotation} (using 0)"));
            }
        }
        (lens, rule, problems)
    }

    /// What is out of range, for a projection of vertical field of view `fov_y` (empty
    /// when nothing is).
    pub fn problems(&self, fov_y: f32) -> Vec<String> {
        self.resolve(fov_y).2
    }
}

/// Texels along each side of the built-in apertures' images.
pub const BUILT_IN_APERTURE_SIZE: u32 = 64;

/// Largest aperture image accepted, texels per side.
pub const MAX_APERTURE_IMAGE_SIZE: u32 = 1024;

/// Most sides of a [`BokehAperture::Polygon`] (more are clamped, with a warning: on the
/// 64-texel built-in image a 64-gon is already a circle, and the shape's cost grows
/// with its sides — four billion of them hung the main world).
pub const MAX_APERTURE_SIDES: u32 = 64;

/// Steps of a polygon's rotation between two of its vertices ([`BokehAperture::Polygon`]).
const APERTURE_ROTATION_STEPS: u32 = 256;

/// A camera's aperture image, checked and normalised (main world, then extracted): `id`
/// names its texture in the render world.
#[derive(Component, Clone, Debug)]
pub struct BokehApertureShape {
    /// Unique per distinct aperture (a changed image gets a new one).
    pub id: u64,
    /// The shape.
    pub aperture: Arc<Aperture>,
}

/// What names an aperture in the cache.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum ApertureKey {
    Hexagon,
    Circle,
    /// Sides, and rotation in steps of 1/`APERTURE_ROTATION_STEPS` of the turn between
    /// two vertices.
    Polygon {
        sides: u32,
        rotation: u32,
    },
    Image(AssetId<Image>),
}

impl ApertureKey {
    fn of(aperture: &BokehAperture) -> Self {
        match aperture {
            BokehAperture::Hexagon => ApertureKey::Hexagon,
            BokehAperture::Circle => ApertureKey::Circle,
            BokehAperture::Polygon { sides, rotation } => {
                // A regular polygon repeats every turn between two vertices: the key is
                // the rotation within it, in APERTURE_ROTATION_STEPS.
                let sides = (*sides).clamp(3, MAX_APERTURE_SIDES);
                let step = std::f32::consts::TAU / sides as f32;
                let r = if rotation.is_finite() { *rotation } else { 0.0 };
                let steps = APERTURE_ROTATION_STEPS as f32;
                let k = ((r.rem_euclid(step) / step) * steps).round() as u32;
                ApertureKey::Polygon {
                    sides,
                    rotation: k % APERTURE_ROTATION_STEPS,
                }
            }
            BokehAperture::Image(handle) => ApertureKey::Image(handle.id()),
        }
    }
}

/// The apertures made so far (main world), each once.
#[derive(Resource, Default)]
struct BokehApertureCache {
    shapes: HashMap<ApertureKey, BokehApertureShape>,
    next_id: u64,
}

impl BokehApertureCache {
    fn insert(&mut self, key: ApertureKey, aperture: Aperture) -> BokehApertureShape {
        self.next_id += 1;
        let shape = BokehApertureShape {
            id: self.next_id,
            aperture: Arc::new(aperture),
        };
        self.shapes.insert(key, shape.clone());
        shape
    }
}

/// The transmission image of a Bevy image: linear luminance × alpha per texel.
pub fn aperture_from_image(image: &Image) -> Result<Aperture, String> {
    let (width, height) = (image.width(), image.height());
    if width.max(height) > MAX_APERTURE_IMAGE_SIZE {
        return Err(format!(
            "the aperture image is {width}×{height}, larger than {MAX_APERTURE_IMAGE_SIZE}²"
        ));
    }
    if image.data.is_none() {
        return Err("the aperture image has no CPU copy (RenderAssetUsages::MAIN_WORLD)".into());
    }
    if width == 0 || height == 0 || width != height {
        // Named by the aperture's own check below, without reading any texel.
        return Aperture::from_image(width, height, &[]).map_err(|e| e.to_string());
    }
    crate::image_data::check_texel_data(image)
        .map_err(|e| format!("the aperture image cannot be read: {e}"))?;
    let mut weights = Vec::with_capacity((width * height) as usize);
    for y in 0..height {
        for x in 0..width {
            let c = image
                .get_color_at(x, y)
                .map_err(|e| format!("the aperture image cannot be read: {e}"))?
                .to_linear();
            let luminance = 0.2126 * c.red + 0.7152 * c.green + 0.0722 * c.blue;
            weights.push(luminance * c.alpha);
        }
    }
    Aperture::from_image(width, height, &weights).map_err(|e| e.to_string())
}

/// Gives every bokeh camera its aperture shape, making each distinct shape once; an
/// image's is remade when the image changes.
fn prepare_bokeh_apertures(
    mut commands: Commands,
    cameras: Query<(Entity, &BokehDepthOfField, Option<&BokehApertureShape>)>,
    images: Res<Assets<Image>>,
    mut events: MessageReader<AssetEvent<Image>>,
    mut cache: ResMut<BokehApertureCache>,
) {
    for event in events.read() {
        if let AssetEvent::Modified { id } | AssetEvent::Removed { id } = event {
            cache.shapes.remove(&ApertureKey::Image(*id));
        }
    }
    let mut used = HashSet::new();
    for (entity, settings, current) in &cameras {
        let key = ApertureKey::of(&settings.aperture);
        used.insert(key);
        let shape = match cache.shapes.get(&key) {
            Some(shape) => shape.clone(),
            None => match key {
                ApertureKey::Hexagon => {
                    cache.insert(key, Aperture::hexagon(BUILT_IN_APERTURE_SIZE))
                }
                ApertureKey::Circle => cache.insert(key, Aperture::circle(BUILT_IN_APERTURE_SIZE)),
                ApertureKey::Polygon { sides, rotation } => {
                    let step = std::f32::consts::TAU / sides as f32;
                    let angle = rotation as f32 / APERTURE_ROTATION_STEPS as f32 * step;
                    cache.insert(key, Aperture::polygon(BUILT_IN_APERTURE_SIZE, sides, angle))
                }
                ApertureKey::Image(id) => {
                    let Some(image) = images.get(id) else {
                        // Loading: the circle meanwhile (no warning).
                        let circle = ApertureKey::Circle;
                        let shape = match cache.shapes.get(&circle) {
                            Some(shape) => shape.clone(),
                            None => cache.insert(circle, Aperture::circle(BUILT_IN_APERTURE_SIZE)),
                        };
                        if current.map(|c| c.id) != Some(shape.id) {
                            commands.entity(entity).insert(shape);
                        }
                        continue;
                    };
                    let aperture = aperture_from_image(image).unwrap_or_else(|e| {
                        warn!(
                            "Penumbra: BokehDepthOfField on {entity}: {e}; using a circular \
                             aperture"
                        );
                        Aperture::circle(BUILT_IN_APERTURE_SIZE)
                    });
                    // Cached either way: a bad image warns once per load.
                    cache.insert(key, aperture)
                }
            },
        };
        if current.map(|c| c.id) != Some(shape.id) {
            commands.entity(entity).insert(shape);
        }
    }
    // Shapes no camera uses any more are dropped (an animated rotation made one a frame,
    // kept for ever); the built-in ones stay.
    cache
        .shapes
        .retain(|k, _| used.contains(k) || matches!(k, ApertureKey::Hexagon | ApertureKey::Circle));
}

/// Warns once per change of a camera's settings when some are out of range, when its
/// projection is not perspective, or when it also has Bevy's `DepthOfField`.
#[allow(clippy::type_complexity, reason = "a Bevy system")]
fn warn_bad_bokeh_settings(
    cameras: Query<
        (Entity, &BokehDepthOfField, &Projection, Has<DepthOfField>),
        Or<(Changed<BokehDepthOfField>, Added<DepthOfField>)>,
    >,
) {
    for (entity, settings, projection, bevy_dof) in &cameras {
        if bevy_dof {
            warn!(
                "Penumbra: BokehDepthOfField on {entity}: the camera also has Bevy's \
                 DepthOfField (two lens blurs); Penumbra's is off while Bevy's is there"
            );
            continue;
        }
        let Projection::Perspective(perspective) = projection else {
            warn!(
                "Penumbra: BokehDepthOfField on {entity}: the camera's projection is not \
                 perspective; no depth of field"
            );
            continue;
        };
        let problems = settings.problems(perspective.fov);
        if !problems.is_empty() {
            warn!(
                "Penumbra: BokehDepthOfField on {entity}: {}; clamped",
                problems.join(", ")
            );
        }
    }
}

/// The passes read the view's depth buffer: it must be bindable.
fn configure_bokeh_depth_textures(mut cameras: Query<&mut Camera3d, With<BokehDepthOfField>>) {
    for mut camera in &mut cameras {
        let usages = TextureUsages::from(camera.depth_texture_usages);
        if !usages.contains(TextureUsages::TEXTURE_BINDING) {
            camera.depth_texture_usages = (usages | TextureUsages::TEXTURE_BINDING).into();
        }
    }
}

impl Plugin for BokehDepthOfFieldPlugin {
    fn build(&self, app: &mut App) {
        bevy_penumbra_df::register_shader_library(app);
        app.register_type::<BokehDepthOfField>()
            .init_resource::<BokehApertureCache>()
            .add_plugins(render::sync_plugin())
            .add_systems(
                PostUpdate,
                (
                    timed(warn_bad_bokeh_settings).after(bevy::camera::CameraUpdateSystems),
                    // Its new images' events are sent this frame.
                    timed(prepare_bokeh_apertures).before(bevy::asset::AssetEventSystems),
                    timed(configure_bokeh_depth_textures),
                ),
            );
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

#[cfg(test)]
mod tests;
