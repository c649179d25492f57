//! The caster spheres' pass of billboard reflections (`shaders/reflections/spheres.wgsl`):
//! once per frame and reflecting view with reflection shadows, each object slot's
//! camera-relative bounding sphere into a pooled buffer, read by the tile cull and the
//! trace (16 bytes and a compare per object where they tested the record and its
//! transform). Nothing without reflection shadows or distance-field objects.

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
use penumbra_cinematic_core::reflections::pass::ReflectionUniform;
use std::num::NonZeroU64;

/// Bytes of one sphere (`vec4<f32>`).
pub(super) const SPHERE_BYTES: u64 = 16;
/// Invocations per workgroup (`spheres.wgsl`).
const GROUP: u32 = 64;
/// Most workgroups along one dispatch dimension.
const MAX_GROUPS_X: u32 = 65_535;

/// The pass's layout and pipeline.
pub(super) struct SpheresPipeline {
    layout: BindGroupLayoutDescriptor,
    pipeline: CachedComputePipelineId,
}

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
                ),
            ),
        );
        let pipeline = pipeline_cache.queue_compute_pipeline(ComputePipelineDescriptor {
            label: Some("penumbra_reflection_spheres".into()),
            layout: vec![layout.clone()],
            shader,
            entry_point: Some("spheres_main".into()),
            ..default()
        });
        SpheresPipeline { layout, pipeline }
    }
}

/// A view's sphere buffer, its bind group and this frame's slot count.
pub(super) struct ViewCasterSpheres {
    pub(super) buffer: Buffer,
    /// Spheres the buffer holds.
    slots: u64,
    group: Option<(BindGroup, [BufferId; 3])>,
    /// Slots to write this frame (0: no pass).
    count: u32,
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
        }
    }

    /// Grows the buffer to `count` slots if needed and binds it with `uniform` and
    /// `objects`; `count` 0: no pass this frame.
    #[allow(clippy::too_many_arguments, reason = "the pass's inputs")]
    pub(super) fn prepare(
        &mut self,
        allocations: &PenumbraGpuAllocations,
        device: &RenderDevice,
        pipeline_cache: &PipelineCache,
        pipeline: &SpheresPipeline,
        uniform: &Buffer,
        objects: &Buffer,
        count: u32,
    ) {
        self.count = count;
        if count == 0 {
            return;
        }
        if self.slots < u64::from(count) {
            *self = ViewCasterSpheres::new(allocations, device, count);
            self.count = count;
        }
        let key = [uniform.id(), objects.id(), self.buffer.id()];
        if self.group.as_ref().map(|(_, k)| k) != Some(&key) {
            let group = allocations.bind_group(
                device,
                "penumbra_reflection_spheres_bind_group",
                &pipeline_cache.get_bind_group_layout(&pipeline.layout),
                &BindGroupEntries::sequential((
                    uniform.as_entire_binding(),
                    objects.as_entire_binding(),
                    self.buffer.as_entire_binding(),
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
        pipeline_cache
            .get_compute_pipeline(pipeline.pipeline)
            .map(|_| self.group.is_some())
    }

    /// Records the pass (when [`Self::ready`]).
    pub(super) fn dispatch(
        &self,
        encoder: &mut CommandEncoder,
        pipeline_cache: &PipelineCache,
        pipeline: &SpheresPipeline,
    ) {
        let (Some(compute), Some((group, _))) = (
            pipeline_cache.get_compute_pipeline(pipeline.pipeline),
            self.group.as_ref(),
        ) else {
            return;
        };
        if self.count == 0 {
            return;
        }
        let groups = self.count.div_ceil(GROUP);
        let x = groups.min(MAX_GROUPS_X);
        let mut pass = encoder.begin_compute_pass(&ComputePassDescriptor {
            label: Some("penumbra_reflection_spheres"),
            timestamp_writes: None,
        });
        pass.set_pipeline(compute);
        pass.set_bind_group(0, group, &[]);
        pass.dispatch_workgroups(x, groups.div_ceil(x), 1);
    }
}
