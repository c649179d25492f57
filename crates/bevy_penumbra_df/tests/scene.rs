//! The distance-field scene's main-world behaviour (no GPU): mesh casters are baked
//! once per mesh and share one atlas placement, freed space is reused, a volume that
//! finds no free box goes bricked, an over-budget atlas falls back to half resolution
//! and then skips with a warning, large volumes go bricked, bad transforms
//! are skipped, uploads follow changes only ("skip what is not needed"), and the memory
//! of a 1,000-instance / 50-asset scene.

use bevy::math::DVec3;
use bevy::prelude::*;
use bevy_penumbra_df::{
    CasterSource, DistanceFieldCaster, DistanceFieldScene, DistanceFieldScenePlugin,
    DistanceFieldSceneSettings, DistanceFieldUploadStats, SdfAssetPlugin, SdfBakeCache,
    SdfVolumeAsset,
};
use penumbra_df_core::object::{ShapeKind, flags, unpack_10_10_12};
use penumbra_sdf::SdfVolume;

#[path = "support/main_world.rs"]
mod main_world;

fn app(settings: DistanceFieldSceneSettings) -> App {
    let mut app = main_world::main_world_app();
    app.insert_resource(settings)
        .insert_resource(SdfBakeCache::with_directory(None))
        .add_plugins((SdfAssetPlugin, DistanceFieldScenePlugin));
    app.finish();
    app.cleanup();
    app
}

/// A caster of the SDF asset `h`.
fn sdf_caster(app: &mut App, h: &Handle<SdfVolumeAsset>) -> Entity {
    app.world_mut()
        .spawn(DistanceFieldCaster {
            source: CasterSource::Sdf(h.clone()),
            ..default()
        })
        .id()
}

/// `n` analytic sphere casters of `radius`, 1 m apart along x.
fn spheres_in_a_row(app: &mut App, n: usize, radius: f32) -> Vec<Entity> {
    (0..n)
        .map(|i| {
            app.world_mut()
                .spawn((
                    DistanceFieldCaster {
                        source: CasterSource::Sphere { radius },
                        ..default()
                    },
                    Transform::from_xyz(i as f32, 0.0, 0.0),
                ))
                .id()
        })
        .collect()
}

fn update_until(app: &mut App, mut done: impl FnMut(&App) -> bool) {
    for _ in 0..3000 {
        app.update();
        if done(app) {
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    panic!("condition not reached in 3000 frames");
}

fn stats(app: &App) -> DistanceFieldUploadStats {
    app.world().resource::<DistanceFieldUploadStats>().clone()
}

/// A synthetic SDF of `n³` samples (a sphere), 1 cm voxels.
fn volume(n: u32) -> SdfVolumeAsset {
    volume_of(UVec3::splat(n))
}

/// A synthetic SDF of `dims` samples (an ellipsoid-ish blob), 1 cm voxels.
fn volume_of(dims: UVec3) -> SdfVolumeAsset {
    let c = (dims - UVec3::ONE).as_vec3() * 0.5;
    let r = c.min_element() * 0.8;
    let distances = (0..dims.element_product()).map(|i| {
        let p = Vec3::new(
            (i % dims.x) as f32,
            ((i / dims.x) % dims.y) as f32,
            (i / (dims.x * dims.y)) as f32,
        );
        ((p - c).length() - r) * 0.01
    });
    SdfVolumeAsset {
        volume: SdfVolume::from_distances(dims, -c.as_dvec3() * 0.01, 0.01, distances),
    }
}

#[test]
fn mesh_casters_bake_once_and_share_one_placement() {
    let mut app = app(DistanceFieldSceneSettings::default());
    let mesh = app
        .world_mut()
        .resource_mut::<Assets<Mesh>>()
        .add(Sphere::new(0.5).mesh().ico(3).unwrap());
    let instances: Vec<Entity> = (0..5)
        .map(|i| {
            app.world_mut()
                .spawn((
                    Mesh3d(mesh.clone()),
                    DistanceFieldCaster::default(),
                    // Uniform scales (a stretch bakes its own: `stretched_casters.rs`).
                    Transform::from_xyz(i as f32 * 2.0, 0.0, 0.0)
                        .with_scale(Vec3::splat(1.0 + i as f32 * 0.2)),
                ))
                .id()
        })
        .collect();
    update_until(&mut app, |app| stats(app).objects == 5);
    let s = stats(&app);
    assert_eq!(s.atlas_volumes, 1, "five instances, one SDF");
    assert!(s.atlas_used_bytes > 0 && s.atlas_used_bytes <= s.atlas_bytes);
    let scene = app.world().resource::<DistanceFieldScene>();
    let regions: std::collections::HashSet<[u32; 3]> = instances
        .iter()
        .map(|&e| scene.records()[scene.slot(e).unwrap() as usize].params())
        .collect();
    assert_eq!(regions.len(), 1, "all instances point at one atlas region");
    let r = &scene.records()[scene.slot(instances[0]).unwrap() as usize];
    assert_eq!(r.kind(), ShapeKind::Volume as u32);
    // Despawning every instance frees the atlas.
    for e in instances {
        app.world_mut().despawn(e);
    }
    app.update();
    let s = stats(&app);
    assert_eq!((s.objects, s.atlas_volumes, s.atlas_used_bytes), (0, 0, 0));
}

#[test]
fn over_budget_volumes_fall_back_then_skip() {
    // The smallest atlas: 32×32×8 texels.
    let mut app = app(DistanceFieldSceneSettings {
        atlas_budget_bytes: 32 * 32 * 8 * 2,
        ..default()
    });
    let (small, big, huge) = {
        let mut sdfs = app.world_mut().resource_mut::<Assets<SdfVolumeAsset>>();
        (
            sdfs.add(volume(8)),
            sdfs.add(volume(16)),
            sdfs.add(volume(64)),
        )
    };
    let spawn = sdf_caster;
    let a = spawn(&mut app, &small);
    let b = spawn(&mut app, &big); // 16³ → 9³ (still > 8 deep) → 5³
    let c = spawn(&mut app, &huge); // 64³ → 33³ → 17³: never fits, skipped
    app.update();
    let scene = app.world().resource::<DistanceFieldScene>();
    let dims = |e: Entity| {
        let r = &scene.records()[scene.slot(e).unwrap() as usize];
        unpack_10_10_12(r.params()[1]) + UVec3::ONE
    };
    assert_eq!(dims(a), UVec3::splat(8));
    assert_eq!(dims(b), UVec3::splat(5));
    assert!(scene.slot(c).is_none(), "the huge volume is skipped");
    let s = stats(&app);
    assert_eq!((s.objects, s.atlas_downsampled, s.atlas_skipped), (2, 1, 1));
    // Switching a caster to a volume that fits nowhere lets its old volume go.
    app.world_mut()
        .get_mut::<DistanceFieldCaster>(a)
        .unwrap()
        .source = CasterSource::Sdf(huge.clone());
    app.update();
    let s = stats(&app);
    assert_eq!((s.objects, s.atlas_volumes), (1, 1), "{s:?}");
    // Freed space is reused: despawn the small one, a new small one fits again.
    app.world_mut().despawn(a);
    app.update();
    let d = spawn(&mut app, &small);
    app.update();
    assert!(
        app.world()
            .resource::<DistanceFieldScene>()
            .slot(d)
            .is_some()
    );
}

/// A caster whose SDF fits nowhere is placed once atlas space is freed (before, it was
/// skipped for good).
#[test]
fn unplaceable_volumes_are_retried_when_space_frees() {
    let mut app = app(DistanceFieldSceneSettings {
        atlas_budget_bytes: 32 * 32 * 8 * 2,
        ..default()
    });
    // Each fills the whole 32×32×8 atlas; the second fits nowhere, even at a quarter.
    let (first, second) = {
        let mut sdfs = app.world_mut().resource_mut::<Assets<SdfVolumeAsset>>();
        let dims = UVec3::new(32, 32, 8);
        (sdfs.add(volume_of(dims)), sdfs.add(volume_of(dims)))
    };
    let spawn = sdf_caster;
    let a = spawn(&mut app, &first);
    let b = spawn(&mut app, &second);
    app.update();
    let slot = |app: &App, e: Entity| app.world().resource::<DistanceFieldScene>().slot(e);
    // Casters are placed in entity order: one of them got the atlas.
    let (a, b) = if slot(&app, a).is_some() {
        (a, b)
    } else {
        (b, a)
    };
    assert!(slot(&app, a).is_some() && slot(&app, b).is_none());
    assert_eq!(stats(&app).atlas_skipped, 1);
    app.world_mut().despawn(a);
    app.update();
    app.update();
    assert!(slot(&app, b).is_some(), "placed once the atlas had room");
    let s = stats(&app);
    assert_eq!(
        (s.objects, s.atlas_volumes, s.atlas_skipped),
        (1, 1, 0),
        "{s:?}"
    );
}

/// The object buffer's cap (here 10; the device's storage-binding limit in practice):
/// casters beyond it are skipped and counted, the first ones in entity order keep their
/// slots, and waiting ones join, in entity order, as slots free up.
#[test]
fn casters_beyond_the_cap_wait_for_a_slot() {
    let mut app = app(DistanceFieldSceneSettings {
        max_casters: 10,
        ..default()
    });
    let ids: Vec<Entity> = spheres_in_a_row(&mut app, 15, 0.2);
    app.update();
    // Entity order (`Entity: Ord`), not necessarily spawn order.
    let mut ids = ids;
    ids.sort_unstable();
    let present = |app: &App| -> Vec<bool> {
        let scene = app.world().resource::<DistanceFieldScene>();
        ids.iter().map(|&e| scene.slot(e).is_some()).collect()
    };
    let want: Vec<bool> = (0..15).map(|i| i < 10).collect();
    assert_eq!(present(&app), want);
    assert_eq!((stats(&app).objects, stats(&app).over_cap), (10, 5));
    for &e in &ids[..3] {
        app.world_mut().despawn(e);
    }
    app.update();
    let want: Vec<bool> = (0..15).map(|i| (3..13).contains(&i)).collect();
    assert_eq!(present(&app), want);
    assert_eq!((stats(&app).objects, stats(&app).over_cap), (10, 2));
}

#[test]
fn bad_transforms_are_skipped_not_fatal() {
    let mut app = app(DistanceFieldSceneSettings::default());
    let cases = [
        Transform::from_scale(Vec3::new(1.0, 0.0, 1.0)),
        Transform::from_xyz(f32::NAN, 0.0, 0.0),
        Transform::from_xyz(0.0, f32::INFINITY, 0.0),
    ];
    let ok = app
        .world_mut()
        .spawn((
            DistanceFieldCaster {
                source: CasterSource::Sphere { radius: 1.0 },
                ..default()
            },
            Transform::default(),
        ))
        .id();
    for t in cases {
        app.world_mut().spawn((
            DistanceFieldCaster {
                source: CasterSource::Sphere { radius: 1.0 },
                ..default()
            },
            t,
        ));
    }
    app.update();
    let scene = app.world().resource::<DistanceFieldScene>();
    assert_eq!(scene.len(), 1);
    assert!(scene.slot(ok).is_some());
}

/// `ao_transmission` reaches the record's flags (foliage 0.5), clamped (3 → 1, NaN → 0)
/// rather than skipping the caster; the other flags are untouched.
#[test]
fn ao_transmission_reaches_the_record_clamped() {
    let mut app = app(DistanceFieldSceneSettings::default());
    let ids: Vec<Entity> = [0.5, 3.0, f32::NAN]
        .into_iter()
        .map(|ao_transmission| {
            app.world_mut()
                .spawn((
                    DistanceFieldCaster {
                        source: CasterSource::Sphere { radius: 1.0 },
                        ao_transmission,
                        ..default()
                    },
                    Transform::default(),
                ))
                .id()
        })
        .collect();
    app.update();
    let scene = app.world().resource::<DistanceFieldScene>();
    let got: Vec<f32> = ids
        .iter()
        .map(|&e| {
            let f = scene.records()[scene.slot(e).expect("encoded") as usize].flags();
            assert!(flags::casts_occlusion(f) && flags::casts_shadows(f));
            flags::ao_transmission(f)
        })
        .collect();
    assert_eq!(got, [128.0 / 255.0, 1.0, 0.0]);
}

/// 50 distinct 50³ SDFs and 1,000 instances: the memory a typical level needs.
#[test]
fn memory_of_a_thousand_instances_of_fifty_assets() {
    let mut app = app(DistanceFieldSceneSettings::default());
    let handles: Vec<Handle<SdfVolumeAsset>> = {
        let mut sdfs = app.world_mut().resource_mut::<Assets<SdfVolumeAsset>>();
        (0..50).map(|_| sdfs.add(volume(50))).collect()
    };
    for i in 0..1000 {
        app.world_mut().spawn((
            DistanceFieldCaster {
                source: CasterSource::Sdf(handles[i % 50].clone()),
                ..default()
            },
            Transform::from_xyz((i % 40) as f32, 0.0, (i / 40) as f32),
        ));
    }
    app.update();
    let s = stats(&app);
    assert_eq!((s.objects, s.atlas_volumes), (1000, 50));
    let object_buffer = s.slots as u64 * 128;
    println!(
        "1,000 instances / 50 assets of 50³: atlas texture {} bytes ({} used by SDFs), object buffer {} bytes, first-frame upload {} bytes",
        s.atlas_bytes, s.atlas_used_bytes, object_buffer, s.total_bytes
    );
    // 50 volumes of 56³ blocks (50 rounded up to 8) × 2 bytes.
    assert_eq!(s.atlas_used_bytes, 50 * 56u64.pow(3) * 2);
    assert_eq!(object_buffer, 128_000);
}

/// Without casters nothing is allocated or uploaded; a static scene uploads nothing
/// after its first frame; moving k casters uploads k records.
#[test]
fn uploads_follow_changes_only() {
    let mut app = app(DistanceFieldSceneSettings::default());
    app.update();
    let stats = app.world().resource::<DistanceFieldUploadStats>().clone();
    assert_eq!(
        stats,
        DistanceFieldUploadStats::default(),
        "no casters: nothing"
    );
    let ids: Vec<Entity> = spheres_in_a_row(&mut app, 200, 0.5);
    app.update();
    let stats = app.world().resource::<DistanceFieldUploadStats>().clone();
    assert_eq!((stats.frame_records, stats.objects), (200, 200));
    assert_eq!(stats.frame_object_bytes, 200 * (4 + 128));
    for _ in 0..3 {
        app.update();
        let stats = app.world().resource::<DistanceFieldUploadStats>();
        assert_eq!(
            (stats.frame_records, stats.frame_object_bytes),
            (0, 0),
            "static frame"
        );
    }
    for &e in &ids[..7] {
        app.world_mut()
            .get_mut::<Transform>(e)
            .unwrap()
            .translation
            .y += 1.0;
    }
    app.world_mut().despawn(ids[100]);
    app.update();
    let stats = app.world().resource::<DistanceFieldUploadStats>().clone();
    assert_eq!(stats.frame_records, 8, "7 moved + 1 removed");
    assert_eq!(stats.objects, 199);
}

/// A volume of at least `sparse_min_bytes` is placed as sparse bricks when that halves
/// it (its record flagged `BRICKED`, `params.x` its brick-table offset); a small one
/// stays dense; freeing it frees its pool, coarse grid and table range, which the next
/// bricked volume reuses; `u64::MAX` keeps every volume dense.
#[test]
fn large_volumes_are_placed_as_bricks_and_freed() {
    let mut app = app(DistanceFieldSceneSettings::default());
    let (big, small, other) = {
        let mut sdfs = app.world_mut().resource_mut::<Assets<SdfVolumeAsset>>();
        (
            sdfs.add(volume(128)),
            sdfs.add(volume(32)),
            sdfs.add(volume_of(UVec3::new(128, 120, 128))),
        )
    };
    let (a, b) = (sdf_caster(&mut app, &big), sdf_caster(&mut app, &small));
    update_until(&mut app, |app| stats(app).objects == 2);
    let s = stats(&app);
    let dense_bytes = 2 * 128u64.pow(3) + 2 * 32u64.pow(3);
    println!(
        "bricked {}: atlas {} of {dense_bytes} dense bytes, table {} bytes",
        s.atlas_bricked, s.atlas_used_bytes, s.brick_table_bytes
    );
    assert_eq!(s.atlas_bricked, 1);
    assert!(
        s.brick_table_bytes > 0 && s.atlas_used_bytes * 2 < dense_bytes,
        "{s:?}"
    );
    let record = |app: &App, e: Entity| {
        let scene = app.world().resource::<DistanceFieldScene>();
        scene.records()[scene.slot(e).expect("placed") as usize]
    };
    let (ra, rb) = (record(&app, a), record(&app, b));
    assert_ne!(ra.flags() & flags::BRICKED, 0);
    assert_eq!(rb.flags() & flags::BRICKED, 0);
    assert_eq!(ra.kind(), ShapeKind::Volume as u32);
    assert_eq!(
        (ra.params()[0], unpack_10_10_12(ra.params()[1])),
        (0, UVec3::splat(127))
    );
    let table_bytes = s.brick_table_bytes;
    app.world_mut().despawn(a);
    app.update();
    let s = stats(&app);
    assert_eq!(
        (s.atlas_bricked, s.atlas_used_bytes),
        (0, 2 * 32u64.pow(3)),
        "{s:?}"
    );
    let c = sdf_caster(&mut app, &other);
    update_until(&mut app, |app| stats(app).objects == 2);
    assert_eq!(
        record(&app, c).params()[0],
        0,
        "the freed table range is reused"
    );
    assert!(stats(&app).brick_table_bytes <= table_bytes);

    let mut dense = self::app(DistanceFieldSceneSettings {
        sparse_min_bytes: u64::MAX,
        ..default()
    });
    let big = dense
        .world_mut()
        .resource_mut::<Assets<SdfVolumeAsset>>()
        .add(volume(128));
    let d = sdf_caster(&mut dense, &big);
    update_until(&mut dense, |app| stats(app).objects == 1);
    assert_eq!(stats(&dense).atlas_bricked, 0);
    assert_eq!(record(&dense, d).flags() & flags::BRICKED, 0);
}

/// A floor-like SDF of `dims` samples: the plane through the middle of y, 1 cm voxels.
fn plane_of(dims: UVec3) -> SdfVolumeAsset {
    let mid = (dims.y - 1) as f32 * 0.5;
    let distances =
        (0..dims.element_product()).map(|i| (((i / dims.x) % dims.y) as f32 - mid) * 0.01);
    SdfVolumeAsset {
        volume: SdfVolume::from_distances(dims, DVec3::ZERO, 0.01, distances),
    }
}

/// A volume that finds no free box dense — a slab as wide as the atlas, one block column
/// of which another volume holds — is placed as sparse bricks at full resolution, not
/// downsampled (the Cornell box's 256-wide walls at the default budget); with every
/// volume kept dense it is halved.
#[test]
fn a_volume_with_no_free_box_goes_bricked_before_it_is_halved() {
    // An atlas of 256 × 256 × 64 voxels.
    let budget = 256 * 256 * 64 * 2;
    let placed = |sparse_min_bytes: u64| {
        let mut app = app(DistanceFieldSceneSettings {
            atlas_budget_bytes: budget,
            sparse_min_bytes,
            ..default()
        });
        let (column, slab) = {
            let mut sdfs = app.world_mut().resource_mut::<Assets<SdfVolumeAsset>>();
            (
                sdfs.add(plane_of(UVec3::new(8, 256, 64))),
                sdfs.add(plane_of(UVec3::new(256, 8, 64))),
            )
        };
        // The column first, at the atlas's x = 0.
        let c = sdf_caster(&mut app, &column);
        update_until(&mut app, |app| stats(app).objects == 1);
        let s = sdf_caster(&mut app, &slab);
        update_until(&mut app, |app| stats(app).objects == 2);
        let scene = app.world().resource::<DistanceFieldScene>();
        let record = |e: Entity| scene.records()[scene.slot(e).expect("placed") as usize];
        assert_eq!(record(c).flags() & flags::BRICKED, 0, "the column is dense");
        let r = record(s);
        (
            r.flags() & flags::BRICKED != 0,
            unpack_10_10_12(r.params()[1]) + UVec3::ONE,
            stats(&app),
        )
    };
    let (bricked, dims, s) = placed(DistanceFieldSceneSettings::default().sparse_min_bytes);
    assert!(bricked, "{s:?}");
    assert_eq!(dims, UVec3::new(256, 8, 64));
    assert_eq!((s.atlas_bricked, s.atlas_downsampled), (1, 0), "{s:?}");
    let (bricked, dims, s) = placed(u64::MAX);
    assert!(!bricked);
    assert_eq!(dims, UVec3::new(129, 5, 33), "halved");
    assert_eq!((s.atlas_bricked, s.atlas_downsampled), (0, 1), "{s:?}");
}
