//! Wavefront OBJ reading that keeps the file's vertex numbering: vertex `i` of the mesh is the
//! file's `i`-th `v` statement, so output frames, `[pins] vertices` and any pipeline keyed by
//! index (Blender's Mesh Cache modifier) refer to the vertices the user wrote.
//!
//! We read OBJ ourselves because the crates renumber or give up: tobj numbers positions by their
//! first use in a face, per object, and obj-rs panics (`unimplemented!`) on free-form statements.
//!
//! Read: `v x y z [w | r g b]` in float64, `f` with every corner form (`v`, `v/vt`, `v//vn`,
//! `v/vt/vn`, negative indices counting back from the last vertex so far), polygons split into
//! triangle fans, `\` line continuations and `#` comments. Every other statement (`vt`, `vn`,
//! `o`, `g`, `s`, `usemtl`, `mtllib`, `l`, `p`, free-form geometry) is ignored: a surface needs
//! only positions and faces. Faces may name vertices defined further down the file. Errors name
//! the line.

use glam::DVec3;

use super::Mesh;

/// A syntax error and the (1-based) line it is on.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ObjError {
    pub line: usize,
    pub message: String,
}

/// Parses OBJ text into a mesh with the file's vertex order. The mesh is not validated yet.
pub fn parse_obj(text: &str) -> Result<Mesh, ObjError> {
    let mut mesh = Mesh::default();
    // The line of each triangle, to name it if an index turns out to be beyond the last vertex.
    let mut triangle_lines: Vec<usize> = Vec::new();
    let mut polygon: Vec<u32> = Vec::new();
    for (line, statement) in statements(text) {
        let error = |message: String| ObjError { line, message };
        let mut words = statement.split_whitespace();
        match words.next() {
            Some("v") => {
                let numbers: Vec<&str> = words.collect();
                if !(3..=7).contains(&numbers.len()) {
                    return Err(error(format!(
                        "a vertex needs x y z (and optionally w or r g b), found {} numbers",
                        numbers.len()
                    )));
                }
                let mut coordinates = [0.0; 3];
                for (value, word) in coordinates.iter_mut().zip(&numbers) {
                    *value = word
                        .parse::<f64>()
                        .map_err(|_| error(format!("'{word}' is not a number")))?;
                }
                mesh.positions.push(DVec3::from_array(coordinates));
            }
            Some("f") => {
                polygon.clear();
                for corner in words {
                    polygon.push(
                        corner_index(corner, mesh.positions.len()).map_err(|message| {
                            error(format!("face corner '{corner}': {message}"))
                        })?,
                    );
                }
                if polygon.len() < 3 {
                    return Err(error(format!(
                        "a face needs at least 3 corners, found {}",
                        polygon.len()
                    )));
                }
                let before = mesh.triangles.len();
                super::io::fan_triangulate(&polygon, &mut mesh.triangles);
                triangle_lines.resize(triangle_lines.len() + mesh.triangles.len() - before, line);
            }
            _ => {}
        }
    }
    let vertex_count = mesh.positions.len();
    for (triangle, line) in mesh.triangles.iter().zip(&triangle_lines) {
        if let Some(index) = triangle.iter().find(|i| **i as usize >= vertex_count) {
            return Err(ObjError {
                line: *line,
                message: format!(
                    "face uses vertex {} but the file has {vertex_count} vertices",
                    u64::from(*index) + 1
                ),
            });
        }
    }
    Ok(mesh)
}

/// The statements of an OBJ file with the line each starts on: comments removed, lines ending
/// in `\` joined to the next.
fn statements(text: &str) -> impl Iterator<Item = (usize, String)> + '_ {
    let mut lines = text.lines().enumerate();
    std::iter::from_fn(move || {
        let (index, first) = lines.next()?;
        let mut statement = String::new();
        let mut part = first;
        loop {
            let code = part.split('#').next().unwrap_or("");
            match code.trim_end().strip_suffix('\\') {
                Some(continued) => {
                    statement.push_str(continued);
                    statement.push(' ');
                    match lines.next() {
                        Some((_, next)) => part = next,
                        None => break,
                    }
                }
                None => {
                    statement.push_str(code);
                    break;
                }
            }
        }
        Some((index + 1, statement))
    })
}

/// The 0-based vertex index of a face corner (`v`, `v/vt`, `v//vn` or `v/vt/vn`), given how many
/// vertices precede it (what a negative index counts back from).
fn corner_index(corner: &str, vertices_so_far: usize) -> Result<u32, String> {
    let text = corner.split('/').next().unwrap_or("");
    let index: i64 = text
        .parse()
        .map_err(|_| "the vertex index is not an integer".to_owned())?;
    let zero_based = match index {
        0 => return Err("vertex indices start at 1".to_owned()),
        i if i > 0 => i - 1,
        i => {
            let back = i.unsigned_abs();
            if back > vertices_so_far as u64 {
                return Err(format!(
                    "counts back {back} vertices but only {vertices_so_far} precede it"
                ));
            }
            vertices_so_far as i64 - back as i64
        }
    };
    // The last u32 is kept free so that a vertex count always fits in a u32 as well.
    u32::try_from(zero_based)
        .ok()
        .filter(|i| *i < u32::MAX)
        .ok_or_else(|| format!("vertex index {index} is beyond what hooke supports"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertices_keep_the_files_order_whatever_order_faces_use_them() {
        let mesh = parse_obj("v 1 0 0\nv 0 1 0\nv 0 0 1\nv 2 2 2\nf 3 1 2\nf 2 4 3\n").unwrap();
        assert_eq!(mesh.positions[0], DVec3::new(1.0, 0.0, 0.0));
        assert_eq!(mesh.positions[3], DVec3::new(2.0, 2.0, 2.0));
        assert_eq!(mesh.triangles, vec![[2, 0, 1], [1, 3, 2]]);
    }

    #[test]
    fn every_corner_form_and_negative_indices_name_the_same_vertices() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n\
                    f 1 2 3\nf 1/1 2/1 3/1\nf 1//1 2//1 3//1\nf 1/1/1 2/1/1 3/1/1\nf -3 -2 -1\n";
        let mesh = parse_obj(text).unwrap();
        assert_eq!(mesh.triangles, vec![[0, 1, 2]; 5]);
    }

    #[test]
    fn continuations_comments_and_other_statements_are_handled() {
        let text = "# a quad\nmtllib a.mtl\no sheet\nv 0 0 0 # origin\nv 1 0 0\nv 1 1 0\n\
                    v 0 1 0 1.0\ng top\ns off\nusemtl red\nl 1 2\nf 1 2 \\\n 3 4\n";
        let mesh = parse_obj(text).unwrap();
        assert_eq!(mesh.positions.len(), 4);
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn faces_may_name_vertices_defined_later() {
        let mesh = parse_obj("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
        assert_eq!(mesh.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn errors_name_the_line() {
        let cases = [
            ("v 0 0 0\nv 1 0\n", 2, "found 2 numbers"),
            ("v 0 0 0\nv 1 x 0\n", 2, "'x' is not a number"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n",
                4,
                "at least 3 corners",
            ),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", 4, "start at 1"),
            ("v 0 0 0\nv 1 0 0\nf -3 1 2\nv 0 1 0\n", 3, "only 2 precede"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 9\n",
                5,
                "vertex 9 but the file has 3",
            ),
            (
                "v 0 0 0\nf 1 2 99999999999\n",
                2,
                "beyond what hooke supports",
            ),
            ("v 0 0 0\nf 1 2 a/1\n", 2, "not an integer"),
        ];
        for (text, line, message) in cases {
            let error = parse_obj(text).unwrap_err();
            assert_eq!(error.line, line, "{text:?}: {error:?}");
            assert!(error.message.contains(message), "{text:?}: {error:?}");
        }
    }
}
