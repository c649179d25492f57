//! Bake benchmarks: run time and error together.
//!
//! `cargo bench -p penumbra_sdf --bench bake` (release). Prints, for the Stanford bunny
//! at 64 samples along its longest axis, the median times of Penumbra, `mesh_to_sdf` 0.4 and —
//! when `python3` can `import igl` (`pip install numpy libigl`) — libigl's
//! fast-winding-number signed distance (`benches/libigl_sdf.py`), all on the same
//! sample positions in one run; their errors against f64 brute force on 3,000 random
//! samples (max and p99 in voxels, sign errors where the exact winding number is
//! decisive, |w − ½| > 0.3); and the time ratios. Then how Penumbra's time scales with
//! samples (32…256 along the longest axis) and with triangles (spheres of 1k…64k
//! triangles). Then sparse bricks (`penumbra_sdf::bricks`): for the bunny at 64…256
//! samples, the time to cut a baked grid into bricks (the scene's main thread pays it when
//! a large volume is placed), bytes against dense, and both fields' errors against f64
//! brute force (bricks read exactly the dense grid within their band and a lower bound
//! beyond it, so their far-field error is larger by design). Needs `../shared/meshes`
//! for the bunny parts.

#![allow(missing_docs, reason = "criterion_group! generates undocumented items")]

use criterion::{Criterion, criterion_group, criterion_main};
use glam::{UVec3, Vec3};
use penumbra_sdf::bricks::{BrickedVolume, DEFAULT_BAND_VOXELS};
use penumbra_sdf::{BakeSettings, SdfVolume, TriMesh, bake, exact, obj, shapes};
use std::path::PathBuf;
use std::time::{Duration, Instant};

fn settings(n: u32) -> BakeSettings {
    BakeSettings::longest_axis(n)
}

fn bunny_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/meshes/stanford-bunny.obj")
}

fn bunny() -> Option<TriMesh> {
    let path = bunny_path();
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

/// `tris` are relative to `origin` (the mesh's `TriMesh::origin`).
fn errors(
    tris: &[[Vec3; 3]],
    origin: glam::DVec3,
    v: &SdfVolume,
    value: impl Fn(UVec3) -> f32,
) -> Errors {
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
        let p = v.position(c.x, c.y, c.z) - origin;
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
        (v.origin - mesh.origin).as_vec3().to_array(),
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

/// libigl's signed distance on `v`'s samples through `benches/libigl_sdf.py`: its median
/// time and values by cell (`(k, j, i)` order), or `None` when python or libigl is
/// missing.
fn libigl_bake(mesh_path: &std::path::Path, v: &SdfVolume) -> Option<(Duration, Vec<f32>)> {
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("benches/libigl_sdf.py");
    let out = std::env::temp_dir().join(format!("penumbra_libigl_{}.npy", std::process::id()));
    let o = v.origin;
    let result = std::process::Command::new("python3")
        .arg(&script)
        .arg(mesh_path)
        .args([o.x, o.y, o.z, v.voxel_size as f64].map(|x| format!("{x:.17e}")))
        .args([v.dims.x, v.dims.y, v.dims.z].map(|n| n.to_string()))
        .arg(&out)
        .output()
        .ok()?;
    if !result.status.success() {
        eprintln!(
            "SKIPPED libigl comparison: {}",
            String::from_utf8_lossy(&result.stderr)
                .lines()
                .last()
                .unwrap_or("python3 failed")
        );
        return None;
    }
    let stdout = String::from_utf8_lossy(&result.stdout);
    let seconds: f64 = stdout
        .split_whitespace()
        .skip_while(|w| *w != "libigl_seconds")
        .nth(1)?
        .parse()
        .ok()?;
    let bytes = std::fs::read(&out).ok()?;
    let _ = std::fs::remove_file(&out);
    // .npy v1: magic (6), version (2), header length (u16 LE), header, data.
    let header = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let values = bytes[10 + header..]
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    Some((Duration::from_secs_f64(seconds), values))
}

/// The median time of `runs` runs after one untimed warm-up run (as the libigl script
/// does: the first run in a process pays for page faults and thread start-up), and the
/// last result. The host's run-to-run noise is about ±10 %: a median is steadier than a
/// best.
fn time<T>(f: impl FnMut() -> T, runs: u32) -> (Duration, T) {
    let mut f = f;
    std::hint::black_box(f());
    let mut times = Vec::with_capacity(runs as usize);
    let mut out = None;
    for _ in 0..runs {
        let t = Instant::now();
        let r = f();
        times.push(t.elapsed());
        out = Some(r);
    }
    times.sort_unstable();
    (times[times.len() / 2], out.expect("runs > 0"))
}

fn comparison(c: &mut Criterion) {
    let Some(mesh) = bunny() else { return };
    let (tris, _) = mesh.validate().unwrap();
    let (t_ours, ours) = time(|| bake(&mesh, &settings(64), None).unwrap(), 9);
    let v = &ours.volume;
    let (t_theirs, theirs) = time(|| mesh_to_sdf_bake(&mesh, v), 5);
    let (nx, ny, nz) = (v.dims.x, v.dims.y, v.dims.z);
    let e_ours = errors(&tris, mesh.origin, v, |c| v.get(c.x, c.y, c.z));
    let e_theirs = errors(&tris, mesh.origin, v, |c| {
        theirs[(c.z + c.y * nz + c.x * ny * nz) as usize]
    });
    let igl = libigl_bake(&bunny_path(), v).map(|(t, values)| {
        (
            t,
            errors(&tris, mesh.origin, v, |c| values[v.index(c.x, c.y, c.z)]),
        )
    });
    println!(
        "\nbunny {} triangles, {nx}x{ny}x{nz} samples (median of runs after a warm-up run: 9 / 5 / 5, bake only, {} threads)",
        mesh.triangles.len(),
        rayon::current_num_threads()
    );
    println!("| | time | max error (voxel) | p99 (voxel) | sign errors |");
    println!("|---|---|---|---|---|");
    let mut rows = vec![
        ("penumbra_sdf", t_ours, &e_ours),
        ("mesh_to_sdf 0.4", t_theirs, &e_theirs),
    ];
    if let Some((t, e)) = &igl {
        rows.push(("libigl 2.6 (FWN sign, python)", *t, e));
    }
    for (name, t, e) in rows {
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
    if let Some((t, _)) = &igl {
        println!(
            "speed-up over libigl: {:.2}x",
            t.as_secs_f64() / t_ours.as_secs_f64()
        );
    }
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
        for n in [32, 64, 128, 256] {
            let runs = if n >= 256 { 1 } else { 2 };
            let (t, b) = time(|| bake(&mesh, &settings(n), None).unwrap(), runs);
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

fn bricks(_c: &mut Criterion) {
    let Some(mesh) = bunny() else { return };
    let (tris, _) = mesh.validate().unwrap();
    println!(
        "\nbunny as sparse bricks (band {DEFAULT_BAND_VOXELS} voxels; errors in voxels against f64 brute force, 3,000 random samples):"
    );
    println!(
        "| n | dense bytes | bricks bytes | ratio | bricking time | dense max / p99 | bricks max / p99 |"
    );
    println!("|---|---|---|---|---|---|---|");
    for n in [64, 128, 256] {
        let v = bake(&mesh, &settings(n), None).unwrap().volume;
        let runs = if n >= 256 { 3 } else { 5 };
        let (t, b) = time(|| BrickedVolume::from_volume(&v, DEFAULT_BAND_VOXELS), runs);
        let h = v.voxel_size;
        let dense = errors(&tris, mesh.origin, &v, |c| v.get(c.x, c.y, c.z));
        let sparse = errors(&tris, mesh.origin, &v, |c| b.sample_voxels(c.as_vec3()) * h);
        println!(
            "| {n} | {} | {} | {:.3} | {:.1} ms | {:.3} / {:.3} | {:.3} / {:.3} |",
            b.dense_bytes(),
            b.bytes(),
            b.bytes() as f64 / b.dense_bytes() as f64,
            t.as_secs_f64() * 1e3,
            dense.max,
            dense.p99,
            sparse.max,
            sparse.p99
        );
    }
}

criterion_group!(benches, comparison, scaling, bricks);
criterion_main!(benches);
