use super::*;

/// A cube's faces are its normals (also against the winding); smoothed corners, a
/// normal 10° off on every corner, are apart; degenerate triangles, missing normals
/// and out-of-range indices are skipped; no triangle at all is not apart.
#[test]
fn shading_apart_from_faces_tells_smooth_from_flat() {
    let p = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0)];
    let tris = [[0, 1, 2], [1, 3, 2]];
    assert!(!shading_apart_from_faces(&p, &[Vec3::Z; 4], tris));
    assert!(!shading_apart_from_faces(&p, &[-Vec3::Z; 4], tris));
    let off = Vec3::new(0.0, 10f32.to_radians().sin(), 10f32.to_radians().cos());
    assert!(shading_apart_from_faces(&p, &[off; 4], tris));
    // One corner in twelve (8 %) apart: below the share.
    let mut some = [Vec3::Z; 4];
    some[0] = off;
    let six = [[0, 1, 2], [1, 3, 2], [1, 3, 2], [1, 3, 2]];
    assert!(!shading_apart_from_faces(&p, &some, six));
    assert!(!shading_apart_from_faces(
        &p,
        &[off; 4],
        [[0, 0, 1], [0, 1, 9]]
    ));
    assert!(!shading_apart_from_faces(&p, &[Vec3::ZERO; 4], tris));
    assert!(!shading_apart_from_faces(&p, &[off; 4], []));
    assert!(!shading_apart_from_faces(&[Vec3::NAN; 4], &[off; 4], tris));
}

/// A ground (solid below y = 0) seen from above is not seen from inside, its
/// underside is, at any tilt of the normal within 60° of straight down; a floor
/// receiver beside a unit box standing on it (the box's field falls upward there) is
/// not, nor one under an overhang half a voxel above it, nor a receiver inside a field
/// that deepens away from the eye, nor NaN.
#[test]
fn a_solid_seen_from_its_inside() {
    let h = 0.1;
    let probe = FROM_INSIDE_PROBE_VOXELS * h;
    let ground = |q: Vec3| q.y;
    let seen = |d: &dyn Fn(Vec3) -> f32, p: Vec3, n: Vec3| {
        seen_from_inside(d(p), d(p + n * probe), d(p - n * probe), h)
    };
    assert!(!seen(&ground, Vec3::ZERO, Vec3::Y));
    for deg in [0.0f32, 30.0, 59.0] {
        let (s, c) = deg.to_radians().sin_cos();
        assert!(seen(&ground, Vec3::ZERO, Vec3::new(s, -c, 0.0)), "{deg}");
    }
    assert!(!seen(
        &ground,
        Vec3::ZERO,
        Vec3::new(0.9, -0.1, 0.0).normalize()
    ));
    let boxed = |q: Vec3| {
        let c = q - Vec3::new(0.0, 0.5, 0.0);
        let e = c.abs() - Vec3::splat(0.5);
        e.max(Vec3::ZERO).length() + e.max_element().min(0.0)
    };
    for x in [0.5, 0.51, 0.55, 0.6] {
        assert!(!seen(&boxed, Vec3::new(x, 0.0, 0.0), Vec3::Y), "{x}");
    }
    // Deep inside, but the field deepens away from the eye.
    assert!(!seen(&ground, Vec3::new(0.0, -1.0, 0.0), Vec3::Y));
    assert!(!seen_from_inside(0.0, f32::NAN, 1.0, h));
    assert!(!seen_from_inside(f32::NAN, -1.0, 1.0, h));
    assert!(!seen_from_inside(0.0, -1.0, 1.0, 0.0));
    // A floor under an overhang half a voxel above: off the caster's surface.
    let gap = 0.5 * h;
    let overhang = |q: Vec3| gap - q.y;
    assert!(!seen(&overhang, Vec3::ZERO, Vec3::Y));
}

/// `shadow.wgsl` uses these constants, and the shell is the baker's; solid fields,
/// unknown normals and analytic shapes (voxel 0) get no offset; a grazing ray's start
/// is capped.
#[test]
fn the_self_shadow_start_and_its_shader_twin() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shaders/df/shadow.wgsl");
    let source = std::fs::read_to_string(path).expect("shadow.wgsl");
    for (name, value) in [
        ("SELF_SHADOW_VOXELS", SELF_SHADOW_VOXELS),
        ("SHELL_VOXELS", SHELL_VOXELS),
        ("SELF_SHADOW_MAX_START_VOXELS", SELF_SHADOW_MAX_START_VOXELS),
        ("FINE_FIELD_BIAS_VOXELS", FINE_FIELD_BIAS_VOXELS),
        ("FIELD_NORMAL_REACH_VOXELS", FIELD_NORMAL_REACH_VOXELS),
        ("FIELD_NORMAL_STEP_VOXELS", FIELD_NORMAL_STEP_VOXELS),
        ("FIELD_NORMAL_MIN_GRADIENT", FIELD_NORMAL_MIN_GRADIENT),
        ("FIELD_NORMAL_MAX_GRADIENT", FIELD_NORMAL_MAX_GRADIENT),
        ("FIELD_NORMAL_MIN_AGREEMENT", FIELD_NORMAL_MIN_AGREEMENT),
        ("FIELD_NORMAL_MIN_FACING", FIELD_NORMAL_MIN_FACING),
        (
            "FIELD_NORMAL_MIN_FACING_SHADED",
            FIELD_NORMAL_MIN_FACING_SHADED,
        ),
        ("FLAT_SHADED_SIN", FLAT_SHADED_SIN),
        ("FACE_NORMAL_PLANE_SIN", FACE_NORMAL_PLANE_SIN),
        ("FACE_NORMAL_MIN_AGREEMENT", FACE_NORMAL_MIN_AGREEMENT),
        ("FACE_DEPTH_TOLERANCE", FACE_DEPTH_TOLERANCE),
        ("FROM_INSIDE_MIN_DEPTH_VOXELS", FROM_INSIDE_MIN_DEPTH_VOXELS),
        ("FROM_INSIDE_PROBE_VOXELS", FROM_INSIDE_PROBE_VOXELS),
        ("FROM_INSIDE_MIN_DROP_VOXELS", FROM_INSIDE_MIN_DROP_VOXELS),
        (
            "FROM_INSIDE_ON_SURFACE_VOXELS",
            FROM_INSIDE_ON_SURFACE_VOXELS,
        ),
        ("PENUMBRA_MIN_STEP", PENUMBRA_MIN_STEP),
        ("SURFACE_STEP_VOXELS", SURFACE_STEP_VOXELS),
        ("THIN_CROSSING_COSINE", THIN_CROSSING_COSINE),
    ] {
        let line = source
            .lines()
            .find(|l| l.starts_with(&format!("const {name}: f32 = ")))
            .unwrap_or_else(|| panic!("{name} in shadow.wgsl"));
        let wgsl: f32 = line
            .trim_start_matches(&format!("const {name}: f32 = "))
            .trim_end_matches(';')
            .parse()
            .expect("a float");
        assert_eq!(wgsl, value, "{name}");
    }
    // The shell is the one the plugin's two-sided bakes put about the surface.
    let penumbra_sdf::SignMethod::TwoSided { shell_voxels } = penumbra_sdf::SignMethod::TWO_SIDED
    else {
        unreachable!("TWO_SIDED is two-sided")
    };
    assert_eq!(SHELL_VOXELS, shell_voxels);
    let up = Vec3::Y;
    let h = 0.1;
    assert_eq!(self_shadow_start(h, false, up, up), 0.0);
    assert_eq!(self_shadow_start(h, true, Vec3::ZERO, up), 0.0);
    assert_eq!(self_shadow_start(0.0, true, up, up), 0.0);
    assert_eq!(self_shadow_start(f32::NAN, true, up, up), 0.0);
    let rise = (SHELL_VOXELS + SELF_SHADOW_VOXELS) * h;
    assert!((self_shadow_start(h, true, up, up) - rise).abs() < 1e-6);
    let grazing = Vec3::new(1.0, 0.01, 0.0).normalize();
    let most = rise + SELF_SHADOW_MAX_START_VOXELS * h;
    assert!((self_shadow_start(h, true, up, grazing) - most).abs() < 1e-6);
    // The march starts at the bias, or sooner in a finer field, never inside a shell.
    let bias = 0.04;
    assert_eq!(march_start(bias, 0.0, false, up, up), bias);
    assert_eq!(march_start(bias, f32::NAN, false, up, up), bias);
    assert_eq!(march_start(bias, 0.1, false, up, up), bias);
    let fine = 0.005;
    assert_eq!(
        march_start(bias, fine, false, up, up),
        FINE_FIELD_BIAS_VOXELS * fine
    );
    assert_eq!(
        march_start(bias, fine, true, up, grazing),
        self_shadow_start(fine, true, up, grazing)
    );
    assert_eq!(march_start(bias, h, true, up, up), bias.max(rise));
}

/// The two-sided penumbra: covered at −1 and below, half at a grazing silhouette,
/// open at 1 and above, monotonic between; NaN counts as covered.
#[test]
fn the_penumbra_is_half_open_at_a_silhouette() {
    assert_eq!(penumbra_visibility(-1.0), 0.0);
    assert_eq!(penumbra_visibility(-5.0), 0.0);
    assert_eq!(penumbra_visibility(0.0), 0.5);
    assert_eq!(penumbra_visibility(1.0), 1.0);
    assert_eq!(penumbra_visibility(3.0), 1.0);
    assert_eq!(penumbra_visibility(f32::NAN), 0.0);
    let mut last = 0.0;
    for i in -100..=100 {
        let v = penumbra_visibility(i as f32 / 100.0);
        assert!(v >= last, "{i}");
        last = v;
    }
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shaders/df/shadow.wgsl");
    let source = std::fs::read_to_string(path).expect("shadow.wgsl");
    assert!(
        source.contains("return 0.25 * (1.0 + x) * (1.0 + x) * (2.0 - x);"),
        "shadow.wgsl's penumbra_visibility is this one"
    );
}

/// The march's steps: a shell entered covers the cone; a solid is marched through,
/// at least a quarter radius a step, and covers it where the ray leaves by the
/// opposite face (a thin part), not where it leaves by a side (a corner, a
/// silhouette); outside, a step of at least a quarter voxel (a hundredth of a radius
/// for analytic shapes).
#[test]
fn the_penumbra_march_covers_the_cone_through_thin_parts_only() {
    let (cone, voxel) = (0.4, 0.1);
    let never = || -> Vec3 { panic!("no normal needed") };
    let no_rim = |_: Vec3| -> f32 { panic!("no rim needed") };
    let near =
        |(a, b): (f32, f32), (x, y): (f32, f32)| (a - x).abs() < 1e-6 && (b - y).abs() < 1e-6;
    let mut entered = None;
    assert_eq!(
        penumbra_step(-0.01, cone, voxel, true, &mut entered, never, never, no_rim),
        (-1.0, 0.0)
    );
    // Outside: the distance, at least a quarter voxel (or a quarter radius).
    assert_eq!(
        penumbra_step(0.3, cone, voxel, false, &mut entered, never, never, no_rim),
        (0.75, 0.3)
    );
    assert!(near(
        penumbra_step(
            0.001,
            cone,
            voxel,
            false,
            &mut entered,
            never,
            never,
            no_rim
        ),
        (0.0025, SURFACE_STEP_VOXELS * voxel)
    ));
    assert_eq!(
        penumbra_step(0.001, 0.2, 0.0, false, &mut entered, never, never, no_rim).1,
        0.002
    );
    // In: the entry normal is read once; steps of at least a quarter radius.
    let (ratio, step) = penumbra_step(
        -0.02,
        cone,
        voxel,
        false,
        &mut entered,
        || Vec3::Y,
        never,
        no_rim,
    );
    assert!(near((ratio, step), (-0.05, 0.1)) && entered == Some(Vec3::Y));
    let (_, step) = penumbra_step(-0.2, cone, voxel, false, &mut entered, never, never, no_rim);
    assert_eq!(step, 0.2);
    // Out by the opposite face: a thin part, as far as it covers the cone.
    let mut thin = entered;
    assert_eq!(
        penumbra_step(
            0.01,
            cone,
            voxel,
            false,
            &mut thin,
            never,
            || -Vec3::Y,
            |n| {
                assert_eq!(n, Vec3::Y);
                thin_crossing_ratio([0.0; 4], cone, 1.0)
            }
        )
        .0,
        -1.0
    );
    assert_eq!(thin, None);
    // ... and the march goes on where it does not cover it all.
    let mut edge = entered;
    let (ratio, step) = penumbra_step(
        0.01,
        cone,
        voxel,
        false,
        &mut edge,
        never,
        || -Vec3::Y,
        |_| -0.25,
    );
    assert!(ratio == -0.25 && step > 0.0, "{ratio} {step}");
    // Out by a side (a corner) or the same side (a silhouette's chord): the ratio.
    for out in [Vec3::X, Vec3::new(0.2, 0.98, 0.0)] {
        let mut side = entered;
        let (ratio, _) = penumbra_step(0.01, cone, voxel, false, &mut side, never, || out, no_rim);
        assert!((ratio - 0.025).abs() < 1e-6, "{out}: {ratio}");
    }
    // The normal of a plane's distance, and none where the gradient vanishes.
    let n = tetrahedral_normal(Vec3::ONE, 0.1, |q| q.dot(Vec3::new(0.0, 0.6, 0.8)));
    assert!(n.abs_diff_eq(Vec3::new(0.0, 0.6, 0.8), 1e-5), "{n}");
    assert_eq!(tetrahedral_normal(Vec3::ONE, 0.1, |_| 1.0), Vec3::ZERO);
    assert!((crossing_stencil(cone, voxel) - 0.05).abs() < 1e-7);
    assert!((crossing_stencil(cone, 0.0) - 0.02).abs() < 1e-7);
}
