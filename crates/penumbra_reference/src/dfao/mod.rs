//! Distance-field ambient occlusion: the CPU model of the trace, upsample and
//! specular-occlusion steps (`shaders/df/ao_trace.wgsl`, `df/ao_upsample.wgsl`,
//! `lighting/ao.wgsl`), and Monte Carlo ground truth on triangles.
//!
//! **The trace** ([`pixel_ao`]), after Wright 2015 and Unreal 4's DFAO: from a pixel's
//! position, lifted `bias` along its normal (for each baked field finer than that, 1.5 of
//! its voxels: [`penumbra_df_core::ao::object_bias`]), `n` cones
//! ([`penumbra_df_core::ao`]) are marched through every occluding object near enough to
//! matter. Per object and cone,
//! sphere tracing (steps of at least half the cone's radius) within the part of the
//! cone that meets the object's bounding ball; at each sample the object leaves
//! `d / r` of the cone open (`d` its distance, `r` the cone's radius there: Unreal's
//! approximate cone intersection, penumbra only — inside an object the cone is shut),
//! never less than `1 − (R / r)²` for an object of bounding radius `R` (small objects on
//! the axis dim a cone rather than close it). A caster with an AO transmission `τ`
//! ([`flags::ao_transmission`]: foliage, Unreal's softened occlusion of two-sided
//! distance fields) leaves `τ + (1 − τ) v` of a cone it would leave `v` of: it can dim
//! a cone to `τ`, never close it. A cone's visibility is the minimum over
//! its samples and over the objects; the AO is the mean over the cones (they carry
//! equal cosine weight), the bent normal the visibility-weighted sum of the cones'
//! centres, less the sum's bias when every cone is open (so an open surface's bent normal
//! is its normal), normalised.
//!
//! **Tiles** ([`trace_view`]): the GPU pass works in 8×8 tiles; each splits its pixels
//! into two ranges of distance from the camera (either side of the middle), bounds each
//! range by a ball, and keeps an object for a range when the object's ball, grown by the
//! influence distance, meets the range's ball and one distance sample at the ball's
//! centre minus its radius is within the influence distance. A pixel marches the objects
//! of its range only. For distance fields that are 1-Lipschitz (analytic shapes) this
//! never changes a result (tested: [`trace_view`] = [`pixel_ao`] per pixel).
//!
//! **Ground truth** ([`monte_carlo_ao`]): cosine-weighted stratified rays from the
//! surface point against the scene's triangles, limited to the same max distance: AO =
//! the unoccluded fraction, bent normal = the normalised mean unoccluded direction.

use crate::df::{Atlas, object_distance};
use crate::df_shadow::cone_interval;
use crate::shadow_mask::{bounding_sphere, cull_slack, facing_the_eye, position_from_depth};
use glam::{Mat3, Mat4, UVec2, Vec2, Vec3, Vec4};
use penumbra_df_core::ao::{
    AoTrace, MIN_STEP_FRACTION, TILE, cone_axis, cone_tan_half, cone_weight_direction, object_bias,
    tangent_frame,
};
use penumbra_df_core::cull::CameraOrigin;
use penumbra_df_core::object::{ObjectRecord, ShapeKind, flags};
use penumbra_df_core::shadow::SHELL_VOXELS;

/// One pixel's occlusion: AO (1 open, 0 occluded) and the unit bent normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AoSample {
    /// Unoccluded fraction of the cosine-weighted hemisphere.
    pub ao: f32,
    /// Unit mean unoccluded direction (world space).
    pub bent_normal: Vec3,
}

impl AoSample {
    /// An open pixel (and the background's value): AO 1, bent normal `n`.
    pub fn open(n: Vec3) -> AoSample {
        AoSample {
            ao: 1.0,
            bent_normal: n,
        }
    }

    /// As the GPU stores it: `(ao, bent_normal)`.
    pub fn to_vec4(self) -> Vec4 {
        Vec4::new(
            self.ao,
            self.bent_normal.x,
            self.bent_normal.y,
            self.bent_normal.z,
        )
    }
}

/// Whether the object `r` (ball `sphere`, `None` unbounded) can occlude a point at `p`.
fn in_reach(sphere: Option<(Vec3, f32)>, p: Vec3, influence: f32) -> bool {
    sphere.is_none_or(|(c, radius)| {
        (c - p).length() - radius < influence + cull_slack(radius + influence)
    })
}

/// The visibility of one cone (from receiver `p` of unit normal `n`, lifted
/// [`object_bias`] along it; unit `axis` rising `rise` per metre above the receiver's
/// tangent plane) through object `r`, and the distance evaluations it took. The cone's radius at a sample is capped by the sample's height
/// above the plane: the part of the cone below it is not in the hemisphere, and the
/// receiver's own surface is never nearer than that height. A two-sided field is read
/// as its surface, not its shell (the distance plus the shell, [`SHELL_VOXELS`]): a
/// receiver on it sits inside its own shell, which would otherwise close every cone.
#[allow(clippy::too_many_arguments, reason = "the march's inputs")]
fn march_cone(
    r: &ObjectRecord,
    sphere: Option<(Vec3, f32)>,
    (p, n): (Vec3, Vec3),
    axis: Vec3,
    rise: f32,
    tan_half: f32,
    trace: &AoTrace,
    camera: &CameraOrigin,
    atlas: &Atlas,
) -> (f32, u32) {
    let voxel = if r.kind() == ShapeKind::Volume as u32 {
        r.conservative_scale()
    } else {
        0.0
    };
    // A receiver inside an analytic shape is not occluded by it: the shape stands in for
    // the receiver's own mesh (a character's capsules).
    if r.kind() != ShapeKind::Volume as u32 && object_distance(r, p, camera, atlas) < 0.0 {
        return (1.0, 1);
    }
    let bias = object_bias(trace.bias, voxel);
    let o = p + n * bias;
    let (mut t, mut t_end) = (bias, trace.max_distance);
    if let Some((center, radius)) = sphere {
        let Some((t0, t1)) = cone_interval(o - center, axis, radius, tan_half) else {
            return (1.0, 0);
        };
        t = t.max(t0);
        t_end = t_end.min(t1);
    }
    let shell = if r.kind() == ShapeKind::Volume as u32 && r.flags() & flags::TWO_SIDED != 0 {
        SHELL_VOXELS * r.conservative_scale()
    } else {
        0.0
    };
    let mut v = 1.0f32;
    let mut evaluations = 0;
    for _ in 0..trace.steps_per_cone {
        if t >= t_end {
            break;
        }
        let d = object_distance(r, o + axis * t, camera, atlas);
        evaluations += 1;
        let cone = (t * tan_half).max(1e-6);
        let floor = sphere.map_or(0.0, |(_, radius)| 1.0 - (radius / cone).powi(2).min(1.0));
        let surface = d + shell;
        if surface <= 0.0 {
            v = v.min(floor);
            break;
        }
        let open = cone.min(bias + t * rise).max(1e-6);
        v = v.min((surface / open).max(floor));
        t += d.max(cone * MIN_STEP_FRACTION);
    }
    let v = v.clamp(0.0, 1.0).powf(trace.shaping);
    // A transmissive caster (foliage) lets `transmission` of what it covers through.
    let transmission = flags::ao_transmission(r.flags());
    (transmission + (1.0 - transmission) * v, evaluations)
}

/// The open fraction of a disc of radius 1 whose centre lies `x` from a straight edge
/// (negative: behind it): `½ + (asin x + x √(1 − x²)) / π`, 0 at −1, ½ at 0, 1 at 1.
pub fn disc_coverage(x: f32) -> f32 {
    let x = x.clamp(-1.0, 1.0);
    0.5 + (x.asin() + x * (1.0 - x * x).max(0.0).sqrt()) * std::f32::consts::FRAC_1_PI
}

/// Combines per-cone visibilities into the AO and bent normal (world space, around unit
/// normal `n`).
pub fn combine(visibility: &[f32], n: Vec3) -> AoSample {
    let count = visibility.len() as u32;
    let (t, b) = tangent_frame(n);
    let mut sum = Vec3::ZERO;
    let mut open = Vec3::ZERO;
    let mut ao = 0.0f32;
    for (k, &v) in visibility.iter().enumerate() {
        let w = cone_weight_direction(k as u32, count);
        sum += w * v;
        open += w;
        ao += v;
    }
    let ao = ao / count.max(1) as f32;
    // Less the open sum's sideways bias, in proportion: an open pixel bends nothing.
    let bent = sum - Vec3::new(open.x, open.y, 0.0) * ao;
    let world = t * bent.x + b * bent.y + n * bent.z;
    let len = world.length();
    AoSample {
        ao,
        bent_normal: if len > 1e-6 { world / len } else { n },
    }
}

/// The AO at camera-relative `p` with unit normal `n` over every occluding object of
/// `records` (the GPU pass's result without its tiles), and the distance evaluations.
pub fn pixel_ao_counted(
    records: &[ObjectRecord],
    atlas: &Atlas,
    camera: &CameraOrigin,
    p: Vec3,
    n: Vec3,
    trace: &AoTrace,
) -> (AoSample, u32) {
    pixel_ao_filtered(records, atlas, camera, p, n, trace, |_| true)
}

/// [`pixel_ao_counted`] without the count.
pub fn pixel_ao(
    records: &[ObjectRecord],
    atlas: &Atlas,
    camera: &CameraOrigin,
    p: Vec3,
    n: Vec3,
    trace: &AoTrace,
) -> AoSample {
    pixel_ao_counted(records, atlas, camera, p, n, trace).0
}

#[allow(clippy::too_many_arguments, reason = "the pass's inputs")]
fn pixel_ao_filtered(
    records: &[ObjectRecord],
    atlas: &Atlas,
    camera: &CameraOrigin,
    p: Vec3,
    n: Vec3,
    trace: &AoTrace,
    keep: impl Fn(usize) -> bool,
) -> (AoSample, u32) {
    let (visibility, evaluations) = cone_visibilities(records, atlas, camera, p, n, trace, keep);
    (combine(&visibility, n), evaluations)
}

/// Each cone's visibility through the objects of `records` that `keep` keeps, and the
/// distance evaluations.
#[allow(clippy::too_many_arguments, reason = "the pass's inputs")]
fn cone_visibilities(
    records: &[ObjectRecord],
    atlas: &Atlas,
    camera: &CameraOrigin,
    p: Vec3,
    n: Vec3,
    trace: &AoTrace,
    keep: impl Fn(usize) -> bool,
) -> (Vec<f32>, u32) {
    let count = trace.cone_count;
    let tan_half = cone_tan_half(count);
    let (t, b) = tangent_frame(n);
    let influence = trace.influence();
    let mut visibility = vec![1.0f32; count as usize];
    let mut evaluations = 0;
    for (slot, r) in records.iter().enumerate() {
        if !flags::casts_occlusion(r.flags()) || !keep(slot) {
            continue;
        }
        let sphere = bounding_sphere(r, camera);
        if !in_reach(sphere, p, influence) {
            continue;
        }
        for (k, v) in visibility.iter_mut().enumerate() {
            let a = cone_axis(k as u32, count);
            let axis = t * a.x + b * a.y + n * a.z;
            let (cone, e) =
                march_cone(r, sphere, (p, n), axis, a.z, tan_half, trace, camera, atlas);
            *v = v.min(cone);
            evaluations += e;
        }
    }
    (visibility, evaluations)
}

/// A view to trace: depth (reverse-Z, 0 background) and unit normals per pixel.
pub struct AoView<'a> {
    /// Inverse projection.
    pub view_from_clip: Mat4,
    /// Camera rotation.
    pub world_from_view: Mat3,
    /// View size, pixels.
    pub size: UVec2,
    /// Reverse-Z depth per pixel (row-major, top row first).
    pub depth: &'a [f32],
    /// Unit world normal per pixel (the G-buffer's).
    pub normals: &'a [Vec3],
}

/// Per tile of trace texels: its two distance ranges' balls.
struct TileRanges {
    split: f32,
    balls: [Option<(Vec3, f32)>; 2],
}

fn tile_ranges(points: &[(Vec3, f32)]) -> TileRanges {
    let (lo_d, hi_d) = points
        .iter()
        .fold((f32::MAX, f32::MIN), |(l, h), &(_, d)| (l.min(d), h.max(d)));
    let split = 0.5 * (lo_d + hi_d);
    let mut balls = [None, None];
    for (range, ball) in balls.iter_mut().enumerate() {
        let mut lo = Vec3::splat(f32::MAX);
        let mut hi = Vec3::splat(f32::MIN);
        for &(p, d) in points {
            if usize::from(d > split) == range {
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        if lo.x <= hi.x {
            *ball = Some(((lo + hi) * 0.5, (hi - lo).length() * 0.5));
        }
    }
    TileRanges { split, balls }
}

/// Whether object `r` may occlude some pixel in `ball` (the tile test): its ball grown
/// by the influence meets `ball`, and its distance at the ball's centre, less the ball's
/// radius, is within the influence.
pub fn tile_keeps(
    r: &ObjectRecord,
    ball: (Vec3, f32),
    influence: f32,
    camera: &CameraOrigin,
    atlas: &Atlas,
) -> bool {
    let (c, radius) = ball;
    if let Some((center, object_radius)) = bounding_sphere(r, camera) {
        let reach = object_radius + radius + influence;
        if (center - c).length() >= reach + cull_slack(reach) {
            return false;
        }
    }
    let d = object_distance(r, c, camera, atlas);
    d - radius < influence + cull_slack(radius + influence)
}

/// The trace pass over a view (`trace_size` texels at `divisor`, texel `(i, j)` tracing
/// pixel `(i, j) · divisor + jitter`), with its 8×8 tiles and two ranges per tile:
/// `(ao, bent normal)` per texel; background texels are `(1, 0, 0, 0)`.
pub fn trace_view(
    records: &[ObjectRecord],
    atlas: &Atlas,
    camera: &CameraOrigin,
    view: &AoView,
    divisor: u32,
    jitter: UVec2,
    trace: &AoTrace,
) -> Vec<Vec4> {
    trace_view_counted(records, atlas, camera, view, divisor, jitter, trace).0
}

/// [`trace_view`] and the distance evaluations of its texels' marches (the tile tests'
/// one sample per object and range not counted).
pub fn trace_view_counted(
    records: &[ObjectRecord],
    atlas: &Atlas,
    camera: &CameraOrigin,
    view: &AoView,
    divisor: u32,
    jitter: UVec2,
    trace: &AoTrace,
) -> (Vec<Vec4>, u64) {
    let mut evaluations = 0u64;
    let size = penumbra_df_core::ao::trace_size(view.size, divisor);
    let mut out = vec![Vec4::new(1.0, 0.0, 0.0, 0.0); (size.x * size.y) as usize];
    let influence = trace.influence();
    for_each_tile_texel(
        records,
        atlas,
        camera,
        view,
        (divisor, jitter),
        influence,
        |texel, p, n, kept| {
            let (s, e) = pixel_ao_filtered(records, atlas, camera, p, n, trace, |slot| kept[slot]);
            evaluations += u64::from(e);
            out[(texel.y * size.x + texel.x) as usize] = s.to_vec4();
        },
    );
    (out, evaluations)
}

/// The objects-per-tile debug view's numbers: per trace texel (as [`trace_view`]), how
/// many objects its tile keeps for the texel's distance range (0 for background).
pub fn tile_object_counts(
    records: &[ObjectRecord],
    atlas: &Atlas,
    camera: &CameraOrigin,
    view: &AoView,
    divisor: u32,
    jitter: UVec2,
    trace: &AoTrace,
) -> Vec<u32> {
    let size = penumbra_df_core::ao::trace_size(view.size, divisor);
    let mut out = vec![0; (size.x * size.y) as usize];
    for_each_tile_texel(
        records,
        atlas,
        camera,
        view,
        (divisor, jitter),
        trace.influence(),
        |texel, _, _, kept| {
            out[(texel.y * size.x + texel.x) as usize] = kept.iter().filter(|&&k| k).count() as u32;
        },
    );
    out
}

/// Calls `visit(texel, position, normal, kept)` for every surface texel of the trace at
/// `(divisor, jitter)`, `kept[slot]` telling whether its tile keeps object `slot` for
/// the texel's distance range.
fn for_each_tile_texel(
    records: &[ObjectRecord],
    atlas: &Atlas,
    camera: &CameraOrigin,
    view: &AoView,
    (divisor, jitter): (u32, UVec2),
    influence: f32,
    mut visit: impl FnMut(UVec2, Vec3, Vec3, &[bool]),
) {
    let size = penumbra_df_core::ao::trace_size(view.size, divisor);
    let pixel_of = |i: u32, j: u32| {
        let p = UVec2::new(i, j) * divisor.max(1) + jitter;
        p.min(view.size - UVec2::ONE)
    };
    for ty in (0..size.y).step_by(TILE as usize) {
        for tx in (0..size.x).step_by(TILE as usize) {
            let mut texels = Vec::new();
            for j in ty..(ty + TILE).min(size.y) {
                for i in tx..(tx + TILE).min(size.x) {
                    let px = pixel_of(i, j);
                    let k = (px.y * view.size.x + px.x) as usize;
                    let depth = view.depth[k];
                    if depth > 0.0 {
                        let p = position_from_depth(
                            view.view_from_clip,
                            view.world_from_view,
                            view.size.as_vec2(),
                            px.as_vec2(),
                            depth,
                        );
                        // Turned to face the eye (`ao_trace.wgsl`): an inverted normal
                        // would start the cones inside the receiver's own caster.
                        texels.push((UVec2::new(i, j), p, facing_the_eye(view.normals[k], p)));
                    }
                }
            }
            if texels.is_empty() {
                continue;
            }
            let points: Vec<(Vec3, f32)> =
                texels.iter().map(|&(_, p, _)| (p, p.length())).collect();
            let ranges = tile_ranges(&points);
            let kept: [Vec<bool>; 2] = std::array::from_fn(|range| {
                records
                    .iter()
                    .map(|r| {
                        ranges.balls[range].is_some_and(|ball| {
                            flags::casts_occlusion(r.flags())
                                && tile_keeps(r, ball, influence, camera, atlas)
                        })
                    })
                    .collect()
            });
            for (texel, p, n) in texels {
                let range = usize::from(p.length() > ranges.split);
                visit(texel, p, n, &kept[range]);
            }
        }
    }
}

/// Ground truth: `rays_sqrt²` cosine-weighted stratified rays (concentric disc mapping)
/// from `p + n · 10⁻⁴` against `bvh`'s triangles, each blocked when it hits one within
/// `max_distance`.
pub fn monte_carlo_ao(
    bvh: &penumbra_sdf::bvh::Bvh,
    p: Vec3,
    n: Vec3,
    max_distance: f32,
    rays_sqrt: u32,
) -> AoSample {
    let (t, b) = tangent_frame(n);
    let origin = p + n * 1e-4 * (1.0 + p.abs().max_element());
    let mut open = 0u32;
    let mut sum = Vec3::ZERO;
    for i in 0..rays_sqrt {
        for j in 0..rays_sqrt {
            let u = Vec2::new(
                (i as f32 + 0.5) / rays_sqrt as f32,
                (j as f32 + 0.5) / rays_sqrt as f32,
            );
            let d = concentric_disc(u);
            let local = Vec3::new(d.x, d.y, (1.0 - d.length_squared()).max(0.0).sqrt());
            let dir = (t * local.x + b * local.y + n * local.z).normalize();
            if bvh.ray_nearest(origin, dir, 0.0, max_distance).is_none() {
                open += 1;
                sum += dir;
            }
        }
    }
    let len = sum.length();
    AoSample {
        ao: open as f32 / (rays_sqrt * rays_sqrt).max(1) as f32,
        bent_normal: if len > 1e-6 { sum / len } else { n },
    }
}

/// Shirley and Chiu's concentric map of `[0, 1]²` onto the unit disc (area-preserving).
fn concentric_disc(u: Vec2) -> Vec2 {
    let a = u * 2.0 - Vec2::ONE;
    if a == Vec2::ZERO {
        return Vec2::ZERO;
    }
    let (r, phi) = if a.x.abs() > a.y.abs() {
        (a.x, std::f32::consts::FRAC_PI_4 * (a.y / a.x))
    } else {
        (
            a.y,
            std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (a.x / a.y),
        )
    };
    Vec2::new(r * phi.cos(), r * phi.sin())
}

mod apply;
mod far;
mod heightfield;
mod temporal;
#[cfg(test)]
mod temporal_tests;
#[cfg(test)]
mod tests;

pub use far::{
    FarField, march_field, pixel_ao_far, pixel_ao_with_terrain, trace_view_far,
    trace_view_with_terrain,
};
pub use heightfield::{
    heightfield_ao, heightfield_visibilities, march_terrain, texture_visibilities,
};
pub use temporal::{AoHistory, TemporalFrame, TemporalSteps, temporal_step};

pub use apply::{
    SpecularOcclusion, TraceSource, UPSAMPLE_DEPTH_TOLERANCE, UPSAMPLE_NORMAL_POWER, blend,
    cone_cone_intersection, finish_ao, specular_occlusion, upsample, upsample_samples,
};
