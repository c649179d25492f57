//! `HairPlugin` in a Bevy app on lavapipe: bad input, the MSAA-off fallback, a deferred
//! MSAA camera, skinning, and hair cards from a glTF file.
//!
//! - Bad strands (no points, one point, a NaN point, zero and NaN widths) are skipped and
//!   the good ones drawn; an asset with no good strand gets no mesh; an atlas that fails
//!   to load is dropped and the hair drawn without it; a `.hair` file loads from disk and
//!   a malformed one fails with its line number.
//! - `Msaa::Off`: the per-pixel test with a dithered threshold — every pixel fully
//!   covered or not, thin strands thinned out rather than lost.
//! - A `PenumbraLighting` camera with `DeferredMsaa`: strands resolve over the deferred
//!   floor with their widths' coverage.
//! - Strands bound to a skin follow its joint.
//! - A glTF hair card (a ribbon; Bevy's loader un-indexes it) becomes its strand.

mod hair_scene;
use hair_scene::*;

use bevy::asset::LoadState;
use bevy::prelude::*;
use bevy_penumbra_cinematic::hair::{
    Hair, HairBuilt, HairMaterial, HairPlugin, HairStrands, Strand, StrandProblem,
};
use penumbra_test::{CaptureFormat, HeadlessRender, gpu_or_skip};

const WIDTH: u32 = 64;
const HEIGHT: u32 = 64;

#[derive(Resource)]
struct Spawned {
    mixed: Entity,
    all_bad: Entity,
    missing_atlas: Entity,
    from_file: Entity,
    bad_file: Handle<HairStrands>,
}

fn bad_input_scene(
    mut commands: Commands,
    mut strand_assets: ResMut<Assets<HairStrands>>,
    asset_server: Res<AssetServer>,
) {
    let good = pixel_strand(Vec2::new(4.0, 8.0), Vec2::new(28.0, 8.0), 2.0, HEIGHT);
    let bad = |points: Vec<Vec3>, width: f32| Strand {
        points,
        width,
        slot: 0,
    };
    let two = vec![Vec3::ZERO, Vec3::X];
    let mixed = commands
        .spawn(Hair {
            strands: strand_assets.add(HairStrands::new(vec![
                bad(vec![], 1.0),
                good.clone(),
                bad(vec![Vec3::ONE], 1.0),
                bad(vec![Vec3::ZERO, Vec3::NAN], 1.0),
                bad(two.clone(), 0.0),
                bad(two.clone(), f32::NAN),
            ])),
            debug_coverage: true,
            ..default()
        })
        .id();
    let all_bad = commands
        .spawn(Hair {
            strands: strand_assets.add(HairStrands::new(vec![bad(two, -1.0)])),
            debug_coverage: true,
            ..default()
        })
        .id();
    let missing_atlas = commands
        .spawn(Hair {
            strands: strand_assets.add(HairStrands::new(vec![pixel_strand(
                Vec2::new(4.0, 24.0),
                Vec2::new(28.0, 24.0),
                2.0,
                HEIGHT,
            )])),
            atlas: Some(asset_server.load("no_such_atlas.png")),
            debug_coverage: true,
            ..default()
        })
        .id();
    let from_file = commands
        .spawn(Hair {
            strands: asset_server.load("good.hair"),
            debug_coverage: true,
            ..default()
        })
        .id();
    let bad_file = asset_server.load("bad.hair");
    commands.insert_resource(Spawned {
        mixed,
        all_bad,
        missing_atlas,
        from_file,
        bad_file,
    });
    commands.spawn(pixel_camera(WIDTH, HEIGHT));
}

fn coverage_in_rows(image: &[[f32; 4]], rows: std::ops::Range<u32>) -> f32 {
    rows.flat_map(|y| (0..WIDTH).map(move |x| (y * WIDTH + x) as usize))
        .map(|i| image[i][0])
        .sum()
}

#[test]
fn bad_input_is_skipped_and_the_rest_drawn() {
    if !gpu_or_skip("bad_input_is_skipped_and_the_rest_drawn") {
        return;
    }
    let assets = std::env::temp_dir().join(format!("penumbra_hair_assets_{}", std::process::id()));
    std::fs::create_dir_all(&assets).unwrap();
    std::fs::write(
        assets.join("good.hair"),
        format!(
            "penumbra-hair 1\n# one strand across row 40\nstrand 2 0  4 {y} 0  28 {y} 0\n",
            y = HEIGHT - 40
        ),
    )
    .unwrap();
    std::fs::write(assets.join("bad.hair"), "penumbra-hair 1\nstrand 2 0 1 2\n").unwrap();
    let mut harness = HeadlessRender::new(WIDTH, HEIGHT)
        .format(CaptureFormat::LinearF16)
        .frames(4);
    harness.asset_root = Some(assets.clone());
    // Until the files have loaded (or failed).
    harness.warm_up = Some(|world: &mut World| {
        let Some(spawned) = world.get_resource::<Spawned>() else {
            return false;
        };
        let server = world.resource::<AssetServer>();
        let hair = world.get::<Hair>(spawned.missing_atlas).unwrap();
        let atlas = hair.atlas.as_ref().unwrap();
        matches!(server.get_load_state(atlas), Some(LoadState::Failed(_)))
            && matches!(
                server.get_load_state(&spawned.bad_file),
                Some(LoadState::Failed(_))
            )
            && world.get::<HairBuilt>(spawned.from_file).is_some()
    });
    let mut app = harness.app();
    app.add_plugins(HairPlugin)
        .add_systems(Startup, bad_input_scene);
    let (capture, app) = harness.run_keeping_app(app).expect("renders");
    let image = capture.to_linear();
    save_coverage("hair_bad_input", &image, WIDTH, HEIGHT);
    let world = app.world();
    let spawned = world.resource::<Spawned>();
    // The mixed asset: its good strand is drawn, about 24 px × 2 px of coverage on rows
    // 7–9, and nothing else anywhere but the other strands' rows.
    assert!(world.get::<Mesh3d>(spawned.mixed).is_some());
    let elsewhere = coverage_in_rows(&image, 0..6)
        + coverage_in_rows(&image, 11..22)
        + coverage_in_rows(&image, 27..38)
        + coverage_in_rows(&image, 43..HEIGHT);
    assert_eq!(elsewhere, 0.0);
    let drawn = coverage_in_rows(&image, 6..11);
    assert!((drawn - 48.0).abs() < 4.0, "{drawn}");
    // Nothing drawable: no mesh.
    assert!(world.get::<Mesh3d>(spawned.all_bad).is_none());
    assert!(world.get::<HairBuilt>(spawned.all_bad).is_some());
    // The missing atlas is dropped; the strand is drawn untextured.
    let material = world
        .get::<MeshMaterial3d<HairMaterial>>(spawned.missing_atlas)
        .expect("a material");
    let material = world
        .resource::<Assets<HairMaterial>>()
        .get(&material.0)
        .unwrap();
    assert!(material.atlas.is_none());
    let drawn = coverage_in_rows(&image, 22..27);
    assert!((drawn - 48.0).abs() < 4.0, "{drawn}");
    // The file's strand is drawn.
    let drawn = coverage_in_rows(&image, 38..43);
    assert!((drawn - 48.0).abs() < 4.0, "{drawn}");
    // The malformed file failed, naming its line.
    let server = world.resource::<AssetServer>();
    let Some(LoadState::Failed(error)) = server.get_load_state(&spawned.bad_file) else {
        panic!("bad.hair did not fail");
    };
    assert!(error.to_string().contains("line 2"), "{error}");
    // The checks' reasons, as the warning names them.
    let (_, dropped) = penumbra_cinematic_core::hair::strands::check_strands(vec![Strand {
        points: vec![],
        width: 1.0,
        slot: 0,
    }]);
    assert_eq!(dropped[0].1, StrandProblem::TooFewPoints);
    drop(app);
    let _ = std::fs::remove_dir_all(&assets);
}

fn msaa_off_scene(mut commands: Commands, mut strand_assets: ResMut<Assets<HairStrands>>) {
    // Strands 0.2, 0.4, 1 and 2 px wide, slanting 4 px over 60 (every sub-pixel offset).
    let strands = [0.2f32, 0.4, 1.0, 2.0]
        .iter()
        .enumerate()
        .map(|(k, w)| {
            let y = 8.0 + 16.0 * k as f32 + 0.3;
            pixel_strand(Vec2::new(2.0, y), Vec2::new(62.0, y + 4.0), *w, HEIGHT)
        })
        .collect();
    commands.spawn(Hair {
        strands: strand_assets.add(HairStrands::new(strands)),
        debug_coverage: true,
        ..default()
    });
    commands
        .spawn(pixel_camera(WIDTH, HEIGHT))
        .insert(Msaa::Off);
}

#[test]
fn without_msaa_hair_falls_back_to_a_dithered_per_pixel_test() {
    if !gpu_or_skip("without_msaa_hair_falls_back_to_a_dithered_per_pixel_test") {
        return;
    }
    let harness = HeadlessRender::new(WIDTH, HEIGHT)
        .format(CaptureFormat::LinearF16)
        .frames(3);
    let mut app = harness.app();
    app.add_plugins(HairPlugin)
        .add_systems(Startup, msaa_off_scene);
    let image = harness.run(app).expect("renders").to_linear();
    save_coverage("hair_msaa_off", &image, WIDTH, HEIGHT);
    assert!(
        image.iter().all(|p| p[0] == 0.0 || p[0] == 1.0),
        "partial coverage without MSAA"
    );
    for (k, w) in [0.2f32, 0.4, 1.0, 2.0].iter().enumerate() {
        let rows = 16 * k as u32..16 * (k as u32 + 1);
        let width = coverage_in_rows(&image, rows) / 60.0;
        println!("MSAA off: a {w} px strand covers {width:.3} px on average");
        // Thin strands keep their share of pixels (the fade), not none.
        assert!((width - w).abs() < 0.1 + 0.1 * w, "{w}: {width}");
    }
}

fn deferred_msaa_scene(
    mut commands: Commands,
    mut strand_assets: ResMut<Assets<HairStrands>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    let strands = (0..4)
        .map(|k| {
            let y = 8.0 + 16.0 * k as f32 + 0.3;
            pixel_strand(
                Vec2::new(2.0, y),
                Vec2::new(62.0, y + 4.0),
                0.5 + 0.5 * k as f32,
                HEIGHT,
            )
        })
        .collect();
    commands.spawn(Hair {
        strands: strand_assets.add(HairStrands::new(strands)),
        debug_coverage: true,
        ..default()
    });
    // A black deferred floor behind the hair, shaded by Penumbra's lighting pass.
    commands.spawn((
        Mesh3d(meshes.add(Rectangle::new(WIDTH as f32, HEIGHT as f32))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::BLACK,
            ..default()
        })),
        Transform::from_xyz(WIDTH as f32 / 2.0, HEIGHT as f32 / 2.0, -1.0),
    ));
    commands.spawn((
        pixel_camera(WIDTH, HEIGHT),
        bevy_penumbra_df::PenumbraLighting,
        bevy_penumbra_df::lighting::DeferredMsaa::default(),
    ));
}

#[test]
fn hair_draws_into_a_deferred_msaa_camera() {
    if !gpu_or_skip("hair_draws_into_a_deferred_msaa_camera") {
        return;
    }
    let harness = HeadlessRender::new(WIDTH, HEIGHT)
        .format(CaptureFormat::LinearF16)
        .frames(4);
    let mut app = harness.app();
    app.add_plugins((
        bevy_penumbra_df::PenumbraLightingPlugin::default(),
        HairPlugin,
    ))
    .insert_resource(bevy::pbr::DefaultOpaqueRendererMethod::deferred())
    .insert_resource(GlobalAmbientLight {
        brightness: 0.0,
        ..default()
    })
    .add_systems(Startup, deferred_msaa_scene);
    let image = harness.run(app).expect("renders").to_linear();
    save_coverage("hair_deferred_msaa", &image, WIDTH, HEIGHT);
    // Partly covered pixels: the hair's samples resolved with the floor's.
    let partial = image.iter().filter(|p| p[0] > 0.1 && p[0] < 0.9).count();
    for k in 0..4 {
        let w = 0.5 + 0.5 * k as f32;
        let width = coverage_in_rows(&image, 16 * k..16 * (k + 1)) / 60.0;
        println!("deferred MSAA: a {w} px strand covers {width:.3} px on average");
        assert!((width - w).abs() < 0.125, "{w}: {width}");
    }
    assert!(partial > 100, "{partial} partly covered pixels");
}

fn skinned_scene(
    mut commands: Commands,
    mut strand_assets: ResMut<Assets<HairStrands>>,
    mut bindposes: ResMut<Assets<bevy::mesh::skinning::SkinnedMeshInverseBindposes>>,
) {
    use bevy::mesh::{PrimitiveTopology, VertexAttributeValues};
    let mut strands = HairStrands::new(vec![pixel_strand(
        Vec2::new(4.0, 20.0),
        Vec2::new(60.0, 20.0),
        2.0,
        HEIGHT,
    )]);
    // A one-vertex "skin" near the root, bound wholly to joint 0.
    let skin = Mesh::new(
        PrimitiveTopology::PointList,
        bevy::asset::RenderAssetUsages::MAIN_WORLD,
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![[4.0f32, 44.0, 0.0]])
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_JOINT_INDEX,
        VertexAttributeValues::Uint16x4(vec![[0, 0, 0, 0]]),
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, vec![[1.0f32, 0.0, 0.0, 0.0]]);
    assert!(strands.bind_to_skin(&skin));
    // The joint moved 16 world units down: the strand follows, 16 px lower.
    let joint = commands.spawn(Transform::from_xyz(0.0, -16.0, 0.0)).id();
    commands.spawn((
        Hair {
            strands: strand_assets.add(strands),
            debug_coverage: true,
            ..default()
        },
        bevy::mesh::skinning::SkinnedMesh {
            inverse_bindposes: bindposes.add(vec![Mat4::IDENTITY]),
            joints: vec![joint],
        },
    ));
    commands.spawn(pixel_camera(WIDTH, HEIGHT));
}

#[test]
fn skinned_hair_follows_its_joint() {
    if !gpu_or_skip("skinned_hair_follows_its_joint") {
        return;
    }
    let harness = HeadlessRender::new(WIDTH, HEIGHT)
        .format(CaptureFormat::LinearF16)
        .frames(4);
    let mut app = harness.app();
    app.add_plugins(HairPlugin)
        .add_systems(Startup, skinned_scene);
    let image = harness.run(app).expect("renders").to_linear();
    save_coverage("hair_skinned", &image, WIDTH, HEIGHT);
    let at_bind_pose = coverage_in_rows(&image, 17..24);
    let moved = coverage_in_rows(&image, 33..40);
    println!(
        "skinned strand: coverage {at_bind_pose} at the bind pose's rows, {moved} 16 px lower"
    );
    assert!(at_bind_pose < 1.0, "{at_bind_pose}");
    assert!((moved - 112.0).abs() < 6.0, "{moved}");
}

/// A glTF file of one hair card — a ribbon of three cross-sections, 2 px wide, along
/// row 50 — written into `dir`.
fn write_card_gltf(dir: &std::path::Path) {
    let y = (HEIGHT - 50) as f32;
    let mut positions = Vec::new();
    let mut uvs = Vec::new();
    for (k, x) in [4.0f32, 32.0, 60.0].iter().enumerate() {
        for side in [-1.0f32, 1.0] {
            positions.extend([*x, y + side, 0.0]);
            uvs.extend([0.5 + 0.5 * side, k as f32 / 2.0]);
        }
    }
    let indices: [u16; 12] = [0, 1, 2, 1, 3, 2, 2, 3, 4, 3, 5, 4];
    let mut bin = Vec::new();
    for v in positions.iter().chain(&uvs) {
        bin.extend(v.to_le_bytes());
    }
    for i in indices {
        bin.extend(i.to_le_bytes());
    }
    std::fs::write(dir.join("cards.bin"), &bin).unwrap();
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},
"buffers":[{{"uri":"cards.bin","byteLength":{len}}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":72}},{{"buffer":0,"byteOffset":72,"byteLength":48}},{{"buffer":0,"byteOffset":120,"byteLength":24}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":6,"type":"VEC3","min":[4,{lo},0],"max":[60,{hi},0]}},
{{"bufferView":1,"componentType":5126,"count":6,"type":"VEC2"}},
{{"bufferView":2,"componentType":5123,"count":12,"type":"SCALAR"}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1}},"indices":2}}]}}]}}"#,
        len = bin.len(),
        lo = y - 1.0,
        hi = y + 1.0
    );
    std::fs::write(dir.join("cards.gltf"), json).unwrap();
}

#[derive(Resource)]
struct Card(Handle<Mesh>);

fn card_scene(mut commands: Commands, asset_server: Res<AssetServer>) {
    commands.insert_resource(Card(asset_server.load("cards.gltf#Mesh0/Primitive0")));
    commands.spawn(pixel_camera(WIDTH, HEIGHT));
}

/// Once the card's mesh has loaded: its strands, drawn.
fn hair_from_card(
    mut commands: Commands,
    card: Res<Card>,
    meshes: Res<Assets<Mesh>>,
    mut strand_assets: ResMut<Assets<HairStrands>>,
    mut done: Local<bool>,
) {
    let Some(mesh) = meshes.get(&card.0).filter(|_| !*done) else {
        return;
    };
    *done = true;
    let strands = HairStrands::from_ribbon_mesh(mesh, 1).expect("a ribbon mesh");
    commands.spawn(Hair {
        strands: strand_assets.add(strands),
        debug_coverage: true,
        ..default()
    });
}

#[test]
fn hair_cards_load_from_gltf() {
    if !gpu_or_skip("hair_cards_load_from_gltf") {
        return;
    }
    let assets = std::env::temp_dir().join(format!("penumbra_hair_gltf_{}", std::process::id()));
    std::fs::create_dir_all(&assets).unwrap();
    write_card_gltf(&assets);
    let mut harness = HeadlessRender::new(WIDTH, HEIGHT)
        .format(CaptureFormat::LinearF16)
        .frames(4);
    harness.asset_root = Some(assets.clone());
    harness.warm_up = Some(|world: &mut World| {
        let mut hairs = world.query::<&HairBuilt>();
        hairs.iter(world).next().is_some()
    });
    let mut app = harness.app();
    app.add_plugins(HairPlugin)
        .add_systems(Startup, card_scene)
        .add_systems(Update, hair_from_card);
    let image = harness.run(app).expect("renders").to_linear();
    save_coverage("hair_gltf_card", &image, WIDTH, HEIGHT);
    // The card's centre line along row 50, 2 px wide over 56 px.
    let drawn = coverage_in_rows(&image, 47..54);
    let total = coverage_in_rows(&image, 0..HEIGHT);
    println!("glTF card: coverage {drawn} on its rows, {total} in all (its area: 112)");
    assert!((drawn - 112.0).abs() < 6.0, "{drawn}");
    assert_eq!(drawn, total);
    let _ = std::fs::remove_dir_all(&assets);
}
