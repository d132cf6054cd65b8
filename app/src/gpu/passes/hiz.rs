//! Occlusion tiles (Hi-Z) from everything drawn into the view's keys so far (`hiz.wgsl`),
//! rebuilt before each level of the view's traversal (see [`super::traverse`]).

use super::plan::FramePlan;
use super::{BindGroups, FrameBuffers, Gpu};
use crate::gpu::GpuError;

/// Layout, pipeline and bind group of the Hi-Z build.
pub(in crate::gpu) struct HizPass {
    bgl: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    groups: BindGroups,
    workgroups: (u32, u32),
}

/// The pass's bind group layouts (one group), checked against `hiz.wgsl` by a test.
pub(in crate::gpu) fn bind_group_entries() -> Vec<Vec<wgpu::BindGroupLayoutEntry>> {
    let cs = wgpu::ShaderStages::COMPUTE;
    vec![vec![
        super::uniform(0, false, cs),
        super::storage(1, true, cs),
        super::storage(2, false, cs),
    ]]
}

impl HizPass {
    pub(in crate::gpu) fn new(device: &wgpu::Device) -> Result<Self, GpuError> {
        let (bgl, pipeline) =
            super::one_group_pipeline(device, "hiz", &bind_group_entries()[0], "build_tiles")?;
        Ok(Self {
            bgl,
            pipeline,
            groups: BindGroups::default(),
            workgroups: (0, 0),
        })
    }

    pub(in crate::gpu) fn prepare(&mut self, gpu: Gpu<'_>, plan: &FramePlan, bufs: &FrameBuffers) {
        self.groups.set_buffers(
            gpu,
            &self.bgl,
            "hiz",
            0,
            &[&bufs.view, &bufs.keys, &bufs.tiles],
        );
        self.workgroups = plan.hiz_groups;
    }

    /// Records one build into a traversal's compute pass (its layout differs: the caller
    /// rebinds its own groups after it).
    pub(in crate::gpu) fn dispatch(&self, pass: &mut wgpu::ComputePass<'_>) {
        let Some(bg) = self.groups.get(0) else {
            return;
        };
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, bg, &[]);
        pass.dispatch_workgroups(self.workgroups.0, self.workgroups.1, 1);
    }
}
