use super::*;

fn small() -> ClipmapLayout {
    ClipmapLayout::new(3, 32, 6.4, 2.0).0
}

#[test]
fn bad_layouts_are_clamped_and_named() {
    // (levels, resolution, first extent, growth) → (levels, resolution, extent, growth,
    // problem lines).
    type Request = (u32, u32, f32, f32);
    let nan = f32::NAN;
    type Expected = (u32, u32, f32, f32, usize);
    let table: [(Request, Expected); 9] = [
        ((4, 128, 25.6, 2.0), (4, 128, 25.6, 2.0, 0)),
        ((0, 128, 25.6, 2.0), (1, 128, 25.6, 2.0, 1)),
        ((99, 128, 25.6, 2.0), (MAX_LEVELS, 128, 25.6, 2.0, 1)),
        ((4, 0, 25.6, 2.0), (4, MIN_RESOLUTION, 25.6, 2.0, 1)),
        ((4, 100, 25.6, 2.0), (4, 104, 25.6, 2.0, 1)),
        ((4, 1 << 20, 25.6, 2.0), (4, MAX_RESOLUTION, 25.6, 2.0, 1)),
        ((4, 128, nan, 2.0), (4, 128, 25.6, 2.0, 1)),
        ((4, 128, -3.0, 0.5), (4, 128, 25.6, 1.0, 2)),
        ((4, 128, 1e-9, f32::INFINITY), (4, 128, 1.28, 2.0, 2)),
    ];
    for ((l, r, e, g), (l2, r2, e2, g2, n)) in table {
        let (layout, problems) = ClipmapLayout::new(l, r, e, g);
        let got = (
            layout.levels,
            layout.resolution,
            layout.first_extent,
            layout.growth,
        );
        assert_eq!(got, (l2, r2, e2, g2), "{:?}", (l, r, e, g));
        assert_eq!(problems.len(), n, "{problems:?}");
        assert!(layout.extent(layout.levels - 1).is_finite());
    }
    let (huge, problems) = ClipmapLayout::new(8, 128, 25.6, 1e30);
    assert!(
        huge.extent(7).is_finite() && !problems.is_empty(),
        "{problems:?}"
    );
}

#[test]
fn windows_are_brick_aligned_around_the_camera_anywhere() {
    let layout = ClipmapLayout::DEFAULT;
    for camera in [
        Vec3::ZERO,
        Vec3::new(3.3, -7.9, 0.01),
        Vec3::new(1.0e5, 20.0, -1.0e5),
    ] {
        for level in 0..layout.levels {
            let o = layout.window_origin(level, camera).expect("finite");
            assert_eq!(o % BRICK as i32, IVec3::ZERO);
            let centre =
                layout.texel_centre(level, o + IVec3::splat(64)) - 0.5 * layout.texel(level);
            let off = (centre - camera).abs().max_element();
            assert!(
                off <= 0.5 * BRICK as f32 * layout.texel(level) * 1.001,
                "{off}"
            );
        }
    }
    // An odd number of bricks per side (24 texels: 3) stays brick-aligned too.
    let odd = ClipmapLayout::new(2, 24, 4.8, 2.0).0;
    for x in [0.0, 0.7, 1.7, -3.3] {
        let o = odd.window_origin(0, Vec3::new(x, 1.2, -x)).unwrap();
        assert_eq!(o % BRICK as i32, IVec3::ZERO, "{o}");
    }
    assert_eq!(layout.window_origin(0, Vec3::NAN), None);
    assert_eq!(layout.window_origin(0, Vec3::splat(1e30)), None);
    // Toroidal: the texels of a window land on every storage texel once.
    let o = IVec3::new(-40, 8, 1000);
    let mut seen = vec![false; 128 * 128 * 128];
    for z in 0..128 {
        for y in 0..128 {
            for x in 0..128 {
                let s = layout.storage(o + IVec3::new(x, y, z));
                let i = (s.x + 128 * (s.y + 128 * s.z)) as usize;
                assert!(!seen[i]);
                seen[i] = true;
            }
        }
    }
}

#[test]
fn a_still_camera_composes_nothing_after_the_first_frames() {
    let layout = small();
    let mut state = ClipmapState::new(layout);
    let camera = Vec3::new(1.0, 2.0, 3.0);
    let first = state.update(camera, &[], usize::MAX);
    assert_eq!(first.jobs.len(), 3 * 64);
    assert_eq!(first.scrolled, 3 * 64);
    for _ in 0..20 {
        let u = state.update(camera, &[], usize::MAX);
        assert_eq!(
            (u.jobs.len(), u.scrolled, u.dirtied, u.pending),
            (0, 0, 0, 0)
        );
    }
    for level in 0..3 {
        assert_eq!(state.valid_bits(level), vec![u32::MAX; 2]);
    }
}

#[test]
fn moving_one_brick_reveals_one_slab() {
    let layout = small();
    let mut state = ClipmapState::new(layout);
    state.update(Vec3::ZERO, &[], usize::MAX);
    // One level-0 brick (1.6 m) along x: level 0 reveals a 4 × 4 slab; level 1's bricks
    // are 3.2 m, and 1.6 m rounds it over too (0.5 bricks rounds away from zero).
    let u = state.update(Vec3::new(1.6, 0.0, 0.0), &[], usize::MAX);
    let level0: Vec<_> = u.jobs.iter().filter(|j| j.level == 0).collect();
    assert_eq!(level0.len(), 16);
    let x = state.window(0).unwrap().max.x - 1;
    assert!(level0.iter().all(|j| j.brick.x == x), "{level0:?}");
}

#[test]
fn far_levels_move_less_often_and_dirty_regions_reach_them_at_once() {
    assert!((0..8).all(|f| ClipmapState::moves_on(0, f) && ClipmapState::moves_on(1, f)));
    let moves: Vec<u64> = (0..8).filter(|&f| ClipmapState::moves_on(2, f)).collect();
    assert_eq!(moves.len(), 4);
    let moves: Vec<u64> = (0..8).filter(|&f| ClipmapState::moves_on(3, f)).collect();
    assert_eq!(moves.len(), 2);
    let layout = small();
    let mut state = ClipmapState::new(layout);
    state.update(Vec3::ZERO, &[], usize::MAX);
    // A caster appears near the camera: every level has pending bricks around it.
    let d = DirtyBox {
        min: Vec3::splat(0.5),
        max: Vec3::splat(0.7),
    };
    let u = state.update(Vec3::ZERO, &[d], 0);
    assert!(u.dirtied > 0 && u.jobs.is_empty());
    for level in 0..3 {
        let b = layout
            .bricks_near(level, d.min, d.max, layout.band(level))
            .unwrap();
        assert!(b.iter().all(|b| !state.is_valid(level, b)), "level {level}");
    }
}

#[test]
fn dirty_boxes_mark_exactly_the_bricks_within_the_band() {
    let layout = small();
    let level = 0;
    let t = layout.texel(level);
    let band = layout.band(level);
    let (min, max) = (Vec3::new(0.3, -1.0, 2.0), Vec3::new(0.9, 0.2, 2.1));
    let bricks = layout.bricks_near(level, min, max, band).unwrap();
    // Brute force: a brick is marked iff one of its texel centres lies within `band`
    // of the box along each axis (the box grown by the band).
    let b = BRICK as i32;
    for z in -6..6 {
        for y in -6..6 {
            for x in -6..6 {
                let brick = IVec3::new(x, y, z);
                let near = (0..b * b * b).any(|i| {
                    let w = brick * b + IVec3::new(i % b, (i / b) % b, i / (b * b));
                    let c = (w.as_vec3() + 0.5) * t;
                    c.cmpge(min - band).all() && c.cmple(max + band).all()
                });
                assert_eq!(bricks.contains(brick), near, "{brick}");
            }
        }
    }
    assert!(layout.bricks_near(0, Vec3::NAN, max, band).is_none());
}

#[test]
fn a_teleport_spreads_over_frames_under_the_budget() {
    let layout = small();
    let mut state = ClipmapState::new(layout);
    state.update(Vec3::ZERO, &[], usize::MAX);
    let camera = Vec3::new(500.0, 0.0, -300.0);
    let mut frames = 0;
    let mut total = 0;
    loop {
        let u = state.update(camera, &[], 20);
        assert!(u.jobs.len() <= 20);
        total += u.jobs.len();
        frames += 1;
        // Finest level first: level 0 is whole before level 1 starts.
        if u.jobs.iter().any(|j| j.level > 0) {
            assert!(state.levels[0].pending.is_empty());
        }
        if u.pending == 0 && (0..3).all(|l| state.window(l).is_some()) {
            break;
        }
        assert!(frames < 100);
    }
    // Every brick of every level once (level 2 moved on its own frames; none lost).
    assert!(total >= 3 * 64, "{total}");
    assert!(frames >= 3 * 64 / 20);
    for level in 0..3 {
        assert_eq!(state.valid_bits(level), vec![u32::MAX; 2], "level {level}");
    }
}

#[test]
fn valid_bits_follow_storage_addresses() {
    let layout = small();
    let mut state = ClipmapState::new(layout);
    state.update(Vec3::new(-3.0, 0.0, 0.0), &[], usize::MAX);
    let d = DirtyBox {
        min: Vec3::new(-2.0, 0.1, 0.1),
        max: Vec3::new(-1.9, 0.2, 0.2),
    };
    state.update(Vec3::new(-3.0, 0.0, 0.0), &[d], 0);
    let bits = state.valid_bits(0);
    let window = state.window(0).unwrap();
    for b in window.iter() {
        let s = b.rem_euclid(IVec3::splat(4));
        let i = (s.x + 4 * (s.y + 4 * s.z)) as usize;
        assert_eq!(
            bits[i / 32] >> (i % 32) & 1 == 1,
            state.is_valid(0, b),
            "{b}"
        );
    }
    assert!(bits.iter().map(|w| w.count_zeros()).sum::<u32>() > 0);
}

#[test]
fn record_dirty_boxes_hold_the_bounding_ball_and_skip_what_stays_out() {
    use crate::object::{CasterShape, ObjectDesc, encode, flags};
    use glam::{Affine3A, Quat};
    let live = flags::LIVE | flags::CASTS_OCCLUSION | flags::VISIBLE;
    for offset in [Vec3::ZERO, Vec3::new(1.0e5, 3.0, -1.0e5)] {
        let m = Affine3A::from_scale_rotation_translation(
            Vec3::new(2.0, 1.0, 0.5),
            Quat::from_rotation_y(0.7),
            offset + Vec3::new(1.0, 2.0, 3.0),
        );
        let shape = CasterShape::Cuboid {
            half_extents: Vec3::new(0.5, 1.0, 0.25),
        };
        let r = encode(&ObjectDesc {
            world_from_local: m,
            shape,
            flags: live,
        })
        .unwrap();
        let d = record_dirty_box(&r).expect("composes");
        // Every corner of the box (world) is inside, and the box is not huge.
        for i in 0..8 {
            let c = Vec3::new(
                if i & 1 == 0 { -0.5 } else { 0.5 },
                if i & 2 == 0 { -1.0 } else { 1.0 },
                if i & 4 == 0 { -0.25 } else { 0.25 },
            );
            let w = m.transform_point3(c);
            assert!(w.cmpge(d.min).all() && w.cmple(d.max).all(), "{w} {d:?}");
        }
        assert!((d.max - d.min).max_element() < 5.0, "{d:?}");
        let foliage = encode(&ObjectDesc {
            world_from_local: m,
            shape,
            flags: live | flags::ao_transmission_bits(0.5),
        })
        .unwrap();
        assert!(record_dirty_box(&foliage).is_none());
        let no_ao = encode(&ObjectDesc {
            world_from_local: m,
            shape,
            flags: flags::LIVE | flags::CASTS_SHADOWS | flags::VISIBLE,
        })
        .unwrap();
        assert!(record_dirty_box(&no_ao).is_none());
    }
    let plane = encode(&ObjectDesc {
        world_from_local: Affine3A::IDENTITY,
        shape: CasterShape::Plane,
        flags: live | flags::UNBOUNDED,
    })
    .unwrap();
    let d = record_dirty_box(&plane).unwrap();
    let layout = ClipmapLayout::DEFAULT;
    let mut state = ClipmapState::new(layout);
    state.update(Vec3::ZERO, &[], usize::MAX);
    // A plane that changes dirties every brick of every level.
    let u = state.update(Vec3::ZERO, &[d], 0);
    assert_eq!(u.dirtied, 4 * layout.bricks_per_level() as usize);
}
