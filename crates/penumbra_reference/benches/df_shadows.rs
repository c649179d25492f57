//! Distance-field shadows: run time against error.
//!
//! Two scenes, every pixel of a 96×96 view: a Cornell box (2 m) lit by a sphere light
//! under its ceiling, its two boxes baked to SDFs; and the Stanford bunny (scaled to
//! ≈ 1 m) on a plane under a 3° sun. Each pixel's visibility comes from the mask pass's
//! CPU model (`penumbra_reference::shadow_mask`, equal to the GPU pass on lavapipe:
//! `bevy_penumbra_df/tests/shadow_mask_gpu.rs`) and is compared with Monte Carlo ground
//! truth traced on the triangles (12 × 12 stratified rays toward the light's disc; those
//! below the surface's tangent plane count as blocked).
//! Swept: steps per object and SDF resolution (samples along the longest axis), traced
//! at full and at half resolution (bilateral upsample); and, around the defaults, the
//! shaping exponent and the world-space bias.
//!
//! Error: mean |model − truth| over the pixels either side puts in shadow or penumbra
//! (`< 0.99`), and over all pixels. Cost: distance evaluations per pixel (the GPU pass's
//! work, deterministic: the Pareto front is taken on it) and the model's time over the
//! whole view, one thread, median of 3 (criterion times the defaults).
//! Writes `target/penumbra_bench/df_shadows.{md,csv}`.
//!
//! `cargo bench -p penumbra_reference --bench df_shadows` (needs `../shared/meshes`).

#![allow(missing_docs, reason = "criterion_group! generates undocumented items")]

#[path = "support/mod.rs"]
mod support;

use criterion::{Criterion, criterion_group};
use glam::{Affine3A, Vec3};
use penumbra_df_core::cull::CameraOrigin;
use penumbra_df_core::object::{CasterShape, ObjectRecord, flags};
use penumbra_df_core::shadow::{ShadowLight, ShadowLightKind};
use penumbra_reference::camera::PerspectiveCamera;
use penumbra_reference::df::Atlas;
use penumbra_reference::df_shadow::{
    AreaLight, Occluder, ShadowSettings, TriangleOccluder, monte_carlo_visibility,
};
use penumbra_reference::shadow_mask::{
    ReceiverNormal, pack_gbuffer_normal, pixel_visibility_counted, receiver_normal,
    unpack_gbuffer_normal, upsample,
};
use penumbra_sdf::BakeSettings;
use penumbra_sdf::geometry::Aabb;
use penumbra_sdf::grid::GridPolicy;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;
use support::{Placed, world_triangles};

const SIZE: u32 = 96;
const MC: u32 = 12;
const STEPS: [u32; 5] = [8, 16, 32, 64, 128];
const RESOLUTIONS: [u32; 4] = [16, 32, 64, 128];
/// `DistanceFieldShadows::default()`.
const DEFAULT_STEPS: u32 = 64;
const DEFAULT_BIAS: f32 = 0.04;
const BIASES: [f32; 5] = [0.01, 0.02, 0.04, 0.06, 0.08];
const DEFAULT_SHAPING: f32 = 1.25;
/// Shaping costs nothing, so the default must be the best one at its work: swept in
/// steps of 0.05 around it (coarser ones show the curve's shape).
const SHAPINGS: [f32; 10] = [2.0, 1.5, 1.4, 1.35, 1.3, 1.25, 1.2, 1.15, 1.1, 1.0];

struct Scene {
    name: &'static str,
    /// Meshes baked to SDFs (the sweep's resolution applies).
    baked: Vec<Placed>,
    /// Analytic casters (walls), exact in both the model and the truth.
    analytic: Vec<(CasterShape, Affine3A)>,
    light: AreaLight,
    camera: PerspectiveCamera,
    /// World points seen by the pixels (`None`: background).
    points: Vec<Option<Vec3>>,
    /// Their surfaces' unit normals, facing the camera (the hit triangle's; zero for
    /// the background), as the G-buffer stores them.
    normals: Vec<Vec3>,
    /// What the mask pass knows of each normal from the depth buffer about it
    /// (`shadow_mask::receiver_normal` on the view's points: flat-shaded at all of them
    /// but where a neighbour is another face along both sides of an axis).
    receivers: Vec<ReceiverNormal>,
    truth: Vec<f32>,
    /// The plugin's default bake of the first mesh: samples along its longest axis.
    default_resolution: u32,
}

/// Traces the view on the triangles and computes the ground truth once per scene.
fn finish_scene(mut scene: Scene) -> Scene {
    let triangles = world_triangles(&scene.baked, &scene.analytic);
    let tris = TriangleOccluder::new(&triangles);
    let bvh = penumbra_sdf::bvh::Bvh::build(&triangles);
    let settings = ShadowSettings {
        max_distance: 30.0,
        max_steps: DEFAULT_STEPS,
        // Truth rays start just off the surface (the model's bias is a setting).
        bias: 1e-3,
    };
    scene.points = (0..SIZE * SIZE)
        .map(|i| {
            let ray = scene
                .camera
                .ray((i % SIZE) as f32 + 0.5, (i / SIZE) as f32 + 0.5);
            let plane = if ray.dir.y < 0.0 {
                -ray.origin.y / ray.dir.y
            } else {
                f32::INFINITY
            };
            let t = tris
                .first_hit(ray.origin, ray.dir, 100.0)
                .map_or(plane, |t| t.min(plane));
            t.is_finite().then(|| ray.origin + ray.dir * t)
        })
        .collect();
    // The surfaces' geometric normals (facing the camera); the model reads them through
    // the G-buffer's encoding, the truth keeps light below their tangent planes out.
    let geometric: Vec<Vec3> = (0..SIZE * SIZE)
        .map(|i| {
            let ray = scene
                .camera
                .ray((i % SIZE) as f32 + 0.5, (i / SIZE) as f32 + 0.5);
            let Some(p) = scene.points[i as usize] else {
                return Vec3::ZERO;
            };
            let n = match bvh.ray_nearest(ray.origin, ray.dir, 0.0, 100.0) {
                Some((t, _, k)) if (ray.origin + ray.dir * t - p).length() < 1e-4 => {
                    let [a, b, c] = triangles[k as usize];
                    (b - a).cross(c - a).normalize_or_zero()
                }
                _ => Vec3::Y, // the ground plane
            };
            if n.dot(ray.dir) > 0.0 { -n } else { n }
        })
        .collect();
    scene.normals = geometric
        .iter()
        .map(|&n| unpack_gbuffer_normal(pack_gbuffer_normal(n)))
        .collect();
    let eye = scene.camera.world_from_view.w_axis.truncate();
    let at = |x: i64, y: i64| -> Option<Vec3> {
        let inside = (0..i64::from(SIZE)).contains(&x) && (0..i64::from(SIZE)).contains(&y);
        inside
            .then(|| scene.points[(y * i64::from(SIZE) + x) as usize].map(|p| p - eye))
            .flatten()
    };
    scene.receivers = (0..i64::from(SIZE * SIZE))
        .map(|i| {
            let (x, y) = (i % i64::from(SIZE), i / i64::from(SIZE));
            let normal = scene.normals[i as usize];
            at(x, y).map_or(ReceiverNormal::from(normal), |p| {
                let neighbours = [[at(x - 1, y), at(x + 1, y)], [at(x, y - 1), at(x, y + 1)]];
                receiver_normal(p, normal, neighbours)
            })
        })
        .collect();
    let occluders: [&dyn Occluder; 1] = [&tris];
    scene.truth = scene
        .points
        .iter()
        .zip(&geometric)
        .map(|(p, &n)| {
            p.map_or(1.0, |p| {
                monte_carlo_visibility(&occluders, p, n, &scene.light, &settings, MC)
            })
        })
        .collect();
    scene
}

fn bunny() -> Option<Scene> {
    // The mesh a game would have.
    let mesh = support::bunny_mesh()?;
    let world_from_local = Affine3A::IDENTITY;
    let mut b = Aabb::EMPTY;
    mesh.positions.iter().for_each(|&p| b.grow(p));
    let default_resolution = GridPolicy::default()
        .resolve(&b)
        .map(|g| g.dims.max_element() - 4)
        .unwrap_or(0);
    Some(finish_scene(Scene {
        name: "bunny on a plane, 3° sun",
        baked: vec![Placed {
            mesh,
            world_from_local,
        }],
        analytic: Vec::new(),
        light: AreaLight::Directional {
            to_light: Vec3::new(0.55, 0.7, 0.45).normalize(),
            angular_diameter: 3f32.to_radians(),
        },
        camera: PerspectiveCamera::looking_at(
            Vec3::new(0.4, 1.4, 2.2),
            Vec3::new(-0.25, 0.25, -0.2),
            std::f32::consts::FRAC_PI_4,
            SIZE,
            SIZE,
        ),
        points: Vec::new(),
        normals: Vec::new(),
        receivers: Vec::new(),
        truth: Vec::new(),
        default_resolution,
    }))
}

fn cornell() -> Scene {
    let (analytic, baked) = support::cornell_box();
    let mut b = Aabb::EMPTY;
    baked[0].mesh.positions.iter().for_each(|&p| b.grow(p));
    let default_resolution = GridPolicy::default()
        .resolve(&b)
        .map(|g| g.dims.max_element() - 4)
        .unwrap_or(0);
    finish_scene(Scene {
        name: "Cornell box, sphere light r = 0.2 m",
        baked,
        analytic,
        light: AreaLight::Sphere {
            center: Vec3::new(0.0, 1.7, 0.1),
            radius: 0.2,
        },
        camera: PerspectiveCamera::looking_at(
            Vec3::new(0.0, 1.0, 3.3),
            Vec3::new(0.0, 0.9, 0.0),
            0.75,
            SIZE,
            SIZE,
        ),
        points: Vec::new(),
        normals: Vec::new(),
        receivers: Vec::new(),
        truth: Vec::new(),
        default_resolution,
    })
}

/// The scene's object records and atlas with its meshes baked at `resolution`.
fn records(scene: &Scene, resolution: u32) -> (Vec<ObjectRecord>, Atlas) {
    let live = flags::LIVE | flags::CASTS_SHADOWS | flags::VISIBLE;
    let settings = BakeSettings::longest_axis(resolution);
    support::build_records(&scene.baked, &scene.analytic, &settings, live)
}

fn model_light(scene: &Scene, camera: &CameraOrigin, c: Config) -> ShadowLight {
    let (kind, source) = match scene.light {
        AreaLight::Directional {
            to_light,
            angular_diameter,
        } => (
            ShadowLightKind::Directional(to_light),
            (0.5 * angular_diameter).tan(),
        ),
        AreaLight::Sphere { center, radius } => (
            ShadowLightKind::Positional(camera.relative([0, 0, 0], center)),
            radius,
        ),
    };
    ShadowLight {
        kind,
        source,
        max_distance: 30.0,
        bias: c.bias,
        shaping: c.shaping,
        range: 30.0,
        max_steps: c.steps,
        max_view_distance: f32::INFINITY,
        spot: None,
    }
}

/// One configuration of the sweep.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Config {
    steps: u32,
    shaping: f32,
    bias: f32,
    half: bool,
    /// The surface's own shadow from the G-buffer normal (`shadow_mask::horizon`).
    horizon: bool,
}

impl Config {
    /// The resolution column: `full` or `half`, and whether the own-shadow term is off.
    fn label(&self) -> String {
        let resolution = if self.half { "half" } else { "full" };
        if self.horizon {
            resolution.to_string()
        } else {
            format!("{resolution}, no own shadow")
        }
    }
}

impl Config {
    const DEFAULT: Config = Config {
        steps: DEFAULT_STEPS,
        shaping: DEFAULT_SHAPING,
        bias: DEFAULT_BIAS,
        half: false,
        horizon: true,
    };
}

/// The view's mask by the model (traced at every pixel, or at pixels `(2i, 2j)` then
/// upsampled bilaterally), and its distance evaluations.
fn mask(scene: &Scene, records: &[ObjectRecord], atlas: &Atlas, c: Config) -> (Vec<f32>, u64) {
    let eye = scene.camera.world_from_view.w_axis.truncate();
    let camera = CameraOrigin::at(eye).expect("finite");
    let light = model_light(scene, &camera, c);
    let mut evaluations = 0u64;
    let mut trace = |i: usize| {
        scene.points[i].map_or(1.0, |p| {
            let p = camera.relative([0, 0, 0], p);
            let normal = if c.horizon {
                scene.receivers[i]
            } else {
                ReceiverNormal::default()
            };
            let (v, n) = pixel_visibility_counted(records, atlas, &camera, p, normal, &light);
            evaluations += n as u64;
            v
        })
    };
    if !c.half {
        let mask = (0..scene.points.len()).map(&mut trace).collect();
        return (mask, evaluations);
    }
    let half = glam::UVec2::new(SIZE.div_ceil(2), SIZE.div_ceil(2));
    let traced: Vec<f32> = (0..half.x * half.y)
        .map(|i| {
            let (x, y) = (2 * (i % half.x), 2 * (i / half.x));
            trace((y * SIZE + x) as usize)
        })
        .collect();
    let distance: Vec<f32> = scene
        .points
        .iter()
        .map(|p| p.map_or(0.0, |p| (p - eye).length()))
        .collect();
    let full = glam::UVec2::splat(SIZE);
    (upsample(&traced, half, &distance, full), evaluations)
}

/// (mean error over shadowed-or-penumbra pixels, their count, mean over all pixels).
fn errors(scene: &Scene, mask: &[f32]) -> (f32, usize, f32) {
    let (mut affected, mut n_affected, mut all, mut n) = (0.0f32, 0, 0.0f32, 0);
    for ((p, m), t) in scene.points.iter().zip(mask).zip(&scene.truth) {
        if p.is_none() {
            continue;
        }
        let e = (m - t).abs();
        all += e;
        n += 1;
        if *m < 0.99 || *t < 0.99 {
            affected += e;
            n_affected += 1;
        }
    }
    (
        affected / n_affected.max(1) as f32,
        n_affected,
        all / n.max(1) as f32,
    )
}

struct Row {
    scene: &'static str,
    resolution: u32,
    config: Config,
    /// Distance evaluations per pixel (the work; deterministic).
    evaluations: f64,
    seconds: f64,
    error: f32,
    affected: usize,
    error_all: f32,
    pareto: bool,
    default: bool,
}

/// The configurations swept at one SDF resolution: steps (full and half resolution),
/// shapings and biases, each around the defaults.
fn configs() -> Vec<Config> {
    let mut out = Vec::new();
    for &steps in &STEPS {
        for half in [false, true] {
            out.push(Config {
                steps,
                half,
                ..Config::DEFAULT
            });
        }
    }
    for &shaping in SHAPINGS.iter().filter(|&&s| s != DEFAULT_SHAPING) {
        out.push(Config {
            shaping,
            ..Config::DEFAULT
        });
    }
    for &bias in BIASES.iter().filter(|&&b| b != DEFAULT_BIAS) {
        out.push(Config {
            bias,
            ..Config::DEFAULT
        });
    }
    for half in [false, true] {
        out.push(Config {
            half,
            horizon: false,
            ..Config::DEFAULT
        });
    }
    out
}

/// `a` dominates `b`: no more work and no more error, and less of one.
fn dominates(a: (f64, f32), b: (f64, f32)) -> bool {
    a.0 <= b.0 && a.1 <= b.1 && (a.0 < b.0 || a.1 < b.1)
}

fn sweep(scene: &Scene) -> Vec<Row> {
    let mut rows = Vec::new();
    let mut resolutions = RESOLUTIONS.to_vec();
    resolutions.push(scene.default_resolution);
    resolutions.sort_unstable();
    resolutions.dedup();
    for &resolution in &resolutions {
        let (records, atlas) = records(scene, resolution);
        for config in configs() {
            let mut times = Vec::new();
            let (mut m, mut evaluations) = (Vec::new(), 0);
            for _ in 0..3 {
                let start = Instant::now();
                (m, evaluations) = mask(scene, &records, &atlas, config);
                times.push(start.elapsed().as_secs_f64());
            }
            times.sort_by(f64::total_cmp);
            let (error, affected, error_all) = errors(scene, &m);
            rows.push(Row {
                scene: scene.name,
                resolution,
                config,
                evaluations: evaluations as f64 / (SIZE * SIZE) as f64,
                seconds: times[1],
                error,
                affected,
                error_all,
                pareto: false,
                default: resolution == scene.default_resolution && config == Config::DEFAULT,
            });
        }
    }
    let flags: Vec<bool> = rows
        .iter()
        .map(|r| {
            !rows
                .iter()
                .filter(|o| o.scene == r.scene)
                .any(|o| dominates((o.evaluations, o.error), (r.evaluations, r.error)))
        })
        .collect();
    for (r, f) in rows.iter_mut().zip(flags) {
        r.pareto = f;
    }
    rows
}

fn write_tables(rows: &[Row]) {
    let mut md = String::from(
        "| scene | SDF samples (longest axis) | steps | shaping | bias (m) | resolution | distance evaluations / pixel | time (ms, 96², 1 thread) | mean error, shadowed or penumbra | pixels | mean error, all | Pareto | default |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let mut csv = String::from(
        "scene,sdf_resolution,steps,shaping,bias,half,own_shadow,evaluations_per_pixel,seconds,error_affected,affected_pixels,error_all,pareto,default\n",
    );
    for r in rows {
        let c = r.config;
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {:.2} | {:.1} | {:.4} | {} | {:.4} | {} | {} |",
            r.scene,
            r.resolution,
            c.steps,
            c.shaping,
            c.bias,
            c.label(),
            r.evaluations,
            r.seconds * 1e3,
            r.error,
            r.affected,
            r.error_all,
            if r.pareto { "✓" } else { "" },
            if r.default { "default" } else { "" }
        );
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{},{:.3},{:.6},{:.5},{},{:.5},{},{}",
            r.scene,
            r.resolution,
            c.steps,
            c.shaping,
            c.bias,
            c.half,
            c.horizon,
            r.evaluations,
            r.seconds,
            r.error,
            r.affected,
            r.error_all,
            r.pareto,
            r.default
        );
    }
    println!("{md}");
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/penumbra_bench");
    if std::fs::create_dir_all(&dir).is_ok() {
        let _ = std::fs::write(dir.join("df_shadows.md"), &md);
        let _ = std::fs::write(dir.join("df_shadows.csv"), &csv);
        println!("wrote {}", dir.join("df_shadows.{md,csv}").display());
    }
}

/// Both scenes at their default SDF resolution: per configuration, the summed work and
/// the mean of the two errors, with the Pareto front — where the defaults are chosen.
fn combined(rows: &[Row]) {
    let at_default: Vec<&Row> = rows
        .iter()
        .filter(|r| {
            rows.iter()
                .any(|d| d.default && d.scene == r.scene && d.resolution == r.resolution)
        })
        .collect();
    let scenes = rows.iter().filter(|r| r.default).count();
    let table: Vec<(Config, f64, f32)> = configs()
        .into_iter()
        .filter_map(|c| {
            let rs: Vec<&&Row> = at_default.iter().filter(|r| r.config == c).collect();
            (rs.len() == scenes).then(|| {
                let work = rs.iter().map(|r| r.evaluations).sum::<f64>();
                let error = rs.iter().map(|r| r.error).sum::<f32>() / scenes as f32;
                (c, work, error)
            })
        })
        .collect();
    println!("Both scenes at their default SDF resolution:");
    println!(
        "| steps | shaping | bias (m) | resolution | distance evaluations / pixel (sum) | mean error (shadowed or penumbra) | Pareto | default |\n|---|---|---|---|---|---|---|---|"
    );
    for &(c, work, error) in &table {
        let front = !table
            .iter()
            .any(|&(_, w, e)| dominates((w, e), (work, error)));
        println!(
            "| {} | {} | {} | {} | {work:.2} | {error:.4} | {} | {} |",
            c.steps,
            c.shaping,
            c.bias,
            c.label(),
            if front { "✓" } else { "" },
            if c == Config::DEFAULT { "default" } else { "" }
        );
    }
}

fn bench(c: &mut Criterion) {
    let mut scenes = vec![cornell()];
    scenes.extend(bunny());
    let mut rows = Vec::new();
    for scene in &scenes {
        println!(
            "{}: the plugin's default bake has {} samples along the longest axis",
            scene.name, scene.default_resolution
        );
        rows.extend(sweep(scene));
    }
    write_tables(&rows);
    combined(&rows);
    // Where the defaults' error lies: on the floor (y = 0) or on the other surfaces (the
    // casters themselves, the walls).
    for scene in &scenes {
        let (records, atlas) = records(scene, scene.default_resolution);
        let (m, _) = mask(scene, &records, &atlas, Config::DEFAULT);
        let mut sums = [(0.0f32, 0usize); 2];
        for ((p, v), t) in scene.points.iter().zip(&m).zip(&scene.truth) {
            if let Some(p) = p
                && (*v < 0.99 || *t < 0.99)
            {
                let s = &mut sums[usize::from(p.y >= 1e-3)];
                s.0 += (v - t).abs();
                s.1 += 1;
            }
        }
        let mean = |(sum, n): (f32, usize)| sum / n.max(1) as f32;
        println!(
            "{}, defaults, shadowed or penumbra pixels: floor {:.4} over {}, other surfaces \
             {:.4} over {}",
            scene.name,
            mean(sums[0]),
            sums[0].1,
            mean(sums[1]),
            sums[1].1
        );
    }
    for scene in &scenes {
        let (records, atlas) = records(scene, scene.default_resolution.max(2));
        c.bench_function(&format!("df_shadows/{}/defaults", scene.name), |b| {
            b.iter(|| mask(scene, &records, &atlas, Config::DEFAULT));
        });
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}

fn main() {
    benches();
    Criterion::default().final_summary();
}
