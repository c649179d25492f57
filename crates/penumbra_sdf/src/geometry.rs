//! Triangle primitives: closest point, solid angle, ray intersection.

use glam::{Vec3, Vec3A};

/// Which feature of a triangle a closest point lies on (used to pick pseudonormals and
/// to reason about ties at shared vertices and edges).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Feature {
    /// Vertex 0, 1 or 2.
    Vertex(u8),
    /// Edge 0 (v0–v1), 1 (v1–v2) or 2 (v2–v0).
    Edge(u8),
    /// The interior of the face.
    Face,
}

/// The point of triangle `(a, b, c)` closest to `p`, and the feature it lies on
/// (Ericson, *Real-Time Collision Detection*, §5.1.5). Degenerate triangles are handled
/// (the result is the closest point of the segment or point they collapse to).
#[inline]
pub fn closest_point_on_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> (Vec3, Feature) {
    let (q, f) = closest_point_on_triangle_a(p.into(), a.into(), b.into(), c.into());
    (q.into(), f)
}

/// [`closest_point_on_triangle`] on SIMD vectors (the BVH's hot path).
#[inline]
pub fn closest_point_on_triangle_a(p: Vec3A, a: Vec3A, b: Vec3A, c: Vec3A) -> (Vec3A, Feature) {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, Feature::Vertex(0));
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (b, Feature::Vertex(1));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let denom = d1 - d3;
        let v = if denom > 0.0 { d1 / denom } else { 0.0 };
        return (a + ab * v, Feature::Edge(0));
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (c, Feature::Vertex(2));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let denom = d2 - d6;
        let w = if denom > 0.0 { d2 / denom } else { 0.0 };
        return (a + ac * w, Feature::Edge(2));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let denom = (d4 - d3) + (d5 - d6);
        let w = if denom > 0.0 { (d4 - d3) / denom } else { 0.0 };
        return (b + (c - b) * w, Feature::Edge(1));
    }
    let sum = va + vb + vc;
    if sum.abs() <= f32::MIN_POSITIVE || !sum.is_finite() {
        // Degenerate (zero-area) triangle whose regions all failed: fall back to the
        // closest of its three edges.
        return closest_on_degenerate(p, a, b, c);
    }
    let denom = 1.0 / sum;
    let v = vb * denom;
    let w = vc * denom;
    (a + ab * v + ac * w, Feature::Face)
}

fn closest_on_segment(p: Vec3A, a: Vec3A, b: Vec3A) -> Vec3A {
    let ab = b - a;
    let len2 = ab.length_squared();
    if len2 <= 0.0 {
        return a;
    }
    a + ab * ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
}

fn closest_on_degenerate(p: Vec3A, a: Vec3A, b: Vec3A, c: Vec3A) -> (Vec3A, Feature) {
    let candidates = [
        (closest_on_segment(p, a, b), Feature::Edge(0)),
        (closest_on_segment(p, b, c), Feature::Edge(1)),
        (closest_on_segment(p, c, a), Feature::Edge(2)),
    ];
    candidates
        .into_iter()
        .min_by(|x, y| {
            (x.0 - p)
                .length_squared()
                .total_cmp(&(y.0 - p).length_squared())
        })
        .expect("three candidates")
}

/// Signed solid angle of triangle `(a, b, c)` seen from `p`, divided by 4π: the
/// triangle's contribution to the generalized winding number (Van Oosterom & Strackee
/// 1983). Positive when `p` is behind the triangle (on the side opposite to the normal
/// `(b − a) × (c − a)`), so a closed, outward-oriented mesh sums to 1 inside.
#[inline]
pub fn winding_contribution(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> f32 {
    winding_contribution_a(p.into(), a.into(), b.into(), c.into())
}

/// [`winding_contribution`] on SIMD vectors.
#[inline]
pub fn winding_contribution_a(p: Vec3A, a: Vec3A, b: Vec3A, c: Vec3A) -> f32 {
    let a = a - p;
    let b = b - p;
    let c = c - p;
    let la = a.length();
    let lb = b.length();
    let lc = c.length();
    let det = a.dot(b.cross(c));
    let div = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    det.atan2(div) * (1.0 / (2.0 * std::f32::consts::PI))
}

/// Ray–triangle intersection (Möller–Trumbore). Returns `(t, front_facing)` for a hit at
/// `t ∈ (t_min, t_max)`; `front_facing` is true when the ray hits the side the normal
/// `(b − a) × (c − a)` points to.
#[inline]
pub fn ray_triangle(
    origin: Vec3,
    dir: Vec3,
    a: Vec3,
    b: Vec3,
    c: Vec3,
    t_min: f32,
    t_max: f32,
) -> Option<(f32, bool)> {
    ray_triangle_a(
        origin.into(),
        dir.into(),
        [a.into(), b.into(), c.into()],
        t_min,
        t_max,
    )
}

/// [`ray_triangle`] on SIMD vectors.
#[inline]
pub fn ray_triangle_a(
    origin: Vec3A,
    dir: Vec3A,
    [a, b, c]: [Vec3A; 3],
    t_min: f32,
    t_max: f32,
) -> Option<(f32, bool)> {
    let e1 = b - a;
    let e2 = c - a;
    let pv = dir.cross(e2);
    let det = e1.dot(pv);
    if det.abs() < 1e-12 {
        return None;
    }
    let inv = 1.0 / det;
    let tv = origin - a;
    let u = tv.dot(pv) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qv = tv.cross(e1);
    let v = dir.dot(qv) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(qv) * inv;
    (t > t_min && t < t_max).then_some((t, det > 0.0))
}

/// Axis-aligned bounding box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
}

impl Aabb {
    /// The empty box (grows to fit the first point).
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    /// Grows the box to contain `p`.
    #[inline]
    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// The union of two boxes.
    #[inline]
    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    /// Size along each axis (negative for the empty box).
    #[inline]
    pub fn size(&self) -> Vec3 {
        self.max - self.min
    }

    /// Centre.
    #[inline]
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Half the surface area (the SAH cost measure); 0 for the empty box.
    #[inline]
    pub fn half_area(&self) -> f32 {
        let s = self.size().max(Vec3::ZERO);
        s.x * s.y + s.y * s.z + s.z * s.x
    }

    /// Squared distance from `p` to the box (0 inside).
    #[inline]
    pub fn distance_squared(&self, p: Vec3) -> f32 {
        let d = (self.min - p).max(p - self.max).max(Vec3::ZERO);
        d.length_squared()
    }

    /// Ray slab test: whether the ray hits the box within `(t_min, t_max)`.
    #[inline]
    pub fn hit_by_ray(&self, origin: Vec3, inv_dir: Vec3, t_min: f32, t_max: f32) -> bool {
        let t0 = (self.min - origin) * inv_dir;
        let t1 = (self.max - origin) * inv_dir;
        let near = t0.min(t1).max_element().max(t_min);
        let far = t0.max(t1).min_element().min(t_max);
        near <= far
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// f64 brute force: closest point by dense sampling of barycentric coordinates is too
    /// slow; instead check the defining property: no point of the triangle is closer.
    #[test]
    fn closest_point_is_no_farther_than_any_triangle_point() {
        let (a, b, c) = (
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.5, 1.5, 0.3),
        );
        let mut seed = 1u32;
        let mut rnd = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1u32 << 24) as f32 * 6.0 - 3.0
        };
        for _ in 0..2000 {
            let p = Vec3::new(rnd(), rnd(), rnd());
            let (q, _) = closest_point_on_triangle(p, a, b, c);
            let d = (q - p).length();
            for i in 0..=20 {
                for j in 0..=(20 - i) {
                    let (u, v) = (i as f32 / 20.0, j as f32 / 20.0);
                    let s = a + (b - a) * u + (c - a) * v;
                    assert!(
                        d <= (s - p).length() + 1e-5,
                        "p {p}: {d} > {}",
                        (s - p).length()
                    );
                }
            }
        }
    }

    #[test]
    fn features_are_reported() {
        let (a, b, c) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        assert_eq!(
            closest_point_on_triangle(Vec3::new(-1.0, -1.0, 0.0), a, b, c).1,
            Feature::Vertex(0)
        );
        assert_eq!(
            closest_point_on_triangle(Vec3::new(0.5, -1.0, 0.0), a, b, c).1,
            Feature::Edge(0)
        );
        assert_eq!(
            closest_point_on_triangle(Vec3::new(1.0, 1.0, 0.0), a, b, c).1,
            Feature::Edge(1)
        );
        assert_eq!(
            closest_point_on_triangle(Vec3::new(-1.0, 0.5, 0.0), a, b, c).1,
            Feature::Edge(2)
        );
        assert_eq!(
            closest_point_on_triangle(Vec3::new(0.2, 0.2, 1.0), a, b, c).1,
            Feature::Face
        );
    }

    #[test]
    fn degenerate_triangles_do_not_produce_nan() {
        let p = Vec3::new(0.3, 0.7, -0.2);
        for (a, b, c) in [
            (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO),
            (Vec3::ZERO, Vec3::X, Vec3::X * 2.0),
            (Vec3::ZERO, Vec3::ZERO, Vec3::Y),
        ] {
            let (q, _) = closest_point_on_triangle(p, a, b, c);
            assert!(q.is_finite(), "{q}");
            assert!(winding_contribution(p, a, b, c).abs() < 1e-6);
        }
    }

    #[test]
    fn solid_angles_of_a_closed_tetrahedron_sum_to_one_inside_zero_outside() {
        let v = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        ];
        // Outward-oriented faces.
        let faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        let w = |p: Vec3| -> f32 {
            faces
                .iter()
                .map(|f| winding_contribution(p, v[f[0]], v[f[1]], v[f[2]]))
                .sum()
        };
        assert!((w(Vec3::splat(0.2)) - 1.0).abs() < 1e-5);
        assert!(w(Vec3::splat(2.0)).abs() < 1e-5);
        assert!(w(Vec3::new(-0.3, 0.2, 0.1)).abs() < 1e-5);
    }

    #[test]
    fn ray_hits_report_distance_and_facing() {
        let (a, b, c) = (Vec3::ZERO, Vec3::X, Vec3::Y); // normal +Z
        let down = ray_triangle(Vec3::new(0.2, 0.2, 2.0), -Vec3::Z, a, b, c, 0.0, 10.0);
        assert_eq!(down.map(|h| h.1), Some(true));
        assert!((down.unwrap().0 - 2.0).abs() < 1e-6);
        let up = ray_triangle(Vec3::new(0.2, 0.2, -1.0), Vec3::Z, a, b, c, 0.0, 10.0);
        assert_eq!(up.map(|h| h.1), Some(false));
        assert!(ray_triangle(Vec3::new(0.8, 0.8, 2.0), -Vec3::Z, a, b, c, 0.0, 10.0).is_none());
        assert!(ray_triangle(Vec3::new(0.2, 0.2, 2.0), -Vec3::Z, a, b, c, 0.0, 1.0).is_none());
    }
}
