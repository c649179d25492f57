//! The `subsurface` example runs headless (in process) and its screenshot matches the
//! reference kept in `assets/reference/subsurface.png`; the same scene with `--no-sss`
//! (the skin unscattered) does not.
//!
//! To accept a deliberate change: `PENUMBRA_BLESS=1 cargo test --test subsurface_example`,
//! then look at the new reference before committing it.

#[path = "../examples/subsurface.rs"]
#[allow(dead_code, reason = "the example's main is not used here")]
mod subsurface;

use penumbra_test::{Tolerance, check_golden, compare_rgba8, gpu_or_skip, image, output_dir};
use std::path::PathBuf;
use subsurface::Options;

/// Frames before the capture.
const FRAMES: &str = "8";

fn capture(extra: &[&str]) -> image::RgbaImage {
    let dir = output_dir();
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join(format!("subsurface.headless{}.png", extra.concat()));
    let args = ["--headless", "--frames", FRAMES, "--size", "256x256"];
    let options = Options::parse(
        args.iter()
            .chain(extra)
            .map(|s| s.to_string())
            .chain(["--out".to_string(), out.display().to_string()]),
    )
    .unwrap();
    subsurface::run_headless(&options).unwrap();
    image::open(&out).unwrap().to_rgba8()
}

#[test]
fn subsurface_example_matches_reference() {
    if !gpu_or_skip("subsurface_example_matches_reference") {
        return;
    }
    let actual = capture(&[]);
    let reference =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/reference/subsurface.png");
    check_golden("subsurface", &actual, &reference, &Tolerance::GOLDEN);
    // Without scattering the skin's shadow edges are sharp and dark: a different image.
    let unscattered = capture(&["--no-sss"]);
    let cmp = compare_rgba8(&unscattered, &actual, &Tolerance::GOLDEN);
    assert!(!cmp.passed, "scattering changed nothing: {cmp}");
}
