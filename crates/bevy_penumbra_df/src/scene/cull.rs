//! Per-view GPU culling of the object buffer (`df/cull.wgsl`) into a compact list of
//! slots, its count and indirect dispatch arguments, for the passes that walk it.
//!
//! The buffers live on the view ([`CulledObjects`]) and are reused: they grow with the
//! object buffer, the view uniform is rewritten each frame, the counters are cleared
//! on the GPU, and the bind groups are made again only when a buffer changes. A
//! consumer calls [`CulledObjects::prepare`] in its prepare system and
//! [`CulledObjects::dispatch`] in its pass.

use super::render::{DistanceFieldGpu, DistanceFieldPipelines};
use crate::gpu_allocations::PenumbraGpuAllocations;
use bevy::prelude::*;
use bevy::render::render_resource::{
    BindGroup, BindGroupEntries, Buffer, BufferId, BufferUsages, ComputePassDescriptor,
    PipelineCache,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderQueue};
use penumbra_df_core::cull::{CameraOrigin, Frustum, cull_view_words, grid_64};

/// Size of the culling pass's view uniform (`CullView` in `df/cull.wgsl`).
pub(crate) const CULL_VIEW_BYTES: u64 = 144;

/// One view's culling output and its pooled buffers (render world).
#[derive(Component)]
pub struct CulledObjects {
    /// `array<u32>` of the surviving slots.
    pub list: Buffer,
    /// Their count (`u32`).
    pub count: Buffer,
    /// `[x, y, z]` workgroups of 64 for passes walking the list.
    pub indirect: Buffer,
    view: Buffer,
    /// Slots `list` holds.
    capacity: u32,
    /// The cull and indirect passes' bind groups, and the object buffer they bind.
    bind_groups: Option<(BufferId, BindGroup, BindGroup)>,
    /// This frame's workgroups (0 while nothing to cull).
    groups: [u32; 3],
}

impl CulledObjects {
    fn new(allocations: &PenumbraGpuAllocations, device: &RenderDevice, slots: u32) -> Self {
        let capacity = slots.max(64).next_power_of_two();
        let buffer = |label, size, usage| allocations.sized_buffer(device, label, size, usage);
        let counter = BufferUsages::STORAGE | BufferUsages::COPY_DST | BufferUsages::COPY_SRC;
        CulledObjects {
            list: buffer(
                "penumbra_df_culled",
                capacity as u64 * 4,
                BufferUsages::STORAGE,
            ),
            count: buffer("penumbra_df_culled_count", 4, counter),
            indirect: buffer(
                "penumbra_df_culled_indirect",
                12,
                counter | BufferUsages::INDIRECT,
            ),
            view: buffer(
                "penumbra_df_cull_view",
                CULL_VIEW_BYTES,
                BufferUsages::UNIFORM | BufferUsages::COPY_DST,
            ),
            capacity,
            bind_groups: None,
            groups: [0; 3],
        }
    }

    /// Fits the view's culling buffers to the object buffer (creating them the first
    /// time, growing them when the buffer grew), writes the view uniform for a camera at
    /// world position `camera` with camera-relative `clip_from_relative`, and makes the
    /// bind groups if a buffer changed. Nothing to cull (no object buffer yet, pipelines
    /// compiling, a camera beyond the tile range): no dispatch this frame.
    #[allow(clippy::too_many_arguments, reason = "the frame's inputs, each needed")]
    pub fn prepare(
        current: Option<Mut<CulledObjects>>,
        commands: &mut EntityCommands,
        gpu: &DistanceFieldGpu,
        pipelines: &DistanceFieldPipelines,
        pipeline_cache: &PipelineCache,
        allocations: &PenumbraGpuAllocations,
        device: &RenderDevice,
        queue: &RenderQueue,
        clip_from_relative: Mat4,
        camera: Vec3,
    ) {
        let (Some(objects), Some(origin)) = (gpu.objects.as_ref(), CameraOrigin::at(camera)) else {
            if let Some(mut c) = current {
                c.groups = [0; 3];
            }
            return;
        };
        let slots = gpu.slot_count;
        let mut fresh = None;
        let culled = match current {
            Some(c) if c.capacity >= slots => c.into_inner(),
            _ => fresh.insert(CulledObjects::new(allocations, device, slots)),
        };
        let (groups, groups_x) = grid_64(slots);
        let frustum = Frustum::from_clip_from_relative(clip_from_relative);
        let words = cull_view_words(&frustum, &origin, slots, groups_x);
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        queue.write_buffer(&culled.view, 0, &bytes);
        if culled.bind_groups.as_ref().map(|b| b.0) != Some(objects.id()) {
            let layout = |l| pipeline_cache.get_bind_group_layout(l);
            let cull = allocations.bind_group(
                device,
                "penumbra_df_cull",
                &layout(&pipelines.cull_layout),
                &BindGroupEntries::with_indices((
                    (0, objects.as_entire_binding()),
                    (1, culled.view.as_entire_binding()),
                    (2, culled.list.as_entire_binding()),
                    (3, culled.count.as_entire_binding()),
                )),
            );
            let indirect = allocations.bind_group(
                device,
                "penumbra_df_indirect",
                &layout(&pipelines.indirect_layout),
                &BindGroupEntries::with_indices((
                    (3, culled.count.as_entire_binding()),
                    (4, culled.indirect.as_entire_binding()),
                )),
            );
            culled.bind_groups = Some((objects.id(), cull, indirect));
        }
        culled.groups = groups;
        if let Some(fresh) = fresh {
            commands.insert(fresh);
        }
    }

    /// Records the culling passes (the count cleared first). `false` when nothing was
    /// prepared this frame or the pipelines are compiling: the list is not valid.
    pub fn dispatch(
        &self,
        ctx: &mut RenderContext,
        pipelines: &DistanceFieldPipelines,
        pipeline_cache: &PipelineCache,
    ) -> bool {
        let (Some((_, cull_bind, indirect_bind)), Some(cull), Some(indirect)) = (
            &self.bind_groups,
            pipeline_cache.get_compute_pipeline(pipelines.cull),
            pipeline_cache.get_compute_pipeline(pipelines.indirect),
        ) else {
            return false;
        };
        if self.groups[0] == 0 {
            return false;
        }
        let encoder = ctx.command_encoder();
        encoder.clear_buffer(&self.count, 0, None);
        let mut pass = encoder.begin_compute_pass(&ComputePassDescriptor {
            label: Some("penumbra_df_cull"),
            timestamp_writes: None,
        });
        pass.set_pipeline(cull);
        pass.set_bind_group(0, cull_bind, &[]);
        pass.dispatch_workgroups(self.groups[0], self.groups[1], self.groups[2]);
        pass.set_pipeline(indirect);
        pass.set_bind_group(0, indirect_bind, &[]);
        pass.dispatch_workgroups(1, 1, 1);
        true
    }
}
