//! Bake accuracy against exact f64 ground truth (brute-force distance and winding
//! number): |error| ≤ 0.1 voxel everywhere, p99 ≤ 0.05 voxel, and no sign errors on
//! closed meshes beyond one voxel from the surface, nor on open ones wherever the
//! winding number is decisive (|w − ½| > 0.3).

use glam::{UVec3, Vec3};
use penumbra_sdf::{BakeSettings, SdfVolume, TriMesh, bake, exact, obj, shapes};
use std::path::PathBuf;

/// Statistics of a bake against ground truth, in voxels.
#[derive(Debug, Default)]
struct Accuracy {
    samples: usize,
    max_error: f64,
    p99_error: f64,
    sign_errors: usize,
    sign_checked: usize,
}

/// Compares the samples in `which` (all when `None`) with ground truth.
fn accuracy(
    mesh: &TriMesh,
    volume: &SdfVolume,
    closed: bool,
    which: Option<Vec<UVec3>>,
) -> Accuracy {
    let (tris, _) = mesh.validate().unwrap();
    let dims = volume.dims;
    let cells: Vec<UVec3> = which.unwrap_or_else(|| {
        (0..dims.z)
            .flat_map(|k| {
                (0..dims.y).flat_map(move |j| (0..dims.x).map(move |i| UVec3::new(i, j, k)))
            })
            .collect()
    });
    let h = volume.voxel_size as f64;
    let mut errors = Vec::with_capacity(cells.len());
    let mut acc = Accuracy::default();
    for c in cells {
        // Validated triangles are relative to the mesh's origin.
        let p = volume.position(c.x, c.y, c.z) - mesh.origin;
        let v = volume.get(c.x, c.y, c.z) as f64;
        let d = exact::distance(p, &tris);
        errors.push((v.abs() - d).abs() / h);
        let w = exact::winding_number(p, &tris);
        // On the surface itself (d = 0) both signs are exact: ±0.
        let on_surface = d <= 1e-4 * h;
        let decisive = !on_surface && if closed { d > h } else { (w - 0.5).abs() > 0.3 };
        if decisive {
            acc.sign_checked += 1;
            if (v < 0.0) != (w > 0.5) {
                acc.sign_errors += 1;
            }
        }
    }
    errors.sort_by(f64::total_cmp);
    acc.samples = errors.len();
    acc.max_error = *errors.last().unwrap();
    acc.p99_error = errors[(errors.len() * 99).div_ceil(100) - 1];
    acc
}

fn settings(n: u32) -> BakeSettings {
    BakeSettings::longest_axis(n)
}

fn assert_accurate(name: &str, a: &Accuracy) {
    println!("{name}: {a:?}");
    assert!(
        a.max_error <= 0.1,
        "{name}: max error {} voxel",
        a.max_error
    );
    assert!(
        a.p99_error <= 0.05,
        "{name}: p99 error {} voxel",
        a.p99_error
    );
    assert_eq!(
        a.sign_errors, 0,
        "{name}: {} sign errors of {}",
        a.sign_errors, a.sign_checked
    );
    assert!(a.sign_checked > 0);
}

#[test]
fn procedural_meshes_are_exact_everywhere() {
    let cases: Vec<(&str, TriMesh, bool)> = vec![
        ("sphere", shapes::sphere(1.0, 48, 24), true),
        ("cuboid", shapes::cuboid(Vec3::new(1.0, 0.6, 0.3)), true),
        ("torus", shapes::torus(1.0, 0.35, 48, 24), true),
        ("thin plate", shapes::thin_plate(1.0, 0.8, 0.01), true),
        ("open bowl", shapes::open_bowl(1.0, 48, 12), false),
        ("intersecting soup", shapes::intersecting_soup(), false),
    ];
    for (name, mesh, closed) in cases {
        let baked = bake(&mesh, &settings(32), None).unwrap();
        let a = accuracy(&mesh, &baked.volume, closed, None);
        assert_accurate(name, &a);
    }
}

/// `../shared/meshes` beside the checkout, or `None` after reporting `test` as skipped
/// (a failure under CI).
pub fn shared_meshes(test: &str) -> Option<PathBuf> {
    penumbra_testkit::shared_dir(test, env!("CARGO_MANIFEST_DIR"), "meshes")
}

/// Deterministic pseudo-random sample cells.
fn random_cells(dims: UVec3, n: usize, seed: u64) -> Vec<UVec3> {
    let mut s = seed;
    let mut next = move |m: u32| {
        s = s
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((s >> 33) % m as u64) as u32
    };
    (0..n)
        .map(|_| UVec3::new(next(dims.x), next(dims.y), next(dims.z)))
        .collect()
}

#[test]
fn shared_meshes_are_exact_on_random_samples() {
    let Some(dir) = shared_meshes("shared_meshes_are_exact_on_random_samples") else {
        return;
    };
    for (file, closed) in [
        ("spot.obj", true),
        ("teapot.obj", false),
        ("stanford-bunny.obj", false),
    ] {
        let text = std::fs::read_to_string(dir.join(file)).unwrap();
        let mesh = obj::parse_obj(&text).unwrap();
        let baked = bake(&mesh, &settings(64), None).unwrap();
        let cells = random_cells(baked.volume.dims, 3000, 7);
        let a = accuracy(&mesh, &baked.volume, closed, Some(cells));
        assert_accurate(file, &a);
    }
}

#[test]
fn output_is_identical_for_any_thread_count() {
    let mesh = shapes::intersecting_soup();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let four = rayon::ThreadPoolBuilder::new()
        .num_threads(4)
        .build()
        .unwrap();
    let a = one.install(|| bake(&mesh, &settings(40), None).unwrap().volume);
    let b = four.install(|| bake(&mesh, &settings(40), None).unwrap().volume);
    assert!(
        a.data
            .iter()
            .zip(&b.data)
            .all(|(x, y)| x.to_bits() == y.to_bits())
    );
    assert_eq!(a, b);
}

/// A plate thinner than a voxel, placed between sample layers, and a single-sided quad
/// (no inside at all) both keep negative samples next to every point of their surface.
#[test]
fn thin_features_keep_a_negative_sample() {
    // Tilted so that no sample layer lies in its plane.
    let tilt = glam::Quat::from_rotation_x(0.3) * glam::Quat::from_rotation_z(0.2);
    let quad = TriMesh {
        positions: [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .map(|(x, z)| tilt * Vec3::new(x, 0.0, z))
            .to_vec(),
        triangles: vec![[0, 2, 1], [0, 3, 2]],
        ..Default::default()
    };
    let mut plate = shapes::thin_plate(1.0, 1.0, 0.004);
    for p in &mut plate.positions {
        p.y += 0.0123; // off the sample lattice
    }
    for (name, mesh) in [("plate", plate), ("quad", quad)] {
        let baked = bake(&mesh, &settings(33), None).unwrap();
        let v = &baked.volume;
        assert!(
            baked.thin_feature_samples > 0,
            "{name}: the guard had nothing to do"
        );
        // Every surface point's cell has a sample ≤ 0.
        let (tris, _) = mesh.validate().unwrap();
        for t in &tris {
            for (u, w) in [(0.2, 0.3), (0.5, 0.25), (0.1, 0.8)] {
                let s = t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * w;
                let g = ((s.as_dvec3() - v.origin) / v.voxel_size as f64)
                    .floor()
                    .as_uvec3();
                let inside = (0..8u32)
                    .any(|c| v.get(g.x + (c & 1), g.y + ((c >> 1) & 1), g.z + (c >> 2)) <= 0.0);
                assert!(inside, "{name}: no negative sample around {s}");
            }
        }
        // Distances keep their exact magnitude.
        let a = accuracy(&mesh, v, true, None);
        assert!(a.max_error <= 0.1, "{name}: {a:?}");
    }
}

/// The baker decides most signs from coarser winding-number grids (a heuristic): on
/// every sample of the real meshes it must agree with a direct fast-winding-number
/// evaluation wherever that is decisive (|w − ½| > 0.3). The thin-feature guard, which
/// legitimately flips samples next to thin surfaces, is off here.
#[test]
fn hierarchical_signs_match_direct_winding_numbers_everywhere() {
    let Some(dir) = shared_meshes("hierarchical_signs_match_direct_winding_numbers_everywhere")
    else {
        return;
    };
    for file in ["spot.obj", "teapot.obj", "stanford-bunny.obj"] {
        let text = std::fs::read_to_string(dir.join(file)).unwrap();
        let mesh = obj::parse_obj(&text).unwrap();
        let raw_signs = BakeSettings {
            keep_thin_features: false,
            ..settings(64)
        };
        let baked = bake(&mesh, &raw_signs, None).unwrap();
        let v = &baked.volume;
        let (tris, _) = mesh.validate().unwrap();
        let bvh = penumbra_sdf::bvh::Bvh::build(&tris);
        let (mut checked, mut wrong) = (0usize, 0usize);
        for k in 0..v.dims.z {
            for j in 0..v.dims.y {
                for i in 0..v.dims.x {
                    let d = v.get(i, j, k);
                    let w = bvh.winding_number((v.position(i, j, k) - mesh.origin).as_vec3());
                    if d != 0.0 && (w - 0.5).abs() > 0.3 {
                        checked += 1;
                        wrong += usize::from((d < 0.0) != (w > 0.5));
                    }
                }
            }
        }
        println!("{file}: {wrong} sign disagreements of {checked} samples");
        assert!(checked as f64 > 0.9 * v.data.len() as f64);
        assert_eq!(wrong, 0, "{file}");
    }
}
