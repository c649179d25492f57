use super::*;
use crate::shapes;

/// Outside the sample box a two-sided field stays a lower bound of the distance to
/// its shell, positive: a flat 1 m quad (the box a few voxels thick) read from above,
/// beside and below its box. With the margin measured from the mesh alone, the shell
/// reached past the shrunk box and every point outside read as inside (−0.14 m at
/// 0.3 m above the quad).
#[test]
fn a_flat_two_sided_field_is_outside_its_box() {
    let quad = TriMesh {
        positions: vec![
            Vec3::new(-0.5, 0.0, -0.5),
            Vec3::new(0.5, 0.0, -0.5),
            Vec3::new(0.5, 0.0, 0.5),
            Vec3::new(-0.5, 0.0, 0.5),
        ],
        triangles: vec![[0, 2, 1], [0, 3, 2]],
        ..Default::default()
    };
    let settings = BakeSettings {
        sign: SignMethod::TWO_SIDED,
        ..BakeSettings::longest_axis(32)
    };
    let v = bake(&quad, &settings, None).unwrap().volume;
    let h = f64::from(v.voxel_size);
    let shell = 0.866 * h;
    for p in [
        glam::DVec3::new(0.1, 0.3, 0.0),
        glam::DVec3::new(0.0, -0.5, 0.2),
        glam::DVec3::new(0.2, 1.5, -0.3),
        glam::DVec3::new(0.9, 0.05, 0.0),
        glam::DVec3::new(-0.8, 0.4, 0.7),
    ] {
        // The exact distance to the quad, less the shell.
        let c = glam::DVec3::new(p.x.clamp(-0.5, 0.5), 0.0, p.z.clamp(-0.5, 0.5));
        let truth = (p - c).length() - shell;
        let d = f64::from(v.sample(p));
        assert!(d > 0.0, "{p}: {d} inside");
        assert!(d <= truth + 0.05 * h, "{p}: {d} over the truth {truth}");
    }
}

/// The thin-feature guard's triangle prefilter (skip triangles whose box holds only
/// settled cells) flips exactly the samples the full lattice walk flips.
/// Outside its sample box a solid field is outside, even where the thin-feature guard
/// put an inside sample on the box shrunk by the margin: a 2 mm plate in a grid of 18 mm
/// voxels (the guard flips a sample on the plate's bounds, where the margin's box ends),
/// read beyond every face of its box. Reading the sign at the shrunk box alone made the
/// whole half-space beyond that face inside (a metal plaque on `FlightHelmet`'s base
/// shadowed the base).
#[test]
fn a_thin_part_on_its_bounds_leaves_the_outside_outside() {
    let plate = shapes::cuboid(Vec3::new(0.25, 0.15, 0.001));
    let bake = bake(&plate, &BakeSettings::longest_axis(32), None).unwrap();
    assert!(bake.thin_feature_samples > 0, "the guard flipped nothing");
    let v = bake.volume;
    let h = f64::from(v.voxel_size);
    let lo = v.origin;
    let hi = v.origin + (v.dims.as_dvec3() - glam::DVec3::ONE) * h;
    let mut checked = 0;
    for axis in 0..3 {
        for side in [-1.0, 1.0] {
            for (u, w) in [(0.0, 0.0), (0.3, -0.2), (-0.45, 0.4)] {
                let mut p = glam::DVec3::new(u * 0.5, w * 0.3, 0.0);
                p[axis] = if side < 0.0 { lo[axis] } else { hi[axis] } + side * 0.5 * h;
                // The exact distance to the box.
                let half = glam::DVec3::new(0.25, 0.15, 0.001);
                let truth = (p.abs() - half).max(glam::DVec3::ZERO).length();
                let d = f64::from(v.sample(p));
                assert!(d > 0.0, "{p}: {d} inside");
                assert!(d <= truth + 0.05 * h, "{p}: {d} over the truth {truth}");
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 18);
}

#[test]
fn thin_feature_prefilter_changes_nothing() {
    let mut plate = shapes::thin_plate(1.0, 1.0, 0.004);
    // Between sample layers, tilted: the guard has work to do.
    let tilt = glam::Quat::from_rotation_x(0.3) * glam::Quat::from_rotation_z(0.2);
    plate
        .positions
        .iter_mut()
        .for_each(|p| *p = tilt * *p + Vec3::splat(0.013));
    let cases = [
        ("plate", plate),
        ("torus", shapes::torus(1.0, 0.05, 64, 16)),
        ("soup", shapes::intersecting_soup()),
        ("sphere", shapes::sphere(1.0, 32, 16)),
    ];
    let mut guarded = 0;
    for (name, mesh) in cases {
        let settings = BakeSettings {
            keep_thin_features: false,
            ..BakeSettings::longest_axis(24)
        };
        let unguarded = bake(&mesh, &settings, None).unwrap();
        let (tris, _) = mesh.validate().unwrap();
        let border = unguarded.grid.border;
        let run = |skip: bool| {
            let mut v = unguarded.volume.clone();
            let origin = v.origin.as_vec3();
            let n = keep_thin_features_with(&mut v, &tris, origin, border, skip);
            (n, v.data.iter().map(|h| h.to_bits()).collect::<Vec<_>>())
        };
        let (with, without) = (run(true), run(false));
        assert_eq!(with.0, without.0, "{name}: samples flipped");
        let first = with.1.iter().zip(&without.1).position(|(a, b)| a != b);
        assert_eq!(first, None, "{name}: first differing sample");
        guarded += with.0;
    }
    assert!(guarded > 0, "no case exercised the guard");
}

/// The thin-wall rule (`grid::ThinWalls`): a closed plate 2 cm thick under the
/// default 2.3 cm voxels measures its wall and bakes with two voxels across it (2.3
/// times finer, under the rule's cap of 3), and its field is closer to the exact
/// distance of the box near the plate; a 1 m cube and a two-sided bake keep their
/// grids.
#[test]
fn thin_walls_get_finer_voxels() {
    use crate::grid::ThinWalls;
    let plate = shapes::thin_plate(1.0, 1.0, 0.02);
    let on = bake(&plate, &BakeSettings::default(), None).unwrap();
    let off_settings = BakeSettings {
        grid: GridPolicy {
            thin_walls: ThinWalls::OFF,
            ..GridPolicy::default()
        },
        ..BakeSettings::default()
    };
    let off = bake(&plate, &off_settings, None).unwrap();
    let wall = on.wall_thickness.expect("a wall");
    assert!((wall - 0.02).abs() < 1e-4, "{wall}");
    // Two voxels across the wall, within the cap.
    let want = (off.grid.voxel_size / (0.5 * wall)).min(ThinWalls::default().max_refine);
    assert!(
        (on.thin_wall_refine - want).abs() < 0.05,
        "{} vs {want}",
        on.thin_wall_refine
    );
    assert_eq!(off.thin_wall_refine, 1.0);
    let ratio = off.grid.voxel_size / on.grid.voxel_size;
    assert!((ratio - want).abs() < 0.1, "{ratio} vs {want}");
    // The exact distance of the box (half extents 0.5, 0.01, 0.5) near its faces.
    let exact = |p: Vec3| {
        let q = p.abs() - Vec3::new(0.5, 0.01, 0.5);
        q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
    };
    let error = |b: &Bake| {
        let (mut sum, mut n) = (0.0f64, 0);
        for i in 0..17 {
            for j in 0..13 {
                for k in 0..17 {
                    let p = Vec3::new(
                        -0.4 + 0.05 * i as f32,
                        -0.03 + 0.005 * j as f32,
                        -0.4 + 0.05 * k as f32,
                    );
                    let got = b.volume.sample(p.as_dvec3());
                    sum += f64::from((got - exact(p)).abs());
                    n += 1;
                }
            }
        }
        sum / f64::from(n)
    };
    let (e_on, e_off) = (error(&on), error(&off));
    println!("plate: mean |field − exact| {e_on:.5} m refined, {e_off:.5} m not");
    assert!(e_on < 0.6 * e_off, "{e_on} {e_off}");

    let cube = bake(
        &shapes::cuboid(Vec3::splat(0.5)),
        &BakeSettings::default(),
        None,
    )
    .unwrap();
    assert_eq!(cube.thin_wall_refine, 1.0);
    let shell = BakeSettings {
        sign: SignMethod::TWO_SIDED,
        ..BakeSettings::default()
    };
    let shell = bake(&plate, &shell, None).unwrap();
    assert_eq!((shell.wall_thickness, shell.thin_wall_refine), (None, 1.0));
}

/// Ground ([`SignMethod::SolidBelow`]): rolling hills bake as the top of a solid — every
/// sample under the sheet within its footprint is inside and every other outside (the
/// analytic heights decide, away from the sheet by half a voxel), the magnitudes are the
/// exact (f64, brute force) distances to the triangles, and the box reaches below the
/// sheet. The same sheet turned so that its up is +z (rays up the grid's columns) or
/// tilted by 30° (rays from every sample), baked with its up, gives the same signs: the
/// direction is the mesh's, not the grid's.
#[test]
fn a_ground_sheet_bakes_solid_below() {
    let height = |x: f32, z: f32| 0.15 * (3.0 * x).sin() * (2.0 * z).cos();
    let (positions, indices) = crate::ground::tests::sheet(24, height);
    let triangles: Vec<[u32; 3]> = indices.chunks(3).map(|t| [t[0], t[1], t[2]]).collect();
    for turn in [
        glam::Quat::IDENTITY,
        glam::Quat::from_rotation_x(std::f32::consts::FRAC_PI_2),
        glam::Quat::from_rotation_x(0.5),
    ] {
        let up = turn * Vec3::Y * 2.0;
        let mesh = TriMesh {
            positions: positions.iter().map(|&p| turn * p).collect(),
            triangles: triangles.clone(),
            ..Default::default()
        };
        let settings = BakeSettings {
            sign: SignMethod::SolidBelow { up },
            ..BakeSettings::longest_axis(40)
        };
        let bake = bake(&mesh, &settings, None).unwrap();
        let v = &bake.volume;
        let h = f64::from(v.voxel_size);
        let tris: Vec<[Vec3; 3]> = mesh
            .triangles
            .iter()
            .map(|t| t.map(|i| mesh.positions[i as usize]))
            .collect();
        let border = bake.grid.border;
        let (mut inside, mut checked) = (0, 0);
        for k in border..v.dims.z - border {
            for j in border..v.dims.y - border {
                for i in border..v.dims.x - border {
                    let p = v.origin + h * glam::DVec3::new(i as f64, j as f64, k as f64);
                    let exact = crate::exact::distance(p, &tris);
                    let got = f64::from(v.get(i, j, k));
                    assert!(
                        (got.abs() - exact).abs() <= 2e-3 * exact + 1e-4,
                        "({i}, {j}, {k}): |{got}| vs exact {exact}"
                    );
                    // In the sheet's own frame.
                    let q = turn.inverse().as_dquat() * p;
                    let (x, z) = (q.x as f32, q.z as f32);
                    let edge = 1.0 - x.abs().max(z.abs());
                    if exact < 0.5 * h || f64::from(edge).abs() < 0.5 * h {
                        continue;
                    }
                    let below = edge > 0.0 && q.y < f64::from(height(x, z));
                    assert_eq!(got < 0.0, below, "({i}, {j}, {k}) at {q}: {got}");
                    checked += 1;
                    inside += usize::from(below);
                }
            }
        }
        // The box reaches at least 3 voxels below the lowest point of the sheet.
        let lowest = (0..8)
            .map(|c| {
                let corner = UVec3::new(c & 1, (c >> 1) & 1, c >> 2) * (v.dims - 1);
                let p = v.origin + h * corner.as_dvec3();
                (turn.inverse().as_dquat() * p).y
            })
            .fold(f64::INFINITY, f64::min);
        assert!(lowest <= -0.15 - 3.0 * h, "box bottom {lowest}");
        assert!(inside > checked / 10, "{inside} of {checked} inside");
    }
}

/// A flat floor (one quad) baked as ground has samples inside below it: a ray from
/// above stops on it. Bad ups are refused.
#[test]
fn a_flat_ground_quad_has_an_inside() {
    let (positions, indices) = crate::ground::tests::sheet(1, |_, _| 0.0);
    let mesh = TriMesh {
        positions,
        triangles: indices.chunks(3).map(|t| [t[0], t[1], t[2]]).collect(),
        ..Default::default()
    };
    let settings = BakeSettings {
        sign: SignMethod::SolidBelow { up: Vec3::Y },
        ..BakeSettings::longest_axis(32)
    };
    let v = bake(&mesh, &settings, None).unwrap().volume;
    let h = f64::from(v.voxel_size);
    for x in [-0.8, -0.3, 0.0, 0.45, 0.9] {
        let below = v.sample(glam::DVec3::new(x, -1.5 * h, 0.2));
        let above = v.sample(glam::DVec3::new(x, 1.5 * h, 0.2));
        assert!(
            below < 0.0 && above > 0.0,
            "x {x}: below {below}, above {above}"
        );
    }
    for up in [Vec3::ZERO, Vec3::NAN, Vec3::new(f32::INFINITY, 0.0, 0.0)] {
        let settings = BakeSettings {
            sign: SignMethod::SolidBelow { up },
            ..BakeSettings::longest_axis(32)
        };
        assert!(
            matches!(bake(&mesh, &settings, None), Err(BakeError::Settings(_))),
            "{up}"
        );
    }
}
