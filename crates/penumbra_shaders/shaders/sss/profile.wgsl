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
