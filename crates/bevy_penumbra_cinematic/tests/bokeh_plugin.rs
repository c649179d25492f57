//! `BokehDepthOfFieldPlugin` in a Bevy app on lavapipe, end to end: a bright far point
//! spreads into the hexagonal aperture at its circle of confusion with its energy kept,
//! the in-focus object is the input bit for bit, with and without MSAA; steady frames
//! allocate nothing; a second render is bit-identical (sprites sum in slot order, not
//! in the order threads finish); removing the component restores the sharp image.
//!
//! The scene (linear HDR capture, no tonemapping): unlit, so the sharp image is known —
//! a dark wall 20 m away, a bright 0.2 m square in front of it, an in-focus square at the
//! 5 m focal distance. The shaders themselves are checked against the CPU model in the
//! root package's `tests/bokeh_gpu.rs`.

use bevy::camera::Hdr;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::prelude::*;
use bevy_penumbra_cinematic::{BokehAperture, BokehDepthOfField, BokehDepthOfFieldPlugin};
use bevy_penumbra_df::PenumbraGpuAllocations;
use penumbra_cinematic_core::dof::Lens;
use penumbra_reference::camera::PerspectiveCamera;
use penumbra_test::{CaptureFormat, HeadlessRender, KeptApp, gpu_or_skip};

const WIDTH: u32 = 127;
const HEIGHT: u32 = 95;
const FOCAL_DISTANCE: f32 = 5.0;
const F_STOPS: f32 = 0.01;
const WALL: f32 = 0.02;
/// The bright square's centre and radiance.
const LIGHT: Vec3 = Vec3::new(4.5, 0.9, -19.9);
const LIGHT_RADIANCE: f32 = 20.0;
/// The in-focus square's centre and half size.
const SHARP: Vec3 = Vec3::new(-1.2, -0.2, -FOCAL_DISTANCE);
const SHARP_HALF: f32 = 0.5;

fn settings() -> BokehDepthOfField {
    BokehDepthOfField {
        focal_distance: FOCAL_DISTANCE,
        aperture_f_stops: F_STOPS,
        aperture: BokehAperture::Hexagon,
        ..default()
    }
}

fn unlit(materials: &mut Assets<StandardMaterial>, color: LinearRgba) -> Handle<StandardMaterial> {
    materials.add(StandardMaterial {
        base_color: color.into(),
        unlit: true,
        ..default()
    })
}

fn spawn_scene(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    let quad = |size: f32| Rectangle::new(size, size);
    commands.spawn((
        Mesh3d(meshes.add(Rectangle::new(60.0, 40.0))),
        MeshMaterial3d(unlit(&mut materials, LinearRgba::gray(WALL))),
        Transform::from_xyz(0.0, 0.0, -20.0),
    ));
    commands.spawn((
        Mesh3d(meshes.add(quad(0.2))),
        MeshMaterial3d(unlit(&mut materials, LinearRgba::gray(LIGHT_RADIANCE))),
        Transform::from_translation(LIGHT),
    ));
    commands.spawn((
        Mesh3d(meshes.add(quad(2.0 * SHARP_HALF))),
        MeshMaterial3d(unlit(&mut materials, LinearRgba::rgb(0.8, 0.3, 0.1))),
        Transform::from_translation(SHARP),
    ));
    commands.spawn((
        Mesh3d(meshes.add(quad(0.4))),
        MeshMaterial3d(unlit(&mut materials, LinearRgba::rgb(0.1, 0.5, 0.9))),
        Transform::from_translation(SHARP + Vec3::new(0.1, 0.1, 0.01)),
    ));
}

/// Renders the scene (`bokeh` on the camera or not) and keeps the app.
fn render(bokeh: Option<BokehDepthOfField>, msaa: Msaa) -> (Vec<[f32; 4]>, KeptApp) {
    render_removing(bokeh, msaa, None)
}

/// [`render`], the component removed after `remove_after` frames.
fn render_removing(
    bokeh: Option<BokehDepthOfField>,
    msaa: Msaa,
    remove_after: Option<u32>,
) -> (Vec<[f32; 4]>, KeptApp) {
    let harness = HeadlessRender::new(WIDTH, HEIGHT)
        .format(CaptureFormat::LinearF16)
        .frames(6);
    let mut app = harness.app();
    app.add_plugins(BokehDepthOfFieldPlugin)
        .add_systems(Startup, spawn_scene)
        .add_systems(Startup, move |mut commands: Commands| {
            let mut camera = commands.spawn((
                Camera3d::default(),
                Hdr,
                Tonemapping::None,
                msaa,
                Transform::IDENTITY,
            ));
            if let Some(bokeh) = bokeh.clone() {
                camera.insert(bokeh);
            }
        });
    if let Some(frames) = remove_after {
        app.add_systems(
            Update,
            move |mut commands: Commands,
                  cameras: Query<Entity, With<BokehDepthOfField>>,
                  mut n: Local<u32>| {
                *n += 1;
                if *n == frames {
                    for camera in &cameras {
                        commands.entity(camera).remove::<BokehDepthOfField>();
                    }
                }
            },
        );
    }
    let (capture, app) = harness.run_keeping_app(app).expect("renders");
    (capture.to_linear(), app)
}

fn lens() -> Lens {
    settings().resolve(PerspectiveProjection::default().fov).0
}

/// Pixel position of a point in front of the camera at the origin looking down −Z:
/// `penumbra_reference`'s camera with Bevy's default field of view.
fn project(p: Vec3) -> Vec2 {
    let camera = PerspectiveCamera::looking_at(
        Vec3::ZERO,
        Vec3::NEG_Z,
        PerspectiveProjection::default().fov,
        WIDTH,
        HEIGHT,
    );
    let (x, y) = camera.project(p).expect("in front of the camera");
    Vec2::new(x, y)
}

fn at(image: &[[f32; 4]], x: u32, y: u32) -> [f32; 4] {
    image[(y * WIDTH + x) as usize]
}

fn check_bokeh(msaa: Msaa) {
    let (sharp, _) = render(None, msaa);
    let (blurred, _) = render(Some(settings()), msaa);
    save(&format!("bokeh_plugin_{msaa:?}_sharp"), &sharp);
    save(&format!("bokeh_plugin_{msaa:?}_blurred"), &blurred);
    // The in-focus square, inset by 2 pixels (MSAA edges mix depths): the input exactly.
    let lo = project(SHARP + Vec3::new(-SHARP_HALF, SHARP_HALF, 0.0)).ceil() + 2.0;
    let hi = project(SHARP + Vec3::new(SHARP_HALF, -SHARP_HALF, 0.0)).floor() - 2.0;
    let mut inside = 0;
    for y in lo.y as u32..hi.y as u32 {
        for x in lo.x as u32..hi.x as u32 {
            assert_eq!(
                at(&blurred, x, y),
                at(&sharp, x, y),
                "{msaa:?}: in-focus pixel ({x}, {y}) changed"
            );
            inside += 1;
        }
    }
    assert!(inside > 150, "{inside} in-focus pixels checked");

    // The light's energy above the wall, in a window around it: kept.
    let center = project(LIGHT);
    let coc = lens().coc(-LIGHT.z, HEIGHT);
    let reach = (0.5 * coc + 4.0) as i32;
    let window = || {
        (-reach..=reach).flat_map(move |dy| {
            (-reach..=reach)
                .map(move |dx| ((center.x as i32 + dx) as u32, (center.y as i32 + dy) as u32))
        })
    };
    let mut energy = [0.0f64; 2];
    for (x, y) in window() {
        for (e, image) in energy.iter_mut().zip([&sharp, &blurred]) {
            *e += f64::from(at(image, x, y)[1] - WALL);
        }
    }
    // The footprint: where the spread light is above half its mean level over the
    // hexagon (vertex-up, circumradius CoC / 2: area 3√3/2 · (CoC / 2)²), the edge of an
    // anti-aliased shape.
    let level = energy[0] as f32 / (2.598 * 0.25 * coc * coc);
    let (mut rows, mut cols) = (Vec::new(), Vec::new());
    for (x, y) in window() {
        if at(&blurred, x, y)[1] - WALL > 0.5 * level {
            rows.push(y);
            cols.push(x);
        }
    }
    let ratio = energy[1] / energy[0];
    println!(
        "{msaa:?}: energy {:.3} → {:.3} (ratio {ratio:.4}); CoC {coc:.1} px",
        energy[0], energy[1]
    );
    assert!((ratio - 1.0).abs() < 0.01, "{msaa:?}: energy ratio {ratio}");
    // A hexagon with a vertex up: as tall as the CoC, √3/2 as wide (the light itself is
    // about a pixel wide).
    let extent = |v: &[u32]| (v.iter().max().unwrap() - v.iter().min().unwrap() + 1) as f32;
    let (height, width) = (extent(&rows), extent(&cols));
    println!(
        "{msaa:?}: footprint {width} × {height} px (hexagon: {:.1} × {coc:.1})",
        0.866 * coc
    );
    assert!(
        (height - coc).abs() <= 3.0,
        "{msaa:?}: height {height} vs CoC {coc}"
    );
    assert!(
        (width - 0.866 * coc).abs() <= 3.0,
        "{msaa:?}: width {width} vs {}",
        0.866 * coc
    );
}

#[test]
fn far_point_spreads_into_the_aperture_and_focus_is_untouched() {
    if !gpu_or_skip("far_point_spreads_into_the_aperture_and_focus_is_untouched") {
        return;
    }
    check_bokeh(Msaa::Off);
}

#[test]
fn multisampled_views_read_their_first_sample() {
    if !gpu_or_skip("multisampled_views_read_their_first_sample") {
        return;
    }
    check_bokeh(Msaa::Sample4);
}

#[test]
fn steady_frames_allocate_nothing_and_removal_restores_the_image() {
    if !gpu_or_skip("steady_frames_allocate_nothing_and_removal_restores_the_image") {
        return;
    }
    let (sharp, _) = render(None, Msaa::Off);
    let (blurred, mut app) = render(Some(settings()), Msaa::Off);
    assert_ne!(blurred, sharp);
    let (again, _) = render(Some(settings()), Msaa::Off);
    let differing = again.iter().zip(&blurred).filter(|(a, b)| a != b).count();
    assert_eq!(differing, 0, "a second render differs (the sprites' order)");
    let before = app.world().resource::<PenumbraGpuAllocations>().counts();
    assert!(before.textures >= 1 && before.buffers >= 4, "{before:?}");
    for _ in 0..3 {
        app.update();
    }
    let after = app.world().resource::<PenumbraGpuAllocations>().counts();
    assert_eq!(before, after, "steady frames allocated");
    drop(app);
    // Without the component the camera renders as before.
    let (restored, _) = render_removing(Some(settings()), Msaa::Off, Some(3));
    assert_eq!(restored, sharp, "removing the component left the blur");
}

/// Writes `image` (linear, scaled ×4 for visibility) as a PNG in the test output folder.
fn save(name: &str, image: &[[f32; 4]]) {
    let dir = penumbra_test::output_dir();
    std::fs::create_dir_all(&dir).unwrap();
    let bytes: Vec<u8> = image
        .iter()
        .flat_map(|p| {
            let e = |c: f32| ((c * 4.0).clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0) as u8;
            [e(p[0]), e(p[1]), e(p[2]), 255]
        })
        .collect();
    penumbra_test::image::RgbaImage::from_raw(WIDTH, HEIGHT, bytes)
        .unwrap()
        .save(dir.join(format!("{name}.png")))
        .unwrap();
}
