//! Named vertex selections (`corners`, `top-edge`, ...) for pins and drags.

use glam::DVec3;

use super::PinSelector;
use crate::mesh::{Mesh, axes_by_extent};

/// Vertices a named selector picks.
pub fn select_vertices(mesh: &Mesh, selector: PinSelector) -> Vec<u32> {
    let (lo, hi) = mesh.bounds();
    let extent = hi - lo;
    match selector {
        PinSelector::Corners | PinSelector::TopCorners => {
            let [u, v, _] = axes_by_extent(extent);
            let mut corners: Vec<u32> = [
                (lo[u], lo[v]),
                (hi[u], lo[v]),
                (lo[u], hi[v]),
                (hi[u], hi[v]),
            ]
            .iter()
            .map(|&(cu, cv)| nearest_vertex(mesh, |p| (p[u] - cu).powi(2) + (p[v] - cv).powi(2)))
            .collect();
            if selector == PinSelector::TopCorners {
                corners.sort_by(|a, b| {
                    mesh.positions[*b as usize]
                        .y
                        .total_cmp(&mesh.positions[*a as usize].y)
                });
                corners.truncate(2);
            }
            corners
        }
        PinSelector::TopEdge => {
            let tolerance = 1e-6 * extent.max_element();
            (0..mesh.vertex_count() as u32)
                .filter(|&i| mesh.positions[i as usize].y >= hi.y - tolerance)
                .collect()
        }
    }
}

fn nearest_vertex(mesh: &Mesh, distance: impl Fn(DVec3) -> f64) -> u32 {
    (0..mesh.vertex_count() as u32)
        .min_by(|a, b| {
            distance(mesh.positions[*a as usize]).total_cmp(&distance(mesh.positions[*b as usize]))
        })
        .unwrap_or(0)
}
