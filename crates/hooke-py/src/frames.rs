//! `hooke.FrameWriter`: a simulation's frames from Python, in the formats `hooke run` writes
//! (PLY or OBJ sequences, a Blender point cache, a USD stage), through the same writer.

use std::path::PathBuf;
use std::sync::Mutex;

use hooke_core::frames::{FrameDestination, FrameFormat, FrameTiming};
use pyo3::prelude::*;

use crate::errors::{HookeError, OrRaise, input};
use crate::simulation::Simulation;

/// Writes frames of one simulation: `write()` adds the current state; `close()` (or leaving a
/// `with` block) completes a `.pc2` or `.usda` file, which appears under its name only then.
#[pyclass(module = "hooke._native", name = "FrameWriter")]
pub struct FrameWriter {
    simulation: Py<Simulation>,
    writer: Mutex<Option<hooke_core::frames::FrameWriter>>,
    path: PathBuf,
}

impl std::fmt::Debug for FrameWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "FrameWriter({})", self.path.display())
    }
}

#[pymethods]
impl FrameWriter {
    /// Frames of `simulation` into `output`: a directory (`frame-NNNNNNN.ply` or `.obj`, or
    /// `frames.pc2` / `frames.usda`), or a `.usda` or `.pc2` file. `format` is `"ply"`,
    /// `"obj"`, `"pc2"` or `"usda"` (default: the file's extension, else `"ply"`);
    /// `frame_every` is the steps between frames, which sets the USD time codes.
    #[new]
    #[pyo3(signature = (simulation, output, *, format = None, frame_every = 1))]
    fn new(
        simulation: Bound<'_, Simulation>,
        output: PathBuf,
        format: Option<&str>,
        frame_every: u64,
    ) -> PyResult<Self> {
        let format = format
            .map(|name| {
                FrameFormat::from_name(name).ok_or_else(|| {
                    input(format!(
                        "format '{name}': expected one of {}",
                        FrameFormat::choices()
                    ))
                })
            })
            .transpose()?;
        if frame_every == 0 {
            return Err(input("frame_every must be at least 1"));
        }
        let destination = FrameDestination::resolve(&output, format).map_err(|c| {
            input(format!(
                "{} is a .{} file but format is '{}'",
                output.display(),
                c.named.name(),
                c.given.name()
            ))
        })?;
        std::fs::create_dir_all(&destination.directory)
            .map_err(|e| input(format!("{}: {e}", destination.directory.display())))?;
        let owner = simulation.borrow();
        let writer = owner.with(|s| {
            let timing = FrameTiming {
                dt: s.material().dt,
                frame_every,
            };
            Ok(hooke_core::frames::FrameWriter::to(
                &destination,
                owner.name(),
                &s.model().triangles,
                owner.uvs(),
                timing,
            ))
        })?;
        drop(owner);
        Ok(Self {
            simulation: simulation.unbind(),
            writer: Mutex::new(Some(writer)),
            path: output,
        })
    }

    /// Adds the simulation's current state as the frame of its step counter.
    fn write(&self, py: Python<'_>) -> PyResult<()> {
        let mut guard = self.lock()?;
        let writer = guard
            .as_mut()
            .ok_or_else(|| HookeError::new_err("the frame writer is closed"))?;
        self.simulation.borrow(py).with(|s| {
            let state = s.state().or_raise()?;
            let colliders = if writer.draws_colliders() {
                s.colliders().or_raise()?
            } else {
                Vec::new()
            };
            let step = s.steps_taken();
            writer
                .write(step, &state.positions, &colliders)
                .map_err(|e| input(format!("{}: {e}", writer.path(step).display())))
        })
    }

    /// Completes the output (a `.pc2` or `.usda` file appears now) and returns the number of
    /// frames written. Closing again does nothing.
    fn close(&self) -> PyResult<usize> {
        let mut guard = self.lock()?;
        match guard.take() {
            Some(writer) => writer
                .finish()
                .map_err(|e| input(format!("{}: {e}", self.path.display()))),
            None => Ok(0),
        }
    }

    /// Frames written so far.
    #[getter]
    fn frames_written(&self) -> PyResult<usize> {
        Ok(self.lock()?.as_ref().map_or(0, |w| w.frames_written()))
    }

    /// Where the frames go (the directory or the file given).
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    /// Closes the writer, also when the block raised: the frames written so far are kept.
    fn __exit__(
        &self,
        _kind: Option<Bound<'_, PyAny>>,
        _value: Option<Bound<'_, PyAny>>,
        _traceback: Option<Bound<'_, PyAny>>,
    ) -> PyResult<bool> {
        self.close()?;
        Ok(false)
    }

    fn __repr__(&self) -> String {
        format!("<hooke.FrameWriter {}>", self.path.display())
    }
}

impl FrameWriter {
    fn lock(&self) -> PyResult<std::sync::MutexGuard<'_, Option<hooke_core::frames::FrameWriter>>> {
        self.writer
            .lock()
            .map_err(|_| HookeError::new_err("the frame writer failed in another thread"))
    }
}

impl Drop for FrameWriter {
    /// A writer nobody closed still completes its file: frames are never thrown away.
    fn drop(&mut self) {
        if let Ok(mut guard) = self.writer.lock()
            && let Some(writer) = guard.take()
        {
            let _ = writer.finish();
        }
    }
}
