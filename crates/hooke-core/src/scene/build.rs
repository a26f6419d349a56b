//! [`SceneFile::build`]: range checks naming the field, the mesh, the pins, the model and the
//! time step.

use std::path::Path;

use glam::DVec3;

use super::inputs::keyframe_path;
use super::{
    MeshGenerator, PinSection, Scene, SceneError, SceneFile, StiffnessKind, TimeStep, require,
    select_vertices,
};
use crate::handles::{Handle, HandleMotion};
use crate::mesh::{self, Mesh, MeshWarning};
use crate::stability::{AUTO_DT_SAFETY, stability_limit};
use crate::tearing::Tearing;
use crate::{MassModel, Material, Model, ModelOptions, StiffnessModel};

/// Generated sheets are 1 micrometre to 1000 km a side: beyond that, float32 positions cannot
/// tell neighbouring vertices apart and the generators' spacing arithmetic overflows.
const MIN_SIDE: f64 = 1e-6;
const MAX_SIDE: f64 = 1e6;
/// The longest side over the shortest: a thinner strip would need more than a million times
/// more cells along its length than across it in the irregular generator's sampling grid.
const MAX_ASPECT: f64 = 1e4;

impl SceneFile {
    /// Checks every value, builds the mesh and model, and settles the time step.
    ///
    /// `path` locates mesh files and names the scene in errors. A dt above the stability bound is
    /// an error unless `allow_unstable`.
    pub fn build(&self, path: &Path, allow_unstable: bool) -> Result<Scene, SceneError> {
        let path_name = path.display().to_string();
        let invalid = |field: &str, message: String| SceneError::Invalid {
            path: path_name.clone(),
            field: field.to_owned(),
            message,
        };
        let (mesh, mesh_warnings) = self.build_mesh(path, &invalid)?;
        self.build_with_mesh(mesh, mesh_warnings, path, allow_unstable)
    }

    /// Builds the scene around a mesh given directly (arrays from Python, say): the `[mesh]`
    /// section is not read. `path` names the scene in errors.
    pub fn build_with_mesh(
        &self,
        mesh: Mesh,
        mesh_warnings: Vec<MeshWarning>,
        path: &Path,
        allow_unstable: bool,
    ) -> Result<Scene, SceneError> {
        let path_name = path.display().to_string();
        let invalid = |field: &str, message: String| SceneError::Invalid {
            path: path_name.clone(),
            field: field.to_owned(),
            message,
        };

        let material = &self.material;
        // The masses a vertex property gives replace a placeholder once the model is built.
        let mass_property = material
            .mass
            .property
            .as_deref()
            .map(|name| vertex_property(&mesh, name, "material.mass.property", &invalid))
            .transpose()?;
        let mass = match (
            material.mass.total,
            material.mass.per_vertex,
            material.mass.area_density,
            &mass_property,
        ) {
            (Some(total), None, None, None) => MassModel::TotalUniform(total),
            (None, Some(m), None, None) => MassModel::PerVertex(m),
            (None, None, Some(rho), None) => MassModel::AreaDensity(rho),
            (None, None, None, Some(_)) => MassModel::PerVertex(1.0),
            _ => {
                return Err(invalid(
                    "material.mass",
                    "give exactly one of total, per_vertex, area_density or property".into(),
                ));
            }
        };
        let stiffness_factors = self.stiffness_factors(&mesh, &invalid)?;
        let bending = self.bending.as_ref().filter(|b| b.enabled);
        for (field, value) in [
            ("bending.stiffness", bending.map(|b| b.stiffness)),
            ("material.mass.total", material.mass.total),
            ("material.mass.per_vertex", material.mass.per_vertex),
            ("material.mass.area_density", material.mass.area_density),
            ("material.stiffness", Some(material.stiffness)),
            (
                "material.rest_length_scale",
                Some(material.rest_length_scale),
            ),
        ] {
            if let Some(value) = value {
                require(value > 0.0 && value.is_finite(), || {
                    invalid(field, format!("must be a positive number, found {value}"))
                })?;
            }
        }
        require(
            material.damping >= 0.0 && material.damping.is_finite(),
            || {
                invalid(
                    "material.damping",
                    format!("must be zero or positive, found {}", material.damping),
                )
            },
        )?;
        let stiffness = match material.stiffness_model {
            StiffnessKind::Uniform => StiffnessModel::Uniform(material.stiffness),
            StiffnessKind::InverseRestLength => {
                StiffnessModel::InverseRestLength(material.stiffness)
            }
        };
        let pinned = select_pinned(&mesh, &self.pins, "pins", &invalid)?;
        let options = ModelOptions {
            stiffness,
            mass,
            rest_length_scale: material.rest_length_scale,
            pinned,
        };
        let mut model =
            Model::from_mesh(&mesh, &options).map_err(|e| invalid("material", e.to_string()))?;
        if let Some(masses) = mass_property {
            model.masses = masses;
        }
        if let Some(bending) = bending {
            model
                .add_bending_springs(
                    &mesh.bending_pairs(),
                    bending.stiffness,
                    material.rest_length_scale,
                )
                .map_err(|e| invalid("bending", e.to_string()))?;
            let damping = bending.damping;
            require(damping >= 0.0 && damping.is_finite(), || {
                invalid(
                    "bending.damping",
                    format!("must be zero or positive, found {damping}"),
                )
            })?;
            model.bending_damping = damping;
        }
        if let Some(factors) = stiffness_factors {
            for (k, [a, b]) in model.stiffnesses.iter_mut().zip(&model.spring_ends) {
                *k *= 0.5 * (factors[*a as usize] + factors[*b as usize]);
            }
        }

        if let Some(tearing) = self.tearing.as_ref().filter(|t| t.enabled) {
            let max_stretch = tearing.max_stretch;
            require(max_stretch > 1.0 && max_stretch.is_finite(), || {
                invalid(
                    "tearing.max_stretch",
                    format!(
                        "must be a number above 1 (a spring's length over its rest length), found {max_stretch}"
                    ),
                )
            })?;
            model.tearing = Some(Tearing { max_stretch });
        }

        let (control, collision) = self.build_inputs(&mesh, &invalid)?;
        model.collision = collision;
        self.resolve_handles(&mesh, &mut model, &invalid)?;
        require(self.simulation.frame_every > 0, || {
            invalid("simulation.frame_every", "must be at least 1".into())
        })?;
        let name = self.name.clone().unwrap_or_else(|| {
            path.file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "scene".to_owned())
        });
        let mut scene = Scene {
            name,
            mesh,
            mesh_warnings,
            model,
            material: Material {
                dt: 0.0,
                damping: material.damping,
                gravity: DVec3::from_array(self.simulation.gravity),
                stiffness_scale: 1.0,
            },
            control,
            steps: self.simulation.steps,
            frame_every: self.simulation.frame_every,
            max_stable_dt: 0.0,
        };
        scene.set_time_step(self.simulation.dt, path, allow_unstable)?;
        Ok(scene)
    }
}

/// The vertices a `[pins]`-like section names (indices, selectors and boxes, added up), sorted;
/// `prefix` names the section in errors.
fn select_pinned(
    mesh: &Mesh,
    pins: &PinSection,
    prefix: &str,
    invalid: &dyn Fn(&str, String) -> SceneError,
) -> Result<Vec<u32>, SceneError> {
    let count = mesh.vertex_count();
    let mut pinned = Vec::new();
    for &v in &pins.vertices {
        require((v as usize) < count, || {
            invalid(
                &format!("{prefix}.vertices"),
                format!("vertex {v} does not exist (mesh has {count} vertices)"),
            )
        })?;
        pinned.push(v);
    }
    for selector in &pins.select {
        pinned.extend(select_vertices(mesh, *selector));
    }
    for (k, b) in pins.boxes.iter().enumerate() {
        pinned.extend(vertices_in_box(mesh, b.min, b.max, &|message| {
            invalid(&format!("{prefix}.boxes[{k}]"), message)
        })?);
    }
    pinned.sort_unstable();
    pinned.dedup();
    Ok(pinned)
}

/// The vertices of `mesh` inside the box from `min` to `max` (boundary included); a box that
/// holds none is an error, made by `invalid`, since it is a mistake in the scene.
fn vertices_in_box(
    mesh: &Mesh,
    min: [f64; 3],
    max: [f64; 3],
    invalid: &dyn Fn(String) -> SceneError,
) -> Result<Vec<u32>, SceneError> {
    let (lo, hi) = (DVec3::from_array(min), DVec3::from_array(max));
    let inside: Vec<u32> = (0..mesh.vertex_count() as u32)
        .filter(|&i| {
            let p = mesh.positions[i as usize];
            p.cmpge(lo).all() && p.cmple(hi).all()
        })
        .collect();
    require(!inside.is_empty(), || invalid("contains no vertex".into()))?;
    Ok(inside)
}

/// The mesh's per-vertex property `name`, every value positive and finite; `field` is the
/// scene key that named it.
fn vertex_property(
    mesh: &Mesh,
    name: &str,
    field: &str,
    invalid: &dyn Fn(&str, String) -> SceneError,
) -> Result<Vec<f64>, SceneError> {
    let values = mesh.vertex_properties.get(name).ok_or_else(|| {
        let known: Vec<&str> = mesh.vertex_properties.keys().map(String::as_str).collect();
        invalid(
            field,
            if known.is_empty() {
                format!(
                    "the mesh has no vertex property '{name}' (it has none; PLY files can carry them)"
                )
            } else {
                format!(
                    "the mesh has no vertex property '{name}' (it has: {})",
                    known.join(", ")
                )
            },
        )
    })?;
    if let Some(vertex) = values.iter().position(|v| !(*v > 0.0 && v.is_finite())) {
        return Err(invalid(
            field,
            format!(
                "'{name}' must be a positive number at every vertex, found {} at vertex {vertex}",
                values[vertex]
            ),
        ));
    }
    Ok(values.clone())
}

impl Scene {
    /// Sets dt from the stability bound of the model as it is now (after a caller changed its
    /// masses or stiffnesses, say): `"auto"` is a safe fraction of the bound; a dt above the
    /// bound is refused unless `allow_unstable`. `path` names the scene in errors.
    pub fn set_time_step(
        &mut self,
        dt: TimeStep,
        path: &Path,
        allow_unstable: bool,
    ) -> Result<(), SceneError> {
        let path_name = path.display().to_string();
        let invalid = |field: &str, message: String| SceneError::Invalid {
            path: path_name.clone(),
            field: field.to_owned(),
            message,
        };
        let limit = stability_limit(&self.model, self.material.damping);
        self.material.dt = match dt {
            TimeStep::Auto => {
                require(limit.max_dt.is_finite(), || {
                    invalid(
                        "simulation.dt",
                        "\"auto\" needs springs or damping to bound the step; give dt in seconds"
                            .into(),
                    )
                })?;
                AUTO_DT_SAFETY * limit.max_dt
            }
            TimeStep::Seconds(dt) => {
                require(dt > 0.0 && dt.is_finite(), || {
                    invalid(
                        "simulation.dt",
                        format!("must be a positive number of seconds, found {dt}"),
                    )
                })?;
                if dt > limit.max_dt && !allow_unstable {
                    return Err(SceneError::UnstableTimeStep {
                        path: path_name,
                        dt,
                        max_dt: limit.max_dt,
                        vertex: limit.limiting_vertex.unwrap_or(0),
                    });
                }
                dt
            }
        };
        self.max_stable_dt = limit.max_dt;
        Ok(())
    }
}

impl SceneFile {
    fn build_mesh(
        &self,
        path: &Path,
        invalid: &dyn Fn(&str, String) -> SceneError,
    ) -> Result<(Mesh, Vec<MeshWarning>), SceneError> {
        let section = &self.mesh;
        require(section.center.iter().all(|c| c.is_finite()), || {
            invalid(
                "mesh.center",
                format!("must be finite, found {:?}", section.center),
            )
        })?;
        let center = DVec3::from_array(section.center);
        if section.generator != MeshGenerator::File {
            require(
                section
                    .size
                    .iter()
                    .all(|s| (MIN_SIDE..=MAX_SIDE).contains(s)),
                || {
                    invalid(
                        "mesh.size",
                        format!(
                            "both sides must be {MIN_SIDE:e}..={MAX_SIDE:e} m, found {:?}",
                            section.size
                        ),
                    )
                },
            )?;
            let [a, b] = section.size;
            require(a.max(b) <= MAX_ASPECT * a.min(b), || {
                invalid(
                    "mesh.size",
                    format!(
                        "one side may be at most {MAX_ASPECT:e} times the other, found {:?}",
                        section.size
                    ),
                )
            })?;
        }
        let mesh = match section.generator {
            MeshGenerator::Grid => {
                let [columns, rows] = section.resolution.ok_or_else(|| {
                    invalid(
                        "mesh.resolution",
                        "a grid needs resolution = [columns, rows]".into(),
                    )
                })?;
                require(
                    (2..=8192).contains(&columns) && (2..=8192).contains(&rows),
                    || {
                        invalid(
                            "mesh.resolution",
                            format!(
                                "each side must be 2..=8192 vertices, found [{columns}, {rows}]"
                            ),
                        )
                    },
                )?;
                mesh::grid(columns, rows, section.size, section.plane, center)
            }
            MeshGenerator::Irregular => {
                let vertices = section.vertices.ok_or_else(|| {
                    invalid(
                        "mesh.vertices",
                        "an irregular mesh needs vertices = N".into(),
                    )
                })?;
                require((16..=50_000_000).contains(&vertices), || {
                    invalid(
                        "mesh.vertices",
                        format!("must be 16..=50000000, found {vertices}"),
                    )
                })?;
                mesh::irregular(vertices, section.size, section.seed, section.plane, center)
            }
            MeshGenerator::File => {
                let relative = section.path.as_ref().ok_or_else(|| {
                    invalid(
                        "mesh.path",
                        "generator = \"file\" needs path = \"mesh.obj\"".into(),
                    )
                })?;
                let file = path.parent().unwrap_or(Path::new("")).join(relative);
                let (mut mesh, warnings) = mesh::load_mesh(&file)?;
                for p in &mut mesh.positions {
                    *p += center;
                }
                return Ok((mesh, warnings));
            }
        };
        let warnings = mesh
            .validate(&format!("{} (generated mesh)", path.display()))
            .map_err(mesh::MeshLoadError::from)?;
        Ok((mesh, warnings))
    }

    /// The scene's `[[handle]]`s, their vertices pinned in `model` (whose colliders are set).
    fn resolve_handles(
        &self,
        mesh: &Mesh,
        model: &mut Model,
        invalid: &dyn Fn(&str, String) -> SceneError,
    ) -> Result<(), SceneError> {
        for (k, section) in self.handles.iter().enumerate() {
            let field = format!("handle[{k}]");
            let vertices = select_pinned(mesh, &section.pins(), &field, invalid)?;
            require(!vertices.is_empty(), || {
                invalid(
                    &field,
                    "holds no vertex: give vertices, select or boxes".into(),
                )
            })?;
            let colliders = model.collision.colliders.len();
            let motion = match (&section.path, section.collider) {
                (Some(keys), None) => HandleMotion::Path(Box::new(keyframe_path(
                    keys,
                    section.repeat,
                    &format!("{field}.path"),
                    invalid,
                )?)),
                (None, Some(c)) => {
                    require(c < colliders, || {
                        invalid(
                            &format!("{field}.collider"),
                            format!("collider {c} does not exist (the scene has {colliders})"),
                        )
                    })?;
                    HandleMotion::Collider(c)
                }
                _ => {
                    return Err(invalid(
                        &field,
                        "give exactly one of path (keyframes [t, dx, dy, dz]) or collider (an index)"
                            .into(),
                    ));
                }
            };
            for &v in &vertices {
                model.pinned[v as usize] = true;
            }
            model.handles.push(Handle { vertices, motion });
        }
        Ok(())
    }

    /// Per-vertex stiffness factors from `material.stiffness_property` and the
    /// `material.stiffness_region` boxes, multiplied; `None` when the scene has neither.
    fn stiffness_factors(
        &self,
        mesh: &Mesh,
        invalid: &dyn Fn(&str, String) -> SceneError,
    ) -> Result<Option<Vec<f64>>, SceneError> {
        let material = &self.material;
        let mut factors = material
            .stiffness_property
            .as_deref()
            .map(|name| vertex_property(mesh, name, "material.stiffness_property", invalid))
            .transpose()?;
        for (k, region) in material.stiffness_regions.iter().enumerate() {
            let field = format!("material.stiffness_region[{k}]");
            require(region.factor > 0.0 && region.factor.is_finite(), || {
                invalid(
                    &format!("{field}.factor"),
                    format!("must be a positive number, found {}", region.factor),
                )
            })?;
            let inside = vertices_in_box(mesh, region.min, region.max, &|m| invalid(&field, m))?;
            let factors = factors.get_or_insert_with(|| vec![1.0; mesh.vertex_count()]);
            for v in inside {
                factors[v as usize] *= region.factor;
            }
        }
        Ok(factors)
    }
}
