//! Penumbra's WGSL library as Bevy shader assets.

use bevy::prelude::*;
use bevy::render::RenderApp;

/// Strong handles keeping Penumbra's shader library (`penumbra_shaders::SHADERS`)
/// loaded, so `#import penumbra::…` resolves in every Penumbra pipeline. Present in the
/// main and the render world.
#[derive(Resource, Reflect, Debug, Default, Clone)]
#[reflect(Resource, Clone, Default)]
pub struct PenumbraShaderLibrary {
    /// One handle per `penumbra_shaders::SHADERS` entry, in the same order.
    pub handles: Vec<Handle<Shader>>,
}

impl PenumbraShaderLibrary {
    /// The handle of the library file at `path` (relative to `shaders/`, e.g.
    /// `df/cull.wgsl`). Panics on an unknown path: paths are compile-time constants of
    /// this crate, checked by its tests.
    pub fn handle(&self, path: &str) -> Handle<Shader> {
        let index = penumbra_shaders::SHADERS
            .iter()
            .position(|s| s.path == path)
            .unwrap_or_else(|| panic!("no Penumbra shader {path}"));
        self.handles[index].clone()
    }
}

impl PenumbraShaderLibrary {
    /// Queues the compute pipeline running `entry` of library file `path` with one bind
    /// group `layout`.
    pub fn queue_compute(
        &self,
        pipeline_cache: &bevy::render::render_resource::PipelineCache,
        label: &'static str,
        layout: &bevy::render::render_resource::BindGroupLayoutDescriptor,
        path: &str,
        entry: &'static str,
    ) -> bevy::render::render_resource::CachedComputePipelineId {
        self.queue_compute_layouts(
            pipeline_cache,
            label,
            std::slice::from_ref(layout),
            path,
            entry,
        )
    }

    /// [`Self::queue_compute`] with bind groups `0..` of `layouts`.
    pub fn queue_compute_layouts(
        &self,
        pipeline_cache: &bevy::render::render_resource::PipelineCache,
        label: &'static str,
        layouts: &[bevy::render::render_resource::BindGroupLayoutDescriptor],
        path: &str,
        entry: &'static str,
    ) -> bevy::render::render_resource::CachedComputePipelineId {
        pipeline_cache.queue_compute_pipeline(
            bevy::render::render_resource::ComputePipelineDescriptor {
                label: Some(label.into()),
                layout: layouts.to_vec(),
                shader: self.handle(path),
                entry_point: Some(entry.into()),
                ..default()
            },
        )
    }
}

/// A placeholder texture of `size` texels (bound where a pass's input does not exist yet).
fn placeholder(
    device: &bevy::render::renderer::RenderDevice,
    label: &'static str,
    size: bevy::render::render_resource::Extent3d,
    dimension: bevy::render::render_resource::TextureDimension,
    format: bevy::render::render_resource::TextureFormat,
) -> bevy::render::render_resource::TextureView {
    use bevy::render::render_resource::{TextureDescriptor, TextureUsages, TextureViewDescriptor};
    device
        .create_texture(&TextureDescriptor {
            label: Some(label),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension,
            format,
            usage: TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        })
        .create_view(&TextureViewDescriptor::default())
}

/// An empty 3D `R16Float` texture (2×2×2), bound as the atlas where no SDF volume exists
/// (analytic casters only).
pub fn empty_atlas(
    device: &bevy::render::renderer::RenderDevice,
) -> bevy::render::render_resource::TextureView {
    use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
    let size = Extent3d {
        width: 2,
        height: 2,
        depth_or_array_layers: 2,
    };
    let (d3, r16) = (TextureDimension::D3, TextureFormat::R16Float);
    placeholder(device, "penumbra_df_empty_atlas", size, d3, r16)
}

/// A 1×1 `R32Uint` brick table for passes bound before any volume is placed as bricks
/// (no record reads it then).
pub fn empty_brick_table(
    device: &bevy::render::renderer::RenderDevice,
) -> bevy::render::render_resource::TextureView {
    use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
    let (d2, r32) = (TextureDimension::D2, TextureFormat::R32Uint);
    placeholder(
        device,
        "penumbra_df_empty_brick_table",
        Extent3d::default(),
        d2,
        r32,
    )
}

/// Registers the shader library once (idempotent) and mirrors it into the render world,
/// with the GPU allocation counters (`gpu_allocations`). Cost: one small asset per
/// module at startup; nothing per frame.
pub fn register_shader_library(app: &mut App) {
    crate::gpu_allocations::register_gpu_allocations(app);
    if !app.world().contains_resource::<PenumbraShaderLibrary>() {
        let Some(mut shaders) = app.world_mut().get_resource_mut::<Assets<Shader>>() else {
            warn!(
                "Penumbra: no `Assets<Shader>` (add DefaultPlugins first); Penumbra's shaders are not registered"
            );
            return;
        };
        let handles = penumbra_shaders::SHADERS
            .iter()
            .map(|s| shaders.add(Shader::from_wgsl(s.source, format!("penumbra/{}", s.path))))
            .collect();
        app.insert_resource(PenumbraShaderLibrary { handles })
            .register_type::<PenumbraShaderLibrary>();
    }
    let library = app.world().resource::<PenumbraShaderLibrary>().clone();
    if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
        render_app.insert_resource(library);
    }
}
