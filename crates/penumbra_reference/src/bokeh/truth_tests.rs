//! The scatter model against the ray-traced thin lens ([`super::truth`]).

use super::truth::{pinhole_image, thin_lens_image};
use super::*;
use crate::camera::PerspectiveCamera;
use crate::pbr::{DirectionalLight, Material};
use crate::scene::{Object, Scene, Shape};
use glam::{UVec2, Vec2, Vec3};

/// Far lights behind the focal plane, a ball in focus in front of them, a ball near the
/// camera, a lit ground with a shadow running through every depth.
fn scene() -> Scene {
    let matte = |c: Vec3| Material {
        base_color: c,
        ..Material::default()
    };
    let lamp = |x: f32, y: f32| Object {
        shape: Shape::Sphere {
            center: Vec3::new(x, y, -14.0),
            radius: 0.18,
        },
        material: Material {
            emissive: Vec3::splat(40.0),
            ..matte(Vec3::ZERO)
        },
    };
    Scene {
        objects: vec![
            Object {
                shape: Shape::Rect {
                    center: Vec3::new(0.0, 5.0, -15.0),
                    normal: Vec3::Z,
                    u: Vec3::X,
                    half_size: Vec2::new(30.0, 10.0),
                },
                material: matte(Vec3::new(0.2, 0.25, 0.4)),
            },
            Object {
                shape: Shape::Rect {
                    center: Vec3::new(0.0, 0.0, -5.0),
                    normal: Vec3::Y,
                    u: Vec3::X,
                    half_size: Vec2::new(30.0, 10.0),
                },
                material: matte(Vec3::new(0.5, 0.45, 0.3)),
            },
            lamp(-2.5, 3.0),
            lamp(1.5, 4.2),
            lamp(3.5, 2.2),
            Object {
                shape: Shape::Sphere {
                    center: Vec3::new(-0.9, 0.7, 0.0),
                    radius: 0.7,
                },
                material: matte(Vec3::new(0.8, 0.2, 0.1)),
            },
            Object {
                shape: Shape::Sphere {
                    center: Vec3::new(0.9, 0.6, 3.0),
                    radius: 0.25,
                },
                material: matte(Vec3::new(0.1, 0.7, 0.2)),
            },
        ],
        lights: vec![(
            DirectionalLight {
                direction_to_light: Vec3::new(0.6, 1.0, 0.4).normalize(),
                color_lux: Vec3::splat(3.0),
            },
            true,
        )],
        ambient: Vec3::splat(0.15),
        background: Vec3::new(0.05, 0.05, 0.08),
        exposure: 1.0,
    }
}

/// A 128 × 80 camera 5 m from the origin and its lens, focused there, at `f_stops`.
fn camera_and_lens(f_stops: f32) -> (PerspectiveCamera, Lens) {
    camera_and_lens_sized(f_stops, UVec2::new(128, 80), 40.0)
}

/// [`camera_and_lens`] at `size` with circles of confusion up to `max_coc` pixels.
fn camera_and_lens_sized(f_stops: f32, size: UVec2, max_coc: f32) -> (PerspectiveCamera, Lens) {
    let fov = 0.8;
    let camera = PerspectiveCamera::looking_at(
        Vec3::new(0.0, 1.0, 5.0),
        Vec3::new(0.0, 1.0, 0.0),
        fov,
        size.x,
        size.y,
    );
    let lens = Lens {
        focal_distance: 5.0,
        f_stops,
        sensor_height: 0.01866,
        fov_y: fov,
        max_coc,
        max_depth: f32::INFINITY,
    };
    (camera, lens)
}

fn display(c: Vec3) -> Vec3 {
    let f = |v: f32| {
        let v = v.clamp(0.0, 1.0);
        if v <= 0.003_130_8 {
            12.92 * v
        } else {
            1.055 * v.powf(1.0 / 2.4) - 0.055
        }
    };
    Vec3::new(f(c.x), f(c.y), f(c.z))
}

/// The pixels of each region: in focus (a circle of confusion under 1 px and no blur
/// of another depth within reach), out-of-focus interiors (at least 2 px, steady
/// within reach), borders (the circles of confusion within reach span over 4 px).
fn masks(coc: &[f32], size: UVec2) -> [Vec<bool>; 3] {
    let reach = coc.iter().fold(0.0f32, |m, c| m.max(c.abs())) * 0.5 + 1.0;
    let r = reach.ceil() as i32;
    let mut out = [
        vec![false; coc.len()],
        vec![false; coc.len()],
        vec![false; coc.len()],
    ];
    for y in 0..size.y as i32 {
        for x in 0..size.x as i32 {
            let here = coc[(y as u32 * size.x + x as u32) as usize];
            let (mut lo, mut hi) = (here, here);
            for dy in -r..=r {
                for dx in -r..=r {
                    let (qx, qy) = (x + dx, y + dy);
                    if qx < 0 || qy < 0 || qx >= size.x as i32 || qy >= size.y as i32 {
                        continue;
                    }
                    let c = coc[(qy as u32 * size.x + qx as u32) as usize];
                    // Only a blur that reaches this pixel counts.
                    if ((dx * dx + dy * dy) as f32).sqrt() <= 0.5 * c.abs() + 1.0 {
                        lo = lo.min(c);
                        hi = hi.max(c);
                    }
                }
            }
            let i = (y as u32 * size.x + x as u32) as usize;
            if hi - lo > 4.0 {
                out[2][i] = true;
            } else if here.abs() < 1.0 {
                out[0][i] = true;
            } else if here.abs() >= 2.0 {
                out[1][i] = true;
            }
        }
    }
    out
}

/// [`masks`] of `input`'s circles of confusion through `lens`.
fn image_masks(input: &BokehImage, lens: &Lens) -> [Vec<bool>; 3] {
    let coc: Vec<f32> = input
        .distance
        .iter()
        .map(|&d| lens.coc(d, input.size.y))
        .collect();
    masks(&coc, input.size)
}

/// Mean display-encoded error of `image` against `truth` over the pixels of `mask`
/// (largest channel), and how many pixels that is.
fn display_error(image: &[Vec3], truth: &[Vec3], mask: &[bool]) -> (f32, usize) {
    let (sum, n) = image
        .iter()
        .zip(truth)
        .zip(mask)
        .filter(|(_, m)| **m)
        .fold((0.0f32, 0), |(s, n), ((a, b), _)| {
            (s + (display(*a) - display(*b)).abs().max_element(), n + 1)
        });
    (sum / n.max(1) as f32, n)
}

/// The scatter model is close to the thin lens everywhere and far closer than the
/// pinhole image out of focus and on the borders; in focus it is the pinhole image.
#[test]
fn scatter_model_against_the_thin_lens() {
    let (camera, lens) = camera_and_lens(0.06);
    let size = UVec2::new(camera.width, camera.height);
    let scene = scene();
    let aperture = Aperture::hexagon(64);
    let input = pinhole_image(&scene, &camera);
    let (truth, pinholes) = thin_lens_image(&scene, &camera, &lens, &aperture, 16);
    assert!(pinholes >= 64, "{pinholes} pinholes");
    let (model, sprites) = depth_of_field(&input, &lens, &aperture, &SpriteRule::default());
    let masks = image_masks(&input, &lens);
    let names = ["in focus", "out-of-focus interiors", "borders"];
    let error = |image: &[Vec3], mask: &[bool]| display_error(image, &truth, mask);
    // `PENUMBRA_BOKEH_DUMP=DIR`: the three images as PPM, display-encoded.
    if let Ok(dir) = std::env::var("PENUMBRA_BOKEH_DUMP") {
        for (name, img) in [
            ("truth", &truth),
            ("model", &model),
            ("pinhole", &input.color),
        ] {
            let mut bytes = format!("P6 {} {} 255\n", size.x, size.y).into_bytes();
            for c in img.iter() {
                let d = display(*c) * 255.0;
                bytes.extend([d.x as u8, d.y as u8, d.z as u8]);
            }
            std::fs::write(format!("{dir}/{name}.ppm"), bytes).expect("writes");
        }
    }
    let all = vec![true; truth.len()];
    let (model_all, _) = error(&model, &all);
    let (pinhole_all, _) = error(&input.color, &all);
    eprintln!(
        "{pinholes} pinholes, {} sprites; mean display error, model / pinhole: all {model_all:.4} / {pinhole_all:.4}",
        sprites.len()
    );
    let mut figures = Vec::new();
    for (name, mask) in names.iter().zip(&masks) {
        let (m, n) = error(&model, mask);
        let (p, _) = error(&input.color, mask);
        eprintln!("  {name} ({n} px): {m:.4} / {p:.4}");
        figures.push((m, p, n));
    }
    assert!(figures.iter().all(|f| f.2 > 300), "{figures:?}");
    assert!(figures[0].0 < 0.02, "in focus");
    assert!(figures[1].0 < 0.4 * figures[1].1, "out of focus");
    assert!(figures[2].0 < 0.6 * figures[2].1, "borders");
    assert!(model_all < 0.5 * pinhole_all, "overall");
}

/// `(lower − upper) / total` luminance within `radius` of `center`, split at the
/// spot's own centroid: positive where the spot is heavier below it.
fn vertical_balance(image: &[Vec3], size: UVec2, center: Vec2, radius: f32) -> f32 {
    let spot: Vec<(Vec2, f32)> = (0..size.x * size.y)
        .map(|i| {
            let p = Vec2::new((i % size.x) as f32, (i / size.x) as f32) + 0.5;
            (p, image[i as usize].x)
        })
        .filter(|(p, _)| (*p - center).length() <= radius)
        .collect();
    let total: f32 = spot.iter().map(|s| s.1).sum();
    let centroid_y = spot.iter().map(|(p, l)| p.y * l).sum::<f32>() / total;
    let lower: f32 = spot
        .iter()
        .filter(|(p, _)| p.y > centroid_y)
        .map(|s| s.1)
        .sum();
    (2.0 * lower - total) / total
}

/// With a triangle (vertex up), a far highlight's bokeh is the triangle upright (heavy
/// below) and a near one's point-reflected (heavy above), as through the thin lens.
/// (Symmetric shapes such as the hexagon cannot tell.)
#[test]
fn bokeh_orientation_matches_the_thin_lens() {
    let (camera, lens) = camera_and_lens(0.015);
    let size = UVec2::new(camera.width, camera.height);
    let lamp = |center: Vec3, radius: f32| Object {
        shape: Shape::Sphere { center, radius },
        material: Material {
            base_color: Vec3::ZERO,
            emissive: Vec3::splat(400.0),
            ..Material::default()
        },
    };
    let (far, near) = (Vec3::new(-4.0, 1.0, -14.0), Vec3::new(0.5, 1.0, 2.5));
    let scene = Scene {
        objects: vec![lamp(far, 0.3), lamp(near, 0.03)],
        exposure: 1.0,
        ..Scene::default()
    };
    let aperture = Aperture::polygon(64, 3, std::f32::consts::FRAC_PI_2);
    let input = pinhole_image(&scene, &camera);
    let (truth, _) = thin_lens_image(&scene, &camera, &lens, &aperture, 16);
    let (model, _) = depth_of_field(&input, &lens, &aperture, &SpriteRule::default());
    for (name, at, distance) in [("far", far, 19.0), ("near", near, 2.5)] {
        let (x, y) = camera.project(at).expect("in view");
        let radius = 0.5 * lens.coc(distance, size.y).abs() + 4.0;
        let center = Vec2::new(x, y);
        let t = vertical_balance(&truth, size, center, radius);
        let m = vertical_balance(&model, size, center, radius);
        eprintln!("{name} (radius {radius:.1} px): balance truth {t:.3}, model {m:.3}");
        // Measured: far 0.111 / 0.089, near −0.117 / −0.045 (the half-resolution
        // round trip softens the spot); the aperture unreflected for near sprites gives
        // +0.045 there.
        assert!(
            t.abs() > 0.1 && m * t > 0.0 && m.abs() > 0.3 * t.abs(),
            "{name}"
        );
    }
}

/// Quarter-resolution layers for large sprites: against the thin lens, the error of
/// each `quarter_coc` beside the scatter pass's fragments (its work).
#[test]
fn quarter_resolution_error_against_work() {
    let (camera, lens) = camera_and_lens_sized(0.03, UVec2::new(256, 160), 64.0);
    let scene = scene();
    let aperture = Aperture::hexagon(64);
    let input = pinhole_image(&scene, &camera);
    let (truth, _) = thin_lens_image(&scene, &camera, &lens, &aperture, 16);
    let masks = image_masks(&input, &lens);
    let error = |image: &[Vec3], mask: &[bool]| display_error(image, &truth, mask).0;
    let half = downsample(&input, &lens);
    let mut rows = Vec::new();
    for quarter_coc in [16.0, 20.0, 24.0, 32.0, 48.0, f32::INFINITY] {
        let rule = SpriteRule {
            quarter_coc,
            ..SpriteRule::default()
        };
        let (model, sprites) = depth_of_field(&input, &lens, &aperture, &rule);
        let fragments = scatter_fragments(&sprites, half.size, rule.quarter_diameter());
        let e = [
            error(&model, &vec![true; truth.len()]),
            error(&model, &masks[1]),
            error(&model, &masks[2]),
        ];
        eprintln!(
            "quarter_coc {quarter_coc:>4}: {fragments:>7} fragments; error all {:.4}, \
             out of focus {:.4}, borders {:.4}",
            e[0], e[1], e[2]
        );
        rows.push((quarter_coc, fragments, e));
    }
    let default = SpriteRule::default().quarter_coc;
    let at = |q: f32| rows.iter().find(|r| r.0 == q).expect("swept");
    let (d, all_half) = (at(default), at(f32::INFINITY));
    // Measured: 357,233 fragments against 532,800 (0.67), error unchanged to 10⁻⁴.
    assert!(
        d.1 * 4 < all_half.1 * 3,
        "work: {} against {}",
        d.1,
        all_half.1
    );
    for k in 0..3 {
        assert!(
            d.2[k] < all_half.2[k] * 1.25 + 0.001,
            "error {k}: {:?} against {:?}",
            d.2,
            all_half.2
        );
    }
}
