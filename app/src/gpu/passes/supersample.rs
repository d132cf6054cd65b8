//! Supersampling's resolve (`supersample.wgsl`): with [`Quality::supersample`] k > 1 the frame
//! is drawn into a target k times the size (every pass sees a k²-times larger image, as the
//! CPU's `render_supersampled` draws the view k times larger) and this pass box-filters it to
//! the caller's target in linear light, as the CPU's `RgbaImage::downsample`.
//!
//! [`Quality::supersample`]: thicket_core::quality::Quality::supersample

use super::{BindGroups, Bound, BufferPool, Gpu, Timestamps};
use crate::gpu::GpuError;
use crate::gpu::gpu_data::SupersampleUniform;

/// The samples per pixel side a frame of `width`×`height` draws on a device whose textures
/// are at most `max_texture` texels a side: the CPU's
/// [`thicket_core::render::supersample_factor`] (the same k wherever both can draw it), and
/// no more than fits the device.
#[must_use]
pub(in crate::gpu) fn samples_per_side(width: u32, height: u32, k: u32, max_texture: u32) -> u32 {
    let k = thicket_core::render::supersample_factor(width, height, k);
    k.min(max_texture / width.max(height).max(1)).max(1)
}

/// The pass's bind group layout (one group), checked against `supersample.wgsl` by a test.
pub(in crate::gpu) fn bind_group_entries() -> Vec<Vec<wgpu::BindGroupLayoutEntry>> {
    let cs = wgpu::ShaderStages::COMPUTE;
    vec![vec![
        super::uniform(0, false, cs),
        wgpu::BindGroupLayoutEntry {
            binding: 1,
            visibility: cs,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: false },
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        },
        super::storage_texture_rgba8(2, cs),
    ]]
}

/// The samples target (kept while its size holds, freed by a one-sample frame), layout,
/// pipeline and bind group.
pub(in crate::gpu) struct SupersamplePass {
    bgl: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    groups: BindGroups,
    /// The k-times target the frame's passes draw into, and its size.
    samples: Option<(wgpu::Texture, wgpu::TextureView, (u32, u32))>,
    /// Workgroups of this frame's resolve (`None`: the frame draws one sample per pixel).
    workgroups: Option<(u32, u32)>,
}

impl SupersamplePass {
    pub(in crate::gpu) fn new(device: &wgpu::Device) -> Result<Self, GpuError> {
        let (bgl, pipeline) = super::one_group_pipeline(
            device,
            "supersample",
            &bind_group_entries()[0],
            "resolve_samples",
        )?;
        Ok(Self {
            bgl,
            pipeline,
            groups: BindGroups::default(),
            samples: None,
            workgroups: None,
        })
    }

    /// Texels of the samples target held now (0 when none).
    pub(in crate::gpu) fn samples_texels(&self) -> u64 {
        self.samples
            .as_ref()
            .map_or(0, |(_, _, (w, h))| u64::from(*w) * u64::from(*h))
    }

    /// This frame's samples target for `k` samples per side of a `target_size` image (the view
    /// the shade pass writes), or `None` for one sample per pixel, when the pass does not
    /// run. The target is created only when its size changes.
    pub(in crate::gpu) fn prepare(
        &mut self,
        gpu: Gpu<'_>,
        pool: &mut BufferPool,
        k: u32,
        target_size: (u32, u32),
        target: &wgpu::TextureView,
    ) -> Option<wgpu::TextureView> {
        if k <= 1 {
            // A one-sample frame frees the samples target (k² times the image's texels).
            self.workgroups = None;
            self.samples = None;
            // The bind group holds the target's view too.
            self.groups.truncate(0);
            return None;
        }
        let size = (target_size.0 * k, target_size.1 * k);
        if self.samples.as_ref().is_none_or(|(_, _, s)| *s != size) {
            let texture = gpu.create_texture(&wgpu::TextureDescriptor {
                label: Some("supersample samples"),
                size: wgpu::Extent3d {
                    width: size.0,
                    height: size.1,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Rgba8Unorm,
                usage: wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            });
            let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
            self.samples = Some((texture, view, size));
        }
        let view = self.samples.as_ref().map(|(_, v, _)| v.clone())?;
        let params = SupersampleUniform {
            k,
            width: target_size.0,
            height: target_size.1,
            pad: 0,
        };
        let params_buf = pool.upload(
            gpu,
            "supersample",
            0,
            bytemuck::bytes_of(&params),
            wgpu::BufferUsages::UNIFORM,
        );
        let entries = vec![
            (0, Bound::whole(&params_buf)),
            (1, Bound::View(view.clone())),
            (2, Bound::View(target.clone())),
        ];
        self.groups.set(gpu, &self.bgl, "supersample", 0, entries);
        self.workgroups = Some((target_size.0.div_ceil(8), target_size.1.div_ceil(8)));
        Some(view)
    }

    pub(in crate::gpu) fn encode(
        &self,
        enc: &mut wgpu::CommandEncoder,
        ts: &mut Option<Timestamps>,
    ) {
        let (Some(groups), Some(bg)) = (self.workgroups, self.groups.get(0)) else {
            return;
        };
        let mut pass = super::compute_pass(enc, ts, "supersample");
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, bg, &[]);
        pass.dispatch_workgroups(groups.0, groups.1, 1);
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn samples_per_side_follows_the_cpu_and_the_device_limit() {
        // The CPU's factor where the device can draw it.
        assert_eq!(super::samples_per_side(96, 80, 3, 8192), 3);
        assert_eq!(super::samples_per_side(96, 80, 1, 8192), 1);
        // A device with 256-texel textures fits 2 samples per side of a 96-pixel image.
        assert_eq!(super::samples_per_side(96, 80, 3, 256), 2);
        // Never below one sample.
        assert_eq!(super::samples_per_side(512, 80, 3, 256), 1);
    }
}
