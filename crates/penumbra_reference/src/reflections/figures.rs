//! Figures of billboard reflections: the pass (`penumbra_cinematic_core::reflections`)
//! against this module's truth — accuracy over roughness and anisotropy, the footprint's
//! calibration, reflection shadows against exact visibility, the blur's growth with
//! distance and roughness.

use super::*;

/// The test scene of the pass against the truth: a floor (y = 0) seen from 1.2 m up,
/// a striped sign (a transparent hole, a half-transparent band) before a larger
/// sign, both facing the camera (images 16 × 8, emissive 4).
mod scene {
    use super::super::*;
    use crate::camera::PerspectiveCamera;
    use glam::{Mat4, UVec2};
    use penumbra_cinematic_core::reflections::Billboard;
    use penumbra_cinematic_core::reflections::pass::{ReflectionUniform, Surface};

    pub const EMISSIVE: f32 = 4.0;
    pub const IMAGE: UVec2 = UVec2::new(16, 8);

    pub fn billboards() -> (Vec<GpuBillboard>, Vec<MipChain>) {
        let stripes: Vec<Vec4> = (0..IMAGE.x * IMAGE.y)
            .map(|i| {
                let (x, y) = (i % IMAGE.x, i / IMAGE.x);
                let c = [
                    Vec3::new(1.0, 0.2, 0.1),
                    Vec3::new(0.1, 0.9, 0.3),
                    Vec3::new(0.2, 0.3, 1.0),
                ][(x / 3 % 3) as usize];
                let a = if (6..10).contains(&x) && (2..6).contains(&y) {
                    0.0
                } else if y == 7 {
                    0.5
                } else {
                    1.0
                };
                c.extend(a)
            })
            .collect();
        let glow: Vec<Vec4> = (0..IMAGE.x * IMAGE.y)
            .map(|i| {
                let (x, y) = (i % IMAGE.x, i / IMAGE.x);
                let v = 0.3 + 0.7 * ((x + 2 * y) % 5) as f32 / 4.0;
                Vec4::new(v, v * 0.8, 0.2, 1.0)
            })
            .collect();
        let quads = [
            (Vec3::new(-0.5, 0.9, -2.5), Vec2::new(1.6, 1.0), 0u32),
            (Vec3::new(0.5, 1.2, -4.5), Vec2::new(3.0, 1.8), 1),
        ];
        let gpu = quads
            .iter()
            .map(|&(at, size, layer)| {
                let q = Billboard::from_transform(Mat4::from_translation(at), size).unwrap();
                GpuBillboard {
                    center: q.center,
                    layer,
                    half_x: q.half_x,
                    emissive: EMISSIVE,
                    half_y: q.half_y,
                    layers: u32::MAX,
                }
            })
            .collect();
        let images = [stripes, glow]
            .iter()
            .map(|t| MipChain::from_straight_alpha(IMAGE.x, IMAGE.y, t))
            .collect();
        (gpu, images)
    }

    pub fn settings(anisotropy: f32, footprint_slope: f32) -> ReflectionUniform {
        let mut s = ReflectionUniform::new(2, IMAGE, 5);
        s.anisotropy = anisotropy;
        s.footprint_slope = footprint_slope;
        s
    }

    /// The floor points a `w × h` camera sees (1.2 m up, looking 1 m down over 5 m).
    pub fn floor(w: u32, h: u32, perceptual_roughness: f32) -> Vec<Surface> {
        let camera = PerspectiveCamera::looking_at(
            Vec3::new(0.0, 1.2, 3.0),
            Vec3::new(0.0, 0.2, -2.0),
            std::f32::consts::FRAC_PI_4,
            w,
            h,
        );
        (0..w * h)
            .filter_map(|i| {
                let ray = camera.ray((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
                (ray.dir.y < -1e-3).then(|| Surface {
                    position: ray.at(-ray.origin.y / ray.dir.y),
                    normal: Vec3::Y,
                    view: -ray.dir,
                    perceptual_roughness,
                })
            })
            .collect()
    }

    /// The truth's lobe at a surface: Bevy's roughness, anisotropy along the view's
    /// projection on the surface (the pass's convention).
    pub fn truth_lobe(s: &Surface, anisotropy: f32) -> (Frame, Lobe) {
        let along = s.view - s.normal * s.normal.dot(s.view);
        let t = if along.length_squared() > 1e-8 {
            along
        } else {
            penumbra_cinematic_core::reflections::pass::any_perpendicular(s.normal)
        };
        let alpha = penumbra_cinematic_core::reflections::pass::roughness(s.perceptual_roughness);
        (
            Frame::new(s.normal, t),
            Lobe {
                alpha_t: alpha * (1.0 + anisotropy),
                alpha_b: alpha * (1.0 - anisotropy),
            },
        )
    }
}

/// Mean |layer − truth| (radiance over the emissive, and coverage) over the floor
/// points reflecting something, for the pass and for a sharp mirror (no footprint).
fn pass_against_truth(
    perceptual_roughness: f32,
    anisotropy: f32,
    footprint_slope: f32,
    taps: u32,
    samples: u32,
    grid: (u32, u32),
) -> (f32, f32, f32, usize) {
    use penumbra_cinematic_core::reflections::pass::reflect_pixel;
    let (billboards, images) = scene::billboards();
    let truth = BillboardTruth {
        billboards: &billboards,
        images: &images,
        occluders: None,
    };
    let mut settings = scene::settings(anisotropy, footprint_slope);
    settings.taps = taps;
    let norm = Vec4::new(
        1.0 / scene::EMISSIVE,
        1.0 / scene::EMISSIVE,
        1.0 / scene::EMISSIVE,
        1.0,
    );
    let (mut pass_err, mut sharp_err, mut coverage_err, mut n) = (0.0f32, 0.0f32, 0.0f32, 0usize);
    for (k, s) in scene::floor(grid.0, grid.1, perceptual_roughness)
        .iter()
        .enumerate()
    {
        let (frame, lobe) = scene::truth_lobe(s, anisotropy);
        let want = lobe_mean(frame, s.view, lobe, samples, 0x5eed + k as u64, |l| {
            truth.radiance(s.position, l)
        });
        let got = reflect_pixel(s, &billboards, &images, &settings);
        let sharp = reflect_pixel(
            &penumbra_cinematic_core::reflections::pass::Surface {
                perceptual_roughness: 0.0,
                ..*s
            },
            &billboards,
            &images,
            &settings,
        );
        if want.w < 0.01 && got.w < 0.01 {
            continue;
        }
        let e = ((got - want) * norm).truncate().abs().max_element();
        if e > 0.2 && std::env::var("PENUMBRA_DEBUG").is_ok() {
            eprintln!(
                "  at {} (view {}): pass {got} truth {want}",
                s.position, s.view
            );
        }
        pass_err += e;
        sharp_err += ((sharp - want) * norm).truncate().abs().max_element();
        coverage_err += (got.w - want.w).abs();
        n += 1;
    }
    let n_f = n.max(1) as f32;
    (pass_err / n_f, sharp_err / n_f, coverage_err / n_f, n)
}

const EMISSIVE: f32 = scene::EMISSIVE;

fn scene_billboards() -> (Vec<GpuBillboard>, Vec<MipChain>) {
    scene::billboards()
}

fn scene_settings() -> penumbra_cinematic_core::reflections::pass::ReflectionUniform {
    scene::settings(
        0.0,
        penumbra_cinematic_core::reflections::pass::FOOTPRINT_SLOPE,
    )
}

fn scene_floor(w: u32, h: u32, r: f32) -> Vec<penumbra_cinematic_core::reflections::pass::Surface> {
    scene::floor(w, h, r)
}

fn scene_lobe(s: &penumbra_cinematic_core::reflections::pass::Surface, a: f32) -> (Frame, Lobe) {
    scene::truth_lobe(s, a)
}

fn pass_against_truth_pub(r: f32, a: f32, slope: f32) -> (f32, f32, f32, usize) {
    pass_against_truth(
        r,
        a,
        slope,
        penumbra_cinematic_core::reflections::pass::DEFAULT_TAPS,
        1024,
        (48, 36),
    )
}

fn pass_against_truth_taps(r: f32, a: f32, taps: u32) -> (f32, f32, f32, usize) {
    pass_against_truth(
        r,
        a,
        penumbra_cinematic_core::reflections::pass::FOOTPRINT_SLOPE,
        taps,
        1024,
        (48, 36),
    )
}

/// The pass against the truth on a floor: near the mirror limit they agree; as the
/// floor roughens, the pass's footprint follows the truth's blur far better than a
/// sharp mirror would, anisotropic lobes included.
#[test]
fn the_pass_follows_the_truth() {
    let mut rows = Vec::new();
    for (roughness, anisotropy) in [
        (0.0f32, 0.0f32),
        (0.2, 0.0),
        (0.35, 0.0),
        (0.5, 0.0),
        (0.2, 0.8),
    ] {
        let (pass, sharp, coverage, n) = pass_against_truth(
            roughness,
            anisotropy,
            penumbra_cinematic_core::reflections::pass::FOOTPRINT_SLOPE,
            penumbra_cinematic_core::reflections::pass::DEFAULT_TAPS,
            1024,
            (48, 36),
        );
        eprintln!(
            "perceptual roughness {roughness}, anisotropy {anisotropy}: {n} points; mean |pass − truth| {pass:.4} (coverage {coverage:.4}), sharp mirror {sharp:.4}"
        );
        rows.push((roughness, anisotropy, pass, sharp));
    }
    for (roughness, anisotropy, pass, sharp) in rows {
        // Measured 0.022 (mirror), 0.038, 0.053, 0.030 and 0.071 (anisotropic).
        assert!(
            pass < 0.08,
            "roughness {roughness}, anisotropy {anisotropy}: {pass}"
        );
        if roughness >= 0.2 {
            assert!(
                pass < 0.6 * sharp,
                "roughness {roughness}, anisotropy {anisotropy}: pass {pass}, sharp {sharp}"
            );
        }
    }
}

/// Reflection shadows against exact visibility: a wall between the striped sign and the
/// floor before it, as triangles for the truth and as its exact distance for the pass's
/// march. Mean |pass − truth| over the points whose truth or pass reflects something, with
/// the march's steps swept, and without shadows.
fn shadows_against_truth(perceptual_roughness: f32, steps: u32) -> (f32, usize) {
    shadows_against_truth_among(
        &wall(),
        perceptual_roughness,
        steps,
        penumbra_cinematic_core::reflections::pass::SHADOW_CONE,
    )
}

/// A wall between the striped sign and the floor before it (box: centre, half size).
fn wall() -> Vec<(Vec3, Vec3)> {
    vec![(Vec3::new(-0.7, 0.3, -1.9), Vec3::new(0.5, 0.3, 0.05))]
}

/// A row of posts between the signs and the floor (boxes: centre, half size): many
/// small occluders for the march to pass.
fn posts() -> Vec<(Vec3, Vec3)> {
    (0..8)
        .map(|k| {
            (
                Vec3::new(-1.4 + 0.4 * k as f32, 0.45, -1.6 - 0.1 * (k % 3) as f32),
                Vec3::new(0.04, 0.45, 0.04),
            )
        })
        .collect()
}

/// [`shadows_against_truth`] among any boxes.
fn shadows_against_truth_among(
    boxes: &[(Vec3, Vec3)],
    perceptual_roughness: f32,
    steps: u32,
    cone: f32,
) -> (f32, usize) {
    use penumbra_cinematic_core::reflections::pass::{ShadowCasters, reflect_pixel_shadowed};
    // Two triangles per face of each box.
    let faces = [
        [0, 1, 3, 2],
        [4, 6, 7, 5],
        [0, 4, 5, 1],
        [2, 3, 7, 6],
        [0, 2, 6, 4],
        [1, 5, 7, 3],
    ];
    let triangles: Vec<[Vec3; 3]> = boxes
        .iter()
        .flat_map(|&(center, half)| {
            let corner = move |i: u32| {
                center
                    + half
                        * Vec3::new(
                            if i & 1 == 0 { -1.0 } else { 1.0 },
                            if i & 2 == 0 { -1.0 } else { 1.0 },
                            if i & 4 == 0 { -1.0 } else { 1.0 },
                        )
            };
            faces.iter().flat_map(move |f| {
                [
                    [corner(f[0]), corner(f[1]), corner(f[2])],
                    [corner(f[0]), corner(f[2]), corner(f[3])],
                ]
            })
        })
        .collect();
    let occluder = TriangleOccluder::new(&triangles);
    let box_distance = |i: usize, p: Vec3| {
        let (center, half) = boxes[i];
        let q = (p - center).abs() - half;
        q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
    };
    let distance = |p: Vec3| {
        (0..boxes.len())
            .map(|i| box_distance(i, p))
            .fold(f32::MAX, f32::min)
    };
    let spheres: Vec<_> = boxes.iter().map(|&(c, h)| Some((c, h.length()))).collect();
    let casters = ShadowCasters {
        spheres: &spheres,
        distance: box_distance,
    };
    let (billboards, images) = scene_billboards();
    let truth = BillboardTruth {
        billboards: &billboards,
        images: &images,
        occluders: Some(&occluder),
    };
    let mut settings = scene_settings();
    settings.shadow_steps = steps;
    settings.object_count = boxes.len() as u32;
    settings.shadow_cone = cone;
    let norm = 1.0 / EMISSIVE;
    let (mut err, mut n) = (0.0f32, 0usize);
    for (k, s) in scene_floor(48, 36, perceptual_roughness).iter().enumerate() {
        // Points under the wall's footprint are inside it: skipped.
        if distance(s.position) <= 0.0 {
            continue;
        }
        let (frame, lobe) = scene_lobe(s, 0.0);
        let want = lobe_mean(frame, s.view, lobe, 1024, 0x5eed + k as u64, |l| {
            truth.radiance(s.position, l)
        });
        let got = reflect_pixel_shadowed(s, &billboards, &images, &settings, &casters);
        if want.w < 0.01 && got.w < 0.01 {
            continue;
        }
        err += (got - want).truncate().abs().max_element() * norm;
        n += 1;
    }
    (err / n.max(1) as f32, n)
}

/// Reflection shadows follow exact visibility: with the march, a near-mirror floor's
/// error against the truth (a wall hiding part of a sign) falls to a quarter of the
/// error without shadows — about the pass's error where nothing is hidden.
#[test]
fn reflection_shadows_follow_exact_visibility() {
    let (unshadowed, _) = shadows_against_truth(0.0, 0);
    let (shadowed, n) = shadows_against_truth(0.0, 32);
    eprintln!(
        "reflection shadows: {n} points; mean |pass − truth| {shadowed:.4} with, {unshadowed:.4} without"
    );
    // Measured 0.024 with, 0.103 without (0.022 on the scene without the wall).
    assert!(
        shadowed < 0.03 && shadowed < 0.3 * unshadowed,
        "{shadowed} with, {unshadowed} without"
    );
}

/// The 10–90 % width (metres, along x) of a reflected edge: a floor line under a
/// billboard whose left half is opaque white, `distance` away along a 45° mirror ray,
/// for the pass and for the truth.
fn edge_widths(perceptual_roughness: f32, distance: f32) -> (f32, f32) {
    use glam::{Mat4, UVec2};
    use penumbra_cinematic_core::reflections::Billboard;
    use penumbra_cinematic_core::reflections::pass::{ReflectionUniform, Surface, reflect_pixel};
    // Fine enough that no footprint here reaches the chain's last levels.
    let size = UVec2::new(512, 16);
    let texels: Vec<Vec4> = (0..size.x * size.y)
        .map(|i| {
            if i % size.x < size.x / 2 {
                Vec4::ONE
            } else {
                Vec4::ZERO
            }
        })
        .collect();
    let images = [MipChain::from_straight_alpha(size.x, size.y, &texels)];
    let quad = Billboard::from_transform(
        Mat4::from_translation(Vec3::new(0.0, distance, -distance)),
        Vec2::new(10.0 * distance, 2.0 * distance),
    )
    .unwrap();
    let billboards = [GpuBillboard::new(&quad, 0, 1.0)];
    let truth = BillboardTruth {
        billboards: &billboards,
        images: &images,
        occluders: None,
    };
    let settings = ReflectionUniform::new(1, size, images[0].levels.len() as u32);
    let view = Vec3::new(0.0, 1.0, 1.0).normalize();
    // Wide enough for the blur at perceptual roughness 0.5 to reach its plateaus.
    let half = 2.0 * distance;
    let xs: Vec<f32> = (0..=400)
        .map(|k| -half + 2.0 * half * k as f32 / 400.0)
        .collect();
    let profile = |f: &dyn Fn(f32) -> f32| xs.iter().map(|&x| f(x)).collect::<Vec<f32>>();
    let surface = |x: f32| Surface {
        position: Vec3::new(x, 0.0, 0.0),
        normal: Vec3::Y,
        view,
        perceptual_roughness,
    };
    let pass = profile(&|x| reflect_pixel(&surface(x), &billboards, &images, &settings).w);
    let want = profile(&|x| {
        let s = surface(x);
        let (frame, lobe) = scene_lobe(&s, 0.0);
        lobe_mean(frame, view, lobe, 4096, 0x77 + (x * 1e4) as u64, |l| {
            truth.radiance(s.position, l)
        })
        .w
    });
    // Coverage falls from ~1 (left) to 0 (right): where it crosses 0.9 and 0.1.
    let width = |p: &[f32]| {
        let (lo, hi) = (p[0], p[p.len() - 1]);
        let at = |level: f32| {
            let target = hi + level * (lo - hi);
            let k = p
                .iter()
                .position(|&v| v < target)
                .unwrap_or(p.len() - 1)
                .max(1);
            let (a, b) = (p[k - 1], p[k]);
            xs[k - 1] + (xs[k] - xs[k - 1]) * (a - target) / (a - b).max(1e-9)
        };
        at(0.1) - at(0.9)
    };
    (width(&pass), width(&want))
}

/// The blur of a reflected edge grows with distance × roughness as the truth's does:
/// doubling the distance doubles both widths, and the pass's width stays within a
/// third of the truth's (a box filter against GGX's long tail: narrower at low
/// roughness, wider at high).
#[test]
fn blur_grows_with_distance_and_roughness_as_the_truth() {
    let mut rows = Vec::new();
    for roughness in [0.2f32, 0.35, 0.5] {
        for distance in [1.0f32, 2.0, 4.0, 8.0] {
            let (pass, truth) = edge_widths(roughness, distance);
            eprintln!(
                "perceptual roughness {roughness}, distance {distance} m: 10–90 % edge width pass {pass:.3} m, truth {truth:.3} m (ratio {:.2})",
                pass / truth
            );
            rows.push((roughness, distance, pass, truth));
        }
    }
    for w in rows.windows(2) {
        let ((r0, d0, p0, t0), (r1, d1, p1, t1)) = (w[0], w[1]);
        if r0 == r1 {
            let (pass, truth) = (p1 / p0, t1 / t0);
            assert!(
                (1.8..2.2).contains(&pass) && (1.8..2.2).contains(&truth),
                "r {r0}: {d0} → {d1} m: pass ×{pass}, truth ×{truth}"
            );
        }
    }
    for (r, d, pass, truth) in rows {
        // Measured 0.83 (0.2), 0.96–0.97 (0.35), 1.10–1.14 (0.5).
        assert!(
            (0.75..1.33).contains(&(pass / truth)),
            "r {r}, {d} m: pass {pass}, truth {truth}"
        );
    }
}

/// Taps along elongated footprints against the truth (`cargo test -p
/// penumbra_reference --lib footprint_taps_sweep -- --ignored --nocapture`).
#[test]
#[ignore = "a measurement: taps against error"]
fn footprint_taps_sweep() {
    for taps in [1u32, 2, 4, 8] {
        let mut line = format!("taps {taps}:");
        for (roughness, anisotropy) in [
            (0.0f32, 0.0f32),
            (0.2, 0.0),
            (0.35, 0.0),
            (0.5, 0.0),
            (0.2, 0.8),
        ] {
            let (pass, ..) = pass_against_truth_taps(roughness, anisotropy, taps);
            line += &format!("  r{roughness}/a{anisotropy} {pass:.4}");
        }
        eprintln!("{line}");
    }
}

/// Reflection shadows against exact visibility, with the march's steps swept
/// (`cargo test -p penumbra_reference --lib reflection_shadow_steps -- --ignored
/// --nocapture`).
#[test]
#[ignore = "a measurement: reflection shadows' steps against error"]
fn reflection_shadow_steps() {
    for roughness in [0.0f32, 0.3] {
        for steps in [0u32, 2, 4, 8, 16, 32, 64] {
            let (err, n) = shadows_against_truth(roughness, steps);
            let (posts_err, posts_n) = shadows_against_truth_among(
                &posts(),
                roughness,
                steps,
                penumbra_cinematic_core::reflections::pass::SHADOW_CONE,
            );
            eprintln!(
                "perceptual roughness {roughness}, steps {steps:>2}: a wall {err:.4} ({n} points), eight posts {posts_err:.4} ({posts_n} points)"
            );
        }
    }
}

/// The footprint's slope against the truth: mean error per roughness for a sweep of
/// slopes (`cargo test -p penumbra_reference --lib footprint_slope_sweep -- --ignored
/// --nocapture`).
#[test]
#[ignore = "a measurement: the footprint slope's calibration"]
fn footprint_slope_sweep() {
    for slope in [1.0f32, 1.532, 2.0, 2.5, 3.0, 3.5, 4.0, 6.0] {
        let mut line = format!("slope {slope:>5}:");
        let mut total = 0.0;
        for (roughness, anisotropy) in [
            (0.0f32, 0.0f32),
            (0.2, 0.0),
            (0.35, 0.0),
            (0.5, 0.0),
            (0.2, 0.8),
        ] {
            let (pass, _, coverage, _) = pass_against_truth_pub(roughness, anisotropy, slope);
            line += &format!("  r{roughness}/a{anisotropy} {pass:.4} ({coverage:.3})");
            total += pass;
        }
        eprintln!("{line}  sum {total:.4}");
    }
}

/// Layers and half resolution against error (`cargo test -p penumbra_reference --lib
/// layers_and_half_resolution -- --ignored --nocapture`): a 64 × 48 view of the floor
/// (perceptual roughness 0.2), mean error against the truth over the pixels reflecting
/// something, with 1 to 4 layers at full resolution and 3 at half resolution (traced at
/// even pixels, upsampled by the lighting pass's model).
#[test]
#[ignore = "a measurement: layers and half resolution against error"]
fn layers_and_half_resolution_against_error() {
    use crate::camera::PerspectiveCamera;
    use glam::IVec2;
    use penumbra_cinematic_core::reflections::pass::{Surface, reflect_pixel, upsample_half};
    let (w, h) = (64i32, 48i32);
    let eye = Vec3::new(0.0, 1.2, 3.0);
    let target = Vec3::new(0.0, 0.2, -2.0);
    let camera =
        PerspectiveCamera::looking_at(eye, target, std::f32::consts::FRAC_PI_4, w as u32, h as u32);
    let forward = (target - eye).normalize();
    let surface = |p: IVec2| {
        let ray = camera.ray(p.x as f32 + 0.5, p.y as f32 + 0.5);
        (ray.dir.y < -1e-3).then(|| {
            let t = -ray.origin.y / ray.dir.y;
            (
                Surface {
                    position: ray.at(t),
                    normal: Vec3::Y,
                    view: -ray.dir,
                    perceptual_roughness: 0.2,
                },
                -t * ray.dir.dot(forward),
            )
        })
    };
    let (billboards, images) = scene::billboards();
    let truth = BillboardTruth {
        billboards: &billboards,
        images: &images,
        occluders: None,
    };
    let pixels: Vec<IVec2> = (0..w * h).map(|i| IVec2::new(i % w, i / w)).collect();
    let want: Vec<Option<Vec4>> = pixels
        .iter()
        .map(|&p| {
            surface(p).map(|(s, _)| {
                let (frame, lobe) = scene::truth_lobe(&s, 0.0);
                lobe_mean(
                    frame,
                    s.view,
                    lobe,
                    1024,
                    0x1a + (p.y * w + p.x) as u64,
                    |l| truth.radiance(s.position, l),
                )
            })
        })
        .collect();
    let error = |got: &dyn Fn(IVec2) -> Vec4| {
        let (mut sum, mut n) = (0.0f32, 0usize);
        for (k, &p) in pixels.iter().enumerate() {
            let Some(want) = want[k] else { continue };
            let got = got(p);
            if want.w < 0.01 && got.w < 0.01 {
                continue;
            }
            sum += ((got - want) / scene::EMISSIVE)
                .truncate()
                .abs()
                .max_element();
            n += 1;
        }
        (sum / n.max(1) as f32, n)
    };
    for layers in 1..=4u32 {
        let mut settings = scene::settings(
            0.0,
            penumbra_cinematic_core::reflections::pass::FOOTPRINT_SLOPE,
        );
        settings.max_layers = layers;
        let (e, n) = error(&|p| {
            surface(p).map_or(Vec4::ZERO, |(s, _)| {
                reflect_pixel(&s, &billboards, &images, &settings)
            })
        });
        eprintln!("{layers} layer(s), full resolution: {n} pixels, mean |pass − truth| {e:.4}");
    }
    let settings = scene::settings(
        0.0,
        penumbra_cinematic_core::reflections::pass::FOOTPRINT_SLOPE,
    );
    let half = IVec2::new(w / 2, h / 2);
    let traced: Vec<Vec4> = (0..half.x * half.y)
        .map(|i| {
            let p = IVec2::new(i % half.x, i / half.x) * 2;
            surface(p).map_or(Vec4::ZERO, |(s, _)| {
                reflect_pixel(&s, &billboards, &images, &settings)
            })
        })
        .collect();
    let view_z = |p: IVec2| surface(p).map_or(f32::NEG_INFINITY, |s| s.1);
    let (e, n) = error(&|p| {
        upsample_half(
            |t| traced[(t.y * half.x + t.x) as usize],
            view_z,
            half,
            p,
            view_z(p),
        )
    });
    eprintln!("3 layers, half resolution: {n} pixels, mean |pass − truth| {e:.4}");
}

/// The reflection-shadow cone's width against the truth (`cargo test -p
/// penumbra_reference --lib shadow_cone_sweep -- --ignored --nocapture`): mean error on
/// the wall and the posts, mirror and rough floors, 32 steps.
#[test]
#[ignore = "a measurement: the shadow cone's calibration"]
fn shadow_cone_sweep() {
    for cone in [0.0f32, 0.0625, 0.125, 0.25, 0.5, 1.0] {
        let mut line = format!("cone {cone:>5}:");
        let mut total = 0.0;
        for roughness in [0.0f32, 0.3, 0.5] {
            for (name, boxes) in [("wall", wall()), ("posts", posts())] {
                let (e, _) = shadows_against_truth_among(&boxes, roughness, 32, cone);
                line += &format!("  r{roughness} {name} {e:.4}");
                total += e;
            }
        }
        eprintln!("{line}  sum {total:.4}");
    }
}
