//! # Penumbra
//!
//! Bevy plugins for Unreal-4-style distance-field lighting (mesh signed distance fields,
//! an SDF atlas and GPU object buffer, ray-marched soft shadows, distance-field ambient
//! occlusion, a global SDF) and the Samaritan demo's cinematic effects.
//!
//! Add [`PenumbraPlugins`] after Bevy's `DefaultPlugins`, then tag entities, lights and
//! cameras with Penumbra's components. A scene pays only for what it uses: features whose
//! components are absent run no pass and upload nothing.
//!
//! So far: the plugin group, the shader library every feature's WGSL imports
//! (`#import penumbra::math::…`), and signed distance fields as assets (`.psdf`
//! loading, runtime baking of meshes with a disk cache). See `ARCHITECTURE.md`.

use bevy::app::plugin_group;
use bevy::prelude::*;

pub use bevy_penumbra_df as df;
pub use penumbra_shaders as shaders;

plugin_group! {
    /// Everything Penumbra adds, as one group:
    /// `app.add_plugins((DefaultPlugins, PenumbraPlugins))`.
    pub struct PenumbraPlugins {
        :PenumbraCorePlugin,
        bevy_penumbra_df::sdf_asset:::SdfAssetPlugin,
    }
}

/// Registers Penumbra's WGSL modules (`penumbra_shaders::SHADERS`) as Bevy shader
/// assets, so `#import penumbra::…` resolves in every Penumbra pipeline. Cost: one small
/// asset per module at startup; nothing per frame.
#[derive(Default)]
pub struct PenumbraCorePlugin;

/// Strong handles keeping Penumbra's shader library loaded.
#[derive(Resource, Debug, Default)]
pub struct PenumbraShaderLibrary {
    /// One handle per `penumbra_shaders::SHADERS` entry, in the same order.
    pub handles: Vec<Handle<Shader>>,
}

impl Plugin for PenumbraCorePlugin {
    fn build(&self, app: &mut App) {
        let Some(mut shaders) = app.world_mut().get_resource_mut::<Assets<Shader>>() else {
            warn!(
                "PenumbraCorePlugin: no `Assets<Shader>` (add DefaultPlugins first); Penumbra's shaders are not registered"
            );
            return;
        };
        let handles = penumbra_shaders::SHADERS
            .iter()
            .map(|s| shaders.add(Shader::from_wgsl(s.source, format!("penumbra/{}", s.path))))
            .collect();
        app.insert_resource(PenumbraShaderLibrary { handles });
    }
}

/// Common imports: `use penumbra::prelude::*;`.
pub mod prelude {
    pub use crate::{PenumbraCorePlugin, PenumbraPlugins};
    pub use bevy_penumbra_df::{
        SdfAssetPlugin, SdfBakeFailed, SdfBakeRequest, SdfBakeTask, SdfBaked, SdfVolumeAsset,
    };
}
