//! The GPU device: adapter choice, optional features, and device errors as values.

use std::sync::{Arc, Mutex};

/// Optional features hooke uses when the adapter has them.
pub const OPTIONAL_FEATURES: wgpu::Features = wgpu::Features::SHADER_FLOAT32_ATOMIC
    .union(wgpu::Features::TIMESTAMP_QUERY)
    .union(wgpu::Features::FLOAT32_BLENDABLE);

#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error(
        "no GPU adapter found ({0}); on Debian, `apt-get install mesa-vulkan-drivers` provides a software one"
    )]
    NoAdapter(String),
    #[error("the GPU device could not be created: {0}")]
    Device(String),
    #[error("{what} needs {feature}, which {adapter} does not have")]
    Unsupported {
        what: String,
        feature: &'static str,
        adapter: String,
    },
    #[error("{what}: the mesh needs {needed} bytes in one buffer; {adapter} allows {limit}")]
    TooLarge {
        what: &'static str,
        needed: u64,
        limit: u64,
        adapter: String,
    },
    #[error("GPU error: {0}")]
    Validation(String),
    #[error("reading back from the GPU failed: {0}")]
    ReadBack(String),
}

/// One adapter as `hooke info --gpu` lists it.
#[derive(Clone, Debug)]
pub struct AdapterSummary {
    pub info: wgpu::AdapterInfo,
    pub features: wgpu::Features,
}

/// An adapter, its device and queue, and the optional features that were granted.
#[derive(Debug)]
pub struct GpuContext {
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    /// The optional features (of [`OPTIONAL_FEATURES`]) this device has.
    pub features: wgpu::Features,
    errors: Arc<Mutex<Vec<String>>>,
    /// Read-backs that waited for the GPU (see [`GpuContext::blocking_reads`]).
    blocking_reads: std::sync::atomic::AtomicU64,
    /// Compute and render pipelines created (see [`GpuContext::pipelines_created`]).
    pipelines_created: std::sync::atomic::AtomicU64,
}

fn instance() -> wgpu::Instance {
    // Honours WGPU_BACKEND and the other WGPU_* instance variables.
    wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env())
}

/// Every adapter the instance sees, with its features.
pub fn list_adapters() -> Vec<AdapterSummary> {
    let instance = instance();
    pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()))
        .into_iter()
        .map(|a| AdapterSummary {
            info: a.get_info(),
            features: a.features(),
        })
        .collect()
}

impl GpuContext {
    /// Opens the adapter named by `WGPU_ADAPTER_NAME` (and `WGPU_BACKEND`), else the default one.
    pub fn new() -> Result<Arc<Self>, GpuError> {
        Self::open(&instance(), None)
    }

    /// Opens an adapter that can present to `window`, and the surface for it.
    pub fn for_window<W>(window: Arc<W>) -> Result<(Arc<Self>, wgpu::Surface<'static>), GpuError>
    where
        W: wgpu::rwh::HasWindowHandle
            + wgpu::rwh::HasDisplayHandle
            + std::fmt::Debug
            + Send
            + Sync
            + 'static,
    {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_with_display_handle_from_env(
                Box::new(Arc::clone(&window)),
            ));
        let surface = instance
            .create_surface(window)
            .map_err(|e| GpuError::Device(format!("cannot draw into the window: {e}")))?;
        let context = Self::open(&instance, Some(&surface))?;
        Ok((context, surface))
    }

    /// Opens an adapter that can present to a web page's canvas, and the surface for it. In a
    /// browser nothing may block, so this one is async.
    #[cfg(target_arch = "wasm32")]
    pub async fn for_canvas(
        canvas: wgpu::web_sys::HtmlCanvasElement,
    ) -> Result<(Arc<Self>, wgpu::Surface<'static>), GpuError> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends: wgpu::Backends::BROWSER_WEBGPU,
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        });
        let surface = instance
            .create_surface(wgpu::SurfaceTarget::Canvas(canvas))
            .map_err(|e| GpuError::Device(format!("cannot draw into the canvas: {e}")))?;
        let context = Self::open_async(&instance, Some(&surface)).await?;
        Ok((context, surface))
    }

    fn open(
        instance: &wgpu::Instance,
        surface: Option<&wgpu::Surface<'_>>,
    ) -> Result<Arc<Self>, GpuError> {
        pollster::block_on(Self::open_async(instance, surface))
    }

    async fn open_async(
        instance: &wgpu::Instance,
        surface: Option<&wgpu::Surface<'_>>,
    ) -> Result<Arc<Self>, GpuError> {
        let adapter = wgpu::util::initialize_adapter_from_env_or_default(instance, surface)
            .await
            .map_err(|e| GpuError::NoAdapter(e.to_string()))?;
        let info = adapter.get_info();
        let features = adapter.features() & OPTIONAL_FEATURES;
        let available = adapter.limits();
        let limits = wgpu::Limits {
            max_storage_buffer_binding_size: available.max_storage_buffer_binding_size,
            max_buffer_size: available.max_buffer_size,
            max_compute_workgroups_per_dimension: available.max_compute_workgroups_per_dimension,
            ..wgpu::Limits::default()
        };
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("hooke"),
                required_features: features,
                required_limits: limits,
                ..Default::default()
            })
            .await
            .map_err(|e| GpuError::Device(e.to_string()))?;
        // wgpu's default handler panics; keep errors as values and report them on the next call.
        let errors = Arc::new(Mutex::new(Vec::new()));
        let sink = Arc::clone(&errors);
        device.on_uncaptured_error(Arc::new(move |error: wgpu::Error| {
            if let Ok(mut errors) = sink.lock() {
                errors.push(error.to_string());
            }
        }));
        let lost = Arc::clone(&errors);
        device.set_device_lost_callback(move |reason, message| {
            if let Ok(mut errors) = lost.lock() {
                errors.push(format!("device lost ({reason:?}): {message}"));
            }
        });
        Ok(Arc::new(Self {
            adapter,
            device,
            queue,
            info,
            features,
            errors,
            blocking_reads: Default::default(),
            pipelines_created: Default::default(),
        }))
    }

    /// `"llvmpipe (LLVM 15.0.6, 256 bits), Vulkan, Cpu"`.
    pub fn describe(&self) -> String {
        format!(
            "{}, {:?}, {:?}",
            self.info.name, self.info.backend, self.info.device_type
        )
    }

    pub fn has(&self, feature: wgpu::Features) -> bool {
        self.features.contains(feature)
    }

    /// One line per optional feature: granted, or what hooke does without it.
    pub fn feature_report(&self) -> Vec<String> {
        [
            (
                wgpu::Features::SHADER_FLOAT32_ATOMIC,
                "SHADER_FLOAT32_ATOMIC",
                "scatter atomic-f32 unavailable; use atomic-fixed or incidence",
            ),
            (
                wgpu::Features::TIMESTAMP_QUERY,
                "TIMESTAMP_QUERY",
                "per-phase times fall back to wall clock with a wait per phase",
            ),
            (
                wgpu::Features::FLOAT32_BLENDABLE,
                "FLOAT32_BLENDABLE",
                "scatter blend-r32f unavailable; blend-r16f and blend-rgba8 remain",
            ),
        ]
        .into_iter()
        .map(|(feature, name, fallback)| {
            if self.has(feature) {
                format!("{name}: yes")
            } else {
                format!("{name}: no ({fallback})")
            }
        })
        .collect()
    }

    /// How many read-backs so far waited for the GPU. An interactive frame loop must not add
    /// to it; the viewer reports it and its smoke test checks it.
    pub fn blocking_reads(&self) -> u64 {
        self.blocking_reads
            .load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Counts a read-back that waits for the GPU.
    pub(crate) fn note_blocking_read(&self) {
        self.blocking_reads
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }

    /// Whether command buffers get debug groups (each pass under its phase's name). Not on
    /// Mesa's lavapipe (llvmpipe over Vulkan): Mesa 22.3's build crashes (SIGSEGV) on
    /// command-buffer debug labels; every other adapter records them.
    pub fn records_debug_groups(&self) -> bool {
        !(self.info.backend == wgpu::Backend::Vulkan && self.info.name.starts_with("llvmpipe"))
    }

    /// How many compute and render pipelines were created on this device. Compiling a pipeline
    /// stalls a frame on a real GPU: an interactive frame loop, a drag, a slider must not add
    /// to it; the viewer reports it and its smoke test checks it.
    pub fn pipelines_created(&self) -> u64 {
        self.pipelines_created
            .load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Counts a pipeline creation (every one goes through `gpu::compute_pipeline` or
    /// `gpu::render_pipeline`).
    pub(crate) fn note_pipeline(&self) {
        self.pipelines_created
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }

    /// Records an error to be returned by the next [`GpuContext::take_error`].
    pub(crate) fn report(&self, message: String) {
        if let Ok(mut errors) = self.errors.lock() {
            errors.push(message);
        }
    }

    /// Device errors since the last call, as one error.
    pub fn take_error(&self) -> Result<(), GpuError> {
        let mut errors = self
            .errors
            .lock()
            .map_err(|e| GpuError::Validation(e.to_string()))?;
        if errors.is_empty() {
            Ok(())
        } else {
            let joined = errors.join("; ");
            errors.clear();
            Err(GpuError::Validation(joined))
        }
    }
}

/// Whether tests must fail rather than skip without an adapter (`HOOKE_REQUIRE_GPU=1`, set by CI).
pub fn gpu_required() -> bool {
    std::env::var("HOOKE_REQUIRE_GPU").is_ok_and(|v| v == "1")
}

/// The device for a test, or `None` with the reason printed when there is none; without one a
/// test panics instead when [`gpu_required`].
pub fn test_context() -> Option<Arc<GpuContext>> {
    match GpuContext::new() {
        Ok(context) => Some(context),
        Err(error) if gpu_required() => panic!("HOOKE_REQUIRE_GPU=1 but no GPU: {error}"),
        Err(error) => {
            eprintln!("GPU solvers not tested: {error}");
            None
        }
    }
}
