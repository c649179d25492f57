// Distance-field soft shadows: the per-pixel visibility of one light through the
// scene's distance-field objects. CPU model: `penumbra_reference::shadow_mask` (same
// culling, march, clamps and shaping, in the same order).
//
// Per object, sphere-trace toward the light, through the object too, keeping the least
// `d / r(t)` down to −1 (`r(t) = t · tan θ`); the object leaves its smoothstep from −1 to
// 1 of the light open (the two-sided penumbra: ½ at a silhouette; `penumbra_visibility`),
// and the smallest over the objects wins. A bounded object of radius R covers at most
// (R / r)² of the cone's section, so its ratio stays above 1 − 2 (R / r)² (tiny objects
// on the axis).
#define_import_path penumbra::df::shadow

#import penumbra::df::object::{
    DistanceFieldObject, FLAG_CASTS_SHADOWS, FLAG_CAST_HIDDEN_SHADOW, FLAG_LIVE, FLAG_TWO_SIDED,
    FLAG_VISIBLE,
    KIND_CAPSULE, KIND_SPHERE, KIND_VOLUME,
    camera_relative, object_kind, rows_column, shape_bounds, transform_rows,
}
#import penumbra::df::distance::object_distance

// A light as the shadow passes see it (64 bytes; `penumbra_reference::shadow_mask::MaskLight`).
struct ShadowLight {
    // xyz: unit vector toward the light (directional) or camera-relative position
    // (point, spot); w: 0 directional, 1 positional.
    position_or_direction: vec4<f32>,
    // Positional: source radius, metres. Directional: tan of half the angular diameter.
    source: f32,
    // Directional: ray length, metres.
    max_distance: f32,
    // Start offset along the ray, metres.
    bias: f32,
    // Visibility v becomes v^shaping (the encoder clamps shaping to [0.05, 20]).
    shaping: f32,
    // Positional: the light's range, metres (culling).
    range: f32,
    max_steps: u32,
    // Directional: pixels farther than this from the camera, metres, are not traced
    // (visibility 1); the light cull drops casters that could shadow only those.
    max_view_distance: f32,
    reserved: u32,
    // Spot lights: xyz the unit direction the spot points, w the cosine of its outer
    // angle (w < −1: no cone).
    spot: vec4<f32>,
}

struct ShadowRay {
    dir: vec3<f32>,
    t_max: f32,
    tan_half: f32,
}

fn is_directional(light: ShadowLight) -> bool {
    return light.position_or_direction.w == 0.0;
}

// Gershgorin bound of the largest singular value of the matrix with columns c0, c1, c2
// (exact for rotation × scale).
fn max_scale(c0: vec3<f32>, c1: vec3<f32>, c2: vec3<f32>) -> f32 {
    let g01 = abs(dot(c0, c1));
    let g02 = abs(dot(c0, c2));
    let g12 = abs(dot(c1, c2));
    return sqrt(max(max(dot(c0, c0) + g01 + g02, dot(c1, c1) + g01 + g12), dot(c2, c2) + g02 + g12));
}

// Camera-relative bounding sphere (xyz centre, w radius) of a shape; w < 0: unbounded.
fn bounding_sphere(o: DistanceFieldObject, camera_tile: vec3<i32>, camera_offset: vec3<f32>) -> vec4<f32> {
    let b = shape_bounds(o);
    if !b.bounded {
        return vec4<f32>(0.0, 0.0, 0.0, -1.0);
    }
    let half = (b.max - b.min) * 0.5;
    let center_tile = transform_rows(o.world_from_shape, (b.min + b.max) * 0.5);
    let center = camera_relative(o.tile, center_tile, camera_tile, camera_offset);
    let cx = rows_column(o.world_from_shape, 0u);
    let cy = rows_column(o.world_from_shape, 1u);
    let cz = rows_column(o.world_from_shape, 2u);
    let f = bitcast<vec3<f32>>(o.params);
    var radius: f32;
    switch object_kind(o) {
        case KIND_SPHERE: {
            radius = f.x * max_scale(cx, cy, cz);
        }
        case KIND_CAPSULE: {
            radius = length(cy) * f.y + f.x * max_scale(cx, cy, cz);
        }
        default: {
            let ax = cx * half.x;
            let ay = cy * half.y;
            let az = cz * half.z;
            radius = max(
                max(length(ax + ay + az), length(ax + ay - az)),
                max(length(ax - ay + az), length(ax - ay - az)),
            );
        }
    }
    return vec4<f32>(center, radius);
}

// Signed distance from p to the convex hull of balls (a, ra) and (b, rb) (Quílez).
fn round_cone_distance(p: vec3<f32>, a: vec3<f32>, b: vec3<f32>, ra: f32, rb: f32) -> f32 {
    let ba = b - a;
    let l2 = dot(ba, ba);
    let rr = ra - rb;
    let a2 = l2 - rr * rr;
    if a2 <= 0.0 {
        return min(length(p - a) - ra, length(p - b) - rb);
    }
    let il2 = 1.0 / l2;
    let pa = p - a;
    let y = dot(pa, ba);
    let z = y - l2;
    let w = pa * l2 - ba * y;
    let x2 = dot(w, w);
    let y2 = y * y * l2;
    let z2 = z * z * l2;
    let k = sign(rr) * rr * rr * x2;
    if sign(z) * a2 * z2 > k {
        return sqrt(x2 + z2) * il2 - rb;
    }
    if sign(y) * a2 * y2 < k {
        return sqrt(x2 + y2) * il2 - ra;
    }
    return (sqrt(x2 * a2 * il2) + y * rr) * il2 - ra;
}

// Slack added to bounding radii in culling tests (rounding must never drop an object).
fn cull_slack(radius: f32) -> f32 {
    return radius * 1e-4 + 1e-4;
}

fn shadow_ray(p: vec3<f32>, light: ShadowLight) -> ShadowRay {
    if is_directional(light) {
        return ShadowRay(light.position_or_direction.xyz, light.max_distance, light.source);
    }
    let v = light.position_or_direction.xyz - p;
    let d = max(length(v), 1e-6);
    let s = clamp(light.source / max(d, light.source), 0.0, 1.0);
    let tan_half = s / sqrt(max(1.0 - s * s, 1e-12));
    return ShadowRay(v / d, max(d - light.source, 0.0), tan_half);
}

// Whether the object (bounding sphere `sphere`) can reach the cone of `ray` from `p`.
fn object_in_cone(sphere: vec4<f32>, p: vec3<f32>, ray: ShadowRay) -> bool {
    if sphere.w < 0.0 {
        return true;
    }
    let end = p + ray.dir * ray.t_max;
    return round_cone_distance(sphere.xyz, p, end, 0.0, ray.t_max * ray.tan_half)
        < sphere.w + cull_slack(sphere.w);
}

// The part (x, y) of the ray o + t · dir (o relative to a ball's centre) where the
// cone of radius t · tan_half meets the ball; y < x: never; cones wider than 45°: all.
fn cone_interval(o: vec3<f32>, dir: vec3<f32>, radius: f32, tan_half: f32) -> vec2<f32> {
    let a = 1.0 - tan_half * tan_half;
    if a <= 1e-6 {
        return vec2<f32>(-3.4e38, 3.4e38);
    }
    let b = 2.0 * (dot(o, dir) - radius * tan_half);
    let c = dot(o, o) - radius * radius;
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return vec2<f32>(1.0, -1.0);
    }
    let s = sqrt(disc);
    return vec2<f32>((-b - s) / (2.0 * a), (-b + s) / (2.0 * a));
}

// Self-shadow offset of two-sided fields (`penumbra_df_core::shadow::{SELF_SHADOW_VOXELS,
// SHELL_VOXELS, SELF_SHADOW_MAX_START_VOXELS}`).
const SELF_SHADOW_VOXELS: f32 = 0.5;
const SHELL_VOXELS: f32 = 0.8660254;
const SELF_SHADOW_MAX_START_VOXELS: f32 = 4.0;
const FINE_FIELD_BIAS_VOXELS: f32 = 2.0;

// Where the march through object `o` starts along the ray for a receiver of unit normal
// `n` (zero: unknown): for a two-sided (shell) field, where the ray has risen past the
// shell about the receiver's own surface and half a voxel more, at most 4 voxels
// farther; 0 for solid fields and analytic shapes
// (`penumbra_df_core::shadow::self_shadow_start`).
fn self_shadow_start(o: DistanceFieldObject, n: vec3<f32>, dir: vec3<f32>) -> f32 {
    let voxel = o.conservative_scale;
    let shell = object_kind(o) == KIND_VOLUME && (o.flags & FLAG_TWO_SIDED) != 0u;
    if !shell || !(voxel > 0.0) || all(n == vec3<f32>(0.0)) {
        return 0.0;
    }
    let rise = (SHELL_VOXELS + SELF_SHADOW_VOXELS) * voxel;
    return min(rise / max(dot(n, dir), 1e-3), rise + SELF_SHADOW_MAX_START_VOXELS * voxel);
}

// Where the march through object `o` starts along the ray from a receiver of unit normal
// `n` (zero: unknown) under a light of world bias `bias`: the bias, or
// FINE_FIELD_BIAS_VOXELS voxels of a finer field (a small prop keeps its contact
// shadows), and never inside a two-sided field's own shell
// (`penumbra_df_core::shadow::march_start`).
fn march_start(o: DistanceFieldObject, n: vec3<f32>, dir: vec3<f32>, bias: f32) -> f32 {
    var start = bias;
    let voxel = o.conservative_scale;
    if object_kind(o) == KIND_VOLUME && voxel > 0.0 {
        start = min(start, FINE_FIELD_BIAS_VOXELS * voxel);
    }
    return max(start, self_shadow_start(o, n, dir));
}

// The field's own normal at a receiver, and when it replaces the G-buffer's
// (`penumbra_df_core::shadow::FIELD_NORMAL_*`).
const FIELD_NORMAL_REACH_VOXELS: f32 = 1.0;
const FIELD_NORMAL_STEP_VOXELS: f32 = 0.5;
const FIELD_NORMAL_MIN_GRADIENT: f32 = 0.25;
const FIELD_NORMAL_MAX_GRADIENT: f32 = 2.0;
const FIELD_NORMAL_MIN_AGREEMENT: f32 = 0.7;
const FIELD_NORMAL_MIN_FACING: f32 = 0.3;
const FIELD_NORMAL_MIN_FACING_SHADED: f32 = 0.0;
// A G-buffer normal is its face's own where the depth buffer lies in its tangent plane
// within this sine (`penumbra_df_core::shadow::FLAT_SHADED_SIN`; `shadow_trace.wgsl`'s
// `flat_shaded`).
const FLAT_SHADED_SIN: f32 = 0.07;
// Where the G-buffer normal still hides the light, the depth buffer's face normal
// decides if every neighbour lies within this sine of its plane and it agrees with the
// G-buffer normal by this cosine (`penumbra_df_core::shadow::FACE_NORMAL_*`;
// `shadow_trace.wgsl`'s `depth_face_normal`).
const FACE_NORMAL_PLANE_SIN: f32 = 0.2;
const FACE_NORMAL_MIN_AGREEMENT: f32 = 0.9;
// The face-normal prepass's normal is trusted where its reverse-Z depth lies within this
// fraction of the G-buffer's (`penumbra_df_core::shadow::FACE_DEPTH_TOLERANCE`).
const FACE_DEPTH_TOLERANCE: f32 = 0.001;
// A receiver sees a solid volume from its inside (the back of an open surface baked
// solid) where the field, read FROM_INSIDE_PROBE_VOXELS voxels along its normal toward
// the eye, lies FROM_INSIDE_MIN_DEPTH_VOXELS inside and falls by FROM_INSIDE_MIN_DROP_VOXELS
// from the probe behind it, the receiver within FROM_INSIDE_ON_SURFACE_VOXELS of its
// surface (`penumbra_df_core::shadow::seen_from_inside`).
const FROM_INSIDE_MIN_DEPTH_VOXELS: f32 = 0.25;
const FROM_INSIDE_PROBE_VOXELS: f32 = 1.0;
const FROM_INSIDE_MIN_DROP_VOXELS: f32 = 0.5;
const FROM_INSIDE_ON_SURFACE_VOXELS: f32 = 0.25;
// No field normal: `w` above every distance.
const NO_FIELD_NORMAL: vec4<f32> = vec4<f32>(0.0, 0.0, 0.0, 3.0e38);

// The outward normal of volume `o`'s surface at the receiver `p`, from the field's
// gradient (a tetrahedron of four samples) — about the point a voxel along `side` (the
// G-buffer normal turned to face the eye) for a two-sided field, whose shell is
// symmetric about its sheet, so that the normal is the side the eye sees: xyz the unit
// normal, w the field's mean distance there (among several objects the smallest wins).
// NO_FIELD_NORMAL where `o` is not a volume, `p` lies farther than
// FIELD_NORMAL_REACH_VOXELS outside its surface, or the gradient's length is not a
// distance's. CPU model: `penumbra_reference::shadow_mask::field_normal`.
fn caster_field_normal(
    o: DistanceFieldObject,
    p: vec3<f32>,
    side: vec3<f32>,
    camera_tile: vec3<i32>,
    camera_offset: vec3<f32>,
    atlas: texture_3d<f32>,
    brick_table: texture_2d<u32>,
) -> vec4<f32> {
    let h = o.conservative_scale;
    if object_kind(o) != KIND_VOLUME || !(h > 0.0) {
        return NO_FIELD_NORMAL;
    }
    if !(object_distance(o, p, camera_tile, camera_offset, atlas, brick_table) <= FIELD_NORMAL_REACH_VOXELS * h) {
        return NO_FIELD_NORMAL;
    }
    // A two-sided field's shell is symmetric about its sheet: read it on the side seen.
    let two_sided = (o.flags & FLAG_TWO_SIDED) != 0u;
    let q = p + side * select(0.0, h, two_sided);
    let s = FIELD_NORMAL_STEP_VOXELS * h;
    let d = tetrahedral_distances(o, q, s, camera_tile, camera_offset, atlas, brick_table);
    let g = tetrahedral_gradient(d, s);
    let len = length(g);
    if !(len >= FIELD_NORMAL_MIN_GRADIENT && len <= FIELD_NORMAL_MAX_GRADIENT) {
        return NO_FIELD_NORMAL;
    }
    return vec4<f32>(g / len, 0.25 * (d.x + d.y + d.z + d.w));
}

// Whether the receiver at `p` (unit normal `n` turned to face the eye; zero: unknown)
// sees solid volume `o` from its inside: then `o` is not marched for it and the field's
// reversed normal gives its own shadow (`penumbra_df_core::shadow::seen_from_inside`).
// One to three reads, for solid volumes whose bounding ball `sphere` holds `p`.
// Whether camera-relative `p` lies inside object `o`'s analytic shape (never a volume):
// such a shape stands in for the mesh the receiver is on (a character's capsules), so it
// does not shadow it (`penumbra_reference::shadow_mask::inside_analytic`).
fn inside_analytic(
    o: DistanceFieldObject,
    p: vec3<f32>,
    camera_tile: vec3<i32>,
    camera_offset: vec3<f32>,
    atlas: texture_3d<f32>,
    brick_table: texture_2d<u32>,
) -> bool {
    return object_kind(o) != KIND_VOLUME && object_distance(o, p, camera_tile, camera_offset, atlas, brick_table) < 0.0;
}

fn seen_from_inside(
    o: DistanceFieldObject,
    sphere: vec4<f32>,
    p: vec3<f32>,
    n: vec3<f32>,
    camera_tile: vec3<i32>,
    camera_offset: vec3<f32>,
    atlas: texture_3d<f32>,
    brick_table: texture_2d<u32>,
) -> bool {
    let h = o.conservative_scale;
    let v = p - sphere.xyz;
    if object_kind(o) != KIND_VOLUME || (o.flags & FLAG_TWO_SIDED) != 0u || !(h > 0.0)
        || all(n == vec3<f32>(0.0)) || dot(v, v) > sphere.w * sphere.w {
        return false;
    }
    let at = object_distance(o, p, camera_tile, camera_offset, atlas, brick_table);
    if !(abs(at) <= FROM_INSIDE_ON_SURFACE_VOXELS * h) {
        return false;
    }
    let probe = n * (FROM_INSIDE_PROBE_VOXELS * h);
    let front = object_distance(o, p + probe, camera_tile, camera_offset, atlas, brick_table);
    let back = object_distance(o, p - probe, camera_tile, camera_offset, atlas, brick_table);
    return front <= -FROM_INSIDE_MIN_DEPTH_VOXELS * h && front - back <= -FROM_INSIDE_MIN_DROP_VOXELS * h;
}

// The tetrahedral stencil's corners (`penumbra_df_core::shadow::tetrahedral_gradient`).
const TETRAHEDRON_0: vec3<f32> = vec3<f32>(1.0, -1.0, -1.0);
const TETRAHEDRON_1: vec3<f32> = vec3<f32>(-1.0, -1.0, 1.0);
const TETRAHEDRON_2: vec3<f32> = vec3<f32>(-1.0, 1.0, -1.0);
const TETRAHEDRON_3: vec3<f32> = vec3<f32>(1.0, 1.0, 1.0);

// Object `o`'s distances at the corners of a tetrahedron `s` from `q` along each axis.
fn tetrahedral_distances(
    o: DistanceFieldObject,
    q: vec3<f32>,
    s: f32,
    camera_tile: vec3<i32>,
    camera_offset: vec3<f32>,
    atlas: texture_3d<f32>,
    brick_table: texture_2d<u32>,
) -> vec4<f32> {
    return vec4<f32>(
        object_distance(o, q + TETRAHEDRON_0 * s, camera_tile, camera_offset, atlas, brick_table),
        object_distance(o, q + TETRAHEDRON_1 * s, camera_tile, camera_offset, atlas, brick_table),
        object_distance(o, q + TETRAHEDRON_2 * s, camera_tile, camera_offset, atlas, brick_table),
        object_distance(o, q + TETRAHEDRON_3 * s, camera_tile, camera_offset, atlas, brick_table),
    );
}

// The gradient from the tetrahedron's distances `d`, `s` from its centre.
fn tetrahedral_gradient(d: vec4<f32>, s: f32) -> vec3<f32> {
    return (TETRAHEDRON_0 * d.x + TETRAHEDRON_1 * d.y + TETRAHEDRON_2 * d.z + TETRAHEDRON_3 * d.w)
        / (4.0 * s);
}

// The fraction of the light's cone one object leaves open along the ray from p, the
// march starting `start` along it at the earliest (`march_start`, or the light's bias).
fn march_object(
    o: DistanceFieldObject,
    sphere: vec4<f32>,
    p: vec3<f32>,
    ray: ShadowRay,
    light: ShadowLight,
    start: f32,
    camera_tile: vec3<i32>,
    camera_offset: vec3<f32>,
    atlas: texture_3d<f32>,
    brick_table: texture_2d<u32>,
) -> f32 {
    var t = start;
    var t_end = ray.t_max;
    if sphere.w >= 0.0 {
        // March only where the cone meets the object's ball.
        let span = cone_interval(p - sphere.xyz, ray.dir, sphere.w, ray.tan_half);
        if span.y < span.x {
            return 1.0;
        }
        t = max(t, span.x);
        t_end = min(t_end, span.y);
    }
    // The least distance over the cone's radius, down to −1 (inside by a radius): the
    // two-sided penumbra (`penumbra_df_core::shadow::penumbra_step`).
    var v = 1.0;
    var voxel = 0.0;
    if object_kind(o) == KIND_VOLUME {
        voxel = o.conservative_scale;
    }
    let two_sided = object_kind(o) == KIND_VOLUME && (o.flags & FLAG_TWO_SIDED) != 0u;
    // Inside a solid part, and the surface's normal where the ray went in.
    var inside = false;
    var normal_in = vec3<f32>(0.0);
    var before = t;
    for (var step = 0u; step < light.max_steps; step += 1u) {
        if t >= t_end {
            break;
        }
        let d = object_distance(o, p + ray.dir * t, camera_tile, camera_offset, atlas, brick_table);
        let cone = max(t * ray.tan_half, 1e-6);
        // A tiny object covers only (R / r)² of the cone's section, even inside it.
        var floor_v = -1.0;
        if sphere.w >= 0.0 {
            let q = sphere.w / cone;
            floor_v = 1.0 - 2.0 * min(q * q, 1.0);
        }
        let stencil = crossing_stencil(cone, voxel);
        var ratio = d / cone;
        var advance = 0.0;
        if d <= 0.0 {
            if two_sided {
                ratio = -1.0;
            } else {
                if !inside {
                    inside = true;
                    normal_in = crossing_normal(o, p + ray.dir * before, stencil, camera_tile, camera_offset, atlas, brick_table);
                }
                advance = max(-d, cone * PENUMBRA_MIN_STEP);
            }
        } else {
            if inside {
                inside = false;
                let normal_out = crossing_normal(o, p + ray.dir * t, stencil, camera_tile, camera_offset, atlas, brick_table);
                if dot(normal_in, normal_out) < THIN_CROSSING_COSINE {
                    let x = p + ray.dir * (0.5 * (before + t));
                    ratio = thin_crossing_ratio(o, x, normal_in, ray.dir, cone, camera_tile, camera_offset, atlas, brick_table);
                }
            }
            advance = max(d, surface_step(cone, voxel));
        }
        v = min(v, max(ratio, floor_v));
        // Covered (a tiny object's floor still leaves some light).
        if ratio <= -1.0 {
            break;
        }
        before = t;
        t += advance;
    }
    return penumbra_visibility(v);
}

// The two-sided penumbra (`penumbra_df_core::shadow::PENUMBRA_MIN_STEP`): a march goes
// on through a solid occluder, at least this many cone radii a step, keeping the least
// distance over the cone's radius down to −1; the light's open fraction is its
// smoothstep from −1 to 1 (½ where the cone's axis grazes a silhouette).
const PENUMBRA_MIN_STEP: f32 = 0.25;
// Outside, a step of at least this many voxels (at most PENUMBRA_MIN_STEP radii; a
// hundredth of a radius for analytic shapes).
const SURFACE_STEP_VOXELS: f32 = 0.25;

// A ray through a solid part crossed a thin part where the normals where it went in and
// came out meet below this cosine (`penumbra_df_core::shadow::THIN_CROSSING_COSINE`).
const THIN_CROSSING_COSINE: f32 = -0.5;
// How far a grazing crossing's rim reaches along the light, at most, in cone radii
// (`penumbra_df_core::shadow::THIN_CROSSING_MAX_STRETCH`).
const THIN_CROSSING_MAX_STRETCH: f32 = 4.0;

// The least step outside an occluder (`penumbra_df_core::shadow::surface_step`).
fn surface_step(cone: f32, voxel: f32) -> f32 {
    if voxel > 0.0 {
        return min(SURFACE_STEP_VOXELS * voxel, cone * PENUMBRA_MIN_STEP);
    }
    return 0.01 * cone;
}

// The normals' stencil (`penumbra_df_core::shadow::crossing_stencil`).
fn crossing_stencil(cone: f32, voxel: f32) -> f32 {
    return select(0.05 * cone, 0.5 * voxel, voxel > 0.0);
}

// The unit normal of object `o`'s distance at `q` from a tetrahedron of samples `s` from
// it (`penumbra_df_core::shadow::tetrahedral_normal`; zero where the gradient vanishes).
fn crossing_normal(
    o: DistanceFieldObject,
    q: vec3<f32>,
    s: f32,
    camera_tile: vec3<i32>,
    camera_offset: vec3<f32>,
    atlas: texture_3d<f32>,
    brick_table: texture_2d<u32>,
) -> vec3<f32> {
    let g = tetrahedral_gradient(tetrahedral_distances(o, q, s, camera_tile, camera_offset, atlas, brick_table), s);
    let len = length(g);
    return select(vec3<f32>(0.0), g / len, len > 0.0);
}

// Where a march crossed a thin part at `x` (its normal where the ray went in
// `normal_in`, the light along `dir`), how much of the cone of radius `cone` it covers,
// as a ratio: the field read a radius from `x` across the light and a stretched radius
// along its trace in the part's plane (the cone's section meets a tilted part in an
// ellipse) puts the part's edges in each direction; the disc's share of the two slabs'
// crossing is the covered fraction (`penumbra_df_core::shadow::{thin_crossing_ratio,
// thin_crossing_rim}`). NaN: covered.
fn thin_crossing_ratio(
    o: DistanceFieldObject,
    x: vec3<f32>,
    normal_in: vec3<f32>,
    dir: vec3<f32>,
    cone: f32,
    camera_tile: vec3<i32>,
    camera_offset: vec3<f32>,
    atlas: texture_3d<f32>,
    brick_table: texture_2d<u32>,
) -> f32 {
    let across = cross(normal_in, dir);
    let across_len2 = dot(across, across);
    let a = select(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0), abs(normal_in.y) < 0.9);
    let c = cross(normal_in, a);
    let fallback = select(vec3<f32>(0.0), c / length(c), dot(c, c) > 0.0);
    let tilted = across_len2 > 1e-8;
    let u = select(fallback, across * inverseSqrt(max(across_len2, 1e-30)), tilted);
    let stretch = select(1.0, min(1.0 / max(abs(dot(normal_in, dir)), 1e-6), THIN_CROSSING_MAX_STRETCH), tilted);
    let v = cross(normal_in, u);
    let s = cone * stretch;
    let rim = vec4<f32>(
        object_distance(o, x + u * cone, camera_tile, camera_offset, atlas, brick_table),
        object_distance(o, x - u * cone, camera_tile, camera_offset, atlas, brick_table),
        object_distance(o, x + v * s, camera_tile, camera_offset, atlas, brick_table),
        object_distance(o, x - v * s, camera_tile, camera_offset, atlas, brick_table),
    );
    if any(rim != rim) || !(cone > 0.0) {
        return -1.0;
    }
    let e = clamp(vec4<f32>(1.0) - rim / vec4<f32>(cone, cone, s, s), vec4<f32>(0.0), vec4<f32>(1.0));
    let covered = disc_slab(e.x, e.y) * disc_slab(e.z, e.w);
    return clamp(visibility_ratio(1.0 - covered), -1.0, 0.0);
}

// The share of a unit disc's area between x = −b and x = a
// (`penumbra_df_core::shadow::disc_slab`).
fn disc_slab(a: f32, b: f32) -> f32 {
    return clamp(disc_part(a) - disc_part(-b), 0.0, 1.0);
}

fn disc_part(x: f32) -> f32 {
    let y = clamp(x, -1.0, 1.0);
    return (asin(y) + y * sqrt(max(1.0 - y * y, 0.0))) * 0.31830988618;
}

// The ratio whose `penumbra_visibility` is `v`: the inverse smoothstep
// (`penumbra_df_core::shadow::visibility_ratio`).
fn visibility_ratio(v: f32) -> f32 {
    let w = clamp(v, 0.0, 1.0);
    let t = 0.5 - sin(asin(1.0 - 2.0 * w) / 3.0);
    return 2.0 * t - 1.0;
}

// The open fraction of the light's disc for a march's least ratio `x`
// (`penumbra_df_core::shadow::penumbra_visibility`; NaN: covered).
fn penumbra_visibility(ratio: f32) -> f32 {
    let x = select(-1.0, clamp(ratio, -1.0, 1.0), ratio == ratio);
    return 0.25 * (1.0 + x) * (1.0 + x) * (2.0 - x);
}

// The unit normal in a word of Bevy's deferred G-buffer (its fourth channel): 12-bit
// octahedral coordinates (`unpack_24bit_normal`, `octahedral_decode`; flags ignored).
// CPU model: `shadow_mask::unpack_gbuffer_normal`.
fn gbuffer_normal(word: u32) -> vec3<f32> {
    let e = vec2<f32>(f32(word & 0xfffu), f32((word >> 12u) & 0xfffu)) / 4095.0;
    let f = e * 2.0 - 1.0;
    var n = vec3<f32>(f.x, f.y, 1.0 - abs(f.x) - abs(f.y));
    let t = clamp(-n.z, 0.0, 1.0);
    n = vec3<f32>(n.xy + select(vec2<f32>(t), vec2<f32>(-t), n.xy >= vec2<f32>(0.0)), n.z);
    return normalize(n);
}

// A G-buffer normal this far past facing away from the eye is inverted, not a smooth
// normal past a silhouette (`shadow_mask::INVERTED_NORMAL_COS`).
const INVERTED_NORMAL_COS: f32 = 0.25;

// `normal` turned into the hemisphere facing the eye from camera-relative `p`: negated
// when it faces away by more than INVERTED_NORMAL_COS, reflected across the view ray's
// normal plane when by less (a visible surface faces the camera; an inverted G-buffer
// normal would hide a lit face from the light, or turn an AO trace into its own surface).
// CPU model: `shadow_mask::facing_the_eye`.
fn facing_the_eye(normal: vec3<f32>, p: vec3<f32>) -> vec3<f32> {
    let l2 = dot(p, p);
    if !(l2 > 0.0) {
        return normal;
    }
    let to_eye = -p * inverseSqrt(l2);
    let c = dot(normal, to_eye);
    if c < -INVERTED_NORMAL_COS {
        return -normal;
    }
    return normal - 2.0 * min(c, 0.0) * to_eye;
}

// The fraction of the light's disc above the receiver's tangent plane (unit normal `n`;
// zero: unknown, 1): the disc of angular radius θ (tan θ = `tan_half`) centred
// `n · dir / sin θ` radii above the plane. 1 when n · dir ≥ sin θ, 0 when ≤ −sin θ: the
// surface's own shadow, exact for a plane (back faces are dark without a march). CPU
// model: `shadow_mask::horizon`.
fn horizon_visibility(n: vec3<f32>, dir: vec3<f32>, tan_half: f32) -> f32 {
    if all(n == vec3<f32>(0.0)) {
        return 1.0;
    }
    let sin_half = tan_half / sqrt(1.0 + tan_half * tan_half);
    let r = dot(n, dir) / max(sin_half, 1e-6);
    if !(r >= -1e30 && r <= 1e30) {
        return 1.0;
    }
    let x = clamp(r, -1.0, 1.0);
    let h = 0.5 + (x * sqrt(max(1.0 - x * x, 0.0)) + asin(x)) / 3.14159265358979;
    return select(1.0, clamp(h, 0.0, 1.0), h >= 0.0);
}

// Whether a point or spot light reaches camera-relative `p` at all: within its range
// and, for a spot, inside its outer cone (elsewhere Bevy's attenuation is exactly 0: the
// pixel is not traced). A 1e-4 slack keeps rounding from skipping a lit pixel; NaN
// traces. CPU model: `shadow_mask::light_reaches`.
fn light_reaches(light: ShadowLight, p: vec3<f32>) -> bool {
    if is_directional(light) {
        return true;
    }
    let v = p - light.position_or_direction.xyz;
    let d2 = dot(v, v);
    let reach = light.range * (1.0 + 1e-4);
    if d2 > reach * reach {
        return false;
    }
    if light.spot.w >= -1.0 {
        return !(dot(v, light.spot.xyz) < (light.spot.w - 1e-4) * sqrt(d2));
    }
    return true;
}

// Whether the light is traced from camera-relative `p` at all: within a directional
// light's `max_view_distance` of the camera, and reached by a point or spot light
// (`light_reaches`); elsewhere the visibility is 1. CPU model: the first checks of
// `shadow_mask::pixel_visibility_with_terrain`.
fn traces_point(light: ShadowLight, p: vec3<f32>) -> bool {
    return (!is_directional(light) || dot(p, p) <= light.max_view_distance * light.max_view_distance)
        && light_reaches(light, p);
}

// Shaping and clamping; never NaN.
fn finish_visibility(v: f32, shaping: f32) -> f32 {
    let x = min(pow(clamp(v, 0.0, 1.0), shaping), 1.0);
    return select(1.0, x, x >= 0.0);
}

// Whether an object takes part in shadows at all: live, casting, and visible (Bevy hides
// a hidden mesh's shadow) or a hidden-shadow proxy. CPU model: `flags::casts_shadows`.
fn casts_shadows(o: DistanceFieldObject) -> bool {
    return (o.flags & FLAG_LIVE) != 0u && (o.flags & FLAG_CASTS_SHADOWS) != 0u
        && (o.flags & (FLAG_VISIBLE | FLAG_CAST_HIDDEN_SHADOW)) != 0u;
}
