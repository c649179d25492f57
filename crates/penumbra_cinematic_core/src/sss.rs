//! Screen-space subsurface scattering (#20, started): Burley's normalized diffusion
//! profile (Christensen and Burley, "Approximate Reflectance Profiles for Efficient
//! Subsurface Scattering", 2015 — the profile Unreal and Unity HDRP use), per colour
//! channel, and its importance sampling.
//!
//! The profile of shape distance `d` (metres), normalised to integrate to 1 over the plane:
//!
//! ```text
//! R(r) = (e^(−r/d) + e^(−r/(3d))) / (8π d r),      ∫₀^∞ R(r) 2π r dr = 1
//! ```
//!
//! Its radial CDF, the fraction of the energy within `r`, is
//! `1 − ¼ e^(−r/d) − ¾ e^(−r/(3d))`; samples at radii drawn from it weigh equally
//! ([`sample_radius`]). The artist's inputs are a scatter colour and a world-space radius:
//! channel `c` scatters with `d_c = radius · colour_c` ([`ScatterProfile`]).

use encase::ShaderType;
use glam::{Vec3, Vec4};

/// The first deferred lighting pass id of a scattering material: a `StandardMaterial`
/// whose `deferred_lighting_pass_id` is `FIRST_LIGHTING_ID + k` scatters with profile `k`
/// (the G-buffer's 8-bit lighting id is the profile index, as Unreal's G-buffer carries
/// a subsurface profile id).
pub const FIRST_LIGHTING_ID: u8 = 192;

/// Profiles the lighting ids can name (`FIRST_LIGHTING_ID..=255`).
pub const MAX_PROFILES: usize = 256 - FIRST_LIGHTING_ID as usize;

/// The scatter pass's uniform (`penumbra::sss::scatter::SubsurfaceUniform`).
#[derive(ShaderType, Clone, Copy, Debug, PartialEq)]
pub struct SubsurfaceUniform {
    /// Disc samples per pixel.
    pub samples: u32,
    /// The frame the disc's rotation and jitter are hashed with (0 every frame when
    /// temporal randomisation is off).
    pub frame: u32,
    /// [`FIRST_LIGHTING_ID`].
    pub first_id: u32,
    /// 0 shading; 1 the diffuse irradiance before scattering, 2 after (alpha `2 + k` on
    /// pixels of profile `k`).
    pub debug_view: u32,
    /// Per profile: `d` per channel (metres; 0 for unused slots), `w` unused.
    pub profiles: [Vec4; MAX_PROFILES],
}

impl Default for SubsurfaceUniform {
    fn default() -> Self {
        SubsurfaceUniform {
            samples: 0,
            frame: 0,
            first_id: u32::from(FIRST_LIGHTING_ID),
            debug_view: 0,
            profiles: [Vec4::ZERO; MAX_PROFILES],
        }
    }
}

/// Burley's normalized diffusion profile at distance `r` (metres) for shape distance `d`
/// (metres), per unit area: integrates to 1 over the plane. Infinite at `r = 0` (an
/// integrable `1/r` singularity); 0 for `d ≤ 0`.
pub fn profile(r: f32, d: f32) -> f32 {
    if d.is_nan() || d <= 0.0 {
        return 0.0;
    }
    let r = r.max(0.0);
    ((-r / d).exp() + (-r / (3.0 * d)).exp()) / (8.0 * std::f32::consts::PI * d * r)
}

/// The fraction of the profile's energy within distance `r` of its centre.
pub fn cdf(r: f32, d: f32) -> f32 {
    if d.is_nan() || d <= 0.0 {
        return 1.0;
    }
    let x = r.max(0.0) / d;
    // ¼(1 − e^(−x)) + ¾(1 − e^(−x/3)), accurate for small x too.
    -0.25 * (-x).exp_m1() - 0.75 * (-x / 3.0).exp_m1()
}

/// The radius within which a fraction `u` (in `[0, 1)`) of the profile's energy lies: the
/// inverse of [`cdf`], by Newton's method in `x = r / d` from a start within 3 % of the
/// root (at most 8 steps, to a relative `1e-6`). Radii drawn this way from uniform `u`
/// have the profile's radial distribution.
pub fn sample_radius(u: f32, d: f32) -> f32 {
    if d.is_nan() || d <= 0.0 {
        return 0.0;
    }
    let u = u.clamp(0.0, 1.0 - 1e-7);
    // Solve 1 − ¼e^(−x) − ¾e^(−x/3) = u, i.e. g(x) = ¼e^(−x) + ¾e^(−x/3) − (1 − u) = 0,
    // g decreasing and convex. Start from the tail term alone (x = −3 ln((1 − u)/¾)),
    // an over-estimate for u > ¼, else from u itself (the slope at 0 is 1/2).
    let q = 1.0 - u;
    let mut x = if q < 0.75 {
        -3.0 * (q / 0.75).ln()
    } else {
        2.0 * u
    };
    for _ in 0..8 {
        let a = (-x).exp();
        let b = (-x / 3.0).exp();
        let g = 0.25 * a + 0.75 * b - q;
        let slope = -0.25 * a - 0.25 * b;
        let step = g / slope;
        x = (x - step).max(0.0);
        if step.abs() <= 1e-6 * x.max(1e-6) {
            break;
        }
    }
    x * d
}

/// A scattering material's profile: per colour channel, `d = radius · colour`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScatterProfile {
    /// Shape distance per channel, metres.
    pub d: Vec3,
}

impl ScatterProfile {
    /// The profile of a scatter `colour` (each channel in `[0, 1]`: how far that channel
    /// spreads relative to the others; skin ≈ (0.8, 0.3, 0.2)) and a world-space
    /// `radius` (metres: the red channel of skin ≈ 3 mm).
    pub fn new(colour: Vec3, radius: f32) -> Self {
        ScatterProfile {
            d: colour.clamp(Vec3::ZERO, Vec3::ONE) * radius.max(0.0),
        }
    }

    /// The profile's value at distance `r`, per channel.
    pub fn at(&self, r: f32) -> Vec3 {
        Vec3::new(
            profile(r, self.d.x),
            profile(r, self.d.y),
            profile(r, self.d.z),
        )
    }

    /// The radius holding a fraction `u` of the widest channel's energy (the disc the
    /// samples are drawn in).
    pub fn reach(&self, u: f32) -> f32 {
        sample_radius(u, self.d.max_element())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The profile integrates to 1 over the plane, by quadrature of `R(r) 2π r` (not
    /// through the CDF), for shape distances from 0.1 mm to 1 m.
    #[test]
    fn profile_integrates_to_one() {
        for d in [1e-4f32, 3e-3, 0.05, 1.0] {
            // Midpoint rule in x = r / d up to x = 60 (e^(−20) left over).
            let n = 200_000;
            let dx = 60.0 / n as f64;
            let sum: f64 = (0..n)
                .map(|i| {
                    let r = (i as f64 + 0.5) * dx * f64::from(d);
                    f64::from(profile(r as f32, d)) * 2.0 * std::f64::consts::PI * r
                })
                .sum::<f64>()
                * dx
                * f64::from(d);
            assert!((sum - 1.0).abs() < 1e-4, "d {d}: {sum}");
        }
        assert_eq!(profile(1.0, 0.0), 0.0);
        assert_eq!(profile(1.0, f32::NAN), 0.0);
    }

    /// The CDF is the profile's integral, and `sample_radius` inverts it.
    #[test]
    fn sampling_inverts_the_cdf() {
        let d = 0.003;
        // The CDF's slope is the profile times 2π r.
        for r in [1e-5f32, 1e-4, 1e-3, 0.01, 0.03] {
            let h = r * 1e-3;
            let slope = (cdf(r + h, d) - cdf(r - h, d)) / (2.0 * h);
            let want = profile(r, d) * 2.0 * std::f32::consts::PI * r;
            assert!(
                (slope / want - 1.0).abs() < 2e-3,
                "r {r}: {slope} vs {want}"
            );
        }
        let mut worst = 0.0f32;
        for i in 0..=1000 {
            let u = i as f32 / 1000.0 * 0.999;
            let r = sample_radius(u, d);
            worst = worst.max((cdf(r, d) - u).abs());
        }
        assert!(worst < 1e-6, "{worst}");
        assert_eq!(sample_radius(0.0, d), 0.0);
        assert_eq!(sample_radius(0.5, 0.0), 0.0);
        assert!(sample_radius(1.0, d).is_finite());
    }

    #[test]
    fn scatter_profile_scales_each_channel() {
        let p = ScatterProfile::new(Vec3::new(1.0, 0.5, 2.0), 0.004);
        assert_eq!(p.d, Vec3::new(0.004, 0.002, 0.004));
        // Half the energy of the widest channel lies within about 2.1 d (the median).
        let median = p.reach(0.5) / 0.004;
        assert!((cdf(median * 0.004, 0.004) - 0.5).abs() < 1e-6, "{median}");
        assert_eq!(ScatterProfile::new(Vec3::ONE, -1.0).d, Vec3::ZERO);
    }
}
