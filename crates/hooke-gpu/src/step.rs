//! How a step's passes are recorded. The solver writes the list of a step's passes once
//! (`GpuSolver::record_step`) and hands each pass to a [`PassSink`]: [`Fused`] records them all
//! into one encoder (stepping, and the viewer's frames), [`Timestamped`] gives each pass a
//! timestamp query pair, and [`WallClock`] submits each pass alone and waits for it (adapters
//! without timestamp queries).

use std::time::{Duration, Instant};

use hooke_core::PhaseTimes;

use crate::context::{GpuContext, GpuError};

/// The phase of the paper's Table 2 a pass belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    External,
    Force,
    Accumulation,
    Integration,
    Collision,
}

impl Phase {
    /// The debug group a pass of this phase is recorded in.
    pub fn name(self) -> &'static str {
        match self {
            Self::External => "external forces",
            Self::Force => "force calculation",
            Self::Accumulation => "force accumulation",
            Self::Integration => "integration",
            Self::Collision => "collision",
        }
    }
}

/// Records `record` inside a debug group named after `phase` (when `groups`), so a GPU
/// debugger shows each pass under its phase.
fn in_group(
    encoder: &mut wgpu::CommandEncoder,
    phase: Phase,
    groups: bool,
    writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    record: &mut Record<'_>,
) {
    if groups {
        encoder.push_debug_group(phase.name());
    }
    record(encoder, writes);
    if groups {
        encoder.pop_debug_group();
    }
}

/// Timestamp slots of one step: two per pass, at most 8 timed passes.
pub const TIMESTAMP_SLOTS: u32 = 16;

/// Timed steps recorded into one submission: back to back, as the fused steps run, so the GPU
/// does not idle (and perhaps slow its clocks) between them as it did between steps timed one
/// submission at a time.
pub const TIMED_STEPS_PER_SUBMISSION: u32 = 10;

/// Records one pass: gets the encoder and the pass's timestamp writes.
pub type Record<'r> =
    dyn FnMut(&mut wgpu::CommandEncoder, Option<wgpu::ComputePassTimestampWrites<'_>>) + 'r;

/// Where a step's passes go.
pub trait PassSink {
    fn pass(&mut self, phase: Phase, record: &mut Record<'_>) -> Result<(), GpuError>;
}

/// Every pass into one encoder, untimed.
pub struct Fused<'e> {
    pub encoder: &'e mut wgpu::CommandEncoder,
    /// Whether to record debug groups ([`GpuContext::records_debug_groups`]).
    pub groups: bool,
}

impl PassSink for Fused<'_> {
    fn pass(&mut self, phase: Phase, record: &mut Record<'_>) -> Result<(), GpuError> {
        in_group(self.encoder, phase, self.groups, None, record);
        Ok(())
    }
}

/// One step's passes into an encoder, each timed phase's passes with a timestamp pair.
pub struct Timestamped<'e, 'q> {
    pub encoder: &'e mut wgpu::CommandEncoder,
    pub groups: bool,
    pub query_set: &'q wgpu::QuerySet,
    /// The step's first slot of `query_set`: the steps of a submission take theirs in turn.
    pub first: u32,
    /// The phase of each timestamp pair handed out.
    pub phases: Vec<Phase>,
}

impl PassSink for Timestamped<'_, '_> {
    fn pass(&mut self, phase: Phase, record: &mut Record<'_>) -> Result<(), GpuError> {
        let used = 2 * self.phases.len() as u32;
        let writes = (used + 2 <= TIMESTAMP_SLOTS).then(|| {
            self.phases.push(phase);
            wgpu::ComputePassTimestampWrites {
                query_set: self.query_set,
                beginning_of_pass_write_index: Some(self.first + used),
                end_of_pass_write_index: Some(self.first + used + 1),
            }
        });
        in_group(self.encoder, phase, self.groups, writes, record);
        Ok(())
    }
}

/// Each pass submitted alone and waited for, its wall-clock time added to its phase.
pub struct WallClock<'c> {
    pub context: &'c GpuContext,
    pub times: PhaseTimes,
}

impl PassSink for WallClock<'_> {
    fn pass(&mut self, phase: Phase, record: &mut Record<'_>) -> Result<(), GpuError> {
        let mut encoder =
            self.context
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("timed pass"),
                });
        let groups = self.context.records_debug_groups();
        in_group(&mut encoder, phase, groups, None, record);
        let start = Instant::now();
        self.context.queue.submit([encoder.finish()]);
        self.context
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| GpuError::ReadBack(e.to_string()))?;
        add_phase(&mut self.times, phase, start.elapsed());
        Ok(())
    }
}

/// Adds `duration` to `phase`'s time.
pub fn add_phase(times: &mut PhaseTimes, phase: Phase, duration: Duration) {
    match phase {
        Phase::External => times.external += duration,
        Phase::Force => times.force_calculation += duration,
        Phase::Accumulation => *times.force_accumulation.get_or_insert(Duration::ZERO) += duration,
        Phase::Integration => times.integration += duration,
        Phase::Collision => times.collision += duration,
    }
}
