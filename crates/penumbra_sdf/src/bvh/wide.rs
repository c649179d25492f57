//! The closest-point query's data layout: the binary tree collapsed into a 4-wide tree
//! whose nodes hold their children's boxes as structure-of-arrays, and leaves
//! stored as packets of 4 triangles, so one SIMD evaluation bounds 4 children or
//! measures 4 triangles (glam's `Vec4`: SSE2 on x86-64, NEON on aarch64, scalar
//! elsewhere).
//!
//! Each packet lane computes its triangle's squared distance with the same instruction
//! sequence whatever the lane or the traversal order, so a distance never depends on
//! which other triangles share its packet or on the query's hints.

use super::Bvh;
use glam::{BVec4A, Vec3A, Vec4};

/// Child reference flag: the child is a leaf (a run of packets).
const LEAF: u32 = 1 << 31;
/// Child reference of an unused lane.
const NONE: u32 = u32::MAX;
/// Traversal stack entries: up to 3 siblings stay pushed per level of a tree at most
/// `MAX_DEPTH + 1` deep.
const STACK: usize = 3 * (super::MAX_DEPTH + 2);

/// Four children's bounds, structure-of-arrays. Unused lanes have an empty box
/// (`min = +∞`, `max = −∞`), whose lower bound is `+∞`.
#[derive(Clone, Copy, Debug)]
struct Node4 {
    min: [Vec4; 3],
    max: [Vec4; 3],
    /// Interior node index, `LEAF | first packet`, or `NONE`.
    child: [u32; 4],
    /// Packets of a leaf child.
    packets: [u32; 4],
}

/// Four triangles `(a, a + e0, a + e1)`, structure-of-arrays. Lanes past the end of a
/// leaf repeat its first triangle.
#[derive(Clone, Copy, Debug)]
struct Packet {
    a: [Vec4; 3],
    e0: [Vec4; 3],
    e1: [Vec4; 3],
    /// Unit normal (zero for degenerate triangles).
    normal: [Vec4; 3],
    /// Inverse Gram matrix `[g00, g01, g11]` of `(e0, e1)`: the barycentric
    /// coordinates of the projection of `p − a` are `(g00 s + g01 t, g01 s + g11 t)`
    /// with `s = (p − a)·e0`, `t = (p − a)·e1`. NaN for (near-)degenerate triangles, so
    /// the in-face test fails and only the edges count.
    gram_inv: [Vec4; 3],
    /// `1 / |e|²` of the edges ab, bc, ca (0 for a zero-length edge).
    inv_len2: [Vec4; 3],
    /// `|e0|² − e0·e1`: turns `(s, t)` into `(p − b)·(c − b)`.
    bc_offset: Vec4,
    /// Tree-order triangle index of each lane.
    tri: [u32; 4],
}

/// The 4-wide tree.
#[derive(Clone, Debug, Default)]
pub(crate) struct WideTree {
    nodes: Vec<Node4>,
    packets: Vec<Packet>,
    /// Packet holding each tree-order triangle.
    packet_of: Vec<u32>,
}

impl WideTree {
    /// Collapses `bvh` (whose `nodes` and `tris` must be built).
    pub(crate) fn build(bvh: &Bvh) -> WideTree {
        let mut tree = WideTree {
            packet_of: vec![0; bvh.tris.len()],
            ..Default::default()
        };
        if !bvh.nodes.is_empty() {
            tree.collapse(bvh, 0);
        }
        tree
    }

    /// Adds the 4-wide node standing for binary node `root` (and, recursively, its
    /// subtree); returns its index.
    fn collapse(&mut self, bvh: &Bvh, root: usize) -> u32 {
        let node = &bvh.nodes[root];
        let mut kids: Vec<usize> = if node.count > 0 {
            vec![root] // a leaf root: a 4-wide node with one leaf child
        } else {
            vec![root + 1, node.start_or_right as usize]
        };
        // Open the largest interior child until there are 4 (deterministic: ties keep
        // the first).
        while kids.len() < 4 {
            let mut best: Option<(usize, f32)> = None;
            for (pos, &k) in kids.iter().enumerate() {
                let n = &bvh.nodes[k];
                if n.count == 0 {
                    let area = half_area(n.min, n.max);
                    if best.is_none_or(|(_, a)| area > a) {
                        best = Some((pos, area));
                    }
                }
            }
            let Some((pos, _)) = best else { break };
            let k = kids[pos];
            kids[pos] = k + 1;
            kids.insert(pos + 1, bvh.nodes[k].start_or_right as usize);
        }
        let index = self.nodes.len();
        self.nodes.push(Node4 {
            min: [Vec4::INFINITY; 3],
            max: [Vec4::NEG_INFINITY; 3],
            child: [NONE; 4],
            packets: [0; 4],
        });
        for (lane, &k) in kids.iter().enumerate() {
            let n = &bvh.nodes[k];
            let (child, packets) = if n.count > 0 {
                let first = self.packets.len() as u32;
                self.add_leaf(bvh, n.start_or_right as usize, n.count as usize);
                (LEAF | first, self.packets.len() as u32 - first)
            } else {
                (self.collapse(bvh, k), 0)
            };
            let w = &mut self.nodes[index];
            for axis in 0..3 {
                w.min[axis][lane] = n.min[axis];
                w.max[axis][lane] = n.max[axis];
            }
            w.child[lane] = child;
            w.packets[lane] = packets;
        }
        index as u32
    }

    fn add_leaf(&mut self, bvh: &Bvh, start: usize, count: usize) {
        for first in (start..start + count).step_by(4) {
            let mut p = Packet {
                a: [Vec4::ZERO; 3],
                e0: [Vec4::ZERO; 3],
                e1: [Vec4::ZERO; 3],
                normal: [Vec4::ZERO; 3],
                gram_inv: [Vec4::ZERO; 3],
                inv_len2: [Vec4::ZERO; 3],
                bc_offset: Vec4::ZERO,
                tri: [0; 4],
            };
            for lane in 0..4 {
                let i = if first + lane < start + count {
                    first + lane
                } else {
                    first
                };
                self.packet_of[i] = self.packets.len() as u32;
                let [a, b, c] = bvh.tris[i];
                let (e0, e1, e2) = (b - a, c - a, c - b);
                let g = gram_inverse(e0, e1);
                let n = e0.cross(e1);
                let n = if g[0].is_nan() {
                    Vec3A::ZERO
                } else {
                    n.normalize_or_zero()
                };
                let inv = |e: Vec3A| {
                    let l = e.length_squared();
                    if l > 0.0 { 1.0 / l } else { 0.0 }
                };
                for axis in 0..3 {
                    p.a[axis][lane] = a[axis];
                    p.e0[axis][lane] = e0[axis];
                    p.e1[axis][lane] = e1[axis];
                    p.normal[axis][lane] = n[axis];
                    p.gram_inv[axis][lane] = g[axis];
                }
                p.inv_len2[0][lane] = inv(e0);
                p.inv_len2[1][lane] = inv(e2);
                p.inv_len2[2][lane] = inv(e1);
                p.bc_offset[lane] = e0.length_squared() - e0.dot(e1);
                p.tri[lane] = i as u32;
            }
            self.packets.push(p);
        }
    }

    /// The closest triangle to `p` closer than `sqrt(best_d2)`: `(squared distance,
    /// tree-order index)`. `hints` are tree-order triangles evaluated first. Ties go to
    /// the lowest input index (`order`) among the triangles visited.
    pub(crate) fn closest(
        &self,
        p: Vec3A,
        mut best_d2: f32,
        hints: impl IntoIterator<Item = usize>,
        order: &[u32],
    ) -> Option<(f32, usize)> {
        if self.nodes.is_empty() {
            return None;
        }
        let px = [Vec4::splat(p.x), Vec4::splat(p.y), Vec4::splat(p.z)];
        let mut best: Option<usize> = None;
        let visit_packet = |packet: &Packet, best_d2: &mut f32, best: &mut Option<usize>| {
            let d2 = packet.distance_squared(&px);
            if d2.min_element() > *best_d2 {
                return;
            }
            for lane in 0..4 {
                let (d, t) = (d2[lane], packet.tri[lane] as usize);
                if d < *best_d2 || (d == *best_d2 && best.is_some_and(|b| order[t] < order[b])) {
                    *best_d2 = d;
                    *best = Some(t);
                }
            }
        };
        for h in hints {
            if let Some(&q) = self.packet_of.get(h) {
                visit_packet(&self.packets[q as usize], &mut best_d2, &mut best);
            }
        }
        let mut stack = [(0u32, 0.0f32); STACK];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let (reference, lb) = stack[top];
            if lb >= best_d2 {
                continue;
            }
            let node = &self.nodes[reference as usize];
            let lb = node.lower_bounds(&px);
            let useful = lb.cmplt(Vec4::splat(best_d2)).bitmask();
            // Leaves are measured now, interior children pushed so that they pop in lane
            // order. (Sorting the lanes by bound costs more in branch mispredictions than
            // it saves: the hints already make the bound nearly exact.)
            let mut lanes = useful;
            while lanes != 0 {
                let lane = lanes.trailing_zeros() as usize;
                lanes &= lanes - 1;
                let child = node.child[lane];
                if child & LEAF != 0 && lb[lane] < best_d2 {
                    let first = (child & !LEAF) as usize;
                    let count = node.packets[lane] as usize;
                    for packet in &self.packets[first..first + count] {
                        visit_packet(packet, &mut best_d2, &mut best);
                    }
                }
            }
            let mut lanes = useful;
            while lanes != 0 {
                let lane = 31 - lanes.leading_zeros() as usize;
                lanes &= !(1 << lane);
                let child = node.child[lane];
                if child & LEAF == 0 && lb[lane] < best_d2 && top < STACK {
                    stack[top] = (child, lb[lane]);
                    top += 1;
                }
            }
        }
        best.map(|b| (best_d2, b))
    }
}

impl Node4 {
    /// Squared distance from `p` to each child's box: a lower bound of the squared
    /// distance to its triangles. (Bounding slabs along the mean normal were tried as a
    /// second bound: no faster on the bunny, and they double the node size.)
    #[inline]
    fn lower_bounds(&self, p: &[Vec4; 3]) -> Vec4 {
        let mut box_d2 = Vec4::ZERO;
        for axis in 0..3 {
            let d = (self.min[axis] - p[axis])
                .max(p[axis] - self.max[axis])
                .max(Vec4::ZERO);
            box_d2 += d * d;
        }
        box_d2
    }
}

impl Packet {
    /// Squared distance from `p` to each lane's triangle: to its plane when `p` projects
    /// inside it, else to the nearest of its three edges.
    #[inline]
    fn distance_squared(&self, p: &[Vec4; 3]) -> Vec4 {
        let ap = [p[0] - self.a[0], p[1] - self.a[1], p[2] - self.a[2]];
        let dot = |x: &[Vec4; 3], y: &[Vec4; 3]| x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
        let s = dot(&ap, &self.e0);
        let t = dot(&ap, &self.e1);
        let [g00, g01, g11] = self.gram_inv;
        let u = g00 * s + g01 * t;
        let v = g01 * s + g11 * t;
        let inside: BVec4A = u.cmpge(Vec4::ZERO) & v.cmpge(Vec4::ZERO) & (u + v).cmple(Vec4::ONE);
        let h = dot(&ap, &self.normal);
        let plane = h * h;
        let segment = |d: &[Vec4; 3], e: &[Vec4; 3], x: Vec4| {
            let x = x.clamp(Vec4::ZERO, Vec4::ONE);
            let r = [d[0] - x * e[0], d[1] - x * e[1], d[2] - x * e[2]];
            dot(&r, &r)
        };
        let ab = segment(&ap, &self.e0, s * self.inv_len2[0]);
        let ca = segment(&ap, &self.e1, t * self.inv_len2[2]);
        let bp = [ap[0] - self.e0[0], ap[1] - self.e0[1], ap[2] - self.e0[2]];
        let bc_dir = [
            self.e1[0] - self.e0[0],
            self.e1[1] - self.e0[1],
            self.e1[2] - self.e0[2],
        ];
        let bc = segment(&bp, &bc_dir, (t - s + self.bc_offset) * self.inv_len2[1]);
        Vec4::select(inside, plane, ab.min(ca).min(bc))
    }
}

/// Inverse Gram matrix `[g00, g01, g11]` of edges `(e0, e1)`, computed in f64; NaN when
/// the triangle is degenerate (its area is below 1e-6 of its edge lengths' product, so
/// its interior is within 1e-6 × its size of its edges).
fn gram_inverse(e0: Vec3A, e1: Vec3A) -> [f32; 3] {
    let (e0, e1) = (e0.as_dvec3(), e1.as_dvec3());
    let (a, b, c) = (e0.dot(e0), e0.dot(e1), e1.dot(e1));
    let det = a * c - b * b;
    if !(det > 1e-12 * a * c) || !det.is_finite() {
        return [f32::NAN; 3];
    }
    [(c / det) as f32, (-b / det) as f32, (a / det) as f32]
}

fn half_area(min: Vec3A, max: Vec3A) -> f32 {
    let s = (max - min).max(Vec3A::ZERO);
    s.x * s.y + s.y * s.z + s.z * s.x
}

