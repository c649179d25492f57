//! Tessellation factors: an edge's segment count from its bounding sphere's projected
//! diameter, levels and morphs, and the bias that fits the output pool.

use super::MAX_BIAS;
use super::layout::Counts;
use encase::ShaderType;
use glam::{Mat4, Vec3};

/// The camera the factors are computed for, in world space.
#[derive(ShaderType, Clone, Copy, Debug, PartialEq)]
pub struct TessellationView {
    /// Camera position (world).
    pub position: Vec3,
    /// Pixels per world unit at distance 1 (perspective: `½ · height · clip_from_view[1][1]`)
    /// or at any distance (orthographic: the same product).
    pub pixels_per_unit: f32,
    /// 1 for an orthographic projection (no division by distance).
    pub orthographic: u32,
}

impl TessellationView {
    /// The view of a camera at `world_from_view` with projection `clip_from_view`,
    /// rendering `height` pixels.
    pub fn new(world_from_view: Mat4, clip_from_view: Mat4, height: f32) -> Self {
        let orthographic = clip_from_view.w_axis.w == 1.0;
        Self {
            position: world_from_view.w_axis.truncate(),
            pixels_per_unit: 0.5 * height * clip_from_view.y_axis.y,
            orthographic: orthographic as u32,
        }
    }

    /// Projected diameter, in pixels, of the sphere of diameter `diameter` at `centre`.
    pub fn projected_diameter(&self, centre: Vec3, diameter: f32) -> f32 {
        if self.orthographic == 1 {
            diameter * self.pixels_per_unit
        } else {
            diameter * self.pixels_per_unit / (centre - self.position).length().max(1e-4)
        }
    }
}

/// The factor of an edge from `a` to `b` (world, in the edge's canonical order): its
/// bounding sphere's projected diameter over `pixels_per_triangle`, in `[1, 2^max_level]`
/// (1 for a non-finite result).
pub fn edge_factor(
    view: &TessellationView,
    a: Vec3,
    b: Vec3,
    pixels_per_triangle: f32,
    max_level: u32,
) -> f32 {
    let centre = (a + b) * 0.5;
    let px = view.projected_diameter(centre, (b - a).length());
    let f = px / pixels_per_triangle;
    if f.is_finite() {
        f.clamp(1.0, (1u32 << max_level) as f32)
    } else {
        1.0
    }
}

/// `factor` halved `bias` times, at least 1 (exact: a power of two); 1 at
/// [`UNTESSELLATED_BIAS`](super::UNTESSELLATED_BIAS) and beyond.
pub fn biased(factor: f32, bias: u32) -> f32 {
    if bias >= super::UNTESSELLATED_BIAS {
        return 1.0;
    }
    (factor / (1u32 << bias) as f32).max(1.0)
}

/// The output patches with edge factors `factors` need at each bias `0..MAX_BIAS`
/// (vertices, indices).
pub fn demand(factors: impl Iterator<Item = [f32; 3]>) -> [(u64, u64); MAX_BIAS as usize] {
    let mut out = [(0, 0); MAX_BIAS as usize];
    for f in factors {
        for (b, o) in out.iter_mut().enumerate() {
            let counts = Counts::new(f.map(|x| biased(x, b as u32)));
            o.0 += u64::from(counts.vertices());
            o.1 += 3 * u64::from(counts.triangles());
        }
    }
    out
}

/// The smallest bias whose demand fits `(vertex_budget, index_budget)`; the largest if
/// none does (it fits any pool of 3 vertices and 3 indices per patch, which the plugin's
/// always is).
pub fn choose_bias(
    demand: &[(u64, u64); MAX_BIAS as usize],
    vertex_budget: u64,
    index_budget: u64,
) -> u32 {
    demand
        .iter()
        .position(|&(v, i)| v <= vertex_budget && i <= index_budget)
        .unwrap_or(MAX_BIAS as usize - 1) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sphere_measures_an_edge_seen_end_on() {
        let view = TessellationView::new(
            Mat4::IDENTITY,
            Mat4::perspective_rh(1.0, 1.0, 0.1, 100.0),
            512.0,
        );
        // An edge along the view axis, 10 units away, 1 unit long: the same factor as
        // across it.
        let along = edge_factor(
            &view,
            Vec3::new(0.0, 0.0, -9.5),
            Vec3::new(0.0, 0.0, -10.5),
            1.0,
            6,
        );
        let across = edge_factor(
            &view,
            Vec3::new(-0.5, 0.0, -10.0),
            Vec3::new(0.5, 0.0, -10.0),
            1.0,
            6,
        );
        assert_eq!(along, across);
        let px = 512.0 * 0.5 / (0.5f32).tan() / 10.0;
        assert!((across - px).abs() < 1e-3 * px, "{across} {px}");
        assert_eq!(edge_factor(&view, Vec3::NAN, Vec3::X, 1.0, 6), 1.0);
    }

    #[test]
    fn the_bias_is_the_least_that_fits() {
        let d = demand([[5.0; 3], [5.0; 3], [1.0; 3]].into_iter());
        // n = 5: 15 + 3·2² vertices, 15 + 9 + 12 + 1 triangles; n = 1: 3 and 1.
        assert_eq!(d[0], (27 + 27 + 3, 3 * (37 + 37 + 1)));
        assert_eq!(choose_bias(&d, 1000, 1000), 0);
        assert_eq!(choose_bias(&d, 50, 1000), 1);
        assert_eq!(choose_bias(&d, 0, 0), MAX_BIAS - 1);
        // The last bias: every patch its input triangle (3 vertices, 3 indices), which
        // a pool of the input's size holds; /8 (factors 5 → 1) would too here, but a
        // factor of 64 halved three times is still 8.
        assert_eq!(d[MAX_BIAS as usize - 1], (9, 9));
        assert_eq!(biased(64.0, MAX_BIAS - 2), 8.0);
        assert_eq!(biased(64.0, MAX_BIAS - 1), 1.0);
        let d = demand([[64.0; 3]].into_iter());
        assert!(d[MAX_BIAS as usize - 2].0 > 3);
        assert_eq!(choose_bias(&d, 3, 3), MAX_BIAS - 1);
    }
}
