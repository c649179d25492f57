//! Runtime baking of `Mesh`es (feature `bake`): requests, the async bakes, the cache.

use super::{SdfBakeFailed, SdfBaked, SdfVolumeAsset};
use crate::system_times::timed;
use bevy::{
    mesh::{Indices, PrimitiveTopology, VertexAttributeValues},
    platform::collections::{HashMap, HashSet},
    prelude::*,
    tasks::{AsyncComputeTaskPool, Task, futures::check_ready},
};
use penumbra_sdf::{
    BakeSettings, SdfVolume, TriMesh, format,
    mesh::{Topology, triangles_from},
};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};

/// Registers the bake types, the cache and its systems.
pub(super) fn build(app: &mut App) {
    app.register_type::<SdfBakeRequest>()
        .register_type::<SdfBakeTask>()
        .register_type::<SdfBakeWaiting>()
        .register_type::<SdfBakeCache>()
        .register_type::<SdfBakeStats>()
        .init_resource::<SdfBakeCache>()
        .init_resource::<SdfBakeStats>()
        .add_systems(
            Update,
            (timed(start_sdf_bakes), timed(finish_sdf_bakes)).chain(),
        );
}

/// Asks for the mesh's distance field to be baked (or fetched from the cache).
#[derive(Component, Reflect, Clone, Debug)]
#[reflect(Component, Clone)]
pub struct SdfBakeRequest {
    /// The mesh to bake (waits until it is loaded).
    pub mesh: Handle<Mesh>,
    /// Bake settings (grid policy, sign method). Not reflected: a type of the Bevy-free
    /// `penumbra_sdf` crate (reflection sees the default).
    #[reflect(ignore, clone)]
    pub settings: BakeSettings,
    /// The mesh is baked with its positions multiplied by this, per axis
    /// (`Vec3::ONE`: as it is). A scene caster's is its
    /// [`CasterStretch`](crate::CasterStretch).
    pub stretch: Vec3,
}

/// The entity's request is being baked (the bake itself runs in [`SdfBakeCache`]).
#[derive(Component, Reflect, Debug)]
#[reflect(Component)]
pub struct SdfBakeTask {
    #[reflect(ignore)]
    progress: Arc<AtomicU32>,
    key: u64,
}

impl SdfBakeTask {
    /// Fraction done, in [0, 1].
    pub fn progress(&self) -> f32 {
        f32::from_bits(self.progress.load(Ordering::Relaxed))
    }
}

/// Waiting for an identical bake (same mesh content and settings) already running for
/// another entity; answered from memory when it lands.
#[derive(Component, Reflect, Clone, Copy, Debug)]
#[reflect(Component, Clone)]
pub struct SdfBakeWaiting(u64);

/// Where and what has been baked.
#[derive(Resource, Reflect, Debug)]
#[reflect(Resource)]
pub struct SdfBakeCache {
    /// Directory of cached `.psdf` files, or `None` to bake every run (memory only).
    pub directory: Option<PathBuf>,
    memory: HashMap<u64, Handle<SdfVolumeAsset>>,
    /// Bakes running now, by key (so duplicates wait instead of baking again). Kept
    /// here, not on an entity: a despawned requester does not cancel a shared bake.
    #[reflect(ignore)]
    in_flight: HashMap<u64, Task<BakeResult>>,
}

/// A finished bake: the volume and whether it came from the disk cache, or the reason.
type BakeResult = Result<(SdfVolume, bool), String>;

impl Default for SdfBakeCache {
    fn default() -> Self {
        let base = std::env::var_os("XDG_CACHE_HOME")
            .map(PathBuf::from)
            .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")));
        Self::with_directory(base.map(|b| b.join("penumbra/sdf")))
    }
}

impl SdfBakeCache {
    /// A cache using `directory` for `.psdf` files (`None`: memory only).
    pub fn with_directory(directory: Option<PathBuf>) -> Self {
        Self {
            directory,
            memory: HashMap::default(),
            in_flight: HashMap::default(),
        }
    }

    fn path(&self, key: u64) -> Option<PathBuf> {
        self.directory
            .as_ref()
            .map(|d| d.join(format!("{key:016x}.psdf")))
    }
}

/// Counts of what the bake systems did.
#[derive(Resource, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Resource, Clone, Default)]
pub struct SdfBakeStats {
    /// Bakes actually computed.
    pub baked: u32,
    /// Results read from the disk cache.
    pub disk_hits: u32,
    /// Requests answered by an asset already baked or loaded this run.
    pub memory_hits: u32,
    /// Requests that failed.
    pub failed: u32,
}

/// Converts a Bevy mesh to baking input: `Float32x3` positions, triangle list or strip.
pub fn mesh_to_tri_mesh(mesh: &Mesh) -> Result<TriMesh, String> {
    let positions = match mesh.try_attribute(Mesh::ATTRIBUTE_POSITION) {
        Ok(VertexAttributeValues::Float32x3(p)) => {
            p.iter().map(|&v| Vec3::from_array(v)).collect::<Vec<_>>()
        }
        Ok(other) => {
            return Err(format!(
                "positions are {:?}, not Float32x3",
                bevy::mesh::VertexFormat::from(other)
            ));
        }
        Err(e) => {
            return Err(format!(
                "positions not readable in the main world ({e:?}); keep RenderAssetUsages::MAIN_WORLD for SDF casters"
            ));
        }
    };
    let indices: Vec<u32> = match mesh.try_indices_option() {
        Ok(Some(Indices::U16(i))) => i.iter().map(|&x| x as u32).collect(),
        Ok(Some(Indices::U32(i))) => i.clone(),
        Ok(None) => (0..positions.len() as u32).collect(),
        Err(e) => return Err(format!("indices not readable ({e:?})")),
    };
    let topology = match mesh.primitive_topology() {
        PrimitiveTopology::TriangleList => Topology::List,
        PrimitiveTopology::TriangleStrip => Topology::Strip,
        other => return Err(format!("{other:?} meshes have no surface to bake")),
    };
    let triangles = triangles_from(&indices, topology);
    Ok(TriMesh {
        positions,
        triangles,
        ..Default::default()
    })
}

/// FNV-1a 64: a stable content hash (the same across runs and Rust versions).
fn fnv1a(mut hash: u64, bytes: &[u8]) -> u64 {
    for &b in bytes {
        hash ^= b as u64;
        hash = hash.wrapping_mul(0x0100_0000_01b3);
    }
    hash
}

/// The cache key of a bake: mesh content, settings, baker and file-format versions.
fn bake_key(mesh: &TriMesh, settings: &BakeSettings) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325;
    for p in &mesh.positions {
        for c in p.to_array() {
            h = fnv1a(h, &c.to_bits().to_le_bytes());
        }
    }
    for t in &mesh.triangles {
        for i in t {
            h = fnv1a(h, &i.to_le_bytes());
        }
    }
    h = fnv1a(h, format!("{settings:?}").as_bytes());
    h = fnv1a(h, &penumbra_sdf::BAKER_VERSION.to_le_bytes());
    fnv1a(h, &format::VERSION.to_le_bytes())
}

/// Requests not yet started, waiting, finished or failed.
type PendingRequest = (
    Without<SdfBakeTask>,
    Without<SdfBakeWaiting>,
    Without<SdfBaked>,
    Without<SdfBakeFailed>,
);

/// Every state a request can be in once handled.
type BakeState = (SdfBakeTask, SdfBakeWaiting, SdfBaked, SdfBakeFailed);

/// Starts (or answers from the caches) the requests that are new, changed, or whose
/// mesh asset was modified; others keep their state. Each request is converted and
/// hashed once per change, not per frame.
#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
fn start_sdf_bakes(
    mut commands: Commands,
    pending: Query<(Entity, &SdfBakeRequest), PendingRequest>,
    changed: Query<(Entity, &SdfBakeRequest), Changed<SdfBakeRequest>>,
    all: Query<(Entity, &SdfBakeRequest)>,
    mut mesh_events: MessageReader<AssetEvent<Mesh>>,
    meshes: Res<Assets<Mesh>>,
    mut cache: ResMut<SdfBakeCache>,
    mut stats: ResMut<SdfBakeStats>,
) {
    // Requests to (re)start: changed ones and those of modified meshes drop their old
    // outcome first.
    let modified: HashSet<AssetId<Mesh>> = mesh_events
        .read()
        .filter_map(|e| match e {
            AssetEvent::Modified { id } => Some(*id),
            _ => None,
        })
        .collect();
    let mut restart: Vec<Entity> = changed.iter().map(|(e, _)| e).collect();
    if !modified.is_empty() {
        restart.extend(
            all.iter()
                .filter(|(_, r)| modified.contains(&r.mesh.id()))
                .map(|(e, _)| e),
        );
    }
    for &entity in &restart {
        commands.entity(entity).remove::<BakeState>();
    }
    let mut todo: Vec<(Entity, &SdfBakeRequest)> = pending.iter().collect();
    todo.extend(restart.iter().filter_map(|&e| all.get(e).ok()));
    todo.sort_unstable_by_key(|(e, _)| *e);
    todo.dedup_by_key(|(e, _)| *e);
    for (entity, request) in todo {
        let Some(mesh) = meshes.get(&request.mesh) else {
            continue; // not loaded yet: pending, tried again next frame
        };
        let tri_mesh = match mesh_to_tri_mesh(mesh) {
            Ok(m) => stretched(m, request.stretch),
            Err(why) => {
                warn!("SDF bake for {entity}: {why}");
                stats.failed += 1;
                commands.entity(entity).insert(SdfBakeFailed(why));
                continue;
            }
        };
        let key = bake_key(&tri_mesh, &request.settings);
        if let Some(handle) = cache.memory.get(&key) {
            stats.memory_hits += 1;
            commands.entity(entity).insert(SdfBaked(handle.clone()));
            continue;
        }
        if cache.in_flight.contains_key(&key) {
            // The same bake is running: wait for it (converted and hashed only once).
            commands.entity(entity).insert(SdfBakeWaiting(key));
            continue;
        }
        let progress = Arc::new(AtomicU32::new(0.0f32.to_bits()));
        let task = spawn_bake(
            tri_mesh,
            request.settings,
            cache.path(key),
            progress.clone(),
        );
        cache.in_flight.insert(key, task);
        commands
            .entity(entity)
            .insert(SdfBakeTask { progress, key });
    }
}

/// `mesh` with its positions multiplied by `stretch` (unchanged for `Vec3::ONE` or a
/// stretch that is not finite and positive).
fn stretched(mut mesh: TriMesh, stretch: Vec3) -> TriMesh {
    if stretch != Vec3::ONE && stretch.is_finite() && stretch.min_element() > 0.0 {
        for p in &mut mesh.positions {
            *p *= stretch;
        }
    }
    mesh
}

/// A bake (or a disk-cache read) on the async pool; `progress` goes from 0 to 1.
fn spawn_bake(
    tri_mesh: TriMesh,
    settings: BakeSettings,
    path: Option<PathBuf>,
    progress: Arc<AtomicU32>,
) -> Task<BakeResult> {
    AsyncComputeTaskPool::get().spawn(async move {
        if let Some(volume) = path
            .as_ref()
            .and_then(|p| std::fs::read(p).ok())
            .and_then(|bytes| format::from_bytes(&bytes).ok())
        {
            progress.store(1.0f32.to_bits(), Ordering::Relaxed);
            return Ok((volume, true));
        }
        let report = |f: f32| progress.store(f.min(1.0).to_bits(), Ordering::Relaxed);
        let baked =
            penumbra_sdf::bake(&tri_mesh, &settings, Some(&report)).map_err(|e| e.to_string())?;
        progress.store(1.0f32.to_bits(), Ordering::Relaxed);
        if let Some(path) = path {
            let write = path
                .parent()
                .map_or(Ok(()), std::fs::create_dir_all)
                .and_then(|()| std::fs::write(&path, format::to_bytes(&baked.volume)));
            if let Err(e) = write {
                warn!("SDF cache: could not write {}: {e}", path.display());
            }
        }
        Ok((baked.volume, false))
    })
}

/// Hands finished bakes to every entity still waiting for them (the one that started
/// it, if it still exists and still wants it, and the identical requests).
fn finish_sdf_bakes(
    mut commands: Commands,
    tasks: Query<(Entity, &SdfBakeTask)>,
    waiting: Query<(Entity, &SdfBakeWaiting)>,
    mut assets: ResMut<Assets<SdfVolumeAsset>>,
    mut cache: ResMut<SdfBakeCache>,
    mut stats: ResMut<SdfBakeStats>,
) {
    let mut finished = Vec::new();
    for (&key, task) in cache.in_flight.iter_mut() {
        if let Some(result) = check_ready(task) {
            finished.push((key, result));
        }
    }
    finished.sort_unstable_by_key(|(key, _)| *key);
    for (key, result) in finished {
        cache.in_flight.remove(&key);
        let starters: Vec<Entity> = tasks
            .iter()
            .filter(|(_, t)| t.key == key)
            .map(|(e, _)| e)
            .collect();
        let waiters: Vec<Entity> = waiting
            .iter()
            .filter(|(_, w)| w.0 == key)
            .map(|(e, _)| e)
            .collect();
        match result {
            Ok((volume, from_disk)) => {
                if from_disk {
                    stats.disk_hits += 1;
                } else {
                    stats.baked += 1;
                }
                stats.memory_hits += waiters.len() as u32;
                let handle = assets.add(SdfVolumeAsset { volume });
                cache.memory.insert(key, handle.clone());
                for e in starters.into_iter().chain(waiters) {
                    commands
                        .entity(e)
                        .remove::<(SdfBakeTask, SdfBakeWaiting)>()
                        .insert(SdfBaked(handle.clone()));
                }
            }
            Err(why) => {
                let requests = starters.len() + waiters.len();
                warn!("SDF bake failed for {requests} request(s): {why}");
                stats.failed += requests as u32;
                for e in starters.into_iter().chain(waiters) {
                    commands
                        .entity(e)
                        .remove::<(SdfBakeTask, SdfBakeWaiting)>()
                        .insert(SdfBakeFailed(why.clone()));
                }
            }
        }
    }
}
