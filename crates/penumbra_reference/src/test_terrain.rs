//! Test terrain shared by the terrain tests: a valley heightfield, its surface as
//! triangles (for exact distances and rays), and receivers on it.

use glam::{UVec2, Vec2, Vec3};
use penumbra_df_core::heightfield::Heightfield;

/// A valley with walls rising 8 m within 5 m of its floor, over 40 × 40 m, 65 × 65
/// samples.
pub fn valley() -> Heightfield {
    valley_at(Vec3::ZERO)
}

/// [`valley`] moved by `offset`.
pub fn valley_at(offset: Vec3) -> Heightfield {
    let size = UVec2::new(65, 65);
    let extent = Vec2::splat(40.0);
    let origin = Vec2::new(offset.x, offset.z) - 20.0;
    let heights = (0..size.y)
        .flat_map(|j| (0..size.x).map(move |i| (i, j)))
        .map(|(i, j)| {
            let x = origin.x + extent.x * i as f32 / 64.0;
            let z = origin.y + extent.y * j as f32 / 64.0;
            let (x, z) = (x - offset.x, z - offset.z);
            offset.y + 0.6 * (0.4 * x).sin() * (0.3 * z).cos() + 0.4 * x * x / (1.0 + 0.02 * x * x)
        })
        .collect();
    Heightfield::new(size, origin, extent, heights).expect("valid")
}

/// The valley's surface (placed at the origin) as triangles, two per half cell.
pub fn triangles(h: &Heightfield) -> Vec<[Vec3; 3]> {
    let mut out = Vec::new();
    let step = 40.0 / 128.0;
    for j in 0..128 {
        for i in 0..128 {
            let v = |a: u32, b: u32| {
                let xz = Vec2::splat(-20.0) + Vec2::new(a as f32, b as f32) * step;
                Vec3::new(xz.x, h.height(xz), xz.y)
            };
            out.push([v(i, j), v(i, j + 1), v(i + 1, j + 1)]);
            out.push([v(i, j), v(i + 1, j + 1), v(i + 1, j)]);
        }
    }
    out
}

/// Receivers over the valley's floor and slopes (12 × 8, 1–2 m apart) with the
/// surface's normals.
pub fn receivers(h: &Heightfield) -> Vec<(Vec3, Vec3)> {
    let mut out = Vec::new();
    for j in 0..8 {
        for i in 0..12 {
            let xz = Vec2::new(-5.5 + i as f32, -8.0 + 2.0 * j as f32);
            let e = 0.05;
            let g = Vec2::new(
                h.height(xz + Vec2::X * e) - h.height(xz - Vec2::X * e),
                h.height(xz + Vec2::Y * e) - h.height(xz - Vec2::Y * e),
            ) / (2.0 * e);
            out.push((
                Vec3::new(xz.x, h.height(xz), xz.y),
                Vec3::new(-g.x, 1.0, -g.y).normalize(),
            ));
        }
    }
    out
}
