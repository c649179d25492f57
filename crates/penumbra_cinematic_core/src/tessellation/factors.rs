//! Tessellation factors: an edge's segment count from its bounding sphere's projected
//! diameter, levels and morphs, and the bias that fits the output pool.

use super::{MAX_BIAS, Partitioning, grid_triangle_count, grid_vertex_count};
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
/// bounding sphere's projected diameter over `√2 · pixels_per_triangle`, in
/// `[1, 2^max_level]` (1 for a non-finite result). The `√2` centres the power-of-two
/// rounding: an edge gets `2^⌈log₂ f⌉` segments, `0.71–1.41×` the target's count.
pub fn edge_factor(
    view: &TessellationView,
    a: Vec3,
    b: Vec3,
    pixels_per_triangle: f32,
    max_level: u32,
) -> f32 {
    let centre = (a + b) * 0.5;
    let px = view.projected_diameter(centre, (b - a).length());
    let f = px / (pixels_per_triangle * std::f32::consts::SQRT_2);
    if f.is_finite() {
        f.clamp(1.0, (1u32 << max_level) as f32)
    } else {
        1.0
    }
}

/// `factor` halved `bias` times, at least 1 (exact: a power of two).
pub fn biased(factor: f32, bias: u32) -> f32 {
    (factor / (1u32 << bias) as f32).max(1.0)
}

/// The level of factor `f ≥ 1` (`⌈log₂ f⌉`, exact at powers of two) and its morph: the
/// fraction, 0 to 1, of the way the level's new vertices have moved from their coarse
/// midpoints (1 for integer partitioning and for level 0).
pub fn level_of(f: f32, partitioning: Partitioning) -> (u32, f32) {
    let mut level = 0;
    while ((1u32 << level) as f32) < f && level < 31 {
        level += 1;
    }
    let morph = match partitioning {
        Partitioning::Fractional if level > 0 => {
            (f / (1u32 << (level - 1)) as f32 - 1.0).clamp(0.0, 1.0)
        }
        _ => 1.0,
    };
    (level, morph)
}

/// The output a set of patch levels needs at each bias `0..MAX_BIAS` (vertices,
/// indices), a level lowered by the bias down to 0.
pub fn demand(levels: impl Iterator<Item = u32>) -> [(u64, u64); MAX_BIAS as usize] {
    let mut out = [(0, 0); MAX_BIAS as usize];
    for level in levels {
        for (b, o) in out.iter_mut().enumerate() {
            let l = level.saturating_sub(b as u32);
            o.0 += u64::from(grid_vertex_count(l));
            o.1 += 3 * u64::from(grid_triangle_count(l));
        }
    }
    out
}

/// The smallest bias whose demand fits `(vertex_budget, index_budget)`; the largest if
/// none does (the caller checks that level 0 always fits).
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
    fn levels_are_exact_at_powers_of_two_and_morph_continuously() {
        assert_eq!(level_of(1.0, Partitioning::Fractional), (0, 1.0));
        assert_eq!(level_of(2.0, Partitioning::Fractional), (1, 1.0));
        assert_eq!(level_of(4.0, Partitioning::Fractional), (2, 1.0));
        let (l, m) = level_of(4.0001, Partitioning::Fractional);
        assert_eq!(l, 3);
        assert!(m < 1e-3);
        assert_eq!(level_of(3.0, Partitioning::Integer), (2, 1.0));
        // Segments 2^ℓ are within [f, 2f).
        for k in 0..1000 {
            let f = 1.0 + k as f32 * 0.063;
            let (l, _) = level_of(f, Partitioning::Integer);
            let s = (1u32 << l) as f32;
            assert!(s >= f && s < 2.0 * f, "{f} → {s}");
        }
    }

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
        let px = 512.0 * 0.5 / (0.5f32).tan() / 10.0 / std::f32::consts::SQRT_2;
        assert!((across - px).abs() < 1e-3 * px, "{across} {px}");
        assert_eq!(edge_factor(&view, Vec3::NAN, Vec3::X, 1.0, 6), 1.0);
    }

    #[test]
    fn the_bias_is_the_least_that_fits() {
        let d = demand([3, 3, 2].into_iter());
        assert_eq!(d[0], (45 + 45 + 15, 3 * (64 + 64 + 16)));
        assert_eq!(choose_bias(&d, 1000, 1000), 0);
        assert_eq!(choose_bias(&d, 50, 1000), 1);
        assert_eq!(choose_bias(&d, 0, 0), MAX_BIAS - 1);
    }
}
