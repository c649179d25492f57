//! The scene viewer (`examples/viewer.rs`):
//!
//! - its command line and its scene checks reject bad input with the flag or the problem
//!   named (table tests, no GPU);
//! - headless on every scene in `../shared/scenes` and the showcase room: no NaN or Inf
//!   in the dumped buffers, an image that is not blank, the casters baked, each
//!   visibility mask within [0, 1] and shadowed somewhere where casters stand between a
//!   light and receivers; the dump's files and `meta.json` are as documented;
//! - the Cornell box's image matches `assets/reference/viewer_cornell.png`.
//!
//! To accept a deliberate change of the golden image:
//! `PENUMBRA_BLESS=1 cargo test --test viewer`, then look at it before committing.

#[path = "../examples/viewer.rs"]
#[allow(dead_code, reason = "the example's main is not used here")]
mod viewer;

use penumbra_test::{Tolerance, check_golden, gpu_or_skip, image, output_dir};
use std::path::{Path, PathBuf};
use viewer::cli::Args;

fn args(list: &[&str]) -> Result<Args, String> {
    Args::parse_from_args(std::iter::once("viewer").chain(list.iter().copied()))
        .map_err(|e| e.to_string())
}

#[test]
fn flags_take_both_forms_and_negative_vectors() {
    let a = args(&[
        "scene.glb",
        "--headless",
        "--sun=-1,-0.6,-0.5",
        "--eye",
        "-3,2,-1",
        "--target=0,0,0",
        "--fov",
        "30",
        "--point",
        "1,-2,3",
        "--radius=0.25",
        "--point=4,5,6",
        "--size",
        "64x32",
    ])
    .unwrap();
    assert_eq!(a.sun, Some(bevy::math::Vec3::new(-1.0, -0.6, -0.5)));
    assert_eq!(a.eye, Some(bevy::math::Vec3::new(-3.0, 2.0, -1.0)));
    assert_eq!(a.points.len(), 2);
    assert_eq!((a.radius(0), a.radius(1)), (0.25, 0.0));
    assert_eq!(a.size, Some(bevy::math::UVec2::new(64, 32)));
    assert_eq!(a.fov, 30.0);
}

#[test]
fn absurd_flags_are_rejected_with_the_flag_named() {
    let cases: &[(&[&str], &str)] = &[
        (&["--size", "-64x64"], "--size"),
        (&["--size", "0x64"], "--size"),
        (&["--size", "64"], "--size"),
        (&["--size", "100000x64"], "--size"),
        (&["--fov", "0"], "--fov"),
        (&["--fov", "180"], "--fov"),
        (&["--fov", "-10"], "--fov"),
        (&["--fov", "nan"], "--fov"),
        (&["--eye", "nan,0,0"], "--eye"),
        (&["--eye", "1,2"], "--eye"),
        (&["--target", "inf,0,0"], "--target"),
        (&["--eye", "3e38,0,0"], "--eye"),
        (&["--target", "0,-2e7,0"], "--target"),
        (&["--point", "1,1,1e8"], "--point"),
        (&["--sun", "0,0,0"], "--sun"),
        (&["--sun=NaN,1,0"], "--sun"),
        (&["--angle", "-1"], "--angle"),
        (&["--angle", "90"], "--angle"),
        (&["--point", "1,1,1", "--radius", "-0.5"], "--radius"),
        (&["--radius", "0.5"], "--radius"),
        (&["--frames", "0"], "--frames"),
        (&["--eye", "1,1,1", "--target", "1,1,1"], "--eye"),
        (&["--eye", "0,5,0", "--target", "0,0,0"], "--eye"),
        (&["--dump", "out"], "--dump"),
        (&["--headless", "--plain", "--dump", "out"], "--dump"),
        (&["--ao-max-distance", "0"], "--ao-max-distance"),
        (&["--ao-max-distance", "-2"], "--ao-max-distance"),
        (&["--ao-max-distance", "nan"], "--ao-max-distance"),
        (&["--plain", "--ao-max-distance", "2"], "--ao-max-distance"),
        (&["--bogus"], "--bogus"),
    ];
    for (list, flag) in cases {
        let err = args(list).expect_err(&format!("{list:?} was accepted"));
        assert!(
            err.contains(flag),
            "{list:?}: the error does not name {flag}: {err}"
        );
    }
}

/// A scratch file under the test output directory.
fn scratch(name: &str, bytes: &[u8]) -> PathBuf {
    let dir = output_dir().join("viewer_inputs");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

#[test]
fn bad_scene_files_get_one_clear_error() {
    let minimal = |extra: &str| {
        format!(r#"{{"asset":{{"version":"2.0"}}{extra},"scenes":[{{"nodes":[]}}],"scene":0}}"#)
    };
    let cases: Vec<(PathBuf, &str)> = vec![
        (output_dir().join("no/such/scene.glb"), "cannot read"),
        (scratch("text.glb", b"hello, not a glTF"), "not a valid glTF 2.0"),
        (scratch("scene.obj", b"v 0 0 0"), "not a .glb or .gltf"),
        (
            scratch(
                "draco.gltf",
                minimal(r#","extensionsUsed":["KHR_draco_mesh_compression"],"extensionsRequired":["KHR_draco_mesh_compression"]"#)
                    .as_bytes(),
            ),
            "KHR_draco_mesh_compression",
        ),
        (
            scratch(
                "meshopt.gltf",
                minimal(r#","extensionsUsed":["EXT_meshopt_compression"],"extensionsRequired":["EXT_meshopt_compression"]"#)
                    .as_bytes(),
            ),
            "EXT_meshopt_compression",
        ),
        (
            scratch(
                "missing_bin.gltf",
                minimal(r#","buffers":[{"uri":"nowhere.bin","byteLength":64}]"#).as_bytes(),
            ),
            "nowhere.bin",
        ),
        (
            scratch(
                "short_bin.gltf",
                minimal(r#","buffers":[{"uri":"short.bin","byteLength":64}]"#).as_bytes(),
            ),
            "truncated",
        ),
    ];
    scratch("short.bin", &[0; 16]);
    for (path, expected) in &cases {
        let err = viewer::input::check_scene(path).expect_err(&format!("{path:?} accepted"));
        assert!(err.contains(expected), "{path:?}: {err}");
        assert_eq!(err.lines().count(), 1, "one line: {err}");
    }
    // A truncated binary glTF (a real file cut in half).
    if let Some(dir) = scenes_dir() {
        let bytes = std::fs::read(dir.join("CornellBox.glb")).unwrap();
        let cut = scratch("cut.glb", &bytes[..bytes.len() / 2]);
        let err = viewer::input::check_scene(&cut).expect_err("a cut file was accepted");
        assert!(err.contains("cut.glb"), "{err}");
        viewer::input::check_scene(&dir.join("CornellBox.glb")).unwrap();
        viewer::input::check_scene(&dir.join("PalmTree/PalmTree.gltf")).unwrap();
    }
}

fn scenes_dir() -> Option<PathBuf> {
    penumbra_testkit::shared_dir("viewer", env!("CARGO_MANIFEST_DIR"), "scenes")
}

/// Reads a float32 `.npy` written by the viewer: (shape, values).
fn read_npy(path: &Path) -> (Vec<usize>, Vec<f32>) {
    penumbra_reference::npy::read_f32(path).unwrap_or_else(|e| panic!("{e}"))
}

/// What one headless run produced.
struct Run {
    image: image::RgbaImage,
    meta: serde_json::Value,
    dir: PathBuf,
}

fn run(name: &str, extra: &[&str]) -> Run {
    let out_dir = output_dir().join("viewer").join(name);
    let _ = std::fs::remove_dir_all(&out_dir);
    std::fs::create_dir_all(&out_dir).unwrap();
    let png = out_dir.join("frame.png");
    let dump = out_dir.join("dump");
    let (png_s, dump_s) = (png.display().to_string(), dump.display().to_string());
    let mut list = vec!["--headless", "--size", "128x128", "--frames", "3"];
    list.extend_from_slice(extra);
    list.extend_from_slice(&["--out", &png_s, "--dump", &dump_s]);
    let a = args(&list).unwrap();
    viewer::run_headless(&a).unwrap_or_else(|e| panic!("{name}: {e}"));
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dump.join("meta.json")).unwrap()).unwrap();
    Run {
        image: image::open(&png).unwrap().to_rgba8(),
        meta,
        dir: dump,
    }
}

/// Not one colour: a scene seen against the sky (the fox) is mostly background, so the
/// bar is lower than `penumbra_test::assert_not_blank`'s.
fn assert_not_blank(name: &str, img: &image::RgbaImage) {
    let mut colours: Vec<[u8; 3]> = img.pixels().map(|p| [p[0], p[1], p[2]]).collect();
    let sky = colours[0];
    let other = colours.iter().filter(|c| **c != sky).count() as f64 / colours.len() as f64;
    colours.sort_unstable();
    colours.dedup();
    assert!(
        colours.len() > 100,
        "{name}: only {} colours",
        colours.len()
    );
    assert!(
        other > 0.01,
        "{name}: {:.1} % of pixels differ from the corner",
        other * 100.0
    );
    assert!(
        img.pixels().all(|p| p[3] == 255),
        "{name}: transparent pixels"
    );
}

/// The checks every scene passes; returns the fraction of shadowed (< 0.5) surface
/// pixels per light.
fn check_run(name: &str, r: &Run, casters: u64) -> Vec<(String, f64)> {
    assert_not_blank(name, &r.image);
    let c = &r.meta["settings"]["casters"];
    assert_eq!(c["casters"].as_u64(), Some(casters), "{name}: {c}");
    assert_eq!(
        r.meta["settings"]["baked"].as_u64(),
        Some(casters),
        "{name}: not all baked"
    );
    let (shape, depth) = read_npy(&r.dir.join("depth.npy"));
    assert_eq!(shape, [128, 128], "{name}");
    assert!(
        depth
            .iter()
            .all(|d| d.is_nan() || (d.is_finite() && *d > 0.0)),
        "{name}: depth"
    );
    let surface: Vec<bool> = depth.iter().map(|d| d.is_finite()).collect();
    assert!(surface.iter().any(|&s| s), "{name}: no surface in view");
    let (shape, normal) = read_npy(&r.dir.join("normal.npy"));
    assert_eq!(shape, [128, 128, 3], "{name}");
    for (i, n) in normal.chunks_exact(3).enumerate() {
        if surface[i] {
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            assert!((len - 1.0).abs() < 1e-2, "{name}: normal {n:?} at {i}");
        } else {
            assert!(
                n.iter().all(|v| v.is_nan()),
                "{name}: background normal {n:?}"
            );
        }
    }
    let mut shadowed = Vec::new();
    for light in r.meta["lights"].as_array().unwrap() {
        let Some(buffer) = light["buffer"].as_str() else {
            continue;
        };
        let (shape, vis) = read_npy(&r.dir.join(format!("{buffer}.npy")));
        assert_eq!(shape, [128, 128], "{name}: {buffer}");
        assert!(
            vis.iter().all(|v| (0.0..=1.0).contains(v)),
            "{name}: {buffer} outside [0, 1]"
        );
        let on_surface = vis.iter().zip(&surface).filter(|(_, s)| **s);
        let n = surface.iter().filter(|s| **s).count() as f64;
        let dark = on_surface.filter(|(v, _)| **v < 0.5).count() as f64 / n;
        shadowed.push((buffer.to_string(), dark));
    }
    shadowed
}

#[test]
fn viewer_renders_every_shared_scene_and_dumps_its_buffers() {
    if !gpu_or_skip("viewer_renders_every_shared_scene_and_dumps_its_buffers") {
        return;
    }
    let Some(dir) = scenes_dir() else { return };
    let scene = |f: &str| dir.join(f).display().to_string();
    // The Cornell box: a point light under the ceiling; the blocks shadow the floor.
    let cornell = scene("CornellBox.glb");
    let r = run(
        "cornell",
        &[
            &cornell,
            "--eye=-278,273,800",
            "--target=-278,273,-280",
            "--fov",
            "40",
            "--point=-278,500,-280",
            "--radius",
            "20",
            "--no-scene-lights",
        ],
    );
    let s = check_run("cornell", &r, 6);
    let reference =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/reference/viewer_cornell.png");
    check_golden("viewer_cornell", &r.image, &reference, &TOLERANCE);
    assert_eq!(s.len(), 2, "{s:?}");
    for (buffer, dark) in &s {
        assert!(
            *dark > 0.05 && *dark < 0.95,
            "cornell: {buffer} shadowed {dark}"
        );
    }
    // The circuit board: its own sun and ours; the spheres and cubes shadow the board.
    let r = run("depth_of_field", &[&scene("DepthOfFieldExample.glb")]);
    let s = check_run("depth_of_field", &r, 16);
    assert_eq!(s.len(), 2, "{s:?}");
    assert!(s.iter().all(|(_, d)| *d > 0.01), "{s:?}");
    // The same view with Bevy's SSAO: its visibility is dumped as `ssao`, background NaN
    // where the depth is, and it occludes beside the spheres and cubes.
    let r = run(
        "depth_of_field_ssao",
        &[&scene("DepthOfFieldExample.glb"), "--ssao"],
    );
    let (_, depth) = read_npy(&r.dir.join("depth.npy"));
    let (shape, ssao) = read_npy(&r.dir.join("ssao.npy"));
    assert_eq!(shape, [128, 128]);
    assert!(
        depth
            .iter()
            .zip(&ssao)
            .all(|(d, a)| d.is_nan() == a.is_nan())
    );
    let surface: Vec<f32> = ssao.iter().copied().filter(|a| !a.is_nan()).collect();
    assert!(surface.iter().all(|a| (0.0..=1.0).contains(a)));
    let occluded = surface.iter().filter(|&&a| a < 0.8).count();
    assert!(
        occluded > 20 && occluded < surface.len() / 2,
        "ssao: {occluded} of {} occluded",
        surface.len()
    );
    assert!(!r.dir.join("ao.npy").exists());
    // The palm tree on its island (framing the 64 m island would make it a dot): its
    // leaves and trunk shadow the ground.
    let r = run(
        "palm_tree",
        &[
            &scene("PalmTree/PalmTree.gltf"),
            "--sun=-0.3,-1,-0.2",
            "--eye=5,4,7",
            "--target=0,1.8,-0.5",
        ],
    );
    let s = check_run("palm_tree", &r, 10);
    assert!(s[0].1 > 0.005, "{s:?}");
    // The fox is skinned: no mesh caster; capsules fitted to its joints cast instead,
    // on a ground the viewer stands it on (a character stands on nothing in its file).
    let r = run("fox", &[&scene("Fox.glb")]);
    let s = check_run("fox", &r, 0);
    let c = &r.meta["settings"]["casters"];
    assert_eq!(c["skipped_skinned"].as_u64(), Some(0), "{c}");
    assert_eq!(c["capsule_meshes"].as_u64(), Some(1), "{c}");
    let capsules = c["capsules"].as_u64().unwrap_or(0);
    // At least a few joints, at most four capsules a joint (24 joints).
    assert!((6..=96).contains(&capsules), "{c}");
    assert!(r.meta["settings"]["ground"].is_object(), "fox: no ground");
    assert!(s[0].1 > 0.02, "fox: no shadow on its ground: {s:?}");
    // `--no-ground`: the fox alone against the sky.
    let r = run("fox_no_ground", &[&scene("Fox.glb"), "--no-ground"]);
    assert!(
        r.meta["settings"]["ground"].is_null(),
        "fox: a ground anyway"
    );
}

/// The examples' golden-image tolerance.
const TOLERANCE: Tolerance = Tolerance::GOLDEN;

/// The example's binary, built by `cargo test` next to the test binaries.
fn viewer_binary() -> Option<PathBuf> {
    let exe = std::env::current_exe().ok()?;
    let bin = exe.parent()?.parent()?.join("examples").join("viewer");
    if bin.is_file() {
        return Some(bin);
    }
    assert!(std::env::var_os("CI").is_none(), "{bin:?} was not built");
    eprintln!("skipped: {bin:?} not built (cargo test --example viewer builds it)");
    None
}

#[test]
fn the_binary_exits_1_on_bad_files_and_2_on_bad_flags() {
    let Some(bin) = viewer_binary() else { return };
    let missing = output_dir().join("no/such/scene.glb");
    let cases: &[(&[&str], i32, &str)] = &[
        (&[missing.to_str().unwrap(), "--headless"], 1, "cannot read"),
        (&["scene.glb", "--fov", "0"], 2, "--fov"),
        (&["scene.glb", "--sun=0,0,0"], 2, "--sun"),
    ];
    for (list, code, expected) in cases {
        let out = std::process::Command::new(&bin)
            .args(*list)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(*code), "{list:?}: {stderr}");
        assert!(stderr.contains(expected), "{list:?}: {stderr}");
    }
}

#[test]
fn a_scene_without_meshes_renders_an_empty_frame() {
    if !gpu_or_skip("a_scene_without_meshes_renders_an_empty_frame") {
        return;
    }
    let empty = scratch(
        "empty.gltf",
        br#"{"asset":{"version":"2.0"},"scenes":[{"nodes":[0]}],"nodes":[{"name":"nothing"}],"scene":0}"#,
    );
    let r = run("empty", &[empty.to_str().unwrap()]);
    let (_, depth) = read_npy(&r.dir.join("depth.npy"));
    assert!(
        depth.iter().all(|d| d.is_nan()),
        "an empty scene has no surface"
    );
    let sky = r.image.get_pixel(0, 0);
    assert!(
        r.image.pixels().all(|p| p == sky),
        "an empty frame is the clear colour"
    );
    assert_eq!(r.meta["settings"]["casters"]["casters"].as_u64(), Some(0));
}

/// A 2 m quad in y = 0 facing up: 4 positions (48 bytes) then 6 `u16` indices (12).
fn quad_buffer() -> Vec<u8> {
    let mut bytes = Vec::new();
    for p in [
        [-1.0f32, 0.0, -1.0],
        [1.0, 0.0, -1.0],
        [1.0, 0.0, 1.0],
        [-1.0, 0.0, 1.0],
    ] {
        bytes.extend(p.iter().flat_map(|v| v.to_le_bytes()));
    }
    bytes.extend([0u16, 2, 1, 0, 3, 2].iter().flat_map(|i| i.to_le_bytes()));
    bytes
}

#[test]
fn missing_and_broken_textures_are_named_and_the_scene_still_renders() {
    if !gpu_or_skip("missing_and_broken_textures_are_named_and_the_scene_still_renders") {
        return;
    }
    let Some(bin) = viewer_binary() else { return };
    // A valid glTF quad whose material's textures are a missing PNG and a JPEG file of
    // garbage: the header checks pass; Bevy names each file in one error and the scene
    // renders without them (degraded, not fatal), its caster baked.
    scratch("quad.bin", &quad_buffer());
    let gltf = r#"{"asset":{"version":"2.0"},
        "buffers":[{"uri":"quad.bin","byteLength":60}],
        "bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":48},{"buffer":0,"byteOffset":48,"byteLength":12}],
        "accessors":[{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-1,0,-1],"max":[1,0,1]},
            {"bufferView":1,"componentType":5123,"count":6,"type":"SCALAR"}],
        "images":[{"uri":"missing.png"},{"uri":"broken.jpg"}],
        "textures":[{"source":0},{"source":1}],
        "materials":[{"pbrMetallicRoughness":{"baseColorTexture":{"index":0},"metallicRoughnessTexture":{"index":1}}}],
        "meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1,"material":0}]}],
        "nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}],"scene":0}"#;
    scratch("broken.jpg", b"\xff\xd8\xff not a JPEG at all");
    let scene = scratch("missing_image.gltf", gltf.as_bytes());
    // `--out` into a folder that does not exist yet: the viewer makes it.
    let out_dir = output_dir().join("viewer_inputs/new_folder");
    let _ = std::fs::remove_dir_all(&out_dir);
    let out_png = out_dir.join("missing_image.png");
    let dump = output_dir().join("viewer_inputs/missing_image_dump");
    let out = std::process::Command::new(&bin)
        .args([
            scene.to_str().unwrap(),
            "--headless",
            "--size",
            "32x32",
            "--frames",
            "1",
        ])
        .arg("--out")
        .arg(&out_png)
        .arg("--dump")
        .arg(&dump)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    for file in ["missing.png", "broken.jpg"] {
        assert_eq!(
            stderr.lines().filter(|l| l.contains(file)).count(),
            1,
            "{file}: {stderr}"
        );
    }
    assert!(out_png.is_file());
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dump.join("meta.json")).unwrap()).unwrap();
    assert_eq!(meta["settings"]["baked"].as_u64(), Some(1), "{meta}");
}

#[test]
fn a_glb_whose_embedded_image_fails_is_drawn_without_its_textures() {
    if !gpu_or_skip("a_glb_whose_embedded_image_fails_is_drawn_without_its_textures") {
        return;
    }
    let Some(bin) = viewer_binary() else { return };
    // A GLB quad whose base colour is an embedded "PNG" of garbage: Bevy's glTF loader
    // fails the whole scene on it; the viewer loads it again without its textures, warns
    // once, and renders it, its caster baked.
    let mut data = quad_buffer();
    data.extend(b"\x89PNG\r\n\x1a\n not a PNG at all");
    while !data.len().is_multiple_of(4) {
        data.push(0);
    }
    let image_len = data.len() - 60;
    let mut json = format!(
        r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"byteLength":{}}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":12}},
            {{"buffer":0,"byteOffset":60,"byteLength":{image_len}}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-1,0,-1],"max":[1,0,1]}},
            {{"bufferView":1,"componentType":5123,"count":6,"type":"SCALAR"}}],
        "images":[{{"bufferView":2,"mimeType":"image/png"}}],
        "textures":[{{"source":0}}],
        "materials":[{{"pbrMetallicRoughness":{{"baseColorTexture":{{"index":0}},"baseColorFactor":[0.8,0.2,0.2,1]}}}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1,"material":0}}]}}],
        "nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0}}"#,
        data.len()
    )
    .into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let total = 12 + 8 + json.len() + 8 + data.len();
    let mut glb = Vec::new();
    glb.extend(b"glTF");
    glb.extend(2u32.to_le_bytes());
    glb.extend((total as u32).to_le_bytes());
    glb.extend((json.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(&json);
    glb.extend((data.len() as u32).to_le_bytes());
    glb.extend(b"BIN\0");
    glb.extend(&data);
    let scene = scratch("broken_embedded_image.glb", &glb);
    let out_png = output_dir().join("viewer_inputs/broken_embedded_image.png");
    let dump = output_dir().join("viewer_inputs/broken_embedded_image_dump");
    let out = std::process::Command::new(&bin)
        .args([scene.to_str().unwrap(), "--headless", "--size", "32x32"])
        .args(["--frames", "1"])
        .arg("--out")
        .arg(&out_png)
        .arg("--dump")
        .arg(&dump)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert_eq!(
        stderr
            .lines()
            .filter(|l| l.contains("without its textures"))
            .count(),
        1,
        "{stderr}"
    );
    assert!(out_png.is_file());
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dump.join("meta.json")).unwrap()).unwrap();
    assert_eq!(meta["settings"]["baked"].as_u64(), Some(1), "{meta}");
}
