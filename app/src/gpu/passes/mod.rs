//! The GPU frame, one module per pass (see `docs/gpu.md`).
//!
//! A frame is first decided ([`plan::FramePlan`]: sizes, limits, shadow maps, which passes
//! run; pure), then prepared (each pass writes this frame's uniforms into persistent buffers
//! and keeps its bind groups, recreating one only when a resource it binds changed: a size
//! grew, the scene was uploaded again, the shadow plan moved a map), then encoded in pass
//! order. Every buffer, bind group, texture and query set the frame creates goes through
//! [`Gpu`], which counts them ([`super::Renderer::resource_creations`]): a frame whose only
//! change is the camera creates none.
//!
//! | module | passes | shaders |
//! |---|---|---|
//! | [`clear`] | key buffers cleared to "nothing drawn" | `clear.wgsl` |
//! | [`hiz`] | occlusion tiles from the keys drawn so far | `hiz.wgsl` |
//! | [`traverse`] | ASVO traversal and splatting, every view | `asvo_queue.wgsl`, `asvo_splat{32,64}.wgsl` |
//! | [`mesh`] | triangle meshes rasterised into the keys | `mesh{32,64}.wgsl` |
//! | [`resolve`] | keys → G-buffer | `resolve.wgsl` |
//! | `super::krs` | KRS trace and lighting | `krs_trace.wgsl` |
//! | [`shade`] | deferred Phong, shadows, AO → target (or the samples target) | `shade.wgsl` |
//! | [`supersample`] | the samples target box-filtered to the target (`supersample` > 1) | `supersample.wgsl` |
//!
//! Skinning has no pass of its own: `super::skin` prepares the skin data and joint matrices
//! that the traversal and resolve bind.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};

pub(super) mod clear;
pub(super) mod hiz;
pub(super) mod mesh;
pub(super) mod plan;
pub(super) mod resolve;
pub(super) mod shade;
pub(super) mod supersample;
pub(super) mod traverse;

/// The device and queue of a frame, creating through counted calls.
#[derive(Clone, Copy)]
pub(super) struct Gpu<'a> {
    pub(super) device: &'a wgpu::Device,
    pub(super) queue: &'a wgpu::Queue,
    created: &'a AtomicU64,
}

impl<'a> Gpu<'a> {
    pub(super) fn new(
        device: &'a wgpu::Device,
        queue: &'a wgpu::Queue,
        created: &'a AtomicU64,
    ) -> Self {
        Self {
            device,
            queue,
            created,
        }
    }

    fn count(&self) {
        self.created.fetch_add(1, Ordering::Relaxed);
    }

    pub(super) fn create_buffer(&self, desc: &wgpu::BufferDescriptor<'_>) -> wgpu::Buffer {
        self.count();
        self.device.create_buffer(desc)
    }

    pub(super) fn create_bind_group(
        &self,
        desc: &wgpu::BindGroupDescriptor<'_>,
    ) -> wgpu::BindGroup {
        self.count();
        self.device.create_bind_group(desc)
    }

    pub(super) fn create_texture(&self, desc: &wgpu::TextureDescriptor<'_>) -> wgpu::Texture {
        self.count();
        self.device.create_texture(desc)
    }

    pub(super) fn create_query_set(&self, desc: &wgpu::QuerySetDescriptor<'_>) -> wgpu::QuerySet {
        self.count();
        self.device.create_query_set(desc)
    }
}

/// Buffers kept across frames under a name and an index, replaced only when too small.
#[derive(Default)]
pub(super) struct BufferPool {
    buffers: HashMap<(&'static str, usize), wgpu::Buffer>,
}

impl BufferPool {
    /// A buffer of at least `size` bytes with `usage` (a larger one from an earlier frame is
    /// kept: bindings and clears cover only what the frame uses).
    pub(super) fn get(
        &mut self,
        gpu: Gpu<'_>,
        name: &'static str,
        index: usize,
        size: u64,
        usage: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        let size = size.max(16).next_multiple_of(16);
        if let Some(b) = self.buffers.get(&(name, index))
            && b.size() >= size
            && b.usage().contains(usage)
        {
            return b.clone();
        }
        let b = gpu.create_buffer(&wgpu::BufferDescriptor {
            label: Some(name),
            size,
            usage,
            mapped_at_creation: false,
        });
        self.buffers.insert((name, index), b.clone());
        b
    }

    /// A buffer holding `data` from offset 0 (written through the queue; at least 256 bytes,
    /// as an empty binding is not allowed: the zeroed rest is never read).
    pub(super) fn upload(
        &mut self,
        gpu: Gpu<'_>,
        name: &'static str,
        index: usize,
        data: &[u8],
        usage: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        let b = self.get(
            gpu,
            name,
            index,
            (data.len() as u64).max(256),
            usage | wgpu::BufferUsages::COPY_DST,
        );
        if !data.is_empty() {
            gpu.queue.write_buffer(&b, 0, data);
        }
        b
    }

    /// Bytes of every buffer held.
    pub(super) fn bytes(&self) -> u64 {
        self.buffers.values().map(wgpu::Buffer::size).sum()
    }

    /// The buffer last returned under `name` and `index`, if any.
    pub(super) fn peek(&self, name: &'static str, index: usize) -> Option<&wgpu::Buffer> {
        self.buffers.get(&(name, index))
    }
}

/// A resource a bind group entry binds, compared by identity to decide whether a kept bind
/// group still binds what the frame needs.
#[derive(Clone, PartialEq, Eq)]
pub(super) enum Bound {
    /// A buffer range (`None` size: to the end).
    Buffer(wgpu::Buffer, u64, Option<u64>),
    /// A texture view.
    View(wgpu::TextureView),
}

impl Bound {
    /// The whole of `buffer`.
    pub(super) fn whole(buffer: &wgpu::Buffer) -> Self {
        Self::Buffer(buffer.clone(), 0, None)
    }

    /// `size` bytes of `buffer` from `offset`.
    pub(super) fn range(buffer: &wgpu::Buffer, offset: u64, size: u64) -> Self {
        Self::Buffer(buffer.clone(), offset, Some(size))
    }

    fn resource(&self) -> wgpu::BindingResource<'_> {
        match self {
            Self::Buffer(buffer, offset, size) => {
                wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer,
                    offset: *offset,
                    size: size.and_then(wgpu::BufferSize::new),
                })
            }
            Self::View(view) => wgpu::BindingResource::TextureView(view),
        }
    }
}

/// A bind group's entries: (binding number, resource).
pub(super) type Entries = Vec<(u32, Bound)>;

/// Bind groups kept across frames by index, each recreated only when what it binds changed.
#[derive(Default)]
pub(super) struct BindGroups {
    groups: Vec<Option<(Entries, wgpu::BindGroup)>>,
}

impl BindGroups {
    /// Makes group `index` bind `entries` (binding number, resource) with `layout`.
    pub(super) fn set(
        &mut self,
        gpu: Gpu<'_>,
        layout: &wgpu::BindGroupLayout,
        label: &str,
        index: usize,
        entries: Vec<(u32, Bound)>,
    ) {
        if self.groups.len() <= index {
            self.groups.resize_with(index + 1, || None);
        }
        if self.groups[index]
            .as_ref()
            .is_some_and(|(kept, _)| *kept == entries)
        {
            return;
        }
        let wgpu_entries: Vec<wgpu::BindGroupEntry<'_>> = entries
            .iter()
            .map(|(binding, bound)| wgpu::BindGroupEntry {
                binding: *binding,
                resource: bound.resource(),
            })
            .collect();
        let group = gpu.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout,
            entries: &wgpu_entries,
        });
        self.groups[index] = Some((entries, group));
    }

    /// Group `index` binding whole buffers at bindings 0, 1, 2, … in order.
    pub(super) fn set_buffers(
        &mut self,
        gpu: Gpu<'_>,
        layout: &wgpu::BindGroupLayout,
        label: &str,
        index: usize,
        buffers: &[&wgpu::Buffer],
    ) {
        let entries = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| (i as u32, Bound::whole(b)))
            .collect();
        self.set(gpu, layout, label, index, entries);
    }

    /// Keeps only the first `n` groups (the frame uses no more).
    pub(super) fn truncate(&mut self, n: usize) {
        self.groups.truncate(n);
    }

    /// Group `index` as last set.
    pub(super) fn get(&self, index: usize) -> Option<&wgpu::BindGroup> {
        self.groups.get(index)?.as_ref().map(|(_, g)| g)
    }
}

/// A layout entry for a storage buffer.
pub(super) fn storage(
    binding: u32,
    read_only: bool,
    visibility: wgpu::ShaderStages,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A layout entry for a uniform buffer.
pub(super) fn uniform(
    binding: u32,
    dynamic: bool,
    visibility: wgpu::ShaderStages,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: dynamic,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A layout entry for a write-only RGBA8 storage texture (a pass's output image).
pub(super) fn storage_texture_rgba8(
    binding: u32,
    visibility: wgpu::ShaderStages,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::StorageTexture {
            access: wgpu::StorageTextureAccess::WriteOnly,
            format: wgpu::TextureFormat::Rgba8Unorm,
            view_dimension: wgpu::TextureViewDimension::D2,
        },
        count: None,
    }
}

/// A shader module from an embedded WGSL file.
pub(super) fn module(
    device: &wgpu::Device,
    path: &str,
) -> Result<wgpu::ShaderModule, super::GpuError> {
    let src = super::shaders::compose(path)?;
    Ok(device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(path),
        source: wgpu::ShaderSource::Wgsl(src.into()),
    }))
}

/// A bind group layout.
pub(super) fn layout(
    device: &wgpu::Device,
    label: &str,
    entries: &[wgpu::BindGroupLayoutEntry],
) -> wgpu::BindGroupLayout {
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries,
    })
}

/// A pipeline layout of `groups` in order.
pub(super) fn pipeline_layout(
    device: &wgpu::Device,
    label: &str,
    groups: &[&wgpu::BindGroupLayout],
) -> wgpu::PipelineLayout {
    let groups: Vec<Option<&wgpu::BindGroupLayout>> = groups.iter().map(|g| Some(*g)).collect();
    device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &groups,
        immediate_size: 0,
    })
}

/// The bind group layout and compute pipeline of a pass with one bind group, whose shader is
/// `NAME.wgsl` (label `name`, entry point `entry`).
pub(super) fn one_group_pipeline(
    device: &wgpu::Device,
    name: &str,
    entries: &[wgpu::BindGroupLayoutEntry],
    entry: &str,
) -> Result<(wgpu::BindGroupLayout, wgpu::ComputePipeline), super::GpuError> {
    let bgl = layout(device, name, entries);
    let pipeline = compute(
        device,
        name,
        &pipeline_layout(device, name, &[&bgl]),
        &module(device, &format!("{name}.wgsl"))?,
        entry,
    );
    Ok((bgl, pipeline))
}

/// A compute pipeline of `module`'s `entry`.
pub(super) fn compute(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    entry: &str,
) -> wgpu::ComputePipeline {
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: Some(layout),
        module,
        entry_point: Some(entry),
        compilation_options: wgpu::PipelineCompilationOptions::default(),
        cache: None,
    })
}

/// Which pass a timestamp pair measures.
pub(super) struct Timed {
    pub(super) name: &'static str,
    pub(super) first_query: u32,
}

/// Passes timed per frame at most.
pub(super) const MAX_TIMED_PASSES: u32 = 16;

/// Timestamp bookkeeping for one frame.
pub(super) struct Timestamps {
    pub(super) set: wgpu::QuerySet,
    pub(super) used: Vec<Timed>,
}

impl Timestamps {
    fn next(&mut self, name: &'static str) -> Option<u32> {
        let q = self.used.len() as u32 * 2;
        if q / 2 >= MAX_TIMED_PASSES {
            return None;
        }
        self.used.push(Timed {
            name,
            first_query: q,
        });
        Some(q)
    }

    pub(super) fn compute<'a>(
        &'a mut self,
        name: &'static str,
    ) -> Option<wgpu::ComputePassTimestampWrites<'a>> {
        let q = self.next(name)?;
        Some(wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(q),
            end_of_pass_write_index: Some(q + 1),
        })
    }

    pub(super) fn render<'a>(
        &'a mut self,
        name: &'static str,
    ) -> Option<wgpu::RenderPassTimestampWrites<'a>> {
        let q = self.next(name)?;
        Some(wgpu::RenderPassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(q),
            end_of_pass_write_index: Some(q + 1),
        })
    }
}

/// A compute pass named `name`, timed when the frame takes timestamps.
pub(super) fn compute_pass<'e>(
    enc: &'e mut wgpu::CommandEncoder,
    ts: &mut Option<Timestamps>,
    name: &'static str,
) -> wgpu::ComputePass<'e> {
    enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(name),
        timestamp_writes: ts.as_mut().and_then(|t| t.compute(name)),
    })
}

/// The buffers several passes share, persistent across frames (see [`FrameBuffers::prepare`]).
pub(super) struct FrameBuffers {
    /// The view's packed depth+id keys.
    pub(super) keys: wgpu::Buffer,
    /// Every shadow map's keys, each at its plan's offset.
    pub(super) shadow_keys: wgpu::Buffer,
    /// Occlusion tiles (Hi-Z).
    pub(super) tiles: wgpu::Buffer,
    pub(super) gbuffer: wgpu::Buffer,
    pub(super) counters: wgpu::Buffer,
    pub(super) indirect: wgpu::Buffer,
    /// Traversal queues, ping-ponged between levels.
    pub(super) queues: [wgpu::Buffer; 2],
    /// The view's uniform for its first (or only) splat pass and for the id pass.
    pub(super) view: wgpu::Buffer,
    pub(super) view_id: wgpu::Buffer,
    /// One uniform per shadow map.
    pub(super) shadow_views: Vec<wgpu::Buffer>,
    /// The frame's objects (`ObjectGpu`).
    pub(super) objects: wgpu::Buffer,
}

impl FrameBuffers {
    /// The frame's shared buffers, grown to the plan's sizes, with this frame's view uniforms
    /// and objects written into them.
    pub(super) fn prepare(
        pool: &mut BufferPool,
        gpu: Gpu<'_>,
        plan: &plan::FramePlan,
        quality: &thicket_core::quality::Quality,
        objects: &[u8],
        queue_capacity: u64,
    ) -> Self {
        use super::gpu_data::{
            COUNTER_BYTES, MAX_LEVELS, MODE_DEPTH, MODE_ID, MODE_KEY64, QUEUE_ENTRY_BYTES,
        };
        use wgpu::BufferUsages as U;
        let first_mode = if plan.path == super::AtomicPath::Key64 {
            MODE_KEY64
        } else {
            MODE_DEPTH
        };
        let main = &plan.main;
        let view = main.uniform(first_mode, quality, quality.occlusion_culling);
        // The id pass must visit every node the depth pass drew: no culling there.
        let view_id = main.uniform(MODE_ID, quality, false);
        let queue_bytes = queue_capacity * QUEUE_ENTRY_BYTES;
        Self {
            keys: pool.get(gpu, "keys", 0, plan.key_bytes, U::STORAGE),
            shadow_keys: pool.get(gpu, "shadow keys", 0, plan.shadow_key_bytes, U::STORAGE),
            tiles: pool.get(gpu, "occlusion tiles", 0, plan.tile_bytes, U::STORAGE),
            gbuffer: pool.get(
                gpu,
                "gbuffer",
                0,
                plan.gbuffer_bytes,
                U::STORAGE | U::COPY_SRC,
            ),
            counters: pool.get(
                gpu,
                "counters",
                0,
                COUNTER_BYTES,
                U::STORAGE | U::COPY_SRC | U::COPY_DST,
            ),
            indirect: pool.get(
                gpu,
                "indirect",
                0,
                u64::from(MAX_LEVELS) * 12,
                U::STORAGE | U::INDIRECT,
            ),
            queues: [
                pool.get(gpu, "queue a", 0, queue_bytes, U::STORAGE),
                pool.get(gpu, "queue b", 0, queue_bytes, U::STORAGE),
            ],
            view: pool.upload(gpu, "view", 0, bytemuck::bytes_of(&view), U::UNIFORM),
            view_id: pool.upload(
                gpu,
                "view id pass",
                0,
                bytemuck::bytes_of(&view_id),
                U::UNIFORM,
            ),
            shadow_views: plan
                .shadows
                .iter()
                .enumerate()
                .map(|(i, m)| {
                    let u = m.view.uniform(MODE_DEPTH, quality, false);
                    pool.upload(gpu, "shadow view", i, bytemuck::bytes_of(&u), U::UNIFORM)
                })
                .collect(),
            objects: pool.upload(gpu, "objects", 0, objects, U::STORAGE),
        }
    }
}

#[cfg(test)]
mod tests {
    use naga::{AddressSpace, StorageAccess};

    /// (shader, the bind group layouts its pipeline is created with, whether the shader
    /// declares every entry): every pipeline. The queue shader shares the splat shaders'
    /// groups and uses only some of their bindings.
    fn pipelines() -> Vec<(&'static str, Vec<Vec<wgpu::BindGroupLayoutEntry>>, bool)> {
        let traverse = super::traverse::bind_group_entries();
        let splat = traverse[..3].to_vec();
        vec![
            ("clear.wgsl", super::clear::bind_group_entries(), true),
            ("hiz.wgsl", super::hiz::bind_group_entries(), true),
            ("mesh32.wgsl", super::mesh::bind_group_entries(), true),
            ("mesh64.wgsl", super::mesh::bind_group_entries(), true),
            ("resolve.wgsl", super::resolve::bind_group_entries(), true),
            ("shade.wgsl", super::shade::bind_group_entries(), true),
            (
                "supersample.wgsl",
                super::supersample::bind_group_entries(),
                true,
            ),
            ("asvo_splat32.wgsl", splat.clone(), true),
            ("asvo_splat64.wgsl", splat, true),
            ("asvo_queue.wgsl", traverse, false),
            (
                "krs_trace.wgsl",
                super::super::krs::bind_group_entries(),
                true,
            ),
        ]
    }

    /// What a WGSL global needs of its layout entry, as text (`uniform`, `storage read`,
    /// `storage read_write`, `storage texture write`).
    fn wgsl_kind(space: AddressSpace, ty: &naga::TypeInner) -> String {
        match space {
            AddressSpace::Uniform => "uniform".into(),
            AddressSpace::Storage { access } if access.contains(StorageAccess::STORE) => {
                "storage read_write".into()
            }
            AddressSpace::Storage { .. } => "storage read".into(),
            AddressSpace::Handle => match ty {
                naga::TypeInner::Image {
                    class: naga::ImageClass::Storage { access, .. },
                    ..
                } if !access.contains(StorageAccess::LOAD) => "storage texture write".into(),
                naga::TypeInner::Image {
                    class:
                        naga::ImageClass::Sampled {
                            kind: naga::ScalarKind::Float,
                            multi: false,
                        },
                    ..
                } => "texture float".into(),
                other => format!("{other:?}"),
            },
            other => format!("{other:?}"),
        }
    }

    fn entry_kind(e: &wgpu::BindGroupLayoutEntry) -> String {
        match e.ty {
            wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                ..
            } => "uniform".into(),
            wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only },
                ..
            } => if read_only {
                "storage read"
            } else {
                "storage read_write"
            }
            .into(),
            wgpu::BindingType::StorageTexture {
                access: wgpu::StorageTextureAccess::WriteOnly,
                ..
            } => "storage texture write".into(),
            wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { .. },
                multisampled: false,
                ..
            } => "texture float".into(),
            ref other => format!("{other:?}"),
        }
    }

    /// Whether every binding `src` declares is one of `groups`' entries, of the kind that entry
    /// gives (what pipeline creation requires), and with `exact`, every entry is declared.
    fn check(
        src: &str,
        groups: &[Vec<wgpu::BindGroupLayoutEntry>],
        exact: bool,
    ) -> Result<(), String> {
        let module = naga::front::wgsl::parse_str(src).map_err(|e| e.emit_to_string(src))?;
        let mut wgsl: Vec<(u32, u32, String)> = module
            .global_variables
            .iter()
            .filter_map(|(_, g)| {
                let b = g.binding.as_ref()?;
                let kind = wgsl_kind(g.space, &module.types[g.ty].inner);
                Some((b.group, b.binding, kind))
            })
            .collect();
        let mut rust: Vec<(u32, u32, String)> = groups
            .iter()
            .enumerate()
            .flat_map(|(g, entries)| {
                entries
                    .iter()
                    .map(move |e| (g as u32, e.binding, entry_kind(e)))
            })
            .collect();
        wgsl.sort();
        rust.sort();
        let covered = wgsl.iter().all(|b| rust.contains(b));
        if covered && (!exact || wgsl == rust) {
            Ok(())
        } else {
            Err(format!("WGSL {wgsl:?}\nRust {rust:?}"))
        }
    }

    #[test]
    fn every_pipeline_binding_matches_its_shader() {
        let mut failures = Vec::new();
        for (path, groups, exact) in pipelines() {
            let src = crate::gpu::shaders::compose(path).expect("composes");
            if let Err(e) = check(&src, &groups, exact) {
                failures.push(format!("{path}: {e}"));
            }
        }
        assert!(failures.is_empty(), "{}", failures.join("\n"));
    }

    #[test]
    fn a_binding_changed_on_one_side_fails_the_check() {
        let src = crate::gpu::shaders::compose("resolve.wgsl").expect("composes");
        let groups = super::resolve::bind_group_entries();
        assert_eq!(check(&src, &groups, true), Ok(()), "the control passes");
        // WGSL side: a binding renumbered, a read-only buffer made writable.
        let edits = [
            ("@group(0) @binding(9)", "@group(0) @binding(10)"),
            ("var<storage, read> keys", "var<storage, read_write> keys"),
        ];
        for (from, to) in edits {
            assert!(src.contains(from), "resolve.wgsl has {from:?}");
            assert!(
                check(&src.replacen(from, to, 1), &groups, true).is_err(),
                "{from:?}"
            );
        }
        // Rust side: an entry dropped, one made read-only.
        let mut fewer = groups.clone();
        fewer[0].pop();
        assert!(check(&src, &fewer, false).is_err());
        let mut read_only = groups;
        read_only[0][5] = super::storage(5, true, wgpu::ShaderStages::COMPUTE);
        assert!(check(&src, &read_only, false).is_err());
        // A layout entry the shader does not declare fails only the exact check.
        let mut more = super::resolve::bind_group_entries();
        more[0].push(super::storage(11, true, wgpu::ShaderStages::COMPUTE));
        assert_eq!(check(&src, &more, false), Ok(()));
        assert!(check(&src, &more, true).is_err());
    }
}
