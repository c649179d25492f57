// Compute tessellation's shared types and patch math: PN / PN-AEN control points, the
// edge factor, levels. CPU twin: `penumbra_cinematic_core::tessellation::{patch,
// factors}` (the same expressions in the same order).
#define_import_path penumbra::tessellation::patch

const MAX_DISPLACEMENT_LEVELS: u32 = 16u;
// A patch that got no room in the pool (never, when the CPU's budget holds).
const NO_OUTPUT: u32 = 0xffffffffu;

// One input vertex (`TessVertex`).
struct TessVertex {
    position: vec3<f32>,
    normal: vec3<f32>,
    uv: vec2<f32>,
    tangent: vec4<f32>,
    // The position's angle-weighted normal: the displacement direction.
    smooth_normal: vec3<f32>,
    // Largest |Δu|, |Δv| per local unit along the position's edges.
    uv_density: vec2<f32>,
}

struct TessellationView {
    position: vec3<f32>,
    pixels_per_unit: f32,
    orthographic: u32,
}

// `TessellationUniform`.
struct TessellationUniform {
    world_from_local: mat4x4<f32>,
    view: TessellationView,
    pixels_per_triangle: f32,
    max_level: u32,
    // 0 flat, 1 PN-AEN.
    mode: u32,
    // 0 integer, 1 fractional.
    partitioning: u32,
    crack_fixes: u32,
    displacement_scale: f32,
    displacement_midlevel: f32,
    local_per_world: f32,
    map_size: vec2<f32>,
    map_levels: u32,
    patch_count: u32,
    vertex_budget: u32,
    index_budget: u32,
    vertex_words: u32,
    has_tangents: u32,
    // Per level: width, height, first texel.
    map_level_info: array<vec4<u32>, MAX_DISPLACEMENT_LEVELS>,
}

// Per patch: the edges' unbiased factors and the inside segments they ask for (pass 1);
// where its output goes and its inside segments after the bias, or NO_OUTPUT (pass 2).
struct PatchState {
    factors: vec3<f32>,
    inside: u32,
    base_vertex: u32,
    base_index: u32,
    out_inside: u32,
    reserved: u32,
}

// What the allocation wrote: the bias it chose, the output's vertices and indices, the
// patches, and the vertices and indices the view asked for (bias 0).
struct Totals {
    bias: u32,
    vertices: u32,
    indices: u32,
    patches: u32,
    demand_vertices: u32,
    demand_indices: u32,
    reserved: vec2<u32>,
}

fn is_finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

// The projected diameter, in pixels, of the sphere of `diameter` at `centre`.
fn projected_diameter(view: TessellationView, centre: vec3<f32>, diameter: f32) -> f32 {
    if view.orthographic == 1u {
        return diameter * view.pixels_per_unit;
    }
    return diameter * view.pixels_per_unit / max(length(centre - view.position), 1e-4);
}

// An edge's factor from its world endpoints (canonical order).
fn edge_factor(view: TessellationView, a: vec3<f32>, b: vec3<f32>, pixels_per_triangle: f32, max_level: u32) -> f32 {
    let centre = (a + b) * 0.5;
    let px = projected_diameter(view, centre, length(b - a));
    let f = px / pixels_per_triangle;
    if !is_finite(f) {
        return 1.0;
    }
    return clamp(f, 1.0, f32(1u << max_level));
}

// `factor` halved `bias` times, at least 1; 1 at the last bias, UNTESSELLATED_BIAS (every
// patch its input triangle: any pool holds it) (`tessellation::factors::biased`).
const UNTESSELLATED_BIAS: u32 = 4u;

fn biased(factor: f32, bias: u32) -> f32 {
    if bias >= UNTESSELLATED_BIAS {
        return 1.0;
    }
    return max(factor / f32(1u << bias), 1.0);
}

// PN control point of edge a → b next to a, with a's normal n.
fn pn_edge_point(a: vec3<f32>, b: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    return (a * 2.0 + b - n * dot(b - a, n)) / 3.0;
}

fn normalize_or_zero(v: vec3<f32>) -> vec3<f32> {
    let l2 = dot(v, v);
    if l2 > 0.0 && is_finite(l2) {
        return v / sqrt(l2);
    }
    return vec3(0.0);
}

fn pn_edge_normal(a: vec3<f32>, b: vec3<f32>, na: vec3<f32>, nb: vec3<f32>) -> vec3<f32> {
    let d = b - a;
    let v = 2.0 * dot(d, na + nb) / max(dot(d, d), 1e-30);
    return normalize_or_zero(na + nb - d * v);
}

fn bezier(p0: vec3<f32>, c0: vec3<f32>, c1: vec3<f32>, p1: vec3<f32>, t: f32) -> vec3<f32> {
    let s = 1.0 - t;
    return p0 * (s * s * s) + c0 * (3.0 * s * s * t) + c1 * (3.0 * s * t * t) + p1 * (t * t * t);
}

// PN's quadratic normal at barycentric b.
fn pn_normal(p0: vec3<f32>, p1: vec3<f32>, p2: vec3<f32>, n0: vec3<f32>, n1: vec3<f32>, n2: vec3<f32>, b: vec3<f32>) -> vec3<f32> {
    let w = b.x;
    let u = b.y;
    let v = b.z;
    let n110 = pn_edge_normal(p0, p1, n0, n1);
    let n011 = pn_edge_normal(p1, p2, n1, n2);
    let n101 = pn_edge_normal(p2, p0, n2, n0);
    return normalize_or_zero(n0 * (w * w) + n1 * (u * u) + n2 * (v * v) + n110 * (w * u) + n011 * (u * v) + n101 * (w * v));
}

// The surface gradients of u and v over a flat triangle.
fn uv_gradients(p0: vec3<f32>, p1: vec3<f32>, p2: vec3<f32>, t0: vec2<f32>, t1: vec2<f32>, t2: vec2<f32>) -> mat2x3<f32> {
    let e1 = p1 - p0;
    let e2 = p2 - p0;
    let d1 = t1 - t0;
    let d2 = t2 - t0;
    let a = dot(e1, e1);
    let b = dot(e1, e2);
    let c = dot(e2, e2);
    let det = a * c - b * b;
    if det <= 1e-20 * a * c || det == 0.0 {
        return mat2x3<f32>(vec3(0.0), vec3(0.0));
    }
    let gu = e1 * ((c * d1.x - b * d2.x) / det) + e2 * ((a * d2.x - b * d1.x) / det);
    let gv = e1 * ((c * d1.y - b * d2.y) / det) + e2 * ((a * d2.y - b * d1.y) / det);
    return mat2x3<f32>(gu, gv);
}
