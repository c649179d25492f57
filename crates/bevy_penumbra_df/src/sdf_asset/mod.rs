//! Signed distance fields as Bevy assets.
//!
//! - [`SdfVolumeAsset`] wraps a [`penumbra_sdf::SdfVolume`]; [`SdfVolumeLoader`] loads
//!   `.psdf` files (written by `penumbra-bake` or by the cache below). Truncated, corrupt
//!   or other-version files fail to load with a clear error (Bevy logs it); nothing
//!   panics.
//! - Runtime baking: put an [`SdfBakeRequest`] (a `Handle<Mesh>` and
//!   [`BakeSettings`](penumbra_sdf::BakeSettings)) on an entity. Once the mesh is loaded, the bake runs on Bevy's
//!   `AsyncComputeTaskPool`; meanwhile the entity carries an [`SdfBakeTask`] whose
//!   [`SdfBakeTask::progress`] goes from 0 to 1. When done the entity gets
//!   [`SdfBaked`] (the asset handle) or, on bad input, [`SdfBakeFailed`] with the reason.
//!   Requests identical to a bake already running wait for it ([`SdfBakeWaiting`]).
//! - Bakes belong to the cache, not to the entity that started them: despawning it does
//!   not strand the requests waiting on the same bake, and the result is cached anyway.
//!   Changing an entity's request (or modifying its mesh asset) starts over: the
//!   outcome of the old request — baked, failed or in flight — is dropped, so a caster
//!   never gets a stale SDF and a failed one retries with its new mesh.
//! - Caching ([`SdfBakeCache`]): bakes are keyed by mesh content (positions, indices) and
//!   settings. The same key is never baked twice in a run (instances share one asset),
//!   and with a cache directory (the default: `$XDG_CACHE_HOME/penumbra/sdf`, else
//!   `~/.cache/penumbra/sdf`) not across runs either. [`SdfBakeStats`] counts bakes and
//!   hits.
//!
//! Meshes must be triangle lists or strips with `Float32x3` positions still readable in
//! the main world (`RenderAssetUsages::MAIN_WORLD`); others fail with a reason.

#[cfg(feature = "bake")]
mod bake;

#[cfg(feature = "bake")]
pub use bake::{
    SdfBakeCache, SdfBakeRequest, SdfBakeStats, SdfBakeTask, SdfBakeWaiting, mesh_to_tri_mesh,
};

use bevy::{
    asset::{AssetLoader, LoadContext, io::Reader},
    prelude::*,
};
use penumbra_sdf::format;

/// Registers [`SdfVolumeAsset`], its loader, and (feature `bake`) the runtime baking
/// systems.
#[derive(Default)]
pub struct SdfAssetPlugin;

impl Plugin for SdfAssetPlugin {
    fn build(&self, app: &mut App) {
        crate::require_plugin::<AssetPlugin>(
            app,
            "SdfAssetPlugin",
            "AssetPlugin (in DefaultPlugins)",
        );
        app.init_asset::<SdfVolumeAsset>()
            .register_asset_reflect::<SdfVolumeAsset>()
            .register_type::<SdfBaked>()
            .register_type::<SdfBakeFailed>()
            .init_asset_loader::<SdfVolumeLoader>();
        #[cfg(feature = "bake")]
        bake::build(app);
    }
}

/// A signed distance field asset (see [`penumbra_sdf::SdfVolume`] for its layout and
/// conventions: mesh-local units, negative inside).
#[derive(Asset, Reflect, Clone, Debug, PartialEq)]
#[reflect(opaque, Clone, Debug, PartialEq)]
pub struct SdfVolumeAsset {
    /// The distance field.
    pub volume: penumbra_sdf::SdfVolume,
}

/// Loads `.psdf` files.
#[derive(Default, TypePath)]
pub struct SdfVolumeLoader;

/// Why a `.psdf` file failed to load.
#[derive(Debug)]
pub enum SdfLoadError {
    /// Reading failed.
    Io(std::io::Error),
    /// The file is not a valid `.psdf` of this version.
    Format(format::FormatError),
}

impl std::fmt::Display for SdfLoadError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SdfLoadError::Io(e) => write!(f, "reading SDF file: {e}"),
            SdfLoadError::Format(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for SdfLoadError {}

impl AssetLoader for SdfVolumeLoader {
    type Asset = SdfVolumeAsset;
    type Settings = ();
    type Error = SdfLoadError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        _settings: &(),
        _load_context: &mut LoadContext<'_>,
    ) -> Result<Self::Asset, Self::Error> {
        let mut bytes = Vec::new();
        reader
            .read_to_end(&mut bytes)
            .await
            .map_err(SdfLoadError::Io)?;
        let volume = format::from_bytes(&bytes).map_err(SdfLoadError::Format)?;
        Ok(SdfVolumeAsset { volume })
    }

    fn extensions(&self) -> &[&str] {
        &["psdf"]
    }
}
/// The finished distance field of an entity's `SdfBakeRequest` (feature `bake`), or one
/// the app provides itself.
#[derive(Component, Reflect, Clone, Debug)]
#[reflect(Component, Clone)]
pub struct SdfBaked(pub Handle<SdfVolumeAsset>);

/// The bake could not be done; the reason, also logged once as a warning.
#[derive(Component, Reflect, Clone, Debug)]
#[reflect(Component, Clone)]
pub struct SdfBakeFailed(pub String);
