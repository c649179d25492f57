// Screen-space subsurface scattering: Burley's normalized diffusion profile, its radial
// CDF and inverse, and the disc's sample offsets (`penumbra_cinematic_core::sss`,
// `penumbra_reference::sss::disc_samples`).
#define_import_path penumbra::sss::profile

const PI: f32 = 3.14159265358979;
// Successive samples' angles (`penumbra_reference::sss::GOLDEN_ANGLE`).
const GOLDEN_ANGLE: f32 = 2.3999633;

// R(r) = (e^(−r/d) + e^(−r/(3d))) / (8π d r): integrates to 1 over the plane; 0 for d ≤ 0.
fn burley_profile(r: f32, d: f32) -> f32 {
    if !(d > 0.0) {
        return 0.0;
    }
    let x = max(r, 0.0);
    return (exp(-x / d) + exp(-x / (3.0 * d))) / (8.0 * PI * d * x);
}

// 1 − e^(−x) for x ≥ 0, accurate for small x (WGSL has no expm1).
fn one_minus_exp_neg(x: f32) -> f32 {
    if x < 1e-3 {
        return x * (1.0 - x * (0.5 - x / 6.0));
    }
    return 1.0 - exp(-x);
}

// The fraction of the profile's energy within r: ¼(1 − e^(−x)) + ¾(1 − e^(−x/3)).
fn burley_cdf(r: f32, d: f32) -> f32 {
    if !(d > 0.0) {
        return 1.0;
    }
    let x = max(r, 0.0) / d;
    return 0.25 * one_minus_exp_neg(x) + 0.75 * one_minus_exp_neg(x / 3.0);
}

// The radius holding a fraction u of the energy: Newton's method on the CDF (at most 8
// steps), as `sss::sample_radius`.
fn burley_sample_radius(u: f32, d: f32) -> f32 {
    if !(d > 0.0) {
        return 0.0;
    }
    let q = 1.0 - clamp(u, 0.0, 1.0 - 1e-7);
    var x = select(2.0 * (1.0 - q), -3.0 * log(q / 0.75), q < 0.75);
    for (var k = 0u; k < 8u; k += 1u) {
        let a = exp(-x);
        let b = exp(-x / 3.0);
        let step = (0.25 * a + 0.75 * b - q) / (-0.25 * a - 0.25 * b);
        x = max(x - step, 0.0);
        if abs(step) <= 1e-6 * max(x, 1e-6) {
            break;
        }
    }
    return x * d;
}

// Sample i of n on the tangent plane (metres): radius from the widest channel's CDF at
// (i + jitter) / n, angle i · golden angle + rotation.
fn disc_offset(i: u32, n: u32, rotation: f32, jitter: f32, d: f32) -> vec2<f32> {
    let r = burley_sample_radius((f32(i) + jitter) / f32(n), d);
    let a = f32(i) * GOLDEN_ANGLE + rotation;
    return vec2<f32>(cos(a), sin(a)) * r;
}

// One step of the pixel hash (`penumbra_reference::sss::pixel_noise`).
fn mix_hash(h: u32) -> u32 {
    var x = h;
    x ^= x >> 16u;
    x *= 0x7feb352du;
    x ^= x >> 15u;
    x *= 0x846ca68bu;
    x ^= x >> 16u;
    return x;
}

// A per-pixel, per-frame pair in [0, 1) (the disc's rotation and jitter).
fn pixel_noise(pixel: vec2<u32>, frame: u32) -> vec2<f32> {
    let h0 = (pixel.x * 0x8da6b343u) ^ (pixel.y * 0xd8163841u) ^ (frame * 0xcb1ab31fu);
    let h1 = mix_hash(h0);
    let h2 = mix_hash(h1);
    return vec2<f32>(f32(h1 >> 8u), f32(h2 >> 8u)) / 16777216.0;
}

// Two unit tangents completing the unit normal n (Duff et al. 2017).
fn tangent_frame(n: vec3<f32>) -> mat2x3<f32> {
    // copysign(1, n.z), −0 included.
    let s = select(1.0, -1.0, (bitcast<u32>(n.z) & 0x80000000u) != 0u);
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    return mat2x3<f32>(
        vec3<f32>(1.0 + s * n.x * n.x * a, s * b, -s * n.x),
        vec3<f32>(b, s + n.y * n.y * a, -n.y),
    );
}

// A sample's weight per channel: the profile of each channel's `d` at the distance `r`
// between the two surface points, over the density the sample was drawn with (the
// widest channel's profile at its disc radius `disc`).
fn sample_weight(r: f32, disc: f32, d: vec3<f32>, d_max: f32) -> vec3<f32> {
    let sampled = burley_profile(disc, d_max);
    if !(sampled > 0.0) {
        return vec3<f32>(0.0);
    }
    return vec3<f32>(burley_profile(r, d.x), burley_profile(r, d.y), burley_profile(r, d.z)) / sampled;
}
