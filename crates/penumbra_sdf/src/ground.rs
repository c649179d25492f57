//! Ground: an open sheet that faces up everywhere (terrain, a floor, a road) is the top
//! of a solid, and bakes as one ([`crate::SignMethod::SolidBelow`]).
//!
//! Such a sheet has no inside for a winding number to find (it is about ½ on both sides
//! of an open sheet, and the sign a guess), and as a two-sided shell about a voxel thick
//! it shadows itself: a ray leaving a bumpy terrain towards a low sun rises above the
//! sheet by less than the shell's half-thickness for its first voxels and stops inside
//! it (on `terrain.glb` of the shared scenes, with the sun 28° high, 57 of its 821
//! pixels went black where ray tracing lights them). Solid below, the field is the
//! signed distance to the sheet itself, as Unreal's landscapes are heightfields.
//!
//! **The rule** ([`is_ground`]): among the sheet's triangles, weighted by area, the
//! share of the up axis in their normals ([`Facing::up`], the mean of max(n·up, 0)) is
//! at least [`GROUND_MIN_UP`] and the share facing down ([`Facing::down`]) at most
//! [`GROUND_MAX_DOWN`]: a sheet with no overhang and more floor than cliff. Measured on
//! `../shared/scenes` (world up, per mesh): terrains and floors 0.96–1.00 up and under
//! 10⁻⁴ down (the terrain, the palm tree's island and its sea plane, the depth-of-field
//! scene's circuit board, the tonemapping scene's floor, the flat letters lying in
//! `faces.glb`); everything else has 0.16 or more of its area facing down (spheres,
//! boxes, the helmet's parts, a leaf card seen from both sides: ½), or stands upright
//! (the letters standing in `faces.glb`: 0 up).
//!
//! **The sign**: a sample is inside when a ray from it along the up axis crosses the
//! sheet an odd number of times (most of three rays a few degrees apart, so that a ray
//! through a shared edge or a crack does not decide alone): below a single-valued sheet
//! one crossing, above it or beside its footprint none. Where two neighbouring samples
//! cannot lie on opposite sides (either is farther from the surface than the voxel
//! between them), the sign is carried over without rays: rays are cast only within a
//! voxel of the sheet. The sample box reaches [`GROUND_DEPTH_VOXELS`] below the sheet,
//! so that a flat floor has samples inside.
//!
//! Limits: the solid below ends at the sample box and at the footprint's edge (a ray
//! from below or beside the sheet sees a slab, not a terrain's hidden side); a sheet
//! seen from below (a ceiling, a cave's roof) is not ground by this rule and stays a
//! shell.

use glam::Vec3;

/// Least area-weighted share of up in the normals of a ground sheet ([`Facing::up`]).
/// The measured ground sheets score 0.96–1.00, a vertical wall 0; a terrain with steep
/// hills keeps more than half of its area's normal upward.
pub const GROUND_MIN_UP: f32 = 0.5;

/// Most area-weighted share of a ground sheet facing down ([`Facing::down`]): no real
/// overhang (the measured ground sheets: under 10⁻⁴; a closed box or sphere 0.17–0.25).
pub const GROUND_MAX_DOWN: f32 = 0.01;

/// How far below the sheet the sample box of a ground bake reaches, voxels.
pub const GROUND_DEPTH_VOXELS: f32 = 4.0;

/// How a triangle list faces an axis: area-weighted means of max(n·up, 0) and
/// max(−n·up, 0) over its triangles (0 to 1 each; a closed surface has equal shares).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Facing {
    /// Share facing up.
    pub up: f32,
    /// Share facing down.
    pub down: f32,
}

/// How the triangles `indices` (three per triangle, into `positions`) face `up` (any
/// length; normalised here). Zeros for no area, a zero or non-finite `up`, or an index
/// out of range.
pub fn facing(positions: &[Vec3], indices: &[u32], up: Vec3) -> Facing {
    let up = up.normalize_or_zero();
    if up == Vec3::ZERO || indices.iter().any(|&i| i as usize >= positions.len()) {
        return Facing::default();
    }
    let (mut area, mut rise, mut fall) = (0.0f64, 0.0f64, 0.0f64);
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| positions[i as usize]);
        // Twice the area times the unit normal.
        let n = (b - a).cross(c - a);
        let double_area = n.length();
        if !double_area.is_finite() {
            continue;
        }
        let along = f64::from(n.dot(up));
        area += f64::from(double_area);
        rise += along.max(0.0);
        fall += (-along).max(0.0);
    }
    if area <= 0.0 {
        return Facing::default();
    }
    Facing {
        up: (rise / area) as f32,
        down: (fall / area) as f32,
    }
}

/// Whether a sheet facing so is ground (module docs): at least [`GROUND_MIN_UP`] up and
/// at most [`GROUND_MAX_DOWN`] down.
pub fn is_ground(facing: Facing) -> bool {
    facing.up >= GROUND_MIN_UP && facing.down <= GROUND_MAX_DOWN
}

/// The sign of a ground bake (module docs): three rays along `up` a little apart.
///
/// When `up` lies along a grid axis (a terrain's +y, a Z-up export's +z: the common
/// case), the rays run up whole columns of samples, once per column, three columns a
/// few hundredths of a voxel apart (so that no two pass through the same edge of a
/// regular mesh), and a sample counts the crossings above it. Otherwise three rays leave
/// every sample, a few degrees apart.
#[cfg(feature = "bake")]
pub(crate) enum GroundSign {
    /// Crossings up each column of the grid, `axis` (0–2) pointing along `up`
    /// (`towards` +1) or against it (−1).
    Columns {
        axis: usize,
        towards: i32,
        dims: glam::UVec3,
        voxel: f32,
        /// The crossings' distances from one voxel before the column's first sample,
        /// three lists per column (indexed by the other two axes' indices).
        hits: Vec<[Vec<f32>; 3]>,
    },
    /// Rays from every sample.
    Rays([Vec3; 3]),
}

#[cfg(feature = "bake")]
impl GroundSign {
    /// The sign of a grid of `dims` samples from `origin` (`voxel` apart) under `up`
    /// (finite, non-zero: checked by the bake's settings).
    pub(crate) fn new(
        up: Vec3,
        bvh: &crate::bvh::Bvh,
        origin: Vec3,
        voxel: f32,
        dims: glam::UVec3,
    ) -> Self {
        use rayon::prelude::*;
        let up = up.normalize();
        let axis = up.abs().max_position();
        if up.abs()[axis] < 1.0 - 1e-6 {
            let (a, b) = up.any_orthonormal_pair();
            // Skewed by 2–4°, in different directions.
            let rays = [
                up + 0.0123 * a + 0.0411 * b,
                up - 0.0389 * a + 0.0157 * b,
                up + 0.0291 * a - 0.0533 * b,
            ]
            .map(Vec3::normalize);
            return GroundSign::Rays(rays);
        }
        let towards = if up[axis] > 0.0 { 1 } else { -1 };
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let (nu, nv, n) = (dims[u], dims[v], dims[axis]);
        let offsets = [(0.013, 0.029), (-0.031, 0.007), (0.021, -0.017)];
        let dir = Vec3::AXES[axis] * towards as f32;
        let hits = (0..nu * nv)
            .into_par_iter()
            .map(|c| {
                let mut base = Vec3::ZERO;
                base[u] = (c % nu) as f32;
                base[v] = (c / nu) as f32;
                base[axis] = if towards > 0 { -1.0 } else { n as f32 };
                offsets.map(|(du, dv)| {
                    let mut p = base;
                    p[u] += du;
                    p[v] += dv;
                    bvh.ray_hit_distances(origin + voxel * p, dir, 0.0)
                })
            })
            .collect();
        GroundSign::Columns {
            axis,
            towards,
            dims,
            voxel,
            hits,
        }
    }

    /// Whether sample `index` (at `p`) lies below the sheet: most of its rays cross it
    /// an odd number of times.
    pub(crate) fn inside(&self, bvh: &crate::bvh::Bvh, index: glam::UVec3, p: Vec3) -> bool {
        let odd = match self {
            GroundSign::Rays(rays) => rays
                .iter()
                .filter(|&&dir| bvh.ray_crossings(p, dir, 0.0) % 2 == 1)
                .count(),
            GroundSign::Columns {
                axis,
                towards,
                dims,
                voxel,
                hits,
            } => {
                let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                let column = &hits[(index[u] + dims[u] * index[v]) as usize];
                let m = index[*axis];
                let steps = if *towards > 0 { m + 1 } else { dims[*axis] - m };
                let t = steps as f32 * voxel;
                column
                    .iter()
                    .filter(|list| (list.len() - list.partition_point(|&x| x <= t)) % 2 == 1)
                    .count()
            }
        };
        odd >= 2
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A sheet of `n × n` quads over [−1, 1]² at heights `h(x, z)`, normals up: its
    /// positions and triangle indices.
    pub(crate) fn sheet(n: u32, h: impl Fn(f32, f32) -> f32) -> (Vec<Vec3>, Vec<u32>) {
        let mesh = crate::shapes::height_sheet(n, 1.0, h);
        let indices = mesh.triangles.iter().flatten().copied().collect();
        (mesh.positions, indices)
    }

    /// A flat sheet facing up is all up; flipped, all down; a closed box half and half
    /// (⅙ each way: two of its six faces); a wall neither.
    #[test]
    fn facing_measures_the_area_turned_up_and_down() {
        let (p, i) = sheet(4, |_, _| 0.0);
        let f = facing(&p, &i, Vec3::Y);
        assert!((f.up - 1.0).abs() < 1e-6 && f.down == 0.0, "{f:?}");
        let flipped: Vec<u32> = i.chunks(3).flat_map(|t| [t[0], t[2], t[1]]).collect();
        let f = facing(&p, &flipped, Vec3::Y);
        assert!((f.down - 1.0).abs() < 1e-6 && f.up == 0.0, "{f:?}");
        let f = facing(&p, &i, Vec3::X * 3.0);
        assert!(f.up.abs() < 1e-6 && f.down.abs() < 1e-6, "{f:?}");
        let cube = crate::shapes::cuboid(Vec3::splat(0.5));
        let ci: Vec<u32> = cube.triangles.iter().flatten().copied().collect();
        let f = facing(&cube.positions, &ci, Vec3::Y);
        assert!(
            (f.up - 1.0 / 6.0).abs() < 1e-5 && (f.down - 1.0 / 6.0).abs() < 1e-5,
            "{f:?}"
        );
        assert!(!is_ground(f));
        // Bad input: no answer, not a panic.
        assert_eq!(facing(&p, &[0, 1, 99], Vec3::Y), Facing::default());
        assert_eq!(facing(&p, &i, Vec3::ZERO), Facing::default());
    }

    /// Rolling hills are ground; hills with an overhang (a fold facing down) or a
    /// vertical wall are not.
    #[test]
    fn rolling_hills_are_ground_and_overhangs_are_not() {
        let (p, i) = sheet(32, |x, z| 0.2 * (3.0 * x).sin() * (2.0 * z).cos());
        let f = facing(&p, &i, Vec3::Y);
        assert!(is_ground(f), "{f:?}");
        // A fold: the middle column of vertices pushed past its neighbours makes a
        // strip of triangles face down.
        let mut folded = p.clone();
        for (v, q) in folded.iter_mut().enumerate() {
            if v % 33 == 16 {
                q.x += 0.2;
            }
        }
        let f = facing(&folded, &i, Vec3::Y);
        assert!(f.down > GROUND_MAX_DOWN && !is_ground(f), "{f:?}");
        let f = facing(&p, &i, Vec3::Z);
        assert!(!is_ground(f), "{f:?}");
    }
}
