//! A scene whose embedded image cannot be decoded, loaded again without its textures.
//!
//! Bevy's glTF loader decodes a GLB's embedded images with the scene, so one image it
//! cannot decode (a corrupt PNG, a format whose Bevy feature is off) fails the whole
//! scene, where an external image file that fails is only a missing texture. The viewer
//! then loads the scene once more with every texture reference taken out of its JSON
//! (materials keep their factors) from Bevy's in-memory `embedded://` source, and warns
//! once: the scene is drawn, untextured, as a scene with a missing texture is.
//! Self-contained GLB files only: a `.gltf` refers to its buffers by relative paths.

use bevy::asset::io::embedded::EmbeddedAssetRegistry;
use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;
use std::path::Path;

/// Whether a scene's load error is an embedded image Bevy could not decode
/// (`GltfError::ImageError`, `GltfError::InvalidImageMimeType`).
pub fn is_image_error(message: &str) -> bool {
    message.contains("feature for the file format") || message.contains("image mime type")
}

/// The GLB `bytes` with no images, textures or samplers, and no material or extension
/// referring to one; the binary chunk as it was (`gltf::binary::Glb` reads and writes
/// the container).
pub fn strip_textures(bytes: &[u8]) -> Result<Vec<u8>, String> {
    let mut glb = gltf::binary::Glb::from_slice(bytes).map_err(|e| format!("GLB: {e}"))?;
    let mut doc: serde_json::Value =
        serde_json::from_slice(&glb.json).map_err(|e| format!("GLB JSON: {e}"))?;
    let root = doc.as_object_mut().ok_or("GLB JSON is not an object")?;
    for key in ["images", "textures", "samplers"] {
        root.remove(key);
    }
    if let Some(materials) = root.get_mut("materials") {
        drop_texture_references(materials);
    }
    // Texture formats an extension adds (KTX2, WebP) are not needed any more.
    for key in ["extensionsUsed", "extensionsRequired"] {
        if let Some(serde_json::Value::Array(list)) = root.get_mut(key) {
            list.retain(|e| !e.as_str().is_some_and(|e| e.contains("texture")));
        }
    }
    glb.json = serde_json::to_vec(&doc).map_err(|e| e.to_string())?.into();
    glb.to_vec().map_err(|e| format!("GLB: {e}"))
}

/// Removes every object member named `…Texture` (`baseColorTexture`, `normalTexture`,
/// an extension's `clearcoatTexture`, …) below `value`.
fn drop_texture_references(value: &mut serde_json::Value) {
    match value {
        serde_json::Value::Object(map) => {
            map.retain(|k, _| !k.ends_with("Texture"));
            map.values_mut().for_each(drop_texture_references);
        }
        serde_json::Value::Array(list) => list.iter_mut().for_each(drop_texture_references),
        _ => {}
    }
}

/// Loads the GLB at `path` again without its textures (module docs), as the scene of
/// `root`; `Err` when it cannot (not a GLB, unreadable).
pub fn reload_untextured(
    commands: &mut Commands,
    root: Entity,
    path: &Path,
    registry: &EmbeddedAssetRegistry,
    assets: &AssetServer,
) -> Result<(), String> {
    if !path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("glb"))
    {
        return Err("only a GLB file can be loaded again without its textures".into());
    }
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let stripped = strip_textures(&bytes)?;
    let name = Path::new("penumbra_viewer/untextured.glb");
    registry.insert_asset(path.to_path_buf(), name, stripped);
    let scene =
        assets.load(GltfAssetLabel::Scene(0).from_asset(format!("embedded://{}", name.display())));
    commands.entity(root).insert(WorldAssetRoot(scene));
    Ok(())
}
