//! `--dump DIR`: the view's Penumbra buffers as float32 `.npy` files (`NumPy` format 1.0,
//! C order, shape `(H, W)` or `(H, W, 3)`, row 0 at the top) and `DIR/meta.json`.

use bevy::math::{UVec2, Vec3};
use penumbra::df::PenumbraBuffers;
use std::path::Path;

/// What `meta.json` says about the camera and lights.
pub struct DumpMeta {
    /// The scene file (or `showcase`).
    pub scene: String,
    /// Camera position.
    pub eye: Vec3,
    /// The point the camera looks at.
    pub target: Vec3,
    /// Vertical field of view, degrees.
    pub fov_deg: f32,
    /// [`light_summaries`].
    pub lights: Vec<serde_json::Value>,
    /// Casters, bakes, scale.
    pub settings: serde_json::Value,
}

/// Writes every buffer and `meta.json`; returns the bytes written.
pub fn write_dump(dir: &Path, buffers: &PenumbraBuffers, meta: &DumpMeta) -> Result<u64, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    let UVec2 { x: w, y: h } = buffers.size;
    let mut files = serde_json::Map::new();
    let mut bytes = 0;
    for b in &buffers.buffers {
        let mut shape = vec![h as usize, w as usize];
        if b.channels > 1 {
            shape.push(b.channels as usize);
        }
        let file = format!("{}.npy", b.name);
        let path = dir.join(&file);
        penumbra_reference::npy::write_f32(&path, &shape, &b.data)
            .map_err(|e| format!("writing {}: {e}", path.display()))?;
        bytes += std::fs::metadata(&path).map_or(0, |m| m.len());
        files.insert(
            b.name.clone(),
            serde_json::json!({ "file": file, "shape": shape, "dtype": "float32" }),
        );
    }
    let json = serde_json::json!({
        "scene": meta.scene,
        "size": [w, h],
        "camera": {
            "eye": meta.eye.to_array(),
            "target": meta.target.to_array(),
            "up": [0.0, 1.0, 0.0],
            "fov_deg": meta.fov_deg,
            "projection": "pinhole, vertical field of view",
        },
        "lights": meta.lights,
        "buffers": files,
        "meaning": {
            "depth": "distance from the eye to the surface along the pixel-centre ray, scene units (metres); NaN: background",
            "normal": "world-space unit normal the passes read (deferred G-buffer); NaN: background",
            "visibility_<light>": "the distance-field shadow mask the lighting pass reads for that light, 1 = lit; includes the surface's own shadow (n . l); 1 on background",
            "ao": "distance-field ambient occlusion the lighting pass reads, before contrast and min occlusion: 1 = open; NaN: background (with --ao-max-distance)",
            "ssao": "Bevy's ScreenSpaceAmbientOcclusion visibility (spatially denoised, as its lighting reads it): 1 = open; NaN: background (with --ssao and no --ao-max-distance)",
            "bent_normal": "world-space unit bent normal (mean unoccluded direction) of the distance-field AO; NaN: background (with --ao-max-distance)",
            "face_normal": "world-space unit normal of the triangle at the pixel centre, by its winding (the face-normal prepass); NaN: no triangle drawn (background)",
            "rows": "row 0 is the top of the image; pixel (i, j) is sampled at its centre",
        },
        "settings": meta.settings,
    });
    let path = dir.join("meta.json");
    let text = serde_json::to_string_pretty(&json).map_err(|e| e.to_string())?;
    std::fs::write(&path, &text).map_err(|e| format!("writing {}: {e}", path.display()))?;
    Ok(bytes + text.len() as u64)
}

/// The camera's distance-field AO settings as `meta.json` describes them (null: off).
pub fn ao_summary(
    ao: Option<&penumbra::prelude::DistanceFieldAmbientOcclusion>,
) -> serde_json::Value {
    ao.map_or(serde_json::Value::Null, |a| {
        serde_json::json!({
            "max_occlusion_distance": a.max_occlusion_distance,
            "cone_count": a.cone_count,
            "steps_per_cone": a.steps_per_cone,
            "trace_resolution_divisor": a.trace_resolution_divisor,
            "surface_bias": a.surface_bias,
            "occlusion_contrast": a.occlusion_contrast,
            "min_occlusion": a.min_occlusion,
        })
    })
}

/// Every light as `meta.json` describes it: name (as in `visibility_<name>`), kind,
/// travel direction or position, source size, distance-field shadow settings.
pub fn light_summaries(world: &mut bevy::prelude::World) -> Vec<serde_json::Value> {
    use bevy::prelude::*;
    use penumbra::prelude::DistanceFieldShadows;
    let mut query = world.query::<(
        Entity,
        Option<&Name>,
        &GlobalTransform,
        Option<&DirectionalLight>,
        Option<&PointLight>,
        Option<&SpotLight>,
        Option<&DistanceFieldShadows>,
    )>();
    let mut out = Vec::new();
    for (entity, name, transform, directional, point, spot, shadows) in query.iter(world) {
        let buffer = format!(
            "visibility_{}",
            penumbra::df::buffer_dump::light_name(entity, name)
        );
        let name = name.map_or_else(|| entity.to_string(), |n| n.as_str().to_string());
        let shadows = shadows.map(|s| {
            serde_json::json!({
                "angular_diameter_rad": s.angular_diameter,
                "max_distance": s.max_distance,
                "max_view_distance": s.max_view_distance,
                "max_steps": s.max_steps,
                "bias": s.bias,
                "shaping": s.shaping,
                "half_resolution": s.half_resolution,
            })
        });
        let position = transform.translation().to_array();
        let light = if directional.is_some() {
            serde_json::json!({
                "kind": "directional",
                "direction": transform.forward().as_vec3().to_array(),
                "angle_deg": shadows.as_ref().map(|s| s["angular_diameter_rad"].as_f64().unwrap_or(0.0).to_degrees()),
            })
        } else if let Some(p) = point {
            serde_json::json!({ "kind": "point", "position": position, "radius": p.radius })
        } else if let Some(s) = spot {
            serde_json::json!({
                "kind": "spot",
                "position": position,
                "radius": s.radius,
                "direction": transform.forward().as_vec3().to_array(),
                "outer_angle_rad": s.outer_angle,
            })
        } else {
            continue;
        };
        let mut light = light;
        light["name"] = name.into();
        light["buffer"] = if shadows.is_some() {
            buffer.into()
        } else {
            serde_json::Value::Null
        };
        light["distance_field_shadows"] = shadows.unwrap_or(serde_json::Value::Null);
        out.push(light);
    }
    out
}
