//! A thin crossing: where a shadow march went through a thin part (a leaf, a wall) and
//! out by the opposite face ([`THIN_CROSSING_COSINE`](super::THIN_CROSSING_COSINE)),
//! the distance says nothing of how far the part reaches across the cone; the field a
//! little way out in the part's plane does. The cone's section meets a part tilted to
//! the light in an ellipse, `1 / |n · l|` longer along the light's trace in the part's
//! plane, so the rim is read that far along it (a palm frond seen by a low sun).

use glam::Vec3;

/// How far a grazing crossing's rim reaches along the light's direction, at most, in
/// cone radii: [`thin_crossing_rim`] stretches its second pair of points by
/// `1 / |n · l|` up to this (the cone's section meets a part tilted to the light in an
/// ellipse that long).
pub const THIN_CROSSING_MAX_STRETCH: f32 = 4.0;

/// Where a march crossed a thin part (a leaf, a wall:
/// [`THIN_CROSSING_COSINE`](super::THIN_CROSSING_COSINE)), how much of the cone the
/// part covers, as a ratio for [`penumbra_visibility`](super::penumbra_visibility):
/// `rim` the field distances at [`thin_crossing_rim`]'s four points (the first two a
/// radius `cone` across the light, the last two `stretch` radii along it). A point `rim` beyond
/// the part's edge puts the edge `1 − rim / reach` of the way out along its direction;
/// the part covers the slab between the two edges of each pair, and the disc's share of
/// the two slabs' crossing is the covered fraction. NaN: covered.
pub fn thin_crossing_ratio(rim: [f32; 4], cone: f32, stretch: f32) -> f32 {
    if rim.iter().any(|r| r.is_nan()) || cone.is_nan() || cone <= 0.0 {
        return -1.0;
    }
    let reach = [cone, cone, cone * stretch, cone * stretch];
    let e: [f32; 4] = std::array::from_fn(|i| (1.0 - rim[i] / reach[i]).clamp(0.0, 1.0));
    let covered = disc_slab(e[0], e[1]) * disc_slab(e[2], e[3]);
    visibility_ratio(1.0 - covered).clamp(-1.0, 0.0)
}

/// The share of a unit disc's area between `x = −b` and `x = a` (`a, b` in `[0, 1]`).
pub fn disc_slab(a: f32, b: f32) -> f32 {
    let f = |x: f32| {
        let x = x.clamp(-1.0, 1.0);
        (x.asin() + x * (1.0 - x * x).max(0.0).sqrt()) / std::f32::consts::PI
    };
    (f(a) - f(-b)).clamp(0.0, 1.0)
}

/// The ratio whose [`penumbra_visibility`](super::penumbra_visibility) is `v` (the
/// inverse smoothstep).
pub fn visibility_ratio(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    let t = 0.5 - ((1.0 - 2.0 * v).asin() / 3.0).sin();
    2.0 * t - 1.0
}

/// The four points [`thin_crossing_ratio`] reads about crossing point `x` in the plane
/// of the part whose normal where the ray went in is `normal_in`, and the stretch of the
/// second pair: a radius `cone` away across the light's direction `dir`, and
/// `min(1 / |n · l|, THIN_CROSSING_MAX_STRETCH)` radii away along its trace in the
/// plane.
pub fn thin_crossing_rim(x: Vec3, normal_in: Vec3, dir: Vec3, cone: f32) -> ([Vec3; 4], f32) {
    let across = normal_in.cross(dir);
    let (u, stretch) = if across.length_squared() > 1e-8 {
        let c = normal_in.dot(dir).abs();
        (
            across.normalize(),
            (1.0 / c.max(1e-6)).min(THIN_CROSSING_MAX_STRETCH),
        )
    } else {
        let a = if normal_in.y.abs() < 0.9 {
            Vec3::Y
        } else {
            Vec3::X
        };
        (normal_in.cross(a).normalize_or_zero(), 1.0)
    };
    let v = normal_in.cross(u);
    let s = cone * stretch;
    ([x + u * cone, x - u * cone, x + v * s, x - v * s], stretch)
}

#[cfg(test)]
mod tests {
    use super::super::penumbra_visibility;
    use super::*;

    #[test]
    fn the_rim_lies_in_the_part_stretched_along_the_light() {
        let cone = 0.2;
        let dir = Vec3::new(-1.0, -0.6, -0.5).normalize();
        for n in [Vec3::Y, Vec3::X, Vec3::new(0.6, 0.0, 0.8), -dir] {
            let (points, stretch) = thin_crossing_rim(Vec3::ONE, n, dir, cone);
            let want = (1.0 / n.dot(dir).abs()).min(THIN_CROSSING_MAX_STRETCH);
            assert!((stretch - want).abs() < 1e-5, "{n}: {stretch}");
            for (i, q) in points.into_iter().enumerate() {
                let e = q - Vec3::ONE;
                let reach = if i < 2 { cone } else { cone * stretch };
                assert!(e.dot(n).abs() < 1e-5, "{n} {q}");
                assert!((e.length() - reach).abs() < 1e-5, "{n} {q}");
                // The first pair lies square to the light.
                assert!(i >= 2 || e.dot(dir).abs() < 1e-5, "{n} {q}");
            }
        }
    }

    #[test]
    fn the_covered_share_of_the_disc() {
        let cone = 0.3;
        assert_eq!(
            thin_crossing_ratio([f32::NAN, 0.0, 0.0, 0.0], cone, 1.0),
            -1.0
        );
        assert_eq!(thin_crossing_ratio([0.0; 4], cone, 2.0), -1.0);
        assert_eq!(thin_crossing_ratio([cone; 4], cone, 1.0), 0.0);
        // An edge through the axis: half covered.
        let half = thin_crossing_ratio([cone, 0.0, 0.0, 0.0], cone, 1.0);
        assert!(half.abs() < 1e-5, "{half}");
        // The inverse of the penumbra's smoothstep.
        for v in [0.0, 0.1, 0.37, 0.5, 0.8, 1.0] {
            assert!(
                (penumbra_visibility(visibility_ratio(v)) - v).abs() < 1e-5,
                "{v}"
            );
        }
        assert!((disc_slab(1.0, 1.0) - 1.0).abs() < 1e-6 && disc_slab(0.0, 0.0) == 0.0);
    }

    fn basis(n: Vec3) -> (Vec3, Vec3) {
        let a = if n.y.abs() < 0.9 { Vec3::Y } else { Vec3::X };
        let u = n.cross(a).normalize();
        (u, n.cross(u))
    }

    /// Independent truth: a rectangular part in a plane tilted to the light, its
    /// coverage of the cone's section counted by rays (a disc of them, each carried
    /// along the light to the plane) against the estimate from the exact distance to
    /// the rectangle at the rim. Stretching the rim along the light is what makes a
    /// grazing part right: read a radius away (stretch 1), the estimate is far darker.
    #[test]
    fn a_tilted_rectangle_covers_the_cone_as_rays_say() {
        let mut seed = 7_u32;
        let mut rand = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1 << 24) as f32
        };
        let dir = Vec3::new(-1.0, -0.6, -0.5).normalize();
        let cone = 0.15;
        let (mut err, mut err_flat, mut worst, mut n_cases) = (0.0, 0.0, 0.0_f32, 0);
        for _ in 0..200 {
            // A normal 10°–90° from the light, the crossing at the origin.
            let tilt = (10.0 + 80.0 * rand()).to_radians();
            let spin = std::f32::consts::TAU * rand();
            let (a, b) = basis(dir);
            let n = (dir * tilt.cos() + (a * spin.cos() + b * spin.sin()) * tilt.sin()).normalize();
            let (u, _) = basis(n);
            let w = n.cross(u);
            // Edges 0–3 radii along a random frame in the plane, the origin inside.
            let turn = std::f32::consts::TAU * rand();
            let (p, q) = (
                u * turn.cos() + w * turn.sin(),
                n.cross(u * turn.cos() + w * turn.sin()),
            );
            let ext: [f32; 4] = std::array::from_fn(|_| 3.0 * cone * rand().powi(2));
            let distance = |x: Vec3| {
                let (s, t) = (x.dot(p), x.dot(q));
                let ds = (s - ext[0]).max(-ext[1] - s).max(0.0);
                let dt = (t - ext[2]).max(-ext[3] - t).max(0.0);
                (ds * ds + dt * dt).sqrt()
            };
            // Rays: the disc square to the light, carried along it to the plane.
            let (da, db) = basis(dir);
            let (mut hit, k) = (0, 32);
            for i in 0..k {
                for j in 0..k {
                    let (x, y) = (
                        2.0 * (i as f32 + 0.5) / k as f32 - 1.0,
                        2.0 * (j as f32 + 0.5) / k as f32 - 1.0,
                    );
                    if x * x + y * y > 1.0 {
                        continue;
                    }
                    let o = (da * x + db * y) * cone;
                    let at = o - dir * (o.dot(n) / dir.dot(n));
                    hit += usize::from(distance(at) == 0.0);
                }
            }
            let disc = (0..k * k)
                .filter(|m| {
                    let (x, y) = (
                        2.0 * ((m / k) as f32 + 0.5) / k as f32 - 1.0,
                        2.0 * ((m % k) as f32 + 0.5) / k as f32 - 1.0,
                    );
                    x * x + y * y <= 1.0
                })
                .count();
            let truth = 1.0 - hit as f32 / disc as f32;
            let estimate = |stretch_on: bool| {
                let (points, stretch) = thin_crossing_rim(Vec3::ZERO, n, dir, cone);
                if stretch_on {
                    penumbra_visibility(thin_crossing_ratio(points.map(distance), cone, stretch))
                } else {
                    let short = [
                        points[0],
                        points[1],
                        points[2] / stretch,
                        points[3] / stretch,
                    ];
                    penumbra_visibility(thin_crossing_ratio(short.map(distance), cone, 1.0))
                }
            };
            // A march leaves at most ½ where its axis crosses a part (the steps beside
            // the part read a distance of about 0).
            if truth > 0.5 {
                continue;
            }
            let e = (estimate(true) - truth).abs();
            err += e;
            err_flat += (estimate(false) - truth).abs();
            worst = worst.max(e);
            n_cases += 1;
        }
        let (mean, mean_flat) = (err / n_cases as f32, err_flat / n_cases as f32);
        assert!(mean < 0.06 && worst < 0.25, "mean {mean} worst {worst}");
        assert!(
            mean_flat > 1.5 * mean,
            "stretched {mean}, a radius away {mean_flat}"
        );
    }
}
