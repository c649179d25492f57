//! A real window (X11; under `Xvfb` where no display exists): a `PenumbraLighting` camera
//! with distance-field shadows, DFAO, scatter bokeh and deferred 4× MSAA renders into it
//! while the window is resized (wider, then taller), hidden (X11's minimized: unmapped,
//! no frame to present) and shown again, and restored to its first size. No panic and no
//! wgpu error; every capture has the window's size and shows the scene; the restored
//! window shows what the first one did (no stale, mis-sized texture of Penumbra's
//! per-view state); each resize re-makes the same per-view resources and no more.
//!
//! Needs a display: `DISPLAY`, or `Xvfb` (Debian package `xvfb`, which `.ci/run`
//! installs) started by the test itself; otherwise a reported skip (a failure under CI).
// `std::env::set_var` (pointing winit at the test's own X server) is `unsafe`.
#![allow(unsafe_code)]

use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};
use bevy::window::{WindowPlugin, WindowResolution};
use bevy::winit::WinitPlugin;
use penumbra::df::{DistanceFieldScene, GpuAllocationCounts, PenumbraGpuAllocations};
use penumbra::prelude::*;
use penumbra_test::{gpu_or_skip, image::RgbaImage};
use std::process::{Child, Command};
use std::sync::{Arc, Mutex};

const FIRST: UVec2 = UVec2::new(320, 240);

/// What the script does, one step after another.
#[derive(Clone, Copy, Debug)]
enum Step {
    Capture(&'static str),
    Resize(u32, u32),
    Visible(bool),
    Wait(u32),
    Exit,
}

const SCRIPT: [Step; 13] = [
    Step::Capture("first"),
    Step::Resize(480, 200),
    Step::Capture("wide"),
    Step::Resize(200, 360),
    Step::Capture("tall"),
    Step::Visible(false),
    Step::Wait(8),
    Step::Visible(true),
    Step::Wait(2),
    Step::Resize(FIRST.x, FIRST.y),
    Step::Wait(2),
    Step::Capture("restored"),
    Step::Exit,
];

/// Captures by name, the allocation counts at each capture, and the frames rendered.
#[derive(Resource, Clone, Default)]
struct Log(Arc<Mutex<LogData>>);

#[derive(Default)]
struct LogData {
    captures: Vec<(&'static str, RgbaImage)>,
    allocations: Vec<(&'static str, GpuAllocationCounts)>,
    frames: u32,
}

#[derive(Component)]
struct Caster;

/// An X server for the test: the session's (`DISPLAY`) or an `Xvfb` of its own.
struct Display(Option<Child>);

impl Drop for Display {
    fn drop(&mut self) {
        if let Some(child) = &mut self.0 {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

fn display_or_skip(test: &str) -> Option<Display> {
    if std::env::var("DISPLAY").is_ok_and(|d| !d.is_empty()) {
        return Some(Display(None));
    }
    // A display number no server holds: a stale lock or socket (an `Xvfb` killed
    // earlier) made Xvfb exit at once while the old socket passed the wait below, and
    // winit failed to open the display.
    let free = |n: &u32| {
        !std::path::Path::new(&format!("/tmp/.X{n}-lock")).exists()
            && !std::path::Path::new(&format!("/tmp/.X11-unix/X{n}")).exists()
    };
    let first = std::process::id() % 100;
    let number = (0..200)
        .map(|i| 90 + (first + i) % 200)
        .find(free)
        .unwrap_or(90 + first);
    let child = Command::new("Xvfb")
        .args([
            &format!(":{number}"),
            "-screen",
            "0",
            "1024x768x24",
            "-nolisten",
            "tcp",
        ])
        .stderr(std::process::Stdio::null())
        .spawn();
    let Ok(child) = child else {
        penumbra_testkit::skip(
            test,
            "no display: set DISPLAY or install Xvfb (Debian package `xvfb`)",
        );
        return None;
    };
    let socket = format!("/tmp/.X11-unix/X{number}");
    for _ in 0..100 {
        if std::path::Path::new(&socket).exists() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    // SAFETY: set before the app (and winit) start; the test binary runs this one test.
    unsafe { std::env::set_var("DISPLAY", format!(":{number}")) };
    Some(Display(Some(child)))
}

fn spawn_scene(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    commands.spawn((
        Camera3d::default(),
        Transform::from_xyz(2.5, 2.0, 3.5).looking_at(Vec3::new(0.0, 0.4, 0.0), Vec3::Y),
        PenumbraLighting,
        DeferredMsaa::default(),
        DistanceFieldAmbientOcclusion::default(),
        BokehDepthOfField {
            focal_distance: 4.0,
            ..default()
        },
    ));
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(8.0, 8.0))),
        MeshMaterial3d(materials.add(Color::srgb(0.7, 0.7, 0.7))),
    ));
    commands.spawn((
        Mesh3d(meshes.add(Cuboid::new(1.0, 1.0, 1.0))),
        MeshMaterial3d(materials.add(Color::srgb(0.8, 0.4, 0.3))),
        Transform::from_xyz(0.0, 0.5, 0.0),
        DistanceFieldCaster::default(),
        Caster,
    ));
    commands.spawn((
        DirectionalLight {
            illuminance: 8000.0,
            ..default()
        },
        Transform::from_xyz(1.0, 2.0, 0.6).looking_at(Vec3::ZERO, Vec3::Y),
        DistanceFieldShadows::default(),
    ));
}

/// A lit cube on a shadowed and lit floor: far from one colour.
fn shows_the_scene(image: &RgbaImage) -> bool {
    let lumas = image
        .pixels()
        .map(|p| p.0[..3].iter().map(|&c| u32::from(c)).sum::<u32>());
    let (lo, hi) = lumas.fold((u32::MAX, 0), |(lo, hi), l| (lo.min(l), hi.max(l)));
    hi > lo + 150
}

fn to_rgba(image: &Image) -> RgbaImage {
    let image = image
        .clone()
        .try_into_dynamic()
        .expect("a screenshot converts to an image");
    image.to_rgba8()
}

/// Runs [`SCRIPT`] once the caster is baked.
#[allow(clippy::too_many_arguments, reason = "a Bevy system's parameters")]
fn script(
    mut commands: Commands,
    mut at: Local<(usize, u32, bool)>,
    mut windows: Query<&mut Window>,
    casters: Query<Entity, With<Caster>>,
    scene: Res<DistanceFieldScene>,
    allocations: Res<PenumbraGpuAllocations>,
    log: Res<Log>,
    mut exit: MessageWriter<AppExit>,
) {
    let (step, waited, pending) = &mut *at;
    log.0.lock().expect("log").frames += 1;
    if casters.iter().any(|e| scene.slot(e).is_none()) {
        return;
    }
    let Ok(mut window) = windows.single_mut() else {
        return;
    };
    *waited += 1;
    // Each step starts a few frames after the last (a resize reaches the surface a
    // frame or two later).
    if *waited < 3 {
        return;
    }
    match SCRIPT[*step] {
        Step::Capture(name) => {
            if !*pending {
                *pending = true;
                let log = log.clone();
                let counts = allocations.counts();
                commands.spawn(Screenshot::primary_window()).observe(
                    move |captured: On<ScreenshotCaptured>| {
                        let mut data = log.0.lock().expect("log");
                        data.captures.retain(|(n, _)| *n != name);
                        data.captures.push((name, to_rgba(&captured.image)));
                        data.allocations.retain(|(n, _)| *n != name);
                        data.allocations.push((name, counts));
                    },
                );
            }
            let data = log.0.lock().expect("log");
            let Some((_, image)) = data.captures.iter().find(|(n, _)| *n == name) else {
                assert!(*waited < 200, "the capture {name} never came");
                return;
            };
            // The first frames after start show nothing while lavapipe compiles the
            // pipelines: capture again until the scene is there.
            if !shows_the_scene(image) && *waited < 200 {
                drop(data);
                *pending = false;
                return;
            }
            *pending = false;
        }
        Step::Resize(w, h) => window.resolution.set(w as f32, h as f32),
        Step::Visible(visible) => window.visible = visible,
        Step::Wait(n) => {
            if *waited < n {
                return;
            }
        }
        Step::Exit => {
            exit.write(AppExit::Success);
            return;
        }
    }
    *step += 1;
    *waited = 0;
}

#[test]
fn window_resizes_hides_and_restores() {
    let test = "window_resizes_hides_and_restores";
    if !gpu_or_skip(test) {
        return;
    }
    let Some(_display) = display_or_skip(test) else {
        return;
    };
    let log = Log::default();
    let mut app = App::new();
    app.add_plugins(
        DefaultPlugins
            .set(WindowPlugin {
                primary_window: Some(Window {
                    title: "Penumbra window test".into(),
                    resolution: WindowResolution::new(FIRST.x, FIRST.y),
                    ..default()
                }),
                ..default()
            })
            .set(WinitPlugin {
                run_on_any_thread: true,
            }),
    )
    .add_plugins(PenumbraPlugins)
    .insert_resource(bevy::pbr::DefaultOpaqueRendererMethod::deferred())
    .insert_resource(log.clone())
    .insert_resource(bevy::render::error_handler::RenderErrorHandler(
        |error, _, _| panic!("wgpu error: {:?}: {}", error.ty, error.description),
    ))
    .add_systems(Startup, spawn_scene)
    .add_systems(Update, script);
    let exit = app.run();
    assert!(exit.is_success(), "the app ended with {exit:?}");

    let data = log.0.lock().expect("log");
    println!("frames: {}", data.frames);
    for (name, counts) in &data.allocations {
        println!("{name}: Penumbra GPU allocations so far {counts:?}");
    }
    let size = |name: &str| {
        let (_, image) = data
            .captures
            .iter()
            .find(|(n, _)| *n == name)
            .unwrap_or_else(|| panic!("no capture {name}"));
        image
    };
    for (name, expected) in [
        ("first", FIRST),
        ("wide", UVec2::new(480, 200)),
        ("tall", UVec2::new(200, 360)),
        ("restored", FIRST),
    ] {
        let image = size(name);
        assert_eq!(
            UVec2::new(image.width(), image.height()),
            expected,
            "{name}: the capture has the wrong size"
        );
        assert!(
            shows_the_scene(image),
            "{name}: the capture does not show the scene"
        );
    }
    // Each resize re-makes the same per-view resources, nothing more.
    let counts = |name: &str| {
        data.allocations
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, c)| *c)
            .unwrap_or_else(|| panic!("no counts at {name}"))
    };
    let delta = |a: &str, b: &str| {
        let (a, b) = (counts(a), counts(b));
        (
            b.textures - a.textures,
            b.bind_groups - a.bind_groups,
            b.buffers - a.buffers,
        )
    };
    assert_eq!(
        delta("wide", "tall"),
        delta("tall", "restored"),
        "a resize (and a hide) made more than the last resize did"
    );
    // The restored window shows what the first one did.
    let (first, restored) = (size("first"), size("restored"));
    let diff: Vec<u32> = first
        .pixels()
        .zip(restored.pixels())
        .map(|(a, b)| {
            (0..3)
                .map(|k| a.0[k].abs_diff(b.0[k]) as u32)
                .max()
                .unwrap_or(0)
        })
        .collect();
    let mean = diff.iter().sum::<u32>() as f64 / diff.len() as f64;
    let over = diff.iter().filter(|&&d| d > 16).count() as f64 / diff.len() as f64;
    println!(
        "restored vs first: mean |Δ| {mean:.2}/255, {:.2} % of pixels over 16",
        100.0 * over
    );
    assert!(
        mean < 2.0 && over < 0.01,
        "the restored window differs from the first: mean {mean:.2}, {over:.4} over 16"
    );
}
