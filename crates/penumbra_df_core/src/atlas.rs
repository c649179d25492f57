//! Placement of SDF volumes in one 3D atlas texture.
//!
//! The atlas is a grid of 8³-voxel blocks. A volume occupies the smallest box of whole
//! blocks holding it; placement is first-fit in z, then y, then x block order (so the
//! low slices fill first and a shrinking scene leaves free space at the top), found with
//! a summed-volume table of the occupied blocks: `O(blocks)` per allocation, a few
//! hundred microseconds for a 64 MiB atlas, paid only when an SDF asset appears. Freed
//! boxes are reused by later allocations. Deterministic: the same sequence of
//! allocations and frees gives the same placements.
//!
//! Limits: no defragmentation (a long-running scene with heavy churn of differently
//! sized assets can fragment; a full atlas is reported, never silently overwritten), and
//! a volume larger than the atlas along any axis cannot be placed. The atlas is at most
//! [`MAX_ATLAS_SIZE`] (1024 × 1024 × 4096 voxels, 8 GiB): object records address it
//! with 10/10/12-bit coordinates ([`crate::object::pack_10_10_12`]), so a larger budget
//! or device limit is capped there.

use glam::UVec3;

/// Edge of an allocation block, in voxels.
pub const BLOCK: u32 = 8;

/// Bytes per atlas voxel (`R16Float`).
pub const BYTES_PER_VOXEL: u64 = 2;

/// The largest atlas object records can address (10/10/12-bit voxel coordinates).
pub const MAX_ATLAS_SIZE: UVec3 = UVec3::new(1024, 1024, 4096);

/// A placed volume.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct AtlasRegion {
    /// First voxel of the volume in the atlas.
    pub origin: UVec3,
    /// The volume's samples along each axis.
    pub dims: UVec3,
}

impl AtlasRegion {
    fn blocks(&self) -> (UVec3, UVec3) {
        (
            self.origin / BLOCK,
            (self.dims + UVec3::splat(BLOCK - 1)) / BLOCK,
        )
    }
}

/// Why an atlas could not be created or a volume placed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum AtlasError {
    /// The budget cannot hold even one block column of the minimum atlas.
    BudgetTooSmall {
        /// The budget asked for.
        budget_bytes: u64,
    },
    /// A volume with a zero dimension.
    EmptyVolume,
    /// The volume is larger than the atlas along some axis: it can never fit.
    TooLarge {
        /// The volume's dims.
        dims: UVec3,
        /// The atlas size.
        atlas: UVec3,
    },
    /// No free box is large enough right now.
    Full {
        /// The volume's dims.
        dims: UVec3,
        /// Bytes still free (possibly fragmented).
        free_bytes: u64,
    },
}

impl std::fmt::Display for AtlasError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AtlasError::BudgetTooSmall { budget_bytes } => write!(
                f,
                "atlas budget of {budget_bytes} bytes is below the minimum of {} bytes",
                AtlasAllocator::MIN_BUDGET
            ),
            AtlasError::EmptyVolume => write!(f, "volume has a zero dimension"),
            AtlasError::TooLarge { dims, atlas } => {
                write!(f, "volume {dims} is larger than the atlas {atlas}")
            }
            AtlasError::Full { dims, free_bytes } => write!(
                f,
                "atlas full: no free box for a {dims} volume ({free_bytes} bytes free, fragmented)"
            ),
        }
    }
}

impl std::error::Error for AtlasError {}

/// The block allocator of one atlas texture.
#[derive(Clone, Debug)]
pub struct AtlasAllocator {
    /// Atlas size in voxels (a multiple of [`BLOCK`]).
    size: UVec3,
    /// Atlas size in blocks.
    blocks: UVec3,
    /// Occupancy per block, x fastest.
    used: Vec<bool>,
    used_blocks: u64,
}

impl AtlasAllocator {
    /// The smallest budget [`AtlasAllocator::for_budget`] accepts: one 32×32×8 slab.
    pub const MIN_BUDGET: u64 = 32 * 32 * 8 * BYTES_PER_VOXEL;

    /// An empty atlas of `size` voxels, each axis capped at [`MAX_ATLAS_SIZE`] and
    /// rounded down to a multiple of [`BLOCK`] (at least one block).
    pub fn new(size: UVec3) -> AtlasAllocator {
        let blocks = (size.min(MAX_ATLAS_SIZE) / BLOCK).max(UVec3::ONE);
        AtlasAllocator {
            size: blocks * BLOCK,
            blocks,
            used: vec![false; (blocks.x * blocks.y * blocks.z) as usize],
            used_blocks: 0,
        }
    }

    /// The largest atlas within `budget_bytes`, no side longer than `max_dimension`
    /// (the device's 3D texture limit) nor [`MAX_ATLAS_SIZE`]: x and y of 256 voxels
    /// (fewer for tiny budgets, doubled while z would pass its limit), z as deep as the
    /// budget allows. A budget beyond the limits gets the largest atlas they allow.
    pub fn for_budget(budget_bytes: u64, max_dimension: u32) -> Result<Self, AtlasError> {
        if budget_bytes < Self::MIN_BUDGET {
            return Err(AtlasError::BudgetTooSmall { budget_bytes });
        }
        let max_dimension = (max_dimension / BLOCK * BLOCK).max(BLOCK);
        let max_side = max_dimension.min(MAX_ATLAS_SIZE.x);
        let max_depth = max_dimension.min(MAX_ATLAS_SIZE.z) as u64;
        let voxels = budget_bytes / BYTES_PER_VOXEL;
        let mut side = 256.min(max_side);
        while side > 32 && (side as u64 * side as u64 * BLOCK as u64) > voxels {
            side /= 2;
        }
        let depth_for =
            |side: u32| voxels / (side as u64 * side as u64) / BLOCK as u64 * BLOCK as u64;
        while depth_for(side) > max_depth && side * 2 <= max_side {
            side *= 2;
        }
        let depth = depth_for(side).clamp(BLOCK as u64, max_depth) as u32;
        Ok(Self::new(UVec3::new(side, side, depth)))
    }

    /// Atlas size in voxels.
    pub fn size(&self) -> UVec3 {
        self.size
    }

    /// Bytes of the whole texture.
    pub fn bytes(&self) -> u64 {
        self.size.as_u64vec3().element_product() * BYTES_PER_VOXEL
    }

    /// Bytes in allocated blocks.
    pub fn used_bytes(&self) -> u64 {
        self.used_blocks * (BLOCK as u64).pow(3) * BYTES_PER_VOXEL
    }

    /// Bytes in free blocks.
    pub fn free_bytes(&self) -> u64 {
        self.bytes() - self.used_bytes()
    }

    fn block_index(&self, b: UVec3) -> usize {
        (b.x + self.blocks.x * (b.y + self.blocks.y * b.z)) as usize
    }

    /// Places a volume of `dims` samples: first fit in z, y, x block order.
    pub fn allocate(&mut self, dims: UVec3) -> Result<AtlasRegion, AtlasError> {
        if dims.min_element() == 0 {
            return Err(AtlasError::EmptyVolume);
        }
        if dims.cmpgt(self.size).any() {
            return Err(AtlasError::TooLarge {
                dims,
                atlas: self.size,
            });
        }
        let need = (dims + UVec3::splat(BLOCK - 1)) / BLOCK;
        let sat = self.summed_volume();
        let n = self.blocks;
        // Signed: inclusion–exclusion passes through negative partial sums.
        let at =
            |x: u32, y: u32, z: u32| i64::from(sat[(x + (n.x + 1) * (y + (n.y + 1) * z)) as usize]);
        for z in 0..=n.z - need.z {
            for y in 0..=n.y - need.y {
                for x in 0..=n.x - need.x {
                    let (x1, y1, z1) = (x + need.x, y + need.y, z + need.z);
                    let occupied = at(x1, y1, z1) - at(x, y1, z1) - at(x1, y, z1) - at(x1, y1, z)
                        + at(x, y, z1)
                        + at(x, y1, z)
                        + at(x1, y, z)
                        - at(x, y, z);
                    if occupied == 0 {
                        let region = AtlasRegion {
                            origin: UVec3::new(x, y, z) * BLOCK,
                            dims,
                        };
                        self.mark(&region, true);
                        return Ok(region);
                    }
                }
            }
        }
        Err(AtlasError::Full {
            dims,
            free_bytes: self.free_bytes(),
        })
    }

    /// Returns a region's blocks to the free pool. Freeing a region twice, or one this
    /// atlas did not hand out, is a caller bug: the blocks' state is left as it is found
    /// (debug builds assert).
    pub fn free(&mut self, region: &AtlasRegion) {
        self.mark(region, false);
    }

    fn mark(&mut self, region: &AtlasRegion, used: bool) {
        let (first, count) = region.blocks();
        for z in first.z..first.z + count.z {
            for y in first.y..first.y + count.y {
                for x in first.x..first.x + count.x {
                    let i = self.block_index(UVec3::new(x, y, z));
                    debug_assert_ne!(self.used[i], used, "double allocation or free");
                    if self.used[i] != used {
                        self.used[i] = used;
                        if used {
                            self.used_blocks += 1;
                        } else {
                            self.used_blocks -= 1;
                        }
                    }
                }
            }
        }
    }

    /// Inclusive prefix sums of occupied blocks, `(n + 1)³` with a zero border.
    fn summed_volume(&self) -> Vec<u32> {
        let n = self.blocks;
        let (sx, sy) = (n.x + 1, n.y + 1);
        let mut sat = vec![0u32; (sx * sy * (n.z + 1)) as usize];
        let idx = |x: u32, y: u32, z: u32| (x + sx * (y + sy * z)) as usize;
        for z in 1..=n.z {
            for y in 1..=n.y {
                for x in 1..=n.x {
                    let v = u32::from(self.used[self.block_index(UVec3::new(x - 1, y - 1, z - 1))]);
                    sat[idx(x, y, z)] =
                        v + sat[idx(x - 1, y, z)] + sat[idx(x, y - 1, z)] + sat[idx(x, y, z - 1)]
                            - sat[idx(x - 1, y - 1, z)]
                            - sat[idx(x - 1, y, z - 1)]
                            - sat[idx(x, y - 1, z - 1)]
                            + sat[idx(x - 1, y - 1, z - 1)];
                }
            }
        }
        sat
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn overlaps(a: &AtlasRegion, b: &AtlasRegion) -> bool {
        let (a0, an) = a.blocks();
        let (b0, bn) = b.blocks();
        (a0.cmplt(b0 + bn) & b0.cmplt(a0 + an)).all()
    }

    #[test]
    fn budgets_give_bounded_atlases() {
        for (budget, max) in [
            (64 << 20, 2048),
            (256 << 20, 2048),
            (1 << 30, 2048),
            (2 << 20, 2048),
            (AtlasAllocator::MIN_BUDGET, 2048),
            (64 << 20, 256),
        ] {
            let a = AtlasAllocator::for_budget(budget, max).unwrap();
            assert!(a.bytes() <= budget, "{budget}: {} bytes", a.bytes());
            assert!(a.size().max_element() <= max, "{budget}: {}", a.size());
            let cap = (max as u64).pow(3) * BYTES_PER_VOXEL;
            assert!(
                a.bytes() * 2 > budget.min(cap),
                "{budget}: {} bytes",
                a.bytes()
            );
        }
        assert_eq!(
            AtlasAllocator::for_budget(64 << 20, 2048).unwrap().size(),
            UVec3::new(256, 256, 512)
        );
        assert!(matches!(
            AtlasAllocator::for_budget(100, 2048),
            Err(AtlasError::BudgetTooSmall { .. })
        ));
    }

    /// Budgets above 512 MiB on devices with large 3D textures (16384 on many GPUs):
    /// the atlas stays addressable by the records' 10/10/12-bit coordinates, so a
    /// region in its last block encodes and round-trips. Before the cap a 1 GiB budget
    /// gave a 256 × 256 × 8192 atlas whose upper half wrapped to z − 4096 in release
    /// builds.
    #[test]
    fn large_budgets_stay_addressable() {
        use crate::object::{CasterShape, ObjectDesc, encode, flags, unpack_10_10_12};
        for budget in [600u64 << 20, 1 << 30, 4 << 30, 64 << 30] {
            for max in [2048, 8192, 16384] {
                let a = AtlasAllocator::for_budget(budget, max).unwrap();
                let size = a.size();
                assert!(size.cmple(MAX_ATLAS_SIZE).all(), "{budget} {max}: {size}");
                assert!(size.max_element() <= max, "{budget} {max}: {size}");
                assert!(a.bytes() <= budget, "{budget} {max}: {size}");
                // At least half the budget, or the largest atlas the limits allow.
                let largest = MAX_ATLAS_SIZE.min(UVec3::splat(max)).as_u64vec3();
                let cap = largest.element_product() * BYTES_PER_VOXEL;
                assert!(a.bytes() * 2 >= budget.min(cap), "{budget} {max}: {size}");
                let region = AtlasRegion {
                    origin: size - UVec3::splat(BLOCK),
                    dims: UVec3::splat(BLOCK),
                };
                let record = encode(&ObjectDesc {
                    world_from_local: glam::Affine3A::IDENTITY,
                    shape: CasterShape::Volume {
                        region,
                        local_origin: glam::Vec3::ZERO,
                        voxel_size: 0.01,
                        margin: 0.0,
                    },
                    flags: flags::VISIBLE,
                })
                .unwrap();
                let [origin, dims, _] = record.params();
                assert_eq!(unpack_10_10_12(origin), region.origin, "{budget} {max}");
                assert_eq!(unpack_10_10_12(dims) + UVec3::ONE, region.dims);
            }
        }
    }

    #[test]
    fn placements_never_overlap_and_freed_space_is_reused() {
        let mut atlas = AtlasAllocator::new(UVec3::new(64, 64, 64));
        let mut live: Vec<AtlasRegion> = Vec::new();
        let mut s = 3u64;
        let mut next = |m: u32| {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((s >> 33) % m as u64) as u32
        };
        let mut placed = 0;
        for step in 0..3000 {
            if next(3) > 0 || live.is_empty() {
                let dims = UVec3::new(1 + next(30), 1 + next(30), 1 + next(30));
                match atlas.allocate(dims) {
                    Ok(r) => {
                        assert!((r.origin + r.dims).cmple(atlas.size()).all(), "{r:?}");
                        assert!(live.iter().all(|o| !overlaps(o, &r)), "step {step}: {r:?}");
                        live.push(r);
                        placed += 1;
                    }
                    Err(AtlasError::Full { .. }) => {}
                    Err(e) => panic!("{e}"),
                }
            } else {
                let r = live.swap_remove(next(live.len() as u32) as usize);
                atlas.free(&r);
            }
            let used: u64 = live
                .iter()
                .map(|r| r.blocks().1.as_u64vec3().element_product() * 512 * 2)
                .sum();
            assert_eq!(atlas.used_bytes(), used);
        }
        assert!(placed > 500, "{placed}");
        // Everything freed: one allocation of the whole atlas fits again.
        for r in live.drain(..) {
            atlas.free(&r);
        }
        assert_eq!(atlas.used_bytes(), 0);
        assert!(atlas.allocate(UVec3::splat(64)).is_ok());
    }

    #[test]
    fn bad_requests_are_errors() {
        let mut atlas = AtlasAllocator::new(UVec3::new(32, 32, 16));
        assert_eq!(
            atlas.allocate(UVec3::new(0, 4, 4)),
            Err(AtlasError::EmptyVolume)
        );
        assert!(matches!(
            atlas.allocate(UVec3::new(8, 8, 17)),
            Err(AtlasError::TooLarge { .. })
        ));
        assert!(atlas.allocate(UVec3::new(32, 32, 16)).is_ok());
        assert!(matches!(
            atlas.allocate(UVec3::new(1, 1, 1)),
            Err(AtlasError::Full { .. })
        ));
    }
}
