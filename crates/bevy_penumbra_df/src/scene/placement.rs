//! Placing a caster's volume in the atlas, dense or as sparse bricks, shared by every
//! caster that uses it, and letting it go with its last user.

use super::{AtlasUpload, DistanceFieldScene, DistanceFieldSceneSettings, PlacedVolume, bricks};
use crate::sdf_asset::SdfVolumeAsset;
use bevy::prelude::*;
use penumbra_df_core::atlas::{AtlasAllocator, AtlasError, AtlasRegion};

/// Lets `entity` go of its volume; its last user frees its atlas region (and bricks).
pub(super) fn release_volume(scene: &mut DistanceFieldScene, entity: Entity) {
    let Some(id) = scene.caster_volume.remove(&entity) else {
        return;
    };
    let Some(placed) = scene.volumes.get_mut(&id) else {
        return;
    };
    placed.users -= 1;
    if placed.users == 0 {
        let region = placed.region;
        let bricks = placed.table.clone();
        scene.volumes.remove(&id);
        if let Some((range, coarse)) = bricks {
            scene.brick_table.free(range);
            scene.bricked -= 1;
            if let Some(atlas) = scene.atlas.as_mut() {
                atlas.free(&coarse);
            }
        }
        if let Some(atlas) = scene.atlas.as_mut() {
            atlas.free(&region);
            scene.atlas_freed = true;
        }
    }
}

/// Places `id` in the atlas (or finds it there) and counts a user.
pub(super) fn place_volume(
    scene: &mut DistanceFieldScene,
    settings: &DistanceFieldSceneSettings,
    id: AssetId<SdfVolumeAsset>,
    asset: &SdfVolumeAsset,
) -> Option<PlacedVolume> {
    if let Some(placed) = scene.volumes.get_mut(&id) {
        placed.users += 1;
        return Some(placed.clone());
    }
    if scene.unplaceable.contains(&id) || scene.atlas_failed {
        return None;
    }
    if scene.atlas.is_none() {
        match AtlasAllocator::for_budget(settings.atlas_budget_bytes, scene.max_texture_3d) {
            Ok(a) => scene.atlas = Some(a),
            Err(e) => {
                warn!("Penumbra: distance-field atlas: {e}; SDF casters are skipped");
                scene.atlas_failed = true;
                return None;
            }
        }
    }
    let sparse = bricks::Placement::Sparse {
        min_bytes: settings.sparse_min_bytes,
    };
    if let Some(placed) = place_as_bricks(scene, id, &asset.volume, sparse) {
        return Some(placed);
    }
    let mut volume = std::borrow::Cow::Borrowed(&asset.volume);
    let mut halvings = 0;
    let region = loop {
        let atlas = scene.atlas.as_mut().expect("created above");
        match atlas.allocate(volume.dims) {
            Ok(region) => break region,
            Err(e @ (AtlasError::Full { .. } | AtlasError::TooLarge { .. })) if halvings < 2 => {
                // No free box for the dense grid: its bricks may fit between the other
                // volumes at full resolution (unless every volume is to stay dense).
                if halvings == 0
                    && settings.sparse_min_bytes != u64::MAX
                    && let Some(placed) =
                        place_as_bricks(scene, id, &asset.volume, bricks::Placement::Fallback)
                {
                    return Some(placed);
                }
                if !scene.warned_full {
                    warn!(
                        "Penumbra: distance-field {e} (budget {} bytes, see \
                         DistanceFieldSceneSettings::atlas_budget_bytes): volumes that do not fit \
                         are placed as sparse bricks, else at half, then quarter resolution, \
                         else their casters are skipped; counts in DistanceFieldUploadStats. \
                         Reported once.",
                        settings.atlas_budget_bytes
                    );
                    scene.warned_full = true;
                }
                volume = std::borrow::Cow::Owned(volume.downsampled());
                halvings += 1;
            }
            Err(e) => {
                if !scene.warned_full {
                    warn!("Penumbra: distance-field {e}; its casters are skipped. Reported once.");
                    scene.warned_full = true;
                }
                scene.unplaceable.insert(id);
                return None;
            }
        }
    };
    if halvings > 0 {
        scene.downsampled += 1;
    }
    scene.uploads.push(AtlasUpload {
        region,
        data: volume.data.iter().map(|h| h.to_bits()).collect(),
    });
    Some(insert_placed(scene, id, &volume, region, region.dims, None))
}

/// Records `volume` (asset `id`) as placed at `region` (its pool when bricked, with its
/// `table` range and coarse grid) with one user.
pub(super) fn insert_placed(
    scene: &mut DistanceFieldScene,
    id: AssetId<SdfVolumeAsset>,
    volume: &penumbra_sdf::SdfVolume,
    region: AtlasRegion,
    dims: UVec3,
    table: Option<(std::ops::Range<u32>, AtlasRegion)>,
) -> PlacedVolume {
    let placed = PlacedVolume {
        region,
        dims,
        table,
        local_origin: volume.origin.as_vec3(),
        margin: volume.margin,
        voxel_size: volume.voxel_size,
        users: 1,
    };
    scene.volumes.insert(id, placed.clone());
    placed
}

/// Places `volume` (asset `id`) as sparse bricks when `placement` allows and it fits
/// (`bricks::place_bricked`), queuing its uploads.
pub(super) fn place_as_bricks(
    scene: &mut DistanceFieldScene,
    id: AssetId<SdfVolumeAsset>,
    volume: &penumbra_sdf::SdfVolume,
    placement: bricks::Placement,
) -> Option<PlacedVolume> {
    let atlas = scene.atlas.as_mut()?;
    let b = bricks::place_bricked(volume, placement, atlas, &mut scene.brick_table)?;
    scene.uploads.push(AtlasUpload {
        region: b.pool,
        data: b.pool_texels,
    });
    scene.uploads.push(AtlasUpload {
        region: b.coarse,
        data: b.coarse_texels,
    });
    scene.bricked += 1;
    let table = Some((b.table, b.coarse));
    Some(insert_placed(scene, id, volume, b.pool, volume.dims, table))
}
