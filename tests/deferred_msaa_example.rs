//! The `deferred_msaa` example runs headless (in process) and its screenshots with
//! deferred 4× MSAA and without MSAA (`--msaa off`) match the references kept in
//! `assets/reference/deferred_msaa.png` and `deferred_msaa_off.png`; the two differ (the
//! edges are anti-aliased), and the per-sample mask's debug view (`--msaa edges`) differs
//! from both.
//!
//! To accept a deliberate change: `PENUMBRA_BLESS=1 cargo test --test deferred_msaa_example`,
//! then look at the new references before committing them.

#[path = "../examples/deferred_msaa.rs"]
#[allow(dead_code, reason = "the example's main is not used here")]
mod deferred_msaa;

use deferred_msaa::Options;
use penumbra_test::{Tolerance, check_golden, compare_rgba8, gpu_or_skip, image, output_dir};
use std::path::PathBuf;

/// Frames before the capture (the scene is still; the casters land in the first).
const FRAMES: &str = "8";

/// The examples' golden-image tolerance.
const TOLERANCE: Tolerance = Tolerance::GOLDEN;

fn capture(msaa: &str) -> image::RgbaImage {
    let dir = output_dir();
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join(format!("deferred_msaa.headless.{msaa}.png"));
    let args = [
        "--headless",
        "--frames",
        FRAMES,
        "--size",
        "256x256",
        "--msaa",
        msaa,
        "--out",
    ];
    let options = Options::parse(
        args.iter()
            .map(|s| s.to_string())
            .chain([out.display().to_string()]),
    )
    .unwrap();
    deferred_msaa::run_headless(&options).unwrap();
    image::open(&out).unwrap().to_rgba8()
}

#[test]
fn deferred_msaa_example_matches_references() {
    if !gpu_or_skip("deferred_msaa_example_matches_references") {
        return;
    }
    let reference = |name: &str| {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("assets/reference/{name}.png"))
    };
    let msaa = capture("4");
    check_golden(
        "deferred_msaa",
        &msaa,
        &reference("deferred_msaa"),
        &TOLERANCE,
    );
    let off = capture("off");
    check_golden(
        "deferred_msaa_off",
        &off,
        &reference("deferred_msaa_off"),
        &TOLERANCE,
    );
    let cmp = compare_rgba8(&off, &msaa, &TOLERANCE);
    assert!(!cmp.passed, "MSAA changes nothing: {cmp}");
    let edges = capture("edges");
    let cmp = compare_rgba8(&edges, &msaa, &TOLERANCE);
    assert!(!cmp.passed, "the per-sample mask view shows nothing: {cmp}");
}
