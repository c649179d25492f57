//! Heightfields as the GPU reads them (`shaders/df/heightfield.wgsl`): one
//! [`HeightfieldRecord`] per terrain in a storage buffer and one `R32Float` texture of
//! [`HeightfieldTexture::width`] texels a row holding, terrain after terrain, its
//! heights (`size.y` rows) and then its per-tile slope bounds (`tiles.y` rows).
//! Positions and heights are relative to the record's 512 m tile, as object records'
//! are, so a terrain far from the origin keeps its precision.
//! [`HeightfieldTexture::distance`] is the GPU's arithmetic on the CPU; it equals
//! [`Heightfield::distance`] up to the rounding of the tile-relative frame.

use super::Heightfield;
use crate::object::{TILE_SIZE, tile_of, tile_relative};
use encase::ShaderType;
use glam::{IVec2, IVec3, UVec2, Vec2, Vec3, Vec4};

/// One terrain on the GPU (a storage-buffer element).
#[derive(ShaderType, Clone, Copy, Debug, Default, PartialEq)]
pub struct HeightfieldRecord {
    /// The 512 m tile positions and heights are relative to.
    pub tile: IVec3,
    /// The texture row of the first height row; the slope bounds follow `size.y` rows
    /// later.
    pub row: u32,
    /// The corner sample's x and z, tile-relative metres.
    pub origin: Vec2,
    /// World size in x and z, metres.
    pub extent: Vec2,
    /// Samples in x and z.
    pub size: UVec2,
    /// Slope tiles in x and z.
    pub tiles: UVec2,
    /// The whole terrain's slope bound `√(1 + L²)`, a slope tile's reach (metres), and
    /// the lowest and highest heights (tile-relative metres).
    pub bounds: Vec4,
}

impl HeightfieldRecord {
    /// The box (min, max) of the surface, tile-relative.
    pub fn aabb(&self) -> (Vec3, Vec3) {
        (
            Vec3::new(self.origin.x, self.bounds.z, self.origin.y),
            Vec3::new(
                self.origin.x + self.extent.x,
                self.bounds.w,
                self.origin.y + self.extent.y,
            ),
        )
    }
}

/// The heightfield texture's contents and the records pointing into it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HeightfieldTexture {
    /// Texels per row.
    pub width: u32,
    /// Rows.
    pub rows: u32,
    /// `width × rows` values, row after row.
    pub texels: Vec<f32>,
    /// One per terrain that fit.
    pub records: Vec<HeightfieldRecord>,
}

impl HeightfieldTexture {
    /// Packs `terrains` into a texture at most `max_side` texels wide and tall; a
    /// terrain that does not fit (or lies beyond the tile grid) is left out and named
    /// in the second value (its index and why). An empty list gives a 1 × 1 texture
    /// and no records.
    pub fn pack(terrains: &[&Heightfield], max_side: u32) -> (Self, Vec<(usize, String)>) {
        let mut refused = Vec::new();
        let mut kept = Vec::new();
        let mut rows = 0u32;
        let mut width = 1u32;
        for (i, h) in terrains.iter().enumerate() {
            let need = h.size.y + h.tiles.y;
            let centre = Vec3::new(
                h.origin.x + 0.5 * h.extent.x,
                0.5 * (h.min_height + h.max_height),
                h.origin.y + 0.5 * h.extent.y,
            );
            let Some(tile) = tile_of(centre) else {
                refused.push((i, "it lies beyond the tile grid".to_string()));
                continue;
            };
            if h.size.x > max_side || rows + need > max_side {
                refused.push((
                    i,
                    format!(
                        "its {}×{} heights do not fit the GPU's {max_side}-texel heightfield \
                         texture beside the others",
                        h.size.x, h.size.y
                    ),
                ));
                continue;
            }
            kept.push((*h, tile, rows));
            rows += need;
            width = width.max(h.size.x);
        }
        let rows_total = rows.max(1);
        let mut texels = vec![0.0f32; (width * rows_total) as usize];
        let mut records = Vec::with_capacity(kept.len());
        for (h, tile, row) in kept {
            let lift = tile[1] as f32 * TILE_SIZE;
            for j in 0..h.size.y {
                let dst = ((row + j) * width) as usize;
                let src = (j * h.size.x) as usize;
                for (d, s) in texels[dst..dst + h.size.x as usize]
                    .iter_mut()
                    .zip(&h.heights[src..src + h.size.x as usize])
                {
                    *d = s - lift;
                }
            }
            for j in 0..h.tiles.y {
                let dst = ((row + h.size.y + j) * width) as usize;
                let src = (j * h.tiles.x) as usize;
                texels[dst..dst + h.tiles.x as usize]
                    .copy_from_slice(&h.lipschitz[src..src + h.tiles.x as usize]);
            }
            let origin = tile_relative(Vec3::new(h.origin.x, 0.0, h.origin.y), tile);
            records.push(HeightfieldRecord {
                tile: IVec3::from_array(tile),
                row,
                origin: Vec2::new(origin.x, origin.z),
                extent: h.extent,
                size: h.size,
                tiles: h.tiles,
                bounds: Vec4::new(
                    h.lipschitz_all,
                    h.reach,
                    h.min_height - lift,
                    h.max_height - lift,
                ),
            });
        }
        (
            HeightfieldTexture {
                width,
                rows: rows_total,
                texels,
                records,
            },
            refused,
        )
    }

    fn load(&self, at: IVec2) -> f32 {
        self.texels[(at.x as u32 + self.width * at.y as u32) as usize]
    }

    /// The surface height (tile-relative) of `h` at tile-relative `(x, z)`, as the GPU
    /// computes it.
    pub fn height(&self, h: &HeightfieldRecord, xz: Vec2) -> f32 {
        let cells = (h.size - UVec2::ONE).as_vec2();
        let g = ((xz - h.origin) / h.extent * cells).clamp(Vec2::ZERO, cells);
        let i0 = g.floor().min(cells - Vec2::ONE);
        let f = g - i0;
        let base = i0.as_ivec2() + IVec2::new(0, h.row as i32);
        let a = self.load(base);
        let b = self.load(base + IVec2::X);
        let c = self.load(base + IVec2::Y);
        let d = self.load(base + IVec2::ONE);
        let x0 = a + (b - a) * f.x;
        let x1 = c + (d - c) * f.x;
        x0 + (x1 - x0) * f.y
    }

    /// [`Heightfield::distance`] of `h` at `p` relative to its tile, as the GPU
    /// computes it.
    pub fn distance(&self, h: &HeightfieldRecord, p: Vec3) -> f32 {
        let xz = Vec2::new(p.x, p.z);
        let cells = (h.size - UVec2::ONE).as_vec2();
        let g = (xz - h.origin) / h.extent * cells;
        let tile = (g.clamp(Vec2::ZERO, cells - 1e-3) / super::SLOPE_TILE as f32).floor();
        let k = self.load(tile.as_ivec2() + IVec2::new(0, (h.row + h.size.y) as i32));
        let gap = p.y - self.height(h, xz);
        let bound = (gap.abs() / k).min(h.bounds.y).max(gap.abs() / h.bounds.x);
        let vertical = if gap < 0.0 { -bound } else { bound };
        let outside = (h.origin - xz)
            .max(xz - h.origin - h.extent)
            .max(Vec2::ZERO);
        if outside == Vec2::ZERO {
            return vertical;
        }
        let above = (p.y - h.bounds.w).max(0.0);
        vertical.max((outside.length_squared() + above * above).sqrt())
    }
}
