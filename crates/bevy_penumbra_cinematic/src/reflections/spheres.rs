//! The caster spheres' pass of billboard reflections (`shaders/reflections/spheres.wgsl`):
//! once per frame and reflecting view with reflection shadows, each object slot's
//! camera-relative bounding sphere into a pooled buffer, read by the tile cull and the
//! trace (16 bytes and a compare per object where they tested the record and its
//! transform). Nothing without reflection shadows or distance-field objects.
//!
//! With more casters than a tile's list holds, the caster grid follows
//! (`penumbra_cinematic_core::reflections::grid`): its header and counts cleared, then
//! three more dispatches (count, a one-workgroup scan, fill) in the same compute pass,
//! into the view's list buffer after the tiles' records.

use bevy::prelude::*;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, storage_buffer_sized, uniform_buffer_sized,
};
use bevy::render::render_resource::{
    BindGroup, BindGroupEntries, BindGroupLayoutDescriptor, BindGroupLayoutEntries, Buffer,
    BufferId, BufferUsages, CachedComputePipelineId, CommandEncoder, ComputePassDescriptor,
    ComputePipelineDescriptor, PipelineCache, ShaderStages, ShaderType,
};
use bevy::render::renderer::RenderDevice;
use bevy_penumbra_df::PenumbraGpuAllocations;
use penumbra_cinematic_core::reflections::grid::{GRID_CELLS, GRID_HEADER_WORDS};
use penumbra_cinematic_core::reflections::pass::ReflectionUniform;
use std::num::NonZeroU64;

/// Bytes of one sphere (`vec4<f32>`).
pub(super) const SPHERE_BYTES: u64 = 16;
/// Invocations per workgroup (`spheres.wgsl`).
const GROUP: u32 = 64;
/// Most workgroups along one dispatch dimension.
const MAX_GROUPS_X: u32 = 65_535;

/// The pass's layout and pipelines: the spheres, then the grid's count, scan and fill.
pub(super) struct SpheresPipeline {
    layout: BindGroupLayoutDescriptor,
    pipelines: [CachedComputePipelineId; 4],
}

/// The entry points, in dispatch order.
const ENTRY_POINTS: [&str; 4] = ["spheres_main", "grid_count", "grid_scan", "grid_fill"];

impl SpheresPipeline {
    /// Queues the pipeline.
    pub(super) fn new(pipeline_cache: &PipelineCache, shader: Handle<Shader>) -> Self {
        let layout = BindGroupLayoutDescriptor::new(
            "penumbra_reflection_spheres_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (
                    uniform_buffer_sized(false, Some(ReflectionUniform::min_size())),
                    storage_buffer_read_only_sized(
                        false,
                        NonZeroU64::new(super::render::OBJECT_BYTES),
                    ),
                    storage_buffer_sized(false, NonZeroU64::new(SPHERE_BYTES)),
                    storage_buffer_sized(false, NonZeroU64::new(4)),
                ),
            ),
        );
        let pipelines = ENTRY_POINTS.map(|entry| {
            pipeline_cache.queue_compute_pipeline(ComputePipelineDescriptor {
                label: Some(format!("penumbra_reflection_{entry}").into()),
                layout: vec![layout.clone()],
                shader: shader.clone(),
                entry_point: Some(entry.into()),
                ..default()
            })
        });
        SpheresPipeline { layout, pipelines }
    }
}

/// A view's sphere buffer, its bind group and this frame's slot count.
pub(super) struct ViewCasterSpheres {
    pub(super) buffer: Buffer,
    /// Spheres the buffer holds.
    slots: u64,
    group: Option<(BindGroup, [BufferId; 4])>,
    /// Slots to write this frame (0: no pass).
    count: u32,
    /// This frame's caster grid: the list buffer and the bytes to clear (its header and
    /// counts) from where it starts.
    grid: Option<(Buffer, u64, u64)>,
}

impl ViewCasterSpheres {
    /// A buffer for `slots` spheres (at least one).
    pub(super) fn new(
        allocations: &PenumbraGpuAllocations,
        device: &RenderDevice,
        slots: u32,
    ) -> Self {
        let slots = u64::from(slots).next_power_of_two().max(1);
        ViewCasterSpheres {
            buffer: allocations.sized_buffer(
                device,
                "penumbra_reflection_spheres",
                slots * SPHERE_BYTES,
                BufferUsages::STORAGE,
            ),
            slots,
            group: None,
            count: 0,
            grid: None,
        }
    }

    /// Grows the buffer to `count` slots if needed and binds it with `uniform`,
    /// `objects` and the view's `lists`; `count` 0: no pass this frame. `grid`: where the
    /// caster grid starts in `lists`, words (`None`: no grid this frame).
    #[allow(clippy::too_many_arguments, reason = "the pass's inputs")]
    pub(super) fn prepare(
        &mut self,
        allocations: &PenumbraGpuAllocations,
        device: &RenderDevice,
        pipeline_cache: &PipelineCache,
        pipeline: &SpheresPipeline,
        (uniform, objects, lists): (&Buffer, &Buffer, &Buffer),
        count: u32,
        grid: Option<u32>,
    ) {
        self.count = count;
        self.grid = grid.filter(|_| count > 0).map(|start| {
            let cleared = u64::from(GRID_HEADER_WORDS + GRID_CELLS) * 4;
            (lists.clone(), u64::from(start) * 4, cleared)
        });
        if count == 0 {
            return;
        }
        if self.slots < u64::from(count) {
            *self = ViewCasterSpheres::new(allocations, device, count);
            self.count = count;
        }
        let key = [uniform.id(), objects.id(), self.buffer.id(), lists.id()];
        if self.group.as_ref().map(|(_, k)| k) != Some(&key) {
            let group = allocations.bind_group(
                device,
                "penumbra_reflection_spheres_bind_group",
                &pipeline_cache.get_bind_group_layout(&pipeline.layout),
                &BindGroupEntries::sequential((
                    uniform.as_entire_binding(),
                    objects.as_entire_binding(),
                    self.buffer.as_entire_binding(),
                    lists.as_entire_binding(),
                )),
            );
            self.group = Some((group, key));
        }
    }

    /// Whether the pass can run this frame: `Some(false)` nothing to do, `None` its
    /// pipeline is compiling.
    pub(super) fn ready(
        &self,
        pipeline_cache: &PipelineCache,
        pipeline: &SpheresPipeline,
    ) -> Option<bool> {
        if self.count == 0 {
            return Some(false);
        }
        let compiled = pipeline
            .pipelines
            .iter()
            .all(|id| pipeline_cache.get_compute_pipeline(*id).is_some());
        compiled.then_some(self.group.is_some())
    }

    /// Records the pass and, with a grid, the grid's (when [`Self::ready`]).
    pub(super) fn dispatch(
        &self,
        encoder: &mut CommandEncoder,
        pipeline_cache: &PipelineCache,
        pipeline: &SpheresPipeline,
    ) {
        let Some((group, _)) = self.group.as_ref() else {
            return;
        };
        let [Some(spheres), Some(count), Some(scan), Some(fill)] = pipeline
            .pipelines
            .map(|id| pipeline_cache.get_compute_pipeline(id))
        else {
            return;
        };
        if self.count == 0 {
            return;
        }
        if let Some((lists, offset, bytes)) = &self.grid {
            encoder.clear_buffer(lists, *offset, Some(*bytes));
        }
        let groups = self.count.div_ceil(GROUP);
        let x = groups.min(MAX_GROUPS_X);
        let y = groups.div_ceil(x);
        let mut pass = encoder.begin_compute_pass(&ComputePassDescriptor {
            label: Some("penumbra_reflection_spheres"),
            timestamp_writes: None,
        });
        pass.set_bind_group(0, group, &[]);
        pass.set_pipeline(spheres);
        pass.dispatch_workgroups(x, y, 1);
        if self.grid.is_some() {
            pass.set_pipeline(count);
            pass.dispatch_workgroups(x, y, 1);
            pass.set_pipeline(scan);
            pass.dispatch_workgroups(1, 1, 1);
            pass.set_pipeline(fill);
            pass.dispatch_workgroups(x, y, 1);
        }
    }
}
