//! Ray-traced ground truth for a whole scene seen through a camera: what the scene
//! viewer's `--dump` buffers (`visibility_<light>`, `ao`) should hold, computed from the
//! scene's triangles alone, with no distance field and no Python.
//!
//! Per pixel: the camera ray's first hit, then
//! - **sun visibility** ([`sun_visibility`]): the fraction of rays toward points spread
//!   uniformly over the sun's disc (angular diameter) that leave the surface on its front
//!   side and meet no triangle;
//! - **ambient occlusion** ([`ambient_occlusion`]): the fraction of cosine-weighted rays
//!   about the normal that meet no triangle within the maximum distance.
//!
//! Occluders are every triangle, from either side, as in the distance fields. Samples are
//! stratified (a 2-D low-discrepancy set, rotated per pixel by a hash of the pixel's
//! index), so the result is deterministic whatever the thread count. Rays meet triangles
//! by Möller–Trumbore (the baker's BVH), which is not watertight: a camera ray exactly
//! through an edge two triangles share can slip between them (a background pixel, skipped
//! by [`compare`]).
//!
//! # Conventions ([`Facing`])
//! [`Facing::Raster`] is what Bevy draws: the camera sees past the back faces of
//! single-sided materials (culled), and a double-sided surface seen from behind is shaded
//! with its normal flipped toward the camera. [`Facing::AllFaces`] is the convention of
//! `../shared/tools/shadow_truth.py` and `ao_truth.py` (Embree): the camera ray stops at
//! any face, shadows test the triangle's unflipped normal, AO flips it toward the camera.
//! The two agree wherever the camera sees only front faces; use `AllFaces` to cross-check
//! against those tools, `Raster` as the truth for what the viewer renders.

use crate::camera::PerspectiveCamera;
use glam::Vec3;
use penumbra_sdf::bvh::Bvh;
use rayon::prelude::*;
use std::path::Path;

/// Which faces the camera sees and which way a surface faces (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Facing {
    /// Bevy's rasterizer: back faces of single-sided materials culled, double-sided
    /// surfaces face the camera.
    Raster,
    /// The Embree oracles: every face is hit; shadows use the triangle's own normal.
    AllFaces,
}

/// A scene's triangles in world space on a BVH.
pub struct SceneTriangles {
    triangles: Vec<[Vec3; 3]>,
    double_sided: Vec<bool>,
    bvh: Bvh,
    /// Half the diagonal of the scene's bounds.
    radius: f32,
}

impl SceneTriangles {
    /// Triangles (world space) and, per triangle, whether its material is double-sided.
    pub fn new(triangles: Vec<[Vec3; 3]>, double_sided: Vec<bool>) -> SceneTriangles {
        assert_eq!(triangles.len(), double_sided.len(), "one flag per triangle");
        let (lo, hi) = triangles.iter().flatten().fold(
            (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
            |(l, h), &p| (l.min(p), h.max(p)),
        );
        SceneTriangles {
            bvh: Bvh::build(&triangles),
            radius: if triangles.is_empty() {
                1.0
            } else {
                (hi - lo).length() * 0.5
            },
            triangles,
            double_sided,
        }
    }

    /// Every mesh of a glTF file's default scene, placed by its node transforms (the
    /// baker's reader: skinned meshes in bind pose). In the [`Facing::Raster`]
    /// convention without its see-through triangles (alpha-blended or transmissive
    /// materials, `penumbra_sdf::gltf_input::TriangleMaterial`): Bevy draws them after
    /// the depth prepass and the G-buffer the passes read, so a pixel of glass shows
    /// what lies behind it, and the scene casters skip them (a goggle's lens, a lamp's
    /// glass). [`Facing::AllFaces`], the Embree oracles' convention, keeps them.
    ///
    /// A file with skinned meshes is read posed instead ([`SceneTriangles::from_gltf_posed`]
    /// at its rest pose: what Bevy draws when no animation plays).
    pub fn from_gltf(path: &Path, facing: Facing) -> Result<SceneTriangles, String> {
        use penumbra_sdf::gltf_input::{GltfSelection, load_gltf_with_sides};
        let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let (mesh, materials, report) =
            load_gltf_with_sides(&bytes, path.parent(), &GltfSelection::Scene)
                .map_err(|e| format!("{}: {e}", path.display()))?;
        if report.skinned_instances > 0 {
            return Self::from_gltf_posed(path, facing, None);
        }
        let world = |i: u32| (mesh.origin + mesh.positions[i as usize].as_dvec3()).as_vec3();
        let (triangles, double_sided) = mesh
            .triangles
            .iter()
            .zip(&materials)
            .filter(|(_, m)| facing == Facing::AllFaces || !m.see_through)
            .map(|(t, m)| (t.map(world), m.double_sided))
            .unzip();
        Ok(SceneTriangles::new(triangles, double_sided))
    }

    /// A glTF file's default scene in an animation's pose (`None`: the rest pose),
    /// skinned meshes deformed by their joints ([`crate::posed_gltf`]); see-through
    /// triangles left out in the [`Facing::Raster`] convention, as in
    /// [`SceneTriangles::from_gltf`].
    pub fn from_gltf_posed(
        path: &Path,
        facing: Facing,
        pose: Option<crate::posed_gltf::Pose>,
    ) -> Result<SceneTriangles, String> {
        let posed = crate::posed_gltf::posed_triangles(path, pose)?;
        let (triangles, double_sided) = posed
            .triangles
            .iter()
            .zip(&posed.double_sided)
            .zip(&posed.see_through)
            .filter(|(_, see_through)| facing == Facing::AllFaces || !**see_through)
            .map(|((t, d), _)| (*t, *d))
            .unzip();
        Ok(SceneTriangles::new(triangles, double_sided))
    }

    /// These triangles and `extra` (each with `double_sided`), on a new BVH.
    pub fn with_extra(self, extra: &[[Vec3; 3]], double_sided: bool) -> SceneTriangles {
        let mut triangles = self.triangles;
        let mut sides = self.double_sided;
        triangles.extend_from_slice(extra);
        sides.extend(std::iter::repeat_n(double_sided, extra.len()));
        SceneTriangles::new(triangles, sides)
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// Whether there are no triangles.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// How far a secondary ray starts off the surface: far above `f32` rounding at the
    /// scene's scale, far below any feature.
    fn bias(&self) -> f32 {
        (self.radius * 1e-5).max(1e-4)
    }

    fn blocked(&self, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        self.bvh.ray_nearest(origin, dir, 0.0, t_max).is_some()
    }
}

/// The surface a camera ray sees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceHit {
    /// Distance from the eye along the ray.
    pub depth: f32,
    /// The hit point.
    pub position: Vec3,
    /// The triangle's normal, turned toward the camera.
    pub normal: Vec3,
    /// The normal shadows test against ([`Facing`]).
    pub shadow_normal: Vec3,
    /// The camera sees the triangle's back (a double-sided one, or any with
    /// [`Facing::AllFaces`]): an open sheet's underside.
    pub back: bool,
}

/// Per pixel (row-major, row 0 at the top), the first surface the camera ray sees.
pub fn primary_hits(
    scene: &SceneTriangles,
    camera: &PerspectiveCamera,
    facing: Facing,
) -> Vec<Option<SurfaceHit>> {
    let (w, h) = (camera.width, camera.height);
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let ray = camera.ray((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
            primary_hit(scene, ray.origin, ray.dir, facing)
        })
        .collect()
}

fn primary_hit(scene: &SceneTriangles, eye: Vec3, dir: Vec3, facing: Facing) -> Option<SurfaceHit> {
    let mut t_min = 0.0f32;
    // A ray crosses few culled faces before it meets one it sees; the bound only guards
    // against a pathological stack of coincident faces.
    for _ in 0..64 {
        let (t, front, index) = scene.bvh.ray_nearest(eye, dir, t_min, f32::INFINITY)?;
        let index = index as usize;
        if facing == Facing::Raster && !front && !scene.double_sided[index] {
            t_min = t + t.abs().max(1.0) * 1e-6;
            continue;
        }
        let [a, b, c] = scene.triangles[index];
        let face = (b - a).cross(c - a).normalize_or(Vec3::Y);
        let toward_camera = if face.dot(dir) > 0.0 { -face } else { face };
        return Some(SurfaceHit {
            depth: t,
            position: eye + dir * t,
            normal: toward_camera,
            back: face.dot(dir) > 0.0,
            shadow_normal: match facing {
                Facing::Raster => toward_camera,
                Facing::AllFaces => face,
            },
        });
    }
    None
}

/// The `i`-th of `n` stratified points of the unit square, rotated by `seed` (toroidally:
/// Cranley–Patterson), from the Hammersley set.
fn sample(i: u32, n: u32, seed: u32) -> (f32, f32) {
    let u = (i as f32 + 0.5) / n as f32;
    let v = i.reverse_bits() as f32 * (1.0 / 4_294_967_296.0);
    let (ru, rv) = (hash(seed) as f32, hash(seed ^ 0x9e37_79b9) as f32);
    let scale = 1.0 / 4_294_967_296.0;
    ((u + ru * scale).fract(), (v + rv * scale).fract())
}

/// A 32-bit integer hash (lowbias32).
fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^ (x >> 16)
}

/// Two unit vectors completing `n` to an orthonormal basis.
fn basis(n: Vec3) -> (Vec3, Vec3) {
    let a = if n.y.abs() < 0.9 { Vec3::Y } else { Vec3::X };
    let u = n.cross(a).normalize();
    (u, n.cross(u))
}

/// Per pixel, the fraction of a directional light of angular diameter
/// `angular_diameter` (radians) travelling along `direction` that reaches the surface
/// (NaN on background). `spp` rays per pixel.
pub fn sun_visibility(
    scene: &SceneTriangles,
    hits: &[Option<SurfaceHit>],
    direction: Vec3,
    angular_diameter: f32,
    spp: u32,
) -> Vec<f32> {
    let to_sun = -direction.normalize();
    let (u, v) = basis(to_sun);
    let tan_half = (angular_diameter * 0.5).tan();
    let bias = scene.bias();
    hits.par_iter()
        .enumerate()
        .map(|(pixel, hit)| {
            let Some(hit) = hit else { return f32::NAN };
            let origin = hit.position + hit.shadow_normal * bias;
            let open = (0..spp)
                .filter(|&i| {
                    let (a, b) = sample(i, spp, pixel as u32);
                    let (r, phi) = (tan_half * a.sqrt(), std::f32::consts::TAU * b);
                    let dir = (to_sun + u * (r * phi.cos()) + v * (r * phi.sin())).normalize();
                    dir.dot(hit.shadow_normal) > 0.0 && !scene.blocked(origin, dir, f32::MAX)
                })
                .count();
            open as f32 / spp as f32
        })
        .collect()
}

/// Per pixel, the fraction of `spp` cosine-weighted rays about the surface normal (turned
/// toward the camera) that meet nothing within `max_distance` (NaN on background).
pub fn ambient_occlusion(
    scene: &SceneTriangles,
    hits: &[Option<SurfaceHit>],
    max_distance: f32,
    spp: u32,
) -> Vec<f32> {
    let bias = scene.bias();
    hits.par_iter()
        .enumerate()
        .map(|(pixel, hit)| {
            let Some(hit) = hit else { return f32::NAN };
            let (u, v) = basis(hit.normal);
            let origin = hit.position + hit.normal * bias;
            let open = (0..spp)
                .filter(|&i| {
                    let (a, b) = sample(i, spp, pixel as u32 ^ 0x5bd1_e995);
                    let (r, phi) = (a.sqrt(), std::f32::consts::TAU * b);
                    let z = (1.0 - r * r).max(0.0).sqrt();
                    let dir = u * (r * phi.cos()) + v * (r * phi.sin()) + hit.normal * z;
                    !scene.blocked(origin, dir, max_distance)
                })
                .count();
            open as f32 / spp as f32
        })
        .collect()
}

/// How far a rendered buffer is from truth.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TruthError {
    /// Mean |ours − truth| over the pixels either calls shadowed (below 0.98): shadows only.
    pub shadowed: f64,
    /// Mean |ours − truth| over every pixel both see a surface on.
    pub all: f64,
    /// Pixels compared (both see a surface).
    pub pixels: usize,
    /// Pixels either calls shadowed.
    pub shadowed_pixels: usize,
}

/// Per pixel where both see a surface (`depth` and `truth` not NaN; `ours` NaN counts as
/// 1, fully open): its index, |ours − truth|, and whether either calls it shadowed
/// (below 0.98).
fn pixel_errors<'a>(
    ours: &'a [f32],
    truth: &'a [f32],
    depth: &'a [f32],
) -> impl Iterator<Item = (usize, f64, bool)> + 'a {
    ours.iter()
        .zip(truth)
        .zip(depth)
        .enumerate()
        .filter(|(_, ((_, t), d))| !(t.is_nan() || d.is_nan()))
        .map(|(i, ((&o, &t), _))| {
            let o = if o.is_nan() { 1.0 } else { o };
            (i, f64::from((o - t).abs()), o < 0.98 || t < 0.98)
        })
}

/// Compares `ours` with `truth` where both see a surface (`depth` and `truth` not NaN;
/// `ours` NaN counts as 1, fully open).
pub fn compare(ours: &[f32], truth: &[f32], depth: &[f32]) -> TruthError {
    let (mut all, mut shadowed) = ((0.0f64, 0usize), (0.0f64, 0usize));
    for (_, e, is_shadowed) in pixel_errors(ours, truth, depth) {
        all = (all.0 + e, all.1 + 1);
        if is_shadowed {
            shadowed = (shadowed.0 + e, shadowed.1 + 1);
        }
    }
    let mean = |(s, n): (f64, usize)| if n == 0 { 0.0 } else { s / n as f64 };
    TruthError {
        shadowed: mean(shadowed),
        all: mean(all),
        pixels: all.1,
        shadowed_pixels: shadowed.1,
    }
}

/// Of [`compare`]'s error over shadowed pixels, the share on the pixels `keep` selects
/// (0 without error).
pub fn shadowed_error_share(
    ours: &[f32],
    truth: &[f32],
    depth: &[f32],
    keep: impl Fn(usize) -> bool,
) -> f64 {
    let (kept, total) = pixel_errors(ours, truth, depth)
        .filter(|&(_, _, shadowed)| shadowed)
        .fold((0.0f64, 0.0f64), |(k, t), (i, e, _)| {
            (if keep(i) { k + e } else { k }, t + e)
        });
    if total > 0.0 { kept / total } else { 0.0 }
}

#[cfg(test)]
mod tests;
