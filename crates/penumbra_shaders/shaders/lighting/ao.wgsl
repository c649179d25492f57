// What Penumbra's lighting pass does with distance-field AO: contrast and min occlusion
// (Unreal's), specular occlusion. CPU model: `penumbra_reference::dfao::{finish_ao,
// specular_occlusion}`.
#define_import_path penumbra::lighting::ao

#import penumbra::lighting::masks::{ambient_occlusion, ao_texel, penumbra_lighting}

const AO_PI: f32 = 3.14159265;

struct PenumbraAo {
    // Finished AO (1 open).
    ao: f32,
    // Unit world-space bent normal.
    bent_normal: vec3<f32>,
}

// The pixel's AO with contrast and min occlusion, and its bent normal; open (and `n`)
// without DFAO.
fn penumbra_ao(frag_xy: vec2<f32>, n: vec3<f32>) -> PenumbraAo {
    if penumbra_lighting.ao_enabled == 0u {
        return PenumbraAo(1.0, n);
    }
    let s = ao_texel(frag_xy);
    var ao = select(1.0, clamp(s.x, 0.0, 1.0), s.x == s.x);
    let contrast = penumbra_lighting.ao_contrast;
    if contrast > 1e-3 {
        let k = 10.0 * contrast;
        let s0 = 1.0 / (1.0 + exp(k * 0.5));
        let s1 = 1.0 / (1.0 + exp(-k * 0.5));
        let sx = 1.0 / (1.0 + exp(-k * (ao - 0.5)));
        ao = clamp((sx - s0) / (s1 - s0), 0.0, 1.0);
    }
    let m = clamp(penumbra_lighting.ao_min_occlusion, 0.0, 1.0);
    ao = m + (1.0 - m) * ao;
    let len = length(s.yzw);
    return PenumbraAo(ao, select(n, s.yzw / len, len > 1e-6));
}

// The objects-per-tile debug view's colour at `frag_xy`: the count the trace stored
// (over `TILE_OBJECTS_SCALE` = 1024) on a heat ramp, t = log2(1 + count) / 8: black,
// blue, cyan, green, yellow, red (count ≥ 255).
fn penumbra_ao_tile_heat(frag_xy: vec2<f32>) -> vec3<f32> {
    let count = textureLoad(ambient_occlusion, vec2<i32>(frag_xy), 0).x * 1024.0;
    let t = clamp(log2(1.0 + max(count, 0.0)) / 8.0, 0.0, 1.0) * 5.0;
    let stops = array<vec3<f32>, 6>(
        vec3(0.0), vec3(0.0, 0.0, 1.0), vec3(0.0, 1.0, 1.0), vec3(0.0, 1.0, 0.0),
        vec3(1.0, 1.0, 0.0), vec3(1.0, 0.0, 0.0),
    );
    let i = min(u32(t), 4u);
    return mix(stops[i], stops[i + 1u], t - f32(i));
}

// The approximate overlap of cones of apertures `a` and `b` whose axes are `between`
// apart (Oat and Sander 2007).
fn cone_cone_intersection(a: f32, b: f32, between: f32) -> f32 {
    let difference = abs(a - b);
    let x = 1.0 - clamp((between - difference) / max(a + b - difference, 1e-6), 0.0, 1.0);
    return x * x * (3.0 - 2.0 * x);
}

// Specular occlusion of a surface (unit `n`, view vector `v`, linear `roughness`) by
// the AO, in the camera's mode; 1 without DFAO.
fn penumbra_ao_specular(ao: PenumbraAo, n: vec3<f32>, v: vec3<f32>, roughness: f32) -> f32 {
    let mode = penumbra_lighting.ao_specular_occlusion;
    if penumbra_lighting.ao_enabled == 0u || mode == 0u {
        return 1.0;
    }
    if mode == 1u {
        let n_dot_v = max(dot(n, v), 1e-4);
        return clamp(pow(n_dot_v + ao.ao, exp2(-16.0 * roughness - 1.0)) - 1.0 + ao.ao, 0.0, 1.0);
    }
    let r = normalize(2.0 * dot(n, v) * n - v);
    let reflection = max(roughness, 0.1) * AO_PI;
    let unoccluded = ao.ao * AO_PI;
    let between = acos(clamp(dot(ao.bent_normal, r), -1.0, 1.0));
    return cone_cone_intersection(reflection, unoccluded, between)
        * clamp((unoccluded - 0.1) / 0.2, 0.0, 1.0);
}
