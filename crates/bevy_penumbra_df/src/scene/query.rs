//! [`DistanceFieldQuery`]: gameplay queries — distance, normal, sphere casts — against
//! the distance-field casters, on the CPU, from the SDFs and shapes the main world
//! already holds (`penumbra_df_core::query` does the work and documents its bounds).

use super::{CasterSource, DistanceFieldCaster, HeightfieldTerrain};
use crate::sdf_asset::{SdfBaked, SdfVolumeAsset};
use bevy::ecs::system::SystemParam;
use bevy::math::Affine3A;
use bevy::prelude::*;
use penumbra_df_core::query::{LocalDistance, QueryObject, QueryScene, QueryShape};

pub use penumbra_df_core::query::SphereHit;

impl LocalDistance for SdfVolumeAsset {
    fn local_distance(&self, q: Vec3) -> f32 {
        self.volume.sample(q.as_dvec3())
    }

    fn local_bounds(&self) -> (Vec3, Vec3) {
        let (lo, hi) = self.volume.bounds();
        (lo.as_vec3(), hi.as_vec3())
    }
}

/// Distance, normal and sphere casts against every [`DistanceFieldCaster`] — for AI,
/// stealth checks and placement — hidden ones included; mesh casters count once their
/// SDF is baked or loaded. Distances are conservative lower bounds (a sphere cast stops
/// at or before a surface, never beyond it).
///
/// ```no_run
/// # use bevy::prelude::*;
/// # use bevy_penumbra_df::DistanceFieldQuery;
/// fn keep_clear(query: DistanceFieldQuery, agents: Query<&Transform>) {
///     for t in &agents {
///         if query.distance(t.translation) < 0.5 {
///             // too close to a wall
///         }
///     }
/// }
/// ```
///
/// Each call gathers the casters (linear in their count); for many queries in one
/// system, [`DistanceFieldQuery::scene`] once and query it.
#[derive(SystemParam)]
pub struct DistanceFieldQuery<'w, 's> {
    casters: Query<
        'w,
        's,
        (
            &'static DistanceFieldCaster,
            &'static GlobalTransform,
            Option<&'static SdfBaked>,
            Option<&'static super::CasterStretch>,
        ),
    >,
    volumes: Res<'w, Assets<SdfVolumeAsset>>,
    terrains: Query<'w, 's, &'static HeightfieldTerrain>,
}

impl DistanceFieldQuery<'_, '_> {
    /// The casters and terrains ([`super::DistanceFieldHeightfield`]) as a scene to
    /// query (casters with bad transforms are left out).
    pub fn scene(&self) -> QueryScene<'_> {
        let terrains = self.terrains.iter().filter_map(|t| match t {
            HeightfieldTerrain::Ready(h) => Some(QueryObject {
                shape: QueryShape::Terrain(h),
                world_from_local: Affine3A::IDENTITY,
            }),
            HeightfieldTerrain::Refused(_) => None,
        });
        QueryScene::new(
            self.casters
                .iter()
                .filter_map(|(caster, transform, baked, stretch)| {
                    let shape = match &caster.source {
                        CasterSource::Mesh => QueryShape::Volume(self.volumes.get(&baked?.0)?),
                        CasterSource::Sdf(handle) => QueryShape::Volume(self.volumes.get(handle)?),
                        CasterSource::Sphere { radius } => QueryShape::Sphere { radius: *radius },
                        CasterSource::Cuboid { half_size } => QueryShape::Cuboid {
                            half_extents: *half_size,
                        },
                        CasterSource::Capsule {
                            radius,
                            half_length,
                        } => QueryShape::Capsule {
                            radius: *radius,
                            half_length: *half_length,
                        },
                        CasterSource::Plane => QueryShape::Plane,
                    };
                    Some(QueryObject {
                        shape,
                        world_from_local: super::stretch::world_from_field(
                            &caster.source,
                            transform,
                            stretch,
                        ),
                    })
                })
                .chain(terrains),
        )
    }

    /// Signed distance from `point` to the nearest caster surface, metres (negative
    /// inside; `f32::INFINITY` with no caster).
    pub fn distance(&self, point: Vec3) -> f32 {
        self.scene().distance(point)
    }

    /// The outward unit normal of the nearest surface at `point` (the distance's
    /// gradient, by central differences of 1 cm); zero where it is undefined.
    pub fn gradient(&self, point: Vec3) -> Vec3 {
        self.scene().gradient(point, 0.01)
    }

    /// Sweeps a sphere of `radius` from `origin` along `direction` up to `max_distance`
    /// metres: where it first touches a caster (within 1 mm), or `None`.
    pub fn sphere_cast(
        &self,
        origin: Vec3,
        direction: Vec3,
        radius: f32,
        max_distance: f32,
    ) -> Option<SphereHit> {
        self.scene()
            .sphere_cast(origin, direction, radius, max_distance, 1e-3)
    }
}
