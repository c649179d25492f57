//! Gameplay queries against a scene of distance-field casters, on the CPU: the distance
//! to the nearest surface, its gradient (the outward normal there), and sphere casts —
//! for AI, stealth checks and placement — from the same SDF volumes and analytic shapes
//! the GPU traces (Bevy's `DistanceFieldQuery` system parameter gathers them).
//!
//! Each object's distance is its local distance times the smallest singular value of
//! its world-from-local linear part: a lower bound of the true world distance under any
//! scale or shear (exact for rigid and uniformly scaled analytic shapes; a baked volume
//! adds its own error, within a tenth of a voxel near the surface), so sphere tracing
//! with it does not pass through a surface. The scene's distance is the smallest over its
//! objects, the ones whose world bounds are farther than the best so far skipped (a
//! skipped object's true distance is at least its bounds' distance, so the result is
//! still a lower bound of the true scene distance).
//!
//! Limits: outside a volume's box its distance is a looser lower bound, so a sphere
//! wider than the bake's border stops up to a couple of voxels early beside it (never
//! late).
//!
//! A baked volume is sampled by the caller's function (`penumbra_sdf`'s
//! `SdfVolume::sample`: trilinear inside the box, a lower bound outside it), so this
//! crate stays free of the baker.

use crate::heightfield::Heightfield;
use crate::object::min_singular_value;
use glam::{Affine3A, Mat3, Vec3};

/// A baked distance field as the queries read it (Bevy's `SdfVolumeAsset` is one).
pub trait LocalDistance {
    /// The signed distance at local point `q`, local units.
    fn local_distance(&self, q: Vec3) -> f32;
    /// The local box the surface lies in (min, max).
    fn local_bounds(&self) -> (Vec3, Vec3);
}

/// What an object's distances come from.
#[derive(Clone, Copy)]
pub enum QueryShape<'a> {
    /// A baked volume (local units = the mesh's).
    Volume(&'a dyn LocalDistance),
    /// A ball around the local origin.
    Sphere {
        /// Radius, local units.
        radius: f32,
    },
    /// A box `[−half, half]`.
    Cuboid {
        /// Half extents, local units.
        half_extents: Vec3,
    },
    /// Points within `radius` of the segment `(0, ±half_length, 0)`.
    Capsule {
        /// Radius, local units.
        radius: f32,
        /// Half the segment's length, local units.
        half_length: f32,
    },
    /// The plane `y = 0`, solid below.
    Plane,
    /// A terrain heightfield (its own coordinates are world ones: place it with the
    /// identity transform).
    Terrain(&'a Heightfield),
}

impl QueryShape<'_> {
    fn distance(&self, q: Vec3) -> f32 {
        match *self {
            QueryShape::Volume(v) => v.local_distance(q),
            QueryShape::Sphere { radius } => q.length() - radius,
            QueryShape::Cuboid { half_extents } => {
                let a = q.abs() - half_extents;
                a.max(Vec3::ZERO).length() + a.max_element().min(0.0)
            }
            QueryShape::Capsule {
                radius,
                half_length,
            } => (q - Vec3::new(0.0, q.y.clamp(-half_length, half_length), 0.0)).length() - radius,
            QueryShape::Plane => q.y,
            QueryShape::Terrain(h) => h.distance(q),
        }
    }

    /// Local bounds, `None` when unbounded.
    fn bounds(&self) -> Option<(Vec3, Vec3)> {
        match *self {
            QueryShape::Volume(v) => Some(v.local_bounds()),
            QueryShape::Sphere { radius } => Some((Vec3::splat(-radius), Vec3::splat(radius))),
            QueryShape::Cuboid { half_extents } => Some((-half_extents, half_extents)),
            QueryShape::Capsule {
                radius,
                half_length,
            } => {
                let h = Vec3::new(radius, half_length + radius, radius);
                Some((-h, h))
            }
            QueryShape::Plane => None,
            QueryShape::Terrain(h) => Some(h.bounds()),
        }
    }
}

/// One caster for queries: its shape and where it is.
#[derive(Clone, Copy)]
pub struct QueryObject<'a> {
    /// Its distances.
    pub shape: QueryShape<'a>,
    /// World from local (the entity's `GlobalTransform`).
    pub world_from_local: Affine3A,
}

struct Prepared<'a> {
    shape: QueryShape<'a>,
    local_from_world: Affine3A,
    /// Smallest singular value of the linear part: world metres per local unit, at least.
    scale: f32,
    /// World bounds; infinite for unbounded shapes.
    min: Vec3,
    max: Vec3,
}

/// Where a sphere cast stopped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereHit {
    /// How far the sphere's centre travelled, metres.
    pub distance: f32,
    /// The sphere's centre at the hit.
    pub center: Vec3,
    /// The unit outward normal of the surface it touched (the scene's gradient there).
    pub normal: Vec3,
}

/// A scene of casters to query.
pub struct QueryScene<'a> {
    objects: Vec<Prepared<'a>>,
    skipped: usize,
}

/// Sphere casts stop after this many steps (a cast grazing a surface creeps along it).
pub const MAX_CAST_STEPS: u32 = 256;

impl<'a> QueryScene<'a> {
    /// The scene of `objects`; an object with a non-finite or singular transform, or a
    /// non-finite shape, is skipped (counted in [`QueryScene::skipped`]).
    pub fn new(objects: impl IntoIterator<Item = QueryObject<'a>>) -> Self {
        let mut out = Vec::new();
        let mut skipped = 0;
        for o in objects {
            match prepare(o) {
                Some(p) => out.push(p),
                None => skipped += 1,
            }
        }
        QueryScene {
            objects: out,
            skipped,
        }
    }

    /// Objects left out for bad transforms or shapes.
    pub fn skipped(&self) -> usize {
        self.skipped
    }

    /// Objects in the scene.
    pub fn len(&self) -> usize {
        self.objects.len()
    }

    /// Whether it has no object.
    pub fn is_empty(&self) -> bool {
        self.objects.is_empty()
    }

    /// The distance from `p` to the nearest surface (negative inside), a lower bound of
    /// the true distance; `+∞` for an empty scene or a non-finite `p`.
    pub fn distance(&self, p: Vec3) -> f32 {
        self.nearest(p).map_or(f32::INFINITY, |(d, _)| d)
    }

    /// [`QueryScene::distance`] and the index (in the order given) of the object that
    /// gave it; `None` for an empty scene or a non-finite `p`.
    pub fn nearest(&self, p: Vec3) -> Option<(f32, usize)> {
        if !p.is_finite() {
            return None;
        }
        let mut best: Option<(f32, usize)> = None;
        for (i, o) in self.objects.iter().enumerate() {
            let bound = (p.clamp(o.min, o.max) - p).length();
            if best.is_some_and(|(d, _)| bound >= d) {
                continue;
            }
            let d = o.shape.distance(o.local_from_world.transform_point3(p)) * o.scale;
            if best.is_none_or(|(b, _)| d < b) {
                best = Some((d, i));
            }
        }
        best
    }

    /// The unit gradient of the distance at `p` (central differences of `h` metres):
    /// the outward normal of the nearest surface; zero where it is undefined.
    pub fn gradient(&self, p: Vec3, h: f32) -> Vec3 {
        let d = |o: Vec3| self.distance(p + o) - self.distance(p - o);
        let g = Vec3::new(d(Vec3::X * h), d(Vec3::Y * h), d(Vec3::Z * h));
        if g.is_finite() {
            g.normalize_or_zero()
        } else {
            Vec3::ZERO
        }
    }

    /// Sweeps a sphere of `radius` from `origin` along `direction` (need not be unit) up
    /// to `max_distance`: where it first touches a surface (within `tolerance`), or
    /// `None` when it gets through, the input is not finite, or the direction is zero.
    /// A sphere that starts inside a surface hits at distance 0.
    pub fn sphere_cast(
        &self,
        origin: Vec3,
        direction: Vec3,
        radius: f32,
        max_distance: f32,
        tolerance: f32,
    ) -> Option<SphereHit> {
        let dir = direction.try_normalize()?;
        if !(origin.is_finite() && radius.is_finite() && max_distance.is_finite()) {
            return None;
        }
        let tolerance = tolerance.max(1e-6);
        let mut t = 0.0f32;
        for _ in 0..MAX_CAST_STEPS {
            let center = origin + dir * t;
            let d = self.distance(center) - radius.max(0.0);
            if d <= tolerance {
                return Some(SphereHit {
                    distance: t,
                    center,
                    normal: self.gradient(center, tolerance.max(1e-3)),
                });
            }
            t += d;
            if t > max_distance {
                return None;
            }
        }
        None
    }
}

fn prepare(o: QueryObject) -> Option<Prepared> {
    let m = o.world_from_local;
    if !m.is_finite() {
        return None;
    }
    let scale = min_singular_value(Mat3::from(m.matrix3));
    if scale.is_nan() || scale <= 1e-12 {
        return None;
    }
    let local_from_world = m.inverse();
    let (min, max) = match o.shape.bounds() {
        Some((lo, hi)) => {
            if !(lo.is_finite() && hi.is_finite()) {
                return None;
            }
            let corners = (0..8).map(|i| {
                let c = Vec3::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                );
                m.transform_point3(c)
            });
            corners.fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), c| {
                (a.min(c), b.max(c))
            })
        }
        None => (Vec3::NEG_INFINITY, Vec3::INFINITY),
    };
    Some(Prepared {
        shape: o.shape,
        local_from_world,
        scale,
        min,
        max,
    })
}

#[cfg(test)]
mod tests;
