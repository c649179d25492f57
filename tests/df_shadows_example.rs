//! The `df_shadows` example runs headless (in process) and its screenshot matches the
//! reference kept in `assets/reference/df_shadows.png`; a frame later in its animation
//! (moved casters and lights) does not.
//!
//! To accept a deliberate change: `PENUMBRA_BLESS=1 cargo test --test df_shadows_example`,
//! then look at the new reference before committing it.

#[path = "../examples/df_shadows.rs"]
#[allow(dead_code, reason = "the example's main is not used here")]
mod df_shadows;

use df_shadows::Options;
use penumbra_test::{Tolerance, check_golden, compare_rgba8, gpu_or_skip, image, output_dir};
use std::path::PathBuf;

/// Frames before the capture: the torus's background bake lands within the first few.
const FRAMES: u32 = 12;

/// The examples' golden-image tolerance.
const TOLERANCE: Tolerance = Tolerance::GOLDEN;

fn capture(frames: u32) -> image::RgbaImage {
    let dir = output_dir();
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join(format!("df_shadows.headless.{frames}.png"));
    let frames = frames.to_string();
    let args = [
        "--headless",
        "--frames",
        &frames,
        "--size",
        "256x256",
        "--out",
    ];
    let options = Options::parse(
        args.iter()
            .map(|s| s.to_string())
            .chain([out.display().to_string()]),
    )
    .unwrap();
    df_shadows::run_headless(&options).unwrap();
    image::open(&out).unwrap().to_rgba8()
}

#[test]
fn df_shadows_example_matches_reference() {
    if !gpu_or_skip("df_shadows_example_matches_reference") {
        return;
    }
    let actual = capture(FRAMES);
    let reference =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/reference/df_shadows.png");
    check_golden("df_shadows", &actual, &reference, &TOLERANCE);
    // The animation moves: a few frames later the image is different.
    let later = capture(FRAMES + 4);
    let cmp = compare_rgba8(&later, &actual, &TOLERANCE);
    assert!(!cmp.passed, "the scene did not move: {cmp}");
}
