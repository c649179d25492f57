//! `PenumbraBufferDump` means exactly what it documents, checked against an analytic
//! scene: a ground plane under a floating sphere caster, a sun straight down. Per pixel-centre
//! ray (pinhole, vertical field of view, +Y up, row 0 at the top):
//!
//! - `depth` is the Euclidean distance to the plane along the ray (not view-space z:
//!   that differs by up to 8 % in the corners here), NaN where the ray misses;
//! - `normal` is the plane's +Y;
//! - `visibility_sun` is ~0 inside the sphere's shadow disc and ~1 outside it;
//! - `ao` is below 1 under the sphere, 1 where the sphere is beyond the max occlusion
//!   distance, NaN on background; `bent_normal` is unit and leans away from the sphere;
//!
//! and dumping every frame creates no GPU resource once running.
//!
//! And `face_normal` (the face-normal prepass) is the plane of each posed triangle: a
//! skinned quad turned by its joint, a quad tilted by a morph target and a lightmapped
//! quad, each against its analytic plane.

use bevy::asset::RenderAssetUsages;
use bevy::camera::visibility::NoFrustumCulling;
use bevy::ecs::schedule::IntoScheduleConfigs;
use bevy::ecs::system::ScheduleSystem;
use bevy::mesh::morph::{MeshMorphWeights, MorphAttributes};
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::pbr::{DefaultOpaqueRendererMethod, Lightmap};
use bevy::prelude::*;
use penumbra::df::{PenumbraBufferDump, PenumbraBuffers, PenumbraGpuAllocations};
use penumbra::prelude::*;
use penumbra_test::harness::KeptApp;
use penumbra_test::{HeadlessRender, gpu_or_skip};

const SIZE: u32 = 64;
const EYE: Vec3 = Vec3::new(0.0, 3.0, 5.0);
const FOV_DEG: f32 = 45.0;
const HALF_PLANE: f32 = 4.0;
/// The sphere floats here: its shadow disc on the plane is in view, not behind it.
const SPHERE: Vec3 = Vec3::new(1.5, 1.5, 0.0);
/// DFAO's max occlusion distance: the whole sphere is within it from under the sphere,
/// none of it from the plane's far corners.
const AO_DISTANCE: f32 = 4.0;

fn scene(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    let grey = materials.add(Color::srgb(0.7, 0.7, 0.7));
    commands.spawn((
        Mesh3d(
            meshes.add(
                Plane3d::default()
                    .mesh()
                    .size(2.0 * HALF_PLANE, 2.0 * HALF_PLANE),
            ),
        ),
        MeshMaterial3d(grey.clone()),
    ));
    commands.spawn((
        Mesh3d(meshes.add(Sphere::new(0.5))),
        MeshMaterial3d(grey),
        Transform::from_translation(SPHERE),
        DistanceFieldCaster {
            source: CasterSource::Sphere { radius: 0.5 },
            ..default()
        },
    ));
    commands.spawn((
        Name::new("sun"),
        DirectionalLight::default(),
        DistanceFieldShadows::default(),
        Transform::default().looking_to(Vec3::NEG_Y, Vec3::Z),
    ));
    commands.spawn((
        Camera3d::default(),
        PenumbraLighting,
        DistanceFieldAmbientOcclusion {
            max_occlusion_distance: AO_DISTANCE,
            ..default()
        },
        Projection::Perspective(PerspectiveProjection {
            fov: FOV_DEG.to_radians(),
            ..default()
        }),
        Transform::from_translation(EYE).looking_at(Vec3::ZERO, Vec3::Y),
    ));
}

/// The ray through the centre of pixel (i, j), as `shadow_truth.py` casts it.
fn ray(i: u32, j: u32) -> Vec3 {
    ray_from(EYE, i, j)
}

/// The ray through the centre of pixel (i, j) of a camera at `eye` looking at the origin.
fn ray_from(eye: Vec3, i: u32, j: u32) -> Vec3 {
    let forward = (Vec3::ZERO - eye).normalize();
    let right = forward.cross(Vec3::Y).normalize();
    let up = right.cross(forward);
    let t = (FOV_DEG.to_radians() * 0.5).tan();
    let x = ((i as f32 + 0.5) / SIZE as f32 * 2.0 - 1.0) * t;
    let y = (1.0 - (j as f32 + 0.5) / SIZE as f32 * 2.0) * t;
    (forward + x * right + y * up).normalize()
}

/// Renders `scene` (its `Startup` system) with `PenumbraPlugins`, deferred, then asks
/// the camera for its buffers: the app, the camera and the first dump.
fn render_and_dump<M>(
    scene: impl IntoScheduleConfigs<ScheduleSystem, M>,
) -> (KeptApp, Entity, PenumbraBuffers) {
    let render = HeadlessRender::new(SIZE, SIZE).frames(4);
    let mut app = render.app();
    app.add_plugins(PenumbraPlugins)
        .insert_resource(DefaultOpaqueRendererMethod::deferred())
        .add_systems(Startup, scene);
    let (_, mut app) = render.run_keeping_app(app).expect("headless render");
    let camera = app
        .world_mut()
        .query_filtered::<Entity, With<Camera3d>>()
        .single(app.world())
        .unwrap();
    app.world_mut()
        .entity_mut(camera)
        .insert(PenumbraBufferDump);
    for _ in 0..30 {
        app.update();
        if let Some(dump) = app.world_mut().entity_mut(camera).take::<PenumbraBuffers>() {
            return (app, camera, dump);
        }
    }
    panic!("the dump did not arrive in 30 frames");
}

#[test]
fn the_dump_is_distance_normal_and_mask_per_pixel_centre() {
    if !gpu_or_skip("the_dump_is_distance_normal_and_mask_per_pixel_centre") {
        return;
    }
    let (mut app, camera, dump) = render_and_dump(scene);
    // Dumping every frame creates nothing new once running (pooled buffers, the bind
    // group kept while its inputs are).
    let allocations = app.world().resource::<PenumbraGpuAllocations>().clone();
    let before = allocations.counts();
    for _ in 0..4 {
        app.update();
    }
    assert_eq!(
        allocations.counts(),
        before,
        "GPU resources created while dumping"
    );
    assert!(
        app.world().get::<PenumbraBuffers>(camera).is_some(),
        "later frames are dumped too"
    );
    assert_eq!(dump.size, UVec2::splat(SIZE));
    let depth = &dump.get("depth").unwrap().data;
    let normal = &dump.get("normal").unwrap().data;
    let sun = &dump.get("visibility_sun").expect("the sun's mask").data;
    let ao = &dump.get("ao").expect("the AO").data;
    let bent = &dump.get("bent_normal").expect("the bent normal").data;
    let (mut plane, mut shadowed, mut lit) = (0, 0, 0);
    let (mut under, mut under_sum, mut open, mut lean, mut leaning) = (0, 0.0, 0, 0.0, 0);
    for j in 0..SIZE {
        for i in 0..SIZE {
            let k = (j * SIZE + i) as usize;
            let d = ray(i, j);
            // Skip rays that pass near the sphere (its mesh is tessellated) or the
            // plane's edge.
            let to_centre = SPHERE - EYE;
            let miss = (to_centre - d * to_centre.dot(d)).length();
            let t = -EYE.y / d.y;
            let hit = EYE + d * t;
            let edge = HALF_PLANE - hit.x.abs().max(hit.z.abs());
            if miss < 0.6 || (d.y < 0.0 && edge.abs() < 0.1) {
                continue;
            }
            if d.y >= 0.0 || edge < 0.0 {
                assert!(
                    depth[k].is_nan(),
                    "({i}, {j}): background depth {}",
                    depth[k]
                );
                assert!(normal[3 * k..3 * k + 3].iter().all(|v| v.is_nan()));
                assert!(ao[k].is_nan() && bent[3 * k..3 * k + 3].iter().all(|v| v.is_nan()));
                continue;
            }
            plane += 1;
            assert!(
                (depth[k] - t).abs() < 1e-3 * t,
                "({i}, {j}): depth {} for {t}",
                depth[k]
            );
            let n = Vec3::from_slice(&normal[3 * k..3 * k + 3]);
            assert!(n.distance(Vec3::Y) < 2e-3, "({i}, {j}): normal {n}");
            let r = Vec2::new(hit.x - SPHERE.x, hit.z - SPHERE.z).length();
            let b = Vec3::from_slice(&bent[3 * k..3 * k + 3]);
            assert!(
                (b.length() - 1.0).abs() < 1e-2 && b.y > 0.0,
                "({i}, {j}): bent normal {b}"
            );
            if r < 0.3 {
                under += 1;
                under_sum += ao[k];
            } else if hit.distance(SPHERE) > AO_DISTANCE + 0.6 {
                open += 1;
                assert!(ao[k] > 0.99, "({i}, {j}): AO {} out of reach", ao[k]);
            } else if r > 0.5 && r < 1.5 {
                // The bent normal leans away from the sphere.
                let away = Vec3::new(hit.x - SPHERE.x, 0.0, hit.z - SPHERE.z).normalize();
                lean += b.dot(away);
                leaning += 1;
            }
            if r < 0.4 {
                shadowed += 1;
                assert!(sun[k] < 0.1, "({i}, {j}): lit {} under the sphere", sun[k]);
            } else if r > 0.6 {
                lit += 1;
                assert!(sun[k] > 0.9, "({i}, {j}): shadowed {} in the open", sun[k]);
            }
        }
    }
    assert!(
        plane > 1000 && shadowed > 5 && lit > 1000,
        "{plane} {shadowed} {lit}"
    );
    // Analytic AO under the sphere's centre: 1 − (R / h)² = 0.889.
    let under_mean = under_sum / under as f32;
    assert!(
        under > 5 && (0.75..0.95).contains(&under_mean),
        "AO under the sphere {under_mean} over {under} pixels"
    );
    assert!(open > 20, "{open} pixels out of the sphere's reach");
    let lean = lean / leaning as f32;
    assert!(
        leaning > 20 && lean > 0.02,
        "bent normals beside the sphere lean {lean} away from it ({leaning} pixels)"
    );
}

/// The face-normal scene's camera.
const FACETS_EYE: Vec3 = Vec3::new(0.0, 0.0, 4.0);
/// Half a quad's side, metres.
const QUAD: f32 = 0.4;
/// The skinned quad's joint turns it this far about +y (radians).
const SKIN_TURN: f32 = 0.7;
/// The morph target pushes the quad's top edge this far back (−z), at weight 1.
const MORPH_PUSH: f32 = 0.6;
/// The lightmapped quad is turned this far about +y.
const LIGHTMAPPED_TURN: f32 = -0.5;

/// A quad in the xy plane, counter-clockwise seen from +z (its winding normal), with
/// what a skinned, lightmapped `StandardMaterial` mesh needs.
fn quad() -> Mesh {
    let h = QUAD;
    Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    )
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_POSITION,
        vec![[-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0]],
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, vec![[0.0, 0.0, 1.0f32]; 4])
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_UV_0,
        vec![[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0f32]],
    )
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_UV_1,
        vec![[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0f32]],
    )
    .with_inserted_indices(Indices::U32(vec![0, 1, 2, 0, 2, 3]))
}

/// A posed quad as the test expects it: centre, in-plane axes (unit) with their half
/// extents, and the winding normal.
struct Posed {
    centre: Vec3,
    axes: [(Vec3, f32); 2],
    normal: Vec3,
}

impl Posed {
    /// Where the ray from the eye along `d` meets the quad, `margin` inside its edges.
    fn hit(&self, d: Vec3, margin: f32) -> bool {
        let t = (self.centre - FACETS_EYE).dot(self.normal) / d.dot(self.normal);
        let p = FACETS_EYE + d * t - self.centre;
        t > 0.0 && self.axes.iter().all(|(a, h)| p.dot(*a).abs() < h - margin)
    }
}

/// The three quads, left to right: skinned, morphed, lightmapped.
fn posed_quads() -> [Posed; 3] {
    let skin = Quat::from_rotation_y(SKIN_TURN);
    let lightmapped = Quat::from_rotation_y(LIGHTMAPPED_TURN);
    // The morph keeps the bottom edge and moves the top one back: a plane through both.
    let up = Vec3::new(0.0, 2.0 * QUAD, -MORPH_PUSH);
    [
        Posed {
            centre: Vec3::new(-1.1, 0.0, 0.0),
            axes: [(skin * Vec3::X, QUAD), (Vec3::Y, QUAD)],
            normal: skin * Vec3::Z,
        },
        Posed {
            centre: Vec3::new(0.0, 0.0, -0.5 * MORPH_PUSH),
            axes: [(Vec3::X, QUAD), (up.normalize(), 0.5 * up.length())],
            normal: Vec3::X.cross(up).normalize(),
        },
        Posed {
            centre: Vec3::new(1.1, 0.0, 0.0),
            axes: [(lightmapped * Vec3::X, QUAD), (Vec3::Y, QUAD)],
            normal: lightmapped * Vec3::Z,
        },
    ]
}

fn facets_scene(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut bindposes: ResMut<Assets<SkinnedMeshInverseBindposes>>,
    mut images: ResMut<Assets<Image>>,
) {
    let grey = materials.add(Color::srgb(0.7, 0.7, 0.7));
    let [skinned_at, _, lightmapped_at] = posed_quads().map(|q| q.centre);
    // Skinned: every vertex on the second joint, which turns the quad about +y.
    let mut skinned = quad();
    skinned.insert_attribute(
        Mesh::ATTRIBUTE_JOINT_INDEX,
        VertexAttributeValues::Uint16x4(vec![[1, 0, 0, 0]; 4]),
    );
    skinned.insert_attribute(
        Mesh::ATTRIBUTE_JOINT_WEIGHT,
        vec![[1.0f32, 0.0, 0.0, 0.0]; 4],
    );
    let root = commands
        .spawn((
            Transform::from_translation(skinned_at),
            Visibility::default(),
        ))
        .id();
    let turned = commands
        .spawn((
            Transform::from_rotation(Quat::from_rotation_y(SKIN_TURN)),
            Visibility::default(),
            ChildOf(root),
        ))
        .id();
    commands.spawn((
        Mesh3d(meshes.add(skinned)),
        MeshMaterial3d(grey.clone()),
        SkinnedMesh {
            inverse_bindposes: bindposes.add(SkinnedMeshInverseBindposes::from(vec![
                Mat4::IDENTITY,
                Mat4::IDENTITY,
            ])),
            joints: vec![root, turned],
        },
        // Its bounds are the bind pose's, at the origin.
        NoFrustumCulling,
    ));
    // Morphed: one target moving the top edge back, at weight 1.
    let push = MorphAttributes::new(Vec3::new(0.0, 0.0, -MORPH_PUSH), Vec3::ZERO, Vec3::ZERO);
    let morphed = quad().with_morph_targets(vec![
        MorphAttributes::default(),
        MorphAttributes::default(),
        push,
        push,
    ]);
    commands.spawn((
        Mesh3d(meshes.add(morphed)),
        MeshMorphWeights::Value { weights: vec![1.0] },
        MeshMaterial3d(grey.clone()),
        NoFrustumCulling,
    ));
    // Lightmapped: Bevy binds its mesh data with the lightmap's bind group.
    commands.spawn((
        Mesh3d(meshes.add(quad())),
        MeshMaterial3d(grey),
        Lightmap {
            image: images.add(Image::default()),
            uv_rect: Rect::new(0.0, 0.0, 1.0, 1.0),
            bicubic_sampling: false,
        },
        Transform::from_translation(lightmapped_at)
            .with_rotation(Quat::from_rotation_y(LIGHTMAPPED_TURN)),
    ));
    // The prepass runs while a light has distance-field shadows.
    commands.spawn((
        DirectionalLight::default(),
        DistanceFieldShadows::default(),
        Transform::default().looking_to(Vec3::new(-0.3, -1.0, -0.4), Vec3::Y),
    ));
    commands.spawn((
        Camera3d::default(),
        PenumbraLighting,
        Projection::Perspective(PerspectiveProjection {
            fov: FOV_DEG.to_radians(),
            ..default()
        }),
        Transform::from_translation(FACETS_EYE).looking_at(Vec3::ZERO, Vec3::Y),
    ));
}

#[test]
fn face_normals_are_the_posed_triangles_of_skinned_morphed_and_lightmapped_meshes() {
    let name = "face_normals_are_the_posed_triangles_of_skinned_morphed_and_lightmapped_meshes";
    if !gpu_or_skip(name) {
        return;
    }
    let (_, _, dump) = render_and_dump(facets_scene);
    let facets = &dump.get("face_normal").expect("the face normals").data;
    let quads = posed_quads();
    let mut inside = [0; 3];
    let mut background = 0;
    for j in 0..SIZE {
        for i in 0..SIZE {
            let k = (j * SIZE + i) as usize;
            let d = ray_from(FACETS_EYE, i, j);
            let got = Vec3::from_slice(&facets[3 * k..3 * k + 3]);
            if let Some(q) = quads.iter().position(|q| q.hit(d, 0.05)) {
                inside[q] += 1;
                let want = quads[q].normal;
                assert!(
                    got.angle_between(want).to_degrees() < 1.0,
                    "quad {q} at ({i}, {j}): face normal {got}, its posed plane's {want}"
                );
            } else if !quads.iter().any(|q| q.hit(d, -0.05)) {
                background += 1;
                assert!(got.is_nan(), "({i}, {j}): background {got}");
            }
        }
    }
    assert!(
        inside.iter().all(|&n| n > 40) && background > 1000,
        "pixels checked: {inside:?} on the quads, {background} background"
    );
}
