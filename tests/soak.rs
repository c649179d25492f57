//! Soak: the `samaritan` example's scene (every Penumbra feature on one deferred 4× MSAA
//! camera: DF shadows from a sun, a spot and a point light, DFAO with the global field,
//! skin, hair, billboard reflections, bokeh, tessellated cobbles, particles) rendered
//! headless for many frames under random churn, each frame: mesh casters spawned,
//! despawned and moved; the lights moved; DFAO's reach changed every 10 frames; and
//! every 6 frames one of the example's own toggles pressed (`1`–`6`: features on and off,
//! `M`: deferred MSAA). Checked: no panic, no wgpu validation error, Penumbra's GPU
//! allocations (`PenumbraGpuAllocations`) do not grow over the second half of the run,
//! and the process's resident memory grows by less than 1 % over it.
//!
//! `cargo test --test soak -- --ignored --nocapture` runs [`FRAMES`] frames
//! (`PENUMBRA_SOAK_FRAMES` overrides) and 10,000 (`soak_ten_thousand_frames`). Window
//! resizing is not churned (the headless target is an image).
//!
//! **Not in CI yet: it fails.** Measured (64×64, 100 frames, 4.1 s a frame on lavapipe
//! with two cores shared): resident memory 3,072 → 4,044 MiB (+31.7 %) over the second
//! half, and Penumbra created 32 textures, 60 bind groups and 7 buffers in frames 52–104
//! against 0, 4 and 3 in frames 26–52 — growth under churn to find (issue #47).

#[path = "../examples/samaritan.rs"]
#[allow(dead_code, reason = "the example's main is not used here")]
mod samaritan;

use bevy::input::InputSystems;
use bevy::prelude::*;
use penumbra::df::{GpuAllocationCounts, PenumbraGpuAllocations};
use penumbra::prelude::*;
use penumbra_test::{HeadlessRender, gpu_or_skip, take_render_errors};
use std::collections::HashMap;

/// Frames [`soak_every_feature_under_churn`] runs (`PENUMBRA_SOAK_FRAMES` overrides).
const FRAMES: u32 = 120;

/// The keys the churn presses: the example's feature toggles and MSAA.
const KEYS: [KeyCode; 7] = [
    KeyCode::Digit1,
    KeyCode::Digit2,
    KeyCode::Digit3,
    KeyCode::Digit4,
    KeyCode::Digit5,
    KeyCode::Digit6,
    KeyCode::KeyM,
];

/// The most churned casters alive at once.
const MAX_SPAWNED: usize = 12;

#[derive(Resource)]
struct Soak {
    rng: u64,
    frame: u32,
    spawned: Vec<Entity>,
    /// Where each light started (it wanders within 0.5 m of it).
    lights: HashMap<Entity, Vec3>,
    /// Per frame: resident bytes and Penumbra's GPU allocations so far.
    log: Vec<(u64, GpuAllocationCounts)>,
    mesh: Option<Handle<Mesh>>,
    material: Option<Handle<StandardMaterial>>,
}

impl Soak {
    fn new(seed: u64) -> Self {
        Self {
            rng: seed,
            frame: 0,
            spawned: Vec::new(),
            lights: HashMap::new(),
            log: Vec::new(),
            mesh: None,
            material: None,
        }
    }

    /// A uniform number in [0, 1) (a PCG-style LCG: deterministic).
    fn next(&mut self) -> f32 {
        self.rng = self
            .rng
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.rng >> 40) as f32 / (1u64 << 24) as f32
    }

    fn around(&mut self, center: Vec3, half: Vec3) -> Vec3 {
        center
            + half
                * Vec3::new(self.next(), self.next(), self.next())
                    .mul_add(Vec3::splat(2.0), Vec3::NEG_ONE)
    }
}

/// The point and spot lights (not casters).
type Lights = (
    Or<(With<PointLight>, With<SpotLight>)>,
    Without<DistanceFieldCaster>,
);

/// The mesh casters (not lights).
type Casters = (
    With<DistanceFieldCaster>,
    Without<PointLight>,
    Without<SpotLight>,
);

/// The process's resident set in bytes (Linux; 0 elsewhere).
fn resident_bytes() -> u64 {
    std::fs::read_to_string("/proc/self/statm")
        .ok()
        .and_then(|s| s.split_whitespace().nth(1)?.parse::<u64>().ok())
        .map_or(0, |pages| pages * 4096)
}

#[allow(clippy::too_many_arguments, reason = "one churn step")]
fn churn(
    mut commands: Commands,
    mut soak: ResMut<Soak>,
    mut keys: ResMut<ButtonInput<KeyCode>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut lights: Query<(Entity, &mut Transform), Lights>,
    mut casters: Query<&mut Transform, Casters>,
    mut ao: Query<&mut DistanceFieldAmbientOcclusion>,
    allocations: Res<PenumbraGpuAllocations>,
) {
    let soak = &mut *soak;
    soak.frame += 1;
    // The example's toggles: a key pressed every 6 frames, released the next.
    if soak.frame % 6 == 1 {
        keys.release_all();
    } else if soak.frame.is_multiple_of(6) {
        let key = KEYS[(soak.next() * KEYS.len() as f32) as usize % KEYS.len()];
        keys.press(key);
    }
    // Casters: spawn, despawn, move.
    let mesh = soak
        .mesh
        .get_or_insert_with(|| meshes.add(Cuboid::new(0.3, 0.5, 0.2)))
        .clone();
    let material = soak
        .material
        .get_or_insert_with(|| materials.add(Color::srgb(0.6, 0.5, 0.4)))
        .clone();
    if soak.spawned.len() < MAX_SPAWNED && soak.next() < 0.5 {
        let at = soak.around(Vec3::new(-0.5, 1.0, -1.5), Vec3::new(1.5, 0.8, 1.2));
        let entity = commands
            .spawn((
                Mesh3d(mesh),
                MeshMaterial3d(material),
                Transform::from_translation(at),
                DistanceFieldCaster::default(),
            ))
            .id();
        soak.spawned.push(entity);
    }
    if !soak.spawned.is_empty() && soak.next() < 0.4 {
        let i = (soak.next() * soak.spawned.len() as f32) as usize % soak.spawned.len();
        commands.entity(soak.spawned.swap_remove(i)).despawn();
    }
    for &entity in &soak.spawned.clone() {
        if let Ok(mut t) = casters.get_mut(entity) {
            let to = soak.around(Vec3::new(-0.5, 1.0, -1.5), Vec3::new(1.5, 0.8, 1.2));
            t.translation = t.translation.lerp(to, 0.1);
            t.rotate_y(0.05);
        }
    }
    // Lights wander within 0.5 m of where they started.
    for (entity, mut t) in &mut lights {
        let home = *soak.lights.entry(entity).or_insert(t.translation);
        t.translation = soak.around(home, Vec3::splat(0.5));
    }
    // DFAO's reach.
    if soak.frame.is_multiple_of(10) {
        let reach = 0.5 + 2.5 * soak.next();
        for mut settings in &mut ao {
            settings.max_occlusion_distance = reach;
        }
    }
    soak.log.push((resident_bytes(), allocations.counts()));
}

/// Runs the soak for `frames` frames; returns the per-frame log.
fn soak(frames: u32) -> Vec<(u64, GpuAllocationCounts)> {
    let render = HeadlessRender::new(64, 64)
        .frames(frames)
        .warm_up(samaritan::casters_ready);
    let mut app = render.app();
    samaritan::add_scene(&mut app);
    app.insert_resource(Soak::new(0x5eed))
        .add_systems(PreUpdate, churn.after(InputSystems));
    let (capture, app) = render.run_keeping_app(app).expect("renders");
    let errors = take_render_errors();
    assert!(errors.is_empty(), "wgpu errors: {errors:#?}");
    let log = app.world().resource::<Soak>().log.clone();
    let mean_ms = capture
        .frame_times
        .iter()
        .map(|d| d.as_secs_f64() * 1e3)
        .sum::<f64>()
        / capture.frame_times.len().max(1) as f64;
    println!(
        "{} frames logged, mean frame time {mean_ms:.1} ms",
        log.len()
    );
    log
}

/// Over the second half of the run: Penumbra created no GPU resource it did not create
/// in the first (its allocations flat), and resident memory grew by less than 1 %.
fn check(log: &[(u64, GpuAllocationCounts)]) {
    let n = log.len();
    assert!(n >= 80, "{n} frames logged");
    let (first, half, last) = (log[n / 4], log[n / 2], log[n - 1]);
    let early = half.1 - first.1;
    let late = last.1 - half.1;
    // Resident memory: the median of 20 frames at each end of the second half.
    let median = |s: &[(u64, GpuAllocationCounts)]| {
        let mut v: Vec<u64> = s.iter().map(|e| e.0).collect();
        v.sort_unstable();
        v[v.len() / 2]
    };
    let (rss_half, rss_last) = (median(&log[n / 2..n / 2 + 20]), median(&log[n - 20..]));
    let growth = rss_last as f64 / rss_half.max(1) as f64 - 1.0;
    println!(
        "GPU allocations: frames {}..{}: {early:?}; frames {}..{}: {late:?}; since start \
         {:?}; resident memory {:.1} → {:.1} MiB ({:+.2} %)",
        n / 4,
        n / 2,
        n / 2,
        n,
        last.1,
        rss_half as f64 / 1048576.0,
        rss_last as f64 / 1048576.0,
        growth * 100.0
    );
    assert!(
        growth < 0.01,
        "resident memory grew {:.2} %",
        growth * 100.0
    );
    assert!(
        late.buffers <= early.buffers && late.textures <= early.textures,
        "GPU allocations grow: {early:?} then {late:?}"
    );
}

#[test]
#[ignore = "fails today (#47): resident memory grows under churn; about 4 s a frame here"]
fn soak_every_feature_under_churn() {
    if !gpu_or_skip("soak_every_feature_under_churn") {
        return;
    }
    let frames = std::env::var("PENUMBRA_SOAK_FRAMES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(FRAMES);
    check(&soak(frames));
}

#[test]
#[ignore = "10,000 frames: run by hand"]
fn soak_ten_thousand_frames() {
    if !gpu_or_skip("soak_ten_thousand_frames") {
        return;
    }
    check(&soak(10_000));
}
