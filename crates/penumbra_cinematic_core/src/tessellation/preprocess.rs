//! The per-mesh preprocessing, once per mesh version: positions welded by their bits,
//! dominant vertices, each edge's opposite pair (meshoptimizer's 12-index patches), the
//! position-averaged normals displacement moves along, and the UV density that picks
//! the displacement mip at corners.

use super::PATCH_INDICES;
use encase::ShaderType;
use glam::{Vec2, Vec3, Vec4};
use std::collections::HashMap;

/// A triangle-list mesh, as borrowed from the app.
#[derive(Clone, Copy, Debug)]
pub struct SourceMesh<'a> {
    /// Positions (local units).
    pub positions: &'a [Vec3],
    /// Vertex normals; `None` computes angle-weighted smooth normals.
    pub normals: Option<&'a [Vec3]>,
    /// Texture coordinates; `None` gives zeros (no displacement).
    pub uvs: Option<&'a [Vec2]>,
    /// Tangents (`w` the bitangent sign), interpolated when present.
    pub tangents: Option<&'a [Vec4]>,
    /// Triangle list.
    pub indices: &'a [u32],
}

/// One input vertex as the tessellation shaders read it
/// (`penumbra::tessellation::types::TessVertex`).
#[derive(ShaderType, Clone, Copy, Debug, PartialEq, Default)]
pub struct TessVertex {
    /// Position (local units).
    pub position: Vec3,
    /// The vertex's own normal (shading, PN control points).
    pub normal: Vec3,
    /// Texture coordinates.
    pub uv: Vec2,
    /// Tangent and bitangent sign (zero when the mesh has none).
    pub tangent: Vec4,
    /// Angle-weighted normal of every triangle at this position: the displacement
    /// direction, the same for every vertex at the position.
    pub smooth_normal: Vec3,
    /// The largest `|Δu|` and `|Δv|` per local unit along the edges at this position
    /// (the corner's displacement mip).
    pub uv_density: Vec2,
}

/// A mesh ready for the tessellator.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TessellationInput {
    /// Input vertices.
    pub vertices: Vec<TessVertex>,
    /// [`PATCH_INDICES`] indices per kept triangle.
    pub patches: Vec<[u32; PATCH_INDICES]>,
    /// Edges used by one triangle (welded by position bits).
    pub boundary_edges: usize,
    /// Edges used by more than two triangles: their sides may crack where normals or
    /// UVs split across them.
    pub non_manifold_edges: usize,
    /// Triangles dropped: repeated corners or a position shared by two corners.
    pub skipped_triangles: usize,
    /// Whether the normals were computed (the mesh had none, or not one per vertex).
    pub computed_normals: bool,
    /// Whether the mesh had texture coordinates.
    pub has_uvs: bool,
    /// Whether the mesh had tangents.
    pub has_tangents: bool,
    /// Bounds of the positions (local units).
    pub min: Vec3,
    /// See [`Self::min`].
    pub max: Vec3,
}

/// Why a mesh cannot be tessellated.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PreprocessError {
    /// The index count is not a multiple of three, or an index is out of range.
    BadIndices,
    /// A position is not finite.
    NonFinitePosition,
    /// No triangle is left.
    Empty,
    /// An attribute's length is not the position count.
    AttributeLength(&'static str),
}

impl std::fmt::Display for PreprocessError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::BadIndices => {
                write!(f, "the indices are not a triangle list within the vertices")
            }
            Self::NonFinitePosition => write!(f, "a position is not finite"),
            Self::Empty => write!(f, "no non-degenerate triangle"),
            Self::AttributeLength(name) => write!(f, "{name} has not one value per vertex"),
        }
    }
}

impl std::error::Error for PreprocessError {}

/// A position's bits, `-0` as `+0`: vertices weld when their keys are equal.
pub fn position_key(p: Vec3) -> [u32; 3] {
    let bits = |x: f32| if x == 0.0 { 0 } else { x.to_bits() };
    [bits(p.x), bits(p.y), bits(p.z)]
}

/// The angle of triangle `(a, b, c)` at `a`.
fn corner_angle(a: Vec3, b: Vec3, c: Vec3) -> f32 {
    let (u, v) = ((b - a).normalize_or_zero(), (c - a).normalize_or_zero());
    u.dot(v).clamp(-1.0, 1.0).acos()
}

impl TessellationInput {
    /// Preprocesses `mesh`.
    pub fn new(mesh: SourceMesh<'_>) -> Result<Self, PreprocessError> {
        let n = mesh.positions.len();
        if !mesh.indices.len().is_multiple_of(3) || mesh.indices.iter().any(|&i| i as usize >= n) {
            return Err(PreprocessError::BadIndices);
        }
        if mesh.positions.iter().any(|p| !p.is_finite()) {
            return Err(PreprocessError::NonFinitePosition);
        }
        for (name, len) in [
            ("the normals", mesh.normals.map(<[_]>::len)),
            ("the texture coordinates", mesh.uvs.map(<[_]>::len)),
            ("the tangents", mesh.tangents.map(<[_]>::len)),
        ] {
            if len.is_some_and(|l| l != n) {
                return Err(PreprocessError::AttributeLength(name));
            }
        }
        // Dominant vertex: the lowest index at each position.
        let mut first_at: HashMap<[u32; 3], u32> = HashMap::new();
        let dominant: Vec<u32> = (0..n as u32)
            .map(|v| {
                *first_at
                    .entry(position_key(mesh.positions[v as usize]))
                    .or_insert(v)
            })
            .collect();
        let triangles: Vec<[u32; 3]> = mesh
            .indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .filter(|t| {
                let d = t.map(|v| dominant[v as usize]);
                d[0] != d[1] && d[1] != d[2] && d[2] != d[0]
            })
            .collect();
        let skipped_triangles = mesh.indices.len() / 3 - triangles.len();
        if triangles.is_empty() {
            return Err(PreprocessError::Empty);
        }
        let p = |v: u32| mesh.positions[v as usize];
        // Angle-weighted face normals per position.
        let mut smooth = vec![Vec3::ZERO; n];
        for t in &triangles {
            let face = (p(t[1]) - p(t[0]))
                .cross(p(t[2]) - p(t[0]))
                .normalize_or_zero();
            for c in 0..3 {
                let angle = corner_angle(p(t[c]), p(t[(c + 1) % 3]), p(t[(c + 2) % 3]));
                smooth[dominant[t[c] as usize] as usize] += face * angle;
            }
        }
        let smooth_of = |v: u32| smooth[dominant[v as usize] as usize].normalize_or_zero();
        let computed_normals = mesh.normals.is_none();
        let normal_of = |v: u32| match mesh.normals {
            Some(normals)
                if normals[v as usize].is_finite()
                    && normals[v as usize].length_squared() > 0.0 =>
            {
                normals[v as usize].normalize()
            }
            _ => smooth_of(v),
        };
        let uv_of = |v: u32| mesh.uvs.map_or(Vec2::ZERO, |uvs| uvs[v as usize]);
        // Edges by their dominant endpoints: (lower, higher) → (triangle, edge) list.
        let mut edges: HashMap<(u32, u32), Vec<(u32, u8)>> = HashMap::new();
        let mut density = vec![Vec2::ZERO; n];
        for (ti, t) in triangles.iter().enumerate() {
            for e in 0..3u8 {
                let (a, b) = (t[e as usize], t[(e as usize + 1) % 3]);
                let (da, db) = (dominant[a as usize], dominant[b as usize]);
                edges
                    .entry((da.min(db), da.max(db)))
                    .or_default()
                    .push((ti as u32, e));
                let len = (p(b) - p(a)).length();
                if len > 0.0 {
                    let d = (uv_of(b) - uv_of(a)).abs() / len;
                    for x in [da, db] {
                        density[x as usize] = density[x as usize].max(d);
                    }
                }
            }
        }
        let mut boundary_edges = 0;
        let mut non_manifold_edges = 0;
        let mut patches: Vec<[u32; PATCH_INDICES]> = triangles
            .iter()
            .map(|t| {
                let mut patch = [0; PATCH_INDICES];
                patch[..3].copy_from_slice(t);
                for e in 0..3 {
                    patch[3 + 2 * e] = t[e];
                    patch[4 + 2 * e] = t[(e + 1) % 3];
                    patch[9 + e] = dominant[t[e] as usize];
                }
                patch
            })
            .collect();
        for list in edges.values() {
            match list.len() {
                1 => boundary_edges += 1,
                2 => {}
                _ => non_manifold_edges += 1,
            }
            for (k, &(ti, e)) in list.iter().enumerate() {
                if list.len() == 1 {
                    continue;
                }
                // The next triangle on the edge (for a manifold edge, the other one).
                let (oi, _) = list[(k + 1) % list.len()];
                let own = &triangles[ti as usize];
                let other = &triangles[oi as usize];
                let (a, b) = (own[e as usize], own[(e as usize + 1) % 3]);
                let at = |v: u32| {
                    *other
                        .iter()
                        .find(|&&o| dominant[o as usize] == dominant[v as usize])
                        .expect("the other triangle shares the edge's positions")
                };
                let patch = &mut patches[ti as usize];
                patch[3 + 2 * e as usize] = at(a);
                patch[4 + 2 * e as usize] = at(b);
            }
        }
        let vertices = (0..n as u32)
            .map(|v| TessVertex {
                position: p(v),
                normal: normal_of(v),
                uv: uv_of(v),
                tangent: mesh.tangents.map_or(Vec4::ZERO, |t| t[v as usize]),
                smooth_normal: smooth_of(v),
                uv_density: density[dominant[v as usize] as usize],
            })
            .collect();
        let (min, max) = mesh.positions.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), &q| (lo.min(q), hi.max(q)),
        );
        Ok(Self {
            vertices,
            patches,
            boundary_edges,
            non_manifold_edges,
            skipped_triangles,
            computed_normals,
            has_uvs: mesh.uvs.is_some(),
            has_tangents: mesh.tangents.is_some(),
            min,
            max,
        })
    }

    /// The patch indices as one flat list (the GPU's patch buffer).
    pub fn patch_words(&self) -> Vec<u32> {
        self.patches.iter().flatten().copied().collect()
    }
}

/// Edges used by exactly one triangle after welding `positions` by their bits; triangles
/// with two corners at one position (degenerate) and zero-length edges are ignored. The
/// tessellator's output has as many as its input when it has no cracks.
pub fn boundary_edge_count(positions: &[Vec3], indices: &[u32]) -> usize {
    let mut ids: HashMap<[u32; 3], u32> = HashMap::new();
    let id: Vec<u32> = positions
        .iter()
        .map(|&q| {
            let next = ids.len() as u32;
            *ids.entry(position_key(q)).or_insert(next)
        })
        .collect();
    let mut count: HashMap<(u32, u32), i32> = HashMap::new();
    for t in indices.chunks_exact(3) {
        let w = [id[t[0] as usize], id[t[1] as usize], id[t[2] as usize]];
        if w[0] == w[1] || w[1] == w[2] || w[2] == w[0] {
            continue;
        }
        for e in 0..3 {
            let (a, b) = (w[e], w[(e + 1) % 3]);
            *count.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    count.values().filter(|&&c| c == 1).count()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles of a square with split normals and a UV seam on the diagonal.
    fn split_square() -> (Vec<Vec3>, Vec<Vec3>, Vec<Vec2>, Vec<u32>) {
        let p = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ];
        let n = vec![
            Vec3::Z,
            Vec3::Z,
            Vec3::Z,
            Vec3::new(0.0, 0.6, 0.8),
            Vec3::new(0.0, 0.6, 0.8),
            Vec3::Z,
        ];
        let uv = vec![
            Vec2::ZERO,
            Vec2::X,
            Vec2::ONE,
            Vec2::splat(0.5),
            Vec2::ONE * 0.9,
            Vec2::Y,
        ];
        (p, n, uv, vec![0, 1, 2, 3, 4, 5])
    }

    #[test]
    fn patches_hold_the_opposite_pairs_and_dominant_vertices() {
        let (p, n, uv, idx) = split_square();
        let input = TessellationInput::new(SourceMesh {
            positions: &p,
            normals: Some(&n),
            uvs: Some(&uv),
            tangents: None,
            indices: &idx,
        })
        .unwrap();
        assert_eq!(input.boundary_edges, 4);
        assert_eq!(input.non_manifold_edges, 0);
        // Triangle 0's edge 2→0 (vertices 2, 0) is triangle 1's edge 0 (3, 4) reversed.
        assert_eq!(input.patches[0], [0, 1, 2, 0, 1, 1, 2, 4, 3, 0, 1, 2]);
        assert_eq!(input.patches[1], [3, 4, 5, 0, 2, 4, 5, 5, 3, 0, 2, 5]);
        assert_eq!(input.vertices[3].smooth_normal, Vec3::Z);
        assert_eq!(boundary_edge_count(&p, &idx), 4);
    }

    #[test]
    fn bad_meshes_are_errors() {
        let (p, _, _, _) = split_square();
        let mesh = |indices: &'static [u32]| SourceMesh {
            positions: &[],
            normals: None,
            uvs: None,
            tangents: None,
            indices,
        };
        assert_eq!(
            TessellationInput::new(mesh(&[0, 1])).unwrap_err(),
            PreprocessError::BadIndices
        );
        let degenerate = SourceMesh {
            positions: &p,
            indices: &[0, 3, 1],
            ..mesh(&[])
        };
        assert_eq!(
            TessellationInput::new(degenerate).unwrap_err(),
            PreprocessError::Empty
        );
        let nan = [Vec3::NAN, Vec3::X, Vec3::Y];
        let bad = SourceMesh {
            positions: &nan,
            indices: &[0, 1, 2],
            ..mesh(&[])
        };
        assert_eq!(
            TessellationInput::new(bad).unwrap_err(),
            PreprocessError::NonFinitePosition
        );
    }
}
