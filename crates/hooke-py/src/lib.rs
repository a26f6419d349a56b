//! `hooke._native`: the Python binding of [`hooke::Simulation`]. The public package
//! (`python/hooke/__init__.py`) re-exports it; `_native.pyi` types it.
//!
//! Arrays cross as numpy arrays: positions out as float32 `(N, 3)` arrays made from a vector
//! the binding gives up (no copy after the read-back); arrays in are read in place when they
//! are already contiguous and of the right type. Stepping releases the GIL.

use pyo3::prelude::*;

mod convert;
mod errors;
mod frames;
mod simulation;

pub use errors::{GpuError, HookeError, InputError, SimulationError};

/// The GPU adapters wgpu sees, as dicts: name, backend, device type, driver, optional features.
#[pyfunction]
fn adapters(py: Python<'_>) -> PyResult<Vec<Bound<'_, pyo3::types::PyDict>>> {
    hooke_gpu::list_adapters()
        .into_iter()
        .map(|adapter| {
            let dict = pyo3::types::PyDict::new(py);
            dict.set_item("name", &adapter.info.name)?;
            dict.set_item(
                "backend",
                format!("{:?}", adapter.info.backend).to_lowercase(),
            )?;
            dict.set_item("device_type", format!("{:?}", adapter.info.device_type))?;
            dict.set_item("driver", &adapter.info.driver)?;
            let features: Vec<String> = hooke_gpu::OPTIONAL_FEATURES
                .iter_names()
                .filter(|(_, f)| adapter.features.contains(*f))
                .map(|(name, _)| name.to_owned())
                .collect();
            dict.set_item("features", features)?;
            Ok(dict)
        })
        .collect()
}

/// The springs hooke makes of `triangles`: one per unique edge, in the order that per-spring
/// arrays (`stiffness=`) follow. `(S, 2)` uint32.
#[pyfunction]
fn springs<'py>(
    py: Python<'py>,
    triangles: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, numpy::PyArray2<u32>>> {
    let triangles = convert::triangles(triangles)?;
    let vertex_count = triangles
        .iter()
        .flatten()
        .max()
        .map_or(0, |m| *m as usize + 1);
    let mesh = hooke_core::mesh::Mesh {
        positions: vec![glam::DVec3::ZERO; vertex_count],
        triangles,
        ..Default::default()
    };
    let ends: Vec<[u32; 2]> = mesh.edges().iter().map(|e| [e.a, e.b]).collect();
    Ok(convert::rows(py, &ends))
}

#[pymodule]
fn _native(module: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = module.py();
    module.add_class::<simulation::Simulation>()?;
    module.add_class::<simulation::Snapshot>()?;
    module.add_class::<frames::FrameWriter>()?;
    module.add_function(wrap_pyfunction!(adapters, module)?)?;
    module.add_function(wrap_pyfunction!(springs, module)?)?;
    module.add("HookeError", py.get_type::<HookeError>())?;
    module.add("InputError", py.get_type::<InputError>())?;
    module.add("SimulationError", py.get_type::<SimulationError>())?;
    module.add("GpuError", py.get_type::<GpuError>())?;
    Ok(())
}
