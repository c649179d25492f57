//! The steps after the trace: the geometry-aware upsample to full resolution
//! (`shaders/df/ao_upsample.wgsl`) and what the lighting pass does with the result
//! (`shaders/lighting/ao.wgsl`): contrast, min occlusion, specular occlusion.

use crate::msaa::SAMPLE_POSITIONS_4X;
use glam::{UVec2, Vec2, Vec3, Vec4};

/// Relative depth difference at which a trace texel's upsample weight reaches zero.
pub const UPSAMPLE_DEPTH_TOLERANCE: f32 = 0.1;
/// Exponent of the normal similarity `max(n · n_s, 0)` in the upsample weight.
pub const UPSAMPLE_NORMAL_POWER: i32 = 8;

/// Where the trace came from: `size` texels, texel `(i, j)` traced at pixel
/// `(i, j) · divisor + jitter` of a `full_size` view whose pixel-centre distances from
/// the camera (0 or NaN: background) and unit normals are `distance` and `normals`.
#[derive(Clone, Copy, Debug)]
pub struct TraceSource<'a> {
    /// The trace: AO and bent normal per texel.
    pub trace: &'a [Vec4],
    /// Texels of the trace.
    pub size: UVec2,
    /// Pixels per trace texel along each axis.
    pub divisor: u32,
    /// Pixel of texel `(0, 0)`.
    pub jitter: UVec2,
    /// Distance from the camera at each pixel's centre.
    pub distance: &'a [f32],
    /// Unit normal at each pixel.
    pub normals: &'a [Vec3],
    /// Pixels of the view.
    pub full_size: UVec2,
}

/// Geometry-aware upsample of a reduced-resolution trace (`trace_size` texels, texel
/// `(i, j)` traced at pixel `(i, j) · divisor + jitter`) to `full_size`: each pixel
/// blends the four texels around it ([`blend`]). Background pixels (`distance` 0 or NaN)
/// get `(1, 0, 0, 0)`.
pub fn upsample(
    trace: &[Vec4],
    trace_size: UVec2,
    divisor: u32,
    jitter: UVec2,
    distance: &[f32],
    normals: &[Vec3],
    full_size: UVec2,
) -> Vec<Vec4> {
    let source = TraceSource {
        trace,
        size: trace_size,
        divisor,
        jitter,
        distance,
        normals,
        full_size,
    };
    let mut out = Vec::with_capacity((full_size.x * full_size.y) as usize);
    for y in 0..full_size.y {
        for x in 0..full_size.x {
            let i = (y * full_size.x + x) as usize;
            let d = distance[i];
            if d.is_nan() || d <= 0.0 {
                out.push(Vec4::new(1.0, 0.0, 0.0, 0.0));
                continue;
            }
            let centre = Vec2::new(x as f32, y as f32) + 0.5;
            out.push(blend(&source, centre, d, normals[i]));
        }
    }
    out
}

/// The AO texel (AO, unit bent normal) of the surface seen at frame-buffer point
/// `screen` (pixels from the top-left corner), `d` from the camera, unit normal `n`: the
/// four trace texels around it blended with bilinear weights scaled by depth similarity
/// (`max(0, 1 − |Δd| / (d · tolerance))`, `Δd` against the distance at the texel's
/// traced pixel) and normal similarity (`max(n · n_s, 0)⁸`); if every weight is zero,
/// the texel closest in depth wins. The bent normal is renormalised (`n` if it vanishes).
pub fn blend(source: &TraceSource<'_>, screen: Vec2, d: f32, n: Vec3) -> Vec4 {
    let TraceSource {
        trace,
        size,
        jitter,
        distance,
        normals,
        full_size,
        ..
    } = *source;
    let divisor = source.divisor.max(1);
    let at = |p: UVec2| (p.y * full_size.x + p.x) as usize;
    let h = ((screen - 0.5 - jitter.as_vec2()) / divisor as f32).max(Vec2::ZERO);
    let (i0, f) = (h.floor(), h - h.floor());
    let (mut sum, mut weights) = (Vec4::ZERO, 0.0f32);
    let (mut nearest, mut nearest_error) = (Vec4::new(1.0, n.x, n.y, n.z), f32::MAX);
    for k in 0..4u32 {
        let o = UVec2::new(k & 1, k >> 1);
        let texel = (i0.as_uvec2() + o).min(size - UVec2::ONE);
        let v = trace[(texel.y * size.x + texel.x) as usize];
        let traced_at = (texel * divisor + jitter).min(full_size - UVec2::ONE);
        let error = (distance[at(traced_at)] - d).abs() / d;
        let wx = if o.x == 1 { f.x } else { 1.0 - f.x };
        let wy = if o.y == 1 { f.y } else { 1.0 - f.y };
        let similar = n
            .dot(normals[at(traced_at)])
            .max(0.0)
            .powi(UPSAMPLE_NORMAL_POWER);
        let w = wx * wy * (1.0 - error / UPSAMPLE_DEPTH_TOLERANCE).max(0.0) * similar;
        sum += v * w;
        weights += w;
        if error < nearest_error {
            nearest_error = error;
            nearest = v;
        }
    }
    let v = if weights > 1e-4 {
        sum / weights
    } else {
        nearest
    };
    let bent = Vec3::new(v.y, v.z, v.w);
    let len = bent.length();
    let bent = if len > 1e-6 { bent / len } else { n };
    Vec4::new(v.x.clamp(0.0, 1.0), bent.x, bent.y, bent.z)
}

/// Deferred MSAA's per-sample upsample (`upsample_samples` in `df/ao_upsample.wgsl`):
/// for each pixel with `per_sample[pixel]` set, sample `s` at
/// [`SAMPLE_POSITIONS_4X`]`[s]` with distance `sample_distance[4 · pixel + s]` and normal
/// `sample_normals[4 · pixel + s]` gets [`blend`] at its own position (background:
/// `(1, 0, 0, 0)`), stored at texel `2 · pixel + (s & 1, s >> 1)` of an image twice the
/// view's size. Texels of the other pixels are `None` (never written).
pub fn upsample_samples(
    source: &TraceSource<'_>,
    sample_distance: &[f32],
    sample_normals: &[Vec3],
    per_sample: &[bool],
) -> Vec<Option<Vec4>> {
    let full = source.full_size;
    let wide = 2 * full.x;
    let mut out = vec![None; (4 * full.x * full.y) as usize];
    for y in 0..full.y {
        for x in 0..full.x {
            let pixel = (y * full.x + x) as usize;
            if !per_sample[pixel] {
                continue;
            }
            for (s, position) in SAMPLE_POSITIONS_4X.iter().enumerate() {
                let d = sample_distance[4 * pixel + s];
                let texel = UVec2::new(2 * x + (s as u32 & 1), 2 * y + (s as u32 >> 1));
                out[(texel.y * wide + texel.x) as usize] = Some(if d.is_nan() || d <= 0.0 {
                    Vec4::new(1.0, 0.0, 0.0, 0.0)
                } else {
                    let screen = Vec2::new(x as f32, y as f32) + *position;
                    blend(source, screen, d, sample_normals[4 * pixel + s])
                });
            }
        }
    }
    out
}

/// Unreal's occlusion contrast and min occlusion on a traced AO: a logistic S-curve of
/// slope `10 · contrast` through ½, normalised to keep 0 and 1 (identity at contrast 0),
/// then lifted to `[min_occlusion, 1]`. NaN counts as open.
pub fn finish_ao(ao: f32, contrast: f32, min_occlusion: f32) -> f32 {
    // NaN (never written by the passes): open.
    let ao = if ao.is_nan() { 1.0 } else { ao.clamp(0.0, 1.0) };
    let shaped = if contrast > 1e-3 {
        let k = 10.0 * contrast;
        let s = |x: f32| 1.0 / (1.0 + (-k * (x - 0.5)).exp());
        ((s(ao) - s(0.0)) / (s(1.0) - s(0.0))).clamp(0.0, 1.0)
    } else {
        ao
    };
    let m = min_occlusion.clamp(0.0, 1.0);
    m + (1.0 - m) * shaped
}

/// How the AO occludes specular indirect light.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpecularOcclusion {
    /// Not at all.
    None,
    /// From the AO alone (Lagarde and de Rousiers 2014, as Bevy's SSAO does).
    NonDirectional,
    /// The overlap of the reflection cone (from roughness) and the visibility cone
    /// (around the bent normal, its aperture from the AO), Unreal's approximation.
    ConeCone,
}

/// The specular occlusion of a surface with AO `ao` and unit `bent` normal, unit normal
/// `n`, unit view vector `v` (toward the camera) and linear `roughness`.
pub fn specular_occlusion(
    mode: SpecularOcclusion,
    ao: f32,
    bent: Vec3,
    n: Vec3,
    v: Vec3,
    roughness: f32,
) -> f32 {
    match mode {
        SpecularOcclusion::None => 1.0,
        SpecularOcclusion::NonDirectional => {
            let n_dot_v = n.dot(v).max(1e-4);
            ((n_dot_v + ao).powf((-16.0 * roughness - 1.0).exp2()) - 1.0 + ao).clamp(0.0, 1.0)
        }
        SpecularOcclusion::ConeCone => {
            let r = (2.0 * n.dot(v) * n - v).normalize_or_zero();
            let reflection = roughness.max(0.1) * std::f32::consts::PI;
            let unoccluded = ao.clamp(0.0, 1.0) * std::f32::consts::PI;
            let between = bent.dot(r).clamp(-1.0, 1.0).acos();
            let o = cone_cone_intersection(reflection, unoccluded, between);
            o * ((unoccluded - 0.1) / 0.2).clamp(0.0, 1.0)
        }
    }
}

/// The approximate overlap (0–1) of two cones of apertures `a` and `b` (radians) whose
/// axes are `between` apart: 1 when one contains the other, 0 when disjoint, a
/// smoothstep between (Oat and Sander 2007, as Unreal uses it).
pub fn cone_cone_intersection(a: f32, b: f32, between: f32) -> f32 {
    let difference = (a - b).abs();
    let x = 1.0 - ((between - difference) / (a + b - difference).max(1e-6)).clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finishing_keeps_the_ends_and_orders() {
        for contrast in [0.0f32, 0.3, 1.0] {
            assert_eq!(finish_ao(0.0, contrast, 0.0), 0.0);
            assert!((finish_ao(1.0, contrast, 0.0) - 1.0).abs() < 1e-6);
            assert!((finish_ao(0.5, contrast, 0.0) - 0.5).abs() < 1e-5);
            assert!(finish_ao(0.3, contrast, 0.0) <= 0.3 + 1e-6);
        }
        assert!(finish_ao(0.3, 1.0, 0.0) < 0.2);
        assert_eq!(finish_ao(0.0, 0.0, 0.25), 0.25);
        assert_eq!(finish_ao(f32::NAN, 0.0, 0.0), 1.0);
    }

    /// Open surfaces keep their specular; fully occluded ones lose it; the cone–cone
    /// mode keeps a reflection along the bent normal and loses one turned away from it.
    #[test]
    fn specular_occlusion_modes() {
        let n = Vec3::Y;
        let v = Vec3::new(0.3, 1.0, 0.0).normalize();
        for mode in [
            SpecularOcclusion::NonDirectional,
            SpecularOcclusion::ConeCone,
        ] {
            assert!(
                specular_occlusion(mode, 1.0, n, n, v, 0.3) > 0.99,
                "{mode:?}"
            );
            assert!(
                specular_occlusion(mode, 0.0, n, n, v, 0.3) < 0.01,
                "{mode:?}"
            );
        }
        assert_eq!(
            specular_occlusion(SpecularOcclusion::None, 0.0, n, n, v, 0.3),
            1.0
        );
        let r = (2.0 * n.dot(v) * n - v).normalize();
        let toward = specular_occlusion(SpecularOcclusion::ConeCone, 0.3, r, n, v, 0.2);
        let away = specular_occlusion(
            SpecularOcclusion::ConeCone,
            0.3,
            (n - r).normalize(),
            n,
            v,
            0.2,
        );
        assert!(toward > 0.9 && away < 0.5, "{toward} {away}");
    }

    /// A pixel whose four texels agree takes their value; across a depth edge the far
    /// texels do not bleed in.
    #[test]
    fn upsample_respects_depth_edges() {
        let full = UVec2::new(8, 4);
        let size = UVec2::new(4, 2);
        // Left half near (1 m, AO 0.2), right half far (10 m, AO 0.9).
        let distance: Vec<f32> = (0..32)
            .map(|i| if i % 8 < 4 { 1.0 } else { 10.0 })
            .collect();
        let normals = vec![Vec3::Y; 32];
        let trace: Vec<Vec4> = (0..8)
            .map(|i| {
                if i % 4 < 2 {
                    Vec4::new(0.2, 0.0, 1.0, 0.0)
                } else {
                    Vec4::new(0.9, 0.0, 1.0, 0.0)
                }
            })
            .collect();
        let out = upsample(&trace, size, 2, UVec2::ZERO, &distance, &normals, full);
        for (i, v) in out.iter().enumerate() {
            let want = if i % 8 < 4 { 0.2 } else { 0.9 };
            assert!((v.x - want).abs() < 1e-6, "pixel {i}: {v}");
            assert!((Vec3::new(v.y, v.z, v.w) - Vec3::Y).length() < 1e-6);
        }
    }

    /// Per sample, each sample of a pixel that straddles the edge takes its own side's
    /// AO, and within a surface each sample blends the texels at its own position;
    /// pixels not shaded per sample are left unwritten.
    #[test]
    fn samples_take_their_own_surface_and_position() {
        let full = UVec2::new(8, 4);
        let distance: Vec<f32> = (0..32)
            .map(|i| if i % 8 < 4 { 1.0 } else { 10.0 })
            .collect();
        let normals = vec![Vec3::Y; 32];
        // Near texels (pixels 0 and 2) AO 0.2 and 0.6; far ones 0.9.
        let trace: Vec<Vec4> = (0..8)
            .map(|i| Vec4::new([0.2, 0.6, 0.9, 0.9][i % 4], 0.0, 1.0, 0.0))
            .collect();
        let source = TraceSource {
            trace: &trace,
            size: UVec2::new(4, 2),
            divisor: 2,
            jitter: UVec2::ZERO,
            distance: &distance,
            normals: &normals,
            full_size: full,
        };
        // Pixels (1, 1) and (3, 1) are shaded per sample; samples 1 and 3 (the right
        // half) of (3, 1) see the far surface.
        let mut sample_distance = vec![1.0f32; 4 * 32];
        sample_distance[4 * 11 + 1] = 10.0;
        sample_distance[4 * 11 + 3] = 10.0;
        let mut per_sample = vec![false; 32];
        per_sample[9] = true;
        per_sample[11] = true;
        let out = upsample_samples(&source, &sample_distance, &vec![Vec3::Y; 128], &per_sample);
        assert_eq!(out.iter().filter(|v| v.is_some()).count(), 8);
        // Pixel 1: bilinear between 0.2 (x = 0) and 0.6 (x = 2) at x + 0.375, 0.875,
        // 0.125, 0.625.
        let want = [(1, [0.375, 0.475, 0.325, 0.425]), (3, [0.6, 0.9, 0.6, 0.9])];
        for (x, values) in want {
            for (s, want) in values.into_iter().enumerate() {
                let s = s as u32;
                let texel = (2 + (s >> 1)) * 16 + 2 * x + (s & 1);
                let v = out[texel as usize].expect("written");
                assert!((v.x - want).abs() < 1e-6, "pixel {x}, sample {s}: {v}");
            }
        }
    }
}
