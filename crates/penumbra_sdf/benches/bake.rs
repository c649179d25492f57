//! Bake benchmarks: run time and error together.
//!
//! `cargo bench -p penumbra_sdf --bench bake` (release). Prints, for the Stanford bunny
//! at 64 samples along its longest axis, Penumbra's and `mesh_to_sdf` 0.4's times (same
//! sample positions, same machine, one run), their errors against f64 brute force on
//! 3,000 random samples (max and p99 in voxels, sign errors where the exact winding
//! number is decisive, |w − ½| > 0.3), and the time ratio; then how Penumbra's time
//! scales with samples (32³…128³) and with triangles (spheres of 1k…64k triangles).
//! Needs `../shared/meshes` for the bunny parts.

#![allow(missing_docs, reason = "criterion_group! generates undocumented items")]

use criterion::{Criterion, criterion_group, criterion_main};
use glam::{UVec3, Vec3};
use penumbra_sdf::{BakeSettings, SdfVolume, TriMesh, bake, exact, obj, shapes};
use std::path::PathBuf;
use std::time::{Duration, Instant};

fn settings(n: u32) -> BakeSettings {
    BakeSettings::longest_axis(n)
}

fn bunny() -> Option<TriMesh> {
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/meshes/stanford-bunny.obj");
    let text = std::fs::read_to_string(&path)
        .map_err(|e| eprintln!("SKIPPED bunny benches: {}: {e}", path.display()))
        .ok()?;
    Some(obj::parse_obj(&text).expect("valid OBJ"))
}

/// Error statistics of `value(cell)` against f64 ground truth, in voxels.
struct Errors {
    max: f64,
    p99: f64,
    sign_errors: usize,
    sign_checked: usize,
}

fn errors(tris: &[[Vec3; 3]], v: &SdfVolume, value: impl Fn(UVec3) -> f32) -> Errors {
    let mut s = 12345u64;
    let mut next = |m: u32| {
        s = s
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((s >> 33) % m as u64) as u32
    };
    let h = v.voxel_size as f64;
    let mut e = Vec::new();
    let (mut sign_errors, mut sign_checked) = (0, 0);
    for _ in 0..3000 {
        let c = UVec3::new(next(v.dims.x), next(v.dims.y), next(v.dims.z));
        let p = v.position(c.x, c.y, c.z);
        let got = value(c) as f64;
        let d = exact::distance(p, tris);
        e.push((got.abs() - d).abs() / h);
        let w = exact::winding_number(p, tris);
        if (w - 0.5).abs() > 0.3 && d > 1e-4 * h {
            sign_checked += 1;
            sign_errors += usize::from((got < 0.0) != (w > 0.5));
        }
    }
    e.sort_by(f64::total_cmp);
    Errors {
        max: *e.last().unwrap(),
        p99: e[e.len() * 99 / 100],
        sign_errors,
        sign_checked,
    }
}

/// `mesh_to_sdf` on exactly Penumbra's sample positions; returns its values by cell.
fn mesh_to_sdf_bake(mesh: &TriMesh, v: &SdfVolume) -> Vec<f32> {
    let vertices: Vec<[f32; 3]> = mesh.positions.iter().map(|p| p.to_array()).collect();
    let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    let grid = mesh_to_sdf::Grid::new(
        v.origin.to_array(),
        [v.voxel_size; 3],
        [v.dims.x as usize, v.dims.y as usize, v.dims.z as usize],
    );
    mesh_to_sdf::generate_grid_sdf(
        &vertices,
        mesh_to_sdf::Topology::TriangleList(Some(&indices)),
        &grid,
        mesh_to_sdf::SignMethod::Raycast,
    )
}

fn time<T>(f: impl FnMut() -> T, runs: u32) -> (Duration, T) {
    let mut f = f;
    let mut best = Duration::MAX;
    let mut out = None;
    for _ in 0..runs {
        let t = Instant::now();
        let r = f();
        best = best.min(t.elapsed());
        out = Some(r);
    }
    (best, out.expect("runs > 0"))
}

fn comparison(c: &mut Criterion) {
    let Some(mesh) = bunny() else { return };
    let (tris, _) = mesh.validate().unwrap();
    let (t_ours, ours) = time(|| bake(&mesh, &settings(64), None).unwrap(), 5);
    let v = &ours.volume;
    let (t_theirs, theirs) = time(|| mesh_to_sdf_bake(&mesh, v), 3);
    let (nx, ny, nz) = (v.dims.x, v.dims.y, v.dims.z);
    let e_ours = errors(&tris, v, |c| v.get(c.x, c.y, c.z));
    let e_theirs = errors(&tris, v, |c| {
        theirs[(c.z + c.y * nz + c.x * ny * nz) as usize]
    });
    println!(
        "\nbunny {} triangles, {nx}x{ny}x{nz} samples (best of runs, bake only, {} threads)",
        mesh.triangles.len(),
        rayon::current_num_threads()
    );
    println!("| | time | max error (voxel) | p99 (voxel) | sign errors |");
    println!("|---|---|---|---|---|");
    for (name, t, e) in [
        ("penumbra_sdf", t_ours, &e_ours),
        ("mesh_to_sdf 0.4", t_theirs, &e_theirs),
    ] {
        println!(
            "| {name} | {:.3} s | {:.4} | {:.4} | {} of {} |",
            t.as_secs_f64(),
            e.max,
            e.p99,
            e.sign_errors,
            e.sign_checked
        );
    }
    println!(
        "speed-up over mesh_to_sdf: {:.2}x",
        t_theirs.as_secs_f64() / t_ours.as_secs_f64()
    );
    println!("penumbra phases: {:?}\n", ours.timings);

    let mut group = c.benchmark_group("bunny_64");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(8));
    group.bench_function("penumbra_sdf", |b| {
        b.iter(|| bake(&mesh, &settings(64), None).unwrap());
    });
    group.finish();
}

fn scaling(_c: &mut Criterion) {
    if let Some(mesh) = bunny() {
        println!("\nbunny, samples along the longest axis:");
        println!("| n | samples | time | ns/sample |");
        println!("|---|---|---|---|");
        for n in [32, 64, 128] {
            let (t, b) = time(|| bake(&mesh, &settings(n), None).unwrap(), 2);
            let samples = b.volume.len();
            println!(
                "| {n} | {samples} | {:.3} s | {:.0} |",
                t.as_secs_f64(),
                t.as_secs_f64() * 1e9 / samples as f64
            );
        }
    }
    println!("\nspheres at 64 samples along the axis, by triangle count:");
    println!("| triangles | time |");
    println!("|---|---|");
    for (sectors, stacks) in [(32, 16), (64, 32), (128, 64), (256, 128)] {
        let mesh = shapes::sphere(1.0, sectors, stacks);
        let (t, b) = time(|| bake(&mesh, &settings(64), None).unwrap(), 2);
        println!("| {} | {:.3} s |", b.mesh.triangles, t.as_secs_f64());
    }
}

criterion_group!(benches, comparison, scaling);
criterion_main!(benches);
