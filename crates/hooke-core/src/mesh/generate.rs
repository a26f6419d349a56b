//! Mesh generators: the paper's regular benchmark grids and irregular meshes of valence 3..12.

use glam::{DVec2, DVec3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::{Mesh, TextureCoordinates};

/// The plane a generated sheet lies in; the first named axis is the "columns" direction.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GridPlane {
    /// Horizontal sheet (y is up): the benchmark workload.
    #[default]
    Xz,
    /// Vertical sheet facing +z: a hanging curtain.
    Xy,
}

impl GridPlane {
    fn place(self, u: f64, v: f64, center: DVec3) -> DVec3 {
        center
            + match self {
                Self::Xz => DVec3::new(u, 0.0, v),
                Self::Xy => DVec3::new(u, -v, 0.0),
            }
    }

    /// The texture coordinates of sheet point `(u, v)` of a `size` sheet: 0..1 across, with
    /// `t` growing upwards on a hanging curtain so that an image is not drawn upside down.
    fn texture(self, u: f64, v: f64, size: [f64; 2]) -> [f64; 2] {
        let s = u / size[0] + 0.5;
        let t = v / size[1] + 0.5;
        match self {
            Self::Xz => [s, t],
            Self::Xy => [s, 1.0 - t],
        }
    }
}

/// A regular grid of `columns x rows` vertices spanning `size` metres, centred on `center`.
///
/// Every quad is split along the same diagonal, so interior vertices have valence 6, as in the
/// paper's benchmark meshes (Fig. 2, Table 2). Vertex `(row, col)` has index `row * columns + col`.
pub fn grid(columns: u32, rows: u32, size: [f64; 2], plane: GridPlane, center: DVec3) -> Mesh {
    assert!(
        columns >= 2 && rows >= 2,
        "a grid needs at least 2x2 vertices"
    );
    let mut positions = Vec::with_capacity((columns * rows) as usize);
    let mut coordinates = Vec::with_capacity((columns * rows) as usize);
    for row in 0..rows {
        for col in 0..columns {
            let u = (f64::from(col) / f64::from(columns - 1) - 0.5) * size[0];
            let v = (f64::from(row) / f64::from(rows - 1) - 0.5) * size[1];
            positions.push(plane.place(u, v, center));
            coordinates.push(plane.texture(u, v, size));
        }
    }
    let mut triangles = Vec::with_capacity(2 * ((columns - 1) * (rows - 1)) as usize);
    for row in 0..rows - 1 {
        for col in 0..columns - 1 {
            let v00 = row * columns + col;
            let v01 = v00 + 1;
            let v10 = v00 + columns;
            let v11 = v10 + 1;
            triangles.push([v00, v10, v11]);
            triangles.push([v00, v11, v01]);
        }
    }
    Mesh {
        uvs: Some(TextureCoordinates::per_vertex(coordinates, &triangles)),
        positions,
        triangles,
        ..Mesh::default()
    }
}

/// An irregular triangulation of a `size` rectangle with about `vertex_count` vertices,
/// numbered row by row.
///
/// Interior points are uniformly random (seeded, so the mesh is reproducible) but kept at least
/// a quarter of the mean spacing apart, which avoids slivers while leaving the Delaunay valences
/// spread over roughly 3..12, the range the paper measured PCA against ECA on. The boundary is
/// sampled evenly so the sheet keeps straight edges and sensible corner vertices.
pub fn irregular(
    vertex_count: u32,
    size: [f64; 2],
    seed: u64,
    plane: GridPlane,
    center: DVec3,
) -> Mesh {
    let vertex_count = vertex_count.max(16) as usize;
    let spacing = (size[0] * size[1] / vertex_count as f64).sqrt();
    let half = DVec2::new(size[0], size[1]) * 0.5;

    let per_side_u = ((size[0] / spacing).round() as usize).max(2);
    let per_side_v = ((size[1] / spacing).round() as usize).max(2);
    let mut points: Vec<DVec2> = Vec::with_capacity(vertex_count);
    for i in 0..per_side_u {
        let u = -half.x + size[0] * i as f64 / per_side_u as f64;
        points.push(DVec2::new(u, -half.y));
        points.push(DVec2::new(-u, half.y));
    }
    for i in 0..per_side_v {
        let v = -half.y + size[1] * i as f64 / per_side_v as f64;
        points.push(DVec2::new(half.x, v));
        points.push(DVec2::new(-half.x, -v));
    }

    let min_distance = 0.25 * spacing;
    let mut occupancy = SpacingGrid::new(half, min_distance);
    for p in &points {
        occupancy.insert(*p);
    }
    let margin = 0.5 * spacing;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut attempts = 0usize;
    while points.len() < vertex_count && attempts < 100 * vertex_count {
        attempts += 1;
        let p = DVec2::new(
            rng.random_range(-half.x + margin..half.x - margin),
            rng.random_range(-half.y + margin..half.y - margin),
        );
        if occupancy.is_free(p) {
            occupancy.insert(p);
            points.push(p);
        }
    }

    // Number vertices in rows of one spacing's height, as meshing tools emit them: neighbours
    // then sit close in memory (random insertion order made the gather 3x slower).
    points.sort_by(|p, q| {
        let row = |v: &DVec2| ((v.y + half.y) / spacing).floor() as i64;
        row(p).cmp(&row(q)).then(p.x.total_cmp(&q.x))
    });
    let delaunay_points: Vec<delaunator::Point> = points
        .iter()
        .map(|p| delaunator::Point { x: p.x, y: p.y })
        .collect();
    let triangulation = delaunator::triangulate(&delaunay_points);
    let triangles: Vec<[u32; 3]> = triangulation
        .triangles
        .chunks_exact(3)
        .map(|t| [t[0] as u32, t[1] as u32, t[2] as u32])
        .collect();
    let coordinates = points
        .iter()
        .map(|p| plane.texture(p.x, p.y, size))
        .collect();
    Mesh {
        positions: points
            .iter()
            .map(|p| plane.place(p.x, p.y, center))
            .collect(),
        uvs: Some(TextureCoordinates::per_vertex(coordinates, &triangles)),
        triangles,
        ..Mesh::default()
    }
}

/// A uniform hash of accepted points, so dart throwing checks only nearby cells.
struct SpacingGrid {
    cell: f64,
    half: DVec2,
    columns: usize,
    cells: Vec<Vec<DVec2>>,
}

impl SpacingGrid {
    fn new(half: DVec2, min_distance: f64) -> Self {
        let columns = ((2.0 * half.x / min_distance).ceil() as usize).max(1) + 1;
        let rows = ((2.0 * half.y / min_distance).ceil() as usize).max(1) + 1;
        Self {
            cell: min_distance,
            half,
            columns,
            cells: vec![Vec::new(); columns * rows],
        }
    }

    fn cell_of(&self, p: DVec2) -> (usize, usize) {
        let c = ((p + self.half) / self.cell).floor().max(DVec2::ZERO);
        let rows = self.cells.len() / self.columns;
        (
            (c.x as usize).min(self.columns - 1),
            (c.y as usize).min(rows - 1),
        )
    }

    fn insert(&mut self, p: DVec2) {
        let (cx, cy) = self.cell_of(p);
        self.cells[cy * self.columns + cx].push(p);
    }

    fn is_free(&self, p: DVec2) -> bool {
        let (cx, cy) = self.cell_of(p);
        let rows = self.cells.len() / self.columns;
        for y in cy.saturating_sub(1)..=(cy + 1).min(rows - 1) {
            for x in cx.saturating_sub(1)..=(cx + 1).min(self.columns - 1) {
                if self.cells[y * self.columns + x]
                    .iter()
                    .any(|q| q.distance_squared(p) < self.cell * self.cell)
                {
                    return false;
                }
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_interior_vertices_have_valence_six() {
        let mesh = grid(8, 6, [1.0, 1.0], GridPlane::Xz, DVec3::ZERO);
        assert_eq!(mesh.positions.len(), 48);
        assert_eq!(mesh.triangles.len(), 2 * 7 * 5);
        let valences = mesh.valences();
        for row in 1..5 {
            for col in 1..7 {
                assert_eq!(valences[row * 8 + col], 6);
            }
        }
        assert!(mesh.validate("grid").expect("valid").is_empty());
    }

    #[test]
    fn grid_springs_are_edges_plus_one_diagonal_per_quad() {
        let (c, r) = (5u32, 4u32);
        let mesh = grid(c, r, [1.0, 1.0], GridPlane::Xy, DVec3::ZERO);
        let expected = (c - 1) * r + c * (r - 1) + (c - 1) * (r - 1);
        assert_eq!(mesh.edges().len(), expected as usize);
    }

    #[test]
    fn irregular_mesh_is_valid_and_spans_valences_three_to_twelve() {
        let mesh = irregular(4000, [1.0, 1.0], 7, GridPlane::Xz, DVec3::ZERO);
        assert!(mesh.validate("irregular").expect("valid").is_empty());
        let valences = mesh.valences();
        let min = *valences.iter().min().expect("vertices");
        let max = *valences.iter().max().expect("vertices");
        assert!(min <= 3, "min valence {min}");
        assert!(max >= 10, "max valence {max}");
    }

    #[test]
    fn irregular_mesh_is_reproducible_from_its_seed() {
        let a = irregular(500, [1.0, 2.0], 3, GridPlane::Xy, DVec3::ONE);
        let b = irregular(500, [1.0, 2.0], 3, GridPlane::Xy, DVec3::ONE);
        assert_eq!(a, b);
    }
}
