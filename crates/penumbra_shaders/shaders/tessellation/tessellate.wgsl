// Compute tessellation, three passes per tessellated entity (one bind group):
//   `factors`  one thread per patch: its edges' factors (canonical endpoints) and level;
//   `allocate` three dispatches of a scan over many workgroups: the least bias (halving
//              all factors) whose output fits the pool, then each patch's first vertex
//              and index (a prefix sum: the output's order is the patches' order,
//              whatever the thread count);
//   `emit`     one workgroup per patch: its layout's vertices (flat or PN-AEN, displaced)
//              and triangles, into the pool the mesh's buffers are copied from.
// CPU model: `penumbra_cinematic_core::tessellation::reference` (`tessellate`).
#define_import_path penumbra::tessellation::tessellate

#import penumbra::tessellation::patch::{
    NO_OUTPUT, PatchState, TessVertex, TessellationUniform, Totals, bezier, biased,
    edge_factor, normalize_or_zero, pn_edge_point, pn_normal, uv_gradients,
}
#import penumbra::tessellation::layout::{
    Counts, counts_of, inner_triangle, outer_vertex, ring_point, ring_vertex,
    ring_base, pattern_position, segments, triangle_count, vertex_count,
}

@group(0) @binding(0) var<uniform> u: TessellationUniform;
@group(0) @binding(1) var<storage, read> vertices: array<TessVertex>;
// 12 per patch: the triangle, each edge's opposite pair, the dominant vertices.
@group(0) @binding(2) var<storage, read> patches: array<u32>;
// The height map's mip chain (`DisplacementMap::texels`).
@group(0) @binding(3) var<storage, read> texels: array<f32>;
@group(0) @binding(4) var<storage, read_write> states: array<PatchState>;
@group(0) @binding(5) var<storage, read_write> totals: Totals;
// The mesh's interleaved vertices: position, normal, uv[, tangent].
@group(0) @binding(6) var<storage, read_write> out_vertices: array<f32>;
@group(0) @binding(7) var<storage, read_write> out_indices: array<u32>;
// Per group of patches and bias: the vertices and indices it asks for (`allocate_reduce`);
// then each group's first vertex and index at the chosen bias (`allocate_choose`).
@group(0) @binding(8) var<storage, read_write> group_sums: array<vec2<u32>>;

const MAX_BIAS: u32 = 5u;

fn patch_index(p: u32, k: u32) -> u32 {
    return patches[p * 12u + k];
}

fn fractional() -> bool {
    return u.partitioning == 1u;
}

// ---- pass 1: factors -------------------------------------------------------------

// Edge e's endpoints in its canonical order (by dominant vertex; own order without
// the crack fixes), local units.
fn canonical_endpoints(p: u32, e: u32) -> array<vec3<f32>, 2> {
    let f = (e + 1u) % 3u;
    if u.crack_fixes == 0u {
        return array(vertices[patch_index(p, e)].position, vertices[patch_index(p, f)].position);
    }
    let da = patch_index(p, 9u + e);
    let db = patch_index(p, 9u + f);
    if db < da {
        return array(vertices[db].position, vertices[da].position);
    }
    return array(vertices[da].position, vertices[db].position);
}

// Dispatched in rows of at most 65,535 groups (`penumbra_cinematic_core::dispatch`).
@compute @workgroup_size(64)
fn factors(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
) {
    let p = (group.y * groups.x + group.x) * 64u + local;
    if p >= u.patch_count {
        return;
    }
    var f = vec3(1.0);
    for (var e = 0u; e < 3u; e += 1u) {
        let ends = canonical_endpoints(p, e);
        let a = (u.world_from_local * vec4(ends[0], 1.0)).xyz;
        let b = (u.world_from_local * vec4(ends[1], 1.0)).xyz;
        f[e] = edge_factor(u.view, a, b, u.pixels_per_triangle, u.max_level);
    }
    states[p].factors = f;
    states[p].inside = segments(max(max(f.x, f.y), f.z));
}

// ---- pass 2: allocate -------------------------------------------------------------
// A prefix sum over many workgroups (`penumbra_cinematic_core::scan`), in three
// dispatches: `allocate_reduce` sums each group of 1,024 patches' demand at every bias;
// `allocate_choose` (one workgroup) picks the least bias whose total fits the pool and
// turns the groups' sums at that bias into their first vertex and index; `allocate_place`
// places each patch from its group's offset. Patches are placed in order; one whose
// output would pass the pool (only when even the largest bias does not fit) is dropped
// with all after it.

const SCAN_THREADS: u32 = 256u;
const ITEMS_PER_THREAD: u32 = 4u;
const GROUP_ITEMS: u32 = SCAN_THREADS * ITEMS_PER_THREAD;

var<workgroup> partial: array<vec2<u32>, SCAN_THREADS>;

fn saturating_add(a: u32, b: u32) -> u32 {
    let s = a + b;
    return select(s, 0xffffffffu, s < a);
}

fn saturating_add2(a: vec2<u32>, b: vec2<u32>) -> vec2<u32> {
    return vec2(saturating_add(a.x, b.x), saturating_add(a.y, b.y));
}

// The workgroup's exclusive scan of the threads' `value`s (Hillis and Steele, saturating,
// in `partial`): this thread's offset; `partial[SCAN_THREADS - 1]` then holds the total.
// Called by every thread of the workgroup; it waits for earlier readers of `partial`.
fn workgroup_exclusive_scan(i: u32, value: vec2<u32>) -> vec2<u32> {
    workgroupBarrier();
    partial[i] = value;
    workgroupBarrier();
    for (var d = 1u; d < SCAN_THREADS; d *= 2u) {
        var add = vec2(0u);
        if i >= d {
            add = partial[i - d];
        }
        workgroupBarrier();
        partial[i] = saturating_add2(partial[i], add);
        workgroupBarrier();
    }
    if i == 0u {
        return vec2(0u);
    }
    return partial[i - 1u];
}

fn group_count() -> u32 {
    return (u.patch_count + GROUP_ITEMS - 1u) / GROUP_ITEMS;
}

// Thread `i` of group `g`'s patches (reduce and place).
fn thread_patches(g: u32, i: u32) -> vec2<u32> {
    let first = min(g * GROUP_ITEMS + i * ITEMS_PER_THREAD, u.patch_count);
    return vec2(first, min(first + ITEMS_PER_THREAD, u.patch_count));
}

fn biased_factors(f: vec3<f32>, bias: u32) -> vec3<f32> {
    return vec3(biased(f.x, bias), biased(f.y, bias), biased(f.z, bias));
}

fn biased_counts(f: vec3<f32>, bias: u32) -> Counts {
    return counts_of(biased_factors(f, bias));
}

// Patch `p`'s output at `bias`: vertices, indices.
fn patch_demand(p: u32, bias: u32) -> vec2<u32> {
    let c = biased_counts(states[p].factors, bias);
    return vec2(vertex_count(c), 3u * triangle_count(c));
}

fn run_demand(run: vec2<u32>, bias: u32) -> vec2<u32> {
    var d = vec2(0u);
    for (var p = run.x; p < run.y; p += 1u) {
        d = saturating_add2(d, patch_demand(p, bias));
    }
    return d;
}

fn fits(d: vec2<u32>) -> bool {
    return d.x <= u.vertex_budget && d.y <= u.index_budget;
}

// Pass 2a, one workgroup per 1,024 patches: the group's demand at each bias.
@compute @workgroup_size(SCAN_THREADS)
fn allocate_reduce(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(local_invocation_index) i: u32,
) {
    let run = thread_patches(group.x, i);
    for (var bias = 0u; bias < MAX_BIAS; bias += 1u) {
        workgroup_exclusive_scan(i, run_demand(run, bias));
        if i == SCAN_THREADS - 1u {
            group_sums[group.x * MAX_BIAS + bias] = partial[i];
        }
    }
}

// Thread `i`'s groups in `allocate_choose`.
fn thread_groups(i: u32) -> vec2<u32> {
    let groups = group_count();
    let run = (groups + SCAN_THREADS - 1u) / SCAN_THREADS;
    let first = min(i * run, groups);
    return vec2(first, min(first + run, groups));
}

fn groups_demand(run: vec2<u32>, bias: u32) -> vec2<u32> {
    var d = vec2(0u);
    for (var g = run.x; g < run.y; g += 1u) {
        d = saturating_add2(d, group_sums[g * MAX_BIAS + bias]);
    }
    return d;
}

// Pass 2b, one workgroup: the bias, each group's first vertex and index, the totals.
@compute @workgroup_size(SCAN_THREADS)
fn allocate_choose(@builtin(local_invocation_index) i: u32) {
    let run = thread_groups(i);
    // Every thread sees the same totals, so picks the same bias.
    var bias = MAX_BIAS - 1u;
    var demand = vec2(0u);
    for (var b = 0u; b < MAX_BIAS; b += 1u) {
        workgroup_exclusive_scan(i, groups_demand(run, b));
        let total = partial[SCAN_THREADS - 1u];
        if b == 0u {
            demand = total;
        }
        if fits(total) && bias == MAX_BIAS - 1u {
            bias = min(bias, b);
        }
    }
    var offset = workgroup_exclusive_scan(i, groups_demand(run, bias));
    for (var g = run.x; g < run.y; g += 1u) {
        let d = group_sums[g * MAX_BIAS + bias];
        group_sums[g * MAX_BIAS] = offset;
        offset = saturating_add2(offset, d);
    }
    if i == SCAN_THREADS - 1u {
        let total = partial[i];
        totals.bias = bias;
        totals.vertices = min(total.x, u.vertex_budget);
        totals.indices = min(total.y, u.index_budget);
        totals.patches = u.patch_count;
        totals.demand_vertices = demand.x;
        totals.demand_indices = demand.y;
    }
}

// Pass 2c, the reduce's workgroups: each patch's first vertex and index, or NO_OUTPUT.
@compute @workgroup_size(SCAN_THREADS)
fn allocate_place(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(local_invocation_index) i: u32,
) {
    let bias = totals.bias;
    let run = thread_patches(group.x, i);
    var base = saturating_add2(
        group_sums[group.x * MAX_BIAS],
        workgroup_exclusive_scan(i, run_demand(run, bias)),
    );
    for (var p = run.x; p < run.y; p += 1u) {
        let c = biased_counts(states[p].factors, bias);
        let n = vec2(vertex_count(c), 3u * triangle_count(c));
        states[p].base_vertex = base.x;
        states[p].base_index = base.y;
        states[p].out_inside = select(NO_OUTPUT, c.inside, fits(saturating_add2(base, n)));
        base = saturating_add2(base, n);
    }
}

// ---- pass 3: emit ----------------------------------------------------------------

// The displacement map (repeating addressing, trilinear between levels).
fn texel(level: u32, x: u32, y: u32) -> f32 {
    let info = u.map_level_info[level];
    return texels[info.z + y * info.x + x];
}

fn wrap(i: f32, n: u32) -> u32 {
    let k = i32(i) % i32(n);
    return u32(select(k, k + i32(n), k < 0));
}

fn bilinear(level: u32, uv: vec2<f32>) -> f32 {
    let info = u.map_level_info[level];
    let x = uv.x * f32(info.x) - 0.5;
    let y = uv.y * f32(info.y) - 0.5;
    let fx = x - floor(x);
    let fy = y - floor(y);
    let x0 = wrap(floor(x), info.x);
    let y0 = wrap(floor(y), info.y);
    let x1 = (x0 + 1u) % info.x;
    let y1 = (y0 + 1u) % info.y;
    let top = texel(level, x0, y0) * (1.0 - fx) + texel(level, x1, y0) * fx;
    let bottom = texel(level, x0, y1) * (1.0 - fx) + texel(level, x1, y1) * fx;
    return top * (1.0 - fy) + bottom * fy;
}

fn sample_height(uv: vec2<f32>, lod_in: f32) -> f32 {
    let last = f32(u.map_levels - 1u);
    let lod = clamp(lod_in, 0.0, last);
    let l0 = floor(lod);
    let l1 = min(l0 + 1.0, last);
    let t = lod - l0;
    let a = bilinear(u32(l0), uv);
    let b = bilinear(u32(l1), uv);
    return a * (1.0 - t) + b * t;
}

fn slope(uv: vec2<f32>, lod: f32) -> vec2<f32> {
    let step = vec2(exp2(clamp(lod, 0.0, f32(u.map_levels - 1u)))) / u.map_size;
    let du = sample_height(uv + vec2(step.x, 0.0), lod) - sample_height(uv - vec2(step.x, 0.0), lod);
    let dv = sample_height(uv + vec2(0.0, step.y), lod) - sample_height(uv - vec2(0.0, step.y), lod);
    return vec2(du / (2.0 * step.x), dv / (2.0 * step.y));
}

fn lod_for(span: vec2<f32>, factor: f32) -> f32 {
    return log2(max(length(span * u.map_size) / factor, 1.0));
}

fn has_map() -> bool {
    return u.map_levels > 0u;
}

struct EdgeCurve {
    p0: vec3<f32>,
    p1: vec3<f32>,
    c0: vec3<f32>,
    c1: vec3<f32>,
    uv0: vec2<f32>,
    uv1: vec2<f32>,
    n0: vec3<f32>,
    n1: vec3<f32>,
    reversed: bool,
}

fn pair_less(a: vec2<u32>, b: vec2<u32>) -> bool {
    let ka = vec2(min(a.x, a.y), max(a.x, a.y));
    let kb = vec2(min(b.x, b.y), max(b.x, b.y));
    return ka.x < kb.x || (ka.x == kb.x && ka.y < kb.y);
}

// Edge e as both its triangles evaluate it (`patch::edge_curve`).
fn edge_curve(p: u32, e: u32) -> EdgeCurve {
    let f = (e + 1u) % 3u;
    let a = patch_index(p, e);
    let b = patch_index(p, f);
    if u.crack_fixes == 0u {
        let va = vertices[a];
        let vb = vertices[b];
        return EdgeCurve(va.position, vb.position, pn_edge_point(va.position, vb.position, va.normal), pn_edge_point(vb.position, va.position, vb.normal), va.uv, vb.uv, va.normal, vb.normal, false);
    }
    let oa = patch_index(p, 3u + 2u * e);
    let ob = patch_index(p, 4u + 2u * e);
    let da = patch_index(p, 9u + e);
    let db = patch_index(p, 9u + f);
    let reversed = db < da;
    var own = vec2(a, b);
    var opposite = vec2(oa, ob);
    var d = vec2(da, db);
    if reversed {
        own = own.yx;
        opposite = opposite.yx;
        d = d.yx;
    }
    var dom = own;
    var other = opposite;
    if pair_less(opposite, own) {
        dom = opposite;
        other = own;
    }
    let p0 = vertices[d.x].position;
    let p1 = vertices[d.y].position;
    let c0 = (pn_edge_point(p0, p1, vertices[dom.x].normal) + pn_edge_point(p0, p1, vertices[other.x].normal)) * 0.5;
    let c1 = (pn_edge_point(p1, p0, vertices[dom.y].normal) + pn_edge_point(p1, p0, vertices[other.y].normal)) * 0.5;
    return EdgeCurve(p0, p1, c0, c1, vertices[dom.x].uv, vertices[dom.y].uv, vertices[d.x].smooth_normal, vertices[d.y].smooth_normal, reversed);
}

fn curve_point(c: EdgeCurve, t: f32) -> vec3<f32> {
    if u.mode == 0u {
        return c.p0 * (1.0 - t) + c.p1 * t;
    }
    return bezier(c.p0, c.c0, c.c1, c.p1, t);
}

// Everything one patch's vertices need (`reference::PatchEval`).
struct Patch {
    own: array<TessVertex, 3>,
    dominant: array<TessVertex, 3>,
    curves: array<EdgeCurve, 3>,
    // Own orientation: per edge, next to corner e and to e + 1.
    control: array<vec3<f32>, 6>,
    centre: vec3<f32>,
    gradients: mat2x3<f32>,
    edge_factors: vec3<f32>,
    counts: Counts,
    factor: f32,
    corner_lods: vec3<f32>,
    patch_lod: f32,
}

var<private> pc: Patch;

struct Out {
    position: vec3<f32>,
    normal: vec3<f32>,
    bary: vec3<f32>,
}

fn prepare_patch(p: u32, state: PatchState, bias: u32) {
    for (var c = 0u; c < 3u; c += 1u) {
        pc.own[c] = vertices[patch_index(p, c)];
        if u.crack_fixes == 1u {
            pc.dominant[c] = vertices[patch_index(p, 9u + c)];
        } else {
            pc.dominant[c] = pc.own[c];
        }
    }
    for (var e = 0u; e < 3u; e += 1u) {
        let curve = edge_curve(p, e);
        pc.curves[e] = curve;
        if curve.reversed {
            pc.control[2u * e] = curve.c1;
            pc.control[2u * e + 1u] = curve.c0;
        } else {
            pc.control[2u * e] = curve.c0;
            pc.control[2u * e + 1u] = curve.c1;
        }
    }
    pc.edge_factors = biased_factors(state.factors, bias);
    pc.counts = counts_of(pc.edge_factors);
    let e = (pc.control[0] + pc.control[1] + pc.control[2] + pc.control[3] + pc.control[4] + pc.control[5]) / 6.0;
    let v = (pc.own[0].position + pc.own[1].position + pc.own[2].position) / 3.0;
    pc.centre = e + (e - v) * 0.5;
    pc.gradients = uv_gradients(pc.own[0].position, pc.own[1].position, pc.own[2].position, pc.own[0].uv, pc.own[1].uv, pc.own[2].uv);
    pc.factor = max(max(pc.edge_factors.x, pc.edge_factors.y), pc.edge_factors.z);
    pc.corner_lods = vec3(0.0);
    pc.patch_lod = 0.0;
    if has_map() {
        let segment = u.pixels_per_triangle * f32(1u << bias) / u.view.pixels_per_unit * u.local_per_world;
        for (var c = 0u; c < 3u; c += 1u) {
            let d = pc.dominant[c];
            let world = (u.world_from_local * vec4(d.position, 1.0)).xyz;
            var distance = 1.0;
            if u.view.orthographic == 0u {
                distance = length(world - u.view.position);
            }
            pc.corner_lods[c] = log2(max(length(d.uv_density * u.map_size) * segment * distance, 1.0));
        }
        // The mean of the edges' texel spans.
        var sum = 0.0;
        for (var k = 0u; k < 3u; k += 1u) {
            sum += length((pc.own[(k + 1u) % 3u].uv - pc.own[k].uv) * u.map_size);
        }
        pc.patch_lod = log2(max(sum / 3.0 / pc.factor, 1.0));
    }
}

fn displaced(position: vec3<f32>, direction: vec3<f32>, uv: vec2<f32>, lod: f32) -> vec3<f32> {
    if !has_map() {
        return position;
    }
    let h = sample_height(uv, lod);
    return position + direction * (u.displacement_scale * (h - u.displacement_midlevel));
}

fn shading_normal(b: vec3<f32>, lod: f32) -> vec3<f32> {
    let n0 = pc.own[0].normal;
    let n1 = pc.own[1].normal;
    let n2 = pc.own[2].normal;
    var base: vec3<f32>;
    if u.mode == 0u {
        base = normalize_or_zero(n0 * b.x + n1 * b.y + n2 * b.z);
    } else {
        base = pn_normal(pc.own[0].position, pc.own[1].position, pc.own[2].position, n0, n1, n2, b);
    }
    if !has_map() {
        return base;
    }
    let uv = pc.own[0].uv * b.x + pc.own[1].uv * b.y + pc.own[2].uv * b.z;
    let s = slope(uv, lod) * u.displacement_scale;
    return normalize_or_zero(base - (pc.gradients[0] * s.x + pc.gradients[1] * s.y));
}

fn axis(c: u32) -> vec3<f32> {
    var b = vec3(0.0);
    b[c] = 1.0;
    return b;
}

fn corner(c: u32) -> Out {
    let v = pc.dominant[c];
    let lod = pc.corner_lods[c];
    var direction = v.normal;
    if u.crack_fixes == 1u {
        direction = v.smooth_normal;
    }
    let bary = axis(c);
    return Out(displaced(v.position, direction, v.uv, lod), shading_normal(bary, lod), bary);
}

// Edge e's vertex x in its canonical order (0 and nₑ: its corners).
fn edge_point(e: u32, x: u32) -> Out {
    let n = pc.counts.edges[e];
    let curve = pc.curves[e];
    var first = e;
    var last = (e + 1u) % 3u;
    if curve.reversed {
        first = (e + 1u) % 3u;
        last = e;
    }
    if x == 0u {
        return corner(first);
    }
    if x == n {
        return corner(last);
    }
    let t = pattern_position(pc.edge_factors[e], n, x, fractional());
    var lod = 0.0;
    if has_map() {
        lod = lod_for(curve.uv1 - curve.uv0, pc.edge_factors[e]);
    }
    let s = 1.0 - t;
    let uv = curve.uv0 * s + curve.uv1 * t;
    let direction = normalize_or_zero(curve.n0 * s + curve.n1 * t);
    let position = displaced(curve_point(curve, t), direction, uv, lod);
    var own_t = t;
    if curve.reversed {
        own_t = 1.0 - t;
    }
    var bary = vec3(0.0);
    bary[e] = 1.0 - own_t;
    bary[(e + 1u) % 3u] = own_t;
    return Out(position, shading_normal(bary, lod), bary);
}

// Edge e's own parameter of its vertex j from corner e.
fn edge_t(e: u32, j: u32) -> f32 {
    let n = pc.counts.edges[e];
    if pc.curves[e].reversed {
        return 1.0 - pattern_position(pc.edge_factors[e], n, n - j, fractional());
    }
    return pattern_position(pc.edge_factors[e], n, j, fractional());
}

// The patch's surface at own barycentric b, displaced.
fn inside_point(b: vec3<f32>) -> Out {
    let p0 = pc.own[0].position;
    let p1 = pc.own[1].position;
    let p2 = pc.own[2].position;
    var position: vec3<f32>;
    if u.mode == 0u {
        position = p0 * b.x + p1 * b.y + p2 * b.z;
    } else {
        position = pn_point(b);
    }
    let uv = pc.own[0].uv * b.x + pc.own[1].uv * b.y + pc.own[2].uv * b.z;
    var d0 = pc.dominant[0].normal;
    var d1 = pc.dominant[1].normal;
    var d2 = pc.dominant[2].normal;
    if u.crack_fixes == 1u {
        d0 = pc.dominant[0].smooth_normal;
        d1 = pc.dominant[1].smooth_normal;
        d2 = pc.dominant[2].smooth_normal;
    }
    let direction = normalize_or_zero(d0 * b.x + d1 * b.y + d2 * b.z);
    return Out(displaced(position, direction, uv, pc.patch_lod), shading_normal(b, pc.patch_lod), b);
}

// Local vertex v of the patch (`layout::place`).
fn patch_vertex(v: u32) -> Out {
    let c = pc.counts;
    if v < c.edges.x + c.edges.y + c.edges.z {
        var e = 0u;
        var base = 0u;
        while v >= base + c.edges[e] {
            base += c.edges[e];
            e += 1u;
        }
        let j = v - base;
        if j == 0u {
            return corner(e);
        }
        var x = j;
        if pc.curves[e].reversed {
            x = c.edges[e] - j;
        }
        return edge_point(e, x);
    }
    let n = c.inside;
    var r = 1u;
    while v >= ring_base(c, r) + 3u * (n - 2u * r) {
        r += 1u;
    }
    let local = v - ring_base(c, r);
    let side = n - 2u * r;
    return inside_point(ring_point(pc.factor, n, r, local / side, r + local % side, fractional()));
}

fn pn_point(b: vec3<f32>) -> vec3<f32> {
    let w = b.x;
    let s = b.y;
    let v = b.z;
    let c = pc.control;
    return pc.own[0].position * (w * w * w)
        + pc.own[1].position * (s * s * s)
        + pc.own[2].position * (v * v * v)
        + c[0] * (3.0 * w * w * s)
        + c[1] * (3.0 * w * s * s)
        + c[5] * (3.0 * w * w * v)
        + c[2] * (3.0 * s * s * v)
        + c[4] * (3.0 * w * v * v)
        + c[3] * (3.0 * s * v * v)
        + pc.centre * (6.0 * w * s * v);
}

fn write_triangle(at: u32, tri: vec3<u32>) {
    out_indices[at] = tri.x;
    out_indices[at + 1u] = tri.y;
    out_indices[at + 2u] = tri.z;
}

// The zipper of edge e with side e of ring 1 (`layout::zipper`), written from triangle
// `first` on: nₑ + n − 2 triangles, advancing along whichever side's next vertex comes
// first.
fn write_zipper(e: u32, base_vertex: u32, first: u32) {
    let c = pc.counts;
    let n = c.inside;
    let ne = c.edges[e];
    var a = 0u;
    var b = 0u;
    var at = first;
    while a < ne || b < n - 2u {
        let outer = outer_vertex(c, e, a) + base_vertex;
        let inner = ring_vertex(c, 1u, e, 1u + b) + base_vertex;
        if b == n - 2u || (a < ne && edge_t(e, a + 1u) <= pattern_position(pc.factor, n, 2u + b, fractional())) {
            write_triangle(3u * at, vec3(outer, outer_vertex(c, e, a + 1u) + base_vertex, inner));
            a += 1u;
        } else {
            write_triangle(3u * at, vec3(outer, ring_vertex(c, 1u, e, 2u + b) + base_vertex, inner));
            b += 1u;
        }
        at += 1u;
    }
}

fn write_vertex(index: u32, o: Out) {
    let base = index * u.vertex_words;
    out_vertices[base] = o.position.x;
    out_vertices[base + 1u] = o.position.y;
    out_vertices[base + 2u] = o.position.z;
    out_vertices[base + 3u] = o.normal.x;
    out_vertices[base + 4u] = o.normal.y;
    out_vertices[base + 5u] = o.normal.z;
    let b = o.bary;
    let uv = pc.own[0].uv * b.x + pc.own[1].uv * b.y + pc.own[2].uv * b.z;
    out_vertices[base + 6u] = uv.x;
    out_vertices[base + 7u] = uv.y;
    if u.has_tangents == 1u {
        let t = normalize_or_zero(pc.own[0].tangent.xyz * b.x + pc.own[1].tangent.xyz * b.y + pc.own[2].tangent.xyz * b.z);
        out_vertices[base + 8u] = t.x;
        out_vertices[base + 9u] = t.y;
        out_vertices[base + 10u] = t.z;
        out_vertices[base + 11u] = pc.own[0].tangent.w;
    }
}

@compute @workgroup_size(64)
fn emit(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) t: u32,
) {
    let p = group.x + group.y * groups.x;
    if p >= u.patch_count {
        return;
    }
    let state = states[p];
    if state.out_inside == NO_OUTPUT {
        return;
    }
    prepare_patch(p, state, totals.bias);
    let c = pc.counts;
    for (var v = t; v < vertex_count(c); v += 64u) {
        write_vertex(state.base_vertex + v, patch_vertex(v));
    }
    // Triangles: the zippers (one thread each, serial), then the rest in parallel.
    let first = state.base_index / 3u;
    var zippers = 0u;
    if c.inside > 1u {
        zippers = c.edges.x + c.edges.y + c.edges.z + 3u * (c.inside - 2u);
        if t < 3u {
            var offset = 0u;
            for (var e = 0u; e < t; e += 1u) {
                offset += c.edges[e] + c.inside - 2u;
            }
            write_zipper(t, state.base_vertex, first + offset);
        }
    }
    for (var k = t; k < triangle_count(c) - zippers; k += 64u) {
        write_triangle(3u * (first + zippers + k), inner_triangle(c, k) + vec3(state.base_vertex));
    }
}
