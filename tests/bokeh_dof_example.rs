//! The `bokeh_dof` example runs headless (in process) on Bevy's depth-of-field scene
//! (`../shared/scenes/DepthOfFieldExample.glb`) and its screenshot matches the reference
//! kept in `assets/reference/bokeh_dof.png`; the same view without depth of field differs
//! from it (the blur is there).
//!
//! To accept a deliberate change: `PENUMBRA_BLESS=1 cargo test --test bokeh_dof_example`,
//! then look at the new reference before committing it.

#[path = "../examples/bokeh_dof.rs"]
#[allow(dead_code, reason = "the example's main is not used here")]
mod bokeh_dof;

use bokeh_dof::Options;
use penumbra_test::{Tolerance, check_golden, compare_rgba8, gpu_or_skip, image, output_dir};
use std::path::PathBuf;

/// Frames after the scene has loaded (it is still).
const FRAMES: &str = "4";

fn capture(dof: &str, scenes: &std::path::Path) -> image::RgbaImage {
    let dir = output_dir();
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join(format!("bokeh_dof.headless.{dof}.png"));
    let args = [
        "--headless",
        "--frames",
        FRAMES,
        "--size",
        "256x192",
        "--dof",
        dof,
        "--assets",
        &scenes.display().to_string(),
        "--out",
        &out.display().to_string(),
    ]
    .map(String::from);
    let options = Options::parse(args).unwrap();
    bokeh_dof::run_headless(&options).unwrap();
    image::open(&out).unwrap().to_rgba8()
}

#[test]
fn bokeh_dof_example_matches_reference() {
    if !gpu_or_skip("bokeh_dof_example_matches_reference") {
        return;
    }
    let Some(scenes) = penumbra_testkit::shared_dir(
        "bokeh_dof_example_matches_reference",
        env!("CARGO_MANIFEST_DIR"),
        "scenes",
    ) else {
        return;
    };
    let bokeh = capture("penumbra", &scenes);
    let reference =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/reference/bokeh_dof.png");
    check_golden("bokeh_dof", &bokeh, &reference, &Tolerance::GOLDEN);
    let sharp = capture("off", &scenes);
    let cmp = compare_rgba8(&sharp, &bokeh, &Tolerance::GOLDEN);
    assert!(!cmp.passed, "the depth of field changes nothing: {cmp}");
}
