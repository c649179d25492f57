//! Hair as strands: polylines with a width and a texture-atlas slot, built in code or
//! read from a small text format, and checked — strands with fewer than two points,
//! non-finite points or widths that are not positive and finite are dropped, each with
//! a reason the caller can report once.
//!
//! The text format (`.hair`, UTF-8; `#` starts a comment):
//!
//! ```text
//! penumbra-hair 1
//! # strand <width, metres> <atlas slot> <x y z> <x y z> ...
//! strand 0.0008 3  0 1.70 0.09  0 1.69 0.10  0 1.67 0.105
//! ```

use glam::Vec3;

/// One strand: a polyline, root first.
#[derive(Clone, Debug, PartialEq)]
pub struct Strand {
    /// Points, metres, in the hair's space.
    pub points: Vec<Vec3>,
    /// Width, metres.
    pub width: f32,
    /// Which hair of the texture atlas it shows.
    pub slot: u32,
}

/// Why a strand was dropped.
#[derive(Clone, Debug, PartialEq)]
pub enum StrandProblem {
    /// Fewer than two points.
    TooFewPoints,
    /// A NaN or infinite point.
    NotFinite,
    /// A width that is not positive and finite.
    BadWidth(f32),
}

/// The strands that can be drawn, and what was dropped (strand index, reason).
pub fn check_strands(strands: Vec<Strand>) -> (Vec<Strand>, Vec<(usize, StrandProblem)>) {
    let mut kept = Vec::with_capacity(strands.len());
    let mut dropped = Vec::new();
    for (i, strand) in strands.into_iter().enumerate() {
        let problem = if strand.points.len() < 2 {
            Some(StrandProblem::TooFewPoints)
        } else if !strand.points.iter().all(|p| p.is_finite()) {
            Some(StrandProblem::NotFinite)
        } else if !(strand.width.is_finite() && strand.width > 0.0) {
            Some(StrandProblem::BadWidth(strand.width))
        } else {
            None
        };
        match problem {
            Some(p) => dropped.push((i, p)),
            None => kept.push(strand),
        }
    }
    (kept, dropped)
}

/// A malformed `.hair` file: the line (1-based) and what is wrong.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParseError {
    /// 1-based line number.
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

impl std::fmt::Display for ParseError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "line {}: {}", self.line, self.message)
    }
}

impl std::error::Error for ParseError {}

/// The strands of a `.hair` file (unchecked: see [`check_strands`]).
pub fn parse_hair(text: &str) -> Result<Vec<Strand>, ParseError> {
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.split('#').next().unwrap_or("").trim()))
        .filter(|(_, l)| !l.is_empty());
    let error = |line, message: &str| ParseError {
        line,
        message: message.to_string(),
    };
    match lines.next() {
        Some((_, "penumbra-hair 1")) => {}
        Some((line, _)) => return Err(error(line, "expected the header `penumbra-hair 1`")),
        None => return Err(error(1, "empty file")),
    }
    let mut strands = Vec::new();
    for (line, text) in lines {
        let mut words = text.split_whitespace();
        if words.next() != Some("strand") {
            return Err(error(line, "expected `strand <width> <slot> <x y z>...`"));
        }
        let width: f32 = words
            .next()
            .and_then(|w| w.parse().ok())
            .ok_or_else(|| error(line, "the width is not a number"))?;
        let slot: u32 = words
            .next()
            .and_then(|w| w.parse().ok())
            .ok_or_else(|| error(line, "the atlas slot is not a whole number"))?;
        let numbers: Vec<f32> = words
            .map(|w| w.parse::<f32>())
            .collect::<Result<_, _>>()
            .map_err(|_| error(line, "a coordinate is not a number"))?;
        if !numbers.len().is_multiple_of(3) {
            return Err(error(line, "the coordinates are not whole points (x y z)"));
        }
        strands.push(Strand {
            points: numbers
                .chunks(3)
                .map(|c| Vec3::new(c[0], c[1], c[2]))
                .collect(),
            width,
            slot,
        });
    }
    Ok(strands)
}

/// A cross-section's width: the distance between its two vertices farthest apart along
/// the section's longest bounding-box axis — the greatest distance between its vertices
/// for the two or three collinear vertices of a ribbon's section, in one pass over any
/// number (every pair was 4·10¹⁰ distances for a 200,000-vertex section).
fn section_width(points: impl Iterator<Item = Vec3> + Clone) -> f32 {
    let (lo, hi) = points
        .clone()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p), hi.max(p))
        });
    let axis = (hi - lo).max_position();
    let key = |p: &Vec3| p[axis];
    let first = points.clone().min_by(|a, b| key(a).total_cmp(&key(b)));
    let last = points.max_by(|a, b| key(a).total_cmp(&key(b)));
    match (first, last) {
        (Some(a), Some(b)) => a.distance(b),
        _ => 0.0,
    }
}

/// Strands from a mesh of ribbons, as artists author hair cards (Samaritan's pipeline: a
/// glTF mesh of strips): each connected piece of the triangle list is one strand; its
/// vertices are grouped into cross-sections by their `uv.y` (along the hair, root at the
/// smallest), each section's centre is a point of the strand and its extent across a
/// width (the strand takes their mean); the atlas slot is the piece's mean `uv.x` times
/// `slots`. Pieces with fewer than two sections come back with fewer than two points,
/// for [`check_strands`] to drop. Indices out of range and vertices whose `uv.y` is not
/// finite are skipped.
pub fn strands_from_ribbons(
    positions: &[Vec3],
    uvs: &[glam::Vec2],
    indices: &[u32],
    slots: u32,
) -> Vec<Strand> {
    let n = positions.len().min(uvs.len());
    // Union-find over the vertices the triangles join.
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut used = vec![false; n];
    for tri in indices.chunks_exact(3) {
        let [a, b, c] = [tri[0] as usize, tri[1] as usize, tri[2] as usize];
        if a >= n || b >= n || c >= n {
            continue;
        }
        for (x, y) in [(a, b), (b, c)] {
            let (rx, ry) = (root(&mut parent, x), root(&mut parent, y));
            parent[rx.max(ry)] = rx.min(ry);
        }
        used[a] = true;
        used[b] = true;
        used[c] = true;
    }
    // Pieces in order of their first vertex (deterministic).
    let mut pieces: Vec<Vec<usize>> = Vec::new();
    let mut piece_of = std::collections::HashMap::new();
    for i in (0..n).filter(|&i| used[i]) {
        let r = root(&mut parent, i);
        let k = *piece_of.entry(r).or_insert_with(|| {
            pieces.push(Vec::new());
            pieces.len() - 1
        });
        pieces[k].push(i);
    }
    pieces
        .into_iter()
        .map(|mut piece| {
            // A vertex with no place along the hair (NaN or infinite `uv.y`) is left out.
            piece.retain(|&i| uvs[i].y.is_finite());
            piece.sort_by(|&a, &b| uvs[a].y.total_cmp(&uvs[b].y).then(a.cmp(&b)));
            let mut points = Vec::new();
            let mut widths = Vec::new();
            let mut start = 0;
            while start < piece.len() {
                let v = uvs[piece[start]].y;
                // At least the first vertex: the walk always moves on.
                let end = start
                    + piece[start..]
                        .iter()
                        .take_while(|&&i| (uvs[i].y - v).abs() <= 1e-5)
                        .count()
                        .max(1);
                let section = &piece[start..end];
                let centre =
                    section.iter().map(|&i| positions[i]).sum::<Vec3>() / section.len() as f32;
                points.push(centre);
                widths.push(section_width(section.iter().map(|&i| positions[i])));
                start = end;
            }
            let u = piece.iter().map(|&i| uvs[i].x).sum::<f32>() / piece.len() as f32;
            Strand {
                points,
                width: widths.iter().sum::<f32>() / widths.len().max(1) as f32,
                slot: ((u * slots as f32).floor().max(0.0) as u32).min(slots.saturating_sub(1)),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_format_round_trips_and_names_its_errors() {
        let text = "penumbra-hair 1\n# a beard\nstrand 0.0008 3  0 1.7 0.09  0 1.69 0.1\n\nstrand 1e-3 0 1 2 3 4 5 6 7 8 9 # three points\n";
        let strands = parse_hair(text).unwrap();
        assert_eq!(strands.len(), 2);
        assert_eq!(strands[0].slot, 3);
        assert_eq!(
            strands[0].points,
            vec![Vec3::new(0.0, 1.7, 0.09), Vec3::new(0.0, 1.69, 0.1)]
        );
        assert_eq!(strands[1].points.len(), 3);
        for (bad, line) in [
            ("", 1),
            ("hair 2\n", 1),
            ("penumbra-hair 1\nstrand x 0 0 0 0 1 1 1\n", 2),
            ("penumbra-hair 1\nstrand 0.1 -1 0 0 0 1 1 1\n", 2),
            ("penumbra-hair 1\n\nstrand 0.1 0 0 0 0 1 1\n", 3),
            ("penumbra-hair 1\nstrand 0.1 0 0 0 0 1 1 z\n", 2),
            ("penumbra-hair 1\nbraid 0.1 0\n", 2),
        ] {
            let e = parse_hair(bad).unwrap_err();
            assert_eq!(e.line, line, "{bad:?}: {e}");
        }
    }

    #[test]
    fn ribbons_give_back_the_strands_they_were_built_from() {
        // Two strands as ribbons (a vertex pair per point, ± half the width across), the
        // second's vertices listed in reverse, with a lone triangle that has one section.
        let strands = [
            (
                vec![
                    Vec3::ZERO,
                    Vec3::new(0.0, -0.1, 0.02),
                    Vec3::new(0.0, -0.2, 0.05),
                ],
                0.004,
                1,
            ),
            (
                vec![Vec3::new(1.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.3)],
                0.01,
                3,
            ),
        ];
        let (mut positions, mut uvs, mut indices) = (Vec::new(), Vec::new(), Vec::new());
        for (s, (points, width, slot)) in strands.iter().enumerate() {
            let base = positions.len() as u32;
            let mut verts = Vec::new();
            for (k, p) in points.iter().enumerate() {
                let v = k as f32 / (points.len() - 1) as f32;
                let u = (*slot as f32 + 0.5) / 4.0;
                verts.push((*p - Vec3::X * width / 2.0, glam::Vec2::new(u - 0.1, v)));
                verts.push((*p + Vec3::X * width / 2.0, glam::Vec2::new(u + 0.1, v)));
            }
            let order: Vec<usize> = if s == 1 {
                (0..verts.len()).rev().collect()
            } else {
                (0..verts.len()).collect()
            };
            let index_of = |k: usize| base + order.iter().position(|&o| o == k).unwrap() as u32;
            for &o in &order {
                positions.push(verts[o].0);
                uvs.push(verts[o].1);
            }
            for k in 0..points.len() - 1 {
                let [a, b, c, d] = [2 * k, 2 * k + 1, 2 * k + 2, 2 * k + 3].map(index_of);
                indices.extend([a, b, c, b, d, c]);
            }
        }
        let base = positions.len() as u32;
        positions.extend([Vec3::ZERO, Vec3::X, Vec3::Y]);
        uvs.extend([glam::Vec2::ZERO; 3]);
        indices.extend([base, base + 1, base + 2, 0, 1, 99]);
        let found = strands_from_ribbons(&positions, &uvs, &indices, 4);
        assert_eq!(found.len(), 3);
        for (got, (points, width, slot)) in found.iter().zip(&strands) {
            assert_eq!(got.slot, *slot);
            assert!((got.width - width).abs() < 1e-6, "{} vs {width}", got.width);
            assert_eq!(got.points.len(), points.len());
            for (a, b) in got.points.iter().zip(points) {
                assert!(a.distance(*b) < 1e-6, "{a} vs {b}");
            }
        }
        let (kept, dropped) = check_strands(found);
        assert_eq!((kept.len(), dropped.len()), (2, 1));
    }

    #[test]
    fn bad_strands_are_dropped_with_a_reason() {
        let strand = |points: Vec<Vec3>, width| Strand {
            points,
            width,
            slot: 0,
        };
        let two = vec![Vec3::ZERO, Vec3::Y];
        let (kept, dropped) = check_strands(vec![
            strand(two.clone(), 0.001),
            strand(vec![Vec3::ZERO], 0.001),
            strand(vec![Vec3::ZERO, Vec3::NAN], 0.001),
            strand(two.clone(), 0.0),
            strand(two.clone(), f32::NAN),
            strand(vec![], 0.001),
        ]);
        assert_eq!(kept.len(), 1);
        assert_eq!(
            dropped.iter().map(|(i, _)| *i).collect::<Vec<_>>(),
            vec![1, 2, 3, 4, 5]
        );
        assert_eq!(dropped[0].1, StrandProblem::TooFewPoints);
        assert_eq!(dropped[1].1, StrandProblem::NotFinite);
        assert_eq!(dropped[2].1, StrandProblem::BadWidth(0.0));
    }

    /// A ribbon vertex whose `uv.y` is NaN or infinite is left out of its strand (it
    /// looped forever: its section took no vertex and the walk never moved on, #47), and a
    /// piece whose vertices all share one `uv.y` costs a pass over them, not one per pair.
    #[test]
    fn ribbons_with_bad_or_flat_uvs_finish_and_skip_the_bad_vertices() {
        let positions = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0)];
        let indices = [0, 1, 2, 1, 3, 2];
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let uvs = [
                glam::Vec2::new(0.0, 0.0),
                glam::Vec2::new(0.1, 0.0),
                glam::Vec2::new(0.0, bad),
                glam::Vec2::new(0.1, 1.0),
            ];
            let found = strands_from_ribbons(&positions, &uvs, &indices, 1);
            assert_eq!(found.len(), 1, "{bad}");
            // Sections at v = 0 (vertices 0, 1) and v = 1 (vertex 3); vertex 2 left out.
            assert_eq!(
                found[0].points,
                vec![Vec3::new(0.5, 0.0, 0.0), Vec3::new(1.0, 1.0, 0.0)]
            );
            assert!(found[0].points.iter().all(|p| p.is_finite()), "{bad}");
        }
        // 200,000 vertices in one section: the O(k²) width was 4·10¹⁰ distances.
        let n = 200_000u32;
        let positions: Vec<Vec3> = (0..n)
            .map(|i| Vec3::new(i as f32 * 1e-5, 0.0, 0.0))
            .collect();
        let uvs = vec![glam::Vec2::ZERO; n as usize];
        let indices: Vec<u32> = (0..n - 2).flat_map(|i| [i, i + 1, i + 2]).collect();
        let found = strands_from_ribbons(&positions, &uvs, &indices, 1);
        assert_eq!(found.len(), 1);
        assert_eq!(found[0].points.len(), 1);
        let span = (n - 1) as f32 * 1e-5;
        assert!(
            (found[0].width - span).abs() < 1e-3 * span,
            "{} vs {span}",
            found[0].width
        );
    }
}
