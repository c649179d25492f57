//! Who still needs a distance-field-shadowed light's shadow map.
//!
//! Penumbra's masks shade only what its lighting pass shades: deferred materials on
//! `PenumbraLighting` cameras. Everything else that Bevy lights reads the light's shadow
//! map. Each frame (render world, before Bevy prepares lights) a DF-shadowed light keeps
//! its shadow map when any of these exists, and renders none otherwise:
//!
//! - an active 3D camera without Penumbra's lighting pass (a minimap, a split screen, a
//!   probe camera, a Penumbra camera that fell back to Bevy for MSAA);
//! - on a Penumbra camera, a visible mesh whose material Bevy lights in its forward pass:
//!   alpha-blended or transmissive, or opaque / alpha-masked with the forward method;
//! - the light is volumetric (`VolumetricLight`: Bevy's fog samples the map).
//!
//! A forward mesh marked [`ReadsNoShadowMaps`] (an unlit effect, Penumbra's particle
//! discs; hair, which marches those lights' visibility itself) does not count.
//!
//! Cost: one hash lookup per visible mesh of each Penumbra camera per frame, stopping at
//! the first forward material; nothing for apps without DF-shadowed lights.

use super::DistanceFieldShadows;
use crate::lighting::PenumbraLightingView;
use bevy::material::{OpaqueRendererMethod, RenderPhaseType};
use bevy::pbr::{
    ExtractedDirectionalLight, ExtractedPointLight, PreparedMaterial, RenderMaterialInstances,
};
use bevy::platform::collections::HashSet;
use bevy::prelude::*;
use bevy::render::Extract;
use bevy::render::erased_render_asset::ErasedRenderAssets;
use bevy::render::sync_world::MainEntity;
use bevy::render::view::{ExtractedView, RenderVisibleEntities};

/// Put on a mesh whose material Bevy draws in a forward phase (blended, transmissive or
/// forward) but which reads no distance-field-shadowed light's shadow map — unlit
/// effects, like `DistanceFieldParticles`' discs, or hair, which takes those lights'
/// visibility from the distance fields: it does not keep their shadow maps alive. Cost:
/// one set entry per marked entity per frame.
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Clone, Default)]
pub struct ReadsNoShadowMaps;

/// Render world: this frame's entities marked [`ReadsNoShadowMaps`].
#[derive(Resource, Default)]
pub(super) struct NoShadowMapReaders(HashSet<MainEntity>);

pub(super) fn extract_no_shadow_map_readers(
    mut readers: ResMut<NoShadowMapReaders>,
    marked: Extract<Query<Entity, With<ReadsNoShadowMaps>>>,
) {
    readers.0.clear();
    readers.0.extend(marked.iter().map(MainEntity::from));
}

/// Render-world view data the decision reads.
type ViewQuery<'a> = (Has<PenumbraLightingView>, Option<&'a RenderVisibleEntities>);

/// Whether DF-shadowed lights need their shadow maps this frame (render world), and
/// the system that applies it.
#[derive(Resource, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Resource, Clone, Default)]
pub struct ShadowMapConsumers {
    /// Some view shades materials with Bevy's lighting (module docs).
    pub forward_lit: bool,
}

/// Decides [`ShadowMapConsumers`] and switches off the shadow maps no one reads.
pub(super) fn skip_unread_shadow_maps(
    views: Query<ViewQuery, (With<ExtractedView>, With<Camera3d>)>,
    material_instances: Res<RenderMaterialInstances>,
    materials: Res<ErasedRenderAssets<PreparedMaterial>>,
    readers: Res<NoShadowMapReaders>,
    mut consumers: ResMut<ShadowMapConsumers>,
    mut points: Query<&mut ExtractedPointLight, With<DistanceFieldShadows>>,
    mut directionals: Query<&mut ExtractedDirectionalLight, With<DistanceFieldShadows>>,
) {
    if points.is_empty() && directionals.is_empty() {
        // No DF-shadowed light: nothing to decide (and no stale answer left behind).
        consumers.forward_lit = false;
        return;
    }
    let forward_lit = views.iter().any(|(penumbra, visible)| {
        !penumbra
            || visible.is_some_and(|v| {
                sees_forward_material(v, &material_instances, &materials, &readers)
            })
    });
    consumers.forward_lit = forward_lit;
    for mut light in &mut points {
        light.shadow_maps_enabled &= forward_lit || light.volumetric;
    }
    for mut light in &mut directionals {
        light.shadow_maps_enabled &= forward_lit || light.volumetric;
    }
}

/// Whether a view shows a mesh whose material Bevy's forward pass lights. Materials not
/// prepared yet are not drawn this frame, and meshes without a material instance are not
/// Bevy's materials: neither counts.
fn sees_forward_material(
    visible: &RenderVisibleEntities,
    material_instances: &RenderMaterialInstances,
    materials: &ErasedRenderAssets<PreparedMaterial>,
    readers: &NoShadowMapReaders,
) -> bool {
    crate::lighting::visible_meshes(visible).any(|entity: MainEntity| {
        !readers.0.contains(&entity)
            && material_instances
                .instances
                .get(&entity)
                .and_then(|instance| materials.get(instance.asset_id))
                .is_some_and(|material| {
                    is_forward_lit(
                        material.properties.render_phase_type,
                        material.properties.render_method,
                    )
                })
    })
}

/// Whether Bevy's forward pass lights a material of this phase and method.
fn is_forward_lit(phase: RenderPhaseType, method: OpaqueRendererMethod) -> bool {
    match phase {
        RenderPhaseType::Opaque | RenderPhaseType::AlphaMask => {
            method != OpaqueRendererMethod::Deferred
        }
        RenderPhaseType::Transmissive | RenderPhaseType::Transparent => true,
    }
}
