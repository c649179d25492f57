//! Bad input gets a clear error or documented handling, never a panic.

use glam::Vec3;
use penumbra_sdf::{
    BakeError, BakeSettings, SignMethod, TriMesh, bake,
    gltf_input::{GltfSelection, load_gltf},
    mesh::MeshError,
    shapes,
};

fn settings(n: u32) -> BakeSettings {
    BakeSettings::longest_axis(n)
}

#[test]
fn bad_meshes_and_settings_are_errors() {
    let tri = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
    type Check = fn(&BakeError) -> bool;
    let cases: Vec<(&str, TriMesh, BakeSettings, Check)> = vec![
        ("empty", TriMesh::default(), settings(16), |e| {
            *e == BakeError::Mesh(MeshError::Empty)
        }),
        (
            "nan",
            TriMesh {
                positions: vec![Vec3::ZERO, Vec3::X, Vec3::NAN],
                triangles: vec![[0, 1, 2]],
                ..Default::default()
            },
            settings(16),
            |e| matches!(e, BakeError::Mesh(MeshError::NonFinitePosition { .. })),
        ),
        (
            "index",
            TriMesh {
                positions: tri.clone(),
                triangles: vec![[0, 1, 3]],
                ..Default::default()
            },
            settings(16),
            |e| matches!(e, BakeError::Mesh(MeshError::IndexOutOfRange { .. })),
        ),
        (
            "zero area",
            TriMesh {
                positions: tri.clone(),
                triangles: vec![[0, 0, 1]],
                ..Default::default()
            },
            settings(16),
            |e| *e == BakeError::Mesh(MeshError::AllTrianglesDegenerate),
        ),
        (
            // Found by `cargo xtask fuzz` (obj): a finite vertex so far out that squared
            // distances overflow f32 made the sampler's nearest-triangle query fail.
            "far vertex",
            TriMesh {
                positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 9.2e18, 1.0)],
                triangles: vec![[0, 1, 2]],
                ..Default::default()
            },
            settings(8),
            |e| {
                matches!(
                    e,
                    BakeError::Mesh(MeshError::CoordinateTooLarge { vertex: 2, .. })
                )
            },
        ),
        (
            "huge",
            shapes::cuboid(Vec3::ONE),
            settings(1_000_000),
            |e| matches!(e, BakeError::Grid(_)),
        ),
        ("tiny", shapes::cuboid(Vec3::ONE), settings(3), |e| {
            matches!(e, BakeError::Grid(_))
        }),
        (
            "threshold",
            shapes::cuboid(Vec3::ONE),
            BakeSettings {
                sign: SignMethod::BackfaceRatio { threshold: 1.5 },
                ..settings(16)
            },
            |e| matches!(e, BakeError::Settings(_)),
        ),
        (
            "shell",
            shapes::cuboid(Vec3::ONE),
            BakeSettings {
                sign: SignMethod::TwoSided {
                    shell_voxels: f32::NAN,
                },
                ..settings(16)
            },
            |e| matches!(e, BakeError::Settings(_)),
        ),
    ];
    for (name, mesh, s, expected) in cases {
        let e = bake(&mesh, &s, None).unwrap_err();
        assert!(expected(&e), "{name}: {e:?}");
        assert!(!e.to_string().is_empty());
    }
}

/// Documented handling: a flat mesh bakes (its plane gets zero or negative samples by
/// the thin-feature guard); degenerate triangles are dropped and counted.
#[test]
fn flat_and_partly_degenerate_meshes_bake() {
    let mesh = TriMesh {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::Z, Vec3::X * 2.0],
        triangles: vec![[0, 2, 1], [0, 1, 3]],
        ..Default::default()
    };
    let baked = bake(&mesh, &settings(16), None).unwrap();
    assert_eq!(baked.mesh.degenerate_dropped, 1);
    assert!(baked.volume.data.iter().all(|v| v.to_f32().is_finite()));
    assert!(baked.volume.data.iter().any(|v| v.to_f32() <= 0.0));
}

#[test]
fn every_sign_method_agrees_on_a_closed_box_away_from_the_surface() {
    let mesh = shapes::cuboid(Vec3::new(1.0, 0.7, 0.4));
    let reference = bake(&mesh, &settings(24), None).unwrap().volume;
    for sign in [SignMethod::BACKFACE_RATIO, SignMethod::RayParity] {
        let v = bake(
            &mesh,
            &BakeSettings {
                sign,
                ..settings(24)
            },
            None,
        )
        .unwrap()
        .volume;
        let h = v.voxel_size;
        for (a, b) in v.data.iter().zip(&reference.data) {
            let (a, b) = (a.to_f32(), b.to_f32());
            assert_eq!(a.abs(), b.abs());
            if b.abs() > h {
                assert_eq!(a < 0.0, b < 0.0, "{sign:?}");
            }
        }
    }
    // Two-sided: unsigned minus the shell.
    let v = bake(
        &mesh,
        &BakeSettings {
            sign: SignMethod::TWO_SIDED,
            ..settings(24)
        },
        None,
    )
    .unwrap()
    .volume;
    let inside = v.data.iter().filter(|x| x.to_f32() < 0.0).count();
    let ref_inside = reference.data.iter().filter(|x| x.to_f32() < 0.0).count();
    assert!(
        inside > 0 && inside < ref_inside,
        "two-sided makes a shell, not a solid"
    );
}

/// One triangle's three positions (0,0,0), (1,0,0), (0,1,0) as a base64 `data:` URI.
fn triangle_buffer_uri() -> String {
    let floats: Vec<u8> = [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]
        .iter()
        .flat_map(|f| f.to_le_bytes())
        .collect();
    use base64::Engine;
    format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&floats)
    )
}

#[test]
fn bad_gltf_files_are_errors() {
    let tetra_json = |uri: &str, byte_length: usize| {
        format!(
            r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"uri":"{uri}","byteLength":{byte_length}}}],
            "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}}],
            "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3",
            "min":[0,0,0],"max":[1,1,0]}}],
            "meshes":[{{"name":"tri","primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
            "nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0}}"#
        )
    };
    let uri = triangle_buffer_uri();
    // The good file reads one triangle, by scene and by name.
    let good = tetra_json(&uri, 36);
    let (m, report) = load_gltf(good.as_bytes(), None, &GltfSelection::Scene).unwrap();
    assert_eq!((m.triangles.len(), report.primitives), (1, 1));
    let (m, _) = load_gltf(good.as_bytes(), None, &GltfSelection::Mesh("tri".into())).unwrap();
    assert_eq!(m.origin + m.positions[1].as_dvec3(), glam::DVec3::X);
    // Node graphs that are not forests: a cycle (which never ended before) and a node
    // with two parents.
    let with_nodes = |nodes: &str| good.replace(r#""nodes":[{"mesh":0}]"#, nodes);
    let cycle = with_nodes(r#""nodes":[{"children":[1]},{"mesh":0,"children":[0]}]"#);
    let shared = with_nodes(r#""nodes":[{"children":[2]},{"children":[2]},{"mesh":0}]"#).replace(
        r#""scenes":[{"nodes":[0]}]"#,
        r#""scenes":[{"nodes":[0,1]}]"#,
    );
    assert_ne!(cycle, good);
    assert_ne!(shared, good);
    // Bad ones.
    let cases: Vec<(&str, String)> = vec![
        ("garbage", "not json at all".into()),
        ("glb header only", "glTF\u{2}\0\0\0".into()),
        ("short buffer", tetra_json(&uri, 360)),
        (
            "bad base64",
            tetra_json("data:application/octet-stream;base64,@@@@", 36),
        ),
        ("missing file", tetra_json("nope.bin", 36)),
        ("remote", tetra_json("https://example.invalid/x.bin", 36)),
        ("absolute", tetra_json("/etc/passwd", 36)),
        ("parent", tetra_json("../x.bin", 36)),
        (
            "parent, percent-encoded",
            tetra_json("sub/%2e%2e/%2e%2e/x.bin", 36),
        ),
        ("cycle", cycle),
        ("two parents", shared),
        // The `gltf` crate panics on these (found by `cargo xtask fuzz`): they must be
        // errors with no `catch_unwind`, which `panic = "abort"` disables.
        (
            "POSITION names a missing accessor",
            good.replace(r#""POSITION":0"#, r#""POSITION":5"#),
        ),
        (
            "float indices",
            good.replace(r#""POSITION":0}"#, r#""POSITION":0},"indices":0"#),
        ),
        ("count 0", good.replace(r#""count":3"#, r#""count":0"#)),
        (
            "stride shorter than an element",
            good.replace(
                r#""byteLength":36}],"#,
                r#""byteLength":36,"byteStride":4}],"#,
            ),
        ),
        (
            "elements past the view",
            good.replace(r#""count":3"#, r#""count":4"#),
        ),
        (
            "GLB length shorter than its header",
            "glTF\u{2}\0\0\0\u{4}\0\0\0JSON".into(),
        ),
    ];
    for (name, text) in cases {
        let r = load_gltf(
            text.as_bytes(),
            Some(std::path::Path::new("/nonexistent")),
            &GltfSelection::Scene,
        );
        let e = r.err().unwrap_or_else(|| panic!("{name}: accepted"));
        assert!(!e.to_string().is_empty(), "{name}");
        if name.starts_with("absolute") || name.starts_with("parent") {
            assert!(e.to_string().contains("refused"), "{name}: {e}");
        }
        let expected = match name {
            "POSITION names a missing accessor" => "POSITION names accessor 5, but the file has 1",
            "float indices" => "indices must be unsigned integer scalars",
            "count 0" => "count 0 (1 to",
            "stride shorter than an element" => {
                "byteStride 4 is shorter than an element (12 bytes)"
            }
            "elements past the view" => "pass the end of buffer view 0 (36 bytes)",
            "GLB length shorter than its header" => "length 4 is shorter than the 12-byte header",
            _ => "",
        };
        assert!(e.to_string().contains(expected), "{name}: {e}");
    }
    let e = load_gltf(good.as_bytes(), None, &GltfSelection::Mesh("nope".into())).unwrap_err();
    assert!(e.to_string().contains("\"tri\""), "{e}");
}

#[test]
fn each_triangle_knows_whether_its_material_is_double_sided_or_see_through() {
    use penumbra_sdf::gltf_input::{TriangleMaterial, load_gltf_with_sides};
    let uri = triangle_buffer_uri();
    // Five primitives on one triangle: a double-sided material, a single-sided one, none,
    // an alpha-blended one, a transmissive one (glass).
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"uri":"{uri}","byteLength":36}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3",
        "min":[0,0,0],"max":[1,1,0]}}],
        "extensionsUsed":["KHR_materials_transmission"],
        "materials":[{{"doubleSided":true}},{{}},{{"alphaMode":"BLEND"}},
            {{"extensions":{{"KHR_materials_transmission":{{"transmissionFactor":1}}}}}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"material":0}},
            {{"attributes":{{"POSITION":0}},"material":1}},{{"attributes":{{"POSITION":0}}}},
            {{"attributes":{{"POSITION":0}},"material":2}},
            {{"attributes":{{"POSITION":0}},"material":3}}]}}],
        "nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0}}"#
    );
    let (mesh, sides, _) =
        load_gltf_with_sides(json.as_bytes(), None, &GltfSelection::Scene).unwrap();
    assert_eq!(mesh.triangles.len(), 5);
    let m = |double_sided, see_through| TriangleMaterial {
        double_sided,
        see_through,
    };
    assert_eq!(
        sides,
        [
            m(true, false),
            m(false, false),
            m(false, false),
            m(false, true),
            m(false, true)
        ]
    );
}

/// A 700-byte glTF whose POSITION accessor is sparse, has no buffer view and claims 2·10⁹
/// elements was read by reserving 48 GB (`memory allocation of 48000000000 bytes
/// failed`, an abort, #47): now an error naming the mesh, the accessor and the limit,
/// before anything is allocated. A sparse accessor within the limit still reads.
#[test]
fn a_sparse_accessor_claiming_billions_of_elements_is_an_error() {
    use base64::Engine;
    // One sparse element: index 2 (u32), value (0, 1, 0).
    let bytes: Vec<u8> = 2u32
        .to_le_bytes()
        .into_iter()
        .chain([0.0f32, 1.0, 0.0].iter().flat_map(|f| f.to_le_bytes()))
        .collect();
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bytes)
    );
    let json = |count: u64| {
        format!(
            r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"uri":"{uri}","byteLength":16}}],
            "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":4}},
                           {{"buffer":0,"byteOffset":4,"byteLength":12}}],
            "accessors":[{{"componentType":5126,"count":{count},"type":"VEC3",
                "min":[0,0,0],"max":[1,1,0],
                "sparse":{{"count":1,"indices":{{"bufferView":0,"componentType":5125}},
                           "values":{{"bufferView":1}}}}}}],
            "meshes":[{{"name":"huge","primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
            "nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0}}"#
        )
    };
    let text = json(2_000_000_000);
    assert!(text.len() < 1000, "{} bytes", text.len());
    let e = load_gltf(text.as_bytes(), None, &GltfSelection::Scene).unwrap_err();
    let message = e.to_string();
    for part in ["\"huge\"", "POSITION", "2000000000", "67108864"] {
        assert!(message.contains(part), "{part} not in: {message}");
    }
    // Three elements, the third set by the sparse value: one triangle.
    let (m, _) = load_gltf(json(3).as_bytes(), None, &GltfSelection::Scene).unwrap();
    assert_eq!(m.triangles.len(), 1);
    assert_eq!(m.origin + m.positions[2].as_dvec3(), glam::DVec3::Y);
}
