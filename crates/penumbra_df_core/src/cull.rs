//! Frustum culling of object records: the CPU reference of the GPU culling pass
//! (`shaders/df/cull.wgsl`), which must produce the same set of slots.
//!
//! Positions are **camera-relative**: a record's tile-relative position is moved to the
//! camera's tile as `(tile − camera_tile) × TILE_SIZE + (position − camera_offset)`, so
//! the numbers stay small wherever the scene is. The test is exact for the record's
//! oriented bounding box against each plane (the box's projected radius
//! `Σ |n · axisᵢ|`), conservative near frustum corners (a box outside the frustum but
//! straddling two planes' corner is kept), like every plane-based culler.

use crate::object::{ObjectRecord, ShapeKind, TILE_SIZE, flags, tile_of, tile_relative};
use glam::{Mat4, Vec3, Vec4};

/// Where the camera is: its tile and its position within the tile.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraOrigin {
    /// The tile.
    pub tile: [i32; 3],
    /// Position relative to the tile (`position − tile × TILE_SIZE`).
    pub offset: Vec3,
}

impl CameraOrigin {
    /// The origin of a camera at world position `p`; `None` when `p` is not finite or
    /// beyond the tile range.
    pub fn at(p: Vec3) -> Option<CameraOrigin> {
        let tile = tile_of(p)?;
        p.is_finite().then(|| CameraOrigin {
            tile,
            offset: tile_relative(p, tile),
        })
    }

    /// A record's tile-relative position `p`, relative to the camera.
    pub fn relative(&self, tile: [i32; 3], p: Vec3) -> Vec3 {
        let d = Vec3::new(
            (tile[0] - self.tile[0]) as f32,
            (tile[1] - self.tile[1]) as f32,
            (tile[2] - self.tile[2]) as f32,
        );
        d * TILE_SIZE + (p - self.offset)
    }
}

/// Up to six planes `n · p + w ≥ 0` (unit `n`) bounding the visible volume, in
/// camera-relative world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frustum {
    /// The planes; degenerate ones (an infinite far plane) are `(0, 0, 0, 1)`.
    pub planes: [Vec4; 6],
}

impl Frustum {
    /// The frustum of `clip_from_relative`: the view-projection matrix applied to
    /// camera-relative world positions (the view matrix without its translation).
    /// wgpu clip space: `−w ≤ x, y ≤ w`, `0 ≤ z ≤ w` (Bevy's reverse-Z infinite
    /// projections give one plane at infinity, which never culls).
    pub fn from_clip_from_relative(m: Mat4) -> Frustum {
        let r = [m.row(0), m.row(1), m.row(2), m.row(3)];
        let raw = [
            r[3] + r[0],
            r[3] - r[0],
            r[3] + r[1],
            r[3] - r[1],
            r[2],
            r[3] - r[2],
        ];
        Frustum {
            planes: raw.map(|p| {
                let len = p.truncate().length();
                if len > 1e-12 * p.w.abs().max(1.0) {
                    p / len
                } else if p.w >= 0.0 {
                    Vec4::new(0.0, 0.0, 0.0, 1.0)
                } else {
                    // Nothing satisfies it: an empty frustum.
                    Vec4::new(0.0, 0.0, 0.0, -1.0)
                }
            }),
        }
    }

    /// Whether the box `center ± Σ axes` (axes are half-extent vectors) may be visible.
    pub fn intersects_obb(&self, center: Vec3, axes: [Vec3; 3]) -> bool {
        self.planes.iter().all(|p| {
            let n = p.truncate();
            let radius = axes.iter().map(|a| n.dot(*a).abs()).sum::<f32>();
            n.dot(center) + p.w >= -radius
        })
    }
}

/// Words of the culling pass's `CullView` uniform (`shaders/df/cull.wgsl`, 144 bytes):
/// planes, camera tile, camera offset, object count and the dispatch row width.
pub fn cull_view_words(
    frustum: &Frustum,
    camera: &CameraOrigin,
    objects: u32,
    groups_x: u32,
) -> Vec<u32> {
    let mut words = Vec::with_capacity(36);
    for p in frustum.planes {
        words.extend(p.to_array().map(f32::to_bits));
    }
    words.extend([
        camera.tile[0] as u32,
        camera.tile[1] as u32,
        camera.tile[2] as u32,
        0,
    ]);
    words.extend(camera.offset.extend(0.0).to_array().map(f32::to_bits));
    words.extend([objects, groups_x, 0, 0]);
    words
}

/// Workgroups of 64 covering `n` invocations as a 2D grid (x ≤ 65535, the portable
/// limit): `([x, y, 1], x)`; shaders rebuild the index as `id.x + id.y · x · 64`.
pub fn grid_64(n: u32) -> ([u32; 3], u32) {
    let groups = n.div_ceil(64).max(1);
    let x = groups.min(65_535);
    ([x, groups.div_ceil(x), 1], x)
}

/// Whether a record survives culling: live, visible, and unbounded or intersecting the
/// frustum.
pub fn is_visible(record: &ObjectRecord, camera: &CameraOrigin, frustum: &Frustum) -> bool {
    let f = record.flags();
    if f & flags::LIVE == 0 || f & flags::VISIBLE == 0 {
        return false;
    }
    let Some((min, max)) = record.shape_bounds() else {
        return f & flags::UNBOUNDED != 0;
    };
    let m = record.world_from_shape();
    let center = m.transform_point3((min + max) * 0.5);
    let half = (max - min) * 0.5;
    let axes = [
        Vec3::from(m.matrix3.x_axis) * half.x,
        Vec3::from(m.matrix3.y_axis) * half.y,
        Vec3::from(m.matrix3.z_axis) * half.z,
    ];
    frustum.intersects_obb(camera.relative(record.tile(), center), axes)
}

/// The slots that survive culling, in increasing order.
pub fn cull(records: &[ObjectRecord], camera: &CameraOrigin, frustum: &Frustum) -> Vec<u32> {
    records
        .iter()
        .enumerate()
        .filter(|(_, r)| is_visible(r, camera, frustum))
        .map(|(i, _)| i as u32)
        .collect()
}

/// Bounds of a cull volume: `(centre, radius)` in camera-relative metres.
pub type Ball = (Vec3, f32);

/// The bounding sphere of a live object's shape (camera-relative), or `None` for
/// unbounded shapes (planes): for spheres and capsules, their own radius (and half
/// length) scaled by a bound of the transform's largest singular value (Gershgorin on
/// `MᵀM`: exact without shear); for boxes and volumes, the largest of the transformed
/// box's four half-diagonals (exact for the parallelepiped).
pub fn bounding_sphere(r: &ObjectRecord, camera: &CameraOrigin) -> Option<Ball> {
    let (min, max) = r.shape_bounds()?;
    let m = r.world_from_shape();
    let half = (max - min) * 0.5;
    let center = camera.relative(r.tile(), m.transform_point3((min + max) * 0.5));
    let (cx, cy, cz) = (
        Vec3::from(m.matrix3.x_axis),
        Vec3::from(m.matrix3.y_axis),
        Vec3::from(m.matrix3.z_axis),
    );
    let [p0, p1, _] = r.params();
    let radius = match r.kind() {
        k if k == ShapeKind::Sphere as u32 => f32::from_bits(p0) * max_scale(cx, cy, cz),
        k if k == ShapeKind::Capsule as u32 => {
            cy.length() * f32::from_bits(p1) + f32::from_bits(p0) * max_scale(cx, cy, cz)
        }
        _ => {
            let (ax, ay, az) = (cx * half.x, cy * half.y, cz * half.z);
            (ax + ay + az)
                .length()
                .max((ax + ay - az).length())
                .max((ax - ay + az).length().max((ax - ay - az).length()))
        }
    };
    Some((center, radius))
}

/// An upper bound of the largest singular value of the matrix with columns `c0, c1, c2`:
/// the square root of Gershgorin's bound on `MᵀM`'s largest eigenvalue (exact when the
/// columns are orthogonal: rotation times scale).
pub fn max_scale(c0: Vec3, c1: Vec3, c2: Vec3) -> f32 {
    let (g01, g02, g12) = (c0.dot(c1).abs(), c0.dot(c2).abs(), c1.dot(c2).abs());
    (c0.length_squared() + g01 + g02)
        .max(c1.length_squared() + g01 + g12)
        .max(c2.length_squared() + g02 + g12)
        .sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::object::{CasterShape, ObjectDesc, encode};
    use glam::{Affine3A, Quat};

    fn camera(eye: Vec3, target: Vec3) -> (CameraOrigin, Frustum) {
        let origin = CameraOrigin::at(eye).unwrap();
        // Bevy's default: reverse-Z infinite perspective.
        let proj = Mat4::perspective_infinite_reverse_rh(1.0, 1.5, 0.1);
        let view = Mat4::look_at_rh(Vec3::ZERO, target - eye, Vec3::Y);
        (origin, Frustum::from_clip_from_relative(proj * view))
    }

    fn sphere(at: Vec3, r: f32) -> ObjectRecord {
        encode(&ObjectDesc {
            world_from_local: Affine3A::from_translation(at),
            shape: CasterShape::Sphere { radius: r },
            flags: flags::VISIBLE,
        })
        .unwrap()
    }

    /// Culling agrees with projecting sampled points of each sphere: every sphere with a
    /// point on screen is kept; kept spheres are at most slightly off screen.
    #[test]
    fn culling_matches_projection() {
        for eye in [Vec3::new(0.0, 1.0, 5.0), Vec3::new(1e5, 3.0, -2e5)] {
            let (origin, frustum) = camera(eye, eye + Vec3::new(0.3, -0.1, -1.0));
            let proj = Mat4::perspective_infinite_reverse_rh(1.0, 1.5, 0.1);
            let view = Mat4::look_at_rh(eye, eye + Vec3::new(0.3, -0.1, -1.0), Vec3::Y);
            let mut s = 1u64;
            let mut rnd = move || {
                s = s
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                (s >> 40) as f32 / (1u64 << 24) as f32 - 0.5
            };
            let (mut kept, mut on_screen) = (0, 0);
            for _ in 0..2000 {
                let c = eye + Vec3::new(rnd(), rnd(), rnd()) * 60.0;
                let r = 0.2 + (rnd() + 0.5) * 2.0;
                let rec = sphere(c, r);
                let visible = is_visible(&rec, &origin, &frustum);
                // Sample the sphere's surface and centre in f64 around the eye.
                let any_on_screen = (0..200).any(|k| {
                    let t = k as f32 * 2.399_963;
                    let z = 1.0 - 2.0 * (k as f32 + 0.5) / 200.0;
                    let d = Vec3::new(
                        (1.0 - z * z).sqrt() * t.cos(),
                        (1.0 - z * z).sqrt() * t.sin(),
                        z,
                    );
                    let p = c + d * r * (k % 2) as f32;
                    let clip = proj * view * p.extend(1.0);
                    clip.w > 0.0
                        && clip.x.abs() <= clip.w
                        && clip.y.abs() <= clip.w
                        && clip.z >= 0.0
                        && clip.z <= clip.w
                });
                if any_on_screen {
                    on_screen += 1;
                    assert!(visible, "eye {eye}: sphere {c} r {r} on screen but culled");
                }
                kept += usize::from(visible);
            }
            assert!(on_screen > 100, "{on_screen}");
            // Conservative only at corners: few false positives.
            assert!(
                kept <= on_screen + on_screen / 5 + 5,
                "kept {kept}, on screen {on_screen}"
            );
        }
    }

    #[test]
    fn flags_and_unbounded_shapes() {
        let (origin, frustum) = camera(Vec3::ZERO, -Vec3::Z);
        let mut invisible = sphere(-5.0 * Vec3::Z, 1.0);
        invisible.0[27] &= !flags::VISIBLE;
        assert!(!is_visible(&invisible, &origin, &frustum));
        assert!(!is_visible(&ObjectRecord::EMPTY, &origin, &frustum));
        let plane = encode(&ObjectDesc {
            world_from_local: Affine3A::from_rotation_translation(
                Quat::IDENTITY,
                Vec3::new(0.0, -1.0, 50.0),
            ),
            shape: CasterShape::Plane,
            flags: flags::VISIBLE,
        })
        .unwrap();
        assert!(is_visible(&plane, &origin, &frustum));
        let behind = sphere(5.0 * Vec3::Z, 1.0);
        assert!(!is_visible(&behind, &origin, &frustum));
        assert_eq!(
            cull(
                &[behind, invisible, sphere(-5.0 * Vec3::Z, 1.0)],
                &origin,
                &frustum
            ),
            vec![2]
        );
    }
}
