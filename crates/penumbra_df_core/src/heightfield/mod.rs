//! Heightfields (terrain) as distance-field casters: a grid of heights over a world
//! rectangle, solid below, whose conservative distance lets cones and the global field
//! treat it like any other caster (UE4's landscape heightfield occlusion).
//!
//! The surface is the bilinear interpolation of the grid. Its distance at `p` is
//! bounded below by the vertical gap over the slope: `(p.y − H(x, z)) / √(1 + L²)`, with
//! `L` a bound of the surface's slope between `p` and its nearest surface point (the
//! gap is at most `√(1 + L²)` times the distance). `L` is per 8 × 8-cell tile (the
//! steepest cell edge in the tile and its neighbours), so flat ground is not penalised
//! for a cliff elsewhere; it bounds the slope only within a tile's width `R` of the
//! tile, so the distance is `max(min(gap / k_tile, R), gap / k_all)`. Outside the rectangle the
//! heightfield ends: the distance is at least the horizontal distance to the rectangle
//! (and the terrain's edge heights beyond it, clamped).

use glam::{UVec2, Vec2, Vec3};

mod gpu;
pub use gpu::{HeightfieldRecord, HeightfieldTexture};

/// Cells per slope tile side.
pub const SLOPE_TILE: u32 = 8;

/// Why heights cannot make a heightfield.
#[derive(Clone, Debug, PartialEq)]
pub enum HeightfieldError {
    /// Fewer than 2 × 2 samples, or a size that does not match the heights.
    BadSize {
        /// Samples claimed.
        size: UVec2,
        /// Heights given.
        heights: usize,
    },
    /// The world size is not finite and positive.
    BadExtent(Vec2),
    /// A height is NaN or infinite (its index).
    NonFinite(usize),
}

impl std::fmt::Display for HeightfieldError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            HeightfieldError::BadSize { size, heights } => write!(
                f,
                "a heightfield needs at least 2 × 2 samples and one height per sample \
                 (size {size}, {heights} heights)"
            ),
            HeightfieldError::BadExtent(e) => {
                write!(
                    f,
                    "the heightfield's world size {e} is not finite and positive"
                )
            }
            HeightfieldError::NonFinite(i) => write!(f, "height {i} is not finite"),
        }
    }
}

impl std::error::Error for HeightfieldError {}

/// A heightfield: `size.x × size.y` heights (metres, x fastest) spanning `extent`
/// metres in x and z from `origin` (the corner sample's world x, z); heights are world y.
#[derive(Clone, Debug, PartialEq)]
pub struct Heightfield {
    size: UVec2,
    origin: Vec2,
    extent: Vec2,
    heights: Vec<f32>,
    /// Per slope tile, the slope bound `√(1 + L²)`.
    lipschitz: Vec<f32>,
    /// The slope bound of the whole heightfield.
    lipschitz_all: f32,
    /// The reach of a tile's bound: a tile's width, metres.
    reach: f32,
    tiles: UVec2,
    min_height: f32,
    max_height: f32,
}

impl Heightfield {
    /// A heightfield from its heights, checked.
    pub fn new(
        size: UVec2,
        origin: Vec2,
        extent: Vec2,
        heights: Vec<f32>,
    ) -> Result<Self, HeightfieldError> {
        if size.x < 2 || size.y < 2 || heights.len() != (size.x as usize) * (size.y as usize) {
            return Err(HeightfieldError::BadSize {
                size,
                heights: heights.len(),
            });
        }
        if !(extent.is_finite() && extent.min_element() > 0.0 && origin.is_finite()) {
            return Err(HeightfieldError::BadExtent(extent));
        }
        if let Some(i) = heights.iter().position(|h| !h.is_finite()) {
            return Err(HeightfieldError::NonFinite(i));
        }
        let cell = extent / (size - UVec2::ONE).as_vec2();
        let cells = size - UVec2::ONE;
        let tiles = (cells + UVec2::splat(SLOPE_TILE - 1)) / SLOPE_TILE;
        let h = |i: u32, j: u32| heights[(i + size.x * j) as usize];
        // Steepest edge slope per cell (bilinear: the gradient within a cell is bounded by
        // its edges' slopes along each axis).
        let mut cell_slope = vec![0.0f32; (cells.x * cells.y) as usize];
        for j in 0..cells.y {
            for i in 0..cells.x {
                let sx = (h(i + 1, j) - h(i, j))
                    .abs()
                    .max((h(i + 1, j + 1) - h(i, j + 1)).abs())
                    / cell.x;
                let sz = (h(i, j + 1) - h(i, j))
                    .abs()
                    .max((h(i + 1, j + 1) - h(i + 1, j)).abs())
                    / cell.y;
                cell_slope[(i + cells.x * j) as usize] = (sx * sx + sz * sz).sqrt();
            }
        }
        // Per tile: the steepest cell in it and in the neighbouring tiles (a distance
        // sample near a tile's edge can be nearest to the next tile's surface).
        let mut tile_slope = vec![0.0f32; (tiles.x * tiles.y) as usize];
        for j in 0..cells.y {
            for i in 0..cells.x {
                let (ti, tj) = (i / SLOPE_TILE, j / SLOPE_TILE);
                let s = cell_slope[(i + cells.x * j) as usize];
                for dj in -1i32..=1 {
                    for di in -1i32..=1 {
                        let (a, b) = (ti as i32 + di, tj as i32 + dj);
                        if a >= 0 && b >= 0 && (a as u32) < tiles.x && (b as u32) < tiles.y {
                            let t = &mut tile_slope[(a as u32 + tiles.x * b as u32) as usize];
                            *t = t.max(s);
                        }
                    }
                }
            }
        }
        let min_height = heights.iter().copied().fold(f32::INFINITY, f32::min);
        let max_height = heights.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        let steepest = cell_slope.iter().copied().fold(0.0f32, f32::max);
        Ok(Heightfield {
            size,
            origin,
            extent,
            lipschitz: tile_slope.iter().map(|s| (1.0 + s * s).sqrt()).collect(),
            lipschitz_all: (1.0 + steepest * steepest).sqrt(),
            reach: SLOPE_TILE as f32 * cell.min_element(),
            heights,
            tiles,
            min_height,
            max_height,
        })
    }

    /// The surface height at world `(x, z)` (bilinear; clamped to the edge beyond).
    pub fn height(&self, xz: Vec2) -> f32 {
        let g = ((xz - self.origin) / self.extent * (self.size - UVec2::ONE).as_vec2())
            .clamp(Vec2::ZERO, (self.size - UVec2::ONE).as_vec2());
        let i0 = g.floor().min((self.size - UVec2::splat(2)).as_vec2());
        let f = g - i0;
        let (i, j) = (i0.x as u32, i0.y as u32);
        let h = |di: u32, dj: u32| self.heights[(i + di + self.size.x * (j + dj)) as usize];
        let a = h(0, 0) + (h(1, 0) - h(0, 0)) * f.x;
        let b = h(0, 1) + (h(1, 1) - h(0, 1)) * f.x;
        a + (b - a) * f.y
    }

    /// World bounds (min, max) of the surface.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        (
            Vec3::new(self.origin.x, self.min_height, self.origin.y),
            Vec3::new(
                self.origin.x + self.extent.x,
                self.max_height,
                self.origin.y + self.extent.y,
            ),
        )
    }

    /// A lower bound of the signed distance from world `p` to the terrain (negative
    /// below it), metres (module docs).
    pub fn distance(&self, p: Vec3) -> f32 {
        let xz = Vec2::new(p.x, p.z);
        let g = (xz - self.origin) / self.extent * (self.size - UVec2::ONE).as_vec2();
        let cells = (self.size - UVec2::ONE).as_vec2();
        let tile = (g.clamp(Vec2::ZERO, cells - 1e-3) / SLOPE_TILE as f32).floor();
        let k = self.lipschitz[(tile.x as u32 + self.tiles.x * tile.y as u32) as usize];
        let gap = p.y - self.height(xz);
        let bound = (gap.abs() / k)
            .min(self.reach)
            .max(gap.abs() / self.lipschitz_all);
        let vertical = bound.copysign(gap);
        // Beyond the rectangle the terrain ends: at least as far as the rectangle's
        // edge, and no nearer than its highest point allows.
        let outside = (self.origin - xz)
            .max(xz - self.origin - self.extent)
            .max(Vec2::ZERO);
        if outside == Vec2::ZERO {
            return vertical;
        }
        let above = (p.y - self.max_height).max(0.0);
        vertical.max((outside.length_squared() + above * above).sqrt())
    }
}

#[cfg(test)]
mod tests;
