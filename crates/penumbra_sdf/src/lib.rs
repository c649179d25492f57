//! # `penumbra_sdf`
//!
//! Signed distance fields baked from triangle meshes, with no Bevy dependency.
//!
//! - **Exact distances**: the closest point on the nearest triangle, found with a BVH
//!   ([`bvh`]); stored as f16 ([`SdfVolume`]), so the only error is f16 rounding.
//! - **Robust sign** ([`SignMethod`]): the generalized winding number (Jacobson et al.
//!   2013) evaluated with Barill et al.'s fast approximation (SIGGRAPH 2018) by default —
//!   correct on open meshes, soups and intersecting shells, where Unreal's back-face ratio
//!   flips signs near sharp edges. The back-face ratio, ray parity and a two-sided shell
//!   are available for comparison and for foliage; ground ([`ground`]: an open sheet
//!   facing up, solid below it) for terrain and floors.
//! - **Grid policy** ([`GridPolicy`]): padded bounds, cubic voxels, resolution by samples
//!   along the longest axis or per unit with clamps, and a memory guard.
//! - **Ground truth** ([`exact`]): f64 brute force, the reference for tests and benches.
//!
//! Conventions: distances are in the mesh's own units, negative inside; triangles are
//! counter-clockwise seen from outside (glTF, Bevy). See `volume` for the sample layout.

#[cfg(feature = "bake")]
pub mod bake;
pub mod bricks;
#[cfg(feature = "bake")]
pub mod bvh;
pub mod exact;
pub mod format;
pub mod geometry;
#[cfg(feature = "bake")]
pub mod gltf_input;
pub mod grid;
pub mod ground;
pub mod mesh;
#[cfg(feature = "bake")]
pub mod obj;
pub mod openness;
pub mod shapes;
#[cfg(feature = "bake")]
pub mod thickness;
pub mod volume;

/// Version of the baking algorithm: bumped whenever [`bake()`] can produce different
/// output for the same input and settings, so caches keyed on it (as
/// `bevy_penumbra_df`'s is) never serve a stale bake.
pub const BAKER_VERSION: u32 = 4;

#[cfg(feature = "bake")]
pub use bake::{Bake, BakeError, BakeSettings, BakeTimings, SignMethod, bake};
pub use grid::{GridPolicy, GridSpec, Resolution};
pub use mesh::{MeshError, TriMesh};
pub use volume::SdfVolume;

/// Why a mesh file could not be loaded.
#[cfg(feature = "bake")]
#[derive(Debug)]
pub enum LoadError {
    /// Reading the file failed.
    Io(std::io::Error),
    /// Malformed OBJ.
    Obj(obj::ObjError),
    /// Malformed or unusable glTF.
    Gltf(gltf_input::GltfError),
    /// Not `.obj`, `.gltf` or `.glb`.
    UnknownFormat(String),
    /// `--mesh NAME` given for a format without named meshes.
    NamedMeshUnsupported,
}

#[cfg(feature = "bake")]
impl std::fmt::Display for LoadError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LoadError::Io(e) => write!(f, "{e}"),
            LoadError::Obj(e) => write!(f, "{e}"),
            LoadError::Gltf(e) => write!(f, "{e}"),
            LoadError::UnknownFormat(ext) => {
                write!(
                    f,
                    "unknown mesh format {ext:?} (expected .obj, .gltf or .glb)"
                )
            }
            LoadError::NamedMeshUnsupported => {
                write!(f, "selecting a mesh by name needs a glTF file")
            }
        }
    }
}

#[cfg(feature = "bake")]
impl std::error::Error for LoadError {}

/// Loads a mesh file by extension: `.obj` (whole file), `.gltf` / `.glb` (the default
/// scene with node transforms, or the mesh named `mesh`). Returns the mesh and notes
/// worth showing a user (skipped primitives, skinned meshes read in bind pose).
#[cfg(feature = "bake")]
pub fn load_mesh_file(
    path: &std::path::Path,
    mesh: Option<&str>,
) -> Result<(TriMesh, Vec<String>), LoadError> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "obj" => {
            if mesh.is_some() {
                return Err(LoadError::NamedMeshUnsupported);
            }
            let text = std::fs::read_to_string(path).map_err(LoadError::Io)?;
            obj::parse_obj(&text)
                .map(|m| (m, Vec::new()))
                .map_err(LoadError::Obj)
        }
        "gltf" | "glb" => {
            let bytes = std::fs::read(path).map_err(LoadError::Io)?;
            let selection = mesh.map_or(gltf_input::GltfSelection::Scene, |m| {
                gltf_input::GltfSelection::Mesh(m.to_string())
            });
            let (m, report) = gltf_input::load_gltf(&bytes, path.parent(), &selection)
                .map_err(LoadError::Gltf)?;
            let mut notes = Vec::new();
            if report.skipped_primitives > 0 {
                notes.push(format!(
                    "{} point/line primitives skipped",
                    report.skipped_primitives
                ));
            }
            if report.skinned_instances > 0 {
                notes.push(format!(
                    "{} skinned mesh instances read in their bind pose",
                    report.skinned_instances
                ));
            }
            Ok((m, notes))
        }
        other => Err(LoadError::UnknownFormat(other.to_string())),
    }
}
