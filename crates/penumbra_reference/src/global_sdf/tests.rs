use super::*;
use penumbra_df_core::clipmap::{DirtyBox, GlobalFieldView};

type Shape = AnalyticCaster;

/// Scene randomness: a deterministic generator and what the tests draw from it.
struct Rng(u32);

impl Rng {
    fn unit(&mut self) -> f32 {
        let mut g = penumbra_testkit::XorShift(self.0);
        let u = g.unit();
        self.0 = g.0;
        u
    }
    fn range(&mut self, a: f32, b: f32) -> f32 {
        a + (b - a) * self.unit()
    }
    fn vec(&mut self, a: f32) -> Vec3 {
        Vec3::new(self.range(-a, a), self.range(-a, a), self.range(-a, a))
    }
    fn shape(&mut self, around: Vec3) -> Shape {
        let centre = around + self.vec(6.0);
        if self.unit() < 0.5 {
            Shape::Sphere {
                centre,
                radius: self.range(0.1, 1.2),
            }
        } else {
            let half = Vec3::new(
                self.range(0.03, 1.5),
                self.range(0.03, 0.8),
                self.range(0.03, 1.0),
            );
            Shape::Cuboid { centre, half }
        }
    }
}

/// Three levels of 24³ (27 bricks each), 0.2 m texels at level 0.
fn layout() -> ClipmapLayout {
    ClipmapLayout::new(3, 24, 4.8, 2.0).0
}

fn composed(field: &mut GlobalField, jobs: &[BrickJob], shapes: &[Shape]) {
    let objects: Vec<FieldObject> = shapes.iter().map(|s| s.field_object()).collect();
    for &job in jobs {
        field.compose(job, &objects);
    }
}

/// Every valid brick of `field` equals the same brick composed from scratch now.
fn check(
    field: &GlobalField,
    state: &ClipmapState,
    shapes: &[Shape],
    frame: usize,
) -> Result<(), String> {
    let mut scratch = GlobalField::new(field.layout, field.format);
    for level in 0..field.layout.levels {
        let Some(window) = state.window(level) else {
            continue;
        };
        let jobs: Vec<BrickJob> = window
            .iter()
            .filter(|&b| state.is_valid(level, b))
            .map(|brick| BrickJob { level, brick })
            .collect();
        composed(&mut scratch, &jobs, shapes);
        let b = BRICK as i32;
        for job in jobs {
            for i in 0..b * b * b {
                let w = job.brick * b + IVec3::new(i % b, (i / b) % b, i / (b * b));
                let (got, want) = (field.texel(level, w), scratch.texel(level, w));
                if got.to_bits() != want.to_bits() {
                    return Err(format!(
                        "frame {frame}: level {level} texel {w} holds {got}, a composition from \
                         scratch {want}"
                    ));
                }
            }
        }
    }
    Ok(())
}

/// A long random sequence of walks, teleports and caster moves, appearances and
/// removals under a small per-frame budget, checked every frame. `drop` leaves out the
/// dirty region of that index (counting from 0 over the run).
fn random_sequence(
    frames: usize,
    drop: Option<usize>,
) -> Result<(GlobalField, ClipmapState, Vec<Shape>), String> {
    let mut rng = Rng(0x9e37_79b9);
    let mut camera = Vec3::new(0.3, 1.7, -0.4);
    let mut shapes: Vec<Shape> = (0..10).map(|_| rng.shape(camera)).collect();
    let mut field = GlobalField::new(layout(), ClipmapFormat::F16);
    let mut state = ClipmapState::new(layout());
    let mut dirty_index = 0;
    for frame in 0..frames {
        let mut dirty = Vec::new();
        if frame > 0 {
            let e = rng.unit();
            if e < 0.05 {
                camera = rng.vec(300.0);
            } else if e < 0.7 {
                camera += rng.vec(1.2);
            }
            // Frame 1 always moves caster 0 (the dropped-region check relies on it).
            let c = rng.unit();
            if (frame == 1 || c < 0.5) && !shapes.is_empty() {
                let i = if frame == 1 {
                    0
                } else {
                    (rng.unit() * shapes.len() as f32) as usize % shapes.len()
                };
                let old = shapes[i];
                shapes[i] = rng.shape(camera);
                dirty.extend([old.dirty(), shapes[i].dirty()]);
            } else if c < 0.7 {
                let s = rng.shape(camera);
                shapes.push(s);
                dirty.push(s.dirty());
            } else if c < 0.85 && !shapes.is_empty() {
                let i = (rng.unit() * shapes.len() as f32) as usize % shapes.len();
                dirty.push(shapes.swap_remove(i).dirty());
            }
        }
        let kept: Vec<DirtyBox> = dirty
            .into_iter()
            .filter(|_| {
                dirty_index += 1;
                drop != Some(dirty_index - 1)
            })
            .collect();
        let budget = if frame == 0 {
            usize::MAX
        } else {
            4 + (rng.unit() * 30.0) as usize
        };
        let update = state.update(camera, &kept, budget);
        composed(&mut field, &update.jobs, &shapes);
        check(&field, &state, &shapes, frame)?;
    }
    // Drained: every brick of every window valid, all equal to scratch.
    let update = state.update(camera, &[], usize::MAX);
    composed(&mut field, &update.jobs, &shapes);
    check(&field, &state, &shapes, frames)?;
    Ok((field, state, shapes))
}

#[test]
fn incremental_updates_equal_a_composition_from_scratch() {
    let (_, state, _) = random_sequence(300, None).unwrap();
    assert_eq!(state.pending(), 0);
    for level in 0..3 {
        assert!(state.valid_bits(level).iter().all(|&w| w != 0));
    }
}

#[test]
fn the_sequence_check_fails_when_one_dirty_region_is_dropped() {
    // Frame 1 moves caster 0: region 0 is where it was, region 1 where it is now.
    for dropped in [0, 1] {
        let err = random_sequence(5, Some(dropped)).err();
        assert!(
            err.as_deref().is_some_and(|e| e.starts_with("frame 1:")),
            "dropping region {dropped}: {err:?}"
        );
    }
}

#[test]
fn stored_values_are_conservative_within_two_quanta() {
    for format in [ClipmapFormat::F16, ClipmapFormat::Unorm8] {
        let band = 0.8;
        let q = format.quantum(band);
        for i in 0..=4000 {
            let d = -1.0 + 2.0 * i as f32 / 4000.0;
            let s = store(format, d, band);
            let want = d.clamp(-band, band);
            assert!(s <= want, "{format:?} {d}: {s}");
            assert!(s >= want - 2.0 * q, "{format:?} {d}: {s}");
        }
    }
}

#[test]
fn the_field_is_within_a_texel_diagonal_above_the_true_distance() {
    let (field, state, shapes) = random_sequence(60, None).unwrap();
    let camera = state
        .origin(0)
        .map(|o| field.layout.texel_centre(0, o + IVec3::splat(12)))
        .unwrap();
    let mut rng = Rng(12345);
    let mut levels = [0usize; 3];
    for i in 0..20_000 {
        // Each level's reach in turn: ± 2.4, 4.8 and 9.6 m.
        let p = camera + rng.vec(2.4 * (1 << (i % 3)) as f32);
        let Some((v, level)) = field.sample(&state, p) else {
            continue;
        };
        levels[level as usize] += 1;
        let truth = analytic_distance(&shapes, p);
        let t = field.layout.texel(level);
        let diagonal = t * 3f32.sqrt();
        let band = field.layout.band(level);
        assert!(
            v <= truth + diagonal,
            "{p}: field {v}, truth {truth} (level {level})"
        );
        // Not garbage below either: a caster that is gone, or a stale brick, would
        // read far below the truth.
        let q = field.format.quantum(band);
        assert!(
            v >= truth.min(band) - diagonal - 2.0 * q,
            "{p}: field {v}, truth {truth} (level {level})"
        );
    }
    assert!(levels.iter().all(|&n| n > 500), "{levels:?}");
}

/// The records' path (what the GPU runs) against exact distances: a plane, a ball and a
/// box as GPU object records, 10⁵ m from the origin, composed whole; the field within a
/// texel diagonal above the truth and not far below it.
#[test]
fn composing_records_is_within_a_texel_diagonal_of_the_truth() {
    use crate::df::Atlas;
    use glam::Affine3A;
    use penumbra_df_core::object::{CasterShape, ObjectDesc, encode, flags};
    let offset = Vec3::new(1.0e5, 0.0, -1.0e5);
    let live = flags::LIVE | flags::CASTS_OCCLUSION | flags::VISIBLE;
    let shapes = [
        Shape::Sphere {
            centre: offset + Vec3::new(0.4, 1.0, -0.3),
            radius: 0.7,
        },
        Shape::Cuboid {
            centre: offset + Vec3::new(-1.5, 0.5, 0.8),
            half: Vec3::new(0.6, 0.5, 0.05),
        },
    ];
    let mut records = vec![
        encode(&ObjectDesc {
            world_from_local: Affine3A::from_translation(offset),
            shape: CasterShape::Plane,
            flags: live | flags::UNBOUNDED,
        })
        .unwrap(),
    ];
    for s in &shapes {
        let (centre, shape) = match *s {
            Shape::Sphere { centre, radius } => (centre, CasterShape::Sphere { radius }),
            Shape::Cuboid { centre, half } => (centre, CasterShape::Cuboid { half_extents: half }),
        };
        records.push(
            encode(&ObjectDesc {
                world_from_local: Affine3A::from_translation(centre),
                shape,
                flags: live,
            })
            .unwrap(),
        );
    }
    let truth = |p: Vec3| analytic_distance(&shapes, p).min(p.y - offset.y);
    let layout = layout();
    let atlas = Atlas::new(glam::UVec3::ONE);
    for format in [ClipmapFormat::F16, ClipmapFormat::Unorm8] {
        let mut state = ClipmapState::new(layout);
        let mut field = GlobalField::new(layout, format);
        let camera = offset + Vec3::new(0.1, 1.2, 0.0);
        for job in state.update(camera, &[], usize::MAX).jobs {
            field.compose_records(job, &records, &atlas);
        }
        let mut rng = Rng(99);
        let mut worst = f32::NEG_INFINITY;
        for i in 0..20_000 {
            let p = camera + rng.vec(2.4 * (1 << (i % 3)) as f32);
            let Some((v, level)) = field.sample(&state, p) else {
                continue;
            };
            let d = truth(p);
            let diagonal = layout.texel(level) * 3f32.sqrt();
            let band = layout.band(level);
            // Deeper inside than the band the field reads −band: still inside.
            assert!(
                v <= d.max(-band) + diagonal,
                "{format:?} {p}: {v} truth {d}"
            );
            let q = format.quantum(band);
            // Positions 10⁵ m out carry f32 rounding (8 mm) in the truth's arithmetic.
            assert!(
                v >= d.min(band) - diagonal - 2.0 * q - 0.02,
                "{format:?} {p}: {v} truth {d}"
            );
            worst = worst.max((v - d) / diagonal);
        }
        // The bound is nearly reached: the dilation lowers everything by half a
        // diagonal, and near surfaces the field comes within that of it.
        assert!(worst > -0.5, "{worst}");
    }
}

/// The GPU's way of sampling (camera-relative positions, per-level offsets, validity
/// bits) reads what the world-space sampler reads, level for level, valid or not.
#[test]
fn sampling_from_the_camera_equals_sampling_in_the_world() {
    let (field, state, _) = random_sequence(40, None).unwrap();
    let camera = Vec3::new(0.1, 1.3, -0.2) + field.layout.texel_centre(0, state.origin(0).unwrap());
    let view = GlobalFieldView::new(&state, camera.as_dvec3());
    let valid = GlobalFieldView::valid_bits(&state);
    let mut rng = Rng(3);
    let (mut both, mut edge) = (0, 0);
    for i in 0..20_000 {
        let p = camera + rng.vec(2.4 * (1 << (i % 3)) as f32);
        for first in 0..3 {
            let world = field.sample_from(&state, p, first);
            let relative = field.sample_view(&view, &valid, p - camera, first);
            match (world, relative) {
                (Some((a, la)), Some((b, lb))) if la == lb => {
                    assert!((a - b).abs() < 1e-4, "{p}: {a} {b}");
                    both += 1;
                }
                (None, None) => {}
                // A point on a window's edge: world positions 300 m out round
                // differently from camera-relative ones.
                _ => edge += 1,
            }
        }
    }
    assert!(
        both > 10_000 && edge * 2000 < both,
        "{both} agree, {edge} on edges"
    );
}
