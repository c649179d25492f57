//! The viewer's lights: the sun and `--point` lights it spawns, the scene's own lights
//! given distance-field shadows (or removed), and the shadow settings and bias fitted to
//! the scene's size and its coarsest two-sided caster.

use super::cli::Args;
use super::{BakeClock, Framing, ViewerArgs, ViewerScene};
use bevy::prelude::*;
use penumbra::df::{
    CasterSource, DistanceFieldAmbientOcclusion, DistanceFieldCaster, DistanceFieldShadows,
    SdfBaked, SdfVolumeAsset,
};

/// The distance-field shadow settings for this scene's size.
pub fn shadow_settings(framing: &Framing, angle_deg: f32) -> DistanceFieldShadows {
    let d = DistanceFieldShadows::default();
    let s = framing.scale();
    DistanceFieldShadows {
        angular_diameter: angle_deg.to_radians(),
        max_distance: d.max_distance * s,
        max_view_distance: (d.max_view_distance * s)
            .max(framing.eye.distance(framing.center) + 2.0 * framing.radius),
        bias: d.bias * s,
        ..d
    }
}

pub(crate) fn spawn_lights(commands: &mut Commands, args: &Args, framing: &Framing) {
    let sun = args.sun.unwrap_or(Vec3::new(-0.4, -1.0, -0.3)).normalize();
    let up = if sun.cross(Vec3::Y).length() < 1e-3 {
        Vec3::Z
    } else {
        Vec3::Y
    };
    let mut light = commands.spawn((
        Name::new("sun"),
        DirectionalLight {
            illuminance: 8_000.0,
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::default().looking_to(sun, up),
    ));
    if !args.plain {
        light.insert(shadow_settings(framing, args.angle));
    }
    for (i, &position) in args.points.iter().enumerate() {
        // About 2,000 lux at the scene's centre.
        let d2 = position.distance_squared(framing.center).max(1e-4);
        let mut light = commands.spawn((
            Name::new(format!("point{i}")),
            PointLight {
                intensity: 2_000.0 * 4.0 * std::f32::consts::PI * d2,
                radius: args.radius(i),
                range: 4.0 * framing.radius + position.distance(framing.center),
                shadow_maps_enabled: true,
                ..default()
            },
            Transform::from_translation(position),
        ));
        if !args.plain {
            light.insert(shadow_settings(framing, 0.0));
        }
    }
}

/// The scene's own lights: distance-field shadows (and shadow maps, for plain Bevy), or
/// removed with `--no-scene-lights`.
#[allow(clippy::type_complexity)]
pub(crate) fn shadow_scene_lights(
    mut commands: Commands,
    args: Res<ViewerArgs>,
    framing: Res<Framing>,
    root: Single<Entity, With<ViewerScene>>,
    parents: Query<&ChildOf>,
    mut lights: Query<
        (
            Entity,
            Option<&mut DirectionalLight>,
            Option<&mut PointLight>,
            Option<&mut SpotLight>,
        ),
        Or<(Added<DirectionalLight>, Added<PointLight>, Added<SpotLight>)>,
    >,
) {
    for (entity, directional, point, spot) in &mut lights {
        if !parents.iter_ancestors(entity).any(|a| a == *root) {
            continue;
        }
        if args.0.no_scene_lights {
            commands
                .entity(entity)
                .remove::<(DirectionalLight, PointLight, SpotLight)>();
            continue;
        }
        let angle = if let Some(mut l) = directional {
            l.shadow_maps_enabled = true;
            args.0.angle
        } else {
            if let Some(mut l) = point {
                l.shadow_maps_enabled = true;
            }
            if let Some(mut l) = spot {
                l.shadow_maps_enabled = true;
            }
            0.0
        };
        if !args.0.plain {
            commands
                .entity(entity)
                .insert(shadow_settings(&framing, angle));
        }
    }
}

/// Once every caster is baked: the shadow rays' bias is at least two voxels of the
/// coarsest two-sided caster, so that a surface does not shadow itself from inside its
/// own shell (a shell is about a voxel thick; scenes in odd units or with large open
/// meshes have coarse voxels). Solid casters need no such margin. Applied to every
/// light when that voxel size changes, else only to lights that just got
/// `DistanceFieldShadows`: a bias set in the panel stays. DFAO's surface bias likewise.
#[allow(clippy::type_complexity)]
pub(crate) fn fit_shadow_bias(
    casters: Query<(&DistanceFieldCaster, Option<&SdfBaked>, &GlobalTransform)>,
    rebaked: Query<(), Or<(Changed<SdfBaked>, Changed<DistanceFieldCaster>)>>,
    volumes: Res<Assets<SdfVolumeAsset>>,
    mut lights: Query<&mut DistanceFieldShadows>,
    mut occlusion: Query<&mut DistanceFieldAmbientOcclusion>,
    mut fitted: Local<Option<f32>>,
    mut clock: ResMut<BakeClock>,
) {
    // Mesh casters wait for their bake; analytic ones (capsules, `--ground`) for nothing.
    if casters
        .iter()
        .any(|(c, baked, _)| baked.is_none() && c.source == CasterSource::Mesh)
    {
        return;
    }
    if clock.1.is_none() {
        clock.1 = Some(clock.0.elapsed());
    }
    // (Reading `is_added` through `Mut` does not mark the light changed.)
    let any_new =
        lights.iter_mut().any(|l| l.is_added()) || occlusion.iter_mut().any(|a| a.is_added());
    if fitted.is_some() && rebaked.is_empty() && !any_new {
        return;
    }
    let voxel = casters
        .iter()
        .filter(|(c, ..)| c.two_sided)
        .filter_map(|(_, baked, transform)| {
            let volume = &volumes.get(&baked?.0)?.volume;
            let scale = transform
                .affine()
                .matrix3
                .abs()
                .to_cols_array()
                .into_iter()
                .fold(0.0f32, f32::max);
            Some(volume.voxel_size * scale)
        })
        .fold(0.0f32, f32::max);
    let all = *fitted != Some(voxel);
    *fitted = Some(voxel);
    for mut light in &mut lights {
        if (all || light.is_added()) && light.bias < 2.0 * voxel {
            light.bias = 2.0 * voxel;
        }
    }
    // DFAO's cones start above the same shell, within a quarter of their reach (beyond
    // it the cones would start out of reach; the shell may then occlude a little).
    for mut ao in &mut occlusion {
        let bias = (2.0 * voxel).min(0.25 * ao.max_occlusion_distance);
        if (all || ao.is_added()) && ao.surface_bias < bias {
            ao.surface_bias = bias;
        }
    }
}
