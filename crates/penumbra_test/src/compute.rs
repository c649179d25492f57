//! A bare wgpu device on the Vulkan adapter (lavapipe in CI) for *contract tests*:
//! dispatch one of Penumbra's compute shaders on known input, read the result back,
//! compare with the CPU reference. No Bevy app, no render graph: the shader and the
//! data are the whole test.

use wgpu::util::DeviceExt;

/// A device and its queue.
pub struct GpuCompute {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
}

impl GpuCompute {
    /// A device on the first Vulkan adapter with that adapter's own limits, or `None`
    /// without one (use with [`crate::gpu_or_skip`]).
    pub fn new() -> Option<GpuCompute> {
        Self::with_features(wgpu::Features::empty())
    }

    /// As [`Self::new`], also requiring `features`; `None` where the adapter lacks them.
    pub fn with_features(features: wgpu::Features) -> Option<GpuCompute> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends: wgpu::Backends::VULKAN,
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        });
        let adapter =
            bevy::tasks::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                force_fallback_adapter: false,
                compatible_surface: None,
            }))
            .ok()?;
        if !adapter.features().contains(features) {
            return None;
        }
        let (device, queue) =
            bevy::tasks::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
                label: Some("penumbra_test_compute"),
                // Multisampled `Rgba32Uint` (Bevy's G-buffer, as Penumbra's deferred
                // MSAA renders it) needs the adapter's own format features; the bokeh
                // layers blend `Rgba32Float`.
                required_features: features
                    | adapter.features()
                        & (wgpu::Features::TEXTURE_ADAPTER_SPECIFIC_FORMAT_FEATURES
                            | wgpu::Features::FLOAT32_BLENDABLE),
                required_limits: adapter.limits(),
                experimental_features: wgpu::ExperimentalFeatures::disabled(),
                memory_hints: wgpu::MemoryHints::Performance,
                trace: wgpu::Trace::Off,
            }))
            .ok()?;
        Some(GpuCompute { device, queue })
    }

    /// A compute pipeline (layout from the shader) for `entry` in WGSL `source`.
    pub fn pipeline(&self, source: &str, entry: &str) -> wgpu::ComputePipeline {
        let module = self
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(entry),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            });
        self.device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: None,
                module: &module,
                entry_point: Some(entry),
                compilation_options: bevy_like_compilation(),
                cache: None,
            })
    }

    /// A compute pipeline for `entry` with explicit bind group layouts (needed where the
    /// derived layout would not fit, e.g. unfilterable float textures).
    pub fn pipeline_with_layouts(
        &self,
        source: &str,
        entry: &str,
        layouts: &[&wgpu::BindGroupLayout],
    ) -> wgpu::ComputePipeline {
        let module = self
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(entry),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            });
        let layout = self
            .device
            .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(entry),
                bind_group_layouts: &layouts.iter().map(|l| Some(*l)).collect::<Vec<_>>(),
                immediate_size: 0,
            });
        self.device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: bevy_like_compilation(),
                cache: None,
            })
    }

    /// A texture holding tightly packed `data` (`bytes_per_texel` each, rows along x),
    /// usable as a texture binding, storage texture and copy source/destination.
    pub fn texture(
        &self,
        label: &str,
        size: wgpu::Extent3d,
        dimension: wgpu::TextureDimension,
        format: wgpu::TextureFormat,
        bytes_per_texel: u32,
        data: &[u8],
    ) -> wgpu::Texture {
        let usage = wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC
            | wgpu::TextureUsages::COPY_DST
            | if matches!(
                format,
                wgpu::TextureFormat::R32Float | wgpu::TextureFormat::Rgba16Float
            ) {
                wgpu::TextureUsages::STORAGE_BINDING
            } else {
                wgpu::TextureUsages::empty()
            };
        let texture = self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension,
            format,
            usage,
            view_formats: &[],
        });
        if !data.is_empty() {
            self.queue.write_texture(
                texture.as_image_copy(),
                data,
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(size.width * bytes_per_texel),
                    rows_per_image: Some(size.height),
                },
                size,
            );
        }
        texture
    }

    /// Reads a 2D texture back as tightly packed rows.
    pub fn read_texture_2d(&self, texture: &wgpu::Texture) -> Vec<u8> {
        let (width, height) = (texture.width(), texture.height());
        let texel = texture.format().block_copy_size(None).unwrap_or(4);
        let row = width * texel;
        let padded = row.next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("penumbra_test_texture_readback"),
            size: (padded * height) as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_texture_to_buffer(
            texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded),
                    rows_per_image: Some(height),
                },
            },
            texture.size(),
        );
        self.queue.submit([encoder.finish()]);
        let slice = buffer.slice(..);
        slice.map_async(wgpu::MapMode::Read, |r| r.expect("map readback buffer"));
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .expect("device poll");
        let mapped = slice.get_mapped_range();
        let mut out = Vec::with_capacity((row * height) as usize);
        for y in 0..height {
            let start = (y * padded) as usize;
            out.extend_from_slice(&mapped[start..start + row as usize]);
        }
        out
    }

    /// A buffer initialised with `bytes` (padded to 4 bytes, at least 16), usable as a
    /// storage buffer, copy source and destination, plus `extra` usages.
    pub fn buffer(&self, label: &str, bytes: &[u8], extra: wgpu::BufferUsages) -> wgpu::Buffer {
        let mut data = bytes.to_vec();
        data.resize(data.len().next_multiple_of(4).max(16), 0);
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: &data,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST
                    | extra,
            })
    }

    /// A zeroed storage buffer of `size` bytes (rounded up to 16).
    pub fn zeroed(&self, label: &str, size: u64, extra: wgpu::BufferUsages) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: size.next_multiple_of(16).max(16),
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST
                | extra,
            mapped_at_creation: false,
        })
    }

    /// A bind group of `pipeline`'s group 0 from `(binding, buffer)` pairs (a layout
    /// derived from the shader holds only the bindings its entry point uses).
    pub fn bind(
        &self,
        pipeline: &wgpu::ComputePipeline,
        buffers: &[(u32, &wgpu::Buffer)],
    ) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .map(|(binding, b)| wgpu::BindGroupEntry {
                binding: *binding,
                resource: b.as_entire_binding(),
            })
            .collect();
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipeline.get_bind_group_layout(0),
            entries: &entries,
        })
    }

    /// Records and submits one dispatch of `workgroups`.
    pub fn dispatch(
        &self,
        pipeline: &wgpu::ComputePipeline,
        bind: &wgpu::BindGroup,
        workgroups: [u32; 3],
    ) {
        let mut encoder = self.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, bind, &[]);
            pass.dispatch_workgroups(workgroups[0], workgroups[1], workgroups[2]);
        }
        self.queue.submit([encoder.finish()]);
    }

    /// Records and submits one dispatch of `workgroups` with bind groups `0..`.
    pub fn dispatch_groups(
        &self,
        pipeline: &wgpu::ComputePipeline,
        groups: &[&wgpu::BindGroup],
        workgroups: [u32; 3],
    ) {
        let mut encoder = self.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(pipeline);
            for (i, g) in groups.iter().enumerate() {
                pass.set_bind_group(i as u32, *g, &[]);
            }
            pass.dispatch_workgroups(workgroups[0], workgroups[1], workgroups[2]);
        }
        self.queue.submit([encoder.finish()]);
    }

    /// Waits for the queue and copies `buffer`'s first `size` bytes back.
    pub fn read(&self, buffer: &wgpu::Buffer, size: u64) -> Vec<u8> {
        let size = size.next_multiple_of(4);
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("penumbra_test_readback"),
            size: size.max(4),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, size.max(4));
        self.queue.submit([encoder.finish()]);
        let slice = staging.slice(..);
        slice.map_async(wgpu::MapMode::Read, |r| r.expect("map readback buffer"));
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .expect("device poll");
        let out = slice.get_mapped_range().to_vec();
        staging.unmap();
        out[..size as usize].to_vec()
    }

    /// Waits until all submitted work is done (for timing).
    pub fn wait(&self) {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .expect("device poll");
    }
}

/// Compilation options as Bevy's `PipelineCache` uses them: workgroup memory is **not**
/// zero-initialized (`ComputePipelineDescriptor::zero_initialize_workgroup_memory`
/// defaults to `false` there), so contract tests see the same uninitialized workgroup
/// memory as the plugin's passes. (A shader that relied on WGSL's zero-initialization
/// passed here under wgpu's default and crashed lavapipe inside Bevy.)
fn bevy_like_compilation() -> wgpu::PipelineCompilationOptions<'static> {
    wgpu::PipelineCompilationOptions {
        zero_initialize_workgroup_memory: false,
        ..Default::default()
    }
}

/// `value` laid out as a WGSL uniform (`encase`).
pub fn uniform_bytes<T>(value: &T) -> Vec<u8>
where
    T: bevy::render::render_resource::ShaderType
        + bevy::render::render_resource::encase::internal::WriteInto,
{
    let mut bytes = bevy::render::render_resource::encase::UniformBuffer::new(Vec::new());
    bytes.write(value).expect("a uniform encodes");
    bytes.into_inner()
}

/// `value` laid out as a WGSL storage buffer (`encase`).
pub fn storage_bytes<T>(value: &T) -> Vec<u8>
where
    T: bevy::render::render_resource::ShaderType
        + bevy::render::render_resource::encase::internal::WriteInto,
{
    let mut bytes = bevy::render::render_resource::encase::StorageBuffer::new(Vec::new());
    bytes.write(value).expect("a storage value encodes");
    bytes.into_inner()
}
