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
    // The gltf crate validates structure but can still panic on inconsistent accessor
    // data; a corrupt file must be an error, never a crash.
    std::panic::catch_unwind(|| load_gltf_unguarded(bytes, base_dir, selection)).unwrap_or_else(
        |_| {
            Err(GltfError::Parse(
                "inconsistent accessor or buffer data".into(),
            ))
        },
    )
}

fn load_gltf_unguarded(
    bytes: &[u8],
    base_dir: Option<&Path>,
    selection: &GltfSelection,
) -> Result<(TriMesh, Vec<TriangleMaterial>, GltfReport), GltfError> {
    let gltf = gltf::Gltf::from_slice(bytes).map_err(|e| GltfError::Parse(e.to_string()))?;
    let mut buffers = Vec::new();
    for buffer in gltf.document.buffers() {
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf
                .blob
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
        mesh_names: gltf
            .document
            .meshes()
            .map(|m| m.name().unwrap_or("").to_string())
            .collect(),
        ..Default::default()
    };
    match selection {
        GltfSelection::Mesh(name) => {
            let mesh = gltf
                .document
                .meshes()
                .find(|m| m.name() == Some(name.as_str()))
                .ok_or_else(|| {
                    GltfError::NotFound(format!(
                        "no mesh named {name:?} (meshes: {:?})",
                        report.mesh_names
                    ))
                })?;
            append_mesh(&mesh, DMat4::IDENTITY, &buffers, &mut out, &mut report)?;
        }
        GltfSelection::Scene => {
            let scene = gltf
                .document
                .default_scene()
                .or_else(|| gltf.document.scenes().next())
                .ok_or_else(|| GltfError::NotFound("the file has no scene".into()))?;
            let mut stack: Vec<(gltf::Node, DMat4)> =
                scene.nodes().map(|n| (n, DMat4::IDENTITY)).collect();
            // Each node is reached once in a forest; a second visit means a cycle (which
            // would never end) or a shared child.
            let mut visited = vec![false; gltf.document.nodes().count()];
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
                    append_mesh(&mesh, world, &buffers, &mut out, &mut report)?;
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
    buffers: &[Vec<u8>],
    out: &mut Triangles,
    report: &mut GltfReport,
) -> Result<(), GltfError> {
    // A mirroring transform flips the winding: swap two corners to keep outside out.
    let flip = transform.determinant() < 0.0;
    for primitive in mesh.primitives() {
        let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| d.as_slice()));
        let (Some(positions), true) = (
            reader.read_positions(),
            matches!(
                primitive.mode(),
                Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
            ),
        ) else {
            report.skipped_primitives += 1;
            continue;
        };
        // Checked before reading: the reader reserves what an accessor claims.
        let claims = [
            primitive
                .get(&gltf::Semantic::Positions)
                .map(|a| ("POSITION", a)),
            primitive.indices().map(|a| ("indices", a)),
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
        let base = out.positions.len() as u32;
        out.positions
            .extend(positions.map(|p| transform.transform_point3(Vec3::from_array(p).as_dvec3())));
        let count = out.positions.len() as u32 - base;
        let indices: Vec<u32> = match reader.read_indices() {
            Some(i) => i.into_u32().collect(),
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
