//! The volume fit: capsules that best cover the solid a joint skins.
//!
//! The bind-pose mesh is sampled on a grid ([`SolidSamples::new`]): each cell centre is
//! inside or outside the solid by the signed count of the triangles a ray along +z
//! crosses below it (the winding number along one axis; a mesh that is not closed reads
//! as what its crossings enclose), and each inside cell belongs to the joint of the
//! nearest vertex in grid steps (a breadth-first flood from the cells holding vertices).
//! A joint's capsule then minimises the volume it gets wrong: its own inside cells left
//! out plus outside cells taken in ([`fit_volume_along`]). Cells inside the solid but
//! skinned to other joints cost nothing either way (the union of capsules covers them).
//! What a joint's capsule leaves out and no other joint's capsule holds, in pieces
//! connected through cell faces, may get capsules of its own ([`piece_capsules`]): a
//! capsule per joint cannot hold two ears, or a paw bent from its leg.
//!
//! This is the quantity a shadow sees (the caster's occupied space), where the vertex
//! fit counts vertices, which crowd where a mesh is finely tessellated (a face, paws)
//! and are sparse on a flat flank.

use super::FittedCapsule;
use glam::{Mat4, Vec3};
use std::collections::VecDeque;

/// A joint needs this many inside samples for the volume fit (else its vertices fit).
pub(super) const MIN_INSIDE_SAMPLES: usize = 8;

/// Cells along the bind-pose box's longest side.
pub(super) const CELLS_ALONG_LONGEST: usize = 96;

/// The grid over the bind-pose mesh: which cells are inside the solid, and the cells
/// each joint owns.
pub(super) struct SolidSamples {
    /// The grid's lower corner (mesh space), its cell size and cells per axis.
    origin: Vec3,
    cell: f32,
    dims: [usize; 3],
    /// Per cell (x fastest): inside the solid.
    inside: Vec<bool>,
    /// Per joint: the inside cells it owns (indices).
    owned: Vec<Vec<usize>>,
}

impl SolidSamples {
    fn centre(&self, i: usize) -> Vec3 {
        let [nx, ny, _] = self.dims;
        let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
        self.origin + (Vec3::new(x as f32, y as f32, z as f32) + 0.5) * self.cell
    }

    /// Samples the solid the `triangles` over `positions` enclose; `owner[v]` is vertex
    /// `v`'s dominant joint. `None` when no triangle is usable or nothing is inside.
    pub(super) fn new(
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        owner: &[Option<usize>],
    ) -> Option<SolidSamples> {
        let corners = |t: &[u32; 3]| -> Option<[Vec3; 3]> {
            let p = t.map(|i| positions.get(i as usize).copied());
            let p = [p[0]?, p[1]?, p[2]?];
            p.iter().all(|v| v.is_finite()).then_some(p)
        };
        let tris: Vec<[Vec3; 3]> = triangles.iter().filter_map(corners).collect();
        let (lo, hi) = tris
            .iter()
            .flatten()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(*p), hi.max(*p))
            });
        let extent = (hi - lo).max_element();
        if tris.is_empty() || !extent.is_finite() || extent <= 0.0 {
            return None;
        }
        let cell = extent / CELLS_ALONG_LONGEST as f32;
        if !cell.is_normal() {
            return None; // a mesh too small for f32 cells
        }
        // One cell of margin on every side: the outside around the mesh is sampled too.
        let origin = lo - Vec3::splat(cell);
        let dims = ((hi - lo) / cell)
            .ceil()
            .min(Vec3::splat(CELLS_ALONG_LONGEST as f32))
            .as_uvec3()
            + glam::UVec3::splat(3);
        let [nx, ny, nz] = dims.to_array().map(|d| d as usize);
        let centre = |x: usize, y: usize, z: usize| {
            origin + (Vec3::new(x as f32, y as f32, z as f32) + 0.5) * cell
        };
        let index = |x: usize, y: usize, z: usize| (z * ny + y) * nx + x;

        // Crossings of each column's ray (+z), binned by the triangles' xy boxes.
        let mut crossings: Vec<Vec<(f32, i32)>> = vec![Vec::new(); nx * ny];
        // A column sits a little off the cell centre so that it misses shared edges.
        let jitter = Vec3::new(0.000_37, 0.000_61, 0.0) * cell;
        for t in &tris {
            let tlo = t[0].min(t[1]).min(t[2]);
            let thi = t[0].max(t[1]).max(t[2]);
            let x0 = (((tlo.x - origin.x) / cell - 0.5).floor().max(0.0)) as usize;
            let y0 = (((tlo.y - origin.y) / cell - 0.5).floor().max(0.0)) as usize;
            let x1 = (((thi.x - origin.x) / cell - 0.5).ceil() as usize).min(nx - 1);
            let y1 = (((thi.y - origin.y) / cell - 0.5).ceil() as usize).min(ny - 1);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let c = centre(x, y, 0) + jitter;
                    if let Some(hit) = column_crossing(t, c.x, c.y) {
                        crossings[y * nx + x].push(hit);
                    }
                }
            }
        }
        let mut inside = vec![false; nx * ny * nz];
        for y in 0..ny {
            for x in 0..nx {
                let column = &mut crossings[y * nx + x];
                column.sort_by(|a, b| a.0.total_cmp(&b.0));
                let (mut k, mut winding) = (0, 0);
                for z in 0..nz {
                    let cz = centre(x, y, z).z;
                    while k < column.len() && column[k].0 < cz {
                        winding += column[k].1;
                        k += 1;
                    }
                    inside[index(x, y, z)] = winding > 0;
                }
            }
        }
        if !inside.iter().any(|&i| i) {
            return None;
        }

        // Joints: each cell takes the joint of the first vertex seeded into it (vertex
        // order), then a breadth-first flood gives every cell its nearest seed's.
        let mut joint = vec![usize::MAX; nx * ny * nz];
        let mut queue = VecDeque::new();
        for (v, p) in positions.iter().enumerate() {
            let Some(Some(j)) = owner.get(v) else {
                continue;
            };
            if !p.is_finite() {
                continue;
            }
            let g = ((*p - origin) / cell).floor();
            if g.cmplt(Vec3::ZERO).any() {
                continue; // a vertex no triangle uses, off the grid
            }
            let (x, y, z) = (g.x as usize, g.y as usize, g.z as usize);
            if x < nx && y < ny && z < nz && joint[index(x, y, z)] == usize::MAX {
                joint[index(x, y, z)] = *j;
                queue.push_back((x, y, z));
            }
        }
        while let Some((x, y, z)) = queue.pop_front() {
            let j = joint[index(x, y, z)];
            let steps = [
                (x.wrapping_sub(1), y, z),
                (x + 1, y, z),
                (x, y.wrapping_sub(1), z),
                (x, y + 1, z),
                (x, y, z.wrapping_sub(1)),
                (x, y, z + 1),
            ];
            for (a, b, c) in steps {
                if a < nx && b < ny && c < nz && joint[index(a, b, c)] == usize::MAX {
                    joint[index(a, b, c)] = j;
                    queue.push_back((a, b, c));
                }
            }
        }
        let joints = owner.iter().flatten().map(|j| j + 1).max().unwrap_or(0);
        let mut owned = vec![Vec::new(); joints];
        for (i, (&j, &is_inside)) in joint.iter().zip(&inside).enumerate() {
            if is_inside && j != usize::MAX {
                owned[j].push(i);
            }
        }
        Some(SolidSamples {
            origin,
            cell,
            dims: [nx, ny, nz],
            inside,
            owned,
        })
    }
}

/// Where the ray from `(x, y, −∞)` along +z crosses triangle `t`: its z and +1 when it
/// enters the solid there (the face looks down, −z), −1 when it leaves.
fn column_crossing(t: &[Vec3; 3], x: f32, y: f32) -> Option<(f32, i32)> {
    let edge = |a: Vec3, b: Vec3| (b.x - a.x) * (y - a.y) - (b.y - a.y) * (x - a.x);
    let w0 = edge(t[1], t[2]);
    let w1 = edge(t[2], t[0]);
    let w2 = edge(t[0], t[1]);
    let area = w0 + w1 + w2;
    let same = (w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0) || (w0 <= 0.0 && w1 <= 0.0 && w2 <= 0.0);
    if !same || area.abs() <= f32::EPSILON * 16.0 * (t[1] - t[0]).length_squared() {
        return None;
    }
    let z = (w0 * t[0].z + w1 * t[1].z + w2 * t[2].z) / area;
    // Counter-clockwise seen from +z (area > 0): the face looks up, the ray leaves.
    Some((z, if area > 0.0 { -1 } else { 1 }))
}

/// A joint's samples in its space: its own inside cells, and the outside cells near
/// them (those within the inside cells' bounding sphere, grown by half its radius).
pub(super) struct JointSamples {
    pub(super) inside: Vec<Vec3>,
    pub(super) outside: Vec<Vec3>,
    /// The grid cell of each inside sample, and the grid's cells per axis.
    cells: Vec<usize>,
    dims: [usize; 3],
}

impl JointSamples {
    pub(super) fn new(samples: &SolidSamples, joint: usize, to_joint: Mat4) -> JointSamples {
        let own_cells = samples.owned.get(joint).map_or(&[][..], Vec::as_slice);
        let own: Vec<Vec3> = own_cells.iter().map(|&i| samples.centre(i)).collect();
        let (inside, cells): (Vec<Vec3>, Vec<usize>) = own
            .iter()
            .zip(own_cells)
            .map(|(p, &i)| (to_joint.transform_point3(*p), i))
            .filter(|(p, _)| p.is_finite())
            .unzip();
        if own.is_empty() {
            return JointSamples {
                inside,
                outside: Vec::new(),
                cells,
                dims: samples.dims,
            };
        }
        let centre = own.iter().copied().sum::<Vec3>() / own.len() as f32;
        let reach = own.iter().map(|p| p.distance(centre)).fold(0.0, f32::max) * 1.5;
        // The cells of the box around that sphere, then those within it.
        let [nx, ny, nz] = samples.dims;
        let cell_of =
            |v: f32, o: f32, n: usize| (((v - o) / samples.cell).max(0.0) as usize).min(n - 1);
        let lo = centre - Vec3::splat(reach);
        let hi = centre + Vec3::splat(reach);
        let mut outside = Vec::new();
        for z in cell_of(lo.z, samples.origin.z, nz)..=cell_of(hi.z, samples.origin.z, nz) {
            for y in cell_of(lo.y, samples.origin.y, ny)..=cell_of(hi.y, samples.origin.y, ny) {
                for x in cell_of(lo.x, samples.origin.x, nx)..=cell_of(hi.x, samples.origin.x, nx) {
                    let i = (z * ny + y) * nx + x;
                    if samples.inside[i] {
                        continue;
                    }
                    let p = samples.centre(i);
                    if p.distance(centre) <= reach {
                        let q = to_joint.transform_point3(p);
                        if q.is_finite() {
                            outside.push(q);
                        }
                    }
                }
            }
        }
        JointSamples {
            inside,
            outside,
            cells,
            dims: samples.dims,
        }
    }
}

/// A joint's first capsule: along the best of `axes` and the inside samples' principal
/// axis, the one that gets the least volume wrong (ties to the smaller).
pub(super) fn first_capsule(
    samples: &JointSamples,
    axes: Vec<Vec3>,
    joint: usize,
) -> Option<FittedCapsule> {
    best_capsule(&samples.inside, &samples.outside, axes, joint)
}

/// The capsules for what a joint's `first` capsule leaves out: its cells outside it and
/// not `covered` by another joint's first capsule (`covered` takes a point in this
/// joint's space), in pieces connected through cell faces (an ear each, a snout). Each
/// piece of at least [`MIN_PIECE`] of the joint's cells gets a capsule of its own where
/// that capsule gets less than [`PIECE_WRONG`] of what leaving the piece out does wrong
/// (the largest pieces first, at most [`MAX_PIECES`]).
pub(super) fn piece_capsules(
    samples: &JointSamples,
    first: &FittedCapsule,
    joint: usize,
    covered: impl Fn(Vec3) -> bool,
) -> Vec<FittedCapsule> {
    let left: Vec<usize> = (0..samples.inside.len())
        .filter(|&i| first.distance(samples.inside[i]) > 0.0 && !covered(samples.inside[i]))
        .collect();
    let min_piece = MIN_INSIDE_SAMPLES.max((MIN_PIECE * samples.inside.len() as f32) as usize);
    let mut pieces = pieces(&left, &samples.cells, samples.dims);
    pieces.retain(|p| p.len() >= min_piece);
    pieces.sort_by_key(|p| std::cmp::Reverse(p.len()));
    let mut out = Vec::new();
    for piece in pieces.into_iter().take(MAX_PIECES) {
        let points: Vec<Vec3> = piece.iter().map(|&i| samples.inside[i]).collect();
        let Some(capsule) = best_capsule(&points, &samples.outside, Vec::new(), joint) else {
            continue;
        };
        let missed = points
            .iter()
            .filter(|p| capsule.distance(**p) > 0.0)
            .count();
        let taken = samples
            .outside
            .iter()
            .filter(|p| capsule.distance(**p) <= 0.0)
            .count();
        let wrong = MISSED_WEIGHT * missed as f32 + taken as f32;
        if wrong < PIECE_WRONG * MISSED_WEIGHT * points.len() as f32 {
            out.push(capsule);
        }
    }
    out
}

/// A piece left out must hold this share of its joint's cells (and 8) to be fitted.
const MIN_PIECE: f32 = 0.02;
/// At most this many pieces of a joint get capsules, and a piece's capsule must get
/// less than this share of what leaving it out gets wrong. On the Fox over four poses
/// (capsules; mean error on shadowed pixels at rest / Survey / Walk / Run; their mean):
/// no pieces 20, 0.113 / 0.082 / 0.120 / 0.144, 0.115; one at 0.3: 25, 0.094; one at
/// 0.5: 27, 0.093; two at 0.3: 28, 0.092; two at 0.5: 30, 0.090; **three at 0.5: 31,
/// 0.079 / 0.064 / 0.081 / 0.109, 0.083** (four at 0.5 and three at 0.7 the same);
/// two at 0.2: 21, 0.114.
const MAX_PIECES: usize = 3;
const PIECE_WRONG: f32 = 0.5;

/// The capsule over `inside` (along `axes` and their principal axis) that gets the
/// least volume wrong against `outside`; ties to the smaller.
fn best_capsule(
    inside: &[Vec3],
    outside: &[Vec3],
    mut axes: Vec<Vec3>,
    joint: usize,
) -> Option<FittedCapsule> {
    axes.push(super::principal_axis(inside));
    axes.into_iter()
        .filter_map(|axis| {
            let (cost, center, half_length, radius) = fit_volume_along(inside, outside, axis)?;
            let capsule = FittedCapsule {
                joint,
                center,
                axis: axis.normalize(),
                half_length,
                radius,
                vertices: 0,
                covered: 0.0,
            };
            Some((cost, capsule))
        })
        .min_by(|a, b| {
            a.0.total_cmp(&b.0)
                .then(a.1.volume().total_cmp(&b.1.volume()))
        })
        .map(|(_, capsule)| capsule)
}

/// The `members` (indices into `cells`) in pieces connected through cell faces, each
/// sorted; pieces in the order of their first member in `members`.
fn pieces(members: &[usize], cells: &[usize], dims: [usize; 3]) -> Vec<Vec<usize>> {
    let [nx, ny, nz] = dims;
    let at: std::collections::HashMap<usize, usize> =
        members.iter().map(|&m| (cells[m], m)).collect();
    let mut seen = std::collections::HashSet::new();
    let mut out = Vec::new();
    for &start in members {
        if !seen.insert(start) {
            continue;
        }
        let mut piece = vec![start];
        let mut k = 0;
        while k < piece.len() {
            let c = cells[piece[k]];
            let (x, y, z) = (c % nx, (c / nx) % ny, c / (nx * ny));
            let mut near = Vec::with_capacity(6);
            if x > 0 {
                near.push(c - 1);
            }
            if x + 1 < nx {
                near.push(c + 1);
            }
            if y > 0 {
                near.push(c - nx);
            }
            if y + 1 < ny {
                near.push(c + nx);
            }
            if z > 0 {
                near.push(c - nx * ny);
            }
            if z + 1 < nz {
                near.push(c + nx * ny);
            }
            for n in near {
                if let Some(&m) = at.get(&n)
                    && seen.insert(m)
                {
                    piece.push(m);
                }
            }
            k += 1;
        }
        piece.sort_unstable();
        out.push(piece);
    }
    out
}

/// What a joint's inside sample left out costs, against 1 for an outside sample taken
/// in. Left-out space loses a shadow that rays see; taken-in space is mostly beside the
/// mesh, within a penumbra. 2 gave the least shadow error on the Fox over four poses
/// (mean error on shadowed pixels, rest / Survey / Walk / Run: 0.119 / 0.096 / 0.127 /
/// 0.159 at 1, 0.114 / 0.087 / 0.124 / 0.149 at 1.5, 0.113 / 0.082 / 0.120 / 0.144 at
/// 2, 0.113 / 0.085 / 0.117 / 0.148 at 3, 0.118 / 0.093 / 0.132 / 0.164 at 4).
const MISSED_WEIGHT: f32 = 2.0;

/// Radii tried per axis: these quantiles of the inside samples' distances from it.
const RADIUS_QUANTILES: usize = 24;

/// The capsule along `axis` through the inside samples' centroid that gets the least
/// volume wrong (inside samples left out + outside samples taken in; ties to the
/// smaller capsule), with its cost in samples. `None` for a degenerate axis or no
/// inside sample.
///
/// With the core segment `[t0, t1]` holding the centroid (`t0 ≤ 0 ≤ t1`), a sample at
/// axial `t < 0` and radial `r ≤ R` is inside exactly when `t0 ≤ t + √(R² − r²)`, and
/// one at `t ≥ 0` when `t1 ≥ t − √(R² − r²)`: for each radius the two ends are chosen
/// apart, each by a sweep over its side's binned keys.
fn fit_volume_along(
    inside: &[Vec3],
    outside: &[Vec3],
    axis: Vec3,
) -> Option<(f32, Vec3, f32, f32)> {
    let axis = axis.try_normalize()?;
    if inside.is_empty() {
        return None;
    }
    let centroid = inside.iter().copied().sum::<Vec3>() / inside.len() as f32;
    let polar = |p: &Vec3| {
        let d = *p - centroid;
        let t = d.dot(axis);
        (t, (d - t * axis).length())
    };
    // Each sample with what taking it in changes the cost by; a large joint's samples
    // are thinned to every k-th, each counting k.
    let thinned = |points: &[Vec3], gain: f32| -> Vec<Polar> {
        let k = points.len().div_ceil(MAX_SAMPLES_PER_SIDE).max(1);
        points
            .iter()
            .step_by(k)
            .map(|p| {
                let (t, r) = polar(p);
                Polar {
                    t,
                    r,
                    gain: gain * k as f32,
                }
            })
            .collect()
    };
    let mut polars = thinned(inside, -MISSED_WEIGHT);
    polars.extend(thinned(outside, 1.0));
    let mut radial: Vec<f32> = inside.iter().map(|p| polar(p).1).collect();
    radial.sort_by(f32::total_cmp);
    let span = polars.iter().map(|p| p.t.abs()).fold(0.0, f32::max);
    let mut best: Option<(f32, f32, f32, f32, f32)> = None; // cost, volume, R, t0, t1
    for k in 1..=RADIUS_QUANTILES {
        let q = k as f32 / RADIUS_QUANTILES as f32;
        let radius =
            radial[((q * (radial.len() - 1) as f32).round() as usize).min(radial.len() - 1)];
        if radius.is_nan() || radius <= 0.0 {
            continue;
        }
        let missed: f32 = polars
            .iter()
            .filter(|p| p.gain < 0.0 && p.r > radius)
            .map(|p| -p.gain)
            .sum();
        let (low_cost, t0) = best_end(&polars, radius, span, true);
        let (high_cost, t1) = best_end(&polars, radius, span, false);
        let cost = missed + low_cost + high_cost;
        let volume = super::capsule_volume(radius, 0.5 * (t1 - t0));
        if best.is_none_or(|(c, v, ..)| cost < c || (cost == c && volume < v)) {
            best = Some((cost, volume, radius, t0, t1));
        }
    }
    let (cost, _, radius, t0, t1) = best?;
    Some((
        cost,
        centroid + 0.5 * (t0 + t1) * axis,
        0.5 * (t1 - t0),
        radius,
    ))
}

/// A sample in the axis's cylindrical coordinates about the centroid, and what taking
/// it into the capsule changes the cost by (negative for the joint's own).
struct Polar {
    t: f32,
    r: f32,
    gain: f32,
}

/// Samples a joint's fit weighs on each side (inside, outside) before thinning.
const MAX_SAMPLES_PER_SIDE: usize = 4096;

/// Bins of the sweep over the segment's end (the samples lie on a grid: a bin is far
/// finer than a cell for any joint of a few cells).
const END_BINS: usize = 512;

/// The best end of the segment on one side (`low`: `t < 0`, the end `t0 ≤ 0`; else
/// `t ≥ 0`, the end `t1 ≥ 0`) for radius `radius`: its cost (own samples of that side
/// within the radius left out, outside ones taken in) and the end. `span` bounds the
/// samples' `|t|`.
///
/// A sample is taken in when the end reaches its key (`−(t + h)` or `t − h`, at least
/// 0, `h = √(R² − r²)`): the keys are binned (bin 0: key 0, taken in by any end) and
/// swept outwards, each bin remembering its largest key, so no sort is needed.
fn best_end(polars: &[Polar], radius: f32, span: f32, low: bool) -> (f32, f32) {
    let mut gain = [0.0f32; END_BINS];
    let mut reach = [0.0f32; END_BINS];
    let mut cost = 0.0;
    let scale = (END_BINS - 1) as f32 / span.max(f32::MIN_POSITIVE);
    for p in polars {
        if p.r > radius || (p.t < 0.0) != low {
            continue;
        }
        if p.gain < 0.0 {
            cost -= p.gain; // left out until taken in
        }
        let h = (radius * radius - p.r * p.r).max(0.0).sqrt();
        let key = if low { -(p.t + h) } else { p.t - h };
        let bin = if key <= 0.0 {
            0
        } else {
            ((key * scale) as usize + 1).min(END_BINS - 1)
        };
        gain[bin] += p.gain;
        reach[bin] = reach[bin].max(key.max(0.0));
    }
    cost += gain[0];
    let (mut best_cost, mut best_reach, mut far) = (cost, 0.0, 0.0f32);
    for bin in 1..END_BINS {
        if gain[bin] == 0.0 && reach[bin] == 0.0 {
            continue;
        }
        cost += gain[bin];
        far = far.max(reach[bin]);
        if cost < best_cost {
            (best_cost, best_reach) = (cost, far);
        }
    }
    (best_cost, if low { -best_reach } else { best_reach })
}
