//! Triangle meshes: the surface a mass-spring system is built from.
//!
//! A [`Mesh`] is a flat list of vertex positions (metres) and triangles (vertex indices).
//! Its unique edges become springs (paper Section 2), its vertices point masses. What the
//! simulation does not use but output needs is carried along: texture coordinates (written to
//! OBJ and USD frames) and the file's other per-vertex numbers (which a scene can turn into
//! masses or stiffnesses).

mod generate;
mod io;
mod obj;

pub use generate::{GridPlane, grid, irregular};
pub use io::{
    MeshFormat, MeshLoadError, load_mesh, parse_mesh, read_ply_state, write_ply_frame,
    write_ply_state,
};
pub use obj::ObjError;

use std::collections::BTreeMap;

use glam::DVec3;

/// A triangulated surface.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions in metres; length `n_vertices`.
    pub positions: Vec<DVec3>,
    /// Triangles as indices into `positions`; length `n_triangles`.
    pub triangles: Vec<[u32; 3]>,
    /// Texture coordinates, if the file had them (or the generator made them).
    pub uvs: Option<TextureCoordinates>,
    /// The file's other numeric per-vertex properties by name (a PLY `property float stiffness`,
    /// say), each of length `n_vertices`.
    pub vertex_properties: BTreeMap<String, Vec<f64>>,
}

/// Texture coordinates kept as the file has them: per triangle corner an index into
/// `coordinates`, so a seam (one vertex, a UV on each side) survives.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TextureCoordinates {
    /// `(u, v)` pairs.
    pub coordinates: Vec<[f64; 2]>,
    /// Per triangle, the coordinates of its three corners (indices into `coordinates`);
    /// length `n_triangles`.
    pub corners: Vec<[u32; 3]>,
}

impl TextureCoordinates {
    /// One UV per vertex (PLY `s t`): vertex `i` has `coordinates[i]`.
    pub fn per_vertex(coordinates: Vec<[f64; 2]>, triangles: &[[u32; 3]]) -> Self {
        Self {
            coordinates,
            corners: triangles.to_vec(),
        }
    }

    /// Whether every vertex has one UV, `coordinates[vertex]` (USD's "vertex" interpolation,
    /// PLY's `s t`), rather than one per triangle corner ("faceVarying").
    pub fn is_per_vertex(&self, triangles: &[[u32; 3]], vertex_count: usize) -> bool {
        self.coordinates.len() == vertex_count && self.corners == triangles
    }
}

/// Something wrong with a mesh that makes it unusable as a mass-spring system.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MeshError {
    #[error("{source_name}: mesh has no triangles")]
    Empty { source_name: String },
    #[error(
        "{source_name}: triangle {triangle} uses vertex index {index}, out of range (mesh has {vertex_count} vertices)"
    )]
    IndexOutOfRange {
        source_name: String,
        triangle: usize,
        index: u32,
        vertex_count: usize,
    },
    #[error("{source_name}: vertex {vertex} has a non-finite coordinate {position:?}")]
    NonFiniteVertex {
        source_name: String,
        vertex: usize,
        position: [f64; 3],
    },
    #[error("{source_name}: triangle {triangle} is degenerate ({reason})")]
    DegenerateTriangle {
        source_name: String,
        triangle: usize,
        reason: String,
    },
    #[error("{source_name}: texture coordinates: {message}")]
    TextureCoordinates {
        source_name: String,
        message: String,
    },
    #[error(
        "{source_name}: vertex property '{name}' has {found} values for {vertex_count} vertices"
    )]
    VertexPropertyLength {
        source_name: String,
        name: String,
        found: usize,
        vertex_count: usize,
    },
    #[error(
        "{source_name}: edge {a}-{b} has zero length (both vertices at {position:?}); a spring needs a rest length"
    )]
    ZeroLengthEdge {
        source_name: String,
        a: u32,
        b: u32,
        position: [f64; 3],
    },
}

/// A property of a mesh that is allowed but worth telling the user about.
#[derive(Clone, Debug, PartialEq)]
pub enum MeshWarning {
    /// An edge shared by more than two triangles; its spring is still created once.
    NonManifoldEdge { a: u32, b: u32, triangle_count: u32 },
    /// Vertices no triangle uses: free point masses without springs.
    UnreferencedVertices { count: usize, first: u32 },
    /// Some faces have texture coordinates and some have none, so the mesh has none.
    PartialTextureCoordinates { triangles_without: usize },
}

impl std::fmt::Display for MeshWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NonManifoldEdge {
                a,
                b,
                triangle_count,
            } => write!(
                f,
                "edge {a}-{b} is non-manifold (shared by {triangle_count} triangles)"
            ),
            Self::UnreferencedVertices { count, first } => write!(
                f,
                "{count} vertices are used by no triangle (first: vertex {first}); they fall freely"
            ),
            Self::PartialTextureCoordinates { triangles_without } => write!(
                f,
                "{triangles_without} triangles have no texture coordinates while others do; the output will have no UVs"
            ),
        }
    }
}

/// The undirected edge `{p, q}` as one sortable number: the lower index in the high half.
fn edge_key(p: u32, q: u32) -> u64 {
    (u64::from(p.min(q)) << 32) | u64::from(p.max(q))
}

/// Axis-aligned bounding box `(min, max)` of points.
pub fn bounds(points: &[DVec3]) -> (DVec3, DVec3) {
    points.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    )
}

/// The axes (0 = x, 1 = y, 2 = z) from the longest `extent` to the shortest: a sheet lies in
/// the plane of the first two.
pub fn axes_by_extent(extent: DVec3) -> [usize; 3] {
    let mut axes = [0usize, 1, 2];
    axes.sort_by(|a, b| extent[*b].total_cmp(&extent[*a]));
    axes
}

/// A unique undirected edge `a < b` and how many triangles share it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Edge {
    pub a: u32,
    pub b: u32,
    pub triangle_count: u32,
}

/// A bending spring's two vertices (`far`, sorted) and the edge it crosses (`across`, sorted).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct BendingPair {
    pub far: [u32; 2],
    pub across: [u32; 2],
}

/// Twice the area below which a triangle counts as degenerate, relative to its longest edge squared.
/// A sliver this thin has no meaningful normal and makes its springs nearly collinear.
const DEGENERATE_AREA_RATIO: f64 = 1e-12;

impl Mesh {
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Unique undirected edges, sorted by `(a, b)`, derived by sorting the triangles' edge keys.
    pub fn edges(&self) -> Vec<Edge> {
        let mut keys: Vec<u64> = Vec::with_capacity(self.triangles.len() * 3);
        for t in &self.triangles {
            for (p, q) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                keys.push(edge_key(p, q));
            }
        }
        keys.sort_unstable();
        let mut edges: Vec<Edge> = Vec::with_capacity(keys.len() / 2 + 1);
        for key in keys {
            let (a, b) = ((key >> 32) as u32, key as u32);
            match edges.last_mut() {
                Some(last) if last.a == a && last.b == b => last.triangle_count += 1,
                _ => edges.push(Edge {
                    a,
                    b,
                    triangle_count: 1,
                }),
            }
        }
        edges
    }

    /// The far vertices of every two triangles that share an edge, as sorted pairs, each once,
    /// with the edge they cross: the classic distance-2 bending springs, which resist folding
    /// across that edge. Pairs an edge already joins (or that name one vertex twice) are left
    /// out; an edge shared by more than two triangles pairs every two of them; a pair that
    /// crosses two edges keeps the first.
    pub fn bending_pairs(&self) -> Vec<BendingPair> {
        // (edge key, far vertex) per triangle corner, sorted so an edge's triangles are adjacent.
        let mut opposite: Vec<(u64, u32)> = Vec::with_capacity(self.triangles.len() * 3);
        for t in &self.triangles {
            for k in 0..3 {
                let (p, q, far) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
                opposite.push((edge_key(p, q), far));
            }
        }
        opposite.sort_unstable();
        let edges: std::collections::HashSet<u64> = opposite.iter().map(|(e, _)| *e).collect();
        let mut pairs: Vec<BendingPair> = Vec::new();
        for shared in opposite.chunk_by(|x, y| x.0 == y.0) {
            for (i, &(key, c)) in shared.iter().enumerate() {
                for &(_, d) in &shared[i + 1..] {
                    if c != d && !edges.contains(&edge_key(c, d)) {
                        pairs.push(BendingPair {
                            far: [c.min(d), c.max(d)],
                            across: [(key >> 32) as u32, key as u32],
                        });
                    }
                }
            }
        }
        pairs.sort_unstable();
        pairs.dedup_by_key(|p| p.far);
        pairs
    }

    /// Checks that the mesh can be simulated; `source_name` (a file name or generator) is put in every message.
    pub fn validate(&self, source_name: &str) -> Result<Vec<MeshWarning>, MeshError> {
        let source_name = source_name.to_owned();
        if self.triangles.is_empty() {
            return Err(MeshError::Empty { source_name });
        }
        if let Some((vertex, p)) = self
            .positions
            .iter()
            .enumerate()
            .find(|(_, p)| !p.is_finite())
        {
            return Err(MeshError::NonFiniteVertex {
                source_name,
                vertex,
                position: p.to_array(),
            });
        }
        let vertex_count = self.positions.len();
        let mut referenced = vec![false; vertex_count];
        for (triangle, t) in self.triangles.iter().enumerate() {
            if let Some(&index) = t.iter().find(|&&i| i as usize >= vertex_count) {
                return Err(MeshError::IndexOutOfRange {
                    source_name,
                    triangle,
                    index,
                    vertex_count,
                });
            }
            if t[0] == t[1] || t[1] == t[2] || t[2] == t[0] {
                return Err(MeshError::DegenerateTriangle {
                    source_name,
                    triangle,
                    reason: format!("repeats a vertex: {t:?}"),
                });
            }
            let [p0, p1, p2] = t.map(|i| self.positions[i as usize]);
            for (a, b, pa, pb) in [
                (t[0], t[1], p0, p1),
                (t[1], t[2], p1, p2),
                (t[2], t[0], p2, p0),
            ] {
                if pa == pb {
                    return Err(MeshError::ZeroLengthEdge {
                        source_name,
                        a: a.min(b),
                        b: a.max(b),
                        position: pa.to_array(),
                    });
                }
            }
            let longest_squared = (p1 - p0)
                .length_squared()
                .max((p2 - p1).length_squared())
                .max((p0 - p2).length_squared());
            let twice_area = (p1 - p0).cross(p2 - p0).length();
            if twice_area <= DEGENERATE_AREA_RATIO * longest_squared {
                return Err(MeshError::DegenerateTriangle {
                    source_name,
                    triangle,
                    reason: format!(
                        "its vertices {t:?} are collinear (area {:.3e} m^2)",
                        twice_area / 2.0
                    ),
                });
            }
            for &i in t {
                referenced[i as usize] = true;
            }
        }
        self.validate_extras(&source_name)?;
        let mut warnings: Vec<MeshWarning> = self
            .edges()
            .into_iter()
            .filter(|e| e.triangle_count > 2)
            .map(|e| MeshWarning::NonManifoldEdge {
                a: e.a,
                b: e.b,
                triangle_count: e.triangle_count,
            })
            .collect();
        let unreferenced = referenced.iter().filter(|r| !**r).count();
        if let Some(first) = referenced.iter().position(|r| !r) {
            warnings.push(MeshWarning::UnreferencedVertices {
                count: unreferenced,
                first: first as u32,
            });
        }
        Ok(warnings)
    }

    /// Checks the texture coordinates and vertex properties against the triangles and vertices.
    fn validate_extras(&self, source_name: &str) -> Result<(), MeshError> {
        let vertex_count = self.positions.len();
        for (name, values) in &self.vertex_properties {
            if values.len() != vertex_count {
                return Err(MeshError::VertexPropertyLength {
                    source_name: source_name.to_owned(),
                    name: name.clone(),
                    found: values.len(),
                    vertex_count,
                });
            }
        }
        let Some(uvs) = &self.uvs else {
            return Ok(());
        };
        let error = |message: String| MeshError::TextureCoordinates {
            source_name: source_name.to_owned(),
            message,
        };
        if uvs.corners.len() != self.triangles.len() {
            return Err(error(format!(
                "{} triangles have UVs, the mesh has {}",
                uvs.corners.len(),
                self.triangles.len()
            )));
        }
        if let Some(k) = uvs
            .coordinates
            .iter()
            .position(|c| !c.iter().all(|x| x.is_finite()))
        {
            return Err(error(format!(
                "coordinate {k} is not finite: {:?}",
                uvs.coordinates[k]
            )));
        }
        let count = uvs.coordinates.len();
        if let Some((triangle, index)) = uvs
            .corners
            .iter()
            .enumerate()
            .find_map(|(t, c)| c.iter().find(|i| **i as usize >= count).map(|i| (t, *i)))
        {
            return Err(error(format!(
                "triangle {triangle} uses coordinate {index}, out of range (there are {count})"
            )));
        }
        Ok(())
    }

    /// The same surface with vertex `k` being this mesh's vertex `order[k]` (`order` a
    /// permutation): triangles and vertex properties follow; texture coordinates stay per
    /// corner, so they still fit.
    pub fn renumbered(&self, order: &[u32]) -> Mesh {
        let mut new_index = vec![0u32; order.len()];
        for (k, &old) in order.iter().enumerate() {
            new_index[old as usize] = k as u32;
        }
        let permute = |values: &Vec<f64>| order.iter().map(|&i| values[i as usize]).collect();
        Mesh {
            positions: order.iter().map(|&i| self.positions[i as usize]).collect(),
            triangles: self
                .triangles
                .iter()
                .map(|t| t.map(|i| new_index[i as usize]))
                .collect(),
            uvs: self.uvs.clone(),
            vertex_properties: self
                .vertex_properties
                .iter()
                .map(|(name, values)| (name.clone(), permute(values)))
                .collect(),
        }
    }

    /// The same surface with its vertices in a random order (seeded): what a mesh exported
    /// from a tool that does not care about locality looks like.
    pub fn shuffled(&self, seed: u64) -> Mesh {
        use rand::SeedableRng;
        use rand::seq::SliceRandom;
        let mut order: Vec<u32> = (0..self.positions.len() as u32).collect();
        order.shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(seed));
        self.renumbered(&order)
    }

    /// Per-vertex valence (number of unique incident edges).
    pub fn valences(&self) -> Vec<u32> {
        let mut valence = vec![0u32; self.positions.len()];
        for e in self.edges() {
            valence[e.a as usize] += 1;
            valence[e.b as usize] += 1;
        }
        valence
    }

    /// Area of each triangle in m^2.
    pub fn triangle_areas(&self) -> Vec<f64> {
        self.triangles
            .iter()
            .map(|t| {
                let [p0, p1, p2] = t.map(|i| self.positions[i as usize]);
                0.5 * (p1 - p0).cross(p2 - p0).length()
            })
            .collect()
    }

    /// Axis-aligned bounding box `(min, max)`.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        bounds(&self.positions)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> Mesh {
        Mesh {
            positions: vec![
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(1.0, 0.0, 1.0),
                DVec3::new(0.0, 0.0, 1.0),
            ],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            ..Mesh::default()
        }
    }

    #[test]
    fn bending_pairs_join_the_far_corners_across_each_shared_edge() {
        // Two triangles sharing the diagonal 0-2: one pair, across it.
        assert_eq!(
            square().bending_pairs(),
            [BendingPair {
                far: [1, 3],
                across: [0, 2]
            }]
        );
        // On a grid every interior edge gives one pair, none of them an edge.
        let sheet = grid(6, 5, [1.0, 1.0], GridPlane::Xz, DVec3::ZERO);
        let edges = sheet.edges();
        let interior = edges.iter().filter(|e| e.triangle_count == 2).count();
        let pairs = sheet.bending_pairs();
        assert_eq!(pairs.len(), interior);
        assert!(pairs.iter().all(|p| {
            let [a, b] = p.far;
            a < b && !edges.iter().any(|e| (e.a, e.b) == (a, b))
        }));
        // Each crosses an interior edge, between its two far corners.
        assert!(pairs.iter().all(|p| {
            let [c, d] = p.across;
            edges
                .iter()
                .any(|e| (e.a, e.b) == (c, d) && e.triangle_count == 2)
        }));
        // A tetrahedron's far corners across an edge are already joined: no pairs.
        let tetrahedron = Mesh {
            positions: vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z],
            triangles: vec![[0, 1, 2], [0, 3, 1], [1, 3, 2], [0, 2, 3]],
            ..Mesh::default()
        };
        assert!(tetrahedron.bending_pairs().is_empty());
    }

    #[test]
    fn square_has_five_unique_edges_with_shared_diagonal() {
        let edges = square().edges();
        assert_eq!(edges.len(), 5);
        let diagonal = edges
            .iter()
            .find(|e| (e.a, e.b) == (0, 2))
            .expect("diagonal 0-2");
        assert_eq!(diagonal.triangle_count, 2);
    }

    #[test]
    fn out_of_range_index_names_triangle_and_count() {
        let mut mesh = square();
        mesh.triangles[1] = [0, 2, 9];
        let err = mesh.validate("sq.obj").unwrap_err();
        assert_eq!(
            err.to_string(),
            "sq.obj: triangle 1 uses vertex index 9, out of range (mesh has 4 vertices)"
        );
    }

    #[test]
    fn nan_coordinate_is_rejected() {
        let mut mesh = square();
        mesh.positions[2].y = f64::NAN;
        assert!(matches!(
            mesh.validate("m").unwrap_err(),
            MeshError::NonFiniteVertex { vertex: 2, .. }
        ));
    }

    #[test]
    fn collinear_and_repeated_triangles_are_degenerate() {
        let mut mesh = square();
        mesh.positions[3] = DVec3::new(0.5, 0.0, 0.5);
        assert!(matches!(
            mesh.validate("m").unwrap_err(),
            MeshError::DegenerateTriangle { triangle: 1, .. }
        ));
        let mut mesh = square();
        mesh.triangles[0] = [0, 1, 1];
        assert!(matches!(
            mesh.validate("m").unwrap_err(),
            MeshError::DegenerateTriangle { triangle: 0, .. }
        ));
    }

    #[test]
    fn coincident_vertices_give_zero_length_edge() {
        let mut mesh = square();
        mesh.positions[3] = mesh.positions[2];
        assert!(matches!(
            mesh.validate("m").unwrap_err(),
            MeshError::ZeroLengthEdge { a: 2, b: 3, .. }
        ));
    }

    #[test]
    fn a_renumbered_mesh_is_the_same_surface() {
        let mut mesh = square();
        mesh.vertex_properties
            .insert("k".into(), vec![1.0, 2.0, 3.0, 4.0]);
        let shuffled = mesh.renumbered(&[2, 0, 3, 1]);
        assert_eq!(shuffled.positions[0], mesh.positions[2]);
        assert_eq!(shuffled.vertex_properties["k"], vec![3.0, 1.0, 4.0, 2.0]);
        for (t, u) in mesh.triangles.iter().zip(&shuffled.triangles) {
            for (a, b) in t.iter().zip(u) {
                assert_eq!(mesh.positions[*a as usize], shuffled.positions[*b as usize]);
            }
        }
        assert_eq!(mesh.shuffled(3).edges().len(), mesh.edges().len());
    }

    #[test]
    fn non_manifold_edge_is_a_warning() {
        let mut mesh = square();
        mesh.positions.push(DVec3::new(0.5, 1.0, 0.5));
        mesh.triangles.push([0, 2, 4]);
        let warnings = mesh.validate("m").expect("valid with warning");
        assert_eq!(
            warnings,
            vec![MeshWarning::NonManifoldEdge {
                a: 0,
                b: 2,
                triangle_count: 3
            }]
        );
    }
}
