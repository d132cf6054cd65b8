//! Keys → G-buffer (`resolve.wgsl`): each pixel's id looked up in the voxel attributes,
//! the skinned normals or the triangles, one dispatch per pool chunk over the ids it holds.

use super::plan::FramePlan;
use super::{BindGroups, BufferPool, FrameBuffers, Gpu, Timestamps};
use crate::gpu::GpuError;
use crate::gpu::gpu_data::ResolveChunk;
use crate::gpu::scene::SceneCache;
use crate::gpu::skin::SkinFrame;

/// Layout, pipeline and one bind group per pool chunk.
pub(in crate::gpu) struct ResolvePass {
    bgl: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    groups: BindGroups,
    chunks: usize,
    workgroups: (u32, u32),
}

/// The pass's bind group layouts (one group), checked against `resolve.wgsl` by a test.
pub(in crate::gpu) fn bind_group_entries() -> Vec<Vec<wgpu::BindGroupLayoutEntry>> {
    use super::{storage, uniform};
    let cs = wgpu::ShaderStages::COMPUTE;
    vec![vec![
        uniform(0, false, cs),
        storage(1, true, cs),
        storage(2, true, cs),
        storage(3, true, cs),
        storage(4, true, cs),
        storage(5, false, cs),
        storage(6, true, cs),
        storage(7, true, cs),
        storage(8, true, cs),
        uniform(9, false, cs),
    ]]
}

impl ResolvePass {
    pub(in crate::gpu) fn new(device: &wgpu::Device) -> Result<Self, GpuError> {
        let (bgl, pipeline) =
            super::one_group_pipeline(device, "resolve", &bind_group_entries()[0], "resolve")?;
        Ok(Self {
            bgl,
            pipeline,
            groups: BindGroups::default(),
            chunks: 0,
            workgroups: (0, 0),
        })
    }

    pub(in crate::gpu) fn prepare(
        &mut self,
        gpu: Gpu<'_>,
        pool: &mut BufferPool,
        plan: &FramePlan,
        bufs: &FrameBuffers,
        (scene, skin): (&SceneCache, &SkinFrame),
    ) {
        for (i, (c, skin_data)) in scene.chunks.iter().zip(&skin.data_bufs).enumerate() {
            let range = ResolveChunk {
                attr_start: c.attr_start,
                attr_end: c.attr_end,
                others: u32::from(i == 0),
                pad: 0,
            };
            let range_buf = pool.upload(
                gpu,
                "resolve chunk",
                i,
                bytemuck::bytes_of(&range),
                wgpu::BufferUsages::UNIFORM,
            );
            let buffers = [
                &bufs.view,
                &bufs.keys,
                &c.attr_buf,
                &bufs.objects,
                &scene.tri_buf,
                &bufs.gbuffer,
                skin_data,
                &skin.joint_buf,
                &scene.texture_buf,
                &range_buf,
            ];
            self.groups
                .set_buffers(gpu, &self.bgl, "resolve", i, &buffers);
        }
        self.chunks = scene.chunks.len().min(skin.data_bufs.len());
        self.groups.truncate(self.chunks);
        self.workgroups = plan.pixel_groups;
    }

    pub(in crate::gpu) fn encode(
        &self,
        enc: &mut wgpu::CommandEncoder,
        ts: &mut Option<Timestamps>,
    ) {
        let mut pass = super::compute_pass(enc, ts, "resolve");
        pass.set_pipeline(&self.pipeline);
        for i in 0..self.chunks {
            if let Some(bg) = self.groups.get(i) {
                pass.set_bind_group(0, bg, &[]);
                pass.dispatch_workgroups(self.workgroups.0, self.workgroups.1, 1);
            }
        }
    }
}
