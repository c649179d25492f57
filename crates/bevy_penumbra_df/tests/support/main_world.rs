//! A headless app with what the distance-field scene's main world needs and no
//! renderer: time, transforms, assets, meshes, visibility and shader assets. Tests add
//! Penumbra's plugins (and any settings first), then `finish` and `cleanup`.

use bevy::prelude::*;

pub fn main_world_app() -> App {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        TransformPlugin,
        AssetPlugin::default(),
        bevy::mesh::MeshPlugin,
        bevy::camera::visibility::VisibilityPlugin,
    ))
    .init_asset::<Shader>();
    app
}
