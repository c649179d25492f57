//! Screen-tile culling of the billboards: per tile of the trace's pixels, the billboards
//! some pixel's reflection could meet, so the trace tests those instead of every one.
//!
//! A tile is bounded by a sphere around its pixels' positions, a cone around their mirror
//! directions and the largest footprint spread (`|major| + |minor|` per metre travelled)
//! among them ([`TileBounds`]). [`tile_keeps`] is conservative: it keeps every billboard
//! that [`super::pass::footprint_hit`] could accept for any ray from the sphere, along
//! the cone, with at most that spread — so culling never changes the image, only the work.
//! A billboard is dropped when
//! - every point of the sphere lies on its back side (it is one-sided);
//! - every direction of the cone runs parallel to or away from its front;
//! - the sphere is farther from its plane than `max_distance`;
//! - no ray of the cone comes near it: the accepted hits lie within `R + E` of its centre
//!   (`R` its bounding radius; `E` the footprint's reach on its plane, at most
//!   `2 √2 w / (f sin φ)` for a cross-section of half-width `w = spread · t`, the smallest
//!   facing `f` of the cone on its plane, `φ` the angle between its axes), and the cone,
//!   widened by the sphere's radius, misses that ball.

use glam::Vec3;

use super::pass::GpuBillboard;

/// Trace pixels per tile side.
pub const TILE: u32 = 16;

/// What a tile's pixels can reflect from: their positions, mirror directions and
/// footprint spreads, bounded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TileBounds {
    /// Centre of a sphere holding every pixel's position.
    pub center: Vec3,
    /// Its radius, metres.
    pub radius: f32,
    /// Axis of a cone holding every pixel's mirror direction (unit).
    pub axis: Vec3,
    /// The cosine of the cone's half-angle (−1: every direction).
    pub cos_angle: f32,
    /// The largest `|major| + |minor|` among the pixels (footprint half-width per metre).
    pub spread: f32,
}

impl TileBounds {
    /// The bounds of a tile's pixels `(position, mirror direction, spread)`; `None` when
    /// it has none (the sky). The sphere is the positions' box's circumsphere; the cone's
    /// axis is the normalised sum of the directions (every direction when that sum
    /// vanishes), its angle the widest of them.
    pub fn from_pixels(
        pixels: impl IntoIterator<Item = (Vec3, Vec3, f32)> + Clone,
    ) -> Option<Self> {
        let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
        let (mut sum, mut spread, mut any) = (Vec3::ZERO, 0.0f32, false);
        for (p, d, s) in pixels.clone() {
            lo = lo.min(p);
            hi = hi.max(p);
            sum += d;
            spread = spread.max(s);
            any = true;
        }
        if !any {
            return None;
        }
        let length = sum.length();
        let (axis, mut cos_angle) = if length > 1e-3 {
            (sum / length, 1.0f32)
        } else {
            (Vec3::Z, -1.0)
        };
        if cos_angle > -1.0 {
            for (_, d, _) in pixels {
                cos_angle = cos_angle.min(axis.dot(d));
            }
        }
        Some(TileBounds {
            center: (lo + hi) * 0.5,
            radius: (hi - lo).length() * 0.5,
            axis,
            // Rounding: a hair wider.
            cos_angle: (cos_angle - 1e-4).max(-1.0),
            spread,
        })
    }
}

/// Whether some pixel of a tile bounded by `b` could reflect `billboard` (module docs).
pub fn tile_keeps(b: &TileBounds, billboard: &GpuBillboard, max_distance: f32) -> bool {
    let quad = billboard.billboard();
    let cross = quad.half_x.cross(quad.half_y);
    let area = cross.length();
    if area.is_nan() || area <= 0.0 {
        return false;
    }
    let n = cross / area;
    // Signed distance of the sphere's centre from the plane (front positive).
    let plane = (b.center - quad.center).dot(n);
    if plane + b.radius <= 0.0 {
        return false; // all behind
    }
    if plane - b.radius > max_distance {
        return false; // every hit farther than max_distance
    }
    // The cone's directions against −n: hits need d·n < 0.
    let sin_angle = (1.0 - b.cos_angle * b.cos_angle).max(0.0).sqrt();
    let toward = -b.axis.dot(n); // cos of the axis against −n
    let toward_sin = (1.0 - toward * toward).max(0.0).sqrt();
    // The largest and smallest cos(d, −n) over the cone.
    let (max_facing, min_facing) = if b.cos_angle <= -1.0 {
        (1.0, -1.0)
    } else {
        let widest = toward * b.cos_angle + toward_sin * sin_angle; // cos(α − θ)
        let narrowest = toward * b.cos_angle - toward_sin * sin_angle; // cos(α + θ)
        let contains_minus_n = toward >= b.cos_angle;
        (if contains_minus_n { 1.0 } else { widest }, narrowest)
    };
    if max_facing <= 0.0 {
        return false; // parallel to or away from the front
    }
    // Angular test, when the footprint's reach on the plane is bounded.
    if min_facing <= 1e-3 || b.cos_angle <= -1.0 {
        return true;
    }
    let sin_phi = area / (quad.half_x.length() * quad.half_y.length());
    let t_max = ((plane + b.radius).max(0.0) / min_facing).min(max_distance);
    // |o'| ≤ √2 |o| / f for a cross-section offset o projected along the ray.
    let reach =
        2.0 * std::f32::consts::SQRT_2 * b.spread * t_max / (min_facing * sin_phi.max(1e-6));
    let ball = quad.half_x.length() + quad.half_y.length() + reach + b.radius;
    let v = quad.center - b.center;
    let dist = v.length();
    if dist <= ball {
        return true;
    }
    // The cone (half-angle θ) widened by the ball's angular radius.
    let cos_to = b.axis.dot(v) / dist;
    let sin_ball = ball / dist;
    let cos_ball = (1.0 - sin_ball * sin_ball).max(0.0).sqrt();
    // angle(axis, v) ≤ θ + β  ⟺  cos(angle) ≥ cos(θ + β) (when θ + β < π).
    let cos_sum = b.cos_angle * cos_ball - sin_angle * sin_ball;
    let sum_past_pi = b.cos_angle < 0.0 && cos_ball < 0.0;
    sum_past_pi || cos_to >= cos_sum - 1e-5
}

#[cfg(test)]
mod tests {
    use super::super::Billboard;
    use super::super::pass::{Lobe, footprint_hit};
    use super::*;
    use glam::{Mat4, Quat, Vec2};

    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            ((self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 40) as f32) / (1u64 << 24) as f32
        }
        fn signed(&mut self) -> f32 {
            2.0 * self.next() - 1.0
        }
        fn unit(&mut self) -> Vec3 {
            loop {
                let v = Vec3::new(self.signed(), self.signed(), self.signed());
                if v.length_squared() > 1e-3 && v.length_squared() <= 1.0 {
                    return v.normalize();
                }
            }
        }
    }

    /// Conservative: for random tiles and billboards, every ray drawn from a tile's
    /// bounds (a point in its sphere, a direction in its cone, a footprint within its
    /// spread) that `footprint_hit` accepts belongs to a billboard the tile keeps — and
    /// the test still drops most billboards.
    #[test]
    fn culling_keeps_every_billboard_a_ray_can_reach() {
        let mut rng = Rng(0x0123_4567_89ab_cdef);
        let (mut hits, mut kept, mut total) = (0, 0, 0);
        for _ in 0..400 {
            let center = Vec3::new(rng.signed(), rng.signed(), rng.signed()) * 5.0;
            let radius = 0.05 + 0.5 * rng.next();
            let axis = rng.unit();
            let angle = 0.4 * rng.next() * rng.next();
            // Wide footprints on small quads half the time: hits beside the quad.
            let spread = if rng.next() < 0.5 {
                0.3 * rng.next() * rng.next()
            } else {
                0.5 * rng.next()
            };
            let bounds = TileBounds {
                center,
                radius,
                axis,
                cos_angle: angle.cos(),
                spread,
            };
            for _ in 0..20 {
                let transform = Mat4::from_scale_rotation_translation(
                    Vec3::new(0.5 + rng.next(), 0.5 + rng.next(), 1.0),
                    Quat::from_axis_angle(rng.unit(), 6.0 * rng.next()),
                    center
                        + axis * (8.0 * rng.next())
                        + Vec3::new(rng.signed(), rng.signed(), rng.signed()) * 4.0,
                );
                let scale = if spread > 0.2 {
                    0.1 + 0.2 * rng.next()
                } else {
                    1.0
                };
                let quad =
                    Billboard::from_transform(transform, Vec2::new(1.0, 0.6) * scale).unwrap();
                let gpu = GpuBillboard {
                    center: quad.center,
                    layer: 0,
                    half_x: quad.half_x,
                    emissive: 1.0,
                    half_y: quad.half_y,
                    reserved: 0,
                };
                let keeps = tile_keeps(&bounds, &gpu, 30.0);
                total += 1;
                kept += usize::from(keeps);
                for _ in 0..200 {
                    // A point in the sphere, a direction in the cone.
                    let p = center + rng.unit() * radius * rng.next().cbrt();
                    let tilt = angle * rng.next().sqrt();
                    let side = rng.unit().cross(axis).normalize_or_zero();
                    let dir = (Quat::from_axis_angle(side, tilt) * axis).normalize();
                    let a = rng.unit().cross(dir).normalize_or_zero();
                    let bdir = dir.cross(a);
                    let share = rng.next();
                    let lobe = Lobe {
                        dir,
                        major: a * (spread * share),
                        minor: bdir * (spread * (1.0 - share)),
                    };
                    if footprint_hit(&quad, 0, p, &lobe, 30.0).is_some() {
                        hits += 1;
                        assert!(
                            keeps,
                            "a reachable billboard culled: {bounds:?} {gpu:?} ray {p} {dir}"
                        );
                    }
                }
            }
        }
        println!("culling: {kept} of {total} kept; {hits} sampled hits, all kept");
        assert!(hits > 1000, "{hits} hits sampled");
        assert!(kept * 2 < total, "culling keeps {kept} of {total}");
    }

    /// A wide footprint reaches a small billboard its mirror ray misses: kept; a narrow
    /// one does not: dropped.
    #[test]
    fn the_footprint_reaches_beside_the_ray() {
        // A small quad 5 m ahead, 0.6 m to the side, facing the tile.
        let quad = Billboard::from_transform(
            Mat4::from_translation(Vec3::new(0.6, 0.0, 5.0))
                * Mat4::from_rotation_y(std::f32::consts::PI),
            Vec2::splat(0.2),
        )
        .unwrap();
        let gpu = GpuBillboard {
            center: quad.center,
            layer: 0,
            half_x: quad.half_x,
            emissive: 1.0,
            half_y: quad.half_y,
            reserved: 0,
        };
        let tile = |spread: f32| TileBounds {
            center: Vec3::ZERO,
            radius: 0.01,
            axis: Vec3::Z,
            cos_angle: 1.0,
            spread,
        };
        let lobe = Lobe {
            dir: Vec3::Z,
            major: Vec3::X * 0.25,
            minor: Vec3::Y * 0.25,
        };
        assert!(footprint_hit(&quad, 0, Vec3::ZERO, &lobe, 30.0).is_some());
        assert!(tile_keeps(&tile(0.5), &gpu, 30.0));
        assert!(!tile_keeps(&tile(0.01), &gpu, 30.0));
        // Behind the tile, or beyond max_distance: dropped.
        assert!(!tile_keeps(&tile(0.5), &gpu, 4.0));
    }
}
