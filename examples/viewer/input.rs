//! Checks a scene file before Bevy loads it, so that what Bevy cannot load fails with one
//! clear error (and a non-zero exit) instead of a window that never fills: missing or
//! unreadable files, files that are not glTF 2.0, truncated binary chunks or buffers,
//! and required extensions Bevy does not support (Draco and meshopt compression, …).

use std::path::Path;

/// Extensions Bevy 0.19's glTF loader supports (a file may *require* only these).
const SUPPORTED_REQUIRED: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_materials_unlit",
    "KHR_materials_transmission",
    "KHR_materials_ior",
    "KHR_materials_volume",
    "KHR_materials_specular",
    "KHR_materials_clearcoat",
    "KHR_materials_anisotropy",
    "KHR_texture_transform",
];

/// Why a scene cannot be shown.
pub fn check_scene(path: &Path) -> Result<(), String> {
    let shown = path.display();
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if !matches!(ext.as_deref(), Some("glb" | "gltf")) {
        return Err(format!("{shown}: not a .glb or .gltf file"));
    }
    let bytes = std::fs::read(path).map_err(|e| format!("{shown}: cannot read: {e}"))?;
    let gltf = gltf::Gltf::from_slice(&bytes)
        .map_err(|e| format!("{shown}: not a valid glTF 2.0 file: {e}"))?;
    if let Some(unsupported) = gltf
        .extensions_required()
        .find(|e| !SUPPORTED_REQUIRED.contains(e))
    {
        return Err(format!(
            "{shown}: requires the glTF extension {unsupported}, which Bevy's loader does \
             not support{}",
            match unsupported {
                "KHR_draco_mesh_compression" | "EXT_meshopt_compression" =>
                    " (compressed geometry: decompress it first, e.g. `gltf-transform copy`)",
                _ => "",
            }
        ));
    }
    // Every buffer must be present and as long as the file says.
    let dir = path.parent().unwrap_or(Path::new("."));
    for buffer in gltf.buffers() {
        let have = match buffer.source() {
            gltf::buffer::Source::Bin => gltf.blob.as_ref().map_or(0, Vec::len),
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                // Base64 data: 3 bytes per 4 characters after the comma.
                uri.split_once(',')
                    .map_or(0, |(_, d)| d.trim_end_matches('=').len() * 3 / 4)
            }
            gltf::buffer::Source::Uri(uri) => {
                let file = dir.join(percent_decode(uri));
                std::fs::metadata(&file)
                    .map_err(|e| format!("{shown}: buffer {}: {e}", file.display()))?
                    .len() as usize
            }
        };
        if have < buffer.length() {
            return Err(format!(
                "{shown}: buffer {} is truncated: {have} of {} bytes",
                buffer.index(),
                buffer.length()
            ));
        }
    }
    Ok(())
}

/// `%20` and friends in relative URIs.
fn percent_decode(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%'
            && let Some(v) = uri
                .get(i + 1..i + 3)
                .and_then(|h| u8::from_str_radix(h, 16).ok())
        {
            out.push(v);
            i += 3;
            continue;
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}
