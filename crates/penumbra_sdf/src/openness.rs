//! How open a surface is, to choose between a solid bake and a two-sided shell.
//!
//! The **open index** is the length of the surface's boundary (edges used by one
//! triangle, after welding equal positions) over the square root of its area: a
//! dimensionless figure, 0 for a closed mesh. By the isoperimetric inequality any flat
//! sheet scores at least 2√π ≈ 3.54 (a disc; a square scores 4), and curved open sheets
//! score about as much or more, while a closed surface with a few holes scores far less.
//! Measured on `../shared/scenes` (per glTF primitive): nearly closed parts 0.43–0.67
//! (`FlightHelmet`'s hose, metal and rubber parts, the barn lamp's metal and glass), open
//! sheets 3.99–19.6 (the terrain, the palm tree's island, the Cornell box's walls, the
//! flat letters of `faces.glb`, the Kenney props' open pieces before merging).
//! [`NEARLY_CLOSED_OPEN_INDEX`] sits between the two groups (their geometric middle).

use glam::Vec3;
use std::collections::HashMap;

/// Surfaces scoring at most this are nearly closed: a solid bake signs them well.
pub const NEARLY_CLOSED_OPEN_INDEX: f32 = 1.5;

/// The open index of a triangle list (`indices`, three per triangle, into `positions`):
/// boundary length over √area, 0 when closed. Positions are welded on a grid of 10⁻⁵ of
/// the mesh's size (seams whose positions differ by rounding are one vertex); edges used
/// by three or more triangles are not boundary. Infinite for no triangles, zero area,
/// or an index out of range.
pub fn open_index(positions: &[Vec3], indices: &[u32]) -> f32 {
    if indices.len() < 3 || positions.iter().any(|p| !p.is_finite()) {
        return f32::INFINITY;
    }
    let (lo, hi) = positions
        .iter()
        .fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
    let cell = ((hi - lo).max_element() * 1e-5).max(f32::MIN_POSITIVE);
    let mut welded: HashMap<[i64; 3], u32> = HashMap::new();
    let mut first = Vec::new();
    let ids: Vec<u32> = positions
        .iter()
        .map(|p| {
            let key = p.to_array().map(|c| (c / cell).round() as i64);
            let next = welded.len() as u32;
            *welded.entry(key).or_insert_with(|| {
                first.push(*p);
                next
            })
        })
        .collect();
    let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
    let mut area = 0.0f64;
    for t in indices.chunks_exact(3) {
        let Some(t) = t
            .iter()
            .map(|&i| ids.get(i as usize).copied())
            .collect::<Option<Vec<u32>>>()
        else {
            return f32::INFINITY;
        };
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| first[i as usize].as_dvec3());
        area += 0.5 * (b - a).cross(c - a).length();
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            if a != b {
                *edges.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
    }
    if area.is_nan() || area <= 0.0 {
        return f32::INFINITY;
    }
    let boundary: f64 = edges
        .iter()
        .filter(|&(_, &n)| n == 1)
        .map(|(&(a, b), _)| f64::from(first[a as usize].distance(first[b as usize])))
        .sum();
    (boundary / area.sqrt()) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes;

    fn index_of(mesh: &crate::TriMesh) -> f32 {
        let flat: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
        open_index(&mesh.positions, &flat)
    }

    #[test]
    fn closed_meshes_score_zero_and_sheets_at_least_two_root_pi() {
        assert_eq!(index_of(&shapes::cuboid(Vec3::splat(0.5))), 0.0);
        assert_eq!(index_of(&shapes::torus(0.5, 0.2, 24, 12)), 0.0);
        // A unit square: boundary 4 over √1.
        let square = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        let quad = open_index(&square, &[0, 1, 2, 0, 2, 3]);
        assert!((quad - 4.0).abs() < 1e-5, "{quad}");
        // A fine disc approaches the isoperimetric bound 2√π.
        let n = 256;
        let mut disc = vec![Vec3::ZERO];
        disc.extend((0..n).map(|i| {
            let a = std::f32::consts::TAU * i as f32 / n as f32;
            Vec3::new(a.cos(), a.sin(), 0.0)
        }));
        let fan: Vec<u32> = (0..n as u32)
            .flat_map(|i| [0, 1 + i, 1 + (i + 1) % n as u32])
            .collect();
        let d = open_index(&disc, &fan);
        assert!((d - 2.0 * std::f32::consts::PI.sqrt()).abs() < 0.01, "{d}");
        // A box without its lid is open (a lidless crate: boundary 4 over √5).
        let cube = shapes::cuboid(Vec3::splat(0.5));
        let mut tris: Vec<u32> = cube.triangles.iter().flatten().copied().collect();
        let lid: Vec<usize> = cube
            .triangles
            .iter()
            .enumerate()
            .filter(|(_, t)| t.iter().all(|&i| cube.positions[i as usize].z > 0.0))
            .map(|(k, _)| k)
            .collect();
        assert_eq!(lid.len(), 2);
        for k in lid.into_iter().rev() {
            tris.drain(3 * k..3 * k + 3);
        }
        let crate_ = open_index(&cube.positions, &tris);
        assert!((crate_ - 4.0 / 5f32.sqrt()).abs() < 1e-4, "{crate_}");
        assert!(crate_ > NEARLY_CLOSED_OPEN_INDEX);
    }

    #[test]
    fn a_sphere_with_a_small_hole_is_nearly_closed_and_bad_input_is_open() {
        // Remove one triangle at a UV sphere's equator: a small hole.
        let sphere = shapes::sphere(1.0, 32, 16);
        let mut tris: Vec<u32> = sphere.triangles.iter().flatten().copied().collect();
        let k = tris.len() / 6 * 3;
        tris.drain(k..k + 3);
        let holed = open_index(&sphere.positions, &tris);
        // Three edges of about 0.2 over √(4π).
        assert!(holed > 0.1 && holed < 0.3, "{holed}");
        assert!(holed <= NEARLY_CLOSED_OPEN_INDEX);
        // Nothing, zero area, an index out of range, NaN: open.
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y];
        assert_eq!(open_index(&p, &[]), f32::INFINITY);
        assert_eq!(open_index(&p, &[0, 0, 0]), f32::INFINITY);
        assert_eq!(open_index(&p, &[0, 1, 9]), f32::INFINITY);
        assert_eq!(
            open_index(&[Vec3::NAN, Vec3::X, Vec3::Y], &[0, 1, 2]),
            f32::INFINITY
        );
    }
}
