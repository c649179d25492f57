//! Billboard reflections (Samaritan; Mittring and Dudash, GDC 2011): textured quads —
//! lit signs, windows — reflected on every deferred surface, glossy and anisotropic,
//! composited up to [`BillboardReflections::max_layers`] deep.
//!
//! # Technique
//!
//! Each G-buffer pixel's mirror ray (from its normal and the view vector) is intersected
//! with the [`ReflectionBillboard`]s its screen tile can reach (a small pass lists them
//! per 16 × 16 tile, conservatively: [`BillboardReflections::tile_culling`]): one-sided
//! quads, exactly. The nearest hits within
//! [`BillboardReflections::max_distance`] whose footprint overlaps the image are sampled
//! over the GGX lobe's footprint at the hit distance — a mip level from the lobe's width
//! and taps along its long axis, which grows toward grazing angles (the streaks of wet
//! streets) and with [`BillboardReflections::anisotropy`] — and composited front to back
//! (premultiplied alpha), each dimmed by its reflection shadow — a soft march along the
//! mirror ray through the distance-field scene (each quarter of the ray through the
//! objects near it), as Samaritan's reflection shadows ray-cast the distance field. The result is the view's specular layer
//! (`bevy_penumbra_df::lighting::PenumbraSpecularLayer`): Penumbra's lighting pass adds
//! it under Bevy's environment BRDF and lets it cover the environment map's specular by
//! its coverage, so energy is not added twice. The model, shared arithmetic and its
//! derivation: `penumbra_cinematic_core::reflections::pass`.
//!
//! # Images: one texture array
//!
//! The billboards' images live in one `Rgba16Float` texture array with a full mip chain
//! built on the CPU (premultiplied, 2 × 2 box filter) when an image is added or changes.
//! **Every image must have the same size**; any format Bevy can read texel by texel
//! (`Image::get_color_at`: 8-bit sRGB or linear, 16- and 32-bit float, …) is converted.
//! The array takes the size most billboards' images share (ties: the larger); a
//! billboard whose image has another size is skipped with one warning, as is one whose
//! image cannot be read (its format, or its data not kept in the main world), is over
//! 8,192 texels a side, or would be the array's 257th. An image still loading is
//! skipped silently.
//!
//! An image keeps its layer while a billboard shows it: a changed image re-uploads its
//! own layer, a new one takes the first free layer, and a removed billboard frees its
//! image's layer and uploads nothing ([`ReflectionImageUploads`] counts). The array
//! texture grows to the next power of two of the layers and is made anew only on a new
//! image size, more layers than it holds, or under a quarter of them in use. A mip chain
//! (CPU, 4/3 × 16 bytes per texel) is dropped when no billboard refers to its image.
//!
//! The component reflects a quad; it draws nothing. Show the sign itself with a mesh on
//! the same entity (a `Rectangle` of the same size with an emissive material), or not.
//!
//! **Render layers.** A camera reflects the billboards whose `RenderLayers` (none: layer
//! 0) share one of its own, as Bevy draws meshes: each distinct set of layers among the
//! billboards is a bit of [`GpuBillboard::layers`](penumbra_cinematic_core::reflections::pass::GpuBillboard),
//! each view's uniform the bits it sees, and the cull and the trace skip the others. Up
//! to 32 distinct sets; billboards past them are reflected by every camera (one
//! warning).
//!
//! # Limits
//!
//! - Only the billboards reflect: other geometry is not in the reflection (screen-space
//!   reflections or environment maps serve it). It occludes them through the
//!   distance-field scene ([`BillboardReflections::reflection_shadows`]): geometry
//!   without a `DistanceFieldCaster` does not.
//! - Deferred MSAA (`DeferredMsaa`): the trace runs once per pixel, from the pixel's
//!   representative sample (the samples' mean where they agree, the first covered
//!   sample on edges), and every sample of the pixel reads that reflection: on an edge
//!   between a reflecting and a rough surface the rough one's samples take the other's
//!   reflection (one pixel wide). The clearcoat layer does not reflect billboards, and SSAO's or DFAO's
//!   specular occlusion does not dim them (their reflection shadows do).
//! - The footprint is a box filter (mip levels and taps); GGX's long tail is not: against
//!   the Monte Carlo truth the mean error is 2–7 % of the signs' luminance
//!   (`penumbra_reference::reflections`), mostly at the images' edges.
//! - Reflection shadows see distance-field casters only. Their cone (an eighth of the
//!   lobe's footprint, calibrated against exact visibility) takes the nearest surface as
//!   covering it whole: thin occluders in rough reflections come out too dark. A surface
//!   behind the billboard's plane (the wall a sign hangs on) hides nothing.
//! - Cost: per shaded pixel, one ray–quad test per billboard of its tile (every billboard
//!   when more than 128 reach the tile), then up to `max_layers` footprints of 4
//!   trilinear taps, and the shadow march (`shadow_steps` × the distance-field objects);
//!   half resolution quarters it. On lavapipe at 384 × 288: 15–20 ms for a few signs,
//!   ~90 ms for 100, ~850 ms for 1,000 (250 ms at half resolution). Memory: the array
//!   (4/3 × 8 bytes per texel per image), 32 bytes per billboard, the layer texture (8
//!   bytes per pixel, a quarter at half resolution) and up to 129 words per tile (129
//!   more with reflection shadows: the caster list).
//! - **Many casters**: with reflection shadows a small compute pass first writes each
//!   object's camera-relative bounding sphere (16 bytes), and the tile cull lists each
//!   tile's shadow casters (up to 128: those within reach of some ray of its pixels, up
//!   to the farthest billboard the tile keeps); each segment of a pixel's march gathers
//!   its own from that list, and a segment that gathers more than 32 marches all its
//!   candidates. A glossy floor's tiles list few, but tiles holding the casters' own
//!   glossy surfaces face every way: on a model of the benchmark's stress scene (1,000
//!   casters, 100 signs; `penumbra_cinematic_core`'s test `reflection_shadow_work`) 118
//!   of 160 tiles at 320 × 180 are over 128. With more than 128 casters the same pass
//!   therefore also sorts their centres into a uniform grid (at most 32³ cells over their
//!   box; 256 KiB and 8 bytes per object of the view's list buffer), and a pixel of an
//!   overflowing tile, or of one listing more than 64, gathers each segment's casters
//!   from the cells near it — the same casters, no pixel changed
//!   (`penumbra_cinematic_core::reflections::grid`): 34 sphere tests per pixel on that
//!   model instead of 3,156. On lavapipe the pass there takes
//!   0.3 s (1.7 s with every object tested, 8.5 s before the spheres, the lists and 8
//!   segments; 5 frames at 320 × 180). Casters much larger than the rest (wider than a
//!   cell) are tested by every gather; a scene whose casters spread over kilometres
//!   has coarse cells.

mod collect;
mod render;
mod spheres;
mod upload;

pub use upload::ReflectionImageUploads;

use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy_penumbra_df::PenumbraLighting;
use bevy_penumbra_df::system_times::timed;

pub use penumbra_cinematic_core::reflections::{DEFAULT_LAYERS, MAX_LAYERS};

/// Adds billboard reflections: [`ReflectionBillboard`] and [`BillboardReflections`].
/// Needs `PenumbraLightingPlugin`. Part of `PenumbraPlugins` (feature `reflections`).
#[derive(Default)]
pub struct BillboardReflectionsPlugin;

/// A quad reflected by [`BillboardReflections`] cameras: the `size` rectangle in the
/// entity's local XY plane, facing local +Z (Bevy's `Rectangle`), placed by its
/// `GlobalTransform` (scale included). One-sided: it reflects only toward the side it
/// faces. Hidden entities do not reflect.
#[derive(Component, Reflect, Clone, Debug)]
#[reflect(Component, Clone, Default)]
#[require(Transform, Visibility)]
pub struct ReflectionBillboard {
    /// The image: linear or sRGB colour with straight alpha (0 transparent); every
    /// billboard image must have the same size (module docs). Default: none (skipped).
    pub image: Handle<Image>,
    /// Size of the quad before the transform's scale, metres. Default 1 × 1. A zero or
    /// non-finite size (or transform) is skipped with one warning.
    pub size: Vec2,
    /// The luminance of an image texel of 1, cd/m² (the units of Bevy's emissive
    /// colours and environment map intensity). Default 1000 (a lit sign). No cost.
    pub emissive: f32,
}

impl Default for ReflectionBillboard {
    fn default() -> Self {
        ReflectionBillboard {
            image: Handle::default(),
            size: Vec2::ONE,
            emissive: 1000.0,
        }
    }
}

/// What a camera's lighting pass shows of its reflections.
#[derive(Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ReflectionDebugView {
    /// Shading.
    #[default]
    None,
    /// The specular layer itself, unexposed: premultiplied reflected radiance (cd/m²)
    /// and coverage in alpha.
    Layer,
}

/// Billboard reflections on a [`PenumbraLighting`] camera (module docs).
#[derive(Component, Reflect, Clone, Debug)]
#[reflect(Component, Clone, Default)]
#[require(PenumbraLighting)]
pub struct BillboardReflections {
    /// Hits composited per pixel, nearest first, 1..=[`MAX_LAYERS`]. Default
    /// [`DEFAULT_LAYERS`] (3, Samaritan's). Cost: a footprint sample per layer hit.
    pub max_layers: u32,
    /// Billboards farther along the reflected ray than this are not reflected, metres.
    /// Default 100 (also what NaN, negative or infinite values become, with a warning);
    /// 0 reflects nothing. No cost beyond the hits it keeps.
    pub max_distance: f32,
    /// Trace at half resolution (each 2 × 2 block's top-left pixel) and upsample with
    /// depth weights in the lighting pass. Default false. A quarter of the trace's cost.
    pub half_resolution: bool,
    /// Stretches the reflection along the plane of incidence (wet-street streaks):
    /// GGX `α_t = α (1 + a)`, `α_b = α (1 − a)` with the tangent toward the viewer,
    /// `[0, 0.95]`. Default 0. Cost: more taps along the footprint (at most 8).
    pub anisotropy: f32,
    /// Reflection shadows: each hit dimmed by a soft march along the mirror ray through
    /// the distance-field scene's shadow-casting objects (`DistanceFieldCaster`s), so a
    /// building between a sign and the street hides its reflection. Default true. Cost:
    /// per reflecting pixel, the ray to its last hit in 8 segments, each reached by the
    /// march culled once (a bounding-sphere test per object of its tile's caster list,
    /// or per object when the tile has none; it keeps the objects within the shadow cone
    /// of that segment, at most 32, else it marches every candidate there), then up to
    /// `shadow_steps` distance evaluations of the kept objects; nothing while the scene
    /// has no caster.
    pub reflection_shadows: bool,
    /// The march's steps, `1..=256`. Default 32.
    pub shadow_steps: u32,
    /// The narrowest shadow cone (tangent of its half-angle; rough surfaces widen it
    /// with their lobe): softness of a mirror's reflection shadows, `[0.001, 1]`.
    /// Default 0.02. No cost.
    pub shadow_softness: f32,
    /// Cull the billboards per 16 × 16-pixel tile of the trace (a small pass listing
    /// those some pixel of the tile could reflect) instead of testing every billboard at
    /// every pixel; with reflection shadows it lists each tile's shadow casters too (the
    /// objects some pixel's march could gather). Changes no pixel where no march segment
    /// gathers more than 32 casters (elsewhere steps may differ in length, by casters too
    /// far to dim a hit). Default true; off only to compare. Memory: up to 129 words per
    /// tile, 129 more with reflection shadows.
    pub tile_culling: bool,
    /// Debug view. Default none.
    pub debug_view: ReflectionDebugView,
}

impl Default for BillboardReflections {
    fn default() -> Self {
        BillboardReflections {
            max_layers: DEFAULT_LAYERS as u32,
            max_distance: 100.0,
            half_resolution: false,
            anisotropy: 0.0,
            reflection_shadows: true,
            shadow_steps: 32,
            shadow_softness: penumbra_cinematic_core::reflections::pass::DEFAULT_SHADOW_SOFTNESS,
            tile_culling: true,
            debug_view: ReflectionDebugView::None,
        }
    }
}

impl BillboardReflections {
    /// The settings clamped to their ranges, and what was out of range.
    pub fn resolve(&self) -> (BillboardReflections, Vec<String>) {
        let mut problems = Vec::new();
        let mut out = self.clone();
        if !(1..=MAX_LAYERS as u32).contains(&self.max_layers) {
            problems.push(format!(
                "max_layers {} not in 1..={MAX_LAYERS}",
                self.max_layers
            ));
            out.max_layers = self.max_layers.clamp(1, MAX_LAYERS as u32);
        }
        if !(self.max_distance.is_finite() && self.max_distance >= 0.0) {
            out.max_distance = BillboardReflections::default().max_distance;
            problems.push(format!(
                "max_distance {} is not a finite distance ≥ 0 (using {})",
                self.max_distance, out.max_distance
            ));
        }
        let max = penumbra_cinematic_core::reflections::pass::MAX_ANISOTROPY;
        if !(0.0..=max).contains(&self.anisotropy) {
            problems.push(format!("anisotropy {} not in [0, {max}]", self.anisotropy));
            out.anisotropy = if self.anisotropy.is_nan() {
                0.0
            } else {
                self.anisotropy.clamp(0.0, max)
            };
        }
        if !(1..=256).contains(&self.shadow_steps) {
            problems.push(format!("shadow_steps {} not in 1..=256", self.shadow_steps));
            out.shadow_steps = self.shadow_steps.clamp(1, 256);
        }
        if !(0.001..=1.0).contains(&self.shadow_softness) {
            problems.push(format!(
                "shadow_softness {} not in [0.001, 1]",
                self.shadow_softness
            ));
            out.shadow_softness = if self.shadow_softness.is_nan() {
                penumbra_cinematic_core::reflections::pass::DEFAULT_SHADOW_SOFTNESS
            } else {
                self.shadow_softness.clamp(0.001, 1.0)
            };
        }
        (out, problems)
    }
}

/// Warns once per change when a camera's settings are out of range.
fn warn_bad_reflection_settings(
    cameras: Query<(Entity, &BillboardReflections), Changed<BillboardReflections>>,
) {
    for (entity, settings) in &cameras {
        let (_, problems) = settings.resolve();
        if !problems.is_empty() {
            warn!(
                "Penumbra: BillboardReflections on {entity}: {}; clamped",
                problems.join(", ")
            );
        }
    }
}

impl Plugin for BillboardReflectionsPlugin {
    fn build(&self, app: &mut App) {
        bevy_penumbra_df::register_shader_library(app);
        app.register_type::<ReflectionBillboard>()
            .register_type::<BillboardReflections>()
            .init_resource::<collect::ReflectionScene>()
            .init_resource::<collect::ReflectionMipChains>()
            .add_plugins(render::sync_plugin())
            .add_systems(
                PostUpdate,
                (
                    timed(warn_bad_reflection_settings),
                    timed(collect::collect_reflection_billboards)
                        .after(TransformSystems::Propagate)
                        .after(bevy::asset::AssetEventSystems)
                        .after(bevy::camera::visibility::VisibilitySystems::VisibilityPropagate),
                ),
            );
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render::build(render_app);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy::asset::RenderAssetUsages;
    use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};

    fn image(width: u32, height: u32, format: TextureFormat, texel: &[u8]) -> Image {
        Image::new_fill(
            Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            TextureDimension::D2,
            texel,
            format,
            RenderAssetUsages::default(),
        )
    }

    /// An oversized billboard image is refused by its size before a texel is converted
    /// (the size was checked after converting every texel to 16 bytes, #47), with the
    /// size and the limit named; a readable one converts; one without main-world data
    /// says so.
    #[test]
    fn billboard_images_are_sized_before_they_are_read() {
        let srgb = TextureFormat::Rgba8UnormSrgb;
        let orange = [255, 128, 0, 255];
        let wide = image(collect::MAX_IMAGE_SIDE + 1, 1, srgb, &orange);
        let e = collect::linear_texels(&wide).unwrap_err();
        assert!(e.contains("8193×1") && e.contains("8192"), "{e}");
        let (size, texels) = collect::linear_texels(&image(2, 2, srgb, &orange)).unwrap();
        assert_eq!((size, texels.len()), (UVec2::new(2, 2), 4));
        assert!((texels[0].x - 1.0).abs() < 1e-6 && texels[0].w == 1.0);
        let mut no_data = image(2, 2, srgb, &orange);
        no_data.data = None;
        let e = collect::linear_texels(&no_data).unwrap_err();
        assert!(e.contains("main world"), "{e}");
    }

    /// The main world's list: valid billboards in entity order sharing layers by image;
    /// zero-size, non-finite, odd-sized and unreadable ones skipped; nothing without a
    /// reflecting camera.
    #[test]
    fn billboards_are_collected_and_bad_ones_skipped() {
        let mut app = App::new();
        app.add_plugins((MinimalPlugins, AssetPlugin::default()))
            .init_asset::<Image>()
            .init_resource::<collect::ReflectionScene>()
            .init_resource::<collect::ReflectionMipChains>()
            .add_systems(PostUpdate, collect::collect_reflection_billboards);
        let world = app.world_mut();
        let mut images = world.resource_mut::<Assets<Image>>();
        let srgb = TextureFormat::Rgba8UnormSrgb;
        let red = images.add(image(16, 8, srgb, &[255, 0, 0, 255]));
        let blue = images.add(image(16, 8, srgb, &[0, 0, 255, 128]));
        let small = images.add(image(8, 8, srgb, &[0, 255, 0, 255]));
        let unreadable = images.add(image(16, 8, TextureFormat::Rgb10a2Unorm, &[7, 7, 7, 7]));
        let mut spawn = |image: &Handle<Image>, size: Vec2, transform: Transform| {
            world
                .spawn((
                    ReflectionBillboard {
                        image: image.clone(),
                        size,
                        ..default()
                    },
                    GlobalTransform::from(transform),
                    InheritedVisibility::VISIBLE,
                ))
                .id()
        };
        let at = |x: f32| Transform::from_xyz(x, 1.0, -3.0);
        let a = spawn(&red, Vec2::ONE, at(0.0));
        let b = spawn(&blue, Vec2::new(2.0, 1.0), at(1.0));
        let c = spawn(&red, Vec2::ONE, at(2.0));
        spawn(&small, Vec2::ONE, at(3.0));
        spawn(&red, Vec2::new(0.0, 1.0), at(4.0));
        spawn(&red, Vec2::ONE, Transform::from_xyz(f32::NAN, 0.0, 0.0));
        spawn(&unreadable, Vec2::ONE, at(5.0));
        app.update();
        let scene = app.world().resource::<collect::ReflectionScene>();
        assert!(
            scene.billboards.is_empty() && scene.images.is_none(),
            "no camera"
        );
        app.world_mut().spawn(BillboardReflections::default());
        app.update();
        let scene = app.world().resource::<collect::ReflectionScene>();
        let mut kept = [a, b, c];
        kept.sort();
        let xs: Vec<f32> = scene.billboards.iter().map(|g| g.center.x).collect();
        let want: Vec<f32> = kept
            .iter()
            .map(|e| {
                app.world()
                    .get::<GlobalTransform>(*e)
                    .unwrap()
                    .translation()
                    .x
            })
            .collect();
        assert_eq!(xs, want, "the valid billboards, in entity order");
        let images = scene.images.as_ref().expect("an array");
        assert_eq!(images.size, UVec2::new(16, 8));
        assert_eq!(images.layers.len(), 2, "red and blue: one layer each");
        let layer_of = |x: f32| {
            scene
                .billboards
                .iter()
                .find(|g| g.center.x == x)
                .unwrap()
                .layer
        };
        assert_eq!(layer_of(0.0), layer_of(2.0), "one image, one layer");
        assert_ne!(layer_of(0.0), layer_of(1.0));
        let (red_index, blue_index) = (layer_of(0.0) as usize, layer_of(1.0) as usize);
        // Blue's straight alpha 0.5 (sRGB 0 0 255, alpha 128/255), premultiplied.
        let blue_layer = images.layers[layer_of(1.0) as usize].as_ref().unwrap();
        let texel = blue_layer.levels[0][0];
        assert!((texel.w - 128.0 / 255.0).abs() < 1e-3 && (texel.z - texel.w).abs() < 1e-3);
        // A steady frame keeps the same array (no upload).
        let before = images.clone();
        app.update();
        let scene = app.world().resource::<collect::ReflectionScene>();
        assert!(std::sync::Arc::ptr_eq(
            &before,
            scene.images.as_ref().unwrap()
        ));
        // Blue's billboard removed: its layer is freed, red keeps its own, and blue's mip
        // chain is dropped (red's, the small and the unreadable image's stay: billboards
        // still refer to them).
        app.world_mut().despawn(b);
        app.update();
        let scene = app.world().resource::<collect::ReflectionScene>();
        let images = scene.images.as_ref().expect("an array");
        assert!(
            images.layers.get(blue_index).is_none_or(Option::is_none),
            "blue's layer freed"
        );
        assert!(std::sync::Arc::ptr_eq(
            images.layers[red_index].as_ref().unwrap(),
            before.layers[red_index].as_ref().unwrap()
        ));
        let chains = &app.world().resource::<collect::ReflectionMipChains>().0;
        assert!(!chains.contains_key(&blue.id()), "blue's chain dropped");
        assert!(
            chains.contains_key(&red.id()) && chains.len() == 3,
            "{}",
            chains.len()
        );
    }

    /// More distinct images than the array's layers: the billboards beyond are skipped.
    #[test]
    fn the_array_holds_at_most_256_images() {
        let mut app = App::new();
        app.add_plugins((MinimalPlugins, AssetPlugin::default()))
            .init_asset::<Image>()
            .init_resource::<collect::ReflectionScene>()
            .init_resource::<collect::ReflectionMipChains>()
            .add_systems(PostUpdate, collect::collect_reflection_billboards);
        let world = app.world_mut();
        world.spawn(BillboardReflections::default());
        for k in 0..260u32 {
            let image = world.resource_mut::<Assets<Image>>().add(image(
                1,
                1,
                TextureFormat::Rgba8Unorm,
                &[(k % 256) as u8, (k / 256) as u8, 0, 255],
            ));
            world.spawn((
                ReflectionBillboard { image, ..default() },
                GlobalTransform::from_xyz(k as f32, 1.0, -3.0),
                InheritedVisibility::VISIBLE,
            ));
        }
        app.update();
        let scene = app.world().resource::<collect::ReflectionScene>();
        assert_eq!(scene.images.as_ref().unwrap().layers.len(), 256);
        assert_eq!(scene.billboards.len(), 256);
    }

    #[test]
    fn bad_settings_are_clamped_and_named() {
        let (good, problems) = BillboardReflections::default().resolve();
        assert!(problems.is_empty());
        assert_eq!(good.max_layers, 3);
        let (bad, problems) = BillboardReflections {
            max_layers: 0,
            max_distance: f32::NAN,
            anisotropy: 2.0,
            ..default()
        }
        .resolve();
        assert_eq!(problems.len(), 3, "{problems:?}");
        assert_eq!(bad.max_layers, 1);
        assert_eq!(bad.max_distance, 100.0);
        assert_eq!(bad.anisotropy, 0.95);
    }
}
