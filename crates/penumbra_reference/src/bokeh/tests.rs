use super::*;
use glam::{UVec2, Vec2, Vec3};

/// Focused at 3 m with Bevy's sensor; `f_stops` well under 1 gives small test images
/// large blurs.
fn lens_at(f_stops: f32) -> Lens {
    Lens {
        focal_distance: 3.0,
        f_stops,
        sensor_height: 0.01866,
        fov_y: 0.8,
        max_coc: 64.0,
        max_depth: f32::INFINITY,
    }
}

fn lens() -> Lens {
    lens_at(0.035)
}

/// The circle of confusion is the spread of a point's image over pinholes across the
/// aperture disc, each view sheared to keep the focal plane fixed: projected here by
/// hand, not from the formula.
#[test]
fn coc_is_the_spread_over_the_aperture() {
    let lens = lens_at(1.4);
    let height = 720;
    let a = lens.aperture_diameter();
    let s = lens.focal_distance;
    // Image y of a point at distance z straight ahead, seen from a pinhole at height p:
    // the ray from the pinhole through the point meets the focal plane at
    // p + (0 − p) s / z; the focal plane spans 2 s tan(fov / 2) over the image.
    let image_y = |p: f32, z: f32| {
        let on_plane = p - p * s / z;
        on_plane / (2.0 * s * (0.5 * lens.fov_y).tan()) * height as f32
    };
    for z in [0.5f32, 1.0, 2.0, 2.9, 3.0, 3.3, 6.0, 40.0] {
        // Signed as the circle of confusion: the image flips in front of the plane.
        let spread = image_y(0.5 * a, z) - image_y(-0.5 * a, z);
        let coc = lens.coc(z, height);
        assert!(
            (coc - spread).abs() <= 1e-3 * spread.abs().max(1.0),
            "z {z}: coc {coc}, spread {spread}"
        );
    }
    assert_eq!(lens.coc(3.0, height), 0.0);
    // The sky: the limit, finite; bad distances: in focus.
    let sky = lens.coc(f32::INFINITY, height);
    assert!(
        (sky - lens.coc(1e9, height)).abs() < 1e-3 && sky > 0.0,
        "{sky}"
    );
    assert_eq!(lens.coc(f32::NAN, height), 0.0);
    assert_eq!(lens.coc(-1.0, height), 0.0);
    assert_eq!(lens.coc(1e-4, height), -64.0);
}

/// A far black field at one distance with one bright pixel.
fn bright_pixel(size: u32, at: UVec2, z: f32) -> BokehImage {
    let n = (size * size) as usize;
    let mut color = vec![Vec3::ZERO; n];
    color[(at.y * size + at.x) as usize] = Vec3::splat(1000.0);
    BokehImage {
        size: UVec2::splat(size),
        color,
        distance: vec![z; n],
    }
}

/// A single bright pixel spreads into the aperture's shape scaled to its circle of
/// confusion, with its energy kept: at half resolution (24 px) and at quarter resolution
/// (48 px, over `SpriteRule::quarter_coc`).
#[test]
fn a_bright_pixel_spreads_into_the_aperture() {
    let size = 128;
    let z = 12.0;
    for (lens, quarter) in [(lens(), false), (lens_at(0.0175), true)] {
        let coc = lens.coc(z, size);
        let rule = SpriteRule::default();
        assert_eq!(coc >= rule.quarter_coc, quarter, "{coc}");
        assert!(coc > 20.0 && coc < 50.0, "{coc}");
        for (name, aperture) in [
            ("circle", Aperture::circle(64)),
            ("hexagon", Aperture::hexagon(64)),
        ] {
            for at in [UVec2::new(64, 64), UVec2::new(57, 70)] {
                let image = bright_pixel(size, at, z);
                let (out, sprites) = depth_of_field(&image, &lens, &aperture, &rule);
                let bright = sprites
                    .iter()
                    .max_by(|a, b| a.color.x.total_cmp(&b.color.x))
                    .expect("sprites");
                assert_eq!(is_quarter(bright, rule.quarter_diameter()), quarter);
                let energy: f32 = out.iter().map(|c| c.x).sum();
                let peak = 1000.0 / (aperture.mean() * coc * coc);
                let (mut both, mut either) = (0, 0);
                for y in 0..size {
                    for x in 0..size {
                        let d = UVec2::new(x, y).as_vec2() - at.as_vec2();
                        let uv = d / coc + 0.5;
                        let inside_shape = uv.cmpge(Vec2::ZERO).all()
                            && uv.cmple(Vec2::ONE).all()
                            && aperture.sample(uv) > 0.5;
                        let lit = out[(y * size + x) as usize].x > 0.5 * peak;
                        both += u32::from(inside_shape && lit);
                        either += u32::from(inside_shape || lit);
                    }
                }
                let iou = both as f32 / either as f32;
                eprintln!(
                    "{name} at {at}: coc {coc:.2} px, energy {energy:.2} of 1000, IoU {iou:.3}"
                );
                assert!((energy - 1000.0).abs() < 10.0, "{name}: energy {energy}");
                assert!(iou >= 0.9, "{name}: IoU {iou}");
            }
        }
    }
}

/// Pixels whose circle of confusion is under half a pixel keep their input bit for bit
/// when nothing in front of them is blurred; far ones change.
#[test]
fn in_focus_pixels_are_untouched() {
    let lens = lens();
    let size = UVec2::new(96, 64);
    let n = (size.x * size.y) as usize;
    let color: Vec<Vec3> = (0..n)
        .map(|i| {
            Vec3::new(
                (i % 7) as f32 * 0.3,
                (i % 11) as f32 * 0.1,
                1.0 + (i % 5) as f32,
            )
        })
        .collect();
    // Left: in focus (and within the depth of field); right: far behind.
    let distance: Vec<f32> = (0..n)
        .map(|i| {
            if (i as u32 % size.x) < 48 {
                3.0 + 0.001 * (i % 3) as f32
            } else {
                20.0
            }
        })
        .collect();
    let image = BokehImage {
        size,
        color: color.clone(),
        distance: distance.clone(),
    };
    let (out, _) = depth_of_field(
        &image,
        &lens,
        &Aperture::hexagon(32),
        &SpriteRule::default(),
    );
    let (mut kept, mut changed) = (0, 0);
    for i in 0..n {
        if lens.coc(distance[i], size.y).abs() < 0.5 {
            assert_eq!(
                out[i].to_array().map(f32::to_bits),
                color[i].to_array().map(f32::to_bits)
            );
            kept += 1;
        } else {
            changed += usize::from(out[i] != color[i]);
        }
    }
    assert!(kept > 2000 && changed > 2000, "{kept} {changed}");
}

/// The 1-or-4 rule: on a smooth far field about a quarter of the sprites, on noise
/// none saved; the result moves little.
#[test]
fn merging_blocks_saves_sprites() {
    let lens = lens();
    let size = UVec2::new(96, 64);
    let n = (size.x * size.y) as usize;
    let smooth: Vec<Vec3> = (0..n)
        .map(|i| Vec3::splat(1.0 + 0.002 * (i as u32 % size.x) as f32))
        .collect();
    let noisy: Vec<Vec3> = (0..n)
        .map(|i| Vec3::splat(((i * 7919) % 13) as f32))
        .collect();
    let aperture = Aperture::circle(32);
    for (name, color, most) in [("smooth", smooth, 0.3), ("noise", noisy, 1.0)] {
        let image = BokehImage {
            size,
            color,
            distance: vec![20.0; n],
        };
        let merged = SpriteRule::default();
        let all = SpriteRule {
            merge: false,
            ..merged
        };
        let (a, sa) = depth_of_field(&image, &lens, &aperture, &merged);
        let (b, sb) = depth_of_field(&image, &lens, &aperture, &all);
        let difference = a
            .iter()
            .zip(&b)
            .map(|(a, b)| (*a - *b).abs().max_element())
            .sum::<f32>()
            / n as f32;
        let ratio = sa.len() as f32 / sb.len() as f32;
        eprintln!(
            "{name}: {} sprites merged, {} not ({ratio:.3}); mean |Δ| {difference:.4}",
            sa.len(),
            sb.len()
        );
        assert_eq!(sb.len(), n / 4);
        assert!(ratio <= most, "{name}: {ratio}");
        assert!(
            difference < 0.02 * (1.0 + 12.0 * f32::from(u8::from(most == 1.0))),
            "{name}"
        );
    }
}

/// A 4×4 group is its sixteen sprites drawn as one quad: on a flat far field the
/// layers' weights are those of one sprite per pixel to float rounding, for a fraction
/// of the fragments.
#[test]
fn groups_spread_what_their_sixteen_sprites_spread() {
    let lens = lens();
    let size = UVec2::new(96, 64);
    let n = (size.x * size.y) as usize;
    let image = BokehImage {
        size,
        color: vec![Vec3::ONE; n],
        distance: vec![20.0; n],
    };
    let aperture = Aperture::hexagon(64);
    let half = downsample(&image, &lens);
    let groups = SpriteRule {
        quarter_coc: f32::INFINITY,
        ..SpriteRule::default()
    };
    let blocks = SpriteRule {
        merge_groups: false,
        ..groups
    };
    let single = SpriteRule {
        merge: false,
        ..groups
    };
    let run = |rule: &SpriteRule| {
        let sprites = sprites(&half, rule);
        let fragments = scatter_fragments(&sprites, half.size, rule.quarter_diameter());
        let layers = scatter_sprites(&sprites, &aperture, half.size, rule.quarter_diameter());
        (sprites, fragments, layers.far)
    };
    let (reference, single_fragments, want) = run(&single);
    let diameter = reference[0].diameter;
    for (name, rule, sixteens, most) in [("blocks", blocks, 0, 0.45), ("groups", groups, 96, 0.2)] {
        let (sprites, fragments, got) = run(&rule);
        let count = sprites.iter().filter(|s| s.weight == 16.0).count();
        let worst = got
            .iter()
            .zip(&want)
            .map(|(g, w)| (g.w - w.w).abs())
            .fold(0.0f32, f32::max);
        let ratio = fragments as f32 / single_fragments as f32;
        eprintln!(
            "{name}: {} sprites ({count} groups) of {diameter:.1} px, {ratio:.3} of the \
             fragments; largest weight difference {worst:.1e}",
            sprites.len()
        );
        assert_eq!(count, sixteens, "{name}");
        assert!(worst < 1e-4, "{name}: {worst}");
        assert!(ratio < most, "{name}: {ratio}");
    }
}

#[test]
fn bad_aperture_images_are_rejected() {
    assert_eq!(Aperture::from_image(0, 0, &[]), Err(ApertureError::Empty));
    assert_eq!(
        Aperture::from_image(2, 1, &[1.0, 1.0]),
        Err(ApertureError::NotSquare {
            width: 2,
            height: 1
        })
    );
    assert_eq!(
        Aperture::from_image(2, 2, &[1.0]),
        Err(ApertureError::WrongLength {
            expected: 4,
            got: 1
        })
    );
    assert_eq!(
        Aperture::from_image(2, 2, &[0.0, f32::NAN, -1.0, 0.0]),
        Err(ApertureError::Blank)
    );
    let a = Aperture::from_image(2, 2, &[2.0, f32::INFINITY, 0.5, 0.5]).expect("usable");
    assert_eq!(a.weights(), &[1.0, 0.0, 0.5, 0.5]);
    // The built-in shapes' areas: π/4 and 3√3/8 of the square.
    assert!((Aperture::circle(128).mean() - std::f32::consts::FRAC_PI_4).abs() < 2e-3);
    assert!((Aperture::hexagon(128).mean() - 3.0 * 3f32.sqrt() / 8.0).abs() < 2e-3);
}

/// A blurred square in front of the focal plane over a sharp background: its interior
/// shows its colour, its silhouette spreads into a fringe about half its circle of
/// confusion wide that mixes the two, and the background beyond keeps its input.
#[test]
fn a_blurred_foreground_covers_and_fringes() {
    let lens = lens();
    let size = UVec2::new(128, 96);
    let n = (size.x * size.y) as usize;
    let (near, back) = (Vec3::new(4.0, 0.5, 0.1), Vec3::new(0.1, 0.2, 1.0));
    let inside = |i: usize| {
        let (x, y) = (i as u32 % size.x, i as u32 / size.x);
        (40..88).contains(&x) && (30..66).contains(&y)
    };
    let image = BokehImage {
        size,
        color: (0..n)
            .map(|i| if inside(i) { near } else { back })
            .collect(),
        distance: (0..n).map(|i| if inside(i) { 1.5 } else { 3.0 }).collect(),
    };
    let coc = -lens.coc(1.5, size.y);
    assert!(coc > 10.0 && coc < 30.0, "{coc}");
    let (out, sprites) =
        depth_of_field(&image, &lens, &Aperture::circle(32), &SpriteRule::default());
    assert!(sprites.iter().all(|s| s.near));
    // Distance from the square's edge, pixels (negative inside).
    let edge = |x: u32, y: u32| {
        let dx = (40.0 - x as f32 - 0.5).max(x as f32 + 0.5 - 88.0);
        let dy = (30.0 - y as f32 - 0.5).max(y as f32 + 0.5 - 66.0);
        dx.max(dy)
    };
    let (mut interior, mut fringe, mut beyond) = (0, 0, 0);
    let mut edge_mix = Vec::new();
    for y in 0..size.y {
        for x in 0..size.x {
            let i = (y * size.x + x) as usize;
            let e = edge(x, y);
            if e < -0.5 * coc - 2.0 {
                assert!(
                    (out[i] - near).abs().max_element() < 0.01 * 4.0,
                    "interior {x},{y}: {}",
                    out[i]
                );
                interior += 1;
            } else if e > 0.0 && e < 1.0 && (x as f32 - 64.0).abs() < 10.0 {
                // Just outside the top and bottom edges, away from the corners: a
                // straight edge blurred by a symmetric kernel is half covered.
                edge_mix.push((out[i].x - back.x) / (near.x - back.x));
                fringe += 1;
            } else if e > 0.5 && e < 0.2 * coc {
                // Between the two colours, strictly.
                let t = (out[i].x - back.x) / (near.x - back.x);
                assert!(t > 0.05 && t < 0.95, "fringe {x},{y}: {t}");
                fringe += 1;
            } else if e > 0.5 * coc + 2.0 {
                assert_eq!(out[i], back, "beyond {x},{y}");
                beyond += 1;
            }
        }
    }
    let mix = edge_mix.iter().sum::<f32>() / edge_mix.len() as f32;
    eprintln!(
        "coc {coc:.1} px: {} edge pixels, mean mix {mix:.3}",
        edge_mix.len()
    );
    assert!((mix - 0.5).abs() < 0.08, "the edge is {mix} covered");
    assert!(
        interior > 100 && fringe > 200 && beyond > 2000,
        "{interior} {fringe} {beyond}"
    );
}

/// Every sprite spreads unit weight over the texel centres its quad covers, at every
/// size, single or block, far or near (so a near region's interior is opaque and
/// sprites of different sizes mix by their energy): summed here texel by texel, not
/// through the table. The analytic area (`mean · d²`) is off by up to a half for the
/// small sprites that most of a lightly blurred image is made of.
#[test]
fn sprites_spread_unit_weight_at_every_size() {
    for (name, aperture) in [
        ("circle", Aperture::circle(64)),
        ("hexagon", Aperture::hexagon(64)),
        (
            "triangle",
            Aperture::polygon(64, 3, std::f32::consts::FRAC_PI_2),
        ),
    ] {
        // Worst under NORM_TABLE_MAX (the table), above it (the area), and with the area
        // everywhere.
        let (mut worst, mut worst_large, mut worst_area) =
            ((0.0f32, 0.0f32), (0.0f32, 0.0f32), (0.0f32, 0.0f32));
        for k in 0..=800 {
            let diameter = 1.0 + 0.1 * k as f32;
            for (weight, center) in [(1.0, Vec2::splat(40.5)), (4.0, Vec2::splat(40.0))] {
                for near in [false, true] {
                    let s = Sprite {
                        center,
                        diameter,
                        color: Vec3::ONE,
                        weight,
                        near,
                    };
                    let reach = 0.5 * (diameter + weight.sqrt() - 1.0);
                    let mut sum = 0.0;
                    let n = reach.ceil() as i32 + 1;
                    for y in -n..=n {
                        for x in -n..=n {
                            let p = center.floor() + Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                            let o = p - center;
                            // The quad: left and top edges inclusive.
                            if o.x >= -reach && o.x < reach && o.y >= -reach && o.y < reach {
                                sum += sprite_weight(&s, &aperture, p);
                            }
                        }
                    }
                    let error = (sum / weight - 1.0).abs();
                    let w = if diameter < NORM_TABLE_MAX {
                        &mut worst
                    } else {
                        &mut worst_large
                    };
                    if error > w.0 {
                        *w = (error, diameter);
                    }
                    let area = aperture.mean() * diameter * diameter;
                    let error =
                        (sum / weight * aperture.normalisation(diameter) / area - 1.0).abs();
                    if error > worst_area.0 {
                        worst_area = (error, diameter);
                    }
                }
            }
        }
        eprintln!(
            "{name}: worst |Σ weight − 1| {:.4} (d = {:.2}) under {NORM_TABLE_MAX} px, {:.4} \
             (d = {:.1}) above; normalised by the area everywhere it was {:.3} (d = {:.1})",
            worst.0, worst.1, worst_large.0, worst_large.1, worst_area.0, worst_area.1
        );
        assert!(worst.0 < 0.01, "{name}: {worst:?}");
        assert!(worst_large.0 < 0.01, "{name}: {worst_large:?}");
    }
}

/// A quarter-resolution sprite spreads its weight over the quarter texels it covers, as
/// a half-resolution one does: blocks and single pixels, wherever their centre falls
/// in the quarter texel (one sample per quarter texel was up to 13 % off).
#[test]
fn quarter_resolution_sprites_spread_their_weight() {
    for (name, aperture) in [
        ("circle", Aperture::circle(64)),
        ("hexagon", Aperture::hexagon(64)),
    ] {
        let mut worst = [(0.0f32, 0.0f32); 2];
        for k in 0..=480 {
            let diameter = 16.0 + 0.2 * k as f32;
            for (weight, center) in [
                (4.0, Vec2::splat(41.0)),
                (1.0, Vec2::new(40.5, 41.5)),
                (1.0, Vec2::new(41.5, 40.5)),
            ] {
                let i = usize::from(weight < 2.0);
                for near in [false, true] {
                    let s = Sprite {
                        center,
                        diameter,
                        color: Vec3::ONE,
                        weight,
                        near,
                    };
                    let block = if weight > 1.0 { 1.0 } else { 0.0 };
                    let (c, d) = (
                        0.5 * center,
                        0.5 * (quarter_diameter(diameter) + block) + 0.5,
                    );
                    let mut sum = 0.0;
                    let n = d.ceil() as i32 + 2;
                    for y in -n..=n {
                        for x in -n..=n {
                            let p = c.floor() + Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                            let o = p - c;
                            if o.x >= -0.5 * d && o.x < 0.5 * d && o.y >= -0.5 * d && o.y < 0.5 * d
                            {
                                sum += quarter_sprite_weight(&s, &aperture, p);
                            }
                        }
                    }
                    let error = (sum / weight - 1.0).abs();
                    if error > worst[i].0 {
                        worst[i] = (error, diameter);
                    }
                }
            }
        }
        eprintln!(
            "{name}: worst |Σ weight / weight − 1| at quarter resolution: blocks {:.4} (d = {:.1}), \
             single pixels {:.4} (d = {:.1})",
            worst[0].0, worst[0].1, worst[1].0, worst[1].1
        );
        assert!(worst[0].0 < 0.01, "{name} blocks: {:?}", worst[0]);
        assert!(worst[1].0 < 0.01, "{name} single pixels: {:?}", worst[1]);
    }
}

/// One infinite (or NaN) pixel of the HDR target: the output stays finite everywhere
/// and the pixel blurs as the brightest finite one would (it made its sprite, and the
/// square the sprite covers, NaN, #47).
#[test]
fn an_infinite_pixel_blurs_as_the_brightest_finite_one() {
    let size = 64;
    let at = UVec2::new(32, 32);
    let lens = lens();
    let aperture = Aperture::circle(64);
    let rule = SpriteRule::default();
    let finite = {
        let mut image = bright_pixel(size, at, 12.0);
        image.color[(at.y * size + at.x) as usize] = Vec3::splat(scatter::MAX_SCENE_COLOR);
        depth_of_field(&image, &lens, &aperture, &rule).0
    };
    for bad in [f32::INFINITY, f32::NAN] {
        let mut image = bright_pixel(size, at, 12.0);
        image.color[(at.y * size + at.x) as usize] = Vec3::splat(bad);
        let (out, _) = depth_of_field(&image, &lens, &aperture, &rule);
        let non_finite = out.iter().filter(|c| !c.is_finite()).count();
        assert_eq!(non_finite, 0, "{bad}: {non_finite} pixels not finite");
        if bad.is_infinite() {
            assert_eq!(out, finite, "{bad}");
        }
    }
}
