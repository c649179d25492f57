//! The brick table: how a volume stored as sparse bricks (`penumbra_sdf::bricks`) is
//! addressed on the GPU.
//!
//! A bricked volume's record ([`crate::object::CasterShape::BrickedVolume`], flag
//! [`crate::object::flags::BRICKED`]) holds the index of its first entry in one shared
//! table of `u32` entries: a header ([`HEADER_ENTRIES`]: the atlas origin of its coarse
//! grid, packed 10/10/12 — `penumbra_sdf::bricks`' samples at the bricks' corners, a
//! small dense volume of its own), then one entry per brick, x fastest over the volume's
//! brick grid (`penumbra_sdf::bricks::brick_grid` of its dims). A brick's entry is either
//! - **stored**: the atlas block (8³ voxels, [`crate::atlas::BLOCK`]) holding the brick's
//!   8³ samples, as block coordinates 7/7/9 bits (the largest atlas,
//!   [`crate::atlas::MAX_ATLAS_SIZE`], is 128 × 128 × 512 blocks); or
//! - **empty** ([`EMPTY`] set): the brick's sample of smallest magnitude as IEEE half
//!   bits in the low 16 bits (voxels, signed).
//!
//! The table lives in an `R32Uint` 2-D texture [`TABLE_WIDTH`] texels wide, entry `i` at
//! texel `(i mod TABLE_WIDTH, i / TABLE_WIDTH)` (a texture so that the passes' shared
//! WGSL functions can take it as an argument, as they take the atlas). CPU reference:
//! `penumbra_reference::df::Atlas::table`; WGSL: `shaders/df/distance.wgsl`.

use glam::{UVec2, UVec3};

/// Entries before a volume's brick entries: its coarse grid's atlas origin.
pub const HEADER_ENTRIES: u32 = 1;

/// Texels per row of the brick-table texture.
pub const TABLE_WIDTH: u32 = 4096;

/// An entry's tag bit for an empty brick.
pub const EMPTY: u32 = 1 << 31;

/// The entry of a brick stored in atlas block `block` (block coordinates, not voxels);
/// `None` beyond the largest atlas.
pub fn stored_entry(block: UVec3) -> Option<u32> {
    (block.x < 128 && block.y < 128 && block.z < 512)
        .then_some(block.x | block.y << 7 | block.z << 14)
}

/// The entry of an empty brick whose sample of smallest magnitude has IEEE half bits
/// `least`.
pub fn empty_entry(least: u16) -> u32 {
    EMPTY | least as u32
}

/// What an entry says: `Ok(block)` for a stored brick, `Err(half bits)` for an empty one.
pub fn decode(entry: u32) -> Result<UVec3, u16> {
    if entry & EMPTY != 0 {
        Err(entry as u16)
    } else {
        Ok(UVec3::new(
            entry & 0x7f,
            (entry >> 7) & 0x7f,
            (entry >> 14) & 0x1ff,
        ))
    }
}

/// The texel holding entry `index`.
pub fn table_texel(index: u32) -> UVec2 {
    UVec2::new(index % TABLE_WIDTH, index / TABLE_WIDTH)
}

/// Samples along each edge of a brick: one atlas block.
pub const BRICK_SAMPLES: u32 = crate::atlas::BLOCK;

/// Atlas blocks along each axis of a pool holding `stored` bricks (at least one): the
/// smallest near-cube, x then y then z.
pub fn pool_blocks(stored: u32) -> UVec3 {
    let n = stored.max(1);
    let x = (n as f64).cbrt().ceil() as u32;
    let y = (n as f64 / x as f64).sqrt().ceil() as u32;
    let z = n.div_ceil(x * y);
    UVec3::new(x, y, z)
}

/// A bricked volume laid out for the GPU: its table entries and its pool of bricks.
#[derive(Clone, Debug, PartialEq)]
pub struct BrickLayout {
    /// One entry per brick, x fastest over the brick grid.
    pub entries: Vec<u32>,
    /// The pool's size in voxels (whole blocks).
    pub pool_dims: UVec3,
    /// The pool's texels as IEEE half bits, x fastest; unused blocks hold zeros.
    pub pool: Vec<u16>,
}

/// Lays out a bricked volume whose pool will sit at atlas voxel `pool_origin` (a block
/// corner) and its coarse grid at `coarse_origin`: `bricks` has one item per brick in
/// table order, `None` for a stored brick (the next 8³ of `samples`, half bits, x
/// fastest) and `Some(half bits)` of an empty brick's sample of smallest magnitude.
/// `None` when the pool or the coarse grid would lie beyond the largest atlas.
pub fn layout(
    bricks: impl IntoIterator<Item = Option<u16>>,
    samples: &[u16],
    pool_origin: UVec3,
    coarse_origin: UVec3,
) -> Option<BrickLayout> {
    let len = (BRICK_SAMPLES * BRICK_SAMPLES * BRICK_SAMPLES) as usize;
    let stored = (samples.len() / len) as u32;
    let blocks = pool_blocks(stored);
    let pool_dims = blocks * BRICK_SAMPLES;
    let mut pool = vec![0u16; (pool_dims.x * pool_dims.y * pool_dims.z) as usize];
    let first = pool_origin / BRICK_SAMPLES;
    let mut entries = vec![crate::object::pack_10_10_12(coarse_origin)?];
    let mut next = 0u32;
    for brick in bricks {
        let entry = match brick {
            Some(least) => empty_entry(least),
            None => {
                let b = UVec3::new(
                    next % blocks.x,
                    (next / blocks.x) % blocks.y,
                    next / (blocks.x * blocks.y),
                );
                let src = samples.get(len * next as usize..)?.get(..len)?;
                // A row of the brick (x fastest) is a row of the pool.
                let row = BRICK_SAMPLES as usize;
                for (r, src_row) in src.chunks_exact(row).enumerate() {
                    let r = r as u32;
                    let v = b * BRICK_SAMPLES + UVec3::new(0, r % BRICK_SAMPLES, r / BRICK_SAMPLES);
                    let start = (v.x + pool_dims.x * (v.y + pool_dims.y * v.z)) as usize;
                    pool[start..start + row].copy_from_slice(src_row);
                }
                next += 1;
                stored_entry(first + b)?
            }
        };
        entries.push(entry);
    }
    Some(BrickLayout {
        entries,
        pool_dims,
        pool,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entries_round_trip() {
        for b in [
            UVec3::ZERO,
            UVec3::new(127, 127, 511),
            UVec3::new(5, 90, 300),
        ] {
            assert_eq!(decode(stored_entry(b).expect("in range")), Ok(b));
        }
        assert_eq!(stored_entry(UVec3::new(128, 0, 0)), None);
        assert_eq!(stored_entry(UVec3::new(0, 0, 512)), None);
        for h in [0u16, 0x3c00, 0xbc00, 0x7bff, 0xfbff] {
            assert_eq!(decode(empty_entry(h)), Err(h));
        }
        assert_eq!(table_texel(TABLE_WIDTH + 3), UVec2::new(3, 1));
    }

    #[test]
    fn pools_are_near_cubes_that_hold_every_brick() {
        for n in [0u32, 1, 2, 7, 8, 9, 26, 27, 28, 1000, 4567] {
            let b = pool_blocks(n);
            let cap = b.x * b.y * b.z;
            assert!(cap >= n.max(1), "{n}: {b}");
            assert!(b.max_element() <= b.min_element() + 2, "{n}: {b}");
            assert!(cap <= n.max(1) + b.x * b.y, "{n}: {b} wastes a layer");
        }
    }

    /// Each stored brick's samples land in the block its entry names; empty bricks keep
    /// their value.
    #[test]
    fn layout_places_each_brick_where_its_entry_says() {
        let len = 512;
        let samples: Vec<u16> = (0..3 * len as u16).collect();
        let bricks = [None, Some(0x4400), None, None, Some(0xc400)];
        let origin = UVec3::new(16, 8, 24);
        let coarse = UVec3::new(40, 0, 8);
        let l = layout(bricks, &samples, origin, coarse).expect("fits");
        assert_eq!(l.entries.len(), 6);
        assert_eq!(crate::object::unpack_10_10_12(l.entries[0]), coarse);
        let e = &l.entries[HEADER_ENTRIES as usize..];
        assert_eq!(decode(e[1]), Err(0x4400));
        assert_eq!(decode(e[4]), Err(0xc400));
        for (k, e) in [e[0], e[2], e[3]].into_iter().enumerate() {
            let block = decode(e).expect("stored") * BRICK_SAMPLES - origin;
            for n in [0u32, 1, 8, 64, 511] {
                let v = block + UVec3::new(n % 8, (n / 8) % 8, n / 64);
                let at = (v.x + l.pool_dims.x * (v.y + l.pool_dims.y * v.z)) as usize;
                assert_eq!(l.pool[at], samples[k * len + n as usize]);
            }
        }
        assert!(layout([None], &samples[..10], origin, coarse).is_none());
        assert!(layout([None], &samples, UVec3::new(1024, 0, 0), coarse).is_none());
        assert!(layout([None], &samples, origin, UVec3::new(1024, 0, 0)).is_none());
    }
}
