//! Wavefront OBJ reading that keeps the file's vertex numbering: vertex `i` of the mesh is the
//! file's `i`-th `v` statement, so output frames, `[pins] vertices` and any pipeline keyed by
//! index (Blender's Mesh Cache modifier) refer to the vertices the user wrote.
//!
//! We read OBJ ourselves because the crates renumber or give up: tobj numbers positions by their
//! first use in a face, per object, and obj-rs panics (`unimplemented!`) on free-form statements.
//!
//! Read: `v x y z [w | r g b]` in float64, `vt u [v [w]]`, `f` with every corner form (`v`,
//! `v/vt`, `v//vn`, `v/vt/vn`, negative indices counting back from the last vertex or texture
//! coordinate so far), polygons split into triangle fans, `\` line continuations and `#`
//! comments. The faces' texture coordinates are kept per corner, seams included; if only some
//! faces have them, the mesh has none and a warning says so. Every other statement (`vn`, `o`,
//! `g`, `s`, `usemtl`, `mtllib`, `l`, `p`, free-form geometry) is ignored. Faces may name
//! vertices defined further down the file. Errors name the line.

use glam::DVec3;

use super::{Mesh, MeshWarning, TextureCoordinates};

/// A syntax error and the (1-based) line it is on.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ObjError {
    pub line: usize,
    pub message: String,
}

/// Parses OBJ text into a mesh with the file's vertex order, and a warning if only some faces
/// have texture coordinates. The mesh is not validated yet.
pub fn parse_obj(text: &str) -> Result<(Mesh, Vec<MeshWarning>), ObjError> {
    let mut mesh = Mesh::default();
    // The line of each triangle, to name it if an index turns out to be beyond the last vertex.
    let mut triangle_lines: Vec<usize> = Vec::new();
    let mut polygon: Vec<u32> = Vec::new();
    let mut coordinates: Vec<[f64; 2]> = Vec::new();
    // Per triangle, its corners' texture coordinates if the face gave them.
    let mut corner_uvs: Vec<Option<[u32; 3]>> = Vec::new();
    let mut polygon_uvs: Vec<u32> = Vec::new();
    for (line, statement) in statements(text) {
        let error = |message: String| ObjError { line, message };
        let mut words = statement.split_whitespace();
        match words.next() {
            Some("v") => {
                let xyz = leading_numbers::<3>(
                    words,
                    3..=7,
                    "a vertex needs x y z (and optionally w or r g b)",
                )
                .map_err(error)?;
                mesh.positions.push(DVec3::from_array(xyz));
            }
            Some("vt") => {
                let uv = leading_numbers::<2>(
                    words,
                    1..=3,
                    "a texture coordinate needs u (and optionally v and w)",
                )
                .map_err(error)?;
                coordinates.push(uv);
            }
            Some("f") => {
                polygon.clear();
                polygon_uvs.clear();
                let mut corners = 0;
                for corner in words {
                    corners += 1;
                    let (vertex, uv) =
                        corner_indices(corner, mesh.positions.len(), coordinates.len()).map_err(
                            |message| error(format!("face corner '{corner}': {message}")),
                        )?;
                    polygon.push(vertex);
                    polygon_uvs.extend(uv);
                }
                if polygon.len() < 3 {
                    return Err(error(format!(
                        "a face needs at least 3 corners, found {}",
                        polygon.len()
                    )));
                }
                let before = mesh.triangles.len();
                super::io::fan_triangulate(&polygon, &mut mesh.triangles);
                let added = mesh.triangles.len() - before;
                triangle_lines.resize(triangle_lines.len() + added, line);
                if polygon_uvs.len() == corners {
                    let mut fan = Vec::with_capacity(added);
                    super::io::fan_triangulate(&polygon_uvs, &mut fan);
                    corner_uvs.extend(fan.into_iter().map(Some));
                } else {
                    corner_uvs.resize(corner_uvs.len() + added, None);
                }
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
    let mut warnings = Vec::new();
    let without = corner_uvs.iter().filter(|c| c.is_none()).count();
    if without == 0 && !corner_uvs.is_empty() {
        let count = coordinates.len();
        for (corners, line) in corner_uvs.iter().flatten().zip(&triangle_lines) {
            if let Some(index) = corners.iter().find(|i| **i as usize >= count) {
                return Err(ObjError {
                    line: *line,
                    message: format!(
                        "face uses texture coordinate {} but the file has {count}",
                        u64::from(*index) + 1
                    ),
                });
            }
        }
        mesh.uvs = Some(TextureCoordinates {
            coordinates,
            corners: corner_uvs.into_iter().flatten().collect(),
        });
    } else if without < corner_uvs.len() {
        warnings.push(MeshWarning::PartialTextureCoordinates {
            triangles_without: without,
        });
    }
    Ok((mesh, warnings))
}

/// The first `N` numbers of a statement (missing ones 0; those past `N` are not read), when it
/// has a count of numbers in `counts`; `needs` says what it needs otherwise.
fn leading_numbers<'a, const N: usize>(
    words: impl Iterator<Item = &'a str>,
    counts: std::ops::RangeInclusive<usize>,
    needs: &str,
) -> Result<[f64; N], String> {
    let words: Vec<&str> = words.collect();
    if !counts.contains(&words.len()) {
        return Err(format!("{needs}, found {} numbers", words.len()));
    }
    let mut numbers = [0.0; N];
    for (value, word) in numbers.iter_mut().zip(&words) {
        *value = word
            .parse::<f64>()
            .map_err(|_| format!("'{word}' is not a number"))?;
    }
    Ok(numbers)
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

/// The 0-based vertex and texture coordinate indices of a face corner (`v`, `v/vt`, `v//vn` or
/// `v/vt/vn`), given how many of each precede it (what a negative index counts back from).
fn corner_indices(
    corner: &str,
    vertices_so_far: usize,
    uvs_so_far: usize,
) -> Result<(u32, Option<u32>), String> {
    let mut parts = corner.split('/');
    let vertex = index(parts.next().unwrap_or(""), vertices_so_far, "vertex")?;
    let uv = match parts.next() {
        None | Some("") => None,
        Some(text) => Some(index(text, uvs_so_far, "texture coordinate")?),
    };
    Ok((vertex, uv))
}

/// A 1-based (or negative, counting back from `so_far`) OBJ index of a `what`, 0-based.
fn index(text: &str, so_far: usize, what: &str) -> Result<u32, String> {
    let index: i64 = text
        .parse()
        .map_err(|_| format!("the {what} index is not an integer"))?;
    let zero_based = match index {
        0 => return Err(format!("{what} indices start at 1")),
        i if i > 0 => i - 1,
        i => {
            let back = i.unsigned_abs();
            if back > so_far as u64 {
                return Err(format!(
                    "counts back {back} {what}s but only {so_far} precede it"
                ));
            }
            so_far as i64 - back as i64
        }
    };
    // The last u32 is kept free so that a count always fits in a u32 as well.
    u32::try_from(zero_based)
        .ok()
        .filter(|i| *i < u32::MAX)
        .ok_or_else(|| format!("{what} index {index} is beyond what hooke supports"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertices_keep_the_files_order_whatever_order_faces_use_them() {
        let (mesh, _) =
            parse_obj("v 1 0 0\nv 0 1 0\nv 0 0 1\nv 2 2 2\nf 3 1 2\nf 2 4 3\n").unwrap();
        assert_eq!(mesh.positions[0], DVec3::new(1.0, 0.0, 0.0));
        assert_eq!(mesh.positions[3], DVec3::new(2.0, 2.0, 2.0));
        assert_eq!(mesh.triangles, vec![[2, 0, 1], [1, 3, 2]]);
    }

    #[test]
    fn every_corner_form_and_negative_indices_name_the_same_vertices() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n\
                    f 1 2 3\nf 1/1 2/1 3/1\nf 1//1 2//1 3//1\nf 1/1/1 2/1/1 3/1/1\nf -3 -2 -1\n";
        let (mesh, warnings) = parse_obj(text).unwrap();
        assert_eq!(mesh.triangles, vec![[0, 1, 2]; 5]);
        assert_eq!(
            warnings,
            vec![MeshWarning::PartialTextureCoordinates {
                triangles_without: 3
            }]
        );
        assert_eq!(mesh.uvs, None);
    }

    #[test]
    fn continuations_comments_and_other_statements_are_handled() {
        let text = "# a quad\nmtllib a.mtl\no sheet\nv 0 0 0 # origin\nv 1 0 0\nv 1 1 0\n\
                    v 0 1 0 1.0\ng top\ns off\nusemtl red\nl 1 2\nf 1 2 \\\n 3 4\n";
        let (mesh, _) = parse_obj(text).unwrap();
        assert_eq!(mesh.positions.len(), 4);
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn texture_coordinates_are_kept_per_corner_with_seams() {
        // A quad whose two triangles give vertex 3 (the shared corner) different UVs: a seam.
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
                    vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1 0\nvt 0.5\n\
                    f 1/1/1 2/2/1 3/3/1\nf 1/1 3/-1 4/4\n";
        let (mesh, warnings) = parse_obj(text).unwrap();
        assert!(warnings.is_empty());
        let uvs = mesh.uvs.expect("uvs");
        assert_eq!(uvs.coordinates[3], [0.0, 1.0]);
        assert_eq!(uvs.coordinates[4], [0.5, 0.0], "v defaults to 0");
        assert_eq!(uvs.corners, vec![[0, 1, 2], [0, 4, 3]]);
        assert!(!uvs.is_per_vertex(&mesh.triangles, 4));
    }

    #[test]
    fn faces_may_name_vertices_defined_later() {
        let (mesh, _) = parse_obj("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
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
            ("vt 0.5 x\n", 1, "'x' is not a number"),
            ("vt\n", 1, "found 0 numbers"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/-2 3/1\n",
                5,
                "counts back 2 texture coordinates",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/4\n",
                5,
                "texture coordinate 4 but the file has 1",
            ),
        ];
        for (text, line, message) in cases {
            let error = parse_obj(text).unwrap_err();
            assert_eq!(error.line, line, "{text:?}: {error:?}");
            assert!(error.message.contains(message), "{text:?}: {error:?}");
        }
    }
}
