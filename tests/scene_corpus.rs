//! The scene corpus: every scene in `../shared/scenes` rendered by the scene viewer
//! headless (the skinned Fox walking, on a ground, cast by its fitted capsules and, again,
//! by its field re-baked on the GPU from the pose, #48), with a fixed sun per scene and the viewer's
//! framed camera, its sun visibility and DFAO dumps compared with ray-traced truth on the
//! scene's triangles (`examples/scene_truth.rs`, `penumbra_reference::scene_truth`, the
//! raster convention: what Bevy draws).
//!
//! Each scene has its own bounds, set a little above what it measures today, so that a
//! regression on any kind of content fails here; [`TARGET`] is the goal of issue #45
//! (shadows ≤ 0.10 on shadowed pixels and ≤ 0.03 on all, DFAO ≤ 0.08) and the table
//! printed (and written to `target/penumbra_test/scene_corpus.md`) marks which scenes
//! meet it. The README's table is this one.
//!
//! `PENUMBRA_CORPUS_SUN=x,y,z` renders the corpus under another sun (its direction of
//! travel) into `target/penumbra_test/scene_corpus_sun/`: a check that what holds under the
//! fixed sun is not tuned to it. The bounds are the fixed sun's, so the run only reports
//! (the README's "Under other suns").
//!
//! Skips with a message when `../shared` is absent.

#[path = "../examples/viewer.rs"]
#[allow(dead_code, reason = "the example's main is not used here")]
mod viewer;

#[path = "../examples/scene_truth.rs"]
#[allow(dead_code, reason = "the example's main is not used here")]
mod scene_truth;

use penumbra_reference::scene_truth::Facing;
use penumbra_test::{gpu_or_skip, output_dir};
use std::fmt::Write;

/// Mean errors: shadows on shadowed pixels, shadows on all pixels, DFAO; and the least
/// share of pixels whose face-normal prepass normal is the truth's triangle.
#[derive(Clone, Copy, Debug)]
struct Bounds {
    shadowed: f64,
    all: f64,
    ao: f64,
    facets: f64,
}

impl Bounds {
    /// Whether `self` (measured) is within `limit`.
    fn within(&self, limit: Bounds) -> bool {
        self.shadowed <= limit.shadowed
            && self.all <= limit.all
            && self.ao <= limit.ao
            && self.facets >= limit.facets
    }
}

/// Issue #45's goal for every scene (it set none for the facets).
const TARGET: Bounds = Bounds {
    shadowed: 0.10,
    all: 0.03,
    ao: 0.08,
    facets: 0.0,
};

/// A scene of the corpus: its file under `../shared/scenes`, extra viewer flags, and the
/// bounds it must stay within.
struct Case {
    file: &'static str,
    flags: &'static [&'static str],
    bounds: Bounds,
}

impl Case {
    /// The table's name for it: the file, and the re-bake's resolution where it has one.
    fn label(&self) -> String {
        match self.flags.iter().position(|f| *f == "--rebake") {
            Some(i) => format!("{} (re-baked {}³)", self.file, self.flags[i + 1]),
            None => self.file.to_string(),
        }
    }
}

const fn b(shadowed: f64, all: f64, ao: f64, facets: f64) -> Bounds {
    Bounds {
        shadowed,
        all,
        ao,
        facets,
    }
}

/// The corpus. Bounds: each error measured at the commit that set them, × 1.25 + 0.02,
/// rounded up to the hundredth; the facets' share measured less a hundredth, rounded
/// down to the hundredth (`scene_truth::FACET_DEGREES`).
const CORPUS: &[Case] = &[
    Case {
        file: "CornellBox.glb",
        flags: &[],
        bounds: b(0.05, 0.04, 0.03, 0.99),
    },
    Case {
        file: "DepthOfFieldExample.glb",
        flags: &[],
        bounds: b(0.03, 0.03, 0.10, 0.98),
    },
    Case {
        file: "PalmTree/PalmTree.gltf",
        flags: &["--eye=5,4,7", "--target=0,1.8,-0.5"],
        bounds: b(0.10, 0.03, 0.03, 0.98),
    },
    Case {
        file: "AlienCake/cakeBirthday.glb",
        flags: &[],
        bounds: b(0.05, 0.03, 0.05, 0.99),
    },
    Case {
        file: "AlienCake/alien.glb",
        flags: &[],
        bounds: b(0.04, 0.03, 0.06, 0.99),
    },
    Case {
        file: "AlienCake/tile.glb",
        flags: &[],
        bounds: b(0.02, 0.02, 0.03, 0.99),
    },
    Case {
        file: "ship/craft_speederD.gltf",
        flags: &[],
        bounds: b(0.11, 0.05, 0.06, 0.99),
    },
    Case {
        file: "FlightHelmet/FlightHelmet.gltf",
        flags: &[],
        bounds: b(0.07, 0.03, 0.08, 0.97),
    },
    Case {
        file: "AnisotropyBarnLamp/AnisotropyBarnLamp.gltf",
        flags: &[],
        bounds: b(0.05, 0.03, 0.08, 0.98),
    },
    Case {
        file: "terrain/terrain.glb",
        flags: &[],
        bounds: b(0.10, 0.03, 0.08, 0.97),
    },
    Case {
        file: "TonemappingTest/TonemappingTest.gltf",
        flags: &[],
        bounds: b(0.02, 0.02, 0.03, 0.99),
    },
    // #48: the Fox mid-walk on a ground, cast by capsules fitted to the volume its joints
    // skin, against rays on its skinned triangles (skipped it erred by 0.717 / 0.100; its
    // capsules drawn black inside themselves, 0.29 / 0.045; fitted to the vertices,
    // 0.183 / 0.028). Facets: 94.7 % while the face-normal prepass left skinned meshes
    // out.
    Case {
        file: "Fox.glb",
        flags: &["--ground", "--animation", "1", "--time", "0.35"],
        bounds: b(0.13, 0.04, 0.03, 0.99),
    },
    // #48: the same Fox re-baked on the GPU from its pose (`DistanceFieldRebake`, 48³).
    Case {
        file: "Fox.glb",
        flags: &[
            "--ground",
            "--animation",
            "1",
            "--time",
            "0.35",
            "--rebake",
            "48",
        ],
        bounds: b(0.12, 0.04, 0.03, 0.99),
    },
    Case {
        file: "faces.glb",
        flags: &[],
        bounds: b(0.02, 0.02, 0.03, 0.99),
    },
];

#[test]
fn every_shared_scene_shadows_and_occludes_as_ray_tracing_says() {
    if !gpu_or_skip("every_shared_scene_shadows_and_occludes_as_ray_tracing_says") {
        return;
    }
    let Some(dir) =
        penumbra_testkit::shared_dir("scene_corpus", env!("CARGO_MANIFEST_DIR"), "scenes")
    else {
        return;
    };
    // Another sun (`PENUMBRA_CORPUS_SUN`): report only.
    let other_sun = std::env::var("PENUMBRA_CORPUS_SUN").ok();
    let sun_flag = format!("--sun={}", other_sun.as_deref().unwrap_or("-1,-0.6,-0.5"));
    let out = output_dir().join(if other_sun.is_some() {
        "scene_corpus_sun"
    } else {
        "scene_corpus"
    });
    std::fs::create_dir_all(&out).unwrap();
    let mut table = String::from(
        "| scene | shadows: shadowed px | of it, shading normal turned away | of it, back faces seen | shadows: all px | lit ours / truth | DFAO | AO ours / truth | facets within 2° | atlas KiB | meets #45 |\n\
         |---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let mut failures = Vec::new();
    for case in CORPUS {
        let scene = dir.join(case.file);
        let name = case.label().replace(['/', '.', ' ', '(', ')', '³'], "_");
        let dump = out.join(&name);
        let _ = std::fs::remove_dir_all(&dump);
        let (scene_s, dump_s) = (scene.display().to_string(), dump.display().to_string());
        let png = out.join(format!("{name}.png")).display().to_string();
        let mut list = vec![
            "viewer",
            &scene_s,
            "--headless",
            "--size",
            "128x96",
            "--frames",
            "3",
            &sun_flag,
            "--angle",
            "3",
            "--no-scene-lights",
            "--ao-max-distance",
            "1",
        ];
        list.extend_from_slice(case.flags);
        list.extend_from_slice(&["--out", &png, "--dump", &dump_s]);
        let args = viewer::cli::Args::parse_from_args(list.iter().copied())
            .unwrap_or_else(|e| panic!("{}: {e}", case.file));
        viewer::run_headless(&args).unwrap_or_else(|e| panic!("{}: {e}", case.file));
        let check = scene_truth::check_dump(&dump, Facing::Raster, true)
            .unwrap_or_else(|e| panic!("{}: {e}", case.file));
        let sun = check.sun.expect("the viewer dumps the sun's visibility");
        let ao = check.ao.expect("the viewer dumps DFAO");
        let facets = check.facets.expect("the viewer dumps face normals");
        let got = b(sun.shadowed, sun.all, ao.all, facets);
        writeln!(
            table,
            "| {} | {:.3} | {:.0} % | {:.0} % | {:.3} | {:.2} / {:.2} | {:.3} | {:.2} / {:.2} | {:.1} % | {:.0} | {} |",
            case.label(),
            got.shadowed,
            check.shading_turned_away.unwrap_or(0.0) * 100.0,
            check.back_faces.unwrap_or(0.0) * 100.0,
            got.all,
            check.lit.0,
            check.lit.1,
            got.ao,
            check.ao_mean.0,
            check.ao_mean.1,
            facets * 100.0,
            check.atlas_used_bytes.unwrap_or(0.0) / 1024.0,
            if got.within(TARGET) { "yes" } else { "no" }
        )
        .unwrap();
        if !got.within(case.bounds) {
            failures.push(format!(
                "{}: {got:?} beyond its bounds {:?}",
                case.label(),
                case.bounds
            ));
        }
    }
    eprintln!("{table}");
    let _ = std::fs::write(out.join("scene_corpus.md"), &table);
    if let Some(sun) = other_sun {
        eprintln!("sun {sun}: reported, not held to the fixed sun's bounds");
        return;
    }
    assert!(failures.is_empty(), "{}\n{table}", failures.join("\n"));
}
