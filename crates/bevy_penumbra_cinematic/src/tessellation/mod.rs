//! Compute tessellation (Samaritan's "Tessellation", Mittring and Dudash, GDC 2011): a
//! [`Tessellated`] mesh is cut finer where the camera sees it large, smoothed with
//! PN triangles with adjacent edge normals (PN-AEN) and displaced by a height map, on the
//! GPU, then drawn by Bevy's own material path — shadows, prepass, deferred G-buffer and
//! Penumbra's lighting see the tessellated triangles.
//!
//! # Technique
//!
//! wgpu has no hull or domain shaders, so tessellation is three compute passes per
//! entity (`shaders/tessellation/tessellate.wgsl`, `RenderGraph` schedule, before the
//! cameras): per-patch factors from each edge's bounding sphere projected to the
//! screen (a long thin triangle's short edges stay coarse; an edge seen end-on is not
//! under-tessellated); the allocation, a prefix sum over workgroups of 1,024 patches
//! (`penumbra_cinematic_core::scan`) that picks the least *bias* (all factors halved)
//! whose output fits the entity's pool and places every patch's output (the output's
//! order is the patches', deterministic; the last bias draws every patch as its input
//! triangle, which any pool holds: never holes); one workgroup per patch writing
//! its vertices and triangles. The pool is then copied into the buffers Bevy's mesh
//! allocator holds for the entity's output mesh. A patch is laid out as Direct3D 11's
//! tessellator does with `fractional_odd` partitioning: each edge's own 1-D pattern
//! as the outer ring, shrunken rings inside, a zipper between; an edge's vertices are a
//! function of the edge alone (its canonical direction, its factor, the dominant edge's
//! UVs, the position-averaged normal), so both triangles of an edge produce the same
//! bits: no cracks, also where normals or UVs split. Details, the algorithm's limits and
//! its CPU model: `penumbra_cinematic_core::tessellation`.
//!
//! The preprocessing — welding positions, dominant vertices, each edge's opposite pair
//! (meshoptimizer's 12-index patches), averaged normals — runs once per mesh version
//! on the CPU and is shared by every entity using the mesh.
//!
//! **When it runs.** Only in a frame where the tessellation camera (a [`TessellationCamera`],
//! else among the active 3D cameras one that renders the entity's `RenderLayers`, then
//! one that renders to a window, then the highest order), the entity's transform, its settings or
//! its mesh changed: a still scene costs nothing. The totals (32 bytes) are read back
//! only from such a frame until that tessellation's own arrive, two or three frames: none
//! while still. A hidden entity, or one no view saw last frame (camera or shadow), keeps
//! its last tessellation. Every camera and shadow view draws the same triangles (shadows
//! match the geometry, no self-shadowing acne from mismatched levels).
//!
//! # Use
//!
//! Add [`Tessellated`] to an entity with a `Mesh3d` (a triangle list with positions;
//! normals and UVs are computed or zero when missing) and any material. The plugin
//! replaces the entity's `Mesh3d` by its output mesh once the first tessellation is
//! written (a pool that grows keeps the previous one shown until then) and restores the
//! original when the component is removed. Bevy's `Wireframe` shows the tessellation.
//! A `DistanceFieldCaster` on the entity keeps its distance field baked from the source
//! mesh (the plugin inserts `CasterMesh`): distance-field shadows and occlusion use the
//! untessellated, undisplaced shape.
//!
//! # Limits
//!
//! - The output pool starts at 65,536 triangles and follows the GPU's totals (read back
//!   after each tessellation): up to what the view asked for plus a quarter when it needed
//!   coarser factors, down to twice the use when under an eighth is used. It never exceeds [`Tessellated::max_triangles`]
//!   (at least the input's triangle count): a view that asks for more gets coarser
//!   factors (one warning), down to the input's own triangles (never holes). The unused tail of the pool is drawn as degenerate triangles.
//! - The output mesh has positions, normals, UV 0 and (when the input has them)
//!   tangents; other attributes (colours, a second UV set, joints) are dropped, and
//!   skinned or morphed meshes are not supported (one warning, left untessellated).
//! - Displacement reads the red channel of an uncompressed image (8- or 16-bit unorm,
//!   16- or 32-bit float); other formats are ignored with one warning. The displaced
//!   normal bends the shading normal by the height's slope; a material normal map is
//!   applied on top.
//! - Cost: the vertex and index pools twice (the compute pool and Bevy's mesh buffers):
//!   `(capacity + 2·patches)·(32 or 48) + 12·capacity` bytes each, plus 32 bytes per
//!   input triangle of patch state.

mod input;
mod render;

use bevy::asset::RenderAssetUsages;
use bevy::camera::RenderTarget;
use bevy::camera::primitives::Aabb;
use bevy::camera::visibility::{NoAutoAabb, RenderLayers};
use bevy::platform::collections::{HashMap, HashSet};
use bevy::prelude::*;
use bevy::render::extract_component::ExtractComponentPlugin;
use bevy::render::gpu_readback::{Readback, ReadbackComplete};
use bevy::render::storage::ShaderBuffer;
use bevy::transform::TransformSystems;
use bevy_penumbra_df::CasterMesh;
use bevy_penumbra_df::system_times::timed;
use penumbra_cinematic_core::tessellation::reference::Frame;
use penumbra_cinematic_core::tessellation::uniform::{
    PATCH_STATE_BYTES, TOTALS_BYTES, TessellationUniform,
};
use penumbra_cinematic_core::tessellation::{
    DisplacementMap, MAX_LEVEL, Partitioning, Settings, SurfaceMode, TessellationInput,
    TessellationView,
};
use std::sync::Arc;

pub use input::shape_mesh;
use input::{encase_vec, heights, output_mesh, preprocess};
pub use render::GpuTessellation;

/// The surface a [`Tessellated`] mesh evaluates.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Reflect)]
pub enum TessellationMode {
    /// The input's flat triangles (displacement still adds detail).
    Flat,
    /// PN triangles with adjacent edge normals: a smooth surface through the vertices
    /// and their normals, one curve per edge even where normals split.
    #[default]
    PnAen,
}

/// How factors become segments.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Reflect)]
pub enum TessellationPartitioning {
    /// Equal segments: the triangles pop as the count changes.
    Integer,
    /// Direct3D's `fractional_odd`: new segments grow from zero length, so the surface
    /// moves continuously with the camera.
    #[default]
    Fractional,
}

/// Tessellates the entity's `Mesh3d` every frame its view changes (see the module docs).
#[derive(Component, Reflect, Clone, Debug)]
#[reflect(Component, Clone, Default)]
pub struct Tessellated {
    /// Target length, in pixels, of a tessellated edge (its bounding sphere's projected
    /// diameter). Default 16. Halving it quadruples the triangles. Not finite or ≤ 0:
    /// the default, one warning.
    pub pixels_per_triangle: f32,
    /// The largest factor is `2^max_level`: at most `2^max_level + 1` segments per input
    /// edge. Default 5 (33 segments, about 1,600 triangles per input triangle); clamped
    /// to 6.
    pub max_level: u32,
    /// Height map (red channel, 0–1) displacing along the averaged normal; `None`: no
    /// displacement. Default `None`.
    pub displacement: Option<Handle<Image>>,
    /// Local units a height of 1 moves above the midlevel. Default 0.05.
    pub displacement_scale: f32,
    /// The height that is the surface itself. Default 0.5.
    pub displacement_midlevel: f32,
    /// The surface. Default [`TessellationMode::PnAen`].
    pub mode: TessellationMode,
    /// Segment spacing. Default [`TessellationPartitioning::Fractional`].
    pub partitioning: TessellationPartitioning,
    /// The most triangles the output pool may grow to (raised to the input's count).
    /// Default 1,048,576: about 46 MB of pool twice without tangents, if a view needs it.
    pub max_triangles: u32,
}

impl Default for Tessellated {
    fn default() -> Self {
        Self {
            pixels_per_triangle: 16.0,
            max_level: 5,
            displacement: None,
            displacement_scale: 0.05,
            displacement_midlevel: 0.5,
            mode: TessellationMode::PnAen,
            partitioning: TessellationPartitioning::Fractional,
            max_triangles: 1 << 20,
        }
    }
}

/// Marks the camera whose view drives the tessellation factors (default: among the
/// active 3D cameras, one that renders the entity's `RenderLayers`, then one that renders
/// to a window, then the highest order).
#[derive(Component, Reflect, Clone, Copy, Debug, Default)]
#[reflect(Component, Clone, Default)]
pub struct TessellationCamera;

/// Adds [`Tessellated`]. No such entity: no buffer, no pipeline dispatch.
#[derive(Default)]
pub struct TessellationPlugin;

impl Plugin for TessellationPlugin {
    fn build(&self, app: &mut App) {
        bevy_penumbra_df::register_shader_library(app);
        app.register_type::<Tessellated>()
            .register_type::<TessellationCamera>()
            .init_resource::<TessellationCache>()
            .add_plugins(ExtractComponentPlugin::<TessellationState>::default())
            .add_systems(
                PostUpdate,
                (timed(restore_untessellated), timed(prepare_tessellated))
                    .chain()
                    .after(TransformSystems::Propagate)
                    .after(bevy::asset::AssetEventSystems)
                    .after(bevy::mesh::mark_3d_meshes_as_changed_if_their_assets_changed)
                    .before(bevy::camera::visibility::VisibilitySystems::CalculateBounds)
                    // Last frame's `ViewVisibility`, before it is reset.
                    .before(bevy::camera::visibility::VisibilitySystems::VisibilityPropagate),
            );
        render::build(app);
    }

    fn finish(&self, app: &mut App) {
        render::finish(app);
    }
}

/// A mesh's preprocessing and its GPU copies, shared by the entities that use it.
#[derive(Clone)]
struct CachedInput {
    input: Arc<TessellationInput>,
    vertices: Handle<ShaderBuffer>,
    patches: Handle<ShaderBuffer>,
}

/// A displacement map's mip chain and its GPU copy.
type CachedMap = (Arc<DisplacementMap>, Handle<ShaderBuffer>);

/// Preprocessed meshes and displacement maps, by asset; what was warned about.
#[derive(Resource, Default)]
struct TessellationCache {
    inputs: HashMap<AssetId<Mesh>, Option<CachedInput>>,
    maps: HashMap<AssetId<Image>, Option<CachedMap>>,
    no_map: Option<Handle<ShaderBuffer>>,
    warned: HashSet<(Entity, &'static str)>,
    /// Per tessellated entity, the entity reading its totals back, while the latest
    /// tessellation's have not arrived.
    readbacks: HashMap<Entity, Entity>,
}

impl TessellationCache {
    fn warn_once(&mut self, entity: Entity, what: &'static str, message: impl FnOnce() -> String) {
        if self.warned.insert((entity, what)) {
            warn!("Penumbra: tessellation of {entity}: {}", message());
        }
    }
}

/// The smallest pool, triangles (unless `max_triangles` is smaller): about 3 MB.
const MIN_CAPACITY: u32 = 65_536;

/// What the plugin made for a [`Tessellated`] entity; extracted to the render world.
#[derive(Component, Clone)]
pub struct TessellationState {
    source: Handle<Mesh>,
    /// What the entity's `Mesh3d` shows: the output once it is filled; until then the
    /// source or the previous pool's output.
    shown: Handle<Mesh>,
    output: Handle<Mesh>,
    input: CachedInput,
    texels: Handle<ShaderBuffer>,
    map: Option<Arc<DisplacementMap>>,
    states: Handle<ShaderBuffer>,
    totals: Handle<ShaderBuffer>,
    out_vertices: Handle<ShaderBuffer>,
    out_indices: Handle<ShaderBuffer>,
    vertex_budget: u32,
    index_budget: u32,
    has_tangents: bool,
    uniform: Option<TessellationUniform>,
    /// Bumped whenever the uniform changes: the render world re-tessellates, and stamps
    /// the totals with it (their last word, the low 32 bits).
    generation: u64,
    /// The stamp of the latest totals read back (0: none yet): the read-back runs while
    /// it is not the generation's.
    arrived: u32,
    /// Triangles the pool holds now (between the floor and `max_triangles`).
    capacity: u32,
    /// The latest totals read back (bias, vertices, indices, patches, vertices and
    /// indices asked for).
    latest: Option<[u32; 6]>,
    /// The bounds' margin last inserted (local units).
    margin: f32,
}

impl TessellationState {
    /// The output mesh drawn in place of the source.
    pub fn output(&self) -> &Handle<Mesh> {
        &self.output
    }

    /// The original mesh.
    pub fn source(&self) -> &Handle<Mesh> {
        &self.source
    }

    /// The output pools (interleaved vertices, `u32` indices), the per-patch states and
    /// the totals (bias, vertices, indices, patches, the vertices and indices asked for,
    /// a reserved word, the low 32 bits of the tessellation's generation) the passes
    /// write: for read-back.
    pub fn buffers(&self) -> [&Handle<ShaderBuffer>; 4] {
        [
            &self.out_vertices,
            &self.out_indices,
            &self.states,
            &self.totals,
        ]
    }

    /// The preprocessed input.
    pub fn input(&self) -> &Arc<TessellationInput> {
        &self.input.input
    }

    /// The displacement map in use.
    pub fn map(&self) -> Option<&Arc<DisplacementMap>> {
        self.map.as_ref()
    }

    /// The last uniform written (the frame and settings the output is for).
    pub fn uniform(&self) -> Option<&TessellationUniform> {
        self.uniform.as_ref()
    }

    /// Pool sizes: vertices, indices.
    pub fn budget(&self) -> (u32, u32) {
        (self.vertex_budget, self.index_budget)
    }

    /// The latest totals the GPU wrote (bias, vertices, indices, patches, then the
    /// vertices and indices the view asked for before any bias), read back a frame or
    /// two late; `None` until the first tessellation's are back.
    pub fn latest_totals(&self) -> Option<[u32; 6]> {
        self.latest
    }
}

/// The core settings of a component, with bad values replaced (one warning each).
fn settings_of(entity: Entity, t: &Tessellated, cache: &mut TessellationCache) -> Settings {
    let mut ppt = t.pixels_per_triangle;
    if !(ppt.is_finite() && ppt > 0.0) {
        cache.warn_once(entity, "ppt", || {
            format!("pixels_per_triangle {ppt} is not positive; using 16")
        });
        ppt = 16.0;
    }
    if t.max_level > MAX_LEVEL {
        cache.warn_once(entity, "level", || {
            format!("max_level {} is above {MAX_LEVEL}; clamped", t.max_level)
        });
    }
    let finite = |x: f32, default: f32| if x.is_finite() { x } else { default };
    Settings {
        pixels_per_triangle: ppt,
        max_level: t.max_level.min(MAX_LEVEL),
        mode: match t.mode {
            TessellationMode::Flat => SurfaceMode::Flat,
            TessellationMode::PnAen => SurfaceMode::PnAen,
        },
        partitioning: match t.partitioning {
            TessellationPartitioning::Integer => Partitioning::Integer,
            TessellationPartitioning::Fractional => Partitioning::Fractional,
        },
        displacement_scale: finite(t.displacement_scale, 0.0),
        displacement_midlevel: finite(t.displacement_midlevel, 0.5),
        crack_fixes: true,
    }
}

/// What [`tessellation_view`] reads of the 3D cameras.
type TessellationCameras<'w, 's> = Query<
    'w,
    's,
    (
        &'static Camera,
        &'static GlobalTransform,
        Has<TessellationCamera>,
        Option<&'static RenderLayers>,
        Option<&'static RenderTarget>,
    ),
    With<Camera3d>,
>;

/// The view the factors of an entity on render layers `layers` are computed for: among
/// the active 3D cameras, a [`TessellationCamera`] first, then one that renders the
/// entity's layers, then one that renders to a window (a render-to-texture minimap or
/// mirror does not steer the main view's detail), then the highest order.
fn tessellation_view(
    cameras: &TessellationCameras,
    layers: &RenderLayers,
) -> Option<TessellationView> {
    let (camera, transform, ..) = cameras.iter().filter(|(c, ..)| c.is_active).max_by_key(
        |(c, _, marked, camera_layers, target)| {
            let sees = camera_layers
                .unwrap_or(&RenderLayers::default())
                .intersects(layers);
            let window = target.is_none_or(|t| matches!(t, RenderTarget::Window(_)));
            (*marked, sees, window, c.order)
        },
    )?;
    let height = camera.physical_viewport_size()?.y as f32;
    Some(TessellationView::new(
        transform.to_matrix(),
        camera.clip_from_view(),
        height,
    ))
}

/// Restores the source mesh of entities that lost [`Tessellated`] and stops their
/// read-back (also when the entity was despawned).
fn restore_untessellated(
    mut commands: Commands,
    mut cache: ResMut<TessellationCache>,
    mut removed: RemovedComponents<Tessellated>,
    states: Query<&TessellationState>,
) {
    for entity in removed.read() {
        if let Ok(state) = states.get(entity) {
            commands
                .entity(entity)
                .insert(Mesh3d(state.source.clone()))
                .remove::<(TessellationState, NoAutoAabb, Aabb, CasterMesh)>();
        }
        if let Some(readback) = cache.readbacks.remove(&entity) {
            commands.entity(readback).try_despawn();
        }
        cache.warned.retain(|(e, _)| *e != entity);
    }
}

/// The observer of an entity's totals read-back: keeps those of a tessellation (a stamp
/// of 0: the passes have not run on this buffer yet) and the stamp.
fn read_totals(
    entity: Entity,
    totals: AssetId<ShaderBuffer>,
) -> impl FnMut(On<ReadbackComplete>, Query<&mut TessellationState>) {
    move |event, mut states| {
        let word = |i: usize| {
            event
                .data
                .get(4 * i..4 * i + 4)
                .map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")))
        };
        if let Ok(mut state) = states.get_mut(entity)
            && state.totals.id() == totals
            && let Some(stamp) = word(7)
            && stamp != 0
        {
            state.latest = Some(std::array::from_fn(|i| word(i).expect("8 words")));
            state.arrived = stamp;
        }
    }
}

/// What `prepare_tessellated` reads of a tessellated entity.
type TessellatedEntity = (
    Entity,
    &'static Tessellated,
    &'static Mesh3d,
    &'static GlobalTransform,
    (&'static InheritedVisibility, &'static ViewVisibility),
    Option<&'static mut TessellationState>,
    Option<&'static RenderLayers>,
);

#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
fn prepare_tessellated(
    mut commands: Commands,
    mut cache: ResMut<TessellationCache>,
    mut mesh_events: MessageReader<AssetEvent<Mesh>>,
    mut image_events: MessageReader<AssetEvent<Image>>,
    mut meshes: ResMut<Assets<Mesh>>,
    images: Res<Assets<Image>>,
    mut buffers: ResMut<Assets<ShaderBuffer>>,
    cameras: TessellationCameras,
    mut entities: Query<TessellatedEntity>,
) {
    for event in mesh_events.read() {
        if let AssetEvent::Modified { id } | AssetEvent::Removed { id } = event {
            cache.inputs.remove(id);
        }
    }
    for event in image_events.read() {
        if let AssetEvent::Modified { id } | AssetEvent::Removed { id } = event {
            cache.maps.remove(id);
        }
    }
    let mut used_meshes = HashSet::new();
    let mut used_images = HashSet::new();
    for (entity, tessellated, mesh3d, transform, (inherited, seen), state, layers) in &mut entities
    {
        let view = tessellation_view(&cameras, layers.unwrap_or(&RenderLayers::default()));
        let source = match &state {
            Some(s) if mesh3d.0 == s.shown => s.source.clone(),
            _ => mesh3d.0.clone(),
        };
        used_meshes.insert(source.id());
        if let Some(image) = &tessellated.displacement {
            used_images.insert(image.id());
        }
        let settings = settings_of(entity, tessellated, &mut cache);
        // The preprocessed input (once per mesh version).
        let input = match cache.inputs.get(&source.id()) {
            Some(input) => input.clone(),
            None => {
                let Some(mesh) = meshes.get(&source) else {
                    continue; // not loaded yet
                };
                let input = match preprocess(mesh) {
                    Ok(input) => {
                        if input.non_manifold_edges > 0 {
                            let n = input.non_manifold_edges;
                            cache.warn_once(entity, "manifold", || format!("{n} edges are shared by more than two triangles: they may crack where normals or UVs split"));
                        }
                        let input = Arc::new(input);
                        let vertices = encase_vec(&input.vertices);
                        let patches: Vec<u8> = input
                            .patch_words()
                            .iter()
                            .flat_map(|w| w.to_le_bytes())
                            .collect();
                        Some(CachedInput {
                            vertices: buffers.add(ShaderBuffer::new(
                                &vertices,
                                RenderAssetUsages::RENDER_WORLD,
                            )),
                            patches: buffers
                                .add(ShaderBuffer::new(&patches, RenderAssetUsages::RENDER_WORLD)),
                            input,
                        })
                    }
                    Err(message) => {
                        cache.warn_once(entity, "mesh", || {
                            format!("{message}; it is drawn untessellated")
                        });
                        None
                    }
                };
                cache.inputs.insert(source.id(), input.clone());
                input
            }
        };
        let Some(input) = input else {
            continue;
        };
        // The displacement map.
        let map = match &tessellated.displacement {
            None => None,
            Some(_) if !input.input.has_uvs => {
                cache.warn_once(entity, "uvs", || {
                    "its mesh has no UVs: displacement is off".into()
                });
                None
            }
            Some(handle) => match cache.maps.get(&handle.id()) {
                Some(map) => map.clone(),
                None => {
                    let Some(image) = images.get(handle) else {
                        continue; // not loaded yet
                    };
                    let map = match heights(image) {
                        Ok(map) => {
                            let bytes: Vec<u8> =
                                map.texels.iter().flat_map(|t| t.to_le_bytes()).collect();
                            Some((
                                Arc::new(map),
                                buffers.add(ShaderBuffer::new(
                                    &bytes,
                                    RenderAssetUsages::RENDER_WORLD,
                                )),
                            ))
                        }
                        Err(message) => {
                            cache.warn_once(entity, "map", || {
                                format!("{message}; displacement is off")
                            });
                            None
                        }
                    };
                    cache.maps.insert(handle.id(), map.clone());
                    map
                }
            },
        };
        let patch_count = input.input.patches.len() as u32;
        let max = tessellated.max_triangles.max(patch_count);
        let floor = max.min(MIN_CAPACITY.max(patch_count));
        let current = state
            .as_ref()
            .map_or(floor, |s| s.capacity.clamp(floor, max));
        let triangles = match state.as_ref().and_then(|s| s.latest) {
            // The GPU had to coarsen: grow to what the view asked for, a quarter more
            // (up to `max_triangles`, then one warning).
            Some([bias, _, _, _, _, asked]) if bias > 0 && current < max => (asked / 3)
                .saturating_add(asked / 12)
                .next_multiple_of(4096)
                .clamp(current, max),
            Some([bias, ..]) if bias > 0 => {
                cache.warn_once(entity, "budget", || {
                    format!("the view asks for more than max_triangles ({max}): factors are halved {bias} time(s)")
                });
                current
            }
            // Mostly empty: shrink (the unused tail is drawn as degenerate triangles).
            Some([_, _, indices, ..]) if indices / 3 < current / 8 => (indices / 3 * 2).max(floor),
            _ => current,
        };
        let (vertex_budget, index_budget) = (
            triangles.saturating_add(2 * patch_count),
            triangles.saturating_mul(3),
        );
        let has_tangents = input.input.has_tangents;
        let rebuild = state.as_ref().is_none_or(|s| {
            s.source != source
                || !Arc::ptr_eq(&s.input.input, &input.input)
                || (s.vertex_budget, s.index_budget, s.has_tangents)
                    != (vertex_budget, index_budget, has_tangents)
                || mesh3d.0 != s.shown
        });
        let texels = match &map {
            Some((_, texels)) => texels.clone(),
            None => cache
                .no_map
                .get_or_insert_with(|| {
                    buffers.add(ShaderBuffer::new(&[0; 4], RenderAssetUsages::RENDER_WORLD))
                })
                .clone(),
        };
        let map_data = map.as_ref().map(|(m, _)| m.clone());
        let mut fresh = None;
        let state = match state {
            Some(state) if !rebuild => state.into_inner(),
            old => {
                if let Some(readback) = cache.readbacks.remove(&entity) {
                    commands.entity(readback).try_despawn();
                }
                let output = meshes.add(output_mesh(vertex_budget, index_budget, has_tangents));
                let words = if has_tangents { 12 } else { 8 };
                let storage = |bytes: u64| {
                    ShaderBuffer::with_size(bytes as usize, RenderAssetUsages::RENDER_WORLD)
                };
                let totals = buffers.add(storage(TOTALS_BYTES));
                // Until the new pool is filled, the entity shows what it showed (the
                // source, or the previous pool): no frame without the mesh.
                let shown = match &old {
                    Some(old) if old.source == source => old.shown.clone(),
                    _ => source.clone(),
                };
                let new = TessellationState {
                    source: source.clone(),
                    shown,
                    output: output.clone(),
                    input: input.clone(),
                    texels: texels.clone(),
                    map: map_data.clone(),
                    states: buffers.add(storage(PATCH_STATE_BYTES * u64::from(patch_count))),
                    totals,
                    out_vertices: buffers.add(storage(4 * words * u64::from(vertex_budget))),
                    out_indices: buffers.add(storage(4 * u64::from(index_budget))),
                    vertex_budget,
                    index_budget,
                    has_tangents,
                    uniform: None,
                    generation: 0,
                    arrived: 0,
                    capacity: triangles,
                    latest: None,
                    // NaN: inserted on the first frame.
                    margin: f32::NAN,
                };
                // A distance-field caster keeps baking the source, not the pool.
                commands
                    .entity(entity)
                    .insert((NoAutoAabb, CasterMesh(source.clone())));
                fresh.insert(new)
            }
        };
        state.texels = texels;
        state.map = map_data;
        // The pool has been filled (its totals came back): show it.
        if state.shown != state.output && state.latest.is_some() {
            state.shown = state.output.clone();
            commands.entity(entity).insert(Mesh3d(state.output.clone()));
        }
        // Conservative bounds (PN bulge and displacement), inserted only when they change.
        let margin = (settings.displacement_scale.abs()
            * settings
                .displacement_midlevel
                .max(1.0 - settings.displacement_midlevel))
            + 0.25 * (input.input.max - input.input.min).max_element();
        if state.margin != margin {
            state.margin = margin;
            commands.entity(entity).insert(Aabb::from_min_max(
                input.input.min - margin,
                input.input.max + margin,
            ));
        }
        // Hidden, or out of every view last frame (cameras and shadow views): keep the
        // last tessellation rather than redo it for a view that does not see it.
        let visible = inherited.get() && (seen.get() || state.uniform.is_none());
        if let (Some(view), true) = (view, visible) {
            let frame = Frame {
                view,
                world_from_local: transform.to_matrix(),
            };
            let uniform = TessellationUniform::new(
                &frame,
                &settings,
                state.map.as_deref(),
                patch_count,
                vertex_budget,
                index_budget,
                has_tangents,
            );
            if state.uniform != Some(uniform) {
                state.uniform = Some(uniform);
                state.generation += 1;
            }
        }
        // Read the totals back from a frame that may tessellate until that tessellation's
        // are back (stamped with its generation): a still entity reads nothing back.
        let reading = cache.readbacks.contains_key(&entity);
        let waiting = state.generation != 0 && state.arrived != state.generation as u32;
        if waiting && !reading {
            let readback = commands
                .spawn(Readback::buffer(state.totals.clone()))
                .observe(read_totals(entity, state.totals.id()))
                .id();
            cache.readbacks.insert(entity, readback);
        } else if !waiting && let Some(readback) = cache.readbacks.remove(&entity) {
            commands.entity(readback).try_despawn();
        }
        if let Some(fresh) = fresh {
            commands.entity(entity).insert(fresh);
        }
    }
    // Meshes and images no tessellated entity uses any more: free their preprocessing.
    cache.inputs.retain(|id, _| used_meshes.contains(id));
    cache.maps.retain(|id, _| used_images.contains(id));
}
