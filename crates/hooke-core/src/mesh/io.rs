//! Reading meshes from OBJ and PLY (ASCII and binary) and writing simulation frames as binary PLY.
//!
//! Writes go to a temporary file in the target directory that is renamed into place, so a reader
//! (or a killed run) never sees a torn file.

use std::path::Path;

use glam::DVec3;
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    Addable, BeginList, ElementDef, Encoding, Header, Property, PropertyAccess,
    PropertyAccessResult, PropertyDef, PropertyType, ScalarType,
};
use ply_rs_bw::writer::Writer;

use super::{Mesh, MeshError, MeshWarning, TextureCoordinates};

/// Why a mesh file could not be loaded. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum MeshLoadError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}: unsupported mesh format (expected .obj or .ply)")]
    UnsupportedFormat { path: String },
    #[error("{path}{}: {message}", line.map(|l| format!(" line {l}")).unwrap_or_default())]
    Parse {
        path: String,
        line: Option<usize>,
        message: String,
    },
    #[error(transparent)]
    Invalid(#[from] MeshError),
}

/// A mesh file format hooke reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshFormat {
    /// Wavefront OBJ (see [`super::obj`]).
    Obj,
    /// PLY, ASCII or binary.
    Ply,
}

impl MeshFormat {
    /// The format a file's extension names, if hooke reads it.
    pub fn of_path(path: &Path) -> Option<Self> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("obj") => Some(Self::Obj),
            Some("ply") => Some(Self::Ply),
            _ => None,
        }
    }
}

/// Loads and validates an `.obj` or `.ply` mesh. Vertex `i` of the mesh is the file's vertex `i`
/// (vertices no face uses are kept as free point masses, with a warning); polygons are split
/// into triangle fans.
pub fn load_mesh(path: &Path) -> Result<(Mesh, Vec<MeshWarning>), MeshLoadError> {
    let name = path.display().to_string();
    let format =
        MeshFormat::of_path(path).ok_or(MeshLoadError::UnsupportedFormat { path: name.clone() })?;
    let bytes = crate::input_file::read(path).map_err(io_error(&name))?;
    parse_mesh(&bytes, format, &name)
}

/// Parses and validates a mesh held in memory; `name` is what errors call it.
pub fn parse_mesh(
    bytes: &[u8],
    format: MeshFormat,
    name: &str,
) -> Result<(Mesh, Vec<MeshWarning>), MeshLoadError> {
    let (mesh, mut warnings) = match format {
        MeshFormat::Obj => {
            super::obj::parse_obj(&String::from_utf8_lossy(bytes)).map_err(|error| {
                MeshLoadError::Parse {
                    path: name.to_owned(),
                    line: Some(error.line),
                    message: error.message,
                }
            })?
        }
        MeshFormat::Ply => (load_ply(bytes, name)?, Vec::new()),
    };
    warnings.extend(mesh.validate(name)?);
    Ok((mesh, warnings))
}

fn io_error(path: &str) -> impl FnOnce(std::io::Error) -> MeshLoadError + '_ {
    move |source| MeshLoadError::Io {
        path: path.to_owned(),
        source,
    }
}

pub(super) fn fan_triangulate(polygon: &[u32], triangles: &mut Vec<[u32; 3]>) {
    for k in 1..polygon.len().saturating_sub(1) {
        triangles.push([polygon[0], polygon[k], polygon[k + 1]]);
    }
}

/// An error maker for file `name`'s PLY contents.
fn ply_error(name: &str) -> impl Fn(String) -> MeshLoadError + '_ {
    move |message| MeshLoadError::Parse {
        path: name.to_owned(),
        line: None,
        message,
    }
}

/// A PLY file's `vertex` element (its definition and records) and `face` records, where it
/// has them.
type Elements<V, F> = (Option<(ElementDef, Vec<V>)>, Option<Vec<F>>);

/// Reads a PLY file's elements in the header's order, each into records of its own kind:
/// `vertex` into `V`, `face` into `F`, any other passed over. A map of named properties per
/// vertex and per face (`DefaultElement`) took most of a 512^2 mesh's loading (1.07 s for
/// `hooke run` of 10 steps, 0.4 of them after).
fn read_ply<V: PropertyAccess, F: PropertyAccess>(
    bytes: &[u8],
    name: &str,
) -> Result<Elements<V, F>, MeshLoadError> {
    let parse_error = ply_error(name);
    let mut reader = Reader::new(bytes);
    let header = Parser::<SkippedRecord>::new()
        .read_header(&mut reader)
        .map_err(|e| parse_error(e.to_string()))?;
    check_element_counts(&header, reader.get_ref().len()).map_err(&parse_error)?;
    let (mut vertices, mut faces) = (None, None);
    for definition in header.elements.values() {
        let read = |e: ply_rs_bw::parser::ParseError| parse_error(e.to_string());
        match definition.name.as_str() {
            "vertex" => {
                let records = Parser::<V>::new()
                    .read_payload_for_element(&mut reader, definition, &header)
                    .map_err(read)?;
                vertices = Some((definition.clone(), records));
            }
            "face" => {
                let records = Parser::<F>::new()
                    .read_payload_for_element(&mut reader, definition, &header)
                    .map_err(read)?;
                faces = Some(records);
            }
            _ => {
                Parser::<SkippedRecord>::new()
                    .read_payload_for_element(&mut reader, definition, &header)
                    .map_err(read)?;
            }
        }
    }
    Ok((vertices, faces))
}

/// Refuses a header whose element counts the rest of the file cannot hold. The parser makes one
/// record per promised element before it finds the data missing, so `element face 91111111111`
/// in a 1 kB file would exhaust memory (found by the fuzzer).
fn check_element_counts(header: &Header, payload_bytes: usize) -> Result<(), String> {
    let mut needed: u128 = 0;
    for element in header.elements.values() {
        if element.count > 0 && element.properties.is_empty() {
            return Err(format!(
                "element '{}' has {} entries but no properties",
                element.name, element.count
            ));
        }
        // The fewest bytes one entry takes: binary, each scalar's size and each list's count;
        // ASCII, one character and one separator per value.
        let entry: u128 = match header.encoding {
            Encoding::Ascii => 2 * element.properties.len() as u128,
            _ => element
                .properties
                .values()
                .map(|p| match &p.data_type {
                    PropertyType::Scalar(t) | PropertyType::List(t, _) => scalar_size(t),
                })
                .sum(),
        };
        needed += entry * element.count as u128;
    }
    if needed > payload_bytes as u128 {
        return Err(format!(
            "the header promises at least {needed} bytes of data, the file holds {payload_bytes}"
        ));
    }
    Ok(())
}

fn scalar_size(scalar: &ScalarType) -> u128 {
    match scalar {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

fn load_ply(bytes: &[u8], name: &str) -> Result<Mesh, MeshLoadError> {
    let parse_error = ply_error(name);
    let (vertices, faces) = read_ply::<VertexRecord, FaceRecord>(bytes, name)?;
    let (definition, vertices) =
        vertices.ok_or_else(|| parse_error("no 'vertex' element".into()))?;
    // A record's values are its scalar properties in the header's order.
    let scalars: Vec<&str> = definition
        .properties
        .values()
        .filter(|p| matches!(p.data_type, PropertyType::Scalar(_)))
        .map(|p| p.name.as_str())
        .collect();
    let column = |name: &str| -> Result<Vec<f64>, MeshLoadError> {
        let at = slot(&scalars, name);
        vertices
            .iter()
            .enumerate()
            .map(|(index, vertex)| {
                at.and_then(|at| vertex.0.get(at).copied()).ok_or_else(|| {
                    parse_error(format!("vertex {index} has no numeric '{name}' property"))
                })
            })
            .collect()
    };
    let mut mesh = Mesh::default();
    let [xs, ys, zs] = [column("x")?, column("y")?, column("z")?];
    mesh.positions = (0..vertices.len())
        .map(|i| DVec3::new(xs[i], ys[i], zs[i]))
        .collect();
    // Texture coordinates: the first pair of `UV_NAMES` the vertices have; every other scalar
    // property is kept by name in `mesh.vertex_properties`.
    let uv_pair = UV_NAMES
        .iter()
        .find(|pair| pair.iter().all(|n| scalars.contains(n)));
    let mut per_vertex_uvs = match uv_pair {
        Some([u, v]) => {
            let (us, vs) = (column(u)?, column(v)?);
            Some(us.into_iter().zip(vs).map(|(u, v)| [u, v]).collect())
        }
        None => None,
    };
    for &name in &scalars {
        let is_uv = uv_pair.is_some_and(|pair| pair.contains(&name));
        if !is_uv && !["x", "y", "z"].contains(&name) {
            mesh.vertex_properties
                .insert(name.to_owned(), column(name)?);
        }
    }

    let faces = faces.ok_or_else(|| parse_error("no 'face' element".into()))?;
    for (index, face) in faces.iter().enumerate() {
        let polygon = match &face.indices {
            Some(Ok(polygon)) => polygon,
            Some(Err(())) => {
                return Err(parse_error(format!(
                    "face {index}: 'vertex_indices' must be a list of non-negative integers"
                )));
            }
            None => {
                return Err(parse_error(format!(
                    "face {index} has no 'vertex_indices' list"
                )));
            }
        };
        if polygon.len() < 3 {
            return Err(parse_error(format!(
                "face {index} has {} vertices; a face needs at least 3",
                polygon.len()
            )));
        }
        fan_triangulate(polygon, &mut mesh.triangles);
    }
    if let Some(coordinates) = per_vertex_uvs.take() {
        mesh.uvs = Some(TextureCoordinates::per_vertex(coordinates, &mesh.triangles));
    }
    Ok(mesh)
}

/// The names a PLY vertex's texture coordinates go by, in the order they are looked for
/// (Blender and MeshLab write `s t`; others `u v` or `texture_u texture_v`).
const UV_NAMES: [[&str; 2]; 4] = [
    ["s", "t"],
    ["u", "v"],
    ["texture_u", "texture_v"],
    ["texture_s", "texture_t"],
];

/// A PLY vertex as read: its scalar properties in the order of the header (the parser sets
/// them in that order), each as a float64; lists are passed over.
struct VertexRecord(Vec<f64>);

impl PropertyAccess for VertexRecord {
    fn new() -> Self {
        Self(Vec::new())
    }

    fn set_property(&mut self, _name: &str, property: Property) -> PropertyAccessResult {
        match scalar_as_f64(&property) {
            Some(value) => {
                self.0.push(value);
                PropertyAccessResult::Set
            }
            None => PropertyAccessResult::Ignored,
        }
    }
}

/// A PLY face as read: its `vertex_indices` (or, without one, `vertex_index`) list, or
/// `Err` if that list holds something other than non-negative integers.
struct FaceRecord {
    indices: Option<Result<Vec<u32>, ()>>,
}

impl FaceRecord {
    /// Whether a list named `name` is the face's indices.
    fn takes(&self, name: &str) -> bool {
        name == "vertex_indices" || (name == "vertex_index" && self.indices.is_none())
    }
}

impl PropertyAccess for FaceRecord {
    fn new() -> Self {
        Self { indices: None }
    }

    fn set_property(&mut self, name: &str, property: Property) -> PropertyAccessResult {
        if !self.takes(name) {
            return PropertyAccessResult::Ignored;
        }
        self.indices = Some(list_as_indices(&property).ok_or(()));
        PropertyAccessResult::Set
    }

    /// Unsigned 32-bit indices, the common case, go straight into the face's list.
    fn begin_list_uint(&mut self, name: &str, _len: usize) -> BeginList<'_, u32> {
        if !self.takes(name) {
            return BeginList::UseSetter;
        }
        match self.indices.insert(Ok(Vec::new())) {
            Ok(list) => BeginList::Fill(list),
            Err(()) => BeginList::UseSetter,
        }
    }
}

/// An element hooke does not read.
struct SkippedRecord;

impl PropertyAccess for SkippedRecord {
    fn new() -> Self {
        Self
    }
}

fn scalar_as_f64(property: &Property) -> Option<f64> {
    Some(match *property {
        Property::Float(v) => f64::from(v),
        Property::Double(v) => v,
        Property::Char(v) => f64::from(v),
        Property::UChar(v) => f64::from(v),
        Property::Short(v) => f64::from(v),
        Property::UShort(v) => f64::from(v),
        Property::Int(v) => f64::from(v),
        Property::UInt(v) => f64::from(v),
        _ => return None,
    })
}

fn list_as_indices(property: &Property) -> Option<Vec<u32>> {
    fn convert<T: Copy + TryInto<u32>>(values: &[T]) -> Option<Vec<u32>> {
        values.iter().map(|v| (*v).try_into().ok()).collect()
    }
    match property {
        Property::ListChar(v) => convert(v),
        Property::ListUChar(v) => convert(v),
        Property::ListShort(v) => convert(v),
        Property::ListUShort(v) => convert(v),
        Property::ListInt(v) => convert(v),
        Property::ListUInt(v) => convert(v),
        _ => None,
    }
}

/// Reads a state written by [`write_ply_state`]: per vertex `x y z prev_x prev_y prev_z`.
pub fn read_ply_state(path: &Path) -> Result<crate::State, MeshLoadError> {
    let name = path.display().to_string();
    let bytes = crate::input_file::read(path).map_err(io_error(&name))?;
    let parse_error = ply_error(&name);
    let (vertices, _) = read_ply::<ReadStateVertex, SkippedRecord>(&bytes, &name)?;
    let (_, vertices) = vertices.ok_or_else(|| parse_error("no 'vertex' element".into()))?;
    let mut state = crate::State {
        positions: Vec::with_capacity(vertices.len()),
        previous_positions: Vec::with_capacity(vertices.len()),
    };
    for (index, vertex) in vertices.iter().enumerate() {
        let mut values = [0.0; 6];
        for ((value, read), name) in values.iter_mut().zip(vertex.0).zip(StateVertex::NAMES) {
            *value = read.filter(|x| x.is_finite()).ok_or_else(|| {
                parse_error(format!(
                    "vertex {index} has no finite '{name}' property (a hooke state file has x y z prev_x prev_y prev_z)"
                ))
            })?;
        }
        let [x, y, z, px, py, pz] = values;
        state.positions.push(DVec3::new(x, y, z));
        state.previous_positions.push(DVec3::new(px, py, pz));
    }
    Ok(state)
}

/// A state file's vertex as read: each of [`StateVertex::NAMES`] if the file has it, of any
/// scalar type.
struct ReadStateVertex([Option<f64>; 6]);

impl PropertyAccess for ReadStateVertex {
    fn new() -> Self {
        Self([None; 6])
    }

    fn set_property(&mut self, name: &str, property: Property) -> PropertyAccessResult {
        match slot(&StateVertex::NAMES, name) {
            Some(slot) => {
                self.0[slot] = scalar_as_f64(&property);
                PropertyAccessResult::Set
            }
            None => PropertyAccessResult::Ignored,
        }
    }
}

/// Writes one simulation frame (float32 positions + faces) as binary PLY, atomically, with
/// texture coordinates `s t` when each vertex has one.
pub fn write_ply_frame(
    path: &Path,
    positions: &[DVec3],
    triangles: &[[u32; 3]],
    uvs: Option<&TextureCoordinates>,
) -> std::io::Result<()> {
    let per_vertex = uvs
        .filter(|uvs| uvs.is_per_vertex(triangles, positions.len()))
        .map(|uvs| uvs.coordinates.as_slice());
    let names: &[&str] = if per_vertex.is_some() {
        &FrameVertex::NAMES
    } else {
        &FrameVertex::NAMES[..3]
    };
    let vertices = positions
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let [s, t] = per_vertex.map(|c| c[i]).unwrap_or_default();
            FrameVertex([p.x, p.y, p.z, s, t].map(|value| value as f32))
        })
        .collect();
    write_ply(path, names, ScalarType::Float, &vertices, triangles)
}

/// Writes a resumable state (float64 current and previous positions + faces) as binary PLY, atomically.
pub fn write_ply_state(
    path: &Path,
    positions: &[DVec3],
    previous_positions: &[DVec3],
    triangles: &[[u32; 3]],
) -> std::io::Result<()> {
    let vertices = positions
        .iter()
        .zip(previous_positions)
        .map(|(p, q)| StateVertex([p.x, p.y, p.z, q.x, q.y, q.z]))
        .collect();
    write_ply(
        path,
        &StateVertex::NAMES,
        ScalarType::Double,
        &vertices,
        triangles,
    )
}

/// A written frame's vertex: `x y z s t` (the last two only where the header has them).
///
/// Written through typed elements, not `DefaultElement`s (a map of named properties per
/// vertex): a 512^2 frame took 0.37-0.54 s that way, most of it building and freeing the maps,
/// and now 42-65 ms.
struct FrameVertex([f32; 5]);

impl FrameVertex {
    const NAMES: [&str; 5] = ["x", "y", "z", "s", "t"];
}

impl PropertyAccess for FrameVertex {
    fn new() -> Self {
        Self([0.0; 5])
    }

    fn get_float(&self, name: &str) -> Option<f32> {
        Some(self.0[slot(&Self::NAMES, name)?])
    }
}

/// A written state's vertex: `x y z prev_x prev_y prev_z`.
struct StateVertex([f64; 6]);

impl StateVertex {
    const NAMES: [&str; 6] = ["x", "y", "z", "prev_x", "prev_y", "prev_z"];
}

impl PropertyAccess for StateVertex {
    fn new() -> Self {
        Self([0.0; 6])
    }

    fn get_double(&self, name: &str) -> Option<f64> {
        Some(self.0[slot(&Self::NAMES, name)?])
    }
}

/// Where property `name` is among a record's `names`.
fn slot(names: &[&str], name: &str) -> Option<usize> {
    names.iter().position(|n| *n == name)
}

/// A written triangle: `vertex_indices`.
struct Face([u32; 3]);

impl PropertyAccess for Face {
    fn new() -> Self {
        Self([0; 3])
    }

    fn get_list_uint(&self, name: &str) -> Option<&[u32]> {
        (name == "vertex_indices").then_some(&self.0[..])
    }
}

/// Writes binary PLY: a vertex element of the `vertex_properties` (each of type `scalar`),
/// then a face element of `triangles`. (`&Vec`: what the crate's element writer takes.)
fn write_ply<V: PropertyAccess>(
    path: &Path,
    vertex_properties: &[&str],
    scalar: ScalarType,
    vertices: &Vec<V>,
    triangles: &[[u32; 3]],
) -> std::io::Result<()> {
    let mut header = Header::new();
    header.encoding = Encoding::BinaryLittleEndian;
    header.comments.push("written by hooke".to_owned());
    let mut vertex = ElementDef::new("vertex".to_owned());
    vertex.count = vertices.len();
    for name in vertex_properties {
        vertex.properties.add(PropertyDef::new(
            (*name).to_owned(),
            PropertyType::Scalar(scalar.clone()),
        ));
    }
    let mut face = ElementDef::new("face".to_owned());
    face.count = triangles.len();
    face.properties.add(PropertyDef::new(
        "vertex_indices".to_owned(),
        PropertyType::List(ScalarType::UChar, ScalarType::UInt),
    ));
    header.elements.add(vertex.clone());
    header.elements.add(face.clone());
    let faces: Vec<Face> = triangles.iter().map(|&t| Face(t)).collect();
    crate::atomic_file::write_atomically(path, |writer| {
        let out = &mut &mut *writer;
        Writer::<V>::new().write_header(out, &header)?;
        Writer::<V>::new().write_payload_of_element(out, vertices, &vertex, &header)?;
        Writer::<Face>::new().write_payload_of_element(out, &faces, &face, &header)?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{GridPlane, grid};

    fn write(dir: &tempfile::TempDir, name: &str, text: &str) -> std::path::PathBuf {
        let path = dir.path().join(name);
        std::fs::write(&path, text).expect("write test file");
        path
    }

    #[test]
    fn obj_quads_are_fan_triangulated() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = write(
            &dir,
            "quad.obj",
            "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nf 1 2 3 4\n",
        );
        let (mesh, warnings) = load_mesh(&path).expect("loads");
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert!(warnings.is_empty());
    }

    #[test]
    fn obj_out_of_range_face_names_file_and_line() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = write(
            &dir,
            "bad.obj",
            "v 0 0 0\nv 1 0 0\nv 1 0 1\n# c\nf 1 2 3\nf 1 2 9\n",
        );
        let message = load_mesh(&path).unwrap_err().to_string();
        assert!(message.contains("bad.obj line 6"), "{message}");
    }

    #[test]
    fn obj_nan_vertex_is_named() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = write(&dir, "nan.obj", "v 0 0 0\nv nan 0 0\nv 1 0 1\nf 1 2 3\n");
        let message = load_mesh(&path).unwrap_err().to_string();
        assert!(
            message.contains("nan.obj") && message.contains("vertex 1"),
            "{message}"
        );
    }

    #[test]
    fn ascii_ply_loads_and_bad_index_is_reported() {
        let dir = tempfile::tempdir().expect("tempdir");
        let header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
        let path = write(
            &dir,
            "ok.ply",
            &format!("{header}0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"),
        );
        let (mesh, _) = load_mesh(&path).expect("loads");
        assert_eq!(mesh.triangles, vec![[0, 1, 2]]);
        let path = write(
            &dir,
            "bad.ply",
            &format!("{header}0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n"),
        );
        let message = load_mesh(&path).unwrap_err().to_string();
        assert!(
            message.contains("bad.ply: triangle 0 uses vertex index 7"),
            "{message}"
        );
    }

    #[test]
    fn ply_elements_lists_and_index_names_of_other_writers_are_read() {
        let dir = tempfile::tempdir().expect("tempdir");
        // A list on the vertices before a scalar, an element hooke does not read between
        // them and the faces, `vertex_index`, and a quad: the scalars keep their names.
        let text = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\n\
                    property list uchar int flags\nproperty double y\nproperty short z\n\
                    property uchar quality\nelement edge 1\nproperty int vertex1\n\
                    property int vertex2\nelement face 1\nproperty uchar tag\n\
                    property list uchar short vertex_index\nend_header\n\
                    0 2 7 7 0 0 10\n1 0 0 0 11\n1 0 1 0 12\n0 0 1 0 13\n0 1\n5 4 0 1 2 3\n";
        let (mesh, _) = load_mesh(&write(&dir, "other.ply", text)).expect("loads");
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(mesh.positions[2], DVec3::new(1.0, 1.0, 0.0));
        assert_eq!(
            mesh.vertex_properties["quality"],
            vec![10.0, 11.0, 12.0, 13.0]
        );
        // A negative index, or indices that are not integers, name the face.
        let lists = [
            ("list uchar int", "negative.ply", "face 1"),
            ("list uchar float", "float.ply", "face 0"),
        ];
        for (list, name, face) in lists {
            let text = format!(
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                 property float z\nelement face 2\nproperty {list} vertex_indices\nend_header\n\
                 0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 -1 2\n"
            );
            let message = load_mesh(&write(&dir, name, &text))
                .unwrap_err()
                .to_string();
            assert!(
                message.contains(name)
                    && message.contains(face)
                    && message.contains("non-negative"),
                "{message}"
            );
        }
        // No index list at all.
        let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                    property float z\nelement face 1\nproperty uchar tag\nend_header\n\
                    0 0 0\n1 0 0\n0 1 0\n3\n";
        let message = load_mesh(&write(&dir, "none.ply", text))
            .unwrap_err()
            .to_string();
        assert!(
            message.contains("face 0 has no 'vertex_indices' list"),
            "{message}"
        );
    }

    #[test]
    fn ply_texture_coordinates_and_other_vertex_properties_are_kept() {
        let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                    property float z\nproperty float u\nproperty float v\nproperty double stiffness\n\
                    property uchar red\nelement face 1\nproperty list uchar int vertex_indices\n\
                    end_header\n0 0 0 0 0 2.5 255\n1 0 0 1 0 1 0\n0 1 0 0 1 1 7\n3 0 1 2\n";
        let (mesh, _) = parse_mesh(text.as_bytes(), MeshFormat::Ply, "uv.ply").expect("loads");
        let uvs = mesh.uvs.expect("u v");
        assert_eq!(uvs.coordinates, vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]);
        assert!(uvs.is_per_vertex(&mesh.triangles, 3));
        assert_eq!(mesh.vertex_properties["stiffness"], vec![2.5, 1.0, 1.0]);
        assert_eq!(mesh.vertex_properties["red"], vec![255.0, 0.0, 7.0]);
        assert_eq!(mesh.vertex_properties.len(), 2, "x y z u v are not extra");
    }

    #[test]
    fn truncated_binary_ply_is_an_error_not_a_panic() {
        let dir = tempfile::tempdir().expect("tempdir");
        let mesh = grid(3, 3, [1.0, 1.0], GridPlane::Xz, DVec3::ZERO);
        let path = dir.path().join("frame.ply");
        write_ply_frame(&path, &mesh.positions, &mesh.triangles, None).expect("write");
        let bytes = std::fs::read(&path).expect("read");
        std::fs::write(&path, &bytes[..bytes.len() - 7]).expect("truncate");
        assert!(load_mesh(&path).is_err());
    }

    #[test]
    fn binary_ply_frame_round_trips() {
        let dir = tempfile::tempdir().expect("tempdir");
        let mesh = grid(4, 3, [1.0, 1.0], GridPlane::Xz, DVec3::ZERO);
        let path = dir.path().join("frame.ply");
        write_ply_frame(&path, &mesh.positions, &mesh.triangles, mesh.uvs.as_ref()).expect("write");
        let (loaded, _) = load_mesh(&path).expect("read back");
        assert_eq!(loaded.triangles, mesh.triangles);
        let (written, read) = (mesh.uvs.expect("a grid has UVs"), loaded.uvs.expect("s t"));
        for (a, b) in written.coordinates.iter().zip(&read.coordinates) {
            assert!((a[0] - b[0]).abs() < 1e-7 && (a[1] - b[1]).abs() < 1e-7);
        }
        assert_eq!(read.corners, mesh.triangles);
        for (a, b) in loaded.positions.iter().zip(&mesh.positions) {
            // Frames store float32: exact to f32 rounding of values of order 1.
            assert!((*a - *b).length() < 1e-6);
        }
        let names: Vec<_> = std::fs::read_dir(dir.path()).expect("list").collect();
        assert_eq!(names.len(), 1, "no temporary file left behind");
    }

    #[test]
    fn a_state_reads_back_bit_for_bit_and_a_file_without_one_is_refused_by_name() {
        let dir = tempfile::tempdir().expect("tempdir");
        let mesh = grid(5, 4, [1.0, 1.0], GridPlane::Xz, DVec3::ZERO);
        let previous: Vec<DVec3> = mesh.positions.iter().map(|p| *p * 0.1 + 1e-9).collect();
        let path = dir.path().join("state.ply");
        write_ply_state(&path, &mesh.positions, &previous, &mesh.triangles).expect("write");
        let state = read_ply_state(&path).expect("read");
        assert_eq!(state.positions, mesh.positions);
        assert_eq!(state.previous_positions, previous);
        // A frame has positions but no previous ones.
        let frame = dir.path().join("frame.ply");
        write_ply_frame(&frame, &mesh.positions, &mesh.triangles, None).expect("write");
        let error = read_ply_state(&frame).expect_err("no prev_x").to_string();
        assert!(
            error.contains("frame.ply") && error.contains("vertex 0") && error.contains("prev_x"),
            "{error}"
        );
        // A value that is not finite is named.
        let mut broken = previous.clone();
        broken[3].y = f64::NAN;
        write_ply_state(&path, &mesh.positions, &broken, &mesh.triangles).expect("write");
        let error = read_ply_state(&path).expect_err("nan").to_string();
        assert!(
            error.contains("vertex 3") && error.contains("'prev_y'"),
            "{error}"
        );
        // Any scalar type is read.
        let text = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
                    property int z\nproperty float prev_x\nproperty float prev_y\n\
                    property float prev_z\nend_header\n0 1 2 3 4 5\n0 1.5 2 3 4 5\n";
        let state = read_ply_state(&write(&dir, "ascii.ply", text)).expect("floats");
        assert_eq!(state.positions[1], DVec3::new(0.0, 1.5, 2.0));
        assert_eq!(state.previous_positions[0], DVec3::new(3.0, 4.0, 5.0));
    }

    #[test]
    fn a_header_promising_more_than_the_file_holds_is_refused_before_reading() {
        let header = |count: &str| {
            format!(
                "ply\nformat binary_little_endian 1.0\nelement vertex {count}\nproperty float x\n\
                 property float y\nproperty float z\nelement face 0\n\
                 property list uchar int vertex_indices\nend_header\n"
            )
        };
        let mut bytes = header("4000000000").into_bytes();
        bytes.extend_from_slice(&[0; 12]);
        let message = parse_mesh(&bytes, MeshFormat::Ply, "big.ply")
            .unwrap_err()
            .to_string();
        assert!(
            message.contains("big.ply") && message.contains("promises at least 48000000000 bytes"),
            "{message}"
        );
        // An element of no properties takes no bytes, so only its count could stop a reader.
        let empty = "ply\nformat ascii 1.0\nelement fax 91111111111\nend_header\n";
        let message = parse_mesh(empty.as_bytes(), MeshFormat::Ply, "fax.ply")
            .unwrap_err()
            .to_string();
        assert!(message.contains("element 'fax'"), "{message}");
    }

    #[test]
    fn unknown_extension_is_rejected() {
        let err = load_mesh(Path::new("cloth.stl")).unwrap_err();
        assert_eq!(
            err.to_string(),
            "cloth.stl: unsupported mesh format (expected .obj or .ply)"
        );
    }
}
