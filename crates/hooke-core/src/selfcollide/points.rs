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
    /// and `z`: a whole block at a time where `places` name one of the owner's in order
    /// ([`Points::run`]; a grid's patch is 8 rows of 8 consecutive vertices, its members
    /// sorted by place), a point at a time elsewhere. The culling reads patches this way,
    /// and one load per coordinate took an eighth of a 512^2 step in contact.
    fn gather_into(&self, places: &[u32], mut out: [&mut [f32]; 3]) {
        let mut k = 0;
        while k < places.len() {
            if let Some(block) = places.get(k..k + LANES).and_then(|run| self.run(run)) {
                for (out, axis) in out.iter_mut().zip(block) {
                    out[k..k + LANES].copy_from_slice(axis);
                }
                k += LANES;
            } else {
                let p = self.at(places[k]);
                for (out, value) in out.iter_mut().zip([p.x, p.y, p.z]) {
                    out[k] = value;
                }
                k += 1;
            }
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

    /// The positions at `run` ([`LANES`] places) as one of the owner's blocks, where the
    /// places name one in order ([`Points::lanes`]).
    fn run(&self, run: &[u32]) -> Option<[&[f32; LANES]; 3]> {
        let first = *run.first()?;
        let in_order = run.len() == LANES && run.iter().zip(first..).all(|(&p, q)| p == q);
        in_order.then(|| self.lanes(first)).flatten()
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

/// Positions kept as a solver keeps them: by axis, in blocks of [`LANES`], vertex `v` at
/// place `places[v]` (block `place / LANES`, lane `place % LANES`). The axes are sliced once,
/// when this is made, not per point: the culling reads every vertex each step.
#[derive(Clone, Copy, Debug)]
pub struct BlockPoints<'a> {
    /// Each mesh vertex's place.
    pub places: &'a [u32],
    /// x, y and z, [`LANES`] places a block.
    pub axes: [&'a [[f32; LANES]]; 3],
}

impl Points for BlockPoints<'_> {
    fn count(&self) -> usize {
        self.places.len()
    }

    fn place(&self, v: u32) -> u32 {
        self.places[v as usize]
    }

    fn at(&self, place: u32) -> Vec3 {
        let (block, lane) = (place as usize / LANES, place as usize % LANES);
        let [x, y, z] = self.axes;
        Vec3::new(x[block][lane], y[block][lane], z[block][lane])
    }

    fn lanes(&self, place: u32) -> Option<[&[f32; LANES]; 3]> {
        let place = place as usize;
        if !place.is_multiple_of(LANES) {
            return None;
        }
        let [x, y, z] = self.axes;
        let block = place / LANES;
        Some([x.get(block)?, y.get(block)?, z.get(block)?])
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
