//! Test and example inputs: a rock (a squashed, lumpy dome on a flat base — a UV seam
//! down its side, split normals and a second UV chart at its rim) and a height map that
//! does not tile, so an edge sampled at either side of a seam would crack.

use super::preprocess::{SourceMesh, TessellationInput};
use glam::{Vec2, Vec3};

/// A triangle-list mesh with every attribute.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ShapeMesh {
    /// Positions.
    pub positions: Vec<Vec3>,
    /// Normals (split where the surface creases).
    pub normals: Vec<Vec3>,
    /// Texture coordinates (split at seams).
    pub uvs: Vec<Vec2>,
    /// Triangle list, counter-clockwise seen from outside.
    pub indices: Vec<u32>,
}

fn lump(d: Vec3) -> f32 {
    1.0 + 0.12 * (3.1 * d.x + 1.3).sin() * (2.3 * d.z - 0.4).cos()
        + 0.06 * (5.7 * d.y + 2.1 * d.x).sin()
}

/// The rock: `segments` around, `rings` from the top to the rim, radius 1 (0.7 tall).
pub fn rock(segments: u32, rings: u32) -> ShapeMesh {
    let mut m = ShapeMesh::default();
    let point = |r: u32, s: u32| {
        let theta = std::f32::consts::FRAC_PI_2 * r as f32 / rings as f32;
        let phi = std::f32::consts::TAU * (s % segments) as f32 / segments as f32;
        let d = Vec3::new(
            theta.sin() * phi.cos(),
            theta.cos(),
            -theta.sin() * phi.sin(),
        );
        let p = d * lump(d);
        Vec3::new(p.x, p.y * 0.7, p.z)
    };
    // Dome: the top vertex, then rings 1..=rings with a seam column at s = segments.
    m.positions.push(point(0, 0));
    m.uvs.push(Vec2::new(0.5, 0.0));
    for r in 1..=rings {
        for s in 0..=segments {
            m.positions.push(if r == rings {
                rim(point(r, s))
            } else {
                point(r, s)
            });
            m.uvs.push(Vec2::new(
                s as f32 / segments as f32,
                r as f32 / rings as f32 * 0.8,
            ));
        }
    }
    let ring = |r: u32, s: u32| 1 + (r - 1) * (segments + 1) + s;
    for s in 0..segments {
        m.indices.extend([0, ring(1, s), ring(1, s + 1)]);
    }
    for r in 1..rings {
        for s in 0..segments {
            let (a, b, c, d) = (
                ring(r, s),
                ring(r, s + 1),
                ring(r + 1, s),
                ring(r + 1, s + 1),
            );
            m.indices.extend([a, c, d, a, d, b]);
        }
    }
    let dome = m.positions.len();
    smooth_normals(&mut m);
    // Base: the rim again (split normal, planar UVs) and a centre.
    let centre = m.positions.len() as u32;
    m.positions.push(Vec3::ZERO);
    m.normals.push(-Vec3::Y);
    m.uvs.push(Vec2::new(0.5, 0.9));
    for s in 0..segments {
        let p = m.positions[ring(rings, s) as usize];
        m.positions.push(p);
        m.normals.push(-Vec3::Y);
        m.uvs.push(Vec2::new(0.5 + p.x * 0.1, 0.9 + p.z * 0.1));
    }
    for s in 0..segments {
        let (a, b) = (centre + 1 + s, centre + 1 + (s + 1) % segments);
        m.indices.extend([centre, a, b]);
    }
    debug_assert!(dome < m.positions.len());
    m
}

/// The rim sits on the ground plane.
fn rim(p: Vec3) -> Vec3 {
    Vec3::new(p.x, 0.0, p.z)
}

/// Angle-weighted normals per position over the triangles so far (the dome): the
/// preprocessing's own (`TessellationInput`'s smooth normals).
fn smooth_normals(m: &mut ShapeMesh) {
    let input = TessellationInput::new(SourceMesh {
        positions: &m.positions,
        normals: None,
        uvs: None,
        tangents: None,
        indices: &m.indices,
    })
    .expect("the dome is a valid mesh");
    m.normals = input.vertices.iter().map(|v| v.smooth_normal).collect();
}

/// A `size²` height map in `[0, 1]` of cobbles and ripples that does not tile (texels
/// at `u = 0` and `u = 1` differ).
pub fn height_map(size: u32) -> Vec<f32> {
    let mut out = Vec::with_capacity((size * size) as usize);
    for y in 0..size {
        for x in 0..size {
            let uv = (Vec2::new(x as f32, y as f32) + 0.5) / size as f32;
            let cell = (uv * 6.0).fract() - 0.5;
            let cobble = (1.0 - cell.length() * 2.2).max(0.0).powf(0.6);
            let ripple = 0.5 + 0.5 * (uv.x * 23.0 + uv.y * 7.0).sin();
            out.push((0.65 * cobble + 0.25 * ripple + 0.1 * uv.x).clamp(0.0, 1.0));
        }
    }
    out
}
