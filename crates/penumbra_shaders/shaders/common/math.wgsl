// Shared math for Penumbra's shaders. Conventions as in ARCHITECTURE.md: right-handed,
// +Y up, world units in metres, unit vectors unless stated.
#define_import_path penumbra::math

const PI: f32 = 3.141592653589793;
const TAU: f32 = 6.283185307179586;
const HALF_PI: f32 = 1.5707963267948966;
// Largest finite f32: the "no hit" distance.
const F32_MAX: f32 = 3.40282347e+38;

// Normalizes `v`, or returns `fallback` when `v` is (nearly) zero or not finite.
fn safe_normalize(v: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let len2 = dot(v, v);
    // `len2 == len2` is false for NaN; the upper bound rejects Inf.
    if len2 > 1e-30 && len2 < 1e30 && len2 == len2 {
        return v * inverseSqrt(len2);
    }
    return fallback;
}

// Exact signed distance from `p` to an axis-aligned box centred at the origin with
// half extents `half_size` (negative inside).
fn sd_box(p: vec3<f32>, half_size: vec3<f32>) -> f32 {
    let q = abs(p) - half_size;
    return length(max(q, vec3(0.0))) + min(max(q.x, max(q.y, q.z)), 0.0);
}

// Unsigned distance from `p` to an axis-aligned box [box_min, box_max] (0 inside).
fn distance_to_aabb(p: vec3<f32>, box_min: vec3<f32>, box_max: vec3<f32>) -> f32 {
    let d = max(max(box_min - p, p - box_max), vec3(0.0));
    return length(d);
}

// Rec. 709 luminance of linear RGB.
fn luminance(c: vec3<f32>) -> f32 {
    return dot(c, vec3(0.2126, 0.7152, 0.0722));
}

// Octahedral encoding of a unit vector into [-1, 1]² (Cigolle et al. 2014).
fn octahedral_encode(n: vec3<f32>) -> vec2<f32> {
    let p = n.xy / (abs(n.x) + abs(n.y) + abs(n.z));
    if n.z >= 0.0 {
        return p;
    }
    let s = select(vec2(-1.0), vec2(1.0), p >= vec2(0.0));
    return (1.0 - abs(p.yx)) * s;
}

// Inverse of `octahedral_encode`.
fn octahedral_decode(e: vec2<f32>) -> vec3<f32> {
    var n = vec3(e, 1.0 - abs(e.x) - abs(e.y));
    let t = max(-n.z, 0.0);
    let s = select(vec2(t), vec2(-t), n.xy >= vec2(0.0));
    n = vec3(n.xy + s, n.z);
    return normalize(n);
}
