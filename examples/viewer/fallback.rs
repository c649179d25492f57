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
/// referring to one; the binary chunk as it was.
pub fn strip_textures(bytes: &[u8]) -> Result<Vec<u8>, String> {
    let word = |at: usize| -> Result<u32, String> {
        let b = bytes.get(at..at + 4).ok_or("GLB: truncated")?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    if bytes.get(0..4) != Some(b"glTF".as_slice()) {
        return Err("not a GLB file".into());
    }
    let json_len = word(12)? as usize;
    if word(16)? != 0x4E4F_534A {
        return Err("GLB: the first chunk is not JSON".into());
    }
    let json = bytes.get(20..20 + json_len).ok_or("GLB: truncated JSON")?;
    let rest = &bytes[20 + json_len..];
    let mut doc: serde_json::Value =
        serde_json::from_slice(json).map_err(|e| format!("GLB JSON: {e}"))?;
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
    let mut json = serde_json::to_vec(&doc).map_err(|e| e.to_string())?;
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    let total = 12 + 8 + json.len() + rest.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&0x4E4F_534Au32.to_le_bytes());
    out.extend_from_slice(&json);
    out.extend_from_slice(rest);
    Ok(out)
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
