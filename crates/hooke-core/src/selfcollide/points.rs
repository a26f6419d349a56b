//! Where self-collision reads the step's positions: a slice in mesh order, or a solver's own
//! layout. The culling's proof reads every position once a step; on most steps it clears
//! them and nothing else reads them, so a solver that keeps positions in another order or
//! layout lends them as they are, and they are copied into mesh order only for the passes.

use glam::Vec3;
use rayon::prelude::*;

/// Positions per block of [`Points::lanes`].
pub const LANES: usize = 8;

/// The positions of a mesh's vertices, by mesh vertex index.
pub trait Points: Sync {
    /// How many vertices.
    fn count(&self) -> usize;

    /// Where vertex `v` is stored: the index [`Points::at`] takes. Fixed for the lifetime of
    /// the positions' owner, so a reader may keep it.
    fn place(&self, v: u32) -> u32;

    /// The position stored at `place`.
    fn at(&self, place: u32) -> Vec3;

    /// The positions at `places`, by axis, into the first `places.len()` slots of `x`, `y`
    /// and `z`. The culling reads every patch this way each step; an owner that stores
    /// positions in runs overrides it to copy a run of consecutive places at once.
    fn gather_into(&self, places: &[u32], [x, y, z]: [&mut [f32]; 3]) {
        for (k, &place) in places.iter().enumerate() {
            let p = self.at(place);
            (x[k], y[k], z[k]) = (p.x, p.y, p.z);
        }
    }

    /// The [`LANES`] positions stored at `place..place + LANES`, by axis, where the owner
    /// keeps them as one block per axis (`place` a multiple of `LANES`); `None` where it does
    /// not. The culling measures every patch each step, straight from these where a patch's
    /// members fill blocks, without copying them first.
    fn lanes(&self, place: u32) -> Option<[&[f32; LANES]; 3]> {
        let _ = place;
        None
    }

    /// Every position in mesh order, into `out` (replacing what it held). In chunks of
    /// vertices, one task each: `par_extend` over a mapped range took 3.4x as long here
    /// (0.57 against 0.17 ms for 512^2 on 2 threads).
    fn copy_into(&self, out: &mut Vec<Vec3>) {
        const CHUNK: usize = 4096;
        out.resize(self.count(), Vec3::ZERO);
        out.par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(c, chunk)| {
                for (v, point) in (c * CHUNK..).zip(chunk) {
                    *point = self.at(self.place(v as u32));
                }
            });
    }
}

impl Points for [Vec3] {
    fn count(&self) -> usize {
        self.len()
    }

    fn place(&self, v: u32) -> u32 {
        v
    }

    fn at(&self, place: u32) -> Vec3 {
        self[place as usize]
    }

    fn copy_into(&self, out: &mut Vec<Vec3>) {
        out.clear();
        out.extend_from_slice(self);
    }
}
