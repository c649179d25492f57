use super::*;
use crate::object::TILE_SIZE;
use glam::DVec3;
use penumbra_sdf::exact;

/// Rolling hills and one steep ridge over 40 × 40 m, 65 × 65 samples.
pub(crate) fn terrain() -> Heightfield {
    let size = UVec2::new(65, 65);
    let extent = Vec2::splat(40.0);
    let origin = Vec2::new(-20.0, -20.0);
    let heights = (0..size.y)
        .flat_map(|j| (0..size.x).map(move |i| (i, j)))
        .map(|(i, j)| {
            let x = origin.x + extent.x * i as f32 / 64.0;
            let z = origin.y + extent.y * j as f32 / 64.0;
            1.5 * (0.3 * x).sin() * (0.2 * z).cos() + 4.0 * (1.0 / (1.0 + (x - 8.0).powi(2)))
        })
        .collect();
    Heightfield::new(size, origin, extent, heights).expect("valid")
}

/// The bilinear surface as triangles (two per cell, split so that each triangle lies
/// on the surface at its corners; the bilinear patch between is within the cell's
/// twist of them) for the exact distance.
fn triangles(h: &Heightfield) -> Vec<[DVec3; 3]> {
    let mut out = Vec::new();
    let n = 4; // sub-cells per cell: the bilinear patch, finely
    let cells = h.size - UVec2::ONE;
    let step = h.extent / (cells * n).as_vec2();
    for j in 0..cells.y * n {
        for i in 0..cells.x * n {
            let v = |a: u32, b: u32| {
                let xz = h.origin + Vec2::new(a as f32, b as f32) * step;
                DVec3::new(xz.x as f64, h.height(xz) as f64, xz.y as f64)
            };
            out.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
            out.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
        }
    }
    out
}

/// Against the exact distance to the (finely triangulated) surface at random points
/// above, below and beside the terrain, and just over and under it (on the rolling
/// hills and on the steep ridge): never farther (a lower bound, within the
/// triangulation's error), inside exactly below the surface, and on rolling ground away
/// from the ridge at least 0.8 of the truth on average (the per-tile slope bound: the
/// ridge's slope everywhere would give about 0.4).
#[test]
fn the_distance_is_a_tight_lower_bound() {
    let h = terrain();
    let tris = triangles(&h);
    let mut rng = 0x2545_f491u32;
    let mut unit = || {
        rng ^= rng << 13;
        rng ^= rng >> 17;
        rng ^= rng << 5;
        (rng >> 8) as f32 / (1 << 24) as f32
    };
    // Everywhere, and just over and under the surface (half of those at the ridge).
    let (mut flat, mut ratio) = (0, 0.0f32);
    for i in 0..600 {
        let (x, z) = (unit() * 50.0 - 25.0, unit() * 50.0 - 25.0);
        let p = match i % 3 {
            0 => Vec3::new(x, unit() * 10.0 - 3.0, z),
            1 => {
                let (x, z) = (x * 0.8, z * 0.8);
                Vec3::new(x, h.height(Vec2::new(x, z)) + unit() * 1.5 - 0.3, z)
            }
            _ => {
                let (x, z) = (8.0 + unit() * 4.0 - 2.0, z * 0.8);
                Vec3::new(x, h.height(Vec2::new(x, z)) + unit() * 1.5 - 0.3, z)
            }
        };
        let inside_rect = p.x.abs() < 20.0 && p.z.abs() < 20.0;
        let below = inside_rect && p.y < h.height(Vec2::new(p.x, p.z));
        let truth = exact::distance(p.as_dvec3(), &tris) as f32;
        let d = h.distance(p);
        assert_eq!(d < 0.0, below, "{p}: {d}");
        assert!(d.abs() <= truth + 1e-3, "{p}: {d}, exact {truth}");
        // Rolling ground two tiles (10 m) from the ridge: the local slope bound.
        if i % 3 == 1 && !below && (p.x - 8.0).abs() > 10.0 && truth > 0.05 {
            flat += 1;
            ratio += d / truth;
        }
    }
    let ratio = ratio / flat.max(1) as f32;
    assert!(
        flat > 30 && ratio > 0.8,
        "{flat} points on rolling ground, mean ratio {ratio}"
    );
}

#[test]
fn bad_heights_are_refused_with_a_reason() {
    let ok = |n: u32| vec![0.0f32; (n * n) as usize];
    let table: [(UVec2, Vec2, Vec<f32>, &str); 5] = [
        (UVec2::new(1, 5), Vec2::ONE, vec![0.0; 5], "2 × 2"),
        (UVec2::new(3, 3), Vec2::ONE, vec![0.0; 8], "2 × 2"),
        (UVec2::new(3, 3), Vec2::new(0.0, 1.0), ok(3), "world size"),
        (
            UVec2::new(3, 3),
            Vec2::new(f32::NAN, 1.0),
            ok(3),
            "world size",
        ),
        (
            UVec2::new(2, 2),
            Vec2::ONE,
            vec![0.0, f32::INFINITY, 0.0, 0.0],
            "height 1",
        ),
    ];
    for (size, extent, heights, why) in table {
        let e = Heightfield::new(size, Vec2::ZERO, extent, heights).unwrap_err();
        assert!(e.to_string().contains(why), "{e}");
    }
    // Beside the rectangle: positive, at least the horizontal gap.
    let h = terrain();
    assert!(h.distance(Vec3::new(30.0, -5.0, 0.0)) >= 10.0);
}

/// The GPU's form (tile-relative, heights and slope bounds in a texture beside another
/// terrain) gives the CPU distance: within 1e-5 m near the origin and within f32's
/// rounding of world positions 10⁵ m out.
#[test]
fn the_texture_form_gives_the_cpu_distance() {
    let near = terrain();
    let far = {
        let t = terrain();
        let lift = |v: f32| v + 30.0;
        Heightfield::new(
            t.size,
            t.origin + Vec2::new(1.0e5, -7.0e4),
            t.extent,
            t.heights.iter().copied().map(lift).collect(),
        )
        .expect("valid")
    };
    let small = Heightfield::new(
        UVec2::new(3, 2),
        Vec2::new(5.0, 5.0),
        Vec2::new(2.0, 1.0),
        vec![0.0, 1.0, 0.5, 0.2, 0.3, 0.4],
    )
    .expect("valid");
    let (texture, refused) = HeightfieldTexture::pack(&[&small, &near, &far], 4096);
    assert!(refused.is_empty());
    assert_eq!(texture.records.len(), 3);
    assert_eq!(texture.width, 65);
    let mut rng = 0x2545_f491_u64;
    let mut next = move || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng >> 11) as f32 / (1u64 << 53) as f32
    };
    for (h, record, tolerance) in [
        (&small, &texture.records[0], 1e-5),
        (&near, &texture.records[1], 1e-5),
        (&far, &texture.records[2], 0.02),
    ] {
        let tile = record.tile.as_vec3() * TILE_SIZE;
        let mut worst = 0.0f32;
        for _ in 0..4000 {
            let (lo, hi) = h.bounds();
            let u = Vec3::new(next(), next(), next());
            let world = lo - Vec3::splat(3.0) + (hi - lo + Vec3::splat(6.0)) * u;
            let gpu = texture.distance(record, world - tile);
            worst = worst.max((gpu - h.distance(world)).abs());
        }
        assert!(worst <= tolerance, "{worst} > {tolerance}");
    }
}

/// Terrains that do not fit the texture are left out with a reason; the rest keep
/// their rows.
#[test]
fn terrains_beyond_the_texture_are_left_out() {
    let t = terrain();
    let (texture, refused) = HeightfieldTexture::pack(&[&t, &t, &t], 160);
    // 65 height rows + 8 slope rows each: two fit in 160.
    assert_eq!(texture.records.len(), 2);
    assert_eq!(texture.records[1].row, 73);
    assert_eq!(refused.len(), 1);
    assert_eq!(refused[0].0, 2);
    assert!(refused[0].1.contains("160"), "{}", refused[0].1);
    let (empty, none) = HeightfieldTexture::pack(&[], 160);
    assert!(none.is_empty() && empty.records.is_empty());
    assert_eq!((empty.width, empty.rows, empty.texels.len()), (1, 1, 1));
}
