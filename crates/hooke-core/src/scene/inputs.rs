//! The scene's control (wind, point forces, drags) and collision set-up (colliders,
//! self-collision), each value checked with the field named.

use glam::DVec3;

use super::{ColliderKind, SceneError, SceneFile, SelfCollisionSection, require};
use crate::collide::{Collider, Dynamics, KeyframePath, MAX_KEYFRAMES, Shape};
use crate::mesh::Mesh;
use crate::selfcollide::{self, SelfCollision};
use crate::{Collision, Control, Drag, PointForce, Wind};

impl SceneFile {
    /// The scene's per-step inputs (wind, forces, drags) and its collision set-up.
    pub(super) fn build_inputs(
        &self,
        mesh: &Mesh,
        invalid: &dyn Fn(&str, String) -> SceneError,
    ) -> Result<(Control, Collision), SceneError> {
        let count = mesh.vertex_count();
        let check_vertices =
            |field: &str, vertices: &[u32]| match vertices.iter().find(|v| **v as usize >= count) {
                Some(v) => Err(invalid(
                    field,
                    format!("vertex {v} does not exist (mesh has {count} vertices)"),
                )),
                None => Ok(()),
            };
        let finite = |field: &str, v: [f64; 3]| {
            require(v.iter().all(|x| x.is_finite()), || {
                invalid(field, format!("must be finite, found {v:?}"))
            })
        };
        finite("simulation.gravity", self.simulation.gravity)?;
        let wind = match &self.wind {
            Some(w) => {
                finite("wind.velocity", w.velocity)?;
                require(w.coefficient >= 0.0 && w.coefficient.is_finite(), || {
                    invalid(
                        "wind.coefficient",
                        format!("must be zero or positive, found {}", w.coefficient),
                    )
                })?;
                Some(Wind {
                    velocity: DVec3::from_array(w.velocity),
                    coefficient: w.coefficient,
                })
            }
            None => None,
        };
        let mut point_forces = Vec::new();
        for (k, f) in self.forces.iter().enumerate() {
            check_vertices(&format!("force[{k}].vertices"), &f.vertices)?;
            finite(&format!("force[{k}].force"), f.force)?;
            point_forces.extend(f.vertices.iter().map(|&vertex| PointForce {
                vertex,
                force: DVec3::from_array(f.force),
            }));
        }
        let mut drags = Vec::new();
        for (k, d) in self.drags.iter().enumerate() {
            check_vertices(&format!("drag[{k}].vertices"), &d.vertices)?;
            finite(&format!("drag[{k}].target"), d.target)?;
            require(d.stiffness >= 0.0 && d.stiffness.is_finite(), || {
                invalid(
                    &format!("drag[{k}].stiffness"),
                    format!("must be zero or positive, found {}", d.stiffness),
                )
            })?;
            drags.push(Drag {
                vertices: d.vertices.clone(),
                target: DVec3::from_array(d.target),
                stiffness: d.stiffness,
            });
        }
        let mut colliders = Vec::new();
        for (k, c) in self.colliders.iter().enumerate() {
            let field = |name: &str| format!("collider[{k}].{name}");
            let need = |name: &str, value: Option<[f64; 3]>| {
                let value = value.ok_or_else(|| {
                    invalid(
                        &field(name),
                        format!("a {:?} collider needs {name}", c.kind),
                    )
                })?;
                finite(&field(name), value)?;
                Ok::<DVec3, SceneError>(DVec3::from_array(value))
            };
            require((0.0..=1.0).contains(&c.friction), || {
                invalid(
                    &field("friction"),
                    format!("must be 0..=1, found {}", c.friction),
                )
            })?;
            // A key of another kind of collider is a mistake, not something to ignore.
            let foreign: &[(&str, bool)] = match c.kind {
                ColliderKind::Sphere => &[
                    ("point", c.point.is_some()),
                    ("normal", c.normal.is_some()),
                    ("start", c.start.is_some()),
                    ("end", c.end.is_some()),
                ],
                ColliderKind::Capsule => &[
                    ("center", c.center.is_some()),
                    ("point", c.point.is_some()),
                    ("normal", c.normal.is_some()),
                ],
                ColliderKind::Plane => &[
                    ("center", c.center.is_some()),
                    ("radius", c.radius.is_some()),
                    ("start", c.start.is_some()),
                    ("end", c.end.is_some()),
                ],
            };
            for (name, set) in foreign {
                require(!set, || {
                    invalid(
                        &field(name),
                        format!(
                            "does not apply to a {} collider",
                            format!("{:?}", c.kind).to_lowercase()
                        ),
                    )
                })?;
            }
            // A scripted path starts where its first keyframe is.
            let start = c
                .path
                .as_ref()
                .and_then(|keys| keys.first())
                .map(|[_, x, y, z]| [*x, *y, *z]);
            let radius = || {
                let radius = c.radius.unwrap_or(f64::NAN);
                require(radius > 0.0 && radius.is_finite(), || {
                    invalid(
                        &field("radius"),
                        format!("must be a positive number, found {radius}"),
                    )
                })?;
                Ok::<f64, SceneError>(radius)
            };
            let shape = match c.kind {
                ColliderKind::Sphere => Shape::Sphere {
                    center: need("center", c.center.or(start))?,
                    radius: radius()?,
                },
                ColliderKind::Capsule => Shape::Capsule {
                    start: need("start", c.start.or(start))?,
                    end: need("end", c.end)?,
                    radius: radius()?,
                },
                ColliderKind::Plane => {
                    let normal = need("normal", c.normal)?;
                    let normal = normal
                        .try_normalize()
                        .ok_or_else(|| invalid(&field("normal"), "must not be zero".into()))?;
                    Shape::Plane {
                        point: need("point", c.point.or(start))?,
                        normal,
                    }
                }
            };
            let path = match &c.path {
                None => None,
                Some(keys) => {
                    for (name, set) in [
                        ("velocity", c.velocity.is_some()),
                        ("mass", c.mass.is_some()),
                    ] {
                        require(!set, || {
                            invalid(
                                &field(name),
                                "a collider with a path cannot have one".into(),
                            )
                        })?;
                    }
                    Some(keyframe_path(keys, c.repeat, &field("path"), invalid)?)
                }
            };
            let velocity = match c.velocity {
                Some(v) => {
                    finite(&field("velocity"), v)?;
                    DVec3::from_array(v)
                }
                None => DVec3::ZERO,
            };
            let dynamics = match (c.mass, c.kind) {
                (None, _) => {
                    for (name, set) in [
                        ("force", c.force.is_some()),
                        ("restitution", c.restitution.is_some()),
                    ] {
                        require(!set, || {
                            invalid(&field(name), "applies only to a ball with a mass".into())
                        })?;
                    }
                    None
                }
                (Some(_), ColliderKind::Plane | ColliderKind::Capsule) => {
                    return Err(invalid(
                        &field("mass"),
                        "only spheres can be dynamic".into(),
                    ));
                }
                (Some(mass), ColliderKind::Sphere) => {
                    require(mass > 0.0 && mass.is_finite(), || {
                        invalid(
                            &field("mass"),
                            format!("must be a positive number, found {mass}"),
                        )
                    })?;
                    let restitution = c.restitution.unwrap_or(0.3);
                    require((0.0..=1.0).contains(&restitution), || {
                        invalid(
                            &field("restitution"),
                            format!("must be 0..=1, found {restitution}"),
                        )
                    })?;
                    let force = c.force.unwrap_or([0.0; 3]);
                    finite(&field("force"), force)?;
                    Some(Dynamics {
                        mass,
                        force: DVec3::from_array(force),
                        restitution,
                    })
                }
            };
            colliders.push(Collider {
                shape,
                friction: c.friction,
                velocity,
                dynamics,
                spin: DVec3::ZERO,
                path,
            });
        }
        let collision_thickness = self.collision.as_ref().map_or(0.0, |c| c.thickness);
        require(
            collision_thickness >= 0.0 && collision_thickness.is_finite(),
            || {
                invalid(
                    "collision.thickness",
                    format!("must be zero or positive, found {collision_thickness}"),
                )
            },
        )?;
        let self_collision = self.self_collision_params(invalid)?;
        let control = Control {
            wind,
            point_forces,
            drags,
            ball_pushes: Vec::new(),
        };
        let collision = Collision {
            colliders,
            thickness: collision_thickness,
            self_collision,
        };
        Ok((control, collision))
    }

    fn self_collision_params(
        &self,
        invalid: &dyn Fn(&str, String) -> SceneError,
    ) -> Result<Option<SelfCollision>, SceneError> {
        self.self_collision
            .as_ref()
            .map_or(Ok(None), |section| section.params(invalid))
    }
}

impl SelfCollisionSection {
    /// The self-collision set-up this section asks for (`None` when disabled), its ranges
    /// checked; `invalid` makes the error for a field.
    pub fn params(
        &self,
        invalid: &dyn Fn(&str, String) -> SceneError,
    ) -> Result<Option<SelfCollision>, SceneError> {
        if !self.enabled {
            return Ok(None);
        }
        let section = self;
        let positive = |name: &str, value: f64| {
            require(value > 0.0 && value.is_finite(), || {
                invalid(
                    &format!("self_collision.{name}"),
                    format!("must be a positive number, found {value}"),
                )
            })
        };
        positive("distance", section.distance)?;
        let cell_size = section.cell_size.unwrap_or(2.0 * section.distance);
        positive("cell_size", cell_size)?;
        for (name, value, max) in [
            ("grids", section.grids, selfcollide::MAX_GRIDS),
            ("window", section.window, selfcollide::MAX_WINDOW),
        ] {
            require((1..=max).contains(&value), || {
                invalid(
                    &format!("self_collision.{name}"),
                    format!("must be 1..={max}, found {value}"),
                )
            })?;
        }
        Ok(Some(SelfCollision {
            distance: section.distance,
            cell_size,
            grids: section.grids,
            window: section.window,
        }))
    }
}

/// The keyframed path `keys` (`[t, x, y, z]`), checked; `field` names it in errors.
pub(super) fn keyframe_path(
    keys: &[[f64; 4]],
    repeat: bool,
    field: &str,
    invalid: &dyn Fn(&str, String) -> SceneError,
) -> Result<KeyframePath, SceneError> {
    require(keys.iter().flatten().all(|x| x.is_finite()), || {
        invalid(field, "keyframes must be finite".into())
    })?;
    let keys: Vec<(f64, DVec3)> = keys
        .iter()
        .map(|[t, x, y, z]| (*t, DVec3::new(*x, *y, *z)))
        .collect();
    KeyframePath::new(&keys, repeat).ok_or_else(|| {
        invalid(
            field,
            format!(
                "needs 2 to {MAX_KEYFRAMES} keyframes [t, x, y, z] with increasing t, found {}",
                keys.len()
            ),
        )
    })
}
