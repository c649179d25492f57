//! Distance-field ambient occlusion: run time against error.
//!
//! Three scenes, every pixel of a 96×96 view: a Cornell box (2 m; its two boxes baked to
//! SDFs, the walls analytic boxes); the Stanford bunny (scaled to ≈ 1 m, baked) on an
//! analytic ground plane; and the scene of Bevy's depth-of-field example
//! (`../shared/scenes/DepthOfFieldExample.glb`, read through `penumbra_sdf`'s glTF input:
//! a 6.5 m circuit board with eleven spheres and four cubes, each part baked on its own;
//! the board, a single quad with no inside, becomes a 1 cm analytic box under its surface
//! in the model and the truth alike). SDFs are baked with the plugin's default grid (32
//! samples per metre). Each pixel's AO and bent normal come from the trace pass's CPU
//! model (`penumbra_reference::dfao::trace_view`: 8×8 tiles, two depth ranges; at a
//! divisor above 1 one pixel in `divisor²` is traced and `dfao::upsample` fills in the
//! rest with depth and normal weights) and are compared with Monte Carlo ground truth on
//! the triangles (`dfao::monte_carlo_ao`: 48 × 48 stratified cosine-weighted rays,
//! limited to the same max distance). The G-buffer normals are the triangles' own
//! (facing the camera), through the G-buffer's 24-bit encoding.
//!
//! The max occlusion distance is per scene, about half the extent of the geometry that
//! occludes (the component's default, 10 m, puts each of these scenes wholly in reach):
//! 1 m in the 2 m Cornell box, 0.5 m around the 1 m bunny, 1.5 m on the board (its
//! objects are at most 1 m across and about 1.5 m apart; half the board, 3.2 m, would
//! make every pixel of it see most of them).
//! Swept: cone count × steps per cone × trace divisor; and, around the defaults (9 cones,
//! 8 steps, divisor 4, bias 0.02 m, shaping `CONE_SHAPING`), the shaping exponent (at
//! every cone count) and the bias (at every cone count, with 8 and 16 steps).
//!
//! Error: mean |AO − truth| over every surface pixel (and its sign: mean AO − truth), and
//! over those the truth occludes (AO < 0.99); the bent normal's mean angle to the
//! truth's, radians (same two sets).
//! Cost: distance evaluations per view pixel (the marches' work, without the tile tests'
//! one sample per object and range; deterministic: the Pareto front is taken on it
//! against both errors over all surface pixels, mean |ΔAO| and the bent normal's mean
//! angle, among the configurations a user can set — the shaping rows, which choose a
//! constant, are left off it) and
//! the model's time over the view (trace and upsample), one thread, median of 3
//! (criterion times the defaults). Then the shaping sweep once more at the component's
//! default max distance, 10 m, against truth traced to 10 m: the best shaping depends on
//! how much of the scene is in reach. Writes `target/penumbra_bench/dfao.{md,csv}`.
//!
//! Contact error: the same over the pixels the truth occludes by a quarter or more (AO
//! < 0.75: corners, under and beside casters), where fewer cones or a coarser trace
//! lose detail that the mean over mostly open pixels hides.
//!
//! Every image of the sweep is one frame of the trace's jitter ([`ao_image`]'s `frame`,
//! 0): the temporal filter off. The temporal table runs the filter's CPU model
//! (`dfao::temporal_step`, both steps) over frames `0..N` of a still camera, N = 1, 4,
//! 8, for 9 and 16 cones at divisors 2 and 4, and scores the filtered image against the
//! same truth.
//!
//! `cargo bench -p penumbra_reference --bench dfao` (needs `../shared/meshes` and
//! `../shared/scenes`; a scene whose file is missing is skipped, with a message).

#![allow(missing_docs, reason = "criterion_group! generates undocumented items")]

#[path = "dfao/report.rs"]
mod report;
#[path = "dfao/scenes.rs"]
mod scenes;
#[path = "support/mod.rs"]
mod support;

use criterion::{Criterion, criterion_group};
use glam::{UVec2, Vec2, Vec3, Vec4};
use penumbra_df_core::ao::{AoTrace, CONE_SHAPING, jitter, trace_size};
use penumbra_df_core::cull::CameraOrigin;
use penumbra_reference::dfao::{
    AoView, TemporalFrame, TemporalSteps, temporal_step, trace_view_counted, upsample,
};
use penumbra_reference::shadow_mask::position_from_depth;
use report::{around_defaults, at_ten_metres, combined, tables};
use scenes::{Scene, bunny, cornell, depth_of_field};
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

const SIZE: u32 = 96;
/// Ground truth: `MC²` rays per pixel.
const MC: u32 = 48;
const CONES: [u32; 5] = [4, 6, 9, 12, 16];
const STEPS: [u32; 5] = [8, 12, 16, 24, 32];
const DIVISORS: [u32; 3] = [1, 2, 4];
/// Shaping costs nothing, so the default must be the best one at its work: swept at
/// every cone count (the others at the defaults).
const SHAPINGS: [f32; 9] = [1.0, 0.5, 0.4, 0.33, 0.3, 0.25, 0.2, 0.15, 0.1];
const BIASES: [f32; 5] = [0.005, 0.01, 0.02, 0.04, 0.08];
/// Steps per cone at which the bias is swept (at every cone count, the default divisor).
const BIAS_STEPS: [u32; 2] = [8, 16];
/// A flat glTF part becomes a box this thick under its surface.
const SLAB: f32 = 0.01;

/// [`Config`]'s settings, by name.
/// Truth below this marks a contact pixel ([`Errors::ao_contact`]).
const CONTACT: f32 = 0.75;
/// Frames of the temporal filter's sweep (a still camera: the filter averages the
/// trace's four jitter positions).
const TEMPORAL_FRAMES: [u32; 3] = [1, 4, 8];
/// (cones, divisor) of the temporal sweep, the other settings the defaults'.
const TEMPORAL_CONFIGS: [(u32, u32); 4] = [(9, 2), (9, 4), (16, 2), (16, 4)];

const FIELDS: [&str; 5] = ["cones", "steps", "divisor", "shaping", "bias"];

/// One configuration of the sweep.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Config {
    cones: u32,
    steps: u32,
    /// Trace resolution divisor (1: every pixel; more: upsampled).
    divisor: u32,
    shaping: f32,
    bias: f32,
}

impl Config {
    /// `DistanceFieldAmbientOcclusion::default()`.
    const DEFAULT: Config = Config {
        cones: 9,
        steps: 8,
        divisor: 4,
        shaping: CONE_SHAPING,
        bias: 0.02,
    };

    fn trace(&self, max_distance: f32) -> AoTrace {
        AoTrace {
            max_distance,
            cone_count: self.cones,
            steps_per_cone: self.steps,
            bias: self.bias,
            shaping: self.shaping,
        }
    }

    /// The settings in the order of [`FIELDS`].
    fn fields(&self) -> [f32; 5] {
        [
            self.cones as f32,
            self.steps as f32,
            self.divisor as f32,
            self.shaping,
            self.bias,
        ]
    }

    /// The defaults with `change` made.
    fn around(change: impl FnOnce(&mut Config)) -> Config {
        let mut c = Config::DEFAULT;
        change(&mut c);
        c
    }

    fn label(&self) -> String {
        format!(
            "{} cones, {} steps, divisor {}, shaping {}, bias {}",
            self.cones, self.steps, self.divisor, self.shaping, self.bias
        )
    }
}

/// The view's AO and bent normal per pixel (`(ao, bent)`, full resolution) by the model
/// for jitter frame `frame`: traced at `divisor`, upsampled when above 1; and the
/// marches' distance evaluations.
fn ao_image(scene: &Scene, c: Config, frame: u32) -> (Vec<Vec4>, u64) {
    let eye = scene.camera.world_from_view.w_axis.truncate();
    let camera = CameraOrigin::at(eye).expect("finite");
    let full = UVec2::splat(SIZE);
    let view = AoView {
        view_from_clip: scene.view_from_clip,
        world_from_view: scene.world_from_view,
        size: full,
        depth: &scene.depth,
        normals: &scene.normals,
    };
    let shift = jitter(frame, c.divisor);
    let (traced, evaluations) = trace_view_counted(
        &scene.records,
        &scene.atlas,
        &camera,
        &view,
        c.divisor,
        shift,
        &c.trace(scene.max_distance),
    );
    if c.divisor <= 1 {
        return (traced, evaluations);
    }
    let image = upsample(
        &traced,
        trace_size(full, c.divisor),
        c.divisor,
        shift,
        &scene.distance,
        &scene.normals,
        full,
    );
    (image, evaluations)
}

/// Mean errors against the truth.
#[derive(Clone, Copy, Debug, Default)]
struct Errors {
    /// Mean |AO − truth| over all surface pixels.
    ao: f32,
    /// Mean AO − truth over all surface pixels (> 0: the model occludes too little).
    signed: f32,
    /// … over the pixels the truth occludes (AO < 0.99).
    ao_occluded: f32,
    /// … over the contact pixels, which the truth occludes by a quarter or more
    /// (AO < 0.75: corners, under and beside casters — where detail shows).
    ao_contact: f32,
    /// Mean angle between the bent normals, radians, over all surface pixels.
    bent: f32,
    /// … over the pixels the truth occludes.
    bent_occluded: f32,
    surface: usize,
    occluded: usize,
    contact: usize,
}

fn errors(scene: &Scene, image: &[Vec4]) -> Errors {
    let mut e = Errors::default();
    for (v, t) in image.iter().zip(&scene.truth) {
        let Some(t) = t else { continue };
        let ao = (v.x - t.ao).abs();
        let bent = Vec3::new(v.y, v.z, v.w).angle_between(t.bent_normal);
        e.ao += ao;
        e.signed += v.x - t.ao;
        e.bent += bent;
        e.surface += 1;
        if t.ao < 0.99 {
            e.ao_occluded += ao;
            e.bent_occluded += bent;
            e.occluded += 1;
        }
        if t.ao < CONTACT {
            e.ao_contact += ao;
            e.contact += 1;
        }
    }
    let (all, occluded) = (e.surface.max(1) as f32, e.occluded.max(1) as f32);
    Errors {
        ao: e.ao / all,
        signed: e.signed / all,
        ao_occluded: e.ao_occluded / occluded,
        ao_contact: e.ao_contact / e.contact.max(1) as f32,
        bent: e.bent / all,
        bent_occluded: e.bent_occluded / occluded,
        ..e
    }
}

struct Row {
    scene: String,
    config: Config,
    /// Distance evaluations per view pixel (the work; deterministic).
    evaluations: f64,
    seconds: f64,
    errors: Errors,
    pareto: bool,
}

/// The configurations: cones × steps × divisor, then shapings (at every cone count) and
/// biases (at every cone count and [`BIAS_STEPS`]) around the defaults.
fn configs() -> Vec<Config> {
    let mut out = Vec::new();
    for &cones in &CONES {
        for &steps in &STEPS {
            for &divisor in &DIVISORS {
                out.push(Config::around(|c| {
                    (c.cones, c.steps, c.divisor) = (cones, steps, divisor);
                }));
            }
        }
    }
    for &cones in &CONES {
        for &shaping in SHAPINGS.iter().filter(|&&s| s != Config::DEFAULT.shaping) {
            out.push(Config::around(|c| (c.cones, c.shaping) = (cones, shaping)));
        }
    }
    for &cones in &CONES {
        for steps in BIAS_STEPS {
            for &bias in BIASES.iter().filter(|&&b| b != Config::DEFAULT.bias) {
                out.push(Config::around(|c| {
                    (c.cones, c.steps, c.bias) = (cones, steps, bias);
                }));
            }
        }
    }
    out
}

/// What the Pareto front weighs, each the lower the better: the work (distance
/// evaluations per pixel), the mean |ΔAO| and the bent normal's mean angle (both over
/// all surface pixels) — the two errors against work.
fn costs(work: f64, e: &Errors) -> [f64; 3] {
    [work, f64::from(e.ao), f64::from(e.bent)]
}

/// `a` dominates `b`: no worse in any cost and better in one.
fn dominates(a: [f64; 3], b: [f64; 3]) -> bool {
    a.iter().zip(&b).all(|(x, y)| x <= y) && a.iter().zip(&b).any(|(x, y)| x < y)
}

/// A configuration a user can choose: the shaping rows sweep a constant
/// (`CONE_SHAPING`), not a setting, so they are reported but not on the front.
fn settable(c: &Config) -> bool {
    c.shaping == CONE_SHAPING
}

/// Which of `points` (configuration, costs) are on the Pareto front of the settable ones.
fn front(points: &[(Config, [f64; 3])]) -> Vec<bool> {
    points
        .iter()
        .map(|&(c, p)| settable(&c) && !points.iter().any(|(o, q)| settable(o) && dominates(*q, p)))
        .collect()
}

fn sweep(scene: &Scene) -> Vec<Row> {
    let mut rows: Vec<Row> = configs()
        .into_iter()
        .map(|config| {
            let mut times = Vec::new();
            let (mut image, mut evaluations) = (Vec::new(), 0);
            for _ in 0..3 {
                let start = Instant::now();
                (image, evaluations) = ao_image(scene, config, 0);
                times.push(start.elapsed().as_secs_f64());
            }
            times.sort_by(f64::total_cmp);
            Row {
                scene: scene.name.clone(),
                config,
                evaluations: evaluations as f64 / (SIZE * SIZE) as f64,
                seconds: times[1],
                errors: errors(scene, &image),
                pareto: false,
            }
        })
        .collect();
    let points: Vec<(Config, [f64; 3])> = rows
        .iter()
        .map(|r| (r.config, costs(r.evaluations, &r.errors)))
        .collect();
    for (r, f) in rows.iter_mut().zip(front(&points)) {
        r.pareto = f;
    }
    rows
}

/// The temporal filter's output after `frames` frames of a still camera (frame `k`
/// traced at jitter position `k`), with both of its steps; and the marches' distance
/// evaluations per frame. One frame is [`ao_image`]'s.
fn temporal_image(scene: &Scene, c: Config, frames: u32) -> (Vec<Vec4>, u64) {
    let full = UVec2::splat(SIZE);
    let positions: Vec<Vec3> = (0..SIZE * SIZE)
        .map(|i| {
            let d = scene.depth[i as usize];
            if d <= 0.0 {
                return Vec3::NAN;
            }
            let px = Vec2::new((i % SIZE) as f32, (i / SIZE) as f32);
            position_from_depth(
                scene.view_from_clip,
                scene.world_from_view,
                full.as_vec2(),
                px,
                d,
            )
        })
        .collect();
    let motion = vec![Vec2::ZERO; positions.len()];
    let (mut history, mut evaluations) = (None, 0);
    if frames <= 1 {
        // The filter off: the trace's first jitter position alone.
        return ao_image(scene, c, 0);
    }
    for frame in 0..frames {
        let (image, e) = ao_image(scene, c, frame);
        evaluations += e;
        let step = TemporalFrame {
            size: full,
            current: &image,
            positions: &positions,
            normals: &scene.normals,
            motion: &motion,
            previous_offset: Vec3::ZERO,
        };
        history = Some(temporal_step(&step, history.as_ref(), TemporalSteps::ALL));
    }
    let filtered = history.map_or_else(Vec::new, |h| h.filtered);
    (filtered, evaluations / u64::from(frames))
}

/// The temporal filter on or off (1 frame) after N frames, per scene: the error of
/// [`TEMPORAL_CONFIGS`] against the same truth; appended to `md`.
fn temporal_table(scenes: &[Scene], md: &mut String) {
    let _ = writeln!(
        md,
        "\n## Temporal filter, still camera\n\nFrames 1 = filter off (one jitter \
         position, upsampled). Work per frame.\n\n| scene | cones | divisor | frames | \
         distance evaluations / pixel / frame | mean \\|ΔAO\\| | mean \\|ΔAO\\|, contact \
         | mean AO − truth | bent normal (rad) |\n|---|---|---|---|---|---|---|---|---|"
    );
    for scene in scenes {
        for (cones, divisor) in TEMPORAL_CONFIGS {
            let config = Config::around(|c| (c.cones, c.divisor) = (cones, divisor));
            for frames in TEMPORAL_FRAMES {
                let (image, evaluations) = temporal_image(scene, config, frames);
                let e = errors(scene, &image);
                let _ = writeln!(
                    md,
                    "| {} | {cones} | {divisor} | {frames} | {:.2} | {:.4} | {:.4} | {:+.4} | \
                     {:.4} |",
                    scene.name,
                    evaluations as f64 / f64::from(SIZE * SIZE),
                    e.ao,
                    e.ao_contact,
                    e.signed,
                    e.bent
                );
            }
        }
    }
}

fn bench(c: &mut Criterion) {
    let start = Instant::now();
    let builders: [fn(f32) -> Option<Scene>; 3] = [|m| Some(cornell(m)), bunny, depth_of_field];
    // About half the extent of each scene's occluding geometry (see the module's doc).
    let scenes: Vec<Scene> = builders
        .iter()
        .zip([1.0, 0.5, 1.5])
        .filter_map(|(build, max_distance)| build(max_distance))
        .collect();
    let mut rows = Vec::new();
    for scene in &scenes {
        let t = Instant::now();
        rows.extend(sweep(scene));
        println!(
            "{}: swept in {:.0} s",
            scene.name,
            t.elapsed().as_secs_f64()
        );
    }
    let names: Vec<String> = scenes.iter().map(|s| s.name.clone()).collect();
    let mut md = format!(
        "# DFAO: run time against error\n\n`cargo bench -p penumbra_reference --bench dfao`: \
         {SIZE}×{SIZE} views, truth {MC}×{MC} cosine-weighted rays per pixel; max occlusion \
         distance in the scene's name.\n\n"
    );
    let csv = tables(&rows, &mut md);
    combined(&rows, scenes.len(), &mut md);
    around_defaults(&rows, &names, &mut md);
    temporal_table(&scenes, &mut md);
    at_ten_metres(&builders, &mut md);
    let _ = writeln!(
        md,
        "\nScenes, truth and sweep: {:.0} s.",
        start.elapsed().as_secs_f64()
    );
    println!("{md}");
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/penumbra_bench");
    if std::fs::create_dir_all(&dir).is_ok() {
        let _ = std::fs::write(dir.join("dfao.md"), &md);
        let _ = std::fs::write(dir.join("dfao.csv"), &csv);
        println!("wrote {}", dir.join("dfao.{md,csv}").display());
    }
    for scene in &scenes {
        c.bench_function(&format!("dfao/{}/defaults", scene.name), |b| {
            b.iter(|| ao_image(scene, Config::DEFAULT, 0));
        });
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}

fn main() {
    benches();
    Criterion::default().final_summary();
}
