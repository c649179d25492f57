//! Exact ground truth in f64, by brute force over every triangle: the reference the
//! baker is tested and benchmarked against. O(triangles) per query — for tests only.

use glam::{DVec3, Vec3};

/// A triangle corner: f32 corners are promoted exactly.
pub trait Corner: Copy {
    /// The corner in f64.
    fn to_f64(self) -> DVec3;
}

impl Corner for Vec3 {
    fn to_f64(self) -> DVec3 {
        self.as_dvec3()
    }
}

impl Corner for DVec3 {
    fn to_f64(self) -> DVec3 {
        self
    }
}

fn closest_point_f64(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    // Ericson §5.1.5 in f64.
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

/// Exact unsigned distance from `p` to the nearest of `tris` (f64, brute force).
pub fn distance<T: Corner>(p: DVec3, tris: &[[T; 3]]) -> f64 {
    tris.iter()
        .map(|t| {
            let [a, b, c] = t.map(Corner::to_f64);
            (closest_point_f64(p, a, b, c) - p).length_squared()
        })
        .fold(f64::INFINITY, f64::min)
        .sqrt()
}

/// Exact generalized winding number at `p` (f64 solid angles, brute force).
pub fn winding_number<T: Corner>(p: DVec3, tris: &[[T; 3]]) -> f64 {
    tris.iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| v.to_f64() - p);
            let (la, lb, lc) = (a.length(), b.length(), c.length());
            let det = a.dot(b.cross(c));
            let div = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
            det.atan2(div)
        })
        .sum::<f64>()
        / (2.0 * std::f64::consts::PI)
}
