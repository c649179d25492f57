//! What tessellation costs on lavapipe (ignored: a measurement, no assertion on time).
//!
//! A 10,000-triangle rock (`shapes::rock(100, 50)`) with displacement, rendered at 512²
//! and at 1920×1080 (1080p factors), the pool at its adaptive size: the frame time with the rock untessellated, with it
//! tessellated once (the camera still: the passes do not run again), and re-tessellated
//! every frame (the camera circling); the output's triangles (read back) and the pools'
//! bytes. Run:
//! `cargo test -p bevy_penumbra_cinematic --test tessellation_cost -- --ignored --nocapture`.

use bevy::prelude::*;
use bevy_penumbra_cinematic::tessellation::TessellationState;
use bevy_penumbra_cinematic::{Tessellated, TessellationPlugin};
use penumbra_cinematic_core::tessellation::shapes::rock;
use penumbra_cinematic_core::tessellation::uniform::{PATCH_STATE_BYTES, TOTALS_BYTES};
use penumbra_test::{HeadlessRender, gpu_or_skip};

mod tessellation_scene;
use tessellation_scene::{camera, height_image, mesh_of};

#[derive(Resource, Clone, Copy, PartialEq)]
enum Run {
    Off,
    Still,
    Moving,
}

fn scene(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut images: ResMut<Assets<Image>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    run: Res<Run>,
) {
    let map = images.add(height_image(256));
    let mut rock = commands.spawn((
        Mesh3d(meshes.add(mesh_of(&rock(100, 50), true, true))),
        MeshMaterial3d(materials.add(StandardMaterial::default())),
    ));
    if *run != Run::Off {
        rock.insert(Tessellated {
            displacement: Some(map),
            displacement_scale: 0.1,
            ..default()
        });
    }
    commands.spawn((
        DirectionalLight::default(),
        Transform::from_xyz(1.0, 2.0, 1.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    commands.spawn(camera(2.6));
}

/// A small step around the rock every frame (the same distance: the same factors).
fn circle(
    run: Res<Run>,
    mut cameras: Query<&mut Transform, With<Camera3d>>,
    mut frame: Local<u32>,
) {
    if *run != Run::Moving {
        return;
    }
    *frame += 1;
    let angle = *frame as f32 * 0.01;
    for mut t in &mut cameras {
        let eye = Quat::from_rotation_y(angle) * Vec3::new(0.3, 0.6, 1.0).normalize() * 2.6;
        *t = Transform::from_translation(eye).looking_at(Vec3::new(0.0, 0.3, 0.0), Vec3::Y);
    }
}

/// The GPU time of the tessellation passes (ms, Bevy's render diagnostics), if recorded.
fn pass_time(world: &World) -> Option<f64> {
    let store = world.get_resource::<bevy::diagnostic::DiagnosticsStore>()?;
    store
        .iter()
        .find(|d| d.path().as_str() == "render/penumbra_tessellation/elapsed_gpu")?
        .average()
}

/// Median frame time (ms), output (triangles, pool bytes, pass GPU ms) of one run.
fn measure(width: u32, height: u32, run: Run) -> (f64, Option<(u32, u64, Option<f64>)>) {
    const FRAMES: u32 = 8;
    let mut harness = HeadlessRender::new(width, height).frames(FRAMES);
    if run != Run::Off {
        // Until the pool has grown to the view (the GPU applied no bias).
        harness.warm_up = Some(|world: &mut World| {
            let mut states = world.query::<&TessellationState>();
            states
                .iter(world)
                .next()
                .and_then(TessellationState::latest_totals)
                .is_some_and(|t| t[3] > 0 && t[0] == 0)
        });
    }
    let mut app = harness.app();
    app.add_plugins((
        TessellationPlugin,
        bevy::render::diagnostic::RenderDiagnosticsPlugin,
    ))
    .insert_resource(run)
    .add_systems(Startup, scene)
    .add_systems(Update, circle);
    let (capture, mut app) = harness.run_keeping_app(app).expect("renders");
    let mut times: Vec<f64> = capture.frame_times[1..]
        .iter()
        .map(|d| d.as_secs_f64() * 1e3)
        .collect();
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    let world = app.world_mut();
    let gpu = pass_time(world);
    let mut states = world.query::<&TessellationState>();
    let output = states.iter(world).next().map(|state| {
        let t = state.latest_totals().expect("read back");
        let (vertices, indices) = state.budget();
        let words = state.uniform().expect("uniform").vertex_words;
        let pool = 4 * u64::from(words) * u64::from(vertices)
            + 4 * u64::from(indices)
            + PATCH_STATE_BYTES * state.input().patches.len() as u64
            + TOTALS_BYTES;
        (t[2] / 3, pool, gpu)
    });
    (median, output)
}

#[test]
#[ignore = "a measurement: run with --ignored --nocapture"]
fn tessellation_cost() {
    if !gpu_or_skip("tessellation_cost") {
        return;
    }
    println!(
        "size | off ms | tessellated once ms | every frame ms | passes' GPU time ms | output triangles | pool MB (×2 with the mesh's copy)"
    );
    for (w, h) in [(512, 512), (1920, 1080)] {
        let (off, _) = measure(w, h, Run::Off);
        let (still, out) = measure(w, h, Run::Still);
        let (moving, moving_out) = measure(w, h, Run::Moving);
        let (triangles, pool, _) = out.expect("read back");
        let gpu = moving_out
            .and_then(|o| o.2)
            .map_or("not recorded".to_string(), |ms| format!("{ms:.1}"));
        println!(
            "{w}×{h} | {off:.1} | {still:.1} | {moving:.1} | {gpu} | {triangles} | {:.1}",
            pool as f64 / 1e6
        );
    }
}
