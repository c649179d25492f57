//! The closest-point query's data layout: the binary tree collapsed into a 4-wide tree
//! whose nodes hold their children's boxes as structure-of-arrays, and leaves
//! stored as packets of 4 triangles, so one SIMD evaluation bounds 4 children or
//! measures 4 triangles (glam's `Vec4`: SSE2 on x86-64, NEON on aarch64, scalar
//! elsewhere).
//!
//! A packet computes its lanes' squared distances with the same instruction sequence
//! whatever the traversal order or the query's hints, so a distance never depends on
//! them. (A packet holding a degenerate triangle measures all four lanes the slower way,
//! so a lane's last bits can depend on its packet-mates, fixed when the tree is built.)

use super::Bvh;
use glam::{BVec4A, Vec3A, Vec4};

/// Child reference flag: the child is a leaf (a run of packets).
const LEAF: u32 = 1 << 31;
/// Child reference of an unused lane.
const NONE: u32 = u32::MAX;
/// Traversal stack entries: up to 3 siblings stay pushed per level of a tree at most
/// `MAX_DEPTH + 1` deep.
const STACK: usize = 3 * (super::MAX_DEPTH + 2);

/// Subtrees with at most this many triangles get a bounding cylinder.
const CYLINDER_MAX_TRIANGLES: usize = 256;

/// Four children's bounds, structure-of-arrays. Unused lanes have an empty box
/// (`min = +∞`, `max = −∞`), whose lower bound is `+∞`.
///
/// Besides its box, each small child has a bounding *cylinder*: a disc around its
/// area-weighted centre, perpendicular to its mean normal, of radius `cyl_radius`,
/// thickened by `cyl_half` on both sides. A surface patch seen from a far sample
/// lies almost flat across the line of sight, where a box bound is loose by up to the
/// patch size and the disc bound by only its thickness: that is what prunes the many
/// near-tangent leaves of far-field queries. (Children without one have infinite
/// cylinder dimensions, a zero bound.)
#[derive(Clone, Copy, Debug)]
struct Node4 {
    min: [Vec4; 3],
    max: [Vec4; 3],
    cyl_center: [Vec4; 3],
    cyl_axis: [Vec4; 3],
    cyl_radius: Vec4,
    cyl_half: Vec4,
    /// Interior node index, `LEAF | first packet`, or `NONE`.
    child: [u32; 4],
    /// Packets of a leaf child.
    packets: [u32; 4],
    /// Bit `i` set: lane `i` is a leaf.
    leaf_lanes: u32,
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
    /// In-plane inward normals `n × e` of the edges ab, bc, ca (any length): `p`
    /// projects inside the triangle iff `(p − a)·m_ab ≥ 0`, `(p − a)·m_bc ≥ e0·m_bc`
    /// and `(p − a)·m_ca ≥ 0` — a well-conditioned test even for slivers (barycentric
    /// coordinates from the inverse Gram matrix are not: the first version used them
    /// and a thin plate's side triangles came out up to 18 % too far).
    edge_normal: [[Vec4; 3]; 3],
    /// `e0·m_bc`; `+∞` for (near-)degenerate triangles, so the in-face test fails and
    /// only the edges count.
    bc_threshold: Vec4,
    /// `1 / |e|²` of the edges ab, bc, ca (0 for a zero-length edge).
    inv_len2: [Vec4; 3],
    /// `|e0|² − e0·e1`: turns `(s, t)` into `(p − b)·(c − b)`.
    bc_offset: Vec4,
    /// `|e|²` of the edges ab, bc, ca.
    len2: [Vec4; 3],
    /// Some lane is degenerate (no unit normal): measured with 3D segment distances.
    degenerate: bool,
    /// Tree-order triangle index of each lane.
    tri: [u32; 4],
    /// 1 for real lanes, 0 for padding (repeats of the first triangle).
    real: Vec4,
}

/// Fast-winding-number data of a node's four children: each child's dipole (area-weighted
/// normal sum at its area-weighted centre) and the squared distance beyond which the
/// dipole stands in for its triangles (`(β · radius)²`; `+∞` for unused lanes, never far).
#[derive(Clone, Copy, Debug)]
struct Dipole4 {
    normal: [Vec4; 3],
    center: [Vec4; 3],
    far2: Vec4,
}

/// The 4-wide tree.
#[derive(Clone, Debug, Default)]
pub(crate) struct WideTree {
    nodes: Vec<Node4>,
    dipoles: Vec<Dipole4>,
    packets: Vec<Packet>,
    /// Packet holding each tree-order triangle.
    packet_of: Vec<u32>,
    /// Packets numbered so far while collapsing.
    next_packet: u32,
}

impl WideTree {
    /// Collapses `bvh` (whose `nodes`, `tris` and `dipoles` must be built). The tree
    /// shape is chosen sequentially; bounding cylinders and triangle packets, the bulk
    /// of the work, are computed in parallel (each independently, so the result does
    /// not depend on the thread count).
    pub(crate) fn build(bvh: &Bvh) -> WideTree {
        use rayon::prelude::*;
        let mut tree = WideTree::default();
        if bvh.nodes.is_empty() {
            return tree;
        }
        // Upper bounds (a 4-wide node has at least two children; a leaf at least one
        // triangle), reserved so the vectors never grow by copying.
        let mut leaves = Vec::with_capacity(bvh.nodes.len());
        let mut kids_of = Vec::with_capacity(bvh.nodes.len() / 2 + 1);
        tree.nodes.reserve(bvh.nodes.len() / 2 + 1);
        tree.collapse(bvh, 0, &mut leaves, &mut kids_of);
        // Packets: leaf after leaf, in the order `collapse` numbered them, each made
        // from its triangles `first..end` (the rest of its leaf); collected in parallel
        // straight into place (no zero-fill first: these are megabytes, and a fresh
        // page costs a fault).
        let specs: Vec<(usize, usize)> = leaves
            .iter()
            .flat_map(|&(start, count)| {
                (start..start + count)
                    .step_by(4)
                    .map(move |first| (first, start + count))
            })
            .collect();
        debug_assert_eq!(specs.len(), tree.next_packet as usize);
        specs
            .par_iter()
            .map(|&(first, end)| leaf_packet(bvh, first, end))
            .collect_into_vec(&mut tree.packets);
        tree.packet_of = vec![0; bvh.tris.len()];
        for (q, packet) in tree.packets.iter().enumerate() {
            for &t in &packet.tri {
                tree.packet_of[t as usize] = q as u32;
            }
        }
        let cylinders: Vec<[Option<Cylinder>; 4]> = kids_of
            .par_iter()
            .map(|kids| kids.map(|k| k.and_then(|k| bounding_cylinder(bvh, k))))
            .collect();
        tree.dipoles = kids_of
            .iter()
            .map(|kids| {
                let mut d = Dipole4 {
                    normal: [Vec4::ZERO; 3],
                    center: [Vec4::ZERO; 3],
                    far2: Vec4::INFINITY,
                };
                for (lane, kid) in kids.iter().enumerate() {
                    if let Some(k) = *kid {
                        let dip = &bvh.dipoles[k];
                        for axis in 0..3 {
                            d.normal[axis][lane] = dip.normal_sum[axis];
                            d.center[axis][lane] = dip.center[axis];
                        }
                        d.far2[lane] = (super::BETA * dip.radius).powi(2);
                    }
                }
                d
            })
            .collect();
        for (node, cylinders) in tree.nodes.iter_mut().zip(cylinders) {
            for (lane, cylinder) in cylinders.into_iter().enumerate() {
                if let Some(c) = cylinder {
                    for axis in 0..3 {
                        node.cyl_center[axis][lane] = c.center[axis];
                        node.cyl_axis[axis][lane] = c.axis[axis];
                    }
                    node.cyl_radius[lane] = c.radius;
                    node.cyl_half[lane] = c.half_thickness;
                }
            }
        }
        tree
    }

    /// Adds the 4-wide node standing for binary node `root` (and, recursively, its
    /// subtree); returns its index. Leaf children get packet ranges numbered in the
    /// order they are pushed to `leaves` (`(first triangle, count)`); `kids_of[node]`
    /// records each lane's binary node.
    fn collapse(
        &mut self,
        bvh: &Bvh,
        root: usize,
        leaves: &mut Vec<(usize, usize)>,
        kids_of: &mut Vec<[Option<usize>; 4]>,
    ) -> u32 {
        let node = &bvh.nodes[root];
        let mut slots = [0usize; 4];
        let mut len = if node.count > 0 {
            slots[0] = root; // a leaf root: a 4-wide node with one leaf child
            1
        } else {
            slots[0] = root + 1;
            slots[1] = node.start_or_right as usize;
            2
        };
        // Open the largest interior child until there are 4 (deterministic: ties keep
        // the first).
        while len < 4 {
            let mut best: Option<(usize, f32)> = None;
            for (pos, &k) in slots[..len].iter().enumerate() {
                let n = &bvh.nodes[k];
                if n.count == 0 {
                    let area = half_area(n.min, n.max);
                    if best.is_none_or(|(_, a)| area > a) {
                        best = Some((pos, area));
                    }
                }
            }
            let Some((pos, _)) = best else { break };
            let k = slots[pos];
            slots.copy_within(pos + 1..len, pos + 2);
            slots[pos] = k + 1;
            slots[pos + 1] = bvh.nodes[k].start_or_right as usize;
            len += 1;
        }
        let kids = &slots[..len];
        let index = self.nodes.len();
        self.nodes.push(Node4 {
            min: [Vec4::INFINITY; 3],
            max: [Vec4::NEG_INFINITY; 3],
            cyl_center: [Vec4::ZERO; 3],
            cyl_axis: [Vec4::ZERO; 3],
            cyl_radius: Vec4::INFINITY,
            cyl_half: Vec4::INFINITY,
            child: [NONE; 4],
            packets: [0; 4],
            leaf_lanes: 0,
        });
        let mut lanes = [None; 4];
        for (lane, &k) in kids.iter().enumerate() {
            lanes[lane] = Some(k);
        }
        kids_of.push(lanes);
        for (lane, &k) in kids.iter().enumerate() {
            let n = &bvh.nodes[k];
            let (child, packets) = if n.count > 0 {
                let first = self.next_packet;
                let count = (n.count as usize).div_ceil(4) as u32;
                self.next_packet += count;
                leaves.push((n.start_or_right as usize, n.count as usize));
                (LEAF | first, count)
            } else {
                (self.collapse(bvh, k, leaves, kids_of), 0)
            };
            let w = &mut self.nodes[index];
            for axis in 0..3 {
                w.min[axis][lane] = n.min[axis];
                w.max[axis][lane] = n.max[axis];
            }
            w.child[lane] = child;
            w.packets[lane] = packets;
            if child & LEAF != 0 {
                w.leaf_lanes |= 1 << lane;
            }
        }
        index as u32
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
            packet.measure(&px, best_d2, best, order);
        };
        // Neighbouring samples often share their closest triangle's packet: visit each
        // hinted packet once, now, and skip it in the traversal (measuring a packet again
        // cannot change the result).
        let mut seen = [u32::MAX; 4];
        for (n, h) in hints.into_iter().take(4).enumerate() {
            if let Some(&q) = self.packet_of.get(h)
                && !seen[..n].contains(&q)
            {
                seen[n] = q;
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
            let lb = lb.to_array();
            // Leaves are measured now, interior children pushed so that they pop in lane
            // order. (Sorting the lanes by bound costs more in branch mispredictions than
            // it saves: the hints already make the bound nearly exact.)
            let mut lanes = useful & node.leaf_lanes;
            while lanes != 0 {
                let lane = lanes.trailing_zeros() as usize;
                lanes &= lanes - 1;
                if lb[lane] < best_d2 {
                    let first = (node.child[lane] & !LEAF) as usize;
                    let count = node.packets[lane] as usize;
                    for (index, packet) in (first as u32..).zip(&self.packets[first..first + count])
                    {
                        if !seen.contains(&index) {
                            visit_packet(packet, &mut best_d2, &mut best);
                        }
                    }
                }
            }
            let mut lanes = useful & !node.leaf_lanes;
            while lanes != 0 {
                let lane = 31 - lanes.leading_zeros() as usize;
                lanes &= !(1 << lane);
                if lb[lane] < best_d2 && top < STACK {
                    stack[top] = (node.child[lane], lb[lane]);
                    top += 1;
                }
            }
        }
        best.map(|b| (best_d2, b))
    }
}

impl WideTree {
    /// [`closest`](Self::closest) for four queries at once, sharing one traversal: a
    /// node or packet is fetched once and measured for each query that still needs it.
    /// Nearby queries (consecutive samples of a row) visit nearly the same nodes, so
    /// this pays the traversal's branches and memory latency once for four. Each
    /// query's distance is computed with exactly the instructions of a single query,
    /// so results equal [`closest`](Self::closest)'s. `hints[q]`: query `q`'s hinted
    /// tree-order triangles (`usize::MAX`: none).
    pub(crate) fn closest4(
        &self,
        p: [Vec3A; 4],
        best_d2: [f32; 4],
        hints: [[usize; 2]; 4],
        order: &[u32],
    ) -> [Option<(f32, usize)>; 4] {
        if self.nodes.is_empty() {
            return [None; 4];
        }
        let px = p.map(|p| [Vec4::splat(p.x), Vec4::splat(p.y), Vec4::splat(p.z)]);
        // Per query, as plain arrays (a `Vec4` indexed by a runtime lane compiles to a
        // jump table); a `Vec4` of the bounds only where all four are compared at once.
        let mut best_d2 = best_d2;
        let mut best: [Option<usize>; 4] = [None; 4];
        let mut visit = |packet: &Packet, q: usize, best_d2: &mut [f32; 4]| {
            packet.measure(&px[q], &mut best_d2[q], &mut best[q], order);
        };
        // The hinted packets, measured now and skipped by the traversal (measuring a
        // packet again cannot change a query's result).
        let mut seen = [[u32::MAX; 2]; 4];
        for (q, hints) in hints.iter().enumerate() {
            for (n, &h) in hints.iter().enumerate() {
                if let Some(&packet) = self.packet_of.get(h)
                    && !seen[q].contains(&packet)
                {
                    seen[q][n] = packet;
                    visit(&self.packets[packet as usize], q, &mut best_d2);
                }
            }
        }
        let mut stack = [(0u32, Vec4::ZERO); STACK];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let (reference, lb) = stack[top];
            let active = lb.cmplt(Vec4::from_array(best_d2)).bitmask();
            if active == 0 {
                continue;
            }
            let node = &self.nodes[reference as usize];
            // Queries this node cannot help skip their bounds (+∞ prunes every child).
            let bounds = |q: usize| {
                if active & (1 << q) != 0 {
                    node.lower_bounds(&px[q])
                } else {
                    Vec4::INFINITY
                }
            };
            // Columns: queries; after the transpose, children.
            // As an array: `Mat4::col` with a runtime index compiles to a jump table.
            let by_child = glam::Mat4::from_cols(bounds(0), bounds(1), bounds(2), bounds(3))
                .transpose()
                .to_cols_array_2d()
                .map(Vec4::from_array);
            let bound = Vec4::from_array(best_d2);
            let mut useful = 0u32;
            for (child, lb) in by_child.iter().enumerate() {
                if lb.cmplt(bound).any() {
                    useful |= 1 << child;
                }
            }
            let mut lanes = useful & node.leaf_lanes;
            while lanes != 0 {
                let lane = lanes.trailing_zeros() as usize;
                lanes &= lanes - 1;
                let first = (node.child[lane] & !LEAF) as usize;
                let count = node.packets[lane] as usize;
                let lb = by_child[lane];
                for (index, packet) in (first as u32..).zip(&self.packets[first..first + count]) {
                    let mut queries = lb.cmplt(Vec4::from_array(best_d2)).bitmask();
                    while queries != 0 {
                        let q = queries.trailing_zeros() as usize;
                        queries &= queries - 1;
                        if !seen[q].contains(&index) {
                            visit(packet, q, &mut best_d2);
                        }
                    }
                }
            }
            let mut lanes = useful & !node.leaf_lanes;
            while lanes != 0 {
                let lane = 31 - lanes.leading_zeros() as usize;
                lanes &= !(1 << lane);
                if top < STACK {
                    stack[top] = (node.child[lane], by_child[lane]);
                    top += 1;
                }
            }
        }
        std::array::from_fn(|q| best[q].map(|b| (best_d2[q], b)))
    }
}

impl WideTree {
    /// The fast winding number at `q` (Barill et al. 2018): a child's dipole stands in
    /// for its triangles beyond `β` times its radius, exact solid angles nearer; four
    /// children or four triangles per SIMD evaluation.
    pub(crate) fn winding_number(&self, q: Vec3A) -> f32 {
        if self.nodes.is_empty() {
            return 0.0;
        }
        let qx = [Vec4::splat(q.x), Vec4::splat(q.y), Vec4::splat(q.z)];
        let mut sum = Vec4::ZERO;
        let mut stack = [0u32; STACK];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let index = stack[top] as usize;
            let (node, dip) = (&self.nodes[index], &self.dipoles[index]);
            let d = [
                dip.center[0] - qx[0],
                dip.center[1] - qx[1],
                dip.center[2] - qx[2],
            ];
            let dist2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            let far = dist2.cmpgt(dip.far2);
            let n_dot_d = dip.normal[0] * d[0] + dip.normal[1] * d[1] + dip.normal[2] * d[2];
            let far_term = n_dot_d / (dist2 * dist2.sqrt() * (4.0 * std::f32::consts::PI));
            sum += Vec4::select(far, far_term, Vec4::ZERO);
            let mut near = !far.bitmask() & 0xf;
            while near != 0 {
                let lane = near.trailing_zeros() as usize;
                near &= near - 1;
                let child = node.child[lane];
                if child == NONE {
                    continue;
                }
                if child & LEAF != 0 {
                    let first = (child & !LEAF) as usize;
                    for packet in &self.packets[first..first + node.packets[lane] as usize] {
                        sum += packet.solid_angles(&qx);
                    }
                } else if top < STACK {
                    stack[top] = child;
                    top += 1;
                }
            }
        }
        sum.x + sum.y + sum.z + sum.w
    }
}

impl Node4 {
    /// Lower bounds of the squared distance from `p` to each child's triangles: the
    /// larger of the squared distances to its box and to its cylinder. (A slab along
    /// the mean normal alone was tried first: it never prunes a convex patch seen from
    /// outside, and did not pay for itself.)
    #[inline]
    fn lower_bounds(&self, p: &[Vec4; 3]) -> Vec4 {
        let mut box_d2 = Vec4::ZERO;
        let mut v = [Vec4::ZERO; 3];
        let mut along = Vec4::ZERO;
        for axis in 0..3 {
            let d = (self.min[axis] - p[axis])
                .max(p[axis] - self.max[axis])
                .max(Vec4::ZERO);
            box_d2 += d * d;
            v[axis] = p[axis] - self.cyl_center[axis];
            along += v[axis] * self.cyl_axis[axis];
        }
        let mut lateral2 = Vec4::ZERO;
        for (v, axis) in v.iter().zip(&self.cyl_axis) {
            let l = *v - along * *axis;
            lateral2 += l * l;
        }
        let a = (along.abs() - self.cyl_half).max(Vec4::ZERO);
        let b = (lateral2.sqrt() - self.cyl_radius).max(Vec4::ZERO);
        box_d2.max(a * a + b * b)
    }
}

impl Packet {
    /// Measures this packet from `p` against the best so far (`best_d2`, tree-order
    /// `best`): a lane within `best_d2` replaces it, ties going to the lowest input index
    /// (`order`). Shared by the single and the four-query traversal, so both break ties
    /// alike.
    #[inline]
    fn measure(&self, p: &[Vec4; 3], best_d2: &mut f32, best: &mut Option<usize>, order: &[u32]) {
        let d2 = self.distance_squared(p);
        let mut lanes = d2.cmple(Vec4::splat(*best_d2)).bitmask();
        // Plain arrays: indexing a `Vec4` by a runtime lane compiles to a jump table.
        let d2 = d2.to_array();
        while lanes != 0 {
            let lane = lanes.trailing_zeros() as usize;
            lanes &= lanes - 1;
            let (d, t) = (d2[lane], self.tri[lane] as usize);
            if d < *best_d2 || (d == *best_d2 && best.is_some_and(|b| order[t] < order[b])) {
                *best_d2 = d;
                *best = Some(t);
            }
        }
    }

    /// Each real lane's signed solid angle over 4π seen from `q` (Van Oosterom &
    /// Strackee), padding lanes 0.
    #[inline]
    fn solid_angles(&self, q: &[Vec4; 3]) -> Vec4 {
        let va = [self.a[0] - q[0], self.a[1] - q[1], self.a[2] - q[2]];
        let vb = [va[0] + self.e0[0], va[1] + self.e0[1], va[2] + self.e0[2]];
        let vc = [va[0] + self.e1[0], va[1] + self.e1[1], va[2] + self.e1[2]];
        let dot = |x: &[Vec4; 3], y: &[Vec4; 3]| x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
        let (la, lb, lc) = (
            dot(&va, &va).sqrt(),
            dot(&vb, &vb).sqrt(),
            dot(&vc, &vc).sqrt(),
        );
        let cross = [
            vb[1] * vc[2] - vb[2] * vc[1],
            vb[2] * vc[0] - vb[0] * vc[2],
            vb[0] * vc[1] - vb[1] * vc[0],
        ];
        let det = dot(&va, &cross);
        let div = la * lb * lc + dot(&va, &vb) * lc + dot(&vb, &vc) * la + dot(&vc, &va) * lb;
        atan2(det, div) * self.real * (1.0 / (2.0 * std::f32::consts::PI))
    }

    const EMPTY: Packet = Packet {
        a: [Vec4::ZERO; 3],
        e0: [Vec4::ZERO; 3],
        e1: [Vec4::ZERO; 3],
        normal: [Vec4::ZERO; 3],
        edge_normal: [[Vec4::ZERO; 3]; 3],
        bc_threshold: Vec4::ZERO,
        inv_len2: [Vec4::ZERO; 3],
        bc_offset: Vec4::ZERO,
        len2: [Vec4::ZERO; 3],
        degenerate: false,
        tri: [0; 4],
        real: Vec4::ZERO,
    };

    /// Squared distance from `p` to each lane's triangle: to its plane when `p` projects
    /// inside it, else to the nearest of its three edges — the plane's `h²` plus the
    /// squared distance to the edge within the plane, from the dot products the in-face
    /// test already took (no 3D closest point: about a quarter fewer operations than
    /// [`distance_squared_3d`](Self::distance_squared_3d), which packets with a
    /// degenerate lane use, having no plane).
    #[inline]
    fn distance_squared(&self, p: &[Vec4; 3]) -> Vec4 {
        if self.degenerate {
            return self.distance_squared_3d(p);
        }
        let ap = [p[0] - self.a[0], p[1] - self.a[1], p[2] - self.a[2]];
        let dot = |x: &[Vec4; 3], y: &[Vec4; 3]| x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
        let s = dot(&ap, &self.e0);
        let t = dot(&ap, &self.e1);
        let [m_ab, m_bc, m_ca] = &self.edge_normal;
        let (p_ab, p_bc, p_ca) = (dot(&ap, m_ab), dot(&ap, m_bc), dot(&ap, m_ca));
        let inside: BVec4A =
            p_ab.cmpge(Vec4::ZERO) & p_bc.cmpge(self.bc_threshold) & p_ca.cmpge(Vec4::ZERO);
        let h = dot(&ap, &self.normal);
        let plane = h * h;
        // In the plane, an edge's squared distance: across it `(p−a)·m / |e|` (`|m| =
        // |e|`), along it the overshoot past its ends.
        let edge = |across: Vec4, along: Vec4, len2: Vec4, inv: Vec4| {
            let over = along - along.max(Vec4::ZERO).min(len2);
            (across * across + over * over) * inv
        };
        let ab = edge(p_ab, s, self.len2[0], self.inv_len2[0]);
        let ca = edge(p_ca, t, self.len2[2], self.inv_len2[2]);
        // bc only across its interior: its ends are ab's and ca's. (Its coordinate along
        // comes from `s` and `t`, measured along the other two edges: past a short bc's
        // ends, its rounding divided by |bc| would swamp the overshoot; inside, it only
        // moves the foot of the perpendicular, a second-order change.)
        let along = t - s + self.bc_offset;
        let within = along.cmpge(Vec4::ZERO) & along.cmple(self.len2[1]);
        // `bc_threshold` is `e0·m_bc`, finite here: `(p − a)·m_bc` becomes `(p − b)·m_bc`.
        let across = p_bc - self.bc_threshold;
        let bc = Vec4::select(within, across * across * self.inv_len2[1], Vec4::INFINITY);
        Vec4::select(inside, plane, plane + ab.min(ca).min(bc))
    }

    /// [`distance_squared`](Self::distance_squared) from 3D closest points on the edges.
    #[inline]
    fn distance_squared_3d(&self, p: &[Vec4; 3]) -> Vec4 {
        let ap = [p[0] - self.a[0], p[1] - self.a[1], p[2] - self.a[2]];
        let dot = |x: &[Vec4; 3], y: &[Vec4; 3]| x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
        let s = dot(&ap, &self.e0);
        let t = dot(&ap, &self.e1);
        let [m_ab, m_bc, m_ca] = &self.edge_normal;
        let inside: BVec4A = dot(&ap, m_ab).cmpge(Vec4::ZERO)
            & dot(&ap, m_bc).cmpge(self.bc_threshold)
            & dot(&ap, m_ca).cmpge(Vec4::ZERO);
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

/// The packet of tree-order triangles `first..end.min(first + 4)` (lanes past `end`
/// repeat triangle `first`).
fn leaf_packet(bvh: &Bvh, first: usize, end: usize) -> Packet {
    let mut p = Packet::EMPTY;
    for lane in 0..4 {
        let i = if first + lane < end {
            first + lane
        } else {
            first
        };
        let [a, b, c] = bvh.tris[i];
        let (e0, e1, e2) = (b - a, c - a, c - b);
        let n = unit_normal(e0, e1).unwrap_or(Vec3A::ZERO);
        let m = [n.cross(e0), n.cross(e2), n.cross(-e1)];
        let inv = |e: Vec3A| {
            let l = e.length_squared();
            if l > 0.0 { 1.0 / l } else { 0.0 }
        };
        for axis in 0..3 {
            p.a[axis][lane] = a[axis];
            p.e0[axis][lane] = e0[axis];
            p.e1[axis][lane] = e1[axis];
            p.normal[axis][lane] = n[axis];
            for (edge, m) in m.iter().enumerate() {
                p.edge_normal[edge][axis][lane] = m[axis];
            }
        }
        p.bc_threshold[lane] = if n == Vec3A::ZERO {
            f32::INFINITY
        } else {
            e0.dot(m[1])
        };
        p.inv_len2[0][lane] = inv(e0);
        p.inv_len2[1][lane] = inv(e2);
        p.inv_len2[2][lane] = inv(e1);
        p.bc_offset[lane] = e0.length_squared() - e0.dot(e1);
        p.len2[0][lane] = e0.length_squared();
        p.len2[1][lane] = e2.length_squared();
        p.len2[2][lane] = e1.length_squared();
        p.degenerate |= n == Vec3A::ZERO;
        p.tri[lane] = i as u32;
        p.real[lane] = if first + lane < end { 1.0 } else { 0.0 };
    }
    p
}

/// A disc perpendicular to `axis` through `center`, thickened by `half_thickness`.
#[derive(Clone, Copy, Debug)]
struct Cylinder {
    center: Vec3A,
    axis: Vec3A,
    radius: f32,
    half_thickness: f32,
}

/// The bounding cylinder of binary node `node`'s triangles, padded for rounding, or
/// `None` for a big or normal-less node.
fn bounding_cylinder(bvh: &Bvh, node: usize) -> Option<Cylinder> {
    let range = bvh.triangle_range(node);
    if range.len() > CYLINDER_MAX_TRIANGLES {
        return None;
    }
    let dipole = &bvh.dipoles[node];
    let axis = dipole.normal_sum.try_normalize()?;
    let center = dipole.center;
    let (mut radius2, mut half) = (0.0f32, 0.0f32);
    for t in &bvh.tris[range] {
        for &v in t {
            let d = v - center;
            let h = d.dot(axis);
            half = half.max(h.abs());
            radius2 = radius2.max((d - h * axis).length_squared());
        }
    }
    let radius = radius2.sqrt();
    // Rounding in the build and in the query: pad by a relative 1e-5 of the scale.
    let pad = 1e-5 * (center.abs().max_element() + radius + half);
    Some(Cylinder {
        center,
        axis,
        radius: radius + pad,
        half_thickness: half + pad,
    })
}

/// Four-lane `atan2(y, x)`, absolute error below 2·10⁻⁵ rad (an odd minimax polynomial
/// for `atan` on [0, 1] and the usual octant reductions).
#[inline]
fn atan2(y: Vec4, x: Vec4) -> Vec4 {
    let (ax, ay) = (x.abs(), y.abs());
    let (hi, lo) = (ax.max(ay), ax.min(ay));
    let a = Vec4::select(hi.cmpgt(Vec4::ZERO), lo / hi, Vec4::ZERO);
    let s = a * a;
    let poly = Vec4::splat(-0.011_721_2)
        .mul_add_fallback(s, 0.052_653_32)
        .mul_add_fallback(s, -0.116_432_87)
        .mul_add_fallback(s, 0.193_543_46)
        .mul_add_fallback(s, -0.332_623_47)
        .mul_add_fallback(s, 0.999_977_26);
    let mut r = a * poly;
    r = Vec4::select(
        ay.cmpgt(ax),
        Vec4::splat(std::f32::consts::FRAC_PI_2) - r,
        r,
    );
    r = Vec4::select(
        x.cmplt(Vec4::ZERO),
        Vec4::splat(std::f32::consts::PI) - r,
        r,
    );
    Vec4::select(y.cmplt(Vec4::ZERO), -r, r)
}

/// `self · s + c` without fused multiply-add (SSE2 has none; an emulated one is slow).
trait MulAddFallback {
    fn mul_add_fallback(self, s: Vec4, c: f32) -> Vec4;
}

impl MulAddFallback for Vec4 {
    #[inline]
    fn mul_add_fallback(self, s: Vec4, c: f32) -> Vec4 {
        self * s + Vec4::splat(c)
    }
}

/// The unit normal of a triangle with edges `e0`, `e1`, computed in f64, or `None`
/// when the triangle is degenerate (its area is below 1e-6 of its edge lengths'
/// product, so its interior is within 1e-6 × its size of its edges).
fn unit_normal(e0: Vec3A, e1: Vec3A) -> Option<Vec3A> {
    let (e0, e1) = (e0.as_dvec3(), e1.as_dvec3());
    let n = e0.cross(e1);
    let area2 = n.length_squared();
    let thin = area2.partial_cmp(&(1e-12 * e0.length_squared() * e1.length_squared()));
    if thin != Some(std::cmp::Ordering::Greater) || !area2.is_finite() {
        return None;
    }
    Some((n / area2.sqrt()).as_vec3a())
}

fn half_area(min: Vec3A, max: Vec3A) -> f32 {
    let s = (max - min).max(Vec3A::ZERO);
    s.x * s.y + s.y * s.z + s.z * s.x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simd_atan2_is_accurate_in_every_octant() {
        let mut worst = 0.0f32;
        for i in -40..=40 {
            for j in -40..=40 {
                let (y, x) = (i as f32 * 0.37, j as f32 * 0.29);
                let got = atan2(Vec4::splat(y), Vec4::splat(x)).x;
                let want = if x == 0.0 && y == 0.0 {
                    0.0
                } else {
                    y.atan2(x)
                };
                worst = worst.max((got - want).abs());
            }
        }
        assert!(worst < 2e-5, "{worst}");
        assert_eq!(atan2(Vec4::ZERO, Vec4::ONE).x, 0.0);
    }

    /// The SIMD fast winding number against the exact (f64) generalized winding number,
    /// near and far, on closed, open and self-intersecting meshes.
    #[test]
    fn fast_winding_number_tracks_the_exact_one() {
        for (name, mesh) in [
            ("sphere", crate::shapes::sphere(1.0, 32, 16)),
            ("bowl", crate::shapes::open_bowl(1.0, 32, 8)),
            ("soup", crate::shapes::intersecting_soup()),
        ] {
            let (tris, _) = mesh.validate().unwrap();
            let bvh = Bvh::build(&tris);
            let mut worst = 0.0f64;
            for k in 0..400 {
                let a = k as f32 * 0.61;
                let r = 0.05 + 2.5 * ((k * 37) % 100) as f32 / 100.0;
                let p = glam::Vec3::new(a.cos() * r, (a * 1.7).sin() * r * 0.8, a.sin() * r);
                let w = bvh.winding_number(p) as f64;
                worst = worst.max((w - crate::exact::winding_number(p.as_dvec3(), &tris)).abs());
            }
            assert!(worst < 0.1, "{name}: {worst}");
        }
    }
}
