//! Render-world side of scatter bokeh: extraction, the pooled per-view buffers and
//! half- and quarter-resolution layers, the aperture textures, the bind groups and the three passes.

use super::pipelines::{
    BokehPipelines, SCATTER_LAYERS, ViewBokehPipelines, init_bokeh_pipelines,
    prepare_bokeh_pipelines, unsupported,
};
use super::{BokehApertureShape, BokehDepthOfField};
use bevy::camera::Projection;
use bevy::core_pipeline::{Core3dSystems, schedule::Core3d};
use bevy::platform::collections::{HashMap, HashSet};
use bevy::prelude::*;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::render_resource::encase::UniformBuffer as EncaseBuffer;
use bevy::render::render_resource::{
    BindGroup, BindGroupEntries, Buffer, BufferId, BufferUsages, ComputePassDescriptor, Extent3d,
    LoadOp, Operations, PipelineCache, RenderPassColorAttachment, RenderPassDescriptor, ShaderType,
    StoreOp, TextureDescriptor, TextureDimension, TextureFormat, TextureUsages, TextureView,
    TextureViewDescriptor, TextureViewId,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderQueue, ViewQuery};
use bevy::render::sync_component::{SyncComponent, SyncComponentPlugin};
use bevy::render::sync_world::RenderEntity;
use bevy::render::texture::{CachedTexture, TextureCache};
use bevy::render::view::{ExtractedView, ViewDepthTexture, ViewTarget};
use bevy::render::{Extract, ExtractSchedule, Render, RenderStartup, RenderSystems};
use bevy_penumbra_df::PenumbraGpuAllocations;
use bevy_penumbra_df::system_times::timed;
use penumbra_cinematic_core::dof::{Aperture, BokehView, Lens, SpriteRule, sprite_slots};
use penumbra_cinematic_core::scan::ScanPlan;
use std::sync::Arc;

/// Bytes per sprite slot (`penumbra::dof::types::Sprite`).
const SPRITE_BYTES: u64 = 32;

/// `LayerDraws` (`dof/types.wgsl`): four `draw_indirect` arguments (16 bytes each), then
/// the layers' first indices in the list (a `vec4<u32>`).
const LAYER_DRAWS_BYTES: u64 = 4 * 16 + 16;

/// A bokeh camera's settings in the render world, resolved at extraction.
#[derive(Component, Clone, Debug)]
pub struct ExtractedBokeh {
    lens: Lens,
    rule: SpriteRule,
    aperture: BokehApertureShape,
}

impl SyncComponent for BokehDepthOfField {
    /// Everything the render world keeps for a bokeh camera goes with the component.
    type Target = (
        ExtractedBokeh,
        ViewBokehBuffers,
        ViewBokehTextures,
        ViewBokehBindGroups,
        ViewBokehPipelines,
    );
}

/// An aperture's texture and its normalisation table (`aperture_norm`).
struct ApertureTexture {
    view: TextureView,
    info: Buffer,
}

/// Aperture textures by [`BokehApertureShape::id`], kept while a view uses them.
#[derive(Resource, Default)]
struct BokehApertureTextures(HashMap<u64, ApertureTexture>);

/// A view's pooled buffers: the uniform; the sprite pass's slots and per-block counts;
/// the scan's per-group sums; the compacted list and its draw's arguments.
#[derive(Component)]
pub struct ViewBokehBuffers {
    uniform: Buffer,
    block_counts: Buffer,
    /// One per [`penumbra_cinematic_core::scan::GROUP_ITEMS`] blocks (`ScanPlan::group_sums_len`).
    group_sums: Buffer,
    slots: Buffer,
    sprites: Buffer,
    args: Buffer,
    /// Sprites `slots` and `sprites` hold (4 per block): grown, never shrunk.
    capacity: u32,
    /// Blocks of this frame's view.
    blocks: u32,
    half_size: UVec2,
}

/// A view's layers (from Bevy's `TextureCache`, fetched each frame): near and far at
/// half resolution, then at quarter resolution (`SCATTER_LAYERS`' order).
#[derive(Component)]
pub struct ViewBokehTextures {
    layers: [CachedTexture; 4],
}

/// What a view's bind groups bind: the two main textures, the depth, the layers, the
/// sprite buffer, the aperture.
type BindKey = ([TextureViewId; 7], BufferId, u64);

/// A view's bind groups, remade only when a bound resource changes. The sprite and
/// composite passes read the view's colour, which ping-pongs between Bevy's two main
/// textures as post-processing passes run: one group per texture, picked at dispatch.
#[derive(Component)]
pub struct ViewBokehBindGroups {
    key: BindKey,
    sprites: [(TextureViewId, BindGroup); 2],
    compact: BindGroup,
    scatter: BindGroup,
    composite: [(TextureViewId, BindGroup); 2],
}

pub(super) fn build(render_app: &mut SubApp) {
    render_app.init_resource::<BokehApertureTextures>();
}

/// Adds the passes when the device can run them: compute, storage buffers read by a
/// vertex shader, indirect draws (not WebGL 2). Otherwise one warning, and the
/// component does nothing.
pub(super) fn finish(render_app: &mut SubApp) {
    if let Some(reason) = unsupported(render_app.world()) {
        warn!("Penumbra: BokehDepthOfField is unavailable: {reason}");
        return;
    }
    render_app
        .add_systems(RenderStartup, init_bokeh_pipelines)
        .add_systems(ExtractSchedule, timed(extract_bokeh_depth_of_field))
        .add_systems(
            Render,
            (
                timed(prepare_bokeh_pipelines)
                    .in_set(RenderSystems::Prepare)
                    .before(RenderSystems::PrepareResources),
                timed(prepare_bokeh_textures).in_set(RenderSystems::PrepareResources),
                timed(prepare_bokeh_bind_groups).in_set(RenderSystems::PrepareBindGroups),
            ),
        )
        .add_systems(
            Core3d,
            // Bloom first (its glow is blurred with the image, as Bevy's own depth of
            // field does); motion blur runs before bloom. Bevy's auto exposure is not
            // ordered against either (its system is private): it measures the image
            // before or after the blur, the same mean luminance.
            timed(bokeh_depth_of_field)
                .in_set(Core3dSystems::PostProcess)
                .after(bevy::post_process::bloom::bloom)
                .before(bevy::core_pipeline::tonemapping::tonemapping),
        );
}

/// What extraction reads of a bokeh camera.
type BokehCamera = (
    RenderEntity,
    &'static BokehDepthOfField,
    &'static Projection,
    Option<&'static BokehApertureShape>,
    Has<bevy::post_process::dof::DepthOfField>,
);

/// Copies each perspective bokeh camera's resolved settings and aperture to the render
/// world; anything else loses them (and its resources).
fn extract_bokeh_depth_of_field(mut commands: Commands, cameras: Extract<Query<BokehCamera>>) {
    for (entity, settings, projection, aperture, bevy_dof) in &cameras {
        let Ok(mut render) = commands.get_entity(entity) else {
            continue;
        };
        // Orthographic cameras and those with Bevy's depth of field are warned about in
        // the main world.
        let (Projection::Perspective(perspective), Some(aperture), false) =
            (projection, aperture, bevy_dof)
        else {
            render.remove::<<BokehDepthOfField as SyncComponent>::Target>();
            continue;
        };
        let (lens, rule, _) = settings.resolve(perspective.fov);
        render.insert(ExtractedBokeh {
            lens,
            rule,
            aperture: aperture.clone(),
        });
    }
}

/// Per view: the half-resolution layers, the pooled buffers (grown when the view
/// outgrows them), this frame's uniform and reset sprite count; the aperture textures
/// in use.
#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
fn prepare_bokeh_textures(
    mut commands: Commands,
    mut views: Query<(
        Entity,
        &ExtractedView,
        &ExtractedBokeh,
        Option<&mut ViewBokehBuffers>,
    )>,
    mut texture_cache: ResMut<TextureCache>,
    mut apertures: ResMut<BokehApertureTextures>,
    pipelines: Option<Res<BokehPipelines>>,
    allocations: Res<PenumbraGpuAllocations>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
) {
    let Some(pipelines) = pipelines else {
        return;
    };
    let mut used = HashSet::new();
    for (entity, view, bokeh, buffers) in &mut views {
        // The viewport (the whole target unless split screen).
        let full = view.viewport.zw().max(UVec2::ONE);
        let half = (full + UVec2::ONE) / 2;
        let capacity = sprite_slots(full);
        let mut entity_commands = commands.entity(entity);
        let quarter = (half + UVec2::ONE) / 2;
        let mut layer = |(_, label, _, is_quarter): (&str, &'static str, bool, bool)| {
            let size = if is_quarter { quarter } else { half };
            texture_cache.get(
                &device,
                TextureDescriptor {
                    label: Some(label),
                    size: Extent3d {
                        width: size.x,
                        height: size.y,
                        depth_or_array_layers: 1,
                    },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: TextureDimension::D2,
                    format: pipelines.layer_format,
                    usage: TextureUsages::RENDER_ATTACHMENT | TextureUsages::TEXTURE_BINDING,
                    view_formats: &[],
                },
            )
        };
        let textures = ViewBokehTextures {
            layers: SCATTER_LAYERS.map(&mut layer),
        };
        entity_commands.insert(textures);
        let blocks = capacity / 4;
        let storage = |label, bytes: u64, extra| {
            allocations.sized_buffer(&device, label, bytes, BufferUsages::STORAGE | extra)
        };
        let sprite_bytes = |n: u32| u64::from(n.max(1)) * SPRITE_BYTES;
        // Four counts (one per layer) per block and per group.
        let group_sum_bytes = |blocks: u32| u64::from(ScanPlan::new(blocks).group_sums_len()) * 16;
        let mut fresh = None;
        let buffers = match buffers {
            Some(b) => b.into_inner(),
            None => fresh.insert(ViewBokehBuffers {
                uniform: allocations.sized_buffer(
                    &device,
                    "penumbra_bokeh_view",
                    BokehView::min_size().get(),
                    BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                ),
                block_counts: storage(
                    "penumbra_bokeh_block_counts",
                    u64::from(blocks.max(1)) * 16,
                    BufferUsages::empty(),
                ),
                group_sums: storage(
                    "penumbra_bokeh_group_sums",
                    group_sum_bytes(blocks),
                    BufferUsages::empty(),
                ),
                slots: storage(
                    "penumbra_bokeh_slots",
                    sprite_bytes(capacity),
                    BufferUsages::empty(),
                ),
                sprites: storage(
                    "penumbra_bokeh_sprites",
                    sprite_bytes(capacity),
                    BufferUsages::empty(),
                ),
                // Four draws' arguments and the layers' first indices (`LayerDraws`).
                args: storage(
                    "penumbra_bokeh_draw_args",
                    LAYER_DRAWS_BYTES,
                    BufferUsages::INDIRECT,
                ),
                capacity,
                blocks,
                half_size: half,
            }),
        };
        if buffers.capacity < capacity {
            buffers.block_counts = storage(
                "penumbra_bokeh_block_counts",
                u64::from(blocks) * 16,
                BufferUsages::empty(),
            );
            buffers.group_sums = storage(
                "penumbra_bokeh_group_sums",
                group_sum_bytes(blocks),
                BufferUsages::empty(),
            );
            buffers.slots = storage(
                "penumbra_bokeh_slots",
                sprite_bytes(capacity),
                BufferUsages::empty(),
            );
            buffers.sprites = storage(
                "penumbra_bokeh_sprites",
                sprite_bytes(capacity),
                BufferUsages::empty(),
            );
            buffers.capacity = capacity;
        }
        buffers.blocks = blocks;
        buffers.half_size = half;
        let uniform = BokehView::new(
            &bokeh.lens,
            &bokeh.rule,
            view.clip_from_view.inverse(),
            full,
            capacity,
        )
        .at(view.viewport.xy());
        let mut bytes = EncaseBuffer::new(Vec::new());
        bytes.write(&uniform).expect("the bokeh uniform encodes");
        queue.write_buffer(&buffers.uniform, 0, bytes.as_ref());
        if let Some(fresh) = fresh {
            entity_commands.insert(fresh);
        }
        let shape = &bokeh.aperture;
        used.insert(shape.id);
        apertures
            .0
            .entry(shape.id)
            .or_insert_with(|| aperture_texture(&shape.aperture, &allocations, &device, &queue));
    }
    apertures.0.retain(|id, _| used.contains(id));
}

/// An aperture as an `R16Float` texture and its normalisation table.
fn aperture_texture(
    aperture: &Arc<Aperture>,
    allocations: &PenumbraGpuAllocations,
    device: &RenderDevice,
    queue: &RenderQueue,
) -> ApertureTexture {
    let n = aperture.size();
    let texture = allocations.texture(
        device,
        &TextureDescriptor {
            label: Some("penumbra_bokeh_aperture"),
            size: Extent3d {
                width: n,
                height: n,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: TextureDimension::D2,
            format: TextureFormat::R16Float,
            usage: TextureUsages::TEXTURE_BINDING | TextureUsages::COPY_DST,
            view_formats: &[],
        },
    );
    let texels: Vec<u8> = aperture
        .weights()
        .iter()
        .flat_map(|&w| half::f16::from_f32(w).to_le_bytes())
        .collect();
    queue.write_texture(
        texture.as_image_copy(),
        &texels,
        bevy::render::render_resource::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(2 * n),
            rows_per_image: None,
        },
        texture.size(),
    );
    let words: Vec<u8> = aperture
        .norm_words()
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let info = allocations.sized_buffer(
        device,
        "penumbra_bokeh_aperture_norm",
        words.len() as u64,
        BufferUsages::STORAGE | BufferUsages::COPY_DST,
    );
    queue.write_buffer(&info, 0, &words);
    ApertureTexture {
        view: texture.create_view(&TextureViewDescriptor::default()),
        info,
    }
}

/// What a view's bind groups are made of.
type BindGroupInputs = (
    Entity,
    &'static ViewTarget,
    &'static ViewDepthTexture,
    &'static ExtractedBokeh,
    &'static ViewBokehBuffers,
    &'static ViewBokehTextures,
    Option<&'static ViewBokehBindGroups>,
);

/// A view's bind groups, remade when a bound resource changes.
#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
fn prepare_bokeh_bind_groups(
    mut commands: Commands,
    views: Query<BindGroupInputs>,
    pipelines: Option<Res<BokehPipelines>>,
    apertures: Res<BokehApertureTextures>,
    pipeline_cache: Res<PipelineCache>,
    allocations: Res<PenumbraGpuAllocations>,
    device: Res<RenderDevice>,
) {
    let Some(pipelines) = pipelines else {
        return;
    };
    for (entity, target, depth, bokeh, buffers, textures, groups) in &views {
        let Some(aperture) = apertures.0.get(&bokeh.aperture.id) else {
            continue;
        };
        // Which of the two is current alternates between frames: the key takes them in
        // a fixed order.
        let mut mains = [target.main_texture_view(), target.main_texture_other_view()];
        mains.sort_by_key(|v| v.id());
        let depth_view = depth.view();
        let key = (
            [
                mains[0].id(),
                mains[1].id(),
                depth_view.id(),
                textures.layers[0].default_view.id(),
                textures.layers[1].default_view.id(),
                textures.layers[2].default_view.id(),
                textures.layers[3].default_view.id(),
            ],
            buffers.sprites.id(),
            bokeh.aperture.id,
        );
        if groups.is_some_and(|g| g.key == key) {
            continue;
        }
        let ms = (depth.texture.sample_count() > 1) as usize;
        let sprites_layout = pipeline_cache.get_bind_group_layout(&pipelines.sprites_layout[ms]);
        let composite_layout =
            pipeline_cache.get_bind_group_layout(&pipelines.composite_layout[ms]);
        let per_main = |main: &TextureView| {
            let sprites = allocations.bind_group(
                &device,
                "penumbra_bokeh_sprites",
                &sprites_layout,
                &BindGroupEntries::sequential((
                    buffers.uniform.as_entire_binding(),
                    main,
                    depth_view,
                    buffers.block_counts.as_entire_binding(),
                    buffers.slots.as_entire_binding(),
                )),
            );
            let composite = allocations.bind_group(
                &device,
                "penumbra_bokeh_composite",
                &composite_layout,
                &BindGroupEntries::sequential((
                    buffers.uniform.as_entire_binding(),
                    main,
                    depth_view,
                    &textures.layers[0].default_view,
                    &textures.layers[1].default_view,
                    &textures.layers[2].default_view,
                    &textures.layers[3].default_view,
                )),
            );
            ((main.id(), sprites), (main.id(), composite))
        };
        let (a, b) = (per_main(mains[0]), per_main(mains[1]));
        let compact = allocations.bind_group(
            &device,
            "penumbra_bokeh_compact",
            &pipeline_cache.get_bind_group_layout(&pipelines.compact_layout),
            &BindGroupEntries::sequential((
                buffers.uniform.as_entire_binding(),
                buffers.block_counts.as_entire_binding(),
                buffers.slots.as_entire_binding(),
                buffers.sprites.as_entire_binding(),
                buffers.args.as_entire_binding(),
                buffers.group_sums.as_entire_binding(),
            )),
        );
        let scatter = allocations.bind_group(
            &device,
            "penumbra_bokeh_scatter",
            &pipeline_cache.get_bind_group_layout(&pipelines.scatter_layout),
            &BindGroupEntries::sequential((
                buffers.uniform.as_entire_binding(),
                buffers.sprites.as_entire_binding(),
                &aperture.view,
                &pipelines.sampler,
                aperture.info.as_entire_binding(),
                buffers.args.as_entire_binding(),
            )),
        );
        commands.entity(entity).insert(ViewBokehBindGroups {
            key,
            sprites: [a.0, b.0],
            compact,
            scatter,
            composite: [a.1, b.1],
        });
    }
}

/// The three passes: sprites (compute), scatter (instanced quads into the layers),
/// composite (the view's colour to its other main texture).
fn bokeh_depth_of_field(
    view: ViewQuery<(
        &ViewTarget,
        &ViewBokehBuffers,
        &ViewBokehTextures,
        &ViewBokehBindGroups,
        &ViewBokehPipelines,
    )>,
    pipelines: Option<Res<BokehPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    mut ctx: RenderContext,
) {
    let (target, buffers, textures, groups, ids) = view.into_inner();
    let Some(pipelines) = pipelines else {
        return;
    };
    // Until every pipeline has compiled the view is left as it is.
    let (Some(sprites), Some(reduce), Some(scan), Some(compact), Some(composite)) = (
        pipeline_cache.get_compute_pipeline(ids.sprites),
        pipeline_cache.get_compute_pipeline(pipelines.reduce),
        pipeline_cache.get_compute_pipeline(pipelines.scan),
        pipeline_cache.get_compute_pipeline(pipelines.compact),
        pipeline_cache.get_render_pipeline(ids.composite),
    ) else {
        return;
    };
    let scatter = pipelines
        .scatter
        .map(|id| pipeline_cache.get_render_pipeline(id));
    if scatter.iter().any(Option::is_none) {
        return;
    }
    let source = target.main_texture_view().id();
    let pick = |pair: &'_ [(TextureViewId, BindGroup); 2]| {
        pair.iter()
            .find(|(id, _)| *id == source)
            .map(|(_, g)| g.clone())
    };
    let (Some(sprites_group), Some(composite_group)) =
        (pick(&groups.sprites), pick(&groups.composite))
    else {
        return; // the view's textures changed since the bind groups were made
    };
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let time_span = diagnostics.time_span(ctx.command_encoder(), "penumbra_bokeh_dof");
    {
        let mut pass = ctx
            .command_encoder()
            .begin_compute_pass(&ComputePassDescriptor {
                label: Some("penumbra_bokeh_sprites"),
                timestamp_writes: None,
            });
        pass.set_pipeline(sprites);
        pass.set_bind_group(0, &sprites_group, &[]);
        let blocks = (buffers.half_size + UVec2::ONE) / 2;
        pass.dispatch_workgroups(blocks.x.div_ceil(8), blocks.y.div_ceil(8), 1);
    }
    // The list in block order: a scan of the blocks' counts over many workgroups, the
    // copy in its last pass (each in its own pass: the next reads what the last wrote).
    let [reduce_groups, scan_groups, compact_groups] = ScanPlan::new(buffers.blocks).workgroups();
    for (label, pipeline, workgroups) in [
        ("penumbra_bokeh_reduce", reduce, reduce_groups),
        ("penumbra_bokeh_scan", scan, scan_groups),
        ("penumbra_bokeh_compact", compact, compact_groups),
    ] {
        let mut pass = ctx
            .command_encoder()
            .begin_compute_pass(&ComputePassDescriptor {
                label: Some(label),
                timestamp_writes: None,
            });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &groups.compact, &[]);
        pass.dispatch_workgroups(workgroups, 1, 1);
    }
    // One draw per layer, each over the whole list (`scatter.wgsl`).
    for (layer, (((label, _, _, _), pipeline), texture)) in SCATTER_LAYERS
        .into_iter()
        .zip(scatter.into_iter().flatten())
        .zip(&textures.layers)
        .enumerate()
    {
        let view = &texture.default_view;
        let mut pass = ctx
            .command_encoder()
            .begin_render_pass(&RenderPassDescriptor {
                label: Some(label),
                color_attachments: &[Some(RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: Operations {
                        load: LoadOp::Clear(default()),
                        store: StoreOp::Store,
                    },
                })],
                ..default()
            });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &groups.scatter, &[]);
        pass.draw_indirect(&buffers.args, 16 * layer as u64);
    }
    let post = target.post_process_write();
    {
        let mut pass = ctx
            .command_encoder()
            .begin_render_pass(&RenderPassDescriptor {
                label: Some("penumbra_bokeh_composite"),
                color_attachments: &[Some(RenderPassColorAttachment {
                    view: post.destination,
                    depth_slice: None,
                    resolve_target: None,
                    ops: Operations {
                        load: LoadOp::Clear(default()),
                        store: StoreOp::Store,
                    },
                })],
                ..default()
            });
        pass.set_pipeline(composite);
        pass.set_bind_group(0, &composite_group, &[]);
        pass.draw(0..3, 0..1);
    }
    time_span.end(ctx.command_encoder());
}

/// Registers the component's render-world cleanup.
pub(super) fn sync_plugin() -> SyncComponentPlugin<BokehDepthOfField> {
    SyncComponentPlugin::default()
}
