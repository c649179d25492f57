use super::*;
use glam::{DVec3, Quat};
use penumbra_sdf::{BakeSettings, SdfVolume, bake, exact, shapes};

/// The baker's volume as the queries read it.
struct Baked(SdfVolume);

impl LocalDistance for Baked {
    fn local_distance(&self, q: Vec3) -> f32 {
        self.0.sample(q.as_dvec3())
    }
    fn local_bounds(&self) -> (Vec3, Vec3) {
        let (lo, hi) = self.0.bounds();
        (lo.as_vec3(), hi.as_vec3())
    }
}

fn analytic() -> [(QueryShape<'static>, Affine3A); 4] {
    let rigid = |angle: f32, t: Vec3| {
        Affine3A::from_rotation_translation(
            Quat::from_euler(glam::EulerRot::XYZ, angle, 0.7 * angle, 0.2),
            t,
        )
    };
    [
        (
            QueryShape::Sphere { radius: 0.8 },
            rigid(0.3, Vec3::new(2.0, 1.0, 0.0)),
        ),
        (
            QueryShape::Cuboid {
                half_extents: Vec3::new(0.5, 1.0, 0.25),
            },
            rigid(1.1, Vec3::new(-2.0, 1.2, 0.5)),
        ),
        (
            QueryShape::Capsule {
                radius: 0.3,
                half_length: 0.9,
            },
            rigid(-0.6, Vec3::new(0.0, 1.5, -2.0)),
        ),
        (QueryShape::Plane, Affine3A::IDENTITY),
    ]
}

/// The exact distance of one analytic shape, in its own frame (rigid: no scale).
fn exact_local(shape: &QueryShape, q: Vec3) -> f32 {
    shape.distance(q)
}

/// A torus mesh and its bake (48 samples along its longest axis).
fn torus() -> (penumbra_sdf::TriMesh, Baked) {
    let mesh = shapes::torus(0.5, 0.18, 48, 24);
    let volume = bake(&mesh, &BakeSettings::longest_axis(48), None)
        .expect("bakes")
        .volume;
    (mesh, Baked(volume))
}

struct Rng(penumbra_testkit::XorShift);

impl Rng {
    fn vec(&mut self, a: f32) -> Vec3 {
        let mut c = || self.0.range(-a, a);
        Vec3::new(c(), c(), c())
    }
}

/// Rigidly placed analytic shapes: the query is the exact distance (the smallest over
/// the shapes, each computed in its frame), whatever the bounds skip.
#[test]
fn rigid_analytic_shapes_give_the_exact_distance() {
    let objects = analytic();
    let scene = QueryScene::new(
        objects
            .iter()
            .map(|&(shape, world_from_local)| QueryObject {
                shape,
                world_from_local,
            }),
    );
    assert_eq!((scene.len(), scene.skipped()), (4, 0));
    let mut rng = Rng(penumbra_testkit::XorShift(7));
    for _ in 0..5000 {
        let p = rng.vec(4.0) + Vec3::Y * 2.0;
        let want = objects
            .iter()
            .map(|(s, m)| exact_local(s, m.inverse().transform_point3(p)))
            .fold(f32::INFINITY, f32::min);
        let got = scene.distance(p);
        assert!((got - want).abs() < 1e-4, "{p}: {got} want {want}");
    }
}

/// A baked torus, rotated, scaled 1.5× and moved, against the exact distance to its
/// triangles (f64 brute force): within a tenth of a voxel near the surface and never
/// above the truth by more (trilinear interpolation of a curved surface's distances is
/// not quite a lower bound); a non-uniformly scaled box stays below the exact distance
/// to its triangles and above it times the scale's ratio.
#[test]
fn volumes_and_scaled_shapes_stay_below_the_exact_distance() {
    let (mesh, baked) = torus();
    let volume = &baked.0;
    let torus = Affine3A::from_scale_rotation_translation(
        Vec3::splat(1.5),
        Quat::from_rotation_x(0.8),
        Vec3::new(0.3, 1.0, -0.2),
    );
    let scaled = Affine3A::from_scale_rotation_translation(
        Vec3::new(2.0, 0.5, 1.0),
        Quat::from_rotation_y(0.4),
        Vec3::new(3.0, 0.5, 1.0),
    );
    let torus_scene = QueryScene::new([QueryObject {
        shape: QueryShape::Volume(&baked),
        world_from_local: torus,
    }]);
    let box_scene = QueryScene::new([QueryObject {
        shape: QueryShape::Cuboid {
            half_extents: Vec3::splat(0.5),
        },
        world_from_local: scaled,
    }]);
    let (tris, _) = mesh.validate().expect("valid");
    let world_tris: Vec<[DVec3; 3]> = tris
        .iter()
        .map(|t| t.map(|v| torus.transform_point3(v).as_dvec3()))
        .collect();
    let (box_tris, _) = shapes::cuboid(Vec3::splat(0.5)).validate().expect("valid");
    let box_world: Vec<[DVec3; 3]> = box_tris
        .iter()
        .map(|t| t.map(|v| scaled.transform_point3(v).as_dvec3()))
        .collect();
    let voxel_world = volume.voxel_size * 1.5;
    let mut rng = Rng(penumbra_testkit::XorShift(11));
    let (mut near, mut worst) = (0, 0.0f32);
    for _ in 0..1500 {
        let p = Vec3::new(0.3, 1.0, -0.2) + rng.vec(1.6);
        let truth = exact::distance(p.as_dvec3(), &world_tris) as f32;
        let got = torus_scene.distance(p).abs();
        assert!(got <= truth + 0.1 * voxel_world, "{p}: {got} exact {truth}");
        if truth < 2.0 * voxel_world {
            near += 1;
            worst = worst.max((got - truth).abs() / voxel_world);
        }
        let q = Vec3::new(3.0, 0.5, 1.0) + rng.vec(2.0);
        let box_truth = exact::distance(q.as_dvec3(), &box_world) as f32;
        let inside = box_scene.distance(q) < 0.0;
        if !inside {
            let d = box_scene.distance(q);
            assert!(
                d <= box_truth + 1e-4 && d >= box_truth * 0.25 - 1e-4,
                "{q}: {d} exact {box_truth}"
            );
        }
    }
    assert!(
        near > 50 && worst < 0.1,
        "{near} near-surface points, worst {worst} voxels"
    );
}

/// Sphere casts against brute force (sphere tracing with the exact f64 distance to
/// every triangle, which cannot overshoot): the same rays hit and miss; a hit is never
/// 1 cm past the true first contact (passing through the torus's tube would be 36 cm)
/// and stops where the exact distance is the radius within a tenth of a voxel (the
/// volume's error) — or up to two voxels more outside the volume's box, where its
/// distance is a looser lower bound (the bake's border is 2 voxels, the sphere's radius
/// 4: an early stop, never a pass); the normal at a ball is the ball's.
#[test]
fn sphere_casts_match_brute_force() {
    let (mesh, baked) = torus();
    let volume = &baked.0;
    let (lo, hi) = volume.bounds();
    let torus =
        Affine3A::from_rotation_translation(Quat::from_rotation_x(1.2), Vec3::new(0.0, 1.0, 0.0));
    let ball = Affine3A::from_translation(Vec3::new(2.0, 1.0, 0.0));
    let scene = QueryScene::new([
        QueryObject {
            shape: QueryShape::Volume(&baked),
            world_from_local: torus,
        },
        QueryObject {
            shape: QueryShape::Sphere { radius: 0.4 },
            world_from_local: ball,
        },
    ]);
    let (tris, _) = mesh.validate().expect("valid");
    let mut world: Vec<[DVec3; 3]> = tris
        .iter()
        .map(|t| t.map(|v| torus.transform_point3(v).as_dvec3()))
        .collect();
    let (ball_tris, _) = shapes::sphere(0.4, 96, 48).validate().expect("valid");
    world.extend(
        ball_tris
            .iter()
            .map(|t| t.map(|v| ball.transform_point3(v).as_dvec3())),
    );
    let radius = 0.1;
    let voxel = volume.voxel_size;
    let (mut worst, mut apart) = (0.0f32, 0.0f32);
    let mut rng = Rng(penumbra_testkit::XorShift(5));
    let (mut hits, mut misses) = (0, 0);
    for _ in 0..60 {
        let origin = Vec3::new(-3.0, 1.0, 0.0) + rng.vec(0.3);
        let target = Vec3::new(1.0, 1.0, 0.0) + rng.vec(1.2);
        let dir = (target - origin).normalize();
        let got = scene.sphere_cast(origin, dir, radius, 8.0, 1e-4);
        // Brute force: sphere tracing with the exact distance to every triangle.
        let mut want = None;
        let mut t = 0.0f64;
        for _ in 0..10_000 {
            let p = origin.as_dvec3() + dir.as_dvec3() * t;
            let d = exact::distance(p, &world) - f64::from(radius);
            if d <= 1e-6 {
                want = Some(t as f32);
                break;
            }
            t += d;
            if t > 8.0 {
                break;
            }
        }
        match (got, want) {
            (Some(h), Some(w)) => {
                hits += 1;
                // Not past the true first contact, and stopped touching a surface:
                // the exact distance there is the radius within the volume's error (a
                // grazing ray may stop early by that error over the grazing angle).
                let gap = exact::distance(h.center.as_dvec3(), &world) as f32 - radius;
                let local = torus.inverse().transform_point3(h.center);
                let in_box = local.cmpge(lo.as_vec3()).all() && local.cmple(hi.as_vec3()).all();
                let slack = if in_box { 0.1 } else { 2.0 };
                assert!(
                    h.distance <= w + 0.01 && gap > -0.1 * voxel && gap < slack * voxel,
                    "{origin} → {dir}: {} want {w}, gap {gap}",
                    h.distance
                );
                worst = worst.max(gap.abs() / voxel);
                apart = apart.max((h.distance - w).abs());
            }
            (None, None) => misses += 1,
            _ => panic!("{origin} → {dir}: {got:?} want {want:?}"),
        }
    }
    eprintln!(
        "sphere casts: {hits} hits, {misses} misses; surface gap at most {worst:.3} voxel, \
         distance apart at most {apart:.4} m"
    );
    assert!(hits > 20 && misses > 5, "{hits} hits, {misses} misses");
    let h = scene
        .sphere_cast(Vec3::new(2.0, 3.0, 0.0), -Vec3::Y, 0.1, 5.0, 1e-4)
        .expect("hits the ball");
    assert!(
        (h.distance - 1.5).abs() < 1e-3 && h.normal.angle_between(Vec3::Y) < 0.01,
        "{h:?}"
    );
}

/// Bad input: no panic, a clear answer.
#[test]
fn bad_input_is_answered_safely() {
    let empty = QueryScene::new([]);
    assert_eq!(empty.distance(Vec3::ZERO), f32::INFINITY);
    assert!(
        empty
            .sphere_cast(Vec3::ZERO, Vec3::X, 0.1, 10.0, 1e-3)
            .is_none()
    );
    let bad = QueryScene::new([
        QueryObject {
            shape: QueryShape::Sphere { radius: 1.0 },
            world_from_local: Affine3A::from_translation(Vec3::NAN),
        },
        QueryObject {
            shape: QueryShape::Sphere { radius: 1.0 },
            world_from_local: Affine3A::from_scale(Vec3::new(1.0, 0.0, 1.0)),
        },
        QueryObject {
            shape: QueryShape::Sphere { radius: 1.0 },
            world_from_local: Affine3A::IDENTITY,
        },
    ]);
    assert_eq!((bad.len(), bad.skipped()), (1, 2));
    assert!(bad.nearest(Vec3::NAN).is_none());
    assert!(
        bad.sphere_cast(Vec3::new(5.0, 0.0, 0.0), Vec3::ZERO, 0.1, 10.0, 1e-3)
            .is_none()
    );
    assert!(
        bad.sphere_cast(Vec3::NAN, Vec3::X, 0.1, 10.0, 1e-3)
            .is_none()
    );
    // Starting inside: a hit at once.
    let h = bad
        .sphere_cast(Vec3::ZERO, Vec3::X, 0.1, 10.0, 1e-3)
        .expect("inside");
    assert_eq!(h.distance, 0.0);
}
