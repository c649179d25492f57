//! The temporal filter (`shaders/df/ao_temporal.wgsl`): the trace runs on one pixel of
//! each `divisor × divisor` cell, a different one each frame (four jitter positions);
//! the upsampled result is blended with the previous frame's, reprojected with the
//! motion vectors, so that over a few frames every pixel's own trace contributes.
//!
//! Per full-resolution pixel:
//! 1. **Reprojection**: the history is read at `uv − motion` (Bevy's motion vectors are
//!    the UV change since the previous frame) with bilinear weights over its four
//!    texels; a texel counts only if it holds a surface whose distance from the camera
//!    (stored with it) is within [`HISTORY_DEPTH_TOLERANCE`] of the distance this pixel's
//!    point had from the *previous* camera (**depth rejection**: disocclusions, other
//!    surfaces). Outside the view, or no valid texel: no history.
//! 2. **Confidence** (stored with the history): 0 without history, raised by
//!    [`CONFIDENCE_GAIN`] per frame of accepted history. With the confidence step on, the
//!    history's weight is [`HISTORY_WEIGHT`] × its confidence, and the confidence falls
//!    where the new AO differs from the history by over [`LEAK_TOLERANCE`], to 0 at twice
//!    that (occlusion left behind by a moving caster, or arriving with it: **ghosting**
//!    is flushed in a frame or two instead of fading at 0.85 per frame; the flushed
//!    pixels flicker more, which the fill calms). Off: the weight is [`HISTORY_WEIGHT`].
//! 3. **Spatial fill** (on or off): a pixel whose confidence is below
//!    [`FILL_CONFIDENCE`] (new, or flushed) *shows* the depth- and normal-weighted mean of
//!    the current frame over a `(2·FILL_RADIUS + 1)²` neighbourhood instead of its own
//!    value, which is one jittered trace upsampled and flickers until history builds up.
//! 4. `mix(current, history, weight)`, the bent normal renormalised, is the history the
//!    next frame reads, with the pixel's distance from the camera and its confidence; what
//!    the lighting pass reads is the same blend with the fill in place of the current
//!    value where the fill applies.
//!
//! The fill is display only: kept in the history, a pixel whose own trace differs from
//! its neighbourhood's mean by more than twice [`LEAK_TOLERANCE`] (a contact corner, a
//! crease) compared its own value with the fill it stored, was flushed again, and showed
//! the fill for ever in a still view — whatever history it started from. The scene
//! corpus's DFAO then depended on the order in which casters' fields arrived (the flight
//! helmet 0.063 with its fields baked, 0.069 read from the disk cache) and missed its own
//! trace (the ship 0.059 against 0.028 unfiltered).

use glam::{UVec2, Vec2, Vec3, Vec4};
use penumbra_df_core::ao::{
    CONFIDENCE_GAIN, FILL_CONFIDENCE, FILL_RADIUS, HISTORY_DEPTH_TOLERANCE, HISTORY_WEIGHT,
    LEAK_TOLERANCE,
};

use super::apply::{UPSAMPLE_DEPTH_TOLERANCE, UPSAMPLE_NORMAL_POWER};

/// Which steps of the filter run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TemporalSteps {
    /// The confidence lowers the history's weight and flushes leaked occlusion.
    pub confidence: bool,
    /// Low-confidence pixels take the spatial fill.
    pub spatial_fill: bool,
}

impl TemporalSteps {
    /// Both steps (what the GPU pass does).
    pub const ALL: TemporalSteps = TemporalSteps {
        confidence: true,
        spatial_fill: true,
    };
    /// Plain exponential history with depth rejection.
    pub const PLAIN: TemporalSteps = TemporalSteps {
        confidence: false,
        spatial_fill: false,
    };
}

/// A frame's filtered AO and what the next frame reprojects.
#[derive(Clone, Debug, PartialEq)]
pub struct AoHistory {
    /// `(ao, bent normal)` per pixel: the blend the next frame reprojects (background
    /// `(1, 0, 0, 0)`).
    pub value: Vec<Vec4>,
    /// `(distance from the camera, confidence, 0, 0)` per pixel (background 0).
    pub state: Vec<Vec4>,
    /// `(ao, bent normal)` per pixel: the filter's output, what the lighting pass reads
    /// (`value` with the spatial fill where it applies).
    pub filtered: Vec<Vec4>,
}

impl AoHistory {
    /// A history of `value` and `state` whose output is `value` (no fill).
    pub fn new(value: Vec<Vec4>, state: Vec<Vec4>) -> Self {
        Self {
            filtered: value.clone(),
            value,
            state,
        }
    }
}

/// One frame's inputs at full resolution.
pub struct TemporalFrame<'a> {
    /// View size, pixels.
    pub size: UVec2,
    /// The upsampled trace, `(ao, bent normal)` per pixel.
    pub current: &'a [Vec4],
    /// Camera-relative world position per pixel (NaN: background).
    pub positions: &'a [Vec3],
    /// Unit world normal per pixel.
    pub normals: &'a [Vec3],
    /// Motion vector per pixel: this frame's UV minus the previous frame's.
    pub motion: &'a [Vec2],
    /// The previous camera's position relative to this frame's camera.
    pub previous_offset: Vec3,
}

/// One step of the filter; `history` is the previous frame's (None: first frame).
pub fn temporal_step(
    frame: &TemporalFrame,
    history: Option<&AoHistory>,
    steps: TemporalSteps,
) -> AoHistory {
    let n = (frame.size.x * frame.size.y) as usize;
    let mut value = Vec::with_capacity(n);
    let mut state = Vec::with_capacity(n);
    let mut filtered = Vec::with_capacity(n);
    for y in 0..frame.size.y {
        for x in 0..frame.size.x {
            let (v, s, f) = filter_pixel(frame, history, steps, UVec2::new(x, y));
            value.push(v);
            state.push(s);
            filtered.push(f);
        }
    }
    AoHistory {
        value,
        state,
        filtered,
    }
}

/// `current` blended toward the history `h` by `weight`, its bent normal renormalised
/// (the receiver's normal `n` where it vanishes), the AO clamped to `[0, 1]`.
fn blend(current: Vec4, h: Vec4, weight: f32, n: Vec3) -> Vec4 {
    let v = current + (h - current) * weight;
    let bent = Vec3::new(v.y, v.z, v.w);
    let len = bent.length();
    let bent = if len > 1e-6 { bent / len } else { n };
    Vec4::new(v.x.clamp(0.0, 1.0), bent.x, bent.y, bent.z)
}

fn distance_of(p: Vec3) -> f32 {
    let d = p.length();
    if d.is_finite() && d > 0.0 { d } else { 0.0 }
}

fn filter_pixel(
    frame: &TemporalFrame,
    history: Option<&AoHistory>,
    steps: TemporalSteps,
    xy: UVec2,
) -> (Vec4, Vec4, Vec4) {
    let i = (xy.y * frame.size.x + xy.x) as usize;
    let p = frame.positions[i];
    let d = distance_of(p);
    if d <= 0.0 {
        let open = Vec4::new(1.0, 0.0, 0.0, 0.0);
        return (open, Vec4::ZERO, open);
    }
    let c = frame.current[i];
    let expected = (p - frame.previous_offset).length();
    let reprojected = history.and_then(|h| reproject(frame, h, xy, expected));
    let (weight, confidence) = match reprojected {
        None => (0.0, 0.0),
        Some((h, h_confidence)) => {
            if steps.confidence {
                let leak = (((c.x - h.x).abs() - LEAK_TOLERANCE) / LEAK_TOLERANCE).clamp(0.0, 1.0);
                let trust = h_confidence * (1.0 - leak);
                (HISTORY_WEIGHT * trust, (trust + CONFIDENCE_GAIN).min(1.0))
            } else {
                (HISTORY_WEIGHT, (h_confidence + CONFIDENCE_GAIN).min(1.0))
            }
        }
    };
    let n = frame.normals[i];
    let history_value = blend(c, reprojected.map_or(c, |(h, _)| h), weight, n);
    let filtered = if steps.spatial_fill && confidence < FILL_CONFIDENCE {
        let fill = spatial_fill(frame, xy, d);
        blend(fill, reprojected.map_or(fill, |(h, _)| h), weight, n)
    } else {
        history_value
    };
    (history_value, Vec4::new(d, confidence, 0.0, 0.0), filtered)
}

/// The history at pixel `xy`'s reprojected position and its confidence, from the
/// texels that hold the same surface (stored distance within tolerance of `expected`).
pub(super) fn reproject(
    frame: &TemporalFrame,
    history: &AoHistory,
    xy: UVec2,
    expected: f32,
) -> Option<(Vec4, f32)> {
    let size = frame.size.as_vec2();
    let i = (xy.y * frame.size.x + xy.x) as usize;
    let uv = (xy.as_vec2() + 0.5) / size - frame.motion[i];
    if !(uv.x >= 0.0 && uv.x <= 1.0 && uv.y >= 0.0 && uv.y <= 1.0) {
        return None;
    }
    let h = uv * size - 0.5;
    let (i0, f) = (h.floor(), h - h.floor());
    let (mut sum, mut confidence, mut weights) = (Vec4::ZERO, 0.0f32, 0.0f32);
    for k in 0..4u32 {
        let o = Vec2::new((k & 1) as f32, (k >> 1) as f32);
        let texel = i0 + o;
        if texel.x < 0.0 || texel.y < 0.0 || texel.x >= size.x || texel.y >= size.y {
            continue;
        }
        let j = (texel.y as u32 * frame.size.x + texel.x as u32) as usize;
        let s = history.state[j];
        if !(s.x > 0.0 && (s.x - expected).abs() < HISTORY_DEPTH_TOLERANCE * expected) {
            continue;
        }
        let wx = if o.x == 1.0 { f.x } else { 1.0 - f.x };
        let wy = if o.y == 1.0 { f.y } else { 1.0 - f.y };
        let w = wx * wy;
        sum += history.value[j] * w;
        confidence += s.y * w;
        weights += w;
    }
    (weights > 1e-3).then(|| (sum / weights, confidence / weights))
}

/// The current frame's depth- and normal-weighted mean around pixel `xy` (distance `d`).
fn spatial_fill(frame: &TemporalFrame, xy: UVec2, d: f32) -> Vec4 {
    let i = (xy.y * frame.size.x + xy.x) as usize;
    let n = frame.normals[i];
    let (mut sum, mut weights) = (Vec4::ZERO, 0.0f32);
    for dy in -FILL_RADIUS..=FILL_RADIUS {
        for dx in -FILL_RADIUS..=FILL_RADIUS {
            let q = xy.as_ivec2() + glam::IVec2::new(dx, dy);
            if q.x < 0 || q.y < 0 || q.x >= frame.size.x as i32 || q.y >= frame.size.y as i32 {
                continue;
            }
            let j = (q.y as u32 * frame.size.x + q.x as u32) as usize;
            let dq = distance_of(frame.positions[j]);
            if dq <= 0.0 {
                continue;
            }
            let error = (dq - d).abs() / d;
            let similar = n.dot(frame.normals[j]).max(0.0).powi(UPSAMPLE_NORMAL_POWER);
            let w = (1.0 - error / UPSAMPLE_DEPTH_TOLERANCE).max(0.0) * similar;
            sum += frame.current[j] * w;
            weights += w;
        }
    }
    // The pixel itself always has weight 1.
    sum / weights
}
