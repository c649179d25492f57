//! Mesh casters' SDFs: a bake request per mesh caster (feature `bake`), or, without
//! baking compiled in, a clear failure on each mesh caster that has no SDF.

use super::{CasterSource, DistanceFieldCaster};
#[cfg(not(feature = "bake"))]
use crate::sdf_asset::{SdfBakeFailed, SdfBaked};
use bevy::prelude::*;
#[cfg(feature = "bake")]
use {
    super::CasterStretch,
    crate::sdf_asset::SdfBakeRequest,
    penumbra_sdf::{BakeSettings, GridPolicy, Resolution, SignMethod},
};

/// The world's +y in the space of a mesh placed by `transform` and baked with
/// `stretch` (for a ground caster), rounded to 1/4096 so that float noise in a transform
/// does not re-bake: +y when the transform is singular.
#[cfg(feature = "bake")]
fn local_up(transform: &GlobalTransform, stretch: CasterStretch) -> Vec3 {
    let matrix = transform.affine().matrix3;
    let determinant = matrix.determinant();
    if determinant.is_nan() || determinant.abs() <= 1e-12 {
        return Vec3::Y;
    }
    let up = stretch.direction(Vec3::from(matrix.inverse() * Vec3A::Y));
    let rounded = (up * 4096.0).round() / 4096.0;
    if rounded == Vec3::ZERO || !rounded.is_finite() {
        Vec3::Y
    } else {
        rounded
    }
}

/// Bake settings of a mesh caster placed by `transform`.
#[cfg(feature = "bake")]
fn bake_settings(
    caster: &DistanceFieldCaster,
    transform: &GlobalTransform,
    stretch: CasterStretch,
) -> BakeSettings {
    let scale = if caster.resolution_scale.is_finite() && caster.resolution_scale > 0.0 {
        caster.resolution_scale.clamp(1.0 / 16.0, 8.0)
    } else {
        1.0
    };
    BakeSettings {
        grid: GridPolicy {
            resolution: Resolution::PerUnit {
                density: 32.0 * scale,
                min: 8,
                max: 256,
                // The floor for small meshes scales with the caster's override too.
                min_longest: (penumbra_sdf::grid::DEFAULT_MIN_LONGEST as f32 * scale)
                    .round()
                    .clamp(0.0, 256.0) as u32,
            },
            ..GridPolicy::default()
        },
        sign: if caster.ground {
            SignMethod::SolidBelow {
                up: local_up(transform, stretch),
            }
        } else if caster.two_sided {
            SignMethod::TWO_SIDED
        } else {
            SignMethod::WindingNumber
        },
        ..BakeSettings::default()
    }
}

/// Mesh casters get a bake request (answered from the cache when possible) for their
/// [`CasterMesh`](super::CasterMesh), else their `Mesh3d`, with the [`CasterStretch`]
/// of their transform when they first ask (kept after). A moved caster is looked at
/// again (its settings are unchanged unless it is ground and turned).
#[cfg(feature = "bake")]
#[allow(clippy::type_complexity)]
pub(super) fn request_caster_bakes(
    mut commands: Commands,
    casters: Query<
        (
            Entity,
            &DistanceFieldCaster,
            &Mesh3d,
            &GlobalTransform,
            Option<&super::CasterMesh>,
            Option<&SdfBakeRequest>,
            Option<&CasterStretch>,
        ),
        Or<(
            Changed<DistanceFieldCaster>,
            Changed<Mesh3d>,
            Changed<super::CasterMesh>,
            Changed<GlobalTransform>,
        )>,
    >,
) {
    for (entity, caster, mesh, transform, source, request, stretch) in &casters {
        if caster.source != CasterSource::Mesh {
            continue;
        }
        let mesh = source.map_or(&mesh.0, |s| &s.0);
        let stretch = stretch
            .copied()
            .unwrap_or_else(|| CasterStretch::for_transform(transform));
        let settings = bake_settings(caster, transform, stretch);
        if request
            .is_some_and(|r| r.mesh == *mesh && r.settings == settings && r.stretch == stretch.0)
        {
            continue;
        }
        // A changed request drops the old outcome (see `sdf_asset`): the caster leaves
        // the scene until its new SDF arrives.
        commands.entity(entity).insert((
            SdfBakeRequest {
                mesh: mesh.clone(),
                settings,
                stretch: stretch.0,
            },
            stretch,
        ));
    }
}

/// Without the `bake` feature a mesh caster needs its SDF from elsewhere (an `SdfBaked`
/// the app inserts, or `CasterSource::Sdf`): those without one fail clearly (one warning
/// in all) instead of waiting forever.
#[cfg(not(feature = "bake"))]
#[allow(clippy::type_complexity)]
pub(super) fn request_caster_bakes(
    mut commands: Commands,
    casters: Query<
        (Entity, &DistanceFieldCaster),
        (
            Or<(Changed<DistanceFieldCaster>, Added<Mesh3d>)>,
            Without<SdfBaked>,
            Without<SdfBakeFailed>,
        ),
    >,
    mut warned: Local<bool>,
) {
    const REASON: &str = "bevy_penumbra_df was built without its `bake` feature: mesh \
        casters need an SDF from a `.psdf` file (`CasterSource::Sdf`) or an `SdfBaked`";
    for (entity, caster) in &casters {
        if caster.source != CasterSource::Mesh {
            continue;
        }
        if !std::mem::replace(&mut *warned, true) {
            warn!("Penumbra: caster {entity} skipped: {REASON}");
        }
        commands.entity(entity).insert(SdfBakeFailed(REASON.into()));
    }
}
