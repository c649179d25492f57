//! Compute tessellation (#23, Samaritan's "Tessellation", Mittring and Dudash, GDC 2011):
//! the Bevy-free half — the per-mesh preprocessing, the tessellation factors, the patch
//! evaluation and a CPU reference tessellator that the WGSL passes
//! (`shaders/tessellation/`) follow operation for operation.
//!
//! # The scheme
//!
//! wgpu has no hull or domain shaders, so a patch (one input triangle) is tessellated in
//! compute into a vertex and index pool, in the manner of Direct3D 11's fixed-function
//! tessellator with `fractional_odd` partitioning ([`layout`]).
//!
//! - **Factors** ([`factors`]): an edge asks for `f = D / pixels_per_triangle` segments,
//!   `D` the projected diameter, in pixels, of the edge's bounding sphere (so a long thin
//!   triangle's short edges stay coarse, and an edge seen end-on is not under-
//!   tessellated); `1 ≤ f ≤ 2^max_level`. The inside factor is the largest edge's.
//! - **Layout.** A factor's 1-D pattern has the smallest odd count `n ≥ f` of segments,
//!   `n − 2` of `1/f` and two shorter ones beside the middle. The outer ring is each
//!   edge's own pattern; inner rings are shrunken copies of the triangle carrying the
//!   inside pattern; a zipper joins the outer ring to the first inner ring.
//! - **Crack-free edges.** An edge's vertices are a function of the edge alone, in a
//!   canonical direction (from the endpoint whose *dominant vertex* — the lowest vertex
//!   index at that position — is lower): its factor, pattern, curve, UVs and displacement
//!   direction. Both triangles of an edge write bit-identical vertices, in the same
//!   number, so welding by position bits leaves no boundary edge.
//! - **Partitioning.** [`Partitioning::Fractional`]: as `f` passes an odd number two new
//!   segments are born with zero length in the middle of the pattern, so every vertex
//!   moves continuously with the camera (what is left are zipper diagonals flipping;
//!   measured in `tests/tessellation.rs`). [`Partitioning::Integer`]: `n` equal segments,
//!   which pop when `n` changes.
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
pub mod layout;
pub mod patch;
pub mod preprocess;
pub mod reference;
pub mod shapes;
pub mod uniform;

pub use factors::{TessellationView, edge_factor};
pub use patch::DisplacementMap;
pub use preprocess::{PreprocessError, SourceMesh, TessVertex, TessellationInput};
pub use reference::{TessellatedMesh, tessellate};

/// The highest `max_level`: factors up to `2^6 = 64` (65 segments per edge, about
/// 6,300 triangles per patch).
pub const MAX_LEVEL: u32 = 6;

/// Indices per patch in [`TessellationInput::patches`]: the triangle (0–2), each edge's
/// opposite pair (3–4 edge 0→1, 5–6 edge 1→2, 7–8 edge 2→0, each in the order of the
/// triangle's own corners), the dominant vertex of each corner (9–11).
pub const PATCH_INDICES: usize = 12;

/// Biases the GPU may apply to fit the output pool: each of `0..UNTESSELLATED_BIAS`
/// halves the factors once more; the last, [`UNTESSELLATED_BIAS`], draws every patch as
/// its input triangle (factors 1), which any pool holds (3 vertices and 3 indices per
/// patch), so an over-budget view gets coarser patches, never holes.
pub const MAX_BIAS: u32 = 5;

/// The bias that leaves every patch untessellated (its input triangle).
pub const UNTESSELLATED_BIAS: u32 = MAX_BIAS - 1;

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
    /// `n` equal segments (`n` the smallest odd count ≥ the factor): a change of `n`
    /// pops.
    Integer,
    /// Direct3D's `fractional_odd`: new segments grow from zero length, continuous.
    #[default]
    Fractional,
}

/// What the tessellator does, beside the view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Target length, in pixels, of a tessellated edge's projected bounding sphere.
    pub pixels_per_triangle: f32,
    /// The largest factor is `2^max_level` (`max_level ≤ MAX_LEVEL`).
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
            partitioning: Partitioning::Fractional,
            displacement_scale: 0.0,
            displacement_midlevel: 0.5,
            crack_fixes: true,
        }
    }
}
