//! Penumbra's WGSL library as Bevy shader assets.

use bevy::prelude::*;
use bevy::render::RenderApp;

/// Strong handles keeping Penumbra's shader library (`penumbra_shaders::SHADERS`)
/// loaded, so `#import penumbra::…` resolves in every Penumbra pipeline. Present in the
/// main and the render world.
#[derive(Resource, Debug, Default, Clone)]
pub struct PenumbraShaderLibrary {
    /// One handle per `penumbra_shaders::SHADERS` entry, in the same order.
    pub handles: Vec<Handle<Shader>>,
}

impl PenumbraShaderLibrary {
    /// The handle of the library file at `path` (relative to `shaders/`, e.g.
    /// `df/cull.wgsl`). Panics on an unknown path: paths are compile-time constants of
    /// this crate, checked by its tests.
    pub fn handle(&self, path: &str) -> Handle<Shader> {
        let index = penumbra_shaders::SHADERS
            .iter()
            .position(|s| s.path == path)
            .unwrap_or_else(|| panic!("no Penumbra shader {path}"));
        self.handles[index].clone()
    }
}

/// Registers the shader library once (idempotent) and mirrors it into the render world.
/// Cost: one small asset per module at startup; nothing per frame.
pub fn register_shader_library(app: &mut App) {
    if !app.world().contains_resource::<PenumbraShaderLibrary>() {
        let Some(mut shaders) = app.world_mut().get_resource_mut::<Assets<Shader>>() else {
            warn!(
                "Penumbra: no `Assets<Shader>` (add DefaultPlugins first); Penumbra's shaders are not registered"
            );
            return;
        };
        let handles = penumbra_shaders::SHADERS
            .iter()
            .map(|s| shaders.add(Shader::from_wgsl(s.source, format!("penumbra/{}", s.path))))
            .collect();
        app.insert_resource(PenumbraShaderLibrary { handles });
    }
    let library = app.world().resource::<PenumbraShaderLibrary>().clone();
    if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
        render_app.insert_resource(library);
    }
}
