//! Billboard reflections: the geometry, images, per-pixel pass and tile cull that the
//! shaders (`shaders/reflections/`) and their CPU model share.
//!
//! Samaritan's billboard reflections (Mittring and Dudash, GDC 2011): textured quads —
//! lit signs, windows — placed like any object; each shaded point's reflected eye ray is
//! intersected with every quad, and the nearest few hits are alpha-composited front to
//! back. A [`Billboard`] is one-sided: a ray sees it only from the side its normal faces.
//!
//! Rays are intersected exactly ([`Billboard::intersect`]: plane, then the quad's
//! coordinates in its own — possibly sheared — axes); [`nearest_hits`] keeps the `k`
//! nearest, ordered by distance with ties broken by index, so the composite
//! ([`composite`]) does not depend on the order billboards are listed in.
//!
//! - [`texture`]: the images' mip chains as the texture array holds them, and the
//!   trilinear filter.
//! - [`pass`]: one pixel of the pass — the GGX footprint, its taps, the composite, the
//!   reflection-shadow march, the half-resolution upsample — and the uniform.
//! - [`cull`]: the conservative per-tile billboard test.
//! - [`grid`]: the uniform grid reflection shadows gather their casters from where a
//!   tile's caster list overflows.

use glam::{Mat4, Vec2, Vec3};

pub mod cull;
pub mod grid;
pub mod pass;
pub mod texture;

/// The layers a reflection composites by default (Samaritan's 3).
pub const DEFAULT_LAYERS: usize = 3;

/// The most layers a reflection composites (the shader's registers).
pub const MAX_LAYERS: usize = 4;

/// One reflection billboard: a one-sided quad, `center ± half_x ± half_y`, facing
/// `half_x × half_y`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Billboard {
    /// World-space centre, metres.
    pub center: Vec3,
    /// Half the quad along its image's x axis (left to right), world space.
    pub half_x: Vec3,
    /// Half the quad along its image's y axis, bottom to top, world space.
    pub half_y: Vec3,
}

/// Why a transform and size make no billboard.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BillboardError {
    /// A NaN or infinite value.
    NotFinite,
    /// No area: a zero size or scale, or axes that are parallel.
    NoArea,
}

impl std::fmt::Display for BillboardError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BillboardError::NotFinite => write!(f, "a NaN or infinite transform or size"),
            BillboardError::NoArea => write!(f, "a zero-area quad (zero size or scale)"),
        }
    }
}

impl std::error::Error for BillboardError {}

/// A ray's hit on a billboard.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the (unit) ray, metres.
    pub t: f32,
    /// Image coordinates: `(0, 0)` top left, `(1, 1)` bottom right.
    pub uv: Vec2,
    /// The billboard's index in the list searched.
    pub index: u32,
}

impl Billboard {
    /// The quad of `size` (metres, before the transform's scale) in the local XY plane,
    /// facing local +Z — the mesh of Bevy's `Rectangle` — placed by `world_from_local`.
    pub fn from_transform(world_from_local: Mat4, size: Vec2) -> Result<Self, BillboardError> {
        let center = world_from_local.transform_point3(Vec3::ZERO);
        let half_x = world_from_local.transform_vector3(Vec3::X * (0.5 * size.x));
        let half_y = world_from_local.transform_vector3(Vec3::Y * (0.5 * size.y));
        if !(center.is_finite() && half_x.is_finite() && half_y.is_finite()) {
            return Err(BillboardError::NotFinite);
        }
        let area = half_x.cross(half_y).length();
        let scale = half_x.length_squared() + half_y.length_squared();
        if area.is_nan() || area <= 1e-12 * scale || area <= 0.0 {
            return Err(BillboardError::NoArea);
        }
        Ok(Billboard {
            center,
            half_x,
            half_y,
        })
    }

    /// The unit normal of the side that shows.
    pub fn normal(&self) -> Vec3 {
        self.half_x.cross(self.half_y).normalize()
    }

    /// The front-side hit of the ray `origin + t dir` (`dir` unit) for `t > 0`, if any.
    pub fn intersect(&self, origin: Vec3, dir: Vec3) -> Option<(f32, Vec2)> {
        let n = self.half_x.cross(self.half_y);
        let facing = dir.dot(n);
        if facing.is_nan() || facing >= 0.0 {
            return None; // from behind, or along the plane
        }
        let t = (self.center - origin).dot(n) / facing;
        if t.is_nan() || t <= 0.0 {
            return None;
        }
        let p = origin + dir * t - self.center;
        // Coordinates in the quad's own axes (the dual basis: exact for sheared axes).
        let n2 = n.length_squared();
        let s = p.dot(self.half_y.cross(n)) / n2;
        let r = p.dot(n.cross(self.half_x)) / n2;
        (s.abs() <= 1.0 && r.abs() <= 1.0).then(|| (t, Vec2::new(0.5 + 0.5 * s, 0.5 - 0.5 * r)))
    }
}

/// The `k` nearest front-side hits of the ray within `max_distance`, nearest first;
/// equal distances in index order, so the result does not depend on how the list is
/// ordered beyond the indices it reports.
pub fn nearest_hits(
    billboards: &[Billboard],
    origin: Vec3,
    dir: Vec3,
    max_distance: f32,
    k: usize,
) -> Vec<Hit> {
    let mut hits: Vec<Hit> = Vec::with_capacity(k + 1);
    for (index, billboard) in billboards.iter().enumerate() {
        let Some((t, uv)) = billboard.intersect(origin, dir) else {
            continue;
        };
        if t > max_distance {
            continue;
        }
        let hit = Hit {
            t,
            uv,
            index: index as u32,
        };
        // Insertion into the sorted list (as the shader keeps its k registers).
        let at = hits
            .iter()
            .position(|h| (hit.t, hit.index) < (h.t, h.index))
            .unwrap_or(hits.len());
        if at < k {
            hits.insert(at, hit);
            hits.truncate(k);
        }
    }
    hits
}

/// Front-to-back alpha compositing of `(colour, alpha)` layers, nearest first:
/// `colour += T α c`, `T *= 1 − α` from `T = 1`. Returns the colour and what is left of
/// `T` (the light from behind the layers that still passes).
pub fn composite(layers: impl IntoIterator<Item = (Vec3, f32)>) -> (Vec3, f32) {
    let (mut colour, mut transmittance) = (Vec3::ZERO, 1.0f32);
    for (c, alpha) in layers {
        let alpha = alpha.clamp(0.0, 1.0);
        colour += transmittance * alpha * c;
        transmittance *= 1.0 - alpha;
    }
    (colour, transmittance)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DVec3, Quat};

    /// A small deterministic generator (xorshift*).
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            ((self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 40) as f32) / (1u64 << 24) as f32
        }
        fn vec(&mut self, scale: f32) -> Vec3 {
            Vec3::new(self.next() - 0.5, self.next() - 0.5, self.next() - 0.5) * 2.0 * scale
        }
    }

    /// Möller–Trumbore in f64 against one triangle: (t, barycentrics).
    fn triangle_hit(o: DVec3, d: DVec3, a: DVec3, b: DVec3, c: DVec3) -> Option<(f64, f64, f64)> {
        let (e1, e2) = (b - a, c - a);
        let p = d.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-18 {
            return None;
        }
        let s = o - a;
        let u = s.dot(p) / det;
        let q = s.cross(e1);
        let v = d.dot(q) / det;
        let t = e2.dot(q) / det;
        (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0).then_some((t, u, v))
    }

    /// The quad as two triangles of its corners (f64), front side only: the
    /// intersection and the image coordinates against an independent ray–triangle test.
    #[test]
    fn intersection_matches_two_triangles() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let (mut checked, mut hits) = (0, 0);
        for _ in 0..200 {
            // A non-uniformly scaled parent over a rotated child: sheared axes.
            let parent = Mat4::from_scale(Vec3::new(1.0, 0.4 + rng.next(), 1.0));
            let child = Mat4::from_rotation_z(rng.next() * 1.5);
            let transform = parent
                * child
                * Mat4::from_scale_rotation_translation(
                    Vec3::new(0.5 + rng.next() * 2.0, 0.5 + rng.next() * 2.0, 1.0),
                    Quat::from_euler(
                        glam::EulerRot::YXZ,
                        rng.next() * 6.3,
                        rng.next() * 3.0,
                        rng.next(),
                    ),
                    rng.vec(5.0),
                );
            let quad = Billboard::from_transform(transform, Vec2::new(1.5, 0.8)).unwrap();
            let c =
                |sx: f32, sy: f32| (quad.center + sx * quad.half_x + sy * quad.half_y).as_dvec3();
            let (tl, tr, bl, br) = (c(-1.0, 1.0), c(1.0, 1.0), c(-1.0, -1.0), c(1.0, -1.0));
            for _ in 0..50 {
                let origin = rng.vec(8.0);
                // Aim near the quad so that about half the rays hit.
                let target = quad.center + rng.vec(0.6);
                let dir = (target - origin).normalize();
                let got = quad.intersect(origin, dir);
                let (o, d) = (origin.as_dvec3(), dir.as_dvec3());
                let front = d.dot(quad.half_x.cross(quad.half_y).as_dvec3()) < 0.0;
                // Triangles (bl, br, tl) and (tr, tl, br): uv from the barycentrics.
                let want = triangle_hit(o, d, bl, br, tl)
                    .map(|(t, u, v)| (t, u, 1.0 - v))
                    .or_else(|| triangle_hit(o, d, tr, tl, br).map(|(t, u, v)| (t, 1.0 - u, v)))
                    .filter(|_| front);
                checked += 1;
                match (got, want) {
                    (Some((t, uv)), Some((wt, wu, wv))) => {
                        hits += 1;
                        assert!(
                            (f64::from(t) - wt).abs() < 1e-4 * wt.max(1.0),
                            "t {t} vs {wt}"
                        );
                        assert!(
                            (f64::from(uv.x) - wu).abs() < 1e-4
                                && (f64::from(uv.y) - wv).abs() < 1e-4,
                            "uv {uv} vs ({wu}, {wv})"
                        );
                    }
                    (None, None) => {}
                    (got, want) => {
                        // Rays grazing an edge may differ by rounding: only there.
                        let near_edge = want
                            .is_none_or(|(_, u, v)| u.min(v).min(1.0 - u).min(1.0 - v) < 1e-4)
                            && got.is_none_or(|(_, uv)| {
                                uv.min_element().min(1.0 - uv.max_element()) < 1e-4
                            });
                        assert!(near_edge, "{got:?} vs {want:?}");
                    }
                }
            }
        }
        assert!(hits > checked / 5, "{hits} hits of {checked} rays");
    }

    #[test]
    fn one_sided_with_its_image_upright() {
        // A quad 2 m ahead facing the viewer (local +Z toward the origin).
        let quad = Billboard::from_transform(
            Mat4::from_translation(Vec3::new(0.0, 0.0, -2.0)),
            Vec2::new(2.0, 1.0),
        )
        .unwrap();
        assert_eq!(quad.normal(), Vec3::Z);
        let (t, uv) = quad.intersect(Vec3::ZERO, Vec3::NEG_Z).unwrap();
        assert!((t - 2.0).abs() < 1e-6 && (uv - Vec2::splat(0.5)).length() < 1e-6);
        // Up-left of centre: the image's top left quarter.
        let (_, uv) = quad
            .intersect(Vec3::ZERO, Vec3::new(-0.5, 0.25, -2.0).normalize())
            .unwrap();
        assert!((uv - Vec2::new(0.25, 0.25)).length() < 1e-5, "{uv}");
        // From behind: nothing.
        assert_eq!(quad.intersect(Vec3::new(0.0, 0.0, -4.0), Vec3::Z), None);
        // Behind the ray's origin: nothing.
        assert_eq!(quad.intersect(Vec3::new(0.0, 0.0, -3.0), Vec3::NEG_Z), None);
    }

    #[test]
    fn bad_transforms_are_errors() {
        let size = Vec2::ONE;
        assert_eq!(
            Billboard::from_transform(Mat4::from_translation(Vec3::NAN), size),
            Err(BillboardError::NotFinite)
        );
        assert_eq!(
            Billboard::from_transform(Mat4::from_scale(Vec3::new(1.0, 0.0, 1.0)), size),
            Err(BillboardError::NoArea)
        );
        assert_eq!(
            Billboard::from_transform(Mat4::IDENTITY, Vec2::new(0.0, 1.0)),
            Err(BillboardError::NoArea)
        );
        assert_eq!(
            Billboard::from_transform(Mat4::IDENTITY, Vec2::new(f32::INFINITY, 1.0)),
            Err(BillboardError::NotFinite)
        );
    }

    /// The nearest hits are the sorted list of every hit, cut to `k`; at distinct
    /// distances the composite of a permuted list is the same bit for bit, and equal
    /// distances go in index order (the plugin lists billboards in a stable order).
    #[test]
    fn nearest_hits_do_not_depend_on_the_order() {
        let mut rng = Rng(7);
        // A stack of parallel quads facing +Z at z = −1 … −8.
        let mut quads: Vec<Billboard> = [-1.0, -2.5, -3.0, -4.0, -6.0, -8.0]
            .iter()
            .map(|&z| {
                Billboard::from_transform(
                    Mat4::from_translation(Vec3::new(rng.next() * 0.2, 0.0, z)),
                    Vec2::splat(3.0),
                )
                .unwrap()
            })
            .collect();
        let all = nearest_hits(&quads, Vec3::ZERO, Vec3::NEG_Z, 100.0, 99);
        assert_eq!(all.len(), 6);
        assert!(all.windows(2).all(|w| w[0].t < w[1].t));
        let near = nearest_hits(&quads, Vec3::ZERO, Vec3::NEG_Z, 100.0, 3);
        assert_eq!(near, all[..3].to_vec());
        assert_eq!(
            nearest_hits(&quads, Vec3::ZERO, Vec3::NEG_Z, 3.5, 3).len(),
            3
        );
        assert_eq!(
            nearest_hits(&quads, Vec3::ZERO, Vec3::NEG_Z, 2.0, 3).len(),
            1
        );
        // Colour per billboard (by identity, not index).
        let colour = |b: &Billboard| {
            (
                Vec3::new(b.center.x, -b.center.z, 1.0),
                0.4 + 0.05 * b.center.z.abs(),
            )
        };
        let shade = |list: &[Billboard]| {
            composite(
                nearest_hits(list, Vec3::ZERO, Vec3::NEG_Z, 100.0, DEFAULT_LAYERS)
                    .iter()
                    .map(|h| colour(&list[h.index as usize])),
            )
        };
        let forward = shade(&quads);
        for k in 0..quads.len() {
            quads.rotate_left(1);
            quads.swap(0, k);
            assert_eq!(shade(&quads), forward, "permutation {k}");
        }
        // Equal distances: index order.
        let twins = [quads[0], quads[0]];
        let hits = nearest_hits(&twins, Vec3::ZERO, Vec3::NEG_Z, 100.0, 3);
        assert_eq!(hits.iter().map(|h| h.index).collect::<Vec<_>>(), [0, 1]);
    }

    #[test]
    fn compositing_front_to_back() {
        let red = (Vec3::X, 1.0);
        let half_green = (Vec3::Y, 0.5);
        assert_eq!(composite([red, half_green]), (Vec3::X, 0.0));
        assert_eq!(
            composite([half_green, red]),
            (Vec3::new(0.5, 0.5, 0.0), 0.0)
        );
        assert_eq!(composite([]), (Vec3::ZERO, 1.0));
        let (c, t) = composite([half_green, half_green]);
        assert!((c - Vec3::new(0.0, 0.75, 0.0)).length() < 1e-7 && (t - 0.25).abs() < 1e-7);
    }
}
