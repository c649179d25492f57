//! Hair under a distance-field-shadowed sun, on lavapipe (`shadows` feature): a sphere
//! caster between the sun and two hair entities' horizontal strands.
//!
//! - **Contract.** Each strand point's visibility, read back from the hair's
//!   `HairShadows` buffer, equals the CPU model
//!   (`penumbra_reference::shadow_mask::pixel_visibility` with no normal, on the plugin's
//!   own object records, relative to the hair's origin).
//! - **Shading.** With the sun alone (no ambient), a strip pixel's radiance is linear in
//!   the visibility: the ratio of the render to the same render without
//!   `DistanceFieldShadows` is the visibility interpolated along the strand between its
//!   points — checked against the model on the strands' fully covered rows. The second
//!   entity's points sit after the first's in Bevy's vertex slab (a point index that
//!   ignored the mesh's first vertex would read the first entity's).
//! - **Bricked volumes.** The sphere as a volume placed as sparse bricks gives the
//!   points the visibility it gives placed dense (the hair's pass binds the scene's
//!   brick table; bound empty, the points are off by up to 0.65).
//! - **Shadow maps.** The hair carries `ReadsNoShadowMaps` (the sun's shadow map is not
//!   kept for it), beside five more distance-field-shadowed point lights out of its reach
//!   (more lights than it takes, none of which lights it).

#![cfg(feature = "shadows")]

mod hair_scene;
use hair_scene::*;

use bevy::light::GlobalAmbientLight;
use bevy::prelude::*;
use bevy::render::gpu_readback::{Readback, ReadbackComplete};
use bevy_penumbra_cinematic::hair::{
    HAIR_SHADOWS_HEADER_BYTES, Hair, HairPlugin, HairShadowBuffers, HairShadowTraces, HairStrands,
    Strand,
};
use bevy_penumbra_df::{
    CasterSource, DistanceFieldCaster, DistanceFieldScene, DistanceFieldScenePlugin,
    DistanceFieldSceneSettings, DistanceFieldShadows, DistanceFieldShadowsPlugin,
    DistanceFieldUploadStats, PenumbraLightingPlugin, ReadsNoShadowMaps, SdfAssetPlugin,
    SdfVolumeAsset,
};
use penumbra_df_core::cull::CameraOrigin;
use penumbra_df_core::shadow::{ShadowLight, ShadowLightKind};
use penumbra_reference::analytic_volume;
use penumbra_reference::df::Atlas;
use penumbra_reference::shadow_mask::pixel_visibility;
use penumbra_test::{CaptureFormat, HeadlessRender, KeptApp, gpu_or_skip};

const SIZE: u32 = 64;
/// Strand rows (pixels from the top); even ones on the first entity, odd on the second.
const ROWS: [u32; 7] = [10, 18, 26, 34, 42, 50, 58];
/// Points every 2 px from x = 4 to x = 60.
const X0: f32 = 4.0;
const STEP: f32 = 2.0;
const POINTS: usize = 29;
const SPHERE: Vec3 = Vec3::new(32.0, 32.0, 20.0);
const RADIUS: f32 = 10.0;
const SUN_DEGREES: f32 = 20.0;

fn sun_settings() -> DistanceFieldShadows {
    DistanceFieldShadows {
        angular_diameter: SUN_DEGREES.to_radians(),
        ..default()
    }
}

/// The strand on pixel row `row`, 2 px wide, hair space = world.
fn strand(row: u32) -> Strand {
    Strand {
        points: (0..POINTS)
            .map(|i| to_world(Vec2::new(X0 + STEP * i as f32, row as f32), SIZE))
            .collect(),
        width: 2.0,
        slot: 0,
    }
}

/// The latest read-back `HairShadows` of the first hair entity.
#[derive(Resource, Default, Clone)]
struct ReadBack(Option<Vec<u8>>);

#[derive(Resource)]
struct Entities([Entity; 2]);

/// The caster: the analytic sphere, or the same sphere as a volume placed in the atlas
/// dense or as sparse bricks.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum SphereAs {
    Analytic,
    Volume { bricked: bool },
}

/// Small spheres between the sun and the strands, besides the big one: `CROWD` of them
/// on a 9 × 9 grid over the hair, `CROWD_RADIUS` each, in three layers from
/// `CROWD_HEIGHT` up, 3 apart (more than a workgroup lists at a time).
const CROWD: u32 = 243;
const CROWD_RADIUS: f32 = 1.2;
const CROWD_HEIGHT: f32 = 6.0;

fn scene(
    df: bool,
    sphere: SphereAs,
    crowd: bool,
) -> impl FnMut(Commands, ResMut<Assets<HairStrands>>, ResMut<Assets<SdfVolumeAsset>>) {
    move |mut commands, mut strands, mut sdfs| {
        let mut hairs = [Entity::PLACEHOLDER; 2];
        for (k, hair) in hairs.iter_mut().enumerate() {
            let rows = ROWS.iter().skip(k).step_by(2).map(|&r| strand(r)).collect();
            *hair = commands
                .spawn(Hair {
                    strands: strands.add(HairStrands::new(rows)),
                    ..default()
                })
                .id();
        }
        commands.insert_resource(Entities(hairs));
        let mut sun = commands.spawn((
            DirectionalLight {
                illuminance: 10_000.0,
                shadow_maps_enabled: false,
                ..default()
            },
            Transform::from_xyz(0.0, 0.0, 1.0).looking_at(Vec3::ZERO, Vec3::Y),
        ));
        if df {
            sun.insert(sun_settings());
            // Five distance-field-shadowed point lights whose range ends far from the
            // hair: they light nothing of it, so it still needs no shadow map.
            for i in 0..5 {
                commands.spawn((
                    PointLight {
                        range: 10.0,
                        shadow_maps_enabled: false,
                        ..default()
                    },
                    DistanceFieldShadows::default(),
                    Transform::from_xyz(1000.0 + 50.0 * i as f32, 0.0, 0.0),
                ));
            }
        }
        let source = match sphere {
            SphereAs::Analytic => CasterSource::Sphere { radius: RADIUS },
            SphereAs::Volume { .. } => CasterSource::Sdf(sdfs.add(SdfVolumeAsset {
                volume: analytic_volume::sphere_for_bricks(RADIUS),
            })),
        };
        commands.spawn((
            DistanceFieldCaster {
                source,
                ..default()
            },
            Transform::from_translation(SPHERE),
        ));
        for i in (0..CROWD).filter(|_| crowd) {
            let at = to_world(
                Vec2::new(6.0 + 6.5 * (i % 9) as f32, 6.0 + 6.5 * (i / 9 % 9) as f32),
                SIZE,
            );
            let height = CROWD_HEIGHT + 3.0 * (i / 81) as f32;
            commands.spawn((
                DistanceFieldCaster {
                    source: CasterSource::Sphere {
                        radius: CROWD_RADIUS,
                    },
                    ..default()
                },
                Transform::from_translation(at.with_z(height)),
            ));
        }
        commands.spawn(pixel_camera(SIZE, SIZE));
    }
}

/// Reads the first hair's buffer back every frame once it exists.
fn read_back(
    mut commands: Commands,
    entities: Option<Res<Entities>>,
    buffers: Query<&HairShadowBuffers>,
    mut started: Local<bool>,
) {
    let Some(entities) = entities else { return };
    let Ok(buffers) = buffers.get(entities.0[0]) else {
        return;
    };
    if !*started {
        *started = true;
        commands
            .spawn(Readback::buffer(buffers.shadows.clone()))
            .observe(|event: On<ReadbackComplete>, mut read: ResMut<ReadBack>| {
                read.0 = Some(event.data.clone());
            });
    }
}

fn word(bytes: &[u8], i: usize) -> u32 {
    u32::from_le_bytes(bytes[4 * i..4 * i + 4].try_into().unwrap())
}

fn render(df: bool) -> (Vec<[f32; 4]>, KeptApp) {
    render_with(df, true, SphereAs::Analytic, false)
}

/// [`render`]; `pipelined: false` keeps the render world reachable.
fn render_with(
    df: bool,
    pipelined: bool,
    sphere: SphereAs,
    crowd: bool,
) -> (Vec<[f32; 4]>, KeptApp) {
    let mut harness = HeadlessRender::new(SIZE, SIZE)
        .format(CaptureFormat::LinearF16)
        .frames(4);
    harness.pipelined = pipelined;
    if df {
        // Until a read-back shows the sun traced (slot 0).
        harness.warm_up = Some(|world: &mut World| {
            world
                .resource::<ReadBack>()
                .0
                .as_ref()
                .is_some_and(|b| word(b, 0) == 1 && word(b, 6) == 0)
        });
    }
    let mut app = harness.app();
    app.add_plugins((
        SdfAssetPlugin,
        DistanceFieldScenePlugin,
        PenumbraLightingPlugin::default(),
        DistanceFieldShadowsPlugin,
        HairPlugin,
    ))
    .insert_resource(GlobalAmbientLight {
        brightness: 0.0,
        ..default()
    })
    .insert_resource(DistanceFieldSceneSettings {
        sparse_min_bytes: match sphere {
            SphereAs::Volume { bricked: true } => 0,
            _ => u64::MAX,
        },
        ..default()
    })
    .init_resource::<ReadBack>()
    .add_systems(Startup, scene(df, sphere, crowd))
    .add_systems(Update, read_back);
    let (capture, app) = harness.run_keeping_app(app).expect("renders");
    (capture.to_linear(), app)
}

/// The model's visibility of the sun at each point of the strand on `row`.
fn model_row(app: &App, row: u32) -> Vec<f32> {
    let records = app
        .world()
        .resource::<DistanceFieldScene>()
        .records()
        .to_vec();
    let atlas = Atlas::new(UVec3::ONE);
    // The hair's origin: its translation (zero).
    let origin = CameraOrigin::at(Vec3::ZERO).expect("finite");
    let s = sun_settings();
    let light = ShadowLight {
        kind: ShadowLightKind::Directional(Vec3::Z),
        source: (0.5 * s.angular_diameter).tan(),
        max_distance: s.max_distance,
        bias: s.bias,
        shaping: s.shaping,
        range: 0.0,
        max_steps: s.max_steps,
        max_view_distance: s.max_view_distance,
        spot: None,
    };
    strand(row)
        .points
        .iter()
        .map(|&p| pixel_visibility(&records, &atlas, &origin, p, Vec3::ZERO, &light))
        .collect()
}

/// The exact visibility of the sun's disc (uniform, angular radius `SUN_DEGREES / 2`)
/// from `p` past the sphere: 4,096 directions spread evenly over the disc's solid angle
/// (Fibonacci spiral), each ray tested against the ball.
fn exact_visibility(p: Vec3) -> f32 {
    const N: usize = 4096;
    let cos_max = (0.5 * SUN_DEGREES).to_radians().cos();
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let oc = p - SPHERE;
    let open = (0..N)
        .filter(|&i| {
            let cos_t = 1.0 - (i as f32 + 0.5) / N as f32 * (1.0 - cos_max);
            let sin_t = (1.0 - cos_t * cos_t).sqrt();
            let phi = golden * i as f32;
            let d = Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t);
            let b = oc.dot(d);
            let c = oc.length_squared() - RADIUS * RADIUS;
            // Hit: the nearer root is ahead (the ball is in front of every point).
            !(b * b - c >= 0.0 && -b - (b * b - c).sqrt() > 0.0)
        })
        .count();
    open as f32 / N as f32
}

#[test]
fn hair_takes_distance_field_shadows() {
    if !gpu_or_skip("hair_takes_distance_field_shadows") {
        return;
    }
    let (plain, _) = render(false);
    let (shadowed, app) = render(true);
    let world = app.world();
    let entities = world.resource::<Entities>().0;
    for e in entities {
        assert!(world.get::<ReadsNoShadowMaps>(e).is_some(), "{e}");
    }
    // The contract: the first entity's points (its rows, in order) against the model.
    let bytes = world.resource::<ReadBack>().0.clone().expect("read back");
    let first_rows: Vec<u32> = ROWS.iter().step_by(2).copied().collect();
    assert_eq!(word(&bytes, 1) as usize, POINTS * first_rows.len());
    let (mut diffs, mut shadowed_points, mut penumbra_points) = (Vec::new(), 0, 0);
    for (r, &row) in first_rows.iter().enumerate() {
        for (i, want) in model_row(&app, row).into_iter().enumerate() {
            let at = HAIR_SHADOWS_HEADER_BYTES / 4 + 4 * (r * POINTS + i);
            let got = f32::from_bits(word(&bytes, at));
            shadowed_points += usize::from(want < 0.5);
            penumbra_points += usize::from(want > 0.05 && want < 0.95);
            diffs.push((got - want).abs());
        }
    }
    let max = diffs.iter().copied().fold(0.0, f32::max);
    let mean = diffs.iter().sum::<f32>() / diffs.len() as f32;
    println!(
        "points: {} ({shadowed_points} shadowed, {penumbra_points} penumbra): |gpu − model| \
         mean {mean:.2e}, max {max:.2e}",
        diffs.len()
    );
    assert!(shadowed_points >= 10 && penumbra_points >= 10);
    assert!(max < 1e-3, "mean {mean}, max {max}");

    // The model against the exact visibility, on every point of every strand.
    let (mut model_error, mut unshadowed_error, mut worst) = (0.0, 0.0, 0.0f32);
    let mut n = 0;
    for &row in &ROWS {
        for (p, model) in strand(row).points.iter().zip(model_row(&app, row)) {
            let exact = exact_visibility(*p);
            model_error += (model - exact).abs();
            unshadowed_error += 1.0 - exact;
            worst = worst.max((model - exact).abs());
            n += 1;
        }
    }
    let (model_error, unshadowed_error) = (model_error / n as f32, unshadowed_error / n as f32);
    println!(
        "{n} points against the exact visibility: model mean |Δ| {model_error:.4} (worst \
         {worst:.3}); no shadow {unshadowed_error:.4}"
    );
    // Measured 0.017; ignoring the sphere: 0.098.
    assert!(model_error < 0.025, "{model_error}");

    // The shading: render ratio against the model interpolated between points, on the
    // strands' centre rows (a 2 px strand centred on a pixel edge covers the rows above
    // and below it fully).
    let (mut diffs, mut dark) = (Vec::new(), 0);
    for &row in &ROWS {
        let model = model_row(&app, row);
        for y in [row - 1, row] {
            for x in (X0 as u32 + 1)..(X0 as u32 + STEP as u32 * (POINTS as u32 - 1) - 1) {
                let i = (y * SIZE + x) as usize;
                let lit = plain[i][0] + plain[i][1] + plain[i][2];
                assert!(lit > 1e-3, "pixel ({x}, {y}) unlit");
                let got = (shadowed[i][0] + shadowed[i][1] + shadowed[i][2]) / lit;
                let t = (x as f32 + 0.5 - X0) / STEP;
                let k = t.floor() as usize;
                let want = model[k] + (model[k + 1] - model[k]) * (t - k as f32);
                dark += usize::from(got < 0.5);
                diffs.push((got - want).abs());
            }
        }
    }
    diffs.sort_by(f32::total_cmp);
    let n = diffs.len();
    let mean = diffs.iter().sum::<f32>() / n as f32;
    println!(
        "strip pixels: {n} ({dark} darker than half): |render ratio − model| mean {mean:.4}, \
         p99 {:.4}, max {:.4}",
        diffs[n * 99 / 100],
        diffs[n - 1]
    );
    assert!(dark > 50, "{dark}");
    // Measured: f16 capture rounding. Ignoring the sphere, or taking the first entity's
    // points for the second's, is off by up to 1.
    assert!(mean < 2e-3 && diffs[n - 1] < 0.02, "mean {mean}");
}

/// Each workgroup of 64 points lists, 128 slots at a time, the casters that can meet any
/// of its points' cones, and its points march those: with 243 small spheres over the
/// strands besides the big one (two lists per light, many casters in each, each
/// shadowing a few points, some at a workgroup's edge), the traced visibilities still
/// equal the model's, which marches every object for every point.
#[test]
fn workgroups_list_the_casters_their_points_see() {
    if !gpu_or_skip("workgroups_list_the_casters_their_points_see") {
        return;
    }
    let (_, app) = render_with(true, true, SphereAs::Analytic, true);
    let traced = traced_points(&app);
    let first_rows: Vec<u32> = ROWS.iter().step_by(2).copied().collect();
    let model: Vec<f32> = first_rows
        .iter()
        .flat_map(|&row| model_row(&app, row))
        .collect();
    assert_eq!(traced.len(), model.len());
    // Points the crowd dims (the big sphere's shadow aside).
    let (_, alone) = render_with(true, true, SphereAs::Analytic, false);
    let without: Vec<f32> = traced_points(&alone);
    let dimmed = traced
        .iter()
        .zip(&without)
        .filter(|(a, b)| **a < **b - 0.05)
        .count();
    let max = traced
        .iter()
        .zip(&model)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f32::max);
    println!(
        "{} points, {dimmed} dimmed by the crowd: |gpu − model| max {max:.2e}",
        traced.len()
    );
    assert!(dimmed >= 20, "{dimmed}");
    assert!(max < 1e-3, "max {max}");
}

/// The first hair entity's traced visibilities (its points, strand by strand).
fn traced_points(app: &App) -> Vec<f32> {
    let bytes = app
        .world()
        .resource::<ReadBack>()
        .0
        .clone()
        .expect("read back");
    let n = word(&bytes, 1) as usize;
    (0..n)
        .map(|i| f32::from_bits(word(&bytes, HAIR_SHADOWS_HEADER_BYTES / 4 + 4 * i)))
        .collect()
}

/// With the sphere's volume placed as sparse bricks, the hair's visibility equals that
/// of the same field placed dense (the brick table bound, read through it), but where a
/// penumbra reads an empty brick's lower bound.
#[test]
fn hair_reads_bricked_volumes() {
    if !gpu_or_skip("hair_reads_bricked_volumes") {
        return;
    }
    let bricked_of = |app: &App| {
        app.world()
            .resource::<DistanceFieldUploadStats>()
            .atlas_bricked
    };
    let (_, dense_app) = render_with(true, true, SphereAs::Volume { bricked: false }, false);
    let (_, bricked_app) = render_with(true, true, SphereAs::Volume { bricked: true }, false);
    assert_eq!((bricked_of(&dense_app), bricked_of(&bricked_app)), (0, 1));
    let (dense, bricked) = (traced_points(&dense_app), traced_points(&bricked_app));
    assert_eq!(dense.len(), bricked.len());
    let shadowed = dense.iter().filter(|&&v| v < 0.5).count();
    let diffs: Vec<f32> = dense
        .iter()
        .zip(&bricked)
        .map(|(a, b)| (a - b).abs())
        .collect();
    let mean = diffs.iter().sum::<f32>() / diffs.len() as f32;
    let max = diffs.iter().copied().fold(0.0, f32::max);
    println!(
        "{} points ({shadowed} shadowed by the dense sphere): |bricked − dense| mean {mean:.2e}, \
         max {max:.2e}",
        dense.len()
    );
    assert!(shadowed >= 10, "{shadowed}");
    assert!(mean < 2e-3 && max < 0.05, "mean {mean}, max {max}");
}

/// The cost measurement's scene: `strands` strands of 9 points (16 triangles) scattered
/// over a 512² view, `casters` spheres on a grid above them, the sun with or without
/// `DistanceFieldShadows`.
#[derive(Resource, Clone, Copy)]
struct CostSetup {
    strands: u32,
    casters: u32,
    df: bool,
}

/// A still scene traces nothing: once the hair is traced, frames in which neither the
/// casters, the lights nor the hair change dispatch no trace; moving the caster or a
/// hair traces again (before the fix: one dispatch per hair entity per frame).
#[test]
fn still_hair_is_not_traced_again() {
    if !gpu_or_skip("still_hair_is_not_traced_again") {
        return;
    }
    let (_, mut app) = render_with(true, false, SphereAs::Analytic, false);
    let traces = |app: &App| {
        app.sub_app(bevy::render::RenderApp)
            .world()
            .resource::<HairShadowTraces>()
            .0
    };
    let settled = traces(&app);
    assert!(settled >= 2, "both hair entities traced once: {settled}");
    for _ in 0..6 {
        app.update();
    }
    let still = traces(&app) - settled;
    println!("hair traces: {settled} until settled, {still} in 6 still frames");
    assert_eq!(still, 0, "a still scene re-traced the hair");
    // The caster moves: both entities are traced again.
    let world = app.world_mut();
    let mut casters = world.query_filtered::<&mut Transform, With<DistanceFieldCaster>>();
    for mut t in casters.iter_mut(world) {
        t.translation.x += 1.0;
    }
    let before = traces(&app);
    for _ in 0..3 {
        app.update();
    }
    let moved = traces(&app) - before;
    // One hair moves: that entity alone.
    let first = app.world().resource::<Entities>().0[0];
    app.world_mut()
        .get_mut::<Transform>(first)
        .expect("hair")
        .translation
        .y += 0.5;
    let before = traces(&app);
    for _ in 0..3 {
        app.update();
    }
    let hair_moved = traces(&app) - before;
    println!("hair traces: {moved} after the caster moved, {hair_moved} after a hair moved");
    assert!(moved >= 2, "the caster moved: {moved} traces");
    assert_eq!(hair_moved, 1, "one hair moved: {hair_moved} traces");
}

fn cost_scene(
    setup: Res<CostSetup>,
    mut commands: Commands,
    mut strand_assets: ResMut<Assets<HairStrands>>,
) {
    const VIEW: u32 = 512;
    let hash = |i: u32, k: u32| {
        let mut h = i.wrapping_mul(0x9e37_79b9) ^ k.wrapping_mul(0x85eb_ca6b);
        h ^= h >> 15;
        h = h.wrapping_mul(0x2c1b_3c6d);
        h ^= h >> 12;
        (h & 0xffff) as f32 / 65535.0
    };
    let strands = (0..setup.strands)
        .map(|i| {
            let a = Vec2::new(hash(i, 0), hash(i, 1)) * (VIEW as f32 - 80.0) + 40.0;
            let angle = hash(i, 2) * std::f32::consts::TAU;
            let step = Vec2::from_angle(angle) * 8.0;
            Strand {
                points: (0..9)
                    .map(|k| to_world(a + step * (k as f32 - 4.0), VIEW))
                    .collect(),
                width: 1.0,
                slot: 0,
            }
        })
        .collect();
    commands.spawn(Hair {
        strands: strand_assets.add(HairStrands::new(strands)),
        ..default()
    });
    let mut sun = commands.spawn((
        DirectionalLight {
            illuminance: 10_000.0,
            shadow_maps_enabled: false,
            ..default()
        },
        Transform::from_xyz(0.0, 0.0, 1.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    if setup.df {
        sun.insert(DistanceFieldShadows {
            angular_diameter: 5f32.to_radians(),
            ..default()
        });
    }
    let side = (setup.casters as f32).sqrt().ceil() as u32;
    for c in 0..setup.casters {
        let at = (Vec2::new((c % side) as f32, (c / side) as f32) + 0.5) / side as f32;
        commands.spawn((
            DistanceFieldCaster {
                source: CasterSource::Sphere { radius: 16.0 },
                ..default()
            },
            Transform::from_translation((at * VIEW as f32).extend(40.0)),
        ));
    }
    commands.spawn(pixel_camera(VIEW, VIEW));
}

#[test]
#[ignore = "a measurement: lavapipe frame times, ~8 minutes"]
fn hair_shadow_trace_cost() {
    if !gpu_or_skip("hair_shadow_trace_cost") {
        return;
    }
    let time = |setup: CostSetup| {
        let mut medians = Vec::new();
        for _ in 0..3 {
            let harness = HeadlessRender::new(512, 512).frames(8);
            let mut app = harness.app();
            app.add_plugins((
                SdfAssetPlugin,
                DistanceFieldScenePlugin,
                PenumbraLightingPlugin::default(),
                DistanceFieldShadowsPlugin,
                HairPlugin,
            ))
            .insert_resource(setup)
            .add_systems(Startup, cost_scene);
            let capture = harness.run(app).expect("renders");
            let mut t: Vec<f64> = capture.frame_times[2..]
                .iter()
                .map(|d| d.as_secs_f64() * 1e3)
                .collect();
            t.sort_by(f64::total_cmp);
            medians.push(t[t.len() / 2]);
        }
        medians.sort_by(f64::total_cmp);
        medians[1]
    };
    for strands in [2_000, 20_000] {
        let plain = time(CostSetup {
            strands,
            casters: 16,
            df: false,
        });
        println!(
            "{strands} strands ({} points, {} triangles), shadow maps off: {plain:.1} ms",
            strands * 9,
            strands * 16
        );
        for casters in [1, 16, 64] {
            let t = time(CostSetup {
                strands,
                casters,
                df: true,
            });
            println!(
                "  DF sun, {casters} casters: {t:.1} ms, {:+.1} ms",
                t - plain
            );
        }
    }
}
