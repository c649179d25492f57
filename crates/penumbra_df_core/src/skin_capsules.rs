//! Capsules fitted to a skinned mesh's joints: the casters of an animated character.
//!
//! A distance field baked from a skinned mesh is right in one pose only. Unreal answers
//! with *capsule shadows*: one capsule per bone, traced analytically, following the
//! skeleton every frame (Unreal Engine 4.11, "Capsule Shadows"; the capsules come from
//! the character's physics asset). Here they are fitted to the mesh itself, once per
//! mesh and skin:
//!
//! 1. Each vertex belongs to the joint that weighs most in its skinning (its *dominant*
//!    joint; ties go to the first listed). Vertices with no usable weight, an
//!    out-of-range joint index or a non-finite position belong to none.
//! 2. A joint's vertices are taken to its own space by its inverse bind matrix (the space
//!    that the joint's transform carries rigidly when the skeleton moves).
//! 3. Candidate axes: the bone, towards each child joint (its bind-pose origin in this
//!    joint's space), and the principal axis of the joint's vertices.
//! 4. **With the mesh's triangles** ([`SkinInput::triangles`], what the Bevy side gives),
//!    each capsule is fitted to the *volume* its joint skins: the bind-pose solid is
//!    sampled on a grid (96 cells along its longest side; inside by the signed count of
//!    the faces a ray along +z crosses), each inside cell belongs to the joint of its
//!    nearest vertex, and along each candidate axis (and the principal axis of the
//!    joint's cells) the radius and the two
//!    ends minimise the cells it gets wrong: its own inside cells left out (×2) plus
//!    outside cells taken in. The least wrong capsule wins. A joint is kept when it owns
//!    at least 8 cells. Then what a joint's capsule leaves out and no other joint's
//!    capsule holds, in pieces connected through cell faces (ears, a snout, a foot),
//!    gets capsules of its own: up to three pieces a joint, each of at least 2 % of its
//!    cells, where the piece's capsule gets less than half of what leaving it out does
//!    wrong.
//! 5. **Without triangles** (or where they enclose nothing), the vertex fit: along each
//!    axis, a capsule through the vertices' centroid whose radius covers `√coverage` of
//!    them radially and whose core segment then covers all but `(1 − √coverage) / 2` of
//!    those at each end, so that about `coverage` of the vertices lie inside; the least
//!    volume wins. A joint with fewer than [`CapsuleFitSettings::min_vertices`] vertices
//!    gets none. Vertices crowd where a mesh is finely tessellated, so this fit shrinks
//!    toward detail: on the Fox, mean shadow error on shadowed pixels against ray tracing
//!    over four poses (rest / Survey / Walk / Run) is 0.188 / 0.154 / 0.183 / 0.224 by
//!    vertices (19 capsules), 0.113 / 0.082 / 0.120 / 0.144 by volume (20), 0.079 /
//!    0.064 / 0.081 / 0.109 by volume with pieces (31).
//! 6. A capsule thinner than [`CapsuleFitSettings::min_radius`] of the largest one is
//!    dropped (fingers, a tail's tip: shadows too small to see, a record each).
//!
//! The capsule lives in its joint's space: placed as a child of the joint it follows the
//! joint rigidly, which is exact for vertices that one joint skins alone and an
//! approximation where several blend (elbows, the belly). Limits: a capsule cannot bend,
//! so a joint whose vertices curve (a hand) is covered loosely; thin flat parts (a fin,
//! a cape) are covered loosely by the volume fit (little volume, a large shadow seen
//! flat); morph
//! targets are not seen; the fit is of the bind pose.

use glam::{Mat4, Vec3};

/// How capsules are fitted ([`fit_skin_capsules`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CapsuleFitSettings {
    /// The vertex fit only (no triangles given): the fraction of a joint's vertices its
    /// capsule should hold, in (0, 1]. Larger
    /// covers outliers (fur tufts, ears) with fatter capsules that shadow too much;
    /// smaller leaves the edges of a limb out. Default 0.6: the least shadow error on
    /// the Fox over four poses against ray tracing (mean error on shadowed pixels 0.274 /
    /// 0.205 / 0.187 / 0.197 / 0.204 at 0.3 / 0.45 / 0.6 / 0.75 / 0.9; same capsule
    /// count).
    pub coverage: f32,
    /// The vertex fit only: joints with fewer vertices get no capsule (the volume fit
    /// judges a joint by the cells it owns). Default 16.
    pub min_vertices: usize,
    /// Capsules thinner than this fraction of the largest capsule's radius are dropped.
    /// Default 0.15.
    pub min_radius: f32,
}

impl Default for CapsuleFitSettings {
    fn default() -> Self {
        Self {
            coverage: 0.6,
            min_vertices: 16,
            min_radius: 0.15,
        }
    }
}

/// A skinned mesh, as its vertex attributes and skin give it.
#[derive(Clone, Copy, Debug)]
pub struct SkinInput<'a> {
    /// Bind-pose positions, mesh space.
    pub positions: &'a [Vec3],
    /// Four joint indices per vertex (into `inverse_bindposes`).
    pub joints: &'a [[u16; 4]],
    /// Their four weights per vertex.
    pub weights: &'a [[f32; 4]],
    /// The skin's inverse bind matrices, one per joint: joint space from mesh space.
    pub inverse_bindposes: &'a [Mat4],
    /// Each joint's parent among the skin's joints, if it has one there.
    pub parents: &'a [Option<usize>],
    /// The bind-pose triangles (indices into `positions`): with them each capsule is
    /// fitted to the volume its joint skins; empty, to the vertices.
    pub triangles: &'a [[u32; 3]],
}

/// One fitted capsule, in its joint's space: the points within `radius` of the segment
/// from `center − half_length · axis` to `center + half_length · axis`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FittedCapsule {
    /// The joint (index into the skin's joints).
    pub joint: usize,
    /// Centre of the core segment, joint space.
    pub center: Vec3,
    /// Unit direction of the core segment, joint space.
    pub axis: Vec3,
    /// Half the core segment's length, joint-space units.
    pub half_length: f32,
    /// Radius, joint-space units.
    pub radius: f32,
    /// The joint's vertices the fit saw.
    pub vertices: usize,
    /// The fraction of them inside the capsule.
    pub covered: f32,
}

impl FittedCapsule {
    /// Distance from `p` (joint space) to the capsule's surface, negative inside.
    pub fn distance(&self, p: Vec3) -> f32 {
        let t = (p - self.center)
            .dot(self.axis)
            .clamp(-self.half_length, self.half_length);
        (p - (self.center + t * self.axis)).length() - self.radius
    }

    /// The capsule's volume (joint-space units³).
    pub fn volume(&self) -> f32 {
        capsule_volume(self.radius, self.half_length)
    }
}

fn capsule_volume(radius: f32, half_length: f32) -> f32 {
    std::f32::consts::PI * radius * radius * (2.0 * half_length + 4.0 / 3.0 * radius)
}

/// The vertices each joint dominates: for joint `j`, the indices of the vertices whose
/// largest skin weight is `j`'s.
pub fn dominant_vertices(input: &SkinInput) -> Vec<Vec<usize>> {
    let joint_count = input.inverse_bindposes.len();
    let mut out = vec![Vec::new(); joint_count];
    let n = input
        .positions
        .len()
        .min(input.joints.len())
        .min(input.weights.len());
    for v in 0..n {
        if !input.positions[v].is_finite() {
            continue;
        }
        let mut best: Option<(usize, f32)> = None;
        for k in 0..4 {
            let (j, w) = (usize::from(input.joints[v][k]), input.weights[v][k]);
            // A NaN weight fails `w > 0`.
            if j < joint_count && w > 0.0 && best.is_none_or(|(_, bw)| w > bw) {
                best = Some((j, w));
            }
        }
        if let Some((j, _)) = best {
            out[j].push(v);
        }
    }
    out
}

/// Fits one capsule per joint that skins enough of the mesh (see the module docs).
/// Deterministic. The vertex fit is `O(vertices · log vertices)`; the volume fit adds
/// `O(triangles · columns they cover + cells · joints)` over a grid of about 96 cells
/// along the mesh's longest side (the Fox's 576 triangles and 24 joints: 43–55 ms at
/// opt-level 3).
pub fn fit_skin_capsules(input: &SkinInput, settings: &CapsuleFitSettings) -> Vec<FittedCapsule> {
    let coverage = if settings.coverage.is_finite() {
        settings.coverage.clamp(0.05, 1.0)
    } else {
        CapsuleFitSettings::default().coverage
    };
    let owned = dominant_vertices(input);
    let mut owner = vec![None; input.positions.len()];
    for (joint, vertices) in owned.iter().enumerate() {
        for &v in vertices {
            owner[v] = Some(joint);
        }
    }
    let solid = volume::SolidSamples::new(input.positions, input.triangles, &owner);
    // First each joint's capsule, then (by volume) the pieces that no first capsule
    // holds: where joints' parts overlap, a part inside another's capsule needs none.
    let mut fitted: Vec<Fitted> = Vec::new();
    for (joint, vertices) in owned.iter().enumerate() {
        let to_joint = input.inverse_bindposes[joint];
        if !to_joint.is_finite() || to_joint.determinant().abs() < 1e-12 {
            continue;
        }
        let points: Vec<Vec3> = vertices
            .iter()
            .map(|&v| to_joint.transform_point3(input.positions[v]))
            .filter(|p| p.is_finite())
            .collect();
        // With the volume, a joint is judged by the space it skins; else by its vertices.
        let samples = solid
            .as_ref()
            .map(|s| volume::JointSamples::new(s, joint, to_joint))
            .filter(|s| s.inside.len() >= volume::MIN_INSIDE_SAMPLES);
        if samples.is_none() && points.len() < settings.min_vertices.max(2) {
            continue;
        }
        let mut axes = bone_directions(input, joint);
        if points.len() >= 2 {
            axes.push(principal_axis(&points));
        }
        let first = if let Some(samples) = &samples {
            volume::first_capsule(samples, axes, joint)
        } else {
            axes.into_iter()
                .filter_map(|axis| fit_along(&points, axis, coverage))
                .min_by(|a, b| a.volume().total_cmp(&b.volume()))
        };
        if let Some(first) = first {
            fitted.push(Fitted {
                joint,
                to_joint,
                points,
                samples,
                capsules: vec![first],
            });
        }
    }
    let firsts: Vec<(Mat4, FittedCapsule)> =
        fitted.iter().map(|f| (f.to_joint, f.capsules[0])).collect();
    for f in &mut fitted {
        let Some(samples) = &f.samples else { continue };
        let to_mesh = f.to_joint.inverse();
        let covered = |p: Vec3| {
            let mesh = to_mesh.transform_point3(p);
            firsts.iter().any(|(to_joint, c)| {
                c.joint != f.joint && c.distance(to_joint.transform_point3(mesh)) <= 0.0
            })
        };
        let more = volume::piece_capsules(samples, &f.capsules[0], f.joint, covered);
        f.capsules.extend(more);
    }
    let mut capsules = Vec::new();
    for f in fitted {
        for mut capsule in f.capsules {
            capsule.joint = f.joint;
            capsule.vertices = f.points.len();
            let inside = f
                .points
                .iter()
                .filter(|p| capsule.distance(**p) <= capsule.radius * 1e-4)
                .count();
            capsule.covered = inside as f32 / f.points.len().max(1) as f32;
            capsules.push(capsule);
        }
    }
    let largest = capsules.iter().map(|c| c.radius).fold(0.0, f32::max);
    let min_radius = if settings.min_radius.is_finite() {
        settings.min_radius.max(0.0)
    } else {
        CapsuleFitSettings::default().min_radius
    };
    capsules.retain(|c| c.radius > 0.0 && c.radius >= min_radius * largest);
    capsules
}

/// A joint's fit under way: its space, vertices and samples, and its capsules.
struct Fitted {
    joint: usize,
    to_joint: Mat4,
    points: Vec<Vec3>,
    samples: Option<volume::JointSamples>,
    capsules: Vec<FittedCapsule>,
}

/// Unit directions from `joint` to each of its children's bind-pose origins, in its
/// space.
fn bone_directions(input: &SkinInput, joint: usize) -> Vec<Vec3> {
    input
        .parents
        .iter()
        .enumerate()
        .filter(|&(_, parent)| *parent == Some(joint))
        .filter_map(|(child, _)| {
            let child_origin = input
                .inverse_bindposes
                .get(child)?
                .inverse()
                .transform_point3(Vec3::ZERO);
            let local = input.inverse_bindposes[joint].transform_point3(child_origin);
            local.try_normalize()
        })
        .collect()
}

/// The unit eigenvector of the points' covariance with the largest eigenvalue (power
/// iteration from a direction near the box's diagonal, off every axis, so that it starts
/// on no other eigenvector of an axis-aligned set); `Vec3::Y` for a degenerate set.
fn principal_axis(points: &[Vec3]) -> Vec3 {
    let n = points.len() as f64;
    let mean = points
        .iter()
        .fold(glam::DVec3::ZERO, |s, p| s + p.as_dvec3())
        / n;
    let mut cov = glam::DMat3::ZERO;
    for p in points {
        let d = p.as_dvec3() - mean;
        cov += glam::DMat3::from_cols(d * d.x, d * d.y, d * d.z);
    }
    let cov = cov.as_mat3() / n as f32;
    let (min, max) = points
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
    let extent = max - min;
    let mut v = (extent + Vec3::new(0.013, 0.029, 0.041) * extent.max_element())
        .try_normalize()
        .unwrap_or(Vec3::Y);
    for _ in 0..64 {
        let Some(next) = (cov * v).try_normalize() else {
            return v;
        };
        v = next;
    }
    v
}

/// The `q`-quantile (nearest rank) of `values`, which it sorts.
fn quantile(values: &mut [f32], q: f32) -> f32 {
    values.sort_by(f32::total_cmp);
    let last = values.len() - 1;
    values[((q * last as f32).round() as usize).min(last)]
}

/// A capsule along `axis` through the points' centroid holding about `coverage` of
/// them; `None` for a degenerate axis.
fn fit_along(points: &[Vec3], axis: Vec3, coverage: f32) -> Option<FittedCapsule> {
    let axis = axis.try_normalize()?;
    let centroid = points.iter().copied().sum::<Vec3>() / points.len() as f32;
    let along: Vec<f32> = points.iter().map(|p| (*p - centroid).dot(axis)).collect();
    let radial: Vec<f32> = points
        .iter()
        .zip(&along)
        .map(|(p, t)| (*p - centroid - *t * axis).length())
        .collect();
    let q = coverage.sqrt();
    let radius = quantile(&mut radial.clone(), q);
    // Points within the radius constrain the segment: one at (t, r) is inside when an
    // end lies within h = √(R² − r²) of t along the axis.
    let (mut low, mut high): (Vec<f32>, Vec<f32>) = along
        .iter()
        .zip(&radial)
        .filter(|(_, r)| **r <= radius)
        .map(|(t, r)| {
            let h = (radius * radius - r * r).max(0.0).sqrt();
            (t + h, t - h)
        })
        .unzip();
    if low.is_empty() {
        return None;
    }
    let trim = (1.0 - q) * 0.5;
    let mut start = quantile(&mut low, trim);
    let mut end = quantile(&mut high, 1.0 - trim);
    if start > end {
        let mid = 0.5 * (start + end);
        (start, end) = (mid, mid);
    }
    let mut capsule = FittedCapsule {
        joint: 0,
        center: centroid + 0.5 * (start + end) * axis,
        axis,
        half_length: 0.5 * (end - start),
        radius,
        vertices: points.len(),
        covered: 0.0,
    };
    let inside = points
        .iter()
        .filter(|p| capsule.distance(**p) <= radius * 1e-4)
        .count();
    capsule.covered = inside as f32 / points.len() as f32;
    Some(capsule)
}

mod volume;

#[cfg(test)]
mod tests;
