//! What the distance-field benches share: meshes placed in the world, their triangles
//! for the ray-traced truth, and the object records and atlas the models read.

use glam::{Affine3A, Quat, UVec3, Vec3};
use penumbra_df_core::atlas::AtlasRegion;
use penumbra_df_core::object::{CasterShape, ObjectDesc, ObjectRecord, encode};
use penumbra_reference::df::Atlas;
use penumbra_sdf::geometry::Aabb;
use penumbra_sdf::{BakeSettings, TriMesh, bake, obj, shapes};
use std::path::PathBuf;

/// A mesh placed in the world: baked for the model, traced for the truth.
pub struct Placed {
    pub mesh: TriMesh,
    pub world_from_local: Affine3A,
}

/// The world-space triangles of the meshes and the analytic shapes (cuboids, and 100 m
/// of a plane: beyond every view and reach of the benches).
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

/// The object records (flags `live`) and atlas: the meshes baked with `settings`, side
/// by side along x, then the analytic shapes.
pub fn build_records(
    baked: &[Placed],
    analytic: &[(CasterShape, Affine3A)],
    settings: &BakeSettings,
    live: u32,
) -> (Vec<ObjectRecord>, Atlas) {
    let volumes: Vec<_> = baked
        .iter()
        .map(|p| bake(&p.mesh, settings, None).expect("bakes").volume)
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

/// The 2 m Cornell box of both benches: five analytic walls 4 cm thick around
/// `[-1, 1] × [0, 2] × [-1, 1]` (open towards +z), and its tall and short boxes, to bake.
pub fn cornell_box() -> (Vec<(CasterShape, Affine3A)>, Vec<Placed>) {
    let wall = |half: Vec3, at: Vec3| {
        (
            CasterShape::Cuboid { half_extents: half },
            Affine3A::from_translation(at),
        )
    };
    let t = 0.02;
    let walls = vec![
        wall(Vec3::new(1.0 + t, t, 1.0 + t), Vec3::new(0.0, -t, 0.0)),
        wall(Vec3::new(1.0 + t, t, 1.0 + t), Vec3::new(0.0, 2.0 + t, 0.0)),
        wall(Vec3::new(1.0 + t, 1.0, t), Vec3::new(0.0, 1.0, -1.0 - t)),
        wall(Vec3::new(t, 1.0, 1.0 + t), Vec3::new(-1.0 - t, 1.0, 0.0)),
        wall(Vec3::new(t, 1.0, 1.0 + t), Vec3::new(1.0 + t, 1.0, 0.0)),
    ];
    let boxes = vec![
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
    (walls, boxes)
}

/// `../shared/<sub>` beside the checkout.
pub fn shared(sub: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared")
        .join(sub)
}

/// The Stanford bunny (`../shared/meshes`) scaled to 1 m, standing on y = 0, centred;
/// `None` after a message when the file is missing.
pub fn bunny_mesh() -> Option<TriMesh> {
    let path = shared("meshes/stanford-bunny.obj");
    let text = std::fs::read_to_string(&path)
        .map_err(|e| eprintln!("SKIPPED the bunny scene: {}: {e}", path.display()))
        .ok()?;
    let mut mesh = obj::parse_obj(&text).ok()?;
    mesh.origin = glam::DVec3::ZERO; // the file's centred frame (positions are re-placed below)
    let mut b = Aabb::EMPTY;
    mesh.positions.iter().for_each(|&p| b.grow(p));
    let (scale, c) = (1.0 / b.size().max_element(), b.center());
    for p in &mut mesh.positions {
        *p = Vec3::new(p.x - c.x, p.y - b.min.y, p.z - c.z) * scale;
    }
    Some(mesh)
}
