//! The shadow mask pass's bind group layouts, and deferred MSAA's per-sample variant
//! of the pass with its multisampled inputs. Part of `shadow_passes.rs`.

use super::{HEIGHT, WIDTH};
use penumbra_shaders::flatten_with_defs;
use penumbra_test::GpuCompute;
use penumbra_test::multisample::{MsSample, MsTextures, multisampled_gbuffer};
use penumbra_test::wgpu;

pub fn storage_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    buffer_entry(
        binding,
        wgpu::BufferBindingType::Storage { read_only: true },
    )
}

pub fn uniform_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    buffer_entry(binding, wgpu::BufferBindingType::Uniform)
}

pub fn buffer_entry(binding: u32, ty: wgpu::BufferBindingType) -> wgpu::BindGroupLayoutEntry {
    layout_entry(
        binding,
        wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
    )
}

pub fn texture_entry(
    binding: u32,
    sample_type: wgpu::TextureSampleType,
    view_dimension: wgpu::TextureViewDimension,
    multisampled: bool,
) -> wgpu::BindGroupLayoutEntry {
    layout_entry(
        binding,
        wgpu::BindingType::Texture {
            sample_type,
            view_dimension,
            multisampled,
        },
    )
}

/// An unfilterable float texture.
pub fn float_entry(binding: u32, dim: wgpu::TextureViewDimension) -> wgpu::BindGroupLayoutEntry {
    let float = wgpu::TextureSampleType::Float { filterable: false };
    texture_entry(binding, float, dim, false)
}

/// The `R32Float` mask written.
pub fn mask_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    layout_entry(
        binding,
        wgpu::BindingType::StorageTexture {
            access: wgpu::StorageTextureAccess::WriteOnly,
            format: wgpu::TextureFormat::R32Float,
            view_dimension: wgpu::TextureViewDimension::D2,
        },
    )
}

pub fn layout_entry(binding: u32, ty: wgpu::BindingType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty,
        count: None,
    }
}

/// The mask pass's layout; `samples`: deferred MSAA's per-sample variant
/// (`PENUMBRA_SAMPLE_TRACE`: multisampled depth and G-buffer, the pixel classes).
pub fn trace_layout(gpu: &GpuCompute, samples: bool) -> wgpu::BindGroupLayout {
    use wgpu::{TextureSampleType as T, TextureViewDimension as D};
    let mut entries = vec![
        storage_entry(0),
        storage_entry(1),
        storage_entry(2),
        float_entry(3, D::D3),
        uniform_entry(5),
        uniform_entry(6),
        mask_entry(7),
        storage_entry(8),
        storage_entry(9),
        storage_entry(10),
        uniform_entry(11),
        storage_entry(13),
        float_entry(14, D::D2),
    ];
    if samples {
        entries.extend([
            texture_entry(4, T::Depth, D::D2, true),
            texture_entry(12, T::Uint, D::D2, true),
            texture_entry(15, T::Uint, D::D2, false),
            texture_entry(16, T::Uint, D::D2, false),
        ]);
    } else {
        entries.extend([
            float_entry(4, D::D2),
            texture_entry(12, T::Uint, D::D2, false),
            texture_entry(15, T::Uint, D::D2, false),
            float_entry(16, D::D2),
            float_entry(17, D::D2),
        ]);
    }
    gpu.device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("shadow_trace"),
            entries: &entries,
        })
}

/// Deferred MSAA's per-sample mask pass (`PENUMBRA_SAMPLE_TRACE`) and the view's
/// multisampled inputs, for [`MaskOptions::samples`].
pub struct SampleTrace {
    pub pipeline: wgpu::ComputePipeline,
    pub layout: wgpu::BindGroupLayout,
    pub ms: MsTextures,
    /// `R8Uint` pixel classes (2: shaded per sample).
    pub class: wgpu::Texture,
}

/// Written into the per-sample mask first: what the pass must leave alone.
pub const UNWRITTEN: f32 = -4.0;

pub fn sample_trace(gpu: &GpuCompute, samples: &[MsSample], class: &[u8]) -> SampleTrace {
    let layout = trace_layout(gpu, true);
    let source = flatten_with_defs(
        "#import penumbra::df::shadow_trace\n",
        &["PENUMBRA_SAMPLE_TRACE"],
    )
    .expect("flattens");
    SampleTrace {
        pipeline: gpu.pipeline_with_layouts(&source, "trace", &[&layout]),
        layout,
        ms: multisampled_gbuffer(gpu, WIDTH, HEIGHT, samples),
        class: gpu.texture(
            "class",
            wgpu::Extent3d {
                width: WIDTH,
                height: HEIGHT,
                depth_or_array_layers: 1,
            },
            wgpu::TextureDimension::D2,
            wgpu::TextureFormat::R8Uint,
            1,
            class,
        ),
    }
}
