//! The temporal filter's model over frame sequences of an analytic scene (a sphere and
//! a box on a plane, sphere-traced views): history converges toward the full-resolution
//! trace, depth rejection drops other surfaces, and the ghosting and flicker figures of
//! the filter's steps (`cargo test -p penumbra_reference temporal -- --nocapture`).

use super::temporal::reproject;
use super::tests::{defaults, ground, object, ray_cast_view};
use super::*;
use crate::camera::PerspectiveCamera;
use glam::{Affine3A, Vec2};
use penumbra_df_core::ao::{jitter, trace_size};
use penumbra_df_core::object::CasterShape;

const W: u32 = 48;
const H: u32 = 36;
const DIVISOR: u32 = 2;
const FOV: f32 = 0.9;

fn trace_settings() -> AoTrace {
    AoTrace {
        max_distance: 2.0,
        ..defaults()
    }
}

fn scene(sphere: Vec3) -> Vec<ObjectRecord> {
    vec![
        ground(),
        object(
            CasterShape::Sphere { radius: 0.5 },
            Affine3A::from_translation(sphere),
        ),
        object(
            CasterShape::Cuboid {
                half_extents: Vec3::new(0.4, 0.4, 0.4),
            },
            Affine3A::from_translation(Vec3::new(-1.2, 0.4, -0.8)),
        ),
    ]
}

/// One frame as the passes see it.
struct Shot {
    eye: Vec3,
    size: UVec2,
    depth: Vec<f32>,
    normals: Vec<Vec3>,
    positions: Vec<Vec3>,
    view_from_clip: Mat4,
    world_from_view: Mat3,
}

fn shoot(eye: Vec3, target: Vec3, records: &[ObjectRecord], atlas: &Atlas) -> Shot {
    let camera = PerspectiveCamera::looking_at(eye, target, FOV, W, H);
    let (size, depth, normals, view_from_clip, world_from_view) =
        ray_cast_view(&camera, records, atlas);
    let positions = (0..size.y)
        .flat_map(|y| (0..size.x).map(move |x| UVec2::new(x, y)))
        .map(|px| {
            let d = depth[(px.y * size.x + px.x) as usize];
            if d > 0.0 {
                position_from_depth(
                    view_from_clip,
                    world_from_view,
                    size.as_vec2(),
                    px.as_vec2(),
                    d,
                )
            } else {
                Vec3::NAN
            }
        })
        .collect();
    Shot {
        eye,
        size,
        depth,
        normals,
        positions,
        view_from_clip,
        world_from_view,
    }
}

/// UV of world point `x` in `shot`'s view.
fn uv_of(shot: &Shot, x: Vec3) -> Vec2 {
    let v = shot.world_from_view.transpose() * (x - shot.eye);
    let clip = shot.view_from_clip.inverse() * v.extend(1.0);
    let ndc = Vec2::new(clip.x, clip.y) / clip.w;
    Vec2::new(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5)
}

/// Motion vectors (this UV minus the previous UV) of `shot`'s pixels; `moved(x)` is the
/// world displacement since `previous` of the surface at world point `x`.
fn motion(shot: &Shot, previous: &Shot, moved: impl Fn(Vec3) -> Vec3) -> Vec<Vec2> {
    let mut out = Vec::with_capacity(shot.positions.len());
    for y in 0..shot.size.y {
        for x in 0..shot.size.x {
            let p = shot.positions[(y * shot.size.x + x) as usize];
            if p.is_nan() {
                out.push(Vec2::ZERO);
                continue;
            }
            let world = p + shot.eye;
            let now = (Vec2::new(x as f32, y as f32) + 0.5) / shot.size.as_vec2();
            out.push(now - uv_of(previous, world - moved(world)));
        }
    }
    out
}

/// The upsampled trace of `shot` in frame `f` (jitter `f mod 4`).
fn current(shot: &Shot, records: &[ObjectRecord], atlas: &Atlas, f: u32) -> Vec<Vec4> {
    let origin = CameraOrigin::at(shot.eye).expect("finite");
    let view = AoView {
        view_from_clip: shot.view_from_clip,
        world_from_view: shot.world_from_view,
        size: shot.size,
        depth: &shot.depth,
        normals: &shot.normals,
    };
    let j = jitter(f, DIVISOR);
    let trace = trace_view(
        records,
        atlas,
        &origin,
        &view,
        DIVISOR,
        j,
        &trace_settings(),
    );
    let distance: Vec<f32> = shot.positions.iter().map(|p| p.length()).collect();
    let distance: Vec<f32> = distance
        .into_iter()
        .map(|d| if d.is_nan() { 0.0 } else { d })
        .collect();
    upsample(
        &trace,
        trace_size(shot.size, DIVISOR),
        DIVISOR,
        j,
        &distance,
        &shot.normals,
        shot.size,
    )
}

/// The full-resolution per-pixel trace (what the filter converges toward).
fn reference(shot: &Shot, records: &[ObjectRecord], atlas: &Atlas) -> Vec<f32> {
    let origin = CameraOrigin::at(shot.eye).expect("finite");
    shot.positions
        .iter()
        .zip(&shot.normals)
        .map(|(&p, &n)| {
            if p.is_nan() {
                f32::NAN
            } else {
                pixel_ao(records, atlas, &origin, p, n, &trace_settings()).ao
            }
        })
        .collect()
}

fn mean_error(ao: &[Vec4], truth: &[f32]) -> f32 {
    let (sum, n) = ao
        .iter()
        .zip(truth)
        .filter(|(_, t)| !t.is_nan())
        .fold((0.0, 0), |(s, n), (a, t)| (s + (a.x - t).abs(), n + 1));
    sum / n as f32
}

fn frame<'a>(
    shot: &'a Shot,
    current: &'a [Vec4],
    motion: &'a [Vec2],
    previous_eye: Vec3,
) -> TemporalFrame<'a> {
    TemporalFrame {
        size: shot.size,
        current,
        positions: &shot.positions,
        normals: &shot.normals,
        motion,
        previous_offset: previous_eye - shot.eye,
    }
}

/// On a still view the history gathers the four jitter positions: the output is close
/// to their mean and changes much less from frame to frame than the unfiltered upsample
/// (with or without the steps).
#[test]
fn a_still_view_averages_the_jitter_positions() {
    let atlas = Atlas::new(glam::UVec3::ONE);
    let records = scene(Vec3::new(0.3, 0.7, 0.0));
    let eye = Vec3::new(0.0, 3.0, 3.5);
    let shot = shoot(eye, Vec3::ZERO, &records, &atlas);
    let still = vec![Vec2::ZERO; shot.positions.len()];
    let currents: Vec<Vec<Vec4>> = (0..4)
        .map(|f| current(&shot, &records, &atlas, f))
        .collect();
    let change = |a: &[Vec4], b: &[Vec4]| {
        let (sum, n) = a
            .iter()
            .zip(b)
            .zip(&shot.positions)
            .filter(|(_, p)| !p.is_nan())
            .fold((0.0, 0), |(s, n), ((a, b), _)| {
                (s + (a.x - b.x).abs(), n + 1)
            });
        sum / n as f32
    };
    let raw = (0..4)
        .map(|f| change(&currents[f], &currents[(f + 1) % 4]))
        .sum::<f32>()
        / 4.0;
    let mean: Vec<Vec4> = (0..currents[0].len())
        .map(|k| currents.iter().map(|c| c[k]).sum::<Vec4>() / 4.0)
        .collect();
    for steps in [TemporalSteps::PLAIN, TemporalSteps::ALL] {
        let mut history: Option<AoHistory> = None;
        let mut last = Vec::new();
        for f in 0..24 {
            let c = &currents[(f % 4) as usize];
            let out = temporal_step(&frame(&shot, c, &still, eye), history.as_ref(), steps);
            last = history.map_or_else(Vec::new, |h| h.filtered);
            history = Some(out);
        }
        let out = history.expect("filtered").filtered;
        let (filtered, off_mean) = (change(&out, &last), change(&out, &mean));
        println!(
            "still view {steps:?}: frame-to-frame change {filtered:.5} (unfiltered {raw:.5}), \
             from the jitter mean {off_mean:.5}"
        );
        assert!(
            filtered < 0.3 * raw && off_mean < 0.3 * raw,
            "{steps:?}: change {filtered}, from the mean {off_mean}, unfiltered {raw}"
        );
    }
}

/// A still view whose trace does not change (every pixel traced every frame, as in a
/// view under `min_trace_rows` rows) shows its own trace within a few frames, whatever
/// history it starts from: none, all open at full confidence, or its own trace darkened
/// by 0.3. The spatial fill a low-confidence pixel shows must not become its history: a
/// contact pixel whose trace differs from its neighbourhood's mean by more than twice
/// the leak tolerance then compared its trace with the fill it had stored, was flushed
/// again, and showed the fill for ever.
#[test]
fn a_still_view_converges_to_its_own_trace_from_any_history() {
    let atlas = Atlas::new(glam::UVec3::ONE);
    let records = scene(Vec3::new(0.3, 0.7, 0.0));
    let eye = Vec3::new(0.0, 3.0, 3.5);
    let shot = shoot(eye, Vec3::ZERO, &records, &atlas);
    let still = vec![Vec2::ZERO; shot.positions.len()];
    let trace = reference(&shot, &records, &atlas);
    let c: Vec<Vec4> = trace
        .iter()
        .zip(&shot.normals)
        .map(|(&ao, n)| {
            if ao.is_nan() {
                Vec4::new(1.0, 0.0, 0.0, 0.0)
            } else {
                Vec4::new(ao, n.x, n.y, n.z)
            }
        })
        .collect();
    let f = frame(&shot, &c, &still, eye);
    // The case has pixels the fill moves by more than twice the leak tolerance.
    let fill = temporal_step(&f, None, TemporalSteps::ALL).filtered;
    let sharp = fill
        .iter()
        .zip(&trace)
        .filter(|(v, t)| (v.x - **t).abs() > 2.0 * penumbra_df_core::ao::LEAK_TOLERANCE)
        .count();
    assert!(
        sharp >= 10,
        "{sharp} pixels where the fill departs from the trace"
    );
    let state: Vec<Vec4> = shot
        .positions
        .iter()
        .map(|p| Vec4::new(if p.is_nan() { 0.0 } else { p.length() }, 1.0, 0.0, 0.0))
        .collect();
    let open = AoHistory::new(vec![Vec4::new(1.0, 0.0, 1.0, 0.0); c.len()], state.clone());
    let darker = AoHistory::new(
        c.iter()
            .map(|v| Vec4::new((v.x - 0.3).max(0.0), v.y, v.z, v.w))
            .collect(),
        state,
    );
    for (name, start) in [
        ("none", None),
        ("open", Some(open)),
        ("darker", Some(darker)),
    ] {
        let mut history = start;
        for _ in 0..40 {
            history = Some(temporal_step(&f, history.as_ref(), TemporalSteps::ALL));
        }
        let out = history.expect("filtered").filtered;
        let worst = out
            .iter()
            .zip(&trace)
            .filter(|(_, t)| !t.is_nan())
            .map(|(v, t)| (v.x - t).abs())
            .fold(0.0f32, f32::max);
        println!("still view from {name} history: worst |filtered − trace| {worst:.5}");
        assert!(
            worst < 0.01,
            "from {name} history: {worst} from the trace after 40 frames"
        );
    }
}

/// A history texel of another surface (stored distance 5 m, the pixel's point 2 m from
/// the previous camera) is rejected: the output is the current value, confidence 0. The
/// same surface is kept with the history weight (plain steps).
#[test]
fn depth_rejection_drops_another_surface() {
    let size = UVec2::new(4, 4);
    let n = 16;
    let positions = vec![Vec3::new(0.0, 0.0, -2.0); n];
    let normals = vec![Vec3::Z; n];
    let current = vec![Vec4::new(1.0, 0.0, 0.0, 1.0); n];
    let motion = vec![Vec2::ZERO; n];
    let f = TemporalFrame {
        size,
        current: &current,
        positions: &positions,
        normals: &normals,
        motion: &motion,
        previous_offset: Vec3::ZERO,
    };
    for (stored, kept) in [(5.0, false), (2.02, true)] {
        let history = AoHistory::new(
            vec![Vec4::new(0.0, 0.0, 0.0, 1.0); n],
            vec![Vec4::new(stored, 1.0, 0.0, 0.0); n],
        );
        let out = temporal_step(&f, Some(&history), TemporalSteps::PLAIN);
        let want = if kept {
            1.0 - penumbra_df_core::ao::HISTORY_WEIGHT
        } else {
            1.0
        };
        for (v, s) in out.value.iter().zip(&out.state) {
            assert!((v.x - want).abs() < 1e-5, "stored {stored}: {v}");
            assert_eq!(s.x, 2.0);
            assert_eq!(s.y, if kept { 1.0 } else { 0.0 });
        }
    }
}

/// Ghosting: the sphere moves 1 m after the history has settled; frames until the error
/// (against the full-resolution trace at the new place) is back within 10 % of its
/// steady value there (the mean of the last four of 40 frames). Flicker: a static scene under a camera panning 2 cm a frame; the mean
/// change of each pixel's filtered AO from its reprojected previous value. Printed for
/// every combination of the steps; the confidence must flush faster than the plain
/// history, and any history must flicker less than no filter.
#[test]
fn ghosting_and_flicker_of_the_steps() {
    let atlas = Atlas::new(glam::UVec3::ONE);
    let eye = Vec3::new(0.0, 3.0, 3.5);
    let (a, b) = (Vec3::new(-0.2, 0.7, 0.0), Vec3::new(0.8, 0.7, 0.0));
    let combos = [
        ("plain", TemporalSteps::PLAIN),
        (
            "confidence",
            TemporalSteps {
                confidence: true,
                spatial_fill: false,
            },
        ),
        (
            "fill",
            TemporalSteps {
                confidence: false,
                spatial_fill: true,
            },
        ),
        ("confidence+fill", TemporalSteps::ALL),
    ];
    let mut ghost = Vec::new();
    for (name, steps) in combos {
        let mut history: Option<AoHistory> = None;
        let mut errors = Vec::new();
        let mut previous: Option<Shot> = None;
        for f in 0..52u32 {
            let at = if f < 12 { a } else { b };
            let records = scene(at);
            let shot = shoot(eye, Vec3::ZERO, &records, &atlas);
            let m = match &previous {
                Some(p) => motion(&shot, p, |x| {
                    // The sphere's surface moved with it (from `a` at frame 12).
                    if f == 12 && (x - b).length() < 0.51 {
                        b - a
                    } else {
                        Vec3::ZERO
                    }
                }),
                None => vec![Vec2::ZERO; shot.positions.len()],
            };
            let c = current(&shot, &records, &atlas, f);
            let out = temporal_step(&frame(&shot, &c, &m, eye), history.as_ref(), steps);
            if f >= 12 {
                errors.push(mean_error(
                    &out.filtered,
                    &reference(&shot, &records, &atlas),
                ));
            }
            history = Some(out);
            previous = Some(shot);
        }
        let steady = errors[errors.len() - 4..].iter().sum::<f32>() / 4.0;
        let frames = errors
            .iter()
            .position(|&e| e <= 1.1 * steady)
            .unwrap_or(errors.len());
        println!(
            "ghosting {name}: error {:.4} on the move, steady {steady:.4}, frames to recover {frames}",
            errors[0]
        );
        ghost.push(frames);
    }
    assert!(
        ghost[3] < ghost[0],
        "confidence+fill recovers in {} frames, plain history in {}",
        ghost[3],
        ghost[0]
    );

    let records = scene(Vec3::new(0.3, 0.7, 0.0));
    let mut flicker = Vec::new();
    for (name, steps) in [("none", None)]
        .into_iter()
        .chain(combos.map(|(n, s)| (n, Some(s))))
    {
        let mut history: Option<AoHistory> = None;
        let mut previous: Option<(Shot, AoHistory)> = None;
        let (mut sum, mut count) = (0.0f64, 0u32);
        for f in 0..20u32 {
            let pan = Vec3::new(0.02 * f as f32, 0.0, 0.0);
            let shot = shoot(eye + pan, pan, &records, &atlas);
            let m = match &previous {
                Some((p, _)) => motion(&shot, p, |_| Vec3::ZERO),
                None => vec![Vec2::ZERO; shot.positions.len()],
            };
            let c = current(&shot, &records, &atlas, f);
            let out = match steps {
                Some(steps) => {
                    let fr = frame(
                        &shot,
                        &c,
                        &m,
                        previous.as_ref().map_or(shot.eye, |p| p.0.eye),
                    );
                    temporal_step(&fr, history.as_ref(), steps)
                }
                None => AoHistory::new(
                    c.clone(),
                    shot.positions
                        .iter()
                        .map(|p| {
                            Vec4::new(if p.is_nan() { 0.0 } else { p.length() }, 1.0, 0.0, 0.0)
                        })
                        .collect(),
                ),
            };
            if let Some((p, prev_out)) = &previous
                && f >= 8
            {
                let fr = frame(&shot, &c, &m, p.eye);
                // What the previous frame showed, reprojected.
                let shown = AoHistory::new(prev_out.filtered.clone(), prev_out.state.clone());
                for y in 0..shot.size.y {
                    for x in 0..shot.size.x {
                        let k = (y * shot.size.x + x) as usize;
                        let pos = shot.positions[k];
                        if pos.is_nan() {
                            continue;
                        }
                        let expected = (pos - fr.previous_offset).length();
                        if let Some((h, _)) = reproject(&fr, &shown, UVec2::new(x, y), expected) {
                            sum += f64::from((out.filtered[k].x - h.x).abs());
                            count += 1;
                        }
                    }
                }
            }
            history = Some(out.clone());
            previous = Some((shot, out));
        }
        let mean = (sum / f64::from(count)) as f32;
        println!("flicker {name}: mean frame-to-frame change {mean:.4} over {count} pixels");
        flicker.push(mean);
    }
    assert!(
        flicker[1..].iter().all(|&f| f < 0.6 * flicker[0]),
        "flicker with history {:?} against {} without",
        &flicker[1..],
        flicker[0]
    );
}
