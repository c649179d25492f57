//! The work of billboard reflections' shadow march on a model of the benchmark's stress
//! scene (`examples/bench/scenes.rs`, `spawn_stress`): 1,000 casters on a 2 m grid, 100
//! signs, a glossy ground seen from (0, 7, 38). The pixels (casters and ground), their
//! tiles' caster lists (`reflections::cull::tile_casters`) and
//! each pixel's march (`reflect_pixel_in_tile`) with and without its tile's list,
//! counting distance evaluations, and the sphere tests of the gathers in tiles whose list
//! overflows, from every object and from the caster grid (`reflections::grid`) — measures
//! of the pass's work that do not depend on the device. The casters are spheres of their
//! shapes' bounding radius × 0.7.
//!
//! `cargo test --release -p penumbra_cinematic_core --test reflection_shadow_work --
//! --ignored --nocapture`

use glam::{Mat4, UVec2, Vec3, Vec4};
use penumbra_cinematic_core::reflections::Billboard;
use penumbra_cinematic_core::reflections::cull::{
    TILE, TileBounds, tile_casters, tile_march_length, tile_shadow_cone,
};
use penumbra_cinematic_core::reflections::grid::{CasterGrid, GRID_OVER_LIST};
use penumbra_cinematic_core::reflections::pass::{
    FOOTPRINT_SLOPE, Gather, GpuBillboard, ReflectionUniform, ShadowCasters, Surface, lobe,
    reflect_pixel_gathered, reflect_pixel_in_tile,
};
use penumbra_cinematic_core::reflections::texture::MipChain;
use std::cell::Cell;

fn hash(i: u32, salt: u32) -> f32 {
    let mut x = i.wrapping_mul(0x9E37_79B9) ^ salt.wrapping_mul(0x85EB_CA6B);
    x ^= x >> 15;
    x = x.wrapping_mul(0x2C1B_3C6D);
    x ^= x >> 12;
    (x & 0xFFFF) as f32 / 65536.0
}

/// The stress scene's casters: bounding spheres (centre, radius).
fn casters() -> Vec<Option<(Vec3, f32)>> {
    (0..1000u32)
        .map(|i| {
            let (col, row) = (i % 40, i / 40);
            let at = Vec3::new(
                -39.0 + 2.0 * col as f32 + 0.6 * (hash(i, 1) - 0.5),
                0.6,
                -24.0 + 2.0 * row as f32 + 0.6 * (hash(i, 2) - 0.5),
            );
            let scale = 0.7 + 0.6 * hash(i, 4);
            // Cuboid, sphere, torus, cylinder, capsule: their bounding radii.
            let radius = [0.866, 0.5, 0.75, 0.671, 0.6][(i % 5) as usize] * scale;
            Some((at, radius))
        })
        .collect()
}

/// The stress scene's 100 signs.
fn signs() -> Vec<GpuBillboard> {
    (0..100u32)
        .map(|i| {
            let (at, facing) = if i < 60 {
                (Vec3::new(-44.0 + 1.5 * i as f32, 2.0, -27.0), Vec3::Z)
            } else {
                let side = if i < 80 { -1.0 } else { 1.0 };
                let k = (i - 60) % 20;
                (
                    Vec3::new(side * 44.0, 2.0, -24.0 + 2.5 * k as f32),
                    Vec3::X * -side,
                )
            };
            let x = Vec3::Y.cross(facing);
            let world = Mat4::from_cols(
                x.extend(0.0),
                Vec3::Y.extend(0.0),
                facing.extend(0.0),
                at.extend(1.0),
            );
            let quad = Billboard::from_transform(world, glam::Vec2::new(2.0, 1.0)).expect("a quad");
            GpuBillboard::new(&quad, 0, 1.0)
        })
        .collect()
}

/// The surface under each pixel of a `size` image (Bevy's default 45° vertical field of
/// view): a caster's sphere (perceptual roughness 0.6, as the scene's palette) or the
/// ground (0.25); `None` for the sky.
fn surfaces(size: UVec2, spheres: &[Option<(Vec3, f32)>]) -> Vec<Option<Surface>> {
    let eye = Vec3::new(0.0, 7.0, 38.0);
    let forward = (Vec3::new(0.0, 0.5, 0.0) - eye).normalize();
    let right = forward.cross(Vec3::Y).normalize();
    let up = right.cross(forward);
    let tan = (std::f32::consts::FRAC_PI_4 * 0.5).tan();
    let aspect = size.x as f32 / size.y as f32;
    (0..size.x * size.y)
        .map(|i| {
            let (px, py) = (i % size.x, i / size.x);
            let x = 2.0 * (px as f32 + 0.5) / size.x as f32 - 1.0;
            let y = 1.0 - 2.0 * (py as f32 + 0.5) / size.y as f32;
            let dir = (forward + right * (x * tan * aspect) + up * (y * tan)).normalize();
            let mut nearest: Option<(f32, Vec3)> = None;
            for (c, r) in spheres.iter().flatten() {
                let (oc, r) = (eye - *c, 0.7 * r);
                let b = oc.dot(dir);
                let disc = b * b - (oc.length_squared() - r * r);
                let t = -b - disc.max(0.0).sqrt();
                if disc > 0.0 && t > 0.0 && nearest.is_none_or(|(n, _)| t < n) {
                    nearest = Some((t, *c));
                }
            }
            if let Some((t, c)) = nearest {
                let p = eye + dir * t;
                return Some(Surface {
                    position: p,
                    normal: (p - c).normalize(),
                    view: -dir,
                    perceptual_roughness: 0.6,
                });
            }
            if dir.y >= 0.0 {
                return None;
            }
            let p = eye + dir * (-eye.y / dir.y);
            (p.x.abs() <= 50.0 && p.z.abs() <= 40.0).then_some(Surface {
                position: p,
                normal: Vec3::Y,
                view: -dir,
                perceptual_roughness: 0.25,
            })
        })
        .collect()
}

#[test]
#[ignore = "a measurement (~1 min in release)"]
fn stress_scene_reflection_shadow_work() {
    let spheres = casters();
    let billboards = signs();
    let images = [MipChain::from_straight_alpha(1, 1, &[Vec4::ONE])];
    let evaluations = Cell::new(0u64);
    let shadow = ShadowCasters {
        spheres: &spheres,
        distance: |i: usize, p: Vec3| {
            evaluations.set(evaluations.get() + 1);
            let (c, r) = spheres[i].expect("bounded");
            (p - c).length() - 0.7 * r
        },
    };
    let mut settings = ReflectionUniform::new(billboards.len() as u32, UVec2::ONE, 1);
    settings.shadow_steps = 32;
    settings.object_count = spheres.len() as u32;
    let grid = CasterGrid::new(&spheres);
    for size in [UVec2::new(320, 180), UVec2::new(640, 360)] {
        let pixels = surfaces(size, &spheres);
        let (mut grid_evaluations, mut overflow_pixels) = (0u64, 0usize);
        let (mut long_list_pixels, mut long_list_tests, mut long_list_grid_tests) =
            (0usize, 0u64, 0u64);
        let (mut overflow_tests, mut overflow_every) = (0u64, 0u64);
        grid.tested.set(0);
        grid.gathers.set(0);
        let tiles = UVec2::new(size.x.div_ceil(TILE), size.y.div_ceil(TILE));
        let (mut listed, mut overflowing, mut with_list, mut lists) = (0usize, 0, 0, 0);
        let (mut all, mut tiled, mut reflecting) = (0u64, 0u64, 0usize);
        for tile in 0..tiles.x * tiles.y {
            let (tx, ty) = (tile % tiles.x, tile / tiles.x);
            let members: Vec<Surface> = (0..TILE * TILE)
                .filter_map(|k| {
                    let (x, y) = (tx * TILE + k % TILE, ty * TILE + k / TILE);
                    (x < size.x && y < size.y)
                        .then(|| pixels[(y * size.x + x) as usize])
                        .flatten()
                })
                .collect();
            let Some(bounds) = TileBounds::from_pixels(members.iter().map(|s| {
                let l = lobe(s, 0.0, FOOTPRINT_SLOPE);
                (s.position, l.dir, l.major.length() + l.minor.length())
            })) else {
                continue;
            };
            let length = tile_march_length(&bounds, &billboards, settings.max_distance);
            let cone = tile_shadow_cone(&bounds, settings.shadow_cone, settings.shadow_softness);
            let list = tile_casters(&bounds, &spheres, length, cone, 128);
            match &list {
                Some(l) => {
                    listed += l.len();
                    lists += 1;
                }
                None => overflowing += 1,
            }
            for s in &members {
                let v = reflect_pixel_in_tile(s, &billboards, &images, &settings, &shadow, None);
                all += evaluations.replace(0);
                let tiled_v = reflect_pixel_in_tile(
                    s,
                    &billboards,
                    &images,
                    &settings,
                    &shadow,
                    list.as_deref(),
                );
                tiled += evaluations.replace(0);
                let (tested, gathers) = (grid.tested.get(), grid.gathers.get());
                let from = Gather::for_tile(list.as_deref(), Some(&grid));
                let shader =
                    reflect_pixel_gathered(s, &billboards, &images, &settings, &shadow, from);
                assert_eq!(shader, tiled_v, "the grid changed a pixel");
                match from {
                    Gather::Grid(_) => {
                        grid_evaluations += evaluations.replace(0);
                        overflow_pixels += 1;
                        overflow_tests += grid.tested.get() - tested;
                        overflow_every += (grid.gathers.get() - gathers) * spheres.len() as u64;
                    }
                    Gather::TileGrid(l, _) => {
                        long_list_pixels += 1;
                        long_list_tests += 8 * l.len() as u64;
                        long_list_grid_tests += grid.tested.get() - tested;
                        evaluations.set(0);
                    }
                    _ => evaluations.set(0),
                }
                reflecting += usize::from(v.w > 0.0);
                with_list += usize::from(list.is_some());
            }
        }
        println!(
            "{}x{}: {} tiles with pixels: {lists} listed (mean {:.1} casters), {overflowing} over 128; \
             {reflecting} reflecting pixels ({with_list} pixels in listed tiles); \
             distance evaluations per pixel {:.1} with every object, {:.1} with the lists",
            size.x,
            size.y,
            lists + overflowing,
            listed as f64 / lists.max(1) as f64,
            all as f64 / pixels.iter().flatten().count() as f64,
            tiled as f64 / pixels.iter().flatten().count() as f64,
        );
        let per_pixel = |n: u64| n as f64 / overflow_pixels.max(1) as f64;
        println!(
            "  {overflow_pixels} pixels in overflowing tiles: sphere tests per pixel {:.0} from every \
             object, {:.1} from the grid ({} × {} × {} cells of {:.2} m, {} large); distance \
             evaluations per pixel {:.1} (as without it)",
            per_pixel(overflow_every),
            per_pixel(overflow_tests),
            grid.dims.x,
            grid.dims.y,
            grid.dims.z,
            grid.cell,
            grid.large.len(),
            per_pixel(grid_evaluations),
        );
        let per = |n: u64| n as f64 / long_list_pixels.max(1) as f64;
        println!(
            "  {long_list_pixels} pixels in tiles listing over {GRID_OVER_LIST}: sphere tests per \
             pixel at most {:.0} from the list, {:.1} from the grid",
            per(long_list_tests),
            per(long_list_grid_tests),
        );
    }
}
