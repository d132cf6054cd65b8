//! Deferred shading (`shade.wgsl`): Phong per light with PCF shadows from the shadow maps,
//! ambient occlusion, the KRS objects' lighting, written to the RGBA8 target.

use thicket_core::quality::Quality;
use thicket_core::scene::Document;

use super::plan::FramePlan;
use super::{BindGroups, Bound, BufferPool, FrameBuffers, Gpu, Timestamps};
use crate::gpu::GpuError;
use crate::gpu::gpu_data::{
    LightGpu, MODE_DEPTH, NO_SHADOW_MAP, ShadingUniform, ShadowMapGpu, ao_kernel,
};

/// What shading needs beyond the plan and the shared buffers.
pub(in crate::gpu) struct ShadeInputs<'a> {
    pub(in crate::gpu) doc: &'a Document,
    pub(in crate::gpu) quality: &'a Quality,
    /// Ambient-occlusion radius in world units (0: no samples).
    pub(in crate::gpu) ao_radius: f32,
    /// The KRS pass's per-pixel lighting and its entries per pixel (`None`: no KRS objects).
    pub(in crate::gpu) krs: Option<(&'a wgpu::Buffer, u32)>,
    pub(in crate::gpu) target: &'a wgpu::TextureView,
}

/// Layout, pipeline and bind group of the shade pass.
pub(in crate::gpu) struct ShadePass {
    bgl: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    groups: BindGroups,
    workgroups: (u32, u32),
}

/// The pass's bind group layouts (one group), checked against `shade.wgsl` by a test.
pub(in crate::gpu) fn bind_group_entries() -> Vec<Vec<wgpu::BindGroupLayoutEntry>> {
    use super::{storage, uniform};
    let cs = wgpu::ShaderStages::COMPUTE;
    vec![vec![
        uniform(0, false, cs),
        // The shadow maps (`ShadowMapGpu`, one per shadow-casting light).
        storage(1, true, cs),
        uniform(2, false, cs),
        storage(3, true, cs),
        storage(4, true, cs),
        storage(5, true, cs),
        super::storage_texture_rgba8(6, cs),
        storage(7, true, cs),
    ]]
}

impl ShadePass {
    pub(in crate::gpu) fn new(device: &wgpu::Device) -> Result<Self, GpuError> {
        let (bgl, pipeline) =
            super::one_group_pipeline(device, "shade", &bind_group_entries()[0], "shade")?;
        Ok(Self {
            bgl,
            pipeline,
            groups: BindGroups::default(),
            workgroups: (0, 0),
        })
    }

    pub(in crate::gpu) fn prepare(
        &mut self,
        gpu: Gpu<'_>,
        pool: &mut BufferPool,
        plan: &FramePlan,
        bufs: &FrameBuffers,
        inputs: &ShadeInputs<'_>,
    ) {
        use wgpu::BufferUsages as U;
        let (doc, quality) = (inputs.doc, inputs.quality);
        let lights: Vec<LightGpu> = doc
            .lights
            .iter()
            .enumerate()
            .map(|(i, l)| {
                let c = l.color * l.intensity;
                LightGpu {
                    to_light: (-l.direction.normalize_or_zero()).to_array(),
                    shadow_map: plan
                        .shadows
                        .iter()
                        .position(|m| m.light == i)
                        .map_or(NO_SHADOW_MAP, |m| m as u32),
                    color: c.extend(0.0).to_array(),
                }
            })
            .collect();
        let light_buf = pool.upload(gpu, "lights", 0, bytemuck::cast_slice(&lights), U::STORAGE);
        let shadow_maps: Vec<ShadowMapGpu> = plan
            .shadows
            .iter()
            .map(|m| ShadowMapGpu {
                view: m.view.uniform(MODE_DEPTH, quality, false),
                // Below the binding limit (checked by the plan), so the word index fits.
                key_word_offset: (m.offset / 4) as u32,
                pad: [0; 3],
            })
            .collect();
        let shadow_map_buf = pool.upload(
            gpu,
            "shadow maps",
            0,
            bytemuck::cast_slice(&shadow_maps),
            U::STORAGE,
        );
        let (ao_count, ao_kernel) = ao_kernel(quality.ao_samples, inputs.ao_radius);
        let shading = ShadingUniform {
            ambient: doc.ambient.extend(0.0).to_array(),
            background: doc.background.extend(0.0).to_array(),
            light_count: lights.len() as u32,
            pcf_radius: quality.frame_settings().pcf_radius,
            receiver_px: quality.frame_settings().receiver_px,
            ao_count,
            ao_radius: inputs.ao_radius,
            krs_stride: inputs.krs.map_or(0, |(_, stride)| stride),
            pad: [0; 2],
            ao_kernel,
        };
        let shading_buf = pool.upload(gpu, "shading", 0, bytemuck::bytes_of(&shading), U::UNIFORM);
        let krs_light = match inputs.krs {
            Some((b, _)) => b.clone(),
            None => pool.upload(gpu, "krs lighting (none)", 0, &[], U::STORAGE),
        };
        let entries = vec![
            (0, Bound::whole(&bufs.view)),
            (1, Bound::whole(&shadow_map_buf)),
            (2, Bound::whole(&shading_buf)),
            (3, Bound::whole(&light_buf)),
            (4, Bound::whole(&bufs.gbuffer)),
            (5, Bound::range(&bufs.shadow_keys, 0, plan.shadow_words * 4)),
            (6, Bound::View(inputs.target.clone())),
            (7, Bound::whole(&krs_light)),
        ];
        self.groups.set(gpu, &self.bgl, "shade", 0, entries);
        self.workgroups = plan.pixel_groups;
    }

    pub(in crate::gpu) fn encode(
        &self,
        enc: &mut wgpu::CommandEncoder,
        ts: &mut Option<Timestamps>,
    ) {
        let mut pass = super::compute_pass(enc, ts, "shade");
        pass.set_pipeline(&self.pipeline);
        if let Some(bg) = self.groups.get(0) {
            pass.set_bind_group(0, bg, &[]);
        }
        pass.dispatch_workgroups(self.workgroups.0, self.workgroups.1, 1);
    }
}
