//! `BillboardReflectionsPlugin` in a Bevy app on lavapipe, end to end, on the scene of
//! `reflections_scene`.
//!
//! - Contract: the specular layer (debug view) against the CPU model
//!   (`penumbra_cinematic_core::reflections::pass::reflect_pixel_shadowed`) on the
//!   scene's analytic G-buffer — glossy, anisotropic, with reflection shadows.
//! - Opt-in: a camera without the component renders bit for bit as without the plugin;
//!   with the component, pixels whose reflection misses every billboard are unchanged.
//! - The half-resolution upsample against its model.
//! - Skip: no billboard → no pass and no allocation; steady frames allocate nothing.
//! - The texture array is written layer by layer (a changed image uploads one layer).
//! - `RenderLayers`: a camera reflects only the billboards sharing its layers.
//! - Deferred MSAA: the layer equals the single-sample camera's off the edges.
//! - A wall placed as sparse bricks shadows as the same wall dense.

mod reflections_scene;
use reflections_scene::*;

use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy_penumbra_cinematic::reflections::ReflectionImageUploads;
use bevy_penumbra_cinematic::{ReflectionBillboard, ReflectionDebugView};
use bevy_penumbra_df::PenumbraGpuAllocations;
use penumbra_cinematic_core::reflections::pass::upsample_half;
use penumbra_test::{CaptureFormat, HeadlessRender, KeptApp, gpu_or_skip};

#[test]
fn the_layer_matches_the_model() {
    if !gpu_or_skip("the_layer_matches_the_model") {
        return;
    }
    for setup in [
        Setup::default(),
        Setup {
            perceptual_roughness: 0.5,
            ..default()
        },
        Setup {
            anisotropy: 0.8,
            ..default()
        },
        Setup {
            wall: true,
            ..default()
        },
    ] {
        let (gpu, _app) = render(setup);
        let model = model(setup);
        let name = format!(
            "reflections_layer_r{}_a{}{}",
            setup.perceptual_roughness,
            setup.anisotropy,
            if setup.wall { "_wall" } else { "" }
        );
        save(&name, &gpu);
        let model_image: Vec<[f32; 4]> = model
            .iter()
            .map(|m| m.unwrap_or(Vec4::ZERO).to_array())
            .collect();
        save(&format!("{name}_model"), &model_image);
        let (mean, worst, n, lit) = compare(&gpu, &model);
        println!(
            "{setup:?}: {n} floor pixels, {lit} reflecting; |GPU − model| mean {mean:.2e}, worst {worst:.2e}"
        );
        assert!(lit > 800, "{lit} pixels reflect a billboard");
        if setup.wall {
            // The wall shadows a good part of the striped sign's reflection.
            let unshadowed = model_with(setup, false);
            let shadowed = model
                .iter()
                .zip(&unshadowed)
                .filter(|(s, u)| match (s, u) {
                    (Some(s), Some(u)) => u.x > 0.2 * EMISSIVE && s.x < 0.5 * u.x,
                    _ => false,
                })
                .count();
            println!("  {shadowed} pixels lose more than half their reflection to the wall");
            assert!(shadowed > 100, "{shadowed} shadowed pixels");
        }
        assert!(mean < 2e-3 && worst < 0.05, "mean {mean}, worst {worst}");
    }
}

/// The wall as a volume placed as sparse bricks shadows the reflections as the same
/// volume placed dense does (the pass binds the scene's brick table and reads through
/// it), and the dense volume as the analytic wall does.
#[test]
fn a_bricked_wall_shadows_reflections_as_a_dense_one() {
    if !gpu_or_skip("a_bricked_wall_shadows_reflections_as_a_dense_one") {
        return;
    }
    let layer = |wall_volume| {
        let setup = Setup {
            wall: true,
            wall_volume,
            ..default()
        };
        let (image, app) = render(setup);
        let stats = app
            .world()
            .resource::<bevy_penumbra_df::DistanceFieldUploadStats>()
            .clone();
        (image, (stats.atlas_volumes, stats.atlas_bricked))
    };
    let (analytic, _) = layer(None);
    let (dense, dense_stats) = layer(Some(false));
    let (bricked, bricked_stats) = layer(Some(true));
    assert_eq!((dense_stats, bricked_stats), ((1, 0), (1, 1)));
    let as_model = |image: &[[f32; 4]]| -> Vec<Option<Vec4>> {
        image.iter().map(|p| Some(Vec4::from_array(*p))).collect()
    };
    let (mean, worst, n, lit) = compare(&bricked, &as_model(&dense));
    let (analytic_mean, analytic_worst, ..) = compare(&dense, &as_model(&analytic));
    let unshadowed = render(Setup::default()).0;
    let (shadow_mean, ..) = compare(&dense, &as_model(&unshadowed));
    println!(
        "{n} pixels, {lit} reflecting: |bricked − dense| mean {mean:.2e}, worst {worst:.2e}; \
         |dense − analytic wall| mean {analytic_mean:.2e}, worst {analytic_worst:.2e}; \
         without the wall they differ by {shadow_mean:.2e}"
    );
    assert!(shadow_mean > 0.01, "the wall changes the layer");
    assert!(mean < 1e-3 && worst < 0.05, "mean {mean}, worst {worst}");
    assert!(analytic_mean < 0.1 * shadow_mean, "{analytic_mean}");
}

/// Bevy's `F_AB` (the polynomial: Penumbra's lighting pass does not bind the DFG LUT).
fn f_ab(perceptual_roughness: f32, n_dot_v: f32) -> Vec2 {
    let c0 = Vec4::new(-1.0, -0.0275, -0.572, 0.022);
    let c1 = Vec4::new(1.0, 0.0425, 1.04, -0.04);
    let r = perceptual_roughness * c0 + c1;
    let a004 = (r.x * r.x).min((-9.28 * n_dot_v).exp2()) * r.x + r.y;
    (Vec2::new(-1.04, 1.04) * a004 + Vec2::new(r.z, r.w)).max(Vec2::splat(0.00005))
}

/// The lighting pass adds the layer as specular under Bevy's environment BRDF: the
/// shaded floor minus the floor without the component is `exposure · FssEss · layer`
/// (no environment map: nothing to cover); pixels reflecting nothing are bit for bit
/// unchanged; and without the component the plugin changes nothing.
#[test]
fn the_layer_is_added_as_specular_only_where_it_reflects() {
    if !gpu_or_skip("the_layer_is_added_as_specular_only_where_it_reflects") {
        return;
    }
    let setup = Setup::default();
    let (without_plugin, app) = render(Setup {
        plugin: false,
        reflections: None,
        ..setup
    });
    drop(app);
    let (plain, app) = render(Setup {
        reflections: None,
        ..setup
    });
    drop(app);
    assert_eq!(
        plain, without_plugin,
        "a camera without the component changed"
    );
    let (layer, app) = render(setup);
    drop(app);
    let (shaded, _app) = render(Setup {
        reflections: Some(ReflectionDebugView::None),
        ..setup
    });
    save("reflections_shaded", &shaded);
    let exposure = 1.0 / 1.2;
    // Reflectance 0.5: F0 = 0.04; its pre-baked specular occlusion is 1.
    let f0 = 0.04;
    let (mut worst, mut checked, mut untouched) = (0.0f32, 0, 0);
    for i in 0..(WIDTH * HEIGHT) as usize {
        let (l, s, p) = (Vec4::from_array(layer[i]), shaded[i], plain[i]);
        if l == Vec4::ZERO {
            // Sky pixels show the clear colour in the debug view; floor pixels
            // reflecting nothing must be untouched.
            assert_eq!(s, p, "pixel {i} reflects nothing but changed");
            untouched += 1;
            continue;
        }
        if l.truncate().min_element() < 0.2 {
            continue; // too faint to compare through f16
        }
        let pixel = IVec2::new((i as u32 % WIDTH) as i32, (i as u32 / WIDTH) as i32);
        let Some((_, normal, _, dir)) = analytic_surface(pixel, false) else {
            continue;
        };
        let n_dot_v = (-dir.dot(normal)).max(1e-4);
        let ab = f_ab(setup.perceptual_roughness, n_dot_v);
        let brdf = f0 * ab.x + ab.y;
        for c in 0..3 {
            let want = exposure * brdf * l[c];
            let got = s[c] - p[c];
            // Less two f16 steps of the shaded values (the capture's rounding).
            let step = (2.0f32).powi(s[c].max(p[c]).log2().floor() as i32 - 10);
            let e = ((got - want).abs() - 2.0 * step).max(0.0) / want;
            worst = worst.max(e);
        }
        checked += 1;
    }
    println!(
        "added specular: {checked} pixels checked, worst relative error {worst:.4}; {untouched} untouched"
    );
    assert!(
        checked > 500 && untouched > 3000,
        "{checked} checked, {untouched} untouched"
    );
    // Beyond the capture's rounding, within the layer's own f16 rounding (0.1 %): a
    // layer added without the BRDF (10× here), or with the metallic F0, fails.
    assert!(worst < 0.01, "worst relative error {worst}");
}

/// Deferred MSAA (`DeferredMsaa`): the trace reads each pixel's representative sample,
/// so off the edges the layer equals the single-sample camera's (the representative of
/// a flat pixel is its centre), with and without the wall's reflection shadows.
#[test]
fn deferred_msaa_reflects_as_a_single_sample_camera_does() {
    if !gpu_or_skip("deferred_msaa_reflects_as_a_single_sample_camera_does") {
        return;
    }
    for wall in [false, true] {
        let setup = Setup { wall, ..default() };
        let (single, app) = render(setup);
        drop(app);
        let (msaa, app) = render(Setup {
            msaa: true,
            ..setup
        });
        drop(app);
        save(&format!("reflections_layer_msaa_wall{wall}"), &msaa);
        let (mut sum, mut n, mut far) = (0.0f32, 0usize, 0usize);
        for (s, m) in single.iter().zip(&msaa) {
            let (s, m) = (Vec4::from_array(*s), Vec4::from_array(*m));
            let scale = s.truncate().max_element();
            if scale < 0.05 {
                continue;
            }
            let e = (m - s).truncate().abs().max_element() / scale;
            sum += e;
            n += 1;
            if e > 0.05 {
                far += 1;
            }
        }
        let mean = sum / n.max(1) as f32;
        println!(
            "wall {wall}: {n} reflecting pixels; |MSAA − single| / single mean {mean:.4}, \
             {far} over 5 % (edges)"
        );
        // No reflections under MSAA (or every sample's reflection from a wrong G-buffer)
        // fails all three.
        assert!(n > 800, "{n} reflecting pixels");
        assert!(mean < 0.02, "mean relative difference {mean}");
        assert!(far * 20 < n, "{far} of {n} pixels differ by more than 5 %");
    }
}

/// The composite does not depend on the order the billboards were spawned in (their
/// list order and texture array layers): bit for bit, with a hundred more billboards.
#[test]
fn the_composite_does_not_depend_on_the_order() {
    if !gpu_or_skip("the_composite_does_not_depend_on_the_order") {
        return;
    }
    let setup = Setup {
        extra_billboards: 100,
        perceptual_roughness: 0.4,
        ..default()
    };
    let (forward, app) = render(setup);
    drop(app);
    let (reversed, _app) = render(Setup {
        reversed: true,
        ..setup
    });
    let reflecting = forward.iter().filter(|p| p[3] > 0.0).count();
    let differ = forward
        .iter()
        .zip(&reversed)
        .filter(|(a, b)| a != b)
        .count();
    println!("order: {reflecting} reflecting pixels, {differ} differ when spawned in reverse");
    assert!(reflecting > 1000);
    assert_eq!(differ, 0, "the spawn order changed {differ} pixels");
}

/// Half resolution: each texel shades the top-left pixel of its 2 × 2 block, so those
/// pixels equal the full-resolution layer bit for bit; the others are interpolated
/// within the depth bounds, close to the full-resolution layer on average.
#[test]
fn half_resolution_upsamples_the_full_trace() {
    if !gpu_or_skip("half_resolution_upsamples_the_full_trace") {
        return;
    }
    let (full, app) = render(Setup::default());
    drop(app);
    let (half, _app) = render(Setup {
        half_resolution: true,
        ..default()
    });
    save("reflections_layer_half", &half);
    let (mut differ_even, mut sum_diff, mut sum_full) = (0, 0.0f32, 0.0f32);
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            let i = (y * WIDTH + x) as usize;
            let (f, h) = (Vec4::from_array(full[i]), Vec4::from_array(half[i]));
            if x % 2 == 0 && y % 2 == 0 && f != h {
                differ_even += 1;
            }
            sum_diff += (f - h).truncate().abs().element_sum();
            sum_full += f.truncate().abs().element_sum();
        }
    }
    let relative = sum_diff / sum_full;
    // Every pixel against the model of the upsample, from the GPU's own texels (the
    // even pixels) and the scene's analytic view depth.
    let view_z = |p: IVec2| analytic_surface(p, false).map_or(f32::NEG_INFINITY, |s| s.2);
    let texel = |t: IVec2| Vec4::from_array(half[(2 * t.y * WIDTH as i32 + 2 * t.x) as usize]);
    let half_size = IVec2::new(WIDTH as i32 / 2, HEIGHT as i32 / 2);
    let mut worst = 0.0f32;
    for y in 0..HEIGHT as i32 {
        for x in 0..WIDTH as i32 {
            let z = view_z(IVec2::new(x, y));
            if z == f32::NEG_INFINITY {
                continue; // no lighting pass there
            }
            let want = upsample_half(texel, view_z, half_size, IVec2::new(x, y), z);
            let got = Vec4::from_array(half[(y * WIDTH as i32 + x) as usize]);
            worst = worst.max(
                ((got - want) / Vec4::new(EMISSIVE, EMISSIVE, EMISSIVE, 1.0))
                    .abs()
                    .max_element(),
            );
        }
    }
    println!("half resolution: upsample against its model: worst {worst:.2e}");
    assert!(
        worst < 2e-3,
        "the upsample differs from its model by {worst}"
    );
    println!(
        "half resolution: {differ_even} even pixels differ; mean |half − full| / mean |full| {relative:.4}"
    );
    assert_eq!(
        differ_even, 0,
        "the traced pixels differ from the full-resolution trace"
    );
    assert!(
        relative < 0.1,
        "the upsampled layer is far from the full one: {relative}"
    );
}

/// A camera reflects the billboards its `RenderLayers` share, as Bevy draws meshes:
/// billboards on layer 1 are not in a layer-0 camera's reflections (its layer is dark),
/// and a camera seeing layers 0 and 1 reflects them exactly as a layer-0 camera reflects
/// layer-0 billboards.
#[test]
fn billboards_reflect_in_the_cameras_sharing_their_render_layers() {
    if !gpu_or_skip("billboards_reflect_in_the_cameras_sharing_their_render_layers") {
        return;
    }
    let (reference, _app) = render(Setup::default());
    // A reflection is bright (the signs' emissive is 4); an empty layer's debug view is
    // under 0.03.
    let lit = |image: &[[f32; 4]]| image.iter().filter(|p| p[0] + p[1] + p[2] > 0.2).count();
    assert!(lit(&reference) > 800, "{} pixels reflect", lit(&reference));
    let (hidden, _app) = render(Setup {
        billboard_layer: 1,
        ..default()
    });
    assert_eq!(
        lit(&hidden),
        0,
        "a layer-0 camera reflects layer-1 billboards"
    );
    let (shared, _app) = render(Setup {
        billboard_layer: 1,
        camera_sees_layer_1: true,
        ..default()
    });
    assert_eq!(
        shared, reference,
        "a camera seeing layer 1 reflects otherwise"
    );
}

/// No billboard: the camera's image and GPU allocations equal those without the
/// component; with billboards, steady frames allocate nothing.
#[test]
fn nothing_to_reflect_costs_nothing() {
    if !gpu_or_skip("nothing_to_reflect_costs_nothing") {
        return;
    }
    let empty = Setup {
        billboards: false,
        ..default()
    };
    let (without, app) = render(Setup {
        reflections: None,
        ..empty
    });
    let counts_without = app.world().resource::<PenumbraGpuAllocations>().counts();
    drop(app);
    let (with, app) = render(Setup {
        reflections: Some(ReflectionDebugView::None),
        ..empty
    });
    assert_eq!(without, with, "the image changed");
    assert_eq!(
        app.world().resource::<PenumbraGpuAllocations>().counts(),
        counts_without,
        "GPU resources created with nothing to reflect"
    );
    drop(app);
    let (_, mut app) = render(Setup {
        reflections: Some(ReflectionDebugView::None),
        ..default()
    });
    let allocations = app.world().resource::<PenumbraGpuAllocations>().clone();
    let before = allocations.counts();
    for _ in 0..3 {
        app.update();
    }
    assert_eq!(allocations.counts(), before, "steady frames allocated");
}

/// The texture array is written layer by layer: a changed image uploads its own layer
/// (and the reflection changes), a removed billboard uploads nothing, a new image takes
/// the freed layer; the array texture is made once.
#[test]
fn one_changed_image_uploads_one_layer() {
    if !gpu_or_skip("one_changed_image_uploads_one_layer") {
        return;
    }
    // Not pipelined: the render world stays reachable.
    let harness = HeadlessRender::new(WIDTH, HEIGHT)
        .format(CaptureFormat::LinearF16)
        .frames(5)
        .without_pipelining();
    let (before, mut app) = render_with(
        Setup {
            reflections: Some(ReflectionDebugView::Layer),
            ..default()
        },
        &harness,
    );
    let before = before.to_linear();
    let uploads = |app: &KeptApp| {
        *app.sub_app(RenderApp)
            .world()
            .resource::<ReflectionImageUploads>()
    };
    let first = uploads(&app);
    println!("first frames: {first:?}");
    assert_eq!(first.textures, 1);
    assert!(first.layers >= 2, "{first:?}");
    let mut boards = app
        .world_mut()
        .query::<(Entity, &ReflectionBillboard, &GlobalTransform)>();
    let mut boards: Vec<_> = boards
        .iter(app.world())
        .map(|(e, b, t)| (e, b.image.clone(), t.translation()))
        .collect();
    boards.sort_by(|a, b| a.2.x.total_cmp(&b.2.x));
    // The striped sign (in front, on the left) turns black.
    let (_, stripes, _) = boards[0].clone();
    let black = image_of(&vec![
        Vec4::new(0.0, 0.0, 0.0, 1.0);
        (IMAGE.x * IMAGE.y) as usize
    ]);
    *app.world_mut()
        .resource_mut::<Assets<Image>>()
        .get_mut(&stripes)
        .expect("loaded") = black;
    for _ in 0..2 {
        app.update();
    }
    let changed = uploads(&app);
    println!("one image changed: {changed:?}");
    assert_eq!(
        (changed.textures, changed.layers),
        (first.textures, first.layers + 1),
        "only the changed image's layer"
    );
    // Its reflection dimmed.
    let after = harness
        .read_target(&mut app)
        .expect("reads back")
        .to_linear();
    let (sum_before, sum_after) = (brightness(&before), brightness(&after));
    println!("reflected light: {sum_before:.1} before, {sum_after:.1} after");
    assert!(sum_after < 0.9 * sum_before);
    // A billboard removed: nothing uploaded. A new image: the freed layer, no new array.
    let (glow_board, ..) = boards[2];
    app.world_mut().entity_mut(glow_board).despawn();
    app.update();
    assert_eq!(uploads(&app), changed, "a removal uploads nothing");
    let fresh = app
        .world_mut()
        .resource_mut::<Assets<Image>>()
        .add(image_of(&vec![Vec4::ONE; (IMAGE.x * IMAGE.y) as usize]));
    app.world_mut().spawn((
        ReflectionBillboard {
            image: fresh,
            size: Vec2::ONE,
            ..default()
        },
        Transform::from_xyz(1.5, 0.8, -3.0),
    ));
    for _ in 0..2 {
        app.update();
    }
    let added = uploads(&app);
    println!("one image added: {added:?}");
    assert_eq!(
        (added.textures, added.layers),
        (changed.textures, changed.layers + 1)
    );
    // Steady frames: nothing.
    app.update();
    assert_eq!(uploads(&app), added);
}

fn brightness(image: &[[f32; 4]]) -> f32 {
    image.iter().map(|p| p[0] + p[1] + p[2]).sum()
}
