//! CPU model of the global field's debug views (`shaders/df/global_field_debug.wgsl`,
//! #17 item 7): each pixel's camera ray is sphere-traced through the clipmaps as the
//! GPU reads them ([`GlobalField::sample_view`]: the finest valid level), the surface
//! distance being the stored value plus the level's dilation; a hit is a distance
//! under a quarter of the answering level's texel. The surface is Lambert-shaded by
//! the field's gradient ([`field_normal`]), and tinted by its level
//! ([`FieldDebugMode::Levels`]) or, where its storage brick was composed this frame,
//! orange ([`FieldDebugMode::Updates`]).

use crate::global_sdf::GlobalField;
use crate::particles::field_normal;
use glam::{IVec3, Mat4, Vec2, Vec3, Vec4};
use penumbra_df_core::clipmap::debug::{FieldDebugMode, LEVEL_COLORS};
use penumbra_df_core::clipmap::{BRICK, GlobalFieldView};

/// Where a debug ray stopped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FieldHit {
    /// Distance along the ray, metres.
    pub t: f32,
    /// The clipmap level that answered there.
    pub level: u32,
}

/// What a global-field debug view traces.
pub struct FieldDebugScene<'a> {
    /// The clipmaps' texels.
    pub field: &'a GlobalField,
    /// The camera's view of them.
    pub view: &'a GlobalFieldView,
    /// Validity bits ([`GlobalFieldView::valid_bits`]).
    pub valid: &'a [u32],
    /// Bits of the bricks composed this frame, laid out as `valid`
    /// (`clipmap::debug::composed_bits`).
    pub updated: &'a [u32],
    /// Inverse of the camera-relative view-projection.
    pub relative_from_clip: Mat4,
    /// Step limit.
    pub max_steps: u32,
    /// Trace length, metres.
    pub max_distance: f32,
}

/// Background of rays that hit nothing.
pub const MISS: Vec3 = Vec3::new(0.05, 0.05, 0.08);
/// The tint of bricks composed this frame.
pub const UPDATED: Vec3 = Vec3::new(1.0, 0.45, 0.1);

impl FieldDebugScene<'_> {
    /// The ray direction through `uv` ((0, 0) = top-left image corner).
    pub fn ray(&self, uv: Vec2) -> Vec3 {
        let ndc = Vec2::new(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
        let on_ray = self.relative_from_clip * Vec4::new(ndc.x, ndc.y, 0.5, 1.0);
        (on_ray.truncate() / on_ray.w).normalize()
    }

    /// Sphere tracing along `dir` from the camera; `None` where the ray leaves the
    /// clipmaps, runs out of steps or of length first.
    pub fn trace(&self, dir: Vec3) -> Option<FieldHit> {
        let mut t = 0.0f32;
        for _ in 0..self.max_steps {
            if t >= self.max_distance {
                return None;
            }
            let (d, level) = self.field.sample_view(self.view, self.valid, dir * t, 0)?;
            let l = &self.view.levels[level as usize];
            let d = d + l.dilation;
            if d < 0.25 * l.texel {
                return Some(FieldHit { t, level });
            }
            t += d;
        }
        None
    }

    /// Whether the storage brick holding camera-relative `p` in `level` was composed
    /// this frame.
    pub fn updated_at(&self, level: u32, p: Vec3) -> bool {
        let l = &self.view.levels[level as usize];
        let n = self.view.resolution as i32;
        let w = ((p + l.camera) / l.texel).floor().as_ivec3();
        let b = (l.origin_mod + w).rem_euclid(IVec3::splat(n)) / BRICK as i32;
        let nb = self.view.bricks_per_side as i32;
        let bit = (b.x + nb * (b.y + nb * b.z)) as u32;
        self.updated[(level * self.view.valid_words + bit / 32) as usize] >> (bit % 32) & 1 == 1
    }
}

/// Linear RGB of the debug view at `uv`.
pub fn field_debug_pixel(scene: &FieldDebugScene, mode: FieldDebugMode, uv: Vec2) -> Vec3 {
    let dir = scene.ray(uv);
    let Some(hit) = scene.trace(dir) else {
        return MISS;
    };
    let p = dir * hit.t;
    let n = field_normal(scene.field, scene.view, scene.valid, p).map_or(-dir, |(_, n)| n);
    let light = Vec3::new(0.4, 0.8, 0.3).normalize();
    let c = 0.8 * (0.15 + 0.85 * n.dot(light).max(0.0));
    match mode {
        FieldDebugMode::Levels => c * Vec3::from(LEVEL_COLORS[hit.level as usize]),
        FieldDebugMode::Updates if scene.updated_at(hit.level, p) => c * UPDATED,
        FieldDebugMode::Shaded | FieldDebugMode::Updates => Vec3::splat(c),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::global_sdf::{AnalyticCaster, ClipmapFormat, FieldObject, analytic_distance};
    use penumbra_df_core::clipmap::debug::composed_bits;
    use penumbra_df_core::clipmap::{ClipmapLayout, ClipmapState, ComposeJob};

    const SIZE: u32 = 64;

    fn scene(ball: Vec3) -> Vec<AnalyticCaster> {
        vec![
            AnalyticCaster::Cuboid {
                centre: Vec3::new(0.0, -0.5, 0.0),
                half: Vec3::new(30.0, 0.5, 30.0),
            },
            AnalyticCaster::Sphere {
                centre: Vec3::new(-1.0, 1.0, -1.0),
                radius: 1.0,
            },
            AnalyticCaster::Sphere {
                centre: ball,
                radius: 0.4,
            },
        ]
    }

    struct Setup {
        layout: ClipmapLayout,
        state: ClipmapState,
        field: GlobalField,
        camera: Vec3,
        relative_from_clip: Mat4,
    }

    /// The scene composed from scratch around a camera looking at it.
    fn setup(casters: &[AnalyticCaster]) -> Setup {
        let (layout, _) = ClipmapLayout::new(3, 64, 12.8, 2.0);
        let camera = Vec3::new(0.6, 2.4, 5.0);
        let objects: Vec<FieldObject> = casters.iter().map(|c| c.field_object()).collect();
        let mut state = ClipmapState::new(layout);
        let mut field = GlobalField::new(layout, ClipmapFormat::Unorm8);
        for job in state.update(camera, &[], usize::MAX).jobs {
            field.compose(job, &objects);
        }
        let view = Mat4::look_at_rh(camera, Vec3::new(0.0, 0.5, 0.0), Vec3::Y);
        let view = Mat4::from_mat3(glam::Mat3::from_mat4(view));
        let proj = Mat4::perspective_infinite_reverse_rh(0.9, 1.0, 0.1);
        Setup {
            layout,
            state,
            field,
            camera,
            relative_from_clip: (proj * view).inverse(),
        }
    }

    fn pixels() -> impl Iterator<Item = Vec2> {
        (0..SIZE * SIZE)
            .map(|i| Vec2::new((i % SIZE) as f32 + 0.5, (i / SIZE) as f32 + 0.5) / SIZE as f32)
    }

    /// Exact sphere tracing of the analytic scene: (hit t, closest approach).
    fn exact(casters: &[AnalyticCaster], o: Vec3, dir: Vec3) -> (Option<f32>, f32) {
        let (mut t, mut closest) = (0.0f32, f32::INFINITY);
        for _ in 0..2000 {
            let d = analytic_distance(casters, o + dir * t);
            closest = closest.min(d);
            if d < 1e-5 {
                return (Some(t), 0.0);
            }
            t += d;
            if t > 60.0 {
                break;
            }
        }
        (None, closest)
    }

    /// Against exact ray casts of the analytic scene: the traced surface lies within a
    /// texel of the true one, hits and misses differ only at silhouettes, the shading
    /// follows the true normal, and the level that answers is the finest holding the
    /// point.
    #[test]
    fn the_traced_field_matches_exact_ray_casts() {
        let casters = scene(Vec3::new(1.2, 0.4, 0.5));
        let s = setup(&casters);
        let view = GlobalFieldView::new(&s.state, s.camera.as_dvec3());
        let valid = GlobalFieldView::valid_bits(&s.state);
        let updated = vec![0u32; valid.len()];
        let debug = FieldDebugScene {
            field: &s.field,
            view: &view,
            valid: &valid,
            updated: &updated,
            relative_from_clip: s.relative_from_clip,
            max_steps: 128,
            max_distance: 40.0,
        };
        let texel = s.layout.texel(0);
        let light = Vec3::new(0.4, 0.8, 0.3).normalize();
        let (mut hits, mut worst, mut mismatched, mut shade_err) = (0, 0.0f32, 0, 0.0f32);
        let mut beyond = 0;
        let mut levels = [0usize; 3];
        for uv in pixels() {
            let dir = debug.ray(uv);
            let (truth, closest) = exact(&casters, s.camera, dir);
            let hit = debug.trace(dir);
            match (hit, truth) {
                (Some(hit), Some(_)) => {
                    hits += 1;
                    let p = s.camera + dir * hit.t;
                    // In the answering level's texels.
                    let d = analytic_distance(&casters, p).abs() / s.layout.texel(hit.level);
                    worst = worst.max(d);
                    levels[hit.level as usize] += 1;
                    // The finest level whose window (centred within a brick) holds p.
                    let half = |l: u32| 0.5 * s.layout.extent(l) - BRICK as f32 * s.layout.texel(l);
                    let rel = (p - s.camera).abs().max_element();
                    if rel < half(0) {
                        assert_eq!(hit.level, 0, "at {p}");
                    }
                    let e = 1e-3;
                    let g = |a: Vec3| {
                        analytic_distance(&casters, p + a * e)
                            - analytic_distance(&casters, p - a * e)
                    };
                    let n = Vec3::new(g(Vec3::X), g(Vec3::Y), g(Vec3::Z)).normalize();
                    let want = 0.8 * (0.15 + 0.85 * n.dot(light).max(0.0));
                    let got = field_debug_pixel(&debug, FieldDebugMode::Shaded, uv).x;
                    shade_err += (got - want).abs();
                }
                (None, None) => {}
                (None, Some(t)) => {
                    // Beyond the clipmaps, or a grazing ray at a silhouette.
                    let p = s.camera + dir * t;
                    let last = s.layout.levels - 1;
                    let inside = (p - s.camera).abs().max_element()
                        < 0.5 * s.layout.extent(last) - BRICK as f32 * s.layout.texel(last);
                    if inside {
                        mismatched += 1;
                        let e = 1e-3;
                        let g = |a: Vec3| {
                            analytic_distance(&casters, p + a * e)
                                - analytic_distance(&casters, p - a * e)
                        };
                        let n = Vec3::new(g(Vec3::X), g(Vec3::Y), g(Vec3::Z)).normalize();
                        assert!(n.dot(dir).abs() < 0.3, "a miss at {p}, not grazing");
                    } else {
                        beyond += 1;
                    }
                }
                (Some(_), None) => {
                    mismatched += 1;
                    assert!(closest < 1.5 * texel, "a hit {closest} m from any surface");
                }
            }
        }
        let shade_err = shade_err / hits as f32;
        eprintln!(
            "{hits} hits, worst |d| {worst:.3} texels, {mismatched} silhouette \
             mismatches, {beyond} beyond the clipmaps, mean |Δ shade| {shade_err:.3}, \
             levels {levels:?}"
        );
        assert!(worst < 1.0, "{worst}");
        assert!(mismatched * 200 < (SIZE * SIZE) as usize, "{mismatched}");
        assert!(shade_err < 0.05, "{shade_err}");
        assert!(levels[0] > 0 && levels[1] > 0, "{levels:?}");
        // The level view tints by level.
        let uv = pixels()
            .find(|uv| debug.trace(debug.ray(*uv)).is_some_and(|h| h.level == 1))
            .expect("a level-1 pixel");
        let c = field_debug_pixel(&debug, FieldDebugMode::Levels, uv);
        let grey = field_debug_pixel(&debug, FieldDebugMode::Shaded, uv).x;
        assert!((c - grey * Vec3::from(LEVEL_COLORS[1])).abs().max_element() < 1e-6);
    }

    /// After the small ball moves 1 m, the update view shows its old and new places in
    /// orange and the big sphere away from both grey; a frame later, with nothing
    /// moving, nothing is orange.
    #[test]
    fn the_update_view_shows_the_bricks_composed_this_frame() {
        let (from, to) = (Vec3::new(1.2, 0.4, 0.5), Vec3::new(1.2, 0.4, -0.5));
        let before = scene(from);
        let mut s = setup(&before);
        let after = scene(to);
        let objects: Vec<FieldObject> = after.iter().map(|c| c.field_object()).collect();
        let dirty = [before[2].dirty(), after[2].dirty()];
        let view = GlobalFieldView::new(&s.state, s.camera.as_dvec3());
        let mut counts = Vec::new();
        for frame in 0..2 {
            let update =
                s.state
                    .update(s.camera, if frame == 0 { &dirty } else { &[] }, usize::MAX);
            let jobs: Vec<ComposeJob> = update
                .jobs
                .iter()
                .map(|j| ComposeJob::new(&s.layout, *j))
                .collect();
            for job in &update.jobs {
                s.field.compose(*job, &objects);
            }
            let valid = GlobalFieldView::valid_bits(&s.state);
            let updated = composed_bits(&s.layout, &jobs);
            let debug = FieldDebugScene {
                field: &s.field,
                view: &view,
                valid: &valid,
                updated: &updated,
                relative_from_clip: s.relative_from_clip,
                max_steps: 128,
                max_distance: 40.0,
            };
            let (mut on_ball, mut orange_ball, mut far_orange) = (0, 0, 0);
            for uv in pixels() {
                let dir = debug.ray(uv);
                let Some(hit) = debug.trace(dir) else {
                    continue;
                };
                let p = s.camera + dir * hit.t;
                let c = field_debug_pixel(&debug, FieldDebugMode::Updates, uv);
                let orange = c.x > 2.0 * c.z;
                if (p - to).length() < 0.45 {
                    on_ball += 1;
                    orange_ball += usize::from(orange);
                }
                let reach = 0.4
                    + s.layout.reach(hit.level)
                    + 2.0 * BRICK as f32 * s.layout.texel(hit.level);
                if (p - to).length().min((p - from).length()) > reach {
                    far_orange += usize::from(orange);
                }
            }
            eprintln!(
                "frame {frame}: {} jobs, ball {orange_ball}/{on_ball} orange, {far_orange} \
                 orange far from it",
                jobs.len()
            );
            counts.push((jobs.len(), on_ball, orange_ball, far_orange));
        }
        let (jobs, on_ball, orange_ball, far) = counts[0];
        assert!(jobs > 0 && on_ball > 20 && orange_ball == on_ball && far == 0);
        let (jobs, _, orange_ball, far) = counts[1];
        assert!(jobs == 0 && orange_ball == 0 && far == 0);
    }
}
