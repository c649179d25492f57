//! The showcase example runs headless (its own `run_headless`, in process) and its
//! screenshot matches the reference kept in `assets/reference/showcase.png`.
//!
//! To accept a deliberate change of the scene: `PENUMBRA_BLESS=1 cargo test --test showcase`,
//! then look at the new reference before committing it.

#[path = "../examples/showcase.rs"]
#[allow(dead_code, reason = "the example's main is not used here")]
mod showcase;

use penumbra_test::{Tolerance, check_golden, gpu_or_skip, image, output_dir};
use showcase::Options;
use std::path::PathBuf;

fn reference_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/reference/showcase.png")
}

/// The examples' golden-image tolerance.
const TOLERANCE: Tolerance = Tolerance::GOLDEN;

#[test]
fn showcase_headless_matches_reference() {
    if !gpu_or_skip("showcase_headless_matches_reference") {
        return;
    }
    let dir = output_dir();
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("showcase.headless.png");
    let options = Options::parse(
        ["--headless", "--frames", "30", "--size", "256x256", "--out"]
            .iter()
            .map(|s| s.to_string())
            .chain([out.display().to_string()]),
    )
    .unwrap();
    showcase::run_headless(&options).unwrap();
    let actual = image::open(&out).unwrap().to_rgba8();
    assert_eq!(actual.dimensions(), (256, 256));
    check_golden("showcase", &actual, &reference_path(), &TOLERANCE);
}

#[test]
fn showcase_arguments_are_validated() {
    let parse = |args: &[&str]| Options::parse(args.iter().map(|s| s.to_string()));
    let ok = parse(&[
        "--headless",
        "--frames",
        "3",
        "--out",
        "a.png",
        "--size",
        "64x32",
    ])
    .unwrap();
    assert!(ok.headless);
    assert_eq!(ok.frames, Some(3));
    assert_eq!(ok.size, Some(bevy::math::UVec2::new(64, 32)));
    assert_eq!(ok.out, Some(PathBuf::from("a.png")));
    let bad: &[(&[&str], &str)] = &[
        (&["--frames"], "needs a value"),
        (&["--frames", "x"], "bad number"),
        (&["--frames", "0"], "1..=100000"),
        (&["--size", "64"], "WxH"),
        (&["--size", "0x10"], "1..=8192"),
        (&["--size", "100000x10"], "1..=8192"),
        (&["--fast"], "unknown argument"),
    ];
    for (args, needle) in bad {
        let err = parse(args).unwrap_err();
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}
