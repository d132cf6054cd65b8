//! ASVO traversal and splatting (paper §4, Fig. 8): per object and view, a seed dispatch, then
//! per level an indirect-dispatch preparation and the traversal of that level's queue, which
//! splats leaves and small nodes into the view's keys (`asvo_queue.wgsl`,
//! `asvo_splat32.wgsl`, `asvo_splat64.wgsl`). One pass covers every shadow map; the view's
//! pass rebuilds the Hi-Z tiles ([`super::hiz`]) before each level when occlusion culling is on.

use super::hiz::HizPass;
use super::plan::{FramePlan, ShadowPlan, ViewSpec};
use super::{BindGroups, Bound, BufferPool, FrameBuffers, Gpu, Timestamps};
use crate::gpu::GpuError;
use crate::gpu::gpu_data::{
    MAX_LEVELS, NODE_PARAMS_STRIDE, NodeParams, STATS_PER_LEVEL, STATS_START,
};
use crate::gpu::scene::{FrameObjects, SceneCache};
use crate::gpu::skin::SkinFrame;

/// One traversal to encode: an object seen from a view.
pub(in crate::gpu) struct Traversal {
    first_slot: u32,
    pub(in crate::gpu) depth: u8,
    /// The pool chunk holding the object (selects the group-0 bind group).
    chunk: usize,
}

/// Which view's traversals a pass encodes.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(in crate::gpu) enum Views {
    /// The view, writing depth (two-pass path) or the 64-bit key.
    Main,
    /// The view's id pass (two-pass path).
    MainId,
    /// Every shadow map (depth only).
    Shadows,
}

/// Layouts, pipelines and the bind groups of every view's traversals.
pub(in crate::gpu) struct TraversePass {
    /// Group 0: view, counters, nodes, keys, tiles, skin; 1: node parameters (dynamic
    /// offset); 2: the queues in and out.
    bgl: [wgpu::BindGroupLayout; 3],
    indirect_bgl: wgpu::BindGroupLayout,
    seed: wgpu::ComputePipeline,
    prepare: wgpu::ComputePipeline,
    traverse32: wgpu::ComputePipeline,
    traverse64: Option<wgpu::ComputePipeline>,
    /// Group 0 per pool chunk: the view, its id pass, each shadow map.
    main: BindGroups,
    main_id: BindGroups,
    shadows: Vec<BindGroups>,
    /// Node parameters, queues a→b and b→a, indirect arguments.
    shared: BindGroups,
    main_trav: Vec<Traversal>,
    shadow_travs: Vec<Vec<Traversal>>,
    indirect: Option<wgpu::Buffer>,
}

const PARAMS: usize = 0;
const QUEUES_AB: usize = 1;
const QUEUES_BA: usize = 2;
const INDIRECT: usize = 3;

/// The pass's bind group layouts: groups 0 to 2 of the splat pipelines, and the queue
/// pipelines' group 3 (the indirect arguments). Checked against `asvo_splat32.wgsl`,
/// `asvo_splat64.wgsl` and `asvo_queue.wgsl` by a test.
pub(in crate::gpu) fn bind_group_entries() -> Vec<Vec<wgpu::BindGroupLayoutEntry>> {
    use super::{storage, uniform};
    let cs = wgpu::ShaderStages::COMPUTE;
    vec![
        vec![
            uniform(0, false, cs),
            storage(1, false, cs),
            storage(2, true, cs),
            storage(4, false, cs),
            storage(5, true, cs),
            // Skin data and joint matrices (gpu/skin.rs).
            storage(6, true, cs),
            storage(7, true, cs),
        ],
        vec![uniform(0, true, cs)],
        vec![storage(0, true, cs), storage(1, false, cs)],
        vec![storage(0, false, cs)],
    ]
}

impl TraversePass {
    /// The 64-bit splat pipeline exists only with `int64`.
    pub(in crate::gpu) fn new(device: &wgpu::Device, int64: bool) -> Result<Self, GpuError> {
        use super::compute;
        let entries = bind_group_entries();
        let bgl = [
            super::layout(device, "traverse 0", &entries[0]),
            super::layout(device, "traverse 1", &entries[1]),
            super::layout(device, "traverse 2", &entries[2]),
        ];
        let indirect_bgl = super::layout(device, "indirect", &entries[3]);
        let trav_layout = super::pipeline_layout(device, "traverse", &[&bgl[0], &bgl[1], &bgl[2]]);
        let queue_layout = super::pipeline_layout(
            device,
            "traverse queue",
            &[&bgl[0], &bgl[1], &bgl[2], &indirect_bgl],
        );
        let queue_mod = super::module(device, "asvo_queue.wgsl")?;
        let splat = |label: &str, path: &str| -> Result<wgpu::ComputePipeline, GpuError> {
            Ok(compute(
                device,
                label,
                &trav_layout,
                &super::module(device, path)?,
                "traverse",
            ))
        };
        Ok(Self {
            seed: compute(device, "seed", &queue_layout, &queue_mod, "seed"),
            prepare: compute(
                device,
                "prepare",
                &queue_layout,
                &queue_mod,
                "prepare_indirect",
            ),
            traverse32: splat("traverse32", "asvo_splat32.wgsl")?,
            traverse64: if int64 {
                Some(splat("traverse64", "asvo_splat64.wgsl")?)
            } else {
                None
            },
            bgl,
            indirect_bgl,
            main: BindGroups::default(),
            main_id: BindGroups::default(),
            shadows: Vec::new(),
            shared: BindGroups::default(),
            main_trav: Vec::new(),
            shadow_travs: Vec::new(),
            indirect: None,
        })
    }

    /// Whether the 64-bit splat pipeline exists.
    pub(in crate::gpu) fn has_key64(&self) -> bool {
        self.traverse64.is_some()
    }

    /// Writes every traversal's per-level node parameters and keeps the bind groups of every
    /// view and pool chunk.
    pub(in crate::gpu) fn prepare(
        &mut self,
        gpu: Gpu<'_>,
        pool: &mut BufferPool,
        plan: &FramePlan,
        bufs: &FrameBuffers,
        (scene, objects, skin): (&SceneCache, &FrameObjects, &SkinFrame),
    ) {
        let mut slots: Vec<u8> = Vec::new();
        let mut params = Params {
            scene,
            objects,
            skin,
            slots: &mut slots,
        };
        self.main_trav = params.traversals(&plan.main, STATS_START);
        // Every map counts into the one shadow range: `shadow_levels` is summed over lights,
        // as the CPU's `FrameStats::shadow_levels`.
        self.shadow_travs = plan
            .shadows
            .iter()
            .map(|m| params.traversals(&m.view, STATS_START + MAX_LEVELS * STATS_PER_LEVEL))
            .collect();
        if slots.is_empty() {
            slots.resize(NODE_PARAMS_STRIDE as usize, 0);
        }
        let params_buf = pool.upload(gpu, "node params", 0, &slots, wgpu::BufferUsages::UNIFORM);
        let [qa, qb] = &bufs.queues;
        self.shared.set(
            gpu,
            &self.bgl[1],
            "node params",
            PARAMS,
            vec![(
                0,
                Bound::range(&params_buf, 0, size_of::<NodeParams>() as u64),
            )],
        );
        self.shared
            .set_buffers(gpu, &self.bgl[2], "queues a→b", QUEUES_AB, &[qa, qb]);
        self.shared
            .set_buffers(gpu, &self.bgl[2], "queues b→a", QUEUES_BA, &[qb, qa]);
        self.shared.set_buffers(
            gpu,
            &self.indirect_bgl,
            "indirect",
            INDIRECT,
            &[&bufs.indirect],
        );
        self.indirect = Some(bufs.indirect.clone());

        let group0 = Group0 {
            gpu,
            layout: &self.bgl[0],
            bufs,
            scene,
            skin,
        };
        group0.set(&mut self.main, &bufs.view, &Bound::whole(&bufs.keys));
        group0.set(&mut self.main_id, &bufs.view_id, &Bound::whole(&bufs.keys));
        self.shadows
            .resize_with(plan.shadows.len(), BindGroups::default);
        for ((groups, m), view) in self
            .shadows
            .iter_mut()
            .zip(&plan.shadows)
            .zip(&bufs.shadow_views)
        {
            group0.set(groups, view, &shadow_keys(&bufs.shadow_keys, m));
        }
    }

    /// The traversals of the view (for the splat-bandwidth measurement's work count).
    pub(in crate::gpu) fn main_traversals(&self) -> &[Traversal] {
        &self.main_trav
    }

    /// Encodes `views`' traversals in one pass named `name` (none when they have none), with
    /// the 64-bit splat when `key64`, rebuilding the Hi-Z tiles before each level with `hiz`.
    pub(in crate::gpu) fn encode(
        &self,
        enc: &mut wgpu::CommandEncoder,
        ts: &mut Option<Timestamps>,
        name: &'static str,
        views: Views,
        key64: bool,
        hiz: Option<&HizPass>,
    ) {
        let pipeline = match (&self.traverse64, key64) {
            (Some(p), true) => p,
            _ => &self.traverse32,
        };
        let views: Vec<(&BindGroups, &[Traversal])> = match views {
            Views::Main => vec![(&self.main, &self.main_trav)],
            Views::MainId => vec![(&self.main_id, &self.main_trav)],
            Views::Shadows => self
                .shadows
                .iter()
                .zip(&self.shadow_travs)
                .map(|(g, t)| (g, t.as_slice()))
                .collect(),
        };
        if views.iter().all(|(_, travs)| travs.is_empty()) {
            return;
        }
        let (Some(params), Some(ab), Some(ba), Some(indirect_bg), Some(indirect)) = (
            self.shared.get(PARAMS),
            self.shared.get(QUEUES_AB),
            self.shared.get(QUEUES_BA),
            self.shared.get(INDIRECT),
            &self.indirect,
        ) else {
            return;
        };
        // One pass for every view given (all shadow maps: one timed pass, however many
        // lights cast).
        let mut pass = super::compute_pass(enc, ts, name);
        for (bg0, t) in views.iter().flat_map(|&(bgs, travs)| {
            travs
                .iter()
                .filter_map(move |t| Some((bgs.get(t.chunk)?, t)))
        }) {
            let slot = |level: u32| ((t.first_slot + level) as u64 * NODE_PARAMS_STRIDE) as u32;
            pass.set_bind_group(0, bg0, &[]);
            pass.set_bind_group(3, indirect_bg, &[]);
            pass.set_pipeline(&self.seed);
            pass.set_bind_group(1, params, &[slot(0)]);
            pass.set_bind_group(2, ba, &[]);
            pass.dispatch_workgroups(1, 1, 1);
            for level in 0..=u32::from(t.depth) {
                if let Some(hiz) = hiz {
                    // Occlusion tiles from everything drawn so far (meshes, earlier levels
                    // and objects); its layout differs, so rebind after it.
                    hiz.dispatch(&mut pass);
                    pass.set_bind_group(0, bg0, &[]);
                    pass.set_bind_group(2, ba, &[]);
                    pass.set_bind_group(3, indirect_bg, &[]);
                }
                pass.set_bind_group(1, params, &[slot(level)]);
                pass.set_pipeline(&self.prepare);
                pass.dispatch_workgroups(1, 1, 1);
                pass.set_pipeline(pipeline);
                pass.set_bind_group(2, if level % 2 == 0 { ab } else { ba }, &[]);
                pass.dispatch_workgroups_indirect(indirect, u64::from(level) * 12);
            }
        }
    }
}

/// Each map's passes see only its own range of the shadow key buffer, so the splat and mesh
/// shaders index it from 0 as they index the view's.
pub(in crate::gpu) fn shadow_keys(buffer: &wgpu::Buffer, m: &ShadowPlan) -> Bound {
    Bound::range(buffer, m.offset, m.slot_bytes)
}

/// What group 0 of a traversal binds besides its view and keys.
struct Group0<'a> {
    gpu: Gpu<'a>,
    layout: &'a wgpu::BindGroupLayout,
    bufs: &'a FrameBuffers,
    scene: &'a SceneCache,
    skin: &'a SkinFrame,
}

impl Group0<'_> {
    /// One group per pool chunk: its inner nodes and skin data.
    fn set(&self, groups: &mut BindGroups, view: &wgpu::Buffer, keys: &Bound) {
        let chunks = self.scene.chunks.iter().zip(&self.skin.data_bufs);
        for (i, (chunk, skin_data)) in chunks.enumerate() {
            let entries = vec![
                (0, Bound::whole(view)),
                (1, Bound::whole(&self.bufs.counters)),
                (2, Bound::whole(&chunk.inner_buf)),
                (4, keys.clone()),
                (5, Bound::whole(&self.bufs.tiles)),
                (6, Bound::whole(skin_data)),
                (7, Bound::whole(&self.skin.joint_buf)),
            ];
            groups.set(self.gpu, self.layout, "traverse 0", i, entries);
        }
        groups.truncate(self.scene.chunks.len());
    }
}

/// Builds the per-level node parameters of every object seen from a view.
struct Params<'a> {
    scene: &'a SceneCache,
    objects: &'a FrameObjects,
    skin: &'a SkinFrame,
    slots: &'a mut Vec<u8>,
}

impl Params<'_> {
    fn traversals(&mut self, spec: &ViewSpec, stats_base: u32) -> Vec<Traversal> {
        let cap = self.scene.queue_capacity as u32;
        let entries = self.scene.voxels.iter().zip(&self.objects.world_from_voxel);
        entries
            .zip(&self.skin.params)
            .map(|((e, &world_from_voxel), &skin)| {
                let first_slot = (self.slots.len() as u64 / NODE_PARAMS_STRIDE) as u32;
                let base = NodeParams::for_object(
                    spec.view_from_world * world_from_voxel,
                    world_from_voxel,
                );
                let depth = u32::from(e.depth);
                for level in 0..=depth {
                    let p = NodeParams {
                        level,
                        node_size: 1u32 << (depth - level),
                        leaf_level: depth,
                        queue_capacity: cap,
                        inner_base: e.inner_base,
                        leaf_base: 0,
                        attr_inner_base: e.attr_inner_base,
                        attr_leaf_base: e.attr_leaf_base,
                        stats_base,
                        skin,
                        ..base
                    };
                    self.slots.extend_from_slice(bytemuck::bytes_of(&p));
                    let pad = NODE_PARAMS_STRIDE as usize - size_of::<NodeParams>();
                    self.slots.resize(self.slots.len() + pad, 0);
                }
                Traversal {
                    first_slot,
                    depth: e.depth,
                    chunk: e.chunk,
                }
            })
            .collect()
    }
}
