//! Ray-traced truth for a scene viewer dump: reads `DIR/meta.json` (scene, camera, sun,
//! AO reach) written by `viewer --dump DIR`, ray-traces the scene's triangles
//! (`penumbra_reference::scene_truth`, no distance field, no Python) and prints, as one
//! JSON line, how far the dumped sun visibility and DFAO are from truth.
//!
//! ```text
//! cargo run --example viewer -- SCENE.glb --headless --size 128x96 --sun=-1,-0.6,-0.5 \
//!     --angle 3 --no-scene-lights --ao-max-distance 1 --dump DIR
//! cargo run --release --example scene_truth -- DIR [--facing raster|all-faces] [--write]
//! ```
//!
//! `--facing all-faces` follows the Embree oracles' convention (`../shared/tools`), to
//! cross-check them; `raster` (default) is what Bevy draws. `--write` saves
//! `truth_sun.npy`, `truth_ao.npy`, `truth_back.npy` (1 where the camera sees a
//! triangle's back) and `truth_normal.npy` (the normal shadows test against) beside the
//! dump.

use bevy::math::Vec3;
use penumbra_reference::camera::PerspectiveCamera;
use penumbra_reference::npy;
use penumbra_reference::posed_gltf::Pose;
use penumbra_reference::scene_truth::{self, Facing, SceneTriangles, TruthError};
use std::path::Path;

/// Rays per pixel toward the sun's disc.
pub const SUN_SPP: u32 = 64;
/// Cosine-weighted rays per pixel for AO.
pub const AO_SPP: u32 = 128;

/// A dump compared with truth.
#[derive(Clone, Debug, Default)]
pub struct DumpCheck {
    /// The sun's visibility (`None`: no sun buffer in the dump).
    pub sun: Option<TruthError>,
    /// DFAO (`None`: no `ao` buffer).
    pub ao: Option<TruthError>,
    /// Mean lit fraction over surface pixels: ours, truth.
    pub lit: (f64, f64),
    /// Mean AO over surface pixels: ours, truth.
    pub ao_mean: (f64, f64),
    /// Triangles traced.
    pub triangles: usize,
    /// The distance-field atlas bytes the scene's fields fill (from `meta.json`).
    pub atlas_used_bytes: Option<f64>,
    /// Of the sun's error on shadowed pixels, the share on pixels whose dumped G-buffer
    /// normal faces away from the sun while the triangle the truth hit faces it (a
    /// smooth or normal-mapped normal past the terminator): the surface's own shadow
    /// darkens them, ray tracing lights them, and shading (`n · l ≤ 0` with that
    /// normal) leaves them unlit either way. `None` without a sun or a `normal` buffer.
    pub shading_turned_away: Option<f64>,
    /// Of the sun's error on shadowed pixels, the share on pixels where the camera sees a
    /// triangle's back (an open double-sided sheet's underside, as at a terrain's cut
    /// edge): a solid field has its inside there. `None` without a sun.
    pub back_faces: Option<f64>,
    /// Of the pixels where the truth meets a triangle, the share whose dumped
    /// `face_normal` (the face-normal prepass) is that triangle's plane within
    /// [`FACET_DEGREES`] (either side). `None` without a `face_normal` buffer.
    pub facets: Option<f64>,
}

/// How far a dumped face normal may lie from the truth's triangle and count as its.
pub const FACET_DEGREES: f32 = 2.0;

fn vec3(v: &serde_json::Value) -> Option<Vec3> {
    let a = v.as_array()?;
    Some(Vec3::new(
        a.first()?.as_f64()? as f32,
        a.get(1)?.as_f64()? as f32,
        a.get(2)?.as_f64()? as f32,
    ))
}

fn mean_where(values: &[f32], keep: impl Fn(usize) -> bool) -> f64 {
    let (s, n) = values
        .iter()
        .enumerate()
        .filter(|(i, v)| keep(*i) && !v.is_nan())
        .fold((0.0, 0usize), |(s, n), (_, v)| (s + f64::from(*v), n + 1));
    if n == 0 { 0.0 } else { s / n as f64 }
}

/// Compares the dump in `dir` with truth; `write` saves the truth arrays beside it.
pub fn check_dump(dir: &Path, facing: Facing, write: bool) -> Result<DumpCheck, String> {
    let text = std::fs::read_to_string(dir.join("meta.json"))
        .map_err(|e| format!("{}: {e}", dir.display()))?;
    let meta: serde_json::Value = serde_json::from_str(&text).map_err(|e| e.to_string())?;
    let scene = meta["scene"].as_str().ok_or("meta.json: no scene")?;
    let cam = &meta["camera"];
    let (eye, target) = (
        vec3(&cam["eye"]).ok_or("meta.json: camera eye")?,
        vec3(&cam["target"]).ok_or("meta.json: camera target")?,
    );
    let fov = cam["fov_deg"].as_f64().ok_or("meta.json: fov")? as f32;
    let (w, h) = (
        meta["size"][0].as_u64().ok_or("meta.json: size")? as u32,
        meta["size"][1].as_u64().ok_or("meta.json: size")? as u32,
    );
    let camera = PerspectiveCamera::looking_at(eye, target, fov.to_radians(), w, h);
    // A scene the viewer posed (`--animation`) is posed the same way here.
    let pose = &meta["settings"]["pose"];
    let triangles = match (pose["animation"].as_u64(), pose["time"].as_f64()) {
        (Some(animation), Some(time)) => SceneTriangles::from_gltf_posed(
            Path::new(scene),
            facing,
            Some(Pose {
                animation: animation as usize,
                time: time as f32,
            }),
        )?,
        _ => SceneTriangles::from_gltf(Path::new(scene), facing)?,
    };
    // The viewer's `--ground`: a single-sided square facing up.
    let ground = &meta["settings"]["ground"];
    let triangles = match (vec3(&ground["center"]), ground["half_size"].as_f64()) {
        (Some(c), Some(h)) => {
            let h = h as f32;
            let corner = |x: f32, z: f32| c + Vec3::new(x * h, 0.0, z * h);
            let (a, b, cc, d) = (
                corner(-1.0, -1.0),
                corner(1.0, -1.0),
                corner(1.0, 1.0),
                corner(-1.0, 1.0),
            );
            // Counter-clockwise seen from above (+y): outward normal up.
            triangles.with_extra(&[[a, d, cc], [a, cc, b]], false)
        }
        _ => triangles,
    };
    let hits = scene_truth::primary_hits(&triangles, &camera, facing);
    let (_, depth) = npy::read_f32(&dir.join("depth.npy"))?;
    let mut check = DumpCheck {
        triangles: triangles.len(),
        atlas_used_bytes: meta["settings"]["atlas_used_bytes"].as_f64(),
        ..Default::default()
    };
    let surface = |i: usize| hits[i].is_some() && !depth[i].is_nan();
    let sun = meta["lights"].as_array().and_then(|lights| {
        lights
            .iter()
            .find(|l| l["kind"] == "directional" && l["buffer"].is_string())
    });
    if let Some(sun) = sun {
        let direction = vec3(&sun["direction"]).ok_or("meta.json: sun direction")?;
        let angle = sun["distance_field_shadows"]["angular_diameter_rad"]
            .as_f64()
            .unwrap_or(0.0) as f32;
        let buffer = sun["buffer"].as_str().unwrap_or_default();
        let (_, ours) = npy::read_f32(&dir.join(format!("{buffer}.npy")))?;
        let truth = scene_truth::sun_visibility(&triangles, &hits, direction, angle, SUN_SPP);
        check.sun = Some(scene_truth::compare(&ours, &truth, &depth));
        if let Ok((_, normals)) = npy::read_f32(&dir.join("normal.npy")) {
            let to_sun = -direction.normalize_or_zero();
            let turned_away = |i: usize| {
                let n = normals
                    .get(3 * i..3 * i + 3)
                    .map_or(Vec3::ZERO, |n| Vec3::new(n[0], n[1], n[2]));
                let triangle_lit = hits[i].is_some_and(|h| h.shadow_normal.dot(to_sun) > 0.0);
                n.dot(to_sun) <= 0.0 && triangle_lit
            };
            check.shading_turned_away = Some(scene_truth::shadowed_error_share(
                &ours,
                &truth,
                &depth,
                turned_away,
            ));
        }
        let back = |i: usize| hits[i].is_some_and(|h| h.back);
        check.back_faces = Some(scene_truth::shadowed_error_share(
            &ours, &truth, &depth, back,
        ));
        check.lit = (mean_where(&ours, surface), mean_where(&truth, surface));
        if write {
            let seen: Vec<f32> = (0..hits.len())
                .map(|i| f32::from(u8::from(back(i))))
                .collect();
            npy::write_f32(
                &dir.join("truth_back.npy"),
                &[h as usize, w as usize],
                &seen,
            )
            .map_err(|e| e.to_string())?;
            let normals: Vec<f32> = hits
                .iter()
                .flat_map(|h| h.map_or([f32::NAN; 3], |h| h.shadow_normal.to_array()))
                .collect();
            npy::write_f32(
                &dir.join("truth_normal.npy"),
                &[h as usize, w as usize, 3],
                &normals,
            )
            .map_err(|e| e.to_string())?;
            npy::write_f32(
                &dir.join("truth_sun.npy"),
                &[h as usize, w as usize],
                &truth,
            )
            .map_err(|e| e.to_string())?;
        }
    }
    if let Ok((_, faces)) = npy::read_f32(&dir.join("face_normal.npy")) {
        let cos = FACET_DEGREES.to_radians().cos();
        let (mut seen, mut same) = (0usize, 0usize);
        for (i, hit) in hits.iter().enumerate() {
            let Some(hit) = hit else { continue };
            seen += 1;
            let ours = faces
                .get(3 * i..3 * i + 3)
                .map_or(Vec3::NAN, |n| Vec3::new(n[0], n[1], n[2]));
            // NaN (nothing drawn there) fails the comparison.
            same += usize::from(ours.dot(hit.normal).abs() >= cos);
        }
        check.facets = Some(if seen == 0 {
            1.0
        } else {
            same as f64 / seen as f64
        });
    }
    let reach = meta["settings"]["ambient_occlusion"]["max_occlusion_distance"].as_f64();
    if let (Some(reach), true) = (reach, dir.join("ao.npy").is_file()) {
        let (_, ours) = npy::read_f32(&dir.join("ao.npy"))?;
        let truth = scene_truth::ambient_occlusion(&triangles, &hits, reach as f32, AO_SPP);
        check.ao = Some(scene_truth::compare(&ours, &truth, &depth));
        check.ao_mean = (mean_where(&ours, surface), mean_where(&truth, surface));
        if write {
            npy::write_f32(&dir.join("truth_ao.npy"), &[h as usize, w as usize], &truth)
                .map_err(|e| e.to_string())?;
        }
    }
    Ok(check)
}

#[allow(dead_code, reason = "tests include this file for `check_dump`")]
fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: scene_truth DUMP_DIR [--facing raster|all-faces] [--write]";
    let Some(dir) = args
        .iter()
        .find(|a| !a.starts_with("--") && *a != "raster" && *a != "all-faces")
    else {
        eprintln!("{usage}");
        std::process::exit(2);
    };
    let facing = match args
        .iter()
        .position(|a| a == "--facing")
        .map(|i| args.get(i + 1))
    {
        None => Facing::Raster,
        Some(Some(f)) if f == "raster" => Facing::Raster,
        Some(Some(f)) if f == "all-faces" => Facing::AllFaces,
        _ => {
            eprintln!("{usage}");
            std::process::exit(2);
        }
    };
    let write = args.iter().any(|a| a == "--write");
    match check_dump(Path::new(dir), facing, write) {
        Ok(c) => {
            let round = |v: f64| (v * 1000.0).round() / 1000.0;
            println!(
                "{}",
                serde_json::json!({
                    "shadow_shadowed_px": c.sun.map(|e| round(e.shadowed)),
                    "shadow_all_px": c.sun.map(|e| round(e.all)),
                    "lit_ours_truth": [round(c.lit.0), round(c.lit.1)],
                    "ao": c.ao.map(|e| round(e.all)),
                    "ao_ours_truth": [round(c.ao_mean.0), round(c.ao_mean.1)],
                    "triangles": c.triangles,
                    "atlas_used_bytes": c.atlas_used_bytes,
                    "shading_turned_away": c.shading_turned_away.map(round),
                    "facets": c.facets.map(round),
                    "back_faces": c.back_faces.map(round),
                })
            );
        }
        Err(e) => {
            eprintln!("scene_truth: {e}");
            std::process::exit(1);
        }
    }
}
