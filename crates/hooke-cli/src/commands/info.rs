//! `hooke info`: what a scene is made of, its stable time step and what each method stores.

use std::path::PathBuf;

use clap::Args;
use comfy_table::Table;
use hooke::{MemoryReport, Simulation, SolverChoice};
use hooke_core::collide::{Collider, KeyframePath, Shape};
use hooke_core::handles::{Handle, HandleMotion};
use hooke_core::stability::stability_limit;
use hooke_cpu::layout::VertexOrder;
use hooke_cpu::{CpuOptions, Method};
use hooke_gpu::{GpuContext, GpuMethod, list_adapters};
use serde::Serialize;

use crate::format::{OutputFormat, bytes, table};
use crate::scene_loading::load_scene;

#[derive(Debug, Args)]
#[command(arg_required_else_help = true)]
pub struct InfoArgs {
    /// Scene file (TOML).
    pub scene: Option<PathBuf>,
    /// List GPU adapters and their optional features.
    #[arg(long)]
    pub gpu: bool,
    #[arg(long, value_enum, default_value_t = OutputFormat::Table)]
    pub format: OutputFormat,
}

#[derive(Debug, Serialize)]
struct MethodMemory {
    method: &'static str,
    /// The paper's Table 1 model, in texels: RGB (3 floats) and RGBA (4 floats).
    paper_rgb_texels: usize,
    paper_rgba_texels: usize,
    paper_bytes_fp32: usize,
    /// What hooke's cpu solver allocates.
    positions_bytes: usize,
    topology_bytes: usize,
    per_step_bytes: usize,
    total_bytes: usize,
}

#[derive(Debug, Serialize)]
struct GpuMethodMemory {
    method: String,
    positions_bytes: u64,
    topology_bytes: u64,
    per_step_bytes: u64,
    /// Control (point forces, drags, wind) and collider buffers, allocated whether used or not.
    control_bytes: u64,
    total_bytes: u64,
}

#[derive(Debug, Serialize)]
struct AdapterEntry {
    name: String,
    backend: String,
    device_type: String,
    shader_float32_atomic: bool,
    timestamp_query: bool,
    float32_blendable: bool,
}

#[derive(Debug, Serialize)]
struct Info {
    scene: String,
    vertices: usize,
    triangles: usize,
    springs: usize,
    /// Of `springs`, those joining the far vertices of triangle pairs (`[bending]`).
    bending_springs: usize,
    /// Each bending spring's own damping, N s/m.
    bending_damping: f64,
    pinned: usize,
    total_mass_kg: f64,
    /// `valence_histogram[v]` vertices have v springs.
    valence_histogram: Vec<usize>,
    max_valence: usize,
    mean_valence: f64,
    max_stable_dt: f64,
    limiting_vertex: Option<usize>,
    dt: f64,
    memory: Vec<MethodMemory>,
    /// GPU buffers each method allocates on the adapter in use (empty without a GPU).
    gpu_adapter: Option<String>,
    gpu_memory: Vec<GpuMethodMemory>,
    /// One line per collider: its kind, motion and place.
    colliders: Vec<String>,
    /// The self-collision setting, if on.
    self_collision: Option<String>,
    /// One line per handle: its vertices and what moves it.
    handles: Vec<String>,
    /// Springs break past this many times their rest length (`[tearing]`), if they do.
    tearing_max_stretch: Option<f64>,
}

/// A collider's or handle's keyframed path in a few words.
fn describe_path(path: &KeyframePath) -> String {
    format!(
        "keyframed path, {} keyframes{}",
        path.keyframes().len(),
        if path.repeat { ", repeating" } else { "" }
    )
}

/// A handle in a few words.
fn describe_handle(handle: &Handle) -> String {
    let motion = match &handle.motion {
        HandleMotion::Path(path) => describe_path(path),
        HandleMotion::Collider(c) => format!("follows collider {c}"),
    };
    format!("{} vertices; {motion}", handle.vertices.len())
}

/// A collider in a few words.
fn describe_collider(collider: &Collider) -> String {
    let shape = match collider.shape {
        Shape::Sphere { center, radius } => format!("sphere r = {radius} m at {center}"),
        Shape::Plane { point, normal } => format!("plane through {point}, normal {normal}"),
        Shape::Capsule { start, end, radius } => {
            format!("capsule r = {radius} m from {start} to {end}")
        }
    };
    let motion = match (collider.dynamics, collider.path) {
        (Some(d), _) => format!(
            "dynamic ball {} kg, force {} N, restitution {}",
            d.mass, d.force, d.restitution
        ),
        (None, Some(path)) => describe_path(&path),
        (None, None) if collider.velocity != glam::DVec3::ZERO => {
            format!("moving at {} m/s", collider.velocity)
        }
        (None, None) => "static".to_owned(),
    };
    format!("{shape}; {motion}; friction {}", collider.friction)
}

pub fn run(args: &InfoArgs) -> anyhow::Result<()> {
    if args.gpu {
        print_adapters(args.format)?;
    }
    let Some(path) = &args.scene else {
        return Ok(());
    };
    let scene = load_scene(path, true)?;
    let model = &scene.model;
    let (n_v, n_e) = (model.vertex_count(), model.spring_count());
    let histogram = model.valence_histogram();
    let max_valence = histogram.len().saturating_sub(1);
    let limit = stability_limit(model, scene.material.damping);
    let mut memory = Vec::new();
    for method in Method::ALL {
        let options = CpuOptions {
            method,
            threads: Some(1),
            order: VertexOrder::Mesh,
            ..Default::default()
        };
        let simulation = Simulation::new(model, &scene.material, SolverChoice::Cpu(options), None)?;
        let MemoryReport::Cpu(used) = simulation.memory() else {
            anyhow::bail!("the cpu solver reports cpu memory");
        };
        // Table 1: PCA stores N references+constants per vertex (RGB) and position+mass (RGBA);
        // ECA stores a force per edge (RGB) and edges plus positions (RGBA).
        let (rgb, rgba) = match method {
            Method::Gather => (max_valence * n_v, n_v),
            Method::Scatter => (n_e, n_e + n_v),
        };
        memory.push(MethodMemory {
            method: method.name(),
            paper_rgb_texels: rgb,
            paper_rgba_texels: rgba,
            paper_bytes_fp32: 12 * rgb + 16 * rgba,
            positions_bytes: used.positions,
            topology_bytes: used.topology,
            per_step_bytes: used.per_step,
            total_bytes: used.total(),
        });
    }
    let (gpu_adapter, gpu_memory) = gpu_memory(&scene);
    let info = Info {
        scene: scene.name.clone(),
        vertices: n_v,
        triangles: model.triangles.len(),
        springs: n_e,
        bending_springs: model.bending_springs,
        bending_damping: model.bending_damping,
        pinned: model.pinned.iter().filter(|p| **p).count(),
        total_mass_kg: model.total_mass(),
        mean_valence: 2.0 * n_e as f64 / n_v as f64,
        valence_histogram: histogram,
        max_valence,
        max_stable_dt: limit.max_dt,
        limiting_vertex: limit.limiting_vertex,
        dt: scene.material.dt,
        memory,
        gpu_adapter,
        gpu_memory,
        colliders: scene.model.collision.colliders.iter().map(describe_collider).collect(),
        handles: scene.model.handles.iter().map(describe_handle).collect(),
        tearing_max_stretch: scene.model.tearing.map(|t| t.max_stretch),
        self_collision: scene.model.collision.self_collision.map(|c| {
            format!(
                "distance {} m, cells {} m, K = {} grids (shifted k/K of a cell along (1,1,1)), window {}",
                c.distance, c.cell_size, c.grids, c.window
            )
        }),
    };
    match args.format {
        OutputFormat::Json => println!("{}", serde_json::to_string_pretty(&info)?),
        OutputFormat::Table => print_info(&info),
    }
    Ok(())
}

fn print_info(info: &Info) {
    println!("scene           {}", info.scene);
    let bending = match (info.bending_springs, info.bending_damping) {
        (0, _) => String::new(),
        (n, 0.0) => format!(" ({n} of them bending)"),
        (n, c) => format!(" ({n} of them bending, damped {c} N s/m)"),
    };
    println!(
        "mesh            {} vertices, {} triangles, {} springs{bending}, {} pinned",
        info.vertices, info.triangles, info.springs, info.pinned
    );
    println!("total mass      {:.6} kg", info.total_mass_kg);
    println!(
        "valence         mean {:.2}, max {} (N in the paper's Table 1)",
        info.mean_valence, info.max_valence
    );
    let mut valences = Table::new();
    valences.set_header(vec!["valence", "vertices", "share"]);
    for (valence, count) in info
        .valence_histogram
        .iter()
        .enumerate()
        .filter(|(_, c)| **c > 0)
    {
        valences.add_row(vec![
            valence.to_string(),
            count.to_string(),
            format!("{:.1}%", 100.0 * *count as f64 / info.vertices as f64),
        ]);
    }
    println!("{}", table(valences));
    println!(
        "stable dt       {:.4e} s (set by vertex {}); this scene uses dt = {:.4e} s{}",
        info.max_stable_dt,
        info.limiting_vertex
            .map_or("-".to_owned(), |v| v.to_string()),
        info.dt,
        if info.dt > info.max_stable_dt {
            "  ABOVE THE BOUND"
        } else {
            ""
        }
    );
    for (k, collider) in info.colliders.iter().enumerate() {
        println!("collider {k}      {collider}");
    }
    if let Some(setting) = &info.self_collision {
        println!("self-collision  {setting}");
    }
    for (k, handle) in info.handles.iter().enumerate() {
        println!("handle {k}        {handle}");
    }
    if let Some(stretch) = info.tearing_max_stretch {
        println!(
            "tearing         springs break past {stretch} times their rest length (bending springs with their triangles)"
        );
    }
    let mut memory = Table::new();
    memory.set_header(vec![
        "method",
        "paper RGB texels",
        "paper RGBA texels",
        "paper fp32 bytes",
        "hooke positions",
        "hooke topology",
        "hooke per-step",
        "hooke total",
    ]);
    for m in &info.memory {
        memory.add_row(vec![
            m.method.to_owned(),
            m.paper_rgb_texels.to_string(),
            m.paper_rgba_texels.to_string(),
            bytes(m.paper_bytes_fp32),
            bytes(m.positions_bytes),
            bytes(m.topology_bytes),
            bytes(m.per_step_bytes),
            bytes(m.total_bytes),
        ]);
    }
    println!("memory (paper's Table 1 model next to what the cpu solver allocates):");
    println!("{}", table(memory));
    match &info.gpu_adapter {
        Some(adapter) => {
            let mut gpu = Table::new();
            gpu.set_header(vec![
                "gpu method",
                "positions",
                "topology",
                "per-step",
                "control, colliders",
                "total",
            ]);
            for m in &info.gpu_memory {
                gpu.add_row(vec![
                    m.method.clone(),
                    bytes(m.positions_bytes as usize),
                    bytes(m.topology_bytes as usize),
                    bytes(m.per_step_bytes as usize),
                    bytes(m.control_bytes as usize),
                    bytes(m.total_bytes as usize),
                ]);
            }
            println!("gpu buffers on {adapter} (methods the adapter supports):");
            println!("{}", table(gpu));
        }
        None => println!("gpu buffers: no GPU adapter available"),
    }
}

/// GPU buffer bytes of every method the adapter supports, from real allocations.
fn gpu_memory(scene: &hooke_core::scene::Scene) -> (Option<String>, Vec<GpuMethodMemory>) {
    let Ok(context) = GpuContext::new() else {
        return (None, Vec::new());
    };
    let rows = GpuMethod::all()
        .into_iter()
        .filter_map(|method| {
            let choice = SolverChoice::Gpu(method);
            let simulation =
                Simulation::new(&scene.model, &scene.material, choice, Some(context.clone()))
                    .ok()?;
            let MemoryReport::Gpu(m) = simulation.memory() else {
                return None;
            };
            Some(GpuMethodMemory {
                method: method.name(),
                positions_bytes: m.positions,
                topology_bytes: m.topology,
                per_step_bytes: m.per_step,
                control_bytes: m.control,
                total_bytes: m.total(),
            })
        })
        .collect();
    (Some(context.describe()), rows)
}

fn print_adapters(format: OutputFormat) -> anyhow::Result<()> {
    let adapters: Vec<AdapterEntry> = list_adapters()
        .into_iter()
        .map(|a| AdapterEntry {
            name: a.info.name.clone(),
            backend: format!("{:?}", a.info.backend),
            device_type: format!("{:?}", a.info.device_type),
            shader_float32_atomic: a
                .features
                .contains(hooke_gpu::wgpu::Features::SHADER_FLOAT32_ATOMIC),
            timestamp_query: a
                .features
                .contains(hooke_gpu::wgpu::Features::TIMESTAMP_QUERY),
            float32_blendable: a
                .features
                .contains(hooke_gpu::wgpu::Features::FLOAT32_BLENDABLE),
        })
        .collect();
    if format == OutputFormat::Json {
        println!("{}", serde_json::to_string_pretty(&adapters)?);
        return Ok(());
    }
    let yes = |b: bool| if b { "yes" } else { "no" }.to_owned();
    let mut t = Table::new();
    t.set_header(vec![
        "adapter",
        "backend",
        "type",
        "float32 atomics",
        "timestamps",
        "float32 blending",
    ]);
    for a in &adapters {
        t.add_row(vec![
            a.name.clone(),
            a.backend.clone(),
            a.device_type.clone(),
            yes(a.shader_float32_atomic),
            yes(a.timestamp_query),
            yes(a.float32_blendable),
        ]);
    }
    println!("{}", table(t));
    match GpuContext::new() {
        Ok(context) => println!(
            "in use: {} (WGPU_BACKEND / WGPU_ADAPTER_NAME choose another)",
            context.describe()
        ),
        Err(error) => println!("in use: none ({error})"),
    }
    Ok(())
}
