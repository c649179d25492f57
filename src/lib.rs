//! # Penumbra
//!
//! Bevy plugins for Unreal-4-style distance-field lighting — mesh signed distance fields,
//! an SDF atlas and GPU object buffer, ray-marched soft shadows, distance-field ambient
//! occlusion, a global SDF in camera-centred clipmaps — and the Samaritan demo's cinematic
//! effects: deferred shading with 4× MSAA, scatter bokeh depth of field and screen-space
//! subsurface scattering, billboard reflections, hair strips and compute tessellation.
//!
//! Add [`PenumbraPlugins`] after Bevy's `DefaultPlugins`, then tag entities, lights and
//! cameras with Penumbra's components. A scene pays only for what it uses: features whose
//! components are absent run no pass and upload nothing.
//!
//! The distance-field features are in [`df`] (`bevy_penumbra_df`), the cinematic ones in
//! `cinematic` (`bevy_penumbra_cinematic`, features `dof`, `sss`, `reflections`, `hair` and
//! `tessellation`); the shader library every
//! feature's WGSL imports (`#import penumbra::…`) in [`shaders`]. See `ARCHITECTURE.md`.
//!
//! ```no_run
//! use bevy::prelude::*;
//! use penumbra::prelude::*;
//!
//! fn setup(mut commands: Commands, mut meshes: ResMut<Assets<Mesh>>) {
//!     // A mesh caster: its SDF is baked in the background (once per mesh, cached on disk).
//!     commands.spawn((
//!         Mesh3d(meshes.add(Torus::default())),
//!         DistanceFieldCaster::default(),
//!         Transform::from_xyz(0.0, 0.5, 0.0),
//!     ));
//!     // Analytic casters cost no bake and no atlas space.
//!     commands.spawn((
//!         DistanceFieldCaster { source: CasterSource::Plane, ..default() },
//!         Transform::default(),
//!     ));
//!     // See what the distance fields look like (step heat map or shaded).
//!     commands.spawn((
//!         Camera3d::default(),
//!         DistanceFieldDebugView { mode: DistanceFieldDebugMode::Shaded, ..default() },
//!         Transform::from_xyz(0.0, 2.0, 6.0).looking_at(Vec3::ZERO, Vec3::Y),
//!     ));
//! }
//!
//! App::new()
//!     .add_plugins((DefaultPlugins, PenumbraPlugins))
//!     .add_systems(Startup, setup)
//!     .run();
//! ```

use bevy::app::plugin_group;
use bevy::prelude::*;

#[cfg(any(
    feature = "dof",
    feature = "sss",
    feature = "reflections",
    feature = "hair",
    feature = "tessellation"
))]
pub use bevy_penumbra_cinematic as cinematic;
pub use bevy_penumbra_df as df;
pub use penumbra_shaders as shaders;

plugin_group! {
    /// Everything Penumbra adds, as one group:
    /// `app.add_plugins((DefaultPlugins, PenumbraPlugins))`.
    pub struct PenumbraPlugins {
        :PenumbraCorePlugin,
        bevy_penumbra_df::sdf_asset:::SdfAssetPlugin,
        bevy_penumbra_df::scene:::DistanceFieldScenePlugin,
        #[cfg(feature = "debug_view")]
        bevy_penumbra_df::debug_view:::DistanceFieldDebugPlugin,
        bevy_penumbra_df::lighting:::PenumbraLightingPlugin,
        #[cfg(feature = "shadows")]
        bevy_penumbra_df::shadows:::DistanceFieldShadowsPlugin,
        #[cfg(feature = "ao")]
        bevy_penumbra_df::ao:::DistanceFieldAmbientOcclusionPlugin,
        bevy_penumbra_df::buffer_dump:::PenumbraBufferDumpPlugin,
        bevy_penumbra_df::global_field:::GlobalDistanceFieldPlugin,
        bevy_penumbra_df::particles:::DistanceFieldParticlesPlugin,
        #[cfg(feature = "dof")]
        bevy_penumbra_cinematic::dof:::BokehDepthOfFieldPlugin,
        #[cfg(feature = "sss")]
        bevy_penumbra_cinematic::sss:::SubsurfaceScatteringPlugin,
        #[cfg(feature = "reflections")]
        bevy_penumbra_cinematic::reflections:::BillboardReflectionsPlugin,
        #[cfg(feature = "hair")]
        bevy_penumbra_cinematic::hair:::HairPlugin,
        #[cfg(feature = "tessellation")]
        bevy_penumbra_cinematic::tessellation:::TessellationPlugin,
    }
}

/// Registers Penumbra's WGSL modules (`penumbra_shaders::SHADERS`) as Bevy shader
/// assets, so `#import penumbra::…` resolves in every Penumbra pipeline. Cost: one small
/// asset per module at startup; nothing per frame.
#[derive(Default)]
pub struct PenumbraCorePlugin;

pub use bevy_penumbra_df::PenumbraShaderLibrary;

impl Plugin for PenumbraCorePlugin {
    fn build(&self, app: &mut App) {
        bevy_penumbra_df::register_shader_library(app);
    }
}

/// Common imports: `use penumbra::prelude::*;`.
pub mod prelude {
    pub use crate::{PenumbraCorePlugin, PenumbraPlugins};
    #[cfg(feature = "reflections")]
    pub use bevy_penumbra_cinematic::{BillboardReflections, ReflectionBillboard};
    #[cfg(feature = "dof")]
    pub use bevy_penumbra_cinematic::{BokehAperture, BokehDepthOfField};
    #[cfg(feature = "hair")]
    pub use bevy_penumbra_cinematic::{Hair, HairCoverage, HairStrands};
    #[cfg(feature = "sss")]
    pub use bevy_penumbra_cinematic::{
        ScatteringMaterialPlugin, SubsurfaceProfile, SubsurfaceProfiles, SubsurfaceScattering,
    };
    #[cfg(feature = "tessellation")]
    pub use bevy_penumbra_cinematic::{
        Tessellated, TessellationCamera, TessellationMode, TessellationPartitioning,
    };
    pub use bevy_penumbra_df::{
        CasterSource, DeferredMsaa, DeferredMsaaShading, DistanceFieldCaster,
        DistanceFieldHeightfield, DistanceFieldParticles, DistanceFieldQuery, DistanceFieldRebake,
        DistanceFieldRebakeStats, DistanceFieldScene, DistanceFieldSceneCasters,
        DistanceFieldSceneSettings, DistanceFieldUploadStats, GlobalDistanceField,
        GlobalDistanceFieldStats, MergeDistanceFieldCasters, PenumbraLighting,
        PenumbraLightingPlugin, SceneCasterCounts, SdfAssetPlugin, SdfBakeFailed, SdfBaked,
        SdfVolumeAsset, SkinnedCasters,
    };
    #[cfg(feature = "ao")]
    pub use bevy_penumbra_df::{
        DistanceFieldAmbientOcclusion, DistanceFieldAoDebugView, DistanceFieldSpecularOcclusion,
    };
    #[cfg(feature = "debug_view")]
    pub use bevy_penumbra_df::{DistanceFieldDebugMode, DistanceFieldDebugView};
    #[cfg(feature = "shadows")]
    pub use bevy_penumbra_df::{DistanceFieldShadows, ReadsNoShadowMaps};
    #[cfg(feature = "bake")]
    pub use bevy_penumbra_df::{SdfBakeRequest, SdfBakeTask};
}
