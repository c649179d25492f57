//! A 4× multisampled depth buffer and G-buffer with known contents, for contract tests
//! of the passes that read deferred MSAA's per-sample data: multisampled textures
//! cannot be copied into, so a render pass writes them, one fragment per sample (the
//! fragment shader reads `sample_index`), from a buffer of per-sample values.

use crate::GpuCompute;
use wgpu::util::DeviceExt;

/// One sample's contents.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MsSample {
    /// Reverse-Z depth (0: background).
    pub depth: f32,
    /// The G-buffer texel (Bevy's layout: the packed normal in `.a`).
    pub gbuffer: [u32; 4],
}

/// The textures [`multisampled_gbuffer`] and [`filled_gbuffer`] filled.
pub struct MsTextures {
    /// `Depth32Float`.
    pub depth: wgpu::Texture,
    /// `Rgba32Uint`.
    pub gbuffer: wgpu::Texture,
}

const FILL: &str = r#"
struct Sample { depth: f32, pad: u32, pad2: u32, pad3: u32, gbuffer: vec4<u32> }
@group(0) @binding(0) var<storage, read> samples: array<Sample>;
// x: width; y: samples per pixel.
@group(0) @binding(1) var<uniform> width: vec4<u32>;

@vertex
fn vertex(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

struct Out { @builtin(frag_depth) depth: f32, @location(0) gbuffer: vec4<u32> }

@fragment
fn fragment(@builtin(position) p: vec4<f32>, @builtin(sample_index) s: u32) -> Out {
    let pixel = vec2<u32>(p.xy);
    let v = samples[width.y * (pixel.y * width.x + pixel.x) + s];
    return Out(v.depth, v.gbuffer);
}
"#;

/// A `width × height` 4× depth buffer and G-buffer whose sample `s` of pixel `(x, y)`
/// holds `samples[4 · (y · width + x) + s]`. Both textures can be bound as textures.
pub fn multisampled_gbuffer(
    gpu: &GpuCompute,
    width: u32,
    height: u32,
    samples: &[MsSample],
) -> MsTextures {
    filled_gbuffer(gpu, width, height, 4, samples)
}

/// A `width × height` depth buffer and G-buffer with `sample_count` samples per pixel
/// (1 or 4), sample `s` of pixel `(x, y)` holding
/// `samples[sample_count · (y · width + x) + s]`: for single-sample passes that bind a
/// `texture_depth_2d` (depth textures take no copies either).
pub fn filled_gbuffer(
    gpu: &GpuCompute,
    width: u32,
    height: u32,
    sample_count: u32,
    samples: &[MsSample],
) -> MsTextures {
    assert_eq!(samples.len(), (sample_count * width * height) as usize);
    let device = &gpu.device;
    let texture = |label, format| {
        device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        })
    };
    let depth = texture("ms_depth", wgpu::TextureFormat::Depth32Float);
    let gbuffer = texture("ms_gbuffer", wgpu::TextureFormat::Rgba32Uint);
    let bytes: Vec<u8> = samples
        .iter()
        .flat_map(|s| {
            let mut words = [s.depth.to_bits(), 0, 0, 0, 0, 0, 0, 0];
            words[4..].copy_from_slice(&s.gbuffer);
            words.into_iter().flat_map(u32::to_le_bytes)
        })
        .collect();
    let buffer = gpu.buffer("ms_samples", &bytes, wgpu::BufferUsages::empty());
    let width_uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("ms_width"),
        contents: &[width, sample_count, 0, 0]
            .into_iter()
            .flat_map(u32::to_le_bytes)
            .collect::<Vec<_>>(),
        usage: wgpu::BufferUsages::UNIFORM,
    });
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("ms_fill"),
        source: wgpu::ShaderSource::Wgsl(FILL.into()),
    });
    let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("ms_fill"),
        layout: None,
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vertex"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: Default::default(),
        depth_stencil: Some(wgpu::DepthStencilState {
            format: wgpu::TextureFormat::Depth32Float,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Always),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: wgpu::MultisampleState {
            count: sample_count,
            ..Default::default()
        },
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fragment"),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format: wgpu::TextureFormat::Rgba32Uint,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    });
    let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("ms_fill"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: buffer.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: width_uniform.as_entire_binding(),
            },
        ],
    });
    let (depth_view, gbuffer_view) = (
        depth.create_view(&Default::default()),
        gbuffer.create_view(&Default::default()),
    );
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("ms_fill"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &gbuffer_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(0.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.draw(0..3, 0..1);
    }
    gpu.queue.submit([encoder.finish()]);
    MsTextures { depth, gbuffer }
}
