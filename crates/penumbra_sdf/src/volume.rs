//! [`SdfVolume`]: a signed distance grid in f16, with trilinear sampling and gradient.
//!
//! # Layout and conventions
//! Sample `(i, j, k)` holds the signed distance at `origin + voxel_size · (i, j, k)`,
//! negative inside, stored **in voxels** (multiples of `voxel_size`) as IEEE binary16,
//! x fastest, then y, then z (`index = i + nx · (j + ny · k)`). Voxel units make the
//! field's precision independent of the mesh's scale: f16 keeps 11 significant bits
//! from 6·10⁻⁵ to 65,504 voxels whether a voxel is 3 µm or 3 km (in mesh units, a bunny
//! scaled ×10⁶ overflowed f16 and one scaled ×10⁻³ fell into its subnormals). Distances
//! saturate at ±[`MAX_VOXEL_DISTANCE`] (only grids more than 65,504 voxels across reach
//! it), and a volume never holds a NaN or infinity. [`SdfVolume::get`] and
//! [`SdfVolume::sample`] answer in mesh units.
//!
//! The origin is f64: a mesh 10⁶ m from its frame's origin (survey or CAD coordinates)
//! keeps its samples where they belong (f32 would round them by up to 3 cm there).
//!
//! Queries outside the grid's box return `√(e² + s²)`: a **lower bound** of
//! the true distance. Every surface point lies inside the box shrunk by the volume's
//! [`SdfVolume::margin`] (a bake's border: the surface is at least that far inside), a
//! convex set, so for its point `c` nearest to the query `q` and every surface point
//! `x`, `|q − x|² ≥ |q − c|² + |c − x|²`: with `e = |q − c|` and `s` the sample at `c`,
//! the distance is at least `√(e² + s²)`. Facing a flat side of the surface the bound is
//! exact; far away it approaches the truth. (Adding the distance to the box to the
//! clamped sample instead, as Unreal does, is an upper bound: a sphere-tracing step can
//! jump past a surface that lies obliquely inside the border.) The bound is negative
//! (inside) only where both `s` and the sample at the box's own boundary nearest to `q`
//! are: a ground sheet's solid, cut by the box, goes on below it; a field whose inside
//! reaches the shrunk box but not the boundary is outside there. (The thin-feature
//! guard puts a negative sample up to a voxel beyond a thin part on the mesh's bounds:
//! with the sign of `s` alone, a metal plaque on the front of `FlightHelmet`'s base made
//! the whole half-space in front of it read 2.8 voxels inside, and shadowed the base.)

use glam::{DVec3, UVec3, Vec3};
pub use half::f16;

/// The largest distance a sample holds, in voxels (f16's largest finite value).
pub const MAX_VOXEL_DISTANCE: f32 = 65504.0;

/// A signed distance grid (see the module docs for the layout).
#[derive(Clone, Debug, PartialEq)]
pub struct SdfVolume {
    /// Samples along x, y, z (each ≥ 2).
    pub dims: UVec3,
    /// Position of sample (0, 0, 0), mesh units.
    pub origin: DVec3,
    /// Spacing between samples (isotropic), in mesh units.
    pub voxel_size: f32,
    /// `dims.x · dims.y · dims.z` signed distances **in voxels**, x fastest (see
    /// [`SdfVolume::quantize`]).
    pub data: Vec<f16>,
    /// Voxels between the box's faces and the surface: every surface point lies at
    /// least this far inside the box. A bake's border (2 by default); for volumes of
    /// unknown origin, [`SdfVolume::measured_margin`]. Tightens the bound outside the
    /// box (module docs); must not exceed the truth.
    pub margin: f32,
}

impl SdfVolume {
    /// The stored sample for a signed distance of `voxels` voxels: rounded to f16,
    /// saturated at ±[`MAX_VOXEL_DISTANCE`]; NaN becomes +[`MAX_VOXEL_DISTANCE`] (far
    /// outside), so a volume never holds a non-finite value.
    pub fn quantize(voxels: f32) -> f16 {
        let v = if voxels.is_nan() {
            MAX_VOXEL_DISTANCE
        } else {
            voxels.clamp(-MAX_VOXEL_DISTANCE, MAX_VOXEL_DISTANCE)
        };
        f16::from_f32(v)
    }

    /// A volume from signed distances in mesh units (x fastest), quantized to voxels.
    pub fn from_distances(
        dims: UVec3,
        origin: DVec3,
        voxel_size: f32,
        distances: impl IntoIterator<Item = f32>,
    ) -> SdfVolume {
        let data = distances
            .into_iter()
            .map(|d| Self::quantize(d / voxel_size))
            .collect();
        let mut volume = SdfVolume {
            dims,
            origin,
            voxel_size,
            data,
            margin: 0.0,
        };
        volume.margin = volume.measured_margin();
        volume
    }

    /// A margin the samples prove (see [`SdfVolume::margin`]): the smallest distance of
    /// the box's boundary samples, less the 1-Lipschitz slack between a point of a face
    /// and its nearest sample (√2 / 2 voxel), never negative. Assumes the surface lies
    /// in the box, as for any baked volume.
    pub fn measured_margin(&self) -> f32 {
        let d = self.dims;
        let mut least = f32::INFINITY;
        for k in 0..d.z {
            for j in 0..d.y {
                for i in 0..d.x {
                    let boundary =
                        i == 0 || j == 0 || k == 0 || i + 1 == d.x || j + 1 == d.y || k + 1 == d.z;
                    if boundary {
                        least = least.min(self.get_voxels(i, j, k).abs());
                    }
                }
            }
        }
        (least - std::f32::consts::FRAC_1_SQRT_2).max(0.0)
    }

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

    /// Sample `(i, j, k)` in voxels.
    #[inline]
    pub fn get_voxels(&self, i: u32, j: u32, k: u32) -> f32 {
        self.data[self.index(i, j, k)].to_f32()
    }

    /// Sample `(i, j, k)` in mesh units.
    #[inline]
    pub fn get(&self, i: u32, j: u32, k: u32) -> f32 {
        self.get_voxels(i, j, k) * self.voxel_size
    }

    /// Position of sample `(i, j, k)`.
    #[inline]
    pub fn position(&self, i: u32, j: u32, k: u32) -> DVec3 {
        self.origin + self.voxel_size as f64 * DVec3::new(i as f64, j as f64, k as f64)
    }

    /// The box spanned by the sample positions.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        (
            self.origin,
            self.origin + self.voxel_size as f64 * (self.dims.as_dvec3() - DVec3::ONE),
        )
    }

    /// The signed distance at `p`, mesh units: trilinear inside the box; outside, the
    /// lower bound `√(e² + s²)` of the module docs.
    pub fn sample(&self, p: DVec3) -> f32 {
        let g = ((p - self.origin) / self.voxel_size as f64).as_vec3();
        volume_distance_voxels(g, self.dims, self.margin, |c| self.trilinear_voxels(c))
            * self.voxel_size
    }

    /// Trilinear interpolation at grid coordinates `g` (inside `[0, dims − 1]`), voxels.
    pub(crate) fn trilinear_voxels(&self, g: Vec3) -> f32 {
        let max = (self.dims - UVec3::splat(2)).as_vec3();
        let base = g.floor().clamp(Vec3::ZERO, max);
        let f = (g - base).clamp(Vec3::ZERO, Vec3::ONE);
        let (i, j, k) = (base.x as u32, base.y as u32, base.z as u32);
        trilinear_corners(|di, dj, dk| self.get_voxels(i + di, j + dj, k + dk), f)
    }

    /// Gradient of [`SdfVolume::sample`] by central differences of half a voxel
    /// (≈ the outward surface normal near the surface; not normalized).
    pub fn gradient(&self, p: DVec3) -> Vec3 {
        let h = 0.5 * self.voxel_size as f64;
        let d = |o: DVec3| self.sample(p + o) - self.sample(p - o);
        Vec3::new(d(DVec3::X * h), d(DVec3::Y * h), d(DVec3::Z * h)) / (2.0 * h as f32)
    }

    /// Fraction of samples that are negative (inside).
    pub fn inside_fraction(&self) -> f32 {
        let inside = self.data.iter().filter(|v| v.to_f32() < 0.0).count();
        inside as f32 / self.data.len().max(1) as f32
    }

    /// Half the resolution: every other sample, `⌈(n − 1) / 2⌉ + 1` per axis so the box
    /// stays covered (an even `n − 1` ends on the last sample exactly; an odd one
    /// repeats it, half a new voxel past the old box). Values are re-expressed in the
    /// doubled voxel (halved: exact in f16 above its subnormals).
    pub fn downsampled(&self) -> SdfVolume {
        let dims = self.dims / 2 + UVec3::ONE; // = ⌈(n − 1) / 2⌉ + 1
        let mut data = Vec::with_capacity((dims.x * dims.y * dims.z) as usize);
        for k in 0..dims.z {
            for j in 0..dims.y {
                for i in 0..dims.x {
                    let p = (UVec3::new(i, j, k) * 2).min(self.dims - UVec3::ONE);
                    data.push(Self::quantize(0.5 * self.get_voxels(p.x, p.y, p.z)));
                }
            }
        }
        SdfVolume {
            dims,
            origin: self.origin,
            voxel_size: self.voxel_size * 2.0,
            data,
            // The box keeps its near faces and may grow by half a new voxel at the far
            // ones: the old margin, in new voxels, still holds.
            margin: 0.5 * self.margin,
        }
    }
}

/// The trilinear interpolation at fractions `f` of a cell whose corner `(i, j, k)` (each
/// 0 or 1) holds `corner(i, j, k)`: x first, then y, then z, the GPU's `sample_volume`
/// order (so that the CPU models round as the shaders do).
#[inline]
pub fn trilinear_corners(corner: impl Fn(u32, u32, u32) -> f32, f: Vec3) -> f32 {
    let c = corner;
    let x00 = c(0, 0, 0) + (c(1, 0, 0) - c(0, 0, 0)) * f.x;
    let x10 = c(0, 1, 0) + (c(1, 1, 0) - c(0, 1, 0)) * f.x;
    let x01 = c(0, 0, 1) + (c(1, 0, 1) - c(0, 0, 1)) * f.x;
    let x11 = c(0, 1, 1) + (c(1, 1, 1) - c(0, 1, 1)) * f.x;
    let y0 = x00 + (x10 - x00) * f.y;
    let y1 = x01 + (x11 - x01) * f.y;
    y0 + (y1 - y0) * f.z
}

/// The distance at grid coordinates `g` of a `dims` grid whose trilinear interpolation
/// is `inside` (both in voxels), with the surface at least `margin` voxels inside the
/// box: `inside(g)` in the box; outside, `±√(e² + s²)` with `e` the distance to the box
/// shrunk by the margin and `s = inside(c)` at its point `c` nearest to `g` (the lower
/// bound of the module docs), negative only where the box's boundary sample nearest to
/// `g` is inside too. The GPU's `volume_distance` and the CPU reference model compute
/// the same.
pub fn volume_distance_voxels(
    g: Vec3,
    dims: UVec3,
    margin: f32,
    inside: impl Fn(Vec3) -> f32,
) -> f32 {
    let hi = (dims - UVec3::ONE).as_vec3();
    if g.cmpge(Vec3::ZERO).all() && g.cmple(hi).all() {
        return inside(g);
    }
    // NaN margins fall back to 0 (`clamp` keeps the shrunk box non-empty).
    let m = margin.clamp(0.0, 0.5 * hi.min_element());
    let m = if m >= 0.0 { m } else { 0.0 };
    let c = g.clamp(Vec3::splat(m), hi - m);
    let s = inside(c);
    let r = ((g - c).length_squared() + s * s).sqrt();
    // Inside only where the field's inside reaches the box's own boundary (a ground
    // sheet's solid, cut by the box): a sample of the shrunk box may read inside where
    // the thin-feature guard or a sign decision put a surface's inside a voxel beyond
    // the mesh, and the box's boundary samples are outside.
    if s < 0.0 && inside(g.clamp(Vec3::ZERO, hi)) < 0.0 {
        -r
    } else {
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A volume holding an exact linear function (mesh units) is reproduced by
    /// trilinear sampling, and the gradient is the function's gradient.
    fn linear_volume() -> SdfVolume {
        let dims = UVec3::new(4, 5, 6);
        let origin = DVec3::new(-1.0, 0.0, 2.0);
        let voxel_size = 0.5;
        let mut distances = Vec::new();
        for k in 0..dims.z {
            for j in 0..dims.y {
                for i in 0..dims.x {
                    let p = origin + 0.5 * DVec3::new(i as f64, j as f64, k as f64);
                    distances.push(linear(p));
                }
            }
        }
        SdfVolume::from_distances(dims, origin, voxel_size, distances)
    }

    fn linear(p: DVec3) -> f32 {
        (0.25 * p.x - 0.5 * p.y + 0.125 * p.z) as f32
    }

    #[test]
    fn trilinear_sampling_reproduces_linear_fields() {
        let v = linear_volume();
        for p in [
            DVec3::new(-0.7, 0.3, 2.2),
            DVec3::new(0.4, 1.9, 4.4),
            DVec3::new(0.5, 2.0, 4.5), // the far corner
        ] {
            assert!((v.sample(p) - linear(p)).abs() < 2e-3, "{p}");
        }
        for p in [DVec3::new(-0.2, 0.8, 3.1), DVec3::new(0.1, 1.6, 4.0)] {
            let g = v.gradient(p);
            assert!((g - Vec3::new(0.25, -0.5, 0.125)).length() < 1e-2, "{g}");
        }
    }

    /// Outside the box: `±√(e² + s²)`, never the sum `s + e`.
    #[test]
    fn outside_queries_combine_the_box_distance_and_the_sample_in_quadrature() {
        let v = linear_volume();
        // A corner inside (negative) and one outside (positive).
        for (corner, away) in [
            (DVec3::new(0.5, 2.0, 4.5), DVec3::new(3.0, 0.0, 4.0)),
            (DVec3::new(0.5, 0.0, 2.0), DVec3::new(0.0, -1.0, 0.0)),
        ] {
            let s = v.sample(corner) as f64;
            assert!(s.abs() > 0.3, "{s}");
            let want = s.signum() * (away.length_squared() + s * s).sqrt();
            let got = v.sample(corner + away) as f64;
            assert!((got - want).abs() < 1e-4, "{got} vs {want}");
        }
    }

    #[test]
    fn layout_is_x_fastest() {
        let v = linear_volume();
        assert_eq!(v.index(1, 0, 0), 1);
        assert_eq!(v.index(0, 1, 0), 4);
        assert_eq!(v.index(0, 0, 1), 20);
        assert_eq!(v.position(1, 2, 3), DVec3::new(-0.5, 1.0, 3.5));
    }

    /// Samples are voxels: the same relative precision at any scale, saturated instead
    /// of infinite, and NaN-free.
    #[test]
    fn samples_are_scale_free_and_always_finite() {
        for scale in [1e-6f32, 1e-3, 1.0, 1e3, 1e6] {
            let h = 0.01 * scale;
            let v = SdfVolume::from_distances(
                UVec3::splat(2),
                DVec3::ZERO,
                h,
                [0.3 * h, -2.5 * h, 1e-3 * h, 40.0 * h, 0.0, 0.0, 0.0, 0.0],
            );
            let want = [0.3, -2.5, 1e-3, 40.0];
            for (i, w) in want.iter().enumerate() {
                let got = v.data[i].to_f32();
                assert!((got - w).abs() <= w.abs() * 1e-3, "{scale}: {got} vs {w}");
            }
        }
        let v = SdfVolume::from_distances(
            UVec3::splat(2),
            DVec3::ZERO,
            1.0,
            [1e9, -1e9, f32::INFINITY, f32::NAN, 0.0, 0.0, 0.0, 0.0],
        );
        let got: Vec<f32> = v.data[..4].iter().map(|h| h.to_f32()).collect();
        assert_eq!(
            got,
            [
                MAX_VOXEL_DISTANCE,
                -MAX_VOXEL_DISTANCE,
                MAX_VOXEL_DISTANCE,
                MAX_VOXEL_DISTANCE
            ]
        );
    }

    #[test]
    fn downsampling_keeps_distances_in_mesh_units() {
        let v = linear_volume();
        let half = v.downsampled();
        assert_eq!(half.dims, UVec3::new(3, 3, 4));
        assert_eq!(half.voxel_size, 1.0);
        for (i, j, k) in [(0, 0, 0), (1, 1, 1), (2, 2, 3)] {
            let (a, b) = (half.get(i, j, k), linear(half.position(i, j, k)));
            // Sample (2, 2, 3) repeats (3, 4, 5): the old box's last sample.
            let b = if (i, j, k) == (2, 2, 3) {
                v.get(3, 4, 5)
            } else {
                b
            };
            assert!((a - b).abs() < 2e-3, "{i} {j} {k}: {a} vs {b}");
        }
    }
}
