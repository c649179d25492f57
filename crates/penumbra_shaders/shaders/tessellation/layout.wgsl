// A patch's layout (`penumbra_cinematic_core::tessellation::layout`): the odd fractional
// 1-D pattern of a factor, each edge's own pattern as the outer ring, inner rings from
// the inside factor, and how they are joined. The same expressions as the CPU's.
#define_import_path penumbra::tessellation::layout

const MAX_SEGMENTS: u32 = 65u;

// The smallest odd n ≥ f (1 for f ≤ 1).
fn segments(f: f32) -> u32 {
    var n = 1u;
    while f32(n) < f && n < MAX_SEGMENTS {
        n += 2u;
    }
    return n;
}

// Position k (0..=n) of the pattern of factor f with n = segments(f).
fn pattern_position(f: f32, n: u32, k: u32, fractional: bool) -> f32 {
    if k == 0u {
        return 0.0;
    }
    if k >= n {
        return 1.0;
    }
    if !fractional {
        return f32(k) / f32(n);
    }
    let full = 1.0 / f;
    let short = (1.0 - f32(n - 2u) * full) * 0.5;
    let h = (n - 3u) / 2u;
    if k <= h {
        return f32(k) * full;
    }
    if k == h + 1u {
        return f32(h) * full + short;
    }
    if k == h + 2u {
        return f32(h + 1u) * full + short;
    }
    return f32(k - 2u) * full + short * 2.0;
}

struct Counts {
    edges: vec3<u32>,
    inside: u32,
}

fn counts_of(f: vec3<f32>) -> Counts {
    return Counts(vec3(segments(f.x), segments(f.y), segments(f.z)), segments(max(max(f.x, f.y), f.z)));
}

fn rings(c: Counts) -> u32 {
    return (c.inside - 1u) / 2u;
}

fn outer_count(c: Counts) -> u32 {
    return c.edges.x + c.edges.y + c.edges.z;
}

fn vertex_count(c: Counts) -> u32 {
    let r = rings(c);
    return outer_count(c) + 3u * r * r;
}

fn triangle_count(c: Counts) -> u32 {
    if c.inside == 1u {
        return 1u;
    }
    let r = rings(c);
    return outer_count(c) + 3u * (c.inside - 2u) + 6u * r * (r - 1u) + 1u;
}

fn edge_base(c: Counts, e: u32) -> u32 {
    var base = 0u;
    for (var k = 0u; k < e; k += 1u) {
        base += c.edges[k];
    }
    return base;
}

// Vertex j of edge e from its own first corner (j = nₑ: the next edge's first).
fn outer_vertex(c: Counts, e: u32, j: u32) -> u32 {
    if j >= c.edges[e] {
        return edge_base(c, (e + 1u) % 3u);
    }
    return edge_base(c, e) + j;
}

fn ring_base(c: Counts, r: u32) -> u32 {
    return outer_count(c) + 3u * ((r - 1u) * c.inside - (r - 1u) * r);
}

// Vertex k (r ≤ k ≤ n − r) of side e of ring r.
fn ring_vertex(c: Counts, r: u32, e: u32, k: u32) -> u32 {
    var side = e;
    var at = k;
    if at >= c.inside - r {
        side = (e + 1u) % 3u;
        at = r;
    }
    return ring_base(c, r) + side * (c.inside - 2u * r) + (at - r);
}

// Barycentric of vertex k on side e of ring r: the triangle scaled about its centroid by
// 1 − 2tᵣ, the side's vertices at the pattern's positions r … n − r renormalised.
fn ring_point(f: f32, n: u32, r: u32, e: u32, k: u32, fractional: bool) -> vec3<f32> {
    let tr = pattern_position(f, n, r, fractional);
    let w = tr * (2.0 / 3.0);
    var a = vec3(w);
    a[e] = 1.0 - 2.0 * w;
    var b = vec3(w);
    b[(e + 1u) % 3u] = 1.0 - 2.0 * w;
    let span = pattern_position(f, n, n - r, fractional) - tr;
    var s = 0.0;
    if span > 0.0 {
        s = (pattern_position(f, n, k, fractional) - tr) / span;
    }
    return a * (1.0 - s) + b * s;
}

// Triangle i of the strip between rings r and r + 1 on side e.
fn strip_triangle(c: Counts, r: u32, e: u32, i: u32) -> vec3<u32> {
    let n = c.inside;
    if i == 0u {
        return vec3(ring_vertex(c, r, e, r), ring_vertex(c, r, e, r + 1u), ring_vertex(c, r + 1u, e, r + 1u));
    }
    if i == 2u * (n - 2u * r) - 3u {
        return vec3(ring_vertex(c, r, e, n - r - 1u), ring_vertex(c, r, e, n - r), ring_vertex(c, r + 1u, e, n - r - 1u));
    }
    let k = r + 1u + (i - 1u) / 2u;
    if (i - 1u) % 2u == 0u {
        return vec3(ring_vertex(c, r, e, k), ring_vertex(c, r + 1u, e, k + 1u), ring_vertex(c, r + 1u, e, k));
    }
    return vec3(ring_vertex(c, r, e, k), ring_vertex(c, r, e, k + 1u), ring_vertex(c, r + 1u, e, k + 1u));
}

// The triangles after the zippers (index t counted from the first strip), or the one
// triangle of a patch with n = 1.
fn inner_triangle(c: Counts, t: u32) -> vec3<u32> {
    let n = c.inside;
    if n == 1u {
        return vec3(outer_vertex(c, 0u, 0u), outer_vertex(c, 1u, 0u), outer_vertex(c, 2u, 0u));
    }
    var first = 0u;
    let count = rings(c);
    for (var r = 1u; r < count; r += 1u) {
        let per_side = 2u * (n - 2u * r) - 2u;
        if t < first + 3u * per_side {
            let local = t - first;
            return strip_triangle(c, r, local / per_side, local % per_side);
        }
        first += 3u * per_side;
    }
    return vec3(ring_vertex(c, count, 0u, count), ring_vertex(c, count, 1u, count), ring_vertex(c, count, 2u, count));
}
