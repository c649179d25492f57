//! Procedural test meshes with known geometry, outward-oriented (counter-clockwise seen
//! from outside): the closed and open cases the baker is tested and benchmarked on.

use crate::mesh::TriMesh;
use glam::Vec3;
use std::f32::consts::{PI, TAU};

/// A parametric surface `f(u, v)`, `u, v ∈ [0, 1]`, tessellated into `nu × nv` quads.
/// `wrap_u`/`wrap_v` weld the seam; triangles are wound so that `∂f/∂u × ∂f/∂v` is the
/// front (outside).
fn parametric(
    nu: u32,
    nv: u32,
    wrap_u: bool,
    wrap_v: bool,
    f: impl Fn(f32, f32) -> Vec3,
) -> TriMesh {
    let cols = if wrap_u { nu } else { nu + 1 };
    let rows = if wrap_v { nv } else { nv + 1 };
    let mut positions = Vec::with_capacity((cols * rows) as usize);
    for j in 0..rows {
        for i in 0..cols {
            positions.push(f(i as f32 / nu as f32, j as f32 / nv as f32));
        }
    }
    let id = |i: u32, j: u32| (i % cols) + (j % rows) * cols;
    let mut triangles = Vec::with_capacity((2 * nu * nv) as usize);
    for j in 0..nv {
        for i in 0..nu {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    TriMesh {
        positions,
        triangles,
        ..Default::default()
    }
}

/// A UV sphere of `radius` around the origin (poles welded; the pole rows hold zero-area
/// triangles, which the baker drops).
pub fn sphere(radius: f32, sectors: u32, stacks: u32) -> TriMesh {
    // u: longitude, v: from the south pole (-Y) to the north pole (+Y).
    let mut m = parametric(sectors, stacks, true, false, |u, v| {
        if v <= 0.0 {
            return -radius * Vec3::Y;
        }
        if v >= 1.0 {
            return radius * Vec3::Y;
        }
        let (theta, phi) = (TAU * u, PI * v - PI / 2.0);
        radius * Vec3::new(phi.cos() * theta.cos(), phi.sin(), -phi.cos() * theta.sin())
    });
    weld(&mut m);
    m
}

/// A torus around the Y axis: ring radius `major`, tube radius `minor`.
pub fn torus(major: f32, minor: f32, segments: u32, sides: u32) -> TriMesh {
    parametric(segments, sides, true, true, |u, v| {
        let (theta, phi) = (TAU * u, TAU * v);
        let r = major + minor * phi.cos();
        Vec3::new(r * theta.cos(), minor * phi.sin(), -r * theta.sin())
    })
}

/// An axis-aligned box centred at the origin with the given half extents (12 triangles).
pub fn cuboid(half: Vec3) -> TriMesh {
    let p = |x: f32, y: f32, z: f32| Vec3::new(x * half.x, y * half.y, z * half.z);
    let positions = vec![
        p(-1.0, -1.0, -1.0),
        p(1.0, -1.0, -1.0),
        p(1.0, 1.0, -1.0),
        p(-1.0, 1.0, -1.0),
        p(-1.0, -1.0, 1.0),
        p(1.0, -1.0, 1.0),
        p(1.0, 1.0, 1.0),
        p(-1.0, 1.0, 1.0),
    ];
    let quads = [
        [0, 3, 2, 1], // -Z
        [4, 5, 6, 7], // +Z
        [0, 1, 5, 4], // -Y
        [3, 7, 6, 2], // +Y
        [0, 4, 7, 3], // -X
        [1, 2, 6, 5], // +X
    ];
    let triangles = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    TriMesh {
        positions,
        triangles,
        ..Default::default()
    }
}

/// An open sheet of `n × n` quads over `[−half, half]²` in x and z at heights
/// `height(x, z)`, counter-clockwise seen from above (normals up): a terrain.
pub fn height_sheet(n: u32, half: f32, height: impl Fn(f32, f32) -> f32) -> TriMesh {
    let at = |i: u32| -half + 2.0 * half * i as f32 / n as f32;
    let positions = (0..=n)
        .flat_map(|k| (0..=n).map(move |i| (at(i), at(k))))
        .map(|(x, z)| Vec3::new(x, height(x, z), z))
        .collect();
    let row = n + 1;
    let triangles = (0..n)
        .flat_map(|k| (0..n).map(move |i| k * row + i))
        .flat_map(|a| [[a, a + row, a + 1], [a + 1, a + row, a + row + 1]])
        .collect();
    TriMesh {
        positions,
        triangles,
        ..Default::default()
    }
}

/// A closed thin plate: a box `size.x × thickness × size.z`.
pub fn thin_plate(size_x: f32, size_z: f32, thickness: f32) -> TriMesh {
    cuboid(Vec3::new(size_x / 2.0, thickness / 2.0, size_z / 2.0))
}

/// An open hemispherical bowl of `radius` (the lower half of a sphere, rim at y = 0,
/// opening up), outside facing away from the centre. Open: its winding number is
/// fractional above the rim.
pub fn open_bowl(radius: f32, sectors: u32, stacks: u32) -> TriMesh {
    let mut m = parametric(sectors, stacks, true, false, |u, v| {
        if v <= 0.0 {
            return -radius * Vec3::Y;
        }
        let (theta, phi) = (TAU * u, -PI / 2.0 * (1.0 - v));
        radius * Vec3::new(phi.cos() * theta.cos(), phi.sin(), -phi.cos() * theta.sin())
    });
    weld(&mut m);
    m
}

/// A soup of intersecting closed shells: two overlapping boxes and a sphere through
/// both, concatenated without any boolean union (as modelling tools often export).
pub fn intersecting_soup() -> TriMesh {
    let mut out = cuboid(Vec3::new(0.6, 0.3, 0.3));
    let mut add = |mut m: TriMesh, offset: Vec3| {
        let base = out.positions.len() as u32;
        out.positions
            .extend(m.positions.drain(..).map(|p| p + offset));
        out.triangles
            .extend(m.triangles.iter().map(|t| t.map(|i| i + base)));
    };
    add(cuboid(Vec3::new(0.25, 0.6, 0.25)), Vec3::new(0.3, 0.2, 0.0));
    add(sphere(0.35, 24, 12), Vec3::new(-0.4, 0.1, 0.1));
    out
}

/// Merges vertices at identical positions (the poles of parametric spheres).
fn weld(m: &mut TriMesh) {
    let mut remap = Vec::with_capacity(m.positions.len());
    let mut unique: Vec<Vec3> = Vec::new();
    let mut index = std::collections::HashMap::new();
    for p in &m.positions {
        let key = p.to_array().map(f32::to_bits);
        let i = *index.entry(key).or_insert_with(|| {
            unique.push(*p);
            unique.len() as u32 - 1
        });
        remap.push(i);
    }
    m.positions = unique;
    for t in &mut m.triangles {
        *t = t.map(|i| remap[i as usize]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::exact;

    fn tris(m: &TriMesh) -> Vec<[Vec3; 3]> {
        m.validate().unwrap().0
    }

    #[test]
    fn closed_shapes_wind_once_inside_and_zero_outside() {
        for (name, m, inside) in [
            ("sphere", sphere(1.0, 32, 16), Vec3::new(0.1, 0.2, -0.3)),
            ("torus", torus(1.0, 0.3, 32, 16), Vec3::new(1.0, 0.0, 0.1)),
            (
                "cuboid",
                cuboid(Vec3::new(1.0, 0.5, 0.25)),
                Vec3::new(0.9, 0.4, 0.2),
            ),
            (
                "plate",
                thin_plate(1.0, 1.0, 0.02),
                Vec3::new(0.3, 0.005, 0.2),
            ),
        ] {
            let t = tris(&m);
            let w_in = exact::winding_number(inside.as_dvec3(), &t);
            let w_out = exact::winding_number(glam::DVec3::new(3.0, 2.0, 1.0), &t);
            assert!((w_in - 1.0).abs() < 1e-6, "{name}: inside {w_in}");
            assert!(w_out.abs() < 1e-6, "{name}: outside {w_out}");
        }
        // The torus hole is outside.
        let w_hole = exact::winding_number(glam::DVec3::ZERO, &tris(&torus(1.0, 0.3, 32, 16)));
        assert!(w_hole.abs() < 1e-6);
    }

    #[test]
    fn bowl_is_open_and_soup_overlaps() {
        let bowl = tris(&open_bowl(1.0, 32, 8));
        let w = exact::winding_number(glam::DVec3::new(0.0, -0.5, 0.0), &bowl);
        assert!(w > 0.5 && w < 0.99, "inside the bowl, below the rim: {w}");
        let soup = tris(&intersecting_soup());
        // Inside two shells at once: winding number 2.
        let w2 = exact::winding_number(glam::DVec3::new(0.3, 0.1, 0.0), &soup);
        assert!((w2 - 2.0).abs() < 1e-6, "{w2}");
    }

    #[test]
    fn sphere_vertices_lie_on_the_sphere() {
        let m = sphere(2.0, 16, 8);
        assert!(m.positions.iter().all(|p| (p.length() - 2.0).abs() < 1e-5));
        assert_eq!(m.positions.len(), 16 * 7 + 2);
    }
}
