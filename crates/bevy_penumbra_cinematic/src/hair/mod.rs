//! Hair and beards as camera-facing strips with an alpha test at every MSAA sample
//! (Samaritan's "short hair / beard", Mittring and Dudash, GDC 2011; Lottes, "Alpha-Test
//! and MSAA").
//!
//! # Technique
//!
//! A [`HairStrands`] asset holds strands: polylines with a width and a slot of the hair
//! texture atlas. The plugin turns a [`Hair`] entity's strands into a strip mesh (two
//! vertices per point, two triangles per segment) drawn with a forward material: the
//! vertex shader moves each vertex across the strand's direction *on screen* by half its
//! width in pixels, so every strip faces the camera (the light, in a shadow map). The
//! fragment shader tests the strand's alpha — the atlas's alpha times the width fade —
//! at each of the pixel's MSAA samples (the standard 2×, 4× or 8× pattern of the view's
//! `Msaa`), extrapolating the strip coordinates from the pixel centre by their
//! derivatives, and writes the passing samples as the fragment's `sample_mask`: a
//! supersampled alpha test shaded once per pixel. With `n` samples each sample's
//! threshold is a step `(k + ½)/n`, permuted per pixel, so an alpha of α keeps about
//! `n α` samples (per-pixel coverage error against the exact area, solid strands: 0.108
//! at 2×, 0.061 at 4×, 0.039 at 8×; lavapipe draws only 4×, so 2× and 8× are checked on
//! the model and the shader's pattern and thresholds, `tests/hair_samples_gpu.rs`). Strips write depth (prepass and main pass, the same mask: depth of
//! field, fog and SSAO see the hair) and need no sorting. Shadows cast into Bevy's shadow
//! maps with the same strips, facing the light. It is a forward material, so it draws
//! the same on forward cameras and on `PenumbraLighting` cameras with `DeferredMsaa`
//! (after the deferred lighting, into the same multisampled targets).
//!
//! **Minimum width.** Strands narrower than [`MIN_WIDTH_PX`] (half a pixel, one sample
//! spacing) are drawn at it with their alpha scaled by `width / MIN_WIDTH_PX`: the
//! expected coverage stays the strand's area and thin strands thin out instead of
//! breaking into dashes between samples.
//!
//! **Shading** is Kajiya-Kay's strand model with Scheuermann's two tangent-shifted
//! specular lobes (the second tinted by the hair's colour): diffuse `colour · sin(T, L)/π`,
//! lobes `strength · (n + 2)/2π · sin(T', H)ⁿ`, evaluated on the strand's centre line for
//! every Bevy light (directional, point, spot) times its shadow map, plus Bevy's ambient
//! light; exposure, fog and in-shader tonemapping as Bevy's forward materials do them.
//!
//! **Distance-field shadows** (`shadows` feature). A light with `DistanceFieldShadows`
//! shadows hair through the distance fields, on every camera: each strand point's
//! visibility is marched once per frame in a compute pass (the mask pass's march, from
//! the point, without a surface's own-shadow term) and interpolated along the strand;
//! the light's shadow map is not read for the hair (`ReadsNoShadowMaps`). Up to
//! [`MAX_HAIR_SHADOW_LIGHTS`] such lights reaching a hair entity (lights out of range
//! do not count); skinned hair keeps their shadow maps (one warning). Details and cost:
//! `shadows.rs`.
//!
//! # Inputs
//!
//! - Strands from code ([`HairStrands::new`]), from a `.hair` file (the text format of
//!   `penumbra_cinematic_core::hair::strands`: `penumbra-hair 1`, then one
//!   `strand <width> <slot> <x y z>...` line per strand), or from a mesh of ribbons as
//!   artists author hair cards, e.g. a glTF mesh ([`HairStrands::from_ribbon_mesh`]).
//! - Attach hair to a rigid part by parenting the [`Hair`] entity to it; to a skinned
//!   mesh by binding the strands to its skin ([`HairStrands::bind_to_skin`]: each strand
//!   follows its root's nearest vertex's joints) and giving the [`Hair`] entity the mesh's
//!   `SkinnedMesh`.
//! - Bad strands (fewer than two points, non-finite points, widths not positive and
//!   finite) are skipped with one warning per entity and asset version; an atlas that
//!   fails to load is dropped with one warning (the hair is drawn untextured).
//!
//! # Limits
//!
//! - Without MSAA (`Msaa::Off`) the test is per pixel against a dithered threshold (one
//!   warning per camera): hair aliases and shimmers as any alpha test does.
//! - Hair casts no distance-field shadow (it is no caster): under a light with
//!   `DistanceFieldShadows` neither the hair itself nor the surfaces below get its
//!   shadow.
//! - Widths scale with the entity's transform assuming a uniform scale; strips are flat
//!   (no thickness in depth), lit on their centre line; no self-shadowing beyond the
//!   shadow maps' resolution, no multiple scattering (Marschner's TRT/TT are not modelled).

mod material;
mod mesh;
#[cfg(feature = "shadows")]
mod shadows;

pub use material::{
    ATTRIBUTE_HAIR_STRIP, ATTRIBUTE_HAIR_TANGENT, HAIR_FLAG_ATLAS, HAIR_FLAG_DEBUG_COVERAGE,
    HAIR_SHADOWS_HEADER_BYTES, HairMaterial, HairParams, MAX_HAIR_SHADOW_LIGHTS,
};
pub use mesh::{StrandJoints, joints_from_skin, strip_mesh};
pub use penumbra_cinematic_core::hair::MIN_WIDTH_PX;
pub use penumbra_cinematic_core::hair::strands::{Strand, StrandProblem};
#[cfg(feature = "shadows")]
pub use shadows::{ExtractedHairShadows, GpuHairShadows, HairShadowTraces};

use bevy::asset::io::Reader;
use bevy::asset::{AssetLoader, LoadContext, LoadState};
use bevy::mesh::VertexAttributeValues;
use bevy::platform::collections::{HashMap, HashSet};
use bevy::prelude::*;
use bevy::render::storage::ShaderBuffer;
use bevy_penumbra_df::system_times::timed;
use penumbra_cinematic_core::hair::strands::{check_strands, parse_hair, strands_from_ribbons};

/// Strands of hair: polylines with a width and an atlas slot, in the hair entity's space.
#[derive(Asset, TypePath, Clone, Debug, Default)]
pub struct HairStrands {
    /// The strands, root first.
    pub strands: Vec<Strand>,
    /// Each strand's skin joints ([`HairStrands::bind_to_skin`]).
    pub joints: Option<StrandJoints>,
}

/// Why a mesh of ribbons gave no strands.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum HairMeshError {
    /// The mesh has no `Float32x3` positions.
    NoPositions,
    /// The mesh has no `Float32x2` UVs (along the hair: `uv.y`).
    NoUvs,
    /// The mesh is not a triangle list.
    NotTriangles,
    /// The mesh's vertex data is in the render world only (its `RenderAssetUsages`
    /// lack `MAIN_WORLD`, and it has been extracted).
    NotInMainWorld,
}

impl std::fmt::Display for HairMeshError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::NoPositions => "the hair mesh has no positions",
            Self::NoUvs => "the hair mesh has no UVs (uv.y runs along each strip)",
            Self::NotTriangles => "the hair mesh is not a triangle list",
            Self::NotInMainWorld => {
                "the hair mesh's data is in the render world only: keep \
                 RenderAssetUsages::MAIN_WORLD in its asset usage"
            }
        })
    }
}

impl std::error::Error for HairMeshError {}

impl HairStrands {
    /// Strands built in code.
    pub fn new(strands: Vec<Strand>) -> Self {
        Self {
            strands,
            joints: None,
        }
    }

    /// Strands from a mesh of ribbons (hair cards, e.g. loaded from glTF; vertices of
    /// equal position and UV are welded first): each connected piece is a strand, its cross-sections the vertices of equal `uv.y` (root at the
    /// smallest), its width their mean extent, its slot `⌊mean uv.x · slots⌋`.
    pub fn from_ribbon_mesh(mesh: &Mesh, slots: u32) -> Result<Self, HairMeshError> {
        // Once this succeeds every attribute and the indices are readable.
        let Some(VertexAttributeValues::Float32x3(positions)) = mesh
            .try_attribute_option(Mesh::ATTRIBUTE_POSITION)
            .map_err(|_| HairMeshError::NotInMainWorld)?
        else {
            return Err(HairMeshError::NoPositions);
        };
        let Some(VertexAttributeValues::Float32x2(uvs)) = mesh.attribute(Mesh::ATTRIBUTE_UV_0)
        else {
            return Err(HairMeshError::NoUvs);
        };
        if mesh.primitive_topology() != bevy::mesh::PrimitiveTopology::TriangleList {
            return Err(HairMeshError::NotTriangles);
        }
        // Vertices with equal position and UV are one (loaders split them: Bevy's glTF
        // loader un-indexes meshes without normals to compute flat ones).
        let mut welded = HashMap::new();
        let mut positions_out = Vec::new();
        let mut uvs_out = Vec::new();
        let remap: Vec<u32> = positions
            .iter()
            .zip(uvs)
            .map(|(p, uv)| {
                let key = (p.map(f32::to_bits), uv.map(f32::to_bits));
                *welded.entry(key).or_insert_with(|| {
                    positions_out.push(Vec3::from_array(*p));
                    uvs_out.push(Vec2::from_array(*uv));
                    positions_out.len() as u32 - 1
                })
            })
            .collect();
        let indices: Vec<u32> = match mesh.indices() {
            Some(indices) => indices
                .iter()
                .map(|i| remap.get(i).copied().unwrap_or(u32::MAX))
                .collect(),
            None => remap,
        };
        let (positions, uvs) = (positions_out, uvs_out);
        Ok(Self::new(strands_from_ribbons(
            &positions, &uvs, &indices, slots,
        )))
    }

    /// Binds each strand to the joints of the nearest vertex of `skin` to its root (a
    /// skinned mesh in the hair's space); `false` when `skin` has no positions, joint
    /// indices (`Uint16x4`) and weights.
    pub fn bind_to_skin(&mut self, skin: &Mesh) -> bool {
        self.joints = joints_from_skin(&self.strands, skin);
        self.joints.is_some()
    }

    /// The number of triangles drawn (two per segment of every drawable strand).
    pub fn triangle_count(&self) -> usize {
        self.strands
            .iter()
            .map(|s| 2 * s.points.len().saturating_sub(1))
            .sum()
    }
}

/// Loads `.hair` files.
#[derive(Default, TypePath)]
pub struct HairStrandsLoader;

/// Why a `.hair` file failed to load.
#[derive(Debug)]
pub enum HairLoadError {
    /// Reading failed.
    Io(std::io::Error),
    /// Not UTF-8.
    NotText,
    /// A malformed line.
    Parse(penumbra_cinematic_core::hair::strands::ParseError),
}

impl std::fmt::Display for HairLoadError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Io(e) => write!(f, "reading the hair file: {e}"),
            Self::NotText => f.write_str("the hair file is not UTF-8 text"),
            Self::Parse(e) => write!(f, "hair file {e}"),
        }
    }
}

impl std::error::Error for HairLoadError {}

impl AssetLoader for HairStrandsLoader {
    type Asset = HairStrands;
    type Settings = ();
    type Error = HairLoadError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        _settings: &(),
        _load_context: &mut LoadContext<'_>,
    ) -> Result<HairStrands, HairLoadError> {
        let mut bytes = Vec::new();
        reader
            .read_to_end(&mut bytes)
            .await
            .map_err(HairLoadError::Io)?;
        let text = String::from_utf8(bytes).map_err(|_| HairLoadError::NotText)?;
        Ok(HairStrands::new(
            parse_hair(&text).map_err(HairLoadError::Parse)?,
        ))
    }

    fn extensions(&self) -> &[&str] {
        &["hair"]
    }
}

/// How a strip's coverage of a pixel's samples is decided. The default is the point of
/// the technique; the others exist to measure it against (`tests/hair_*.rs`).
#[derive(Reflect, Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[reflect(Clone, Default, PartialEq)]
#[repr(u8)]
pub enum HairCoverage {
    /// The alpha tested at each of the four samples, written as the sample mask; shaded
    /// once per pixel.
    #[default]
    PerSample,
    /// Shaded and tested once per sample (`@interpolate(sample)`): the same coverage at
    /// up to four times the shading.
    SampleShading,
    /// The centre's alpha turned into samples by the GPU's alpha-to-coverage.
    AlphaToCoverage,
    /// The centre's alpha tested against 0.5 (the geometry's samples kept or dropped
    /// together): aliases and loses sub-pixel strands.
    PerPixel,
}

/// Draws an entity's hair: [`HairStrands`] as camera-facing strips, shaded as hair.
/// Needs the [`HairPlugin`]; the strands are in the entity's space (parent it to a bone,
/// or give it a `SkinnedMesh` with strands bound by [`HairStrands::bind_to_skin`]).
#[derive(Component, Reflect, Clone, Debug)]
#[reflect(Component, Clone, Default)]
#[require(Transform, Visibility)]
pub struct Hair {
    /// The strands.
    pub strands: Handle<HairStrands>,
    /// Multiplies every strand's width. Default 1.
    pub width_scale: f32,
    /// The atlas of individual hairs: [`Hair::atlas_slots`] columns, each one hair with
    /// its root at the top; alpha is the hair's coverage across it, colour tints it.
    /// Linear filtering; leave transparent texels between columns. Default none (a
    /// solid strip).
    pub atlas: Option<Handle<Image>>,
    /// Columns of the atlas. Default 1.
    pub atlas_slots: u32,
    /// Colour at the root (linear albedo). Default a dark brown.
    pub root_color: Color,
    /// Colour at the tip. Default a lighter brown.
    pub tip_color: Color,
    /// Primary (white) highlight's strength: its lobe's peak is `strength · (n + 2)/2π`
    /// (0.08 at the defaults, near Marschner's R lobe: Fresnel's 0.05 over a ~7° wide
    /// longitudinal lobe). Default 0.006.
    pub specular: f32,
    /// Primary highlight's Kajiya-Kay exponent (sharper when larger). Default 80.
    pub specular_exponent: f32,
    /// Secondary (tinted) highlight's strength. Default 0.3.
    pub secondary_specular: f32,
    /// Secondary highlight's exponent. Default 12.
    pub secondary_exponent: f32,
    /// Primary highlight's shift along the strand towards the tip, as a tangent tilt
    /// (cuticle scales; Scheuermann: about −0.1…0.1). Default 0.05.
    pub primary_shift: f32,
    /// Secondary highlight's shift. Default −0.1.
    pub secondary_shift: f32,
    /// How coverage is decided. Default [`HairCoverage::PerSample`]. On lavapipe at 512²
    /// the default costs 8–9 % more than one test per pixel or alpha-to-coverage, shading
    /// per sample 3.5–3.8 × as much (`tests/hair_modes.rs`, `hair_cost_against_time`).
    pub coverage: HairCoverage,
    /// Draws coverage only (white, unlit): the debug and contract view.
    pub debug_coverage: bool,
}

impl Default for Hair {
    fn default() -> Self {
        Self {
            strands: Handle::default(),
            width_scale: 1.0,
            atlas: None,
            atlas_slots: 1,
            root_color: Color::linear_rgb(0.05, 0.025, 0.012),
            tip_color: Color::linear_rgb(0.16, 0.09, 0.05),
            specular: 0.006,
            specular_exponent: 80.0,
            secondary_specular: 0.1,
            secondary_exponent: 12.0,
            primary_shift: 0.05,
            secondary_shift: -0.1,
            coverage: HairCoverage::PerSample,
            debug_coverage: false,
        }
    }
}

impl Hair {
    /// The material parameters (atlas flag as given).
    fn params(&self, atlas: bool) -> HairParams {
        let c = |c: Color| c.to_linear().to_vec4();
        let finite = |x: f32, d: f32| if x.is_finite() { x } else { d };
        HairParams {
            root_color: c(self.root_color),
            tip_color: c(self.tip_color),
            specular: Vec4::new(
                finite(self.specular, 0.0).max(0.0),
                finite(self.specular_exponent, 1.0).max(1.0),
                finite(self.secondary_specular, 0.0).max(0.0),
                finite(self.secondary_exponent, 1.0).max(1.0),
            ),
            primary_shift: finite(self.primary_shift, 0.0),
            secondary_shift: finite(self.secondary_shift, 0.0),
            width_scale: finite(self.width_scale, 1.0).max(0.0),
            atlas_slots: self.atlas_slots.max(1),
            flags: if atlas { HAIR_FLAG_ATLAS } else { 0 }
                | if self.debug_coverage {
                    HAIR_FLAG_DEBUG_COVERAGE
                } else {
                    0
                },
        }
    }
}

/// Adds [`Hair`]: the strands asset and its `.hair` loader, the material and the
/// systems that keep each entity's strip mesh and material up to date. No [`Hair`]
/// entity: no mesh, no pipeline, no draw.
#[derive(Default)]
pub struct HairPlugin;

impl Plugin for HairPlugin {
    fn build(&self, app: &mut App) {
        bevy_penumbra_df::register_shader_library(app);
        app.register_type::<Hair>()
            .init_asset::<HairStrands>()
            .init_asset_loader::<HairStrandsLoader>()
            .add_systems(
                PostUpdate,
                (
                    timed(remove_hair),
                    timed(build_hair),
                    timed(warn_hair_without_msaa)
                        .after(bevy_penumbra_df::lighting::DeferredMsaaSystems::Restore),
                )
                    .chain()
                    .after(bevy::asset::AssetEventSystems),
            );
        if app.get_sub_app(bevy::render::RenderApp).is_none() {
            return;
        }
        if let Some(mut shaders) = app.world_mut().get_resource_mut::<Assets<Shader>>() {
            for (handle, path) in [
                (material::DRAW_SHADER, "hair/draw.wgsl"),
                (material::PREPASS_SHADER, "hair/prepass.wgsl"),
            ] {
                let source = penumbra_shaders::SHADERS
                    .iter()
                    .find(|s| s.path == path)
                    .expect("the hair shaders are in the library")
                    .source;
                let _ = shaders.insert(
                    handle.id(),
                    Shader::from_wgsl(source, format!("penumbra/{path}")),
                );
            }
        }
        app.add_plugins(MaterialPlugin::<HairMaterial>::default());
        #[cfg(feature = "shadows")]
        shadows::build(app);
    }

    fn finish(&self, _app: &mut App) {
        #[cfg(feature = "shadows")]
        shadows::finish(_app);
    }
}

/// A [`Hair`] entity's distance-field visibility buffers (made by the plugin while a
/// light has `DistanceFieldShadows`; `shadows` feature): its strands' centre-line
/// points and the `HairShadows` the compute pass writes and the strips read.
#[derive(Component, Clone, Debug)]
pub struct HairShadowBuffers {
    /// The points, hair space (`vec4`s, the strip mesh's order).
    pub points: Handle<ShaderBuffer>,
    /// The lights and each point's visibility of them.
    pub shadows: Handle<ShaderBuffer>,
    /// Points in `points`.
    pub point_count: u32,
    /// The points' bounding sphere, hair space.
    pub center: Vec3,
    /// Its radius.
    pub radius: f32,
    /// The strip mesh they were made for.
    #[cfg_attr(
        not(feature = "shadows"),
        allow(dead_code, reason = "made only with the `shadows` feature")
    )]
    mesh: AssetId<Mesh>,
}

/// What the plugin made for a [`Hair`] entity (present once its strands were built,
/// also when none was drawable).
#[derive(Component, Debug)]
pub struct HairBuilt {
    strands: AssetId<HairStrands>,
    material: Handle<HairMaterial>,
    atlas_failed: bool,
}

/// Takes the strips off entities that lost their [`Hair`].
fn remove_hair(
    mut commands: Commands,
    mut removed: RemovedComponents<Hair>,
    hairs: Query<(), With<Hair>>,
) {
    for entity in removed.read() {
        if hairs.contains(entity) {
            continue;
        }
        if let Ok(mut entity) = commands.get_entity(entity) {
            entity.remove::<(
                Mesh3d,
                MeshMaterial3d<HairMaterial>,
                HairBuilt,
                HairShadowBuffers,
            )>();
            #[cfg(feature = "shadows")]
            entity.remove::<bevy_penumbra_df::ReadsNoShadowMaps>();
        }
    }
}

/// Builds a [`Hair`] entity's strip mesh when it or its strands change (skipping bad
/// strands with one warning per entity and asset version), and keeps its material in
/// step.
#[allow(
    clippy::too_many_arguments,
    clippy::type_complexity,
    reason = "a Bevy system"
)]
fn build_hair(
    mut commands: Commands,
    mut hairs: Query<(
        Entity,
        Ref<Hair>,
        Option<&mut HairBuilt>,
        Option<&HairShadowBuffers>,
    )>,
    buffers: Option<ResMut<Assets<ShaderBuffer>>>,
    // The visibility buffer of hair that takes no light from the distance fields (made
    // with the first hair).
    mut placeholder: Local<Option<Handle<ShaderBuffer>>>,
    mut events: MessageReader<AssetEvent<HairStrands>>,
    strands: Res<Assets<HairStrands>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<HairMaterial>>,
    asset_server: Res<AssetServer>,
) {
    let changed: HashSet<AssetId<HairStrands>> = events
        .read()
        .filter_map(|e| match e {
            AssetEvent::Added { id } | AssetEvent::Modified { id } => Some(*id),
            _ => None,
        })
        .collect();
    if hairs.is_empty() {
        return;
    }
    let placeholder = match (&*placeholder, buffers) {
        (Some(handle), _) => handle.clone(),
        (None, Some(mut buffers)) => placeholder
            .insert(buffers.add(ShaderBuffer::with_size(
                // Counts of zero: no light's visibility comes from the distance fields.
                HAIR_SHADOWS_HEADER_BYTES + 16,
                bevy::asset::RenderAssetUsages::RENDER_WORLD,
            )))
            .clone(),
        (None, None) => Handle::default(), // no renderer
    };
    for (entity, hair, built, shadow_buffers) in &mut hairs {
        let id = hair.strands.id();
        let atlas_failed = hair
            .atlas
            .as_ref()
            .is_some_and(|a| matches!(asset_server.get_load_state(a), Some(LoadState::Failed(_))));
        // Once per entity: when first built with a failed atlas, or when it fails later.
        let newly_failed = atlas_failed && !built.as_ref().is_some_and(|b| b.atlas_failed);
        let stale = built.as_ref().is_none_or(|b| b.strands != id) || changed.contains(&id);
        if stale {
            let Some(asset) = strands.get(id) else {
                continue;
            };
            if newly_failed {
                warn_atlas_failed(entity);
            }
            let (kept, dropped) = check_strands(asset.strands.clone());
            if let Some((index, problem)) = dropped.first() {
                warn!(
                    "Penumbra: hair on {entity}: {} of {} strands skipped (strand {index}: {problem:?}{})",
                    dropped.len(),
                    asset.strands.len(),
                    if dropped.len() > 1 { ", …" } else { "" }
                );
            }
            let joints = asset.joints.as_ref().map(|joints| {
                let skipped: HashSet<usize> = dropped.iter().map(|(i, _)| *i).collect();
                joints
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| !skipped.contains(i))
                    .map(|(_, j)| *j)
                    .collect::<StrandJoints>()
            });
            let Some(mesh) = strip_mesh(&kept, joints.as_ref()) else {
                warn!("Penumbra: hair on {entity} has no drawable strand; nothing is drawn");
                commands.entity(entity).remove::<Mesh3d>();
                commands.entity(entity).insert(HairBuilt {
                    strands: id,
                    material: Handle::default(),
                    atlas_failed,
                });
                continue;
            };
            // New strips: their visibility buffers come next (`shadows`).
            let material = materials.add(material_of(&hair, atlas_failed, placeholder.clone()));
            commands.entity(entity).insert((
                Mesh3d(meshes.add(mesh)),
                MeshMaterial3d(material.clone()),
                HairBuilt {
                    strands: id,
                    material,
                    atlas_failed,
                },
            ));
            continue;
        }
        let Some(mut built) = built else { continue };
        if newly_failed {
            warn_atlas_failed(entity);
        }
        if hair.is_changed() || atlas_failed != built.atlas_failed {
            if let Some(mut material) = materials.get_mut(&built.material) {
                let shadows =
                    shadow_buffers.map_or_else(|| placeholder.clone(), |b| b.shadows.clone());
                *material = material_of(&hair, atlas_failed, shadows);
            }
            built.atlas_failed = atlas_failed;
        }
    }
}

fn warn_atlas_failed(entity: Entity) {
    warn!("Penumbra: hair on {entity}: its atlas failed to load; drawn without it");
}

fn material_of(hair: &Hair, atlas_failed: bool, shadows: Handle<ShaderBuffer>) -> HairMaterial {
    let atlas = hair.atlas.clone().filter(|_| !atlas_failed);
    HairMaterial {
        params: hair.params(atlas.is_some()),
        atlas,
        shadows,
        coverage: hair.coverage,
    }
}

/// One warning per camera without MSAA while hair exists: the per-pixel fallback.
fn warn_hair_without_msaa(
    hairs: Query<(), With<Hair>>,
    cameras: Query<(Entity, &Msaa), With<Camera3d>>,
    mut warned: Local<HashSet<Entity>>,
) {
    if hairs.is_empty() {
        return;
    }
    for (camera, msaa) in &cameras {
        if *msaa == Msaa::Off && warned.insert(camera) {
            warn!(
                "Penumbra: camera {camera} has MSAA off: hair falls back to a per-pixel alpha test \
                 (aliased; no alpha-to-coverage). Use Msaa::Sample4 for anti-aliased hair."
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy::asset::RenderAssetUsages;
    use bevy::mesh::{Indices, PrimitiveTopology};

    /// A mesh as the main world keeps it after extraction when its asset usage lacks
    /// `MAIN_WORLD`: every CPU read of it is an error (or a panic, through the plain
    /// accessors).
    fn extracted(mut mesh: Mesh) -> Mesh {
        mesh.take_gpu_data().expect("a fresh mesh has its data");
        mesh
    }

    #[test]
    fn a_ribbon_mesh_in_the_render_world_only_is_an_error() {
        let mesh = extracted(Rectangle::new(0.01, 0.1).mesh().build());
        assert_eq!(
            HairStrands::from_ribbon_mesh(&mesh, 1).err(),
            Some(HairMeshError::NotInMainWorld)
        );
    }

    /// A hair card as a glTF loader gives it: one ribbon of three cross-sections, its
    /// UVs running along the hair in `y`; slot from `x` over a 2-slot atlas.
    #[test]
    fn a_ribbon_mesh_gives_its_strand() {
        let positions = vec![
            [-0.001f32, 0.0, 0.0],
            [0.001, 0.0, 0.0],
            [-0.001, -0.05, 0.0],
            [0.001, -0.05, 0.0],
            [-0.001, -0.1, 0.01],
            [0.001, -0.1, 0.01],
        ];
        let uvs = vec![
            [0.5f32, 0.0],
            [1.0, 0.0],
            [0.5, 0.5],
            [1.0, 0.5],
            [0.5, 1.0],
            [1.0, 1.0],
        ];
        let mesh = Mesh::new(
            PrimitiveTopology::TriangleList,
            RenderAssetUsages::MAIN_WORLD,
        )
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions)
        .with_inserted_attribute(Mesh::ATTRIBUTE_UV_0, uvs)
        .with_inserted_indices(Indices::U16(vec![0, 1, 2, 1, 3, 2, 2, 3, 4, 3, 5, 4]));
        let hair = HairStrands::from_ribbon_mesh(&mesh, 2).unwrap();
        assert_eq!(hair.strands.len(), 1);
        let strand = &hair.strands[0];
        assert_eq!(strand.slot, 1);
        assert!((strand.width - 0.002).abs() < 1e-6);
        assert_eq!(strand.points.len(), 3);
        assert!(strand.points[2].distance(Vec3::new(0.0, -0.1, 0.01)) < 1e-6);
        assert_eq!(hair.triangle_count(), 4);
        let no_uvs = Mesh::new(
            PrimitiveTopology::TriangleList,
            RenderAssetUsages::MAIN_WORLD,
        )
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0f32; 3]; 3]);
        assert_eq!(
            HairStrands::from_ribbon_mesh(&no_uvs, 1).unwrap_err(),
            HairMeshError::NoUvs
        );
    }

    /// Removing `Hair` takes the strips away (the mesh would draw on otherwise).
    #[test]
    fn removing_hair_removes_its_strips() {
        let mut app = App::new();
        app.add_systems(Update, remove_hair);
        let entity = app
            .world_mut()
            .spawn((
                Hair::default(),
                Mesh3d(Handle::default()),
                MeshMaterial3d::<HairMaterial>(Handle::default()),
                HairBuilt {
                    strands: AssetId::default(),
                    material: Handle::default(),
                    atlas_failed: false,
                },
            ))
            .id();
        app.update();
        assert!(app.world().get::<Mesh3d>(entity).is_some());
        app.world_mut().entity_mut(entity).remove::<Hair>();
        app.update();
        assert!(app.world().get::<Mesh3d>(entity).is_none());
        assert!(app.world().get::<HairBuilt>(entity).is_none());
        assert!(app.world().get::<Transform>(entity).is_some());
    }
}
