//! Skinned meshes cast through capsules fitted to their joints (`SkinnedCasters::Capsules`,
//! the default): the Fox of `../shared/scenes` gets capsules that hang from its joints,
//! hold its skinned vertices in the pose Bevy's skinning gives them (computed here on the
//! CPU from the joints' transforms, the inverse bind matrices and the weights: linear
//! blend skinning), follow a joint that turns, upload only the records of the joints that
//! moved, hide with the mesh, and go with the settings or the root. Main world only (no
//! GPU).

use bevy::mesh::skinning::SkinnedMesh;
use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;
use bevy_penumbra_df::{
    CasterSource, DistanceFieldCaster, DistanceFieldSceneCasters, DistanceFieldUploadStats,
    SceneCasterCounts, SkinCapsule, SkinCapsules, SkinnedCasters,
};

#[path = "support/scenes_app.rs"]
mod support;

fn app() -> Option<App> {
    support::scenes_app("skin_capsules")
}

/// Spawns the Fox and runs until its capsules exist (or 20 s pass); the root and the
/// mesh entity.
fn fox(app: &mut App) -> (Entity, Entity) {
    let scene = app
        .world()
        .resource::<AssetServer>()
        .load(GltfAssetLabel::Scene(0).from_asset("Fox.glb"));
    let root = app
        .world_mut()
        .spawn((WorldAssetRoot(scene), DistanceFieldSceneCasters::default()))
        .id();
    let start = std::time::Instant::now();
    while start.elapsed().as_secs() < 20 {
        app.update();
        let world = app.world_mut();
        if let Some(mesh) = world
            .query_filtered::<Entity, With<SkinCapsules>>()
            .iter(world)
            .next()
        {
            app.update();
            return (root, mesh);
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    panic!("the fox got no capsules in 20 s");
}

/// The capsules: entity, joint, radius, half length, world transform.
fn capsules(app: &mut App) -> Vec<(Entity, Entity, f32, f32, GlobalTransform)> {
    let world = app.world_mut();
    world
        .query::<(Entity, &SkinCapsule, &DistanceFieldCaster, &GlobalTransform)>()
        .iter(world)
        .map(|(e, s, c, g)| {
            let CasterSource::Capsule {
                radius,
                half_length,
            } = c.source
            else {
                panic!("a skin capsule that is not a capsule: {:?}", c.source);
            };
            (e, s.joint, radius, half_length, *g)
        })
        .collect()
}

/// Distance from world point `p` to a capsule (local y axis) placed by `g`, in the
/// capsule's local units scaled by `g`'s mean scale.
fn capsule_distance(g: &GlobalTransform, radius: f32, half_length: f32, p: Vec3) -> f32 {
    let (scale, _, _) = g.to_scale_rotation_translation();
    let local = g.affine().inverse().transform_point3(p);
    let core = Vec3::new(0.0, local.y.clamp(-half_length, half_length), 0.0);
    ((local - core).length() - radius) * (scale.x + scale.y + scale.z) / 3.0
}

/// For each joint with capsules, the fraction of its skinned vertices (posed) within
/// `slack` of a capsule's radius of one of its capsules (world space).
fn coverage(app: &mut App, mesh: Entity, slack: f32) -> Vec<f32> {
    let vertices = support::skinned_vertices(app, mesh);
    let capsules = capsules(app);
    let mut joints: Vec<Entity> = capsules.iter().map(|c| c.1).collect();
    joints.sort();
    joints.dedup();
    joints
        .iter()
        .map(|joint| {
            let own: Vec<Vec3> = vertices
                .iter()
                .filter(|(_, j)| j == joint)
                .map(|(p, _)| *p)
                .collect();
            let inside = own
                .iter()
                .filter(|p| {
                    capsules
                        .iter()
                        .filter(|c| c.1 == *joint)
                        .any(|(_, _, radius, half, g)| {
                            let (scale, _, _) = g.to_scale_rotation_translation();
                            let world_radius = radius * (scale.x + scale.y + scale.z) / 3.0;
                            capsule_distance(g, *radius, *half, **p) <= slack * world_radius
                        })
                })
                .count();
            inside as f32 / own.len().max(1) as f32
        })
        .collect()
}

#[test]
fn the_fox_casts_through_capsules_that_follow_its_joints() {
    let Some(mut app) = app() else { return };
    let (root, mesh) = fox(&mut app);
    let c = *app.world().get::<SceneCasterCounts>(root).expect("counts");
    let listed = app
        .world()
        .get::<SkinCapsules>(mesh)
        .unwrap()
        .entities()
        .to_vec();
    assert_eq!((c.casters, c.skinned, c.capsule_meshes), (0, 0, 1), "{c:?}");
    assert_eq!(c.capsules as usize, listed.len(), "{c:?}");
    // At most four a joint (one, and three pieces it leaves out), for 21 joints with cells.
    assert!((6..=84).contains(&listed.len()), "{c:?}");
    let all = capsules(&mut app);
    assert_eq!(all.len(), listed.len());
    let joints = app.world().get::<SkinnedMesh>(mesh).unwrap().joints.clone();
    for (e, joint, radius, half, _) in &all {
        assert!(listed.contains(e));
        assert!(joints.contains(joint));
        assert_eq!(
            app.world().get::<ChildOf>(*e).map(|c| c.parent()),
            Some(*joint)
        );
        assert!(radius.is_finite() && *radius > 0.0 && half.is_finite() && *half >= 0.0);
    }
    // In the rest pose: each joint's capsules lie on its skinned vertices (fitted to the
    // volume they skin, most are within half a radius of a capsule's surface, 62–100 %
    // on the Fox; a capsule in the wrong space holds none).
    let rest = coverage(&mut app, mesh, 0.5);
    assert!(rest.iter().all(|&f| f > 0.5), "{rest:?}");

    // Nothing moves: no record is uploaded.
    app.update();
    app.update();
    assert_eq!(
        app.world()
            .resource::<DistanceFieldUploadStats>()
            .frame_records,
        0
    );

    // Turn the joint of one capsule by 60° (a leg lifting): its vertices move with it,
    // and so does the capsule; only the capsules at or below that joint upload.
    let (_, turned, ..) = all[all.len() / 2];
    app.world_mut()
        .get_mut::<Transform>(turned)
        .unwrap()
        .rotate_local_x(1.05);
    app.update();
    let mut below = vec![turned];
    let mut i = 0;
    while i < below.len() {
        if let Some(children) = app.world().get::<Children>(below[i]) {
            below.extend(children.iter());
        }
        i += 1;
    }
    let moved = all.iter().filter(|c| below.contains(&c.1)).count();
    assert_eq!(
        app.world()
            .resource::<DistanceFieldUploadStats>()
            .frame_records,
        moved
    );
    let posed = coverage(&mut app, mesh, 0.5);
    assert!(posed.iter().all(|&f| f > 0.5), "{posed:?}");

    // Hiding the mesh hides its capsules.
    app.world_mut().entity_mut(mesh).insert(Visibility::Hidden);
    app.update();
    app.update();
    for e in &listed {
        assert_eq!(app.world().get::<Visibility>(*e), Some(&Visibility::Hidden));
    }
    let hidden = |app: &mut App| {
        let world = app.world_mut();
        world
            .query_filtered::<&Visibility, With<SkinCapsule>>()
            .iter(world)
            .all(|v| *v == Visibility::Hidden)
    };

    // Other settings: the capsules go.
    app.world_mut()
        .get_mut::<DistanceFieldSceneCasters>(root)
        .unwrap()
        .skinned = SkinnedCasters::Skip;
    app.update();
    app.update();
    assert!(capsules(&mut app).is_empty());
    let c = *app.world().get::<SceneCasterCounts>(root).unwrap();
    assert_eq!(
        (c.skinned, c.capsule_meshes, c.capsules),
        (1, 0, 0),
        "{c:?}"
    );
    // And back; then the root's component removed: gone again.
    app.world_mut()
        .get_mut::<DistanceFieldSceneCasters>(root)
        .unwrap()
        .skinned = SkinnedCasters::Capsules;
    app.update();
    app.update();
    assert_eq!(capsules(&mut app).len(), listed.len());
    // Made again while the mesh is hidden: hidden too.
    assert!(hidden(&mut app));
    app.world_mut()
        .entity_mut(root)
        .remove::<DistanceFieldSceneCasters>();
    app.update();
    app.update();
    assert!(capsules(&mut app).is_empty());
}

#[test]
fn a_despawned_mesh_takes_its_capsules_with_it() {
    // The mesh alone despawned (its joints stay): the hook despawns its capsules. Then
    // the whole scene: nothing left either.
    let Some(mut app) = app() else { return };
    let (root, mesh) = fox(&mut app);
    assert!(!capsules(&mut app).is_empty());
    app.world_mut().entity_mut(mesh).despawn();
    app.update();
    assert!(capsules(&mut app).is_empty());
    let world = app.world_mut();
    assert_eq!(world.query::<&SkinCapsule>().iter(world).count(), 0);
    let (root2, _) = fox(&mut app);
    assert!(!capsules(&mut app).is_empty());
    app.world_mut().entity_mut(root2).despawn();
    app.world_mut().entity_mut(root).despawn();
    app.update();
    assert!(capsules(&mut app).is_empty());
}
