//! Hair strips: the coverage of a camera-facing strip under MSAA with an alpha test
//! at every sample (Samaritan's "short hair / beard"; Lottes, "Alpha-Test and MSAA"),
//! which `bevy_penumbra_cinematic::hair`'s shader computes (`hair/common.wgsl`) and this
//! module models.
//!
//! A strand segment from `a` to `b` (pixel coordinates) of half-width `h` pixels is the
//! rectangle `a + s d + t n`, `0 ≤ s ≤ |b − a|`, `|t| ≤ h` (`d` along, `n` across). Each of
//! a pixel's samples (the standard 2×, 4× or 8× pattern, [`sample_positions`]; 4× below
//! unless a function says `_for` a count) is kept when
//! it lies in the rectangle and the strand's texture alpha there reaches ½ (an alpha test
//! at every sample: a supersampled alpha test); the resolved coverage is the kept
//! samples' share. Strands thinner than
//! [`MIN_WIDTH_PX`] are widened to it and faded by `width / MIN_WIDTH_PX`
//! ([`clamp_width`]): each sample is kept only where the fade reaches its threshold, a
//! quarter permuted per pixel ([`sample_thresholds`]), so a faded strand keeps that share
//! of its samples, its expected coverage stays its area, and it does not vanish between
//! samples.
//!
//! Checked against the exact area of the rectangle inside each pixel
//! ([`exact_coverage`], polygon clipping in `f64`). The strands themselves, their text
//! format and their checks: [`strands`].

use glam::{DVec2, IVec2, Vec2};

pub mod strands;

/// The standard 4× MSAA sample positions within a pixel (Vulkan's and Direct3D's),
/// `(0, 0)` its top-left corner.
pub const SAMPLE_POSITIONS_4X: [Vec2; 4] = [
    Vec2::new(0.375, 0.125),
    Vec2::new(0.875, 0.375),
    Vec2::new(0.125, 0.625),
    Vec2::new(0.625, 0.875),
];

/// The standard 2× MSAA sample positions (Vulkan's and Direct3D's).
pub const SAMPLE_POSITIONS_2X: [Vec2; 2] = [Vec2::new(0.75, 0.75), Vec2::new(0.25, 0.25)];

/// The standard 8× MSAA sample positions (Vulkan's and Direct3D's).
pub const SAMPLE_POSITIONS_8X: [Vec2; 8] = [
    Vec2::new(0.5625, 0.3125),
    Vec2::new(0.4375, 0.6875),
    Vec2::new(0.8125, 0.5625),
    Vec2::new(0.3125, 0.1875),
    Vec2::new(0.1875, 0.8125),
    Vec2::new(0.0625, 0.4375),
    Vec2::new(0.6875, 0.9375),
    Vec2::new(0.9375, 0.0625),
];

/// The standard pattern of `count` samples (2, 4 or 8; any other count: the 4× one, as
/// `hair/samples.wgsl`'s `hair_sample_offset`).
pub fn sample_positions(count: u32) -> &'static [Vec2] {
    match count {
        2 => &SAMPLE_POSITIONS_2X,
        8 => &SAMPLE_POSITIONS_8X,
        _ => &SAMPLE_POSITIONS_4X,
    }
}

/// The narrowest strand drawn, pixels: one sample spacing of the 4× pattern.
pub const MIN_WIDTH_PX: f32 = 0.5;

/// A strand segment on screen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScreenSegment {
    /// Start, pixels.
    pub a: Vec2,
    /// End, pixels.
    pub b: Vec2,
    /// Half the width, pixels.
    pub half_width: f32,
}

/// A strand's drawn width and alpha scale: widths under [`MIN_WIDTH_PX`] are widened to
/// it, their alpha scaled by the ratio (the expected coverage is kept). Non-finite or
/// non-positive widths draw nothing (alpha 0).
pub fn clamp_width(width_px: f32) -> (f32, f32) {
    if !width_px.is_finite() || width_px <= 0.0 {
        return (MIN_WIDTH_PX, 0.0);
    }
    if width_px < MIN_WIDTH_PX {
        (MIN_WIDTH_PX, width_px / MIN_WIDTH_PX)
    } else {
        (width_px, 1.0)
    }
}

/// The four samples' alpha thresholds at `pixel`: `(k + ½) / 4` for `k = 0..4`, permuted
/// per pixel by a hash, so that an alpha of `α` keeps `round(4 α)` samples on average.
pub fn sample_thresholds(pixel: IVec2) -> [f32; 4] {
    let t = sample_thresholds_for(pixel, 4);
    [t[0], t[1], t[2], t[3]]
}

/// The thresholds of `count` samples (clamped to 1..=8; the rest 1) at `pixel`:
/// `(k + ½) / count` for `k = 0..count`, permuted per pixel by a hash (the Lehmer code of
/// the hash modulo `count!`), so that a fade `f` keeps about `count · f` samples
/// (`hair/samples.wgsl`'s `hair_sample_thresholds`).
pub fn sample_thresholds_for(pixel: IVec2, count: u32) -> [f32; 8] {
    let n = count.clamp(1, 8);
    let mut h =
        (pixel.x as u32).wrapping_mul(0x8da6_b343) ^ (pixel.y as u32).wrapping_mul(0xd816_3841);
    h ^= h >> 13;
    h = h.wrapping_mul(0x2c1b_3c6d);
    h ^= h >> 16;
    let permutations: u32 = (2..=n).product();
    let mut order = [0u32, 1, 2, 3, 4, 5, 6, 7];
    let mut code = h % permutations;
    for i in 0..n - 1 {
        let j = i + code % (n - i);
        code /= n - i;
        order.swap(i as usize, j as usize);
    }
    let mut thresholds = [1.0; 8];
    for (t, k) in thresholds.iter_mut().zip(order).take(n as usize) {
        *t = (k as f32 + 0.5) / n as f32;
    }
    thresholds
}

/// The alpha a sample's texture alpha must reach: the alpha test's cutoff.
pub const ALPHA_CUTOFF: f32 = 0.5;

/// The 4× coverage mask of `segment` at `pixel` (bit `i` for sample `i`): samples inside
/// the rectangle where the texture's `alpha(u, v)` — `u` along the strand in `[0, 1]`,
/// `v` across in `[0, 1]` — reaches [`ALPHA_CUTOFF`] (a supersampled alpha test) and
/// the width fade reaches the sample's threshold ([`sample_thresholds`]: a strand faded
/// to `f` keeps about `4 f` of its samples).
pub fn coverage_mask(
    segment: &ScreenSegment,
    pixel: IVec2,
    fade: f32,
    alpha: impl Fn(Vec2) -> f32,
) -> u8 {
    coverage_mask_for(segment, pixel, fade, alpha, 4)
}

/// [`coverage_mask`] under `count`-sample MSAA (2, 4 or 8: [`sample_positions`], with
/// [`sample_thresholds_for`] that count).
pub fn coverage_mask_for(
    segment: &ScreenSegment,
    pixel: IVec2,
    fade: f32,
    alpha: impl Fn(Vec2) -> f32,
    count: u32,
) -> u8 {
    let thresholds = sample_thresholds_for(pixel, count);
    let mut mask = 0u8;
    for (i, offset) in sample_positions(count).iter().enumerate() {
        if fade >= thresholds[i]
            && strip_uv(segment, pixel.as_vec2() + *offset)
                .is_some_and(|uv| alpha(uv) >= ALPHA_CUTOFF)
        {
            mask |= 1 << i;
        }
    }
    mask
}

/// The strip's coordinates `(u, v)` at a screen point, if it lies on the strip.
pub fn strip_uv(segment: &ScreenSegment, p: Vec2) -> Option<Vec2> {
    let ab = segment.b - segment.a;
    let length = ab.length();
    let valid = |x: f32| x.is_finite() && x > 0.0;
    if !valid(length) || !valid(segment.half_width) {
        return None;
    }
    let d = ab / length;
    let n = Vec2::new(-d.y, d.x);
    let q = p - segment.a;
    let (s, t) = (q.dot(d), q.dot(n));
    (s >= 0.0 && s <= length && t.abs() <= segment.half_width)
        .then(|| Vec2::new(s / length, 0.5 + 0.5 * t / segment.half_width))
}

/// The strip at a pixel's `n × n` grid of sample points (`(k + ½) / n`), each kept where
/// `alpha` reaches `threshold`: the share kept (the supersampled reference).
pub fn supersampled_coverage(
    segment: &ScreenSegment,
    pixel: IVec2,
    n: u32,
    threshold: f32,
    alpha: impl Fn(Vec2) -> f32,
) -> f32 {
    let mut kept = 0;
    for j in 0..n {
        for i in 0..n {
            let p = pixel.as_vec2() + (Vec2::new(i as f32, j as f32) + 0.5) / n as f32;
            kept += u32::from(strip_uv(segment, p).is_some_and(|uv| alpha(uv) >= threshold));
        }
    }
    kept as f32 / (n * n) as f32
}

/// The alternatives to a per-sample test, for comparison: the 4× geometric coverage with
/// one alpha test at the pixel's centre (`per_pixel`), or with alpha-to-coverage's mask
/// of `round(4 α)` samples (dithered by [`sample_thresholds`]).
pub fn centre_alpha_mask(
    segment: &ScreenSegment,
    pixel: IVec2,
    alpha: impl Fn(Vec2) -> f32,
    alpha_to_coverage: bool,
) -> u8 {
    let geometric = coverage_mask_with(segment, pixel, |_| 1.0, [0.0; 4]);
    if geometric == 0 {
        return 0;
    }
    // The centre's alpha (extrapolated onto the strip: its coordinates clamped).
    let centre = pixel.as_vec2() + 0.5;
    let ab = segment.b - segment.a;
    let d = ab / ab.length();
    let n = Vec2::new(-d.y, d.x);
    let q = centre - segment.a;
    let uv = Vec2::new(
        (q.dot(d) / ab.length()).clamp(0.0, 1.0),
        (0.5 + 0.5 * q.dot(n) / segment.half_width).clamp(0.0, 1.0),
    );
    let a = alpha(uv);
    if alpha_to_coverage {
        let thresholds = sample_thresholds(pixel);
        let mut mask = 0u8;
        for (i, t) in thresholds.iter().enumerate() {
            if a >= *t {
                mask |= 1 << i;
            }
        }
        geometric & mask
    } else if a >= 0.5 {
        geometric
    } else {
        0
    }
}

/// [`coverage_mask`] with the samples' thresholds given.
pub fn coverage_mask_with(
    segment: &ScreenSegment,
    pixel: IVec2,
    alpha: impl Fn(Vec2) -> f32,
    thresholds: [f32; 4],
) -> u8 {
    let mut mask = 0u8;
    for (i, offset) in SAMPLE_POSITIONS_4X.iter().enumerate() {
        if strip_uv(segment, pixel.as_vec2() + *offset).is_some_and(|uv| alpha(uv) >= thresholds[i])
        {
            mask |= 1 << i;
        }
    }
    mask
}

/// The share of a 4× coverage mask's samples.
pub fn resolved(mask: u8) -> f32 {
    resolved_for(mask, 4)
}

/// The share of a `count`-sample coverage mask's samples (the MSAA resolve's average).
pub fn resolved_for(mask: u8, count: u32) -> f32 {
    let n = count.clamp(1, 8);
    let kept = if n == 8 {
        mask
    } else {
        mask & ((1u8 << n) - 1)
    };
    kept.count_ones() as f32 / n as f32
}

/// The exact area of the segment's rectangle inside `pixel` (the unit square at it), by
/// clipping the rectangle to the square in `f64`.
pub fn exact_coverage(segment: &ScreenSegment, pixel: IVec2) -> f64 {
    let (a, b) = (segment.a.as_dvec2(), segment.b.as_dvec2());
    let ab = b - a;
    let length = ab.length();
    if !(length.is_finite() && length > 0.0) {
        return 0.0;
    }
    let n = DVec2::new(-ab.y, ab.x) / length * f64::from(segment.half_width);
    let mut polygon = vec![a - n, b - n, b + n, a + n];
    let (x0, y0) = (f64::from(pixel.x), f64::from(pixel.y));
    // Clip against x ≥ x0, x ≤ x0 + 1, y ≥ y0, y ≤ y0 + 1.
    for (axis, bound, keep_above) in [
        (0, x0, true),
        (0, x0 + 1.0, false),
        (1, y0, true),
        (1, y0 + 1.0, false),
    ] {
        polygon = clip(&polygon, axis, bound, keep_above);
        if polygon.is_empty() {
            return 0.0;
        }
    }
    let mut area = 0.0;
    for i in 0..polygon.len() {
        let (p, q) = (polygon[i], polygon[(i + 1) % polygon.len()]);
        area += p.x * q.y - q.x * p.y;
    }
    area.abs() * 0.5
}

/// Sutherland–Hodgman against one axis-aligned half-plane.
fn clip(polygon: &[DVec2], axis: usize, bound: f64, keep_above: bool) -> Vec<DVec2> {
    let inside = |p: DVec2| {
        if keep_above {
            p[axis] >= bound
        } else {
            p[axis] <= bound
        }
    };
    let mut out = Vec::with_capacity(polygon.len() + 2);
    for i in 0..polygon.len() {
        let (p, q) = (polygon[i], polygon[(i + 1) % polygon.len()]);
        let (pin, qin) = (inside(p), inside(q));
        if pin {
            out.push(p);
        }
        if pin != qin {
            let t = (bound - p[axis]) / (q[axis] - p[axis]);
            out.push(p + (q - p) * t);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pixels a segment can touch.
    fn pixels(segment: &ScreenSegment) -> impl Iterator<Item = IVec2> {
        let lo = (segment.a.min(segment.b) - segment.half_width - 1.0)
            .floor()
            .as_ivec2();
        let hi = (segment.a.max(segment.b) + segment.half_width + 1.0)
            .ceil()
            .as_ivec2();
        (lo.y..=hi.y).flat_map(move |y| (lo.x..=hi.x).map(move |x| IVec2::new(x, y)))
    }

    #[test]
    fn exact_coverage_of_simple_cases() {
        // A horizontal strip 0.5 px wide through a pixel's middle: half of it.
        let s = ScreenSegment {
            a: Vec2::new(-3.0, 0.5),
            b: Vec2::new(3.0, 0.5),
            half_width: 0.25,
        };
        assert!((exact_coverage(&s, IVec2::ZERO) - 0.5).abs() < 1e-9);
        assert_eq!(exact_coverage(&s, IVec2::new(0, 2)), 0.0);
        // Summed over every pixel: the rectangle's area, at any angle.
        let s = ScreenSegment {
            a: Vec2::new(0.3, 0.7),
            b: Vec2::new(7.1, 4.9),
            half_width: 0.8,
        };
        let total: f64 = pixels(&s).map(|p| exact_coverage(&s, p)).sum();
        let want = f64::from((s.b - s.a).length()) * 1.6;
        assert!((total - want).abs() < 1e-4, "{total} vs {want}");
    }

    /// A strand of known width swept over sub-pixel offsets and angles: the resolved
    /// per-sample coverage, summed along the strand, against its exact area — in mean
    /// within 1/8 pixel of width; per pixel, the 4-sample estimate's error.
    #[test]
    fn per_sample_coverage_follows_the_area() {
        let (mean, per_pixel) = coverage_sweep(4);
        println!(
            "strip coverage: width error mean {mean:.4} px; per pixel mean |Δ| {per_pixel:.3}"
        );
        assert!(mean < 0.125, "mean width error {mean} px");
        // Measured 0.061; one sample at the pixel centre (a per-pixel test) gives more.
        assert!(per_pixel < 0.08, "per-pixel coverage error {per_pixel}");
    }

    /// The coverage of straight strands swept over widths, angles and sub-pixel offsets
    /// under `count`-sample MSAA against the exact area: (mean |width error| in pixels,
    /// mean per-pixel |coverage error|).
    fn coverage_sweep(count: u32) -> (f64, f64) {
        let (mut width_error, mut strands) = (0.0f64, 0usize);
        let (mut pixel_error, mut pixel_count) = (0.0f64, 0usize);
        for width in [0.5f32, 1.0, 1.5, 3.0] {
            for angle_step in 0..24 {
                let angle = angle_step as f32 * std::f32::consts::PI / 24.0 + 0.013;
                for offset_step in 0..8 {
                    let offset = offset_step as f32 / 8.0;
                    let d = Vec2::new(angle.cos(), angle.sin());
                    let centre = Vec2::new(20.0 + offset, 20.0 + 0.37 * offset);
                    let s = ScreenSegment {
                        a: centre - d * 12.0,
                        b: centre + d * 12.0,
                        half_width: 0.5 * width,
                    };
                    let (mut got, mut want) = (0.0f64, 0.0f64);
                    for p in pixels(&s) {
                        let mask = coverage_mask_for(&s, p, 1.0, |_| 1.0, count);
                        let c = f64::from(resolved_for(mask, count));
                        let e = exact_coverage(&s, p);
                        got += c;
                        want += e;
                        if c > 0.0 || e > 0.0 {
                            pixel_error += (c - e).abs();
                            pixel_count += 1;
                        }
                    }
                    width_error += ((got - want) / 24.0).abs();
                    strands += 1;
                }
            }
        }
        (
            width_error / strands as f64,
            pixel_error / pixel_count as f64,
        )
    }

    /// Under 2×, 4× and 8× MSAA each count's own pattern and thresholds: every sample
    /// of a covered pixel is kept (8×: bits 4–7 too; the 4× pattern left them out), the
    /// thresholds are that count's steps, and the coverage follows the area the better
    /// the more samples (measured per pixel: 2× 0.108, 4× 0.061, 8× 0.039).
    #[test]
    fn every_sample_count_tests_its_own_samples() {
        let inside = ScreenSegment {
            a: Vec2::new(-4.0, 5.5),
            b: Vec2::new(14.0, 5.5),
            half_width: 3.0,
        };
        for (count, full) in [(2u32, 0b11u8), (4, 0xf), (8, 0xff)] {
            assert_eq!(sample_positions(count).len(), count as usize);
            assert!(
                sample_positions(count)
                    .iter()
                    .all(|p| p.cmpgt(Vec2::ZERO).all() && p.cmplt(Vec2::ONE).all())
            );
            assert_eq!(
                coverage_mask_for(&inside, IVec2::new(5, 5), 1.0, |_| 1.0, count),
                full
            );
            assert_eq!(resolved_for(full, count), 1.0);
            for y in 0..8 {
                for x in 0..8 {
                    let t = sample_thresholds_for(IVec2::new(x, y), count);
                    let mut steps: Vec<f32> = t[..count as usize].to_vec();
                    steps.sort_by(f32::total_cmp);
                    let want: Vec<f32> = (0..count)
                        .map(|k| (k as f32 + 0.5) / count as f32)
                        .collect();
                    assert_eq!(steps, want, "{count} samples at ({x}, {y})");
                    assert!(t[count as usize..].iter().all(|&v| v == 1.0));
                }
            }
            // A strand faded to 0.3 keeps round(0.3 · count) of each covered pixel's
            // samples (the thresholds are that count's steps).
            for y in 3..8 {
                for x in 0..8 {
                    let m = coverage_mask_for(&inside, IVec2::new(x, y), 0.3, |_| 1.0, count);
                    assert_eq!(m.count_ones(), (0.3 * count as f32).round() as u32);
                }
            }
        }
        assert_eq!(
            sample_thresholds(IVec2::new(3, 9))[..],
            sample_thresholds_for(IVec2::new(3, 9), 4)[..4]
        );
        let sweeps: Vec<(f64, f64)> = [2, 4, 8].map(coverage_sweep).to_vec();
        println!("width error, per-pixel error at 2×, 4×, 8×: {sweeps:.4?}");
        for (count, (width, _)) in [2, 4, 8].iter().zip(&sweeps) {
            assert!(*width < 0.125, "{count}×: mean width error {width} px");
        }
        assert!(
            sweeps[2].1 < sweeps[1].1 && sweeps[1].1 < sweeps[0].1,
            "{sweeps:?}"
        );
        assert!(sweeps[2].1 < 0.045, "8× per-pixel error {}", sweeps[2].1);
    }

    /// A faded strand keeps its share of samples: thresholds spread over the pixel's
    /// samples, a sub-minimum width widened with its alpha scaled.
    #[test]
    fn thin_strands_fade_instead_of_vanishing() {
        assert_eq!(clamp_width(2.0), (2.0, 1.0));
        assert_eq!(clamp_width(0.1), (MIN_WIDTH_PX, 0.2));
        assert_eq!(clamp_width(f32::NAN).1, 0.0);
        assert_eq!(clamp_width(-1.0).1, 0.0);
        // Every pixel's thresholds are the four quarters, permuted.
        for y in 0..16 {
            for x in 0..16 {
                let mut t = sample_thresholds(IVec2::new(x, y));
                t.sort_by(f32::total_cmp);
                assert_eq!(t, [0.125, 0.375, 0.625, 0.875]);
            }
        }
        // A strand 0.1 px wide: drawn at 0.5 px, alpha 0.2. Summed coverage near its area.
        let (width, fade) = clamp_width(0.1);
        let s = ScreenSegment {
            a: Vec2::new(0.2, 10.3),
            b: Vec2::new(64.2, 17.9),
            half_width: 0.5 * width,
        };
        let total: f32 = pixels(&s)
            .map(|p| resolved(coverage_mask(&s, p, fade, |_| 1.0)))
            .sum();
        let area = (s.b - s.a).length() * 0.1;
        println!("a 0.1 px strand: coverage {total:.2} against its area {area:.2}");
        assert!(total > 0.0, "the strand vanished");
        assert!((total - area).abs() < 0.35 * area, "{total} vs {area}");
    }

    /// A hair's alpha: an opaque core, soft edges (`1 − (2v − 1)²`), a tapered tip.
    fn hair_alpha(uv: Vec2) -> f32 {
        let across = 1.0 - (2.0 * uv.y - 1.0).powi(2);
        across * (1.0 - uv.x).min(0.2) / 0.2
    }

    /// Textured strands against a 16× supersampled alpha test (threshold ½): the per-pixel
    /// error of the 4× per-pixel test, alpha-to-coverage and the per-sample test (with
    /// the same ½ threshold), mean and p99; and shimmer — how much a strand's summed
    /// coverage varies (its coefficient of variation) as it drifts by 1/16 pixel a frame,
    /// where the truth keeps it constant. (`-- --nocapture` prints the figures.)
    #[test]
    fn per_sample_alpha_test_against_supersampling() {
        let mut errors: [Vec<f32>; 3] = Default::default();
        let mut shimmer = [0.0f32; 4];
        let mut configurations = 0;
        for angle_step in 0..12 {
            let angle = angle_step as f32 * std::f32::consts::PI / 12.0 + 0.05;
            let d = Vec2::new(angle.cos(), angle.sin());
            for width in [1.0f32, 2.0, 3.0] {
                let mut totals: Vec<[f32; 4]> = Vec::new();
                for frame in 0..16 {
                    let centre = Vec2::new(20.0 + frame as f32 / 16.0, 20.0);
                    let s = ScreenSegment {
                        a: centre - d * 10.0,
                        b: centre + d * 10.0,
                        half_width: 0.5 * width,
                    };
                    let mut total = [0.0f32; 4];
                    for p in pixels(&s) {
                        let reference = supersampled_coverage(&s, p, 4, 0.5, hair_alpha);
                        let methods = [
                            resolved(centre_alpha_mask(&s, p, hair_alpha, false)),
                            resolved(centre_alpha_mask(&s, p, hair_alpha, true)),
                            resolved(coverage_mask(&s, p, 1.0, hair_alpha)),
                        ];
                        if reference > 0.0 || methods.iter().any(|m| *m > 0.0) {
                            for (k, m) in methods.iter().enumerate() {
                                errors[k].push((m - reference).abs());
                            }
                        }
                        for k in 0..3 {
                            total[k] += methods[k];
                        }
                        total[3] += reference;
                    }
                    totals.push(total);
                }
                for k in 0..4 {
                    let mean = totals.iter().map(|t| t[k]).sum::<f32>() / totals.len() as f32;
                    let var = totals.iter().map(|t| (t[k] - mean).powi(2)).sum::<f32>()
                        / totals.len() as f32;
                    shimmer[k] += var.sqrt() / mean.max(1e-6);
                }
                configurations += 1;
            }
        }
        let names = [
            "per-pixel test",
            "alpha to coverage",
            "per-sample test",
            "16× reference",
        ];
        let mut stats = Vec::new();
        for (k, e) in errors.iter_mut().enumerate() {
            e.sort_by(f32::total_cmp);
            let mean = e.iter().sum::<f32>() / e.len() as f32;
            let p99 = e[e.len() * 99 / 100];
            let cv = shimmer[k] / configurations as f32;
            println!(
                "{}: mean |Δ| {mean:.4}, p99 {p99:.3}, shimmer {cv:.4}",
                names[k]
            );
            stats.push((mean, p99, cv));
        }
        println!(
            "{}: shimmer {:.4}",
            names[3],
            shimmer[3] / configurations as f32
        );
        // The per-sample test is the closest to the supersampled alpha test (measured
        // mean 0.060 against 0.176 per pixel and 0.115 alpha-to-coverage) and shimmers
        // less than the per-pixel test (0.028 against 0.042; alpha-to-coverage 0.028,
        // the 16× reference 0.004).
        assert!(
            stats[2].0 < 0.6 * stats[0].0 && stats[2].0 < 0.6 * stats[1].0,
            "{stats:?}"
        );
        assert!(stats[2].2 < 0.8 * stats[0].2, "{stats:?}");
    }
}
