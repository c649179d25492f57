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
}
