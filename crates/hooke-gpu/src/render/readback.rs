//! Reading a little data back without stalling a frame: the copy is recorded into a frame's
//! encoder, mapping is requested after submission, and later frames poll until it is ready.

use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};

use crate::context::GpuContext;

const IDLE: u8 = 0;
const COPIED: u8 = 1;
const MAPPING: u8 = 2;
const READY: u8 = 3;
const FAILED: u8 = 4;

/// One small staging buffer cycling through copy, map and read.
#[derive(Debug)]
pub struct AsyncReadback {
    buffer: wgpu::Buffer,
    state: Arc<AtomicU8>,
}

impl AsyncReadback {
    pub fn new(context: &GpuContext, label: &str, bytes: u64) -> Self {
        Self {
            buffer: context.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            state: Arc::new(AtomicU8::new(IDLE)),
        }
    }

    pub fn is_idle(&self) -> bool {
        self.state.load(Ordering::Acquire) == IDLE
    }

    /// Records a copy of `source` (from offset 0) into the staging buffer, if it is idle.
    pub fn encode_copy(&self, encoder: &mut wgpu::CommandEncoder, source: &wgpu::Buffer) -> bool {
        if !self.is_idle() {
            return false;
        }
        encoder.copy_buffer_to_buffer(source, 0, &self.buffer, 0, self.buffer.size());
        self.state.store(COPIED, Ordering::Release);
        true
    }

    /// After the encoder with the copy was submitted: asks for the mapping.
    pub fn request(&self) {
        if self.state.load(Ordering::Acquire) != COPIED {
            return;
        }
        self.state.store(MAPPING, Ordering::Release);
        let state = Arc::clone(&self.state);
        self.buffer
            .slice(..)
            .map_async(wgpu::MapMode::Read, move |result| {
                state.store(
                    if result.is_ok() { READY } else { FAILED },
                    Ordering::Release,
                );
            });
    }

    /// The bytes, once the GPU has delivered them; never waits.
    pub fn try_take(&self, context: &GpuContext) -> Option<Vec<u8>> {
        let _ = context.device.poll(wgpu::PollType::Poll);
        match self.state.load(Ordering::Acquire) {
            READY => {
                let bytes = self
                    .buffer
                    .slice(..)
                    .get_mapped_range()
                    .ok()
                    .map(|view| view.to_vec());
                self.buffer.unmap();
                self.state.store(IDLE, Ordering::Release);
                bytes
            }
            FAILED => {
                self.state.store(IDLE, Ordering::Release);
                None
            }
            _ => None,
        }
    }
}
