//! Triangle meshes as baking input, and their validation.

use crate::geometry::Aabb;
use glam::{DVec3, Vec3};

/// An indexed triangle mesh in its own (local) units. Triangles are counter-clockwise
/// seen from outside (glTF's and Bevy's convention), so `(b − a) × (c − a)` points out.
///
/// Vertex `i` lies at `origin + positions[i]`: readers of files with far-out coordinates
/// (survey, CAD) parse in f64 and centre the mesh on its bounds before converting to
/// f32, so a mesh 10⁶ m from the file's origin is as precise as one at it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions, relative to `origin`.
    pub positions: Vec<Vec3>,
    /// Vertex indices, three per triangle.
    pub triangles: Vec<[u32; 3]>,
    /// Where the positions are measured from (zero for meshes built in f32).
    pub origin: DVec3,
}

/// Why a mesh cannot be baked.
#[derive(Clone, Debug, PartialEq)]
pub enum MeshError {
    /// No triangles (or no vertices).
    Empty,
    /// A flat index list whose length is not a multiple of 3.
    IndexCountNotMultipleOfThree(usize),
    /// A triangle refers to a vertex that does not exist.
    IndexOutOfRange {
        /// Triangle number.
        triangle: usize,
        /// The bad index.
        index: u32,
        /// Number of vertices.
        vertex_count: usize,
    },
    /// A vertex used by a triangle has a NaN or infinite coordinate.
    NonFinitePosition {
        /// Vertex number.
        vertex: usize,
    },
    /// Every triangle has zero area: there is no surface.
    AllTrianglesDegenerate,
    /// A vertex used by a triangle lies farther than [`MAX_COORDINATE`] from the mesh's
    /// origin along an axis: squared distances across the mesh would overflow `f32`.
    CoordinateTooLarge {
        /// Vertex number.
        vertex: usize,
        /// Its largest coordinate (absolute value).
        coordinate: f32,
    },
    /// The mesh's surface spans less than [`MIN_EXTENT`] along every axis: squared
    /// distances at its scale fall below `f32`'s normal range.
    TooSmall {
        /// Its largest side, mesh units.
        extent: f32,
    },
}

/// The smallest size a mesh may have, mesh units (its bounds' largest side over the
/// triangles kept): 10⁻⁶ (a micrometre in metres). The closest-point test multiplies
/// squared lengths; at 10⁻¹⁹ units (found by `cargo xtask fuzz`) they vanished and no
/// triangle was nearest to anything.
pub const MIN_EXTENT: f32 = 1.0e-6;

/// The largest coordinate a vertex may have, mesh units, measured from the mesh's
/// `origin` (a mesh read in `f64` is centred there, so this bounds its size, not where it
/// stands): 10⁸. The closest-point test multiplies squared lengths (the fourth power of
/// the mesh's extent), which must stay inside `f32`'s range (`cargo xtask fuzz` found a
/// 4·10¹⁰-unit triangle that broke the sampler).
pub const MAX_COORDINATE: f32 = 1.0e8;

impl std::fmt::Display for MeshError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MeshError::Empty => write!(f, "the mesh has no triangles"),
            MeshError::IndexCountNotMultipleOfThree(n) => {
                write!(f, "{n} indices is not a whole number of triangles")
            }
            MeshError::IndexOutOfRange {
                triangle,
                index,
                vertex_count,
            } => write!(
                f,
                "triangle {triangle} uses vertex {index}, but the mesh has {vertex_count} vertices"
            ),
            MeshError::NonFinitePosition { vertex } => {
                write!(f, "vertex {vertex} has a NaN or infinite coordinate")
            }
            MeshError::AllTrianglesDegenerate => {
                write!(
                    f,
                    "every triangle has zero area: there is no surface to bake"
                )
            }
            MeshError::TooSmall { extent } => write!(
                f,
                "the mesh is {extent:e} units across, below the {MIN_EXTENT:e} units a bake \
                 can measure (scale it up)"
            ),
            MeshError::CoordinateTooLarge { vertex, coordinate } => write!(
                f,
                "vertex {vertex} has a coordinate of {coordinate:e}, beyond the \
                 {MAX_COORDINATE:e} units a bake can measure"
            ),
        }
    }
}

impl std::error::Error for MeshError {}

/// How an index list forms triangles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Topology {
    /// Every three indices form a triangle.
    List,
    /// Each index after the second forms a triangle with the two before it, the winding
    /// alternating so that all triangles face the same way.
    Strip,
    /// Each index after the second forms a triangle with the first and the previous one.
    Fan,
}

/// Triangles formed by `indices` under `topology` (incomplete trailing triangles of a
/// list are ignored).
pub fn triangles_from(indices: &[u32], topology: Topology) -> Vec<[u32; 3]> {
    match topology {
        Topology::List => indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect(),
        Topology::Strip => indices
            .windows(3)
            .enumerate()
            .map(|(k, t)| {
                if k % 2 == 0 {
                    [t[0], t[1], t[2]]
                } else {
                    [t[1], t[0], t[2]]
                }
            })
            .collect(),
        Topology::Fan => (1..indices.len().saturating_sub(1))
            .map(|k| [indices[0], indices[k], indices[k + 1]])
            .collect(),
    }
}

/// What [`TriMesh::validate`] found and dropped.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MeshReport {
    /// Triangles kept.
    pub triangles: usize,
    /// Zero-area triangles dropped (they contribute nothing to distance or winding).
    pub degenerate_dropped: usize,
}

impl TriMesh {
    /// A mesh from positions and a flat index list (three per triangle).
    pub fn from_indices(positions: Vec<Vec3>, indices: &[u32]) -> Result<Self, MeshError> {
        if !indices.len().is_multiple_of(3) {
            return Err(MeshError::IndexCountNotMultipleOfThree(indices.len()));
        }
        Ok(TriMesh {
            positions,
            triangles: indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect(),
            origin: DVec3::ZERO,
        })
    }

    /// A mesh from f64 positions: centred on their bounds (of the finite ones) in f64,
    /// then converted, so far-out coordinates keep their precision (see the type's
    /// docs). Non-finite positions stay non-finite (and are reported by
    /// [`TriMesh::validate`] if a triangle uses them).
    pub fn from_f64(positions: &[DVec3], triangles: Vec<[u32; 3]>) -> TriMesh {
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for p in positions.iter().filter(|p| p.is_finite()) {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        let origin = if lo.x <= hi.x {
            (lo + hi) * 0.5
        } else {
            DVec3::ZERO
        };
        TriMesh {
            positions: positions.iter().map(|p| (*p - origin).as_vec3()).collect(),
            triangles,
            origin,
        }
    }

    /// Bounds of the vertices used by triangles, relative to `origin`.
    pub fn bounds(&self) -> Aabb {
        let mut b = Aabb::EMPTY;
        for t in &self.triangles {
            for &i in t {
                if let Some(&p) = self.positions.get(i as usize) {
                    b.grow(p);
                }
            }
        }
        b
    }

    /// Checks the mesh and returns its triangles as corner positions, dropping zero-area
    /// triangles. Errors: empty, bad indices, non-finite positions, no area at all.
    pub fn validate(&self) -> Result<(Vec<[Vec3; 3]>, MeshReport), MeshError> {
        if self.triangles.is_empty() || self.positions.is_empty() {
            return Err(MeshError::Empty);
        }
        let mut tris = Vec::with_capacity(self.triangles.len());
        let mut report = MeshReport::default();
        for (t, idx) in self.triangles.iter().enumerate() {
            let mut corners = [Vec3::ZERO; 3];
            for (k, &i) in idx.iter().enumerate() {
                let p = *self
                    .positions
                    .get(i as usize)
                    .ok_or(MeshError::IndexOutOfRange {
                        triangle: t,
                        index: i,
                        vertex_count: self.positions.len(),
                    })?;
                if !p.is_finite() {
                    return Err(MeshError::NonFinitePosition { vertex: i as usize });
                }
                let coordinate = p.abs().max_element();
                if coordinate > MAX_COORDINATE {
                    return Err(MeshError::CoordinateTooLarge {
                        vertex: i as usize,
                        coordinate,
                    });
                }
                corners[k] = p;
            }
            if !is_degenerate(corners) {
                tris.push(corners);
            } else {
                report.degenerate_dropped += 1;
            }
        }
        if tris.is_empty() {
            return Err(MeshError::AllTrianglesDegenerate);
        }
        let (lo, hi) = tris
            .iter()
            .flatten()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(p), hi.max(p))
            });
        let extent = (hi - lo).max_element();
        if extent < MIN_EXTENT {
            return Err(MeshError::TooSmall { extent });
        }
        report.triangles = tris.len();
        Ok((tris, report))
    }
}

/// Zero area for the baker: the sine of the triangle's largest angle's complement — its
/// area relative to its longest edge squared — at most [`MIN_RELATIVE_AREA`], measured in
/// f64 (in f32 a 0.5 m triangle 10⁻²³ m wide passed `cross ≠ 0` and broke the sampler's
/// closest-point test; found by `cargo xtask fuzz`).
fn is_degenerate([a, b, c]: [Vec3; 3]) -> bool {
    let (a, b, c) = (a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
    let twice_area = (b - a).cross(c - a).length();
    let longest = (b - a)
        .length_squared()
        .max((c - a).length_squared())
        .max((c - b).length_squared());
    twice_area <= MIN_RELATIVE_AREA * longest
}

/// Below this ratio of twice its area to its longest edge squared a triangle is dropped
/// as degenerate (10⁻⁹: a 1 m needle 1 nm wide is still kept).
pub const MIN_RELATIVE_AREA: f64 = 1e-9;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_meshes_are_rejected_with_clear_errors() {
        let quad = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::ONE];
        let cases: Vec<(TriMesh, MeshError)> = vec![
            (TriMesh::default(), MeshError::Empty),
            (
                TriMesh {
                    positions: quad.clone(),
                    triangles: vec![[0, 1, 7]],
                    ..Default::default()
                },
                MeshError::IndexOutOfRange {
                    triangle: 0,
                    index: 7,
                    vertex_count: 4,
                },
            ),
            (
                TriMesh {
                    positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(f32::NAN, 0.0, 0.0)],
                    triangles: vec![[0, 1, 2]],
                    ..Default::default()
                },
                MeshError::NonFinitePosition { vertex: 2 },
            ),
            (
                TriMesh {
                    positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(0.0, f32::INFINITY, 0.0)],
                    triangles: vec![[0, 1, 2]],
                    ..Default::default()
                },
                MeshError::NonFinitePosition { vertex: 2 },
            ),
            (
                TriMesh {
                    positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(0.0, 0.0, -2.0e8)],
                    triangles: vec![[0, 1, 2]],
                    ..Default::default()
                },
                MeshError::CoordinateTooLarge {
                    vertex: 2,
                    coordinate: 2.0e8,
                },
            ),
            (
                // A 0.5-unit sliver 6·10⁻²³ wide (found by the fuzzer, glTF).
                TriMesh {
                    positions: vec![
                        Vec3::new(2.2e-44, 3.2e-23, -0.25),
                        Vec3::new(-2.2e-44, 3.2e-23, 0.25),
                        Vec3::new(-2.2e-44, -3.2e-23, -0.25),
                    ],
                    triangles: vec![[0, 1, 2]],
                    ..Default::default()
                },
                MeshError::AllTrianglesDegenerate,
            ),
            (
                // 10⁻¹⁹ units across (found by the fuzzer, glTF).
                TriMesh {
                    positions: vec![Vec3::ZERO, Vec3::X * 1e-19, Vec3::Y * 1e-19],
                    triangles: vec![[0, 1, 2]],
                    ..Default::default()
                },
                MeshError::TooSmall { extent: 1e-19 },
            ),
            (
                TriMesh {
                    positions: quad.clone(),
                    triangles: vec![[0, 0, 1], [1, 1, 1]],
                    ..Default::default()
                },
                MeshError::AllTrianglesDegenerate,
            ),
        ];
        for (mesh, expected) in cases {
            assert_eq!(mesh.validate().unwrap_err(), expected);
            assert!(!expected.to_string().is_empty());
        }
        assert_eq!(
            TriMesh::from_indices(quad, &[0, 1]).unwrap_err(),
            MeshError::IndexCountNotMultipleOfThree(2)
        );
    }

    #[test]
    fn topologies_form_consistently_wound_triangles() {
        let i = [0, 1, 2, 3, 4];
        assert_eq!(triangles_from(&i, Topology::List), vec![[0, 1, 2]]);
        assert_eq!(
            triangles_from(&i, Topology::Strip),
            vec![[0, 1, 2], [2, 1, 3], [2, 3, 4]]
        );
        assert_eq!(
            triangles_from(&i, Topology::Fan),
            vec![[0, 1, 2], [0, 2, 3], [0, 3, 4]]
        );
        assert!(triangles_from(&i[..2], Topology::Fan).is_empty());
    }

    #[test]
    fn degenerate_triangles_are_dropped_and_counted() {
        let mesh = TriMesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::X * 2.0],
            triangles: vec![[0, 1, 2], [0, 1, 3], [2, 2, 2]],
            ..Default::default()
        };
        let (tris, report) = mesh.validate().unwrap();
        assert_eq!(tris.len(), 1);
        assert_eq!(
            report,
            MeshReport {
                triangles: 1,
                degenerate_dropped: 2
            }
        );
    }
}
