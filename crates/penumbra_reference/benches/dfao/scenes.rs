//! The bench's scenes: meshes baked with the plugin's default grid and analytic shapes,
//! their view (depth, G-buffer normals) and the Monte Carlo truth per pixel.

use super::support::{Placed, world_triangles};
use super::{MC, SIZE, SLAB};
use glam::{Affine3A, Mat3, Mat4, Vec3};
use penumbra_df_core::object::{CasterShape, ObjectRecord, flags};
use penumbra_reference::camera::PerspectiveCamera;
use penumbra_reference::df::Atlas;
use penumbra_reference::dfao::{AoSample, monte_carlo_ao};
use penumbra_reference::shadow_mask::{pack_gbuffer_normal, unpack_gbuffer_normal};
use penumbra_sdf::bvh::Bvh;
use penumbra_sdf::geometry::Aabb;
use penumbra_sdf::gltf_input::{GltfSelection, load_gltf};
use penumbra_sdf::{BakeSettings, TriMesh};
use std::collections::{BTreeMap, HashMap};
use std::time::Instant;

pub struct Scene {
    pub name: String,
    /// The trace's and the truth's max occlusion distance, metres.
    pub max_distance: f32,
    pub camera: PerspectiveCamera,
    pub records: Vec<ObjectRecord>,
    pub atlas: Atlas,
    /// Reverse-Z depth per pixel (0: background).
    pub depth: Vec<f32>,
    /// The G-buffer's unit normals (zero for the background).
    pub normals: Vec<Vec3>,
    /// Distance from the camera per pixel (0: background), for the upsample.
    pub distance: Vec<f32>,
    pub view_from_clip: Mat4,
    pub world_from_view: Mat3,
    /// Ground truth per pixel (`None`: background).
    pub truth: Vec<Option<AoSample>>,
}

/// The object records and atlas: the meshes baked with the plugin's default grid.
pub fn build_records(
    baked: &[Placed],
    analytic: &[(CasterShape, Affine3A)],
) -> (Vec<ObjectRecord>, Atlas) {
    let live = flags::LIVE | flags::CASTS_OCCLUSION | flags::VISIBLE;
    super::support::build_records(baked, analytic, &BakeSettings::default(), live)
}

/// Bakes the scene, traces the view on its triangles (depth, G-buffer normals) and
/// computes the ground truth once.
pub fn finish_scene(
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

pub fn cornell(max_distance: f32) -> Scene {
    let (analytic, baked) = super::support::cornell_box();
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

pub fn bunny(max_distance: f32) -> Option<Scene> {
    let mesh = super::support::bunny_mesh()?;
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
pub fn parts(mesh: &TriMesh) -> Vec<TriMesh> {
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

pub fn depth_of_field(max_distance: f32) -> Option<Scene> {
    let path = super::support::shared("scenes/DepthOfFieldExample.glb");
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
