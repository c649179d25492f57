//! CPU model of screen-space subsurface scattering's kernel (#20, started): the diffuse
//! irradiance around a point of a scattering surface, gathered at `n` importance-sampled
//! offsets on its tangent plane (radii stratified in the widest channel's radial CDF and
//! jittered, angles spread by the golden angle and rotated — jitter and rotation drawn
//! per pixel and frame, so frames average to the convolution), each channel weighted by
//! its own profile over the sampled one and normalised per channel (Jimenez et al.,
//! "Separable Subsurface Scattering", 2015; Unity HDRP's disc sampling of Burley's
//! profile). The independent check is [`convolve`]: the profile integrated against the
//! irradiance on a fine polar grid, no sampling.
//!
//! [`screen`]: the pass over a screen's pixels (depth- and profile-aware), checked against
//! a convolution over the surface itself. The profile and its sampling:
//! `penumbra_cinematic_core::sss`.

use glam::{Vec2, Vec3};
pub use penumbra_cinematic_core::sss::{ScatterProfile, cdf, profile, sample_radius};

pub mod screen;
#[cfg(test)]
mod screen_tests;

/// The golden angle, radians: successive samples' angles, so any `n` of them cover the
/// circle evenly.
pub const GOLDEN_ANGLE: f32 = 2.399_963_3;

/// The `n` sample offsets (metres, on the tangent plane) of a disc: sample `i` at radius
/// `sample_radius((i + jitter) / n)` of the widest channel's profile (`jitter` in
/// `[0, 1)`), angle `i · golden angle + rotation`.
pub fn disc_samples(profile: &ScatterProfile, n: u32, rotation: f32, jitter: f32) -> Vec<Vec2> {
    let d = profile.d.max_element();
    (0..n)
        .map(|i| {
            let r = sample_radius((i as f32 + jitter) / n as f32, d);
            let a = i as f32 * GOLDEN_ANGLE + rotation;
            Vec2::new(a.cos(), a.sin()) * r
        })
        .collect()
}

/// The scattered irradiance at `at`: the mean of `irradiance` at the disc's samples,
/// each channel weighted by its profile over the sampled (widest) one, normalised per
/// channel. A channel whose profile is the widest weighs its samples equally.
pub fn scatter(
    irradiance: impl Fn(Vec2) -> Vec3,
    at: Vec2,
    profile: &ScatterProfile,
    n: u32,
    (rotation, jitter): (f32, f32),
) -> Vec3 {
    let d_max = profile.d.max_element();
    if d_max.is_nan() || d_max <= 0.0 {
        return irradiance(at);
    }
    let (mut sum, mut weights) = (Vec3::ZERO, Vec3::ZERO);
    for offset in disc_samples(profile, n, rotation, jitter) {
        let r = offset.length();
        let sampled = self::profile(r, d_max);
        // Channels narrower than the widest: their profile over the sampled one (a
        // channel of d = 0 keeps only what lies at the centre: no scattering).
        let w = Vec3::new(
            weight(r, profile.d.x, sampled),
            weight(r, profile.d.y, sampled),
            weight(r, profile.d.z, sampled),
        );
        sum += w * irradiance(at + offset);
        weights += w;
    }
    let own = irradiance(at);
    Vec3::select(weights.cmpgt(Vec3::ZERO), sum / weights, own)
}

/// One channel's weight for a sample at radius `r` drawn from a profile whose value there
/// is `sampled`.
fn weight(r: f32, d: f32, sampled: f32) -> f32 {
    if d > 0.0 && sampled > 0.0 {
        profile(r, d) / sampled
    } else {
        0.0
    }
}

/// Ground truth: the irradiance convolved with each channel's profile, by the midpoint
/// rule on a polar grid (`rings` rings uniform in the CDF of that channel, `spokes`
/// angles each), out to where the profile holds all but 10⁻⁵ of its energy.
pub fn convolve(
    irradiance: impl Fn(Vec2) -> Vec3,
    at: Vec2,
    profile: &ScatterProfile,
    rings: u32,
    spokes: u32,
) -> Vec3 {
    let channel = |c: usize| -> f32 {
        let d = profile.d[c];
        if d.is_nan() || d <= 0.0 {
            return irradiance(at)[c];
        }
        let mut sum = 0.0f64;
        // Ring k holds the energy between CDF k/rings and (k + 1)/rings (times 1 − 10⁻⁵).
        for k in 0..rings {
            let lo = sample_radius(k as f32 / rings as f32 * (1.0 - 1e-5), d);
            let hi = sample_radius((k + 1) as f32 / rings as f32 * (1.0 - 1e-5), d);
            let r = 0.5 * (lo + hi);
            for s in 0..spokes {
                let a = (s as f32 + 0.5) / spokes as f32 * std::f32::consts::TAU;
                sum += f64::from(irradiance(at + Vec2::new(a.cos(), a.sin()) * r)[c]);
            }
        }
        (sum / f64::from(rings * spokes)) as f32
    };
    Vec3::new(channel(0), channel(1), channel(2))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Skin-like: red spreads furthest.
    fn skin() -> ScatterProfile {
        ScatterProfile::new(Vec3::new(1.0, 0.4, 0.25), 0.003)
    }

    /// A uniformly lit plane stays as lit (energy kept) for any sample count and rotation.
    #[test]
    fn uniform_light_is_kept() {
        let light = |_: Vec2| Vec3::new(2.0, 1.0, 0.5);
        for n in [1, 4, 16, 64] {
            for rotation in [0.0, 1.3] {
                let got = scatter(light, Vec2::ZERO, &skin(), n, (rotation, 0.5));
                assert!(
                    (got - light(Vec2::ZERO)).abs().max_element() < 1e-5,
                    "{n}: {got}"
                );
            }
        }
        let truth = convolve(light, Vec2::ZERO, &skin(), 64, 64);
        assert!(
            (truth - light(Vec2::ZERO)).abs().max_element() < 1e-4,
            "{truth}"
        );
    }

    /// A thin lit strip on the plane: across it, the scattered light falls off as the
    /// profile's line integral. The truth by quadrature of the strip itself (its width
    /// times the profile integrated along the line, in closed form per sample point)
    /// agrees with `convolve`, and `scatter` with 16 samples converges to it when
    /// averaged over rotations (as the per-frame rotation averages over frames).
    #[test]
    fn a_lit_line_scatters_as_the_profile() {
        let profile = skin();
        let width = 1e-4f32;
        let strip = move |p: Vec2| {
            if p.x.abs() < 0.5 * width {
                Vec3::ONE
            } else {
                Vec3::ZERO
            }
        };
        // ∫ R(√(x² + y²)) dy across the strip's width: the line response times width.
        let line = |x: f32, d: f32| -> f32 {
            let n = 20_000;
            let ymax = 40.0 * d;
            let dy = 2.0 * ymax / n as f32;
            (0..n)
                .map(|i| {
                    let y = -ymax + (i as f32 + 0.5) * dy;
                    profile_at((x * x + y * y).sqrt(), d) * dy
                })
                .sum::<f32>()
                * width
        };
        fn profile_at(r: f32, d: f32) -> f32 {
            super::profile(r, d)
        }
        let mut worst_truth = 0.0f32;
        let mut worst_model = 0.0f32;
        let rotations = 4096;
        for x in [0.0005f32, 0.001, 0.002, 0.004, 0.008] {
            let want = Vec3::new(
                line(x, profile.d.x),
                line(x, profile.d.y),
                line(x, profile.d.z),
            );
            let truth = convolve(strip, Vec2::new(x, 0.0), &profile, 4000, 720);
            // Frames: rotation and jitter from a 2D low-discrepancy sequence.
            let model = (0..rotations)
                .map(|k| {
                    let rotation = k as f32 / rotations as f32 * std::f32::consts::TAU;
                    let jitter = (k as f32 * 0.618_034).fract();
                    scatter(strip, Vec2::new(x, 0.0), &profile, 16, (rotation, jitter))
                })
                .sum::<Vec3>()
                / rotations as f32;
            let rel = |a: Vec3, b: Vec3| ((a - b) / b.max(Vec3::splat(1e-12))).abs();
            // Only the red channel reaches far: judge the channels where the response
            // is at least 20 % of red's.
            for c in 0..3 {
                if want[c] > 0.2 * want.x {
                    worst_truth = worst_truth.max(rel(truth, want)[c]);
                    worst_model = worst_model.max(rel(model, want)[c]);
                }
            }
            eprintln!(
                "x {:.1} mm: line {want:?}, convolve {truth:?}, 16 samples {model:?}",
                x * 1e3
            );
        }
        eprintln!(
            "worst relative error: convolve {worst_truth:.4}, 16 samples (mean of {rotations} rotations) {worst_model:.4}"
        );
        assert!(worst_truth < 0.01, "{worst_truth}");
        assert!(worst_model < 0.06, "{worst_model}");
    }
}
