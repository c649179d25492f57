//! [`BrickedVolume`]: a sparse form of an [`SdfVolume`] that keeps only the bricks near
//! the surface, so that small detailed props can have fine voxels at a fraction of a
//! dense grid's memory (Unreal Engine 5 stores its mesh distance fields the same way).
//!
//! # Layout
//! The dense grid's samples are cut into **bricks** of [`BRICK_SAMPLES`]³ samples that
//! overlap by one sample: brick `b` holds samples `BRICK_SPAN · b + (0..=BRICK_SPAN)` on
//! each axis, so every trilinear cell of the dense grid lies whole inside one brick and a
//! brick is one 8³ block of the atlas (`penumbra_df_core::atlas::BLOCK`). Samples past
//! the dense grid's far faces (the last brick's overhang) repeat the face's sample; they
//! are never weighted. A brick is **stored** when any of its samples lies within the
//! band (`band` voxels) of the surface, or its samples change sign; otherwise it is
//! **empty** and keeps only the sample of smallest magnitude, `m` (signed: every sample
//! in an empty brick has the same sign).
//!
//! # Sampling ([`BrickedVolume::sample_voxels`])
//! In a stored brick: the dense grid's own trilinear interpolation (the same eight
//! samples). In an empty brick: `m`. The dense trilinear value there is a convex
//! combination of eight samples of one sign, each at least `|m|` in magnitude, so `m` is
//! never farther from zero than the dense field: sphere tracing on the bricked field is
//! as conservative as on the dense one, and finds the same surface, since every cell
//! within `band` voxels of it is stored. Far from the surface (more than `band` voxels)
//! distances read low by up to a brick's diagonal (12 voxels): more steps, and a soft
//! shadow's or a cone's occlusion estimate there reads the occluder that much nearer.
//!
//! The GPU reads the same layout: `shaders/df/distance.wgsl` (`sample_bricked`), with
//! the bricks in the atlas and one `u32` per brick in the brick table
//! (`penumbra_df_core::bricks`).

use crate::volume::{SdfVolume, f16};
use glam::{UVec3, Vec3};

/// Samples along each edge of a brick.
pub const BRICK_SAMPLES: u32 = 8;

/// Voxels (sample intervals) along each edge of a brick: bricks overlap by one sample.
pub const BRICK_SPAN: u32 = BRICK_SAMPLES - 1;

/// Samples in one brick.
pub const BRICK_LEN: usize = (BRICK_SAMPLES * BRICK_SAMPLES * BRICK_SAMPLES) as usize;

/// The default band, voxels: bricks with a sample nearer the surface than this are
/// stored. Covers the passes' reads at a receiver (a shadow ray's start 2 voxels off the
/// surface, the field normal's central differences) with a voxel to spare.
pub const DEFAULT_BAND_VOXELS: f32 = 4.0;

/// One brick of a [`BrickedVolume`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Brick {
    /// Stored: its samples are `samples[BRICK_LEN · i ..][..BRICK_LEN]`.
    Stored(u32),
    /// Empty: the sample of smallest magnitude in it, voxels (signed).
    Empty(f16),
}

/// A sparse signed distance grid (module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct BrickedVolume {
    /// The dense grid's samples along x, y, z (each ≥ 2).
    pub dims: UVec3,
    /// Bricks along x, y, z: `⌈(dims − 1) / BRICK_SPAN⌉`.
    pub grid: UVec3,
    /// One per brick, x fastest.
    pub bricks: Vec<Brick>,
    /// The stored bricks' samples, voxels, [`BRICK_LEN`] per brick, x fastest in each.
    pub samples: Vec<f16>,
    /// The band the bricks were chosen with, voxels.
    pub band: f32,
}

/// Bricks along each axis for a dense grid of `dims` samples.
pub fn brick_grid(dims: UVec3) -> UVec3 {
    (dims.max(UVec3::splat(2)) - UVec3::ONE + UVec3::splat(BRICK_SPAN - 1)) / BRICK_SPAN
}

impl BrickedVolume {
    /// The bricks of `volume` that lie within `band` voxels of its surface (module docs).
    pub fn from_volume(volume: &SdfVolume, band: f32) -> BrickedVolume {
        let dims = volume.dims;
        let grid = brick_grid(dims);
        let mut bricks = Vec::with_capacity((grid.x * grid.y * grid.z) as usize);
        let mut samples = Vec::new();
        let mut brick = vec![f16::ZERO; BRICK_LEN];
        for bz in 0..grid.z {
            for by in 0..grid.y {
                for bx in 0..grid.x {
                    let base = UVec3::new(bx, by, bz) * BRICK_SPAN;
                    let mut least = f16::INFINITY;
                    let (mut negative, mut positive) = (false, false);
                    for (n, s) in brick.iter_mut().enumerate() {
                        let n = n as u32;
                        let local = UVec3::new(
                            n % BRICK_SAMPLES,
                            (n / BRICK_SAMPLES) % BRICK_SAMPLES,
                            n / (BRICK_SAMPLES * BRICK_SAMPLES),
                        );
                        let p = (base + local).min(dims - UVec3::ONE);
                        *s = volume.data[volume.index(p.x, p.y, p.z)];
                        let v = s.to_f32();
                        negative |= v < 0.0;
                        positive |= v >= 0.0;
                        if v.abs() < least.to_f32().abs() {
                            least = *s;
                        }
                    }
                    let near = least.to_f32().abs() < band || !(band >= 0.0);
                    if near || (negative && positive) {
                        bricks.push(Brick::Stored((samples.len() / BRICK_LEN) as u32));
                        samples.extend_from_slice(&brick);
                    } else {
                        bricks.push(Brick::Empty(least));
                    }
                }
            }
        }
        BrickedVolume {
            dims,
            grid,
            bricks,
            samples,
            band,
        }
    }

    /// Stored bricks.
    pub fn stored(&self) -> usize {
        self.samples.len() / BRICK_LEN
    }

    /// Bytes the GPU holds for it: the stored bricks' f16 samples and one `u32` table
    /// entry per brick.
    pub fn bytes(&self) -> u64 {
        2 * self.samples.len() as u64 + 4 * self.bricks.len() as u64
    }

    /// Bytes of the dense grid it stands for (f16 samples).
    pub fn dense_bytes(&self) -> u64 {
        2 * (self.dims.x as u64 * self.dims.y as u64 * self.dims.z as u64)
    }

    /// The brick holding grid coordinates `c` (inside `[0, dims − 1]`) and `c` in that
    /// brick's samples (inside `[0, BRICK_SPAN]`).
    pub fn locate(&self, c: Vec3) -> (UVec3, Vec3) {
        let span = BRICK_SPAN as f32;
        let b = (c / span)
            .floor()
            .max(Vec3::ZERO)
            .as_uvec3()
            .min(self.grid - UVec3::ONE);
        (b, c - b.as_vec3() * span)
    }

    /// The bricked field at grid coordinates `c` (inside `[0, dims − 1]`), voxels
    /// (module docs): the trilinear interpolation of a stored brick's samples with the
    /// arithmetic of `SdfVolume`'s and the GPU's, or an empty brick's nearest sample.
    pub fn sample_voxels(&self, c: Vec3) -> f32 {
        let (b, local) = self.locate(c);
        match self.bricks[(b.x + self.grid.x * (b.y + self.grid.y * b.z)) as usize] {
            Brick::Empty(m) => m.to_f32(),
            Brick::Stored(i) => {
                let samples = &self.samples[BRICK_LEN * i as usize..][..BRICK_LEN];
                let i0 = local.floor().min(Vec3::splat(BRICK_SPAN as f32 - 1.0));
                let f = local - i0;
                let i0 = i0.as_uvec3();
                let s = |x: u32, y: u32, z: u32| {
                    let n = (i0.x + x) + BRICK_SAMPLES * ((i0.y + y) + BRICK_SAMPLES * (i0.z + z));
                    samples[n as usize].to_f32()
                };
                let x00 = s(0, 0, 0) + (s(1, 0, 0) - s(0, 0, 0)) * f.x;
                let x10 = s(0, 1, 0) + (s(1, 1, 0) - s(0, 1, 0)) * f.x;
                let x01 = s(0, 0, 1) + (s(1, 0, 1) - s(0, 0, 1)) * f.x;
                let x11 = s(0, 1, 1) + (s(1, 1, 1) - s(0, 1, 1)) * f.x;
                let y0 = x00 + (x10 - x00) * f.y;
                let y1 = x01 + (x11 - x01) * f.y;
                y0 + (y1 - y0) * f.z
            }
        }
    }
}

#[cfg(test)]
mod tests;
