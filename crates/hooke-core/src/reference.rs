//! The float64 reference solver: single-threaded and written for clarity, the oracle of every test.
//!
//! One step is the paper's Section 2 verbatim: total force (eq. 4)
//! `F_tot = F_ext - sum_j F_ij - c (x(t) - x(t-dt))/dt`, then Verlet (eq. 3)
//! `x(t+dt) = F_tot/m dt^2 + 2 x(t) - x(t-dt)`. Pinned vertices keep their position.

use glam::{DVec3, Vec3};

use crate::collide::{
    Collider, advance_balls, apply_pushes, first_non_finite_ball, placed, resolve_placed,
    restore_balls,
};
use crate::diagnostics::{damper_force_on_a, spring_force_on_a};
use crate::forces::add_external_forces;
use crate::handles::place_handles;
use crate::selfcollide::{self, SelfCollision};
use crate::solver::{PhaseTimes, Snapshot, TimingSource};
use crate::tearing::Tears;
use crate::{Control, Material, Model, SimError, Solver, State};

#[derive(Debug)]
pub struct ReferenceSolver {
    model: Model,
    material: Material,
    control: Control,
    self_collision: Option<SelfCollision>,
    state: State,
    forces: Vec<DVec3>,
    /// Colliders as they are now (dynamic balls move; scripted ones are placed by time).
    colliders: Vec<Collider>,
    tears: Tears,
    steps_taken: u64,
}

impl ReferenceSolver {
    pub fn new(model: &Model, material: &Material) -> Self {
        Self {
            state: State::at_rest(model.initial_positions.clone()),
            forces: vec![DVec3::ZERO; model.vertex_count()],
            model: model.clone(),
            colliders: model.collision.colliders.clone(),
            self_collision: model.collision.self_collision,
            material: *material,
            control: Control::default(),
            tears: Tears::new(model),
            steps_taken: 0,
        }
    }

    fn step_once(&mut self) -> Result<(), SimError> {
        let (model, material, state) = (&self.model, &self.material, &mut self.state);
        self.forces.fill(DVec3::ZERO);
        // Springs are tested in float32, as every solver tests them (see `crate::tearing`).
        self.tears.test(|v| state.positions[v as usize].as_vec3());
        add_external_forces(model, state, material, &self.control, &mut self.forces);
        for (s, [a, b]) in model.spring_ends.iter().enumerate() {
            if self.tears.is_broken(s) {
                continue;
            }
            let (a, b) = (*a as usize, *b as usize);
            let force = spring_force_on_a(
                state.positions[a],
                state.positions[b],
                model.rest_lengths[s],
                model.stiffness(s, material.stiffness_scale),
            );
            self.forces[a] += force;
            self.forces[b] -= force;
            if model.bending_damping > 0.0 && model.is_bending(s) {
                let damping = damper_force_on_a(
                    state.positions[a],
                    state.positions[b],
                    state.velocity(a, material.dt),
                    state.velocity(b, material.dt),
                    model.bending_damping,
                );
                self.forces[a] += damping;
                self.forces[b] -= damping;
            }
        }
        let dt = material.dt;
        self.steps_taken += 1;
        // Colliders are placed where they are at the end of this step.
        let t = self.steps_taken as f64 * dt;
        let mut pushes = vec![DVec3::ZERO; self.colliders.len()];
        let colliders = placed(&self.colliders, t);
        for i in 0..model.vertex_count() {
            let x = state.positions[i];
            let x_previous = state.previous_positions[i];
            let next = if model.pinned[i] {
                x
            } else {
                let total = self.forces[i] - material.damping * (x - x_previous) / dt;
                let moved = total / model.masses[i] * dt * dt + 2.0 * x - x_previous;
                let mass = model.masses[i];
                resolve_placed(
                    &colliders,
                    model.collision.thickness,
                    dt,
                    x,
                    moved,
                    |k, c| pushes[k] += c * mass,
                )
            };
            if !next.is_finite() {
                return Err(SimError::NonFinite {
                    step: self.steps_taken,
                    vertex: i,
                });
            }
            state.previous_positions[i] = x;
            state.positions[i] = next;
        }
        advance_balls(&mut self.colliders, &pushes, material.gravity, dt, t);
        if let Some(collider) = first_non_finite_ball(&self.colliders) {
            return Err(SimError::BallNonFinite {
                step: self.steps_taken,
                collider,
            });
        }
        let positions = &mut state.positions;
        place_handles(
            &model.handles,
            &model.initial_positions,
            t,
            &self.colliders,
            &model.collision.colliders,
            |v, p| positions[v as usize] = p,
        );
        if let Some(config) = &self.self_collision {
            resolve_self_collisions(model, state, config);
        }
        Ok(())
    }
}

/// Self-collision in float32, the arithmetic every solver shares (see [`crate::selfcollide`]),
/// its corrections applied to the float64 state.
fn resolve_self_collisions(model: &Model, state: &mut State, config: &SelfCollision) {
    let rounded: Vec<Vec3> = state.positions.iter().map(|p| p.as_vec3()).collect();
    let mut moved = rounded.clone();
    let weights = selfcollide::inverse_masses(model);
    selfcollide::resolve(&mut moved, &weights, &model.adjacency, config);
    for (p, (after, before)) in state.positions.iter_mut().zip(moved.iter().zip(&rounded)) {
        *p += (*after - *before).as_dvec3();
    }
}

impl Solver for ReferenceSolver {
    fn describe(&self) -> String {
        "reference (f64, 1 thread)".to_owned()
    }

    fn set_material(&mut self, material: &Material) -> Result<(), SimError> {
        self.material = *material;
        Ok(())
    }

    fn set_control(&mut self, control: &Control) -> Result<(), SimError> {
        apply_pushes(
            &mut self.colliders,
            &self.model.collision.colliders,
            &control.ball_pushes,
        );
        self.control = control.clone();
        Ok(())
    }

    fn set_self_collision(&mut self, config: Option<SelfCollision>) -> Result<(), SimError> {
        self.self_collision = config;
        Ok(())
    }

    fn step(&mut self, steps: u32) -> Result<(), SimError> {
        for _ in 0..steps {
            self.step_once()?;
        }
        Ok(())
    }

    /// Phases are not separated in this solver: the whole step counts as force calculation.
    fn step_timed(&mut self) -> Result<(PhaseTimes, TimingSource), SimError> {
        let start = std::time::Instant::now();
        self.step_once()?;
        let times = PhaseTimes {
            force_calculation: start.elapsed(),
            ..Default::default()
        };
        Ok((times, TimingSource::WallClock))
    }

    fn read_state(&self) -> Result<State, SimError> {
        Ok(self.state.clone())
    }

    fn write_state(&mut self, state: &State) {
        self.state = state.clone();
    }

    fn steps_taken(&self) -> u64 {
        self.steps_taken
    }

    fn colliders(&self) -> Result<Vec<Collider>, SimError> {
        Ok(placed(
            &self.colliders,
            self.steps_taken as f64 * self.material.dt,
        ))
    }

    fn broken_springs(&self) -> Result<Vec<u32>, SimError> {
        Ok(self.tears.list())
    }

    fn restore(&mut self, snapshot: &Snapshot) -> Result<(), SimError> {
        self.tears.restore(&snapshot.broken_springs)?;
        self.state = snapshot.state.clone();
        restore_balls(&mut self.colliders, &snapshot.colliders);
        self.steps_taken = snapshot.steps_taken;
        Ok(())
    }
}
