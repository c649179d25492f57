//! Contract tests of the distance-field object buffer on the GPU (lavapipe in CI): the
//! delta pass keeps the GPU buffer equal to the CPU mirror under random churn, and the
//! culling pass keeps exactly the objects the CPU frustum test keeps.

use glam::{Affine3A, Mat4, Quat, UVec3, Vec3};
use penumbra_df_core::atlas::AtlasRegion;
use penumbra_df_core::cull::{self, CameraOrigin, Frustum, cull_view_words, grid_64};
use penumbra_df_core::object::{
    CasterShape, ObjectDesc, ObjectRecord, RECORD_BYTES, encode, flags,
};
use penumbra_df_core::table::{
    DELTA_PARAMS_STRIDE, DeltaWrite, Deltas, ObjectTable, writes_per_chunk,
};
use penumbra_shaders::flatten;
use penumbra_test::wgpu::{self, BufferUsages};
use penumbra_test::{GpuCompute, gpu_or_skip};

/// Deterministic pseudo-random numbers.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() * n as f32) as usize % n.max(1)
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.next()
    }
}

/// A random caster: any shape, any rotation, non-uniform scale, anywhere within
/// `spread` of `center`.
fn random_desc(rng: &mut Rng, center: Vec3, spread: f32) -> ObjectDesc {
    let shape = match rng.below(5) {
        0 => CasterShape::Volume {
            region: AtlasRegion {
                origin: UVec3::new(
                    8 * rng.below(32) as u32,
                    8 * rng.below(32) as u32,
                    8 * rng.below(64) as u32,
                ),
                dims: UVec3::new(
                    8 + rng.below(56) as u32,
                    8 + rng.below(56) as u32,
                    8 + rng.below(56) as u32,
                ),
            },
            local_origin: Vec3::new(
                rng.range(-1.0, 0.0),
                rng.range(-1.0, 0.0),
                rng.range(-1.0, 0.0),
            ),
            voxel_size: rng.range(0.01, 0.05),
            margin: rng.range(0.0, 2.0),
        },
        1 => CasterShape::Sphere {
            radius: rng.range(0.1, 2.0),
        },
        2 => CasterShape::Cuboid {
            half_extents: Vec3::new(
                rng.range(0.1, 2.0),
                rng.range(0.1, 2.0),
                rng.range(0.1, 2.0),
            ),
        },
        3 => CasterShape::Capsule {
            radius: rng.range(0.1, 1.0),
            half_length: rng.range(0.0, 2.0),
        },
        _ => CasterShape::Plane,
    };
    let rotation = Quat::from_euler(
        glam::EulerRot::YXZ,
        rng.range(-3.0, 3.0),
        rng.range(-1.5, 1.5),
        rng.range(-3.0, 3.0),
    );
    let scale = Vec3::new(
        rng.range(0.2, 3.0),
        rng.range(0.2, 3.0),
        rng.range(0.2, 3.0),
    );
    let at = center
        + Vec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        ) * spread;
    let mut f = flags::CASTS_SHADOWS;
    if rng.next() < 0.9 {
        f |= flags::VISIBLE;
    }
    ObjectDesc {
        world_from_local: Affine3A::from_scale_rotation_translation(scale, rotation, at),
        shape,
        flags: f,
    }
}

/// The GPU side of the object buffer as the plugin keeps it: a storage buffer grown by
/// doubling (old contents copied), updated by the delta pass.
struct GpuObjects {
    buffer: wgpu::Buffer,
    capacity: u32,
    apply: wgpu::ComputePipeline,
    uploaded_bytes: usize,
    /// Dispatches of the delta pass so far.
    chunks: usize,
    binding_limit: u64,
}

/// A storage-binding limit small enough that frames with more than 64 writes are
/// uploaded in several chunks (the smallest chunk: 64 writes).
const SIMULATED_BINDING_LIMIT: u64 = 64 * DeltaWrite::BYTES as u64;

impl GpuObjects {
    /// Objects uploaded in chunks bound within `binding_limit` bytes.
    fn new(gpu: &GpuCompute, binding_limit: u64) -> GpuObjects {
        let wgsl = flatten("#import penumbra::df::apply_deltas\n").unwrap();
        GpuObjects {
            buffer: gpu.zeroed("objects", 64 * RECORD_BYTES as u64, BufferUsages::empty()),
            capacity: 64,
            apply: gpu.pipeline(&wgsl, "apply_deltas"),
            uploaded_bytes: 0,
            chunks: 0,
            binding_limit,
        }
    }

    fn apply(&mut self, gpu: &GpuCompute, deltas: &Deltas) {
        if deltas.slot_count > self.capacity {
            let capacity = deltas.slot_count.next_power_of_two();
            let grown = gpu.zeroed(
                "objects",
                capacity as u64 * RECORD_BYTES as u64,
                BufferUsages::empty(),
            );
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            encoder.copy_buffer_to_buffer(
                &self.buffer,
                0,
                &grown,
                0,
                self.capacity as u64 * RECORD_BYTES as u64,
            );
            gpu.queue.submit([encoder.finish()]);
            self.buffer = grown;
            self.capacity = capacity;
        }
        if deltas.writes.is_empty() {
            return; // a static frame: nothing uploaded, no pass
        }
        // As the plugin does: one dispatch per chunk, each binding its range of the
        // writes and its params. A small simulated binding limit (the plugin's is the
        // device's, 128 MiB on lavapipe) makes frames of many writes take several.
        let upload = deltas.upload(writes_per_chunk(self.binding_limit));
        self.uploaded_bytes += upload.writes.len();
        self.chunks += upload.chunks.len();
        let writes = gpu.buffer("writes", &upload.writes, BufferUsages::empty());
        let params = gpu.buffer("params", &upload.params, BufferUsages::UNIFORM);
        for (k, chunk) in upload.chunks.iter().enumerate() {
            let bytes = chunk.count as u64 * DeltaWrite::BYTES as u64;
            let bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("apply_deltas"),
                layout: &self.apply.get_bind_group_layout(0),
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: self.buffer.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer: &writes,
                            offset: chunk.first as u64 * DeltaWrite::BYTES as u64,
                            size: std::num::NonZeroU64::new(bytes),
                        }),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer: &params,
                            offset: k as u64 * DELTA_PARAMS_STRIDE,
                            size: std::num::NonZeroU64::new(16),
                        }),
                    },
                ],
            });
            gpu.dispatch(&self.apply, &bind, chunk.groups);
        }
    }

    fn read(&self, gpu: &GpuCompute, slots: u32) -> Vec<ObjectRecord> {
        gpu.read(&self.buffer, slots as u64 * RECORD_BYTES as u64)
            .chunks_exact(RECORD_BYTES)
            .map(|c| ObjectRecord::from_bytes(c.try_into().expect("record bytes")))
            .collect()
    }
}

/// The culling pass's two pipelines.
struct CullPipelines {
    cull: wgpu::ComputePipeline,
    indirect: wgpu::ComputePipeline,
}

impl CullPipelines {
    fn new(gpu: &GpuCompute) -> CullPipelines {
        let wgsl = flatten("#import penumbra::df::cull\n").unwrap();
        CullPipelines {
            cull: gpu.pipeline(&wgsl, "cull"),
            indirect: gpu.pipeline(&wgsl, "write_indirect"),
        }
    }
}

/// Culls `slots` records on the GPU: (sorted survivors, count, indirect args).
fn gpu_cull(
    gpu: &GpuCompute,
    pipelines: &CullPipelines,
    objects: &wgpu::Buffer,
    slots: u32,
    camera: &CameraOrigin,
    frustum: &Frustum,
) -> (Vec<u32>, u32, [u32; 3]) {
    let (cull, indirect_pipeline) = (&pipelines.cull, &pipelines.indirect);
    let (groups, groups_x) = grid_64(slots);
    let view = cull_view_words(frustum, camera, slots, groups_x);
    let view: Vec<u8> = view.iter().flat_map(|w| w.to_le_bytes()).collect();
    let view = gpu.buffer("view", &view, BufferUsages::UNIFORM);
    let culled = gpu.zeroed("culled", slots.max(1) as u64 * 4, BufferUsages::empty());
    let count = gpu.zeroed("count", 4, BufferUsages::empty());
    let indirect = gpu.zeroed("indirect", 12, BufferUsages::INDIRECT);
    let bind = gpu.bind(cull, &[(0, objects), (1, &view), (2, &culled), (3, &count)]);
    gpu.dispatch(cull, &bind, groups);
    let bind = gpu.bind(indirect_pipeline, &[(3, &count), (4, &indirect)]);
    gpu.dispatch(indirect_pipeline, &bind, [1, 1, 1]);
    let words = |b: Vec<u8>| -> Vec<u32> {
        b.chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    };
    let n = words(gpu.read(&count, 4))[0];
    let mut list = words(gpu.read(&culled, n.max(1) as u64 * 4));
    list.truncate(n as usize);
    list.sort_unstable();
    let args = words(gpu.read(&indirect, 12));
    (list, n, [args[0], args[1], args[2]])
}

fn frustum_looking(eye: Vec3, dir: Vec3) -> (CameraOrigin, Frustum) {
    let proj = Mat4::perspective_infinite_reverse_rh(1.1, 1.3, 0.1);
    let view = Mat4::look_to_rh(Vec3::ZERO, dir, Vec3::Y);
    (
        CameraOrigin::at(eye).unwrap(),
        Frustum::from_clip_from_relative(proj * view),
    )
}

/// ≥ 10,000 random adds, removes, moves and rescales over 320 frames, near the origin
/// and 10⁵ m away: after every frame's delta pass the GPU buffer equals the CPU mirror
/// (checked on lavapipe every 25 frames and at the end); static frames upload nothing;
/// then GPU culling equals the CPU frustum test from several cameras.
#[test]
fn gpu_object_buffer_follows_churn_and_culls_like_the_cpu() {
    if !gpu_or_skip("gpu_object_buffer_follows_churn_and_culls_like_the_cpu") {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter present");
    let mut rng = Rng(42);
    let mut table = ObjectTable::new();
    let mut gpu_objects = GpuObjects::new(&gpu, SIMULATED_BINDING_LIMIT);
    let mut live: Vec<(u64, ObjectDesc)> = Vec::new();
    let mut next_key = 0u64;
    let (mut ops, mut static_frames, mut checks) = (0, 0, 0);
    let far = Vec3::new(1e5, 20.0, -1e5);
    for frame in 0..320 {
        let center = if frame % 2 == 0 { Vec3::ZERO } else { far };
        let changes = if frame % 10 == 9 { 0 } else { rng.below(80) };
        for _ in 0..changes {
            ops += 1;
            match rng.below(6) {
                0..=2 => {
                    let desc = random_desc(&mut rng, center, 40.0);
                    table.upsert(next_key, encode(&desc).unwrap());
                    live.push((next_key, desc));
                    next_key += 1;
                }
                3 if !live.is_empty() => {
                    let (key, _) = live.swap_remove(rng.below(live.len()));
                    table.remove(key);
                }
                4 if !live.is_empty() => {
                    // Move.
                    let i = rng.below(live.len());
                    let (key, desc) = &mut live[i];
                    desc.world_from_local.translation +=
                        glam::Vec3A::new(rng.range(-1.0, 1.0), 0.5, rng.range(-1.0, 1.0));
                    table.upsert(*key, encode(desc).unwrap());
                }
                _ if !live.is_empty() => {
                    // Rescale (non-uniformly) and toggle visibility.
                    let i = rng.below(live.len());
                    let (key, desc) = &mut live[i];
                    desc.world_from_local.matrix3 *=
                        glam::Mat3A::from_diagonal(Vec3::new(1.1, 0.9, 1.0));
                    desc.flags ^= flags::VISIBLE;
                    table.upsert(*key, encode(desc).unwrap());
                }
                _ => {}
            }
        }
        let deltas = table.take_deltas();
        let before = gpu_objects.uploaded_bytes;
        gpu_objects.apply(&gpu, &deltas);
        if changes == 0 {
            static_frames += 1;
            assert_eq!(
                gpu_objects.uploaded_bytes, before,
                "static frame {frame} uploaded"
            );
        }
        if frame % 25 == 24 || frame == 319 {
            let gpu_records = gpu_objects.read(&gpu, table.slot_count());
            assert!(
                gpu_records.as_slice() == table.records(),
                "frame {frame}: GPU buffer differs from the CPU mirror in {} of {} slots",
                gpu_records
                    .iter()
                    .zip(table.records())
                    .filter(|(a, b)| a != b)
                    .count(),
                table.slot_count()
            );
            checks += 1;
        }
    }
    assert!(ops >= 10_000, "{ops} operations");
    assert!(static_frames >= 25 && checks >= 12);
    // Frames of more than 64 writes were split (checked equal to the mirror above).
    let frames_with_writes = 320 - static_frames;
    assert!(
        gpu_objects.chunks > frames_with_writes,
        "{} dispatches over {frames_with_writes} frames: nothing was split",
        gpu_objects.chunks
    );
    println!(
        "churn: {ops} operations, {} live objects in {} slots, {} bytes uploaded in total \
         in {} chunks",
        table.len(),
        table.slot_count(),
        gpu_objects.uploaded_bytes,
        gpu_objects.chunks
    );

    let slots = table.slot_count();
    let cameras = [
        frustum_looking(Vec3::new(0.0, 2.0, 30.0), Vec3::new(0.1, -0.1, -1.0)),
        frustum_looking(Vec3::new(-20.0, 5.0, 0.0), Vec3::new(1.0, 0.0, 0.2)),
        frustum_looking(far + Vec3::new(0.0, 2.0, 30.0), Vec3::new(0.0, 0.0, -1.0)),
        frustum_looking(far + Vec3::new(35.0, 0.0, 35.0), Vec3::new(-1.0, 0.0, -1.0)),
    ];
    let pipelines = CullPipelines::new(&gpu);
    for (i, (camera, frustum)) in cameras.iter().enumerate() {
        let want = cull::cull(table.records(), camera, frustum);
        let (got, count, args) = gpu_cull(
            &gpu,
            &pipelines,
            &gpu_objects.buffer,
            slots,
            camera,
            frustum,
        );
        println!("camera {i}: {} of {slots} slots survive", want.len());
        assert!(
            !want.is_empty() && want.len() < table.len(),
            "camera {i}: degenerate view"
        );
        assert_eq!(count as usize, got.len());
        let only_gpu: Vec<_> = got
            .iter()
            .filter(|s| want.binary_search(s).is_err())
            .collect();
        let only_cpu: Vec<_> = want
            .iter()
            .filter(|s| got.binary_search(s).is_err())
            .collect();
        assert!(
            only_gpu.is_empty() && only_cpu.is_empty(),
            "camera {i}: kept only by the GPU {only_gpu:?}, only by the CPU {only_cpu:?}"
        );
        assert_eq!(args, [count.div_ceil(64), 1, 1], "camera {i}");
    }
}

/// One million casters through the delta pass (uploaded in chunks below the 128 MiB
/// binding limit) and the culling pass on lavapipe; prints the times, asserts the
/// buffer equals the mirror and the culled set equals the CPU's. Slow on a CPU
/// rasterizer: run it on purpose,
/// `cargo test --release -p bevy_penumbra_df --test gpu_object_buffer -- --ignored --nocapture`.
#[test]
#[ignore = "a benchmark: about a minute on lavapipe"]
fn million_objects_apply_and_cull() {
    if !gpu_or_skip("million_objects_apply_and_cull") {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter present");
    let n = 1_000_000u64;
    let mut rng = Rng(7);
    let mut table = ObjectTable::new();
    let t = std::time::Instant::now();
    for key in 0..n {
        let desc = random_desc(&mut rng, Vec3::ZERO, 500.0);
        table.upsert(key, encode(&desc).unwrap());
    }
    let deltas = table.take_deltas();
    println!(
        "encode + mirror of {n} records: {:.3} s (CPU)",
        t.elapsed().as_secs_f64()
    );
    // One frame of a million writes, split below the device's real binding limit.
    let limit = gpu.device.limits().max_storage_buffer_binding_size;
    let mut objects = GpuObjects::new(&gpu, limit);
    let t = std::time::Instant::now();
    objects.apply(&gpu, &deltas);
    gpu.read(&objects.buffer, 16); // waits for everything queued
    println!(
        "apply {n} writes ({} MB, {} dispatches under the {limit}-byte binding limit): \
         {:.3} s with CPU conversion and upload",
        objects.uploaded_bytes / 1_000_000,
        objects.chunks,
        t.elapsed().as_secs_f64()
    );
    let back = objects.read(&gpu, table.slot_count());
    assert!(
        back.as_slice() == table.records(),
        "GPU buffer differs from the mirror"
    );
    let (camera, frustum) =
        frustum_looking(Vec3::new(0.0, 50.0, 400.0), Vec3::new(0.0, -0.2, -1.0));
    let pipelines = CullPipelines::new(&gpu);
    gpu_cull(
        &gpu,
        &pipelines,
        &objects.buffer,
        table.slot_count(),
        &camera,
        &frustum,
    ); // warm-up
    let t = std::time::Instant::now();
    let (got, count, _) = gpu_cull(
        &gpu,
        &pipelines,
        &objects.buffer,
        table.slot_count(),
        &camera,
        &frustum,
    );
    let gpu_time = t.elapsed().as_secs_f64();
    let t = std::time::Instant::now();
    let want = cull::cull(table.records(), &camera, &frustum);
    println!(
        "cull {n} objects -> {count} survivors: GPU {gpu_time:.3} s (with buffer setup and reading the list back), CPU reference {:.3} s",
        t.elapsed().as_secs_f64()
    );
    assert_eq!(got, want);
}
