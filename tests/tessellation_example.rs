//! The `tessellation` example runs headless (in process) and its screenshot matches the
//! reference kept in `assets/reference/tessellation.png`; the same scene with
//! `--tessellation off` (the 768-triangle rock) does not, nor with flat patches; the
//! wireframe view matches `assets/reference/tessellation_wireframe.png`.
//!
//! To accept a deliberate change: `PENUMBRA_BLESS=1 cargo test --test tessellation_example`,
//! then look at the new reference before committing it.

#[path = "../examples/tessellation.rs"]
#[allow(dead_code, reason = "the example's main is not used here")]
mod tessellation;

use penumbra_test::{Tolerance, check_golden, compare_rgba8, gpu_or_skip, image, output_dir};
use std::path::PathBuf;
use tessellation::Options;

/// Frames before the capture.
const FRAMES: &str = "8";

fn capture(extra: &[&str]) -> image::RgbaImage {
    let dir = output_dir();
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join(format!("tessellation.headless{}.png", extra.concat()));
    let args = ["--headless", "--frames", FRAMES, "--size", "256x256"];
    let options = Options::parse(
        args.iter()
            .chain(extra)
            .map(|s| s.to_string())
            .chain(["--out".to_string(), out.display().to_string()]),
    )
    .unwrap();
    tessellation::run_headless(&options).unwrap();
    image::open(&out).unwrap().to_rgba8()
}

#[test]
fn tessellation_example_matches_reference() {
    if !gpu_or_skip("tessellation_example_matches_reference") {
        return;
    }
    let actual = capture(&[]);
    let reference =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/reference/tessellation.png");
    check_golden("tessellation", &actual, &reference, &Tolerance::GOLDEN);
    let wireframe = capture(&["--tessellation", "wireframe"]);
    let reference = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("assets/reference/tessellation_wireframe.png");
    check_golden(
        "tessellation_wireframe",
        &wireframe,
        &reference,
        &Tolerance::GOLDEN,
    );
    // Untessellated, or flat patches: different images.
    for mode in ["off", "flat"] {
        let other = capture(&["--tessellation", mode]);
        let cmp = compare_rgba8(&other, &actual, &Tolerance::GOLDEN);
        assert!(!cmp.passed, "--tessellation {mode} changed nothing: {cmp}");
    }
}
