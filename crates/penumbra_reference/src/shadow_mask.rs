//! The CPU model of the distance-field shadow-mask pass (`shaders/df/shadow.wgsl`): for
//! each pixel, the visibility of one light through the scene's distance-field objects —
//! the march of [`crate::df_shadow`] over the GPU object records, with the same
//! per-object cone culling, tiny-object clamp and shaping, in the same order.
//!
//! Conventions: positions are camera-relative world metres (see
//! [`penumbra_df_core::cull::CameraOrigin`]); a pixel's position comes from its depth
//! ([`position_from_depth`]: Bevy's reverse-Z, NDC +y up, pixel centres).
//!
//! **Per-object culling.** An object can lower a pixel's visibility only where the
//! light's cone from the pixel comes closer to it than the cone's radius: the cone is
//! contained in the *round cone* (convex hull of two balls) from `(p, 0)` to
//! `(p + t_max · dir, t_max · tan θ)`, so objects whose bounding sphere misses it are
//! skipped. The GPU also culls per 8×8 tile with a round cone containing every pixel's
//! (from the tile's bounding ball to the light), which never changes a result.

use crate::df::{Atlas, object_distance};
use crate::df_shadow::cone_interval;
use glam::{IVec3, Mat3, Mat4, Vec2, Vec3, Vec4};
use penumbra_df_core::cull::CameraOrigin;
use penumbra_df_core::heightfield::HeightfieldTexture;
use penumbra_df_core::object::{ObjectRecord, ShapeKind, TILE_SIZE, flags};
use penumbra_df_core::shadow::{
    FACE_NORMAL_MIN_AGREEMENT, FACE_NORMAL_PLANE_SIN, FIELD_NORMAL_MAX_GRADIENT,
    FIELD_NORMAL_MIN_AGREEMENT, FIELD_NORMAL_MIN_FACING, FIELD_NORMAL_MIN_FACING_SHADED,
    FIELD_NORMAL_MIN_GRADIENT, FIELD_NORMAL_REACH_VOXELS, FIELD_NORMAL_STEP_VOXELS,
    FLAT_SHADED_SIN, FROM_INSIDE_ON_SURFACE_VOXELS, FROM_INSIDE_PROBE_VOXELS, PENUMBRA_MIN_STEP,
    crossing_stencil, march_start, penumbra_step, penumbra_visibility, seen_from_inside,
    tetrahedral_gradient, tetrahedral_normal, thin_crossing_ratio, thin_crossing_rim,
};

pub use penumbra_df_core::shadow::{ShadowLight as MaskLight, ShadowLightKind as MaskLightKind};

pub use penumbra_df_core::cull::{Ball, bounding_sphere, max_scale};

/// Signed distance from `p` to the convex hull of balls `(a, ra)` and `(b, rb)` (a
/// "round cone"; Quílez's formulation, exact when neither ball contains the other).
pub fn round_cone_distance(p: Vec3, a: Vec3, b: Vec3, ra: f32, rb: f32) -> f32 {
    let ba = b - a;
    let l2 = ba.dot(ba);
    let rr = ra - rb;
    let a2 = l2 - rr * rr;
    if a2 <= 0.0 {
        // One ball contains the other: the hull is the larger ball.
        return ((p - a).length() - ra).min((p - b).length() - rb);
    }
    let il2 = 1.0 / l2;
    let pa = p - a;
    let y = pa.dot(ba);
    let z = y - l2;
    let x2 = (pa * l2 - ba * y).length_squared();
    let y2 = y * y * l2;
    let z2 = z * z * l2;
    let k = rr.signum() * rr * rr * x2;
    if z.signum() * a2 * z2 > k {
        return (x2 + z2).sqrt() * il2 - rb;
    }
    if y.signum() * a2 * y2 < k {
        return (x2 + y2).sqrt() * il2 - ra;
    }
    ((x2 * a2 * il2).sqrt() + y * rr) * il2 - ra
}

/// Culling slack: a bounding sphere counts as touching a cull volume up to this much
/// beyond it (relative to its radius, plus an absolute floor), so rounding never drops
/// an object the other side keeps.
pub fn cull_slack(radius: f32) -> f32 {
    radius * 1e-4 + 1e-4
}

/// The shadow ray from camera-relative `p`: direction, length and the tangent of the
/// cone's half-angle.
pub fn shadow_ray(p: Vec3, light: &MaskLight) -> (Vec3, f32, f32) {
    match light.kind {
        MaskLightKind::Directional(to_light) => (to_light, light.max_distance, light.source),
        MaskLightKind::Positional(position) => {
            let v = position - p;
            let d = v.length().max(1e-6);
            let s = (light.source / d.max(light.source)).clamp(0.0, 1.0);
            let tan_half = s / (1.0 - s * s).max(1e-12).sqrt();
            (v / d, (d - light.source).max(0.0), tan_half)
        }
    }
}

/// The visibility of `light` from camera-relative `p` (1 lit, 0 shadowed): the GPU mask
/// pass's per-pixel result. `normal`: the surface's unit normal there (the pass reads it
/// from the deferred G-buffer, [`unpack_gbuffer_normal`]), or zero when unknown; it adds
/// the surface's own shadow ([`horizon`]). `records` are the object buffer's slots (free
/// slots are skipped).
pub fn pixel_visibility(
    records: &[ObjectRecord],
    atlas: &Atlas,
    camera: &CameraOrigin,
    p: Vec3,
    normal: impl Into<ReceiverNormal>,
    light: &MaskLight,
) -> f32 {
    pixel_visibility_counted(records, atlas, camera, p, normal, light).0
}

/// [`pixel_visibility`] and the number of distance evaluations it took (the pass's
/// work, for run-time-vs-error benches).
pub fn pixel_visibility_counted(
    records: &[ObjectRecord],
    atlas: &Atlas,
    camera: &CameraOrigin,
    p: Vec3,
    normal: impl Into<ReceiverNormal>,
    light: &MaskLight,
) -> (f32, u32) {
    pixel_visibility_with_terrain(
        records,
        atlas,
        camera,
        p,
        normal,
        light,
        &HeightfieldTexture::default(),
    )
}

/// [`pixel_visibility_counted`] with terrains bound (`shaders/df/shadow_trace.wgsl`'s
/// `terrain_visibility`): each terrain whose box, grown by the cone's end radius, meets
/// the box of the shadow ray is sphere-traced along it in its tile's frame
/// ([`HeightfieldTexture::distance`]) with the objects' cone test (`d / r`, shut
/// inside) and no small-object floor; each step at least half a terrain cell across
/// (the bound is small along a slope: a ray grazing one would use up its steps and
/// leak).
#[allow(clippy::too_many_arguments, reason = "the pass's inputs")]
pub fn pixel_visibility_with_terrain(
    records: &[ObjectRecord],
    atlas: &Atlas,
    camera: &CameraOrigin,
    p: Vec3,
    normal: impl Into<ReceiverNormal>,
    light: &MaskLight,
    terrain: &HeightfieldTexture,
) -> (f32, u32) {
    if matches!(light.kind, MaskLightKind::Directional(_)) {
        // The encoder's `max(0)`: NaN traces nothing.
        let reach = light.max_view_distance.max(0.0);
        let near = p.length_squared() <= reach * reach; // false for NaN
        if !near {
            return (1.0, 0);
        }
    }
    if !light_reaches(light, p) {
        return (1.0, 0);
    }
    let (dir, t_max, tan_half) = shadow_ray(p, light);
    let ReceiverNormal {
        normal,
        flat,
        face,
        facet,
    } = normal.into();
    // The pixel's triangle is known (the face-normal prepass): its plane, facing the eye
    // (`p` is camera-relative), alone gives the own shadow, as a ray tracer's does; none
    // of the G-buffer normal's rules below applies.
    let facet = (facet != Vec3::ZERO).then(|| if facet.dot(p) > 0.0 { -facet } else { facet });
    let stored = facet.unwrap_or(normal);
    let mut normal = facet.unwrap_or_else(|| facing_the_eye(normal, p));
    // Whether `normal` is the G-buffer's as stored, facing the eye (the side seen).
    let mut as_stored = normal != Vec3::ZERO && normal == stored;
    // The surface's own shadow; where it hides the whole light, no march. Where the
    // light is below the G-buffer normal's horizon and that normal is not the face's own
    // ([`flat_shaded`]), the caster field the receiver lies on may give the triangles'
    // facing instead ([`receiver_field_normal`]): from facing 0 (then its own horizon)
    // on a caster shaded apart from its faces (`flags::SHADING_APART`), from
    // [`FIELD_NORMAL_MIN_FACING`] (fully lit) on the others. The field must agree with
    // the G-buffer normal as turned to face the eye or as stored (a normal map's normal
    // past a grazing view's silhouette, which [`facing_the_eye`] negated).
    let mut own = horizon(normal, dir, tan_half);
    let mut evaluations = 0;
    // Whether the receiver's shading may part from its faces: it lies on a caster field
    // shaded apart from its faces, or on none whose normal could be read.
    let mut shaded_apart = true;
    if normal != Vec3::ZERO && own < 1.0 && facet.is_none() {
        let (field, reads) = receiver_field_normal_counted(records, atlas, camera, p, normal);
        evaluations += reads;
        shaded_apart = field.is_none_or(|(_, f)| f & flags::SHADING_APART != 0);
        if let Some((field, _)) = field
            && field.dot(normal).max(field.dot(stored)) >= FIELD_NORMAL_MIN_AGREEMENT
            && !flat
        {
            let facing = field.dot(dir);
            // A field was read: `shaded_apart` is its caster's flag.
            if shaded_apart && facing >= FIELD_NORMAL_MIN_FACING_SHADED {
                normal = field;
                own = horizon(normal, dir, tan_half);
                as_stored = false;
            } else if facing >= FIELD_NORMAL_MIN_FACING {
                normal = field;
                own = 1.0;
                as_stored = false;
            }
        }
    }
    // Still hidden and still the G-buffer's own (not a flat-shaded face's), on a caster
    // shaded apart from its faces or on no caster field: the depth buffer's face normal,
    // where it agrees, gives the triangles' facing ([`FACE_NORMAL_MIN_AGREEMENT`]; a
    // smooth normal just past the terminator of facets that face the light). Not on
    // other casters: a scanned mesh's pixel-sized facets make the depth buffer's plane
    // no face's, and its G-buffer normals are its faces'.
    if own < 1.0
        && as_stored
        && !flat
        && facet.is_none()
        && shaded_apart
        && face.dot(normal) >= FACE_NORMAL_MIN_AGREEMENT
    {
        normal = face;
        own = horizon(normal, dir, tan_half);
        as_stored = false;
    }
    if own <= 0.0 {
        return (0.0, evaluations);
    }
    let end = p + dir * t_max;
    let end_radius = t_max * tan_half;
    let mut visibility = 1.0f32;
    // A solid caster the receiver sees from its inside ([`seen_from_inside`]) is not
    // marched; its reversed field normal gives the receiver's own shadow (the least over
    // such casters). Asked only with the G-buffer's normal as stored, facing the eye:
    // not where [`facing_the_eye`] turned it (a normal map's at a grazing view) nor where
    // a field's normal replaced it (the field's outside).
    let mut inside_own: Option<f32> = None;
    for r in records {
        if !flags::casts_shadows(r.flags()) {
            continue;
        }
        let sphere = bounding_sphere(r, camera);
        // Volumes: past the receiver's own surface as the field sees it.
        let voxel = if r.kind() == ShapeKind::Volume as u32 {
            r.conservative_scale()
        } else {
            0.0
        };
        let two_sided = r.flags() & flags::TWO_SIDED != 0;
        let start = march_start(light.bias, voxel, two_sided, normal, dir);
        let (mut t, mut t_end) = (start, t_max);
        if let Some((center, radius)) = sphere {
            if round_cone_distance(center, p, end, 0.0, end_radius) >= radius + cull_slack(radius) {
                continue;
            }
            // March only where the cone meets the object's ball.
            let Some((t0, t1)) = cone_interval(p - center, dir, radius, tan_half) else {
                continue;
            };
            t = t.max(t0);
            t_end = t_end.min(t1);
            let v = p - center;
            if voxel > 0.0 && !two_sided && as_stored && v.dot(v) <= radius * radius {
                // One read, two more where the receiver lies on the field's surface.
                let at = object_distance(r, p, camera, atlas);
                evaluations += 1;
                let on_surface = at.abs() <= FROM_INSIDE_ON_SURFACE_VOXELS * voxel;
                let probe = normal * (FROM_INSIDE_PROBE_VOXELS * voxel);
                let (front, back) = if on_surface {
                    evaluations += 2;
                    (
                        object_distance(r, p + probe, camera, atlas),
                        object_distance(r, p - probe, camera, atlas),
                    )
                } else {
                    (f32::NAN, f32::NAN)
                };
                if seen_from_inside(at, front, back, voxel) {
                    // With the pixel's triangle known, its plane already gave the own
                    // shadow.
                    if facet.is_some() {
                        continue;
                    }
                    // `field_normal`: one read, four more where the receiver lies on it.
                    evaluations += 1;
                    if let Some((n, _)) = field_normal(r, atlas, camera, p, normal) {
                        evaluations += 4;
                        let h = horizon(-n, dir, tan_half);
                        inside_own = Some(inside_own.map_or(h, |o| o.min(h)));
                    }
                    continue;
                }
            }
        }
        // A receiver inside an analytic shape is not shadowed by it: the shape stands in
        // for the receiver's own mesh (a character's capsules).
        if inside_analytic(r, p, camera, atlas) {
            evaluations += 1;
            continue;
        }
        // The least distance over the cone's radius, down to −1: the two-sided penumbra
        // (`penumbra_df_core::shadow::PENUMBRA_MIN_STEP`, `penumbra_step`).
        let mut v = 1.0f32;
        let mut entered = None;
        let mut before = t;
        for _ in 0..light.max_steps {
            if t >= t_end {
                break;
            }
            let d = object_distance(r, p + dir * t, camera, atlas);
            evaluations += 1;
            let cone = (t * tan_half).max(1e-6);
            // A bounded object covers at most (R / r)² of the cone's section, even when
            // the axis runs through it: the ratio stays above 1 − 2 (R / r)².
            let floor = sphere.map_or(-1.0, |(_, radius)| {
                1.0 - 2.0 * (radius / cone).powi(2).min(1.0)
            });
            let s = crossing_stencil(cone, voxel);
            let reads = std::cell::Cell::new(0);
            let normal_at = |at: f32| {
                tetrahedral_normal(p + dir * at, s, |q| {
                    reads.set(reads.get() + 1);
                    object_distance(r, q, camera, atlas)
                })
            };
            let thin = |normal_in: Vec3| {
                let x = p + dir * (0.5 * (before + t));
                let (points, stretch) = thin_crossing_rim(x, normal_in, dir, cone);
                let rim = points.map(|q| {
                    reads.set(reads.get() + 1);
                    object_distance(r, q, camera, atlas)
                });
                thin_crossing_ratio(rim, cone, stretch)
            };
            let (ratio, step) = penumbra_step(
                d,
                cone,
                voxel,
                two_sided,
                &mut entered,
                || normal_at(before),
                || normal_at(t),
                thin,
            );
            evaluations += reads.get();
            v = v.min(ratio.max(floor));
            // Covered (a tiny object's floor still leaves some light).
            if ratio <= -1.0 {
                break;
            }
            before = t;
            t += step;
        }
        visibility = visibility.min(penumbra_visibility(v));
    }
    let (v, e) = terrain_visibility(terrain, camera, p, (dir, t_max, tan_half), light);
    visibility = visibility.min(v);
    evaluations += e;
    let own = inside_own.unwrap_or(own);
    (
        finish(visibility, light.shaping.clamp(0.05, 20.0)).min(own),
        evaluations,
    )
}

/// What the mask pass knows of a receiver's normal: its G-buffer normal (zero: unknown),
/// whether that normal is its face's own ([`flat_shaded`]: then a light below its
/// horizon is the face's own shadow, and no caster field is asked), and the face normal
/// the depth buffer about it gives ([`face_normal`]; zero: none). A bare `Vec3` converts
/// with `flat: false` and no face normal, the pass's answer where it cannot tell (a
/// screen axis with no neighbour on a surface, deferred MSAA's per-sample trace).
/// [`receiver_normal`] and [`receiver_normal_in_depth`] decide both as the pass does.
/// With the face-normal prepass, `facet` is the pixel's triangle normal and the rest is
/// not read.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ReceiverNormal {
    /// The G-buffer's unit normal, or zero when unknown.
    pub normal: Vec3,
    /// Whether the depth buffer about the pixel lies in `normal`'s tangent plane.
    pub flat: bool,
    /// The unit normal of the plane the depth buffer about the pixel lies in, on the
    /// side `normal` (turned to face the eye) faces, or zero where none is trusted.
    pub face: Vec3,
    /// The unit normal of the triangle at the pixel centre by its winding (the
    /// face-normal prepass, where trusted: `penumbra_df_core::shadow::
    /// FACE_DEPTH_TOLERANCE`), or zero when unknown.
    pub facet: Vec3,
}

impl From<Vec3> for ReceiverNormal {
    fn from(normal: Vec3) -> Self {
        ReceiverNormal {
            normal,
            flat: false,
            face: Vec3::ZERO,
            facet: Vec3::ZERO,
        }
    }
}

/// [`ReceiverNormal`] of camera-relative point `p` with G-buffer `normal`, from its
/// depth-buffer neighbours (`neighbours[axis][side]`, camera-relative; `None` outside the
/// viewport or on the background): [`flat_shaded`] and [`face_normal`].
pub fn receiver_normal(
    p: Vec3,
    normal: Vec3,
    neighbours: [[Option<Vec3>; 2]; 2],
) -> ReceiverNormal {
    ReceiverNormal {
        normal,
        flat: flat_shaded(p, normal, neighbours),
        face: face_normal(p, normal, neighbours),
        facet: Vec3::ZERO,
    }
}

/// The normal of the face a pixel sees, from the depth buffer as `shadow_trace.wgsl`'s
/// `depth_face_normal` finds it: along each screen axis the central difference of the
/// two neighbours (the one neighbour's difference where the other is missing), their
/// cross product turned to the side of `normal` (the G-buffer's, turned to face the
/// eye); zero where an axis has no neighbour, the points are degenerate, or any
/// neighbour lies further than [`FACE_NORMAL_PLANE_SIN`] from the plane through `p` (a
/// crease or a silhouette between them).
pub fn face_normal(p: Vec3, normal: Vec3, neighbours: [[Option<Vec3>; 2]; 2]) -> Vec3 {
    let normal = facing_the_eye(normal, p);
    let mut edges = [Vec3::ZERO; 2];
    for (axis, [before, after]) in neighbours.iter().enumerate() {
        edges[axis] = match (before, after) {
            (Some(a), Some(b)) => *b - *a,
            (Some(a), None) => p - *a,
            (None, Some(b)) => *b - p,
            (None, None) => return Vec3::ZERO,
        };
    }
    let c = edges[0].cross(edges[1]);
    // The shader's `!(dot(c, c) > 1e-30)`: degenerate (or NaN) points give no face.
    if c.is_nan() || c.length_squared() <= 1e-30 {
        return Vec3::ZERO;
    }
    let mut n = c.normalize();
    if n.dot(normal) < 0.0 {
        n = -n;
    }
    let in_plane = neighbours.iter().flatten().flatten().all(|&q| {
        let e = q - p;
        e.dot(n).abs() <= FACE_NORMAL_PLANE_SIN * e.length()
    });
    if in_plane { n } else { Vec3::ZERO }
}

/// Whether a pixel's G-buffer `normal` is its surface's own — a flat-shaded face, not a
/// smooth or normal-mapped normal — as `shadow_trace.wgsl`'s `flat_shaded` decides it
/// from the depth buffer: along each screen axis, one of the pixel's two neighbours
/// (`neighbours[axis][side]`, camera-relative depth-buffer points; `None` outside the
/// viewport or on the background) lies in the tangent plane at `p`, within
/// [`FLAT_SHADED_SIN`]. One neighbour per axis, not the nearer: on a face two pixels
/// tall each pixel's other neighbour is another face.
pub fn flat_shaded(p: Vec3, normal: Vec3, neighbours: [[Option<Vec3>; 2]; 2]) -> bool {
    let normal = facing_the_eye(normal, p);
    neighbours.iter().all(|axis| {
        axis.iter().flatten().any(|&q| {
            let e = q - p;
            e.dot(normal).abs() <= FLAT_SHADED_SIN * e.length()
        })
    })
}

/// [`receiver_normal`] for pixel `(x, y)` of a `width × height` reverse-Z depth buffer
/// (`depth[y * width + x]`; 0 background) whose camera-relative points `position(x, y,
/// depth)` gives, with the pixel's G-buffer `normal` (no flat test, no face normal on
/// the background).
pub fn receiver_normal_in_depth(
    depth: &[f32],
    width: u32,
    height: u32,
    (x, y): (u32, u32),
    normal: Vec3,
    position: impl Fn(u32, u32, f32) -> Vec3,
) -> ReceiverNormal {
    let at = |x: i64, y: i64| -> Option<Vec3> {
        if x < 0 || y < 0 || x >= i64::from(width) || y >= i64::from(height) {
            return None;
        }
        let (x, y) = (x as u32, y as u32);
        let d = *depth.get((y * width + x) as usize)?;
        // The shader's `!(d > 0.0)`: background and NaN depths have no point.
        (d > 0.0).then(|| position(x, y, d))
    };
    let (x, y) = (i64::from(x), i64::from(y));
    let Some(p) = at(x, y) else {
        return ReceiverNormal::from(normal);
    };
    receiver_normal(
        p,
        normal,
        [[at(x - 1, y), at(x + 1, y)], [at(x, y - 1), at(x, y + 1)]],
    )
}

/// The outward normal of the caster field that camera-relative receiver `p` lies on,
/// seen from `side` (its G-buffer normal turned to face the eye): among the
/// shadow-casting volumes whose bounding sphere holds `p`, each one's [`field_normal`],
/// the one with the smallest distance (the first slot on a tie). `shadow_trace.wgsl`
/// reads the same objects from its tile's caster list.
pub fn receiver_field_normal(
    records: &[ObjectRecord],
    atlas: &Atlas,
    camera: &CameraOrigin,
    p: Vec3,
    side: Vec3,
) -> Option<Vec3> {
    receiver_field_normal_counted(records, atlas, camera, p, side)
        .0
        .map(|(n, _)| n)
}

/// [`receiver_field_normal`] with the flags of the record it came from, and the distance
/// evaluations it took (one, and four more where the receiver lies on the field).
fn receiver_field_normal_counted(
    records: &[ObjectRecord],
    atlas: &Atlas,
    camera: &CameraOrigin,
    p: Vec3,
    side: Vec3,
) -> (Option<(Vec3, u32)>, u32) {
    let mut evaluations = 0;
    let mut best: Option<(f32, Vec3, u32)> = None;
    for r in records {
        if !flags::casts_shadows(r.flags()) {
            continue;
        }
        let Some((center, radius)) = bounding_sphere(r, camera) else {
            continue;
        };
        let v = p - center;
        if v.dot(v) > radius * radius {
            continue;
        }
        if r.kind() == ShapeKind::Volume as u32 {
            evaluations += 1;
        }
        if let Some((n, d)) = field_normal(r, atlas, camera, p, side) {
            evaluations += 4;
            if best.is_none_or(|(b, _, _)| d < b) {
                best = Some((d, n, r.flags()));
            }
        }
    }
    (best.map(|(_, n, f)| (n, f)), evaluations)
}

/// The outward unit normal of volume record `r`'s surface at camera-relative receiver
/// `p`, and the field's mean distance where it was read: the gradient of the field by a
/// tetrahedron of four samples [`FIELD_NORMAL_STEP_VOXELS`] voxels about `p` — about the
/// point a voxel along `side` (the G-buffer normal turned to face the eye) for a
/// two-sided field, whose shell is symmetric about its sheet, so that the normal is the
/// side the eye sees (read a voxel toward the eye instead, a curved sheet's normal leaned
/// toward the eye: 12° median error on a torus, against 3°). `None` for
/// analytic shapes, where `p` lies more than [`FIELD_NORMAL_REACH_VOXELS`] voxels outside
/// the field's surface, or where the gradient's length is not a distance's
/// ([`FIELD_NORMAL_MIN_GRADIENT`]). `shadow.wgsl`'s `caster_field_normal`.
pub fn field_normal(
    r: &ObjectRecord,
    atlas: &Atlas,
    camera: &CameraOrigin,
    p: Vec3,
    side: Vec3,
) -> Option<(Vec3, f32)> {
    let h = r.conservative_scale();
    if r.kind() != ShapeKind::Volume as u32 || h.is_nan() || h <= 0.0 {
        return None;
    }
    let d = |q: Vec3| object_distance(r, q, camera, atlas);
    // NaN distances read no normal.
    let reach = d(p);
    if reach.is_nan() || reach > FIELD_NORMAL_REACH_VOXELS * h {
        return None;
    }
    let two_sided = r.flags() & flags::TWO_SIDED != 0;
    let q = p + side * if two_sided { h } else { 0.0 };
    let (g, mean) = tetrahedral_gradient(q, FIELD_NORMAL_STEP_VOXELS * h, d);
    let len = g.length();
    if !(FIELD_NORMAL_MIN_GRADIENT..=FIELD_NORMAL_MAX_GRADIENT).contains(&len) {
        return None;
    }
    Some((g / len, mean))
}

/// The terrains' visibility along the shadow ray `(dir, t_max, tan_half)` from
/// camera-relative `p`, and the evaluations.
fn terrain_visibility(
    terrain: &HeightfieldTexture,
    camera: &CameraOrigin,
    p: Vec3,
    (dir, t_max, tan_half): (Vec3, f32, f32),
    light: &MaskLight,
) -> (f32, u32) {
    let (mut visibility, mut evaluations) = (1.0f32, 0);
    for h in &terrain.records {
        let base = (IVec3::from_array(camera.tile) - h.tile).as_vec3() * TILE_SIZE + camera.offset;
        let local = base + p;
        let end = local + dir * t_max;
        let grow = t_max * tan_half;
        let (lo, hi) = h.aabb();
        if (local.min(end) - grow).cmpgt(hi).any() || (local.max(end) + grow).cmplt(lo).any() {
            continue;
        }
        // At least half a cell across the terrain per step: a ray running along a slope
        // (where the bound is small) still crosses the terrain in the step budget.
        let cell = (h.extent / (h.size - glam::UVec2::ONE).as_vec2()).min_element();
        let min_step = 0.5 * cell / Vec2::new(dir.x, dir.z).length().max(1e-3);
        let mut t = light.bias;
        let mut v = 1.0f32;
        for _ in 0..light.max_steps {
            if t >= t_max {
                break;
            }
            let d = terrain.distance(h, local + dir * t);
            evaluations += 1;
            let cone = (t * tan_half).max(1e-6);
            v = v.min(d / cone);
            if v <= -1.0 {
                break;
            }
            t += d.abs().max(min_step).max(cone * PENUMBRA_MIN_STEP);
        }
        visibility = visibility.min(penumbra_visibility(v));
    }
    (visibility, evaluations)
}

/// Whether `p` lies inside object `r`'s analytic shape (a sphere, box, capsule or the
/// solid below a plane; never a volume): such a shape stands in for the mesh the receiver
/// is on (a character's capsules), so it neither shadows nor occludes it.
pub fn inside_analytic(r: &ObjectRecord, p: Vec3, camera: &CameraOrigin, atlas: &Atlas) -> bool {
    r.kind() != ShapeKind::Volume as u32 && object_distance(r, p, camera, atlas) < 0.0
}

/// Whether a point or spot light reaches camera-relative `p` at all: within its range
/// and, for a spot, inside its outer cone — elsewhere Bevy's attenuation is exactly 0,
/// so the pass does not trace (visibility 1, like pixels beyond a directional light's
/// `max_view_distance`). A slack of 10⁻⁴ (relative range, cosine) keeps rounding from
/// skipping a lit pixel; NaN traces. Directional lights reach everywhere.
pub fn light_reaches(light: &MaskLight, p: Vec3) -> bool {
    let MaskLightKind::Positional(at) = light.kind else {
        return true;
    };
    let v = p - at;
    let d2 = v.length_squared();
    let reach = light.range * (1.0 + 1e-4);
    if d2 > reach * reach {
        return false;
    }
    match light.spot {
        Some((dir, cos_outer)) if cos_outer >= -1.0 => {
            // NaN is not outside.
            let outside = v.dot(dir) < (cos_outer - 1e-4) * d2.sqrt();
            !outside
        }
        _ => true,
    }
}

/// How far past facing away from the eye (`−n · e`, cosine) a G-buffer normal must be
/// to count as inverted rather than as a smooth normal past a silhouette
/// ([`facing_the_eye`]). A vertex normal of a mesh with 16 segments around is at most
/// 11° (cosine 0.2) from its faces. `shadow.wgsl`'s `INVERTED_NORMAL_COS`.
pub const INVERTED_NORMAL_COS: f32 = 0.25;

/// A receiver's normal (unit or zero) turned into the hemisphere that faces the eye,
/// for camera-relative position `p` (`shadow.wgsl`'s `facing_the_eye`; the shadow and
/// AO traces turn every G-buffer normal with it). A surface
/// the camera sees faces it (the triangle does, or the rasterizer culled it; Bevy
/// flips a double-sided back face's normal), but a G-buffer normal need not: normals
/// exported opposite to their triangles' winding (the palm tree's leaves: 180° from
/// their faces on both sides) face away from the eye wherever they are seen, and a
/// smooth normal past a silhouette faces away a little. The first is negated (past
/// [`INVERTED_NORMAL_COS`]), the second reflected across the plane normal to the view
/// ray (its direction along the surface kept). Read as they were, inverted normals hid
/// sunlit leaves from the sun (the scene corpus's palm tree: 0.315 → 0.137 mean error
/// on shadowed pixels; reflecting them all: 0.162; negating them all darkened smooth
/// silhouettes: the depth-of-field scene 0.103 → 0.120). Normals that face the eye are
/// returned as they are.
pub fn facing_the_eye(normal: Vec3, p: Vec3) -> Vec3 {
    let to_eye = -p.normalize_or_zero();
    let c = normal.dot(to_eye);
    if c < -INVERTED_NORMAL_COS {
        return -normal;
    }
    normal - 2.0 * c.min(0.0) * to_eye
}

/// The fraction of the light's disc above the receiver's tangent plane (unit `normal`;
/// zero: unknown, 1): the disc of angular radius θ (`tan θ = tan_half`) seen from a
/// plane it is centred `normal · dir / sin θ` radii above. 1 when `normal · dir ≥ sin θ`,
/// 0 when `≤ −sin θ` (back faces), the disc's area above the chord between: the
/// surface's own shadow, exact for a plane. Never NaN.
pub fn horizon(normal: Vec3, dir: Vec3, tan_half: f32) -> f32 {
    if normal == Vec3::ZERO {
        return 1.0;
    }
    let sin_half = tan_half / (1.0 + tan_half * tan_half).sqrt();
    let r = normal.dot(dir) / sin_half.max(1e-6);
    let finite = (-1e30..=1e30).contains(&r); // false for NaN
    if !finite {
        return 1.0;
    }
    let x = r.clamp(-1.0, 1.0);
    let h = 0.5 + (x * (1.0 - x * x).max(0.0).sqrt() + x.asin()) / std::f32::consts::PI;
    if h >= 0.0 { h.clamp(0.0, 1.0) } else { 1.0 }
}

/// The normal word of Bevy's deferred G-buffer (its fourth channel) for unit `n`:
/// `pack_24bit_normal_and_flags(octahedral_encode(n), 0)` — octahedral coordinates at
/// 12 bits each (about 0.05° apart), flags in the top byte. For tests that stand in for
/// Bevy's prepass.
pub fn pack_gbuffer_normal(n: Vec3) -> u32 {
    let n = n / (n.x.abs() + n.y.abs() + n.z.abs());
    let sign = |v: f32| if v > 0.0 { 1.0 } else { -1.0 };
    let wrap = Vec2::new((1.0 - n.y.abs()) * sign(n.x), (1.0 - n.x.abs()) * sign(n.y));
    let xy = if n.z >= 0.0 {
        Vec2::new(n.x, n.y)
    } else {
        wrap
    };
    let e = xy * 0.5 + Vec2::splat(0.5);
    // `u32(saturate(x) * 4095 + 0.5)`; NaN saturates to 0 on the GPU.
    let unorm = |x: f32| (x.clamp(0.0, 1.0) * 4095.0 + 0.5) as u32 & 0xfff;
    unorm(e.x) | (unorm(e.y) << 12)
}

/// The unit normal in a G-buffer normal word (Bevy's `unpack_24bit_normal` and
/// `octahedral_decode`; flags ignored): what the mask pass reads.
pub fn unpack_gbuffer_normal(word: u32) -> Vec3 {
    let e = Vec2::new((word & 0xfff) as f32, ((word >> 12) & 0xfff) as f32) / 4095.0;
    let f = e * 2.0 - Vec2::ONE;
    let mut n = Vec3::new(f.x, f.y, 1.0 - f.x.abs() - f.y.abs());
    let t = (-n.z).clamp(0.0, 1.0);
    let w = |v: f32| if v >= 0.0 { -t } else { t };
    n.x += w(n.x);
    n.y += w(n.y);
    n.normalize()
}

/// Shaping (`v^shaping`), clamping, and no NaN: what the pass writes.
pub fn finish(visibility: f32, shaping: f32) -> f32 {
    let v = visibility.clamp(0.0, 1.0).powf(shaping);
    if v >= 0.0 { v.min(1.0) } else { 1.0 }
}

/// Relative depth difference at which a half-resolution texel's weight in [`upsample`]
/// reaches zero.
pub const UPSAMPLE_DEPTH_TOLERANCE: f32 = 0.1;

/// Bilateral upsampling of a half-resolution mask (`df/shadow_upsample.wgsl`): texel
/// `(i, j)` of `half` (`half_size`) holds the visibility traced at full-resolution pixel
/// `(2i, 2j)`; `distance` holds every full-resolution pixel's distance from the camera
/// (0: background, whose result is 1). Each pixel blends the four texels around it with
/// bilinear weights scaled by `max(0, 1 − |Δd| / (d · tolerance))`; if none is close in
/// depth, the closest texel wins.
pub fn upsample(
    half: &[f32],
    half_size: glam::UVec2,
    distance: &[f32],
    full_size: glam::UVec2,
) -> Vec<f32> {
    let at = |x: u32, y: u32| distance[(y * full_size.x + x) as usize];
    (0..full_size.y)
        .flat_map(|y| (0..full_size.x).map(move |x| (x, y)))
        .map(|(x, y)| {
            let d = at(x, y);
            if d.is_nan() || d <= 0.0 {
                return 1.0;
            }
            let h = Vec2::new(x as f32, y as f32) * 0.5;
            let (i0, f) = (h.floor(), h - h.floor());
            let (mut sum, mut weights, mut nearest, mut nearest_error) =
                (0.0f32, 0.0f32, 1.0f32, f32::MAX);
            for k in 0..4u32 {
                let (ox, oy) = (k & 1, k >> 1);
                let tx = (i0.x as u32 + ox).min(half_size.x - 1);
                let ty = (i0.y as u32 + oy).min(half_size.y - 1);
                let v = half[(ty * half_size.x + tx) as usize];
                let ds = at((2 * tx).min(full_size.x - 1), (2 * ty).min(full_size.y - 1));
                let error = (ds - d).abs() / d;
                let wx = if ox == 1 { f.x } else { 1.0 - f.x };
                let wy = if oy == 1 { f.y } else { 1.0 - f.y };
                let w = wx * wy * (1.0 - error / UPSAMPLE_DEPTH_TOLERANCE).max(0.0);
                sum += v * w;
                weights += w;
                if error < nearest_error {
                    nearest_error = error;
                    nearest = v;
                }
            }
            let out = if weights > 1e-4 {
                sum / weights
            } else {
                nearest
            };
            let out = out.clamp(0.0, 1.0);
            if out >= 0.0 { out } else { 1.0 }
        })
        .collect()
}

/// Camera-relative world position of the pixel centre `(x + ½, y + ½)` at reverse-Z
/// `depth` (> 0), for a `size` image: NDC from the pixel, through `view_from_clip`, then
/// rotated by the camera's world-from-view rotation (no translation: camera-relative).
pub fn position_from_depth(
    view_from_clip: Mat4,
    world_from_view: Mat3,
    size: Vec2,
    pixel: Vec2,
    depth: f32,
) -> Vec3 {
    let uv = (pixel + Vec2::splat(0.5)) / size;
    let ndc = Vec4::new(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, depth, 1.0);
    let v = view_from_clip * ndc;
    world_from_view * (v.truncate() / v.w)
}

#[cfg(test)]
mod tests;
