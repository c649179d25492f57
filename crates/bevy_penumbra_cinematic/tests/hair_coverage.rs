//! Hair strips' coverage on lavapipe against the CPU model
//! (`penumbra_cinematic_core::hair`), under 4× MSAA with an orthographic camera of one
//! world unit per pixel: straight strands of known width, angle and sub-pixel offset,
//! one per 16 × 16 cell, drawn white (`Hair::debug_coverage`), so a pixel's resolved
//! value is its covered samples' share.
//!
//! - Contract: with an atlas whose alpha falls off across the hair, every pixel's count
//!   of covered samples equals the model's (`coverage_mask`: the strip's rectangle, the
//!   atlas's bilinear alpha tested against ½ at the standard 4× positions, the width fade
//!   against the per-pixel permuted thresholds). The same model with the alpha tested at
//!   other positions (the pattern mirrored) disagrees on many samples: a shader whose
//!   sample positions are wrong fails.
//! - Against the truth: without an atlas, each strand's summed coverage over its cell
//!   divided by its length is its width (the exact area is width × length).

mod hair_scene;
use hair_scene::*;

use bevy::prelude::*;
use bevy_penumbra_cinematic::hair::{Hair, HairPlugin, HairStrands, Strand};
use penumbra_cinematic_core::hair::{
    ALPHA_CUTOFF, SAMPLE_POSITIONS_4X, ScreenSegment, clamp_width, sample_thresholds, strip_uv,
};
use penumbra_test::{CaptureFormat, HeadlessRender, gpu_or_skip};

const WIDTH: u32 = 128;
const HEIGHT: u32 = 64;
const CELL: i32 = 16;

/// The strands of cell `k` of a half: a segment through the cell's centre (plus a
/// sub-pixel offset), at an angle and width that vary over the cells. Pixel coordinates
/// (y down) and the width in pixels.
fn cell_segment(k: i32, x0: i32) -> (Vec2, Vec2, f32) {
    let (cx, cy) = (k % 4, k / 4);
    let centre = Vec2::new(
        (x0 + cx * CELL) as f32 + 8.0 + 0.37 * k as f32 % 1.0,
        (cy * CELL) as f32 + 8.0 + 0.61 * k as f32 % 1.0,
    );
    let angle = 0.23 + k as f32 * 0.41;
    let widths = [0.15, 0.3, 0.45, 0.7, 1.0, 1.4, 2.1, 3.3];
    let d = Vec2::new(angle.cos(), angle.sin()) * 5.0;
    (centre - d, centre + d, widths[k as usize % widths.len()])
}

fn strands(x0: i32) -> Vec<Strand> {
    (0..16)
        .map(|k| {
            let (a, b, w) = cell_segment(k, x0);
            pixel_strand(a, b, w, HEIGHT)
        })
        .collect()
}

fn scene(
    mut commands: Commands,
    mut images: ResMut<Assets<Image>>,
    mut strand_assets: ResMut<Assets<HairStrands>>,
) {
    commands.spawn(Hair {
        strands: strand_assets.add(HairStrands::new(strands(0))),
        atlas: Some(images.add(atlas_image())),
        debug_coverage: true,
        ..default()
    });
    commands.spawn(Hair {
        strands: strand_assets.add(HairStrands::new(strands(64))),
        debug_coverage: true,
        ..default()
    });
    commands.spawn(pixel_camera(WIDTH, HEIGHT));
}

/// The model's count of covered samples at `pixel`, the alpha tested at `positions`
/// (the geometry always at the standard ones: the rasterizer's).
fn model_count(
    segment: &ScreenSegment,
    fade: f32,
    atlas: bool,
    pixel: IVec2,
    positions: [Vec2; 4],
) -> u32 {
    let thresholds = sample_thresholds(pixel);
    let alpha = |uv: Vec2| if atlas { atlas_sample(uv) } else { 1.0 };
    (0..4)
        .filter(|&i| {
            let inside = strip_uv(segment, pixel.as_vec2() + SAMPLE_POSITIONS_4X[i]).is_some();
            // The shader extrapolates the coordinates to the sample: affine, so the
            // (unclamped) strip coordinates at the position, valid outside the strip.
            let p = pixel.as_vec2() + positions[i];
            let ab = segment.b - segment.a;
            let d = ab / ab.length();
            let n = Vec2::new(-d.y, d.x);
            let q = p - segment.a;
            let uv = Vec2::new(
                q.dot(d) / ab.length(),
                0.5 + 0.5 * q.dot(n) / segment.half_width,
            );
            inside && alpha(uv) >= ALPHA_CUTOFF && fade >= thresholds[i]
        })
        .count() as u32
}

#[test]
fn strips_cover_the_samples_the_model_covers() {
    if !gpu_or_skip("strips_cover_the_samples_the_model_covers") {
        return;
    }
    let harness = HeadlessRender::new(WIDTH, HEIGHT)
        .format(CaptureFormat::LinearF16)
        .frames(4);
    let mut app = harness.app();
    app.add_plugins(HairPlugin).add_systems(Startup, scene);
    let capture = harness.run(app).expect("renders");
    let gpu = capture.to_linear();
    save_coverage("hair_coverage", &gpu, WIDTH, HEIGHT);
    let count = |p: IVec2| (gpu[(p.y * WIDTH as i32 + p.x) as usize][0] * 4.0).round() as u32;

    let mirrored = SAMPLE_POSITIONS_4X.map(|p| Vec2::new(1.0 - p.x, p.y));
    let (mut covered, mut differ, mut differ_mutated) = (0u32, 0u32, 0u32);
    let mut width_errors = Vec::new();
    for half in [0, 64] {
        let atlas = half == 0;
        for k in 0..16 {
            let (a, b, w) = cell_segment(k, half);
            let (drawn, fade) = clamp_width(w);
            let segment = ScreenSegment {
                a,
                b,
                half_width: drawn / 2.0,
            };
            let (cx, cy) = (half + (k % 4) * CELL, (k / 4) * CELL);
            let mut sum = 0.0;
            for y in cy..cy + CELL {
                for x in cx..cx + CELL {
                    let p = IVec2::new(x, y);
                    let g = count(p);
                    let m = model_count(&segment, fade, atlas, p, SAMPLE_POSITIONS_4X);
                    let mm = model_count(&segment, fade, atlas, p, mirrored);
                    covered += m;
                    differ += g.abs_diff(m);
                    differ_mutated += g.abs_diff(mm);
                    sum += g as f32 / 4.0;
                }
            }
            if !atlas {
                width_errors.push(sum / a.distance(b) - w);
            }
        }
    }
    let mean_width_error =
        width_errors.iter().map(|e| e.abs()).sum::<f32>() / width_errors.len() as f32;
    println!(
        "{covered} samples covered by the model; GPU differs on {differ} ({:.2} %); \
         with the alpha tested at mirrored positions, on {differ_mutated} ({:.2} %)",
        100.0 * differ as f32 / covered as f32,
        100.0 * differ_mutated as f32 / covered as f32
    );
    println!(
        "solid strands' width from the GPU's coverage: mean |error| {mean_width_error:.3} px, {width_errors:.3?}"
    );
    assert!(covered > 1000, "{covered}");
    assert!(
        differ * 200 < covered,
        "{differ} of {covered} samples differ"
    );
    assert!(
        differ_mutated * 20 > covered,
        "the mutation is not seen: {differ_mutated}"
    );
    assert!(mean_width_error < 0.125, "{mean_width_error}");
}
