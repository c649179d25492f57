//! Baking: exact closest-point distance per sample (BVH), sign from the chosen method.
//!
//! Each sample is computed independently of the others and of the thread that computes
//! it (the previous sample in the row only seeds the search bound, never the result), so
//! the output is bit-identical for any thread count.

use crate::bvh::Bvh;
use crate::grid::{GridError, GridPolicy, GridSpec};
use crate::mesh::{MeshError, MeshReport, TriMesh};
use crate::volume::SdfVolume;
use glam::Vec3;
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
}

impl SignMethod {
    /// `TwoSided` with the default shell (√3/2 voxel).
    pub const TWO_SIDED: SignMethod = SignMethod::TwoSided {
        shell_voxels: 0.866_025_4,
    };

    /// `BackfaceRatio` with Unreal's threshold of one half.
    pub const BACKFACE_RATIO: SignMethod = SignMethod::BackfaceRatio { threshold: 0.5 };
}

/// Bake settings.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BakeSettings {
    /// Where samples go.
    pub grid: GridPolicy,
    /// Inside/outside decision.
    pub sign: SignMethod,
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
    /// The grid used.
    pub grid: GridSpec,
    /// Samples made negative by the thin-feature guard (see [`bake`]).
    pub thin_feature_samples: usize,
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
        _ => {}
    }
    let (tris, report) = mesh.validate()?;
    // Work relative to the bounds' centre: keeps f32 precision for meshes far from
    // their origin.
    let mut bounds = crate::geometry::Aabb::EMPTY;
    tris.iter().flatten().for_each(|&p| bounds.grow(p));
    let grid = settings.grid.resolve(&bounds)?;
    let center = bounds.center();
    let local: Vec<[Vec3; 3]> = tris.iter().map(|t| t.map(|p| p - center)).collect();
    let bvh = Bvh::build(&local);

    let dims = grid.dims;
    let slice = (dims.x * dims.y) as usize;
    let mut data = vec![f16::ZERO; slice * dims.z as usize];
    let done = AtomicUsize::new(0);
    let origin = grid.origin - center;
    let h = grid.voxel_size;
    let directions = match settings.sign {
        SignMethod::BackfaceRatio { .. } => fibonacci_directions(64),
        _ => Vec::new(),
    };
    data.par_chunks_mut(slice).enumerate().for_each(|(k, out)| {
        for j in 0..dims.y {
            let mut hint = None;
            let mut bound = f32::INFINITY;
            for i in 0..dims.x {
                let p = origin + h * Vec3::new(i as f32, j as f32, k as f32);
                let hit = bvh
                    .closest(p, bound, hint)
                    .or_else(|| bvh.closest(p, f32::INFINITY, None))
                    .expect("a validated mesh has triangles");
                let d = hit.distance_squared.sqrt();
                hint = Some(hit.triangle);
                // The next sample is at most one voxel farther from this closest point.
                bound = (d + h) * (d + h) * (1.0 + 1e-5) + 1e-12;
                let on_border = [i, j, k as u32]
                    .iter()
                    .zip(dims.to_array())
                    .any(|(&c, n)| c < grid.border || c + grid.border >= n);
                let signed = match settings.sign {
                    _ if on_border => d,
                    SignMethod::TwoSided { shell_voxels } => d - shell_voxels * h,
                    SignMethod::WindingNumber => {
                        if bvh.winding_number(p) > 0.5 {
                            -d
                        } else {
                            d
                        }
                    }
                    SignMethod::RayParity => {
                        let odd = PARITY_DIRECTIONS
                            .iter()
                            .filter(|dir| bvh.ray_crossings(p, dir.normalize(), 0.0) % 2 == 1)
                            .count();
                        if odd >= 2 { -d } else { d }
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
                        if hits > 0 && back as f32 > threshold * hits as f32 {
                            -d
                        } else {
                            d
                        }
                    }
                };
                out[(i + dims.x * j) as usize] = f16::from_f32(signed);
            }
        }
        let n = done.fetch_add(1, Ordering::Relaxed) + 1;
        if let Some(report_progress) = progress {
            report_progress(n as f32 / dims.z as f32);
        }
    });
    let mut volume = SdfVolume {
        dims,
        origin: grid.origin,
        voxel_size: h,
        data,
    };
    let thin_feature_samples = keep_thin_features(&mut volume, &local, origin, grid.border);
    Ok(Bake {
        volume,
        mesh: report,
        grid,
        thin_feature_samples,
    })
}

/// The thin-feature guard (see [`bake`]). `tris` and `origin` are in the same (local)
/// frame. Sequential, in triangle order: deterministic.
fn keep_thin_features(
    volume: &mut SdfVolume,
    tris: &[[Vec3; 3]],
    origin: Vec3,
    border: u32,
) -> usize {
    let h = volume.voxel_size;
    let dims = volume.dims;
    let mut flipped = 0;
    for t in tris {
        let longest = (t[1] - t[0])
            .length()
            .max((t[2] - t[1]).length())
            .max((t[0] - t[2]).length());
        // Lattice spacing ≤ h/2 along every edge; capped for absurdly large triangles.
        let n = ((2.0 * longest / h).ceil() as u32).clamp(1, 2048);
        for a in 0..=n {
            for b in 0..=(n - a) {
                let (u, v) = (a as f32 / n as f32, b as f32 / n as f32);
                let s = t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v;
                let g = (s - origin) / h;
                let base = g.floor();
                if base.min_element() < 0.0 {
                    continue;
                }
                let (i, j, k) = (base.x as u32, base.y as u32, base.z as u32);
                // Leave the border alone: it is outside by construction.
                if i < border || j < border || k < border {
                    continue;
                }
                if i + 1 + border >= dims.x || j + 1 + border >= dims.y || k + 1 + border >= dims.z
                {
                    continue;
                }
                let mut nearest = (f32::INFINITY, 0usize);
                let mut has_inside = false;
                for corner in 0..8u32 {
                    let (di, dj, dk) = (corner & 1, (corner >> 1) & 1, corner >> 2);
                    let index = volume.index(i + di, j + dj, k + dk);
                    if volume.data[index].to_f32() <= 0.0 {
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
                    let v = &mut volume.data[nearest.1];
                    *v = -*v;
                    flipped += 1;
                }
            }
        }
    }
    flipped
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
