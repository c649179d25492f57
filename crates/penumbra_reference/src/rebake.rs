//! Model of the GPU re-bake of a posed mesh (`shaders/df/rebake.wgsl`): per sample of a
//! [`RebakeGrid`], the distance to the nearest triangle (Quílez's point–triangle form)
//! and the sum of the triangles' solid angles (Van Oosterom and Strackee), both in `f32`
//! in the shader's triangle order; the sign from the winding number (inside above ½).
//!
//! Checked against independent truth in the tests: `penumbra_sdf::exact` (f64 brute
//! force, Ericson's closest point, its own winding number), analytic distances to a box,
//! ray parity on closed meshes, and the winding number on open ones.

use glam::{UVec3, Vec3};
use penumbra_df_core::rebake::RebakeGrid;

/// Nearest squared distance and summed solid angle at one sample.
#[derive(Clone, Copy, Debug)]
struct Accumulator {
    distance_squared: f32,
    solid_angle: f32,
}

fn dot2(v: Vec3) -> f32 {
    v.dot(v)
}

fn segment_distance_squared(e: Vec3, pa: Vec3) -> f32 {
    let t = (e.dot(pa) / dot2(e).max(1e-30)).clamp(0.0, 1.0);
    dot2(e * t - pa)
}

/// WGSL's `sign`: 0 at 0.
fn sign(x: f32) -> f32 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// Squared distance from `p` to triangle `abc` (the shader's
/// `triangle_distance_squared`).
pub fn triangle_distance_squared(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> f32 {
    let (ba, cb, ac) = (b - a, c - b, a - c);
    let (pa, pb, pc) = (p - a, p - b, p - c);
    let nor = ba.cross(ac);
    let inside =
        sign(ba.cross(nor).dot(pa)) + sign(cb.cross(nor).dot(pb)) + sign(ac.cross(nor).dot(pc));
    if inside < 2.0 {
        return segment_distance_squared(ba, pa)
            .min(segment_distance_squared(cb, pb))
            .min(segment_distance_squared(ac, pc));
    }
    let h = nor.dot(pa);
    h * h / dot2(nor)
}

/// Solid angle triangle `abc` subtends at `p`, positive seen from its back (the shader's
/// `solid_angle`).
pub fn solid_angle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> f32 {
    let (u, v, w) = (a - p, b - p, c - p);
    let (lu, lv, lw) = (u.length(), v.length(), w.length());
    let det = u.dot(v.cross(w));
    let div = lu * lv * lw + u.dot(v) * lw + v.dot(w) * lu + w.dot(u) * lv;
    if det == 0.0 && div == 0.0 {
        return 0.0;
    }
    2.0 * det.atan2(div)
}

/// One sample: signed distance in voxels and winding number, at `p` relative to the
/// grid's origin, over `corners` (relative to it too).
fn sample(p: Vec3, corners: &[[Vec3; 3]], voxel_size: f32) -> (f32, f32) {
    let acc = corners.iter().fold(
        Accumulator {
            distance_squared: 3.0e38,
            solid_angle: 0.0,
        },
        |acc, [a, b, c]| Accumulator {
            distance_squared: acc
                .distance_squared
                .min(triangle_distance_squared(p, *a, *b, *c)),
            solid_angle: acc.solid_angle + solid_angle(p, *a, *b, *c),
        },
    );
    let winding = acc.solid_angle / (4.0 * std::f32::consts::PI);
    let d = (acc.distance_squared.sqrt() / voxel_size).min(65504.0);
    (if winding > 0.5 { -d } else { d }, winding)
}

/// A bake's output as the model computes it.
#[derive(Clone, Debug)]
pub struct Rebake {
    /// The grid.
    pub grid: RebakeGrid,
    /// Signed distances in voxels, x fastest (`resolution³`).
    pub voxels: Vec<f32>,
    /// The winding number at each sample (where the sign came from).
    pub winding: Vec<f32>,
}

impl Rebake {
    /// The sample at `i`, voxels.
    pub fn at(&self, i: UVec3) -> f32 {
        let r = self.grid.resolution as usize;
        self.voxels[i.x as usize + r * (i.y as usize + r * i.z as usize)]
    }
}

/// The triangles as the pass reads them: non-finite ones left out (the CPU skips them
/// before upload), corners relative to the grid's origin.
pub fn relative_corners(triangles: &[[Vec3; 3]], grid: &RebakeGrid) -> Vec<[Vec3; 3]> {
    triangles
        .iter()
        .filter(|t| t.iter().all(|v| v.is_finite()))
        .map(|t| t.map(|v| v - grid.origin))
        .collect()
}

/// The re-bake of `triangles` (posed, in the grid's space) on `grid`.
pub fn rebake(triangles: &[[Vec3; 3]], grid: RebakeGrid) -> Rebake {
    let corners = relative_corners(triangles, &grid);
    let r = grid.resolution;
    let mut voxels = Vec::with_capacity((r * r * r) as usize);
    let mut winding = Vec::with_capacity(voxels.capacity());
    for k in 0..r {
        for j in 0..r {
            for i in 0..r {
                let p = UVec3::new(i, j, k).as_vec3() * grid.voxel_size;
                let (d, w) = sample(p, &corners, grid.voxel_size);
                voxels.push(d);
                winding.push(w);
            }
        }
    }
    Rebake {
        grid,
        voxels,
        winding,
    }
}

/// The posed triangles' bounds (finite corners only), `None` without any.
pub fn bounds(triangles: &[[Vec3; 3]]) -> Option<(Vec3, Vec3)> {
    let mut corners = triangles
        .iter()
        .filter(|t| t.iter().all(|v| v.is_finite()))
        .flatten();
    let first = *corners.next()?;
    Some(corners.fold((first, first), |(lo, hi), v| (lo.min(*v), hi.max(*v))))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use penumbra_sdf::{exact, shapes};

    /// A closed box `[-h, h]` (`penumbra_sdf::shapes`); `open_top` leaves out its +y
    /// face.
    fn cuboid(h: Vec3, open_top: bool) -> Vec<[Vec3; 3]> {
        let tris = shapes::cuboid(h).validate().expect("a box").0;
        tris.into_iter()
            .filter(|t| !(open_top && t.iter().all(|v| v.y == h.y)))
            .collect()
    }

    /// A UV sphere of `radius` (closed, counter-clockwise outside).
    fn sphere(radius: f32, stacks: u32, sectors: u32) -> Vec<[Vec3; 3]> {
        shapes::sphere(radius, sectors, stacks)
            .validate()
            .expect("a sphere")
            .0
    }

    fn analytic_box_distance(p: Vec3, h: Vec3) -> f32 {
        let q = p.abs() - h;
        q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
    }

    #[test]
    fn a_box_bakes_to_its_analytic_distance() {
        let h = Vec3::new(0.6, 0.3, 0.45);
        let tris = cuboid(h, false);
        let grid = RebakeGrid::around(-h, h, 16).expect("grid");
        let bake = rebake(&tris, grid);
        let mut worst = 0.0f32;
        for k in 0..16 {
            for j in 0..16 {
                for i in 0..16 {
                    let idx = UVec3::new(i, j, k);
                    let truth = analytic_box_distance(grid.position(idx), h) / grid.voxel_size;
                    worst = worst.max((bake.at(idx) - truth).abs());
                }
            }
        }
        // f32 over a 16-voxel box: well under a thousandth of a voxel.
        assert!(worst < 1e-3, "worst error {worst} voxels");
    }

    #[test]
    fn distances_and_winding_match_f64_brute_force() {
        let tris = sphere(0.5, 9, 14);
        let (lo, hi) = bounds(&tris).expect("bounds");
        let grid = RebakeGrid::around(lo, hi, 16).expect("grid");
        let bake = rebake(&tris, grid);
        let (mut worst_distance, mut worst_winding) = (0.0f64, 0.0f64);
        for k in 0..16 {
            for j in 0..16 {
                for i in 0..16 {
                    let idx = UVec3::new(i, j, k);
                    let p = grid.origin.as_dvec3() + idx.as_dvec3() * f64::from(grid.voxel_size);
                    let truth = exact::distance(p, &tris) / f64::from(grid.voxel_size);
                    let w = exact::winding_number(p, &tris);
                    let n = i as usize + 16 * (j as usize + 16 * k as usize);
                    worst_distance =
                        worst_distance.max((f64::from(bake.voxels[n].abs()) - truth).abs());
                    worst_winding = worst_winding.max((f64::from(bake.winding[n]) - w).abs());
                    // Closed: the winding number is 0 or 1, and the sign follows it.
                    assert_eq!(bake.voxels[n] < 0.0, w > 0.5, "sample {idx} (w = {w})");
                }
            }
        }
        assert!(
            worst_distance < 1e-3,
            "distance error {worst_distance} voxels"
        );
        assert!(worst_winding < 1e-4, "winding error {worst_winding}");
    }

    #[test]
    fn the_sign_agrees_with_ray_parity_on_a_closed_mesh() {
        let tris = sphere(0.4, 7, 10);
        let grid = RebakeGrid::around(Vec3::splat(-0.4), Vec3::splat(0.4), 16).expect("grid");
        let bake = rebake(&tris, grid);
        let dir = DVec3::new(0.267, 0.535, 0.802).normalize();
        for k in 0..16 {
            for j in 0..16 {
                for i in 0..16 {
                    let idx = UVec3::new(i, j, k);
                    let p = grid.position(idx).as_dvec3();
                    let crossings = tris.iter().filter(|t| ray_hits(p, dir, t)).count();
                    let d = bake.at(idx);
                    if d.abs() > 0.05 {
                        assert_eq!(d < 0.0, crossings % 2 == 1, "sample {idx}: {d} voxels");
                    }
                }
            }
        }
    }

    /// Möller–Trumbore in f64.
    fn ray_hits(o: DVec3, d: DVec3, t: &[Vec3; 3]) -> bool {
        let [a, b, c] = t.map(Vec3::as_dvec3);
        let (e1, e2) = (b - a, c - a);
        let p = d.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-15 {
            return false;
        }
        let s = o - a;
        let u = s.dot(p) / det;
        let q = s.cross(e1);
        let v = d.dot(q) / det;
        u >= 0.0 && v >= 0.0 && u + v <= 1.0 && e2.dot(q) / det > 0.0
    }

    #[test]
    fn an_open_box_stays_solid_inside() {
        // The top face missing (as a character's neck or sleeve is open): inside, the
        // five faces still subtend more than half the sphere, so it bakes solid; ray
        // parity would call half of it outside.
        let h = Vec3::splat(0.5);
        let tris = cuboid(h, true);
        let grid = RebakeGrid::around(-h, h, 16).expect("grid");
        let bake = rebake(&tris, grid);
        for k in 0..16 {
            for j in 0..16 {
                for i in 0..16 {
                    let idx = UVec3::new(i, j, k);
                    let p = grid.position(idx);
                    let deep_inside = (p.abs() - h * 0.7).max_element() < 0.0 && p.y < 0.2;
                    if deep_inside {
                        assert!(bake.at(idx) < 0.0, "sample {idx} at {p}: {}", bake.at(idx));
                    }
                    if analytic_box_distance(p, h) > 0.1 {
                        assert!(bake.at(idx) > 0.0, "sample {idx} at {p}");
                    }
                }
            }
        }
    }

    /// The runtime's CPU skinning (`penumbra_df_core::rebake::skinned_triangles`, fed
    /// as the plugin feeds it: joint world transforms times inverse binds) poses the Fox
    /// as this crate's glTF truth does (`posed_gltf`, its own skinning in f64).
    #[test]
    fn runtime_skinning_poses_the_fox_as_the_truth_does() {
        use crate::posed_gltf::{Pose, node_poses, posed_triangles};
        use glam::Mat4;
        use penumbra_df_core::rebake::skinned_triangles;
        let test = "runtime_skinning_poses_the_fox_as_the_truth_does";
        let Some(scenes) = penumbra_testkit::shared_dir(test, env!("CARGO_MANIFEST_DIR"), "scenes")
        else {
            return;
        };
        let path = scenes.join("Fox.glb");
        let pose = Pose {
            animation: 2,
            time: 0.4,
        };
        let gltf::Gltf { document, blob } =
            gltf::Gltf::from_slice(&std::fs::read(&path).expect("reads")).expect("parses");
        let blob = blob.expect("a GLB");
        let locals = node_poses(&path, pose).expect("poses");
        let mut world = vec![Mat4::IDENTITY; locals.len()];
        let mut stack: Vec<(gltf::Node, Mat4)> = document
            .default_scene()
            .expect("a scene")
            .nodes()
            .map(|n| (n, Mat4::IDENTITY))
            .collect();
        while let Some((node, parent)) = stack.pop() {
            let l = &locals[node.index()];
            let m =
                parent * Mat4::from_scale_rotation_translation(l.scale, l.rotation, l.translation);
            world[node.index()] = m;
            stack.extend(node.children().map(|c| (c, m)));
        }
        let mut ours = Vec::new();
        for node in document.nodes() {
            let (Some(mesh), Some(skin)) = (node.mesh(), node.skin()) else {
                continue;
            };
            let inverse_binds: Vec<Mat4> = skin
                .reader(|_| Some(&blob))
                .read_inverse_bind_matrices()
                .expect("inverse binds")
                .map(|m| Mat4::from_cols_array_2d(&m))
                .collect();
            let joint_from_bind: Vec<Mat4> = skin
                .joints()
                .zip(&inverse_binds)
                .map(|(j, ib)| world[j.index()] * *ib)
                .collect();
            for primitive in mesh.primitives() {
                let r = primitive.reader(|_| Some(&blob));
                let positions: Vec<Vec3> = r
                    .read_positions()
                    .expect("positions")
                    .map(Vec3::from)
                    .collect();
                let indices: Vec<u32> = r.read_indices().map_or_else(
                    || (0..positions.len() as u32).collect(),
                    |i| i.into_u32().collect(),
                );
                let joints: Vec<[u16; 4]> = r.read_joints(0).expect("joints").into_u16().collect();
                let weights: Vec<[f32; 4]> =
                    r.read_weights(0).expect("weights").into_f32().collect();
                ours.extend(skinned_triangles(
                    &positions,
                    &indices,
                    &joints,
                    &weights,
                    &joint_from_bind,
                ));
            }
        }
        let truth = posed_triangles(&path, Some(pose)).expect("the truth poses");
        assert_eq!(ours.len(), truth.triangles.len());
        let (lo, hi) = bounds(&truth.triangles).expect("bounds");
        let size = (hi - lo).max_element();
        let worst = ours
            .iter()
            .zip(&truth.triangles)
            .flat_map(|(a, b)| (0..3).map(move |k| (a[k] - b[k]).length()))
            .fold(0.0f32, f32::max);
        eprintln!(
            "{} triangles posed; farthest corner {worst:.2e} units apart ({size:.0} across)",
            ours.len()
        );
        assert!(worst < 1e-5 * size, "corners {worst} apart");
    }

    #[test]
    fn degenerate_and_non_finite_triangles_give_finite_samples() {
        let p = Vec3::new(0.1, 0.2, 0.3);
        let tris = vec![
            [Vec3::ZERO, Vec3::ZERO, Vec3::ZERO],
            [Vec3::ZERO, Vec3::X, Vec3::X * 2.0],
            [Vec3::NAN, Vec3::ONE, Vec3::Y],
        ];
        let grid = RebakeGrid::around(Vec3::ZERO, Vec3::splat(2.0), 16).expect("grid");
        let bake = rebake(&tris, grid);
        assert!(bake.voxels.iter().all(|v| v.is_finite()));
        // The segment: distance to it, not to a point.
        let d = triangle_distance_squared(p, Vec3::ZERO, Vec3::X, Vec3::X * 2.0).sqrt();
        assert!((d - (0.2f32 * 0.2 + 0.3 * 0.3).sqrt()).abs() < 1e-6);
        // A point: its distance.
        let d = triangle_distance_squared(p, Vec3::ONE, Vec3::ONE, Vec3::ONE).sqrt();
        assert!((d - (p - Vec3::ONE).length()).abs() < 1e-6);
        // No triangles: as far as f16 holds.
        let empty = rebake(&[], grid);
        assert!(empty.voxels.iter().all(|v| *v == 65504.0));
    }
}
