//! The screen-space pass's CPU model: per scattering pixel, the disc's samples on its
//! tangent plane projected to the screen; a sample counts where the pixel there scatters
//! with the same profile, weighted per channel by the profile at the distance between the
//! two surface points (never under the sample's disc radius) over the density it was
//! drawn with — so a sample that
//! lands on another surface (across a silhouette, a depth step) weighs next to nothing —
//! and normalised per channel. Non-scattering pixels are left as they are.
//!
//! The independent check is [`surface_convolution`]: the irradiance of points spread over
//! the surface itself (with their areas), convolved with the profile in world space —
//! no screen, no sampling.

use super::{ScatterProfile, disc_samples, profile};
use crate::camera::PerspectiveCamera;
use glam::Vec3;

/// The pass's inputs, per pixel (row-major from the top): what a deferred renderer has.
#[derive(Clone, Debug, Default)]
pub struct ScatterInput {
    /// Pixels across and down.
    pub width: u32,
    /// Pixels down.
    pub height: u32,
    /// World position of the surface seen (`None`: the sky).
    pub position: Vec<Option<Vec3>>,
    /// Unit world normal.
    pub normal: Vec<Vec3>,
    /// Diffuse irradiance (before the albedo).
    pub irradiance: Vec<Vec3>,
    /// The pixel's scattering profile (an index into the pass's profiles), if it scatters.
    pub profile: Vec<Option<usize>>,
}

/// A per-pixel, per-frame pair of numbers in `[0, 1)` (rotation and jitter): a hash, so
/// neighbouring pixels and frames decorrelate.
pub fn pixel_noise(x: u32, y: u32, frame: u32) -> (f32, f32) {
    let mut h =
        x.wrapping_mul(0x8da6_b343) ^ y.wrapping_mul(0xd816_3841) ^ frame.wrapping_mul(0xcb1a_b31f);
    let mut next = || {
        h ^= h >> 16;
        h = h.wrapping_mul(0x7feb_352d);
        h ^= h >> 15;
        h = h.wrapping_mul(0x846c_a68b);
        h ^= h >> 16;
        (h >> 8) as f32 / (1u32 << 24) as f32
    };
    (next(), next())
}

/// Two unit tangents completing `n` (Duff et al. 2017).
pub fn tangents(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// The scattered diffuse irradiance of every pixel for `frame` (`n` samples each).
pub fn scatter_screen(
    input: &ScatterInput,
    camera: &PerspectiveCamera,
    profiles: &[ScatterProfile],
    n: u32,
    frame: u32,
) -> Vec<Vec3> {
    let (w, h) = (input.width, input.height);
    let mut out = input.irradiance.clone();
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            let (Some(k), Some(p)) = (input.profile[i], input.position[i]) else {
                continue;
            };
            let prof = &profiles[k];
            let d_max = prof.d.max_element();
            if d_max.is_nan() || d_max <= 0.0 {
                continue;
            }
            let (t, b) = tangents(input.normal[i]);
            let noise = pixel_noise(x, y, frame);
            let (mut sum, mut weights) = (Vec3::ZERO, Vec3::ZERO);
            for o in disc_samples(prof, n, noise.0 * std::f32::consts::TAU, noise.1) {
                let q_world = p + t * o.x + b * o.y;
                let Some((qx, qy)) = camera.project(q_world) else {
                    continue;
                };
                if qx < 0.0 || qy < 0.0 || qx >= w as f32 || qy >= h as f32 {
                    continue;
                }
                let j = (qy as u32 * w + qx as u32) as usize;
                let (Some(kq), Some(q)) = (input.profile[j], input.position[j]) else {
                    continue;
                };
                if kq != k {
                    continue;
                }
                // (Never 0: the profile's 1/r would make the weight ∞/∞.)
                let disc = o.length().max(1e-6 * d_max);
                let sampled = profile(disc, d_max);
                if sampled <= 0.0 {
                    continue;
                }
                // The distance between the surface points, never under the disc's: a
                // sample on the same smooth surface weighs as on the plane (the pixel grid
                // moves it by up to half a pixel), one across a depth step far less.
                let r = (q - p).length().max(disc);
                let wc = Vec3::new(
                    profile(r, prof.d.x),
                    profile(r, prof.d.y),
                    profile(r, prof.d.z),
                ) / sampled;
                sum += wc * input.irradiance[j];
                weights += wc;
            }
            out[i] = Vec3::select(weights.cmpgt(Vec3::ZERO), sum / weights, out[i]);
        }
    }
    out
}

/// Ground truth at surface point `at`: the irradiance of `surface` (points with their
/// areas) convolved with the profile by distance in world space, normalised per channel
/// over the surface (as the pass normalises over the samples it keeps).
pub fn surface_convolution(
    surface: &[(Vec3, f32)],
    irradiance: impl Fn(Vec3) -> Vec3,
    at: Vec3,
    prof: &ScatterProfile,
) -> Vec3 {
    let (mut sum, mut weights) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
    for &(y, area) in surface {
        let r = (y - at).length();
        // The profile's 1/r singularity: a point on top of `at` counts at a quarter of its
        // cell's size (the cells are small against d).
        let r = r.max(0.25 * area.sqrt());
        let w = Vec3::new(
            profile(r, prof.d.x),
            profile(r, prof.d.y),
            profile(r, prof.d.z),
        ) * area;
        sum += (w * irradiance(y)).as_dvec3();
        weights += w.as_dvec3();
    }
    (sum / weights).as_vec3()
}

/// Points over a sphere with their areas, `rings × 2 rings` cells of equal angle.
pub fn sphere_surface(center: Vec3, radius: f32, rings: u32) -> Vec<(Vec3, f32)> {
    let mut out = Vec::new();
    let (nt, np) = (rings, 2 * rings);
    for i in 0..nt {
        let theta = (i as f32 + 0.5) / nt as f32 * std::f32::consts::PI;
        let dtheta = std::f32::consts::PI / nt as f32;
        for j in 0..np {
            let phi = (j as f32 + 0.5) / np as f32 * std::f32::consts::TAU;
            let dphi = std::f32::consts::TAU / np as f32;
            let n = Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            );
            let area = radius * radius * theta.sin() * dtheta * dphi;
            out.push((center + n * radius, area));
        }
    }
    out
}
