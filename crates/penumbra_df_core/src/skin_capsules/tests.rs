use super::*;
use glam::{DVec3, Quat};

/// A tube of `radius` along x from 0 to `length` (rings of 24 vertices every 1 cm),
/// skinned to two joints: joint 0 at the origin, joint 1 (its child) at
/// `length / 2`; each vertex wholly to the nearer joint's side.
struct Arm {
    positions: Vec<Vec3>,
    joints: Vec<[u16; 4]>,
    weights: Vec<[f32; 4]>,
    inverse_bindposes: Vec<Mat4>,
    parents: Vec<Option<usize>>,
}

fn arm(radius: f32, length: f32) -> Arm {
    let mut positions = Vec::new();
    let rings = (length / 0.01).round() as usize;
    for i in 0..=rings {
        let x = length * i as f32 / rings as f32;
        for k in 0..24 {
            let a = std::f32::consts::TAU * k as f32 / 24.0;
            positions.push(Vec3::new(x, radius * a.cos(), radius * a.sin()));
        }
    }
    let half = length / 2.0;
    let joints = positions
        .iter()
        .map(|p| {
            if p.x < half {
                [0, 1, 0, 0]
            } else {
                [1, 0, 0, 0]
            }
        })
        .collect();
    let weights = positions.iter().map(|_| [1.0, 0.0, 0.0, 0.0]).collect();
    Arm {
        positions,
        joints,
        weights,
        inverse_bindposes: vec![
            Mat4::IDENTITY,
            Mat4::from_translation(Vec3::new(-half, 0.0, 0.0)),
        ],
        parents: vec![None, Some(0)],
    }
}

impl Arm {
    fn input(&self) -> SkinInput<'_> {
        SkinInput {
            positions: &self.positions,
            joints: &self.joints,
            weights: &self.weights,
            inverse_bindposes: &self.inverse_bindposes,
            parents: &self.parents,
            triangles: &[],
        }
    }
}

/// Distance from `p` to the capsule, in f64 from its two end points (not through
/// [`FittedCapsule::distance`]).
fn distance_f64(c: &FittedCapsule, p: DVec3) -> f64 {
    let a = (c.center - c.axis * c.half_length).as_dvec3();
    let b = (c.center + c.axis * c.half_length).as_dvec3();
    let ab = b - a;
    let t = if ab.length_squared() > 0.0 {
        ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + t * ab)).length() - f64::from(c.radius)
}

/// Nine tenths of the vertices, as `coverage: 0.9` asks.
fn nine_tenths() -> CapsuleFitSettings {
    CapsuleFitSettings {
        coverage: 0.9,
        ..CapsuleFitSettings::default()
    }
}

#[test]
fn a_tube_gets_one_capsule_per_joint_along_its_bone() {
    let arm = arm(0.1, 1.0);
    let capsules = fit_skin_capsules(&arm.input(), &nine_tenths());
    assert_eq!(capsules.len(), 2, "{capsules:?}");
    for c in &capsules {
        // Along x, as thick as the tube, its core as long as the joint's half of it
        // (minus what 0.9 coverage trims at its ends), in its joint's space: both
        // halves span x ∈ [0, 0.5) there. (The caps reach a radius further: the rims
        // of the tube's ends lie on them.)
        assert!(c.axis.x.abs() > 0.999, "{c:?}");
        assert!((c.radius - 0.1).abs() < 1e-4, "{c:?}");
        let (start, end) = (c.center.x - c.half_length, c.center.x + c.half_length);
        assert!((0.0..0.03).contains(&start), "{c:?}");
        assert!((0.47..0.5).contains(&end), "{c:?}");
        // Its vertices, in joint space, within it (brute force, f64).
        let to_joint = arm.inverse_bindposes[c.joint];
        let (mut n, mut inside) = (0, 0);
        for (p, j) in arm.positions.iter().zip(&arm.joints) {
            if usize::from(j[0]) == c.joint {
                n += 1;
                let q = to_joint.transform_point3(*p).as_dvec3();
                inside += usize::from(distance_f64(c, q) <= 1e-5);
            }
        }
        let fraction = inside as f32 / n as f32;
        assert!((0.85..=0.97).contains(&fraction), "{fraction} {c:?}");
        assert!((fraction - c.covered).abs() < 0.01, "{fraction} {c:?}");
    }
}

#[test]
fn the_capsules_follow_their_joints_as_the_skin_does() {
    // Blend the weights across the elbow (vertices within 5 cm of it weigh both
    // joints), bend the elbow 90°, skin the vertices on the CPU (linear blend skinning)
    // and place each capsule in world space by its joint's posed transform: most of each
    // joint's vertices lie within 2 cm of its capsule, measured in world space.
    let mut arm = arm(0.1, 1.0);
    for (i, p) in arm.positions.iter().enumerate() {
        let w1 = ((p.x - 0.45) / 0.1).clamp(0.0, 1.0);
        arm.joints[i] = [0, 1, 0, 0];
        arm.weights[i] = [1.0 - w1, w1, 0.0, 0.0];
    }
    let capsules = fit_skin_capsules(&arm.input(), &nine_tenths());
    assert_eq!(capsules.len(), 2);
    let shoulder =
        Mat4::from_rotation_translation(Quat::from_rotation_y(0.4), Vec3::new(2.0, 1.0, -3.0));
    let elbow = shoulder
        * Mat4::from_rotation_translation(
            Quat::from_rotation_z(std::f32::consts::FRAC_PI_2),
            Vec3::new(0.5, 0.0, 0.0),
        );
    let joints_world = [shoulder, elbow];
    let posed: Vec<Vec3> = arm
        .positions
        .iter()
        .zip(&arm.weights)
        .map(|(p, w)| {
            (0..2)
                .map(|j| w[j] * (joints_world[j] * arm.inverse_bindposes[j]).transform_point3(*p))
                .sum()
        })
        .collect();
    let owners = dominant_vertices(&arm.input());
    for c in &capsules {
        // The capsule's ends in world space.
        let m = joints_world[c.joint];
        let (a, b) = (
            m.transform_point3(c.center - c.axis * c.half_length),
            m.transform_point3(c.center + c.axis * c.half_length),
        );
        let world = FittedCapsule {
            center: (a + b) * 0.5,
            axis: (b - a).normalize_or(Vec3::X),
            half_length: (b - a).length() * 0.5,
            ..*c
        };
        let near = owners[c.joint]
            .iter()
            .filter(|&&v| distance_f64(&world, posed[v].as_dvec3()) <= 0.02)
            .count();
        let fraction = near as f32 / owners[c.joint].len() as f32;
        assert!(fraction > 0.85, "joint {}: {fraction} {c:?}", c.joint);
    }
    // The forearm's capsule lies along the bent forearm (world space), the upper arm's
    // along the upper arm.
    let direction = |c: &FittedCapsule| joints_world[c.joint].transform_vector3(c.axis).normalize();
    let bone = |j: usize| joints_world[j].transform_vector3(Vec3::X).normalize();
    for c in &capsules {
        assert!(direction(c).dot(bone(c.joint)).abs() > 0.999, "{c:?}");
    }
    assert!(bone(0).dot(bone(1)).abs() < 1e-3, "the elbow is bent 90°");
}

#[test]
fn a_joints_vertices_are_the_ones_it_weighs_most() {
    let positions = [Vec3::ZERO; 5];
    let joints = [
        [0, 1, 2, 3],
        [0, 1, 0, 0],
        [2, 9, 0, 0],
        [1, 2, 0, 0],
        [0, 1, 0, 0],
    ];
    let weights = [
        [0.1, 0.2, 0.6, 0.1],
        [0.5, 0.5, 0.0, 0.0],
        // Joint 9 does not exist: the weight goes to the existing one.
        [0.2, 0.8, 0.0, 0.0],
        // A NaN weight counts for nothing.
        [f32::NAN, 0.3, 0.0, 0.0],
        // No weight at all: no joint.
        [0.0, 0.0, 0.0, 0.0],
    ];
    let input = SkinInput {
        positions: &positions,
        joints: &joints,
        weights: &weights,
        inverse_bindposes: &[Mat4::IDENTITY; 4],
        parents: &[None; 4],
        triangles: &[],
    };
    assert_eq!(
        dominant_vertices(&input),
        vec![vec![1], vec![], vec![0, 2, 3], vec![]]
    );
}

#[test]
fn bad_input_fits_what_it_can_and_never_panics() {
    let mut arm = arm(0.1, 1.0);
    // Non-finite positions and weights, joints out of range, a singular bind matrix,
    // and attribute arrays of different lengths.
    arm.positions[0] = Vec3::NAN;
    arm.weights[1] = [f32::NAN; 4];
    arm.joints[2] = [7, 7, 7, 7];
    arm.weights.truncate(arm.weights.len() - 3);
    let capsules = fit_skin_capsules(&arm.input(), &CapsuleFitSettings::default());
    assert_eq!(capsules.len(), 2);
    assert!(
        capsules
            .iter()
            .all(|c| c.radius.is_finite() && c.center.is_finite())
    );
    arm.inverse_bindposes[1] = Mat4::ZERO;
    assert_eq!(
        fit_skin_capsules(&arm.input(), &CapsuleFitSettings::default()).len(),
        1
    );
    arm.inverse_bindposes[0] = Mat4::from_cols_array(&[f32::INFINITY; 16]);
    assert!(fit_skin_capsules(&arm.input(), &CapsuleFitSettings::default()).is_empty());
    for coverage in [f32::NAN, -1.0, 0.0, 2.0] {
        let settings = CapsuleFitSettings {
            coverage,
            ..CapsuleFitSettings::default()
        };
        let arm = self::arm(0.1, 1.0);
        assert_eq!(fit_skin_capsules(&arm.input(), &settings).len(), 2);
    }
    let empty = SkinInput {
        positions: &[],
        joints: &[],
        weights: &[],
        inverse_bindposes: &[],
        parents: &[],
        triangles: &[],
    };
    assert!(fit_skin_capsules(&empty, &CapsuleFitSettings::default()).is_empty());
}

#[test]
fn small_joints_get_no_capsule() {
    // A thin finger on the arm's end (its own joint, 1 cm across): dropped as thinner
    // than 0.15 of the largest radius; with fewer vertices than the minimum, dropped too.
    let mut arm = arm(0.1, 1.0);
    arm.inverse_bindposes
        .push(Mat4::from_translation(Vec3::new(-1.0, 0.0, 0.0)));
    arm.parents.push(Some(1));
    for i in 0..40 {
        let a = std::f32::consts::TAU * i as f32 / 8.0;
        arm.positions.push(Vec3::new(
            1.0 + 0.002 * i as f32,
            0.005 * a.cos(),
            0.005 * a.sin(),
        ));
        arm.joints.push([2, 0, 0, 0]);
        arm.weights.push([1.0, 0.0, 0.0, 0.0]);
    }
    let keep_all = CapsuleFitSettings {
        min_radius: 0.0,
        ..CapsuleFitSettings::default()
    };
    assert_eq!(fit_skin_capsules(&arm.input(), &keep_all).len(), 3);
    assert_eq!(
        fit_skin_capsules(&arm.input(), &CapsuleFitSettings::default()).len(),
        2
    );
    let few = CapsuleFitSettings {
        min_radius: 0.0,
        min_vertices: 41,
        ..CapsuleFitSettings::default()
    };
    assert_eq!(fit_skin_capsules(&arm.input(), &few).len(), 2);
}

#[test]
fn the_axis_of_least_volume_wins_over_the_bone() {
    // Vertices along z, bone along x: the principal axis wins (least volume).
    let positions: Vec<Vec3> = (0..200)
        .map(|i| {
            let a = i as f32 * 2.399;
            Vec3::new(0.05 * a.cos(), 0.05 * a.sin(), i as f32 / 200.0)
        })
        .collect();
    let n = positions.len();
    let input = SkinInput {
        positions: &positions,
        joints: &vec![[0, 0, 0, 0]; n],
        weights: &vec![[1.0, 0.0, 0.0, 0.0]; n],
        inverse_bindposes: &[Mat4::IDENTITY, Mat4::from_translation(-Vec3::X)],
        parents: &[None, Some(0)],
        triangles: &[],
    };
    let c = fit_skin_capsules(&input, &CapsuleFitSettings::default());
    assert_eq!(c.len(), 1);
    assert!(c[0].axis.z.abs() > 0.99, "{:?}", c[0]);
    assert!(c[0].radius < 0.06, "{:?}", c[0]);
}

#[test]
fn the_fit_is_deterministic() {
    let arm = arm(0.07, 0.8);
    let a = fit_skin_capsules(&arm.input(), &CapsuleFitSettings::default());
    let b = fit_skin_capsules(&arm.input(), &CapsuleFitSettings::default());
    assert_eq!(a, b);
}

/// A closed tube along x of `radius` (24 sides) with rings at `xs` and a cap at each
/// end, skinned wholly to joint 0 (the identity), its triangles facing out.
fn closed_tube(radius: f32, xs: &[f32]) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut positions = Vec::new();
    for &x in xs {
        for k in 0..24 {
            let a = std::f32::consts::TAU * k as f32 / 24.0;
            positions.push(Vec3::new(x, radius * a.cos(), radius * a.sin()));
        }
    }
    let mut triangles = Vec::new();
    for r in 0..xs.len() as u32 - 1 {
        for k in 0..24 {
            let (a, b) = (r * 24 + k, r * 24 + (k + 1) % 24);
            let (c, d) = (a + 24, b + 24);
            triangles.push([a, b, d]);
            triangles.push([a, d, c]);
        }
    }
    let first = positions.len() as u32;
    positions.push(Vec3::new(xs[0], 0.0, 0.0));
    positions.push(Vec3::new(xs[xs.len() - 1], 0.0, 0.0));
    let last_ring = (xs.len() as u32 - 1) * 24;
    for k in 0..24 {
        triangles.push([first, (k + 1) % 24, k]);
        triangles.push([first + 1, last_ring + k, last_ring + (k + 1) % 24]);
    }
    (positions, triangles)
}

/// The volume (m³) where the capsules and the tube `radius` over `[x0, x1]` disagree,
/// by a 64³ midpoint rule over a box around both (exact inside tests, f64): the
/// independent truth of a fit.
fn disagreement(capsules: &[FittedCapsule], radius: f32, x0: f32, x1: f32) -> f64 {
    let r = f64::from(radius);
    let (x0, x1) = (f64::from(x0), f64::from(x1));
    disagreement_with(capsules, x0, x1, |p| {
        p.x >= x0 && p.x <= x1 && p.y.hypot(p.z) <= r
    })
}

/// The volume where the capsules and the solid `inside` disagree, over `x0 − 0.2 ..
/// x1 + 0.2` by ±0.2 in y and z (64³ midpoints).
fn disagreement_with(
    capsules: &[FittedCapsule],
    x0: f64,
    x1: f64,
    inside: impl Fn(DVec3) -> bool,
) -> f64 {
    let (lo, hi) = (
        DVec3::new(x0 - 0.2, -0.2, -0.2),
        DVec3::new(x1 + 0.2, 0.2, 0.2),
    );
    let n = 64;
    let step = (hi - lo) / f64::from(n);
    let mut wrong = 0usize;
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                let p = lo + (DVec3::new(f64::from(i), f64::from(j), f64::from(k)) + 0.5) * step;
                let caps = capsules.iter().any(|c| distance_f64(c, p) <= 0.0);
                wrong += usize::from(inside(p) != caps);
            }
        }
    }
    wrong as f64 * step.x * step.y * step.z
}

/// The capsules fitted (default settings) to a mesh skinned wholly to joint 0 (the
/// identity), by volume when `triangles` are given.
fn fit_one_joint(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<FittedCapsule> {
    let n = positions.len();
    let (joints, weights) = (vec![[0u16; 4]; n], vec![[1.0, 0.0, 0.0, 0.0]; n]);
    let input = SkinInput {
        positions,
        joints: &joints,
        weights: &weights,
        inverse_bindposes: &[Mat4::IDENTITY],
        parents: &[None],
        triangles,
    };
    fit_skin_capsules(&input, &CapsuleFitSettings::default())
}

#[test]
fn with_its_triangles_a_limb_is_fitted_to_its_volume() {
    // A tube 5 cm across and 40 cm long: the capsule that best covers it is as wide as
    // the tube and a little shorter (its round ends leave the rim out).
    let xs: Vec<f32> = (0..=40).map(|i| i as f32 * 0.01).collect();
    let (positions, triangles) = closed_tube(0.05, &xs);
    let c = fit_one_joint(&positions, &triangles);
    assert_eq!(c.len(), 1);
    let cell = 0.5 / volume::CELLS_ALONG_LONGEST as f32;
    assert!(c[0].axis.x.abs() > 0.99, "{:?}", c[0]);
    assert!((c[0].radius - 0.05).abs() < 1.5 * cell, "{:?}", c[0]);
    assert!(
        c[0].center.distance(Vec3::new(0.2, 0.0, 0.0)) < 2.0 * cell,
        "{:?}",
        c[0]
    );
    assert!(c[0].half_length > 0.15, "{:?}", c[0]);
    // Against the exact solid: within a quarter of the tube's volume (π·0.05²·0.4); the
    // best capsule (radius 0.05 reaching both ends) leaves out ⅔π·0.05³, 8 %.
    let tube = std::f64::consts::PI * 0.05f64.powi(2) * 0.4;
    let wrong = disagreement(&c, 0.05, 0.0, 0.4);
    assert!(wrong < 0.25 * tube, "{wrong} of {tube}");
}

#[test]
fn crowded_vertices_do_not_pull_the_volume_fit() {
    // The same tube tessellated finely over its first 8 cm (a paw's detail) and coarsely
    // after: the vertex fit crowds to the fine end, the volume fit covers the limb.
    let mut xs: Vec<f32> = (0..=32).map(|i| i as f32 * 0.0025).collect();
    xs.extend([0.24, 0.4]);
    let (positions, triangles) = closed_tube(0.05, &xs);
    let by_volume = fit_one_joint(&positions, &triangles);
    let by_vertices = fit_one_joint(&positions, &[]);
    let tube = std::f64::consts::PI * 0.05f64.powi(2) * 0.4;
    let (volume, vertices) = (
        disagreement(&by_volume, 0.05, 0.0, 0.4),
        disagreement(&by_vertices, 0.05, 0.0, 0.4),
    );
    assert!(volume < 0.25 * tube, "volume fit: {volume} of {tube}");
    assert!(
        volume < 0.5 * vertices,
        "volume fit {volume}, vertex fit {vertices}"
    );
}

#[test]
fn unusable_triangles_fall_back_to_the_vertex_fit() {
    let arm = arm(0.07, 0.8);
    let vertex_fit = fit_skin_capsules(&arm.input(), &CapsuleFitSettings::default());
    let huge = u32::MAX;
    let n = arm.positions.len() as u32;
    for triangles in [
        vec![[0, 1, huge]],
        vec![[0, 0, 0], [1, 1, 1]],
        vec![[0, 1, n]],
    ] {
        let input = SkinInput {
            triangles: &triangles,
            ..arm.input()
        };
        assert_eq!(
            fit_skin_capsules(&input, &CapsuleFitSettings::default()),
            vertex_fit,
            "{triangles:?}"
        );
    }
    // Non-finite corners are left out, not read.
    let (mut positions, triangles) = closed_tube(0.05, &[0.0, 0.2, 0.4]);
    positions[3] = Vec3::NAN;
    let c = fit_one_joint(&positions, &triangles);
    assert!(
        c.iter()
            .all(|c| c.radius.is_finite() && c.center.is_finite()),
        "{c:?}"
    );
}

#[test]
fn a_part_the_joints_capsule_leaves_out_gets_its_own() {
    // The tube with an ear on top (a closed tube 5 cm across standing from y = 3 cm to
    // 17 cm at x = 0.2), all one joint: the limb's capsule leaves the ear out, and the
    // ear, a connected piece of the joint's cells, gets a capsule of its own.
    let xs: Vec<f32> = (0..=40).map(|i| i as f32 * 0.01).collect();
    let (mut positions, mut triangles) = closed_tube(0.05, &xs);
    let ys: Vec<f32> = (0..=14).map(|i| i as f32 * 0.01).collect();
    let (ear, ear_triangles) = closed_tube(0.025, &ys);
    let first = positions.len() as u32;
    // A quarter turn about z (x → y), then up and along: the ear stands on the limb.
    positions.extend(ear.iter().map(|p| Vec3::new(0.2 - p.y, 0.03 + p.x, p.z)));
    triangles.extend(ear_triangles.iter().map(|t| t.map(|i| i + first)));
    let c = fit_one_joint(&positions, &triangles);
    assert_eq!(c.len(), 2, "{c:?}");
    assert!(
        c[1].center.distance(Vec3::new(0.2, 0.11, 0.0)) < 0.03,
        "{:?}",
        c[1]
    );
    let solid = |p: DVec3| {
        (p.x >= 0.0 && p.x <= 0.4 && p.y.hypot(p.z) <= 0.05)
            || (p.y >= 0.03 && p.y <= 0.17 && (p.x - 0.2).hypot(p.z) <= 0.025)
    };
    let (both, limb) = (
        disagreement_with(&c, 0.0, 0.4, solid),
        disagreement_with(&c[..1], 0.0, 0.4, solid),
    );
    // The ear above the limb is about π·0.025²·0.12 = 2.4e-4 m³.
    assert!(
        both < limb - 1.2e-4,
        "with the ear's capsule {both}, without {limb}"
    );
}

#[test]
fn stray_vertices_and_tiny_meshes_do_not_break_the_volume_fit() {
    // A vertex far off every triangle (no triangle uses it) seeds no cell of the grid.
    let (mut positions, triangles) = closed_tube(0.05, &[0.0, 0.2, 0.4]);
    positions.push(Vec3::splat(-1.0e6));
    let c = fit_one_joint(&positions, &triangles);
    assert_eq!(c.len(), 1, "{c:?}");
    assert!((c[0].radius - 0.05).abs() < 0.01, "{c:?}");
    // A mesh too small for f32 cells falls back to the vertex fit, finite.
    let tiny: Vec<Vec3> = positions.iter().map(|p| *p * 1.0e-44).collect();
    let c = fit_one_joint(&tiny, &triangles);
    assert!(
        c.iter()
            .all(|c| c.radius.is_finite() && c.center.is_finite()),
        "{c:?}"
    );
}
