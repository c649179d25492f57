// Reading the global distance field: camera-relative positions sampled trilinearly in
// the finest valid clipmap level (8-bit texels, four to a word, brick after brick; one
// validity bit per storage brick), and DFAO's far-field cone march through it.
// CPU models: `penumbra_reference::global_sdf::GlobalField::sample_view` and
// `penumbra_reference::dfao::far` (`march_field`); layouts:
// `penumbra_df_core::clipmap::{GlobalFieldView, texel_byte}`.
#define_import_path penumbra::df::global_field

const BRICK: u32 = 8u;
const MAX_LEVELS: u32 = 8u;
// `penumbra_df_core::ao::MIN_STEP_FRACTION`.
const FIELD_MIN_STEP_FRACTION: f32 = 0.5;

struct GlobalFieldLevel {
    // The camera relative to the window's min corner, metres.
    camera: vec3<f32>,
    texel: f32,
    // The window's origin modulo the resolution.
    origin_mod: vec3<i32>,
    band: f32,
    dilation: f32,
    quantum: f32,
    ready: u32,
    _pad: u32,
}

struct GlobalFieldView {
    levels: array<GlobalFieldLevel, MAX_LEVELS>,
    level_count: u32,
    resolution: u32,
    bricks_per_side: u32,
    valid_words: u32,
}

// Group 1 of any pass that reads the field (WGSL cannot pass storage pointers).
@group(1) @binding(0) var<storage, read> global_field: array<u32>;
@group(1) @binding(1) var<storage, read> global_valid: array<u32>;
@group(1) @binding(2) var<uniform> global_view: GlobalFieldView;

// The stored distance of storage texel `s` of `level`, metres.
fn field_texel(level: u32, s: vec3<i32>) -> f32 {
    let view = global_view;
    let n = i32(view.bricks_per_side);
    let b = s / i32(BRICK);
    let inner = s - b * i32(BRICK);
    let brick = u32(b.x + n * (b.y + n * b.z));
    let word = (level * u32(n * n * n) + brick) * (BRICK * BRICK * BRICK / 4u)
        + u32(inner.x / 4 + 2 * (inner.y + i32(BRICK) * inner.z));
    let q = (global_field[word] >> (8u * u32(inner.x % 4))) & 255u;
    let band = view.levels[level].band;
    return (f32(q) / 255.0 - 0.5) * 2.0 * band;
}

// Whether storage brick of texel `s` of `level` is valid.
fn field_valid(level: u32, s: vec3<i32>) -> bool {
    let view = global_view;
    let n = i32(view.bricks_per_side);
    let b = s / i32(BRICK);
    let bit = u32(b.x + n * (b.y + n * b.z));
    return ((global_valid[level * view.valid_words + bit / 32u] >> (bit % 32u)) & 1u) == 1u;
}

// The field at camera-relative `p` in `level`, if its eight texels are in valid bricks:
// (value, 1), else (0, 0).
fn sample_field_level(level: u32, p: vec3<f32>) -> vec2<f32> {
    let view = global_view;
    let l = view.levels[level];
    if l.ready == 0u {
        return vec2<f32>(0.0);
    }
    let u = (p + l.camera) / l.texel - 0.5;
    let w0f = floor(u);
    let n = i32(view.resolution);
    if any(w0f < vec3<f32>(0.0)) || any(w0f >= vec3<f32>(f32(n - 1))) {
        return vec2<f32>(0.0);
    }
    let f = u - w0f;
    let w0 = vec3<i32>(w0f);
    var sum = 0.0;
    for (var k = 0; k < 8; k++) {
        let o = vec3<i32>(k & 1, (k >> 1u) & 1, k >> 2u);
        let s = (l.origin_mod + w0 + o) % n;
        if !field_valid(level, s) {
            return vec2<f32>(0.0);
        }
        let w = select(1.0 - f, f, o == vec3<i32>(1));
        sum += w.x * w.y * w.z * field_texel(level, s);
    }
    return vec2<f32>(sum, 1.0);
}

// From level `first` on, the first level that can be sampled at `p`: (value, level, 1),
// else (0, 0, 0).
fn sample_field(p: vec3<f32>, first: u32) -> vec3<f32> {
    let view = global_view;
    for (var level = first; level < view.level_count; level++) {
        let s = sample_field_level(level, p);
        if s.y > 0.0 {
            return vec3<f32>(s.x, f32(level), 1.0);
        }
    }
    return vec3<f32>(0.0);
}

// The surface distance at camera-relative `p` (the stored value plus its level's
// dilation) in `w` and the field's unit gradient in `xyz`; `ok` false where the field
// cannot be read or has no gradient (`penumbra_reference::particles::field_normal`).
struct FieldNormal {
    normal: vec3<f32>,
    distance: f32,
    ok: bool,
}

fn field_normal(p: vec3<f32>) -> FieldNormal {
    let s = sample_field(p, 0u);
    if s.z == 0.0 {
        return FieldNormal(vec3<f32>(0.0), 0.0, false);
    }
    let level = u32(s.y);
    let l = global_view.levels[level];
    let h = 0.5 * l.texel;
    var at: array<f32, 6>;
    for (var i = 0u; i < 6u; i++) {
        var o = vec3<f32>(0.0);
        o[i / 2u] = select(h, -h, (i % 2u) == 1u);
        let q = sample_field(p + o, level);
        at[i] = select(s.x, q.x, q.z > 0.0);
    }
    let g = vec3<f32>(at[0] - at[1], at[2] - at[3], at[4] - at[5]);
    let len = length(g);
    if !(len > 0.0) {
        return FieldNormal(vec3<f32>(0.0), 0.0, false);
    }
    return FieldNormal(g / len, s.x + l.dilation, true);
}

// The finest level whose band reaches `radius` plus a texel diagonal (the coarsest
// when none does).
fn level_for_radius(radius: f32) -> u32 {
    let view = global_view;
    for (var level = 0u; level < view.level_count; level++) {
        let l = view.levels[level];
        if l.band >= radius + sqrt(3.0) * l.texel {
            return level;
        }
    }
    return view.level_count - 1u;
}

struct FarCone {
    // Cone origin (camera-relative), `bias` above the receiver's plane.
    o: vec3<f32>,
    // Unit axis, rising `rise` per metre above the plane.
    axis: vec3<f32>,
    rise: f32,
    tan_half: f32,
    bias: f32,
    max_distance: f32,
    steps: u32,
    shaping: f32,
    switch_distance: f32,
    min_level: u32,
}

// One cone's visibility through the field from the switch distance to the max
// distance (`dfao::far::march_field`): grown surfaces shut the cone unless the
// receiver's own plane explains the low value; the penumbra takes the distance plus the
// dilation; no step is longer than the distance plus twice the dilation.
fn march_field(c: FarCone) -> f32 {
    let view = global_view;
    var t = max(c.switch_distance, c.bias);
    var v = 1.0;
    for (var i = 0u; i < c.steps; i++) {
        if t >= c.max_distance {
            break;
        }
        let cone = max(t * c.tan_half, 1e-6);
        let open = max(min(cone, c.bias + t * c.rise), 1e-6);
        let first = max(level_for_radius(open), c.min_level);
        let s = sample_field(c.o + c.axis * t, first);
        if s.z == 0.0 {
            t += cone * FIELD_MIN_STEP_FRACTION;
            continue;
        }
        let d = s.x;
        let l = view.levels[u32(s.y)];
        let own_plane = c.bias + t * c.rise - l.dilation;
        if d <= 0.0 && d < own_plane - 0.25 * l.texel {
            v = 0.0;
            break;
        }
        if d < l.band - 2.0 * l.quantum {
            v = min(v, max((d + l.dilation) / open, 0.0));
        }
        t += max(min(max(d, cone * FIELD_MIN_STEP_FRACTION), max(d, 0.0) + 2.0 * l.dilation), 1e-3);
    }
    v = clamp(v, 0.0, 1.0);
    return select(0.0, pow(v, c.shaping), v > 0.0);
}
