//! The `dfao` example runs headless (in process) and its screenshot matches the reference
//! kept in `assets/reference/dfao.png`; without DFAO (`--plain`) the image differs (the
//! occlusion is visible), and a frame later in its animation (the ball rolled) too.
//!
//! To accept a deliberate change: `PENUMBRA_BLESS=1 cargo test --test dfao_example`, then
//! look at the new reference before committing it.

#[path = "../examples/dfao.rs"]
#[allow(dead_code, reason = "the example's main is not used here")]
mod dfao;

use dfao::Options;
use penumbra_test::{Tolerance, check_golden, compare_rgba8, gpu_or_skip, image, output_dir};
use std::path::PathBuf;

/// Frames before the capture: the torus's background bake lands within the first few,
/// and the temporal filter settles.
const FRAMES: u32 = 12;

/// The examples' golden-image tolerance.
const TOLERANCE: Tolerance = Tolerance::GOLDEN;

fn capture(frames: u32, extra: &[&str]) -> image::RgbaImage {
    let dir = output_dir();
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join(format!("dfao.headless.{frames}{}.png", extra.join("")));
    let frames = frames.to_string();
    let args = ["--headless", "--frames", &frames, "--size", "256x256"];
    let options = Options::parse(
        args.iter()
            .chain(extra)
            .map(|s| s.to_string())
            .chain(["--out".to_string(), out.display().to_string()]),
    )
    .unwrap();
    dfao::run_headless(&options).unwrap();
    image::open(&out).unwrap().to_rgba8()
}

#[test]
fn dfao_example_matches_reference() {
    if !gpu_or_skip("dfao_example_matches_reference") {
        return;
    }
    let actual = capture(FRAMES, &[]);
    let reference = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/reference/dfao.png");
    check_golden("dfao", &actual, &reference, &TOLERANCE);
    let plain = capture(FRAMES, &["--plain"]);
    let cmp = compare_rgba8(&plain, &actual, &TOLERANCE);
    assert!(!cmp.passed, "DFAO changes nothing: {cmp}");
    let later = capture(FRAMES + 4, &[]);
    let cmp = compare_rgba8(&later, &actual, &TOLERANCE);
    assert!(!cmp.passed, "the ball did not roll: {cmp}");
}
