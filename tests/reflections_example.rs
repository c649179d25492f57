//! The `reflections` example runs headless (in process) and its screenshot matches the
//! reference kept in `assets/reference/reflections.png`; the same scene with
//! `--no-reflections` does not.
//!
//! To accept a deliberate change: `PENUMBRA_BLESS=1 cargo test --test reflections_example`,
//! then look at the new reference before committing it.

#[path = "../examples/reflections.rs"]
#[allow(dead_code, reason = "the example's main is not used here")]
mod reflections;

use penumbra_test::{Tolerance, check_golden, compare_rgba8, gpu_or_skip, image, output_dir};
use reflections::Options;
use std::path::PathBuf;

/// Frames before the capture.
const FRAMES: &str = "8";

fn capture(extra: &[&str]) -> image::RgbaImage {
    let dir = output_dir();
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join(format!("reflections.headless{}.png", extra.concat()));
    let args = ["--headless", "--frames", FRAMES, "--size", "256x256"];
    let options = Options::parse(
        args.iter()
            .chain(extra)
            .map(|s| s.to_string())
            .chain(["--out".to_string(), out.display().to_string()]),
    )
    .unwrap();
    reflections::run_headless(&options).unwrap();
    image::open(&out).unwrap().to_rgba8()
}

#[test]
fn reflections_example_matches_reference() {
    if !gpu_or_skip("reflections_example_matches_reference") {
        return;
    }
    let actual = capture(&[]);
    let reference =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/reference/reflections.png");
    check_golden("reflections", &actual, &reference, &Tolerance::GOLDEN);
    // Without reflections the wet street shows no signs: a different image.
    let plain = capture(&["--no-reflections"]);
    let cmp = compare_rgba8(&plain, &actual, &Tolerance::GOLDEN);
    assert!(!cmp.passed, "reflections changed nothing: {cmp}");
}
