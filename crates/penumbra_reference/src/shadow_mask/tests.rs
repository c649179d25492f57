use super::*;

/// Terrain shadows against rays: a sun 25° above the horizon and 3° across, across
/// the valley (`test_terrain`; half its receivers mostly shaded), the march's
/// visibility (`pixel_visibility_with_terrain`, nothing but the terrain, 64 steps)
/// against the fraction of 256 rays spread over the sun's disc that miss the
/// triangulated surface within the ray length: mean |Δ| 0.044 (bound 0.06), where
/// ignoring the terrain errs by 0.22. (Without the half-cell minimum step, rays
/// running along a slope use up their steps and leak: 0.139.)
#[test]
fn terrain_shadows_match_rays() {
    use crate::test_terrain::{receivers, triangles, valley};
    use penumbra_sdf::bvh::Bvh;
    let h = valley();
    let bvh = Bvh::build(&triangles(&h));
    let (terrain, _) = HeightfieldTexture::pack(&[&h], 4096);
    let (elevation, azimuth) = (25f32.to_radians(), 70f32.to_radians());
    let to_sun = Vec3::new(
        elevation.cos() * azimuth.cos(),
        elevation.sin(),
        elevation.cos() * azimuth.sin(),
    );
    let light = MaskLight {
        kind: MaskLightKind::Directional(to_sun),
        source: 1.5f32.to_radians().tan(),
        max_distance: 40.0,
        bias: 0.03,
        shaping: 1.0,
        range: 0.0,
        max_steps: 64,
        max_view_distance: f32::INFINITY,
        spot: None,
    };
    let camera = CameraOrigin::at(Vec3::ZERO).expect("finite");
    let (t1, t2) = {
        let a = to_sun.cross(Vec3::Y).normalize();
        (a, to_sun.cross(a))
    };
    let (mut error, mut blind, mut shaded, mut count) = (0.0f32, 0.0f32, 0, 0);
    for (p, n) in receivers(&h) {
        let (model, _) = pixel_visibility_with_terrain(
            &[],
            &Atlas::new(glam::UVec3::ONE),
            &camera,
            p,
            n,
            &light,
            &terrain,
        );
        let mut open = 0;
        for k in 0..256 {
            let r = light.source * ((k as f32 + 0.5) / 256.0).sqrt();
            let a = k as f32 * 2.399_963;
            let d = (to_sun + t1 * (r * a.cos()) + t2 * (r * a.sin())).normalize();
            let own = d.dot(n) > 0.0;
            let hit = bvh
                .ray_nearest(p, d, light.bias, light.max_distance)
                .is_some();
            open += usize::from(own && !hit);
        }
        let truth = open as f32 / 256.0;
        error += (model - truth).abs();
        blind += (horizon(n, to_sun, light.source) - truth).abs();
        shaded += usize::from(truth < 0.5);
        count += 1;
    }
    let (error, blind) = (error / count as f32, blind / count as f32);
    eprintln!(
        "terrain shadows: mean |Δ| {error:.4} vs rays; ignoring the terrain {blind:.4}; {shaded} of {count} receivers mostly shaded"
    );
    assert!(error <= 0.06 && blind > 0.2, "{error} {blind}");
}

/// Normals facing the eye are kept, inverted ones negated, silhouette ones reflected.
#[test]
fn normals_are_turned_to_face_the_eye() {
    let p = Vec3::new(0.0, 0.0, -5.0); // straight ahead: the eye is along +z
    let n = Vec3::new(0.6, 0.0, 0.8);
    assert_eq!(facing_the_eye(n, p), n);
    // Inverted: negated.
    assert!(facing_the_eye(-n, p).distance(n) < 1e-6);
    // A smooth normal a little past a silhouette: reflected, its x kept.
    let past = Vec3::new(0.99, 0.0, -0.141).normalize();
    let turned = facing_the_eye(past, p);
    assert!((turned.x - past.x).abs() < 1e-6 && (turned.z + past.z).abs() < 1e-6);
    // Zero stays zero (no normal: no own shadow).
    assert_eq!(facing_the_eye(Vec3::ZERO, p), Vec3::ZERO);
    // The shader's twin of the threshold.
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../penumbra_shaders/shaders/df/shadow.wgsl"
    );
    let source = std::fs::read_to_string(path).expect("shadow.wgsl");
    let want = format!("const INVERTED_NORMAL_COS: f32 = {INVERTED_NORMAL_COS};");
    assert!(source.lines().any(|l| l == want), "{want}");
}

/// The horizon term against counting: directions spread uniformly over the light's
/// cone (16k per case), the fraction above the tangent plane; from back faces to
/// fully lit, for a 3° sun and a 40° light.
#[test]
fn horizon_is_the_fraction_of_the_light_above_the_plane() {
    let n = Vec3::Y;
    let mut worst = 0.0f32;
    for half_degrees in [1.5f32, 20.0] {
        let half = half_degrees.to_radians();
        for k in -20..=20 {
            // Elevation of the light's centre, from −2θ to 2θ.
            let elevation = half * k as f32 / 10.0;
            let dir = Vec3::new(elevation.cos(), elevation.sin(), 0.0);
            let (u, v) = (dir.cross(Vec3::Z).normalize(), Vec3::Z);
            let (mut above, mut total) = (0u32, 0u32);
            for i in 0..128 {
                for j in 0..128 {
                    // Uniform on the cone's cap: cos uniform in [cos θ, 1].
                    let c = 1.0 - (1.0 - half.cos()) * (i as f32 + 0.5) / 128.0;
                    let sn = (1.0 - c * c).max(0.0).sqrt();
                    let phi = std::f32::consts::TAU * (j as f32 + 0.5) / 128.0;
                    let w = dir * c + (u * phi.cos() + v * phi.sin()) * sn;
                    above += u32::from(w.dot(n) > 0.0);
                    total += 1;
                }
            }
            let want = above as f32 / total as f32;
            let got = horizon(n, dir, half.tan());
            worst = worst.max((got - want).abs());
        }
    }
    // The disc-area formula is exact for small cones; a 40° cone's cap is curved.
    assert!(worst < 0.02, "worst {worst}");
    assert_eq!(horizon(Vec3::ZERO, Vec3::Y, 0.1), 1.0);
    assert_eq!(horizon(Vec3::Y, Vec3::NAN, 0.1), 1.0);
    assert_eq!(horizon(Vec3::Y, -Vec3::Y, 0.1), 0.0);
    assert_eq!(horizon(Vec3::Y, Vec3::Y, 0.0), 1.0);
}

/// The G-buffer normal round trip (Bevy's encoding) loses under 0.1°, in every
/// octant and on the axes.
#[test]
fn gbuffer_normals_round_trip() {
    let mut worst = 0.0f32;
    for i in 0..40 {
        for j in 0..80 {
            let (theta, phi) = (std::f32::consts::PI * i as f32 / 39.0, 0.0785 * j as f32);
            let n = Vec3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            );
            let back = unpack_gbuffer_normal(pack_gbuffer_normal(n));
            worst = worst.max(back.dot(n).clamp(-1.0, 1.0).acos().to_degrees());
        }
    }
    assert!(worst < 0.1, "worst {worst}°");
    for axis in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z] {
        let back = unpack_gbuffer_normal(pack_gbuffer_normal(axis));
        assert!(back.dot(axis) > 0.99999, "{axis} -> {back}");
    }
}

/// Brute force: the distance from `p` to the hull of two balls is the minimum over
/// the interpolated balls (the hull is their union).
fn brute_round_cone(p: Vec3, a: Vec3, b: Vec3, ra: f32, rb: f32) -> f32 {
    (0..=20_000)
        .map(|i| {
            let s = i as f32 / 20_000.0;
            (p - a.lerp(b, s)).length() - (ra + (rb - ra) * s)
        })
        .fold(f32::INFINITY, f32::min)
}

#[test]
fn round_cone_distance_matches_brute_force_outside() {
    let mut state = 12345u32;
    let mut rnd = || {
        state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (state >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0
    };
    let mut worst = 0.0f32;
    for _ in 0..400 {
        let a = Vec3::new(rnd(), rnd(), rnd()) * 3.0;
        let b = Vec3::new(rnd(), rnd(), rnd()) * 3.0;
        let (ra, rb) = (rnd().abs() * 0.5, rnd().abs() * 1.5);
        let p = Vec3::new(rnd(), rnd(), rnd()) * 6.0;
        let want = brute_round_cone(p, a, b, ra, rb);
        if want > 0.0 {
            // Outside the hull the formula is exact (the brute force samples the
            // balls finely; its own error is below 1e-3 here).
            let got = round_cone_distance(p, a, b, ra, rb);
            worst = worst.max((got - want).abs());
        } else {
            assert!(round_cone_distance(p, a, b, ra, rb) <= 1e-3);
        }
    }
    assert!(worst < 2e-3, "worst {worst}");
}

#[test]
fn bounding_sphere_contains_the_shape_under_rotation_and_scale() {
    use penumbra_df_core::object::{CasterShape, ObjectDesc, encode};
    let desc = ObjectDesc {
        shape: CasterShape::Cuboid {
            half_extents: Vec3::new(0.5, 0.2, 1.0),
        },
        world_from_local: glam::Affine3A::from_scale_rotation_translation(
            Vec3::new(2.0, 1.0, 0.5),
            glam::Quat::from_rotation_y(0.7) * glam::Quat::from_rotation_x(0.4),
            Vec3::new(3.0, 1.0, -2.0),
        ),
        flags: flags::LIVE,
    };
    let r = encode(&desc).expect("encodes");
    let camera = CameraOrigin::at(Vec3::new(1.0, 2.0, 3.0)).expect("finite");
    let (c, radius) = bounding_sphere(&r, &camera).expect("bounded");
    let mut far = 0.0f32;
    for i in 0..8 {
        let s = Vec3::new(
            if i & 1 == 0 { -1.0 } else { 1.0 },
            if i & 2 == 0 { -1.0 } else { 1.0 },
            if i & 4 == 0 { -1.0 } else { 1.0 },
        );
        let corner = desc
            .world_from_local
            .transform_point3(s * Vec3::new(0.5, 0.2, 1.0));
        far = far.max((corner - Vec3::new(1.0, 2.0, 3.0) - c).length());
    }
    assert!(
        (far - radius).abs() < 1e-4,
        "farthest corner {far}, radius {radius}"
    );
}

/// On analytic spheres the pass model equals `df_shadow`'s march (whose error
/// against Monte Carlo ground truth is tested there): the record encoding, the cone
/// culling and the clamps change nothing.
#[test]
fn pass_model_equals_the_march_on_spheres() {
    use crate::df_shadow::{AreaLight, Occluder, ShadowSettings, SphereOccluder, df_visibility};
    use penumbra_df_core::object::{CasterShape, ObjectDesc, encode};
    let balls = [
        SphereOccluder {
            center: Vec3::new(0.0, 1.0, 0.0),
            radius: 0.5,
        },
        SphereOccluder {
            center: Vec3::new(1.2, 0.4, -0.3),
            radius: 0.2,
        },
        // Small and high: its cone section is wide, the tiny-object clamp acts.
        SphereOccluder {
            center: Vec3::new(-1.2, 3.0, -1.2),
            radius: 0.05,
        },
        // Far off the rays: culled by the cone test, must not matter.
        SphereOccluder {
            center: Vec3::new(-30.0, 5.0, 20.0),
            radius: 0.3,
        },
    ];
    let eye = Vec3::new(0.3, 2.0, 5.0);
    let camera = CameraOrigin::at(eye).expect("finite");
    let records: Vec<ObjectRecord> = balls
        .iter()
        .map(|b| {
            encode(&ObjectDesc {
                world_from_local: glam::Affine3A::from_translation(b.center),
                shape: CasterShape::Sphere { radius: b.radius },
                flags: flags::LIVE | flags::CASTS_SHADOWS | flags::VISIBLE,
            })
            .expect("encodes")
        })
        .collect();
    let atlas = Atlas::new(glam::UVec3::ONE);
    let occluders: Vec<&dyn Occluder> = balls.iter().map(|b| b as &dyn Occluder).collect();
    let settings = ShadowSettings {
        max_distance: 40.0,
        max_steps: 64,
        bias: 0.01,
    };
    let sun = Vec3::new(0.3, 1.0, 0.2).normalize();
    let lamp = Vec3::new(0.5, 4.0, 0.5);
    let cases = [
        (
            AreaLight::Directional {
                to_light: sun,
                angular_diameter: 0.2,
            },
            MaskLightKind::Directional(sun),
            (0.1f32).tan(),
        ),
        (
            AreaLight::Sphere {
                center: lamp,
                radius: 0.4,
            },
            MaskLightKind::Positional(lamp - eye),
            0.4,
        ),
    ];
    for (area, kind, source) in cases {
        let light = MaskLight {
            kind,
            source,
            max_distance: settings.max_distance,
            bias: settings.bias,
            shaping: 1.0,
            range: 100.0,
            max_steps: settings.max_steps,
            max_view_distance: f32::INFINITY,
            spot: None,
        };
        let mut worst = 0.0f32;
        let mut shadowed = 0;
        for i in 0..40 {
            for j in 0..40 {
                let p = Vec3::new(-2.0 + 0.1 * i as f32, 0.0, -2.0 + 0.1 * j as f32);
                let want = df_visibility(&occluders, p, &area, &settings);
                let got = pixel_visibility(&records, &atlas, &camera, p - eye, Vec3::ZERO, &light);
                worst = worst.max((got - want).abs());
                shadowed += usize::from(want < 0.99);
            }
        }
        assert!(shadowed > 100, "{area:?}: only {shadowed} shadowed points");
        assert!(worst < 2e-4, "{area:?}: worst {worst}");
    }
}

/// The depth-buffer test of a G-buffer normal: a plane's own normal is flat-shaded (also
/// seen turned from the eye, and on a face two pixels tall whose other neighbours lie on
/// other faces); a normal 10° off the plane (a normal map, smooth shading) is not; a
/// pixel with no neighbour along an axis cannot tell (not flat); a NaN point is not.
#[test]
fn the_depth_buffer_tells_a_faces_own_normal() {
    let n = Vec3::new(0.0, 1.0, 0.2).normalize();
    let (u, v) = (n.any_orthonormal_pair().0, n.any_orthonormal_pair().1);
    let p = Vec3::new(0.0, -1.0, -5.0);
    let on = |a: f32, b: f32| Some(p + u * a + v * b);
    let plane = [
        [on(-0.01, 0.0), on(0.01, 0.0)],
        [on(0.0, -0.01), on(0.0, 0.01)],
    ];
    assert!(flat_shaded(p, n, plane));
    assert!(flat_shaded(p, -n, plane));
    let tilted = glam::Quat::from_axis_angle(u, 10f32.to_radians()) * n;
    assert!(!flat_shaded(p, tilted, plane));
    // A face two pixels tall: one neighbour of each axis on another face.
    let other = Some(p + n * 0.01);
    assert!(flat_shaded(
        p,
        n,
        [[on(-0.01, 0.0), other], [other, on(0.0, 0.01)]]
    ));
    assert!(!flat_shaded(p, n, [[other, other], [on(0.0, -0.01), None]]));
    assert!(!flat_shaded(p, n, [[None, None], [on(0.0, -0.01), None]]));
    assert!(!flat_shaded(
        p,
        n,
        [[Some(Vec3::NAN), None], [on(0.0, -0.01), None]]
    ));
}

/// A receiver inside an analytic shape (a character's capsule standing in for its mesh)
/// is not shadowed by it, but still by the others: under a sun straight above, points
/// inside a leg's capsule are lit unless the body's capsule is above them; the ground
/// under the body is dark. (Before the rule, every point inside a capsule read 0.)
#[test]
fn a_receiver_inside_an_analytic_shape_is_not_shadowed_by_it() {
    use penumbra_df_core::object::{CasterShape, ObjectDesc, encode};
    let capsule = |center: Vec3, rotation: glam::Quat, radius: f32, half_length: f32| {
        encode(&ObjectDesc {
            world_from_local: glam::Affine3A::from_rotation_translation(rotation, center),
            shape: CasterShape::Capsule {
                radius,
                half_length,
            },
            flags: flags::LIVE | flags::CASTS_SHADOWS | flags::VISIBLE,
        })
        .expect("encodes")
    };
    // A leg (vertical) at x = 0.5 and a body (lying along x) above x ∈ [−1, 0].
    let leg = capsule(Vec3::new(0.5, 0.6, 0.0), glam::Quat::IDENTITY, 0.15, 0.4);
    let body = capsule(
        Vec3::new(-0.5, 1.4, 0.0),
        glam::Quat::from_rotation_z(std::f32::consts::FRAC_PI_2),
        0.3,
        0.5,
    );
    let records = [leg, body];
    let eye = Vec3::new(0.0, 1.0, 5.0);
    let camera = CameraOrigin::at(eye).expect("finite");
    let atlas = Atlas::new(glam::UVec3::ONE);
    let light = sun(Vec3::Y, 0.02f32.tan());
    let at = |p: Vec3| pixel_visibility(&records, &atlas, &camera, p - eye, Vec3::ZERO, &light);
    // Inside the leg, on its "skin" 2 cm in from the capsule's surface: lit.
    for y in [0.3, 0.6, 0.9] {
        for a in [0.0f32, 1.5, 3.0, 4.5] {
            let p = Vec3::new(0.5 + 0.13 * a.cos(), y, 0.13 * a.sin());
            assert!(inside_analytic(&leg, p - eye, &camera, &atlas));
            assert!(at(p) > 0.99, "{p}: {}", at(p));
        }
    }
    // Inside the body: lit from above; the ground under it: shadowed by it.
    assert!(at(Vec3::new(-0.5, 1.6, 0.0)) > 0.99);
    for x in [-0.9, -0.5, -0.1] {
        assert!(at(Vec3::new(x, 0.0, 0.0)) < 0.05, "ground at {x}");
    }
    // A point inside the body's capsule, under a third capsule above it: shadowed.
    let hat = capsule(Vec3::new(-0.5, 2.5, 0.0), glam::Quat::IDENTITY, 0.3, 0.1);
    let records = [leg, body, hat];
    let v = pixel_visibility(
        &records,
        &atlas,
        &camera,
        Vec3::new(-0.5, 1.6, 0.0) - eye,
        Vec3::ZERO,
        &light,
    );
    assert!(v < 0.05, "{v}");
}

/// The depth buffer's face normal against analytic surfaces: on a plane it is the
/// plane's normal on the G-buffer normal's side; on a sphere of radius 1 sampled 0.02
/// apart it is the sphere's normal within 0.1° (the central difference; one-sided
/// differences err by ~0.6°); across a crease or with an axis missing, none. Under a sun
/// 3° across, a smooth normal tilted 8° past the terminator of a face that faces the sun
/// by 0.1 is lit by the face (ray tracing lights it: nothing else is there), and stays
/// dark where the pass takes the normal for a flat-shaded face's or has no face normal.
#[test]
fn the_depth_buffer_gives_the_face_a_smooth_normal_hides() {
    let p = Vec3::new(0.3, -1.0, -5.0);
    let n = Vec3::new(0.1, 1.0, 0.3).normalize();
    let (u, v) = n.any_orthonormal_pair();
    let plane = |q: Vec3, a: f32, b: f32| Some(q + u * a + v * b);
    let on_plane = [
        [plane(p, -0.01, 0.0), plane(p, 0.01, 0.0)],
        [plane(p, 0.0, -0.01), plane(p, 0.0, 0.01)],
    ];
    let tilted = glam::Quat::from_axis_angle(u, 20f32.to_radians()) * n;
    assert!((face_normal(p, tilted, on_plane) - n).length() < 1e-4);
    // One neighbour per axis: the plane still.
    let one_sided = [[None, on_plane[0][1]], [on_plane[1][0], None]];
    assert!((face_normal(p, tilted, one_sided) - n).length() < 1e-4);
    // A crease 30° up on one side: no face.
    let up = glam::Quat::from_axis_angle(v, 30f32.to_radians());
    let creased = [[on_plane[0][0], Some(p + up * (u * 0.01))], on_plane[1]];
    assert_eq!(face_normal(p, n, creased), Vec3::ZERO);
    assert_eq!(face_normal(p, n, [[None, None], on_plane[1]]), Vec3::ZERO);
    // A sphere of radius 1 about `c`, sampled along two tangent directions.
    let c = Vec3::new(0.0, -2.0, -6.0);
    for dir in [Vec3::Y, Vec3::new(1.0, 1.0, 1.0).normalize(), Vec3::Z] {
        let q = c + dir;
        let (a, b) = dir.any_orthonormal_pair();
        let on = |s: f32, t: f32| Some(c + (dir + a * s + b * t).normalize());
        let sphere = [
            [on(-0.02, 0.0), on(0.02, 0.0)],
            [on(0.0, -0.02), on(0.0, 0.02)],
        ];
        let got = face_normal(q, dir, sphere);
        assert!(got.angle_between(dir).to_degrees() < 0.1, "{dir}: {got}");
    }
    // Past the terminator: the face faces the sun by 0.1, the smooth normal hides it.
    let to_sun = (n * 0.1 + u * (1.0f32 - 0.01).sqrt()).normalize();
    let light = sun(to_sun, 1.5f32.to_radians().tan());
    let smooth = glam::Quat::from_axis_angle(v, -(8f32.to_radians())) * n;
    assert!(
        smooth.dot(to_sun) < -0.02,
        "the smooth normal hides the sun"
    );
    let camera = CameraOrigin::at(Vec3::ZERO).expect("finite");
    let atlas = Atlas::new(glam::UVec3::ONE);
    let at = |r: ReceiverNormal| pixel_visibility(&[], &atlas, &camera, p, r, &light);
    let receiver = receiver_normal(p, smooth, on_plane);
    assert!(!receiver.flat && receiver.face != Vec3::ZERO);
    assert!(at(receiver) > 0.99, "{}", at(receiver));
    assert_eq!(at(ReceiverNormal::from(smooth)), 0.0);
    assert_eq!(
        at(ReceiverNormal {
            flat: true,
            ..receiver
        }),
        0.0
    );
}

/// A sun toward `to_light` whose disc's half angle has tangent `tan_half`: a 20 m march
/// of 64 steps from a 1 cm bias.
fn sun(to_light: Vec3, tan_half: f32) -> MaskLight {
    MaskLight {
        kind: MaskLightKind::Directional(to_light),
        source: tan_half,
        max_distance: 20.0,
        bias: 0.01,
        shaping: 1.0,
        range: 100.0,
        max_steps: 64,
        max_view_distance: f32::INFINITY,
        spot: None,
    }
}
