//! Baking: exact closest-point distance per sample (BVH), sign from the chosen method.
//!
//! Each sample is computed independently of the others and of the thread that computes
//! it (the previous sample in the row only seeds the search bound, never the result), so
//! the output is bit-identical for any thread count.

use crate::bvh::Bvh;
use crate::grid::{GridError, GridPolicy, GridSpec};
use crate::mesh::{MeshError, MeshReport, TriMesh};
use crate::volume::SdfVolume;
use glam::{UVec3, Vec3};
use half::f16;
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// How the baker decides inside from outside.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum SignMethod {
    /// Inside where the generalized winding number exceeds ½ (fast winding number,
    /// Barill et al. 2018). Robust on open meshes, soups and intersecting shells. Default.
    #[default]
    WindingNumber,
    /// Unreal's heuristic: cast rays in many directions; inside when more than
    /// `threshold` of the rays that hit anything hit a back face first. Flips signs near
    /// sharp edges and holes; kept for comparison.
    BackfaceRatio {
        /// Fraction of back-face hits above which a sample is inside (Unreal: 0.5).
        threshold: f32,
    },
    /// Inside when most of three axis-skewed rays cross the surface an odd number of
    /// times. Exact for closed, non-intersecting meshes; wrong near holes.
    RayParity,
    /// Unsigned distance minus `shell_voxels` voxels: every surface becomes a shell of
    /// that half-thickness, so thin and open surfaces (foliage) always get a negative
    /// sample. The default, √3/2 ≈ 0.87 voxel, guarantees one: every point of space is
    /// within half a voxel diagonal of a sample.
    TwoSided {
        /// Shell half-thickness in voxels.
        shell_voxels: f32,
    },
    /// Ground (`crate::ground`): an open sheet facing `up` (mesh space; any length) is
    /// the top of a solid — inside below it, where most of three rays along `up` cross
    /// the surface an odd number of times. The sample box reaches
    /// [`GROUND_DEPTH_VOXELS`](crate::ground::GROUND_DEPTH_VOXELS) below the mesh.
    /// Terrain and floors: no shell to shadow itself.
    SolidBelow {
        /// The sheet's up, in the mesh's space.
        up: Vec3,
    },
}

impl SignMethod {
    /// `TwoSided` with the default shell (√3/2 voxel).
    pub const TWO_SIDED: SignMethod = SignMethod::TwoSided {
        shell_voxels: 0.866_025_4,
    };

    /// `BackfaceRatio` with Unreal's threshold of one half.
    pub const BACKFACE_RATIO: SignMethod = SignMethod::BackfaceRatio { threshold: 0.5 };
}

/// How far a field's zero level lies outside the mesh, voxels: a two-sided bake's
/// shell, 0 for a winding-number sign.
fn shell_voxels(sign: &SignMethod) -> f32 {
    match sign {
        SignMethod::TwoSided { shell_voxels } if shell_voxels.is_finite() => shell_voxels.max(0.0),
        _ => 0.0,
    }
}

/// Bake settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BakeSettings {
    /// Where samples go.
    pub grid: GridPolicy,
    /// Inside/outside decision.
    pub sign: SignMethod,
    /// Run the thin-feature guard (see [`bake`]): surfaces thinner than a voxel keep a
    /// negative sample. Default `true`; turn it off only to inspect raw signs.
    pub keep_thin_features: bool,
}

impl Default for BakeSettings {
    fn default() -> Self {
        Self {
            grid: GridPolicy::default(),
            sign: SignMethod::default(),
            keep_thin_features: true,
        }
    }
}

impl BakeSettings {
    /// `n` samples along the longest axis (2-sample border), winding-number sign.
    pub fn longest_axis(n: u32) -> Self {
        Self {
            grid: GridPolicy {
                resolution: crate::grid::Resolution::LongestAxis(n),
                border_voxels: 2,
                thin_walls: crate::grid::ThinWalls::OFF,
            },
            ..Self::default()
        }
    }
}

/// Why a bake failed.
#[derive(Clone, Debug, PartialEq)]
pub enum BakeError {
    /// The mesh is unusable.
    Mesh(MeshError),
    /// The grid is unusable (bad or too large a resolution).
    Grid(GridError),
    /// A setting is out of range.
    Settings(String),
}

impl std::fmt::Display for BakeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BakeError::Mesh(e) => write!(f, "mesh: {e}"),
            BakeError::Grid(e) => write!(f, "grid: {e}"),
            BakeError::Settings(e) => write!(f, "settings: {e}"),
        }
    }
}

impl std::error::Error for BakeError {}

impl From<MeshError> for BakeError {
    fn from(e: MeshError) -> Self {
        BakeError::Mesh(e)
    }
}

impl From<GridError> for BakeError {
    fn from(e: GridError) -> Self {
        BakeError::Grid(e)
    }
}

/// A finished bake and what it found.
#[derive(Clone, Debug)]
pub struct Bake {
    /// The distance field.
    pub volume: SdfVolume,
    /// Mesh statistics (triangles kept, degenerate dropped).
    pub mesh: MeshReport,
    /// The grid used (its `origin` relative to the mesh's `TriMesh::origin`).
    pub grid: GridSpec,
    /// Samples made negative by the thin-feature guard (see [`bake`]).
    pub thin_feature_samples: usize,
    /// The mesh's wall thickness at the thin-wall rule's quantile (mesh units), when the
    /// rule measured one ([`crate::grid::ThinWalls`]).
    pub wall_thickness: Option<f32>,
    /// How many times finer the thin-wall rule made the voxels (1: not).
    pub thin_wall_refine: f32,
    /// Wall-clock time of each phase.
    pub timings: BakeTimings,
}

/// Wall-clock time of each phase of a bake.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BakeTimings {
    /// Mesh validation and BVH construction.
    pub setup: std::time::Duration,
    /// Exact unsigned distances.
    pub distance: std::time::Duration,
    /// Inside/outside decisions.
    pub sign: std::time::Duration,
    /// The thin-feature guard.
    pub thin_features: std::time::Duration,
}

/// Bakes a signed distance field. `progress`, if given, is called with the fraction of
/// z-slices done (from worker threads, in no particular order).
///
/// **Thin features.** A surface thinner than a voxel (a sheet, a single-sided wall, a
/// plate) may have no sample inside it, and a field with no negative sample near a
/// surface makes that surface invisible to sphere tracing. After sampling, every point
/// of every triangle (on a sub-voxel lattice) is checked: if none of the 8 samples of the
/// cell holding it is ≤ 0, the cell's sample nearest to it is negated. Magnitudes stay
/// exact; only signs within √3/2 voxel of the surface change. The count is reported in
/// [`Bake::thin_feature_samples`].
pub fn bake(
    mesh: &TriMesh,
    settings: &BakeSettings,
    progress: Option<&(dyn Fn(f32) + Sync)>,
) -> Result<Bake, BakeError> {
    match settings.sign {
        SignMethod::BackfaceRatio { threshold } if !(0.0..1.0).contains(&threshold) => {
            return Err(BakeError::Settings(format!(
                "backface threshold {threshold} not in [0, 1)"
            )));
        }
        SignMethod::TwoSided { shell_voxels } if !(0.0..=16.0).contains(&shell_voxels) => {
            return Err(BakeError::Settings(format!(
                "two-sided shell {shell_voxels} voxels not in [0, 16]"
            )));
        }
        SignMethod::SolidBelow { up } if !up.is_finite() || up.length_squared() < 1e-12 => {
            return Err(BakeError::Settings(format!(
                "ground up {up} is not a finite, non-zero direction"
            )));
        }
        _ => {}
    }
    let t_start = std::time::Instant::now();
    let (tris, report) = mesh.validate()?;
    // Work relative to the bounds' centre: keeps f32 precision for meshes far from
    // their origin (`mesh.origin`, f64, carries the rest).
    let mut bounds = crate::geometry::Aabb::EMPTY;
    tris.iter().flatten().for_each(|&p| bounds.grow(p));
    let center = bounds.center();
    let mut local = tris;
    local.iter_mut().for_each(|t| *t = t.map(|p| p - center));
    let bvh = Bvh::build(&local);
    // The thin-wall rule ([`crate::grid::ThinWalls`]): solid bakes only (a shell has no
    // inside to lose, a ground sheet no walls).
    let rule = settings.grid.thin_walls;
    let wall_thickness = (rule.is_on()
        && matches!(
            settings.grid.resolution,
            crate::grid::Resolution::PerUnit { .. }
        )
        && matches!(
            settings.sign,
            SignMethod::WindingNumber | SignMethod::BackfaceRatio { .. } | SignMethod::RayParity
        ))
    .then(|| crate::thickness::wall_thickness_quantile(&local, &bvh, rule.quantile))
    .flatten();
    let (mut grid, mut thin_wall_refine) =
        settings.grid.resolve_with_walls(&bounds, wall_thickness)?;
    if let SignMethod::SolidBelow { up } = settings.sign {
        // Ground: the box reaches below the sheet (the bounds and their copy moved down).
        let down = -up.normalize() * crate::ground::GROUND_DEPTH_VOXELS * grid.voxel_size;
        let mut grown = bounds;
        grown.grow(bounds.min + down);
        grown.grow(bounds.max + down);
        (grid, thin_wall_refine) = settings.grid.resolve_with_walls(&grown, None)?;
    }

    let dims = grid.dims;
    let origin = grid.origin - center;
    let h = grid.voxel_size;
    let ground = match settings.sign {
        SignMethod::SolidBelow { up } => {
            Some(crate::ground::GroundSign::new(up, &bvh, origin, h, dims))
        }
        _ => None,
    };
    let position = |i: u32, j: u32, k: u32| origin + h * Vec3::new(i as f32, j as f32, k as f32);
    let slice = (dims.x * dims.y) as usize;
    let done = AtomicUsize::new(0);
    let report_slice = || {
        let n = done.fetch_add(1, Ordering::Relaxed) + 1;
        if let Some(report_progress) = progress {
            // Two passes over the slices: distances, then signs.
            report_progress(n as f32 / (2 * dims.z) as f32);
        }
    };

    let t_setup = t_start.elapsed();
    // Pass 1: exact unsigned distances, four samples of a row per BVH traversal. Each
    // sample searches from the closest triangles of the sample before its group and of
    // its neighbour in the previous row, bounded by their distance plus its distance to
    // them (the distance function is 1-Lipschitz).
    let mut distance = vec![0.0f32; slice * dims.z as usize];
    distance
        .par_chunks_mut(slice)
        .enumerate()
        .for_each(|(k, out)| {
            let mut above = vec![(f32::INFINITY, u32::MAX); dims.x as usize];
            for j in 0..dims.y {
                let mut left = (f32::INFINITY, u32::MAX);
                for i0 in (0..dims.x).step_by(4) {
                    // Past the row's end the last sample repeats (and is not stored).
                    let column = |q: u32| (i0 + q).min(dims.x - 1);
                    let p = std::array::from_fn(|q| position(column(q as u32), j, k as u32));
                    let bound = std::array::from_fn(|q| {
                        let up = above[column(q as u32) as usize];
                        let b = (left.0 + (q + 1) as f32 * h).min(up.0 + h);
                        b * b * (1.0 + 1e-5) + 1e-30
                    });
                    let hints =
                        std::array::from_fn(|q| [left.1, above[column(q as u32) as usize].1]);
                    let hits = bvh.closest4(p, bound, hints);
                    for (q, hit) in hits.into_iter().enumerate() {
                        let i = i0 + q as u32;
                        if i >= dims.x {
                            break;
                        }
                        let hit = hit
                            .or_else(|| bvh.closest(p[q], f32::INFINITY, &[]))
                            .expect("a validated mesh has triangles");
                        let d = hit.distance_squared.sqrt();
                        left = (d, hit.triangle);
                        above[i as usize] = left;
                        out[(i + dims.x * j) as usize] = d;
                    }
                }
            }
            report_slice();
        });

    let t_distance = t_start.elapsed();
    // Pass 2: signs.
    let levels = match settings.sign {
        SignMethod::WindingNumber => Some(WindingLevels::new(&bvh, dims, &position, &distance, h)),
        _ => None,
    };
    let directions = match settings.sign {
        SignMethod::BackfaceRatio { .. } => fibonacci_directions(64),
        _ => Vec::new(),
    };
    let parity_directions = PARITY_DIRECTIONS.map(Vec3::normalize);
    let mut data = vec![f16::ZERO; distance.len()];
    data.par_chunks_mut(slice).enumerate().for_each(|(k, out)| {
        let k = k as u32;
        for j in 0..dims.y {
            for i in 0..dims.x {
                let index = (i + dims.x * j) as usize;
                let d = distance[index + slice * k as usize];
                let p = position(i, j, k);
                let on_border = [i, j, k]
                    .iter()
                    .zip(dims.to_array())
                    .any(|(&c, n)| c < grid.border || c + grid.border >= n);
                let inside = match settings.sign {
                    _ if on_border => false,
                    SignMethod::TwoSided { shell_voxels } => {
                        out[index] = SdfVolume::quantize(d / h - shell_voxels);
                        continue;
                    }
                    SignMethod::SolidBelow { .. } => ground
                        .as_ref()
                        .expect("computed for this method")
                        .inside(&bvh, UVec3::new(i, j, k), p),
                    SignMethod::WindingNumber => {
                        let levels = levels.as_ref().expect("computed for this method");
                        levels.inside(&bvh, UVec3::new(i, j, k), p, d, h, &distance)
                    }
                    SignMethod::RayParity => {
                        let odd = parity_directions
                            .iter()
                            .filter(|&&dir| bvh.ray_crossings(p, dir, 0.0) % 2 == 1)
                            .count();
                        odd >= 2
                    }
                    SignMethod::BackfaceRatio { threshold } => {
                        let (mut hits, mut back) = (0u32, 0u32);
                        for dir in &directions {
                            if let Some((_, front, _)) =
                                bvh.ray_nearest(p, *dir, 0.0, f32::INFINITY)
                            {
                                hits += 1;
                                back += u32::from(!front);
                            }
                        }
                        hits > 0 && back as f32 > threshold * hits as f32
                    }
                };
                let voxels = d / h;
                out[index] = SdfVolume::quantize(if inside { -voxels } else { voxels });
            }
        }
        report_slice();
    });
    let t_sign = t_start.elapsed();
    let mut volume = SdfVolume {
        dims,
        origin: mesh.origin + grid.origin.as_dvec3(),
        voxel_size: h,
        data,
        // The mesh's bounds are `border` voxels inside the sample box (less f32
        // rounding of the grid's placement); a two-sided field's zero level is its shell,
        // `shell_voxels` outside the mesh. (A margin measured from the mesh alone put a
        // flat sheet's shell outside the shrunk box: every point above the box read as
        // inside it, and shadowed everything.)
        margin: (grid.border as f32 - 0.01 - shell_voxels(&settings.sign)).max(0.0),
    };
    drop(distance);
    let thin_feature_samples = if settings.keep_thin_features {
        keep_thin_features(&mut volume, &local, origin, grid.border)
    } else {
        0
    };
    let t_end = t_start.elapsed();
    Ok(Bake {
        timings: BakeTimings {
            setup: t_setup,
            distance: t_distance - t_setup,
            sign: t_sign - t_distance,
            thin_features: t_end - t_sign,
        },
        volume,
        mesh: report,
        grid,
        thin_feature_samples,
        wall_thickness,
        thin_wall_refine,
    })
}

/// The thin-feature guard (see [`bake`]). `tris` and `origin` are in the same (local)
/// frame.
///
/// Its result is defined sequentially — lattice points in triangle order, each flipping
/// the nearest sample of its cell if the cell has no sample ≤ 0 *at that moment* — and
/// computed in two phases with the same result: in parallel, every lattice point whose
/// cell has no sample ≤ 0 in the unguarded field becomes a candidate (cells with one
/// never flip); then the candidates, in triangle order, are replayed sequentially.
fn keep_thin_features(
    volume: &mut SdfVolume,
    tris: &[[Vec3; 3]],
    origin: Vec3,
    border: u32,
) -> usize {
    keep_thin_features_with(volume, tris, origin, border, true)
}

/// [`keep_thin_features`], with the triangle prefilter (`skip_settled`: skip triangles
/// whose box holds only settled cells) switchable so tests can check it changes nothing.
fn keep_thin_features_with(
    volume: &mut SdfVolume,
    tris: &[[Vec3; 3]],
    origin: Vec3,
    border: u32,
    skip_settled: bool,
) -> usize {
    let h = volume.voxel_size;
    let dims = volume.dims;
    // Lattice spacing ≤ h/2 along every edge. A pathological mesh (a dense soup of
    // huge triangles) could ask for billions of points: past a budget of 16 points per
    // sample the lattice is coarsened uniformly (documented cost bound, never a hang).
    let lattice = |t: &[Vec3; 3]| {
        let longest = (t[1] - t[0])
            .length()
            .max((t[2] - t[1]).length())
            .max((t[0] - t[2]).length());
        (2.0 * longest / h).ceil().max(1.0)
    };
    let total: f64 = tris
        .par_iter()
        .map(|t| {
            let n = lattice(t) as f64;
            (n + 1.0) * (n + 2.0) / 2.0
        })
        .sum();
    let budget = 16.0 * volume.data.len() as f64 + 1e6;
    let scale = if total > budget {
        (budget / total).sqrt()
    } else {
        1.0
    };
    let field = &*volume;
    // Cells (by corner 0) the guard can leave alone: outside the guarded range (the
    // border, the last sample of an axis) or with a sample ≤ 0 already. Most triangles
    // lie only in such cells, and skip their lattice.
    let slice = (dims.x * dims.y) as usize;
    let mut settled = vec![true; field.data.len()];
    settled
        .par_chunks_mut(slice)
        .enumerate()
        .for_each(|(k, out)| {
            let k = k as u32;
            if k < border || k + 1 + border >= dims.z {
                return;
            }
            for j in border..dims.y.saturating_sub(1 + border) {
                for i in border..dims.x.saturating_sub(1 + border) {
                    out[(i + dims.x * j) as usize] = (0..8u32).any(|c| {
                        let (di, dj, dk) = (c & 1, (c >> 1) & 1, c >> 2);
                        non_positive(field.data[field.index(i + di, j + dj, k + dk)])
                    });
                }
            }
        });
    let settled = &settled;
    // Phase 1: candidates `(cell corner 0, nearest sample)`, in triangle order.
    let candidates: Vec<(usize, usize)> = tris
        .par_iter()
        .flat_map_iter(|t| {
            let mut out = Vec::new();
            // The cells of the triangle's box, widened by 10⁻³ voxel for the lattice
            // points' rounding (10⁻⁷ of the grid's extent, at most 256 voxels), clamped
            // to the grid (NaN-free: the triangles are validated).
            let cell_of = |p: Vec3| {
                let g = ((p - origin) / h).max(Vec3::ZERO);
                [g.x as u32, g.y as u32, g.z as u32]
            };
            let pad = Vec3::splat(1e-3 * h);
            let lo = cell_of(t[0].min(t[1]).min(t[2]) - pad);
            let hi = cell_of(t[0].max(t[1]).max(t[2]) + pad);
            let (hi_x, hi_y, hi_z) = (
                hi[0].min(dims.x - 1),
                hi[1].min(dims.y - 1),
                hi[2].min(dims.z - 1),
            );
            let all_settled = (lo[2]..=hi_z).all(|k| {
                (lo[1]..=hi_y).all(|j| (lo[0]..=hi_x).all(|i| settled[field.index(i, j, k)]))
            });
            if skip_settled && all_settled {
                return out;
            }
            let n = ((lattice(t) as f64 * scale).ceil() as u32).clamp(1, 2048);
            let mut last_cell = usize::MAX;
            for a in 0..=n {
                for b in 0..=(n - a) {
                    let (u, v) = (a as f32 / n as f32, b as f32 / n as f32);
                    let s = t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v;
                    let g = (s - origin) / h;
                    // Truncation is the floor here (non-negative; and no libm `floorf`
                    // call where the target lacks SSE4.1's `roundps`).
                    let in_grid = g.min_element() >= 0.0; // false for NaN
                    if !in_grid {
                        continue;
                    }
                    let (i, j, k) = (g.x as u32, g.y as u32, g.z as u32);
                    // Leave the border alone: it is outside by construction.
                    if i < border || j < border || k < border {
                        continue;
                    }
                    if i + 1 + border >= dims.x
                        || j + 1 + border >= dims.y
                        || k + 1 + border >= dims.z
                    {
                        continue;
                    }
                    let cell = field.index(i, j, k);
                    if cell == last_cell {
                        continue; // a later point of the same triangle and cell: a no-op
                    }
                    last_cell = cell;
                    let mut nearest = (f32::INFINITY, 0usize);
                    let mut has_inside = false;
                    for corner in 0..8u32 {
                        let (di, dj, dk) = (corner & 1, (corner >> 1) & 1, corner >> 2);
                        let index = field.index(i + di, j + dj, k + dk);
                        if non_positive(field.data[index]) {
                            has_inside = true;
                            break;
                        }
                        let p = Vec3::new((i + di) as f32, (j + dj) as f32, (k + dk) as f32);
                        let d2 = (p - g).length_squared();
                        if d2 < nearest.0 {
                            nearest = (d2, index);
                        }
                    }
                    if !has_inside {
                        out.push((cell, nearest.1));
                    }
                }
            }
            out
        })
        .collect();
    // Phase 2: replay in order against the field as it changes.
    let (sx, sxy) = (1, (dims.x * dims.y) as usize);
    let dx = dims.x as usize;
    let mut flipped = 0;
    for (cell, nearest) in candidates {
        let has_inside = [0, sx, dx, dx + sx, sxy, sxy + sx, sxy + dx, sxy + dx + sx]
            .iter()
            .any(|&o| non_positive(volume.data[cell + o]));
        if !has_inside {
            let v = &mut volume.data[nearest];
            *v = -*v;
            flipped += 1;
        }
    }
    flipped
}

/// `v <= 0` for a non-NaN half, from its bits (the `half` crate converts in software
/// where the CPU lacks F16C, and this is the guard's inner loop).
#[inline]
fn non_positive(v: f16) -> bool {
    let bits = v.to_bits();
    bits >= 0x8000 || bits == 0
}

/// Winding numbers on a hierarchy of sub-grids (every 4th, then every 2nd sample along
/// each axis), used to skip exact evaluations where the answer is certain.
///
/// A sample takes its sign from the coarser level's samples bracketing it when the
/// ball of radius `d` around it (surface-free: `d` is its exact distance) contains the
/// whole bracket, so the winding number is harmonic — smooth — across it, and all
/// bracketing values agree by a margin of 0.25. Decided samples store the bracketing
/// value nearest ½, so margins never grow on the way down. This is a heuristic, not a
/// proof (a harmonic function is bounded by its values on the bracket's faces, not its
/// corners); the accuracy tests check every sample's sign against direct evaluation.
/// Only samples near the surface or near ½ are evaluated exactly.
struct WindingLevels {
    dims: UVec3,
    /// The level with spacing 2.
    fine: Level,
}

/// Winding numbers (exact or decided) on every `spacing`-th sample along each axis,
/// plus the last sample of each axis.
struct Level {
    spacing: u32,
    dims: UVec3,
    w: Vec<f32>,
}

/// How far from ½ all bracketing winding numbers must be for a sample to take their
/// side without an evaluation of its own.
const SIGN_MARGIN: f32 = 0.25;

impl Level {
    fn new(spacing: u32, sample_dims: UVec3) -> Level {
        let dims = (sample_dims - UVec3::ONE + UVec3::splat(spacing - 1)) / spacing + UVec3::ONE;
        Level {
            spacing,
            dims,
            w: vec![0.0; (dims.x * dims.y * dims.z) as usize],
        }
    }

    /// Sample index of level index `c` along an axis of `n` samples.
    fn position(&self, c: u32, n: u32) -> u32 {
        (self.spacing * c).min(n - 1)
    }

    /// The winding number's side at sample `s` (exact distance `d`) decided from this
    /// level, when safe: `Some(w)` with `w` the bracketing value nearest ½. Safe means
    /// either that `s`'s own surface-free ball contains the whole bracket, or — for
    /// samples near the surface — that `s` lies inside the surface-free ball of a
    /// bracketing sample (the winding number is smooth across that ball too; a sample
    /// across the surface never qualifies, its ball ends at the surface). `distance`:
    /// exact distances of all samples.
    fn decide(
        &self,
        s: UVec3,
        sample_dims: UVec3,
        d: f32,
        h: f32,
        distance: &[f32],
    ) -> Option<f32> {
        let mut lo = [0u32; 3];
        let mut count = [1u32; 3];
        let mut reach2 = 0u32;
        for axis in 0..3 {
            let c0 = s[axis] / self.spacing;
            let p0 = self.position(c0, sample_dims[axis]);
            lo[axis] = c0;
            if p0 != s[axis] {
                let p1 = self.position(c0 + 1, sample_dims[axis]);
                let far = (s[axis] - p0).max(p1 - s[axis]);
                reach2 += far * far;
                count[axis] = 2;
            }
        }
        if reach2 > 0 && d * d <= reach2 as f32 * h * h {
            return self.decide_near_surface(s, sample_dims, h, distance, lo, count);
        }
        let mut nearest: Option<f32> = None;
        for dz in 0..count[2] {
            for dy in 0..count[1] {
                for dx in 0..count[0] {
                    let c = UVec3::new(lo[0] + dx, lo[1] + dy, lo[2] + dz);
                    let w = self.w[(c.x + self.dims.x * (c.y + self.dims.y * c.z)) as usize];
                    if (w - 0.5).abs() <= SIGN_MARGIN {
                        return None;
                    }
                    match nearest {
                        Some(n) if (n > 0.5) != (w > 0.5) => return None,
                        Some(n) if (n - 0.5).abs() <= (w - 0.5).abs() => {}
                        _ => nearest = Some(w),
                    }
                }
            }
        }
        nearest
    }

    /// [`Level::decide`] for a sample whose own ball is too small: the side of every
    /// decisive bracketing sample whose surface-free ball contains `s`, if they agree.
    fn decide_near_surface(
        &self,
        s: UVec3,
        sample_dims: UVec3,
        h: f32,
        distance: &[f32],
        lo: [u32; 3],
        count: [u32; 3],
    ) -> Option<f32> {
        let mut nearest: Option<f32> = None;
        for dz in 0..count[2] {
            for dy in 0..count[1] {
                for dx in 0..count[0] {
                    let c = UVec3::new(lo[0] + dx, lo[1] + dy, lo[2] + dz);
                    let at = UVec3::new(
                        self.position(c.x, sample_dims.x),
                        self.position(c.y, sample_dims.y),
                        self.position(c.z, sample_dims.z),
                    );
                    let gap2 = (at.as_ivec3() - s.as_ivec3()).length_squared() as f32 * h * h;
                    let dc =
                        distance[(at.x + sample_dims.x * (at.y + sample_dims.y * at.z)) as usize];
                    if dc * dc <= gap2 * (1.0 + 1e-4) {
                        continue;
                    }
                    let w = self.w[(c.x + self.dims.x * (c.y + self.dims.y * c.z)) as usize];
                    if (w - 0.5).abs() <= SIGN_MARGIN {
                        continue;
                    }
                    match nearest {
                        Some(n) if (n > 0.5) != (w > 0.5) => return None,
                        Some(n) if (n - 0.5).abs() <= (w - 0.5).abs() => {}
                        _ => nearest = Some(w),
                    }
                }
            }
        }
        nearest
    }
}

impl WindingLevels {
    fn new(
        bvh: &Bvh,
        dims: UVec3,
        position: &(dyn Fn(u32, u32, u32) -> Vec3 + Sync),
        distance: &[f32],
        h: f32,
    ) -> WindingLevels {
        let fill = |level: &mut Level, parent: Option<&Level>| {
            let ld = level.dims;
            let slice = (ld.x * ld.y) as usize;
            let spacing = level.spacing;
            let at = |c: u32, n: u32| (spacing * c).min(n - 1);
            level
                .w
                .par_chunks_mut(slice)
                .enumerate()
                .for_each(|(ck, out)| {
                    for cj in 0..ld.y {
                        for ci in 0..ld.x {
                            let s =
                                UVec3::new(at(ci, dims.x), at(cj, dims.y), at(ck as u32, dims.z));
                            let d = distance[(s.x + dims.x * (s.y + dims.y * s.z)) as usize];
                            out[(ci + ld.x * cj) as usize] = parent
                                .and_then(|p| p.decide(s, dims, d, h, distance))
                                .unwrap_or_else(|| bvh.winding_number(position(s.x, s.y, s.z)));
                        }
                    }
                });
        };
        let mut coarse = Level::new(4, dims);
        fill(&mut coarse, None);
        let mut fine = Level::new(2, dims);
        fill(&mut fine, Some(&coarse));
        WindingLevels { dims, fine }
    }

    /// Whether sample `s` (position `p`, exact distance `d`) is inside.
    fn inside(&self, bvh: &Bvh, s: UVec3, p: Vec3, d: f32, h: f32, distance: &[f32]) -> bool {
        self.fine
            .decide(s, self.dims, d, h, distance)
            .unwrap_or_else(|| bvh.winding_number(p))
            > 0.5
    }
}

/// Skewed directions for parity rays (axis-aligned rays hit edges of axis-aligned
/// meshes exactly, double-counting crossings).
const PARITY_DIRECTIONS: [Vec3; 3] = [
    Vec3::new(1.0, 0.123_4, 0.056_7),
    Vec3::new(-0.078_9, 1.0, 0.134_5),
    Vec3::new(0.091_2, -0.065_4, 1.0),
];

/// `n` directions spread evenly over the sphere (Fibonacci lattice).
fn fibonacci_directions(n: usize) -> Vec<Vec3> {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - (2.0 * i as f32 + 1.0) / n as f32;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * i as f32;
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

#[cfg(test)]
mod tests;
