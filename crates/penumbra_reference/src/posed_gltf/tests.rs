use super::*;
use base64::Engine;

/// A glTF with one triangle skinned to joint 1 (child of joint 0, 1 m up the x axis),
/// whose animation turns joint 1 about z from 0 to 90° over `KEY_INTERVAL` seconds, with
/// the given interpolation (cubic spline: the tangents of [`TANGENTS`]). The mesh's own
/// node is translated far away (ignored when skinned).
fn arm_gltf(interpolation: &str) -> Vec<u8> {
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut push = |bytes: Vec<u8>| {
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        views.push((bin.len(), bytes.len()));
        bin.extend(bytes);
    };
    let f32s = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    // 0: positions (a triangle 2..3 m along x, in bind space = mesh space).
    push(f32s(&[2.0, 0.0, 0.0, 3.0, 0.0, 0.0, 2.0, 1.0, 0.0]));
    // 1: joints (u16 × 4): all to joint 1.
    push(
        [1u16, 0, 0, 0]
            .repeat(3)
            .iter()
            .flat_map(|x| x.to_le_bytes())
            .collect(),
    );
    // 2: weights.
    push(f32s(&[1.0, 0.0, 0.0, 0.0].repeat(3)));
    // 3: inverse bind matrices (column-major): identity, translate(−1, 0, 0).
    let mut ibm = vec![
        1.0f32, 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1.,
    ];
    ibm.extend([
        1.0f32, 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., -1., 0., 0., 1.,
    ]);
    push(f32s(&ibm));
    // 4: times; 5: rotations (quaternions about z: 0°, 90°).
    push(f32s(&[0.0, KEY_INTERVAL]));
    let rotations: Vec<f32> = if interpolation == "CUBICSPLINE" {
        // (in-tangent, value, out-tangent) per key.
        let [in0, out0, in1, out1] = TANGENTS;
        [in0, KEYS[0], out0, in1, KEYS[1], out1].concat()
    } else {
        KEYS.concat()
    };
    push(f32s(&rotations));
    let views_json: Vec<String> = views
        .iter()
        .map(|(o, l)| format!(r#"{{"buffer":0,"byteOffset":{o},"byteLength":{l}}}"#))
        .collect();
    let n_rot = rotations.len() / 4;
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0,2]}}],
        "nodes":[{{"children":[1]}},{{"translation":[1,0,0]}},
                 {{"mesh":0,"skin":0,"translation":[50,0,0]}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"JOINTS_0":1,"WEIGHTS_0":2}}}}]}}],
        "skins":[{{"joints":[0,1],"inverseBindMatrices":3}}],
        "animations":[{{"channels":[{{"sampler":0,"target":{{"node":1,"path":"rotation"}}}}],
                        "samplers":[{{"input":4,"output":5,"interpolation":"{interpolation}"}}]}}],
        "accessors":[
          {{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[2,0,0],"max":[3,1,0]}},
          {{"bufferView":1,"componentType":5123,"count":3,"type":"VEC4"}},
          {{"bufferView":2,"componentType":5126,"count":3,"type":"VEC4"}},
          {{"bufferView":3,"componentType":5126,"count":2,"type":"MAT4"}},
          {{"bufferView":4,"componentType":5126,"count":2,"type":"SCALAR","min":[0],"max":[{KEY_INTERVAL}]}},
          {{"bufferView":5,"componentType":5126,"count":{n_rot},"type":"VEC4"}}],
        "bufferViews":[{}],
        "buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{}"}}]}}"#,
        views_json.join(","),
        bin.len(),
        base64::engine::general_purpose::STANDARD.encode(&bin)
    );
    json.into_bytes()
}

/// The two keys' rotations: 0° and 90° about z.
const KEYS: [[f32; 4]; 2] = [
    [0.0, 0.0, 0.0, 1.0],
    [
        0.0,
        0.0,
        std::f32::consts::FRAC_1_SQRT_2,
        std::f32::consts::FRAC_1_SQRT_2,
    ],
];
/// Seconds between the keys.
const KEY_INTERVAL: f32 = 2.0;
/// Cubic-spline tangents (per second), all different: key 0's in and out, key 1's in and
/// out. Only key 0's out and key 1's in shape the curve between them.
const TANGENTS: [[f32; 4]; 4] = [
    [9.0, 9.0, 9.0, 9.0],
    [0.0, 0.0, 0.3, 0.0],
    [0.0, 0.0, -0.2, 0.1],
    [-9.0, 9.0, -9.0, 9.0],
];

fn posed(interpolation: &str, time: Option<f32>) -> Vec<Vec3> {
    let dir = std::env::temp_dir().join(format!("penumbra_posed_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("arm_{interpolation}.gltf"));
    std::fs::write(&path, arm_gltf(interpolation)).unwrap();
    let pose = time.map(|time| Pose { animation: 0, time });
    let out = posed_triangles(&path, pose).unwrap();
    assert_eq!(out.triangles.len(), 1);
    assert!(out.skinned[0]);
    out.triangles[0].to_vec()
}

/// The triangle turned by `degrees` about z around the joint at (1, 0, 0).
fn turned(degrees: f32) -> Vec<Vec3> {
    let q = glam::Quat::from_rotation_z(degrees.to_radians());
    [
        Vec3::new(2., 0., 0.),
        Vec3::new(3., 0., 0.),
        Vec3::new(2., 1., 0.),
    ]
    .iter()
    .map(|p| Vec3::X + q * (*p - Vec3::X))
    .collect()
}

fn assert_near(got: &[Vec3], want: &[Vec3]) {
    for (g, w) in got.iter().zip(want) {
        assert!(g.distance(*w) < 1e-5, "{got:?} != {want:?}");
    }
}

#[test]
fn a_skinned_triangle_follows_its_animated_joint() {
    // Rest pose = bind pose: the mesh as stored (its node's translation ignored).
    assert_near(&posed("LINEAR", None), &turned(0.0));
    // Linear: slerp, 45° at half time; clamped past the last key.
    assert_near(&posed("LINEAR", Some(1.0)), &turned(45.0));
    assert_near(&posed("LINEAR", Some(0.5)), &turned(22.5));
    assert_near(&posed("LINEAR", Some(7.0)), &turned(90.0));
    // Step: the key before.
    assert_near(&posed("STEP", Some(1.99)), &turned(0.0));
    assert_near(&posed("STEP", Some(2.0)), &turned(90.0));
    // Cubic spline (glTF 2.0 Appendix C): at s = t / Δ, Δ = 2 s,
    // (2s³ − 3s² + 1) v₀ + Δ (s³ − 2s² + s) b₀ + (−2s³ + 3s²) v₁ + Δ (s³ − s²) a₁, with
    // key 0's out-tangent b₀ and key 1's in-tangent a₁; then normalized.
    let (dt, s) = (KEY_INTERVAL, 0.25f32);
    let h = [
        2.0 * s.powi(3) - 3.0 * s * s + 1.0,
        dt * (s.powi(3) - 2.0 * s * s + s),
        -2.0 * s.powi(3) + 3.0 * s * s,
        dt * (s.powi(3) - s * s),
    ];
    let q: [f32; 4] = std::array::from_fn(|i| {
        h[0] * KEYS[0][i] + h[1] * TANGENTS[1][i] + h[2] * KEYS[1][i] + h[3] * TANGENTS[2][i]
    });
    let q = glam::Quat::from_array(q).normalize();
    let (axis, angle) = q.to_axis_angle();
    assert!(axis.z > 0.999, "{q:?}");
    assert_near(
        &posed("CUBICSPLINE", Some(s * dt)),
        &turned(angle.to_degrees()),
    );
}

#[test]
fn a_bad_animation_index_is_an_error() {
    let dir = std::env::temp_dir().join(format!("penumbra_posed_bad_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("arm.gltf");
    std::fs::write(&path, arm_gltf("LINEAR")).unwrap();
    let pose = Pose {
        animation: 3,
        time: 0.0,
    };
    assert!(posed_triangles(&path, Some(pose)).is_err());
    // The nodes' pose, as an app would set it: joint 1 turned 45° at half time.
    let nodes = node_poses(
        &path,
        Pose {
            animation: 0,
            time: 1.0,
        },
    )
    .unwrap();
    assert_eq!(nodes.len(), 3);
    assert_eq!(nodes[1].translation, Vec3::X);
    let (axis, angle) = nodes[1].rotation.to_axis_angle();
    assert!(axis.z > 0.999 && (angle.to_degrees() - 45.0).abs() < 1e-3);
    assert_eq!(nodes[0].rotation, glam::Quat::IDENTITY);
    assert!(posed_triangles(&dir.join("missing.gltf"), None).is_err());
}
