//! DFAO against a heightfield (terrain): each cone sphere-traces the heightfield's
//! conservative distance (`penumbra_df_core::heightfield`) from the surface bias to the
//! max distance with the approximate cone intersection of the object trace — `d / r`,
//! `r` capped by the sample's height over the receiver's plane, the cone shut where a
//! sample is under the terrain — and the same shaping. The heightfield is one caster:
//! its visibility joins the objects' by the minimum per cone.

use super::{AoSample, combine};
use glam::{IVec3, Vec3};
use penumbra_df_core::ao::{AoTrace, MIN_STEP_FRACTION, cone_axis, cone_tan_half, tangent_frame};
use penumbra_df_core::cull::CameraOrigin;
use penumbra_df_core::heightfield::{Heightfield, HeightfieldTexture};
use penumbra_df_core::object::TILE_SIZE;

/// Each cone's visibility through `terrain` from world `p` (unit normal `n`), and the
/// distance evaluations.
pub fn heightfield_visibilities(
    terrain: &Heightfield,
    p: Vec3,
    n: Vec3,
    trace: &AoTrace,
) -> (Vec<f32>, u32) {
    let count = trace.cone_count;
    let tan_half = cone_tan_half(count);
    let (t, b) = tangent_frame(n);
    let o = p + n * trace.bias;
    let mut evaluations = 0;
    let visibility = (0..count)
        .map(|k| {
            let a = cone_axis(k, count);
            let axis = t * a.x + b * a.y + n * a.z;
            let (v, e) = march_terrain(|q| terrain.distance(q), o, axis, a.z, tan_half, trace);
            evaluations += e;
            v
        })
        .collect();
    (visibility, evaluations)
}

/// One cone's shaped visibility through a terrain whose distance is `distance`, from
/// `o` (the receiver lifted by the bias) along `axis` (rising `rise` over the
/// receiver's plane), and the evaluations.
pub fn march_terrain(
    distance: impl Fn(Vec3) -> f32,
    o: Vec3,
    axis: Vec3,
    rise: f32,
    tan_half: f32,
    trace: &AoTrace,
) -> (f32, u32) {
    let mut s = trace.bias;
    let mut v = 1.0f32;
    let mut evaluations = 0;
    for _ in 0..trace.steps_per_cone {
        if s >= trace.max_distance {
            break;
        }
        let d = distance(o + axis * s);
        evaluations += 1;
        let cone = (s * tan_half).max(1e-6);
        if d <= 0.0 {
            v = 0.0;
            break;
        }
        let open = cone.min(trace.bias + s * rise).max(1e-6);
        v = v.min(d / open);
        s += d.max(cone * MIN_STEP_FRACTION);
    }
    (v.clamp(0.0, 1.0).powf(trace.shaping), evaluations)
}

/// Each cone's visibility through the terrains of `texture` from camera-relative `p`
/// (unit normal `n`) as the trace pass computes it (`shaders/df/ao_trace.wgsl`): per
/// terrain in its tile's frame ([`HeightfieldTexture::distance`]), skipped where the
/// terrain's box is beyond the trace's influence of `p`; the minimum over terrains. And
/// the evaluations.
pub fn texture_visibilities(
    texture: &HeightfieldTexture,
    camera: &CameraOrigin,
    p: Vec3,
    n: Vec3,
    trace: &AoTrace,
) -> (Vec<f32>, u32) {
    let count = trace.cone_count;
    let mut visibility = vec![1.0f32; count as usize];
    let mut evaluations = 0;
    let tan_half = cone_tan_half(count);
    let (t, b) = tangent_frame(n);
    for h in &texture.records {
        let base = (IVec3::from_array(camera.tile) - h.tile).as_vec3() * TILE_SIZE + camera.offset;
        let local = base + p;
        let (lo, hi) = h.aabb();
        if (lo - local).max(local - hi).max(Vec3::ZERO).length() >= trace.influence() {
            continue;
        }
        let o = local + n * trace.bias;
        for (k, v) in visibility.iter_mut().enumerate() {
            let a = cone_axis(k as u32, count);
            let axis = t * a.x + b * a.y + n * a.z;
            let (cone, e) =
                march_terrain(|q| texture.distance(h, q), o, axis, a.z, tan_half, trace);
            *v = v.min(cone);
            evaluations += e;
        }
    }
    (visibility, evaluations)
}

/// The AO and bent normal at world `p` (unit normal `n`) from `terrain` alone.
pub fn heightfield_ao(terrain: &Heightfield, p: Vec3, n: Vec3, trace: &AoTrace) -> AoSample {
    let (visibility, _) = heightfield_visibilities(terrain, p, n, trace);
    combine(&visibility, n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dfao::monte_carlo_ao;
    use crate::test_terrain::{receivers, triangles, valley, valley_at};
    use glam::Vec2;
    use penumbra_df_core::ao::CONE_SHAPING;

    /// Receivers over a valley's floor and its slopes (normals from the surface),
    /// against cosine-weighted Monte Carlo rays on the triangulated terrain, reach 5 m:
    /// mean |ΔAO| 0.072, within 0.08 (the object trace's error on the bench's scenes),
    /// where ignoring the terrain (AO 1) errs by 0.165.
    #[test]
    fn terrain_ao_matches_ray_traced_truth() {
        let h = valley();
        let bvh = penumbra_sdf::bvh::Bvh::build(&triangles(&h));
        let trace = AoTrace {
            max_distance: 5.0,
            cone_count: 9,
            steps_per_cone: 16,
            bias: 0.02,
            shaping: CONE_SHAPING,
        };
        let (mut error, mut blind, mut count) = (0.0f32, 0.0f32, 0);
        for j in 0..8 {
            for i in 0..12 {
                let xz = Vec2::new(-5.5 + i as f32, -8.0 + 2.0 * j as f32);
                let e = 0.05;
                let g = Vec2::new(
                    h.height(xz + Vec2::X * e) - h.height(xz - Vec2::X * e),
                    h.height(xz + Vec2::Y * e) - h.height(xz - Vec2::Y * e),
                ) / (2.0 * e);
                let n = Vec3::new(-g.x, 1.0, -g.y).normalize();
                let p = Vec3::new(xz.x, h.height(xz), xz.y);
                let truth = monte_carlo_ao(&bvh, p, n, trace.max_distance, 24).ao;
                let model = heightfield_ao(&h, p, n, &trace).ao;
                error += (model - truth).abs();
                blind += 1.0 - truth;
                count += 1;
            }
        }
        let (error, blind) = (error / count as f32, blind / count as f32);
        eprintln!("terrain AO: mean |Δ| {error:.4}; ignoring the terrain {blind:.4}");
        assert!(error < 0.08 && blind > 0.15, "{error} {blind}");
    }

    /// The trace pass's arithmetic (terrain texture, camera-relative, tile frames)
    /// gives the world-space cones' visibilities, near the origin and in another tile
    /// (1.7 km out, where the world-space side's own f32 rounding, 0.1 mm, moves a few
    /// cone samples: 0.05 at most, 10⁻³ on average; a wrong tile frame is off by far
    /// more).
    #[test]
    fn the_pass_arithmetic_gives_the_terrain_cones() {
        use penumbra_df_core::cull::CameraOrigin;
        use penumbra_df_core::heightfield::HeightfieldTexture;
        let trace = AoTrace {
            max_distance: 5.0,
            cone_count: 9,
            steps_per_cone: 16,
            bias: 0.02,
            shaping: CONE_SHAPING,
        };
        for offset in [Vec3::ZERO, Vec3::new(1700.0, 20.0, -900.0)] {
            let v = valley();
            let h = valley_at(offset);
            let (texture, _) = HeightfieldTexture::pack(&[&h], 4096);
            let camera = offset + Vec3::new(0.3, 4.0, -0.2);
            let origin = CameraOrigin::at(camera).expect("finite");
            let (mut worst, mut sum, mut count) = (0.0f32, 0.0f32, 0);
            for (p, n) in receivers(&v) {
                let p = p + offset;
                let (want, _) = heightfield_visibilities(&h, p, n, &trace);
                let (got, _) = texture_visibilities(&texture, &origin, p - camera, n, &trace);
                for (a, b) in want.iter().zip(&got) {
                    worst = worst.max((a - b).abs());
                    sum += (a - b).abs();
                    count += 1;
                }
            }
            let mean = sum / count as f32;
            eprintln!("{offset}: cones apart by {worst:.2e} at most, {mean:.2e} on average");
            let tolerance = if offset == Vec3::ZERO { 1e-4 } else { 0.05 };
            assert!(
                worst <= tolerance && mean <= 1e-3,
                "{offset}: {worst} {mean}"
            );
        }
    }

    /// The valley composed into the global field (`compose_records_and_terrain`, the
    /// compose pass's model; no objects): the field is never more than a texel diagonal
    /// above the exact distance to the triangulated terrain; and with a 12 m reach,
    /// cones tracing the terrain to 3 m (the default switch) and the field beyond are
    /// within 0.134 of Monte Carlo rays (bound 0.16), where the field without the terrain
    /// errs by 0.352 (the terrain's own trace all the way: 0.090 — the field's dilation
    /// over-occludes, as for objects).
    #[test]
    fn terrain_in_the_global_field_matches_ray_traced_truth() {
        use crate::df::Atlas;
        use crate::dfao::{FarField, march_field};
        use crate::global_sdf::{ClipmapFormat, GlobalField};
        use penumbra_df_core::clipmap::{ClipmapLayout, ClipmapState};
        use penumbra_df_core::heightfield::HeightfieldTexture;
        let h = valley();
        let bvh = penumbra_sdf::bvh::Bvh::build(&triangles(&h));
        let camera = Vec3::new(0.3, 4.0, -0.2);
        let layout = ClipmapLayout::DEFAULT;
        let (texture, refused) = HeightfieldTexture::pack(&[&h], 4096);
        assert!(refused.is_empty());
        let atlas = Atlas::new(glam::UVec3::ONE);
        let mut state = ClipmapState::new(layout);
        let mut field = GlobalField::new(layout, ClipmapFormat::Unorm8);
        let mut bare = GlobalField::new(layout, ClipmapFormat::Unorm8);
        for job in state.update(camera, &[], usize::MAX).jobs {
            field.compose_records_and_terrain(job, &[], &atlas, &texture);
            bare.compose_records(job, &[], &atlas);
        }
        // Conservative: sample points over the rectangle, within 3 m of the surface.
        let mut worst = f32::NEG_INFINITY;
        for j in 0..40 {
            for i in 0..40 {
                let xz = Vec2::new(-19.0 + 0.95 * i as f32, -19.0 + 0.95 * j as f32);
                let y = h.height(xz) - 1.0 + 0.1 * ((i * 7 + j * 3) % 40) as f32;
                let p = Vec3::new(xz.x, y, xz.y);
                let Some((v, level)) = field.sample(&state, p) else {
                    continue;
                };
                let exact = bvh
                    .closest(p, f32::INFINITY, &[])
                    .map_or(f32::INFINITY, |c| c.distance_squared.sqrt());
                let d = if y < h.height(xz) { -exact } else { exact };
                let diagonal = layout.texel(level) * 3f32.sqrt();
                let band = layout.band(level);
                // The triangles lie within 1 cm of the bilinear patches.
                assert!(v <= d.max(-band) + diagonal + 0.01, "{p}: {v} truth {d}");
                worst = worst.max((v - d) / diagonal);
            }
        }
        assert!(worst > -1.0, "the field is far below the truth: {worst}");
        let trace = AoTrace {
            max_distance: 12.0,
            cone_count: 9,
            steps_per_cone: 16,
            bias: 0.02,
            shaping: CONE_SHAPING,
        };
        const SWITCH: f32 = 3.0;
        let (mut error, mut blind, mut own, mut count) = (0.0f32, 0.0f32, 0.0f32, 0);
        for (p, n) in receivers(&h) {
            let truth = monte_carlo_ao(&bvh, p, n, trace.max_distance, 24).ao;
            // The terrain's own trace up to the switch, the field beyond (DFAO's far
            // field with the terrain among the near casters).
            let ao = |field: &GlobalField| {
                let far = FarField::new(field, &state, camera.as_dvec3(), SWITCH);
                let near = AoTrace {
                    max_distance: SWITCH,
                    ..trace
                };
                let (mut v, _) = heightfield_visibilities(&h, p, n, &near);
                let (t, b) = tangent_frame(n);
                for (k, v) in v.iter_mut().enumerate() {
                    let a = cone_axis(k as u32, trace.cone_count);
                    let axis = t * a.x + b * a.y + n * a.z;
                    let o = p - camera + n * trace.bias;
                    let tan_half = cone_tan_half(trace.cone_count);
                    *v = v.min(march_field(&far, o, axis, a.z, tan_half, &trace).0);
                }
                combine(&v, n).ao
            };
            error += (ao(&field) - truth).abs();
            blind += (ao(&bare) - truth).abs();
            own += (heightfield_ao(&h, p, n, &trace).ao - truth).abs();
            count += 1;
        }
        let (error, blind) = (error / count as f32, blind / count as f32);
        let own = own / count as f32;
        eprintln!(
            "terrain AO to 12 m: through the field beyond 3 m, mean |Δ| {error:.4}; \
             the field without the terrain {blind:.4}; the terrain's own trace all the way {own:.4}"
        );
        assert!(error < 0.16 && blind > 0.3, "{error} {blind}");
    }
}
