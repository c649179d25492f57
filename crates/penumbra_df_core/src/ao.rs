//! The GPU parameters of distance-field ambient occlusion (DFAO): the cone set every
//! pixel traces ([`cone_axis`], [`cone_weight_direction`], [`cone_tan_half`]) and the
//! trace pass's view uniform ([`AoTraceView`], `AoTraceView` in
//! `shaders/df/ao_trace.wgsl`, laid out by `encase` as WGSL lays it out).
//!
//! **Cones.** `n` cones cover the hemisphere around the surface normal with equal
//! cosine weight: their centres are a Fibonacci spiral on the unit disc (`ρ_k =
//! √((k + ½) / n)`, `φ_k = k · 137.5°`) lifted onto the hemisphere (Malley's method),
//! so each stands for `1 / n` of the cosine-weighted hemisphere and the AO is the mean
//! of their visibilities. Each cone's half-angle θ gives it `1 / n` of the hemisphere's
//! solid angle (`cos θ = 1 − 1 / n`, Unreal's rule), at most 45°. The cone is *marched*
//! along an axis tilted up from its centre until its edge clears the tangent plane by
//! a margin (`cos α ≥ tan θ`): the distance field's value at a sample is the distance
//! to the receiver's own plane, shorter than the distance in the cone's section, so a
//! lower axis would see its own flat surface as an occluder. Bent normals use the
//! centres ([`cone_weight_direction`]).

use crate::cull::CameraOrigin;
use encase::ShaderType;
use glam::{IVec3, Mat3, Mat4, UVec2, Vec3};

/// Most cones per pixel.
pub const MAX_CONES: u32 = 16;
/// Most march steps per cone and object.
pub const MAX_STEPS: u32 = 64;
/// Golden angle, radians: the spiral's turn from one cone to the next.
pub const GOLDEN_ANGLE: f32 = 2.399_963_3;
/// The march steps at least this fraction of the cone's radius (sphere tracing
/// otherwise crawls along surfaces parallel to the cone).
pub const MIN_STEP_FRACTION: f32 = 0.5;
/// The exponent applied to each cone's visibility: the approximate cone intersection
/// (penumbra only) reports a cone next to an occluder's edge as nearly shut when about
/// half of it is open; an exponent below 1 opens it up (chosen against ray-traced truth,
/// `cargo bench -p penumbra_reference --bench dfao`).
pub const CONE_SHAPING: f32 = 0.25;
/// Pixels per tile side of the trace pass (its workgroup).
pub const TILE: u32 = 8;

/// How far along the normal (and along its cones) a receiver's trace through a baked
/// field starts at most, in that field's voxels: a field finer than the trace's bias (a
/// small prop: `FlightHelmet`'s parts have 3–8 mm voxels under the 2 cm default) starts
/// this many of its own voxels out instead, so the creases a prop's own field resolves
/// are not skipped. Coarser fields, analytic shapes, terrains and the global field start
/// at the bias ([`object_bias`]; the shadows' `shadow::FINE_FIELD_BIAS_VOXELS` is the
/// same rule). Chosen on the scene corpus (`tests/scene_corpus.rs`, DFAO at a 1 m reach):
/// summed over the helmet, the barn lamp, the alien and the cake 0.196 without the rule,
/// 0.172 at 1 and 1.5 voxels, 0.174 at 2, 0.181 at 3; the helmet 0.090 → 0.074 / 0.079 /
/// 0.083 / 0.088, the alien 0.027 → 0.032 / 0.030 / 0.028 / 0.027 (a field's error
/// near its surface occludes when a trace starts closer).
pub const FINE_FIELD_BIAS_VOXELS: f32 = 1.5;

/// Where a receiver's trace through a field of world voxel size `voxel` (0: an analytic
/// shape) starts, along its normal and along each cone: the trace's `bias`, or
/// [`FINE_FIELD_BIAS_VOXELS`] voxels of a finer field (`ao.wgsl`'s `ao_object_bias`).
pub fn object_bias(bias: f32, voxel: f32) -> f32 {
    if voxel > 0.0 && voxel.is_finite() {
        bias.min(FINE_FIELD_BIAS_VOXELS * voxel)
    } else {
        bias
    }
}

/// Tangent of the half-angle of each of `n` cones (`cos θ = 1 − 1/n`, at most 45°).
pub fn cone_tan_half(n: u32) -> f32 {
    let c = 1.0 - 1.0 / n.clamp(1, MAX_CONES) as f32;
    let s = (1.0 - c * c).max(0.0).sqrt();
    (s / c.max(1e-6)).min(1.0)
}

/// Disc coordinates `(ρ, φ)` of cone `k` of `n`.
fn spiral(k: u32, n: u32) -> (f32, f32) {
    let n = n.clamp(1, MAX_CONES);
    (
        ((k as f32 + 0.5) / n as f32).sqrt(),
        k as f32 * GOLDEN_ANGLE,
    )
}

/// Tangent-space (+Z the normal) centre of cone `k` of `n`: the direction its
/// visibility weights in the bent normal.
pub fn cone_weight_direction(k: u32, n: u32) -> Vec3 {
    let (rho, phi) = spiral(k, n);
    Vec3::new(
        rho * phi.cos(),
        rho * phi.sin(),
        (1.0 - rho * rho).max(0.0).sqrt(),
    )
}

/// Tangent-space axis cone `k` of `n` is marched along: its centre.
pub fn cone_axis(k: u32, n: u32) -> Vec3 {
    cone_weight_direction(k, n)
}

/// An orthonormal tangent frame `(t, b)` for unit `n` (Duff et al. 2017, branchless):
/// tangent-space `v` is `t · v.x + b · v.y + n · v.z`.
pub fn tangent_frame(n: Vec3) -> (Vec3, Vec3) {
    let sign = if n.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// The trace's settings, resolved and clamped (what the pass uses).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AoTrace {
    /// Occluders farther than this along a cone do not occlude, metres (> 0).
    pub max_distance: f32,
    /// Cones per pixel, `1..=MAX_CONES`.
    pub cone_count: u32,
    /// March steps per cone and object, `1..=MAX_STEPS`.
    pub steps_per_cone: u32,
    /// The cones start this far along the normal, metres (≥ 0).
    pub bias: f32,
    /// Cone visibility `v` becomes `v^shaping` ([`CONE_SHAPING`]).
    pub shaping: f32,
}

impl AoTrace {
    /// How far from a pixel an occluder's surface can lower its AO: every sample lies
    /// within `bias + max_distance` of it and occludes only while closer to a surface
    /// than the cone's radius (at most `max_distance · tan θ`).
    pub fn influence(&self) -> f32 {
        self.bias + self.max_distance * (1.0 + cone_tan_half(self.cone_count))
    }
}

/// The trace pass's per-view uniform (`AoTraceView` in `shaders/df/ao_trace.wgsl`).
#[derive(ShaderType, Clone, Copy, Debug, Default, PartialEq)]
pub struct AoTraceView {
    /// Inverse projection (reverse-Z clip to view space).
    pub view_from_clip: Mat4,
    /// The camera's rotation (view to camera-relative world).
    pub world_from_view: Mat3,
    /// The camera's 512 m tile.
    pub camera_tile: IVec3,
    /// Object buffer slots (records to consider).
    pub slot_count: u32,
    /// The camera's position within its tile.
    pub camera_offset: Vec3,
    /// [`AoTrace::max_distance`].
    pub max_distance: f32,
    /// The view's size, pixels.
    pub full_size: UVec2,
    /// The trace's size: `ceil(full_size / divisor)`.
    pub trace_size: UVec2,
    /// Which pixel of its `divisor × divisor` cell each trace texel takes this frame.
    pub jitter: UVec2,
    /// Trace resolution divisor (1: every pixel).
    pub divisor: u32,
    /// [`AoTrace::cone_count`].
    pub cone_count: u32,
    /// [`AoTrace::steps_per_cone`].
    pub steps_per_cone: u32,
    /// [`AoTrace::bias`].
    pub bias: f32,
    /// [`cone_tan_half`] of the cone count.
    pub tan_half: f32,
    /// [`AoTrace::shaping`].
    pub shaping: f32,
    /// [`AoTrace::influence`].
    pub influence: f32,
    /// 1: the objects-per-tile debug view: the trace writes, instead of the AO, the
    /// number of objects its tile keeps for the texel's distance range over
    /// [`TILE_OBJECTS_SCALE`] (`penumbra_reference::dfao::tile_object_counts`).
    pub tile_objects_debug: u32,
    /// With a global distance field: the far field's reach along each cone, metres
    /// (the trace's max distance; [`AoTraceView::max_distance`] is then the switch
    /// distance, where the objects' march stops and the field's begins). 0: no far
    /// field.
    pub far_distance: f32,
    /// Terrains (heightfield records bound) each cone also marches up to
    /// [`AoTraceView::max_distance`] (`penumbra_reference::dfao::texture_visibilities`).
    pub heightfield_count: u32,
    /// The viewport's origin in the render target, pixels: where the view's pixels are
    /// read from the prepass textures (the target's size; the AO textures are the
    /// viewport's). Zero for a camera without a viewport.
    pub origin: UVec2,
}

/// The objects-per-tile debug view stores `count / TILE_OBJECTS_SCALE` in the AO channel
/// (exact in `f16`; counts above it show as it).
pub const TILE_OBJECTS_SCALE: f32 = 1024.0;

impl AoTraceView {
    /// The uniform for a camera at `camera` (world position) with the given projection
    /// inverse and rotation.
    #[allow(clippy::too_many_arguments, reason = "one uniform's fields")]
    pub fn new(
        camera: &CameraOrigin,
        view_from_clip: Mat4,
        world_from_view: Mat3,
        full_size: UVec2,
        divisor: u32,
        jitter: UVec2,
        slot_count: u32,
        trace: &AoTrace,
    ) -> AoTraceView {
        let divisor = divisor.max(1);
        AoTraceView {
            view_from_clip,
            world_from_view,
            camera_tile: IVec3::from_array(camera.tile),
            slot_count,
            camera_offset: camera.offset,
            max_distance: trace.max_distance,
            full_size,
            trace_size: trace_size(full_size, divisor),
            jitter: jitter.min(UVec2::splat(divisor - 1)),
            divisor,
            cone_count: trace.cone_count,
            steps_per_cone: trace.steps_per_cone,
            bias: trace.bias,
            tan_half: cone_tan_half(trace.cone_count),
            shaping: trace.shaping,
            influence: trace.influence(),
            tile_objects_debug: 0,
            far_distance: 0.0,
            heightfield_count: 0,
            origin: UVec2::ZERO,
        }
    }

    /// The uniform of a trace that marches the objects up to `switch_distance` along
    /// each cone and a global distance field from there to `trace.max_distance`
    /// (`penumbra_reference::dfao::far`): the objects' part is a trace whose max distance
    /// (and influence, which culls the objects) is the switch distance. A switch at or
    /// beyond the max distance is the objects-only trace.
    pub fn with_far_field(self, trace: &AoTrace, switch_distance: f32) -> AoTraceView {
        // NaN or at least the reach: the objects-only trace.
        if switch_distance.is_nan() || switch_distance >= trace.max_distance {
            return self;
        }
        let near = AoTrace {
            max_distance: switch_distance.max(0.0),
            ..*trace
        };
        AoTraceView {
            max_distance: near.max_distance,
            influence: near.influence(),
            far_distance: trace.max_distance,
            ..self
        }
    }
}

/// History weight of the temporal filter at full confidence: each frame keeps this much
/// of the reprojected history (Unreal's `r.AOHistoryWeight`, 0.85: about 6 frames).
pub const HISTORY_WEIGHT: f32 = 0.85;
/// Relative difference between a history texel's distance from the camera and the
/// distance the pixel's surface point had from the previous camera beyond which the
/// texel is another surface (rejected).
pub const HISTORY_DEPTH_TOLERANCE: f32 = 0.05;
/// Confidence gained per frame of accepted history (full after one jitter cycle).
pub const CONFIDENCE_GAIN: f32 = 0.25;
/// Where the new AO differs from the history by more than this (occlusion left behind
/// by a moving caster, or arriving with it), the confidence falls, to 0 at twice this.
pub const LEAK_TOLERANCE: f32 = 0.05;
/// Pixels whose confidence is below this get the spatial fill.
pub const FILL_CONFIDENCE: f32 = 0.5;
/// The spatial fill's radius, pixels (a `(2r + 1)²` neighbourhood).
pub const FILL_RADIUS: i32 = 2;

/// The temporal pass's per-view uniform (`AoTemporalView` in `shaders/df/ao_temporal.wgsl`).
#[derive(ShaderType, Clone, Copy, Debug, Default, PartialEq)]
pub struct AoTemporalView {
    /// Inverse projection (reverse-Z clip to view space).
    pub view_from_clip: Mat4,
    /// The camera's rotation (view to camera-relative world).
    pub world_from_view: Mat3,
    /// The previous frame's camera position relative to this frame's, metres.
    pub previous_offset: Vec3,
    /// 1 when the history holds a previous frame of this view (0: first frame, resize).
    pub history_valid: u32,
    /// The view's size, pixels.
    pub full_size: UVec2,
    /// 1: the confidence lowers the history's weight (flushes leaked occlusion).
    pub confidence: u32,
    /// 1: pixels of low confidence take a spatial fill of the current frame.
    pub spatial_fill: u32,
    /// The viewport's origin in the render target ([`AoTraceView::origin`]).
    pub origin: UVec2,
}

/// The default fewest rows a view's trace keeps ([`view_divisor`]).
pub const MIN_TRACE_ROWS: u32 = 96;

/// The divisor a view of `full_size` pixels traces at for a requested `divisor`: the
/// largest at most `divisor` that keeps `min_rows` rows of traced pixels (or every row
/// of a view shorter than that). With [`MIN_TRACE_ROWS`], views 384 pixels tall or more
/// keep a divisor of 4; smaller ones (a picture-in-picture, a render-to-texture minimap,
/// a headless check at 128 × 96) trace more densely, at no more cost than a 384-pixel
/// view: one traced texel per 4 × 4 block of a 128 × 96 view lost the scene corpus's
/// contact occlusion (mean error against ray tracing, 128 × 96: the ship 0.089 → 0.059,
/// the depth-of-field scene 0.088 → 0.072, the flight helmet 0.165 → 0.141).
pub fn view_divisor(full_size: UVec2, divisor: u32, min_rows: u32) -> u32 {
    let mut d = divisor.max(1);
    while d > 1 && full_size.y / d < min_rows {
        d -= 1;
    }
    d
}

/// The trace's size for a view of `full_size` at `divisor`.
pub fn trace_size(full_size: UVec2, divisor: u32) -> UVec2 {
    let d = divisor.max(1);
    UVec2::new(full_size.x.div_ceil(d), full_size.y.div_ceil(d)).max(UVec2::ONE)
}

/// The jitter of frame `frame` for a `divisor`: four positions of the `divisor ×
/// divisor` cell, in the order (0,0), (1,1), (1,0), (0,1) scaled by `divisor / 2`.
pub fn jitter(frame: u32, divisor: u32) -> UVec2 {
    if divisor <= 1 {
        return UVec2::ZERO;
    }
    let step = divisor / 2;
    let [x, y] = [[0, 0], [1, 1], [1, 0], [0, 1]][(frame % 4) as usize];
    UVec2::new(x * step, y * step)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_views_trace_at_least_the_minimum_rows() {
        let rows = |s, d| view_divisor(s, d, MIN_TRACE_ROWS);
        // 0 rows: the divisor whatever the size.
        assert_eq!(view_divisor(UVec2::new(64, 64), 4, 0), 4);
        // Tall enough: the requested divisor.
        assert_eq!(rows(UVec2::new(1920, 1080), 4), 4);
        assert_eq!(rows(UVec2::new(512, 384), 4), 4);
        // Smaller: the largest divisor that keeps the rows, 1 below them.
        assert_eq!(rows(UVec2::new(384, 288), 4), 3);
        assert_eq!(rows(UVec2::new(256, 192), 4), 2);
        assert_eq!(rows(UVec2::new(128, 96), 4), 1);
        assert_eq!(rows(UVec2::new(64, 64), 4), 1);
        for h in 1..600 {
            let d = rows(UVec2::new(h, h), 4);
            assert!((1..=4).contains(&d));
            assert!(d == 1 || h / d >= MIN_TRACE_ROWS, "{h}: {d}");
            assert!(d == 4 || h / (d + 1) < MIN_TRACE_ROWS, "{h}: {d}");
        }
        // Never below 1; a requested 1 stays 1.
        assert_eq!(rows(UVec2::new(4000, 4000), 0), 1);
        assert_eq!(rows(UVec2::new(4000, 4000), 1), 1);
    }

    #[test]
    fn cones_cover_the_hemisphere_and_clear_the_plane() {
        for n in 1..=MAX_CONES {
            let t = cone_tan_half(n);
            assert!(t > 0.0 && t <= 1.0, "{n}: {t}");
            for k in 0..n {
                let axis = cone_axis(k, n);
                assert!((axis.length() - 1.0).abs() < 1e-5);
                assert!(cone_weight_direction(k, n).z > 0.0);
            }
        }
        assert!((cone_tan_half(9) - 27.27f32.to_radians().tan()).abs() < 1e-3);
    }

    #[test]
    fn tangent_frames_are_orthonormal() {
        for n in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.3, -0.5, 0.8).normalize(),
        ] {
            let (t, b) = tangent_frame(n);
            for (u, v) in [(t, b), (t, n), (b, n)] {
                assert!(u.dot(v).abs() < 1e-5);
            }
            assert!((t.cross(b) - n).length() < 1e-5, "{n}");
        }
    }

    /// `ao.wgsl` uses the same constant (`AO_FINE_FIELD_BIAS_VOXELS`: shader modules share one
    /// namespace where they are composed flat); analytic shapes and coarse fields keep the bias.
    #[test]
    fn the_fine_field_bias_and_its_shader_twin() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shaders/df/ao.wgsl");
        let source = std::fs::read_to_string(path).expect("ao.wgsl");
        let name = "const AO_FINE_FIELD_BIAS_VOXELS: f32 = ";
        let line = source
            .lines()
            .find(|l| l.starts_with(name))
            .expect("AO_FINE_FIELD_BIAS_VOXELS in ao.wgsl");
        let wgsl: f32 = line
            .trim_start_matches(name)
            .trim_end_matches(';')
            .parse()
            .expect("a float");
        assert_eq!(wgsl, FINE_FIELD_BIAS_VOXELS);
        assert_eq!(object_bias(0.02, 0.0), 0.02);
        assert_eq!(object_bias(0.02, f32::NAN), 0.02);
        assert_eq!(object_bias(0.02, 0.05), 0.02);
        assert_eq!(object_bias(0.02, 0.004), FINE_FIELD_BIAS_VOXELS * 0.004);
    }

    #[test]
    fn the_uniform_has_wgsl_layout() {
        // mat4 64 + mat3 48 + 16 + 16 + 8 + 8 + 8 + 7 words, then the viewport origin
        // (8, aligned to 8), rounded up to the struct's 16-byte alignment (the WGSL
        // struct's size: `penumbra_shaders`' layout test).
        assert_eq!(AoTraceView::min_size().get(), 224);
        assert_eq!(jitter(5, 2), UVec2::new(1, 1));
        assert_eq!(jitter(2, 4), UVec2::new(2, 0));
        assert_eq!(trace_size(UVec2::new(5, 4), 2), UVec2::new(3, 2));
    }
}
