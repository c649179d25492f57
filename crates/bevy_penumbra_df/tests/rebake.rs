//! The GPU re-bake's main-world side (`DistanceFieldRebake`) on the Fox of
//! `../shared/scenes`: the mesh gets a caster entity instead of capsules; the caster's
//! cube (its transform maps voxels to the world) holds every vertex skinned as Bevy
//! skins it, with the margin; a turned joint moves the cube on the next bake, and only
//! on a bake frame (`interval`); a new resolution makes a new caster; removing the
//! component or despawning the mesh despawns the caster, and the scene's rule casts the
//! mesh again (capsules, or its bind-pose field); a still pose is not baked again,
//! and a new one marks its cube dirty in the global field even where the cube stays.
//! Main world only (no GPU);
//! `rebake_gpu.rs` checks the pass, the scene corpus the shadows it casts.

use bevy::mesh::skinning::SkinnedMesh;
use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;
use bevy_penumbra_df::{
    CasterSource, DistanceFieldCaster, DistanceFieldRebake, DistanceFieldRebakeStats,
    DistanceFieldSceneCasters, GlobalDistanceField, GlobalDistanceFieldPlugin,
    GlobalDistanceFieldStats, RebakeCaster, RebakedFrom, SkinCapsules, SkinnedCasters,
};
use penumbra_df_core::rebake::REBAKE_MARGIN;

#[path = "support/scenes_app.rs"]
mod support;

/// Spawns the Fox (scene casters at their defaults) and runs until its skinned mesh
/// exists; inserts `rebake` on it and runs until its caster exists. The mesh entity.
fn fox(app: &mut App, rebake: DistanceFieldRebake) -> Entity {
    let scene = app
        .world()
        .resource::<AssetServer>()
        .load(GltfAssetLabel::Scene(0).from_asset("Fox.glb"));
    app.world_mut()
        .spawn((WorldAssetRoot(scene), DistanceFieldSceneCasters::default()));
    let start = std::time::Instant::now();
    let mut mesh = None;
    while start.elapsed().as_secs() < 20 {
        let world = app.world_mut();
        if mesh.is_none() {
            mesh = world
                .query_filtered::<Entity, With<SkinnedMesh>>()
                .iter(world)
                .next();
            if let Some(m) = mesh {
                world.entity_mut(m).insert(rebake.clone());
            }
        }
        if let Some(m) = mesh
            && world.get::<RebakeCaster>(m).is_some()
        {
            app.update();
            return m;
        }
        app.update();
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    panic!("the fox got no re-baked caster in 20 s");
}

/// The caster entity, its resolution (from its volume's cube) and its transform.
fn caster(app: &App, mesh: Entity) -> (Entity, Transform) {
    let world = app.world();
    let caster = world.get::<RebakeCaster>(mesh).expect("re-baked").entity();
    assert_eq!(world.get::<RebakedFrom>(caster), Some(&RebakedFrom(mesh)));
    let source = &world
        .get::<DistanceFieldCaster>(caster)
        .expect("a caster")
        .source;
    assert!(matches!(source, CasterSource::Sdf(_)), "{source:?}");
    (caster, *world.get::<Transform>(caster).expect("placed"))
}

/// Every skinned vertex lies in the cube `[margin, resolution − 1 − margin]` voxels.
fn assert_cube_holds(app: &App, mesh: Entity, resolution: u32) {
    let (_, transform) = caster(app, mesh);
    let voxel = transform.scale.x;
    let lo = REBAKE_MARGIN - 1e-3;
    let hi = (resolution - 1) as f32 - REBAKE_MARGIN + 1e-3;
    let mut touches = 0;
    for (v, _) in support::skinned_vertices(app, mesh) {
        let i = (v - transform.translation) / voxel;
        assert!(
            i.cmpge(Vec3::splat(lo)).all() && i.cmple(Vec3::splat(hi)).all(),
            "vertex {v} at voxel {i}, outside the cube's margin"
        );
        touches += usize::from(i.min_element() < lo + 0.01 || i.max_element() > hi - 0.01);
    }
    // The cube is as tight as its margin allows along the pose's longest side.
    assert!(touches >= 1, "no vertex touches the cube's margin");
}

#[test]
fn the_fox_rebakes_into_a_cube_that_follows_its_pose() {
    let Some(mut app) = support::scenes_app("the_fox_rebakes_into_a_cube_that_follows_its_pose")
    else {
        return;
    };
    let mesh = fox(
        &mut app,
        DistanceFieldRebake {
            resolution: 24,
            interval: 3,
            ..default()
        },
    );
    // Re-baked meshes get no capsules.
    let world = app.world_mut();
    assert_eq!(
        world
            .query::<&SkinCapsules>()
            .iter(world)
            .filter(|c| !c.entities().is_empty())
            .count(),
        0
    );
    assert_cube_holds(&app, mesh, 24);
    // Turn the first joint with children (the root of the legs and spine) a quarter turn:
    // the cube follows on the next bake, not before.
    let skin = app.world().get::<SkinnedMesh>(mesh).unwrap().clone();
    let joint = skin.joints[1];
    let (_, before) = caster(&app, mesh);
    app.world_mut()
        .get_mut::<Transform>(joint)
        .unwrap()
        .rotate_local_x(std::f32::consts::FRAC_PI_2);
    let mut moved_at = None;
    for frame in 1..=3 {
        app.update();
        let (_, now) = caster(&app, mesh);
        if now != before {
            moved_at.get_or_insert(frame);
        }
    }
    let moved_at = moved_at.expect("the cube follows the turned joint within an interval");
    assert_cube_holds(&app, mesh, 24);
    // Still: the cube stays between bakes and at them.
    let (_, settled) = caster(&app, mesh);
    for _ in 0..4 {
        app.update();
        assert_eq!(caster(&app, mesh).1, settled);
    }
    eprintln!("the cube moved {moved_at} frame(s) after the joint turned (interval 3)");
    // A new resolution: a new caster, the old one gone.
    let (old, _) = caster(&app, mesh);
    app.world_mut()
        .get_mut::<DistanceFieldRebake>(mesh)
        .unwrap()
        .resolution = 40;
    app.update();
    app.update();
    let (new, _) = caster(&app, mesh);
    assert_ne!(new, old);
    assert!(app.world().get_entity(old).is_err(), "the old caster stays");
    assert_cube_holds(&app, mesh, 40);
    // Removing the component lets the caster go.
    app.world_mut()
        .entity_mut(mesh)
        .remove::<DistanceFieldRebake>();
    app.update();
    app.update();
    assert!(
        app.world().get_entity(new).is_err(),
        "the caster outlives its component"
    );
    assert!(app.world().get::<RebakeCaster>(mesh).is_none());
}

/// Runs until `done` holds (at most 20 s of updates); panics with `what` otherwise.
fn run_until(app: &mut App, what: &str, mut done: impl FnMut(&mut World) -> bool) {
    let start = std::time::Instant::now();
    while start.elapsed().as_secs() < 20 {
        app.update();
        if done(app.world_mut()) {
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    panic!("{what} within 20 s");
}

/// Capsule casters under the mesh's `SkinCapsules`.
fn capsules(world: &World, mesh: Entity) -> usize {
    world
        .get::<SkinCapsules>(mesh)
        .map_or(0, |c| c.entities().len())
}

#[test]
fn a_mesh_whose_rebake_goes_casts_by_the_rule_again() {
    let test = "a_mesh_whose_rebake_goes_casts_by_the_rule_again";
    // Capsules (the default): they go while re-baked and come back after.
    let Some(mut app) = support::scenes_app(test) else {
        return;
    };
    let mesh = fox(&mut app, DistanceFieldRebake::default());
    assert_eq!(
        capsules(app.world(), mesh),
        0,
        "capsules beside the re-bake"
    );
    app.world_mut()
        .entity_mut(mesh)
        .remove::<DistanceFieldRebake>();
    run_until(&mut app, "no capsules came back", |w| {
        capsules(w, mesh) > 0 && w.get::<RebakeCaster>(mesh).is_none()
    });
    // The bind-pose field: it goes while re-baked (no field cast twice) and comes back.
    let Some(mut app) = support::scenes_app(test) else {
        return;
    };
    let scene = app
        .world()
        .resource::<AssetServer>()
        .load(GltfAssetLabel::Scene(0).from_asset("Fox.glb"));
    app.world_mut().spawn((
        WorldAssetRoot(scene),
        DistanceFieldSceneCasters {
            skinned: SkinnedCasters::BindPose,
            ..default()
        },
    ));
    let bind_pose = |w: &mut World| {
        w.query_filtered::<Entity, (With<SkinnedMesh>, With<DistanceFieldCaster>)>()
            .iter(w)
            .next()
    };
    run_until(&mut app, "no bind-pose caster", |w| bind_pose(w).is_some());
    let mesh = bind_pose(app.world_mut()).unwrap();
    app.world_mut()
        .entity_mut(mesh)
        .insert(DistanceFieldRebake::default());
    run_until(
        &mut app,
        "the bind-pose field stayed beside the re-bake",
        |w| w.get::<RebakeCaster>(mesh).is_some() && w.get::<DistanceFieldCaster>(mesh).is_none(),
    );
    app.world_mut()
        .entity_mut(mesh)
        .remove::<DistanceFieldRebake>();
    run_until(&mut app, "no bind-pose field came back", |w| {
        w.get::<RebakeCaster>(mesh).is_none() && w.get::<DistanceFieldCaster>(mesh).is_some()
    });
}

#[test]
fn a_despawned_fox_takes_its_rebaked_caster_along() {
    let Some(mut app) = support::scenes_app("a_despawned_fox_takes_its_rebaked_caster_along")
    else {
        return;
    };
    let mesh = fox(&mut app, DistanceFieldRebake::default());
    let (caster, _) = caster(&app, mesh);
    app.world_mut().entity_mut(mesh).despawn();
    app.update();
    assert!(
        app.world().get_entity(caster).is_err(),
        "the caster outlives its mesh"
    );
}

#[test]
fn a_still_fox_is_not_baked_again_and_a_new_pose_dirties_the_global_field() {
    let test = "a_still_fox_is_not_baked_again_and_a_new_pose_dirties_the_global_field";
    let Some(dir) = support::scenes_dir(test) else {
        return;
    };
    let mut app = support::scenes_app_with(&dir, |app| {
        app.add_plugins(GlobalDistanceFieldPlugin);
    });
    app.world_mut().spawn((
        Transform::from_xyz(0.0, 40.0, 60.0),
        GlobalDistanceField::default(),
    ));
    let mesh = fox(&mut app, DistanceFieldRebake::default());
    // Until the new camera's clipmaps are composed.
    for _ in 0..100 {
        if app.world().resource::<GlobalDistanceFieldStats>().pending == 0 {
            break;
        }
        app.update();
    }
    let rebakes = |app: &App| app.world().resource::<DistanceFieldRebakeStats>().clone();
    // The Fox stands in its rest pose (nothing plays its animations): after its first
    // bake, frame after frame, nothing is baked and nothing is dirtied.
    for _ in 0..3 {
        app.update();
        let stats = rebakes(&app);
        assert_eq!(
            stats,
            DistanceFieldRebakeStats {
                meshes: 1,
                bakes: 0,
                still: 1,
                triangles: 0
            }
        );
        let field = app.world().resource::<GlobalDistanceFieldStats>();
        assert_eq!(field.dirty_regions, 0, "{field:?}");
    }
    // A turned joint: one bake of every triangle, and the global field told of its
    // cube: one region for the bake, plus where the caster's record was and is if the
    // cube moved.
    let skin = app.world().get::<SkinnedMesh>(mesh).unwrap().clone();
    let (_, before) = caster(&app, mesh);
    app.world_mut()
        .get_mut::<Transform>(skin.joints[skin.joints.len() / 2])
        .unwrap()
        .rotate_local_z(0.2);
    app.update();
    let stats = rebakes(&app);
    assert_eq!((stats.bakes, stats.still), (1, 0), "{stats:?}");
    assert!(stats.triangles > 500, "{stats:?}");
    let moved = caster(&app, mesh).1 != before;
    let field = app.world().resource::<GlobalDistanceFieldStats>();
    assert_eq!(
        field.dirty_regions,
        1 + 2 * usize::from(moved),
        "cube moved: {moved}; {field:?}"
    );
    assert!(field.dirtied > 0, "no brick composed again: {field:?}");
    eprintln!("a turned joint: {stats:?}, cube moved: {moved}, {field:?}");
}
