//! hooke's exceptions and the mapping of the library's errors onto them. Each carries the
//! library's message unchanged (a scene error names the file, line and field, as on the CLI).

use pyo3::PyErr;
use pyo3::exceptions::PyException;

pyo3::create_exception!(
    _native,
    HookeError,
    PyException,
    "Every error hooke raises is a HookeError."
);
pyo3::create_exception!(
    _native,
    InputError,
    HookeError,
    "A scene, mesh, array or argument that hooke cannot take (the message says which and why)."
);
pyo3::create_exception!(
    _native,
    SimulationError,
    HookeError,
    "The simulation left the numbers (non-finite positions, an explosion) or a fixed-point sum overflowed."
);
pyo3::create_exception!(
    _native,
    GpuError,
    HookeError,
    "No GPU adapter, a missing optional feature, or a device error."
);

/// An input error with `message`.
pub fn input(message: impl Into<String>) -> PyErr {
    InputError::new_err(message.into())
}

/// Maps a library error onto hooke's exceptions.
pub trait IntoPyErr {
    fn into_py_err(self) -> PyErr;
}

impl IntoPyErr for hooke_core::SimError {
    fn into_py_err(self) -> PyErr {
        SimulationError::new_err(self.to_string())
    }
}

impl IntoPyErr for hooke_gpu::GpuError {
    fn into_py_err(self) -> PyErr {
        GpuError::new_err(self.to_string())
    }
}

impl IntoPyErr for hooke::EngineError {
    fn into_py_err(self) -> PyErr {
        match self {
            hooke::EngineError::Gpu(e) => e.into_py_err(),
            hooke::EngineError::Simulation(e) => e.into_py_err(),
            hooke::EngineError::Cpu(e) => HookeError::new_err(e.to_string()),
            other => input(other.to_string()),
        }
    }
}

impl IntoPyErr for hooke::FrameError {
    fn into_py_err(self) -> PyErr {
        match self {
            hooke::FrameError::Gpu(e) => e.into_py_err(),
            hooke::FrameError::Simulation(e) => e.into_py_err(),
        }
    }
}

/// Errors of reading input (scene files, meshes, saved states, images): the input's fault.
macro_rules! input_errors {
    ($($error:ty),*) => {$(
        impl IntoPyErr for $error {
            fn into_py_err(self) -> PyErr {
                input(self.to_string())
            }
        }
    )*};
}
input_errors!(
    hooke_core::scene::SceneError,
    hooke_core::mesh::MeshLoadError,
    hooke_core::mesh::MeshError,
    hooke_core::ModelError,
    hooke::state_file::StateFileError,
    std::io::Error,
    hooke_gpu::render::ImageError
);

/// `result.map_err(IntoPyErr::into_py_err)`, shorter.
pub trait OrRaise<T> {
    fn or_raise(self) -> pyo3::PyResult<T>;
}

impl<T, E: IntoPyErr> OrRaise<T> for Result<T, E> {
    fn or_raise(self) -> pyo3::PyResult<T> {
        self.map_err(IntoPyErr::into_py_err)
    }
}
