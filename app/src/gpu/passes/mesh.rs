//! Triangle meshes rasterised into the key buffers (`mesh32.wgsl`, `mesh64.wgsl`): the
//! fragment shader writes depth (and id) with atomics, so the render pass has only a
//! discarded depth attachment to give it a target.

use std::collections::HashMap;

use super::plan::FramePlan;
use super::traverse::shadow_keys;
use super::{BindGroups, Bound, FrameBuffers, Gpu, Timestamps};
use crate::gpu::GpuError;
use crate::gpu::scene::SceneCache;

/// Layout, pipelines, bind groups and the dummy depth attachments.
pub(in crate::gpu) struct MeshPass {
    bgl: wgpu::BindGroupLayout,
    mesh32: wgpu::RenderPipeline,
    mesh64: Option<wgpu::RenderPipeline>,
    /// 0: the view (first pass), 1: its id pass.
    main: BindGroups,
    shadows: BindGroups,
    /// Depth attachments by size (the atomics do the depth test).
    attachments: HashMap<(u32, u32), wgpu::TextureView>,
    /// This frame's: the view's attachment, the shadow maps' shared one, the viewport of
    /// each map, triangles drawn in the view and in the maps.
    main_attachment: Option<wgpu::TextureView>,
    shadow_attachment: Option<wgpu::TextureView>,
    shadow_viewports: Vec<(u32, u32)>,
    triangles: u32,
    caster_triangles: u32,
}

/// The pass's bind group layouts (one group), checked against `mesh32.wgsl` and `mesh64.wgsl`
/// by a test.
pub(in crate::gpu) fn bind_group_entries() -> Vec<Vec<wgpu::BindGroupLayoutEntry>> {
    let vf = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
    vec![vec![
        super::uniform(0, false, vf),
        super::storage(1, true, wgpu::ShaderStages::VERTEX),
        super::storage(2, false, wgpu::ShaderStages::FRAGMENT),
    ]]
}

impl MeshPass {
    /// The 64-bit pipeline exists only with `int64`.
    pub(in crate::gpu) fn new(device: &wgpu::Device, int64: bool) -> Result<Self, GpuError> {
        let bgl = super::layout(device, "mesh", &bind_group_entries()[0]);
        let layout = super::pipeline_layout(device, "mesh", &[&bgl]);
        let pipeline = |label: &str, path: &str| -> Result<wgpu::RenderPipeline, GpuError> {
            let m = super::module(device, path)?;
            Ok(
                device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some(label),
                    layout: Some(&layout),
                    vertex: wgpu::VertexState {
                        module: &m,
                        entry_point: Some("vs_main"),
                        compilation_options: wgpu::PipelineCompilationOptions::default(),
                        buffers: &[],
                    },
                    primitive: wgpu::PrimitiveState {
                        cull_mode: None,
                        ..Default::default()
                    },
                    depth_stencil: Some(wgpu::DepthStencilState {
                        format: wgpu::TextureFormat::Depth32Float,
                        depth_write_enabled: Some(false),
                        depth_compare: Some(wgpu::CompareFunction::Always),
                        stencil: wgpu::StencilState::default(),
                        bias: wgpu::DepthBiasState::default(),
                    }),
                    multisample: wgpu::MultisampleState::default(),
                    fragment: Some(wgpu::FragmentState {
                        module: &m,
                        entry_point: Some("fs_main"),
                        compilation_options: wgpu::PipelineCompilationOptions::default(),
                        targets: &[],
                    }),
                    multiview_mask: None,
                    cache: None,
                }),
            )
        };
        Ok(Self {
            mesh32: pipeline("mesh32", "mesh32.wgsl")?,
            mesh64: if int64 {
                Some(pipeline("mesh64", "mesh64.wgsl")?)
            } else {
                None
            },
            bgl,
            main: BindGroups::default(),
            shadows: BindGroups::default(),
            attachments: HashMap::new(),
            main_attachment: None,
            shadow_attachment: None,
            shadow_viewports: Vec::new(),
            triangles: 0,
            caster_triangles: 0,
        })
    }

    fn attachment(&mut self, gpu: Gpu<'_>, (w, h): (u32, u32)) -> wgpu::TextureView {
        self.attachments
            .entry((w, h))
            .or_insert_with(|| {
                gpu.create_texture(&wgpu::TextureDescriptor {
                    label: Some("mesh pass attachment"),
                    size: wgpu::Extent3d {
                        width: w,
                        height: h,
                        depth_or_array_layers: 1,
                    },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format: wgpu::TextureFormat::Depth32Float,
                    usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                    view_formats: &[],
                })
                .create_view(&wgpu::TextureViewDescriptor::default())
            })
            .clone()
    }

    pub(in crate::gpu) fn prepare(
        &mut self,
        gpu: Gpu<'_>,
        plan: &FramePlan,
        bufs: &FrameBuffers,
        scene: &SceneCache,
    ) {
        let tris = &scene.tri_buf;
        self.main
            .set_buffers(gpu, &self.bgl, "mesh", 0, &[&bufs.view, tris, &bufs.keys]);
        self.main.set_buffers(
            gpu,
            &self.bgl,
            "mesh id",
            1,
            &[&bufs.view_id, tris, &bufs.keys],
        );
        for (i, (m, v)) in plan.shadows.iter().zip(&bufs.shadow_views).enumerate() {
            let entries = vec![
                (0, Bound::whole(v)),
                (1, Bound::whole(tris)),
                (2, shadow_keys(&bufs.shadow_keys, m)),
            ];
            self.shadows.set(gpu, &self.bgl, "mesh shadow", i, entries);
        }
        self.shadows.truncate(plan.shadows.len());
        self.main_attachment = Some(self.attachment(gpu, plan.size()));
        // One attachment for every map's mesh draw (each draws into its own viewport of it).
        self.shadow_attachment = plan.shadow_attachment.map(|s| self.attachment(gpu, s));
        self.shadow_viewports = plan
            .shadows
            .iter()
            .map(|m| (m.view.width, m.view.height))
            .collect();
        self.triangles = scene.tri_count;
        self.caster_triangles = scene.caster_tris;
    }

    /// Every map's casters in one render pass, each map in its own viewport of the shared
    /// attachment (the fragment's pixel indexes that map's key range).
    pub(in crate::gpu) fn encode_shadows(
        &self,
        enc: &mut wgpu::CommandEncoder,
        ts: &mut Option<Timestamps>,
    ) {
        let Some(attachment) = &self.shadow_attachment else {
            return;
        };
        let mut pass = depth_only_pass(enc, ts, "shadow meshes", attachment);
        pass.set_pipeline(&self.mesh32);
        for (i, &(mw, mh)) in self.shadow_viewports.iter().enumerate() {
            let Some(bg) = self.shadows.get(i) else {
                continue;
            };
            pass.set_viewport(0.0, 0.0, mw as f32, mh as f32, 0.0, 1.0);
            pass.set_scissor_rect(0, 0, mw, mh);
            pass.set_bind_group(0, bg, &[]);
            pass.draw(0..self.caster_triangles * 3, 0..1);
        }
    }

    /// The view's meshes: the 64-bit key when `key64`, else depth (or ids when `id_pass`).
    pub(in crate::gpu) fn encode_view(
        &self,
        enc: &mut wgpu::CommandEncoder,
        ts: &mut Option<Timestamps>,
        key64: bool,
        id_pass: bool,
    ) {
        let (Some(attachment), Some(bg)) =
            (&self.main_attachment, self.main.get(usize::from(id_pass)))
        else {
            return;
        };
        if self.triangles == 0 {
            return;
        }
        let pipeline = match (&self.mesh64, key64) {
            (Some(p), true) => p,
            _ => &self.mesh32,
        };
        let mut pass = depth_only_pass(enc, ts, "meshes", attachment);
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, bg, &[]);
        pass.draw(0..self.triangles * 3, 0..1);
    }
}

/// A render pass with only a depth attachment, cleared and discarded: the mesh passes write
/// their depth into the key buffer with atomics, the attachment only gives them a target.
fn depth_only_pass<'e>(
    enc: &'e mut wgpu::CommandEncoder,
    ts: &mut Option<Timestamps>,
    name: &'static str,
    attachment: &wgpu::TextureView,
) -> wgpu::RenderPass<'e> {
    enc.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(name),
        color_attachments: &[],
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: attachment,
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Clear(1.0),
                store: wgpu::StoreOp::Discard,
            }),
            stencil_ops: None,
        }),
        timestamp_writes: ts.as_mut().and_then(|t| t.render(name)),
        occlusion_query_set: None,
        multiview_mask: None,
    })
}
