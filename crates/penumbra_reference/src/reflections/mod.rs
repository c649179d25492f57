//! Billboard reflections' ground truth (#21, started): Monte Carlo integration of a GGX
//! specular lobe — isotropic or anisotropic — over the radiance each reflected direction
//! sees, with the visible normals sampled as Heitz does ("Sampling the GGX Distribution
//! of Visible Normals", JCGT 2018), so each sample weighs `F(v·h) · G2(v, l) / G1(v)`
//! (height-correlated Smith). The radiance function is the caller's: for billboards, the
//! exact composite of every quad along the ray, occluded by the scene.
//!
//! Checked against an independent quadrature of the same lobe (`D G2 / (4 n·v)` over the
//! half-vector hemisphere) and against the mirror limit.

use crate::df_shadow::TriangleOccluder;
use glam::{Vec2, Vec3, Vec4};
use penumbra_cinematic_core::reflections::pass::GpuBillboard;
use penumbra_cinematic_core::reflections::texture::MipChain;

/// A GGX lobe's roughness (`α = perceptual²`) along the surface's tangent and bitangent.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lobe {
    /// Along the tangent.
    pub alpha_t: f32,
    /// Along the bitangent.
    pub alpha_b: f32,
}

impl Lobe {
    /// An isotropic lobe.
    pub fn isotropic(alpha: f32) -> Self {
        Lobe {
            alpha_t: alpha,
            alpha_b: alpha,
        }
    }

    /// Smith's `Λ` of a direction in the local frame (z the normal).
    pub fn lambda(&self, w: Vec3) -> f32 {
        let a2 = (self.alpha_t * w.x).powi(2) + (self.alpha_b * w.y).powi(2);
        let z2 = w.z * w.z;
        0.5 * ((1.0 + a2 / z2.max(1e-20)).sqrt() - 1.0)
    }

    /// The normal distribution at a local half vector `h`.
    pub fn d(&self, h: Vec3) -> f32 {
        let (at, ab) = (self.alpha_t, self.alpha_b);
        let k = (h.x / at).powi(2) + (h.y / ab).powi(2) + h.z * h.z;
        1.0 / (std::f32::consts::PI * at * ab * k * k)
    }

    /// A visible normal for the local view `v` (`v.z > 0`) from `u` in `[0, 1)²`.
    pub fn sample_visible_normal(&self, v: Vec3, u: Vec2) -> Vec3 {
        // Stretch the view to the hemisphere configuration.
        let vh = Vec3::new(self.alpha_t * v.x, self.alpha_b * v.y, v.z).normalize();
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = if len2 > 0.0 {
            Vec3::new(-vh.y, vh.x, 0.0) / len2.sqrt()
        } else {
            Vec3::X
        };
        let t2 = vh.cross(t1);
        let r = u.x.sqrt();
        let phi = std::f32::consts::TAU * u.y;
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
        // Unstretch.
        Vec3::new(self.alpha_t * nh.x, self.alpha_b * nh.y, nh.z.max(0.0)).normalize()
    }
}

/// Schlick's Fresnel.
pub fn fresnel(f0: Vec3, v_dot_h: f32) -> Vec3 {
    f0 + (Vec3::ONE - f0) * (1.0 - v_dot_h).clamp(0.0, 1.0).powi(5)
}

/// An orthonormal frame: tangent, bitangent, normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// The anisotropy's direction (`Lobe::alpha_t` is along it).
    pub t: Vec3,
    /// `n × t`.
    pub b: Vec3,
    /// The surface normal.
    pub n: Vec3,
}

impl Frame {
    /// The frame of normal `n` with its tangent along `tangent` projected on the plane.
    pub fn new(n: Vec3, tangent: Vec3) -> Self {
        let t = (tangent - n * n.dot(tangent)).normalize();
        Frame {
            t,
            b: n.cross(t),
            n,
        }
    }

    fn to_local(self, w: Vec3) -> Vec3 {
        Vec3::new(w.dot(self.t), w.dot(self.b), w.dot(self.n))
    }

    fn to_world(self, w: Vec3) -> Vec3 {
        self.t * w.x + self.b * w.y + self.n * w.z
    }
}

/// A small deterministic generator (xorshift*), for reproducible estimates.
#[derive(Clone, Debug)]
pub struct Rng(pub u64);

impl Rng {
    /// The next number in `[0, 1)`.
    pub fn next_f32(&mut self) -> f32 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        ((self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 40) as f32) / (1u64 << 24) as f32
    }
}

/// The specular light leaving toward the eye (`view`: unit, from the surface to the
/// eye) for a lobe on `frame` with reflectance `f0`, the incoming radiance per world
/// direction given by `radiance`: `n` visible-normal samples (reflections below the
/// horizon count as 0).
pub fn specular_estimate(
    frame: Frame,
    view: Vec3,
    lobe: Lobe,
    f0: Vec3,
    n: u32,
    rng: &mut Rng,
    mut radiance: impl FnMut(Vec3) -> Vec3,
) -> Vec3 {
    let v = frame.to_local(view);
    if v.z <= 0.0 {
        return Vec3::ZERO;
    }
    let g1v = 1.0 / (1.0 + lobe.lambda(v));
    let mut sum = Vec3::ZERO;
    for _ in 0..n {
        let u = Vec2::new(rng.next_f32(), rng.next_f32());
        let h = lobe.sample_visible_normal(v, u);
        let l = 2.0 * v.dot(h) * h - v;
        if l.z <= 0.0 {
            continue;
        }
        let g2 = 1.0 / (1.0 + lobe.lambda(v) + lobe.lambda(l));
        sum += fresnel(f0, v.dot(h)) * (g2 / g1v) * radiance(frame.to_world(l));
    }
    sum / n as f32
}

/// The billboards' ground truth along one ray: every quad the ray meets from its front,
/// nearest first and without a layer limit, each its image's bilinear sample at the hit
/// (level 0: no filtering), composited front to back up to the first occluding triangle.
pub struct BillboardTruth<'a> {
    /// The quads (their image layer and emissive).
    pub billboards: &'a [GpuBillboard],
    /// Each layer's image (premultiplied; only level 0 is read).
    pub images: &'a [MipChain],
    /// Triangles that hide what lies behind them.
    pub occluders: Option<&'a TriangleOccluder>,
}

impl BillboardTruth<'_> {
    /// Premultiplied radiance (cd/m²) and coverage arriving along `dir` at `origin`.
    pub fn radiance(&self, origin: Vec3, dir: Vec3) -> Vec4 {
        let mut hits: Vec<(f32, u32, Vec2)> = self
            .billboards
            .iter()
            .enumerate()
            .filter_map(|(i, b)| {
                b.billboard()
                    .intersect(origin, dir)
                    .map(|(t, uv)| (t, i as u32, uv))
            })
            .collect();
        hits.sort_by(|a, b| (a.0, a.1).partial_cmp(&(b.0, b.1)).expect("finite"));
        let blocked = self
            .occluders
            .and_then(|o| o.first_hit(origin, dir, f32::MAX))
            .unwrap_or(f32::INFINITY);
        let (mut colour, mut transmittance) = (Vec3::ZERO, 1.0f32);
        for (t, i, uv) in hits {
            if t >= blocked {
                break;
            }
            let b = &self.billboards[i as usize];
            let texel = self.images[b.layer as usize].bilinear(0, uv);
            colour += transmittance * texel.truncate() * b.emissive;
            transmittance *= 1.0 - texel.w.clamp(0.0, 1.0);
        }
        colour.extend(1.0 - transmittance)
    }
}

/// The lobe-weighted mean of a radiance function over reflected directions — what a
/// specular layer should hold (the environment BRDF scales it after): `Σ L w / Σ w` with
/// `w = G2 / G1` over visible-normal samples (F = 1), below-horizon reflections kept as
/// black. Premultiplied radiance and coverage, as [`BillboardTruth::radiance`].
pub fn lobe_mean(
    frame: Frame,
    view: Vec3,
    lobe: Lobe,
    n: u32,
    seed: u64,
    mut radiance: impl FnMut(Vec3) -> Vec4,
) -> Vec4 {
    let mut cache = Vec::with_capacity(n as usize);
    let weight = specular_estimate(frame, view, lobe, Vec3::ONE, n, &mut Rng(seed), |_| {
        Vec3::ONE
    })
    .x;
    let colour = specular_estimate(frame, view, lobe, Vec3::ONE, n, &mut Rng(seed), |l| {
        let r = radiance(l);
        cache.push(r.w);
        r.truncate()
    });
    let mut k = 0;
    let coverage = specular_estimate(frame, view, lobe, Vec3::ONE, n, &mut Rng(seed), |_| {
        k += 1;
        Vec3::splat(cache[k - 1])
    })
    .x;
    if weight <= 0.0 {
        return Vec4::ZERO;
    }
    (colour / weight).extend(coverage / weight)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lobe's directional albedo (F = 1) by quadrature over half vectors: `∫ D G2
    /// (v·h) / (n·v) dω_h` over the `h` whose reflection is above the horizon, with
    /// `θ_h = atan(α tan x)` on a uniform `x` grid (dense where D peaks) — no sampling.
    fn albedo_by_quadrature(lobe: Lobe, v: Vec3) -> f64 {
        let alpha = f64::from(lobe.alpha_t.max(lobe.alpha_b));
        let (nx, nphi) = (4000, 720);
        let mut sum = 0.0f64;
        for i in 0..nx {
            let x = (i as f64 + 0.5) / nx as f64 * std::f64::consts::FRAC_PI_2;
            let theta = (alpha * x.tan()).atan();
            let dtheta = alpha / x.cos().powi(2) / (1.0 + (alpha * x.tan()).powi(2))
                * (std::f64::consts::FRAC_PI_2 / nx as f64);
            for j in 0..nphi {
                let phi = (j as f64 + 0.5) / nphi as f64 * std::f64::consts::TAU;
                let h = Vec3::new(
                    (theta.sin() * phi.cos()) as f32,
                    (theta.sin() * phi.sin()) as f32,
                    theta.cos() as f32,
                );
                let vh = v.dot(h);
                if vh <= 0.0 {
                    continue;
                }
                let l = 2.0 * vh * h - v;
                if l.z <= 0.0 {
                    continue;
                }
                let g2 = 1.0 / (1.0 + lobe.lambda(v) + lobe.lambda(l));
                let d_omega = theta.sin() * dtheta * std::f64::consts::TAU / nphi as f64;
                sum += f64::from(lobe.d(h) * g2 * vh / v.z) * d_omega;
            }
        }
        sum
    }

    /// White furnace: the estimate of a lobe under uniform radiance 1 (F = 1) is its
    /// directional albedo; against the quadrature, isotropic and anisotropic, grazing
    /// views included.
    #[test]
    fn the_estimate_matches_the_lobe_albedo() {
        let frame = Frame::new(Vec3::Z, Vec3::X);
        let mut worst = 0.0f64;
        for lobe in [
            Lobe::isotropic(0.05),
            Lobe::isotropic(0.3),
            Lobe::isotropic(0.7),
            Lobe {
                alpha_t: 0.5,
                alpha_b: 0.1,
            },
        ] {
            for (theta, phi) in [(0.0f32, 0.0f32), (0.8, 0.3), (1.3, 1.2)] {
                let v = Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                );
                let want = albedo_by_quadrature(lobe, v);
                let mut rng = Rng(0x1234_5678_9abc_def1);
                let got =
                    specular_estimate(frame, v, lobe, Vec3::ONE, 200_000, &mut rng, |_| Vec3::ONE);
                let e = (f64::from(got.x) - want).abs();
                worst = worst.max(e);
                assert!(
                    e < 0.004,
                    "{lobe:?} at θ {theta}: estimate {} vs quadrature {want}",
                    got.x
                );
            }
        }
        eprintln!("white furnace: worst |estimate − quadrature| {worst:.4}");
    }

    /// A near-mirror lobe returns the radiance of the mirror direction.
    #[test]
    fn a_smooth_lobe_is_a_mirror() {
        let n = Vec3::new(0.2, 1.0, 0.1).normalize();
        let frame = Frame::new(n, Vec3::X);
        let view = Vec3::new(0.3, 0.5, 0.8).normalize();
        let mirror = 2.0 * view.dot(n) * n - view;
        let radiance = |l: Vec3| Vec3::new(l.x, l.y, l.z) * 0.5 + 0.5;
        let mut rng = Rng(3);
        let got = specular_estimate(
            frame,
            view,
            Lobe::isotropic(1e-4),
            Vec3::ONE,
            256,
            &mut rng,
            radiance,
        );
        assert!(
            (got - radiance(mirror)).length() < 1e-3,
            "{got} vs {}",
            radiance(mirror)
        );
    }

    /// Anisotropy stretches the reflection along the tangent: the spread of reflected
    /// directions is wider along `t` than along `b`.
    #[test]
    fn anisotropy_spreads_along_the_tangent() {
        let lobe = Lobe {
            alpha_t: 0.4,
            alpha_b: 0.05,
        };
        let mut rng = Rng(11);
        let (mut sx, mut sy) = (0.0f32, 0.0f32);
        for _ in 0..10_000 {
            let h = lobe.sample_visible_normal(Vec3::Z, Vec2::new(rng.next_f32(), rng.next_f32()));
            sx += h.x * h.x;
            sy += h.y * h.y;
        }
        assert!(sx > 20.0 * sy, "spread along t {sx}, along b {sy}");
    }
}

#[cfg(test)]
mod figures;
