//! The GPU solver's choices: the data structure (gather or scatter) and scatter's
//! accumulation, and what each costs in memory.

/// How scatter (ECA) sums the spring forces at the vertices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Accumulation {
    /// Float atomics (needs SHADER_FLOAT32_ATOMIC); summation order varies from run to run.
    AtomicF32,
    /// Integer atomics on fixed-point values; deterministic, works on WebGPU.
    AtomicFixed,
    /// Each vertex gathers its springs' forces; deterministic, no atomics.
    Incidence,
    /// The paper's path: point primitives blended into a 32-bit float target.
    BlendR32f,
    /// ... into a 16-bit float target.
    BlendR16f,
    /// ... into two 8-bit fixed-point targets (positive and negative parts), as the paper had to.
    BlendRgba8,
}

impl Accumulation {
    pub const ALL: [Accumulation; 6] = [
        Self::AtomicF32,
        Self::AtomicFixed,
        Self::Incidence,
        Self::BlendR32f,
        Self::BlendR16f,
        Self::BlendRgba8,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Self::AtomicF32 => "atomic-f32",
            Self::AtomicFixed => "atomic-fixed",
            Self::Incidence => "incidence",
            Self::BlendR32f => "blend-r32f",
            Self::BlendR16f => "blend-r16f",
            Self::BlendRgba8 => "blend-rgba8",
        }
    }

    /// The accumulation of this [`Accumulation::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|a| a.name() == name)
    }

    /// Whether results are bit-identical from run to run by construction. (Blending happens in
    /// primitive order, so the blend paths are deterministic on conforming hardware too; the
    /// tests check it rather than promise it.)
    pub fn is_deterministic(self) -> bool {
        matches!(self, Self::AtomicFixed | Self::Incidence)
    }

    pub(crate) fn required_feature(self) -> Option<(wgpu::Features, &'static str)> {
        match self {
            Self::AtomicF32 => Some((
                wgpu::Features::SHADER_FLOAT32_ATOMIC,
                "SHADER_FLOAT32_ATOMIC",
            )),
            Self::BlendR32f => Some((wgpu::Features::FLOAT32_BLENDABLE, "FLOAT32_BLENDABLE")),
            _ => None,
        }
    }

    pub(crate) fn blend_format(self) -> Option<wgpu::TextureFormat> {
        match self {
            Self::BlendR32f => Some(wgpu::TextureFormat::Rgba32Float),
            Self::BlendR16f => Some(wgpu::TextureFormat::Rgba16Float),
            Self::BlendRgba8 => Some(wgpu::TextureFormat::Rgba8Unorm),
            _ => None,
        }
    }
}

/// Which of the paper's data structures the GPU solver uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GpuMethod {
    /// Point-centric (PCA): per-vertex sums over a CSR adjacency in valence-sorted order.
    Gather,
    /// Edge-centric (ECA): one force per spring, then an accumulation.
    Scatter(Accumulation),
}

impl GpuMethod {
    /// Every method, gather first.
    pub fn all() -> Vec<GpuMethod> {
        std::iter::once(Self::Gather)
            .chain(Accumulation::ALL.map(Self::Scatter))
            .collect()
    }

    /// `"gather"` or `"scatter/<accumulation>"`.
    pub fn name(self) -> String {
        match self {
            Self::Gather => "gather".to_owned(),
            Self::Scatter(a) => format!("scatter/{}", a.name()),
        }
    }

    /// The method of this [`GpuMethod::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        match name.split_once('/') {
            None if name == "gather" => Some(Self::Gather),
            Some(("scatter", accumulation)) => {
                Accumulation::from_name(accumulation).map(Self::Scatter)
            }
            _ => None,
        }
    }

    pub fn is_deterministic(self) -> bool {
        match self {
            Self::Gather => true,
            Self::Scatter(a) => a.is_deterministic(),
        }
    }
}

/// Bytes of GPU memory by role (the paper's Table 1 from the real allocations).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GpuMemory {
    /// Two position buffers and the deltas.
    pub positions: u64,
    /// Adjacency (gather) or springs and accumulation structures (scatter).
    pub topology: u64,
    /// Per-vertex forces and integration constants, per-spring forces, accumulators, targets.
    pub per_step: u64,
    /// Per-step inputs (point forces, drags, wind) and collision: allocated whether used or
    /// not, so a drag or a slider writes into buffers that exist.
    pub control: u64,
}

impl GpuMemory {
    /// Everything the solver allocated.
    pub fn total(&self) -> u64 {
        self.positions + self.topology + self.per_step + self.control
    }

    /// What the paper's Table 1 counts: positions, topology and per-step buffers.
    pub fn table_1(&self) -> u64 {
        self.positions + self.topology + self.per_step
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_method_is_found_by_its_name() {
        for method in GpuMethod::all() {
            assert_eq!(GpuMethod::from_name(&method.name()), Some(method));
        }
        for bad in [
            "",
            "scatter",
            "scatter/",
            "gather/incidence",
            "scatter/nope",
            "nope",
        ] {
            assert_eq!(GpuMethod::from_name(bad), None, "{bad}");
        }
    }
}
