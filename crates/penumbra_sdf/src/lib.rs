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
//!   are available for comparison and for foliage.
//! - **Grid policy** ([`GridPolicy`]): padded bounds, cubic voxels, resolution by samples
//!   along the longest axis or per unit with clamps, and a memory guard.
//! - **Ground truth** ([`exact`]): f64 brute force, the reference for tests and benches.
//!
//! Conventions: distances are in the mesh's own units, negative inside; triangles are
//! counter-clockwise seen from outside (glTF, Bevy). See `volume` for the sample layout.

pub mod bake;
pub mod bvh;
pub mod exact;
pub mod format;
pub mod geometry;
pub mod grid;
pub mod mesh;
pub mod obj;
pub mod shapes;
pub mod volume;

pub use bake::{Bake, BakeError, BakeSettings, SignMethod, bake};
pub use grid::{GridPolicy, GridSpec, Resolution};
pub use mesh::{MeshError, TriMesh};
pub use volume::SdfVolume;
