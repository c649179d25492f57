//! The `penumbra-bake` binary: outputs, and errors for bad arguments and files.

use penumbra_sdf::format;
use std::process::Command;

fn bake_cmd() -> Command {
    Command::new(env!("CARGO_BIN_EXE_penumbra-bake"))
}

fn temp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("penumbra_bake_{name}_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

const CUBE_OBJ: &str = "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n\
f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 4 8 7 3\nf 1 5 8 4\nf 2 3 7 6\n";

#[test]
fn bakes_obj_to_psdf_and_npy_with_sidecar() {
    let dir = temp_dir("ok");
    let mesh = dir.join("cube.obj");
    std::fs::write(&mesh, CUBE_OBJ).unwrap();
    let (psdf, npy) = (dir.join("cube.psdf"), dir.join("cube.npy"));
    let out = bake_cmd()
        .args([mesh.to_str().unwrap(), "--resolution", "20", "--out"])
        .arg(&psdf)
        .arg("--npy")
        .arg(&npy)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("12 triangles") && stdout.contains("20x20x20"),
        "{stdout}"
    );
    let v = format::from_bytes(&std::fs::read(&psdf).unwrap()).unwrap();
    assert_eq!(v.dims.to_array(), [20, 20, 20]);
    // A sample near the centre: inside, at its exact distance to the nearest face.
    let p = v.position(9, 9, 9);
    let expected = -(1.0 - p.abs().max_element()) as f32;
    assert!(
        (v.get(9, 9, 9) - expected).abs() < 1e-3,
        "{} vs {expected}",
        v.get(9, 9, 9)
    );
    let npy_bytes = std::fs::read(&npy).unwrap();
    assert_eq!(npy_bytes, format::to_npy(&v));
    let json = std::fs::read_to_string(dir.join("cube.npy.json")).unwrap();
    assert!(json.contains("\"dims\": [20, 20, 20]"), "{json}");
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn bad_arguments_and_files_fail_clearly() {
    let dir = temp_dir("bad");
    let broken = dir.join("broken.obj");
    std::fs::write(&broken, "v 0 0 0\nf 1 2 3\n").unwrap();
    let empty = dir.join("empty.obj");
    std::fs::write(&empty, "# nothing\n").unwrap();
    let cube = dir.join("cube.obj");
    std::fs::write(&cube, CUBE_OBJ).unwrap();
    let cases: Vec<(Vec<String>, i32, &str)> = vec![
        (vec![], 2, "usage"),
        (
            vec!["a.obj".into(), "--resolution".into()],
            2,
            "needs a value",
        ),
        (
            vec!["a.obj".into(), "--resolution".into(), "x".into()],
            2,
            "bad number",
        ),
        (
            vec!["a.obj".into(), "--sign".into(), "magic".into()],
            2,
            "unknown method",
        ),
        (
            vec![
                "a.obj".into(),
                "--resolution".into(),
                "8".into(),
                "--voxels-per-unit".into(),
                "3".into(),
            ],
            2,
            "only one",
        ),
        (
            vec![dir.join("missing.obj").display().to_string()],
            1,
            "missing.obj",
        ),
        (vec![broken.display().to_string()], 1, "line 2"),
        (vec![empty.display().to_string()], 1, "no triangles"),
        (
            vec![broken.with_extension("stl").display().to_string()],
            1,
            "unknown mesh format",
        ),
        // A real mesh, so that the grid's size guard (not the empty-mesh check) answers.
        (
            vec![
                cube.display().to_string(),
                "--resolution".into(),
                "100000".into(),
            ],
            1,
            "exceeds the limit",
        ),
    ];
    for (args, code, needle) in cases {
        let out = bake_cmd().args(&args).output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(code), "{args:?}: {stderr}");
        assert!(stderr.contains(needle), "{args:?}: {stderr}");
    }
    std::fs::remove_dir_all(dir).ok();
}
