//! Billboard reflections' tile culling changes no pixel (on the scene of
//! `reflections_scene`), and lavapipe's frame time against the billboard count and the
//! settings (an ignored measurement).

mod reflections_scene;
use reflections_scene::*;

use bevy::prelude::*;
use bevy_penumbra_cinematic::ReflectionDebugView;
use penumbra_cinematic_core::reflections::grid::GRID_OVER_LIST;
use penumbra_test::{HeadlessRender, gpu_or_skip};

/// Tile culling changes no pixel: the layer with it equals the layer testing every
/// billboard at every pixel, bit for bit — glossy, anisotropic, at half resolution, with
/// a hundred billboards more (lists of many lengths), and with the wall's reflection
/// shadows (the tiles' caster lists must hold it wherever it dims a hit).
#[test]
fn tile_culling_changes_no_pixel() {
    if !gpu_or_skip("tile_culling_changes_no_pixel") {
        return;
    }
    for setup in [
        Setup {
            extra_billboards: 100,
            ..default()
        },
        Setup {
            perceptual_roughness: 0.6,
            extra_billboards: 100,
            ..default()
        },
        Setup {
            anisotropy: 0.9,
            half_resolution: true,
            extra_billboards: 100,
            ..default()
        },
        Setup {
            wall: true,
            ..default()
        },
        Setup {
            wall: true,
            perceptual_roughness: 0.5,
            half_resolution: true,
            ..default()
        },
    ] {
        let (culled, app) = render(setup);
        drop(app);
        let (every, _app) = render(Setup {
            tile_culling: false,
            ..setup
        });
        let reflecting = every.iter().filter(|p| p[3] > 0.0).count();
        let differ = culled.iter().zip(&every).filter(|(a, b)| a != b).count();
        println!("tile culling, {setup:?}: {reflecting} reflecting pixels, {differ} differ");
        assert!(reflecting > 1000, "{reflecting} reflecting pixels");
        assert_eq!(differ, 0, "tile culling changed {differ} pixels");
    }
}

/// Where a tile's caster list overflows (a crowd of 800 sphere casters between the floor
/// and the signs), its pixels gather each segment's casters from the caster grid: the
/// layer equals the one gathering from every object (no tile culling), bit for bit, and
/// the crowd's shadows show in it. The CPU model of the tiles (the floor's analytic
/// G-buffer, `cull::tile_casters`) confirms that most reflecting pixels lie in tiles whose
/// list overflows.
#[test]
fn the_caster_grid_changes_no_pixel() {
    if !gpu_or_skip("the_caster_grid_changes_no_pixel") {
        return;
    }
    let setup = Setup {
        crowd: 800,
        perceptual_roughness: 0.3,
        ..default()
    };
    let (overflowing, long, reflecting_model) = overflowing_tile_pixels(setup);
    println!(
        "the model: {overflowing} of {reflecting_model} reflecting pixels in tiles over their \
         list, {long} in tiles listing over {GRID_OVER_LIST} (the grid too)"
    );
    assert!(
        overflowing * 2 > reflecting_model && long > 0,
        "{overflowing} of {reflecting_model} pixels in overflowing tiles, {long} in long lists"
    );
    let (grid, app) = render(setup);
    drop(app);
    let (every, app) = render(Setup {
        tile_culling: false,
        ..setup
    });
    drop(app);
    let (open, _app) = render(Setup { crowd: 0, ..setup });
    let reflecting = every.iter().filter(|p| p[3] > 0.0).count();
    let differ = grid.iter().zip(&every).filter(|(a, b)| a != b).count();
    let shadowed = every.iter().zip(&open).filter(|(a, b)| a != b).count();
    println!(
        "caster grid: {reflecting} reflecting pixels, {differ} differ, {shadowed} shadowed by the crowd"
    );
    if differ > 0 {
        save("caster_grid_grid", &grid);
        save("caster_grid_every", &every);
    }
    assert!(reflecting > 1000, "{reflecting} reflecting pixels");
    assert!(
        shadowed > reflecting / 10,
        "the crowd dims {shadowed} pixels"
    );
    assert_eq!(differ, 0, "the caster grid changed {differ} pixels");
}

/// The model's count of reflecting floor pixels in tiles whose caster list overflows
/// (over 128), in tiles listing over `GRID_OVER_LIST`, and of all reflecting floor pixels.
fn overflowing_tile_pixels(setup: Setup) -> (usize, usize, usize) {
    use penumbra_cinematic_core::reflections::cull::{
        TILE, TileBounds, tile_casters, tile_march_length, tile_shadow_cone,
    };
    use penumbra_cinematic_core::reflections::pass::{FOOTPRINT_SLOPE, Surface, lobe};
    let spheres: Vec<_> = crowd(setup.crowd)
        .into_iter()
        .map(|c| Some((c, CROWD_RADIUS)))
        .collect();
    let billboards = model_billboards();
    let settings = penumbra_cinematic_core::reflections::pass::ReflectionUniform::new(3, IMAGE, 1);
    let (mut overflowing, mut long, mut reflecting) = (0, 0, 0);
    for ty in 0..HEIGHT.div_ceil(TILE) {
        for tx in 0..WIDTH.div_ceil(TILE) {
            let surfaces: Vec<Surface> = (0..TILE * TILE)
                .filter_map(|k| {
                    let pixel =
                        IVec2::new((tx * TILE + k % TILE) as i32, (ty * TILE + k / TILE) as i32);
                    let (position, normal, _, dir) = analytic_surface(pixel, false)?;
                    Some(Surface {
                        position,
                        normal,
                        view: -dir,
                        perceptual_roughness: setup.perceptual_roughness,
                    })
                })
                .collect();
            let Some(bounds) = TileBounds::from_pixels(surfaces.iter().map(|s| {
                let l = lobe(s, 0.0, FOOTPRINT_SLOPE);
                (s.position, l.dir, l.major.length() + l.minor.length())
            })) else {
                continue;
            };
            let length = tile_march_length(&bounds, &billboards, settings.max_distance);
            if length.is_nan() || length <= 0.0 {
                continue;
            }
            let cone = tile_shadow_cone(&bounds, settings.shadow_cone, settings.shadow_softness);
            reflecting += surfaces.len();
            match tile_casters(&bounds, &spheres, length, cone, 128) {
                None => overflowing += surfaces.len(),
                Some(list) if list.len() > GRID_OVER_LIST => long += surfaces.len(),
                Some(_) => {}
            }
        }
    }
    (overflowing, long, reflecting)
}

/// Lavapipe's frame time against the billboard count and the settings (a measurement):
/// 384 × 288, the median of 10 frames after 4, 3 runs. `cargo test -p
/// bevy_penumbra_cinematic --test reflections_plugin reflections_against_time --
/// --ignored --nocapture`
#[test]
#[ignore = "a measurement (~5 min)"]
fn reflections_against_time() {
    if !gpu_or_skip("reflections_against_time") {
        return;
    }
    let harness = HeadlessRender::new(384, 288).frames(14);
    let median = |setup| {
        let (capture, _) = render_with(setup, &harness);
        let mut ms: Vec<f64> = capture.frame_times[4..]
            .iter()
            .map(|t| t.as_secs_f64() * 1e3)
            .collect();
        ms.sort_by(f64::total_cmp);
        ms[ms.len() / 2]
    };
    let shaded = Setup {
        reflections: Some(ReflectionDebugView::None),
        ..default()
    };
    for run in 0..3 {
        let mut line = format!(
            "run {run}: no component {:.1} ms",
            median(Setup {
                reflections: None,
                ..shaded
            })
        );
        for (name, setup) in [
            ("3 billboards", shaded),
            (
                "1 layer",
                Setup {
                    max_layers: 1,
                    ..shaded
                },
            ),
            (
                "half res",
                Setup {
                    half_resolution: true,
                    ..shaded
                },
            ),
            (
                "wall + shadows",
                Setup {
                    wall: true,
                    ..shaded
                },
            ),
            (
                "10",
                Setup {
                    extra_billboards: 8,
                    ..shaded
                },
            ),
            (
                "100",
                Setup {
                    extra_billboards: 98,
                    ..shaded
                },
            ),
            (
                "1000",
                Setup {
                    extra_billboards: 998,
                    ..shaded
                },
            ),
            (
                "1000 half res",
                Setup {
                    extra_billboards: 998,
                    half_resolution: true,
                    ..shaded
                },
            ),
            (
                "1000 unculled",
                Setup {
                    extra_billboards: 998,
                    tile_culling: false,
                    ..shaded
                },
            ),
            (
                "1000 mirror",
                Setup {
                    extra_billboards: 998,
                    perceptual_roughness: 0.0,
                    ..shaded
                },
            ),
            (
                "1000 mirror unculled",
                Setup {
                    extra_billboards: 998,
                    perceptual_roughness: 0.0,
                    tile_culling: false,
                    ..shaded
                },
            ),
        ] {
            line += &format!(", {name}: {:.1}", median(setup));
        }
        println!("{line}");
    }
}
