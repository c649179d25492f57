//! How thick a mesh's walls are: the *shape diameter* along one ray (Shapira et al.,
//! "Consistent mesh partitioning and skeletonisation using the shape diameter function",
//! 2008, with one ray instead of a cone), measured at triangle centroids and weighted by
//! area. A wall thinner than two voxels of a field is where a distance field loses its
//! inside: trilinear interpolation between samples that straddle a thin solid never
//! reaches the negative core, so light leaks through and a march steps past it (the
//! baker's thin-feature guard keeps one negative sample, not the wall's width).
//! [`crate::grid::ThinWalls`] uses [`wall_thickness_quantile`] to refine the grid of
//! meshes whose walls are thin.
//!
//! A wall's thickness at a triangle is the distance along the triangle's inward normal
//! (against its winding's normal) to the first surface the ray leaves the solid through
//! (a back face). A ray that meets nothing, or first enters a surface (an open sheet, an
//! inverted or overlapping part), measures no wall there: its area counts as thick.

use crate::bvh::Bvh;
use glam::Vec3;

/// At most this many triangles are measured (evenly strided through the mesh), so a
/// mesh of a million triangles costs as much as one of a few thousand.
pub const WALL_SAMPLES: usize = 4096;

/// The area-weighted `quantile` (0–1) of the wall thickness of triangles `tris` (with
/// their BVH `bvh`), in the triangles' units: the thickness below which that share of the
/// measured area lies. `None` when that share of the area measures no wall (open
/// sheets, inverted normals) or the mesh has no area. Deterministic.
pub fn wall_thickness_quantile(tris: &[[Vec3; 3]], bvh: &Bvh, quantile: f32) -> Option<f32> {
    if tris.is_empty() || !(0.0..=1.0).contains(&quantile) {
        return None;
    }
    let stride = tris.len().div_ceil(WALL_SAMPLES).max(1);
    let mut walls: Vec<(f32, f32)> = Vec::new();
    let mut total = 0.0f64;
    for t in tris.iter().step_by(stride) {
        let cross = (t[1] - t[0]).cross(t[2] - t[0]);
        let area = 0.5 * cross.length();
        if !(area > 0.0 && area.is_finite()) {
            continue;
        }
        total += f64::from(area);
        let inward = -cross.normalize();
        let centroid = (t[0] + t[1] + t[2]) / 3.0;
        // Start past the triangle itself (relative to its size and position).
        let t_min = 1e-4 * (area.sqrt() + centroid.abs().max_element() * 1e-2);
        if let Some((distance, front, _)) = bvh.ray_nearest(centroid, inward, t_min, f32::MAX)
            && !front
        {
            walls.push((distance, area));
        }
    }
    if total <= 0.0 {
        return None;
    }
    walls.sort_by(|a, b| a.0.total_cmp(&b.0));
    let wanted = f64::from(quantile) * total;
    let mut area = 0.0f64;
    for (distance, a) in walls {
        area += f64::from(a);
        if area >= wanted {
            return Some(distance);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes;

    fn tris(mesh: &crate::TriMesh) -> Vec<[Vec3; 3]> {
        mesh.triangles
            .iter()
            .map(|t| t.map(|i| mesh.positions[i as usize]))
            .collect()
    }

    /// A plate 2 cm thick measures 2 cm at any quantile its faces dominate; a sphere of
    /// radius 1 measures chords (2 cos θ of the triangles' inward rays: about 2); an open
    /// quad and an inverted plate measure no wall.
    #[test]
    fn walls_measure_their_thickness() {
        let plate = tris(&shapes::thin_plate(1.0, 1.0, 0.02));
        let bvh = Bvh::build(&plate);
        let t = wall_thickness_quantile(&plate, &bvh, 0.1).expect("a wall");
        assert!((t - 0.02).abs() < 1e-4, "{t}");
        // The rim (4 % of the area) measures the plate's width: past the faces' share.
        let t = wall_thickness_quantile(&plate, &bvh, 0.99).expect("a wall");
        assert!(t > 0.5, "{t}");

        let sphere = tris(&shapes::sphere(1.0, 48, 24));
        let bvh = Bvh::build(&sphere);
        let t = wall_thickness_quantile(&sphere, &bvh, 0.5).expect("a wall");
        assert!((t - 2.0).abs() < 0.02, "{t}");

        let inverted: Vec<[Vec3; 3]> = plate.iter().map(|t| [t[0], t[2], t[1]]).collect();
        let bvh = Bvh::build(&inverted);
        assert_eq!(wall_thickness_quantile(&inverted, &bvh, 0.1), None);

        let quad = vec![
            [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 0.0, 1.0)],
            [Vec3::ZERO, Vec3::new(1.0, 0.0, 1.0), Vec3::Z],
        ];
        let bvh = Bvh::build(&quad);
        assert_eq!(wall_thickness_quantile(&quad, &bvh, 0.1), None);
        assert_eq!(wall_thickness_quantile(&[], &bvh, 0.1), None);
    }
}
