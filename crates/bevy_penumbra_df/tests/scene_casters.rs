//! `DistanceFieldSceneCasters` on real glTF files (`../shared/scenes`): the caster count
//! and the skip rule per scene, shared bakes across instances of a scene, the skinned Fox
//! skipped or cast from its bind pose (`skin_capsules.rs` has its capsules), re-tagging when the settings change, untagging
//! when the component is removed. Main world only (no GPU): Bevy's renderer is built
//! with no backend.

use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;
use bevy_penumbra_df::{
    CasterSource, DistanceFieldCaster, DistanceFieldSceneCaster, DistanceFieldSceneCasters,
    DistanceFieldUploadStats, FOLIAGE_AO_TRANSMISSION, MergeDistanceFieldCasters,
    SceneCasterCounts, SdfBakeStats, SdfBaked, SkinnedCasters,
};
use std::path::PathBuf;

#[path = "support/scenes_app.rs"]
mod support;

fn scenes_dir() -> Option<PathBuf> {
    support::scenes_dir("scene_casters")
}

fn app(dir: &std::path::Path) -> App {
    support::scenes_app_at(dir)
}

/// Coarse bakes: the tests are about tagging, not accuracy.
fn coarse() -> DistanceFieldSceneCasters {
    DistanceFieldSceneCasters {
        caster: DistanceFieldCaster {
            resolution_scale: 0.125,
            ..default()
        },
        ..default()
    }
}

fn spawn(app: &mut App, file: &str, settings: DistanceFieldSceneCasters) -> Entity {
    let scene = app
        .world()
        .resource::<AssetServer>()
        .load(GltfAssetLabel::Scene(0).from_asset(file.to_string()));
    app.world_mut()
        .spawn((WorldAssetRoot(scene), settings))
        .id()
}

/// Runs until every tagged mesh caster has its SDF (or 20 s pass; analytic casters, a
/// skinned mesh's capsules, have none).
fn settle(app: &mut App) {
    let start = std::time::Instant::now();
    let mut quiet = 0;
    while start.elapsed().as_secs() < 20 {
        app.update();
        let world = app.world_mut();
        let meshes = world
            .query_filtered::<(), With<Mesh3d>>()
            .iter(world)
            .count();
        let waiting = world
            .query_filtered::<&DistanceFieldCaster, Without<SdfBaked>>()
            .iter(world)
            .filter(|c| c.source == CasterSource::Mesh)
            .count();
        quiet = if meshes > 0 && waiting == 0 {
            quiet + 1
        } else {
            0
        };
        if quiet > 5 {
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    panic!("the scene did not settle in 20 s");
}

fn counts(app: &App, root: Entity) -> SceneCasterCounts {
    *app.world()
        .get::<SceneCasterCounts>(root)
        .expect("SceneCasterCounts on the root")
}

fn casters(app: &mut App) -> Vec<(Entity, DistanceFieldCaster)> {
    let world = app.world_mut();
    world
        .query::<(Entity, &DistanceFieldCaster)>()
        .iter(world)
        .map(|(e, c)| (e, c.clone()))
        .collect()
}

#[test]
fn cornell_box_twice_tags_every_mesh_and_shares_the_bakes() {
    let Some(dir) = scenes_dir() else { return };
    let mut app = app(&dir);
    let a = spawn(&mut app, "CornellBox.glb", coarse());
    let b = spawn(&mut app, "CornellBox.glb", coarse());
    settle(&mut app);
    // 4 nodes, 6 primitives (the room is 3): every mesh entity under the root is a
    // caster. All materials are double-sided in the file: the light panel and the room's
    // walls are open (two-sided shells), the two blocks closed (solid). The room's union
    // is open too (a box without its front): a shell either way, so it stays in pieces.
    let ca = counts(&app, a);
    assert_eq!(ca, counts(&app, b));
    let meshes = {
        let world = app.world_mut();
        world
            .query_filtered::<(), With<Mesh3d>>()
            .iter(world)
            .count() as u32
    };
    assert_eq!(
        (ca.casters + ca.merged) * 2,
        meshes,
        "every mesh entity is a caster or merged into one: {ca:?}"
    );
    // The walls and the light panel are open sheets (two-sided); the blocks are
    // double-sided but closed (solid).
    assert_eq!(
        (ca.casters, ca.two_sided, ca.solid_double_sided, ca.merged),
        (6, 4, 2, 0),
        "{ca:?}"
    );
    // Boxes and walls: flat-shaded, their G-buffer normals are their faces'.
    assert_eq!(ca.shaded_apart, 0, "{ca:?}");
    let all = casters(&mut app);
    assert!(all.iter().all(|(_, c)| c.resolution_scale == 0.125));
    // Shared bakes: the second instance bakes nothing; one atlas volume per distinct
    // mesh primitive.
    let bakes = *app.world().resource::<SdfBakeStats>();
    let stats = app.world().resource::<DistanceFieldUploadStats>().clone();
    assert_eq!(bakes.failed, 0, "{bakes:?}");
    assert_eq!(
        bakes.baked + bakes.memory_hits,
        2 * ca.casters,
        "one request per caster: {bakes:?}"
    );
    assert!(bakes.baked <= ca.casters, "{bakes:?}");
    assert_eq!(stats.atlas_volumes as u32, bakes.baked, "{stats:?}");
    assert_eq!(stats.objects as u32, 2 * ca.casters, "{stats:?}");
}

#[test]
fn fox_is_skipped_or_cast_from_its_bind_pose() {
    let Some(dir) = scenes_dir() else { return };
    let mut app = app(&dir);
    let skip = DistanceFieldSceneCasters {
        skinned: SkinnedCasters::Skip,
        ..coarse()
    };
    let root = spawn(&mut app, "Fox.glb", skip);
    settle(&mut app);
    let c = counts(&app, root);
    assert_eq!((c.casters, c.skinned), (0, 1), "{c:?}");
    assert!(casters(&mut app).is_empty());
    // Changing the settings re-tags: the bind pose becomes a caster.
    app.world_mut()
        .get_mut::<DistanceFieldSceneCasters>(root)
        .unwrap()
        .skinned = SkinnedCasters::BindPose;
    settle(&mut app);
    let c = counts(&app, root);
    assert_eq!((c.casters, c.skinned), (1, 0), "{c:?}");
    let all = casters(&mut app);
    assert_eq!(all.len(), 1);
    assert_eq!(
        app.world().get::<DistanceFieldSceneCaster>(all[0].0),
        Some(&DistanceFieldSceneCaster(root))
    );
    // Removing the component removes the casters it made.
    app.world_mut()
        .entity_mut(root)
        .remove::<DistanceFieldSceneCasters>();
    app.update();
    app.update();
    assert!(casters(&mut app).is_empty());
    assert!(app.world().get::<SceneCasterCounts>(root).is_none());
}

#[test]
fn palm_tree_open_sheets_are_ground_and_small_meshes_are_skipped() {
    let Some(dir) = scenes_dir() else { return };
    let mut app = app(&dir);
    let root = spawn(&mut app, "PalmTree/PalmTree.gltf", coarse());
    settle(&mut app);
    let c = counts(&app, root);
    // 10 meshes, one primitive each: trunk, 7 leaves, landscape, water. Every material
    // is double-sided (none alpha-masked); the leaves are closed (modelled with
    // thickness), two meshes are open sheets facing up: the island and the sea, ground.
    assert_eq!(
        (c.casters, c.two_sided, c.ground, c.solid_double_sided),
        (10, 0, 2, 8),
        "{c:?}"
    );
    // The leaves are smooth-shaded (shaded apart from their faces); the low-poly trunk,
    // island and sea are flat-shaded.
    assert_eq!(c.shaded_apart, 7, "{c:?}");
    {
        let world = app.world_mut();
        let mut q = world.query::<(&Name, &bevy_penumbra_df::CasterShading)>();
        for (name, shading) in q.iter(world) {
            assert_eq!(
                shading.apart,
                name.ends_with("Leaves"),
                "{name}: {shading:?}"
            );
        }
    }
    // A size threshold above the leaves (≈ 1.7 m) but below the trunk and the
    // landscape skips the leaves.
    app.world_mut()
        .get_mut::<DistanceFieldSceneCasters>(root)
        .unwrap()
        .min_size = 2.5;
    settle(&mut app);
    let c = counts(&app, root);
    assert_eq!((c.casters, c.small), (3, 7), "{c:?}");
    assert_eq!(casters(&mut app).len(), 3);
}

/// Glass casts nothing: the flight helmet's goggle lenses (alpha-blended) and the barn
/// lamp's glass (`KHR_materials_transmission`, a transmissive `StandardMaterial`) are
/// skipped, as Bevy draws both after the G-buffer the passes read.
#[test]
fn blended_and_transmissive_glass_casts_nothing() {
    let Some(dir) = scenes_dir() else { return };
    let mut app = app(&dir);
    let helmet = spawn(&mut app, "FlightHelmet/FlightHelmet.gltf", coarse());
    let lamp = spawn(
        &mut app,
        "AnisotropyBarnLamp/AnisotropyBarnLamp.gltf",
        coarse(),
    );
    settle(&mut app);
    let (h, l) = (counts(&app, helmet), counts(&app, lamp));
    assert_eq!(h.blended, 1, "{h:?}");
    assert_eq!(l.blended, 1, "{l:?}");
}

#[test]
fn a_respawned_scene_is_tagged_again_and_counted_once() {
    let Some(dir) = scenes_dir() else { return };
    let mut app = app(&dir);
    let skip = DistanceFieldSceneCasters {
        skinned: SkinnedCasters::Skip,
        ..coarse()
    };
    let root = spawn(&mut app, "Fox.glb", skip);
    settle(&mut app);
    assert_eq!(counts(&app, root).skinned, 1);
    // The root's scene is replaced (as a hot reload respawns it): the old instance is
    // despawned, the new one's meshes are tagged, the counts describe the new one only.
    let cornell = app
        .world()
        .resource::<AssetServer>()
        .load(GltfAssetLabel::Scene(0).from_asset("CornellBox.glb"));
    app.world_mut()
        .entity_mut(root)
        .insert(WorldAssetRoot(cornell));
    let start = std::time::Instant::now();
    while counts(&app, root).casters == 0 {
        assert!(
            start.elapsed().as_secs() < 20,
            "the new scene was not tagged in 20 s"
        );
        app.update();
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    settle(&mut app);
    let c = counts(&app, root);
    assert_eq!(
        (c.casters, c.two_sided, c.skinned, c.merged),
        (6, 4, 0, 0),
        "{c:?}"
    );
    assert_eq!(casters(&mut app).len(), 6);
}

/// Alpha-masked meshes (foliage cards) get the scene's `masked_ao_transmission` and are
/// two-sided; opaque ones keep the template's (solid), but a flat opaque quad is a
/// two-sided shell too. Needs no `../shared`.
#[test]
fn masked_meshes_let_the_foliage_transmission_through() {
    let mut app = app(std::path::Path::new("assets"));
    let (card, solid) = {
        let world = app.world_mut();
        let mut meshes = world.resource_mut::<Assets<Mesh>>();
        let card = meshes.add(Rectangle::new(1.0, 1.0));
        let solid = meshes.add(Cuboid::new(1.0, 1.0, 1.0));
        (card, solid)
    };
    let (masked, opaque) = {
        let mut materials = app.world_mut().resource_mut::<Assets<StandardMaterial>>();
        let masked = materials.add(StandardMaterial {
            alpha_mode: AlphaMode::Mask(0.5),
            ..default()
        });
        (masked, materials.add(StandardMaterial::default()))
    };
    let leaf = app
        .world_mut()
        .spawn((Mesh3d(card.clone()), MeshMaterial3d(masked)))
        .id();
    let block = app
        .world_mut()
        .spawn((Mesh3d(solid), MeshMaterial3d(opaque.clone())))
        .id();
    // An opaque single-sided quad (a decal): flat and open, so a shell, but no foliage.
    let decal = app
        .world_mut()
        .spawn((Mesh3d(card.clone()), MeshMaterial3d(opaque)))
        .id();
    app.world_mut()
        .spawn((coarse(), Transform::default(), Visibility::default()))
        .add_children(&[leaf, block, decal]);
    for _ in 0..5 {
        app.update();
    }
    let caster = |e: Entity| {
        app.world()
            .get::<DistanceFieldCaster>(e)
            .cloned()
            .expect("tagged")
    };
    let (leaf, block, decal) = (caster(leaf), caster(block), caster(decal));
    assert!(leaf.two_sided);
    assert_eq!(leaf.ao_transmission, FOLIAGE_AO_TRANSMISSION);
    assert!(!block.two_sided);
    assert_eq!(block.ao_transmission, 0.0);
    assert!(decal.two_sided);
    assert_eq!(decal.ao_transmission, 0.0);
}

/// The primitives of one glTF mesh bake as one field over their union: the cake's six
/// slices are six meshes of seven open primitives each (crust, icing, cut faces, a
/// candle); the union of each closes, so it bakes solid (no two-sided shell), on the
/// first primitive's entity, and the others carry no caster.
#[test]
fn a_meshs_primitives_bake_as_one_field() {
    let Some(dir) = scenes_dir() else { return };
    let mut app = app(&dir);
    let root = spawn(&mut app, "AlienCake/cakeBirthday.glb", coarse());
    settle(&mut app);
    let c = counts(&app, root);
    println!("{c:?}");
    let meshes = {
        let world = app.world_mut();
        world
            .query_filtered::<(), With<Mesh3d>>()
            .iter(world)
            .count() as u32
    };
    assert_eq!(meshes, 42, "seven primitives per slice");
    assert_eq!(c.casters + c.merged + c.small, meshes, "{c:?}");
    assert_eq!(c.casters, 6, "one caster per slice: {c:?}");
    let all = casters(&mut app);
    let world = app.world_mut();
    for (entity, caster) in &all {
        let merged = world
            .get::<bevy_penumbra_df::CasterMesh>(*entity)
            .expect("the union as the caster's mesh");
        let union = world
            .resource::<Assets<Mesh>>()
            .get(&merged.0)
            .expect("loaded");
        assert!(union.count_vertices() > 100, "{}", union.count_vertices());
        assert!(!caster.two_sided, "the union is solid");
        // The union carries its members' normals (it had none, so a merged caster was
        // never taken for smooth-shaded), and its shading is decided from them.
        let normals = union.attribute(Mesh::ATTRIBUTE_NORMAL).map(|n| n.len());
        assert_eq!(normals, Some(union.count_vertices()));
        let apart = bevy_penumbra_df::mesh_shading_apart(union);
        assert_eq!(
            world
                .get::<bevy_penumbra_df::CasterShading>(*entity)
                .map(|s| s.apart),
            Some(apart)
        );
    }
    eprintln!(
        "cake: {} of {} casters shaded apart",
        c.shaded_apart, c.casters
    );
    // One request per caster; equal unions share a bake.
    let bakes = *world.resource::<SdfBakeStats>();
    assert_eq!(bakes.failed, 0, "{bakes:?}");
    assert_eq!(
        bakes.baked + bakes.memory_hits + bakes.disk_hits,
        6,
        "{bakes:?}"
    );
}

/// `MergeDistanceFieldCasters` bakes a subtree of several nodes (a prop) as one field:
/// two open halves of a box on two nodes close together, so the union is solid, on the
/// first mesh; without the marker each half is its own caster. Needs no `../shared`.
#[test]
fn a_marked_subtree_bakes_as_one_field() {
    let mut app = app(std::path::Path::new("assets"));
    // Two open halves of a unit box: the bottom, front and left faces, and the top,
    // back and right ones (three faces each, so neither closes alone).
    let halves = {
        let full: Mesh = Cuboid::new(1.0, 1.0, 1.0).into();
        let Some(bevy::mesh::Indices::U32(all)) = full.indices().cloned() else {
            panic!("u32 indices")
        };
        let world = app.world_mut();
        let mut meshes = world.resource_mut::<Assets<Mesh>>();
        // Bevy's cuboid: 6 faces of 6 indices (front, back, right, left, top, bottom).
        let face = |k: usize| all[6 * k..6 * k + 6].to_vec();
        let half = |faces: [usize; 3]| {
            let mut m = full.clone();
            m.insert_indices(bevy::mesh::Indices::U32(
                faces.iter().flat_map(|&k| face(k)).collect(),
            ));
            m
        };
        [meshes.add(half([0, 3, 5])), meshes.add(half([1, 2, 4]))]
    };
    let spawn_prop = |app: &mut App, marked: bool| {
        let world = app.world_mut();
        let parts: Vec<Entity> = halves
            .iter()
            .map(|h| {
                // Each half on its own node (a child of a child).
                let node = world
                    .spawn((Transform::default(), Visibility::default()))
                    .id();
                let mesh = world.spawn(Mesh3d(h.clone())).id();
                world.entity_mut(node).add_child(mesh);
                node
            })
            .collect();
        let prop = world
            .spawn((Transform::default(), Visibility::default()))
            .id();
        world.entity_mut(prop).add_children(&parts);
        if marked {
            world.entity_mut(prop).insert(MergeDistanceFieldCasters);
        }
        let root = world
            .spawn((coarse(), Transform::default(), Visibility::default()))
            .id();
        world.entity_mut(root).add_child(prop);
        root
    };
    let plain = spawn_prop(&mut app, false);
    let merged = spawn_prop(&mut app, true);
    let later = spawn_prop(&mut app, false);
    for _ in 0..5 {
        app.update();
    }
    let c = counts(&app, plain);
    assert_eq!((c.casters, c.merged), (2, 0), "{c:?}");
    let c = counts(&app, merged);
    assert_eq!((c.casters, c.merged, c.two_sided), (1, 1, 0), "{c:?}");
    // A marker inserted once the prop is tagged (as after a glTF scene spawns)
    // re-decides its subtree.
    assert_eq!(counts(&app, later).casters, 2);
    let prop = app.world().get::<Children>(later).expect("the prop")[0];
    app.world_mut()
        .entity_mut(prop)
        .insert(MergeDistanceFieldCasters);
    for _ in 0..5 {
        app.update();
    }
    let c = counts(&app, later);
    assert_eq!((c.casters, c.merged), (1, 1), "{c:?}");
    // The merged caster's mesh is the union of both halves: 6 faces.
    let world = app.world_mut();
    let unions: Vec<usize> = world
        .query::<(&bevy_penumbra_df::CasterMesh, &DistanceFieldSceneCaster)>()
        .iter(world)
        .filter(|(_, tag)| tag.0 == merged || tag.0 == later)
        .map(|(m, _)| {
            world
                .resource::<Assets<Mesh>>()
                .get(&m.0)
                .map_or(0, |u| u.indices().map_or(0, |i| i.len() / 3))
        })
        .collect();
    assert_eq!(
        unions,
        [12, 12],
        "one union of 12 triangles per merged prop"
    );
}

/// Ground (rule 5): an open sheet facing up bakes solid below it, along the world's +y
/// in the mesh's space — a floor quad (double-sided or not), the same quad mirrored
/// (scale −1 in x: its twin), and a quad lying in its local xy plane under a node that
/// turns it to face up (a Z-up export: up is the mesh's +z). A ceiling (the quad turned
/// to face down) and an upright card stay two-sided shells.
#[test]
fn open_sheets_facing_up_bake_as_ground() {
    use bevy_penumbra_df::SdfBakeRequest;
    use penumbra_sdf::SignMethod;
    let mut app = app(std::path::Path::new("assets"));
    let (floor, card) = {
        let mut meshes = app.world_mut().resource_mut::<Assets<Mesh>>();
        (
            meshes.add(Plane3d::default().mesh().size(4.0, 4.0).build()),
            meshes.add(Rectangle::new(4.0, 4.0)),
        )
    };
    let (single, double) = {
        let mut materials = app.world_mut().resource_mut::<Assets<StandardMaterial>>();
        let double = materials.add(StandardMaterial {
            double_sided: true,
            cull_mode: None,
            ..default()
        });
        (materials.add(StandardMaterial::default()), double)
    };
    let cases = [
        (
            "floor",
            floor.clone(),
            double.clone(),
            Transform::default(),
            Some(Vec3::Y),
        ),
        (
            "single-sided floor",
            floor.clone(),
            single,
            Transform::default(),
            Some(Vec3::Y),
        ),
        (
            "mirrored floor",
            floor.clone(),
            double.clone(),
            Transform::from_scale(Vec3::new(-1.0, 1.0, 1.0)),
            Some(Vec3::Y),
        ),
        (
            "Z-up floor",
            card.clone(),
            double.clone(),
            Transform::from_rotation(Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2)),
            Some(Vec3::Z),
        ),
        (
            "ceiling",
            floor,
            double.clone(),
            Transform::from_rotation(Quat::from_rotation_x(std::f32::consts::PI)),
            None,
        ),
        ("upright card", card, double, Transform::default(), None),
    ];
    let root = app
        .world_mut()
        .spawn((coarse(), Transform::default(), Visibility::default()))
        .id();
    let entities: Vec<Entity> = cases
        .iter()
        .map(|(_, mesh, material, transform, _)| {
            app.world_mut()
                .spawn((
                    Mesh3d(mesh.clone()),
                    MeshMaterial3d(material.clone()),
                    *transform,
                    ChildOf(root),
                ))
                .id()
        })
        .collect();
    for _ in 0..5 {
        app.update();
    }
    for ((name, .., up), entity) in cases.iter().zip(entities) {
        let caster = app.world().get::<DistanceFieldCaster>(entity).expect(name);
        assert_eq!(caster.ground, up.is_some(), "{name}");
        assert_eq!(caster.two_sided, up.is_none(), "{name}");
        let request = app.world().get::<SdfBakeRequest>(entity).expect(name);
        match (up, request.settings.sign) {
            (Some(want), SignMethod::SolidBelow { up }) => {
                assert!(up.abs_diff_eq(*want, 1e-3), "{name}: up {up}, want {want}");
            }
            (None, SignMethod::TwoSided { .. }) => {}
            (_, sign) => panic!("{name}: {sign:?}"),
        }
    }
    let c = counts(&app, root);
    assert_eq!((c.casters, c.ground, c.two_sided), (6, 4, 2), "{c:?}");
}
