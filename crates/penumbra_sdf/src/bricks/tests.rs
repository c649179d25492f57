use super::*;
use glam::DVec3;

/// A sphere of `radius` voxels centred in a `dims` grid, sampled exactly.
fn sphere(dims: UVec3, radius: f32) -> SdfVolume {
    let centre = (dims - UVec3::ONE).as_vec3() * 0.5;
    let mut d = Vec::new();
    for k in 0..dims.z {
        for j in 0..dims.y {
            for i in 0..dims.x {
                d.push((UVec3::new(i, j, k).as_vec3() - centre).length() - radius);
            }
        }
    }
    let mut v = SdfVolume::from_distances(dims, DVec3::ZERO, 1.0, d);
    v.margin = 2.0;
    v
}

/// Deterministic points of `[0, dims − 1]` (a 3-D Halton set).
fn points(dims: UVec3, n: u32) -> impl Iterator<Item = Vec3> {
    let hi = (dims - UVec3::ONE).as_vec3();
    (1..=n).map(move |i| DVec3::from(penumbra_testkit::halton3(i)).as_vec3() * hi)
}

fn dense(v: &SdfVolume, c: Vec3) -> f32 {
    v.trilinear_voxels(c)
}

/// With every brick stored, the bricked field is the dense one everywhere, on a grid
/// whose sides are not whole bricks (the last brick overhangs; a span of 8 instead of
/// 7, or bricks that did not overlap, fail here).
#[test]
fn every_brick_stored_is_the_dense_field() {
    let v = sphere(UVec3::new(23, 9, 16), 5.0);
    let b = BrickedVolume::from_volume(&v, f32::INFINITY);
    assert_eq!(b.grid, UVec3::new(4, 2, 3));
    assert_eq!(b.stored(), 24);
    let mut worst = 0.0f32;
    for c in points(v.dims, 4000).chain([Vec3::ZERO, (v.dims - UVec3::ONE).as_vec3()]) {
        worst = worst.max((b.sample_voxels(c) - dense(&v, c)).abs());
    }
    assert!(worst < 1e-4, "bricked differs from dense by {worst} voxels");
}

/// Within the band the bricked field is the dense one; beyond it, never farther from
/// zero and of the same sign (a conservative distance); and a sphere's bricks take a
/// small share of its grid.
#[test]
fn bricks_keep_the_band_and_bound_the_rest() {
    let v = sphere(UVec3::splat(200), 80.0);
    let b = BrickedVolume::from_volume(&v, DEFAULT_BAND_VOXELS);
    let share = b.bytes() as f64 / b.dense_bytes() as f64;
    assert!(share < 0.3, "bricked bytes are {share:.3} of dense");
    let (mut near, mut far, mut worst_near, mut lowest_far) = (0, 0, 0.0f32, f32::INFINITY);
    let mut far_ratio = 0.0f64;
    for c in points(v.dims, 20_000) {
        let (d, s) = (dense(&v, c), b.sample_voxels(c));
        assert!(
            d.signum() == s.signum() && s.abs() <= d.abs() + 1e-4,
            "at {c}: bricked {s}, dense {d}"
        );
        if d.abs() < DEFAULT_BAND_VOXELS - 1.0 {
            near += 1;
            worst_near = worst_near.max((s - d).abs());
        } else {
            far += 1;
            lowest_far = lowest_far.min(s.abs() / d.abs());
            far_ratio += (s / d) as f64;
        }
    }
    assert!(near > 500 && far > 5000, "near {near}, far {far}");
    assert!(
        worst_near < 1e-4,
        "bricked differs from dense by {worst_near} in the band"
    );
    // Empty bricks read the coarse grid less a voxel, at least their nearest sample (the
    // nearest sample alone reads as low as 0.25 and 0.78 on average here).
    let mean = far_ratio / far as f64;
    println!("far from the surface: bricked / dense ≥ {lowest_far:.3}, mean {mean:.3}");
    assert!(
        lowest_far > 0.6 && mean > 0.95,
        "far reads {lowest_far} (mean {mean}) of dense"
    );
}

/// Sphere tracing the bricked field toward a sphere's centre stops at the analytic
/// surface (independent truth), as the dense field does, from every direction.
#[test]
fn sphere_tracing_the_bricks_finds_the_analytic_surface() {
    let dims = UVec3::splat(100);
    let radius = 30.0;
    let v = sphere(dims, radius);
    let b = BrickedVolume::from_volume(&v, DEFAULT_BAND_VOXELS);
    let centre = Vec3::splat(49.5);
    let (mut steps_dense, mut steps_bricked) = (0, 0);
    for (n, dir) in points(UVec3::splat(3), 200).enumerate() {
        let dir = (dir - Vec3::ONE).normalize_or(Vec3::X);
        let start = centre + dir * 48.0;
        let trace = |f: &dyn Fn(Vec3) -> f32, steps: &mut u32| {
            let mut t = 0.0;
            for _ in 0..256 {
                *steps += 1;
                let d = f(start - dir * t);
                if d < 0.01 {
                    break;
                }
                t += d;
            }
            t
        };
        let t_dense = trace(&|c| dense(&v, c), &mut steps_dense);
        let t_bricked = trace(&|c| b.sample_voxels(c), &mut steps_bricked);
        let truth = 48.0 - radius;
        assert!(
            (t_bricked - truth).abs() < 0.05 && (t_bricked - t_dense).abs() < 0.02,
            "direction {n}: bricked hit at {t_bricked}, dense {t_dense}, truth {truth}"
        );
    }
    assert!(steps_bricked >= steps_dense && steps_bricked < 4 * steps_dense);
}

/// A band of zero keeps only the bricks the surface crosses; a NaN band stores all.
#[test]
fn degenerate_bands() {
    let v = sphere(UVec3::splat(40), 12.0);
    let crossing = BrickedVolume::from_volume(&v, 0.0);
    assert!(crossing.stored() > 0 && crossing.stored() < crossing.bricks.len());
    let all = BrickedVolume::from_volume(&v, f32::NAN);
    assert_eq!(all.stored(), all.bricks.len());
    let tiny = sphere(UVec3::splat(2), 0.1);
    let t = BrickedVolume::from_volume(&tiny, 4.0);
    assert_eq!(t.grid, UVec3::ONE);
    assert!((t.sample_voxels(Vec3::splat(0.5)) - dense(&tiny, Vec3::splat(0.5))).abs() < 1e-4);
}

/// A plane's field is linear: empty bricks read it to within the slack (the coarse
/// grid is exact, also where the last bricks overhang the grid); stored bricks exactly.
#[test]
fn a_plane_reads_exactly_less_the_slack_far_from_it() {
    let dims = UVec3::new(40, 60, 30);
    let n = Vec3::new(0.3, 0.9, 0.2).normalize();
    let mut d = Vec::new();
    for k in 0..dims.z {
        for j in 0..dims.y {
            for i in 0..dims.x {
                d.push(n.dot(UVec3::new(i, j, k).as_vec3()) - 25.0);
            }
        }
    }
    let v = SdfVolume::from_distances(dims, DVec3::ZERO, 1.0, d);
    let b = BrickedVolume::from_volume(&v, DEFAULT_BAND_VOXELS);
    assert!(
        b.stored() < b.bricks.len() / 2,
        "{} of {}",
        b.stored(),
        b.bricks.len()
    );
    for c in points(dims, 5000) {
        let (want, got) = (dense(&v, c), b.sample_voxels(c));
        let (brick, _) = b.locate(c);
        let i = (brick.x + b.grid.x * (brick.y + b.grid.y * brick.z)) as usize;
        let slack = match b.bricks[i] {
            Brick::Stored(_) => 0.0,
            Brick::Empty(_) => COARSE_SLACK_VOXELS,
        };
        // Between the dense value and it less the slack (an empty brick's nearest sample
        // may lie nearer the plane than that); f16 samples: 0.02-voxel steps.
        let (got, want) = (got * want.signum(), want.abs());
        assert!(
            got <= want + 0.05 && got >= want - slack - 0.05,
            "at {c}: {got}, dense {want}"
        );
    }
}

/// The row-at-a-time scan over half-float bits picks the same bricks, empty values and
/// samples as the definition (every sample in turn, as `f32`), on a grid whose last
/// bricks overhang every axis and whose samples include ±0, ±∞, NaN and ties of
/// magnitude between signs.
#[test]
fn the_brick_scan_follows_the_definition() {
    let dims = UVec3::new(28, 12, 17);
    let mut s = 0x2545_f491_4f6c_dd1du64;
    let special = [
        0.0f32,
        -0.0,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NAN,
        2.5,
        -2.5,
    ];
    let data: Vec<f16> = (0..dims.element_product())
        .map(|i| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            let noise = ((s >> 16) % 4000) as f32 * 0.01;
            // Beyond x = 13, positive and at least 6 from zero: empty bricks for the
            // smaller bands, negative ones too beyond x = 20.
            let far = [f32::INFINITY, f32::NEG_INFINITY, f32::NAN, -f32::NAN];
            let v = match i % dims.x {
                // Rare non-finite samples among the far ones: a NaN of either sign
                // counts as neither sign, −∞ as negative.
                x if x > 13 && s.is_multiple_of(97) => far[(s >> 8) as usize % far.len()],
                x if x > 20 => -6.0 - noise,
                x if x > 13 => 6.0 + noise,
                _ if s.is_multiple_of(11) => special[(s >> 8) as usize % special.len()],
                _ => noise - 20.0,
            };
            f16::from_f32(v)
        })
        .collect();
    let mut v = SdfVolume::from_distances(dims, DVec3::ZERO, 1.0, vec![0.0; data.len()]);
    v.data = data;
    for band in [0.5, DEFAULT_BAND_VOXELS, 9.0] {
        let b = BrickedVolume::from_volume(&v, band);
        let mut stored = 0u32;
        for (n, brick) in b.bricks.iter().enumerate() {
            let n = n as u32;
            let base = UVec3::new(
                n % b.grid.x,
                (n / b.grid.x) % b.grid.y,
                n / (b.grid.x * b.grid.y),
            ) * BRICK_SPAN;
            let mut expected = Vec::with_capacity(BRICK_LEN);
            let mut least = f16::INFINITY;
            let (mut negative, mut positive) = (false, false);
            for l in 0..BRICK_LEN as u32 {
                let local = UVec3::new(l % 8, (l / 8) % 8, l / 64);
                let p = (base + local).min(dims - UVec3::ONE);
                let sample = v.data[v.index(p.x, p.y, p.z)];
                let x = sample.to_f32();
                negative |= x < 0.0;
                positive |= x >= 0.0;
                if x.abs() < least.to_f32().abs() {
                    least = sample;
                }
                expected.push(sample);
            }
            if least.to_f32().abs() < band || (negative && positive) {
                assert_eq!(*brick, Brick::Stored(stored), "brick {n}, band {band}");
                let got = &b.samples[stored as usize * BRICK_LEN..][..BRICK_LEN];
                assert!(
                    got.iter()
                        .zip(&expected)
                        .all(|(a, e)| a.to_bits() == e.to_bits()),
                    "brick {n}'s samples"
                );
                stored += 1;
            } else {
                assert_eq!(brick.clone(), Brick::Empty(least), "brick {n}, band {band}");
            }
        }
        let empty = b.bricks.len() - stored as usize;
        assert!(
            stored > 0 && (band > 6.0 || empty > 0),
            "band {band}: {stored} stored"
        );
    }
}
