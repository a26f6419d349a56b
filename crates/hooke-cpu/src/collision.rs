//! The collision phase of the CPU step: colliders (the rule of `hooke_core::collide`), dynamic
//! balls, and self-collision (`hooke_core::selfcollide`).

use glam::{DVec3, Vec3};
use hooke_core::{collide, handles, selfcollide};
use rayon::prelude::*;

use crate::early::{EarlyBlocks, EarlyStep};
use crate::layout::LANES;
use crate::simd::{Point, point_slot};
use crate::{CpuSolver, Topology, blocks, sweep};

/// A step's new positions as the solver keeps them, lent to self-collision: by axis in blocks
/// of [`LANES`], and as one 16-byte point per vertex where the integration wrote them (the
/// force pass of an irregular mesh reads them). A patch that fills none of the solver's blocks
/// (an irregular mesh's slices hold vertices of like valence from a window of 256) is then
/// read a point at a time with one load, not one from each axis.
struct SolverPoints<'a> {
    blocks: selfcollide::BlockPoints<'a>,
    points: Option<&'a [[Point; LANES]]>,
}

impl selfcollide::Points for SolverPoints<'_> {
    fn count(&self) -> usize {
        self.blocks.count()
    }

    fn place(&self, v: u32) -> u32 {
        self.blocks.place(v)
    }

    fn at(&self, place: u32) -> Vec3 {
        match self.points {
            Some(points) => Vec3::from_slice(&points.as_flattened()[point_slot(place) as usize]),
            None => self.blocks.at(place),
        }
    }

    fn lanes(&self, place: u32) -> Option<[&[f32; LANES]; 3]> {
        self.blocks.lanes(place)
    }

    fn gather_into(&self, places: &[u32], [xs, ys, zs]: [&mut [f32]; 3]) {
        let Some(points) = self.points else {
            return self.blocks.gather_into(places, [xs, ys, zs]);
        };
        let points = points.as_flattened();
        let outs = xs.iter_mut().zip(ys.iter_mut()).zip(zs.iter_mut());
        for (((x, y), z), &place) in outs.zip(places) {
            [*x, *y, *z, _] = points[point_slot(place) as usize];
        }
    }
}

impl CpuSolver {
    /// Parts vertices that came too close to each other (see `hooke_core::selfcollide`), in
    /// mesh order so every solver sorts the same keys the same way. With `timed`, returns
    /// where its time went (`None` without self-collision). With `early`, the next step's
    /// slices outside the passes' zone run beside them (see [`crate::early`]; the caller has
    /// checked that they may).
    pub(crate) fn self_collide(
        &mut self,
        timed: bool,
        early: bool,
    ) -> Option<selfcollide::PartTimes> {
        let config = self.self_collision?;
        self.self_collider.time_parts(timed);
        let buffers = early.then(|| sweep::Buffers::of(self, false));
        // The step's new positions, where the solver keeps them (its numbering, by axis, and
        // as points where the integration wrote them).
        let points = SolverPoints {
            blocks: selfcollide::BlockPoints {
                places: &self.numbering.internal,
                axes: self.next.axes(),
            },
            points: self.points_fresh.then_some(self.points.as_slice()),
        };
        let isa = self.options.instruction_set;
        let slices = self.numbering.slice_count();
        let (adjacency, weights) = (&self.model.adjacency, &self.inverse_masses);
        let collider = &mut self.self_collider;
        let mut resolve = |beside: Option<&dyn selfcollide::Beside>| {
            collider.resolve_beside(&points, weights, adjacency, &config, beside)
        };
        let (moves, done) = match (&buffers, &mut self.topology) {
            (
                Some(buffers),
                Topology::Scatter {
                    springs,
                    incidence,
                    spring_forces,
                },
            ) => {
                let blocks = self
                    .blocks
                    .as_ref()
                    .expect("only blocked scatter steps early");
                let next = blocks::BlockSteps::new(
                    blocks,
                    isa,
                    springs,
                    incidence,
                    blocks::Forces::new(spring_forces),
                    &self.integrator,
                    buffers,
                );
                let beside = EarlyBlocks::new(next);
                #[cfg(test)]
                let beside = beside.eagerly(self.early_eagerly);
                (resolve(Some(&beside)), Some(beside.done()))
            }
            (Some(buffers), Topology::Gather(table)) => {
                let kernel = sweep::gather_run(isa, table, &self.integrator);
                let beside = EarlyStep::new(buffers, &kernel, slices);
                #[cfg(test)]
                let beside = beside.eagerly(self.early_eagerly);
                (resolve(Some(&beside)), Some(beside.done()))
            }
            _ => (resolve(None), None),
        };
        if done.is_some() {
            self.early = done;
        }
        // Only moved vertices are written back; each move shifts the step's motion too.
        let mut watch = selfcollide::Stopwatch::start(timed);
        let internal = &self.numbering.internal;
        let mut points = self.points_fresh.then_some(self.points.as_flattened_mut());
        for (v, c) in moves {
            let k = internal[v as usize] as usize;
            let moved = Vec3::from_array(self.next.get(k)) + c;
            self.next.set(k, moved.to_array());
            self.delta
                .set(k, (Vec3::from_array(self.delta.get(k)) + c).to_array());
            if let Some(points) = points.as_deref_mut() {
                points[point_slot(k as u32) as usize] = moved.extend(0.0).to_array();
            }
        }
        let mut parts = self.self_collider.part_times();
        parts.moving += watch.lap();
        timed.then_some(parts)
    }

    /// Places the handles' vertices where their paths or colliders have taken them at the end
    /// of this step (see `hooke_core::handles`); after `collide`, which moves the balls.
    pub(crate) fn move_handles(&mut self) {
        if self.model.handles.is_empty() {
            return;
        }
        let t = (self.steps_taken + 1) as f64 * self.material.dt;
        let internal = &self.numbering.internal;
        let (next, delta, current) = (&mut self.next, &mut self.delta, &self.current);
        handles::place_handles(
            &self.model.handles,
            &self.model.initial_positions,
            t,
            &self.colliders,
            &self.model.collision.colliders,
            |v, p| {
                let k = internal[v as usize] as usize;
                let p = p.as_vec3();
                next.set(k, p.to_array());
                delta.set(k, (p - Vec3::from_array(current.get(k))).to_array());
            },
        );
    }

    /// Moves vertices that ended inside a collider out of it (see `hooke_core::collide`), in
    /// parallel over vertex chunks, before the new positions become current; then advances
    /// dynamic balls by the momentum the cloth took from them. Returns the first ball that
    /// became non-finite.
    pub(crate) fn collide(&mut self) -> Option<usize> {
        if self.colliders.is_empty() {
            return None;
        }
        let thickness = self.model.collision.thickness;
        // Colliders are placed where they are at the end of the step being finished.
        let (dt, t) = (
            self.material.dt,
            (self.steps_taken + 1) as f64 * self.material.dt,
        );
        let colliders = collide::placed(&self.colliders, t);
        let colliders = colliders.as_slice();
        let reaches: Vec<collide::Reach> = colliders
            .iter()
            .map(|c| collide::Reach::of(c, thickness))
            .collect();
        let reaches = reaches.as_slice();
        let (current, scales) = (&self.current, &self.integrator.scales);
        let (real, count) = (self.model.vertex_count(), colliders.len());
        let (masses, original) = (&self.model.masses, &self.numbering.original);
        let [nx, ny, nz] = self.next.axes_mut();
        let [dx, dy, dz] = self.delta.axes_mut();
        let free = scales.axis(0);
        let [cx, cy, cz] = current.axes();
        // Per slice and collider: sum of m c over the slice's vertices (kg m).
        self.slice_pushes.clear();
        self.slice_pushes.resize(free.len() * count, DVec3::ZERO);
        nx.par_iter_mut()
            .zip(ny.par_iter_mut())
            .zip(nz.par_iter_mut())
            .zip(
                dx.par_iter_mut()
                    .zip(dy.par_iter_mut())
                    .zip(dz.par_iter_mut()),
            )
            .zip(self.slice_pushes.par_chunks_mut(count))
            .enumerate()
            .for_each(|(slice, ((((nx, ny), nz), ((dx, dy), dz)), pushes))| {
                for lane in 0..LANES {
                    let k = slice * LANES + lane;
                    if k >= real || free[slice][lane] <= 0.0 {
                        continue;
                    }
                    // Out of every collider's reach: the exact test would leave the position,
                    // and the delta becomes next - x, as below.
                    let next = Vec3::new(nx[lane], ny[lane], nz[lane]);
                    if !reaches.iter().any(|r| r.may_touch(next)) {
                        let d = next - Vec3::new(cx[slice][lane], cy[slice][lane], cz[slice][lane]);
                        (dx[lane], dy[lane], dz[lane]) = (d.x, d.y, d.z);
                        continue;
                    }
                    let x = DVec3::new(
                        cx[slice][lane].into(),
                        cy[slice][lane].into(),
                        cz[slice][lane].into(),
                    );
                    let next = DVec3::new(nx[lane].into(), ny[lane].into(), nz[lane].into());
                    let mass = masses[original[k] as usize];
                    let p =
                        collide::resolve_placed(colliders, thickness, dt, x, next, |c, moved| {
                            pushes[c] += moved * mass
                        })
                        .as_vec3();
                    (nx[lane], ny[lane], nz[lane]) = (p.x, p.y, p.z);
                    let d = p - x.as_vec3();
                    (dx[lane], dy[lane], dz[lane]) = (d.x, d.y, d.z);
                }
            });
        if collide::any_dynamic(&self.colliders) {
            // Summed in slice order: the same result for any thread count.
            let mut pushes = vec![DVec3::ZERO; count];
            for chunk in self.slice_pushes.chunks(count) {
                for (total, push) in pushes.iter_mut().zip(chunk) {
                    *total += *push;
                }
            }
            collide::advance_balls(&mut self.colliders, &pushes, self.material.gravity, dt, t);
        }
        collide::first_non_finite_ball(&self.colliders)
    }
}

#[cfg(test)]
mod tests {
    use hooke_core::selfcollide::Points;

    use super::*;
    use crate::CpuOptions;
    use crate::lanes::Soa;
    use hooke_core::{Model, Solver, State};

    #[test]
    fn gather_copies_runs_and_single_points_alike() {
        let n = 40;
        let mut lanes = Soa::zeros(n / LANES);
        for k in 0..n {
            lanes.set(k, [k as f32, 100.0 + k as f32, -(k as f32)]);
        }
        let internal: Vec<u32> = (0..n as u32).collect();
        let points = selfcollide::BlockPoints {
            places: &internal,
            axes: lanes.axes(),
        };
        // An aligned run, a run that is not aligned, a run with a gap, a block's places out of
        // order, and a short tail.
        let places: Vec<u32> = (8..16)
            .chain(17..25)
            .chain([0, 1, 2, 3, 5, 6, 7, 8])
            .chain([24, 26, 25, 27, 28, 29, 30, 31])
            .chain(32..37)
            .collect();
        let mut out = [[0.0f32; 64]; 3];
        let [x, y, z] = &mut out;
        points.gather_into(&places, [x, y, z]);
        for (k, &place) in places.iter().enumerate() {
            let expected = points.at(place);
            assert_eq!(
                [out[0][k], out[1][k], out[2][k]],
                expected.to_array(),
                "slot {k}"
            );
            assert_eq!(expected.x, place as f32);
        }
    }

    /// The folding cloth's initial positions (upright, in x-y) folded in two across the
    /// middle, the upper half laid a fifth of the self-collision distance in front of the
    /// lower: grouped where they lie, a patch would hold vertices of both layers.
    fn folded_in_two(model: &Model) -> Vec<DVec3> {
        let distance = model
            .collision
            .self_collision
            .expect("self-collision")
            .distance;
        let middle = model.initial_positions.iter().map(|p| p.y).sum::<f64>()
            / model.initial_positions.len() as f64;
        model
            .initial_positions
            .iter()
            .map(|&p| {
                if p.y > middle {
                    DVec3::new(p.x, 2.0 * middle - p.y, p.z + 0.2 * distance)
                } else {
                    p
                }
            })
            .collect()
    }

    #[test]
    fn a_folded_state_written_in_is_grouped_as_the_scene_laid_the_cloth_out() {
        let scene = hooke_testkit::folding_cloth();
        let model = &scene.model;
        let folded = folded_in_two(model);
        let patches = |solver: &CpuSolver| {
            let culling = solver.self_collider.culling();
            (0..culling.patch_count() as u32)
                .map(|p| culling.members_of(p).to_vec())
                .collect::<Vec<_>>()
        };
        let options = CpuOptions {
            threads: Some(2),
            ..Default::default()
        };
        let mut fresh = CpuSolver::new(model, &scene.material, options).expect("cpu solver");
        fresh.step(1).expect("stable");
        let mut refolded = CpuSolver::new(model, &scene.material, options).expect("cpu solver");
        refolded.write_state(&State::at_rest(folded.clone()));
        refolded.step(1).expect("stable");
        assert_eq!(patches(&refolded), patches(&fresh));
        // Grouped where the points lie instead, the patches differ: the check above can fail.
        let mut by_points = CpuSolver::new(model, &scene.material, options).expect("cpu solver");
        by_points.self_collider = selfcollide::Resolver::default();
        by_points.write_state(&State::at_rest(folded));
        by_points.step(1).expect("stable");
        assert_ne!(patches(&by_points), patches(&fresh));
    }

    #[test]
    fn a_mesh_placed_in_folds_is_grouped_along_its_surface() {
        let scene = hooke_testkit::folding_cloth();
        let flat = &scene.model;
        // The cloth folded as in the test above, but placed so by its model, as a mesh file
        // holding a folded cloth is: it has no flat layout to group by.
        let mut model = flat.clone();
        model.initial_positions = folded_in_two(flat);
        // Patches whose vertices their own springs do not join into one piece: pieces of two
        // layers, where grouped by where the vertices lie.
        let split = |solver: &CpuSolver| {
            let culling = solver.self_collider.culling();
            let order: Vec<u32> = (0..culling.patch_count() as u32)
                .flat_map(|p| culling.members_of(p).to_vec())
                .collect();
            selfcollide::split_patches(&order, &flat.adjacency)
        };
        let options = CpuOptions {
            threads: Some(2),
            ..Default::default()
        };
        let mut folded = CpuSolver::new(&model, &scene.material, options).expect("cpu solver");
        folded.step(1).expect("stable");
        let mut by_points = CpuSolver::new(&model, &scene.material, options).expect("cpu solver");
        by_points.self_collider = selfcollide::Resolver::default();
        by_points.step(1).expect("stable");
        assert_eq!(split(&folded), 0);
        // Each patch is whole blocks of the solver's, which the culling reads straight from it.
        let culling = folded.self_collider.culling();
        for p in 0..culling.patch_count() as u32 {
            for run in culling.places_of(p).chunks(LANES) {
                assert_eq!(run[0] as usize % LANES, 0, "patch {p}: {run:?}");
                assert!(
                    run.windows(2).all(|w| w[1] == w[0] + 1),
                    "patch {p}: {run:?}"
                );
            }
        }
        // Grouped where the points lie instead, patches hold pieces of both layers.
        assert!(split(&by_points) >= 4, "{}", split(&by_points));
    }
}
