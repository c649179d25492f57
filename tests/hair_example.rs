//! The `hair` example runs headless (in process) and its screenshot matches the
//! reference kept in `assets/reference/hair.png`; the same scene with `--hair off`
//! does not, nor with one alpha test per pixel (`--hair per-pixel`).
//!
//! To accept a deliberate change: `PENUMBRA_BLESS=1 cargo test --test hair_example`,
//! then look at the new reference before committing it.

#[path = "../examples/hair.rs"]
#[allow(dead_code, reason = "the example's main is not used here")]
mod hair;

use hair::Options;
use penumbra_test::{Tolerance, check_golden, compare_rgba8, gpu_or_skip, image, output_dir};
use std::path::PathBuf;

/// Frames before the capture.
const FRAMES: &str = "8";

fn capture(extra: &[&str]) -> image::RgbaImage {
    let dir = output_dir();
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join(format!("hair.headless{}.png", extra.concat()));
    let args = ["--headless", "--frames", FRAMES, "--size", "256x256"];
    let options = Options::parse(
        args.iter()
            .chain(extra)
            .map(|s| s.to_string())
            .chain(["--out".to_string(), out.display().to_string()]),
    )
    .unwrap();
    hair::run_headless(&options).unwrap();
    image::open(&out).unwrap().to_rgba8()
}

#[test]
fn hair_example_matches_reference() {
    if !gpu_or_skip("hair_example_matches_reference") {
        return;
    }
    let actual = capture(&[]);
    let reference = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/reference/hair.png");
    check_golden("hair", &actual, &reference, &Tolerance::GOLDEN);
    // Without hair, or with the per-pixel test: different images.
    for mode in ["off", "per-pixel"] {
        let other = capture(&["--hair", mode]);
        let cmp = compare_rgba8(&other, &actual, &Tolerance::GOLDEN);
        assert!(!cmp.passed, "--hair {mode} changed nothing: {cmp}");
    }
}
