//! Contract test of the posed-mesh re-bake on lavapipe (`df/rebake.wgsl`, run through
//! wgpu directly): the packed f16 samples the GPU writes equal the CPU model's
//! (`penumbra_reference::rebake`, itself checked against f64 brute force and analytic
//! distances in its unit tests) to f16 rounding, with the same sign wherever the model's
//! winding number is not within a hair of ½; on a closed sphere beside an open box, and
//! on the Fox (`../shared/scenes/Fox.glb`) mid-walk at the default resolution.

use glam::{UVec3, Vec3};
use penumbra_df_core::rebake::{RebakeGrid, output_word_offset};
use penumbra_reference::posed_gltf::{Pose, posed_triangles};
use penumbra_reference::rebake::{Rebake, bounds, rebake, relative_corners};
use penumbra_sdf::volume::f16;
use penumbra_sdf::{TriMesh, shapes};
use penumbra_shaders::flatten;
use penumbra_test::wgpu::BufferUsages;
use penumbra_test::{GpuCompute, gpu_or_skip, uniform_bytes};
use std::time::Instant;

/// The GPU's bake of `triangles` on `grid`: signed voxels, x fastest, and the
/// dispatch's wall time (lavapipe: a CPU).
fn gpu_rebake(gpu: &GpuCompute, triangles: &[[Vec3; 3]], grid: RebakeGrid) -> (Vec<f32>, f64) {
    let pipeline = gpu.pipeline(
        &flatten("#import penumbra::df::rebake\n").expect("flattens"),
        "rebake",
    );
    let corners = relative_corners(triangles, &grid);
    let bytes: Vec<u8> = corners
        .iter()
        .flatten()
        .flat_map(|v| v.extend(0.0).to_array())
        .flat_map(f32::to_le_bytes)
        .collect();
    let corner_buffer = gpu.buffer("corners", &bytes, BufferUsages::empty());
    let params = grid.params(corners.len() as u32);
    let params = gpu.buffer("params", &uniform_bytes(&params), BufferUsages::UNIFORM);
    let output = gpu.zeroed("samples", grid.output_bytes(), BufferUsages::empty());
    let bind = gpu.bind(
        &pipeline,
        &[(0, &params), (1, &corner_buffer), (2, &output)],
    );
    let groups = grid.workgroups();
    let start = Instant::now();
    gpu.dispatch(&pipeline, &bind, groups.to_array());
    gpu.wait();
    let seconds = start.elapsed().as_secs_f64();
    let out = gpu.read(&output, grid.output_bytes());
    let r = grid.resolution;
    let mut voxels = Vec::with_capacity((r * r * r) as usize);
    for k in 0..r {
        for j in 0..r {
            for i in 0..r {
                let at =
                    output_word_offset(&grid, UVec3::new(i, j, k)) as usize + 2 * (i % 2) as usize;
                voxels.push(f16::from_le_bytes([out[at], out[at + 1]]).to_f32());
            }
        }
    }
    (voxels, seconds)
}

/// Compares the GPU's samples with the model's: the largest difference beyond f16
/// rounding (voxels) and the samples whose sign differs where the winding number is
/// clear of ½.
fn compare(gpu: &[f32], model: &Rebake) -> (f32, usize) {
    let (mut worst, mut flipped) = (0.0f32, 0);
    for ((g, m), w) in gpu.iter().zip(&model.voxels).zip(&model.winding) {
        let rounded = f16::from_f32(*m).to_f32();
        // One f16 step at the value, plus f32 differences in the sums.
        let step = (m.abs() * 2f32.powi(-10)).max(2f32.powi(-24));
        let apart = (g.abs() - rounded.abs()).abs() - step;
        worst = worst.max(apart);
        if (w - 0.5).abs() > 1e-3 && (*g < 0.0) != (*m < 0.0) {
            flipped += 1;
        }
    }
    (worst, flipped)
}

/// `mesh`'s triangles moved by `offset`.
fn placed(mesh: &TriMesh, offset: Vec3) -> Vec<[Vec3; 3]> {
    let tris = mesh.validate().expect("a valid shape").0;
    tris.into_iter().map(|t| t.map(|v| v + offset)).collect()
}

#[test]
fn rebake_matches_the_model() {
    if !gpu_or_skip("rebake_matches_the_model") {
        return;
    }
    let gpu = GpuCompute::new().expect("adapter");
    // More than one tile of triangles, the last one partial. Far from the origin,
    // as a character in a large level is.
    let far = Vec3::new(4000.0, 12.0, -2500.0);
    let mut triangles = placed(
        &shapes::sphere(0.35, 10, 6),
        far + Vec3::new(-0.4, 0.0, 0.0),
    );
    // A box with its top left open.
    let h = Vec3::new(0.3, 0.25, 0.3);
    triangles.extend(
        placed(&shapes::cuboid(h), far + Vec3::new(0.4, 0.0, 0.1))
            .into_iter()
            .filter(|t| t.iter().any(|v| v.y < far.y + h.y - 1e-3)),
    );
    triangles.push([Vec3::NAN, far, far + Vec3::X]);
    let (lo, hi) = bounds(&triangles).expect("bounds");
    let grid = RebakeGrid::around(lo, hi, 24).expect("grid");
    let model = rebake(&triangles, grid);
    let (voxels, seconds) = gpu_rebake(&gpu, &triangles, grid);
    let (worst, flipped) = compare(&voxels, &model);
    let inside = model.voxels.iter().filter(|v| **v < 0.0).count();
    eprintln!(
        "{} triangles, {}³: {inside} samples inside; GPU − model beyond f16 rounding {worst:.2e} \
         voxels, {flipped} signs differ; {seconds:.3} s on this adapter",
        triangles.len(),
        grid.resolution
    );
    assert!(inside > 500, "the solids bake inside ({inside} samples)");
    assert!(worst < 2e-3, "the GPU's samples differ by {worst} voxels");
    assert_eq!(flipped, 0, "signs differ");
}

#[test]
fn rebake_of_the_walking_fox_matches_the_model() {
    let test = "rebake_of_the_walking_fox_matches_the_model";
    if !gpu_or_skip(test) {
        return;
    }
    let Some(scenes) = penumbra_testkit::shared_dir(test, env!("CARGO_MANIFEST_DIR"), "scenes")
    else {
        return;
    };
    let posed = posed_triangles(
        &scenes.join("Fox.glb"),
        Some(Pose {
            animation: 1,
            time: 0.35,
        }),
    )
    .expect("the Fox poses");
    let (lo, hi) = bounds(&posed.triangles).expect("bounds");
    let grid = RebakeGrid::around(lo, hi, 32).expect("grid");
    let gpu = GpuCompute::new().expect("adapter");
    let start = Instant::now();
    let model = rebake(&posed.triangles, grid);
    let model_seconds = start.elapsed().as_secs_f64();
    let (voxels, seconds) = gpu_rebake(&gpu, &posed.triangles, grid);
    let (worst, flipped) = compare(&voxels, &model);
    let inside = model.voxels.iter().filter(|v| **v < 0.0).count();
    eprintln!(
        "the Fox (walk, 0.35 s): {} triangles, {}³, voxel {:.2} units: {inside} samples \
         inside; GPU − model beyond f16 rounding {worst:.2e} voxels, {flipped} signs differ; \
         GPU {seconds:.3} s on this adapter, model {model_seconds:.3} s",
        posed.triangles.len(),
        grid.resolution,
        grid.voxel_size,
    );
    assert!(
        inside > 100,
        "the Fox bakes solid ({inside} samples inside)"
    );
    // The pass's time by resolution on this adapter (figures, not checked).
    let times: Vec<String> = [16, 32, 48, 64]
        .iter()
        .map(|&r| {
            let grid = RebakeGrid::around(lo, hi, r).expect("grid");
            let (_, s) = gpu_rebake(&gpu, &posed.triangles, grid);
            format!("{r}³ {:.0} ms", s * 1e3)
        })
        .collect();
    eprintln!("the Fox's bake on this adapter: {}", times.join(", "));
    assert!(worst < 2e-3, "the GPU's samples differ by {worst} voxels");
    assert_eq!(flipped, 0, "signs differ");
}
