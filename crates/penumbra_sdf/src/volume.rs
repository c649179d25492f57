//! [`SdfVolume`]: a signed distance grid in f16, with trilinear sampling and gradient.
//!
//! # Layout and conventions
//! Sample `(i, j, k)` holds the signed distance at `origin + voxel_size · (i, j, k)`, in
//! the mesh's own units, negative inside. Samples are stored x fastest, then y, then z
//! (`index = i + nx · (j + ny · k)`), as IEEE binary16.
//!
//! Queries outside the grid's box return the sample at the clamped position plus the
//! distance from the query to the box: an upper bound on the true distance that stays
//! conservative for sphere tracing.

use glam::{UVec3, Vec3};
pub use half::f16;

/// A signed distance grid (see the module docs for the layout).
#[derive(Clone, Debug, PartialEq)]
pub struct SdfVolume {
    /// Samples along x, y, z (each ≥ 2).
    pub dims: UVec3,
    /// Position of sample (0, 0, 0).
    pub origin: Vec3,
    /// Spacing between samples (isotropic), in mesh units.
    pub voxel_size: f32,
    /// `dims.x · dims.y · dims.z` signed distances, x fastest.
    pub data: Vec<f16>,
}

impl SdfVolume {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.data.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// Linear index of sample `(i, j, k)`.
    #[inline]
    pub fn index(&self, i: u32, j: u32, k: u32) -> usize {
        (i + self.dims.x * (j + self.dims.y * k)) as usize
    }

    /// Sample `(i, j, k)` as f32.
    #[inline]
    pub fn get(&self, i: u32, j: u32, k: u32) -> f32 {
        self.data[self.index(i, j, k)].to_f32()
    }

    /// Position of sample `(i, j, k)`.
    #[inline]
    pub fn position(&self, i: u32, j: u32, k: u32) -> Vec3 {
        self.origin + self.voxel_size * Vec3::new(i as f32, j as f32, k as f32)
    }

    /// The box spanned by the sample positions.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        (
            self.origin,
            self.origin + self.voxel_size * (self.dims.as_vec3() - Vec3::ONE),
        )
    }

    /// Trilinearly interpolated distance at `p` (inside the box), or the clamped sample
    /// plus the distance to the box (outside).
    pub fn sample(&self, p: Vec3) -> f32 {
        let (lo, hi) = self.bounds();
        let q = p.clamp(lo, hi);
        self.trilinear(q) + (p - q).length()
    }

    fn trilinear(&self, q: Vec3) -> f32 {
        let g = (q - self.origin) / self.voxel_size;
        let max = (self.dims - UVec3::splat(2)).as_vec3();
        let base = g.floor().clamp(Vec3::ZERO, max);
        let f = (g - base).clamp(Vec3::ZERO, Vec3::ONE);
        let (i, j, k) = (base.x as u32, base.y as u32, base.z as u32);
        let c = |di: u32, dj: u32, dk: u32| self.get(i + di, j + dj, k + dk);
        let x00 = c(0, 0, 0) + (c(1, 0, 0) - c(0, 0, 0)) * f.x;
        let x10 = c(0, 1, 0) + (c(1, 1, 0) - c(0, 1, 0)) * f.x;
        let x01 = c(0, 0, 1) + (c(1, 0, 1) - c(0, 0, 1)) * f.x;
        let x11 = c(0, 1, 1) + (c(1, 1, 1) - c(0, 1, 1)) * f.x;
        let y0 = x00 + (x10 - x00) * f.y;
        let y1 = x01 + (x11 - x01) * f.y;
        y0 + (y1 - y0) * f.z
    }

    /// Gradient of [`SdfVolume::sample`] by central differences of half a voxel
    /// (≈ the outward surface normal near the surface; not normalized).
    pub fn gradient(&self, p: Vec3) -> Vec3 {
        let h = 0.5 * self.voxel_size;
        let d = |o: Vec3| self.sample(p + o) - self.sample(p - o);
        Vec3::new(d(Vec3::X * h), d(Vec3::Y * h), d(Vec3::Z * h)) / (2.0 * h)
    }

    /// Fraction of samples that are negative (inside).
    pub fn inside_fraction(&self) -> f32 {
        let inside = self.data.iter().filter(|v| v.to_f32() < 0.0).count();
        inside as f32 / self.data.len().max(1) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A volume holding an exact linear function is reproduced exactly by trilinear
    /// sampling, and the gradient is the function's gradient.
    fn linear_volume() -> SdfVolume {
        let dims = UVec3::new(4, 5, 6);
        let origin = Vec3::new(-1.0, 0.0, 2.0);
        let voxel_size = 0.5;
        let f = |p: Vec3| 0.25 * p.x - 0.5 * p.y + 0.125 * p.z;
        let mut data = Vec::new();
        for k in 0..dims.z {
            for j in 0..dims.y {
                for i in 0..dims.x {
                    let p = origin + voxel_size * Vec3::new(i as f32, j as f32, k as f32);
                    data.push(f16::from_f32(f(p)));
                }
            }
        }
        SdfVolume {
            dims,
            origin,
            voxel_size,
            data,
        }
    }

    #[test]
    fn trilinear_sampling_reproduces_linear_fields() {
        let v = linear_volume();
        let f = |p: Vec3| 0.25 * p.x - 0.5 * p.y + 0.125 * p.z;
        for p in [
            Vec3::new(-0.7, 0.3, 2.2),
            Vec3::new(0.4, 1.9, 4.4),
            Vec3::new(0.5, 2.0, 4.5), // the far corner
        ] {
            assert!((v.sample(p) - f(p)).abs() < 2e-3, "{p}");
        }
        for p in [Vec3::new(-0.2, 0.8, 3.1), Vec3::new(0.1, 1.6, 4.0)] {
            let g = v.gradient(p);
            assert!((g - Vec3::new(0.25, -0.5, 0.125)).length() < 1e-2, "{g}");
        }
    }

    #[test]
    fn outside_queries_add_the_distance_to_the_box() {
        let v = linear_volume();
        let corner = Vec3::new(-1.0, 0.0, 2.0);
        let p = corner + Vec3::new(-3.0, 0.0, -4.0);
        assert!((v.sample(p) - (v.sample(corner) + 5.0)).abs() < 1e-4);
    }

    #[test]
    fn layout_is_x_fastest() {
        let v = linear_volume();
        assert_eq!(v.index(1, 0, 0), 1);
        assert_eq!(v.index(0, 1, 0), 4);
        assert_eq!(v.index(0, 0, 1), 20);
        assert_eq!(v.position(1, 2, 3), Vec3::new(-0.5, 1.0, 3.5));
    }
}
