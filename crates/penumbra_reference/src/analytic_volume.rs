//! Volumes sampled from exact analytic distances (no bake): test casters whose field is
//! known exactly at every sample, with a grid as large as a test needs — for instance
//! reaching far past the surface, so that most of its 8³ bricks lie outside the band
//! [`penumbra_sdf::bricks`] stores and the volume is placed as sparse bricks when a
//! scene allows it.

use glam::{UVec3, Vec3};
use penumbra_sdf::SdfVolume;

/// A volume of `distance` sampled every `voxel` over the box `[−reach, reach]` (one
/// sample on each face; `reach` rounded to whole voxels).
pub fn sampled(reach: Vec3, voxel: f32, distance: impl Fn(Vec3) -> f32) -> SdfVolume {
    let steps = (reach / voxel).round().as_uvec3();
    let dims = 2 * steps + UVec3::ONE;
    let origin = -(steps.as_vec3() * voxel);
    let distances = (0..dims.element_product()).map(|i| {
        let c = UVec3::new(i % dims.x, (i / dims.x) % dims.y, i / (dims.x * dims.y));
        distance(origin + c.as_vec3() * voxel)
    });
    SdfVolume::from_distances(dims, origin.as_dvec3(), voxel, distances)
}

/// A sphere of `radius` about the origin, its grid reaching `reach` along each axis.
pub fn sphere(radius: f32, reach: f32, voxel: f32) -> SdfVolume {
    sampled(Vec3::splat(reach), voxel, |p| p.length() - radius)
}

/// A sphere of `radius` that a scene places as sparse bricks when allowed: 40 samples
/// per radius in a grid reaching 1.6 radii, so that about a fifth of its 8³ bricks lie
/// within the stored band of the surface (bricks at least halve it).
pub fn sphere_for_bricks(radius: f32) -> SdfVolume {
    sphere(radius, 1.6 * radius, radius / 40.0)
}

/// A box of half extents `half` about the origin, its grid reaching `margin` past it.
pub fn cuboid(half: Vec3, margin: f32, voxel: f32) -> SdfVolume {
    sampled(half + margin, voxel, |p| {
        let q = p.abs() - half;
        q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn samples_hold_the_exact_distance_at_their_positions() {
        let v = sphere(1.0, 1.5, 0.1);
        assert_eq!(v.dims, UVec3::splat(31));
        assert_eq!(v.origin, DVec3::splat(-1.5f32 as f64));
        // The centre sample: −1 (f16, in voxels: −10); a corner: √3·1.5 − 1.
        let at = |c: UVec3| f32::from(v.data[(c.x + 31 * (c.y + 31 * c.z)) as usize]) * 0.1;
        assert!((at(UVec3::splat(15)) + 1.0).abs() < 1e-3);
        assert!((at(UVec3::ZERO) - (3f32.sqrt() * 1.5 - 1.0)).abs() < 1e-2);
        // Bricks at least halve the bricking sphere (the scenes' rule).
        let v = sphere_for_bricks(2.0);
        let b = penumbra_sdf::bricks::BrickedVolume::from_volume(
            &v,
            penumbra_sdf::bricks::DEFAULT_BAND_VOXELS,
        );
        assert!(
            2 * b.bytes() <= b.dense_bytes(),
            "{} of {}",
            b.bytes(),
            b.dense_bytes()
        );
        let b = cuboid(Vec3::new(0.5, 0.2, 0.1), 0.3, 0.1);
        assert_eq!(b.dims, UVec3::new(17, 11, 9));
        let at = |c: UVec3| f32::from(b.data[(c.x + 17 * (c.y + 11 * c.z)) as usize]) * 0.1;
        // The centre: −0.1 (the nearest face); a face's middle: 0.
        assert!((at(UVec3::new(8, 5, 4)) + 0.1).abs() < 1e-3);
        assert!(at(UVec3::new(8, 5, 5)).abs() < 1e-3);
    }
}
