//! Bevy 0.19 `StandardMaterial` shading, transcribed from `bevy_pbr`'s
//! `pbr_lighting.wgsl`, `pbr_functions.wgsl` and `pbr_ambient.wgsl`.
//!
//! Covered: opaque dielectric/metallic materials lit by directional lights and the global
//! ambient light, no textures, no clearcoat, anisotropy or transmission, no environment
//! map, Bevy's polynomial `F_AB` (the `dfg_lut` feature is off). Output is linear
//! radiance already multiplied by the camera exposure, i.e. what Bevy writes to its view
//! target before tonemapping.

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// A `StandardMaterial` subset: every field means what Bevy's field of the same name means.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Linear RGB base colour (Bevy: `base_color`, converted to linear).
    pub base_color: Vec3,
    /// Perceptual roughness in [0, 1] (Bevy clamps it to ≥ 0.089).
    pub perceptual_roughness: f32,
    /// Metallic in [0, 1].
    pub metallic: f32,
    /// Dielectric reflectance in [0, 1]; F0 = 0.16 · reflectance².
    pub reflectance: f32,
    /// Linear emissive radiance (Bevy: `emissive`, in nits before exposure).
    pub emissive: Vec3,
}

impl Default for Material {
    /// Bevy's `StandardMaterial::default()`: white, roughness 0.5, dielectric, reflectance 0.5.
    fn default() -> Self {
        Self {
            base_color: Vec3::ONE,
            perceptual_roughness: 0.5,
            metallic: 0.0,
            reflectance: 0.5,
            emissive: Vec3::ZERO,
        }
    }
}

/// A directional light as Bevy uploads it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectionalLight {
    /// Unit vector from the surface toward the light (Bevy: `direction_to_light`).
    pub direction_to_light: Vec3,
    /// Linear colour × illuminance in lux (Bevy premultiplies these).
    pub color_lux: Vec3,
}

/// The camera's exposure factor from EV100, as Bevy's `Exposure::exposure()`.
pub fn exposure_from_ev100(ev100: f32) -> f32 {
    (-ev100).exp2() / 1.2
}

/// Bevy's default camera exposure (`Exposure::BLENDER`, EV100 9.7).
pub const EV100_BLENDER: f32 = 9.7;

fn f_schlick(f0: f32, f90: f32, v_dot_h: f32) -> f32 {
    f0 + (f90 - f0) * (1.0 - v_dot_h).powf(5.0)
}

fn f_schlick_vec(f0: Vec3, f90: f32, v_dot_h: f32) -> Vec3 {
    f0 + (Vec3::splat(f90) - f0) * (1.0 - v_dot_h).powf(5.0)
}

fn fresnel(f0: Vec3, l_dot_h: f32) -> Vec3 {
    let f90 = (f0.dot(Vec3::splat(50.0 * 0.33))).clamp(0.0, 1.0);
    f_schlick_vec(f0, f90, l_dot_h)
}

fn d_ggx(roughness: f32, n_dot_h: f32) -> f32 {
    let one_minus = 1.0 - n_dot_h * n_dot_h;
    let a = n_dot_h * roughness;
    let k = roughness / (one_minus + a * a);
    k * k * (1.0 / PI)
}

fn v_smith_ggx_correlated(roughness: f32, n_dot_v: f32, n_dot_l: f32) -> f32 {
    let a2 = roughness * roughness;
    let lambda_v = n_dot_l * ((n_dot_v - a2 * n_dot_v) * n_dot_v + a2).sqrt();
    let lambda_l = n_dot_v * ((n_dot_l - a2 * n_dot_l) * n_dot_l + a2).sqrt();
    0.5 / (lambda_v + lambda_l)
}

/// Bevy's polynomial split-sum scale/bias (`F_AB` without `DFG_LUT`).
pub fn f_ab(perceptual_roughness: f32, n_dot_v: f32) -> Vec2 {
    let c0 = [-1.0, -0.0275, -0.572, 0.022];
    let c1 = [1.0, 0.0425, 1.04, -0.04];
    let r: [f32; 4] = std::array::from_fn(|i| perceptual_roughness * c0[i] + c1[i]);
    let a004 = (r[0] * r[0]).min((-9.28 * n_dot_v).exp2()) * r[0] + r[1];
    Vec2::new(-1.04 * a004 + r[2], 1.04 * a004 + r[3]).max(Vec2::splat(0.00005))
}

fn env_brdf_approx(f0: Vec3, f_ab: Vec2) -> Vec3 {
    f0 * f_ab.x + Vec3::splat(f_ab.y)
}

/// Bevy's roughness remap: clamp perceptual roughness to [0.089, 1], then square.
pub fn perceptual_roughness_to_roughness(perceptual: f32) -> f32 {
    let p = perceptual.clamp(0.089, 1.0);
    p * p
}

/// Shading inputs at one surface point.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    /// Unit world normal.
    pub normal: Vec3,
    /// Unit vector from the surface toward the camera.
    pub view: Vec3,
}

/// Per-material values Bevy derives once per fragment.
struct Derived {
    diffuse_color: Vec3,
    f0: Vec3,
    roughness: f32,
    n_dot_v: f32,
    f_ab: Vec2,
}

fn derive(material: &Material, p: &SurfacePoint) -> Derived {
    let n_dot_v = p.normal.dot(p.view).max(0.0001);
    let f0_dielectric = Vec3::splat(0.16 * material.reflectance * material.reflectance);
    Derived {
        diffuse_color: material.base_color * (1.0 - material.metallic),
        f0: f0_dielectric.lerp(material.base_color, material.metallic),
        roughness: perceptual_roughness_to_roughness(material.perceptual_roughness),
        n_dot_v,
        f_ab: f_ab(material.perceptual_roughness, n_dot_v),
    }
}

/// Radiance (before exposure) reflected toward the viewer from one directional light,
/// ignoring shadowing: Bevy's `lighting::directional_light`.
pub fn directional_light_radiance(
    material: &Material,
    p: &SurfacePoint,
    light: &DirectionalLight,
) -> Vec3 {
    let d = derive(material, p);
    let l = light.direction_to_light;
    let h = (l + p.view).normalize();
    let n_dot_l = p.normal.dot(l).clamp(0.0, 1.0);
    let n_dot_h = p.normal.dot(h).clamp(0.0, 1.0);
    let l_dot_h = l.dot(h).clamp(0.0, 1.0);

    // Burley diffuse.
    let f90 = 0.5 + 2.0 * d.roughness * l_dot_h * l_dot_h;
    let burley = f_schlick(1.0, f90, n_dot_l) * f_schlick(1.0, f90, d.n_dot_v) / PI;
    let diffuse = d.diffuse_color * burley;

    // GGX specular with Bevy's multiscatter energy compensation.
    let dist = d_ggx(d.roughness, n_dot_h);
    let vis = v_smith_ggx_correlated(d.roughness, d.n_dot_v, n_dot_l);
    let f = fresnel(d.f0, l_dot_h);
    let mut specular = dist * vis * f;
    specular *= Vec3::ONE + d.f0 * (1.0 / (d.f_ab.x + d.f_ab.y) - 1.0);

    (diffuse + specular) * n_dot_l * light.color_lux
}

/// Radiance (before exposure) from Bevy's global ambient light (`pbr_ambient.wgsl`), with
/// no occlusion. `ambient_lux` is the linear ambient colour × brightness.
pub fn ambient_radiance(material: &Material, p: &SurfacePoint, ambient_lux: Vec3) -> Vec3 {
    let d = derive(material, p);
    let diffuse_ambient = env_brdf_approx(d.diffuse_color, f_ab(1.0, d.n_dot_v));
    let specular_ambient = env_brdf_approx(d.f0, d.f_ab);
    let specular_occlusion = d.f0.dot(Vec3::splat(50.0 * 0.33)).clamp(0.0, 1.0);
    (diffuse_ambient + specular_ambient * specular_occlusion) * ambient_lux
}

/// Linear → sRGB transfer function (IEC 61966-2-1), as the GPU applies when writing an
/// `*UnormSrgb` target. Input is clamped to [0, 1].
pub fn linear_to_srgb(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// sRGB → linear transfer function (inverse of [`linear_to_srgb`]).
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.040_45 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Encodes linear RGB to 8-bit sRGB with round-to-nearest, as an `Rgba8UnormSrgb` target.
pub fn encode_srgb8(linear: Vec3) -> [u8; 3] {
    linear
        .to_array()
        .map(|c| (linear_to_srgb(c) * 255.0 + 0.5).floor() as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_close(a: f32, b: f32, tol: f32) {
        assert!((a - b).abs() <= tol, "{a} vs {b} (tol {tol})");
    }

    #[test]
    fn srgb_round_trips_and_hits_known_values() {
        for i in 0..=100 {
            let c = i as f32 / 100.0;
            assert_close(srgb_to_linear(linear_to_srgb(c)), c, 1e-5);
        }
        assert_eq!(encode_srgb8(Vec3::new(0.0, 1.0, 0.215_861)), [0, 255, 128]);
    }

    #[test]
    fn burley_diffuse_conserves_roughly_lambert_energy() {
        // Integrate the rough-white-dielectric response (reflectance 0: no specular) over
        // the hemisphere of light directions; Burley at roughness 1 integrates close to
        // Lambert's albedo of 1 (within its known ~±10 % retro-reflection bump).
        let m = Material {
            reflectance: 0.0,
            perceptual_roughness: 1.0,
            ..Default::default()
        };
        let p = SurfacePoint {
            normal: Vec3::Z,
            view: Vec3::Z,
        };
        let n = 256;
        let mut sum = 0.0;
        for i in 0..n {
            for j in 0..n {
                // Uniform hemisphere sampling (pdf 1/2π) on a stratified grid.
                let u = (i as f32 + 0.5) / n as f32;
                let v = (j as f32 + 0.5) / n as f32;
                let z = u;
                let r = (1.0 - z * z).sqrt();
                let phi = 2.0 * PI * v;
                let light = DirectionalLight {
                    direction_to_light: Vec3::new(r * phi.cos(), r * phi.sin(), z),
                    color_lux: Vec3::ONE,
                };
                sum += directional_light_radiance(&m, &p, &light).x * 2.0 * PI;
            }
        }
        let albedo = sum / (n * n) as f32;
        assert!((0.9..1.15).contains(&albedo), "albedo {albedo}");
    }

    #[test]
    fn no_light_from_behind_and_specular_needs_reflectance() {
        let p = SurfacePoint {
            normal: Vec3::Y,
            view: Vec3::new(0.0, 0.6, 0.8),
        };
        let behind = DirectionalLight {
            direction_to_light: -Vec3::Y,
            color_lux: Vec3::ONE,
        };
        assert_eq!(
            directional_light_radiance(&Material::default(), &p, &behind),
            Vec3::ZERO
        );
        // Mirror direction: a shiny dielectric reflects more than a zero-reflectance one.
        let mirror = DirectionalLight {
            direction_to_light: Vec3::new(0.0, 0.6, -0.8),
            color_lux: Vec3::ONE,
        };
        let shiny = Material {
            perceptual_roughness: 0.2,
            ..Default::default()
        };
        let matte = Material {
            reflectance: 0.0,
            ..shiny
        };
        let a = directional_light_radiance(&shiny, &p, &mirror).x;
        let b = directional_light_radiance(&matte, &p, &mirror).x;
        assert!(a > 2.0 * b, "{a} vs {b}");
    }

    #[test]
    fn exposure_matches_bevy_blender_default() {
        assert_close(
            exposure_from_ev100(EV100_BLENDER),
            1.0 / (1.2 * 9.7f32.exp2()),
            1e-9,
        );
    }
}
