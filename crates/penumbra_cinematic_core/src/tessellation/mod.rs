//! Compute tessellation (#23, Samaritan's "Tessellation", Mittring and Dudash, GDC 2011):
//! the Bevy-free half — the per-mesh preprocessing, the tessellation factors, the patch
//! evaluation and a CPU reference tessellator that the WGSL passes
//! (`shaders/tessellation/`) follow operation for operation.
//!
//! # The scheme
//!
//! wgpu has no hull or domain shaders, so a patch (one input triangle) is tessellated in
//! compute into a vertex and index pool. A patch of *level* `L` is the regular grid of
//! `n = 2^L` segments per edge: `(n+1)(n+2)/2` vertices, `n²` triangles, barycentric
//! `(k, i, j)/n` for corners 0, 1, 2 ([`grid_vertex_count`], [`grid_triangles`]).
//!
//! - **Factors** ([`factors`]): an edge asks for `f = D / pixels_per_triangle` segments,
//!   `D` the projected diameter, in pixels, of the edge's bounding sphere (so a long thin
//!   triangle's short edges stay coarse, and an edge seen end-on is not under-
//!   tessellated); `1 ≤ f ≤ 2^max_level`. Its level is `ℓ = ⌈log₂ f⌉`, so an edge ends up
//!   with `f ≤ 2^ℓ < 2f` segments of `½–1×` the target. A patch's level is that of its
//!   largest edge factor.
//! - **Crack-free edges.** An edge's vertices are computed by a function of the edge alone,
//!   in a canonical direction (from the endpoint whose *dominant vertex* — the lowest
//!   vertex index at that position — is lower), at its own level: both triangles of an
//!   edge produce bit-identical vertices. A patch whose level is above an edge's snaps its
//!   grid vertices on that edge to the nearest of the edge's (degenerate triangles, no
//!   T-junctions).
//! - **Partitioning.** [`Partitioning::Integer`] switches an edge's level whole;
//!   [`Partitioning::Fractional`] geomorphs the edges: the vertices an edge's level adds
//!   start at the midpoint of their two coarser neighbours and move to their place as
//!   `f` grows from `2^(ℓ−1)` to `2^ℓ` (`morph = f/2^(ℓ−1) − 1`). Interior vertices are
//!   not morphed: a morph toward neighbours on snapped edge rows moved the surface
//!   *more* than the pop it hides (measured in `tests/tessellation.rs`). With the
//!   displacement mip following the level, a level switch moves the surface little
//!   either way.
//! - **Surfaces** ([`patch`]): flat, or PN triangles (Vlachos et al. 2001) with
//!   **adjacent edge normals** (PN-AEN, `McDonald` and Kilgard 2010): each edge's cubic
//!   control points are the average of the two sides' (the triangle's own normals and the
//!   neighbour's at the same positions), so an edge with split normals is one curve.
//! - **Displacement** along the position-averaged normal by a height map, sampled
//!   trilinearly from a mip chain ([`patch::DisplacementMap`]) at the level where one
//!   tessellated edge spans about one texel; edges sample at the *dominant edge*'s UVs
//!   and corners at the dominant vertex's, so UV seams do not crack.
//!
//! The preprocessing ([`preprocess`]) builds meshoptimizer's 12-index patches
//! (`generateTessellationIndexBuffer`: the triangle, each edge's opposite pair, the three
//! dominant vertices) and the per-vertex data once per mesh.
//!
//! References: Vlachos, Peters, Boyd and Mitchell, "Curved PN Triangles" (I3D 2001);
//! `McDonald` and Kilgard, "Crack-Free Point-Normal Triangles using Adjacent Edge Normals"
//! (NVIDIA 2010); Castaño, "Water-tight, textured, displaced subdivision surface
//! tessellation using Direct3D 11" (Gamefest 2008) for dominant edges and vertices;
//! Strugar, "Continuous Distance-Dependent Level of Detail" (2009) for the geomorph.

pub mod factors;
pub mod patch;
pub mod preprocess;
pub mod reference;
pub mod shapes;
pub mod uniform;

pub use factors::{TessellationView, edge_factor, level_of};
pub use patch::DisplacementMap;
pub use preprocess::{PreprocessError, SourceMesh, TessVertex, TessellationInput};
pub use reference::{TessellatedMesh, tessellate};

/// The highest patch level (`2^6 = 64` segments per edge, 4,096 triangles per patch).
pub const MAX_LEVEL: u32 = 6;

/// Indices per patch in [`TessellationInput::patches`]: the triangle (0–2), each edge's
/// opposite pair (3–4 edge 0→1, 5–6 edge 1→2, 7–8 edge 2→0, each in the order of the
/// triangle's own corners), the dominant vertex of each corner (9–11).
pub const PATCH_INDICES: usize = 12;

/// Biases (each halves the factors) the GPU may apply to fit the output pool.
pub const MAX_BIAS: u32 = 4;

/// The surface a patch evaluates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SurfaceMode {
    /// The input's flat triangles (only displacement adds detail).
    Flat,
    /// PN triangles with adjacent edge normals.
    #[default]
    PnAen,
}

/// How factors become levels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Partitioning {
    /// Power-of-two levels switched whole: a level change pops (little: the
    /// displacement mip follows the level).
    #[default]
    Integer,
    /// Power-of-two levels with the edges' new vertices geomorphed from their coarse
    /// midpoints; interior vertices still switch whole.
    Fractional,
}

/// What the tessellator does, beside the view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Target length, in pixels, of a tessellated edge's projected bounding sphere.
    pub pixels_per_triangle: f32,
    /// Highest level (`≤ MAX_LEVEL`).
    pub max_level: u32,
    /// The surface.
    pub mode: SurfaceMode,
    /// Levels and morphing.
    pub partitioning: Partitioning,
    /// Height (local units) of a texel value of 1 above the midlevel.
    pub displacement_scale: f32,
    /// The texel value that is the surface itself.
    pub displacement_midlevel: f32,
    /// Dominant edges and vertices, AEN and canonical edge evaluation. Off only to show
    /// the cracks they prevent (each side evaluates its own data).
    pub crack_fixes: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            pixels_per_triangle: 16.0,
            max_level: 5,
            mode: SurfaceMode::PnAen,
            partitioning: Partitioning::Integer,
            displacement_scale: 0.0,
            displacement_midlevel: 0.5,
            crack_fixes: true,
        }
    }
}

/// Vertices of a level-`level` patch: `(n+1)(n+2)/2`, `n = 2^level`.
pub const fn grid_vertex_count(level: u32) -> u32 {
    let n = 1 << level;
    (n + 1) * (n + 2) / 2
}

/// Triangles of a level-`level` patch: `n²`.
pub const fn grid_triangle_count(level: u32) -> u32 {
    1 << (2 * level)
}

/// The index, within its patch, of grid vertex `(i, j)` (`i` steps toward corner 1, `j`
/// toward corner 2) of a patch with `n` segments per edge: rows of constant `j`.
pub const fn grid_index(n: u32, i: u32, j: u32) -> u32 {
    j * (n + 1) - j * (j.saturating_sub(1)) / 2 + i
}

/// Triangle `t` of a grid with `n` segments, as grid coordinates `[(i, j); 3]`, wound as
/// the patch (corner 0 → 1 → 2). Row `j` holds `2(n − j) − 1` triangles: up, down, up, …
pub fn grid_triangle(n: u32, t: u32) -> [(u32, u32); 3] {
    // Rows hold 2n−1, 2n−3, …: find the row by the running count.
    let mut j = 0;
    let mut first = 0;
    loop {
        let row = 2 * (n - j) - 1;
        if t < first + row {
            break;
        }
        first += row;
        j += 1;
    }
    let r = t - first;
    let i = r / 2;
    if r.is_multiple_of(2) {
        [(i, j), (i + 1, j), (i, j + 1)]
    } else {
        [(i + 1, j), (i + 1, j + 1), (i, j + 1)]
    }
}

/// All triangles of a grid with `n` segments as local vertex indices.
pub fn grid_triangles(n: u32) -> Vec<[u32; 3]> {
    (0..n * n)
        .map(|t| grid_triangle(n, t).map(|(i, j)| grid_index(n, i, j)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_counts_and_winding() {
        for level in 0..=MAX_LEVEL {
            let n = 1 << level;
            let tris = grid_triangles(n);
            assert_eq!(tris.len() as u32, grid_triangle_count(level));
            let max = tris.iter().flatten().copied().max().unwrap();
            assert_eq!(max + 1, grid_vertex_count(level));
            // Every triangle is wound as (0,0) → (n,0) → (0,n): positive in (i, j).
            for t in 0..n * n {
                let [a, b, c] = grid_triangle(n, t);
                let cross = (b.0 as i64 - a.0 as i64) * (c.1 as i64 - a.1 as i64)
                    - (b.1 as i64 - a.1 as i64) * (c.0 as i64 - a.0 as i64);
                assert_eq!(cross, 1, "level {level} triangle {t}");
            }
            assert_eq!(grid_index(n, n, 0), n);
            assert_eq!(grid_index(n, 0, n), grid_vertex_count(level) - 1);
        }
    }
}
