//! A bounding volume hierarchy over triangles: closest-point queries, ray queries, and
//! the fast winding number (Barill et al. 2018) on the same tree.
//!
//! Built with binned SAH (large subtrees in parallel, deterministically: the tree is the
//! same for any thread count). Triangles are copied into tree order so leaves are
//! contiguous in memory. Closest-point queries run on a 4-wide SIMD copy of the tree
//! with tighter bounds (`wide`): they are the baker's hot path.

use crate::geometry::{self, Aabb};
use glam::{Vec3, Vec3A};

mod wide;

const LEAF_SIZE: usize = 8;
/// Deepest level the build splits to; deeper nodes become (larger) leaves. Keeps the
/// fixed 64-entry traversal stacks from ever overflowing on adversarial meshes.
const MAX_DEPTH: usize = 48;
const BINS: usize = 16;
/// Fast-winding-number accuracy: a node's dipole stands in for its triangles when the
/// query is farther than `BETA ×` the node's radius from its centre (Barill et al. use 2).
const BETA: f32 = 2.0;

#[derive(Clone, Copy, Debug)]
pub(crate) struct Node {
    pub(crate) min: Vec3A,
    pub(crate) max: Vec3A,
    /// Leaf: first triangle (tree order). Interior: index of the right child (the left
    /// child is the next node).
    pub(crate) start_or_right: u32,
    /// Triangles in a leaf; 0 for interior nodes.
    pub(crate) count: u32,
}

/// Per-node data of the fast winding number: the area-weighted normal sum (first-order
/// dipole moment), its expansion centre, and the radius of a ball around the centre
/// containing every triangle of the node.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Dipole {
    pub(crate) normal_sum: Vec3A,
    pub(crate) center: Vec3A,
    radius: f32,
}

/// The result of a closest-point query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestHit {
    /// Squared distance to the closest point.
    pub distance_squared: f32,
    /// Index of the triangle in the input mesh.
    pub triangle: u32,
}

/// The BVH.
#[derive(Clone, Debug)]
pub struct Bvh {
    pub(crate) nodes: Vec<Node>,
    pub(crate) dipoles: Vec<Dipole>,
    /// Triangle corners in tree order.
    pub(crate) tris: Vec<[Vec3A; 3]>,
    /// Input index of each tree-order triangle.
    pub(crate) order: Vec<u32>,
    /// Tree-order index of each input triangle (inverse of `order`).
    inverse: Vec<u32>,
    /// The closest-point query's 4-wide SIMD layout of the same tree.
    wide: wide::WideTree,
}

struct BuildTri {
    bounds: Aabb,
    centroid: Vec3,
    index: u32,
}

impl Bvh {
    /// Builds the tree over triangles given by corner positions.
    pub fn build(tris: &[[Vec3; 3]]) -> Bvh {
        Self::build_with_max_depth(tris, MAX_DEPTH)
    }

    fn build_with_max_depth(tris: &[[Vec3; 3]], max_depth: usize) -> Bvh {
        use rayon::prelude::*;
        // Collected in parallel straight into place: megabytes, where fresh pages cost
        // a fault each.
        let mut items: Vec<BuildTri> = tris
            .par_iter()
            .enumerate()
            .map(|(i, t)| {
                let mut b = Aabb::EMPTY;
                t.iter().for_each(|&v| b.grow(v));
                BuildTri {
                    bounds: b,
                    centroid: b.center(),
                    index: i as u32,
                }
            })
            .collect();
        // A binary tree over n triangles has at most 2n − 1 nodes. Reserving them all
        // costs no page faults for the part never written, and growing the vector
        // would copy it (and fault in a fresh allocation) on the way.
        let mut nodes = Vec::with_capacity(2 * tris.len());
        if !items.is_empty() {
            let bounds = Bounds::of(&items);
            build_recursive(&mut items, bounds, 0, max_depth, &mut nodes, 0);
        }
        let order: Vec<u32> = items.iter().map(|t| t.index).collect();
        let tris: Vec<[Vec3A; 3]> = order
            .par_iter()
            .map(|&i| tris[i as usize].map(Vec3A::from))
            .collect();
        let mut inverse = vec![0u32; order.len()];
        for (tree, &input) in order.iter().enumerate() {
            inverse[input as usize] = tree as u32;
        }
        let mut bvh = Bvh {
            inverse,
            dipoles: vec![
                Dipole {
                    normal_sum: Vec3A::ZERO,
                    center: Vec3A::ZERO,
                    radius: 0.0
                };
                nodes.len()
            ],
            nodes,
            tris,
            order,
            wide: wide::WideTree::default(),
        };
        if !bvh.nodes.is_empty() {
            bvh.compute_dipoles(0);
        }
        bvh.wide = wide::WideTree::build(&bvh);
        bvh
    }

    /// The triangle range (tree order) under a node.
    pub(crate) fn triangle_range(&self, node: usize) -> std::ops::Range<usize> {
        let mut first = node;
        while self.nodes[first].count == 0 {
            first += 1; // left child
        }
        let mut last = node;
        while self.nodes[last].count == 0 {
            last = self.nodes[last].start_or_right as usize; // right child
        }
        let (f, l) = (&self.nodes[first], &self.nodes[last]);
        f.start_or_right as usize..(l.start_or_right + l.count) as usize
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    /// Bounds of all triangles (the empty box for an empty tree).
    pub fn bounds(&self) -> Aabb {
        self.nodes.first().map_or(Aabb::EMPTY, |n| Aabb {
            min: n.min.into(),
            max: n.max.into(),
        })
    }

    /// Returns (area-weighted normal sum, area-weighted centroid sum, area sum).
    fn compute_dipoles(&mut self, node: usize) -> (Vec3A, Vec3A, f32) {
        let n = self.nodes[node];
        let (normal_sum, weighted_center, area) = if n.count > 0 {
            let range = n.start_or_right as usize..(n.start_or_right + n.count) as usize;
            let mut acc = (Vec3A::ZERO, Vec3A::ZERO, 0.0);
            for t in &self.tris[range] {
                let cross = (t[1] - t[0]).cross(t[2] - t[0]);
                let a = 0.5 * cross.length();
                acc.0 += 0.5 * cross;
                acc.1 += a * (t[0] + t[1] + t[2]) / 3.0;
                acc.2 += a;
            }
            acc
        } else {
            let l = self.compute_dipoles(node + 1);
            let r = self.compute_dipoles(n.start_or_right as usize);
            (l.0 + r.0, l.1 + r.1, l.2 + r.2)
        };
        let center = if area > 0.0 {
            weighted_center / area
        } else {
            (n.min + n.max) * 0.5
        };
        // A ball around `center` containing the node's box contains its triangles.
        let radius = (n.min - center).abs().max((n.max - center).abs()).length();
        self.dipoles[node] = Dipole {
            normal_sum,
            center,
            radius,
        };
        (normal_sum, weighted_center, area)
    }

    /// The closest triangle to `p`, searching only closer than
    /// `sqrt(max_distance_squared)` (pass `f32::INFINITY` for no bound). `hints` are
    /// triangles (input indices) likely to be close, e.g. the neighbouring samples'
    /// closest triangles: they tighten the bound before the traversal starts. The
    /// returned distance does not depend on the hints (the triangle may, among exact
    /// ties).
    pub fn closest(&self, p: Vec3, max_distance_squared: f32, hints: &[u32]) -> Option<ClosestHit> {
        let hints = hints.iter().filter_map(|&h| self.tree_index_of(h));
        self.wide
            .closest(p.into(), max_distance_squared, hints, &self.order)
            .map(|(distance_squared, i)| ClosestHit {
                distance_squared,
                triangle: self.order[i],
            })
    }

    /// [`closest`](Self::closest) for four nearby points in one traversal (see
    /// `WideTree::closest4`): the same distances as four single queries. `hints[q]`:
    /// up to two input-index triangles for point `q` (`u32::MAX`: none).
    pub(crate) fn closest4(
        &self,
        p: [Vec3; 4],
        max_distance_squared: [f32; 4],
        hints: [[u32; 2]; 4],
    ) -> [Option<ClosestHit>; 4] {
        let hints = hints.map(|h| h.map(|t| self.tree_index_of(t).unwrap_or(usize::MAX)));
        self.wide
            .closest4(p.map(Vec3A::from), max_distance_squared, hints, &self.order)
            .map(|hit| {
                hit.map(|(distance_squared, i)| ClosestHit {
                    distance_squared,
                    triangle: self.order[i],
                })
            })
    }

    fn tree_index_of(&self, input_index: u32) -> Option<usize> {
        self.inverse.get(input_index as usize).map(|&i| i as usize)
    }

    /// The generalized winding number of the mesh at `q` with Barill et al.'s fast
    /// approximation: exact solid angles for nearby triangles, a first-order dipole for
    /// far clusters. ≈ 1 inside a closed outward-oriented mesh, ≈ 0 outside, fractional
    /// near holes of open meshes.
    pub fn winding_number(&self, q: Vec3) -> f32 {
        self.wide.winding_number(q.into())
    }

    /// The nearest hit of a ray within `(t_min, t_max)`: `(t, front_facing, input index)`.
    pub fn ray_nearest(
        &self,
        origin: Vec3,
        dir: Vec3,
        t_min: f32,
        t_max: f32,
    ) -> Option<(f32, bool, u32)> {
        let mut best = None;
        self.traverse_ray(origin, dir, t_min, t_max, |i, hit, t_best| {
            *t_best = hit.0;
            best = Some((hit.0, hit.1, self.order[i]));
        });
        best
    }

    /// Number of ray crossings within `(t_min, ∞)` (for parity tests).
    pub fn ray_crossings(&self, origin: Vec3, dir: Vec3, t_min: f32) -> u32 {
        let mut count = 0;
        self.traverse_ray(origin, dir, t_min, f32::INFINITY, |_, _, _| count += 1);
        count
    }

    /// The distances of every crossing of a ray within `(t_min, ∞)`, sorted.
    pub fn ray_hit_distances(&self, origin: Vec3, dir: Vec3, t_min: f32) -> Vec<f32> {
        let mut hits = Vec::new();
        self.traverse_ray(origin, dir, t_min, f32::INFINITY, |_, hit, _| {
            hits.push(hit.0);
        });
        hits.sort_by(f32::total_cmp);
        hits
    }

    /// Calls `on_hit(tree index, (t, front_facing), &mut t_max)` for every triangle the
    /// ray hits within `(t_min, t_max)`; the callback may shrink `t_max`.
    fn traverse_ray(
        &self,
        origin: Vec3,
        dir: Vec3,
        t_min: f32,
        mut t_max: f32,
        mut on_hit: impl FnMut(usize, (f32, bool), &mut f32),
    ) {
        if self.nodes.is_empty() {
            return;
        }
        let (origin, dir) = (Vec3A::from(origin), Vec3A::from(dir));
        let inv = dir.recip();
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let index = stack[top] as usize;
            let node = &self.nodes[index];
            if !hit_box(node, origin, inv, t_min, t_max) {
                continue;
            }
            if node.count > 0 {
                let start = node.start_or_right as usize;
                for i in start..start + node.count as usize {
                    if let Some(hit) =
                        geometry::ray_triangle_a(origin, dir, self.tris[i], t_min, t_max)
                    {
                        on_hit(i, hit, &mut t_max);
                    }
                }
            } else if top + 2 <= stack.len() {
                stack[top] = index as u32 + 1;
                stack[top + 1] = node.start_or_right;
                top += 2;
            }
        }
    }
}

/// Ray slab test against a node's box within `(t_min, t_max)`.
#[inline]
fn hit_box(node: &Node, origin: Vec3A, inv_dir: Vec3A, t_min: f32, t_max: f32) -> bool {
    let t0 = (node.min - origin) * inv_dir;
    let t1 = (node.max - origin) * inv_dir;
    let near = t0.min(t1).max_element().max(t_min);
    let far = t0.max(t1).min_element().min(t_max);
    near <= far
}

/// Subtrees with more triangles than this build their halves in parallel.
const PARALLEL_BUILD: usize = 4096;

/// Nodes with more triangles than this bin them in parallel chunks of this size.
const PARALLEL_BIN: usize = 16384;

/// The bounds of a set of build triangles and of their centroids.
#[derive(Clone, Copy, Debug)]
struct Bounds {
    tris: Aabb,
    centroids: Aabb,
}

impl Bounds {
    const EMPTY: Bounds = Bounds {
        tris: Aabb::EMPTY,
        centroids: Aabb::EMPTY,
    };

    fn of(items: &[BuildTri]) -> Bounds {
        let one = |items: &[BuildTri]| {
            items.iter().fold(Bounds::EMPTY, |b, t| Bounds {
                tris: b.tris.union(&t.bounds),
                centroids: b.centroids.union(&Aabb {
                    min: t.centroid,
                    max: t.centroid,
                }),
            })
        };
        if items.len() > PARALLEL_BIN {
            use rayon::prelude::*;
            // Exact min/max: the same result in any grouping.
            items
                .par_chunks(PARALLEL_BIN)
                .map(one)
                .reduce(|| Bounds::EMPTY, |a, b| a.union(&b))
        } else {
            one(items)
        }
    }

    fn union(&self, o: &Bounds) -> Bounds {
        Bounds {
            tris: self.tris.union(&o.tris),
            centroids: self.centroids.union(&o.centroids),
        }
    }
}

/// `depth_left`: levels still allowed below this node (0: make a leaf). `bounds`: the
/// items' bounds (passed down from the parent's binning, so each node reads its items
/// only twice: to bin them and to partition them). Appends the subtree in depth-first
/// order (node indices relative to `nodes`' length on entry plus `base`) and returns its
/// root's index. Large subtrees build their right half on another thread into a separate
/// vector that is appended afterwards, so the result is the same for any thread count.
fn build_recursive(
    items: &mut [BuildTri],
    bounds: Bounds,
    offset: usize,
    depth_left: usize,
    nodes: &mut Vec<Node>,
    base: usize,
) -> usize {
    let index = base + nodes.len();
    nodes.push(Node {
        min: bounds.tris.min.into(),
        max: bounds.tris.max.into(),
        start_or_right: offset as u32,
        count: items.len() as u32,
    });
    if items.len() <= LEAF_SIZE || depth_left == 0 {
        return index;
    }
    let Some((split, left_bounds, right_bounds)) = sah_split(items, &bounds.centroids) else {
        return index; // no useful split (all centroids equal, or SAH prefers a leaf)
    };
    let parallel = items.len() > PARALLEL_BUILD;
    let (left, right) = items.split_at_mut(split);
    let right_index = if parallel {
        let mut right_nodes = Vec::with_capacity(2 * right.len());
        // The right subtree's indices start after the left subtree, unknown until it is
        // built: build it relative to 0 and shift it on appending.
        rayon::join(
            || build_recursive(left, left_bounds, offset, depth_left - 1, nodes, base),
            || {
                let r = offset + split;
                build_recursive(right, right_bounds, r, depth_left - 1, &mut right_nodes, 0)
            },
        );
        let shift = (base + nodes.len()) as u32;
        for n in &mut right_nodes {
            if n.count == 0 {
                n.start_or_right += shift;
            }
        }
        nodes.append(&mut right_nodes);
        shift as usize
    } else {
        build_recursive(left, left_bounds, offset, depth_left - 1, nodes, base);
        let r = offset + split;
        build_recursive(right, right_bounds, r, depth_left - 1, nodes, base)
    };
    let local = index - base;
    nodes[local].start_or_right = right_index as u32;
    nodes[local].count = 0;
    index
}

/// Binned-SAH bins: each bin's triangle and centroid bounds and count.
#[derive(Clone, Copy)]
struct Bins {
    bounds: [Bounds; BINS],
    counts: [usize; BINS],
}

impl Bins {
    const EMPTY: Bins = Bins {
        bounds: [Bounds::EMPTY; BINS],
        counts: [0; BINS],
    };
}

/// Partitions `items` (whose centroids lie in `centroids`) by the best binned-SAH plane
/// and returns the split position and the two sides' bounds, or `None` when a leaf is
/// cheaper or no plane separates the centroids.
fn sah_split(items: &mut [BuildTri], centroids: &Aabb) -> Option<(usize, Bounds, Bounds)> {
    let extent = centroids.size();
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let (lo, span) = (centroids.min[axis], extent[axis]);
    if span <= 0.0 || !span.is_finite() {
        // All centroids coincide: split in the middle if the node is too big for a leaf.
        if items.len() <= 4 * LEAF_SIZE {
            return None;
        }
        let half = items.len() / 2;
        let (left, right) = items.split_at(half);
        return Some((half, Bounds::of(left), Bounds::of(right)));
    }
    // A multiply and an i32 conversion (not a divide and a saturating usize one): this
    // closure runs twice per triangle per tree level.
    let scale = BINS as f32 / span;
    let bin_of = |c: Vec3| {
        let x = match axis {
            0 => c.x,
            1 => c.y,
            _ => c.z,
        };
        (((x - lo) * scale) as i32).clamp(0, BINS as i32 - 1) as usize
    };
    let fill = |items: &[BuildTri]| {
        let mut bins = Bins::EMPTY;
        for t in items {
            let b = bin_of(t.centroid);
            let bin = &mut bins.bounds[b];
            bin.tris = bin.tris.union(&t.bounds);
            bin.centroids.grow(t.centroid);
            bins.counts[b] += 1;
        }
        bins
    };
    let bins = if items.len() > PARALLEL_BIN {
        use rayon::prelude::*;
        // Exact min/max and integer counts: the same bins in any grouping.
        items.par_chunks(PARALLEL_BIN).map(fill).reduce(
            || Bins::EMPTY,
            |mut a, b| {
                for i in 0..BINS {
                    a.bounds[i] = a.bounds[i].union(&b.bounds[i]);
                    a.counts[i] += b.counts[i];
                }
                a
            },
        )
    } else {
        fill(items)
    };
    // Sweep: cost of splitting after bin i.
    let mut left = [Bounds::EMPTY; BINS];
    let mut left_count = [0usize; BINS];
    let (mut acc_b, mut acc_n) = (Bounds::EMPTY, 0);
    for i in 0..BINS {
        acc_b = acc_b.union(&bins.bounds[i]);
        acc_n += bins.counts[i];
        left[i] = acc_b;
        left_count[i] = acc_n;
    }
    let mut best: Option<(f32, usize, Bounds)> = None;
    let (mut acc_b, mut acc_n) = (Bounds::EMPTY, 0);
    for i in (1..BINS).rev() {
        acc_b = acc_b.union(&bins.bounds[i]);
        acc_n += bins.counts[i];
        let cost = left[i - 1].tris.half_area() * left_count[i - 1] as f32
            + acc_b.tris.half_area() * acc_n as f32;
        if left_count[i - 1] > 0 && acc_n > 0 && best.is_none_or(|(c, _, _)| cost < c) {
            best = Some((cost, i, acc_b));
        }
    }
    let (_, split_bin, right_bounds) = best?;
    // In-place partition (deterministic: a fixed sequence of swaps).
    let mut split = 0;
    for i in 0..items.len() {
        if bin_of(items[i].centroid) < split_bin {
            items.swap(i, split);
            split += 1;
        }
    }
    (split > 0 && split < items.len()).then_some((split, left[split_bin - 1], right_bounds))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::exact;

    fn depth(bvh: &Bvh) -> usize {
        let mut max = 0;
        let mut stack = vec![(0usize, 1usize)];
        while let Some((n, d)) = stack.pop() {
            max = max.max(d);
            if bvh.nodes[n].count == 0 {
                stack.push((n + 1, d + 1));
                stack.push((bvh.nodes[n].start_or_right as usize, d + 1));
            }
        }
        max
    }

    /// The depth cap (which keeps the fixed 64-entry traversal stacks from overflowing on
    /// adversarial meshes) holds, and capped trees, with their larger leaves, stay exact.
    #[test]
    fn depth_is_capped_and_capped_trees_stay_exact() {
        let m = crate::shapes::sphere(1.0, 64, 32);
        let (tris, _) = m.validate().unwrap();
        assert!(depth(&Bvh::build(&tris)) > 5);
        let capped = Bvh::build_with_max_depth(&tris, 3);
        assert!(depth(&capped) <= 4, "depth {}", depth(&capped));
        for k in 0..100 {
            let a = k as f32 * 0.7;
            let p = Vec3::new(a.cos() * 1.3, (a * 0.3).sin(), a.sin() * 0.4);
            let got = capped
                .closest(p, f32::INFINITY, &[])
                .unwrap()
                .distance_squared
                .sqrt();
            let want = exact::distance(p.as_dvec3(), &tris);
            assert!((got as f64 - want).abs() <= 1e-5, "{p}: {got} vs {want}");
            let w = capped.winding_number(p) as f64;
            assert!(
                (w - exact::winding_number(p.as_dvec3(), &tris)).abs() < 0.05,
                "{p}: {w}"
            );
        }
    }

    /// Triangles that pass validation but are nearly degenerate: slivers with a vertex
    /// 1e-9 off the line of the other two, and needles.
    fn slivers() -> Vec<[Vec3; 3]> {
        (0..40)
            .map(|k| {
                let a = k as f32 * 0.37;
                let base = Vec3::new(a.cos(), (a * 1.7).sin() * 0.5, a.sin());
                let dir = Vec3::new((a * 2.3).sin(), (a * 0.7).cos(), 0.3).normalize();
                let off = if k % 2 == 0 {
                    dir.cross(Vec3::Z).normalize_or(Vec3::X) * 1e-9
                } else {
                    Vec3::new(1e-6, 0.0, 0.0)
                };
                [base, base + dir * 0.5, base + dir * 0.25 + off]
            })
            .collect()
    }

    /// The SIMD closest-point query (4-wide tree, box and cylinder bounds, triangle
    /// packets) equals f64 brute force near and far from surfaces of every kind, with
    /// and without (possibly misleading) hints.
    /// A deterministic uniform generator on [0, 1) (LCG, top 24 bits).
    fn uniform(seed: u64) -> impl FnMut() -> f32 {
        let mut s = seed;
        move || {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (s >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    /// Four queries in one traversal give exactly the four single queries' distances:
    /// clustered points (as the baker sends), scattered ones, one far from the rest,
    /// bounds that are tight, loose or too small (no hit), and hints.
    #[test]
    fn closest4_equals_four_single_queries() {
        let tris = crate::shapes::torus(1.0, 0.3, 40, 16).validate().unwrap().0;
        let bvh = Bvh::build(&tris);
        let mut next = uniform(7);
        let mut checked = 0;
        for k in 0..3000 {
            let spread = [0.01, 0.3, 3.0][k % 3];
            let base = Vec3::new(next(), next(), next()) * 3.0 - 1.5;
            let p: [Vec3; 4] = std::array::from_fn(|q| {
                let offset = Vec3::new(next(), next(), next()) - 0.5;
                base + offset * spread * if q == 3 && k % 5 == 0 { 10.0 } else { 1.0 }
            });
            let single = p.map(|p| bvh.closest(p, f32::INFINITY, &[]).unwrap());
            let bound: [f32; 4] = std::array::from_fn(|q| {
                let d2 = single[q].distance_squared;
                [f32::INFINITY, d2 * 1.01 + 1e-9, d2 * 0.5][(k + q) % 3]
            });
            let mut hint = || (next() * tris.len() as f32) as u32 % tris.len() as u32;
            let hints: [[u32; 2]; 4] = std::array::from_fn(|q| match (k + q) % 4 {
                0 => [u32::MAX; 2],
                1 => [single[q].triangle, u32::MAX],
                _ => [hint(), single[(q + 1) % 4].triangle],
            });
            let four = bvh.closest4(p, bound, hints);
            for q in 0..4 {
                let want = (single[q].distance_squared <= bound[q]).then_some(single[q]);
                match (four[q], want) {
                    (Some(got), Some(want)) => {
                        assert_eq!(got.distance_squared, want.distance_squared, "{k} {q}");
                        checked += 1;
                    }
                    (None, None) => {}
                    (got, want) => panic!("{k} {q}: {got:?} vs {want:?}"),
                }
            }
        }
        assert!(checked > 6000, "{checked}");
    }

    #[test]
    fn closest_matches_brute_force_near_and_far() {
        let mut cases: Vec<(&str, Vec<[Vec3; 3]>)> = [
            ("sphere", crate::shapes::sphere(1.0, 48, 24)),
            ("torus", crate::shapes::torus(1.0, 0.3, 40, 16)),
            ("thin plate", crate::shapes::thin_plate(1.0, 0.7, 0.001)),
            ("open bowl", crate::shapes::open_bowl(1.0, 32, 8)),
            ("soup", crate::shapes::intersecting_soup()),
        ]
        .into_iter()
        .map(|(name, m)| (name, m.validate().unwrap().0))
        .collect();
        cases.push(("slivers", slivers()));
        let mut next = uniform(99);
        for (name, tris) in cases {
            let bvh = Bvh::build(&tris);
            for k in 0..2000 {
                // Scales from 1e-3 (on the surface) to 4 (far outside).
                let scale = 10f32.powf(-3.0 + 3.6 * next());
                let p = Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * 2.0 * scale
                    + tris[k % tris.len()][0];
                let hint = [(next() * tris.len() as f32) as u32 % tris.len() as u32];
                let hints: &[u32] = if k % 3 == 0 { &[] } else { &hint };
                let got = bvh
                    .closest(p, f32::INFINITY, hints)
                    .unwrap()
                    .distance_squared
                    .sqrt() as f64;
                let want = exact::distance(p.as_dvec3(), &tris);
                assert!(
                    (got - want).abs() <= 2e-6 * (1.0 + want) + 1e-6 * want.max(1e-3),
                    "{name} {p}: {got} vs {want}"
                );
            }
        }
    }
}
