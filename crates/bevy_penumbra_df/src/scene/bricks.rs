//! Volumes stored as sparse bricks (`penumbra_sdf::bricks`): which volumes are, the
//! brick table's CPU mirror and its range allocation.
//!
//! A volume whose dense grid holds at least
//! [`super::DistanceFieldSceneSettings::sparse_min_bytes`] is placed as bricks when that
//! at least halves it: its bricks within [`DEFAULT_BAND_VOXELS`] of the surface go into
//! one pool of whole atlas blocks, its coarse grid (the samples at the bricks' corners)
//! into a small dense region, and a header and one entry per brick into the brick table
//! (`penumbra_df_core::bricks`). Fine fields of small detailed props (the thin-wall rule
//! refines up to 6×) are the case: 10–15 % of a 256-sample field's bricks lie near its
//! surface. Volumes without a surface (a skinned mesh's re-bake
//! placeholder, written on the GPU as a dense field) stay dense.
//!
//! A volume that finds no free box dense (the atlas fragmented: a 256-wide slab needs a
//! free band across the whole atlas) is placed as bricks whatever its size before it is
//! downsampled ([`Placement::Fallback`]): its pool is a near-cube of whole blocks, which
//! fits between other volumes where the slab does not.
//!
//! The table is a CPU mirror sent whole to the render world when it changes (only when
//! a bricked volume is placed: a few hundred kilobytes for a large prop), which keeps
//! the GPU texture's growth simple; freed ranges are reused first-fit.

use penumbra_df_core::atlas::{AtlasAllocator, AtlasRegion};
use penumbra_df_core::bricks::layout;
use penumbra_sdf::SdfVolume;
use penumbra_sdf::bricks::{Brick, BrickedVolume, DEFAULT_BAND_VOXELS};
use std::ops::Range;
use std::sync::Arc;

/// The most entries the brick table holds: 2,048 rows of its texture (the smallest 2D
/// texture size a device may limit to). A volume whose entries would not fit stays dense.
pub(crate) const MAX_TABLE_ENTRIES: usize = penumbra_df_core::bricks::TABLE_WIDTH as usize * 2048;

/// The brick table's CPU mirror and free ranges.
#[derive(Default)]
pub(crate) struct BrickTable {
    entries: Vec<u32>,
    free: Vec<Range<u32>>,
    changed: bool,
}

impl BrickTable {
    /// Whether `len` more entries fit (in a freed range or within [`MAX_TABLE_ENTRIES`]).
    fn fits(&self, len: usize) -> bool {
        self.entries.len() + len <= MAX_TABLE_ENTRIES || self.free.iter().any(|r| r.len() >= len)
    }

    /// A range of `len` entries holding `entries` (first fit in freed ranges, else at the
    /// end).
    fn insert(&mut self, entries: &[u32]) -> Range<u32> {
        let len = entries.len() as u32;
        let start = match self.free.iter().position(|r| r.len() as u32 >= len) {
            Some(i) => {
                let r = self.free[i].clone();
                if r.len() as u32 == len {
                    self.free.remove(i);
                } else {
                    self.free[i].start += len;
                }
                r.start
            }
            None => {
                let start = self.entries.len() as u32;
                self.entries.resize((start + len) as usize, 0);
                start
            }
        };
        self.entries[start as usize..(start + len) as usize].copy_from_slice(entries);
        self.changed = true;
        start..start + len
    }

    /// Lets `range` be reused (its entries stay until overwritten: no record reads them).
    pub(crate) fn free(&mut self, range: Range<u32>) {
        self.free.push(range);
        self.free.sort_by_key(|r| r.start);
        let mut merged: Vec<Range<u32>> = Vec::with_capacity(self.free.len());
        for r in self.free.drain(..) {
            match merged.last_mut() {
                Some(last) if last.end == r.start => last.end = r.end,
                _ => merged.push(r),
            }
        }
        self.free = merged;
    }

    /// The whole table when it changed since the last call.
    pub(crate) fn take_changed(&mut self) -> Option<Arc<[u32]>> {
        std::mem::take(&mut self.changed).then(|| Arc::from(self.entries.as_slice()))
    }

    /// Entries (live or free).
    pub(crate) fn len(&self) -> usize {
        self.entries.len()
    }
}

/// A volume placed as bricks: its pool and coarse grid in the atlas (texels, f16 bits)
/// and its range of the table.
pub(crate) struct PlacedBricks {
    pub(crate) pool: AtlasRegion,
    pub(crate) pool_texels: Vec<u16>,
    pub(crate) coarse: AtlasRegion,
    pub(crate) coarse_texels: Vec<u16>,
    pub(crate) table: Range<u32>,
}

/// When a volume goes bricked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Placement {
    /// First choice: bricks when the dense grid holds at least this many bytes and
    /// bricks at least halve it.
    Sparse {
        /// `DistanceFieldSceneSettings::sparse_min_bytes`.
        min_bytes: u64,
    },
    /// The dense grid found no free box: bricks whatever their size, rather than a
    /// downsampled grid.
    Fallback,
}

/// Places `volume` as bricks if it qualifies (module docs, `placement`) and its pool fits
/// the atlas; `None` places it dense.
pub(crate) fn place_bricked(
    volume: &SdfVolume,
    placement: Placement,
    atlas: &mut AtlasAllocator,
    table: &mut BrickTable,
) -> Option<PlacedBricks> {
    let dense_bytes = 2 * volume.data.len() as u64;
    if let Placement::Sparse { min_bytes } = placement
        && dense_bytes < min_bytes.max(1)
    {
        return None;
    }
    let bricked = BrickedVolume::from_volume(volume, DEFAULT_BAND_VOXELS);
    let entries = bricked.bricks.len() + penumbra_df_core::bricks::HEADER_ENTRIES as usize;
    let halves = 2 * bricked.bytes() <= dense_bytes;
    let sparse = matches!(placement, Placement::Sparse { .. });
    if bricked.stored() == 0 || (sparse && !halves) || !table.fits(entries) {
        return None;
    }
    let cells = bricked.bricks.iter().map(|b| match b {
        Brick::Stored(_) => None,
        Brick::Empty(m) => Some(m.to_bits()),
    });
    let samples: Vec<u16> = bricked.samples.iter().map(|h| h.to_bits()).collect();
    let blocks = penumbra_df_core::bricks::pool_blocks(bricked.stored() as u32);
    let pool = atlas
        .allocate(blocks * penumbra_df_core::bricks::BRICK_SAMPLES)
        .ok()?;
    let Ok(coarse) = atlas.allocate(bricked.coarse_dims()) else {
        atlas.free(&pool);
        return None;
    };
    let Some(l) = layout(cells, &samples, pool.origin, coarse.origin) else {
        atlas.free(&pool);
        atlas.free(&coarse);
        return None;
    };
    debug_assert_eq!(l.pool_dims, pool.dims);
    let table = table.insert(&l.entries);
    Some(PlacedBricks {
        pool,
        pool_texels: l.pool,
        coarse,
        coarse_texels: bricked.coarse.iter().map(|h| h.to_bits()).collect(),
        table,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_ranges_are_reused_first_fit_and_merged() {
        let mut t = BrickTable::default();
        let a = t.insert(&[1, 2, 3]);
        let b = t.insert(&[4, 5]);
        assert_eq!((a.clone(), b.clone()), (0..3, 3..5));
        assert!(t.take_changed().is_some());
        assert!(t.take_changed().is_none());
        t.free(a);
        let c = t.insert(&[6, 7]);
        assert_eq!(c, 0..2);
        t.free(b);
        t.free(c);
        // 0..2, 2..3 and 3..5 merged: a 5-entry volume fits without growing.
        assert_eq!(t.insert(&[8; 5]), 0..5);
        assert_eq!(t.len(), 5);
        assert_eq!(&*t.take_changed().expect("changed"), &[8; 5]);
        assert!(t.fits(5) && t.fits(MAX_TABLE_ENTRIES - 5) && !t.fits(MAX_TABLE_ENTRIES));
    }
}
