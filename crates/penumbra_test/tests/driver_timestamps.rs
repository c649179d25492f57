//! A diagnostic, not a contract: do timestamp queries around a compute pass measure the
//! compute on this driver? Prints, for encoder timestamps and compute-pass timestamps,
//! before and after the device has drawn once, the CPU wall time of a submission and
//! the span the timestamps give.
//!
//! On Mesa's lavapipe (22.3) both kinds measure the compute until a render pass has run;
//! from then on both ends are stamped after the compute (span ≈ 0, the time falls before
//! the span), which is why the benchmark's compute spans under-count there
//! (BENCHMARKS.md). Run: `cargo test -p penumbra_test --test driver_timestamps --
//! --ignored --nocapture`.

use penumbra_test::compute::GpuCompute;
use std::time::Instant;
use wgpu::*;

const SHADER: &str = "
@group(0) @binding(0) var<storage, read_write> out: array<f32>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    var x = f32(id.x);
    for (var i = 0u; i < 20000u; i++) { x = sin(x) * 1.0001 + 0.5; }
    out[id.x] = x;
}";

struct Rig {
    gpu: GpuCompute,
    pipeline: ComputePipeline,
    bind_group: BindGroup,
    queries: QuerySet,
    resolve: Buffer,
    target: TextureView,
}

fn rig() -> Option<Rig> {
    let gpu = GpuCompute::with_features(
        Features::TIMESTAMP_QUERY | Features::TIMESTAMP_QUERY_INSIDE_ENCODERS,
    )?;
    let pipeline = gpu.pipeline(SHADER, "main");
    let out = gpu.zeroed("out", 4 * 64 * 256, BufferUsages::empty());
    let bind_group = gpu.bind(&pipeline, &[(0, &out)]);
    let resolve = gpu.zeroed("resolve", 16, BufferUsages::QUERY_RESOLVE);
    let queries = gpu.device.create_query_set(&QuerySetDescriptor {
        label: None,
        ty: QueryType::Timestamp,
        count: 2,
    });
    let target = gpu
        .device
        .create_texture(&TextureDescriptor {
            label: None,
            size: Extent3d {
                width: 64,
                height: 64,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: TextureDimension::D2,
            format: TextureFormat::Rgba8Unorm,
            usage: TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        })
        .create_view(&Default::default());
    Some(Rig {
        gpu,
        pipeline,
        bind_group,
        queries,
        resolve,
        target,
    })
}

/// One submission: the compute pass between two timestamps (written by the encoder or
/// by the pass), then a render pass that clears when `draw`. Returns (CPU wall, span), ms.
fn measure(rig: &Rig, pass_timestamps: bool, draw: bool) -> (f64, f64) {
    let mut encoder = rig.gpu.device.create_command_encoder(&Default::default());
    if !pass_timestamps {
        encoder.write_timestamp(&rig.queries, 0);
    }
    {
        let mut pass = encoder.begin_compute_pass(&ComputePassDescriptor {
            label: None,
            timestamp_writes: pass_timestamps.then_some(ComputePassTimestampWrites {
                query_set: &rig.queries,
                beginning_of_pass_write_index: Some(0),
                end_of_pass_write_index: Some(1),
            }),
        });
        pass.set_pipeline(&rig.pipeline);
        pass.set_bind_group(0, &rig.bind_group, &[]);
        pass.dispatch_workgroups(256, 1, 1);
    }
    if !pass_timestamps {
        encoder.write_timestamp(&rig.queries, 1);
    }
    if draw {
        encoder.begin_render_pass(&RenderPassDescriptor {
            color_attachments: &[Some(RenderPassColorAttachment {
                view: &rig.target,
                depth_slice: None,
                resolve_target: None,
                ops: Operations {
                    load: LoadOp::Clear(Color::RED),
                    store: StoreOp::Store,
                },
            })],
            ..Default::default()
        });
    }
    encoder.resolve_query_set(&rig.queries, 0..2, &rig.resolve, 0);
    let start = Instant::now();
    rig.gpu.queue.submit([encoder.finish()]);
    rig.gpu.wait();
    let wall = start.elapsed().as_secs_f64() * 1e3;
    let stamps: Vec<u64> = rig
        .gpu
        .read(&rig.resolve, 16)
        .chunks(8)
        .map(|c| u64::from_le_bytes(c.try_into().expect("8 bytes")))
        .collect();
    let period_ms = f64::from(rig.gpu.queue.get_timestamp_period()) * 1e-6;
    (wall, stamps[1].wrapping_sub(stamps[0]) as f64 * period_ms)
}

#[test]
#[ignore = "a diagnostic of the driver's timestamps: prints, asserts nothing"]
fn timestamps_around_a_compute_pass() {
    let Some(rig) = rig() else {
        eprintln!("skipped: no Vulkan adapter with timestamp queries");
        return;
    };
    for (pass_timestamps, draw) in [(false, false), (true, false), (false, true)]
        .into_iter()
        .chain([(false, true), (true, true), (false, false), (true, false)])
    {
        let (wall, span) = measure(&rig, pass_timestamps, draw);
        let kind = if pass_timestamps { "pass" } else { "encoder" };
        let then = if draw { ", then a draw" } else { "" };
        println!("{kind:7} timestamps{then:13}: submission {wall:7.1} ms, span {span:8.3} ms");
    }
}
