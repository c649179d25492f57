//! The bench's scenes: meshes baked with the plugin's default grid and analytic shapes,
//! their view (depth, G-buffer normals) and the Monte Carlo truth per pixel.

use super::{MC, SIZE, SLAB};
use glam::{Affine3A, Mat3, Mat4, Quat, UVec3, Vec3};
use penumbra_df_core::atlas::AtlasRegion;
use penumbra_df_core::object::{CasterShape, ObjectDesc, ObjectRecord, encode, flags};
use penumbra_reference::camera::PerspectiveCamera;
use penumbra_reference::df::Atlas;
use penumbra_reference::dfao::{AoSample, monte_carlo_ao};
use penumbra_reference::shadow_mask::{pack_gbuffer_normal, unpack_gbuffer_normal};
use penumbra_sdf::bvh::Bvh;
use penumbra_sdf::geometry::Aabb;
use penumbra_sdf::gltf_input::{GltfSelection, load_gltf};
use penumbra_sdf::{BakeSettings, TriMesh, bake, obj, shapes};
use std::collections::{BTreeMap, HashMap};
use std::path::PathBuf;
use std::time::Instant;

/// A mesh placed in the world: baked for the model, traced for the truth.
pub struct Placed {
    pub mesh: TriMesh,
    pub world_from_local: Affine3A,
}

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

pub fn shared() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared")
}

pub fn world_triangles(baked: &[Placed], analytic: &[(CasterShape, Affine3A)]) -> Vec<[Vec3; 3]> {
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
pub fn build_records(
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

pub fn bunny(max_distance: f32) -> Option<Scene> {
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
