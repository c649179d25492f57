//! The `samaritan` example (every Penumbra feature on one deferred 4× MSAA camera) runs
//! headless (in process) and its screenshot matches the reference kept in
//! `assets/reference/samaritan.png`; with `--plain` (no distance-field shadows or DFAO)
//! it does not. The man's body is a skinned character cast by capsules fitted to its
//! joints, which follow it as it moves.
//!
//! To accept a deliberate change: `PENUMBRA_BLESS=1 cargo test --test samaritan_example`,
//! then look at the new reference before committing it.

#[path = "../examples/samaritan.rs"]
#[allow(dead_code, reason = "the example's main is not used here")]
mod samaritan;

use bevy::prelude::*;
use penumbra::df::{SceneCasterCounts, SkinCapsules};
use penumbra_test::{
    HeadlessRender, Tolerance, check_golden, compare_rgba8, gpu_or_skip, image, output_dir,
};
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

/// The capsule casters' places.
fn capsule_places(app: &mut App) -> Vec<Vec3> {
    let world = app.world_mut();
    let capsules: Vec<Entity> = world
        .query::<&SkinCapsules>()
        .iter(world)
        .flat_map(|c| c.entities().to_vec())
        .collect();
    capsules
        .iter()
        .filter_map(|&e| world.get::<GlobalTransform>(e))
        .map(GlobalTransform::translation)
        .collect()
}

#[test]
fn the_flagships_man_is_a_skinned_character_cast_by_capsules() {
    if !gpu_or_skip("the_flagships_man_is_a_skinned_character_cast_by_capsules") {
        return;
    }
    let render = HeadlessRender::new(64, 64).frames(2);
    let mut app = render.app();
    samaritan::add_scene(&mut app);
    let (_, mut app) = render.run_keeping_app(app).expect("headless render");
    let world = app.world_mut();
    let counts: Vec<SceneCasterCounts> = world
        .query::<&SceneCasterCounts>()
        .iter(world)
        .copied()
        .collect();
    assert_eq!(counts.len(), 1, "one scene-caster root: {counts:?}");
    let c = counts[0];
    // Legs, body and arms (the hips hold no vertex), and one piece of them that its
    // joint's capsule leaves out and no other capsule holds.
    assert_eq!(
        (c.capsule_meshes, c.capsules, c.skinned),
        (1, 6, 0),
        "{c:?}"
    );
    let before = capsule_places(&mut app);
    assert_eq!(before.len(), 6);
    for _ in 0..3 {
        app.update();
    }
    let after = capsule_places(&mut app);
    let moved = before
        .iter()
        .zip(&after)
        .filter(|(a, b)| a.distance(**b) > 1e-3)
        .count();
    assert!(moved >= 4, "{moved} of 5 capsules follow the skeleton");
}
