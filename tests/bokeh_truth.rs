//! #19's side-by-side figures (ignored: a measurement, ~1 min on lavapipe):
//!
//! ```text
//! cargo test -p penumbra --test bokeh_truth -- --ignored --nocapture
//! ```
//!
//! Bevy's own depth-of-field scene (`../shared/scenes/DepthOfFieldExample.glb`, Bevy's
//! example camera, focused at 7 m, the background at 14 m) at f/0.05 — so the blur
//! reaches ±15 px at 384 × 288 — rendered in one app and one frame by:
//!
//! - **the thin-lens truth**: the scene seen from ≥ 64 pinholes spread evenly over the
//!   hexagonal aperture (`Lens::aperture_diameter` wide, vertex up), each camera moved to
//!   its pinhole with its image window shifted (`SubCameraView`, an off-axis projection)
//!   so the focal plane stays put, the linear HDR read-backs averaged;
//! - Penumbra's `BokehDepthOfField` (hexagon), Bevy's `DepthOfField` in Gaussian and in
//!   bokeh mode, and the sharp pinhole image, each from the centre of the lens.
//!
//! The scene's materials are made Lambertian (no specular): the truth would otherwise
//! average view-dependent highlights over the 45 cm lens, which no post-process depth of
//! field sees.
//!
//! `bokeh_against_the_thin_lens_truth`: mean |Δ| against the truth (linear, relative to
//! the truth's mean) overall and in masks from each pixel's circle of confusion, computed
//! from its distance by casting the pixel's ray against the scene's triangles
//! (`penumbra_sdf`, not the GPU): **in focus** (under ½ px, where Penumbra keeps the
//! input), **interiors** (3 px or more, no depth step within the blur's reach; also split
//! by the blur's size) and **borders** (a sharp and a blurred pixel and a depth step of
//! 15 % within 8 px). Then the lavapipe cost of each, as the mean frame time with one
//! camera over the same camera without depth of field.
//!
//! `bokeh_shape_against_the_thin_lens`: the bokeh shape — a 0.3 m light 20 m away (a
//! 39 px circle of confusion) in front of a dark wall, each method's image against the
//! thin lens's own (the hexagon convolved with the light's square, its plateau the
//! light's energy over the hexagon's area): the footprint's intersection over union at
//! half the plateau and the mean |Δ| around it.
//!
//! `merge_rule_error_against_work`: the sprite rule on this real content — the CPU
//! model (equal to the passes on lavapipe) run on the sharp image and the ray-cast
//! distances with no merging, 2×2 blocks only and blocks and 4×4 groups, each rule's
//! error per mask beside the scatter pass's fragments. At the bench's size and lens:
//!
//! ```text
//! PENUMBRA_BOKEH_TRUTH_SIZE=1920x1080 PENUMBRA_BOKEH_TRUTH_F_STOPS=0.125 \
//!     cargo test -p penumbra --test bokeh_truth -- --ignored --nocapture merge_rule
//! ```

use bevy::camera::{Hdr, ImageRenderTarget, RenderTarget, SubCameraView};
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::post_process::dof::{DepthOfField, DepthOfFieldMode};
use bevy::prelude::*;
use bevy::render::gpu_readback::{Readback, ReadbackComplete};
use bevy::render::render_resource::{TextureFormat, TextureUsages};
use bevy::world_serialization::{WorldAsset, WorldAssetRoot};
use penumbra::prelude::*;
use penumbra_cinematic_core::dof::Lens;
use penumbra_reference::camera::PerspectiveCamera;
use penumbra_reference::df::f16_to_f32;
use penumbra_test::{HeadlessRender, gpu_or_skip};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

/// The views' size: 384 × 288, or `PENUMBRA_BOKEH_TRUTH_SIZE=WxH` (say, the bench's
/// 1920x1080 for [`merge_rule_error_against_work`]'s work at a game's size).
fn size() -> UVec2 {
    static SIZE: std::sync::LazyLock<UVec2> = std::sync::LazyLock::new(|| {
        let parse = |v: String| {
            let (w, h) = v.split_once('x')?;
            Some(UVec2::new(w.parse().ok()?, h.parse().ok()?))
        };
        std::env::var("PENUMBRA_BOKEH_TRUTH_SIZE")
            .ok()
            .and_then(parse)
            .unwrap_or(UVec2::new(384, 288))
    });
    *SIZE
}
const SCENE: &str = "DepthOfFieldExample.glb";

/// A scene, its camera and its lens.
#[derive(Resource, Clone, Copy, Debug, PartialEq)]
struct Setup {
    /// Bevy's depth-of-field scene, or the bright light in front of a dark wall.
    circuit: bool,
    focal_distance: f32,
    f_stops: f32,
    max_depth: f32,
}

/// Bevy's example scene, its camera, focus and max depth, at f/0.05 (or
/// `PENUMBRA_BOKEH_TRUTH_F_STOPS`: the bench's lens is f/0.125 at 1920x1080).
fn circuit() -> Setup {
    let f_stops = std::env::var("PENUMBRA_BOKEH_TRUTH_F_STOPS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0.05);
    Setup {
        circuit: true,
        focal_distance: 7.0,
        f_stops,
        max_depth: 14.0,
    }
}

/// A 0.3 m (5 px) light 20 m away in front of a dark wall, focused at 5 m: its bokeh,
/// against the thin lens's analytic image (75 pinholes would show it as dots).
const LIGHT: Setup = Setup {
    circuit: false,
    focal_distance: 5.0,
    f_stops: 0.03,
    max_depth: f32::INFINITY,
};
const LIGHT_SIZE: f32 = 0.3;
const LIGHT_AT: Vec3 = Vec3::new(0.4, 0.3, -19.9);
const WALL: f32 = 0.02;
/// Pinhole grid across the aperture's bounding square (those inside the hexagon kept).
const GRID: i32 = 11;

/// What one camera renders.
#[derive(Clone, Copy, Debug, PartialEq)]
enum View {
    /// A pinhole at this offset on the lens (camera-space x right, y up, metres).
    Pinhole(Vec2),
    Sharp,
    Penumbra,
    BevyGaussian,
    BevyBokeh,
}

impl Setup {
    fn camera_transform(&self) -> Transform {
        if self.circuit {
            Transform::from_xyz(0.0, 4.5, 8.25).looking_at(Vec3::ZERO, Vec3::Y)
        } else {
            Transform::IDENTITY
        }
    }

    fn settings(&self) -> BokehDepthOfField {
        BokehDepthOfField {
            focal_distance: self.focal_distance,
            aperture_f_stops: self.f_stops,
            max_depth: self.max_depth,
            ..default()
        }
    }

    fn lens(&self) -> Lens {
        self.settings()
            .resolve(PerspectiveProjection::default().fov)
            .0
    }
}

/// Pinhole offsets evenly over the hexagon (vertex up, circumradius half the aperture).
fn pinholes(setup: &Setup) -> Vec<Vec2> {
    let radius = 0.5 * setup.lens().aperture_diameter();
    let apothem = (std::f32::consts::PI / 6.0).cos();
    let inside = |p: Vec2| {
        (0..6).all(|k| {
            let a = std::f32::consts::FRAC_PI_2 + (k as f32 + 0.5) * std::f32::consts::TAU / 6.0;
            p.dot(Vec2::new(a.cos(), a.sin())) <= apothem
        })
    };
    let mut out = Vec::new();
    for j in 0..GRID {
        for i in 0..GRID {
            let p = (Vec2::new(i as f32, j as f32) + 0.5) / GRID as f32 * 2.0 - 1.0;
            if inside(p) {
                out.push(p * radius);
            }
        }
    }
    out
}

/// The camera of `view`, rendering into `target`.
fn spawn_camera(commands: &mut Commands, setup: &Setup, view: View, target: Handle<Image>) {
    let fov = PerspectiveProjection::default().fov;
    let t = (0.5 * fov).tan();
    let aspect = size().x as f32 / size().y as f32;
    let mut transform = setup.camera_transform();
    let mut camera = Camera::default();
    if let View::Pinhole(p) = view {
        transform.translation += transform.rotation * p.extend(0.0);
        // Shift the image window so the focal plane projects where it did.
        camera.sub_camera_view = Some(SubCameraView {
            full_size: size(),
            offset: Vec2::new(
                -p.x / (setup.focal_distance * t * aspect) * 0.5 * size().x as f32,
                p.y / (setup.focal_distance * t) * 0.5 * size().y as f32,
            ),
            size: size(),
        });
    }
    let mut entity = commands.spawn((
        Camera3d::default(),
        camera,
        RenderTarget::Image(ImageRenderTarget::from(target)),
        Hdr,
        Tonemapping::None,
        Msaa::Off,
        transform,
    ));
    let bevy = |mode| DepthOfField {
        mode,
        focal_distance: setup.focal_distance,
        aperture_f_stops: setup.f_stops,
        max_depth: setup.max_depth,
        ..default()
    };
    match view {
        View::Penumbra => {
            entity.insert(setup.settings());
        }
        View::BevyGaussian => {
            entity.insert(bevy(DepthOfFieldMode::Gaussian));
        }
        View::BevyBokeh => {
            entity.insert(bevy(DepthOfFieldMode::Bokeh));
        }
        View::Pinhole(_) | View::Sharp => {}
    }
}

#[derive(Resource)]
struct Views(Vec<View>);

#[derive(Resource)]
struct Targets(Vec<Handle<Image>>);

#[derive(Resource)]
struct SceneHandle(Handle<WorldAsset>);

/// Set once the scene has loaded: the cameras are spawned then (no frames wasted on
/// dozens of cameras rendering an empty scene).
#[derive(Resource)]
struct Ready;

fn scene_ready(world: &mut World) -> bool {
    if world.contains_resource::<Ready>() {
        return true;
    }
    if !world.resource::<Setup>().circuit {
        // Spawned at startup: ready after the first update.
        if world.query::<&Mesh3d>().iter(world).next().is_some() {
            world.insert_resource(Ready);
        }
        return false;
    }
    let Some(handle) = world.get_resource::<SceneHandle>().map(|h| h.0.clone()) else {
        return false;
    };
    let loaded = world
        .resource::<AssetServer>()
        .is_loaded_with_dependencies(&handle);
    if loaded && world.query::<&Mesh3d>().iter(world).next().is_some() {
        // Lambertian: shading that does not depend on where on the 45 cm lens the eye is
        // (otherwise the truth averages the highlights over the lens, which no
        // post-process depth of field sees).
        for (_, m) in world.resource_mut::<Assets<StandardMaterial>>().iter_mut() {
            m.metallic = 0.0;
            m.perceptual_roughness = 1.0;
            m.reflectance = 0.0;
            m.specular_tint = Color::BLACK;
        }
        world.insert_resource(Ready);
    }
    false
}

fn spawn_scene(
    mut commands: Commands,
    setup: Res<Setup>,
    assets: Res<AssetServer>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    if setup.circuit {
        let scene = assets.load(GltfAssetLabel::Scene(0).from_asset(SCENE));
        commands.spawn(WorldAssetRoot(scene.clone()));
        commands.insert_resource(SceneHandle(scene));
        return;
    }
    let mut unlit = |c: f32| {
        materials.add(StandardMaterial {
            base_color: LinearRgba::gray(c).into(),
            unlit: true,
            ..default()
        })
    };
    let (wall, light) = (unlit(WALL), unlit(20.0));
    commands.spawn((
        Mesh3d(meshes.add(Rectangle::new(60.0, 40.0))),
        MeshMaterial3d(wall),
        Transform::from_xyz(0.0, 0.0, -20.0),
    ));
    commands.spawn((
        Mesh3d(meshes.add(Rectangle::new(LIGHT_SIZE, LIGHT_SIZE))),
        MeshMaterial3d(light),
        Transform::from_translation(LIGHT_AT),
    ));
}

fn spawn_cameras(
    mut commands: Commands,
    setup: Res<Setup>,
    views: Res<Views>,
    mut images: ResMut<Assets<Image>>,
    ready: Option<Res<Ready>>,
    mut done: Local<bool>,
) {
    if ready.is_none() || *done {
        return;
    }
    *done = true;
    let mut targets = Vec::new();
    for view in &views.0 {
        let mut image =
            Image::new_target_texture(size().x, size().y, TextureFormat::Rgba16Float, None);
        image.texture_descriptor.usage |= TextureUsages::COPY_SRC;
        let handle = images.add(image);
        spawn_camera(&mut commands, &setup, *view, handle.clone());
        targets.push(handle);
    }
    commands.insert_resource(Targets(targets));
}

/// Renders every view in one app; the linear images in order, and the mean frame time
/// of the counted frames (ms).
fn render(setup: Setup, views: Vec<View>, frames: u32) -> (Vec<Vec<Vec3>>, f64) {
    let scenes = penumbra_testkit::shared_dir("bokeh_truth", env!("CARGO_MANIFEST_DIR"), "scenes")
        .expect("../shared/scenes");
    let mut harness = HeadlessRender::new(32, 32)
        .frames(frames)
        .warm_up(scene_ready);
    harness.asset_root = Some(scenes);
    let mut app = harness.app();
    let count = views.len();
    app.add_plugins(PenumbraPlugins)
        .insert_resource(Views(views))
        .insert_resource(setup)
        .add_systems(Startup, spawn_scene)
        .add_systems(Update, spawn_cameras);
    let (capture, mut app) = harness.run_keeping_app(app).expect("renders");
    let steady = &capture.frame_times[1.min(capture.frame_times.len())..];
    let frame_ms =
        steady.iter().map(|d| d.as_secs_f64()).sum::<f64>() * 1e3 / steady.len().max(1) as f64;
    let slots: Arc<Mutex<HashMap<usize, Vec<u8>>>> = Arc::default();
    let targets = app.world().resource::<Targets>().0.clone();
    for (i, target) in targets.into_iter().enumerate() {
        let sink = slots.clone();
        app.world_mut().spawn(Readback::texture(target)).observe(
            move |event: On<ReadbackComplete>| {
                sink.lock()
                    .unwrap()
                    .entry(i)
                    .or_insert_with(|| event.data.clone());
            },
        );
    }
    for _ in 0..30 {
        app.update();
        if slots.lock().unwrap().len() == count {
            break;
        }
    }
    let mut slots = slots.lock().unwrap();
    assert_eq!(slots.len(), count, "every view read back");
    let images = (0..count)
        .map(|i| {
            slots
                .remove(&i)
                .unwrap()
                .chunks_exact(8)
                .take((size().x * size().y) as usize)
                .map(|p| {
                    let h = |k: usize| f16_to_f32(u16::from_le_bytes([p[2 * k], p[2 * k + 1]]));
                    Vec3::new(h(0), h(1), h(2))
                })
                .collect()
        })
        .collect();
    (images, frame_ms)
}

/// Each pixel's distance along the view axis in Bevy's scene (its max depth for the sky),
/// by casting its
/// ray against the scene's triangles.
fn distances() -> Vec<f32> {
    use penumbra_reference::camera::PerspectiveCamera;
    use penumbra_reference::scene_truth::{Facing, SceneTriangles, primary_hits};
    let dir = penumbra_testkit::shared_dir("bokeh_truth", env!("CARGO_MANIFEST_DIR"), "scenes")
        .expect("../shared/scenes");
    let scene = SceneTriangles::from_gltf(&dir.join(SCENE), Facing::AllFaces).expect("the scene");
    let transform = circuit().camera_transform();
    let camera = PerspectiveCamera {
        world_from_view: transform.to_matrix(),
        fov_y: PerspectiveProjection::default().fov,
        width: size().x,
        height: size().y,
    };
    let forward = transform.forward().as_vec3();
    let far = circuit().max_depth;
    primary_hits(&scene, &camera, Facing::AllFaces)
        .iter()
        .map(|hit| {
            hit.map_or(far, |h| {
                ((h.position - transform.translation).dot(forward)).min(far)
            })
        })
        .collect()
}

/// The masks: (name, pixels).
fn masks(distance: &[f32]) -> Vec<(&'static str, Vec<bool>)> {
    let lens = circuit().lens();
    let coc: Vec<f32> = distance.iter().map(|&z| lens.coc(z, size().y)).collect();
    let (w, h) = (size().x as i32, size().y as i32);
    let at = |v: &[f32], x: i32, y: i32| v[(y.clamp(0, h - 1) * w + x.clamp(0, w - 1)) as usize];
    let window = |x: i32, y: i32, r: i32| {
        let (mut sharp, mut blurred) = (false, false);
        let (mut near, mut far) = (f32::MAX, 0.0f32);
        for dy in -r..=r {
            for dx in -r..=r {
                if dx * dx + dy * dy > r * r {
                    continue;
                }
                let c = at(&coc, x + dx, y + dy).abs();
                sharp |= c < 0.5;
                blurred |= c >= 3.0;
                let z = at(distance, x + dx, y + dy);
                near = near.min(z);
                far = far.max(z);
            }
        }
        (sharp, blurred, far > 1.15 * near)
    };
    let mut in_focus = Vec::new();
    let mut interiors = Vec::new();
    let mut borders = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let c = at(&coc, x, y).abs();
            let (sharp, blurred, step) = window(x, y, 8);
            let border = sharp && blurred && step;
            borders.push(border);
            in_focus.push(!border && c < 0.5);
            let reach = (0.5 * c).ceil() as i32 + 1;
            interiors.push(!border && c >= 3.0 && !window(x, y, reach).2);
        }
    }
    let band = |lo: f32, hi: f32| -> Vec<bool> {
        interiors
            .iter()
            .zip(&coc)
            .map(|(&i, c)| i && (lo..hi).contains(&c.abs()))
            .collect()
    };
    let (small, medium, large) = (band(3.0, 6.0), band(6.0, 10.0), band(10.0, f32::MAX));
    vec![
        ("all", vec![true; distance.len()]),
        ("in focus", in_focus),
        ("interiors", interiors),
        ("borders", borders),
        ("interiors 3-6 px", small),
        ("6-10 px", medium),
        ("10+ px", large),
    ]
}

/// The masks as a table's column headers: each name and its pixel count.
fn mask_columns(masks: &[(&str, Vec<bool>)]) -> String {
    masks
        .iter()
        .map(|(name, m)| format!("{name} ({} px)", m.iter().filter(|&&b| b).count()))
        .collect::<Vec<_>>()
        .join(" | ")
}

/// Mean |Δ| over `mask` relative to the truth's mean there.
fn error(image: &[Vec3], truth: &[Vec3], mask: &[bool]) -> f64 {
    let (mut d, mut t, mut n) = (0.0f64, 0.0f64, 0usize);
    for ((a, b), &m) in image.iter().zip(truth).zip(mask) {
        if m {
            d += f64::from((*a - *b).abs().element_sum() / 3.0);
            t += f64::from(b.element_sum() / 3.0);
            n += 1;
        }
    }
    if n == 0 { f64::NAN } else { d / t }
}

/// The methods compared with the truth, rendered from the centre of the lens.
const METHODS: [(&str, View); 4] = [
    ("sharp (pinhole)", View::Sharp),
    ("Penumbra scatter", View::Penumbra),
    ("Bevy Gaussian", View::BevyGaussian),
    ("Bevy bokeh", View::BevyBokeh),
];

/// The methods' images and the thin-lens truth, rendered in one app.
fn methods_and_truth(setup: Setup) -> (Vec<Vec<Vec3>>, Vec<Vec3>) {
    let holes = pinholes(&setup);
    assert!(holes.len() >= 64, "{} pinholes", holes.len());
    let mut views: Vec<View> = METHODS.iter().map(|(_, v)| *v).collect();
    views.extend(holes.iter().map(|&p| View::Pinhole(p)));
    let (mut images, _) = render(setup, views, 2);
    let n = holes.len() as f32;
    let mut truth = vec![Vec3::ZERO; (size().x * size().y) as usize];
    for image in &images[METHODS.len()..] {
        for (t, p) in truth.iter_mut().zip(image) {
            *t += *p / n;
        }
    }
    let lens = setup.lens();
    println!(
        "{} pinholes; f = {:.2} mm, aperture {:.1} mm, focused at {} m",
        holes.len(),
        lens.focal_length() * 1e3,
        lens.aperture_diameter() * 1e3,
        setup.focal_distance,
    );
    images.truncate(METHODS.len());
    (images, truth)
}

#[test]
#[ignore = "a measurement: ~1 min on lavapipe"]
fn bokeh_against_the_thin_lens_truth() {
    if !gpu_or_skip("bokeh_against_the_thin_lens_truth") {
        return;
    }
    let (images, truth) = methods_and_truth(circuit());
    let masks = masks(&distances());
    println!(
        "CoC at the max depth {} m: {:.1} px",
        circuit().max_depth,
        circuit().lens().coc(circuit().max_depth, size().y)
    );
    let header = mask_columns(&masks);
    println!("| method | {header} |");
    let mut table = HashMap::new();
    for ((name, _), image) in METHODS.iter().zip(&images) {
        let row: Vec<f64> = masks.iter().map(|(_, m)| error(image, &truth, m)).collect();
        println!(
            "| {name} | {} |",
            row.iter()
                .map(|e| format!("{e:.4}"))
                .collect::<Vec<_>>()
                .join(" | ")
        );
        table.insert(*name, row);
    }
    save("bokeh_truth_truth", &truth);
    for ((name, _), image) in METHODS.iter().zip(&images) {
        save(
            &format!("bokeh_truth_{}", name.replace([' ', '(', ')'], "_")),
            image,
        );
    }
    // The truth is right: sharp where the lens is in focus (a quarter-pixel shift of the
    // board's one-pixel traces is all that is left), far from it elsewhere.
    let sharp = &table["sharp (pinhole)"];
    assert!(
        sharp[1] < 0.03,
        "in focus, the truth is sharp: {}",
        sharp[1]
    );
    assert!(
        sharp[2] > 0.2,
        "out of focus, the truth is blurred: {}",
        sharp[2]
    );
    let penumbra = &table["Penumbra scatter"];
    assert!(
        penumbra[0] < 0.5 * sharp[0],
        "Penumbra halves the error of no blur"
    );

    // Cost: one camera per app, mean frame time over 11 frames (after the first).
    let (_, off) = render(circuit(), vec![View::Sharp], 12);
    for (name, view) in &METHODS[1..] {
        let (_, ms) = render(circuit(), vec![*view], 12);
        println!(
            "{name}: {ms:.1} ms per frame, {:+.1} ms over none ({off:.1} ms)",
            ms - off
        );
    }
}

/// The block-merge rule on real content: the scatter model (`penumbra_reference::bokeh`,
/// equal to the passes on lavapipe by `tests/bokeh_gpu.rs`) run on the sharp image and
/// the ray-cast distances of Bevy's depth-of-field scene, for each colour tolerance's
/// growth with the sprite's size, against the thin-lens truth: its error per mask beside
/// the scatter pass's fragments (its work) and the share of blocks merged.
#[test]
#[ignore = "a measurement: ~1 min on lavapipe"]
fn merge_rule_error_against_work() {
    use penumbra_reference::bokeh::{self, Aperture, BokehImage, SpriteRule};
    if !gpu_or_skip("merge_rule_error_against_work") {
        return;
    }
    let (images, truth) = methods_and_truth(circuit());
    let distance = distances();
    let masks = masks(&distance);
    let lens = circuit().lens();
    let input = BokehImage {
        size: size(),
        color: images[0].clone(),
        distance,
    };
    let aperture = Aperture::hexagon(64);
    let half = bokeh::downsample(&input, &lens);
    let blocks = f64::from(half.size.x.div_ceil(2) * half.size.y.div_ceil(2));
    let header = mask_columns(&masks);
    println!("| rule | fragments | merged blocks | {header} |");
    let mut rows = Vec::new();
    let mut rules = vec![
        (
            "no merging".to_string(),
            SpriteRule {
                merge: false,
                ..SpriteRule::default()
            },
        ),
        (
            "blocks only".to_string(),
            SpriteRule {
                merge_groups: false,
                ..SpriteRule::default()
            },
        ),
    ];
    rules.push(("blocks and groups".to_string(), SpriteRule::default()));
    for (name, rule) in rules {
        let (model, sprites) = bokeh::depth_of_field(&input, &lens, &aperture, &rule);
        let fragments = bokeh::scatter_fragments(&sprites, half.size, rule.quarter_diameter());
        let merged = sprites
            .iter()
            .map(|s| match s.weight {
                16.0 => 4.0,
                4.0 => 1.0,
                _ => 0.0,
            })
            .sum::<f64>()
            / blocks;
        let errors: Vec<f64> = masks
            .iter()
            .map(|(_, m)| error(&model, &truth, m))
            .collect();
        println!(
            "| {name} | {fragments} | {merged:.3} | {} |",
            errors
                .iter()
                .map(|e| format!("{e:.4}"))
                .collect::<Vec<_>>()
                .join(" | ")
        );
        rows.push((name, fragments, errors));
    }
    // Groups are their sixteen sprites where those agree: the error stays that of
    // blocks alone (measured at 384 × 288: 103,128 fragments against 192,940, each
    // mask's error within 0.3 %) for far fewer fragments.
    let (blocks, groups) = (&rows[1], &rows[2]);
    assert!(
        groups.1 * 10 < blocks.1 * 7,
        "work: {} against {}",
        groups.1,
        blocks.1
    );
    for ((name, _), (g, b)) in masks.iter().zip(groups.2.iter().zip(&blocks.2)) {
        assert!(
            g.is_nan() || *g <= b * 1.01 + 1e-4,
            "{name}: {g} against {b}"
        );
    }
}

/// Pixel position of a point in front of the camera at the origin looking down −Z:
/// `penumbra_reference`'s camera with Bevy's default field of view.
fn project(p: Vec3) -> Vec2 {
    let camera = PerspectiveCamera::looking_at(
        Vec3::ZERO,
        Vec3::NEG_Z,
        PerspectiveProjection::default().fov,
        size().x,
        size().y,
    );
    let (x, y) = camera.project(p).expect("in front of the camera");
    Vec2::new(x, y)
}

/// The thin lens's image of the light, analytically: the aperture (a hexagon, vertex up,
/// as wide as the circle of confusion) convolved with the light's square — where it
/// reaches half its plateau (half of the square's points see the pixel).
fn thin_lens_footprint(coc: f32) -> Vec<bool> {
    let center = project(LIGHT_AT);
    let half = 0.5 * (project(LIGHT_AT + Vec3::splat(0.5 * LIGHT_SIZE)) - center).abs();
    let r = 0.5 * coc;
    let apothem = (std::f32::consts::PI / 6.0).cos();
    let in_hexagon = |d: Vec2| {
        let p = Vec2::new(d.x, -d.y) / r; // image y down, shape y up
        (0..6).all(|k| {
            let a = std::f32::consts::FRAC_PI_2 + (k as f32 + 0.5) * std::f32::consts::TAU / 6.0;
            p.dot(Vec2::new(a.cos(), a.sin())) <= apothem
        })
    };
    (0..size().y)
        .flat_map(|y| (0..size().x).map(move |x| Vec2::new(x as f32 + 0.5, y as f32 + 0.5)))
        .map(|p| {
            let seen = (0..=8)
                .flat_map(|j| (0..=8).map(move |i| Vec2::new(i as f32, j as f32)))
                .filter(|&o| in_hexagon(p - (center + (o / 4.0 - 1.0) * half)))
                .count();
            2 * seen >= 81
        })
        .collect()
}

#[test]
#[ignore = "a measurement: ~10 s on lavapipe"]
fn bokeh_shape_against_the_thin_lens() {
    if !gpu_or_skip("bokeh_shape_against_the_thin_lens") {
        return;
    }
    let views: Vec<View> = METHODS.iter().map(|(_, v)| *v).collect();
    let (images, _) = render(LIGHT, views, 2);
    let energy = |image: &[Vec3]| -> f64 { image.iter().map(|p| f64::from(p.y - WALL)).sum() };
    let coc = LIGHT.lens().coc(-LIGHT_AT.z, size().y);
    let want = thin_lens_footprint(coc);
    let area = want.iter().filter(|&&b| b).count();
    // Half the thin lens's plateau (the light's energy over the hexagon's area): the
    // shape's edge.
    let level = 0.5 * energy(&images[0]) as f32 / (2.598 * 0.25 * coc * coc);
    println!(
        "the light's CoC {coc:.1} px: the thin lens's footprint {area} px, level {:.4}",
        2.0 * level
    );
    let mut iou = HashMap::new();
    for ((name, _), image) in METHODS.iter().zip(&images) {
        let got: Vec<bool> = image.iter().map(|p| p.y - WALL > level).collect();
        let both = got.iter().zip(&want).filter(|(a, b)| **a && **b).count();
        let either = got.iter().zip(&want).filter(|(a, b)| **a || **b).count();
        let i = both as f64 / either.max(1) as f64;
        let peak = image.iter().map(|p| p.y - WALL).fold(0.0, f32::max);
        // Against the thin lens's image itself: its plateau inside the footprint, the wall
        // outside (mean |Δ| over the footprint's bounding square, relative to the plateau).
        let plateau = 2.0 * level;
        let (mut d, mut n) = (0.0f64, 0usize);
        let center = project(LIGHT_AT);
        let reach = (0.5 * coc + 6.0) as i32;
        for y in center.y as i32 - reach..=center.y as i32 + reach {
            for x in center.x as i32 - reach..=center.x as i32 + reach {
                let k = (y as u32 * size().x + x as u32) as usize;
                let lens = if want[k] { plateau } else { 0.0 };
                d += f64::from(((image[k].y - WALL) - lens).abs() / plateau);
                n += 1;
            }
        }
        println!(
            "{name}: footprint IoU {i:.3} ({} px), mean |Δ| / plateau {:.3}, energy {:.2} \
             (in focus {:.2}), peak {peak:.3} (plateau {plateau:.3})",
            got.iter().filter(|&&b| b).count(),
            d / n as f64,
            energy(image),
            energy(&images[0]),
        );
        save(
            &format!("bokeh_shape_{}", name.replace([' ', '(', ')'], "_")),
            image,
        );
        iou.insert(*name, i);
    }
    let penumbra = iou["Penumbra scatter"];
    assert!(
        penumbra > 0.95,
        "Penumbra's bokeh has the lens's shape: {penumbra}"
    );
    assert!(
        penumbra > iou["Bevy Gaussian"] && penumbra > iou["Bevy bokeh"],
        "{iou:?}"
    );
}

/// Writes `image` (linear, Reinhard-mapped) as a PNG in the test output folder.
fn save(name: &str, image: &[Vec3]) {
    let dir = penumbra_test::output_dir();
    std::fs::create_dir_all(&dir).unwrap();
    let bytes: Vec<u8> = image
        .iter()
        .flat_map(|p| {
            let e = |c: f32| ((c / (1.0 + c)).powf(1.0 / 2.2) * 255.0) as u8;
            [e(p.x), e(p.y), e(p.z), 255]
        })
        .collect();
    penumbra_test::image::RgbaImage::from_raw(size().x, size().y, bytes)
        .unwrap()
        .save(dir.join(format!("{name}.png")))
        .unwrap();
}
