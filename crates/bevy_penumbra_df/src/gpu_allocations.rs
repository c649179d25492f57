//! [`PenumbraGpuAllocations`]: running counts of the GPU resources Penumbra creates.
//!
//! Penumbra pools its GPU resources: buffers, textures and bind groups are created when
//! a scene, a view or a light appears, or when the scene outgrows them, and reused
//! otherwise. These counters make that checkable (a steady frame adds nothing; tests
//! assert it) and visible when profiling. The resource is shared by the main and the
//! render world, so main-world code can read what the render world created.

use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::render_resource::{
    BindGroup, BindGroupEntry, BindGroupLayout, Buffer, BufferDescriptor, BufferUsages, Texture,
    TextureDescriptor,
};
use bevy::render::renderer::RenderDevice;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// Counts of the GPU resources Penumbra has created since startup (present in the main
/// and the render world; both share the counters).
#[derive(Resource, Reflect, Clone, Debug, Default)]
#[reflect(Resource, Clone)]
pub struct PenumbraGpuAllocations(#[reflect(ignore)] Arc<Counters>);

#[derive(Debug, Default)]
struct Counters {
    buffers: AtomicU64,
    buffer_bytes: AtomicU64,
    textures: AtomicU64,
    bind_groups: AtomicU64,
}

/// A snapshot of [`PenumbraGpuAllocations`]; subtract two for a frame's.
#[derive(Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Clone, Default)]
pub struct GpuAllocationCounts {
    /// Buffers created.
    pub buffers: u64,
    /// Their total size, bytes.
    pub buffer_bytes: u64,
    /// Textures created.
    pub textures: u64,
    /// Bind groups created.
    pub bind_groups: u64,
}

impl std::ops::Sub for GpuAllocationCounts {
    type Output = GpuAllocationCounts;
    fn sub(self, rhs: Self) -> Self {
        GpuAllocationCounts {
            buffers: self.buffers - rhs.buffers,
            buffer_bytes: self.buffer_bytes - rhs.buffer_bytes,
            textures: self.textures - rhs.textures,
            bind_groups: self.bind_groups - rhs.bind_groups,
        }
    }
}

impl PenumbraGpuAllocations {
    /// The counts so far.
    pub fn counts(&self) -> GpuAllocationCounts {
        let c = &self.0;
        GpuAllocationCounts {
            buffers: c.buffers.load(Ordering::Relaxed),
            buffer_bytes: c.buffer_bytes.load(Ordering::Relaxed),
            textures: c.textures.load(Ordering::Relaxed),
            bind_groups: c.bind_groups.load(Ordering::Relaxed),
        }
    }

    fn count_buffer(&self, size: u64) {
        self.0.buffers.fetch_add(1, Ordering::Relaxed);
        self.0.buffer_bytes.fetch_add(size, Ordering::Relaxed);
    }

    /// Creates (and counts) a buffer.
    pub fn buffer(&self, device: &RenderDevice, desc: &BufferDescriptor) -> Buffer {
        self.count_buffer(desc.size);
        device.create_buffer(desc)
    }

    /// Creates (and counts) an unmapped buffer of `size` bytes.
    pub fn sized_buffer(
        &self,
        device: &RenderDevice,
        label: &'static str,
        size: u64,
        usage: BufferUsages,
    ) -> Buffer {
        self.buffer(
            device,
            &BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: false,
            },
        )
    }

    /// Creates (and counts) a texture.
    pub fn texture(&self, device: &RenderDevice, desc: &TextureDescriptor) -> Texture {
        self.0.textures.fetch_add(1, Ordering::Relaxed);
        device.create_texture(desc)
    }

    /// Creates (and counts) a bind group.
    pub fn bind_group(
        &self,
        device: &RenderDevice,
        label: &'static str,
        layout: &BindGroupLayout,
        entries: &[BindGroupEntry<'_>],
    ) -> BindGroup {
        self.0.bind_groups.fetch_add(1, Ordering::Relaxed);
        device.create_bind_group(label, layout, entries)
    }
}

/// Inserts the counters in the main world and shares them with the render world (once;
/// every Penumbra plugin calls it).
pub fn register_gpu_allocations(app: &mut App) {
    if !app.world().contains_resource::<PenumbraGpuAllocations>() {
        app.init_resource::<PenumbraGpuAllocations>()
            .register_type::<PenumbraGpuAllocations>();
    }
    let shared = app.world().resource::<PenumbraGpuAllocations>().clone();
    if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
        render_app.insert_resource(shared);
    }
}
