//! The `samaritan` example (every Penumbra feature on one deferred 4× MSAA camera) runs
//! headless (in process) and its screenshot matches the reference kept in
//! `assets/reference/samaritan.png`; with `--plain` (no distance-field shadows or DFAO)
//! it does not.
//!
//! To accept a deliberate change: `PENUMBRA_BLESS=1 cargo test --test samaritan_example`,
//! then look at the new reference before committing it.

#[path = "../examples/samaritan.rs"]
#[allow(dead_code, reason = "the example's main is not used here")]
mod samaritan;

use penumbra_test::{Tolerance, check_golden, compare_rgba8, gpu_or_skip, image, output_dir};
use samaritan::Options;
use std::path::PathBuf;

/// Frames before the capture (DFAO's temporal filter and the rain settle in a few).
const FRAMES: &str = "6";

fn capture(extra: &[&str]) -> image::RgbaImage {
    let dir = output_dir();
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join(format!("samaritan.headless{}.png", extra.concat()));
    let args = ["--headless", "--frames", FRAMES, "--size", "256x256"];
    let options = Options::parse(
        args.iter()
            .chain(extra)
            .map(|s| s.to_string())
            .chain(["--out".to_string(), out.display().to_string()]),
    )
    .unwrap();
    samaritan::run_headless(&options).unwrap();
    image::open(&out).unwrap().to_rgba8()
}

#[test]
fn samaritan_example_matches_reference() {
    if !gpu_or_skip("samaritan_example_matches_reference") {
        return;
    }
    let actual = capture(&[]);
    let reference =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/reference/samaritan.png");
    check_golden("samaritan", &actual, &reference, &Tolerance::GOLDEN);
    let plain = capture(&["--plain"]);
    let cmp = compare_rgba8(&plain, &actual, &Tolerance::GOLDEN);
    assert!(
        !cmp.passed,
        "the distance-field effects changed nothing: {cmp}"
    );
}
