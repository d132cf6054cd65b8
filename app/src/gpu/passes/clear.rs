//! Clears the view's and the shadow maps' key buffers to "nothing drawn" (`clear.wgsl`).

use super::plan::{FramePlan, clear_groups};
use super::traverse::shadow_keys;
use super::{BindGroups, Bound, BufferPool, FrameBuffers, Gpu, Timestamps};
use crate::gpu::GpuError;
use crate::gpu::gpu_data::ClearParams;

/// Layout, pipeline and the bind groups: the view's keys, then each shadow map's slot.
pub(in crate::gpu) struct ClearPass {
    bgl: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    groups: BindGroups,
    /// Words each group clears this frame.
    words: Vec<u64>,
}

/// The pass's bind group layouts (one group), checked against `clear.wgsl` by a test.
pub(in crate::gpu) fn bind_group_entries() -> Vec<Vec<wgpu::BindGroupLayoutEntry>> {
    let cs = wgpu::ShaderStages::COMPUTE;
    vec![vec![
        super::uniform(0, false, cs),
        super::storage(1, false, cs),
    ]]
}

impl ClearPass {
    pub(in crate::gpu) fn new(device: &wgpu::Device) -> Result<Self, GpuError> {
        let (bgl, pipeline) =
            super::one_group_pipeline(device, "clear", &bind_group_entries()[0], "clear")?;
        Ok(Self {
            bgl,
            pipeline,
            groups: BindGroups::default(),
            words: Vec::new(),
        })
    }

    pub(in crate::gpu) fn prepare(
        &mut self,
        gpu: Gpu<'_>,
        pool: &mut BufferPool,
        plan: &FramePlan,
        bufs: &FrameBuffers,
    ) {
        let params = |count: u64| ClearParams {
            count: u32::try_from(count).unwrap_or(u32::MAX),
            pad: [0; 3],
        };
        let uniform = wgpu::BufferUsages::UNIFORM;
        self.words.clear();
        self.words.push(plan.pixels * 2);
        let main = pool.upload(
            gpu,
            "clear keys",
            0,
            bytemuck::bytes_of(&params(plan.pixels * 2)),
            uniform,
        );
        let entries = vec![(0, Bound::whole(&main)), (1, Bound::whole(&bufs.keys))];
        self.groups.set(gpu, &self.bgl, "clear keys", 0, entries);
        // Each map's keys only: its slot's tail and the gaps between slots are never read.
        for (i, m) in plan.shadows.iter().enumerate() {
            let words = m.bytes / 4;
            self.words.push(words);
            let count = pool.upload(
                gpu,
                "clear shadow keys",
                i,
                bytemuck::bytes_of(&params(words)),
                uniform,
            );
            let entries = vec![
                (0, Bound::whole(&count)),
                (1, shadow_keys(&bufs.shadow_keys, m)),
            ];
            self.groups
                .set(gpu, &self.bgl, "clear shadow", 1 + i, entries);
        }
        self.groups.truncate(self.words.len());
    }

    /// The frame's clear: every key buffer in one pass.
    pub(in crate::gpu) fn encode(
        &self,
        enc: &mut wgpu::CommandEncoder,
        ts: &mut Option<Timestamps>,
    ) {
        let mut pass = super::compute_pass(enc, ts, "clear");
        self.dispatch(&mut pass, self.words.len());
    }

    /// Only the view's keys, untimed (the splat-bandwidth measurement's restore).
    pub(in crate::gpu) fn encode_view_only(&self, enc: &mut wgpu::CommandEncoder) {
        let mut pass = super::compute_pass(enc, &mut None, "clear keys");
        self.dispatch(&mut pass, 1);
    }

    fn dispatch(&self, pass: &mut wgpu::ComputePass<'_>, groups: usize) {
        pass.set_pipeline(&self.pipeline);
        for (i, &words) in self.words.iter().enumerate().take(groups) {
            let Some(bg) = self.groups.get(i).filter(|_| words > 0) else {
                continue;
            };
            let (gx, gy) = clear_groups(words);
            pass.set_bind_group(0, bg, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
    }
}
