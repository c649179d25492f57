//! A small, strict Wavefront OBJ reader: `v` and `f` records (polygons fan-triangulated;
//! `v/vt/vn` forms and negative, relative indices accepted); everything else is ignored.

use crate::mesh::TriMesh;
use glam::Vec3;

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

/// Parses OBJ text into a triangle mesh. Faces may refer only to vertices defined
/// before them (as the format requires).
pub fn parse_obj(text: &str) -> Result<TriMesh, ObjError> {
    let mut mesh = TriMesh::default();
    let mut face = Vec::with_capacity(8);
    for (n, raw) in text.lines().enumerate() {
        let line = raw.trim();
        let err = |message: String| ObjError {
            line: n + 1,
            message,
        };
        let mut words = line.split_ascii_whitespace();
        match words.next() {
            Some("v") => {
                let mut c = [0.0f32; 3];
                for (k, slot) in c.iter_mut().enumerate() {
                    let w = words
                        .next()
                        .ok_or_else(|| err(format!("vertex needs 3 coordinates, got {k}")))?;
                    *slot = w
                        .parse()
                        .map_err(|_| err(format!("bad vertex coordinate {w:?}")))?;
                }
                mesh.positions.push(Vec3::from_array(c));
            }
            Some("f") => {
                face.clear();
                for w in words {
                    let index_text = w.split('/').next().unwrap_or("");
                    let i: i64 = index_text
                        .parse()
                        .map_err(|_| err(format!("bad face index {w:?}")))?;
                    let count = mesh.positions.len() as i64;
                    let resolved = if i > 0 { i - 1 } else { count + i };
                    if i == 0 || resolved < 0 || resolved >= count {
                        return Err(err(format!(
                            "face index {i} out of range ({count} vertices so far)"
                        )));
                    }
                    face.push(resolved as u32);
                }
                if face.len() < 3 {
                    return Err(err(format!(
                        "face needs at least 3 vertices, got {}",
                        face.len()
                    )));
                }
                for k in 1..face.len() - 1 {
                    mesh.triangles.push([face[0], face[k], face[k + 1]]);
                }
            }
            _ => {}
        }
    }
    Ok(mesh)
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
