//! `.vox` → objects: validation, `dot_vox`, scene graph, normals, octrees.

use std::panic::{AssertUnwindSafe, catch_unwind};

use crate::budget::MemoryBudget;
use std::path::Path;

use glam::{UVec3, Vec3};

use super::chunks::{Layout, validate};
use super::{
    DEFAULT_MAX_VOXELS, IDENTITY, IMat3, MAX_COORD, MAX_FILE_BYTES, MAX_FRAMES, MAX_INSTANCES,
    MAX_SCENE_DEPTH, VoxError, decode_rotation, imat_apply, imat_mul, malformed, scene_error,
    yup_cell_from_mv, yup_from_mv,
};
use crate::scene::{
    Document, FrameSequence, Object, ObjectKind, Transform, VoxelFrame, VoxelModel,
};
use crate::svo::{Svo, Voxel, encode_normal};

/// Limits for [`import_vox_with`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct VoxImportOptions {
    /// Most voxels the import may create, counting every instance.
    pub max_voxels: u64,
    /// The memory the import may fill: the voxels the scene graph places (every instance and
    /// frame) times [`VOX_IMPORT_BYTES_PER_VOXEL`] and the file's own bytes, checked before
    /// any model is built.
    pub memory: MemoryBudget,
}

impl Default for VoxImportOptions {
    fn default() -> Self {
        Self {
            max_voxels: DEFAULT_MAX_VOXELS,
            memory: MemoryBudget::for_this_machine(),
        }
    }
}

/// Peak heap of an import per voxel placed (parsed models, per-instance cells, the octrees
/// built). Measured with a counting allocator: 96 bytes per voxel on obj_house4.vox (180,202
/// voxels), less on the smaller samples; the test `import_memory_is_estimated_before_building`
/// keeps the estimate above every sample's peak.
pub const VOX_IMPORT_BYTES_PER_VOXEL: u64 = 128;

/// The estimated peak memory of importing `voxels` placed voxels from a file of `file_bytes`.
#[must_use]
pub fn estimate_vox_import(voxels: u64, file_bytes: u64) -> u64 {
    voxels
        .saturating_mul(VOX_IMPORT_BYTES_PER_VOXEL)
        .saturating_add(file_bytes.saturating_mul(4))
        .saturating_add(256 << 10)
}

/// What a `.vox` file holds, ready to go into a [`Document`].
#[derive(Debug, Clone, PartialEq)]
pub struct VoxScene {
    /// One voxel object per shape instance in scene-graph order (an animated shape, or a file
    /// without a scene graph holding several models, is one object with a frame sequence). Ids are 1, 2, …; [`VoxScene::add_to`] renumbers them.
    pub objects: Vec<Object>,
    /// The 255 usable palette colours, sRGB RGBA: entry `i` is the file's colour index `i + 1`.
    pub palette: Vec<[u8; 4]>,
    /// Material names shared by every object (`material_names[0]` is `"diffuse"`).
    pub material_names: Vec<String>,
    /// The file's version field (150 or 200 for MagicaVoxel files).
    pub version: u32,
    /// Models stored in the file (before instancing).
    pub model_count: usize,
    /// Voxels stored in the file's models (before instancing; [`VoxScene::voxel_count`] counts
    /// every placed instance).
    pub stored_voxels: u64,
}

impl VoxScene {
    /// Voxels over all objects (every instance and every frame of an animation counted).
    #[must_use]
    pub fn voxel_count(&self) -> u64 {
        self.objects
            .iter()
            .map(|o| match &o.kind {
                ObjectKind::Voxels(v) => (0..v.frame_count())
                    .filter_map(|i| v.frame(i))
                    .map(|(svo, _)| svo.leaf_count())
                    .sum(),
                ObjectKind::Mesh(_) | ObjectKind::Krs(_) => 0,
            })
            .sum()
    }

    /// Moves the objects into `doc` with fresh ids; returns the ids.
    pub fn add_to(self, doc: &mut Document) -> Vec<u64> {
        self.objects
            .into_iter()
            .map(|o| {
                let id = doc.add(o.name, o.kind);
                if let Some(added) = doc.objects.last_mut() {
                    added.transform = o.transform;
                    added.visible = o.visible;
                }
                id
            })
            .collect()
    }
}

/// Reads a `.vox` file with the default limits.
///
/// # Errors
/// A [`VoxError`] naming the file and what is wrong where; never panics on bad input.
pub fn import_vox(path: &Path) -> Result<VoxScene, VoxError> {
    import_vox_with(path, &VoxImportOptions::default())
}

/// Reads a `.vox` file.
///
/// # Errors
/// See [`import_vox`].
pub fn import_vox_with(path: &Path, options: &VoxImportOptions) -> Result<VoxScene, VoxError> {
    let io = |action, source| VoxError::Io {
        path: path.to_owned(),
        action,
        source,
    };
    let len = std::fs::metadata(path).map_err(|e| io("reading", e))?.len();
    if len > MAX_FILE_BYTES {
        return Err(VoxError::TooLarge {
            path: path.to_owned(),
            detail: format!("the file is {len} bytes; the limit is {MAX_FILE_BYTES}"),
        });
    }
    let bytes = std::fs::read(path).map_err(|e| io("reading", e))?;
    import_vox_bytes(&bytes, path, options)
}

/// Reads `.vox` bytes; `path` only names the source in errors.
///
/// # Errors
/// See [`import_vox`].
pub fn import_vox_bytes(
    bytes: &[u8],
    path: &Path,
    options: &VoxImportOptions,
) -> Result<VoxScene, VoxError> {
    let layout = validate(bytes, path)?;
    if layout.total_voxels > options.max_voxels {
        return Err(VoxError::TooLarge {
            path: path.to_owned(),
            detail: format!(
                "the models hold {} voxels; the limit is {}",
                layout.total_voxels, options.max_voxels
            ),
        });
    }
    // Last line of defence: the input has passed `validate`, so dot_vox should neither fail nor
    // panic; if a dot_vox bug panics anyway, the user gets an error instead of a crash.
    let parsed = catch_unwind(AssertUnwindSafe(|| dot_vox::load_bytes(bytes)));
    let data = match parsed {
        Ok(Ok(d)) => d,
        Ok(Err(msg)) => {
            return Err(VoxError::Parser {
                path: path.to_owned(),
                detail: msg.to_owned(),
            });
        }
        Err(_) => {
            return Err(VoxError::Parser {
                path: path.to_owned(),
                detail: "dot_vox panicked".into(),
            });
        }
    };
    check_agreement(&data, &layout, path)?;

    let palette: Vec<[u8; 4]> = (0..255)
        .map(|i| data.palette.get(i).map_or([0, 0, 0, 255], <[u8; 4]>::from))
        .collect();
    let (material_names, material_of_index) = materials(&data);
    let models: Vec<ModelVoxels> = data.models.iter().map(ModelVoxels::new).collect();
    let instances = instances(&data, &layout, &models, path)?;

    let planned: u64 = instances
        .iter()
        .flat_map(|i| &i.frames)
        .map(|f| models[f.model].voxels.len() as u64)
        .sum();
    options
        .memory
        .check(
            &format!(
                "importing {} instance(s) holding {} voxels",
                instances.len(),
                crate::budget::thousands(planned)
            ),
            estimate_vox_import(planned, bytes.len() as u64),
            "raise the limit with --memory-limit, or import a file whose scene graph places \
             fewer copies",
        )
        .map_err(|e| VoxError::TooLarge {
            path: path.to_owned(),
            detail: e.to_string(),
        })?;
    if planned > options.max_voxels {
        return Err(VoxError::TooLarge {
            path: path.to_owned(),
            detail: format!(
                "the scene graph places {} instances holding {planned} voxels; the limit is {}",
                instances.len(),
                options.max_voxels
            ),
        });
    }

    let mut objects = Vec::with_capacity(instances.len());
    for (k, inst) in instances.iter().enumerate() {
        let mut built = Vec::with_capacity(inst.frames.len());
        for frame in &inst.frames {
            let model = &models[frame.model];
            let svo_and_lo = build_instance(model, frame, &palette, &material_of_index);
            built.push(svo_and_lo.map_err(|detail| scene_error(path, inst.node, detail))?);
        }
        // The object sits at frame 0's pivot; every frame's voxels are placed from there.
        let pivot = yup_from_mv(inst.frames[0].pivot_world);
        let pivot_f = Vec3::new(pivot[0] as f32, pivot[1] as f32, pivot[2] as f32);
        let origin_of = |lo: [i64; 3]| {
            Vec3::new(
                (lo[0] - pivot[0]) as f32,
                (lo[1] - pivot[1]) as f32,
                (lo[2] - pivot[2]) as f32,
            )
        };
        let mut built = built.into_iter();
        let Some((svo, lo)) = built.next() else {
            return Err(scene_error(path, inst.node, "an instance without frames"));
        };
        let frames = (inst.frames.len() > 1).then(|| FrameSequence {
            frames: std::iter::once(VoxelFrame::default())
                .chain(built.map(|(svo, lo)| VoxelFrame {
                    svo,
                    origin: origin_of(lo),
                }))
                .collect(),
            ..FrameSequence::default()
        });
        objects.push(Object {
            motion: None,
            id: k as u64 + 1,
            name: inst.name.clone(),
            visible: !inst.hidden,
            transform: Transform {
                translation: pivot_f,
                ..Transform::default()
            },
            kind: ObjectKind::Voxels(VoxelModel {
                svo,
                voxel_size: 1.0,
                origin: origin_of(lo),
                material_names: material_names.clone(),
                rig: None,
                volume: None,
                // The file's colours in file order, so an export can keep every index.
                palette: palette.clone(),
                frames,
            }),
        });
    }
    Ok(VoxScene {
        objects,
        palette,
        material_names,
        version: data.version,
        model_count: data.models.len(),
        stored_voxels: layout.total_voxels,
    })
}

/// dot_vox and the validator must agree on what the file holds, or indices would be wrong.
fn check_agreement(
    data: &dot_vox::DotVoxData,
    layout: &Layout,
    path: &Path,
) -> Result<(), VoxError> {
    let sizes: Vec<[u32; 3]> = data
        .models
        .iter()
        .map(|m| [m.size.x, m.size.y, m.size.z])
        .collect();
    let counts_agree = data
        .models
        .iter()
        .map(|m| m.voxels.len() as u64)
        .sum::<u64>()
        == layout.total_voxels;
    if sizes != layout.model_sizes
        || !counts_agree
        || data.scenes.len() != layout.node_ids.len()
        || data.materials.len() != layout.materials
        || data.layers.len() != layout.layers
    {
        return Err(VoxError::Parser {
            path: path.to_owned(),
            detail: format!(
                "dot_vox read {} models, {} scene nodes, {} materials, {} layers; the chunk \
                 walk found {}, {}, {}, {}",
                data.models.len(),
                data.scenes.len(),
                data.materials.len(),
                data.layers.len(),
                layout.model_sizes.len(),
                layout.node_ids.len(),
                layout.materials,
                layout.layers
            ),
        });
    }
    Ok(())
}

/// Material names (`"diffuse"` first, then each MATL `_type` without its underscore in order of
/// palette index) and the material id of each 0-based palette index.
fn materials(data: &dot_vox::DotVoxData) -> (Vec<String>, [u8; 256]) {
    let mut type_of_file_index: [Option<&str>; 256] = [None; 256];
    for m in &data.materials {
        // MATL ids are file colour indices (1..=255); 256 wraps to 0 like ogt_vox does.
        let Ok(id) = usize::try_from(m.id & 0xff) else {
            continue;
        };
        type_of_file_index[id] = m.material_type();
    }
    let mut names = vec!["diffuse".to_owned()];
    let mut of_index = [0u8; 256];
    for i in 0..255 {
        let Some(t) = type_of_file_index[i + 1] else {
            continue;
        };
        let name = t.trim_start_matches('_');
        if name.is_empty() || name == "diffuse" {
            continue;
        }
        let id = if let Some(k) = names.iter().position(|n| n == name) {
            k
        } else if names.len() < 256 {
            names.push(name.to_owned());
            names.len() - 1
        } else {
            // More than 255 distinct type names only occurs in corrupt files; they share 0.
            0
        };
        of_index[i] = id as u8;
    }
    (names, of_index)
}

/// One model's voxels with outward normals estimated from the 6-neighbourhood, in
/// MagicaVoxel model space.
struct ModelVoxels {
    size: [u32; 3],
    /// `(position, 0-based palette index, outward normal sum; zero = interior)`.
    voxels: Vec<([u8; 3], u8, [i8; 3])>,
}

impl ModelVoxels {
    fn new(model: &dot_vox::Model) -> Self {
        let size = [model.size.x, model.size.y, model.size.z];
        let [sx, sy, sz] = size.map(|s| s as usize);
        // Validated: every edge is 1..=256, so this is at most 2 MiB.
        let mut occupied = vec![0u64; (sx * sy * sz).div_ceil(64)];
        let index = |x: usize, y: usize, z: usize| x + sx * (y + sy * z);
        for v in &model.voxels {
            let i = index(usize::from(v.x), usize::from(v.y), usize::from(v.z));
            if let Some(w) = occupied.get_mut(i / 64) {
                *w |= 1 << (i % 64);
            }
        }
        let solid = |x: i64, y: i64, z: i64| {
            if x < 0 || y < 0 || z < 0 || x >= sx as i64 || y >= sy as i64 || z >= sz as i64 {
                return false;
            }
            let i = index(x as usize, y as usize, z as usize);
            occupied
                .get(i / 64)
                .is_some_and(|w| w & (1 << (i % 64)) != 0)
        };
        // Fallback order when exposed faces cancel (a one-voxel wall): up (+Z here) first.
        const DIRS: [[i8; 3]; 6] = [
            [0, 0, 1],
            [0, 0, -1],
            [1, 0, 0],
            [-1, 0, 0],
            [0, 1, 0],
            [0, -1, 0],
        ];
        let voxels = model
            .voxels
            .iter()
            .map(|v| {
                let p = [i64::from(v.x), i64::from(v.y), i64::from(v.z)];
                let mut sum = [0i8; 3];
                let mut first_exposed = None;
                for d in DIRS {
                    if !solid(
                        p[0] + i64::from(d[0]),
                        p[1] + i64::from(d[1]),
                        p[2] + i64::from(d[2]),
                    ) {
                        first_exposed.get_or_insert(d);
                        for a in 0..3 {
                            sum[a] += d[a];
                        }
                    }
                }
                if sum == [0; 3] {
                    sum = first_exposed.unwrap_or([0; 3]);
                }
                ([v.x, v.y, v.z], v.i, sum)
            })
            .collect();
        Self { size, voxels }
    }
}

/// One shape instance: which model, and where, per animation frame.
struct Instance {
    /// One entry per frame (one for a still shape).
    frames: Vec<InstanceFrame>,
    name: String,
    hidden: bool,
    /// The shape node (for errors).
    node: u32,
}

/// An instance in one frame.
struct InstanceFrame {
    model: usize,
    /// Accumulated rotation (MagicaVoxel space).
    rotation: IMat3,
    /// Accumulated translation: where the model's pivot lands (MagicaVoxel space).
    translation: [i64; 3],
    /// The object's origin in MagicaVoxel space (the pivot, or 0 for files without a graph).
    pivot_world: [i64; 3],
}

/// The frame index `_f` of a keyframe dictionary (0 when absent).
fn frame_index(attributes: &dot_vox::Dict) -> Result<u32, String> {
    match attributes.get("_f") {
        None => Ok(0),
        Some(s) => s
            .trim()
            .parse::<u32>()
            .ok()
            .filter(|&f| f < MAX_FRAMES)
            .ok_or_else(|| {
                format!("frame index _f {s:?} is not a whole number below {MAX_FRAMES}")
            }),
    }
}

/// The keyframe in force at frame `f`: the last one at or before `f`, else the first (keys
/// hold until the next one; voxels cannot be interpolated).
fn key_at<T>(keys: &[(u32, T)], f: u32) -> Option<&T> {
    keys.iter()
        .filter(|(k, _)| *k <= f)
        .max_by_key(|(k, _)| *k)
        .or_else(|| keys.iter().min_by_key(|(k, _)| *k))
        .map(|(_, t)| t)
}

/// A transform keyframe: translation `_t` and rotation `_r`.
type TransformKey = ([i64; 3], IMat3);

/// A transform frame's `_t` and `_r`.
fn frame_transform(frame: &dot_vox::Dict) -> Result<TransformKey, String> {
    let t = match frame.get("_t") {
        None => [0; 3],
        Some(s) => parse_translation(s)
            .ok_or_else(|| format!("translation _t {s:?} is not three integers"))?,
    };
    let r = match frame.get("_r") {
        None => IDENTITY,
        Some(s) => s
            .trim()
            .parse::<u8>()
            .ok()
            .and_then(decode_rotation)
            .ok_or_else(|| format!("rotation _r {s:?} is invalid"))?,
    };
    Ok((t, r))
}

fn parse_translation(s: &str) -> Option<[i64; 3]> {
    let mut it = s.split_ascii_whitespace().map(str::parse::<i32>);
    let t = [it.next()?.ok()?, it.next()?.ok()?, it.next()?.ok()?];
    if it.next().is_some() {
        return None;
    }
    Some(t.map(i64::from))
}

/// Walks the scene graph from the root, or lists the models when there is none.
fn instances(
    data: &dot_vox::DotVoxData,
    layout: &Layout,
    models: &[ModelVoxels],
    path: &Path,
) -> Result<Vec<Instance>, VoxError> {
    use dot_vox::SceneNode;
    if data.scenes.is_empty() {
        // Without a scene graph, several models are the frames of an animation (how
        // MagicaVoxel wrote animations before 0.99); each frame's voxel (0,0,0) is at the origin.
        let frames: Vec<InstanceFrame> = (0..models.len())
            .map(|m| {
                let s = models[m].size.map(i64::from);
                InstanceFrame {
                    model: m,
                    rotation: IDENTITY,
                    // Pivot at floor(size / 2) puts voxel (0,0,0) at the origin.
                    translation: [s[0] / 2, s[1] / 2, s[2] / 2],
                    pivot_world: [0; 3],
                }
            })
            .collect();
        if frames.len() > MAX_FRAMES as usize {
            return Err(VoxError::TooLarge {
                path: path.to_owned(),
                detail: format!(
                    "{} models would be {} animation frames; the limit is {MAX_FRAMES}",
                    frames.len(),
                    frames.len()
                ),
            });
        }
        let name = if frames.len() > 1 {
            "animation".to_owned()
        } else {
            "model 0".to_owned()
        };
        return Ok(if frames.is_empty() {
            Vec::new()
        } else {
            vec![Instance {
                frames,
                name,
                hidden: false,
                node: 0,
            }]
        });
    }
    let root = layout.node_index.get(&0).copied().unwrap_or(0);
    let layer_hidden = |id: u32| {
        usize::try_from(id)
            .ok()
            .and_then(|i| data.layers.get(i))
            .is_some_and(dot_vox::Layer::hidden)
    };
    struct Visit {
        index: usize,
        /// The transform nodes from the root down to here (indices into `data.scenes`).
        chain: Vec<usize>,
        depth: usize,
        hidden: bool,
        name: Option<String>,
    }
    let mut stack = vec![Visit {
        index: root,
        chain: Vec::new(),
        depth: 0,
        hidden: false,
        name: None,
    }];
    let mut out = Vec::new();
    // Instance frames created so far, against the instance budget.
    let mut placed = 0usize;
    let mut visits = 0usize;
    while let Some(v) = stack.pop() {
        let node_id = layout.node_ids.get(v.index).copied().unwrap_or(0);
        visits += 1;
        if visits > MAX_INSTANCES * 8 {
            return Err(VoxError::TooLarge {
                path: path.to_owned(),
                detail: format!(
                    "the scene graph visits more than {} nodes",
                    MAX_INSTANCES * 8
                ),
            });
        }
        if v.depth > MAX_SCENE_DEPTH {
            return Err(scene_error(
                path,
                node_id,
                format!("nesting deeper than {MAX_SCENE_DEPTH} levels (a cycle?)"),
            ));
        }
        let lookup = |child: u32| {
            layout.node_index.get(&child).copied().ok_or_else(|| {
                scene_error(
                    path,
                    node_id,
                    format!("references node {child}, which does not exist"),
                )
            })
        };
        let Some(node) = data.scenes.get(v.index) else {
            return Err(scene_error(path, node_id, "missing from the parsed scene"));
        };
        match node {
            SceneNode::Transform {
                attributes,
                frames,
                child,
                layer_id,
            } => {
                // Every frame's keys are checked here, where the error can name this node.
                for (k, f) in frames.iter().enumerate() {
                    frame_index(&f.attributes)
                        .and_then(|_| frame_transform(&f.attributes))
                        .map_err(|e| scene_error(path, node_id, format!("frame {k}: {e}")))?;
                }
                let hidden = v.hidden
                    || attributes.get("_hidden").is_some_and(|h| h == "1")
                    || layer_hidden(*layer_id);
                let mut chain = v.chain;
                chain.push(v.index);
                stack.push(Visit {
                    index: lookup(*child)?,
                    chain,
                    depth: v.depth + 1,
                    hidden,
                    name: attributes.get("_name").cloned().or(v.name),
                });
            }
            SceneNode::Group { children, .. } => {
                // Reversed so the stack pops children in file order.
                for &c in children.iter().rev() {
                    stack.push(Visit {
                        index: lookup(c)?,
                        chain: v.chain.clone(),
                        depth: v.depth + 1,
                        hidden: v.hidden,
                        name: None,
                    });
                }
            }
            SceneNode::Shape { models: refs, .. } => {
                if refs.is_empty() {
                    return Err(scene_error(path, node_id, "a shape without models"));
                }
                let mut shape_keys = Vec::with_capacity(refs.len());
                for (k, r) in refs.iter().enumerate() {
                    let f = frame_index(&r.attributes)
                        .map_err(|e| scene_error(path, node_id, format!("model {k}: {e}")))?;
                    let model = usize::try_from(r.model_id)
                        .ok()
                        .filter(|&m| m < models.len())
                        .ok_or_else(|| {
                            scene_error(
                                path,
                                node_id,
                                format!(
                                    "uses model {} but the file has {} models",
                                    r.model_id,
                                    models.len()
                                ),
                            )
                        })?;
                    shape_keys.push((f, model));
                }
                let frames = shape_frames(data, &v.chain, &shape_keys)
                    .map_err(|e| scene_error(path, node_id, e))?;
                placed += frames.len();
                if out.len() >= MAX_INSTANCES || placed > MAX_INSTANCES {
                    return Err(VoxError::TooLarge {
                        path: path.to_owned(),
                        detail: format!(
                            "more than {MAX_INSTANCES} shape instances (animation frames counted)"
                        ),
                    });
                }
                let first = frames.first().map_or(0, |f| f.model);
                out.push(Instance {
                    frames,
                    name: v.name.unwrap_or_else(|| format!("model {first}")),
                    hidden: v.hidden,
                    node: node_id,
                });
            }
        }
    }
    if out.is_empty() && !models.is_empty() {
        return Err(malformed(
            path,
            "scene graph",
            format!("the graph places none of the {} models", models.len()),
        ));
    }
    Ok(out)
}

/// A shape's frames under the transforms of `chain`: one frame when neither the shape's
/// models nor the transforms' frames carry more than one frame index `_f`; otherwise frames
/// `0..=max _f`, each node holding its last keyframe at or before the frame (as MagicaVoxel
/// 0.99.7 writes animations: `_f` in the nTRN frame dictionaries and the nSHP model lists).
fn shape_frames(
    data: &dot_vox::DotVoxData,
    chain: &[usize],
    shape_keys: &[(u32, usize)],
) -> Result<Vec<InstanceFrame>, String> {
    use dot_vox::SceneNode;
    let mut transform_keys: Vec<Vec<(u32, TransformKey)>> = Vec::with_capacity(chain.len());
    for &i in chain {
        let Some(SceneNode::Transform { frames, .. }) = data.scenes.get(i) else {
            return Err("a transform above the shape is missing".into());
        };
        let mut keys = Vec::with_capacity(frames.len());
        for f in frames {
            keys.push((frame_index(&f.attributes)?, frame_transform(&f.attributes)?));
        }
        transform_keys.push(keys);
    }
    let mut indices: Vec<u32> = shape_keys
        .iter()
        .map(|(f, _)| *f)
        .chain(transform_keys.iter().flatten().map(|(f, _)| *f))
        .collect();
    indices.sort_unstable();
    indices.dedup();
    let animated = indices.len() > 1;
    let count = if animated {
        indices.last().map_or(1, |&m| m + 1)
    } else {
        1
    };
    (0..count)
        .map(|f| {
            let mut rotation = IDENTITY;
            let mut translation = [0i64; 3];
            for keys in &transform_keys {
                // A still node uses its first frame, as before animation support.
                let key = if animated {
                    key_at(keys, f)
                } else {
                    keys.first().map(|(_, k)| k)
                };
                let (t, r) = key.copied().unwrap_or(([0; 3], IDENTITY));
                let moved = imat_apply(&rotation, t);
                translation = [0, 1, 2].map(|a| translation[a] + moved[a]);
                rotation = imat_mul(&rotation, &r);
            }
            let model = if animated {
                key_at(shape_keys, f).copied()
            } else {
                shape_keys.first().map(|(_, m)| *m)
            };
            Ok(InstanceFrame {
                model: model.ok_or("a shape without models")?,
                rotation,
                translation,
                pivot_world: translation,
            })
        })
        .collect()
}

/// Places one instance's voxels in Y-up world cells; returns its octree (coordinates relative
/// to the minimum cell) and that minimum cell.
fn build_instance(
    model: &ModelVoxels,
    inst: &InstanceFrame,
    palette: &[[u8; 4]],
    material_of_index: &[u8; 256],
) -> Result<(Svo, [i64; 3]), String> {
    let pivot = model.size.map(|s| i64::from(s / 2));
    let cells: Vec<[i64; 3]> = model
        .voxels
        .iter()
        .map(|(p, _, _)| {
            // Doubled coordinates keep the half-voxel centre offset exact in integers.
            let centre2 = [0, 1, 2].map(|a| 2 * (i64::from(p[a]) - pivot[a]) + 1);
            let r = imat_apply(&inst.rotation, centre2);
            let mv_min = [0, 1, 2].map(|a| (r[a] + 2 * inst.translation[a] - 1).div_euclid(2));
            yup_cell_from_mv(mv_min)
        })
        .collect();
    let Some(first) = cells.first() else {
        return Ok((
            Svo::new(1, false).map_err(|e| e.to_string())?,
            yup_from_mv(inst.pivot_world),
        ));
    };
    let mut lo = *first;
    let mut hi = *first;
    for c in &cells {
        for a in 0..3 {
            lo[a] = lo[a].min(c[a]);
            hi[a] = hi[a].max(c[a]);
        }
    }
    if lo.iter().chain(hi.iter()).any(|c| c.abs() > MAX_COORD) {
        return Err(format!(
            "places voxels between {lo:?} and {hi:?}, beyond ±{MAX_COORD} where positions stop being exact"
        ));
    }
    let extent = (0..3).map(|a| hi[a] - lo[a] + 1).max().unwrap_or(1);
    let mut depth = 1u8;
    while (1i64 << depth) < extent {
        depth += 1;
    }
    let voxels = model.voxels.iter().zip(&cells).map(|((_, index, n), c)| {
        let n_mv = imat_apply(&inst.rotation, n.map(i64::from));
        let n_yup = yup_from_mv(n_mv);
        let normal = if n_yup == [0; 3] {
            Vec3::Y
        } else {
            Vec3::new(n_yup[0] as f32, n_yup[1] as f32, n_yup[2] as f32)
        };
        let i = usize::from(*index);
        let voxel = Voxel {
            color: palette.get(i).copied().unwrap_or([0, 0, 0, 255]),
            normal: encode_normal(normal),
            material: material_of_index[i],
            ..Voxel::default()
        };
        let coord = UVec3::new(
            (c[0] - lo[0]) as u32,
            (c[1] - lo[1]) as u32,
            (c[2] - lo[2]) as u32,
        );
        (coord, voxel)
    });
    let svo = Svo::from_voxels(depth, false, voxels).map_err(|e| e.to_string())?;
    Ok((svo, lo))
}

/// World-space (Y-up) integer cells of an imported object, for tests and `info`-style listings.
#[cfg(test)]
pub(crate) fn world_cells(object: &Object) -> Vec<([i64; 3], Voxel)> {
    let ObjectKind::Voxels(v) = &object.kind else {
        return Vec::new();
    };
    let base = object.transform.translation + v.origin;
    let base = [base.x, base.y, base.z].map(|c| c.round() as i64);
    v.svo
        .leaves()
        .into_iter()
        .map(|(c, vox)| {
            (
                [
                    base[0] + i64::from(c.x),
                    base[1] + i64::from(c.y),
                    base[2] + i64::from(c.z),
                ],
                vox,
            )
        })
        .collect()
}
