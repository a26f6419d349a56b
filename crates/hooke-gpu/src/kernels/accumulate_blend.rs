//! `accumulate_blend.wgsl` and `resolve_blend.wgsl`: the paper's own accumulation. A render pass
//! draws two points per spring into a float (32 or 16 bit) or 8-bit target with additive
//! blending, at each end's texel; a compute pass reads the sums back into the per-vertex force
//! buffer. 8-bit targets hold positive and negative parts in two targets, as the paper had to.

use super::ScatterBuffers;
use crate::context::{GpuContext, GpuError};
use crate::gpu::{Kernel, bind_group, render_pipeline, shader_module};
use crate::methods::Accumulation;
use crate::model::BLEND_WIDTH;

#[derive(Debug)]
pub struct AccumulateBlend {
    pipeline: wgpu::RenderPipeline,
    group: wgpu::BindGroup,
    /// The targets drawn into (one for float formats, two for 8 bits).
    targets: Vec<wgpu::TextureView>,
    resolve: Kernel,
    spring_count: u32,
    bytes: u64,
}

impl AccumulateBlend {
    pub fn new(
        context: &GpuContext,
        buffers: &ScatterBuffers<'_>,
        spring_forces: &wgpu::Buffer,
        accumulation: Accumulation,
    ) -> Result<Self, GpuError> {
        let n = buffers.vertex_count;
        let format = accumulation.blend_format().ok_or_else(|| {
            GpuError::Validation(format!(
                "{} is not a blend accumulation",
                accumulation.name()
            ))
        })?;
        let width = BLEND_WIDTH.min(n.max(1));
        let height = n.div_ceil(width).max(1);
        let max_dimension = context.device.limits().max_texture_dimension_2d;
        if height > max_dimension {
            return Err(GpuError::TooLarge {
                what: "blend force target rows",
                needed: u64::from(height),
                limit: u64::from(max_dimension),
                adapter: context.info.name.clone(),
            });
        }
        let split = accumulation == Accumulation::BlendRgba8;
        // Two targets: positive and negative parts. Float targets write only the first; the
        // second stays zero (textures are created cleared) so one resolve kernel serves every
        // format.
        let views: Vec<wgpu::TextureView> = ["force target (positive)", "force target (negative)"]
            .iter()
            .map(|label| {
                context
                    .device
                    .create_texture(&wgpu::TextureDescriptor {
                        label: Some(label),
                        size: wgpu::Extent3d {
                            width,
                            height,
                            depth_or_array_layers: 1,
                        },
                        mip_level_count: 1,
                        sample_count: 1,
                        dimension: wgpu::TextureDimension::D2,
                        format,
                        usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                            | wgpu::TextureUsages::TEXTURE_BINDING,
                        view_formats: &[],
                    })
                    .create_view(&Default::default())
            })
            .collect();
        let module = shader_module(context, "accumulate blend", super::ACCUMULATE_BLEND);
        let additive = wgpu::BlendComponent {
            src_factor: wgpu::BlendFactor::One,
            dst_factor: wgpu::BlendFactor::One,
            operation: wgpu::BlendOperation::Add,
        };
        let target = Some(wgpu::ColorTargetState {
            format,
            blend: Some(wgpu::BlendState {
                color: additive,
                alpha: additive,
            }),
            write_mask: wgpu::ColorWrites::ALL,
        });
        let color_targets = if split {
            vec![target.clone(), target]
        } else {
            vec![target]
        };
        let pipeline = render_pipeline(
            context,
            &wgpu::RenderPipelineDescriptor {
                label: Some("accumulate blend"),
                layout: None,
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some("vs_main"),
                    compilation_options: Default::default(),
                    buffers: &[],
                },
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::PointList,
                    ..Default::default()
                },
                depth_stencil: None,
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some(if split { "fs_split" } else { "fs_signed" }),
                    compilation_options: Default::default(),
                    targets: &color_targets,
                }),
                multiview_mask: None,
                cache: None,
            },
        )?;
        let group = bind_group(
            context,
            "accumulate blend",
            &pipeline.get_bind_group_layout(0),
            // One group for both position buffers: the draw reads no step clock, so either
            // parity's uniforms do.
            &[
                (0, buffers.model.uniforms_binding(0)),
                (1, buffers.springs.as_entire_binding()),
                (2, spring_forces.as_entire_binding()),
            ],
        );
        let resolve = Kernel::new(
            context,
            "resolve blend",
            super::RESOLVE_BLEND,
            "main",
            n,
            |current| {
                vec![
                    (0, buffers.model.uniforms_binding(current)),
                    (1, wgpu::BindingResource::TextureView(&views[0])),
                    (2, wgpu::BindingResource::TextureView(&views[1])),
                    (3, buffers.forces.as_entire_binding()),
                ]
            },
        )?;
        let texel_bytes = u64::from(format.block_copy_size(None).unwrap_or(16));
        let bytes = 2 * u64::from(width) * u64::from(height) * texel_bytes;
        let targets = if split {
            views
        } else {
            views.into_iter().take(1).collect()
        };
        Ok(Self {
            pipeline,
            group,
            targets,
            resolve,
            spring_count: buffers.spring_count,
            bytes,
        })
    }

    /// Bytes of the render targets.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// The render pass: two points per spring blended into the targets.
    pub fn encode_draw(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let attachments: Vec<Option<wgpu::RenderPassColorAttachment<'_>>> = self
            .targets
            .iter()
            .map(|view| {
                Some(wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })
            })
            .collect();
        let timestamp_writes = timestamps.map(|w| wgpu::RenderPassTimestampWrites {
            query_set: w.query_set,
            beginning_of_pass_write_index: w.beginning_of_pass_write_index,
            end_of_pass_write_index: w.end_of_pass_write_index,
        });
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("accumulate blend"),
            color_attachments: &attachments,
            depth_stencil_attachment: None,
            timestamp_writes,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.group, &[]);
        pass.draw(0..2 * self.spring_count, 0..1);
    }

    /// The resolve pass: texel sums back to newtons per vertex.
    pub fn encode_resolve(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        self.resolve.encode(encoder, 0, timestamps);
    }
}
