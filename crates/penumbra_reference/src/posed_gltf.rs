//! A glTF scene's triangles in an animation's pose: the ground truth for characters.
//!
//! Independent of Bevy and of Penumbra's fits: the `gltf` crate's readers, the
//! animation's channels sampled at a time (step, linear with quaternion slerp, or cubic
//! spline as glTF 2.0 §3.11 defines them), node transforms composed from the roots, and
//! skinned meshes deformed by linear blend skinning (`Σ wₖ · jointₖ · inverse_bindₖ · p`;
//! a skinned mesh's own node transform is ignored, as the specification and Bevy do).
//! Morph targets are ignored. Buffers: the GLB chunk, base64 `data:` URIs, or files
//! beside a `.gltf`.

use glam::{DMat4, DQuat, DVec3, Vec3};
use std::path::Path;

/// Which animation, and when.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Index of the animation in the file.
    pub animation: usize,
    /// Seconds from its start (clamped to its samples' range per channel).
    pub time: f32,
}

/// A posed scene's triangles (world space) and, per triangle, whether its material is
/// double-sided and whether it is see-through (alpha-blended or transmissive).
pub struct PosedTriangles {
    /// World-space corners.
    pub triangles: Vec<[Vec3; 3]>,
    /// Per triangle: double-sided material.
    pub double_sided: Vec<bool>,
    /// Per triangle: alpha-blended or transmissive material.
    pub see_through: Vec<bool>,
    /// Per triangle: from a skinned mesh.
    pub skinned: Vec<bool>,
}

fn buffers(
    document: &gltf::Document,
    blob: Option<Vec<u8>>,
    dir: Option<&Path>,
) -> Result<Vec<Vec<u8>>, String> {
    document
        .buffers()
        .map(|b| match b.source() {
            gltf::buffer::Source::Bin => blob.clone().ok_or_else(|| "no GLB binary chunk".into()),
            gltf::buffer::Source::Uri(uri) => {
                if let Some(rest) = uri.strip_prefix("data:") {
                    let (_, payload) = rest.split_once(";base64,").ok_or("bad data URI")?;
                    use base64::Engine;
                    base64::engine::general_purpose::STANDARD
                        .decode(payload)
                        .map_err(|e| e.to_string())
                } else {
                    let dir = dir.ok_or("an external buffer needs the file's directory")?;
                    std::fs::read(dir.join(uri)).map_err(|e| format!("{uri}: {e}"))
                }
            }
        })
        .collect()
}

/// Sampled local transforms (translation, rotation, scale) of the animated nodes.
fn sample(
    document: &gltf::Document,
    buffers: &[Vec<u8>],
    pose: Pose,
    trs: &mut [(DVec3, DQuat, DVec3)],
) -> Result<(), String> {
    use gltf::animation::{Interpolation, Property, util::ReadOutputs};
    let animation = document
        .animations()
        .nth(pose.animation)
        .ok_or_else(|| format!("no animation {}", pose.animation))?;
    for channel in animation.channels() {
        let reader = channel.reader(|b| Some(&buffers[b.index()]));
        let times: Vec<f32> = reader.read_inputs().ok_or("no sampler input")?.collect();
        let values: Vec<[f64; 4]> = match reader.read_outputs().ok_or("no sampler output")? {
            ReadOutputs::Translations(v) | ReadOutputs::Scales(v) => v
                .map(|t| [f64::from(t[0]), f64::from(t[1]), f64::from(t[2]), 0.0])
                .collect(),
            ReadOutputs::Rotations(r) => r.into_f32().map(|q| q.map(f64::from)).collect(),
            ReadOutputs::MorphTargetWeights(_) => continue,
        };
        if times.is_empty() {
            continue;
        }
        if times.iter().any(|t| !t.is_finite()) || times.windows(2).any(|w| w[0] > w[1]) {
            return Err("sampler input times not finite and increasing".into());
        }
        let cubic = channel.sampler().interpolation() == Interpolation::CubicSpline;
        // Cubic splines store (in-tangent, value, out-tangent) per key.
        let value = |k: usize| if cubic { values[3 * k + 1] } else { values[k] };
        if values.len() < times.len() * if cubic { 3 } else { 1 } {
            return Err("sampler output shorter than its input".into());
        }
        let t = pose.time.clamp(times[0], times[times.len() - 1]);
        let k = times.partition_point(|&x| x <= t).saturating_sub(1);
        let k1 = (k + 1).min(times.len() - 1);
        let span = f64::from(times[k1] - times[k]);
        let s = if span > 0.0 {
            f64::from(t - times[k]) / span
        } else {
            0.0
        };
        let rotation = channel.target().property() == Property::Rotation;
        let v: [f64; 4] = match channel.sampler().interpolation() {
            Interpolation::Step => value(k),
            Interpolation::Linear if rotation => {
                let a = DQuat::from_array(value(k));
                let b = DQuat::from_array(value(k1));
                a.slerp(b, s).to_array()
            }
            Interpolation::Linear => {
                let (a, b) = (value(k), value(k1));
                std::array::from_fn(|i| a[i] + (b[i] - a[i]) * s)
            }
            Interpolation::CubicSpline => {
                let (p0, m0) = (values[3 * k + 1], values[3 * k + 2]);
                let (p1, m1) = (values[3 * k1 + 1], values[3 * k1]);
                let (s2, s3) = (s * s, s * s * s);
                let h = [
                    2.0 * s3 - 3.0 * s2 + 1.0,
                    (s3 - 2.0 * s2 + s) * span,
                    -2.0 * s3 + 3.0 * s2,
                    (s3 - s2) * span,
                ];
                std::array::from_fn(|i| h[0] * p0[i] + h[1] * m0[i] + h[2] * p1[i] + h[3] * m1[i])
            }
        };
        let node = &mut trs[channel.target().node().index()];
        match channel.target().property() {
            Property::Translation => node.0 = DVec3::new(v[0], v[1], v[2]),
            Property::Rotation => node.1 = DQuat::from_array(v).normalize(),
            Property::Scale => node.2 = DVec3::new(v[0], v[1], v[2]),
            Property::MorphTargetWeights => {}
        }
    }
    Ok(())
}

/// A node's local transform in a pose.
#[derive(Clone, Debug, PartialEq)]
pub struct NodePose {
    /// The node's name, if it has one.
    pub name: Option<String>,
    /// Translation.
    pub translation: Vec3,
    /// Rotation.
    pub rotation: glam::Quat,
    /// Scale.
    pub scale: Vec3,
}

type Loaded = (gltf::Document, Vec<Vec<u8>>, Vec<(DVec3, DQuat, DVec3)>);

/// The document, its buffers and every node's local transform in `pose`.
fn load_posed(path: &Path, pose: Option<Pose>) -> Result<Loaded, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let gltf::Gltf { document, blob } =
        gltf::Gltf::from_slice(&bytes).map_err(|e| format!("{}: {e}", path.display()))?;
    let buffers = buffers(&document, blob, path.parent())?;
    let mut trs: Vec<(DVec3, DQuat, DVec3)> = document
        .nodes()
        .map(|n| {
            let (t, r, s) = n.transform().decomposed();
            (
                DVec3::from_array(t.map(f64::from)),
                DQuat::from_array(r.map(f64::from)).normalize(),
                DVec3::from_array(s.map(f64::from)),
            )
        })
        .collect();
    if let Some(pose) = pose {
        sample(&document, &buffers, pose, &mut trs)?;
    }
    Ok((document, buffers, trs))
}

/// Every node's local transform in `pose`, by node index: what an app sets on the
/// nodes' entities to show that pose (the scene viewer's `--animation`).
pub fn node_poses(path: &Path, pose: Pose) -> Result<Vec<NodePose>, String> {
    let (document, _, trs) = load_posed(path, Some(pose))?;
    Ok(document
        .nodes()
        .zip(trs)
        .map(|(node, (t, r, s))| NodePose {
            name: node.name().map(str::to_string),
            translation: t.as_vec3(),
            rotation: r.as_quat(),
            scale: s.as_vec3(),
        })
        .collect())
}

/// The default scene's triangles in `pose` (or the rest pose: the nodes' own
/// transforms, skinned meshes still skinned by their joints there).
pub fn posed_triangles(path: &Path, pose: Option<Pose>) -> Result<PosedTriangles, String> {
    let (document, buffers, trs) = load_posed(path, pose)?;
    // World transforms, from the default scene's roots.
    let scene = document
        .default_scene()
        .or_else(|| document.scenes().next())
        .ok_or("the file has no scene")?;
    let mut world = vec![None; trs.len()];
    let mut stack: Vec<(gltf::Node, DMat4)> = scene.nodes().map(|n| (n, DMat4::IDENTITY)).collect();
    while let Some((node, parent)) = stack.pop() {
        let (t, r, s) = trs[node.index()];
        let m = parent * DMat4::from_scale_rotation_translation(s, r, t);
        if world[node.index()].replace(m).is_some() {
            return Err("the node graph is not a forest".into());
        }
        stack.extend(node.children().map(|c| (c, m)));
    }
    let mut out = PosedTriangles {
        triangles: Vec::new(),
        double_sided: Vec::new(),
        see_through: Vec::new(),
        skinned: Vec::new(),
    };
    for node in document.nodes() {
        let (Some(mesh), Some(node_world)) = (node.mesh(), world[node.index()]) else {
            continue;
        };
        let skin: Option<Vec<DMat4>> = match node.skin() {
            Some(skin) => {
                let inverse: Vec<DMat4> = skin
                    .reader(|b| Some(&buffers[b.index()]))
                    .read_inverse_bind_matrices()
                    .map(|m| {
                        m.map(|c| DMat4::from_cols_array_2d(&c.map(|r| r.map(f64::from))))
                            .collect()
                    })
                    .unwrap_or_default();
                let joints = skin
                    .joints()
                    .enumerate()
                    .map(|(k, j)| {
                        let joint = world[j.index()].ok_or("a joint outside the scene")?;
                        Ok(joint * inverse.get(k).copied().unwrap_or(DMat4::IDENTITY))
                    })
                    .collect::<Result<Vec<_>, String>>()?;
                Some(joints)
            }
            None => None,
        };
        let flip = skin.is_none() && node_world.determinant() < 0.0;
        for primitive in mesh.primitives() {
            if primitive.mode() != gltf::mesh::Mode::Triangles {
                continue;
            }
            let reader = primitive.reader(|b| Some(&buffers[b.index()]));
            let Some(positions) = reader.read_positions() else {
                continue;
            };
            let mut points: Vec<DVec3> = positions
                .map(|p| DVec3::from_array(p.map(f64::from)))
                .collect();
            match &skin {
                Some(joints) => {
                    let j: Vec<[u16; 4]> = reader
                        .read_joints(0)
                        .ok_or("a skinned primitive without JOINTS_0")?
                        .into_u16()
                        .collect();
                    let w: Vec<[f32; 4]> = reader
                        .read_weights(0)
                        .ok_or("a skinned primitive without WEIGHTS_0")?
                        .into_f32()
                        .collect();
                    if j.len() < points.len() || w.len() < points.len() {
                        return Err("JOINTS_0 or WEIGHTS_0 shorter than POSITION".into());
                    }
                    for (i, p) in points.iter_mut().enumerate() {
                        let mut posed = DVec3::ZERO;
                        for k in 0..4 {
                            let m = joints
                                .get(usize::from(j[i][k]))
                                .ok_or("a joint index out of range")?;
                            posed += f64::from(w[i][k]) * m.transform_point3(*p);
                        }
                        *p = posed;
                    }
                }
                None => {
                    for p in &mut points {
                        *p = node_world.transform_point3(*p);
                    }
                }
            }
            let indices: Vec<u32> = match reader.read_indices() {
                Some(i) => i.into_u32().collect(),
                None => (0..points.len() as u32).collect(),
            };
            let material = primitive.material();
            let see_through = material.alpha_mode() == gltf::material::AlphaMode::Blend
                || material
                    .transmission()
                    .is_some_and(|t| t.transmission_factor() > 0.0);
            for t in indices.chunks_exact(3) {
                let corner = |i: u32| points.get(i as usize).map(|p| p.as_vec3());
                let (Some(a), Some(b), Some(c)) = (corner(t[0]), corner(t[1]), corner(t[2])) else {
                    return Err("an index out of range".into());
                };
                out.triangles.push(if flip { [a, c, b] } else { [a, b, c] });
                out.double_sided.push(material.double_sided());
                out.see_through.push(see_through);
                out.skinned.push(skin.is_some());
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests;
