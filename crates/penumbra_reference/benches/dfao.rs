//! Distance-field ambient occlusion: run time against error.
//!
//! Three scenes, every pixel of a 96×96 view: a Cornell box (2 m; its two boxes baked to
//! SDFs, the walls analytic boxes); the Stanford bunny (scaled to ≈ 1 m, baked) on an
//! analytic ground plane; and the scene of Bevy's depth-of-field example
//! (`../shared/scenes/DepthOfFieldExample.glb`, read through `penumbra_sdf`'s glTF input:
//! a 6.5 m circuit board with eleven spheres and four cubes, each part baked on its own;
//! the board, a single quad with no inside, becomes a 1 cm analytic box under its surface
//! in the model and the truth alike). SDFs are baked with the plugin's default grid (32
//! samples per metre). Each pixel's AO and bent normal come from the trace pass's CPU
//! model (`penumbra_reference::dfao::trace_view`: 8×8 tiles, two depth ranges; at a
//! divisor above 1 one pixel in `divisor²` is traced and `dfao::upsample` fills in the
//! rest with depth and normal weights) and are compared with Monte Carlo ground truth on
//! the triangles (`dfao::monte_carlo_ao`: 48 × 48 stratified cosine-weighted rays,
//! limited to the same max distance). The G-buffer normals are the triangles' own
//! (facing the camera), through the G-buffer's 24-bit encoding.
//!
//! The max occlusion distance is per scene, about half the extent of the geometry that
//! occludes (the component's default, 10 m, puts each of these scenes wholly in reach):
//! 1 m in the 2 m Cornell box, 0.5 m around the 1 m bunny, 1.5 m on the board (its
//! objects are at most 1 m across and about 1.5 m apart; half the board, 3.2 m, would
//! make every pixel of it see most of them).
//! Swept: cone count × steps per cone × trace divisor; and, around the defaults (9 cones,
//! 16 steps, divisor 2, bias 0.02 m, shaping `CONE_SHAPING`), the shaping exponent (at
//! every cone count) and the bias.
//!
//! Error: mean |AO − truth| over every surface pixel (and its sign: mean AO − truth), and
//! over those the truth occludes (AO < 0.99); the bent normal's mean angle to the
//! truth's, radians (same two sets).
//! Cost: distance evaluations per view pixel (the marches' work, without the tile tests'
//! one sample per object and range; deterministic: the Pareto front is taken on it
//! against the mean AO error over all surface pixels) and
//! the model's time over the view (trace and upsample), one thread, median of 3
//! (criterion times the defaults). Then the shaping sweep once more at the component's
//! default max distance, 10 m, against truth traced to 10 m: the best shaping depends on
//! how much of the scene is in reach. Writes `target/penumbra_bench/dfao.{md,csv}`.
//!
//! Every image is one frame of the trace's jitter ([`ao_image`]'s `frame`, 0 here); a
//! temporal filter's sweep accumulates frames `0..N` of it and scores the filtered image
//! against the same truth, with the frame count one more field of [`Config`].
//!
//! `cargo bench -p penumbra_reference --bench dfao` (needs `../shared/meshes` and
//! `../shared/scenes`; a scene whose file is missing is skipped, with a message).

#![allow(missing_docs, reason = "criterion_group! generates undocumented items")]

use criterion::{Criterion, criterion_group};
use glam::{Affine3A, Mat3, Mat4, Quat, UVec2, UVec3, Vec3, Vec4};
use penumbra_df_core::ao::{AoTrace, CONE_SHAPING, jitter, trace_size};
use penumbra_df_core::atlas::AtlasRegion;
use penumbra_df_core::cull::CameraOrigin;
use penumbra_df_core::object::{CasterShape, ObjectDesc, ObjectRecord, encode, flags};
use penumbra_reference::camera::PerspectiveCamera;
use penumbra_reference::df::Atlas;
use penumbra_reference::dfao::{AoSample, AoView, monte_carlo_ao, trace_view_counted, upsample};
use penumbra_reference::shadow_mask::{pack_gbuffer_normal, unpack_gbuffer_normal};
use penumbra_sdf::bvh::Bvh;
use penumbra_sdf::geometry::Aabb;
use penumbra_sdf::gltf_input::{GltfSelection, load_gltf};
use penumbra_sdf::{BakeSettings, TriMesh, bake, obj, shapes};
use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

const SIZE: u32 = 96;
/// Ground truth: `MC²` rays per pixel.
const MC: u32 = 48;
const CONES: [u32; 5] = [4, 6, 9, 12, 16];
const STEPS: [u32; 5] = [8, 12, 16, 24, 32];
const DIVISORS: [u32; 3] = [1, 2, 4];
/// Shaping costs nothing, so the default must be the best one at its work: swept at
/// every cone count (the others at the defaults).
const SHAPINGS: [f32; 9] = [1.0, 0.5, 0.4, 0.33, 0.3, 0.25, 0.2, 0.15, 0.1];
const BIASES: [f32; 5] = [0.005, 0.01, 0.02, 0.04, 0.08];
/// A flat glTF part becomes a box this thick under its surface.
const SLAB: f32 = 0.01;

/// [`Config`]'s settings, by name.
const FIELDS: [&str; 5] = ["cones", "steps", "divisor", "shaping", "bias"];

/// One configuration of the sweep.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Config {
    cones: u32,
    steps: u32,
    /// Trace resolution divisor (1: every pixel; more: upsampled).
    divisor: u32,
    shaping: f32,
    bias: f32,
}

impl Config {
    /// `DistanceFieldAmbientOcclusion::default()`.
    const DEFAULT: Config = Config {
        cones: 9,
        steps: 16,
        divisor: 2,
        shaping: CONE_SHAPING,
        bias: 0.02,
    };

    fn trace(&self, max_distance: f32) -> AoTrace {
        AoTrace {
            max_distance,
            cone_count: self.cones,
            steps_per_cone: self.steps,
            bias: self.bias,
            shaping: self.shaping,
        }
    }

    /// The settings in the order of [`FIELDS`].
    fn fields(&self) -> [f32; 5] {
        [
            self.cones as f32,
            self.steps as f32,
            self.divisor as f32,
            self.shaping,
            self.bias,
        ]
    }

    /// The defaults with `change` made.
    fn around(change: impl FnOnce(&mut Config)) -> Config {
        let mut c = Config::DEFAULT;
        change(&mut c);
        c
    }

    fn label(&self) -> String {
        format!(
            "{} cones, {} steps, divisor {}, shaping {}, bias {}",
            self.cones, self.steps, self.divisor, self.shaping, self.bias
        )
    }
}

/// A mesh placed in the world: baked for the model, traced for the truth.
struct Placed {
    mesh: TriMesh,
    world_from_local: Affine3A,
}

struct Scene {
    name: String,
    /// The trace's and the truth's max occlusion distance, metres.
    max_distance: f32,
    camera: PerspectiveCamera,
    records: Vec<ObjectRecord>,
    atlas: Atlas,
    /// Reverse-Z depth per pixel (0: background).
    depth: Vec<f32>,
    /// The G-buffer's unit normals (zero for the background).
    normals: Vec<Vec3>,
    /// Distance from the camera per pixel (0: background), for the upsample.
    distance: Vec<f32>,
    view_from_clip: Mat4,
    world_from_view: Mat3,
    /// Ground truth per pixel (`None`: background).
    truth: Vec<Option<AoSample>>,
}

fn shared() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared")
}

fn world_triangles(baked: &[Placed], analytic: &[(CasterShape, Affine3A)]) -> Vec<[Vec3; 3]> {
    let mut tris = Vec::new();
    for p in baked {
        let (t, _) = p.mesh.validate().expect("valid mesh");
        tris.extend(
            t.into_iter()
                .map(|t| t.map(|v| p.world_from_local.transform_point3(v))),
        );
    }
    for (shape, m) in analytic {
        let local = match shape {
            CasterShape::Cuboid { half_extents } => {
                shapes::cuboid(*half_extents).validate().expect("box").0
            }
            // 100 m of the plane: beyond every view and max distance here.
            CasterShape::Plane => {
                let c = |x: f32, z: f32| Vec3::new(x, 0.0, z) * 50.0;
                vec![
                    [c(-1.0, -1.0), c(-1.0, 1.0), c(1.0, 1.0)],
                    [c(-1.0, -1.0), c(1.0, 1.0), c(1.0, -1.0)],
                ]
            }
            other => panic!("no triangles for {other:?}"),
        };
        tris.extend(local.into_iter().map(|t| t.map(|v| m.transform_point3(v))));
    }
    tris
}

/// The object records and atlas: the meshes baked with the plugin's default grid, side
/// by side along x, then the analytic shapes.
fn build_records(
    baked: &[Placed],
    analytic: &[(CasterShape, Affine3A)],
) -> (Vec<ObjectRecord>, Atlas) {
    let live = flags::LIVE | flags::CASTS_OCCLUSION | flags::VISIBLE;
    let volumes: Vec<_> = baked
        .iter()
        .map(|p| {
            bake(&p.mesh, &BakeSettings::default(), None)
                .expect("bakes")
                .volume
        })
        .collect();
    let size = UVec3::new(
        volumes.iter().map(|v| v.dims.x).sum(),
        volumes.iter().map(|v| v.dims.y).max().unwrap_or(1),
        volumes.iter().map(|v| v.dims.z).max().unwrap_or(1),
    );
    let mut atlas = Atlas::new(size.max(UVec3::ONE));
    let mut records = Vec::new();
    let mut x = 0;
    for (p, v) in baked.iter().zip(&volumes) {
        let origin = UVec3::new(x, 0, 0);
        let bits: Vec<u16> = v.data.iter().map(|h| h.to_bits()).collect();
        atlas.write(origin, v.dims, &bits);
        records.push(
            encode(&ObjectDesc {
                world_from_local: p.world_from_local,
                shape: CasterShape::Volume {
                    region: AtlasRegion {
                        origin,
                        dims: v.dims,
                    },
                    local_origin: v.origin.as_vec3(),
                    voxel_size: v.voxel_size,
                    margin: v.margin,
                },
                flags: live,
            })
            .expect("encodes"),
        );
        x += v.dims.x;
    }
    for (shape, m) in analytic {
        records.push(
            encode(&ObjectDesc {
                world_from_local: *m,
                shape: *shape,
                flags: live,
            })
            .expect("encodes"),
        );
    }
    (records, atlas)
}

/// Bakes the scene, traces the view on its triangles (depth, G-buffer normals) and
/// computes the ground truth once.
fn finish_scene(
    name: String,
    max_distance: f32,
    baked: Vec<Placed>,
    analytic: Vec<(CasterShape, Affine3A)>,
    camera: PerspectiveCamera,
) -> Scene {
    let start = Instant::now();
    let triangles = world_triangles(&baked, &analytic);
    let bvh = Bvh::build(&triangles);
    let (records, atlas) = build_records(&baked, &analytic);
    let baked_in = start.elapsed().as_secs_f64();
    let eye = camera.world_from_view.w_axis.truncate();
    let world_from_view = Mat3::from_mat4(camera.world_from_view);
    let clip_from_view = Mat4::perspective_infinite_reverse_rh(camera.fov_y, 1.0, 0.1);
    let pixels = (SIZE * SIZE) as usize;
    let (mut depth, mut normals, mut distance) = (
        vec![0.0; pixels],
        vec![Vec3::ZERO; pixels],
        vec![0.0; pixels],
    );
    let mut truth = vec![None; pixels];
    for i in 0..pixels {
        let ray = camera.ray(
            (i as u32 % SIZE) as f32 + 0.5,
            (i as u32 / SIZE) as f32 + 0.5,
        );
        let Some((t, _, k)) = bvh.ray_nearest(ray.origin, ray.dir, 0.0, 200.0) else {
            continue;
        };
        let p = ray.at(t);
        let [a, b, c] = triangles[k as usize];
        let n = (b - a).cross(c - a).normalize_or_zero();
        let n = if n.dot(ray.dir) > 0.0 { -n } else { n };
        let clip = clip_from_view * (world_from_view.transpose() * (p - eye)).extend(1.0);
        depth[i] = clip.z / clip.w;
        normals[i] = unpack_gbuffer_normal(pack_gbuffer_normal(n));
        distance[i] = t;
        truth[i] = Some(monte_carlo_ao(&bvh, p, n, max_distance, MC));
    }
    println!(
        "{name}: {} triangles, {} objects, baked in {baked_in:.1} s, truth in {:.1} s",
        triangles.len(),
        records.len(),
        start.elapsed().as_secs_f64() - baked_in
    );
    Scene {
        name,
        max_distance,
        camera,
        records,
        atlas,
        depth,
        normals,
        distance,
        view_from_clip: clip_from_view.inverse(),
        world_from_view,
        truth,
    }
}

fn cornell(max_distance: f32) -> Scene {
    let wall = |half: Vec3, at: Vec3| {
        (
            CasterShape::Cuboid { half_extents: half },
            Affine3A::from_translation(at),
        )
    };
    let t = 0.02;
    let analytic = vec![
        wall(Vec3::new(1.0 + t, t, 1.0 + t), Vec3::new(0.0, -t, 0.0)),
        wall(Vec3::new(1.0 + t, t, 1.0 + t), Vec3::new(0.0, 2.0 + t, 0.0)),
        wall(Vec3::new(1.0 + t, 1.0, t), Vec3::new(0.0, 1.0, -1.0 - t)),
        wall(Vec3::new(t, 1.0, 1.0 + t), Vec3::new(-1.0 - t, 1.0, 0.0)),
        wall(Vec3::new(t, 1.0, 1.0 + t), Vec3::new(1.0 + t, 1.0, 0.0)),
    ];
    let baked = vec![
        Placed {
            mesh: shapes::cuboid(Vec3::new(0.3, 0.6, 0.3)),
            world_from_local: Affine3A::from_rotation_translation(
                Quat::from_rotation_y(0.3),
                Vec3::new(-0.35, 0.6, -0.3),
            ),
        },
        Placed {
            mesh: shapes::cuboid(Vec3::splat(0.3)),
            world_from_local: Affine3A::from_rotation_translation(
                Quat::from_rotation_y(-0.3),
                Vec3::new(0.4, 0.3, 0.35),
            ),
        },
    ];
    let camera = PerspectiveCamera::looking_at(
        Vec3::new(0.0, 1.0, 3.3),
        Vec3::new(0.0, 0.9, 0.0),
        0.75,
        SIZE,
        SIZE,
    );
    finish_scene(
        format!("Cornell box ({max_distance} m)"),
        max_distance,
        baked,
        analytic,
        camera,
    )
}

fn bunny(max_distance: f32) -> Option<Scene> {
    let path = shared().join("meshes/stanford-bunny.obj");
    let text = std::fs::read_to_string(&path)
        .map_err(|e| eprintln!("SKIPPED the bunny scene: {}: {e}", path.display()))
        .ok()?;
    let mut mesh = obj::parse_obj(&text).ok()?;
    mesh.origin = glam::DVec3::ZERO; // the file's centred frame (positions are re-placed below)
    let mut b = Aabb::EMPTY;
    mesh.positions.iter().for_each(|&p| b.grow(p));
    // A 1 m bunny standing on y = 0, centred.
    let (scale, c) = (1.0 / b.size().max_element(), b.center());
    for p in &mut mesh.positions {
        *p = Vec3::new(p.x - c.x, p.y - b.min.y, p.z - c.z) * scale;
    }
    let camera = PerspectiveCamera::looking_at(
        Vec3::new(0.5, 1.8, 1.8),
        Vec3::new(-0.1, 0.3, -0.1),
        std::f32::consts::FRAC_PI_4,
        SIZE,
        SIZE,
    );
    Some(finish_scene(
        format!("bunny on a plane ({max_distance} m)"),
        max_distance,
        vec![Placed {
            mesh,
            world_from_local: Affine3A::IDENTITY,
        }],
        vec![(CasterShape::Plane, Affine3A::IDENTITY)],
        camera,
    ))
}

/// The connected parts of a mesh (vertices at one position, to 10 µm, joined), with
/// `origin` kept.
fn parts(mesh: &TriMesh) -> Vec<TriMesh> {
    let key = |p: Vec3| (p * 1e5).round().as_ivec3().to_array();
    let mut first = HashMap::new();
    let weld: Vec<u32> = (0..mesh.positions.len() as u32)
        .map(|i| *first.entry(key(mesh.positions[i as usize])).or_insert(i))
        .collect();
    let mut parent: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    fn root(parent: &mut [u32], mut i: u32) -> u32 {
        while parent[i as usize] != i {
            parent[i as usize] = parent[parent[i as usize] as usize];
            i = parent[i as usize];
        }
        i
    }
    for t in &mesh.triangles {
        let a = root(&mut parent, weld[t[0] as usize]);
        for &v in &t[1..] {
            let b = root(&mut parent, weld[v as usize]);
            parent[b as usize] = a;
        }
    }
    let mut groups: BTreeMap<u32, Vec<[u32; 3]>> = BTreeMap::new();
    for t in &mesh.triangles {
        let r = root(&mut parent, weld[t[0] as usize]);
        groups.entry(r).or_default().push(*t);
    }
    groups
        .into_values()
        .map(|triangles| {
            let mut index = HashMap::new();
            let mut positions = Vec::new();
            let triangles = triangles
                .iter()
                .map(|t| {
                    t.map(|v| {
                        *index.entry(v).or_insert_with(|| {
                            positions.push(mesh.positions[v as usize]);
                            positions.len() as u32 - 1
                        })
                    })
                })
                .collect();
            TriMesh {
                positions,
                triangles,
                origin: mesh.origin,
            }
        })
        .collect()
}

fn depth_of_field(max_distance: f32) -> Option<Scene> {
    let path = shared().join("scenes/DepthOfFieldExample.glb");
    let bytes = std::fs::read(&path)
        .map_err(|e| eprintln!("SKIPPED the glTF scene: {}: {e}", path.display()))
        .ok()?;
    let (mesh, _) = load_gltf(&bytes, path.parent(), &GltfSelection::Scene)
        .map_err(|e| eprintln!("SKIPPED the glTF scene: {}: {e}", path.display()))
        .ok()?;
    let (mut baked, mut analytic) = (Vec::new(), Vec::new());
    for mut part in parts(&mesh) {
        let mut b = Aabb::EMPTY;
        part.positions.iter().for_each(|&p| b.grow(p));
        let center = (part.origin + b.center().as_dvec3()).as_vec3();
        if b.size().y < 1e-3 {
            // The board: a box under its surface.
            let half = Vec3::new(0.5 * b.size().x, 0.5 * SLAB, 0.5 * b.size().z);
            let at = center - Vec3::Y * 0.5 * SLAB;
            analytic.push((
                CasterShape::Cuboid { half_extents: half },
                Affine3A::from_translation(at),
            ));
            continue;
        }
        let c = b.center();
        part.positions.iter_mut().for_each(|p| *p -= c);
        part.origin = glam::DVec3::ZERO;
        baked.push(Placed {
            mesh: part,
            world_from_local: Affine3A::from_translation(center),
        });
    }
    let camera = PerspectiveCamera::looking_at(
        Vec3::new(0.0, 5.0, 3.5),
        Vec3::new(0.0, 0.2, 0.5),
        0.8,
        SIZE,
        SIZE,
    );
    Some(finish_scene(
        format!("DepthOfFieldExample.glb ({max_distance} m)"),
        max_distance,
        baked,
        analytic,
        camera,
    ))
}

/// The view's AO and bent normal per pixel (`(ao, bent)`, full resolution) by the model
/// for jitter frame `frame`: traced at `divisor`, upsampled when above 1; and the
/// marches' distance evaluations.
fn ao_image(scene: &Scene, c: Config, frame: u32) -> (Vec<Vec4>, u64) {
    let eye = scene.camera.world_from_view.w_axis.truncate();
    let camera = CameraOrigin::at(eye).expect("finite");
    let full = UVec2::splat(SIZE);
    let view = AoView {
        view_from_clip: scene.view_from_clip,
        world_from_view: scene.world_from_view,
        size: full,
        depth: &scene.depth,
        normals: &scene.normals,
    };
    let shift = jitter(frame, c.divisor);
    let (traced, evaluations) = trace_view_counted(
        &scene.records,
        &scene.atlas,
        &camera,
        &view,
        c.divisor,
        shift,
        &c.trace(scene.max_distance),
    );
    if c.divisor <= 1 {
        return (traced, evaluations);
    }
    let image = upsample(
        &traced,
        trace_size(full, c.divisor),
        c.divisor,
        shift,
        &scene.distance,
        &scene.normals,
        full,
    );
    (image, evaluations)
}

/// Mean errors against the truth.
#[derive(Clone, Copy, Debug, Default)]
struct Errors {
    /// Mean |AO − truth| over all surface pixels.
    ao: f32,
    /// Mean AO − truth over all surface pixels (> 0: the model occludes too little).
    signed: f32,
    /// … over the pixels the truth occludes (AO < 0.99).
    ao_occluded: f32,
    /// Mean angle between the bent normals, radians, over all surface pixels.
    bent: f32,
    /// … over the pixels the truth occludes.
    bent_occluded: f32,
    surface: usize,
    occluded: usize,
}

fn errors(scene: &Scene, image: &[Vec4]) -> Errors {
    let mut e = Errors::default();
    for (v, t) in image.iter().zip(&scene.truth) {
        let Some(t) = t else { continue };
        let ao = (v.x - t.ao).abs();
        let bent = Vec3::new(v.y, v.z, v.w).angle_between(t.bent_normal);
        e.ao += ao;
        e.signed += v.x - t.ao;
        e.bent += bent;
        e.surface += 1;
        if t.ao < 0.99 {
            e.ao_occluded += ao;
            e.bent_occluded += bent;
            e.occluded += 1;
        }
    }
    let (all, occluded) = (e.surface.max(1) as f32, e.occluded.max(1) as f32);
    Errors {
        ao: e.ao / all,
        signed: e.signed / all,
        ao_occluded: e.ao_occluded / occluded,
        bent: e.bent / all,
        bent_occluded: e.bent_occluded / occluded,
        ..e
    }
}

struct Row {
    scene: String,
    config: Config,
    /// Distance evaluations per view pixel (the work; deterministic).
    evaluations: f64,
    seconds: f64,
    errors: Errors,
    pareto: bool,
}

/// The configurations: cones × steps × divisor, then shapings (at every cone count) and
/// biases around the defaults.
fn configs() -> Vec<Config> {
    let mut out = Vec::new();
    for &cones in &CONES {
        for &steps in &STEPS {
            for &divisor in &DIVISORS {
                out.push(Config::around(|c| {
                    (c.cones, c.steps, c.divisor) = (cones, steps, divisor);
                }));
            }
        }
    }
    for &cones in &CONES {
        for &shaping in SHAPINGS.iter().filter(|&&s| s != Config::DEFAULT.shaping) {
            out.push(Config::around(|c| (c.cones, c.shaping) = (cones, shaping)));
        }
    }
    for &bias in BIASES.iter().filter(|&&b| b != Config::DEFAULT.bias) {
        out.push(Config::around(|c| c.bias = bias));
    }
    out
}

/// `a` dominates `b`: no more work and no more error, and less of one.
fn dominates(a: (f64, f32), b: (f64, f32)) -> bool {
    a.0 <= b.0 && a.1 <= b.1 && (a.0 < b.0 || a.1 < b.1)
}

fn sweep(scene: &Scene) -> Vec<Row> {
    let mut rows: Vec<Row> = configs()
        .into_iter()
        .map(|config| {
            let mut times = Vec::new();
            let (mut image, mut evaluations) = (Vec::new(), 0);
            for _ in 0..3 {
                let start = Instant::now();
                (image, evaluations) = ao_image(scene, config, 0);
                times.push(start.elapsed().as_secs_f64());
            }
            times.sort_by(f64::total_cmp);
            Row {
                scene: scene.name.clone(),
                config,
                evaluations: evaluations as f64 / (SIZE * SIZE) as f64,
                seconds: times[1],
                errors: errors(scene, &image),
                pareto: false,
            }
        })
        .collect();
    let front: Vec<bool> = rows
        .iter()
        .map(|r| {
            !rows
                .iter()
                .any(|o| dominates((o.evaluations, o.errors.ao), (r.evaluations, r.errors.ao)))
        })
        .collect();
    for (r, f) in rows.iter_mut().zip(front) {
        r.pareto = f;
    }
    rows
}

/// The per-scene table: appended to `md`, returned as CSV.
fn tables(rows: &[Row], md: &mut String) -> String {
    let header = "scene | cones | steps | divisor | shaping | bias (m) | distance evaluations / pixel | time (ms, one thread) | mean \\|ΔAO\\|, all | mean AO − truth, all | mean \\|ΔAO\\|, occluded | occluded pixels | surface pixels | bent normal (rad), all | bent normal (rad), occluded | Pareto | default";
    let _ = writeln!(md, "| {header} |\n|{}", "---|".repeat(17));
    let mut csv = String::from(
        "scene,cones,steps,divisor,shaping,bias,evaluations_per_pixel,milliseconds,ao_error_all,\
         ao_signed_all,ao_error_occluded,occluded_pixels,surface_pixels,bent_error_all,bent_error_occluded,\
         pareto,default\n",
    );
    for r in rows {
        let (c, e) = (r.config, r.errors);
        let cells = [
            r.scene.clone(),
            c.cones.to_string(),
            c.steps.to_string(),
            c.divisor.to_string(),
            c.shaping.to_string(),
            c.bias.to_string(),
            format!("{:.2}", r.evaluations),
            format!("{:.2}", r.seconds * 1e3),
            format!("{:.4}", e.ao),
            format!("{:+.4}", e.signed),
            format!("{:.4}", e.ao_occluded),
            e.occluded.to_string(),
            e.surface.to_string(),
            format!("{:.4}", e.bent),
            format!("{:.4}", e.bent_occluded),
        ];
        let (front, default) = (r.pareto, c == Config::DEFAULT);
        let _ = writeln!(
            md,
            "| {} | {} | {} |",
            cells.join(" | "),
            if front { "✓" } else { "" },
            if default { "default" } else { "" }
        );
        let _ = writeln!(csv, "{},{front},{default}", cells.join(","));
    }
    csv
}

/// Every scene: per configuration, the summed work and the mean of the AO errors (all
/// surface pixels), with the Pareto front.
fn combined(rows: &[Row], scenes: usize, md: &mut String) {
    let table: Vec<(Config, f64, f32)> = configs()
        .into_iter()
        .map(|c| {
            let rs: Vec<&Row> = rows.iter().filter(|r| r.config == c).collect();
            let work = rs.iter().map(|r| r.evaluations).sum::<f64>();
            let error = rs.iter().map(|r| r.errors.ao).sum::<f32>() / scenes.max(1) as f32;
            (c, work, error)
        })
        .collect();
    md.push_str(
        "\n## All scenes\n\nPer configuration: distance evaluations per pixel summed over the scenes, mean \\|ΔAO\\| (all surface pixels) averaged over them. Pareto front only, and the defaults.\n\n| cones | steps | divisor | shaping | bias (m) | evaluations / pixel (sum) | mean \\|ΔAO\\| | Pareto | default |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for &(c, work, error) in &table {
        let front = !table
            .iter()
            .any(|&(_, w, e)| dominates((w, e), (work, error)));
        if front || c == Config::DEFAULT {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {} | {work:.1} | {error:.4} | {} | {} |",
                c.cones,
                c.steps,
                c.divisor,
                c.shaping,
                c.bias,
                if front { "✓" } else { "" },
                if c == Config::DEFAULT { "default" } else { "" }
            );
        }
    }
}

/// Per scene, one setting at a time around the defaults (the others at theirs), and the
/// check lines: the defaults' error against 0.08, and whether they are on the front.
fn around_defaults(rows: &[Row], names: &[String], md: &mut String) {
    md.push_str(
        "\n## Around the defaults\n\nOne setting varied, the others at the defaults: \
         `mean |ΔAO| (evaluations / pixel)`, ✓ on the scene's Pareto front.\n\n",
    );
    let only = |c: &Config, k: usize| {
        (0..FIELDS.len()).all(|j| j == k || c.fields()[j] == Config::DEFAULT.fields()[j])
    };
    for name in names {
        let _ = writeln!(md, "**{name}**\n");
        let scene: Vec<&Row> = rows.iter().filter(|r| &r.scene == name).collect();
        for (k, label) in FIELDS.iter().enumerate() {
            let mut line: Vec<&&Row> = scene.iter().filter(|r| only(&r.config, k)).collect();
            line.sort_by(|a, b| a.config.fields()[k].total_cmp(&b.config.fields()[k]));
            let cells: Vec<String> = line
                .iter()
                .map(|r| {
                    let default = if r.config == Config::DEFAULT {
                        " (default)"
                    } else {
                        ""
                    };
                    let front = if r.pareto { " ✓" } else { "" };
                    let (e, w) = (r.errors.ao, r.evaluations);
                    format!(
                        "{label} {}{default}: {e:.4} ({w:.0}){front}",
                        r.config.fields()[k]
                    )
                })
                .collect();
            let _ = writeln!(md, "- {}", cells.join("; "));
        }
        // The best shaping at each cone count (steps, divisor and bias at the defaults).
        let best: Vec<String> = CONES
            .iter()
            .filter_map(|&cones| {
                let at = |r: &&&Row| {
                    Config::around(|c| (c.cones, c.shaping) = (cones, r.config.shaping)) == r.config
                };
                let r = scene
                    .iter()
                    .filter(at)
                    .min_by(|a, b| a.errors.ao.total_cmp(&b.errors.ao))?;
                Some(format!(
                    "{cones} cones: {} ({:.4})",
                    r.config.shaping, r.errors.ao
                ))
            })
            .collect();
        let _ = writeln!(md, "- best shaping per cone count: {}", best.join("; "));
        let Some(d) = scene.iter().find(|r| r.config == Config::DEFAULT) else {
            continue;
        };
        let _ = writeln!(
            md,
            "\n{name}: defaults mean AO error {:.4} (≤ 0.08: {}); mean AO − truth {:+.4}, bent \
             normal {:.3} rad (occluded pixels), {:.0} evaluations / pixel, {:.1} ms",
            d.errors.ao,
            if d.errors.ao <= 0.08 { "yes" } else { "no" },
            d.errors.signed,
            d.errors.bent_occluded,
            d.evaluations,
            d.seconds * 1e3
        );
        if d.pareto {
            let _ = writeln!(md, "{name}: the defaults are on the Pareto front\n");
            continue;
        }
        let mut by: Vec<&&Row> = scene
            .iter()
            .filter(|r| {
                r.pareto && dominates((r.evaluations, r.errors.ao), (d.evaluations, d.errors.ao))
            })
            .collect();
        by.sort_by(|a, b| a.errors.ao.total_cmp(&b.errors.ao));
        let list: Vec<String> = by
            .iter()
            .take(3)
            .map(|r| {
                format!(
                    "{} ({:.4} at {:.0} evaluations / pixel)",
                    r.config.label(),
                    r.errors.ao,
                    r.evaluations
                )
            })
            .collect();
        let _ = writeln!(
            md,
            "{name}: the defaults are NOT on the Pareto front; dominated by {} front point(s), \
             the most accurate: {}\n",
            by.len(),
            list.join("; ")
        );
    }
}

/// The shaping sweep again (9 cones, the other settings at the defaults) at the
/// component's default max distance, 10 m, against truth traced to 10 m.
fn at_ten_metres(builders: &[fn(f32) -> Option<Scene>], md: &mut String) {
    md.push_str("\n## Shaping at the component's 10 m max distance\n\n`shaping: mean |ΔAO| (mean AO − truth)`, all surface pixels; 9 cones, 16 steps, divisor 2, bias 0.02 m.\n\n");
    for build in builders {
        let Some(scene) = build(10.0) else { continue };
        let errors: Vec<(f32, Errors)> = SHAPINGS
            .iter()
            .map(|&shaping| {
                let (image, _) = ao_image(&scene, Config::around(|c| c.shaping = shaping), 0);
                (shaping, errors(&scene, &image))
            })
            .collect();
        let best = errors.iter().min_by(|a, b| a.1.ao.total_cmp(&b.1.ao));
        let cells: Vec<String> = errors
            .iter()
            .map(|(s, e)| format!("{s}: {:.4} ({:+.4})", e.ao, e.signed))
            .collect();
        let best = best.map_or(String::new(), |(s, e)| format!("; best {s} ({:.4})", e.ao));
        let _ = writeln!(md, "- {}: {}{best}", scene.name, cells.join("; "));
    }
}

fn bench(c: &mut Criterion) {
    let start = Instant::now();
    let builders: [fn(f32) -> Option<Scene>; 3] = [|m| Some(cornell(m)), bunny, depth_of_field];
    // About half the extent of each scene's occluding geometry (see the module's doc).
    let scenes: Vec<Scene> = builders
        .iter()
        .zip([1.0, 0.5, 1.5])
        .filter_map(|(build, max_distance)| build(max_distance))
        .collect();
    let mut rows = Vec::new();
    for scene in &scenes {
        let t = Instant::now();
        rows.extend(sweep(scene));
        println!(
            "{}: swept in {:.0} s",
            scene.name,
            t.elapsed().as_secs_f64()
        );
    }
    let names: Vec<String> = scenes.iter().map(|s| s.name.clone()).collect();
    let mut md = format!(
        "# DFAO: run time against error\n\n`cargo bench -p penumbra_reference --bench dfao`: \
         {SIZE}×{SIZE} views, truth {MC}×{MC} cosine-weighted rays per pixel; max occlusion \
         distance in the scene's name.\n\n"
    );
    let csv = tables(&rows, &mut md);
    combined(&rows, scenes.len(), &mut md);
    around_defaults(&rows, &names, &mut md);
    at_ten_metres(&builders, &mut md);
    let _ = writeln!(
        md,
        "\nScenes, truth and sweep: {:.0} s.",
        start.elapsed().as_secs_f64()
    );
    println!("{md}");
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/penumbra_bench");
    if std::fs::create_dir_all(&dir).is_ok() {
        let _ = std::fs::write(dir.join("dfao.md"), &md);
        let _ = std::fs::write(dir.join("dfao.csv"), &csv);
        println!("wrote {}", dir.join("dfao.{md,csv}").display());
    }
    for scene in &scenes {
        c.bench_function(&format!("dfao/{}/defaults", scene.name), |b| {
            b.iter(|| ao_image(scene, Config::DEFAULT, 0));
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
