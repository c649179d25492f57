//! SDF assets in a Bevy app: the `.psdf` loader (good and corrupt files), runtime baking
//! with progress, instance sharing, and the disk cache across app runs.

use bevy::{asset::LoadState, prelude::*};
use bevy_penumbra_df::{
    SdfAssetPlugin, SdfBakeCache, SdfBakeFailed, SdfBakeRequest, SdfBakeStats, SdfBakeTask,
    SdfBakeWaiting, SdfBaked, SdfVolumeAsset, mesh_to_tri_mesh,
};
use penumbra_sdf::{BakeSettings, GridPolicy, Resolution, format};
use std::path::PathBuf;

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("bevy_penumbra_df_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn app(asset_dir: &std::path::Path, cache: Option<PathBuf>) -> App {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        AssetPlugin {
            file_path: asset_dir.display().to_string(),
            ..default()
        },
        SdfAssetPlugin,
    ))
    .init_asset::<Mesh>()
    .insert_resource(SdfBakeCache::with_directory(cache));
    app.finish();
    app.cleanup();
    app
}

fn settings() -> BakeSettings {
    BakeSettings {
        grid: GridPolicy {
            resolution: Resolution::LongestAxis(24),
            border_voxels: 2,
            thin_walls: penumbra_sdf::grid::ThinWalls::OFF,
        },
        ..default()
    }
}

fn update_until(app: &mut App, mut done: impl FnMut(&mut App) -> bool) {
    for _ in 0..2000 {
        app.update();
        if done(app) {
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    panic!("condition not reached in 2000 frames");
}

#[test]
fn loads_psdf_files_and_rejects_corrupt_ones() {
    let dir = temp_dir("loader");
    let mesh = penumbra_sdf::shapes::sphere(1.0, 16, 8);
    let volume = penumbra_sdf::bake(&mesh, &settings(), None).unwrap().volume;
    let bytes = format::to_bytes(&volume);
    std::fs::write(dir.join("good.psdf"), &bytes).unwrap();
    let mut corrupt = bytes.clone();
    corrupt[100] ^= 0xff;
    std::fs::write(dir.join("corrupt.psdf"), &corrupt).unwrap();
    std::fs::write(dir.join("truncated.psdf"), &bytes[..50]).unwrap();

    let mut app = app(&dir, None);
    let server = app.world().resource::<AssetServer>().clone();
    let good: Handle<SdfVolumeAsset> = server.load("good.psdf");
    let bad: Vec<Handle<SdfVolumeAsset>> =
        vec![server.load("corrupt.psdf"), server.load("truncated.psdf")];
    update_until(&mut app, |app| {
        let server = app.world().resource::<AssetServer>();
        server.is_loaded(&good)
            && bad
                .iter()
                .all(|h| matches!(server.load_state(h), LoadState::Failed(_)))
    });
    let assets = app.world().resource::<Assets<SdfVolumeAsset>>();
    assert_eq!(assets.get(&good).unwrap().volume, volume);
    let server = app.world().resource::<AssetServer>();
    for h in &bad {
        let LoadState::Failed(e) = server.load_state(h) else {
            unreachable!()
        };
        let message = e.to_string();
        assert!(
            message.contains("checksum") || message.contains("truncated"),
            "{message}"
        );
    }
}

#[test]
fn bakes_meshes_with_progress_shares_instances_and_caches_on_disk() {
    let dir = temp_dir("bake");
    let cache = dir.join("cache");
    let sphere = Sphere::new(0.5).mesh().ico(3).unwrap();
    let expected = penumbra_sdf::bake(&mesh_to_tri_mesh(&sphere).unwrap(), &settings(), None)
        .unwrap()
        .volume;

    let run = |expect: SdfBakeStats| {
        let mut app = app(&dir, Some(cache.clone()));
        let handle = app
            .world_mut()
            .resource_mut::<Assets<Mesh>>()
            .add(sphere.clone());
        let first = app
            .world_mut()
            .spawn(SdfBakeRequest {
                mesh: handle.clone(),
                settings: settings(),
                stretch: Vec3::ONE,
            })
            .id();
        // A duplicate in the same frame must not start a second bake.
        let same_frame = app
            .world_mut()
            .spawn(SdfBakeRequest {
                mesh: handle.clone(),
                settings: settings(),
                stretch: Vec3::ONE,
            })
            .id();
        // A second instance of the same mesh, requested one frame later.
        app.update();
        let progress_seen = app
            .world()
            .get::<SdfBakeTask>(first)
            .map(SdfBakeTask::progress);
        let second = app
            .world_mut()
            .spawn(SdfBakeRequest {
                mesh: handle,
                settings: settings(),
                stretch: Vec3::ONE,
            })
            .id();
        update_until(&mut app, |app| {
            [first, same_frame, second]
                .iter()
                .all(|&e| app.world().get::<SdfBaked>(e).is_some())
        });
        assert_eq!(
            app.world().get::<SdfBaked>(same_frame).unwrap().0,
            app.world().get::<SdfBaked>(first).unwrap().0
        );
        let a = app.world().get::<SdfBaked>(first).unwrap().0.clone();
        let b = app.world().get::<SdfBaked>(second).unwrap().0.clone();
        assert_eq!(a, b, "instances share one asset");
        let assets = app.world().resource::<Assets<SdfVolumeAsset>>();
        assert_eq!(assets.get(&a).unwrap().volume, expected);
        assert_eq!(*app.world().resource::<SdfBakeStats>(), expect);
        // The first run's bake is in flight after one frame (progress: see
        // `bake_progress_rises_to_one`); the second run reads the disk cache.
        assert!(progress_seen.is_none_or(|p| (0.0..=1.0).contains(&p)));
    };
    // First run bakes once; second instance is a memory hit.
    run(SdfBakeStats {
        baked: 1,
        disk_hits: 0,
        memory_hits: 2,
        failed: 0,
    });
    assert_eq!(std::fs::read_dir(&cache).unwrap().count(), 1);
    // A new app (a second run of the game) reads the disk cache instead of baking.
    run(SdfBakeStats {
        baked: 0,
        disk_hits: 1,
        memory_hits: 2,
        failed: 0,
    });
}

#[test]
fn unbakeable_meshes_fail_with_a_reason() {
    let dir = temp_dir("fail");
    let mut app = app(&dir, None);
    let lines = Mesh::new(
        bevy::mesh::PrimitiveTopology::LineList,
        bevy::asset::RenderAssetUsages::default(),
    )
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_POSITION,
        vec![[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0]],
    );
    let empty = Mesh::new(
        bevy::mesh::PrimitiveTopology::TriangleList,
        bevy::asset::RenderAssetUsages::default(),
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, Vec::<[f32; 3]>::new());
    let mut entities = Vec::new();
    for mesh in [lines, empty] {
        let handle = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
        entities.push(
            app.world_mut()
                .spawn(SdfBakeRequest {
                    mesh: handle,
                    settings: settings(),
                    stretch: Vec3::ONE,
                })
                .id(),
        );
    }
    update_until(&mut app, |app| {
        entities
            .iter()
            .all(|&e| app.world().get::<SdfBakeFailed>(e).is_some())
    });
    let reasons: Vec<String> = entities
        .iter()
        .map(|&e| app.world().get::<SdfBakeFailed>(e).unwrap().0.clone())
        .collect();
    assert!(reasons[0].contains("LineList"), "{}", reasons[0]);
    assert!(reasons[1].contains("no triangles"), "{}", reasons[1]);
    assert_eq!(app.world().resource::<SdfBakeStats>().failed, 2);
}

/// A bake slow enough to be in flight for many frames (≈ 0.3–1 s on two cores).
fn slow_settings() -> BakeSettings {
    BakeSettings {
        grid: GridPolicy {
            resolution: Resolution::LongestAxis(112),
            border_voxels: 2,
            thin_walls: penumbra_sdf::grid::ThinWalls::OFF,
        },
        ..default()
    }
}

fn request(app: &mut App, mesh: &Handle<Mesh>, settings: BakeSettings) -> Entity {
    app.world_mut()
        .spawn(SdfBakeRequest {
            mesh: mesh.clone(),
            settings,
            stretch: Vec3::ONE,
        })
        .id()
}

fn add_mesh(app: &mut App, mesh: Mesh) -> Handle<Mesh> {
    app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh)
}

fn baked_volume(app: &App, e: Entity) -> Option<penumbra_sdf::SdfVolume> {
    let handle = &app.world().get::<SdfBaked>(e)?.0;
    let assets = app.world().resource::<Assets<SdfVolumeAsset>>();
    Some(assets.get(handle)?.volume.clone())
}

fn lines() -> Mesh {
    Mesh::new(
        bevy::mesh::PrimitiveTopology::LineList,
        bevy::asset::RenderAssetUsages::default(),
    )
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_POSITION,
        vec![[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0]],
    )
}

/// An identical request waits for the running bake without being converted and hashed
/// again every frame (its state is set once), and still gets the result when the entity
/// that started the bake is despawned mid-bake (before, the key leaked and it waited
/// forever).
#[test]
fn waiting_requests_are_set_once_and_survive_their_starter() {
    let dir = temp_dir("waiters");
    let mut app = app(&dir, None);
    let mesh = add_mesh(&mut app, Sphere::new(0.5).mesh().ico(4).unwrap());
    let a = request(&mut app, &mesh, slow_settings());
    let b = request(&mut app, &mesh, slow_settings());
    app.update();
    // Requests are handled in entity order: one starts the bake, the other waits.
    let (starter, waiter) = if app.world().get::<SdfBakeTask>(a).is_some() {
        (a, b)
    } else {
        (b, a)
    };
    assert!(app.world().get::<SdfBakeTask>(starter).is_some());
    let set_at = |app: &App| {
        app.world()
            .entity(waiter)
            .get_ref::<SdfBakeWaiting>()
            .map(|w| w.last_changed())
    };
    let first = set_at(&app).expect("the identical request waits");
    for _ in 0..3 {
        app.update();
        if app.world().get::<SdfBaked>(waiter).is_some() {
            break;
        }
        assert_eq!(set_at(&app), Some(first), "the waiting state was set again");
    }
    app.world_mut().despawn(starter);
    update_until(&mut app, |app| {
        app.world().get::<SdfBaked>(waiter).is_some()
    });
    let stats = *app.world().resource::<SdfBakeStats>();
    assert_eq!((stats.baked, stats.memory_hits, stats.failed), (1, 1, 0));
}

/// A request that changes while its bake runs gets the new mesh's SDF, never the stale
/// one; a failed request retries when its mesh changes, whether the request names a new
/// mesh or the mesh asset itself is modified.
#[test]
fn changed_requests_drop_stale_and_failed_outcomes() {
    let dir = temp_dir("changes");
    let mut app = app(&dir, None);
    let big = add_mesh(&mut app, Sphere::new(0.5).mesh().ico(4).unwrap());
    let small = Cuboid::new(0.4, 0.3, 0.2).mesh().build();
    let small_handle = add_mesh(&mut app, small.clone());
    let want = penumbra_sdf::bake(&mesh_to_tri_mesh(&small).unwrap(), &slow_settings(), None)
        .unwrap()
        .volume;
    // Mid-bake, the entity's request changes to another mesh.
    let e = request(&mut app, &big, slow_settings());
    app.update();
    assert!(app.world().get::<SdfBakeTask>(e).is_some());
    app.world_mut().get_mut::<SdfBakeRequest>(e).unwrap().mesh = small_handle;
    update_until(&mut app, |app| {
        baked_volume(app, e).is_some() && app.world().resource::<SdfBakeStats>().baked == 2
    });
    assert!(baked_volume(&app, e).unwrap() == want, "a stale SDF");

    // A failed request retries with a new mesh…
    let bad = add_mesh(&mut app, lines());
    let f = request(&mut app, &bad, settings());
    update_until(&mut app, |app| {
        app.world().get::<SdfBakeFailed>(f).is_some()
    });
    let good = add_mesh(&mut app, Sphere::new(0.3).mesh().ico(2).unwrap());
    app.world_mut().get_mut::<SdfBakeRequest>(f).unwrap().mesh = good;
    update_until(&mut app, |app| app.world().get::<SdfBaked>(f).is_some());
    assert!(app.world().get::<SdfBakeFailed>(f).is_none());
    // …and when its mesh asset is fixed in place.
    let g = request(&mut app, &bad, settings());
    update_until(&mut app, |app| {
        app.world().get::<SdfBakeFailed>(g).is_some()
    });
    app.world_mut()
        .resource_mut::<Assets<Mesh>>()
        .insert(&bad, Sphere::new(0.2).mesh().ico(2).unwrap())
        .unwrap();
    update_until(&mut app, |app| app.world().get::<SdfBaked>(g).is_some());
}

/// `SdfBakeTask::progress` moves from 0 towards 1 during a bake: seen at several values
/// in between, never decreasing, never outside [0, 1]. (The task stores 1 as it ends, but
/// the component is gone by the frame that would show it.)
#[test]
fn bake_progress_rises_to_one() {
    let dir = temp_dir("progress");
    let mut app = app(&dir, None);
    let mesh = add_mesh(&mut app, Sphere::new(0.5).mesh().ico(4).unwrap());
    let e = request(&mut app, &mesh, slow_settings());
    let mut seen = Vec::new();
    update_until(&mut app, |app| {
        if let Some(task) = app.world().get::<SdfBakeTask>(e) {
            seen.push(task.progress());
        }
        app.world().get::<SdfBaked>(e).is_some()
    });
    let between = seen.iter().filter(|&&p| p > 0.0 && p < 1.0).count();
    println!("progress seen: {seen:?}");
    assert!(
        seen.windows(2).all(|w| w[0] <= w[1]),
        "progress went back: {seen:?}"
    );
    assert!(between >= 3, "progress seen at {between} values in (0, 1)");
    assert!(seen.iter().all(|p| (0.0..=1.0).contains(p)));
}
