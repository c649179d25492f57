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
//!
//! **Shadow casters.** With reflection shadows the tile also lists the objects some
//! pixel's shadow march could gather ([`tile_casters`]): a march ends at its last hit,
//! which lies at most [`tile_march_length`] along the ray (the farthest [`tile_reach`]
//! of the billboards the tile keeps), and gathers, per segment, the objects whose
//! bounding sphere comes within `cone · t` of it — so an object farther than
//! `r + cone · length` from every ray of the tile's sphere and cone is dropped
//! ([`tile_keeps_caster`]). Each pixel's march then gathers from its tile's list instead
//! of every object, with the same result; a segment that gathers more than
//! `MAX_SHADOW_CASTERS` marches the tile's list, not every object (its steps may then
//! differ in length, by objects too far to dim any hit).

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
    tile_reach(b, billboard, max_distance).is_some()
}

/// [`tile_keeps`], with a bound on how far along its ray a pixel of the tile meets
/// `billboard` (metres, at most `max_distance`); `None` when no pixel can reflect it.
/// A hit lies at most `(plane + radius) / f` along the ray (`f` the smallest facing of
/// the cone) and within `R + E` of the quad's centre, so at most `|v| + R + E + radius`
/// from the tile's centre.
pub fn tile_reach(b: &TileBounds, billboard: &GpuBillboard, max_distance: f32) -> Option<f32> {
    let quad = billboard.billboard();
    let cross = quad.half_x.cross(quad.half_y);
    let area = cross.length();
    if area.is_nan() || area <= 0.0 {
        return None;
    }
    let n = cross / area;
    // Signed distance of the sphere's centre from the plane (front positive).
    let plane = (b.center - quad.center).dot(n);
    if plane + b.radius <= 0.0 {
        return None; // all behind
    }
    if plane - b.radius > max_distance {
        return None; // every hit farther than max_distance
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
        return None; // parallel to or away from the front
    }
    // Angular test, when the footprint's reach on the plane is bounded.
    if min_facing <= 1e-3 || b.cos_angle <= -1.0 {
        return Some(max_distance);
    }
    let sin_phi = area / (quad.half_x.length() * quad.half_y.length());
    let t_max = ((plane + b.radius).max(0.0) / min_facing).min(max_distance);
    // |o'| ≤ √2 |o| / f for a cross-section offset o projected along the ray.
    let reach =
        2.0 * std::f32::consts::SQRT_2 * b.spread * t_max / (min_facing * sin_phi.max(1e-6));
    let ball = quad.half_x.length() + quad.half_y.length() + reach + b.radius;
    let v = quad.center - b.center;
    let dist = v.length();
    let farthest = t_max.min(dist + ball);
    if dist <= ball {
        return Some(farthest);
    }
    // The cone (half-angle θ) widened by the ball's angular radius.
    let cos_to = b.axis.dot(v) / dist;
    let sin_ball = ball / dist;
    let cos_ball = (1.0 - sin_ball * sin_ball).max(0.0).sqrt();
    // angle(axis, v) ≤ θ + β  ⟺  cos(angle) ≥ cos(θ + β) (when θ + β < π).
    let cos_sum = b.cos_angle * cos_ball - sin_angle * sin_ball;
    let sum_past_pi = b.cos_angle < 0.0 && cos_ball < 0.0;
    (sum_past_pi || cos_to >= cos_sum - 1e-5).then_some(farthest)
}

/// The farthest any pixel of a tile bounded by `b` meets one of `billboards` (metres,
/// [`tile_reach`] over those the tile keeps, widened a hair for rounding); 0 when it
/// keeps none. Its reflection-shadow marches end there.
pub fn tile_march_length(b: &TileBounds, billboards: &[GpuBillboard], max_distance: f32) -> f32 {
    let farthest = billboards
        .iter()
        .filter_map(|billboard| tile_reach(b, billboard, max_distance))
        .fold(0.0f32, f32::max);
    farthest * (1.0 + 1e-3)
}

/// The widest reflection-shadow cone of a tile's pixels (tangent of its half-angle): a
/// pixel's is `max(|major| · shadow_cone, shadow_softness)` and `|major|` is at most
/// the tile's spread.
pub fn tile_shadow_cone(b: &TileBounds, shadow_cone: f32, shadow_softness: f32) -> f32 {
    (b.spread * shadow_cone).max(shadow_softness)
}

/// Whether an object bounded by `sphere` (centre and radius, in the frame of `b`;
/// `None`: unbounded) may come within reach of a reflection-shadow march of a pixel of
/// the tile bounded by `b`: a march of length at most `length` along a ray from the
/// tile's sphere within its cone, whose cone is at most `cone` — the objects the
/// pixel's per-segment gather ([`super::pass::shadow_casters`]) can keep. Those lie
/// within `r + cone · length` of a point `o + d t` (`t ≤ length`), hence within
/// `ρ = r + cone · length + radius` of the point `c + d t` of the cone from the tile's
/// centre `c`: the object's centre is at most `length + ρ` from `c`, and at an angle to
/// the axis of at most the cone's half-angle plus `asin(ρ / |v|)`.
pub fn tile_keeps_caster(
    b: &TileBounds,
    sphere: Option<(Vec3, f32)>,
    length: f32,
    cone: f32,
) -> bool {
    let Some((center, r)) = sphere else {
        return true;
    };
    let reach = r + cone * length + b.radius;
    // 10× the pixels' slack (`pass::cull_slack`): rounding never drops an object.
    let reach = reach + reach * 1e-3 + 1e-3;
    let v = center - b.center;
    let dist = v.length();
    if dist <= reach {
        return true;
    }
    if dist > length + reach {
        return false;
    }
    if b.cos_angle <= -1.0 {
        return true;
    }
    let sin_angle = (1.0 - b.cos_angle * b.cos_angle).max(0.0).sqrt();
    let cos_to = b.axis.dot(v) / dist;
    let sin_ball = reach / dist;
    let cos_ball = (1.0 - sin_ball * sin_ball).max(0.0).sqrt();
    let cos_sum = b.cos_angle * cos_ball - sin_angle * sin_ball;
    let sum_past_pi = b.cos_angle < 0.0 && cos_ball < 0.0;
    sum_past_pi || cos_to >= cos_sum - 1e-5
}

/// A tile's list of shadow casters: the objects of `spheres` that [`tile_keeps_caster`]
/// keeps, ascending; `None` when more than `capacity` (the tile's pixels then gather from
/// every object). Empty when the marches have no length (the tile reflects nothing).
pub fn tile_casters(
    b: &TileBounds,
    spheres: &[Option<(Vec3, f32)>],
    length: f32,
    cone: f32,
    capacity: usize,
) -> Option<Vec<usize>> {
    let mut kept = Vec::new();
    if length.is_nan() || length <= 0.0 {
        return Some(kept);
    }
    for (i, sphere) in spheres.iter().enumerate() {
        if tile_keeps_caster(b, *sphere, length, cone) {
            if kept.len() == capacity {
                return None;
            }
            kept.push(i);
        }
    }
    Some(kept)
}

#[cfg(test)]
mod tests {
    use super::super::Billboard;
    use super::super::pass::{
        FOOTPRINT_SLOPE, Lobe, ReflectionUniform, ShadowCasters, Surface, footprint_hit, lobe,
        reflect_pixel, reflect_pixel_in_tile, reflect_pixel_shadowed,
    };
    use super::super::texture::MipChain;
    use super::*;
    use glam::{Mat4, Quat, UVec2, Vec2, Vec4};

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
                let gpu = GpuBillboard::new(&quad, 0, 1.0);
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
        let gpu = GpuBillboard::new(&quad, 0, 1.0);
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

    /// A floor patch of `pixels` seen from `eye`: each pixel's surface, lobe and its
    /// tile's bounds.
    fn floor_tile(
        rng: &mut Rng,
        eye: Vec3,
        patch: Vec3,
        size: f32,
        roughness: f32,
    ) -> (Vec<Surface>, TileBounds) {
        let surfaces: Vec<Surface> = (0..64)
            .map(|_| {
                let position = patch + Vec3::new(rng.signed(), 0.0, rng.signed()) * size;
                Surface {
                    position,
                    normal: (Vec3::Y + Vec3::new(rng.signed(), 0.0, rng.signed()) * 0.05)
                        .normalize(),
                    view: (eye - position).normalize(),
                    perceptual_roughness: roughness * (0.5 + 0.5 * rng.next()),
                }
            })
            .collect();
        let lobes: Vec<(Vec3, Vec3, f32)> = surfaces
            .iter()
            .map(|s| {
                let l = lobe(s, 0.0, FOOTPRINT_SLOPE);
                (s.position, l.dir, l.major.length() + l.minor.length())
            })
            .collect();
        let bounds = TileBounds::from_pixels(lobes.iter().copied()).expect("pixels");
        (surfaces, bounds)
    }

    /// A tile's caster list holds every object its pixels' marches gather: for random
    /// floor tiles, signs and sphere casters strewn along the mirror rays, each pixel's
    /// reflection (shadows included) is the same bits with the tile's list as with every
    /// object — and the list leaves out most of the objects.
    #[test]
    fn tile_caster_lists_change_no_pixel() {
        let mut rng = Rng(0x005e_ed0f_ca57);
        let (mut listed, mut total, mut shadowed, mut pixels) = (0usize, 0usize, 0usize, 0usize);
        let images = [MipChain::from_straight_alpha(1, 1, &[Vec4::ONE])];
        for _ in 0..60 {
            let eye = Vec3::new(rng.signed() * 4.0, 2.0 + 4.0 * rng.next(), 12.0);
            let patch = Vec3::new(rng.signed() * 6.0, 0.0, rng.signed() * 6.0);
            // Small tiles (far or dense pixels) and large ones.
            let size = if rng.next() < 0.5 {
                0.02 + 0.1 * rng.next()
            } else {
                0.2 + 0.5 * rng.next()
            };
            let roughness = 0.6 * rng.next();
            let (surfaces, bounds) = floor_tile(&mut rng, eye, patch, size, roughness);
            // Signs across the mirror rays, 4–20 m on.
            let billboards: Vec<GpuBillboard> = (0..3)
                .map(|_| {
                    let t = 4.0 + 16.0 * rng.next();
                    let at = bounds.center + bounds.axis * t;
                    // Turned up to 45° off facing the tile: hits beyond the centre's distance.
                    let tilt = Quat::from_axis_angle(rng.unit(), 0.8 * rng.next());
                    let quad = Billboard::from_transform(
                        Mat4::from_translation(at)
                            * Mat4::from_quat(
                                tilt * Quat::from_rotation_arc(Vec3::Z, -bounds.axis),
                            ),
                        Vec2::new(3.0 + 4.0 * rng.next(), 2.0 + 2.0 * rng.next()),
                    )
                    .expect("a quad");
                    GpuBillboard::new(&quad, 0, 1.0)
                })
                .collect();
            // 30 spheres: near some pixel's mirror ray or anywhere around it.
            let spheres: Vec<Option<(Vec3, f32)>> = (0..30)
                .map(|_| {
                    let s = &surfaces[(rng.next() * 63.0) as usize];
                    let dir = lobe(s, 0.0, FOOTPRINT_SLOPE).dir;
                    let off = if rng.next() < 0.4 { 0.8 } else { 6.0 };
                    let c = s.position
                        + dir * (22.0 * rng.next())
                        + Vec3::new(rng.signed(), rng.signed(), rng.signed()) * off;
                    Some((c, 0.05 + 0.4 * rng.next()))
                })
                .collect();
            let casters = ShadowCasters {
                spheres: &spheres,
                distance: |i: usize, p: Vec3| {
                    let (c, r) = spheres[i].expect("bounded");
                    (p - c).length() - r
                },
            };
            let mut settings = ReflectionUniform::new(3, UVec2::ONE, 1);
            settings.shadow_steps = 48;
            settings.object_count = spheres.len() as u32;
            let length = tile_march_length(&bounds, &billboards, settings.max_distance);
            let cone = tile_shadow_cone(&bounds, settings.shadow_cone, settings.shadow_softness);
            let list = tile_casters(&bounds, &spheres, length, cone, 128).expect("fits");
            listed += list.len();
            total += spheres.len();
            for s in &surfaces {
                let all = reflect_pixel_shadowed(s, &billboards, &images, &settings, &casters);
                let tiled = reflect_pixel_in_tile(
                    s,
                    &billboards,
                    &images,
                    &settings,
                    &casters,
                    Some(&list),
                );
                assert_eq!(
                    all, tiled,
                    "a caster the pixel's march needs is off its tile's list"
                );
                let bare = reflect_pixel(s, &billboards, &images, &settings);
                shadowed += usize::from((all - bare).abs().max_element() > 0.05);
                pixels += usize::from(bare.w > 0.0);
            }
        }
        println!(
            "tile caster lists: {listed} of {total} objects listed; {pixels} reflecting pixels, {shadowed} shadowed"
        );
        assert!(
            pixels > 1000 && shadowed > 300,
            "{pixels} reflecting, {shadowed} shadowed"
        );
        assert!(listed * 2 < total, "the lists keep {listed} of {total}");
    }

    /// In a crowded scene (1,000 small casters, 100 of them within 30 cm of the tile's
    /// mirror rays in their first 4 m, a sign 40 m on) a pixel's segments gather more than
    /// `MAX_SHADOW_CASTERS` and march every candidate: with the tile's list that is the
    /// tile's casters, not all 1,000 (before the lists: every object at every step).
    #[test]
    fn a_crowded_march_evaluates_its_tiles_casters_only() {
        use std::cell::Cell;
        let mut rng = Rng(0x00c4_0ded);
        let eye = Vec3::new(0.0, 1.0, 30.0);
        let (surfaces, bounds) = floor_tile(&mut rng, eye, Vec3::new(0.0, 0.0, 20.0), 0.1, 0.25);
        let side = bounds.axis.cross(Vec3::Y).normalize();
        let spheres: Vec<Option<(Vec3, f32)>> = (0..1000)
            .map(|i| {
                let (along, off) = if i < 100 {
                    (4.0 * rng.next(), 0.3 * rng.signed())
                } else {
                    (
                        40.0 * rng.next(),
                        (5.0 + 35.0 * rng.next()) * rng.signed().signum(),
                    )
                };
                let at = bounds.center + bounds.axis * along + side * off;
                Some((at, 0.01))
            })
            .collect();
        let evaluations = Cell::new(0usize);
        let casters = ShadowCasters {
            spheres: &spheres,
            distance: |i: usize, p: Vec3| {
                evaluations.set(evaluations.get() + 1);
                let (c, r) = spheres[i].expect("bounded");
                (p - c).length() - r
            },
        };
        let sign = Billboard::from_transform(
            Mat4::from_translation(bounds.center + bounds.axis * 40.0)
                * Mat4::from_quat(Quat::from_rotation_arc(Vec3::Z, -bounds.axis)),
            Vec2::new(20.0, 20.0),
        )
        .expect("a quad");
        let billboards = [GpuBillboard::new(&sign, 0, 1.0)];
        let images = [MipChain::from_straight_alpha(1, 1, &[Vec4::ONE])];
        let mut settings = ReflectionUniform::new(1, UVec2::ONE, 1);
        settings.shadow_steps = 64;
        settings.object_count = spheres.len() as u32;
        let length = tile_march_length(&bounds, &billboards, settings.max_distance);
        let cone = tile_shadow_cone(&bounds, settings.shadow_cone, settings.shadow_softness);
        let list = tile_casters(&bounds, &spheres, length, cone, 128).expect("fits");
        let (mut all, mut tiled, mut reflecting) = (0, 0, 0);
        for s in &surfaces {
            let bare = reflect_pixel_shadowed(s, &billboards, &images, &settings, &casters);
            all += evaluations.replace(0);
            reflect_pixel_in_tile(s, &billboards, &images, &settings, &casters, Some(&list));
            tiled += evaluations.replace(0);
            reflecting += usize::from(bare.w > 0.0);
        }
        println!(
            "crowded march: {} casters listed, march length {length:.1} m; distance evaluations {all} with every object, {tiled} with the list ({reflecting} reflecting pixels)",
            list.len()
        );
        assert_eq!(reflecting, surfaces.len());
        assert!(list.len() < 128, "{} listed", list.len());
        assert!(all > 64 * 1000, "the marches overflow: {all} evaluations");
        assert!(
            tiled * 5 < all,
            "{tiled} evaluations with the list, {all} without"
        );
    }
}
