//! A small, strict Wavefront OBJ reader: `v` and `f` records (polygons fan-triangulated;
//! `v/vt/vn` forms and negative, relative indices accepted); everything else is ignored.
//! Coordinates are parsed in f64 and the mesh centred on its bounds before conversion
//! ([`TriMesh::from_f64`]): survey and CAD exports 10⁶ m from their origin keep their
//! precision.

use crate::mesh::TriMesh;
use glam::DVec3;

/// A malformed OBJ file.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjError {
    /// 1-based line number.
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

impl std::fmt::Display for ObjError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "OBJ line {}: {}", self.line, self.message)
    }
}

impl std::error::Error for ObjError {}

/// Bytes per parallel parsing chunk (cut at the next line end).
const CHUNK_BYTES: usize = 256 * 1024;

/// Parses OBJ text into a triangle mesh. Faces may refer only to vertices defined
/// before them (as the format requires).
///
/// Large files are parsed in chunks on the rayon pool; indices are resolved afterwards
/// in file order, so the mesh and the first error reported are the same as a
/// sequential parse.
pub fn parse_obj(text: &str) -> Result<TriMesh, ObjError> {
    use rayon::prelude::*;
    let mut bounds = vec![0];
    while let Some(&last) = bounds.last() {
        if last >= text.len() {
            break;
        }
        let cut = (last + CHUNK_BYTES).min(text.len());
        let end = text.as_bytes()[cut..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(text.len(), |p| cut + p + 1);
        bounds.push(end);
    }
    let chunks: Vec<Chunk> = bounds
        .par_windows(2)
        .map(|w| Chunk::parse(&text[w[0]..w[1]]))
        .collect();
    let mut positions: Vec<DVec3> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut first_line = 1;
    for chunk in chunks {
        let base = positions.len() as i64;
        positions.extend_from_slice(&chunk.positions);
        let mut resolved = Vec::with_capacity(8);
        for face in &chunk.faces {
            let count = base + face.vertices_before as i64;
            resolved.clear();
            for &i in &chunk.indices[face.first as usize..(face.first + face.len) as usize] {
                let r = if i > 0 { i - 1 } else { count + i };
                if i == 0 || r < 0 || r >= count {
                    return Err(ObjError {
                        line: first_line + face.line,
                        message: format!("face index {i} out of range ({count} vertices so far)"),
                    });
                }
                resolved.push(r as u32);
            }
            for k in 1..resolved.len() - 1 {
                triangles.push([resolved[0], resolved[k], resolved[k + 1]]);
            }
        }
        if let Some(mut e) = chunk.error {
            e.line += first_line;
            return Err(e);
        }
        first_line += chunk.lines;
    }
    Ok(TriMesh::from_f64(&positions, triangles))
}

/// One chunk of lines, parsed without knowing the vertices before it.
#[derive(Default)]
struct Chunk {
    positions: Vec<DVec3>,
    /// Raw (1-based or negative) indices of all faces.
    indices: Vec<i64>,
    faces: Vec<Face>,
    /// Lines in the chunk.
    lines: usize,
    /// The first syntax error, with a 0-based line number within the chunk; faces
    /// before it are kept so that an earlier out-of-range index still wins.
    error: Option<ObjError>,
}

struct Face {
    /// 0-based line within the chunk.
    line: usize,
    /// Vertices defined earlier in the chunk.
    vertices_before: u32,
    first: u32,
    len: u32,
}

impl Chunk {
    fn parse(text: &str) -> Chunk {
        let mut chunk = Chunk::default();
        for (n, raw) in text.lines().enumerate() {
            chunk.lines = n + 1;
            if let Err(message) = chunk.parse_line(n, raw.trim()) {
                chunk.error = Some(ObjError { line: n, message });
                break;
            }
        }
        chunk
    }

    fn parse_line(&mut self, n: usize, line: &str) -> Result<(), String> {
        let mut words = line.split_ascii_whitespace();
        match words.next() {
            Some("v") => {
                let mut c = [0.0f64; 3];
                for (k, slot) in c.iter_mut().enumerate() {
                    let w = words
                        .next()
                        .ok_or_else(|| format!("vertex needs 3 coordinates, got {k}"))?;
                    *slot = w
                        .parse()
                        .map_err(|_| format!("bad vertex coordinate {w:?}"))?;
                }
                self.positions.push(DVec3::from_array(c));
            }
            Some("f") => {
                let first = self.indices.len();
                for w in words {
                    let index_text = w.split_once('/').map_or(w, |(index, _)| index);
                    let i: i64 = index_text
                        .parse()
                        .map_err(|_| format!("bad face index {w:?}"))?;
                    self.indices.push(i);
                }
                let len = self.indices.len() - first;
                if len < 3 {
                    return Err(format!("face needs at least 3 vertices, got {len}"));
                }
                self.faces.push(Face {
                    line: n,
                    vertices_before: self.positions.len() as u32,
                    first: first as u32,
                    len: len as u32,
                });
            }
            _ => {}
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_vertices_polygons_and_index_forms() {
        let text = "# comment\no cube\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n\
                    f 1/1/1 2/1/1 3/1/1 4/1/1\nf -4 -3 -2\ns off\n";
        let m = parse_obj(text).unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 2]]);
    }

    /// A file long enough to be parsed in several chunks gives the same mesh as its
    /// parts, and errors keep their file line numbers and order.
    #[test]
    fn chunked_parsing_matches_and_reports_the_first_error() {
        let mut text = String::new();
        let n = 40_000;
        for k in 0..n {
            text.push_str(&format!("v {k} {}.5 -{k}e-3\n", k % 7));
            if k >= 2 {
                text.push_str(&format!("f {} -2 -1\n", k - 1));
            }
        }
        assert!(text.len() > 3 * CHUNK_BYTES);
        let m = parse_obj(&text).unwrap();
        assert_eq!(m.positions.len(), n);
        let last = m.origin + m.positions[n - 1].as_dvec3();
        let want = DVec3::new(
            (n - 1) as f64,
            ((n - 1) % 7) as f64 + 0.5,
            -((n - 1) as f64) * 1e-3,
        );
        assert!((last - want).length() < 1e-3, "{last} vs {want}");
        assert_eq!(m.triangles.len(), n - 2);
        assert!(
            m.triangles
                .iter()
                .enumerate()
                .all(|(t, tri)| *tri == [t as u32, t as u32 + 1, t as u32 + 2])
        );
        // An out-of-range index late in the file, then a syntax error after it.
        let lines: Vec<&str> = text.lines().collect();
        let mut bad = lines.clone();
        let late = lines.len() - 10;
        bad[late] = "f 1 2 999999";
        bad[late + 5] = "v 1 x 2";
        let e = parse_obj(&bad.join("\n")).unwrap_err();
        assert_eq!(
            (e.line, e.message.contains("out of range")),
            (late + 1, true),
            "{e}"
        );
        // A syntax error in an early chunk wins over everything after it.
        bad[100] = "f 1 2";
        let e = parse_obj(&bad.join("\n")).unwrap_err();
        assert_eq!(
            (e.line, e.message.contains("at least 3")),
            (101, true),
            "{e}"
        );
    }

    /// Far-out coordinates are parsed in f64 and centred: the mesh keeps its shape to
    /// f32 precision of its own size, not of its distance from the origin.
    #[test]
    fn far_coordinates_keep_their_precision() {
        let text = "v 1000000.001 -2000000 3e6\nv 1000000.002 -2000000 3e6\n\
                    v 1000000.001 -1999999.999 3e6\nf 1 2 3\n";
        let m = parse_obj(text).unwrap();
        let centre = DVec3::new(1000000.0015, -1999999.9995, 3e6);
        assert!((m.origin - centre).length() < 1e-8, "{}", m.origin);
        let edge = m.positions[1] - m.positions[0];
        // In f32 the three vertices would collapse onto one (spacing 0.0625 at 10⁶).
        assert!((edge.x - 1e-3).abs() < 1e-9 && edge.y == 0.0, "{edge}");
        let edge = m.positions[2] - m.positions[0];
        assert!((edge.y - 1e-3).abs() < 1e-9 && edge.x == 0.0, "{edge}");
    }

    #[test]
    fn malformed_files_name_the_line() {
        let cases = [
            ("v 1 2\n", 1, "3 coordinates"),
            ("v 1 2 x\n", 1, "bad vertex"),
            ("v 0 0 0\nf 1 2 3\n", 2, "out of range"),
            ("v 0 0 0\nv 0 0 0\nv 0 0 0\nf 0 1 2\n", 4, "out of range"),
            ("v 0 0 0\nv 1 0 0\nf 1 2\n", 3, "at least 3"),
            ("v 0 0 0\nf a b c\n", 2, "bad face index"),
        ];
        for (text, line, needle) in cases {
            let e = parse_obj(text).unwrap_err();
            assert_eq!(e.line, line, "{text:?}");
            assert!(e.message.contains(needle), "{text:?}: {e}");
        }
    }
}
