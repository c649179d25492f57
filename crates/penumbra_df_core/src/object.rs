//! The GPU record of one distance-field caster instance, and its encoding.
//!
//! One record is 128 bytes (32 little-endian words), so a million casters fit one
//! 128 MiB storage binding. WGSL view (`shaders/df/object.wgsl`, `DistanceFieldObject`):
//!
//! | words | field | meaning |
//! |---|---|---|
//! | 0–11 | `shape_from_world: mat3x4` rows | tile-relative world position → shape space |
//! | 12–23 | `world_from_shape: mat3x4` rows | shape space → tile-relative world position |
//! | 24–26 | `tile: vec3<i32>` | world position = `tile × TILE_SIZE` + the above |
//! | 27 | `flags: u32` | [`flags`] bits; shape kind in bits 8–11; AO transmission in bits 16–23 |
//! | 28–30 | `params: vec3<u32>` | per kind, see [`CasterShape`] |
//! | 31 | `conservative_scale: f32` | world metres per shape-space distance unit: the smallest singular value of the linear part (times the voxel size for volumes), so a distance read in shape space times this never overestimates the world distance, however non-uniform the scale |
//!
//! *Shape space* is the shape's own frame: for an SDF volume, its **voxel** coordinates
//! (sample `(i, j, k)` at `(i, j, k)`), so that an atlas lookup is
//! `atlas_origin + p + ½`; for analytic shapes, the mesh-like local frame the shape is
//! centred in. Distances read in shape space are in *local units* for analytic shapes and
//! in *voxels* for volumes (whose texels hold voxels; `shape_from_world` folds the voxel
//! size in, and so does `conservative_scale`).

use crate::atlas::AtlasRegion;
use glam::{Affine3A, DMat3, Mat3, UVec3, Vec3, Vec3A};

/// Size of a position tile, metres. World positions are stored as a tile index and a
/// position within ±½ tile of its centre, where f32 keeps 0.03 mm precision.
pub const TILE_SIZE: f32 = 512.0;

/// Words per record.
pub const RECORD_WORDS: usize = 32;

/// Bytes per record.
pub const RECORD_BYTES: usize = RECORD_WORDS * 4;

/// Flag bits of a record (word 27).
pub mod flags {
    /// The caster shadows lights that use distance-field shadows.
    pub const CASTS_SHADOWS: u32 = 1 << 0;
    /// The caster occludes distance-field ambient occlusion.
    pub const CASTS_OCCLUSION: u32 = 1 << 1;
    /// Two-sided (foliage): baked as a shell around every surface (`SignMethod::
    /// TWO_SIDED`), so thin and open surfaces are solid about a voxel thick. Passes
    /// treat it as any other caster (the shell occludes fully; softer ambient occlusion
    /// comes from [`AO_TRANSMISSION_SHIFT`]); informational.
    pub const TWO_SIDED: u32 = 1 << 2;
    /// Visible (`Visibility` resolved to visible). Invisible records are culled from
    /// views and cast no shadow (as Bevy hides a hidden mesh's shadow), unless
    /// [`CAST_HIDDEN_SHADOW`] is set.
    pub const VISIBLE: u32 = 1 << 3;
    /// Unbounded (planes): never frustum-culled.
    pub const UNBOUNDED: u32 = 1 << 4;
    /// The slot holds a live object (cleared in freed slots).
    pub const LIVE: u32 = 1 << 5;
    /// Casts its shadow while invisible (a shadow proxy; Unreal's "Cast Hidden Shadow").
    pub const CAST_HIDDEN_SHADOW: u32 = 1 << 6;
    /// The caster's shading normals are not its faces' (smooth vertex normals or a normal
    /// map: `shadow::shading_apart_from_faces`): where a receiver's G-buffer normal on
    /// it hides a light, the caster field's own normal decides whether its triangles face
    /// the light (`shadow::FIELD_NORMAL_MIN_FACING_SHADED`).
    pub const SHADING_APART: u32 = 1 << 7;
    /// A volume stored as sparse bricks ([`crate::bricks`]): `params.x` is its first
    /// entry in the brick table, not an atlas origin. Set by [`super::encode`] for
    /// [`super::CasterShape::BrickedVolume`] and cleared for every other shape.
    pub const BRICKED: u32 = 1 << 12;

    /// Whether a record with flags `f` shadows distance-field-shadowed lights: live,
    /// [`CASTS_SHADOWS`], and visible or [`CAST_HIDDEN_SHADOW`]
    /// (`casts_shadows` in `shaders/df/shadow.wgsl`).
    pub const fn casts_shadows(f: u32) -> bool {
        f & LIVE != 0 && f & CASTS_SHADOWS != 0 && f & (VISIBLE | CAST_HIDDEN_SHADOW) != 0
    }
    /// Whether a record with flags `f` occludes distance-field ambient occlusion:
    /// live, [`CASTS_OCCLUSION`], and visible or [`CAST_HIDDEN_SHADOW`]
    /// (`casts_occlusion` in `shaders/df/ao.wgsl`).
    pub const fn casts_occlusion(f: u32) -> bool {
        f & LIVE != 0 && f & CASTS_OCCLUSION != 0 && f & (VISIBLE | CAST_HIDDEN_SHADOW) != 0
    }
    /// Shift of the shape kind ([`super::ShapeKind`]).
    pub const KIND_SHIFT: u32 = 8;
    /// Mask of the shape kind after shifting.
    pub const KIND_MASK: u32 = 0xf;
    /// Shift of the caster's ambient-occlusion transmission, an 8-bit fraction
    /// ([`ao_transmission_bits`]): the share of the light in a cone that the caster
    /// lets through where it would close the cone (foliage: Unreal's softened occlusion
    /// of two-sided distance fields). 0 (the default) is solid.
    pub const AO_TRANSMISSION_SHIFT: u32 = 16;
    /// Mask of the transmission after shifting.
    pub const AO_TRANSMISSION_MASK: u32 = 0xff;

    /// The flag bits holding transmission `t` (clamped to 0…1, NaN as 0; steps of 1/255).
    pub fn ao_transmission_bits(t: f32) -> u32 {
        let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
        ((t * 255.0).round() as u32) << AO_TRANSMISSION_SHIFT
    }

    /// The transmission held in flags `f` (`ao_transmission` in `shaders/df/object.wgsl`).
    pub fn ao_transmission(f: u32) -> f32 {
        ((f >> AO_TRANSMISSION_SHIFT) & AO_TRANSMISSION_MASK) as f32 / 255.0
    }
}

/// Shape kinds as stored in the flags.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum ShapeKind {
    /// An SDF volume in the atlas.
    Volume = 0,
    /// A sphere.
    Sphere = 1,
    /// A box.
    Cuboid = 2,
    /// A capsule along the local y axis.
    Capsule = 3,
    /// The plane `y = 0`, solid below.
    Plane = 4,
}

/// What a caster's distances come from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CasterShape {
    /// A baked SDF volume placed in the atlas. `params` = packed atlas origin (voxels,
    /// 10/10/12 bits), packed `dims − 1` (10/10/12 bits), `margin` (f32 bits).
    Volume {
        /// Where it is in the atlas.
        region: AtlasRegion,
        /// Local position of sample (0, 0, 0).
        local_origin: Vec3,
        /// Sample spacing in local units.
        voxel_size: f32,
        /// Voxels between the box's faces and the surface (`SdfVolume::margin`): the
        /// distance outside the box is a lower bound measured to the box shrunk by it.
        margin: f32,
    },
    /// A baked SDF volume stored as sparse bricks ([`crate::bricks`]): kind
    /// [`ShapeKind::Volume`] with [`flags::BRICKED`]. `params` = the index of its first
    /// brick-table entry, packed `dims − 1` (10/10/12 bits), `margin` (f32 bits).
    BrickedVolume {
        /// Index of its first entry in the brick table (one entry per brick, x fastest).
        table_offset: u32,
        /// The dense grid's samples along each axis (its shape space is that grid's).
        dims: UVec3,
        /// Local position of sample (0, 0, 0).
        local_origin: Vec3,
        /// Sample spacing in local units.
        voxel_size: f32,
        /// As [`CasterShape::Volume`]'s.
        margin: f32,
    },
    /// A sphere of `radius` around the local origin. `params.x` = radius (f32 bits).
    Sphere {
        /// Radius, local units.
        radius: f32,
    },
    /// A box `[−half, half]`. `params` = half extents (f32 bits).
    Cuboid {
        /// Half extents, local units.
        half_extents: Vec3,
    },
    /// A capsule: points within `radius` of the segment from `(0, −half_length, 0)` to
    /// `(0, half_length, 0)`. `params` = radius, half length (f32 bits).
    Capsule {
        /// Radius, local units.
        radius: f32,
        /// Half the length of the core segment, local units.
        half_length: f32,
    },
    /// The infinite plane `y = 0` of the local frame, solid below (`y < 0`).
    Plane,
}

impl CasterShape {
    /// Its kind.
    pub fn kind(&self) -> ShapeKind {
        match self {
            CasterShape::Volume { .. } | CasterShape::BrickedVolume { .. } => ShapeKind::Volume,
            CasterShape::Sphere { .. } => ShapeKind::Sphere,
            CasterShape::Cuboid { .. } => ShapeKind::Cuboid,
            CasterShape::Capsule { .. } => ShapeKind::Capsule,
            CasterShape::Plane => ShapeKind::Plane,
        }
    }

    /// Shape-space bounding box, `None` when unbounded.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        match *self {
            CasterShape::Volume { region, .. } => {
                Some((Vec3::ZERO, (region.dims - UVec3::ONE).as_vec3()))
            }
            CasterShape::BrickedVolume { dims, .. } => {
                Some((Vec3::ZERO, (dims - UVec3::ONE).as_vec3()))
            }
            CasterShape::Sphere { radius } => Some((Vec3::splat(-radius), Vec3::splat(radius))),
            CasterShape::Cuboid { half_extents } => Some((-half_extents, half_extents)),
            CasterShape::Capsule {
                radius,
                half_length,
            } => {
                let h = Vec3::new(radius, half_length + radius, radius);
                Some((-h, h))
            }
            CasterShape::Plane => None,
        }
    }
}

/// A caster instance as the CPU knows it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObjectDesc {
    /// World from local (Bevy's `GlobalTransform`).
    pub world_from_local: Affine3A,
    /// Its shape.
    pub shape: CasterShape,
    /// [`flags`] bits (the kind bits are set by [`encode`]).
    pub flags: u32,
}

/// Why a caster cannot be encoded (the caller skips it with a warning).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ObjectError {
    /// The transform has a NaN or infinite component.
    NonFiniteTransform,
    /// The transform collapses a direction (a zero or near-zero scale).
    SingularTransform,
    /// A shape parameter is negative, NaN or infinite.
    BadShape,
    /// The position is beyond ±2³¹ tiles.
    TooFar,
    /// An atlas region beyond the records' 10/10/12-bit coordinates (see
    /// [`crate::atlas::MAX_ATLAS_SIZE`]).
    AtlasRegionOutOfRange,
}

impl std::fmt::Display for ObjectError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            ObjectError::NonFiniteTransform => "transform is not finite",
            ObjectError::SingularTransform => "transform is singular (zero scale)",
            ObjectError::BadShape => "shape parameters are negative or not finite",
            ObjectError::TooFar => "position is too far from the origin",
            ObjectError::AtlasRegionOutOfRange => {
                "atlas region is beyond the records' 10/10/12-bit coordinates"
            }
        })
    }
}

impl std::error::Error for ObjectError {}

/// One encoded record.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ObjectRecord(pub [u32; RECORD_WORDS]);

impl ObjectRecord {
    /// The record of a free slot: all zero (not [`flags::LIVE`], so never drawn).
    pub const EMPTY: ObjectRecord = ObjectRecord([0; RECORD_WORDS]);

    /// Little-endian bytes, as uploaded.
    pub fn to_bytes(&self) -> [u8; RECORD_BYTES] {
        let mut out = [0u8; RECORD_BYTES];
        for (chunk, w) in out.chunks_exact_mut(4).zip(self.0) {
            chunk.copy_from_slice(&w.to_le_bytes());
        }
        out
    }

    /// Parses little-endian bytes (as read back).
    pub fn from_bytes(bytes: &[u8; RECORD_BYTES]) -> ObjectRecord {
        let mut words = [0u32; RECORD_WORDS];
        for (w, chunk) in words.iter_mut().zip(bytes.chunks_exact(4)) {
            *w = u32::from_le_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]);
        }
        ObjectRecord(words)
    }

    fn f(&self, i: usize) -> f32 {
        f32::from_bits(self.0[i])
    }

    /// Rows of a 3×4 matrix starting at word `at`, as an affine transform.
    fn affine(&self, at: usize) -> Affine3A {
        let row = |r: usize| {
            [
                self.f(at + 4 * r),
                self.f(at + 4 * r + 1),
                self.f(at + 4 * r + 2),
                self.f(at + 4 * r + 3),
            ]
        };
        let (r0, r1, r2) = (row(0), row(1), row(2));
        Affine3A {
            matrix3: Mat3::from_cols(
                Vec3::new(r0[0], r1[0], r2[0]),
                Vec3::new(r0[1], r1[1], r2[1]),
                Vec3::new(r0[2], r1[2], r2[2]),
            )
            .into(),
            translation: Vec3A::new(r0[3], r1[3], r2[3]),
        }
    }

    /// Tile-relative world → shape space.
    pub fn shape_from_world(&self) -> Affine3A {
        self.affine(0)
    }

    /// Shape space → tile-relative world.
    pub fn world_from_shape(&self) -> Affine3A {
        self.affine(12)
    }

    /// The position tile.
    pub fn tile(&self) -> [i32; 3] {
        [self.0[24] as i32, self.0[25] as i32, self.0[26] as i32]
    }

    /// The flags word.
    pub fn flags(&self) -> u32 {
        self.0[27]
    }

    /// The shape kind.
    pub fn kind(&self) -> u32 {
        (self.0[27] >> flags::KIND_SHIFT) & flags::KIND_MASK
    }

    /// The three parameter words.
    pub fn params(&self) -> [u32; 3] {
        [self.0[28], self.0[29], self.0[30]]
    }

    /// World metres per shape-space distance unit (see the module docs).
    pub fn conservative_scale(&self) -> f32 {
        self.f(31)
    }

    /// Shape-space bounding box from the stored parameters (what the GPU culling pass
    /// reads), `None` for unbounded shapes and unknown kinds.
    pub fn shape_bounds(&self) -> Option<(Vec3, Vec3)> {
        let [p0, p1, p2] = self.params();
        let f = f32::from_bits;
        if self.flags() & flags::UNBOUNDED != 0 {
            return None;
        }
        match self.kind() {
            k if k == ShapeKind::Volume as u32 => Some((Vec3::ZERO, unpack_10_10_12(p1).as_vec3())),
            k if k == ShapeKind::Sphere as u32 => Some((Vec3::splat(-f(p0)), Vec3::splat(f(p0)))),
            k if k == ShapeKind::Cuboid as u32 => {
                let h = Vec3::new(f(p0), f(p1), f(p2));
                Some((-h, h))
            }
            k if k == ShapeKind::Capsule as u32 => {
                let h = Vec3::new(f(p0), f(p1) + f(p0), f(p0));
                Some((-h, h))
            }
            _ => None,
        }
    }
}

/// Packs three values into 10/10/12 bits (x lowest); `None` when one does not fit.
pub fn pack_10_10_12(v: UVec3) -> Option<u32> {
    (v.x < 1024 && v.y < 1024 && v.z < 4096).then_some(v.x | (v.y << 10) | (v.z << 20))
}

/// Inverse of [`pack_10_10_12`].
pub fn unpack_10_10_12(p: u32) -> UVec3 {
    UVec3::new(p & 0x3ff, (p >> 10) & 0x3ff, p >> 20)
}

/// The tile holding world position `p` (nearest multiple of [`TILE_SIZE`]).
pub fn tile_of(p: Vec3) -> Option<[i32; 3]> {
    let t = (p.as_dvec3() / TILE_SIZE as f64).round();
    let ok = t.abs().max_element() < i32::MAX as f64;
    ok.then_some([t.x as i32, t.y as i32, t.z as i32])
}

/// `p − tile × TILE_SIZE`, exactly where representable (computed in f64).
pub fn tile_relative(p: Vec3, tile: [i32; 3]) -> Vec3 {
    let t = glam::DVec3::new(tile[0] as f64, tile[1] as f64, tile[2] as f64) * TILE_SIZE as f64;
    (p.as_dvec3() - t).as_vec3()
}

/// The smallest singular value of `m` (f64, closed-form eigenvalues of `mᵀm`).
pub fn min_singular_value(m: Mat3) -> f32 {
    let m = m.as_dmat3();
    let a = m.transpose() * m;
    smallest_symmetric_eigenvalue(&a).max(0.0).sqrt() as f32
}

/// Smallest eigenvalue of a symmetric 3×3 matrix (Smith 1961, trigonometric form).
fn smallest_symmetric_eigenvalue(a: &DMat3) -> f64 {
    let (a00, a11, a22) = (a.x_axis.x, a.y_axis.y, a.z_axis.z);
    let (a01, a02, a12) = (a.y_axis.x, a.z_axis.x, a.z_axis.y);
    let p1 = a01 * a01 + a02 * a02 + a12 * a12;
    let q = (a00 + a11 + a22) / 3.0;
    if p1 <= 1e-30 * q * q {
        return a00.min(a11).min(a22);
    }
    let p2 = (a00 - q).powi(2) + (a11 - q).powi(2) + (a22 - q).powi(2) + 2.0 * p1;
    let p = (p2 / 6.0).sqrt();
    let b = (*a - DMat3::from_diagonal(glam::DVec3::splat(q))) * (1.0 / p);
    let r = (b.determinant() / 2.0).clamp(-1.0, 1.0);
    let phi = r.acos() / 3.0;
    // Eigenvalues q + 2p cos(phi + 2πk/3); the smallest is k = 1.
    q + 2.0 * p * (phi + 2.0 * std::f64::consts::PI / 3.0).cos()
}

/// A volume's shape-from-local transform, params and distance scale: `first` (atlas
/// origin or brick-table offset), packed `dims − 1`, margin.
fn volume_params(
    first: u32,
    dims: UVec3,
    local_origin: Vec3,
    voxel_size: f32,
    margin: f32,
    scale: f32,
) -> Result<(Affine3A, [u32; 3], f32), ObjectError> {
    let valid = voxel_size.is_finite()
        && voxel_size > 0.0
        && local_origin.is_finite()
        && margin.is_finite()
        && margin >= 0.0;
    if !valid {
        return Err(ObjectError::BadShape);
    }
    Ok((
        Affine3A::from_scale_rotation_translation(
            Vec3::splat(voxel_size),
            glam::Quat::IDENTITY,
            local_origin,
        ),
        [
            first,
            pack_10_10_12(dims.saturating_sub(UVec3::ONE))
                .ok_or(ObjectError::AtlasRegionOutOfRange)?,
            margin.to_bits(),
        ],
        // Shape-space distances are voxels.
        scale * voxel_size,
    ))
}

/// Encodes a caster. Errors (skip the caster, warn once) for non-finite or singular
/// transforms, bad shape parameters and positions beyond the tile range.
pub fn encode(desc: &ObjectDesc) -> Result<ObjectRecord, ObjectError> {
    let m = Mat3::from(desc.world_from_local.matrix3);
    let t = Vec3::from(desc.world_from_local.translation);
    if !m.is_finite() || !t.is_finite() {
        return Err(ObjectError::NonFiniteTransform);
    }
    let scale = min_singular_value(m);
    let largest = m
        .x_axis
        .length()
        .max(m.y_axis.length())
        .max(m.z_axis.length());
    // NaN scales fail both comparisons and are rejected too.
    if scale.is_nan() || scale <= 1e-6 * largest || scale < f32::MIN_POSITIVE {
        return Err(ObjectError::SingularTransform);
    }
    let tile = tile_of(t).ok_or(ObjectError::TooFar)?;
    let world_from_local = Affine3A::from_mat3_translation(m, tile_relative(t, tile));
    let positive = |x: f32| x.is_finite() && x >= 0.0;
    let (local_from_shape, params, scale_per_unit) = match desc.shape {
        CasterShape::Volume {
            region,
            local_origin,
            voxel_size,
            margin,
        } => volume_params(
            pack_10_10_12(region.origin).ok_or(ObjectError::AtlasRegionOutOfRange)?,
            region.dims,
            local_origin,
            voxel_size,
            margin,
            scale,
        )?,
        CasterShape::BrickedVolume {
            table_offset,
            dims,
            local_origin,
            voxel_size,
            margin,
        } => volume_params(table_offset, dims, local_origin, voxel_size, margin, scale)?,
        CasterShape::Sphere { radius } if positive(radius) => {
            (Affine3A::IDENTITY, [radius.to_bits(), 0, 0], scale)
        }
        CasterShape::Cuboid { half_extents }
            if half_extents.is_finite() && half_extents.min_element() >= 0.0 =>
        {
            (
                Affine3A::IDENTITY,
                half_extents.to_array().map(f32::to_bits),
                scale,
            )
        }
        CasterShape::Capsule {
            radius,
            half_length,
        } if positive(radius) && positive(half_length) => (
            Affine3A::IDENTITY,
            [radius.to_bits(), half_length.to_bits(), 0],
            scale,
        ),
        CasterShape::Plane => (Affine3A::IDENTITY, [0; 3], scale),
        _ => return Err(ObjectError::BadShape),
    };
    let world_from_shape = world_from_local * local_from_shape;
    let shape_from_world = world_from_shape.inverse();
    if !Mat3::from(shape_from_world.matrix3).is_finite() {
        return Err(ObjectError::SingularTransform);
    }
    let mut words = [0u32; RECORD_WORDS];
    let mut put_rows = |at: usize, a: &Affine3A| {
        let m = Mat3::from(a.matrix3);
        for r in 0..3 {
            let row = m.row(r);
            words[at + 4 * r] = row.x.to_bits();
            words[at + 4 * r + 1] = row.y.to_bits();
            words[at + 4 * r + 2] = row.z.to_bits();
            words[at + 4 * r + 3] = a.translation[r].to_bits();
        }
    };
    put_rows(0, &shape_from_world);
    put_rows(12, &world_from_shape);
    words[24] = tile[0] as u32;
    words[25] = tile[1] as u32;
    words[26] = tile[2] as u32;
    let kind = desc.shape.kind() as u32;
    let mut f =
        desc.flags & !(flags::KIND_MASK << flags::KIND_SHIFT | flags::BRICKED) | flags::LIVE;
    f |= kind << flags::KIND_SHIFT;
    if matches!(desc.shape, CasterShape::BrickedVolume { .. }) {
        f |= flags::BRICKED;
    }
    if desc.shape.bounds().is_none() {
        f |= flags::UNBOUNDED;
    }
    words[27] = f;
    words[28..31].copy_from_slice(&params);
    words[31] = scale_per_unit.to_bits();
    Ok(ObjectRecord(words))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    fn sphere_at(t: Vec3, scale: Vec3) -> ObjectDesc {
        ObjectDesc {
            world_from_local: Affine3A::from_scale_rotation_translation(
                scale,
                Quat::from_rotation_y(0.7) * Quat::from_rotation_x(0.3),
                t,
            ),
            shape: CasterShape::Sphere { radius: 0.5 },
            flags: flags::VISIBLE | flags::CASTS_SHADOWS,
        }
    }

    #[test]
    fn records_round_trip_and_invert() {
        let desc = sphere_at(Vec3::new(1.5, -2.0, 3.0), Vec3::new(1.0, 2.0, 0.5));
        let r = encode(&desc).unwrap();
        assert_eq!(ObjectRecord::from_bytes(&r.to_bytes()), r);
        assert_eq!(r.kind(), ShapeKind::Sphere as u32);
        assert_eq!(r.flags() & flags::LIVE, flags::LIVE);
        assert!(
            (r.conservative_scale() - 0.5).abs() < 1e-6,
            "{}",
            r.conservative_scale()
        );
        let p = Vec3::new(0.3, 0.2, -0.4);
        let world = r.world_from_shape().transform_point3(p);
        assert!(world.distance(desc.world_from_local.transform_point3(p)) < 1e-5);
        assert!(r.shape_from_world().transform_point3(world).distance(p) < 1e-5);
    }

    #[test]
    fn far_positions_keep_precision_in_their_tile() {
        for far in [1e5f32, -3.3e5, 7.77e4] {
            let t = Vec3::new(far, 12.25, -far);
            let r = encode(&sphere_at(t, Vec3::ONE)).unwrap();
            let tile = r.tile();
            let rel = r.world_from_shape().translation;
            assert!(rel.abs().max_element() <= TILE_SIZE / 2.0 + 1e-3, "{rel}");
            // Reconstructed in f64: the input position exactly (it is an f32).
            let back = glam::DVec3::new(tile[0] as f64, tile[1] as f64, tile[2] as f64)
                * TILE_SIZE as f64
                + Vec3::from(rel).as_dvec3();
            assert_eq!(back.as_vec3(), t, "{far}");
        }
    }

    #[test]
    fn conservative_scale_is_the_smallest_singular_value() {
        let cases = [
            (Mat3::IDENTITY, 1.0),
            (Mat3::from_diagonal(Vec3::new(3.0, 0.25, 2.0)), 0.25),
            (
                Mat3::from_quat(Quat::from_rotation_z(0.4))
                    * Mat3::from_diagonal(Vec3::new(2.0, 5.0, 0.1)),
                0.1,
            ),
            // Shear: singular values of [[1,1,0],[0,1,0],[0,0,1]] are (√5 ± 1)/2 and 1.
            (
                Mat3::from_cols(Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Z),
                (5f32.sqrt() - 1.0) / 2.0,
            ),
        ];
        for (m, want) in cases {
            let got = min_singular_value(m);
            assert!(
                (got - want).abs() < 1e-5 * want.max(1.0),
                "{m}: {got} vs {want}"
            );
        }
    }

    #[test]
    fn bad_casters_are_errors() {
        let ok = sphere_at(Vec3::ZERO, Vec3::ONE);
        let mut nan = ok;
        nan.world_from_local.translation.x = f32::NAN;
        let mut singular = ok;
        singular.world_from_local.matrix3.y_axis = Vec3A::ZERO;
        let mut flat = ok;
        flat.world_from_local = Affine3A::from_scale(Vec3::new(1.0, 1e-9, 1.0));
        let mut bad_radius = ok;
        bad_radius.shape = CasterShape::Sphere { radius: -1.0 };
        let mut inf_box = ok;
        inf_box.shape = CasterShape::Cuboid {
            half_extents: Vec3::new(1.0, f32::INFINITY, 1.0),
        };
        let mut bad_voxel = ok;
        bad_voxel.shape = CasterShape::Volume {
            region: AtlasRegion {
                origin: UVec3::ZERO,
                dims: UVec3::splat(8),
            },
            local_origin: Vec3::ZERO,
            voxel_size: 0.0,
            margin: 0.0,
        };
        let mut far = ok;
        far.world_from_local.translation.x = 1e38;
        let mut unaddressable = ok;
        unaddressable.shape = CasterShape::Volume {
            region: AtlasRegion {
                origin: UVec3::new(0, 0, 4096),
                dims: UVec3::splat(8),
            },
            local_origin: Vec3::ZERO,
            voxel_size: 0.1,
            margin: 0.0,
        };
        for (name, desc, want) in [
            ("nan", nan, ObjectError::NonFiniteTransform),
            ("singular", singular, ObjectError::SingularTransform),
            ("flat", flat, ObjectError::SingularTransform),
            ("radius", bad_radius, ObjectError::BadShape),
            ("box", inf_box, ObjectError::BadShape),
            ("voxel", bad_voxel, ObjectError::BadShape),
            ("far", far, ObjectError::TooFar),
            ("atlas z", unaddressable, ObjectError::AtlasRegionOutOfRange),
        ] {
            assert_eq!(encode(&desc), Err(want), "{name}");
        }
    }

    #[test]
    fn packing_round_trips() {
        for v in [
            UVec3::ZERO,
            UVec3::new(1023, 1023, 4095),
            UVec3::new(8, 512, 2040),
        ] {
            assert_eq!(pack_10_10_12(v).map(unpack_10_10_12), Some(v));
        }
        for v in [
            UVec3::new(1024, 0, 0),
            UVec3::new(0, 1024, 0),
            UVec3::new(0, 0, 4096),
        ] {
            assert_eq!(pack_10_10_12(v), None, "{v}");
        }
    }
}
