//! glTF 2.0 / GLB input: every mesh of a scene placed by its node transforms, or one
//! named mesh in its own space.
//!
//! Buffers may be the GLB binary chunk, base64 `data:` URIs, or files next to the
//! `.gltf` (relative URIs only; nothing is fetched from the network). Only triangle-list
//! primitives are read; strips and fans are triangulated; points and lines are skipped.
//! Skinned meshes are read in their bind pose (the node transforms, not the skin), and
//! morph targets are ignored — both reported in [`GltfReport`].
//!
//! Node transforms are composed in f64 and the mesh centred on its bounds before
//! conversion to f32 ([`TriMesh::from_f64`]). A node graph that is not a forest (a
//! cycle, or a node with two parents, both invalid glTF) is an error, never a hang.

mod accessor;

use crate::mesh::{Topology, TriMesh, triangles_from};
use glam::{DMat4, DVec3, Vec3};
use gltf::mesh::Mode;
use std::path::Path;

/// What to read from a glTF file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum GltfSelection {
    /// All meshes of the default scene (or the first scene), each instance placed by
    /// its node's world transform.
    Scene,
    /// The mesh with this name, in its own local space (all of its primitives).
    Mesh(String),
}

/// Why a glTF file could not be read.
#[derive(Debug)]
pub enum GltfError {
    /// The file is not valid glTF / GLB.
    Parse(String),
    /// A buffer is missing or cannot be loaded.
    Buffer(String),
    /// The selection matched nothing.
    NotFound(String),
    /// An accessor claims more elements than are read ([`MAX_ACCESSOR_ELEMENTS`]) — a
    /// sparse accessor needs no buffer for them, so a few hundred bytes could ask for
    /// tens of gigabytes.
    TooLarge(String),
}

/// The most elements read from one POSITION or index accessor, and positions from one
/// file (2²⁶ = 67,108,864: 1.5 GiB of f64 positions; a mesh that large is far beyond what
/// a distance field resolves).
pub const MAX_ACCESSOR_ELEMENTS: usize = 1 << 26;

impl std::fmt::Display for GltfError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            GltfError::Parse(e) => write!(f, "invalid glTF: {e}"),
            GltfError::Buffer(e) => write!(f, "glTF buffer: {e}"),
            GltfError::NotFound(e) => write!(f, "{e}"),
            GltfError::TooLarge(e) => write!(f, "glTF too large: {e}"),
        }
    }
}

impl std::error::Error for GltfError {}

/// Notes about what was read.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct GltfReport {
    /// Primitives read.
    pub primitives: usize,
    /// Primitives skipped (points, lines, or without positions).
    pub skipped_primitives: usize,
    /// Mesh instances that have a skin (read in bind pose).
    pub skinned_instances: usize,
    /// Names of the meshes in the file (to help pick one).
    pub mesh_names: Vec<String>,
}

/// Reads triangles from glTF or GLB bytes. `base_dir` resolves relative buffer URIs
/// of `.gltf` files (`None`: only GLB and `data:` buffers).
pub fn load_gltf(
    bytes: &[u8],
    base_dir: Option<&Path>,
    selection: &GltfSelection,
) -> Result<(TriMesh, GltfReport), GltfError> {
    load_gltf_with_sides(bytes, base_dir, selection).map(|(mesh, _, report)| (mesh, report))
}

/// What a renderer needs to know of a triangle's material ([`load_gltf_with_sides`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TriangleMaterial {
    /// Double-sided: a renderer draws its back faces; a single-sided triangle seen from
    /// behind is culled.
    pub double_sided: bool,
    /// See-through: alpha-blended (`alphaMode: BLEND`) or transmissive
    /// (`KHR_materials_transmission` with a factor above 0: glass). Bevy draws both after
    /// its opaque passes (transparent and transmissive phases), so they are in neither
    /// the depth prepass nor the deferred G-buffer, and Penumbra's scene casters skip
    /// them.
    pub see_through: bool,
}

/// [`load_gltf`], and for each triangle what its material tells a renderer
/// ([`TriangleMaterial`]).
pub fn load_gltf_with_sides(
    bytes: &[u8],
    base_dir: Option<&Path>,
    selection: &GltfSelection,
) -> Result<(TriMesh, Vec<TriangleMaterial>, GltfReport), GltfError> {
    load_gltf_unguarded(bytes, base_dir, selection)
}

/// Parses and validates the document. Two checks come first because the `gltf` crate
/// panics without them: a GLB header whose length is shorter than the header itself
/// (a subtraction that overflows), and a primitive whose `POSITION` names an accessor
/// that does not exist (its validation indexes the accessors before checking).
fn parse(bytes: &[u8]) -> Result<(gltf::Document, Option<Vec<u8>>), GltfError> {
    if bytes.starts_with(b"glTF") && bytes.len() >= 12 {
        let length = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]);
        if length < 12 {
            return Err(GltfError::Parse(format!(
                "GLB header: the file's length {length} is shorter than the 12-byte header"
            )));
        }
    }
    let gltf::Gltf { document, blob } = gltf::Gltf::from_slice_without_validation(bytes)
        .map_err(|e| GltfError::Parse(e.to_string()))?;
    let json = document.into_json();
    for (m, mesh) in json.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let position = gltf::json::validation::Checked::Valid(gltf::Semantic::Positions);
            if let Some(a) = primitive.attributes.get(&position)
                && a.value() >= json.accessors.len()
            {
                return Err(GltfError::Parse(format!(
                    "mesh {m} primitive {p}: POSITION names accessor {}, but the file has {}",
                    a.value(),
                    json.accessors.len()
                )));
            }
        }
    }
    let document = gltf::Document::from_json(json).map_err(|e| GltfError::Parse(e.to_string()))?;
    Ok((document, blob))
}

fn load_gltf_unguarded(
    bytes: &[u8],
    base_dir: Option<&Path>,
    selection: &GltfSelection,
) -> Result<(TriMesh, Vec<TriangleMaterial>, GltfReport), GltfError> {
    let (document, blob) = parse(bytes)?;
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => blob
                .clone()
                .ok_or_else(|| GltfError::Buffer("GLB binary chunk missing".into()))?,
            gltf::buffer::Source::Uri(uri) => load_uri(uri, base_dir)?,
        };
        if data.len() < buffer.length() {
            return Err(GltfError::Buffer(format!(
                "buffer {} holds {} bytes, needs {}",
                buffer.index(),
                data.len(),
                buffer.length()
            )));
        }
        buffers.push(data);
    }
    let mut out = Triangles::default();
    let mut report = GltfReport {
        mesh_names: document
            .meshes()
            .map(|m| m.name().unwrap_or("").to_string())
            .collect(),
        ..Default::default()
    };
    match selection {
        GltfSelection::Mesh(name) => {
            let mesh = document
                .meshes()
                .find(|m| m.name() == Some(name.as_str()))
                .ok_or_else(|| {
                    GltfError::NotFound(format!(
                        "no mesh named {name:?} (meshes: {:?})",
                        report.mesh_names
                    ))
                })?;
            append_mesh(
                &mesh,
                DMat4::IDENTITY,
                &document,
                &buffers,
                &mut out,
                &mut report,
            )?;
        }
        GltfSelection::Scene => {
            let scene = document
                .default_scene()
                .or_else(|| document.scenes().next())
                .ok_or_else(|| GltfError::NotFound("the file has no scene".into()))?;
            let mut stack: Vec<(gltf::Node, DMat4)> =
                scene.nodes().map(|n| (n, DMat4::IDENTITY)).collect();
            // Each node is reached once in a forest; a second visit means a cycle (which
            // would never end) or a shared child.
            let mut visited = vec![false; document.nodes().count()];
            while let Some((node, parent)) = stack.pop() {
                if std::mem::replace(&mut visited[node.index()], true) {
                    return Err(GltfError::Parse(format!(
                        "node {} is reached twice from the scene's roots (a cycle or a node \
                         with two parents): the node hierarchy must be a forest",
                        node.index()
                    )));
                }
                let local = node.transform().matrix().map(|c| c.map(f64::from));
                let world = parent * DMat4::from_cols_array_2d(&local);
                if let Some(mesh) = node.mesh() {
                    report.skinned_instances += usize::from(node.skin().is_some());
                    append_mesh(&mesh, world, &document, &buffers, &mut out, &mut report)?;
                }
                stack.extend(node.children().map(|c| (c, world)));
            }
        }
    }
    Ok((
        TriMesh::from_f64(&out.positions, out.triangles),
        out.materials,
        report,
    ))
}

/// Triangles gathered in f64, before centring.
#[derive(Default)]
struct Triangles {
    positions: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    /// Per triangle: what its material tells a renderer.
    materials: Vec<TriangleMaterial>,
}

fn load_uri(uri: &str, base_dir: Option<&Path>) -> Result<Vec<u8>, GltfError> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, payload) = rest
            .split_once(";base64,")
            .ok_or_else(|| GltfError::Buffer("only base64 data URIs are supported".into()))?;
        use base64::Engine;
        return base64::engine::general_purpose::STANDARD
            .decode(payload)
            .map_err(|e| GltfError::Buffer(format!("bad base64 data URI: {e}")));
    }
    if uri.contains("://") {
        return Err(GltfError::Buffer(format!(
            "remote buffer {uri:?} is not fetched"
        )));
    }
    let dir = base_dir.ok_or_else(|| {
        GltfError::Buffer(format!(
            "external buffer {uri:?} needs the file's directory"
        ))
    })?;
    let decoded = percent_decode(uri);
    // Only files in the glTF's directory or below: an absolute path or `..` would read
    // anything the process can (`/etc/passwd`, `../../secret`).
    let inside = Path::new(&decoded).components().all(|c| {
        matches!(
            c,
            std::path::Component::Normal(_) | std::path::Component::CurDir
        )
    });
    if !inside || decoded.is_empty() {
        return Err(GltfError::Buffer(format!(
            "external buffer {uri:?} is not a relative path inside the file's directory \
             (absolute paths and `..` are refused)"
        )));
    }
    let path = dir.join(&decoded);
    std::fs::read(&path).map_err(|e| GltfError::Buffer(format!("{}: {e}", path.display())))
}

fn percent_decode(s: &str) -> String {
    let hex = |b: u8| (b as char).to_digit(16).map(|d| d as u8);
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let escaped = (bytes[i] == b'%' && i + 2 < bytes.len())
            .then(|| Some(hex(bytes[i + 1])? * 16 + hex(bytes[i + 2])?))
            .flatten();
        if let Some(v) = escaped {
            out.push(v);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

fn append_mesh(
    mesh: &gltf::Mesh,
    transform: DMat4,
    document: &gltf::Document,
    buffers: &[Vec<u8>],
    out: &mut Triangles,
    report: &mut GltfReport,
) -> Result<(), GltfError> {
    // A mirroring transform flips the winding: swap two corners to keep outside out.
    let flip = transform.determinant() < 0.0;
    for primitive in mesh.primitives() {
        let position = primitive.get(&gltf::Semantic::Positions);
        let (Some(position), true) = (
            position,
            matches!(
                primitive.mode(),
                Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
            ),
        ) else {
            report.skipped_primitives += 1;
            continue;
        };
        // Checked before reading: a small file can claim billions of elements.
        let index_accessor = primitive.indices();
        let claims = [
            Some(("POSITION", &position)),
            index_accessor.as_ref().map(|a| ("indices", a)),
        ];
        for (what, accessor) in claims.into_iter().flatten() {
            let total = if what == "POSITION" {
                out.positions.len().saturating_add(accessor.count())
            } else {
                accessor.count()
            };
            if total > MAX_ACCESSOR_ELEMENTS {
                return Err(GltfError::TooLarge(format!(
                    "mesh {} ({:?}) primitive {}: accessor {} ({what}) claims {} elements{}; \
                     at most {MAX_ACCESSOR_ELEMENTS} are read",
                    mesh.index(),
                    mesh.name().unwrap_or(""),
                    primitive.index(),
                    accessor.index(),
                    accessor.count(),
                    if total > accessor.count() {
                        format!(" ({total} positions with the file's earlier meshes)")
                    } else {
                        String::new()
                    },
                )));
            }
        }
        let root = document.as_json();
        let what = |name: &str| {
            format!(
                "mesh {} primitive {} {name}",
                mesh.index(),
                primitive.index()
            )
        };
        let base = out.positions.len() as u32;
        accessor::for_each_element(
            root,
            buffers,
            position.index(),
            &what("POSITION"),
            false,
            |p| {
                // Rounded to f32 first, as the file stores it (quantized ones included).
                let p = Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32);
                out.positions.push(transform.transform_point3(p.as_dvec3()));
            },
        )?;
        let count = out.positions.len() as u32 - base;
        let indices: Vec<u32> = match primitive.indices() {
            Some(a) => {
                let mut indices = Vec::with_capacity(a.count().min(MAX_ACCESSOR_ELEMENTS));
                accessor::for_each_element(
                    root,
                    buffers,
                    a.index(),
                    &what("indices"),
                    true,
                    |i| {
                        indices.push(i[0] as u32);
                    },
                )?;
                indices
            }
            None => (0..count).collect(),
        };
        let topology = match primitive.mode() {
            Mode::Triangles => Topology::List,
            Mode::TriangleStrip => Topology::Strip,
            _ => Topology::Fan,
        };
        let tris = triangles_from(&indices, topology);
        let material = primitive.material();
        let transmissive = material
            .transmission()
            .is_some_and(|t| t.transmission_factor() > 0.0);
        let material = TriangleMaterial {
            double_sided: material.double_sided(),
            see_through: material.alpha_mode() == gltf::material::AlphaMode::Blend || transmissive,
        };
        for t in tris {
            // Out-of-range indices stay out of range (base + i ≥ len) and are reported
            // by `TriMesh::validate`.
            let t = t.map(|i| base.saturating_add(i));
            out.triangles
                .push(if flip { [t[0], t[2], t[1]] } else { t });
            out.materials.push(material);
        }
        report.primitives += 1;
    }
    Ok(())
}
