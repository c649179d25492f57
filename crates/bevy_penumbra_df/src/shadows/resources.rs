//! A view's pooled GPU resources for the shadow passes: created with the view's first
//! shadowed light and reused. Uniforms are rewritten each frame (`write_buffer`), the
//! storage buffers grow with the object buffer (never per frame), counters are cleared
//! on the GPU, and bind groups are rebuilt only when a resource they bind changes.

use super::msaa::SampleTraceInputs;
use super::render::{DistanceFieldShadowedLight, ShadowPipelines};
use crate::gpu_allocations::PenumbraGpuAllocations;
use bevy::prelude::*;
use bevy::render::render_resource::{
    BindGroup, BindGroupEntries, Buffer, BufferId, BufferUsages, PipelineCache, TextureView,
    TextureViewId,
};
use bevy::render::renderer::{RenderDevice, RenderQueue};
use penumbra_df_core::cull::{CameraOrigin, Frustum, cull_view_words, grid_64};
use penumbra_df_core::shadow::{
    SHADOW_GRID_BYTES, SHADOW_GRID_MAX_CELLS, SHADOW_GRID_VIEW_BYTES, SHADOW_LIGHT_BYTES,
    SHADOW_TRACE_VIEW_BYTES, ShadowLight, ShadowLightKind, grid_view_words, half_size,
    trace_view_words, words_to_bytes,
};

/// The light-space grid's item list is sized for every caster in `MAX_CELLS` cells; above
/// this many bytes a directional light culls from its plain list instead.
const MAX_GRID_ITEM_BYTES: u64 = 16 << 20;
/// Bytes of `ShadowUpsampleView` (`df/shadow_upsample.wgsl`).
pub(super) const UPSAMPLE_VIEW_BYTES: u64 = 64 + 16 + 16;
/// Bytes of `ShadowCullView` (the frustum cull's `CullView` layout).
pub(super) const CULL_VIEW_BYTES: u64 = 6 * 16 + 16 + 16 + 16;
/// Bytes of the grid fill's per-cell cursors.
pub(super) const CURSOR_BYTES: u64 = 4096;

/// A view's shadow resources (render world).
#[derive(Component)]
pub struct DistanceFieldShadowResources {
    /// `ShadowCullView`, the `ShadowTraceView`s at full and half resolution, and the
    /// upsample pass's view.
    cull_view: Buffer,
    full_view: Buffer,
    half_view: Buffer,
    upsample_view: Buffer,
    /// Deferred MSAA's per-sample trace: `ShadowTraceView` over twice the view's size.
    sample_view: Buffer,
    /// Per light, in mask-layer order.
    pub(super) lights: Vec<LightResources>,
    /// Bound as the terrains while the scene has none (made when first needed).
    pub(super) no_terrain: Option<(Buffer, TextureView)>,
}

/// One light's buffers and bind groups.
pub(super) struct LightResources {
    light: Buffer,
    grid_view: Buffer,
    /// The culled slots (`capacity` of them) and their count.
    list: Buffer,
    pub(super) count: Buffer,
    /// The light-space grid; its items, large list and cursors (directional lights;
    /// 16-byte stand-ins otherwise).
    pub(super) grid: Buffer,
    items: Buffer,
    large: Buffer,
    pub(super) cursors: Buffer,
    capacity: u32,
    /// Whether `items` holds `MAX_CELLS` entries per slot (the grid is usable).
    grid_items: bool,
    /// This frame: whether the pass uses the grid, and traces at half resolution.
    pub(super) use_grid: bool,
    pub(super) half: bool,
    pub(super) bind_groups: Option<LightBindGroups>,
    /// The external resources `bind_groups` were made with.
    key: Option<BindKey>,
}

/// A light's bind groups for the cull, grid, trace and upsample passes.
pub(super) struct LightBindGroups {
    pub(super) cull: BindGroup,
    pub(super) grid: Option<BindGroup>,
    pub(super) trace: BindGroup,
    pub(super) upsample: Option<BindGroup>,
    /// Deferred MSAA's per-sample trace (`msaa.rs`).
    pub(super) sample_trace: Option<BindGroup>,
}

/// What a light's bind groups reference besides its own buffers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct BindKey {
    objects: BufferId,
    atlas: TextureViewId,
    brick_table: TextureViewId,
    depth: TextureViewId,
    gbuffer: TextureViewId,
    face: (TextureViewId, TextureViewId),
    layer: TextureViewId,
    half: Option<(TextureViewId, TextureViewId)>,
    terrain: (BufferId, TextureViewId),
    /// The per-sample trace's depth, G-buffer, classes and layer.
    samples: Option<[TextureViewId; 4]>,
}

/// The view-level textures the bind groups reference.
pub(super) struct ViewTextures<'a> {
    pub(super) objects: &'a Buffer,
    pub(super) atlas: &'a TextureView,
    pub(super) brick_table: &'a TextureView,
    pub(super) depth: &'a TextureView,
    pub(super) gbuffer: &'a TextureView,
    /// The face-normal prepass's target and depth (or empty textures).
    pub(super) face: (&'a TextureView, &'a TextureView),
    /// The terrains' records and heights (`GpuHeightfields`, or none).
    pub(super) terrain: (&'a Buffer, &'a TextureView),
    pub(super) layers: &'a [TextureView],
    pub(super) half: Option<&'a (TextureView, TextureView)>,
    /// Deferred MSAA: what the per-sample trace reads and writes.
    pub(super) samples: Option<SampleTraceInputs<'a>>,
}

fn storage(
    allocations: &PenumbraGpuAllocations,
    device: &RenderDevice,
    label: &'static str,
    size: u64,
    usage: BufferUsages,
) -> Buffer {
    let size = size.max(16).next_multiple_of(4);
    allocations.sized_buffer(device, label, size, BufferUsages::STORAGE | usage)
}

fn uniform(
    allocations: &PenumbraGpuAllocations,
    device: &RenderDevice,
    label: &'static str,
    size: u64,
) -> Buffer {
    let usage = BufferUsages::UNIFORM | BufferUsages::COPY_DST;
    allocations.sized_buffer(device, label, size, usage)
}

impl LightResources {
    /// Buffers for up to `capacity` slots; with the grid's for a directional light.
    fn new(
        allocations: &PenumbraGpuAllocations,
        device: &RenderDevice,
        capacity: u32,
        directional: bool,
    ) -> LightResources {
        let item_bytes = capacity as u64 * SHADOW_GRID_MAX_CELLS as u64 * 4;
        let grid_items = directional && item_bytes <= MAX_GRID_ITEM_BYTES;
        let grid_size = |bytes: u64| if directional { bytes } else { 16 };
        let clear = BufferUsages::COPY_DST;
        LightResources {
            light: uniform(
                allocations,
                device,
                "penumbra_df_shadow_light",
                SHADOW_LIGHT_BYTES as u64,
            ),
            grid_view: uniform(
                allocations,
                device,
                "penumbra_df_shadow_grid_view",
                SHADOW_GRID_VIEW_BYTES as u64,
            ),
            list: storage(
                allocations,
                device,
                "penumbra_df_shadow_objects",
                capacity as u64 * 4,
                BufferUsages::empty(),
            ),
            count: storage(
                allocations,
                device,
                "penumbra_df_shadow_object_count",
                16,
                clear,
            ),
            // Bound by the trace pass for every light (its layout's minimum size).
            grid: storage(
                allocations,
                device,
                "penumbra_df_shadow_grid",
                SHADOW_GRID_BYTES as u64,
                clear,
            ),
            items: storage(
                allocations,
                device,
                "penumbra_df_shadow_grid_items",
                if grid_items { item_bytes } else { 16 },
                BufferUsages::empty(),
            ),
            large: storage(
                allocations,
                device,
                "penumbra_df_shadow_grid_large",
                grid_size(capacity as u64 * 4),
                BufferUsages::empty(),
            ),
            cursors: storage(
                allocations,
                device,
                "penumbra_df_shadow_grid_cursors",
                grid_size(CURSOR_BYTES),
                clear,
            ),
            capacity,
            grid_items,
            use_grid: false,
            half: false,
            bind_groups: None,
            key: None,
        }
    }

    /// Whether these buffers serve a light of this kind over `slots` slots.
    fn fits(&self, slots: u32, directional: bool) -> bool {
        let has_grid = self.cursors.size() >= CURSOR_BYTES;
        slots <= self.capacity && has_grid == directional
    }
}

/// Slots a view's buffers are sized for: the object buffer's, rounded up.
fn capacity_for(slots: u32) -> u32 {
    slots.max(64).next_power_of_two()
}

impl DistanceFieldShadowResources {
    /// A view's uniforms; its lights' buffers come with [`Self::fit`].
    pub(super) fn new(
        allocations: &PenumbraGpuAllocations,
        device: &RenderDevice,
    ) -> DistanceFieldShadowResources {
        let trace_bytes = SHADOW_TRACE_VIEW_BYTES as u64;
        DistanceFieldShadowResources {
            cull_view: uniform(
                allocations,
                device,
                "penumbra_df_shadow_cull_view",
                CULL_VIEW_BYTES,
            ),
            full_view: uniform(
                allocations,
                device,
                "penumbra_df_shadow_trace_view",
                trace_bytes,
            ),
            half_view: uniform(
                allocations,
                device,
                "penumbra_df_shadow_trace_view",
                trace_bytes,
            ),
            upsample_view: uniform(
                allocations,
                device,
                "penumbra_df_shadow_upsample_view",
                UPSAMPLE_VIEW_BYTES,
            ),
            sample_view: uniform(
                allocations,
                device,
                "penumbra_df_shadow_sample_trace_view",
                trace_bytes,
            ),
            lights: Vec::new(),
            no_terrain: None,
        }
    }

    /// One light's buffers per frame light, grown (or re-made for a change of kind)
    /// where they no longer fit; untouched otherwise.
    pub(super) fn fit(
        &mut self,
        allocations: &PenumbraGpuAllocations,
        device: &RenderDevice,
        frame: &[DistanceFieldShadowedLight],
        slots: u32,
    ) {
        self.lights.truncate(frame.len());
        for (i, light) in frame.iter().enumerate() {
            let directional = light.is_directional();
            match self.lights.get(i) {
                Some(r) if r.fits(slots, directional) => {}
                _ => {
                    let fresh =
                        LightResources::new(allocations, device, capacity_for(slots), directional);
                    if i < self.lights.len() {
                        self.lights[i] = fresh;
                    } else {
                        self.lights.push(fresh);
                    }
                }
            }
        }
    }

    /// Writes this frame's uniforms and (re)makes the bind groups that changed.
    #[allow(clippy::too_many_arguments, reason = "the frame's inputs, each needed")]
    pub(super) fn update(
        &mut self,
        allocations: &PenumbraGpuAllocations,
        device: &RenderDevice,
        queue: &RenderQueue,
        pipelines: &ShadowPipelines,
        pipeline_cache: &PipelineCache,
        view: &ShadowViewParams,
        frame: &[DistanceFieldShadowedLight],
        textures: &ViewTextures,
    ) {
        let (_, groups_x) = grid_64(view.slots);
        let cull = cull_view_words(&view.frustum, &view.camera, view.slots, groups_x);
        queue.write_buffer(&self.cull_view, 0, &words_to_bytes(&cull));
        let trace = |stride: u32, size: UVec2| {
            words_to_bytes(&trace_view_words(
                view.view_from_clip,
                view.world_from_view,
                &view.camera,
                size,
                stride,
                view.inputs,
                view.heightfields,
                UVec4::new(view.origin.x, view.origin.y, view.size.x, view.size.y),
            ))
        };
        queue.write_buffer(&self.full_view, 0, &trace(1, view.size));
        queue.write_buffer(&self.half_view, 0, &trace(2, half_size(view.size)));
        if textures.samples.is_some() {
            queue.write_buffer(&self.sample_view, 0, &trace(1, 2 * view.size));
        }
        let mut upsample: Vec<u32> = view
            .view_from_clip
            .to_cols_array()
            .map(f32::to_bits)
            .to_vec();
        let h = half_size(view.size);
        upsample.extend([h.x, h.y, view.size.x, view.size.y]);
        upsample.extend([view.origin.x, view.origin.y, 0, 0]);
        queue.write_buffer(&self.upsample_view, 0, &words_to_bytes(&upsample));
        let views = [
            &self.full_view,
            &self.half_view,
            &self.upsample_view,
            &self.cull_view,
            &self.sample_view,
        ];
        for (i, ((light, r), layer)) in frame
            .iter()
            .zip(&mut self.lights)
            .zip(textures.layers)
            .enumerate()
        {
            // A light that cannot be placed (non-finite, beyond ±2³¹ tiles) marches
            // nothing: its mask is all lit.
            let params = light.shadow_light(&view.camera).unwrap_or(UNLIT);
            queue.write_buffer(&r.light, 0, &words_to_bytes(&params.to_words()));
            let to_light = match params.kind {
                ShadowLightKind::Directional(d) if r.grid_items => Some(d),
                _ => None,
            };
            r.use_grid = to_light.is_some();
            let grid_view = grid_view_words(&view.camera, to_light.unwrap_or(Vec3::Y), r.use_grid);
            queue.write_buffer(&r.grid_view, 0, &words_to_bytes(&grid_view));
            r.half = light.settings.half_resolution && textures.half.is_some();
            let key = BindKey {
                objects: textures.objects.id(),
                atlas: textures.atlas.id(),
                brick_table: textures.brick_table.id(),
                depth: textures.depth.id(),
                gbuffer: textures.gbuffer.id(),
                face: (textures.face.0.id(), textures.face.1.id()),
                layer: layer.id(),
                half: textures
                    .half
                    .filter(|_| r.half)
                    .map(|(storage, sampled)| (storage.id(), sampled.id())),
                terrain: (textures.terrain.0.id(), textures.terrain.1.id()),
                samples: textures.samples.as_ref().and_then(|s| {
                    let layer = s.layers.get(i)?;
                    Some([s.depth.id(), s.gbuffer.id(), s.class.id(), layer.id()])
                }),
            };
            if r.key != Some(key) || r.bind_groups.is_none() {
                r.bind_groups = Some(bind_groups(
                    allocations,
                    device,
                    pipelines,
                    pipeline_cache,
                    r,
                    views,
                    textures,
                    (layer, i),
                ));
                r.key = Some(key);
            }
        }
    }
}

/// A light that traces nothing.
const UNLIT: ShadowLight = ShadowLight {
    kind: ShadowLightKind::Directional(Vec3::Y),
    source: 0.0,
    max_distance: 0.0,
    bias: 0.0,
    shaping: 1.0,
    range: 0.0,
    max_steps: 0,
    max_view_distance: 0.0,
    spot: None,
};

/// A view as the shadow passes see it this frame.
pub(super) struct ShadowViewParams {
    pub(super) camera: CameraOrigin,
    pub(super) frustum: Frustum,
    pub(super) view_from_clip: Mat4,
    pub(super) world_from_view: Mat3,
    /// The viewport's size (the mask's at full resolution) and its origin in the render
    /// target (where the prepass textures are read).
    pub(super) size: UVec2,
    pub(super) origin: UVec2,
    pub(super) slots: u32,
    /// Which normals the bindings hold (`penumbra_df_core::shadow::TRACE_*`).
    pub(super) inputs: u32,
    /// Terrains bound.
    pub(super) heightfields: u32,
}

#[allow(clippy::too_many_arguments, reason = "every binding of four passes")]
fn bind_groups(
    allocations: &PenumbraGpuAllocations,
    device: &RenderDevice,
    pipelines: &ShadowPipelines,
    pipeline_cache: &PipelineCache,
    r: &LightResources,
    [full_view, half_view, upsample_view, cull_view, sample_view]: [&Buffer; 5],
    t: &ViewTextures,
    (layer, index): (&TextureView, usize),
) -> LightBindGroups {
    let layout = |l| pipeline_cache.get_bind_group_layout(l);
    let cull = allocations.bind_group(
        device,
        "penumbra_df_shadow_cull",
        &layout(&pipelines.cull_layout),
        &BindGroupEntries::sequential((
            t.objects.as_entire_binding(),
            cull_view.as_entire_binding(),
            r.light.as_entire_binding(),
            r.list.as_entire_binding(),
            r.count.as_entire_binding(),
        )),
    );
    let grid = r.grid_items.then(|| {
        allocations.bind_group(
            device,
            "penumbra_df_shadow_grid",
            &layout(&pipelines.grid_layout),
            &BindGroupEntries::sequential((
                t.objects.as_entire_binding(),
                r.list.as_entire_binding(),
                r.count.as_entire_binding(),
                r.grid_view.as_entire_binding(),
                r.grid.as_entire_binding(),
                r.items.as_entire_binding(),
                r.large.as_entire_binding(),
                r.cursors.as_entire_binding(),
            )),
        )
    });
    // Half resolution: trace into the half texture, then upsample into the layer.
    let half = t.half.filter(|_| r.half);
    let (target, trace_view) = match half {
        Some((storage, _)) => (storage, half_view),
        None => (layer, full_view),
    };
    let trace = allocations.bind_group(
        device,
        "penumbra_df_shadow_trace",
        &layout(&pipelines.trace_layout),
        &BindGroupEntries::sequential((
            t.objects.as_entire_binding(),
            r.list.as_entire_binding(),
            r.count.as_entire_binding(),
            t.atlas,
            t.depth,
            trace_view.as_entire_binding(),
            r.light.as_entire_binding(),
            target,
            r.grid.as_entire_binding(),
            r.items.as_entire_binding(),
            r.large.as_entire_binding(),
            r.grid_view.as_entire_binding(),
            t.gbuffer,
            t.terrain.0.as_entire_binding(),
            t.terrain.1,
            t.brick_table,
            t.face.0,
            t.face.1,
        )),
    );
    let upsample = half.map(|(_, sampled)| {
        allocations.bind_group(
            device,
            "penumbra_df_shadow_upsample",
            &layout(&pipelines.upsample_layout),
            &BindGroupEntries::sequential((
                sampled,
                t.depth,
                upsample_view.as_entire_binding(),
                layer,
            )),
        )
    });
    let sample_trace = t.samples.as_ref().and_then(|s| {
        let target = s.layers.get(index)?;
        Some(allocations.bind_group(
            device,
            "penumbra_df_shadow_sample_trace",
            &layout(&pipelines.sample_trace_layout),
            &BindGroupEntries::sequential((
                t.objects.as_entire_binding(),
                r.list.as_entire_binding(),
                r.count.as_entire_binding(),
                t.atlas,
                s.depth,
                sample_view.as_entire_binding(),
                r.light.as_entire_binding(),
                target,
                r.grid.as_entire_binding(),
                r.items.as_entire_binding(),
                r.large.as_entire_binding(),
                r.grid_view.as_entire_binding(),
                s.gbuffer,
                t.terrain.0.as_entire_binding(),
                t.terrain.1,
                s.class,
                t.brick_table,
            )),
        ))
    });
    LightBindGroups {
        cull,
        grid,
        trace,
        upsample,
        sample_trace,
    }
}
