//! The global distance field's updates and storage, on the CPU model
//! (`penumbra_df_core::clipmap` + `penumbra_reference::global_sdf`).
//!
//! The scene: a town of 1,000 analytic casters over 400 × 400 m — 600 buildings (boxes
//! 2–12 m wide, 3–20 m tall) and 400 props (balls of 0.3–2 m) — on a ground slab, with
//! exact distances. The clipmaps: the default layout (4 levels of 128³, 25.6 m to
//! 204.8 m, ± 4 texels).
//!
//! **Updates**, 60 frames a second, with the default budget and without one: bricks
//! composed per frame (a brick is 8³ texels), distance evaluations per frame (texels ×
//! the objects that pass the brick's cull), the frames that ended with bricks still
//! pending (the sampler falls back to coarser levels there), and frames to settle — for a
//! still camera, a walk at 5 m/s, a flight at 30 m/s, one caster moving, 100 casters
//! moving, and a teleport across the town.
//!
//! **Storage**: memory per layout and format, and each format's error against the exact
//! distance at random points of each level (mean and 99th percentile of |field −
//! min(truth, band)|, and the largest overshoot above the truth in texel diagonals,
//! which the composition bounds by 1).
//!
//! `cargo bench -p penumbra_reference --bench global_sdf`; writes
//! `target/penumbra_bench/global_sdf.md`.

#![allow(missing_docs, reason = "criterion_group! generates undocumented items")]

use criterion::{Criterion, criterion_group};
use glam::{IVec3, Vec3};
use penumbra_df_core::ao::{AoTrace, CONE_SHAPING};
use penumbra_df_core::clipmap::{
    BrickJob, ClipmapLayout, ClipmapState, DEFAULT_BRICK_BUDGET, DirtyBox,
};
use penumbra_df_core::cull::CameraOrigin;
use penumbra_df_core::object::ObjectRecord;
use penumbra_reference::df::Atlas;
use penumbra_reference::dfao::{FarField, pixel_ao_counted, pixel_ao_far};
use penumbra_reference::global_sdf::scenarios::{TELEPORT, scenarios, town};
use penumbra_reference::global_sdf::{
    AnalyticCaster, ClipmapFormat, FieldObject, GlobalField, analytic_distance, closed_room,
};
use std::fmt::Write as _;
use std::path::PathBuf;

use penumbra_testkit::XorShift as Rng;

/// One scenario's figures.
#[derive(Default)]
struct Figures {
    frames: usize,
    bricks: Vec<usize>,
    evaluations: Vec<usize>,
    pending_frames: usize,
    /// Frames from the last event until nothing was pending.
    settle: usize,
}

/// Runs `frames` frames: `step(frame, camera, casters)` moves the camera and casters
/// and returns the dirty regions. The first frame (composing everything) is not counted.
fn scenario(
    casters: &mut Vec<AnalyticCaster>,
    frames: usize,
    budget: usize,
    mut step: impl FnMut(usize, &mut Vec3, &mut Vec<AnalyticCaster>) -> Vec<DirtyBox>,
) -> Figures {
    let layout = ClipmapLayout::DEFAULT;
    let mut state = ClipmapState::new(layout);
    let mut field = GlobalField::new(layout, ClipmapFormat::F16);
    let mut camera = Vec3::new(0.0, 1.7, 0.0);
    let compose = |field: &mut GlobalField, jobs: &[BrickJob], casters: &[AnalyticCaster]| {
        let objects: Vec<FieldObject> = casters.iter().map(|c| c.field_object()).collect();
        jobs.iter()
            .map(|&j| field.compose(j, &objects).evaluations)
            .sum::<usize>()
    };
    let u = state.update(camera, &[], usize::MAX);
    compose(&mut field, &u.jobs, casters);
    let mut f = Figures {
        frames,
        ..Figures::default()
    };
    for frame in 0..frames {
        let dirty = step(frame, &mut camera, casters);
        let u = state.update(camera, &dirty, budget);
        f.evaluations.push(compose(&mut field, &u.jobs, casters));
        f.bricks.push(u.jobs.len());
        if u.pending > 0 {
            f.pending_frames += 1;
            f.settle += 1;
        } else if !dirty.is_empty() || !u.jobs.is_empty() {
            f.settle = 0;
        }
    }
    f
}

fn stats(v: &[usize]) -> (f64, usize) {
    let mean = v.iter().sum::<usize>() as f64 / v.len().max(1) as f64;
    (mean, v.iter().copied().max().unwrap_or(0))
}

fn updates(md: &mut String) {
    md.push_str(
        "## Updates (60 frames per second)\n\n| scenario | budget (bricks / frame) | frames | bricks / frame, mean | max | texels / frame, max | evaluations / frame, mean | max | frames ending with bricks pending |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    let scenarios = scenarios();
    let base = town();
    for (name, frames, make) in &scenarios {
        for budget in [1024, DEFAULT_BRICK_BUDGET, usize::MAX] {
            let mut casters = base.clone();
            let f = scenario(&mut casters, *frames, budget, make());
            let (b_mean, b_max) = stats(&f.bricks);
            let (e_mean, e_max) = stats(&f.evaluations);
            let budget = if budget == usize::MAX {
                "none".to_string()
            } else {
                budget.to_string()
            };
            let settle = if *name == TELEPORT {
                format!(" (settled after {} frames)", f.pending_frames + 1)
            } else {
                String::new()
            };
            let _ = writeln!(
                md,
                "| {name} | {budget} | {} | {b_mean:.1} | {b_max} | {} | {e_mean:.0} | {e_max} | {}{settle} |",
                f.frames,
                b_max * 512,
                f.pending_frames
            );
        }
    }
}

fn storage(md: &mut String) {
    md.push_str("\n## Memory\n\n| levels × resolution | f16 | unorm8 |\n|---|---|---|\n");
    for (levels, res) in [(4u32, 64u32), (4, 128), (4, 256), (6, 128)] {
        let texels = u64::from(levels) * u64::from(res).pow(3);
        let _ = writeln!(
            md,
            "| {levels} × {res}³ | {:.1} MiB | {:.1} MiB |",
            texels as f64 * 2.0 / 1048576.0,
            texels as f64 / 1048576.0
        );
    }
    md.push_str(
        "\n## Storage error (town, camera at the centre, 20,000 points per level within the band of a surface; the default layout without its dilation)\n\n| format | level | texel (m) | mean \\|field − min(truth, band)\\| (m) | p99 (m) | largest overshoot above truth (texel diagonals) |\n|---|---|---|---|---|---|\n",
    );
    let casters = town();
    let objects: Vec<FieldObject> = casters.iter().map(|c| c.field_object()).collect();
    // The formats' own error: without the dilation (which lowers every value by the
    // same known amount).
    let layout = ClipmapLayout {
        dilation_texels: 0.0,
        ..ClipmapLayout::DEFAULT
    };
    let camera = Vec3::new(3.0, 1.7, -2.0);
    for format in [ClipmapFormat::F16, ClipmapFormat::Unorm8] {
        let mut state = ClipmapState::new(layout);
        let mut field = GlobalField::new(layout, format);
        for job in state.update(camera, &[], usize::MAX).jobs {
            field.compose(job, &objects);
        }
        let mut rng = Rng(77);
        for level in 0..layout.levels {
            let o = state.origin(level).expect("composed");
            let t = layout.texel(level);
            let (lo, hi) = (
                layout.texel_centre(level, o),
                layout.texel_centre(level, o + IVec3::splat(layout.resolution as i32 - 1)),
            );
            let band = layout.band(level);
            let mut errors = Vec::new();
            let mut overshoot = f32::NEG_INFINITY;
            while errors.len() < 20_000 {
                // Points near surfaces: within the band of the ground or a caster.
                let p = Vec3::new(
                    rng.range(lo.x, hi.x),
                    rng.range(0.0, 25.0 * (level + 1) as f32),
                    rng.range(lo.z, hi.z),
                );
                let truth = analytic_distance(&casters, p);
                if truth.abs() > band {
                    continue;
                }
                let Some(v) = field.sample_level(&state, level, p) else {
                    continue;
                };
                errors.push((v - truth.min(band)).abs());
                overshoot = overshoot.max((v - truth) / (t * 3f32.sqrt()));
            }
            errors.sort_by(f32::total_cmp);
            let mean = errors.iter().sum::<f32>() / errors.len() as f32;
            let _ = writeln!(
                md,
                "| {format:?} | {level} | {t:.2} | {mean:.4} | {:.4} | {overshoot:.2} |",
                errors[errors.len() * 99 / 100]
            );
        }
    }
}

/// The component's trace: 9 cones, 8 steps, 10 m, bias 0.02 m.
fn trace() -> AoTrace {
    AoTrace {
        max_distance: 10.0,
        cone_count: 9,
        steps_per_cone: 8,
        bias: 0.02,
        shaping: CONE_SHAPING,
    }
}

/// The field of `records` around `camera` (whole) with band and dilation in texels.
fn field_of(
    records: &[ObjectRecord],
    camera: Vec3,
    band: f32,
    dilation: f32,
) -> (GlobalField, ClipmapState) {
    let layout = ClipmapLayout {
        band_texels: band,
        dilation_texels: dilation,
        ..ClipmapLayout::DEFAULT
    };
    let atlas = Atlas::new(glam::UVec3::ONE);
    let mut state = ClipmapState::new(layout);
    let mut field = GlobalField::new(layout, ClipmapFormat::Unorm8);
    for job in state.update(camera, &[], usize::MAX).jobs {
        field.compose_records(job, records, &atlas);
    }
    (field, state)
}

/// Mean AO over `receivers` (world position, normal) with the far field from 1 m, the
/// samples reading level `min_level` or coarser.
fn far_ao(
    records: &[ObjectRecord],
    field: &GlobalField,
    state: &ClipmapState,
    camera: Vec3,
    receivers: &[(Vec3, Vec3)],
    min_level: u32,
) -> f32 {
    let origin = CameraOrigin::at(camera).expect("finite");
    let atlas = Atlas::new(glam::UVec3::ONE);
    let far = FarField {
        min_level,
        ..FarField::new(field, state, camera.as_dvec3(), 1.0)
    };
    receivers
        .iter()
        .map(|&(p, n)| {
            pixel_ao_far(records, &atlas, &origin, p - camera, n, &trace(), &far)
                .0
                .ao
        })
        .sum::<f32>()
        / receivers.len() as f32
}

/// Thin walls: a closed 4 × 2.5 × 4 m room (truth: AO 0 everywhere inside), and the far
/// field's over-occlusion on open ground (balls of radius D/2 at D = 2–6 m over a plane:
/// analytic AO 0.75), per band and dilation.
fn thin_walls(md: &mut String) {
    md.push_str("\n## Thin walls\n\nA closed room, 4 × 2.5 × 4 m inside (every ray hits a wall within 5 m: truth AO 0), walls of the given thickness; mean AO of four receivers (floor ×2, a wall, the ceiling; each at least 1.2 m from the walls it faces, beyond the switch) with the component's trace (9 cones, 8 steps, 10 m) and the far field from 1 m, the samples forced to read level L or coarser (level L's texel: 0.2 · 2^L m). Open ground: mean |AO − analytic| of balls over a plane seen through the far field (the objects' own trace: see the tests).\n\n| band (texels) | dilation (texels) | wall (m) | AO, L ≥ 0 | L ≥ 1 | L ≥ 2 | L ≥ 3 | objects only |\n|---|---|---|---|---|---|---|---|\n");
    let half = Vec3::new(2.0, 1.25, 2.0);
    // At least 1.2 m from the walls they face: beyond the 1 m switch.
    let receivers = [
        (Vec3::new(0.0, 0.0, 0.0), Vec3::Y),
        (Vec3::new(0.6, 0.0, -0.7), Vec3::Y),
        (Vec3::new(2.0, 1.2, 0.3), -Vec3::X),
        (Vec3::new(-0.5, 2.5, 0.5), -Vec3::Y),
    ];
    let camera = Vec3::new(0.0, 1.2, 0.0);
    let mut summary = Vec::new();
    for band in [4.0f32, 8.0, 16.0] {
        for dilation in [0.0f32, 0.5, 0.87] {
            let mut thinnest = [None::<f32>; 4];
            for wall in [0.4f32, 0.2, 0.1, 0.05, 0.02] {
                let records: Vec<ObjectRecord> =
                    closed_room(half, wall).iter().map(|c| c.record()).collect();
                let (field, state) = field_of(&records, camera, band, dilation);
                let ao: Vec<f32> = (0..4)
                    .map(|l| far_ao(&records, &field, &state, camera, &receivers, l))
                    .collect();
                let origin = CameraOrigin::at(camera).expect("finite");
                let atlas = Atlas::new(glam::UVec3::ONE);
                let objects = receivers
                    .iter()
                    .map(|&(p, n)| {
                        pixel_ao_counted(&records, &atlas, &origin, p - camera, n, &trace())
                            .0
                            .ao
                    })
                    .sum::<f32>()
                    / receivers.len() as f32;
                for (l, &a) in ao.iter().enumerate() {
                    if a <= 0.05 {
                        thinnest[l] = Some(wall);
                    }
                }
                let _ = writeln!(
                    md,
                    "| {band} | {dilation} | {wall} | {:.3} | {:.3} | {:.3} | {:.3} | {objects:.3} |",
                    ao[0], ao[1], ao[2], ao[3]
                );
            }
            // Open ground.
            let mut error = 0.0;
            let ds = [2.0f32, 3.0, 4.0, 6.0];
            for d in ds {
                let ground = AnalyticCaster::Cuboid {
                    centre: Vec3::new(0.0, -0.5, 0.0),
                    half: Vec3::new(200.0, 0.5, 200.0),
                };
                let ball = AnalyticCaster::Sphere {
                    centre: Vec3::new(0.0, d, 0.0),
                    radius: 0.5 * d,
                };
                let records = [ground.record(), ball.record()];
                let camera = Vec3::new(0.0, 1.7, 2.0);
                let (field, state) = field_of(&records, camera, band, dilation);
                let ao = far_ao(
                    &records,
                    &field,
                    &state,
                    camera,
                    &[(Vec3::new(0.05, 0.0, -0.03), Vec3::Y)],
                    0,
                );
                error += (ao - 0.75).abs() / ds.len() as f32;
            }
            summary.push((band, dilation, thinnest, error));
        }
    }
    md.push_str("\n| band (texels) | dilation (texels) | thinnest wall with AO ≤ 0.05, L ≥ 0 / 1 / 2 / 3 (m) | open ground: mean \\|ΔAO\\| |\n|---|---|---|---|\n");
    for (band, dilation, thinnest, error) in summary {
        let cells: Vec<String> = thinnest
            .iter()
            .map(|t| t.map_or("> 0.4".to_string(), |w| w.to_string()))
            .collect();
        let _ = writeln!(
            md,
            "| {band} | {dilation} | {} | {error:.4} |",
            cells.join(" / ")
        );
    }
}

fn bench(c: &mut Criterion) {
    let mut md = String::from(
        "# Global distance field: updates and storage\n\n`cargo bench -p penumbra_reference --bench global_sdf`: the CPU model, a town of 1,000 analytic casters, the default layout (4 levels of 128³ from 25.6 m, ± 4 texels).\n\n",
    );
    updates(&mut md);
    storage(&mut md);
    thin_walls(&mut md);
    println!("{md}");
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/penumbra_bench");
    if std::fs::create_dir_all(&dir).is_ok() {
        let _ = std::fs::write(dir.join("global_sdf.md"), &md);
    }
    let casters = town();
    let objects: Vec<FieldObject> = casters.iter().map(|c| c.field_object()).collect();
    let mut field = GlobalField::new(ClipmapLayout::DEFAULT, ClipmapFormat::F16);
    c.bench_function("global_sdf/compose one level-0 brick by the ground", |b| {
        b.iter(|| {
            field.compose(
                BrickJob {
                    level: 0,
                    brick: IVec3::new(0, -1, 0),
                },
                &objects,
            )
        });
    });
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
