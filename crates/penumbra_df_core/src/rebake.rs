//! The GPU re-bake of a posed mesh (a hero character, #48): its grid, the pass's uniform
//! (`shaders/df/rebake.wgsl`, laid out by `encase`) and its output's layout.
//!
//! A re-baked caster owns one fixed cube of `resolution³` samples in the atlas, placed
//! once. Each bake centres the cube on the posed mesh's bounds and spreads it so that the
//! longest side, plus [`REBAKE_MARGIN`] voxels at each end, spans it ([`RebakeGrid`]):
//! the voxel size follows the pose, the atlas footprint never changes. Every sample is
//! the exact distance to the nearest posed triangle (brute force over all of them, tiled
//! through workgroup memory) signed by the generalized winding number (Jacobson et al.
//! 2013) summed over the same triangles: inside where it exceeds ½, so the sign survives
//! the open seams, separate eyes and overlapping parts characters are made of, where ray
//! parity and back-face counts flip. Cost: `resolution³ × triangles` point–triangle
//! evaluations a bake (the Fox, 576 triangles at 48³: 64 M).
//!
//! Output: signed distances **in voxels** as f16 (the atlas's `R16Float` and
//! [`penumbra_sdf`'s `SdfVolume`] convention), two samples to a `u32` along x, rows
//! padded to [`ROW_ALIGNMENT`] bytes so that one `copy_buffer_to_texture` puts the
//! volume into its atlas region. The CPU model is `penumbra_reference::rebake`.
//!
//! [`penumbra_sdf`'s `SdfVolume`]: https://docs.rs/penumbra_sdf

use encase::ShaderType;
use glam::{Mat4, UVec3, Vec3};

/// Samples along x, y and z of one invocation's work: two along x (packed into one
/// `u32`), the workgroup 4 × 4 × 4 invocations over 8 × 4 × 4 samples.
pub const WORKGROUP_SAMPLES: UVec3 = UVec3::new(8, 4, 4);

/// Triangles loaded into workgroup memory at a time (one per invocation).
pub const TRIANGLE_TILE: u32 = 64;

/// Voxels between the cube's faces and the posed mesh's bounds (the volume's `margin`).
pub const REBAKE_MARGIN: f32 = 2.0;

/// The smallest and largest `resolution` (samples along each axis; a multiple of 8, the
/// atlas's block and [`WORKGROUP_SAMPLES`]).
pub const MIN_RESOLUTION: u32 = 16;
/// See [`MIN_RESOLUTION`].
pub const MAX_RESOLUTION: u32 = 128;

/// `bytes_per_row` of a buffer-to-texture copy must be a multiple of this (wgpu's
/// `COPY_BYTES_PER_ROW_ALIGNMENT`).
pub const ROW_ALIGNMENT: u32 = 256;

/// Where a bake's samples lie: a cube of `resolution³` samples, `voxel_size` apart,
/// sample (0, 0, 0) at `origin` (the posed mesh's space: world space for a skinned mesh).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RebakeGrid {
    /// Position of sample (0, 0, 0).
    pub origin: Vec3,
    /// Spacing of the samples, in the mesh's units.
    pub voxel_size: f32,
    /// Samples along each axis (a multiple of 8 in `MIN_RESOLUTION..=MAX_RESOLUTION`).
    pub resolution: u32,
}

impl RebakeGrid {
    /// The cube for a pose whose triangles lie within `min..=max`: centred on that box,
    /// its longest side plus [`REBAKE_MARGIN`] voxels at each end spanning the cube.
    /// `resolution` is rounded to a multiple of 8 and clamped to
    /// `MIN_RESOLUTION..=MAX_RESOLUTION`. `None` for an empty, inverted or non-finite box
    /// (the caller keeps the last bake).
    pub fn around(min: Vec3, max: Vec3, resolution: u32) -> Option<RebakeGrid> {
        if !(min.is_finite() && max.is_finite()) || min.cmpgt(max).any() {
            return None;
        }
        let resolution = clamp_resolution(resolution);
        let extent = (max - min).max_element();
        // A point or a flat box still gets a cube: a tiny one, a voxel per micro-unit.
        let extent = extent.max(1e-6 * max.abs().max(min.abs()).max_element().max(1.0));
        let voxel_size = extent / (resolution as f32 - 1.0 - 2.0 * REBAKE_MARGIN);
        if !(voxel_size.is_finite() && voxel_size > 0.0) {
            return None;
        }
        let centre = 0.5 * (min + max);
        Some(RebakeGrid {
            origin: centre - Vec3::splat(0.5 * voxel_size * (resolution - 1) as f32),
            voxel_size,
            resolution,
        })
    }

    /// Samples along each axis.
    pub fn dims(&self) -> UVec3 {
        UVec3::splat(self.resolution)
    }

    /// The position of sample `(i, j, k)`.
    pub fn position(&self, i: UVec3) -> Vec3 {
        self.origin + i.as_vec3() * self.voxel_size
    }

    /// Bytes of one row of the output (`resolution` f16 samples, padded to
    /// [`ROW_ALIGNMENT`]).
    pub fn bytes_per_row(&self) -> u32 {
        (2 * self.resolution).div_ceil(ROW_ALIGNMENT) * ROW_ALIGNMENT
    }

    /// Bytes of the whole output buffer.
    pub fn output_bytes(&self) -> u64 {
        self.bytes_per_row() as u64 * self.resolution as u64 * self.resolution as u64
    }

    /// Workgroups to dispatch.
    pub fn workgroups(&self) -> UVec3 {
        self.dims() / WORKGROUP_SAMPLES
    }

    /// The pass's uniform for `triangles` posed triangles.
    pub fn params(&self, triangles: u32) -> RebakeParams {
        RebakeParams {
            voxel_size: self.voxel_size,
            resolution: self.resolution,
            triangles,
            row_words: self.bytes_per_row() / 4,
        }
    }
}

/// `resolution` rounded to a multiple of 8 and clamped to
/// `MIN_RESOLUTION..=MAX_RESOLUTION`.
pub fn clamp_resolution(resolution: u32) -> u32 {
    (resolution.saturating_add(4) / 8 * 8).clamp(MIN_RESOLUTION, MAX_RESOLUTION)
}

/// The re-bake pass's uniform (`RebakeParams` in `shaders/df/rebake.wgsl`).
#[derive(ShaderType, Clone, Copy, Debug, Default, PartialEq)]
pub struct RebakeParams {
    /// Spacing of the samples.
    pub voxel_size: f32,
    /// Samples along each axis.
    pub resolution: u32,
    /// Posed triangles in the triangle buffer: three `vec4<f32>` corners each (`w`
    /// unused), **relative to sample (0, 0, 0)** ([`RebakeGrid::origin`], subtracted on
    /// the CPU so that a character far from the world's origin keeps its precision).
    pub triangles: u32,
    /// `u32` words per row of the output ([`RebakeGrid::bytes_per_row`] / 4).
    pub row_words: u32,
}

/// The byte offset in the output of the word holding samples `(i & !1, j, k)` and
/// `(i | 1, j, k)` (the low half holds the even one).
pub fn output_word_offset(grid: &RebakeGrid, i: UVec3) -> u64 {
    (i.z as u64 * grid.resolution as u64 + i.y as u64) * grid.bytes_per_row() as u64
        + (i.x / 2) as u64 * 4
}

/// A skinned mesh's triangles in a pose, by linear blend skinning on the CPU as Bevy's
/// vertex shader skins them (`Σ weight · joint_from_bind[joint] · position`, the weights
/// as stored, not renormalised): `joint_from_bind[j]` is joint `j`'s world transform
/// times its inverse bind matrix. `indices` in threes (a ragged tail is left out);
/// a vertex whose index, joint or weight is out of range or non-finite takes no
/// contribution from it, and a triangle with a non-finite corner is left out (the pass
/// reads only finite ones).
pub fn skinned_triangles(
    positions: &[Vec3],
    indices: &[u32],
    joints: &[[u16; 4]],
    weights: &[[f32; 4]],
    joint_from_bind: &[Mat4],
) -> Vec<[Vec3; 3]> {
    let posed: Vec<Vec3> = positions
        .iter()
        .enumerate()
        .map(|(v, p)| {
            let (Some(joint), Some(weight)) = (joints.get(v), weights.get(v)) else {
                return Vec3::NAN;
            };
            let (mut m, mut blended) = (Mat4::ZERO, false);
            for (j, w) in joint.iter().zip(weight) {
                if let Some(jm) = joint_from_bind.get(usize::from(*j))
                    && w.is_finite()
                    && *w != 0.0
                {
                    m += *jm * *w;
                    blended = true;
                }
            }
            // No joint moves it: it has no place in the pose.
            if blended {
                m.transform_point3(*p)
            } else {
                Vec3::NAN
            }
        })
        .collect();
    indices
        .chunks_exact(3)
        .filter_map(|t| {
            let corner = |i: u32| posed.get(i as usize).copied().filter(|v| v.is_finite());
            Some([corner(t[0])?, corner(t[1])?, corner(t[2])?])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cube_holds_the_pose_with_its_margin() {
        let (min, max) = (Vec3::new(-1.0, 0.0, 2.0), Vec3::new(1.0, 3.0, 2.5));
        let grid = RebakeGrid::around(min, max, 32).expect("grid");
        assert_eq!(grid.resolution, 32);
        // The longest side (3) spans 32 − 1 − 4 voxels.
        assert!((grid.voxel_size - 3.0 / 27.0).abs() < 1e-6);
        let last = grid.position(UVec3::splat(31));
        let margin = Vec3::splat(REBAKE_MARGIN * grid.voxel_size);
        assert!((grid.origin + margin).cmple(min + 1e-5).all(), "{grid:?}");
        assert!((last - margin).cmpge(max - 1e-5).all(), "{grid:?}");
        // Centred: the y axis (the longest) touches the margin at both ends.
        assert!((grid.origin.y + margin.y - min.y).abs() < 1e-5);
    }

    #[test]
    fn resolutions_are_whole_workgroups_and_rows_copyable() {
        assert_eq!(clamp_resolution(0), MIN_RESOLUTION);
        assert_eq!(clamp_resolution(33), 32);
        assert_eq!(clamp_resolution(37), 40);
        assert_eq!(clamp_resolution(u32::MAX), MAX_RESOLUTION);
        for r in [16, 24, 32, 64, 128] {
            let grid = RebakeGrid::around(Vec3::ZERO, Vec3::ONE, r).expect("grid");
            assert_eq!(grid.workgroups() * WORKGROUP_SAMPLES, grid.dims());
            assert_eq!(grid.bytes_per_row() % ROW_ALIGNMENT, 0);
            assert!(grid.bytes_per_row() >= 2 * r);
            assert_eq!(
                output_word_offset(&grid, UVec3::new(r - 1, r - 1, r - 1)) + 4,
                grid.output_bytes() - (grid.bytes_per_row() - r * 2) as u64
            );
        }
    }

    #[test]
    fn skinning_blends_the_joints_and_drops_what_it_cannot_pose() {
        let positions = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let joints = [[0, 1, 0, 0], [1, 0, 0, 0], [0, 0, 0, 0], [7, 0, 0, 0]];
        let weights = [
            [0.5, 0.5, 0.0, 0.0],
            [1.0, 0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0, 0.0],
        ];
        let moves = [
            Mat4::from_translation(Vec3::new(0.0, 2.0, 0.0)),
            Mat4::from_rotation_z(std::f32::consts::FRAC_PI_2),
        ];
        let tris = skinned_triangles(
            &positions,
            &[0, 1, 2, 1, 2, 3, 0],
            &joints,
            &weights,
            &moves,
        );
        // Vertex 3's joint is out of range: its triangle goes; the ragged tail too.
        assert_eq!(tris.len(), 1);
        let [a, b, c] = tris[0];
        // Half translated, half rotated (the origin stays): (0, 1, 0).
        assert!((a - Vec3::new(0.0, 1.0, 0.0)).length() < 1e-6, "{a}");
        // Rotated a quarter turn about z: x → y.
        assert!((b - Vec3::Y).length() < 1e-6, "{b}");
        assert!((c - Vec3::new(0.0, 3.0, 0.0)).length() < 1e-6, "{c}");
        // Missing skin attributes or a NaN joint matrix: nothing posed, no panic.
        assert!(skinned_triangles(&positions, &[0, 1, 2], &[], &[], &moves).is_empty());
        let nan = [Mat4::NAN, Mat4::NAN];
        assert!(skinned_triangles(&positions, &[0, 1, 2], &joints, &weights, &nan).is_empty());
    }

    #[test]
    fn bad_poses_get_no_grid() {
        assert!(RebakeGrid::around(Vec3::ONE, Vec3::ZERO, 32).is_none());
        assert!(RebakeGrid::around(Vec3::NAN, Vec3::ONE, 32).is_none());
        assert!(RebakeGrid::around(Vec3::ZERO, Vec3::INFINITY, 32).is_none());
        assert!(RebakeGrid::around(Vec3::splat(-f32::MAX), Vec3::splat(f32::MAX), 32).is_none());
        // A single point: a tiny cube, not a division by zero.
        let grid = RebakeGrid::around(Vec3::ONE, Vec3::ONE, 16).expect("point");
        assert!(grid.voxel_size > 0.0 && grid.origin.is_finite());
    }
}
