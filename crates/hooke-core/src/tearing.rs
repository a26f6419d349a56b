//! Tearing: springs that break when stretched too far, the rule every solver follows.
//!
//! At the start of each step, before any force, every unbroken spring is tested on the
//! positions the step starts from. An edge spring breaks when its ends are more than
//! `max_stretch` times its rest length apart. A bending spring is the hinge between two
//! triangles: it breaks when any of their five edges passes that test, so a tear is never held
//! shut by bending springs across it. Tests are done in float32 on float32 positions by every
//! solver (the reference rounds its own), and each is a function of the positions alone, so the
//! same positions break the same springs everywhere, in any order. A broken spring exerts no
//! force from then on, for good (a snapshot keeps the list), and a triangle with a broken edge
//! is no longer drawn.

use glam::Vec3;

use crate::{Model, SimError};

/// When springs break.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tearing {
    /// A spring breaks when stretched past this many times its rest length (more than 1).
    pub max_stretch: f64,
}

/// An edge spring's test: its two vertices and the square of the length at which it breaks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TearTest {
    pub ends: [u32; 2],
    pub limit_squared: f32,
}

impl TearTest {
    /// True if the ends, at `a` and `b`, are far enough apart to break the spring.
    #[inline]
    pub fn breaks(&self, a: Vec3, b: Vec3) -> bool {
        let d = b - a;
        // Written out so that every solver (and WGSL's tear kernel) sums in the same order.
        d.x * d.x + d.y * d.y + d.z * d.z > self.limit_squared
    }
}

/// The tests of a model's springs under a [`Tearing`].
#[derive(Clone, Debug, PartialEq)]
pub struct TearRule {
    /// Per spring in order; a bending spring's test is never used (it has `hinges`).
    tests: Vec<TearTest>,
    /// The first bending spring: springs from here on break with their hinges.
    first_bending: usize,
    /// Per bending spring, the edge springs of its two triangles.
    hinges: Vec<[u32; 5]>,
    /// Per edge spring, the bending springs whose hinges hold it (CSR: `edge_hinges.range(e)`).
    edge_hinges: crate::Adjacency,
}

impl TearRule {
    pub fn new(model: &Model, tearing: &Tearing) -> Self {
        let tests = (0..model.spring_count())
            .map(|s| {
                let limit = tearing.max_stretch * model.rest_lengths[s];
                TearTest {
                    ends: model.spring_ends[s],
                    limit_squared: (limit * limit) as f32,
                }
            })
            .collect();
        let first_bending = model.first_bending_spring();
        // Each hinge edge paired with its bending spring, as a two-ended "spring" whose far
        // end is the bending spring's index: the CSR lists an edge's hinges in order.
        let pairs: Vec<[u32; 2]> = model
            .bending_hinges
            .iter()
            .enumerate()
            .flat_map(|(k, hinge)| {
                let bending = (first_bending + k) as u32;
                hinge.iter().map(move |&e| [e, bending])
            })
            .collect();
        let edge_hinges = crate::Adjacency::from_springs(model.spring_count(), &pairs);
        Self {
            tests,
            first_bending,
            hinges: model.bending_hinges.clone(),
            edge_hinges,
        }
    }

    /// True if edge spring `e` (one of the first [`TearRule::first_bending`]) is past its limit
    /// with its vertices at `position`s.
    #[inline]
    pub fn edge_breaks(&self, e: usize, position: impl Fn(u32) -> Vec3) -> bool {
        let test = &self.tests[e];
        test.breaks(position(test.ends[0]), position(test.ends[1]))
    }

    /// The springs that break, in order, given the edge springs that pass their test
    /// (`passing`, from [`TearRule::edge_breaks`] on the same positions), leaving out those
    /// already `broken`: those edges, and every bending spring with one of them in its hinge.
    /// The work is the passing edges' hinges, not every spring.
    pub fn breaking(&self, passing: &[u32], broken: &[bool]) -> Vec<u32> {
        let mut springs: Vec<u32> = passing
            .iter()
            .flat_map(|&e| {
                let hinges = self.edge_hinges.range(e as usize);
                std::iter::once(e).chain(self.edge_hinges.neighbors[hinges].iter().copied())
            })
            .filter(|&s| !broken[s as usize])
            .collect();
        springs.sort_unstable();
        springs.dedup();
        springs
    }

    /// Per spring, its test (a bending spring's is its own ends', unused).
    pub fn tests(&self) -> &[TearTest] {
        &self.tests
    }

    pub fn first_bending(&self) -> usize {
        self.first_bending
    }

    pub fn hinges(&self) -> &[[u32; 5]] {
        &self.hinges
    }

    pub fn spring_count(&self) -> usize {
        self.tests.len()
    }
}

/// A solver's tearing state: which springs have broken, and (when the model tears) the rule
/// that breaks more.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Tears {
    rule: Option<TearRule>,
    broken: Vec<bool>,
    count: usize,
}

impl Tears {
    /// Nothing broken yet; springs break only if `model.tearing` says so.
    pub fn new(model: &Model) -> Self {
        Self {
            rule: model.tearing.map(|t| TearRule::new(model, &t)),
            broken: vec![false; model.spring_count()],
            count: 0,
        }
    }

    /// Breaks the springs that `position`s stretch past their limits; returns how many.
    pub fn test(&mut self, position: impl Fn(u32) -> Vec3) -> usize {
        let Some(rule) = &self.rule else {
            return 0;
        };
        let newly = newly_broken(rule, &self.broken, position);
        self.mark(&newly);
        newly.len()
    }

    /// The rule, when the model tears.
    pub fn rule(&self) -> Option<&TearRule> {
        self.rule.as_ref()
    }

    /// Marks `newly` broken (springs a solver found with [`TearRule::breaks`]).
    pub fn mark(&mut self, newly: &[u32]) {
        for &s in newly {
            self.count += usize::from(!self.broken[s as usize]);
            self.broken[s as usize] = true;
        }
    }

    /// Per spring: broken or not.
    pub fn flags(&self) -> &[bool] {
        &self.broken
    }

    pub fn is_broken(&self, spring: usize) -> bool {
        self.broken[spring]
    }

    /// How many springs have broken.
    pub fn count(&self) -> usize {
        self.count
    }

    /// The broken springs, in order.
    pub fn list(&self) -> Vec<u32> {
        broken_list(&self.broken)
    }

    /// Takes a snapshot's list of broken springs (every other spring whole again).
    pub fn restore(&mut self, list: &[u32]) -> Result<(), SimError> {
        self.broken = broken_flags(list, self.broken.len())?;
        self.count = self.broken.iter().filter(|b| **b).count();
        Ok(())
    }
}

/// The springs that are not yet `broken` and that `rule` breaks at `position`s, in order.
pub fn newly_broken(rule: &TearRule, broken: &[bool], position: impl Fn(u32) -> Vec3) -> Vec<u32> {
    let passing: Vec<u32> = (0..rule.first_bending() as u32)
        .filter(|&e| rule.edge_breaks(e as usize, &position))
        .collect();
    rule.breaking(&passing, broken)
}

/// The indices of the `true` flags, in order: a state's broken springs as a list.
pub fn broken_list(broken: &[bool]) -> Vec<u32> {
    (0..broken.len() as u32)
        .filter(|&s| broken[s as usize])
        .collect()
}

/// Flags for `spring_count` springs with those of `list` set; an error if the list names a
/// spring that does not exist.
pub fn broken_flags(list: &[u32], spring_count: usize) -> Result<Vec<bool>, SimError> {
    let mut flags = vec![false; spring_count];
    for &spring in list {
        *flags
            .get_mut(spring as usize)
            .ok_or(SimError::NoSuchSpring {
                spring,
                spring_count,
            })? = true;
    }
    Ok(flags)
}

/// Per triangle, the springs along its three edges (what drawing checks for a broken edge).
pub fn triangle_edge_springs(model: &Model) -> Vec<[u32; 3]> {
    let index = model.edge_springs();
    model
        .triangles
        .iter()
        .map(|t| {
            std::array::from_fn(|k| {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                index[&[a.min(b), a.max(b)]]
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{GridPlane, grid};
    use crate::{MassModel, ModelOptions, StiffnessModel};
    use glam::DVec3;

    fn sheet_with_bending() -> Model {
        let mesh = grid(4, 3, [3.0, 2.0], GridPlane::Xy, DVec3::ZERO);
        let options = ModelOptions {
            stiffness: StiffnessModel::Uniform(10.0),
            mass: MassModel::PerVertex(1.0),
            rest_length_scale: 1.0,
            pinned: vec![],
        };
        let mut model = Model::from_mesh(&mesh, &options).expect("model");
        model
            .add_bending_springs(&mesh.bending_pairs(), 1.0, 1.0)
            .expect("bending");
        model
    }

    #[test]
    fn a_spring_breaks_only_past_its_limit_and_bending_springs_with_their_edge() {
        let model = sheet_with_bending();
        let rule = TearRule::new(&model, &Tearing { max_stretch: 1.5 });
        let broken = vec![false; model.spring_count()];
        let at_rest = |v: u32| model.initial_positions[v as usize].as_vec3();
        assert!(newly_broken(&rule, &broken, at_rest).is_empty());
        // Stretch the sheet 1.4x along x: no spring is past 1.5x.
        let stretched = |f: f32| move |v: u32| at_rest(v) * Vec3::new(f, 1.0, 1.0);
        assert!(newly_broken(&rule, &broken, stretched(1.4)).is_empty());
        // At 1.6x the horizontal edges break, the diagonals (1.6 * 1 by 1: 1.34x) do not, and
        // so does every bending spring with a horizontal edge among its triangles' (all of
        // them on this sheet, every triangle having one).
        let torn = newly_broken(&rule, &broken, stretched(1.6));
        let horizontal = |s: usize| {
            let [a, b] = model.spring_ends[s];
            model.initial_positions[a as usize].y == model.initial_positions[b as usize].y
        };
        for s in 0..model.spring_count() {
            let breaks = match model.bending_hinge(s) {
                Some(hinge) => hinge.iter().any(|&e| horizontal(e as usize)),
                None => horizontal(s),
            };
            assert_eq!(torn.contains(&(s as u32)), breaks, "spring {s}");
        }
        assert!(torn.iter().any(|&s| model.is_bending(s as usize)));
        // Broken springs are not reported again.
        let flags = broken_flags(&torn, model.spring_count()).expect("in range");
        let more = newly_broken(&rule, &flags, stretched(2.0));
        assert!(!more.is_empty() && more.iter().all(|&s| !flags[s as usize]));
        assert!(newly_broken(&rule, &flags, stretched(1.6)).is_empty());
        assert_eq!(broken_list(&flags), torn);
        let n = model.spring_count();
        assert_eq!(
            broken_flags(&[n as u32], n),
            Err(SimError::NoSuchSpring {
                spring: n as u32,
                spring_count: n
            })
        );
    }

    #[test]
    fn each_triangle_lists_the_springs_of_its_edges() {
        let model = sheet_with_bending();
        for (t, springs) in model.triangles.iter().zip(triangle_edge_springs(&model)) {
            for (k, s) in springs.iter().enumerate() {
                let [a, b] = model.spring_ends[*s as usize];
                let (p, q) = (t[k], t[(k + 1) % 3]);
                assert_eq!([a.min(b), a.max(b)], [p.min(q), p.max(q)]);
            }
        }
    }
}
