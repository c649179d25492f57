//! A patch's layout: where its vertices sit in the triangle (barycentric) and how they
//! are joined, for edge factors `f₀, f₁, f₂` and an inside factor `f = max fₑ`.
//!
//! The 1-D pattern of a factor `f` has the smallest odd count `n ≥ f` of segments:
//! `n − 2` full ones of `1/f` and two short ones of `(1 − (n − 2)/f)/2` on either side of
//! the middle full one ([`Partitioning::Fractional`], as Direct3D 11's `fractional_odd`);
//! or `n` equal ones ([`Partitioning::Integer`]). As `f` grows past an odd number the two
//! short segments are born with zero length in the middle, so every position moves
//! continuously.
//!
//! - **Outer ring**: each edge's own pattern (`nₑ` segments) from its first corner —
//!   computed in the edge's canonical direction, so both triangles of an edge agree.
//! - **Inner rings** `r = 1 … (n − 1)/2`: the triangle scaled about its centroid by
//!   `1 − 2tᵣ` (`tᵣ` the inside pattern's `r`-th position); a side holds the pattern's
//!   vertices `r … n − r` spread from corner to corner, so vertex `k` of every ring lies
//!   across from position `tₖ` of the outer edge. The innermost ring is one triangle.
//! - **Joins**: consecutive inner rings by the regular strip (vertex `k` to `k`); the
//!   outer ring to ring 1 by a zipper that advances along whichever side's next vertex
//!   comes first, so an edge's vertex count is free of the inside's.
//!
//! Vertices, in order: edge 0's `n₀` (from corner 0, its last corner being edge 1's
//! first), edge 1's, edge 2's, then each ring's three sides (`n − 2r` each, a side's last
//! vertex being the next side's first). Triangles: the three zippers (`nₑ + n − 2`
//! each), then the strips between rings (`3 · (2(n − 2r) − 2)` for ring `r`), then the
//! innermost triangle; a patch with `n = 1` is its one triangle.

use super::Partitioning;
use glam::Vec3;

/// Most segments a pattern holds (`2^MAX_LEVEL + 1`).
pub const MAX_SEGMENTS: u32 = (1 << super::MAX_LEVEL) + 1;

/// The pattern's segment count for factor `f`: the smallest odd `n ≥ f` (1 for `f ≤ 1`).
pub fn segments(f: f32) -> u32 {
    let mut n = 1;
    while (n as f32) < f && n < MAX_SEGMENTS {
        n += 2;
    }
    n
}

/// Position `k` (`0..=n`) of the pattern of factor `f` with `n = segments(f)`.
pub fn position(f: f32, n: u32, k: u32, partitioning: Partitioning) -> f32 {
    if k == 0 {
        return 0.0;
    }
    if k >= n {
        return 1.0;
    }
    if partitioning == Partitioning::Integer {
        return k as f32 / n as f32;
    }
    let full = 1.0 / f;
    let short = (1.0 - (n - 2) as f32 * full) * 0.5;
    let h = (n - 3) / 2;
    if k <= h {
        k as f32 * full
    } else if k == h + 1 {
        h as f32 * full + short
    } else if k == h + 2 {
        (h + 1) as f32 * full + short
    } else {
        (k - 2) as f32 * full + short * 2.0
    }
}

/// A patch's counts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Counts {
    /// Each edge's segments.
    pub edges: [u32; 3],
    /// The inside pattern's segments.
    pub inside: u32,
}

impl Counts {
    /// Counts of edge factors `f` (the inside factor is their largest).
    pub fn new(f: [f32; 3]) -> Self {
        let inside = f[0].max(f[1]).max(f[2]);
        Self {
            edges: f.map(segments),
            inside: segments(inside),
        }
    }

    /// Inner rings.
    pub fn rings(&self) -> u32 {
        (self.inside - 1) / 2
    }

    /// Vertices: `Σ nₑ + 3R²`.
    pub fn vertices(&self) -> u32 {
        let r = self.rings();
        self.edges.iter().sum::<u32>() + 3 * r * r
    }

    /// Triangles: 1 for `n = 1`, else `Σ nₑ + 3(n − 2) + 6R(R − 1) + 1`.
    pub fn triangles(&self) -> u32 {
        if self.inside == 1 {
            return 1;
        }
        let r = self.rings();
        self.edges.iter().sum::<u32>() + 3 * (self.inside - 2) + 6 * r * (r - 1) + 1
    }

    /// The first vertex of edge `e`.
    pub fn edge_base(&self, e: usize) -> u32 {
        self.edges[..e].iter().sum()
    }

    /// Vertex `j` of edge `e` from its own first corner (`j = nₑ`: the next edge's first).
    pub fn outer_vertex(&self, e: usize, j: u32) -> u32 {
        if j >= self.edges[e] {
            self.edge_base((e + 1) % 3)
        } else {
            self.edge_base(e) + j
        }
    }

    /// The first vertex of ring `r ≥ 1`.
    pub fn ring_base(&self, r: u32) -> u32 {
        let n = self.inside;
        self.edges.iter().sum::<u32>() + 3 * ((r - 1) * n - (r - 1) * r)
    }

    /// Vertex `k` (`r ≤ k ≤ n − r`) of side `e` of ring `r`.
    pub fn ring_vertex(&self, r: u32, e: usize, k: u32) -> u32 {
        let n = self.inside;
        if k >= n - r {
            return self.ring_vertex(r, (e + 1) % 3, r);
        }
        self.ring_base(r) + e as u32 * (n - 2 * r) + (k - r)
    }
}

/// Where local vertex `v` of a patch is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Place {
    /// On edge `e`, its own step `j` from corner `e` (0: the corner itself).
    Edge {
        /// The edge.
        e: usize,
        /// Its own step.
        j: u32,
    },
    /// Inside, at barycentric `b`.
    Inside(Vec3),
}

/// The place of local vertex `v`.
pub fn place(counts: &Counts, f_inside: f32, partitioning: Partitioning, v: u32) -> Place {
    let outer: u32 = counts.edges.iter().sum();
    if v < outer {
        let mut e = 0;
        while v >= counts.edge_base(e) + counts.edges[e] {
            e += 1;
        }
        return Place::Edge {
            e,
            j: v - counts.edge_base(e),
        };
    }
    let n = counts.inside;
    let mut r = 1;
    while v >= counts.ring_base(r) + 3 * (n - 2 * r) {
        r += 1;
    }
    let local = v - counts.ring_base(r);
    let side = n - 2 * r;
    let e = (local / side) as usize;
    let k = r + local % side;
    Place::Inside(ring_point(f_inside, n, r, e, k, partitioning))
}

/// Barycentric of vertex `k` on side `e` of ring `r` of the inside pattern. Ring `r` is
/// the triangle scaled about its centroid by `1 − 2tᵣ` (corners at `(1 − 2w, w, w)`,
/// `w = 2tᵣ/3`), its side's vertices at the pattern's positions `r … n − r` renormalised:
/// vertex `k` of every ring lies at the same place along the sides' direction, so the
/// strips between rings are never folded.
pub fn ring_point(f: f32, n: u32, r: u32, e: usize, k: u32, partitioning: Partitioning) -> Vec3 {
    let tr = position(f, n, r, partitioning);
    let w = tr * (2.0 / 3.0);
    let corner = |c: usize| {
        let mut b = Vec3::splat(w);
        b[c] = 1.0 - 2.0 * w;
        b
    };
    let span = position(f, n, n - r, partitioning) - tr;
    let s = if span > 0.0 {
        (position(f, n, k, partitioning) - tr) / span
    } else {
        0.0
    };
    corner(e) * (1.0 - s) + corner((e + 1) % 3) * s
}

/// Triangle `t` of a patch as local vertex indices. `edge_t(e, j)` is edge `e`'s own
/// parameter of its vertex `j` (0 at corner `e`, 1 at corner `e + 1`).
pub fn triangle(
    counts: &Counts,
    f_inside: f32,
    partitioning: Partitioning,
    edge_t: &dyn Fn(usize, u32) -> f32,
    t: u32,
) -> [u32; 3] {
    let n = counts.inside;
    if n == 1 {
        return [0, 1, 2].map(|e| counts.outer_vertex(e, 0));
    }
    // The zippers.
    let mut first = 0;
    for e in 0..3 {
        let count = counts.edges[e] + n - 2;
        if t < first + count {
            return zipper(counts, f_inside, partitioning, edge_t, e)[(t - first) as usize];
        }
        first += count;
    }
    // The strips between rings.
    let r_count = counts.rings();
    for r in 1..r_count {
        let per_side = 2 * (n - 2 * r) - 2;
        if t < first + 3 * per_side {
            let local = t - first;
            let e = (local / per_side) as usize;
            return strip_triangle(counts, r, e, local % per_side);
        }
        first += 3 * per_side;
    }
    let r = r_count;
    [0, 1, 2].map(|e| counts.ring_vertex(r, e, r))
}

/// Triangle `i` of the strip between rings `r` and `r + 1` on side `e`.
fn strip_triangle(counts: &Counts, r: u32, e: usize, i: u32) -> [u32; 3] {
    let n = counts.inside;
    let o = |k: u32| counts.ring_vertex(r, e, k);
    let inner = |k: u32| counts.ring_vertex(r + 1, e, k);
    if i == 0 {
        return [o(r), o(r + 1), inner(r + 1)];
    }
    let last = 2 * (n - 2 * r) - 3;
    if i == last {
        return [o(n - r - 1), o(n - r), inner(n - r - 1)];
    }
    // Alternately advance the inner side, then the outer one.
    let k = r + 1 + (i - 1) / 2;
    if (i - 1).is_multiple_of(2) {
        [o(k), inner(k + 1), inner(k)]
    } else {
        [o(k), o(k + 1), inner(k + 1)]
    }
}

/// The zipper of edge `e` (outer) with side `e` of ring 1: `nₑ + n − 2` triangles.
pub fn zipper(
    counts: &Counts,
    f_inside: f32,
    partitioning: Partitioning,
    edge_t: &dyn Fn(usize, u32) -> f32,
    e: usize,
) -> Vec<[u32; 3]> {
    let n = counts.inside;
    let ne = counts.edges[e];
    // Ring 1's vertex `k` lies across from the edge's parameter `t_k` (see `ring_point`).
    let s = |b: u32| position(f_inside, n, 1 + b, partitioning);
    let outer = |a: u32| counts.outer_vertex(e, a);
    let inner = |b: u32| counts.ring_vertex(1, e, 1 + b);
    let (mut a, mut b) = (0, 0);
    let mut out = Vec::with_capacity((ne + n - 2) as usize);
    while a < ne || b < n - 2 {
        if b == n - 2 || (a < ne && edge_t(e, a + 1) <= s(b + 1)) {
            out.push([outer(a), outer(a + 1), inner(b)]);
            a += 1;
        } else {
            out.push([outer(a), inner(b + 1), inner(b)]);
            b += 1;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;

    #[test]
    fn patterns_are_continuous_and_odd() {
        assert_eq!(
            [
                segments(0.5),
                segments(1.0),
                segments(1.01),
                segments(3.0),
                segments(3.5)
            ],
            [1, 1, 3, 3, 5]
        );
        for p in [Partitioning::Fractional, Partitioning::Integer] {
            for k in 0..200 {
                let f = 1.0 + k as f32 * 0.137;
                let n = segments(f);
                let t: Vec<f32> = (0..=n).map(|k| position(f, n, k, p)).collect();
                assert!(t.windows(2).all(|w| w[1] >= w[0]), "{f}: {t:?}");
                // Symmetric.
                for k in 0..=n {
                    assert!((t[k as usize] + t[(n - k) as usize] - 1.0).abs() < 1e-5);
                }
            }
        }
        // Fractional: just past an odd factor the new segments have ~zero length, and
        // every position equals the one just before it.
        let (a, b) = (4.999f32, 5.001f32);
        let (na, nb) = (segments(a), segments(b));
        assert_eq!((na, nb), (5, 7));
        let ta: Vec<f32> = (0..=na)
            .map(|k| position(a, na, k, Partitioning::Fractional))
            .collect();
        let tb: Vec<f32> = (0..=nb)
            .map(|k| position(b, nb, k, Partitioning::Fractional))
            .collect();
        let mut dedup = tb.clone();
        dedup.dedup_by(|x, y| (*x - *y).abs() < 1e-3);
        assert_eq!(dedup.len(), ta.len());
        assert!(
            dedup.iter().zip(&ta).all(|(x, y)| (x - y).abs() < 1e-3),
            "{ta:?} {tb:?}"
        );
    }

    /// Every patch layout tiles the triangle once, counter-clockwise, and its counts hold.
    #[test]
    fn layouts_tile_the_triangle() {
        let corners = [Vec2::ZERO, Vec2::X, Vec2::Y];
        for p in [Partitioning::Fractional, Partitioning::Integer] {
            for f in [
                [1.0, 1.0, 1.0],
                [1.0, 2.5, 1.0],
                [3.0, 3.0, 3.0],
                [2.2, 7.9, 4.4],
                [9.5, 1.0, 1.0],
                [16.0, 15.2, 12.7],
                [1.01, 1.01, 1.5],
            ] {
                let counts = Counts::new(f);
                let f_in = f[0].max(f[1]).max(f[2]);
                let edge_t = |e: usize, j: u32| position(f[e], counts.edges[e], j, p);
                let points: Vec<Vec2> = (0..counts.vertices())
                    .map(|v| {
                        let b = match place(&counts, f_in, p, v) {
                            Place::Edge { e, j } => {
                                let t = edge_t(e, j);
                                let mut b = Vec3::ZERO;
                                b[e] = 1.0 - t;
                                b[(e + 1) % 3] = t;
                                b
                            }
                            Place::Inside(b) => b,
                        };
                        corners[0] * b.x + corners[1] * b.y + corners[2] * b.z
                    })
                    .collect();
                let mut area = 0.0;
                let mut used = vec![false; points.len()];
                for t in 0..counts.triangles() {
                    let tri = triangle(&counts, f_in, p, &edge_t, t);
                    let [a, b, c] = tri.map(|i| points[i as usize]);
                    let signed = 0.5 * (b - a).perp_dot(c - a);
                    assert!(
                        signed >= -1e-6,
                        "{f:?} {p:?} triangle {t} {tri:?}: {signed}"
                    );
                    area += signed;
                    for i in tri {
                        used[i as usize] = true;
                    }
                }
                assert!((area - 0.5).abs() < 1e-4, "{f:?} {p:?}: area {area}");
                assert!(
                    used.iter().all(|&u| u),
                    "{f:?} {p:?}: a vertex no triangle uses"
                );
            }
        }
    }
}
