//! Hair strips' coverage methods on lavapipe against a 16× supersampled alpha test (the
//! CPU's `supersampled_coverage`: the strip's atlas alpha tested against ½ at a 4 × 4
//! grid of each pixel), on strands of eight kinds (angles, widths 0.6–3 px, the atlas's
//! alpha falling off across the hair), each drawn at sixteen sub-pixel offsets — a slow
//! sweep of 0.0625 px steps laid out side by side.
//!
//! - Error: per pixel that either image covers, |resolved GPU coverage − truth|, mean and
//!   99th percentile, for the per-sample test, shading per sample, alpha-to-coverage and
//!   one test per pixel.
//! - Shimmer: each kind's total coverage over the sweep's offsets, its standard deviation
//!   over its mean (a strand that flickers as it moves scores high).
//! - Cost (`#[ignore]`d, `hair_cost_against_time`): lavapipe frame times at 512² with 16,000
//!   and 160,000 hair triangles, per method (measured: 450 / 4,469 ms per sample, 1,568 /
//!   15,462 shading per sample, 418 / 4,108 alpha-to-coverage, 421 / 4,098 per pixel,
//!   over an empty frame's 11 ms).

mod hair_scene;
use hair_scene::*;

use bevy::prelude::*;
use bevy_penumbra_cinematic::hair::{Hair, HairCoverage, HairPlugin, HairStrands, Strand};
use penumbra_cinematic_core::hair::{ScreenSegment, supersampled_coverage};
use penumbra_test::{CaptureFormat, HeadlessRender, gpu_or_skip};

const WIDTH: u32 = 256;
const HEIGHT: u32 = 128;
const CELL: i32 = 16;
const KINDS: i32 = 8;
const OFFSETS: i32 = 16;

/// Kind `k`'s strand at sweep step `j`, in pixels (y down), and its width.
fn sweep_segment(k: i32, j: i32) -> (Vec2, Vec2, f32) {
    let cell = Vec2::new((j * CELL) as f32, (k * CELL) as f32);
    let angle = 0.17 + k as f32 * 0.39;
    let widths = [0.6, 0.8, 1.0, 1.3, 1.7, 2.2, 2.6, 3.0];
    let d = Vec2::new(angle.cos(), angle.sin()) * 5.0;
    // The sweep moves the strand across itself.
    let across = Vec2::new(-angle.sin(), angle.cos());
    let centre = cell + Vec2::splat(8.0) + across * (j as f32 / OFFSETS as f32) + 0.29;
    (centre - d, centre + d, widths[k as usize])
}

#[derive(Resource, Clone, Copy)]
struct Mode(HairCoverage);

fn sweep_scene(
    mut commands: Commands,
    mut images: ResMut<Assets<Image>>,
    mut strand_assets: ResMut<Assets<HairStrands>>,
    mode: Res<Mode>,
) {
    let mut strands = Vec::new();
    for k in 0..KINDS {
        for j in 0..OFFSETS {
            let (a, b, w) = sweep_segment(k, j);
            strands.push(pixel_strand(a, b, w, HEIGHT));
        }
    }
    commands.spawn(Hair {
        strands: strand_assets.add(HairStrands::new(strands)),
        atlas: Some(images.add(atlas_image())),
        debug_coverage: true,
        coverage: mode.0,
        ..default()
    });
    commands.spawn(pixel_camera(WIDTH, HEIGHT));
}

fn render(mode: HairCoverage) -> Vec<[f32; 4]> {
    let harness = HeadlessRender::new(WIDTH, HEIGHT)
        .format(CaptureFormat::LinearF16)
        .frames(3);
    let mut app = harness.app();
    app.add_plugins(HairPlugin)
        .insert_resource(Mode(mode))
        .add_systems(Startup, sweep_scene);
    harness.run(app).expect("renders").to_linear()
}

#[test]
fn per_sample_coverage_is_closest_to_supersampling_and_shimmers_least() {
    if !gpu_or_skip("per_sample_coverage_is_closest_to_supersampling_and_shimmers_least") {
        return;
    }
    // The truth, pixel by pixel.
    let mut truth = vec![0.0f32; (WIDTH * HEIGHT) as usize];
    for k in 0..KINDS {
        for j in 0..OFFSETS {
            let (a, b, w) = sweep_segment(k, j);
            let segment = ScreenSegment {
                a,
                b,
                half_width: w / 2.0,
            };
            for y in k * CELL..(k + 1) * CELL {
                for x in j * CELL..(j + 1) * CELL {
                    truth[(y * WIDTH as i32 + x) as usize] =
                        supersampled_coverage(&segment, IVec2::new(x, y), 4, 0.5, atlas_sample);
                }
            }
        }
    }
    let shimmer = |image: &[f32]| {
        let mut sum = 0.0;
        for k in 0..KINDS {
            let totals: Vec<f32> = (0..OFFSETS)
                .map(|j| {
                    let mut t = 0.0;
                    for y in k * CELL..(k + 1) * CELL {
                        for x in j * CELL..(j + 1) * CELL {
                            t += image[(y * WIDTH as i32 + x) as usize];
                        }
                    }
                    t
                })
                .collect();
            let mean = totals.iter().sum::<f32>() / OFFSETS as f32;
            let var = totals.iter().map(|t| (t - mean).powi(2)).sum::<f32>() / OFFSETS as f32;
            sum += var.sqrt() / mean;
        }
        sum / KINDS as f32
    };
    println!("16× supersampled truth: shimmer {:.4}", shimmer(&truth));
    let mut results = Vec::new();
    for (name, mode) in [
        ("per-sample", HairCoverage::PerSample),
        ("sample shading", HairCoverage::SampleShading),
        ("alpha-to-coverage", HairCoverage::AlphaToCoverage),
        ("per-pixel", HairCoverage::PerPixel),
    ] {
        let gpu: Vec<f32> = render(mode).iter().map(|p| p[0]).collect();
        save_coverage(
            &format!("hair_modes_{}", name.replace(' ', "_")),
            &render_rgba(&gpu),
            WIDTH,
            HEIGHT,
        );
        let mut errors: Vec<f32> = gpu
            .iter()
            .zip(&truth)
            .filter(|(g, t)| **g > 0.0 || **t > 0.0)
            .map(|(g, t)| (g - t).abs())
            .collect();
        errors.sort_by(f32::total_cmp);
        let mean = errors.iter().sum::<f32>() / errors.len() as f32;
        let p99 = errors[errors.len() * 99 / 100];
        let s = shimmer(&gpu);
        println!(
            "{name}: |coverage − 16× truth| mean {mean:.4}, p99 {p99:.3} over {} pixels; shimmer {s:.4}",
            errors.len()
        );
        results.push((name, mean, p99, s));
    }
    let [per_sample, sample_shading, a2c, per_pixel] = results[..] else {
        unreachable!()
    };
    // Shading per sample tests the same alpha at the same samples.
    assert!(
        (per_sample.1 - sample_shading.1).abs() < 0.01,
        "{per_sample:?} vs {sample_shading:?}"
    );
    // The per-sample test is the closest to supersampling, by a margin (measured: mean
    // 0.064, p99 0.25, shimmer 0.021; alpha-to-coverage 0.099, 0.44, 0.035; per pixel
    // 0.140, 0.50, 0.061; the truth's shimmer 0.007).
    assert!(per_sample.1 < 0.08, "{per_sample:?}");
    assert!(per_sample.1 * 1.3 < a2c.1, "{per_sample:?} vs {a2c:?}");
    assert!(
        per_sample.1 * 1.8 < per_pixel.1,
        "{per_sample:?} vs {per_pixel:?}"
    );
    assert!(per_sample.2 < a2c.2 && per_sample.2 < per_pixel.2, "p99");
    assert!(
        per_sample.3 < 0.8 * a2c.3 && per_sample.3 < 0.5 * per_pixel.3,
        "shimmer {per_sample:?} vs {a2c:?}, {per_pixel:?}"
    );
}

fn render_rgba(coverage: &[f32]) -> Vec<[f32; 4]> {
    coverage.iter().map(|c| [*c, *c, *c, 1.0]).collect()
}

#[derive(Resource, Clone, Copy)]
struct CostSetup {
    strands: u32,
    mode: Option<HairCoverage>,
}

/// `strands` strands of 4 segments (8 triangles) around the origin, 0.12 m long, 0.3 mm
/// wide, seen by a perspective camera 0.5 m away (a head's hair at 512²).
fn cost_scene(
    mut commands: Commands,
    mut strand_assets: ResMut<Assets<HairStrands>>,
    setup: Res<CostSetup>,
) {
    let hash = |i: u32, s: u32| {
        let mut h = i.wrapping_mul(0x9e37_79b9) ^ s.wrapping_mul(0x85eb_ca6b);
        h ^= h >> 15;
        h = h.wrapping_mul(0x2c1b_3c6d);
        h ^= h >> 12;
        (h >> 8) as f32 / (1u32 << 24) as f32
    };
    if let Some(mode) = setup.mode {
        let strands: Vec<Strand> = (0..setup.strands)
            .map(|i| {
                let root = Vec3::new(hash(i, 1) - 0.5, hash(i, 2) - 0.5, hash(i, 3) - 0.5) * 0.2;
                let dir = Vec3::new(hash(i, 4) - 0.5, -1.0, hash(i, 5) - 0.5).normalize();
                Strand {
                    points: (0..5).map(|k| root + dir * 0.03 * k as f32).collect(),
                    width: 0.0003,
                    slot: 0,
                }
            })
            .collect();
        commands.spawn(Hair {
            strands: strand_assets.add(HairStrands::new(strands)),
            coverage: mode,
            ..default()
        });
    }
    commands.spawn((
        DirectionalLight::default(),
        Transform::default().looking_to(Vec3::new(-0.3, -0.8, -0.5), Vec3::Y),
    ));
    commands.spawn((
        Camera3d::default(),
        Msaa::Sample4,
        Transform::from_xyz(0.0, 0.0, 0.5).looking_at(Vec3::ZERO, Vec3::Y),
    ));
}

#[test]
#[ignore = "a measurement: lavapipe frame times, ~16 minutes"]
fn hair_cost_against_time() {
    if !gpu_or_skip("hair_cost_against_time") {
        return;
    }
    let time = |strands: u32, mode: Option<HairCoverage>| {
        let mut medians = Vec::new();
        for _ in 0..3 {
            let harness = HeadlessRender::new(512, 512).frames(8);
            let mut app = harness.app();
            app.add_plugins(HairPlugin)
                .insert_resource(CostSetup { strands, mode })
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
    let base = time(0, None);
    println!("no hair: {base:.1} ms per frame (512², 4× MSAA, lavapipe)");
    for strands in [2_000, 20_000] {
        for (name, mode) in [
            ("per-sample", HairCoverage::PerSample),
            ("sample shading", HairCoverage::SampleShading),
            ("alpha-to-coverage", HairCoverage::AlphaToCoverage),
            ("per-pixel", HairCoverage::PerPixel),
        ] {
            let t = time(strands, Some(mode));
            println!(
                "{} triangles, {name}: {t:.1} ms per frame, {:.1} ms over no hair",
                strands * 8,
                t - base
            );
        }
    }
}
