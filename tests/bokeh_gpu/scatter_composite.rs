//! The scatter pass (`dof/scatter.wgsl`) and the composite pass (`dof/composite.wgsl`)
//! against the model (part of `bokeh_gpu.rs`, which holds the image, the lens and the
//! sprite pass they start from).

use super::*;

/// The scatter pass's layers for `sprites` (`(Σ colour · v, Σ v)` per texel, f32).
fn scatter_on_gpu(
    gpu: &GpuCompute,
    sprites: &[Sprite],
    aperture: &Aperture,
    view: &BokehView,
) -> Layers {
    let device = &gpu.device;
    let size = view.half_size;
    // The list layer by layer, as the compaction leaves it, and the layers' draws.
    let (sprites, first) = by_layer(sprites, view.quarter_diameter);
    let ends = [first[1], first[2], first[3], sprites.len()];
    let draws: Vec<u8> = (0..4)
        .flat_map(|l| [4, (ends[l] - first[l]) as u32, 0, 0])
        .chain(first.map(|f| f as u32))
        .flat_map(u32::to_le_bytes)
        .collect();
    let layer_draws = gpu.buffer("layer_draws", &draws, wgpu::BufferUsages::empty());
    let words: Vec<u8> = sprites
        .iter()
        .flat_map(|s| {
            [
                s.center.x, s.center.y, s.diameter, s.weight, s.color.x, s.color.y, s.color.z,
            ]
            .into_iter()
            .chain([if s.near { 1.0 } else { 0.0 }])
        })
        .flat_map(f32::to_le_bytes)
        .collect();
    let sprite_buffer = gpu.buffer("sprites", &words, wgpu::BufferUsages::empty());
    let uniform = gpu.buffer("view", &uniform_bytes(view), wgpu::BufferUsages::UNIFORM);
    let norm: Vec<u8> = aperture
        .norm_words()
        .into_iter()
        .flat_map(f32::to_le_bytes)
        .collect();
    let info = gpu.buffer("aperture_norm", &norm, wgpu::BufferUsages::empty());
    let n = aperture.size();
    let texels: Vec<u8> = aperture
        .weights()
        .iter()
        .flat_map(|&w| half_bits(w).to_le_bytes())
        .collect();
    let aperture_texture = gpu.texture(
        "aperture",
        wgpu::Extent3d {
            width: n,
            height: n,
            depth_or_array_layers: 1,
        },
        wgpu::TextureDimension::D2,
        wgpu::TextureFormat::R16Float,
        2,
        &texels,
    );
    let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        ..Default::default()
    });
    let quarter_size = view.quarter_size;
    let target = |(label, quarter): (&str, bool)| {
        let size = if quarter { quarter_size } else { size };
        device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width: size.x,
                height: size.y,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba32Float,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        })
    };
    // One draw per layer, as the plugin's: near (`NEAR_LAYER`), then far, at half then at
    // quarter resolution (`QUARTER_LAYER`).
    let layers = [
        ("near", false, &["NEAR_LAYER"][..]),
        ("far", false, &[][..]),
        ("near_quarter", true, &["NEAR_LAYER", "QUARTER_LAYER"][..]),
        ("far_quarter", true, &["QUARTER_LAYER"][..]),
    ];
    let targets = layers.map(|(label, quarter, _)| target((label, quarter)));
    let modules = layers.map(|(_, _, defs)| {
        device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("bokeh_scatter"),
            source: wgpu::ShaderSource::Wgsl(
                flatten_with_defs("#import penumbra::dof::scatter\n", defs)
                    .expect("flattens")
                    .into(),
            ),
        })
    });
    let additive = wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::One,
        dst_factor: wgpu::BlendFactor::One,
        operation: wgpu::BlendOperation::Add,
    };
    let layer_target = Some(wgpu::ColorTargetState {
        format: wgpu::TextureFormat::Rgba32Float,
        blend: Some(wgpu::BlendState {
            color: additive,
            alpha: additive,
        }),
        write_mask: wgpu::ColorWrites::ALL,
    });
    let pipelines = modules.each_ref().map(|module| {
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("bokeh_scatter"),
            layout: None,
            vertex: wgpu::VertexState {
                module,
                entry_point: Some("vertex"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleStrip,
                ..Default::default()
            },
            depth_stencil: None,
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module,
                entry_point: Some("fragment"),
                compilation_options: Default::default(),
                targets: std::slice::from_ref(&layer_target),
            }),
            multiview_mask: None,
            cache: None,
        })
    });
    let aperture_view = aperture_texture.create_view(&Default::default());
    let bind = |pipeline: &wgpu::RenderPipeline| {
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("bokeh_scatter"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: uniform.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: sprite_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(&aperture_view),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: wgpu::BindingResource::Sampler(&sampler),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: info.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 5,
                    resource: layer_draws.as_entire_binding(),
                },
            ],
        })
    };
    let views = targets
        .each_ref()
        .map(|t| t.create_view(&Default::default()));
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let attachment = |view| {
            Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })
        };
        for (l, (pipeline, view)) in pipelines.iter().zip(&views).enumerate() {
            let group = bind(pipeline);
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("bokeh_scatter"),
                color_attachments: &[attachment(view)],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.draw(0..4, 0..(ends[l] - first[l]) as u32);
        }
    }
    gpu.queue.submit([encoder.finish()]);
    let read = |t: &wgpu::Texture| -> Vec<Vec4> {
        gpu.read_texture_2d(t)
            .chunks_exact(16)
            .map(|c| {
                let f = |i: usize| {
                    f32::from_le_bytes([c[4 * i], c[4 * i + 1], c[4 * i + 2], c[4 * i + 3]])
                };
                Vec4::new(f(0), f(1), f(2), f(3))
            })
            .collect()
    };
    Layers {
        size,
        near: read(&targets[0]),
        far: read(&targets[1]),
        quarter_size,
        near_quarter: read(&targets[2]),
        far_quarter: read(&targets[3]),
    }
}

#[test]
fn scatter_pass_matches_the_model() {
    if !gpu_or_skip("scatter_pass_matches_the_model") {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter");
    let Model { sprites, view, .. } = model();
    for (name, aperture) in [
        ("hexagon", Aperture::hexagon(64)),
        (
            "triangle",
            Aperture::polygon(64, 3, std::f32::consts::FRAC_PI_2),
        ),
    ] {
        let want = scatter_sprites(&sprites, &aperture, view.half_size, view.quarter_diameter);
        let got = scatter_on_gpu(&gpu, &sprites, &aperture, &view);
        for (layer, g, w, least) in [
            ("near", &got.near, &want.near, 50),
            ("far", &got.far, &want.far, 100),
            ("near_quarter", &got.near_quarter, &want.near_quarter, 30),
            ("far_quarter", &got.far_quarter, &want.far_quarter, 30),
        ] {
            let covered = w.iter().filter(|v| v.w > 1e-3).count();
            let (mut worst_w, mut worst_c, mut sum_w) = (0.0f32, 0.0f32, 0.0f32);
            for (g, w) in g.iter().zip(w) {
                let dw = (g.w - w.w).abs() / w.w.max(0.05);
                worst_w = worst_w.max(dw);
                sum_w += dw;
                if w.w > 0.05 {
                    let dc = (g.truncate() / g.w - w.truncate() / w.w)
                        .abs()
                        .max_element()
                        / (w.truncate() / w.w).max_element().max(1.0);
                    worst_c = worst_c.max(dc);
                }
            }
            let mean_w = sum_w / g.len() as f32;
            eprintln!(
                "{name}, {layer}: {covered} texels covered; weight max rel. Δ {worst_w:.2e} (mean {mean_w:.2e}), resolved colour max rel. Δ {worst_c:.2e}"
            );
            assert!(covered > least, "{name} {layer}");
            // f32 accumulation (`Rgba32Float`, as the plugin's layers where the device
            // blends it): a few ulps (2·10⁻⁷ seen).
            assert!(
                worst_w < 1e-5 && mean_w < 1e-6 && worst_c < 1e-5,
                "{name} {layer}"
            );
        }
    }
}

/// The composite pass's output (`Rgba32Float` target) for `image` over `layers`.
fn composite_on_gpu(
    gpu: &GpuCompute,
    image: &BokehImage,
    layers: &Layers,
    view: &BokehView,
) -> Vec<Vec4> {
    let device = &gpu.device;
    let extent = |s: UVec2| wgpu::Extent3d {
        width: s.x,
        height: s.y,
        depth_or_array_layers: 1,
    };
    let halves4 = |v: &[Vec4]| -> Vec<u8> {
        v.iter()
            .flat_map(|c| c.to_array())
            .flat_map(|x| f16_bits_exact(x).to_le_bytes())
            .collect()
    };
    let floats4 = |v: &[Vec4]| -> Vec<u8> {
        v.iter()
            .flat_map(|c| c.to_array())
            .flat_map(f32::to_le_bytes)
            .collect()
    };
    let color: Vec<Vec4> = image.color.iter().map(|c| c.extend(1.0)).collect();
    let color = gpu.texture(
        "color",
        extent(SIZE),
        wgpu::TextureDimension::D2,
        wgpu::TextureFormat::Rgba16Float,
        8,
        &halves4(&color),
    );
    let near = gpu.texture(
        "near",
        extent(layers.size),
        wgpu::TextureDimension::D2,
        wgpu::TextureFormat::Rgba32Float,
        16,
        &floats4(&layers.near),
    );
    let far = gpu.texture(
        "far",
        extent(layers.size),
        wgpu::TextureDimension::D2,
        wgpu::TextureFormat::Rgba32Float,
        16,
        &floats4(&layers.far),
    );
    let near_quarter = gpu.texture(
        "near_quarter",
        extent(layers.quarter_size),
        wgpu::TextureDimension::D2,
        wgpu::TextureFormat::Rgba32Float,
        16,
        &floats4(&layers.near_quarter),
    );
    let far_quarter = gpu.texture(
        "far_quarter",
        extent(layers.quarter_size),
        wgpu::TextureDimension::D2,
        wgpu::TextureFormat::Rgba32Float,
        16,
        &floats4(&layers.far_quarter),
    );
    let depth = depth_texture(gpu, image);
    let uniform = gpu.buffer("view", &uniform_bytes(view), wgpu::BufferUsages::UNIFORM);
    let target = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("output"),
        size: extent(SIZE),
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba32Float,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let source = format!(
        "{}\n@vertex fn fullscreen(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {{\n    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));\n    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);\n}}\n",
        flatten("#import penumbra::dof::composite\n").expect("flattens")
    );
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("bokeh_composite"),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("bokeh_composite"),
        layout: None,
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("fullscreen"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: Default::default(),
        depth_stencil: None,
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fragment"),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::TextureFormat::Rgba32Float.into())],
        }),
        multiview_mask: None,
        cache: None,
    });
    let views = [&color, &depth, &near, &far, &near_quarter, &far_quarter]
        .map(|t| t.create_view(&Default::default()));
    let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("bokeh_composite"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: uniform.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::TextureView(&views[0]),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: wgpu::BindingResource::TextureView(&views[1]),
            },
            wgpu::BindGroupEntry {
                binding: 3,
                resource: wgpu::BindingResource::TextureView(&views[2]),
            },
            wgpu::BindGroupEntry {
                binding: 4,
                resource: wgpu::BindingResource::TextureView(&views[3]),
            },
            wgpu::BindGroupEntry {
                binding: 5,
                resource: wgpu::BindingResource::TextureView(&views[4]),
            },
            wgpu::BindGroupEntry {
                binding: 6,
                resource: wgpu::BindingResource::TextureView(&views[5]),
            },
        ],
    });
    let out_view = target.create_view(&Default::default());
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("bokeh_composite"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &out_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.draw(0..3, 0..1);
    }
    gpu.queue.submit([encoder.finish()]);
    gpu.read_texture_2d(&target)
        .chunks_exact(16)
        .map(|c| {
            let f =
                |i: usize| f32::from_le_bytes([c[4 * i], c[4 * i + 1], c[4 * i + 2], c[4 * i + 3]]);
            Vec4::new(f(0), f(1), f(2), f(3))
        })
        .collect()
}

/// `v`, already an f16 value (read back from a half-float texture, or the test
/// image's), as f16 bits.
fn f16_bits_exact(v: f32) -> u16 {
    let h = half_bits(v);
    debug_assert!(v == 0.0 || f16_to_f32(h) == v, "{v} is not an f16 value");
    h
}

#[test]
fn composite_pass_matches_the_model() {
    if !gpu_or_skip("composite_pass_matches_the_model") {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter");
    let Model {
        lens,
        image,
        rule,
        sprites,
        view,
    } = model();
    // The GPU's own layers (f16 values) feed both sides.
    let layers = scatter_on_gpu(&gpu, &sprites, &Aperture::hexagon(64), &view);
    let want = composite(&image, &lens, &rule, &layers);
    let got = composite_on_gpu(&gpu, &image, &layers, &view);
    let (mut worst, mut kept, mut in_focus) = (0.0f32, 0, 0);
    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
        let d = (g.truncate() - *w).abs().max_element() / w.max_element().max(1.0);
        worst = worst.max(d);
        let coc = lens.coc(image.distance[i], SIZE.y);
        if coc.abs() < 0.5 && *w == image.color[i] {
            in_focus += 1;
            kept += usize::from(g.truncate() == image.color[i]);
        }
    }
    eprintln!(
        "composite: max relative Δ {worst:.2e}; {kept} of {in_focus} untouched pixels in focus bit-identical"
    );
    assert!(in_focus > 200 && kept == in_focus, "{kept} of {in_focus}");
    // Measured equal: the same f16 inputs, the layers read at exact quarter texels. A
    // near layer's opacity capped at 0.9 moves pixels by 2·10⁻³.
    assert!(worst < 1e-5, "composite differs: {worst}");
}
