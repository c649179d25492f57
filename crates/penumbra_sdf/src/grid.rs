//! Grid policy: where the samples of a bake go.
//!
//! The grid covers the mesh bounds padded by [`GridPolicy::border_voxels`] samples on
//! every side. Voxels are cubes (one `voxel_size` for all axes). The border lies outside
//! the mesh bounds, so it is outside every closed surface; the baker forces it positive
//! for open meshes too, which keeps sphere tracing from entering through the volume's
//! faces.

use crate::geometry::Aabb;
use glam::{UVec3, Vec3};

/// How many samples a bake takes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Resolution {
    /// `n` samples along the longest axis of the padded box (the CLI's `--resolution`).
    LongestAxis(u32),
    /// `density` samples per mesh unit (× the instance's scale, for runtime bakes), each
    /// axis clamped to `[min, max]` samples, and at least `min_longest` samples along the
    /// longest axis (small meshes get finer voxels than `density` gives). Default: 32 per
    /// metre, 8..=256, at least 48 along the longest axis: about 50³ for a 1.5 m mesh,
    /// 48 × 28 × 28 for a 0.7 m helmet (1.7 cm voxels instead of 3.1 cm).
    PerUnit {
        /// Samples per mesh unit.
        density: f32,
        /// Fewest samples along an axis.
        min: u32,
        /// Most samples along an axis.
        max: u32,
        /// Fewest samples along the longest axis (border included; at most `max`; 0: no
        /// such floor).
        min_longest: u32,
    },
}

/// Where samples go.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridPolicy {
    /// Resolution rule.
    pub resolution: Resolution,
    /// Samples of padding outside the mesh bounds on each side (default 2).
    pub border_voxels: u32,
    /// Finer voxels for meshes with thin walls ([`Resolution::PerUnit`] only). Default
    /// [`ThinWalls::default`].
    pub thin_walls: ThinWalls,
}

impl Default for GridPolicy {
    fn default() -> Self {
        Self {
            resolution: Resolution::PerUnit {
                density: 32.0,
                min: 8,
                max: 256,
                min_longest: DEFAULT_MIN_LONGEST,
            },
            border_voxels: 2,
            thin_walls: ThinWalls::default(),
        }
    }
}

/// The thin-wall rule of [`Resolution::PerUnit`] grids: a mesh that bakes solid and whose
/// walls (the area-weighted `quantile` of their thickness,
/// [`crate::thickness::wall_thickness_quantile`]) are thinner than `voxels_across`
/// voxels gets voxels that many times finer than the wall, at most `max_refine` times
/// finer than the rule's own and within its `max` samples per axis. Walls thinner than a
/// voxel lose their inside in a trilinear field (the thin-feature guard keeps one
/// negative sample, not the wall's width). Measured on `../shared/scenes` (ARCHITECTURE.md,
/// "Bake resolution"): the flight helmet's and barn lamp's parts and the palm tree's
/// leaves have walls of 0.08–0.6 voxels at the default density (sheet metal, straps),
/// below what any cap reaches. When it was added, this rule (twice finer at most) took
/// the scene corpus's shadows on shadowed pixels 0.169 → 0.164 (helmet; DFAO
/// 0.141 → 0.136), 0.259 → 0.207 (lamp), 0.135 → 0.118 (palm) for 0.7 → 3.9, 0.2 → 1.4
/// and 4.1 → 8.3 MB of atlas. Baking them two-sided instead (shells) was worse (0.200,
/// 0.360). The cap went 2 → 3 once a field read outside its box stopped turning inside
/// (the helmet's base had hidden the gain): helmet 0.104 → 0.082 for 3.9 → 7.6 MB, lamp
/// 0.205 → 0.195 for 1.4 → 4.3 MB, palm unchanged for 10.3 → 19.9 MB; 4 gave 0.087 and
/// 0.170 for 14.6 and 9.6 MB. Once large fields are placed as sparse bricks
/// ([`crate::bricks`]: the atlas holds only the bricks near the surface), the cap went
/// 3 → 6: lamp 0.169 → 0.084 (its 1–2 mm studs cast) for 4.4 → 5.4 MB of atlas (28.3
/// dense), helmet 0.075 → 0.068 for 7.8 → 12.0 MB (37.7 dense), palm 0.096 → 0.090 for
/// 16.3 → 12.6 MB. The bake itself and the disk cache hold the dense grid (the lamp's
/// bake 3.0 → 6.1 s in a debug build).
/// Cost: one ray per triangle, at most [`crate::thickness::WALL_SAMPLES`], per bake.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinWalls {
    /// Voxels a wall should be across. Default 2.
    pub voxels_across: f32,
    /// The share of the measured area (0–1) whose walls must be that wide. Default 0.1.
    pub quantile: f32,
    /// How many times finer than the rule's own voxels, at most. Default 6 (up to 216×
    /// the samples, within the grid's cap); 1 turns the rule off.
    pub max_refine: f32,
}

impl ThinWalls {
    /// No thin-wall rule.
    pub const OFF: ThinWalls = ThinWalls {
        voxels_across: 2.0,
        quantile: 0.1,
        max_refine: 1.0,
    };

    /// Whether the rule can change a grid.
    pub fn is_on(&self) -> bool {
        self.max_refine > 1.0
            && self.voxels_across > 0.0
            && (0.0..=1.0).contains(&self.quantile)
            && self.max_refine.is_finite()
    }
}

impl Default for ThinWalls {
    fn default() -> Self {
        Self {
            voxels_across: 2.0,
            quantile: 0.1,
            max_refine: 6.0,
        }
    }
}

/// The default floor on samples along a mesh's longest axis ([`Resolution::PerUnit`]).
pub const DEFAULT_MIN_LONGEST: u32 = 48;

/// The largest grid a bake accepts: 2^27 samples (512³ = 256 MiB of f16).
pub const MAX_SAMPLES: u64 = 1 << 27;

/// A resolved grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridSpec {
    /// Samples per axis.
    pub dims: UVec3,
    /// Position of sample (0, 0, 0).
    pub origin: Vec3,
    /// Sample spacing.
    pub voxel_size: f32,
    /// Border samples on each side.
    pub border: u32,
}

impl GridSpec {
    /// Total samples.
    pub fn samples(&self) -> u64 {
        self.dims.x as u64 * self.dims.y as u64 * self.dims.z as u64
    }
}

/// Why a grid cannot be made.
#[derive(Clone, Debug, PartialEq)]
pub enum GridError {
    /// A resolution parameter is zero, negative, NaN or otherwise unusable.
    BadResolution(String),
    /// The grid would exceed [`MAX_SAMPLES`].
    TooLarge {
        /// Requested samples per axis.
        dims: [u64; 3],
    },
}

impl std::fmt::Display for GridError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            GridError::BadResolution(why) => write!(f, "bad resolution: {why}"),
            GridError::TooLarge { dims } => write!(
                f,
                "grid {}×{}×{} = {} samples exceeds the limit of {MAX_SAMPLES} (512³)",
                dims[0],
                dims[1],
                dims[2],
                dims.iter().map(|&d| d as u128).product::<u128>()
            ),
        }
    }
}

impl std::error::Error for GridError {}

impl GridPolicy {
    /// Resolves the grid for mesh bounds `bounds` and the mesh's wall thickness `wall`
    /// (the [`ThinWalls`] quantile, mesh units; `None`: no wall measured or the rule does
    /// not apply), and by how much the thin-wall rule refined it (1: not). A refined grid
    /// that cannot be made (over [`MAX_SAMPLES`]) leaves the rule's own: the rule only
    /// ever adds detail, it never fails a bake the grid alone allows.
    pub fn resolve_with_walls(
        &self,
        bounds: &Aabb,
        wall: Option<f32>,
    ) -> Result<(GridSpec, f32), GridError> {
        let grid = self.resolve(bounds)?;
        let rule = self.thin_walls;
        let Resolution::PerUnit {
            density,
            min,
            max,
            min_longest,
        } = self.resolution
        else {
            return Ok((grid, 1.0));
        };
        let Some(wall) = wall.filter(|w| *w > 0.0 && w.is_finite()) else {
            return Ok((grid, 1.0));
        };
        if !rule.is_on() || wall >= rule.voxels_across * grid.voxel_size {
            return Ok((grid, 1.0));
        }
        let refine = (rule.voxels_across * grid.voxel_size / wall).min(rule.max_refine);
        let pad = 2 * self.border_voxels + 1;
        let longest = grid.dims.max_element().saturating_sub(pad) as f32;
        let finer = GridPolicy {
            resolution: Resolution::PerUnit {
                density: density * refine,
                min,
                max,
                min_longest: ((longest * refine).ceil() as u32)
                    .saturating_add(pad)
                    .max(min_longest)
                    .min(max),
            },
            ..*self
        };
        match finer.resolve(bounds) {
            Ok(refined) => Ok((refined, grid.voxel_size / refined.voxel_size)),
            Err(_) => Ok((grid, 1.0)),
        }
    }

    /// Resolves the grid for mesh bounds `bounds` (must be finite and non-empty).
    pub fn resolve(&self, bounds: &Aabb) -> Result<GridSpec, GridError> {
        let extent = bounds.size().max(Vec3::ZERO);
        let border = self.border_voxels;
        let pad = 2 * border as u64 + 1; // border on both sides, plus the fence post
        let voxel_size = match self.resolution {
            Resolution::LongestAxis(n) => {
                if (n as u64) < pad + 1 {
                    return Err(GridError::BadResolution(format!(
                        "{n} samples along the longest axis leaves none inside a {border}-sample border"
                    )));
                }
                extent.max_element() / (n as u64 - pad) as f32
            }
            Resolution::PerUnit {
                density,
                min,
                max,
                min_longest,
            } => {
                if !(density.is_finite() && density > 0.0) {
                    return Err(GridError::BadResolution(format!("density {density}")));
                }
                if min < 2 || max < min || min_longest > max {
                    return Err(GridError::BadResolution(format!(
                        "min {min}, max {max}, min_longest {min_longest}"
                    )));
                }
                if (max as u64) < pad + 1 {
                    return Err(GridError::BadResolution(format!(
                        "max {max} leaves no samples inside a {border}-sample border"
                    )));
                }
                // Small meshes: at least `min_longest` samples along the longest axis.
                let floor = if (min_longest as u64) > pad {
                    extent.max_element() / (min_longest as u64 - pad) as f32
                } else {
                    f32::INFINITY
                };
                // Cap the longest axis at `max` samples by growing the voxel.
                (1.0 / density)
                    .min(floor)
                    .max(extent.max_element() / (max as u64 - pad) as f32)
            }
        };
        // A point-like or flat mesh: give the voxel a size from the other axes, or 1.
        let voxel_size = if voxel_size > 0.0 && voxel_size.is_finite() {
            voxel_size
        } else {
            let fallback = extent.max_element();
            if fallback > 0.0 { fallback } else { 1.0 }
        };
        let min_samples = match self.resolution {
            Resolution::PerUnit { min, .. } => min as u64,
            Resolution::LongestAxis(_) => 2,
        };
        let dims_u64 = extent.to_array().map(|e| {
            let inner = (e / voxel_size - 1e-4).ceil().max(0.0) as u64;
            (inner + pad).max(min_samples)
        });
        // u128: three saturated u64 axes must not overflow the product.
        let samples: u128 = dims_u64.iter().map(|&d| d as u128).product();
        if samples > MAX_SAMPLES as u128 || dims_u64.iter().any(|&d| d > u32::MAX as u64) {
            return Err(GridError::TooLarge { dims: dims_u64 });
        }
        let dims = UVec3::new(dims_u64[0] as u32, dims_u64[1] as u32, dims_u64[2] as u32);
        // Centre the samples on the mesh bounds.
        let span = voxel_size * (dims.as_vec3() - Vec3::ONE);
        let origin = bounds.center() - 0.5 * span;
        Ok(GridSpec {
            dims,
            origin,
            voxel_size,
            border,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bounds(size: Vec3) -> Aabb {
        Aabb {
            min: Vec3::new(1.0, 2.0, 3.0),
            max: Vec3::new(1.0, 2.0, 3.0) + size,
        }
    }

    #[test]
    fn longest_axis_gets_exactly_n_samples_and_border_is_outside() {
        let b = bounds(Vec3::new(2.0, 1.0, 0.5));
        let g = GridPolicy {
            resolution: Resolution::LongestAxis(64),
            border_voxels: 2,
            thin_walls: ThinWalls::OFF,
        }
        .resolve(&b)
        .unwrap();
        assert_eq!(g.dims.x, 64);
        assert!(g.dims.y < 64 && g.dims.z < g.dims.y);
        // Border samples lie at least `border` voxels outside the bounds.
        let last = g.origin + g.voxel_size * (g.dims.as_vec3() - Vec3::ONE);
        for axis in 0..3 {
            assert!(b.min[axis] - g.origin[axis] >= 2.0 * g.voxel_size - 1e-5);
            assert!(last[axis] - b.max[axis] >= 2.0 * g.voxel_size - 1e-5);
        }
    }

    #[test]
    fn per_unit_density_is_clamped() {
        let policy = GridPolicy::default();
        // 1.5 units at 32 per unit: ~50 samples.
        let g = policy.resolve(&bounds(Vec3::splat(1.5))).unwrap();
        assert!((50..=54).contains(&g.dims.x), "{}", g.dims);
        // 100 units would be 3200 samples: capped at 256 by growing the voxel.
        let g = policy.resolve(&bounds(Vec3::new(100.0, 1.0, 1.0))).unwrap();
        assert_eq!(g.dims.x, 256);
        // A flat mesh still gets the minimum along its flat axis.
        let g = policy.resolve(&bounds(Vec3::new(1.0, 0.0, 1.0))).unwrap();
        assert_eq!(g.dims.y, 8);
        // A 0.7 m prop would get 23 + 5 samples at 32 per unit: the floor gives it 48.
        let g = policy
            .resolve(&bounds(Vec3::new(0.37, 0.72, 0.37)))
            .unwrap();
        assert_eq!(g.dims.y, DEFAULT_MIN_LONGEST, "{}", g.dims);
        assert!(
            (g.voxel_size - 0.72 / 43.0).abs() < 1e-6,
            "{}",
            g.voxel_size
        );
        // Without the floor: the density alone.
        let off = GridPolicy {
            resolution: Resolution::PerUnit {
                density: 32.0,
                min: 8,
                max: 256,
                min_longest: 0,
            },
            border_voxels: 2,
            thin_walls: ThinWalls::OFF,
        };
        let g = off.resolve(&bounds(Vec3::new(0.37, 0.72, 0.37))).unwrap();
        assert_eq!(g.voxel_size, 1.0 / 32.0);
    }

    #[test]
    fn bad_and_huge_resolutions_are_errors() {
        let b = bounds(Vec3::ONE);
        let bad = [
            Resolution::LongestAxis(0),
            Resolution::LongestAxis(5),
            Resolution::PerUnit {
                density: 0.0,
                min: 8,
                max: 256,
                min_longest: 0,
            },
            Resolution::PerUnit {
                density: f32::NAN,
                min: 8,
                max: 256,
                min_longest: 0,
            },
            Resolution::PerUnit {
                density: 10.0,
                min: 300,
                max: 256,
                min_longest: 0,
            },
            Resolution::PerUnit {
                density: 10.0,
                min: 8,
                max: 64,
                min_longest: 65,
            },
        ];
        for resolution in bad {
            let e = GridPolicy {
                resolution,
                border_voxels: 2,
                thin_walls: ThinWalls::OFF,
            }
            .resolve(&b)
            .unwrap_err();
            assert!(
                matches!(e, GridError::BadResolution(_)),
                "{resolution:?}: {e}"
            );
        }
        let e = GridPolicy {
            resolution: Resolution::LongestAxis(100_000),
            border_voxels: 2,
            thin_walls: ThinWalls::OFF,
        }
        .resolve(&b)
        .unwrap_err();
        assert!(matches!(e, GridError::TooLarge { .. }), "{e}");
        // Absurd densities and extents saturate instead of overflowing.
        for (density, size) in [(1e30, 1.0), (1e20, 1e20), (f32::MAX, f32::MAX)] {
            let e = GridPolicy {
                resolution: Resolution::PerUnit {
                    density,
                    min: 8,
                    max: u32::MAX,
                    min_longest: 0,
                },
                border_voxels: 2,
                thin_walls: ThinWalls::OFF,
            }
            .resolve(&bounds(Vec3::splat(size)))
            .unwrap_err();
            assert!(
                matches!(e, GridError::TooLarge { .. }),
                "{density} {size}: {e}"
            );
            assert!(!e.to_string().is_empty());
        }
    }

    /// The thin-wall rule refines within `max` and never turns a grid that fits into one
    /// that does not: 400 units at 1 sample per unit fit (405³ samples), finer (the cap,
    /// six times: 2405³) would not, so the rule's own grid stays.
    #[test]
    fn thin_walls_never_fail_a_grid_that_fits() {
        let policy = GridPolicy {
            resolution: Resolution::PerUnit {
                density: 1.0,
                min: 8,
                max: 1024,
                min_longest: 0,
            },
            ..GridPolicy::default()
        };
        let b = bounds(Vec3::splat(400.0));
        let plain = policy.resolve(&b).unwrap();
        let (grid, refine) = policy.resolve_with_walls(&b, Some(0.25)).unwrap();
        assert_eq!((grid, refine), (plain, 1.0));
        // Smaller, it is refined to the cap (the wall would want eight times finer).
        let b = bounds(Vec3::splat(60.0));
        let (grid, refine) = policy.resolve_with_walls(&b, Some(0.25)).unwrap();
        let cap = ThinWalls::default().max_refine;
        assert!(cap < 8.0 && (refine - cap).abs() < 0.05, "{refine}");
        assert!(grid.voxel_size < policy.resolve(&b).unwrap().voxel_size);
    }
}
