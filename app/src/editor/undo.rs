//! Undo/redo as reversible edits (Fyrox-style): applying an [`Edit`] returns the edit that
//! reverts it, so a step stores only what it changed — a deleted object's payload, an old
//! transform — never a snapshot of the whole document with its octrees.

use glam::UVec3;
use thicket_core::krs::KrsObject;
use thicket_core::krs::TreeParams;
use thicket_core::quality::Quality;
use thicket_core::scene::{
    Document, EnhancementLink, Light, Object, ObjectKind, Transform, TreeBuilderLink, VoxelModel,
};
use thicket_core::skin::{AnimationClip, JointOverride, StretchSettings};
use thicket_core::svo::UndoDelta;

/// One reversible change to the document.
#[derive(Debug, Clone, PartialEq)]
pub enum Edit {
    /// Insert an object at an outliner position.
    Insert {
        /// Position in `Document::objects`.
        index: usize,
        /// The object.
        object: Box<Object>,
    },
    /// Remove the object at an outliner position.
    Remove {
        /// Position in `Document::objects`.
        index: usize,
    },
    /// Rename an object.
    Rename {
        /// Object id.
        id: u64,
        /// New name.
        name: String,
    },
    /// Show or hide an object.
    SetVisible {
        /// Object id.
        id: u64,
        /// New visibility.
        visible: bool,
    },
    /// Move, rotate or scale an object.
    SetTransform {
        /// Object id.
        id: u64,
        /// New transform.
        transform: Transform,
    },
    /// Change a light.
    SetLight {
        /// Light index.
        index: usize,
        /// New value.
        light: Light,
    },
    /// Insert a light at a position in the light list.
    InsertLight {
        /// Position in `Document::lights`.
        index: usize,
        /// The light.
        light: Light,
    },
    /// Remove the light at a position in the light list.
    RemoveLight {
        /// Position in `Document::lights`.
        index: usize,
    },
    /// Change the quality knobs.
    SetQuality(Box<Quality>),
    /// Set voxels of a voxel object to stored values (a sculpt stroke's undo: only the
    /// voxels the stroke touched, with their values before it).
    Voxels {
        /// Object id.
        id: u64,
        /// `(coordinate, value)` pairs to write, in order.
        delta: UndoDelta,
        /// The frame of a frame sequence the voxels belong to (0 for a still model): applying
        /// the edit shows that frame first, so an undo after the playhead moved writes the
        /// frame it was made on.
        frame: usize,
    },
    /// Replace the manual pose overrides of a rigged voxel model.
    SetPose {
        /// Object id.
        id: u64,
        /// The new overrides (the rig's whole list).
        overrides: Vec<JointOverride>,
    },
    /// Replace the stretch settings of a rigged voxel model.
    SetStretch {
        /// Object id.
        id: u64,
        /// The new settings.
        stretch: StretchSettings,
    },
    /// Replace the parameters of a KRS object (kernels, mirrors, placement, distortion).
    SetKrs {
        /// Object id.
        id: u64,
        /// The new parameters.
        krs: Box<KrsObject>,
    },
    /// Set, replace or remove (`None`) the detail-enhancement link of voxel model `source`.
    SetEnhancement {
        /// Id of the coarse model.
        source: u64,
        /// The new link.
        link: Option<Box<EnhancementLink>>,
    },
    /// Replace a voxel object's whole model (a re-enhancement with new settings).
    SetVoxelModel {
        /// Object id.
        id: u64,
        /// The new model.
        model: Box<VoxelModel>,
    },
    /// Replace a voxel model's palette.
    SetPalette {
        /// Object id.
        id: u64,
        /// The new palette.
        palette: Vec<[u8; 4]>,
    },
    /// Set or remove (`None`) the tree-builder parameters stored for KRS object `id`.
    SetTreeParams {
        /// Object id.
        id: u64,
        /// The new parameters.
        params: Option<Box<TreeParams>>,
    },
    /// Replace the document's forest links (a grown, regrown or removed forest).
    SetForests {
        /// The new links.
        forests: Vec<thicket_core::scene::ForestLink>,
    },
    /// Write per-voxel stretch override codes of a rigged model (a stretch-paint stroke's
    /// undo: only the voxels it touched, with their codes before it; 0 removes an override).
    StretchOverrides {
        /// Object id.
        id: u64,
        /// `(voxel, code)` pairs to write, in order.
        entries: Vec<(UVec3, u8)>,
    },
    /// Set a rigged model's playback (only as part of an edit that renumbers its clips: a
    /// deleted clip; scrubbing is not an edit).
    SetPlayback {
        /// Object id.
        id: u64,
        /// The new playback.
        playback: thicket_core::skin::Playback,
    },
    /// Set or remove (`None`) a voxel model's rig (a skeleton edit that keeps the weights).
    SetRig {
        /// Object id.
        id: u64,
        /// The new rig.
        rig: Option<Box<thicket_core::skin::Rig>>,
    },
    /// Replace the animation clips of a rigged model (a key set or deleted, a clip added).
    SetClips {
        /// Object id.
        id: u64,
        /// The new clips.
        clips: Vec<AnimationClip>,
    },
    /// Set or remove (`None`) an object's keyed transforms (a key set or deleted).
    SetMotion {
        /// Object id.
        id: u64,
        /// The new motion.
        motion: Option<Box<thicket_core::scene::ObjectMotion>>,
    },
    /// Several edits as one step (applied in order, reverted in reverse order).
    Group(Vec<Edit>),
}

impl Edit {
    /// Applies the edit and returns its inverse. The editor validates edits before they get
    /// here; an edit naming an object that no longer exists does nothing (and its inverse does
    /// nothing either).
    pub fn apply(self, doc: &mut Document) -> Edit {
        let find = |doc: &mut Document, id: u64| doc.objects.iter().position(|o| o.id == id);
        match self {
            Edit::Insert { index, object } => {
                let index = index.min(doc.objects.len());
                doc.objects.insert(index, *object);
                Edit::Remove { index }
            }
            Edit::Remove { index } => {
                if index < doc.objects.len() {
                    let object = Box::new(doc.objects.remove(index));
                    Edit::Insert { index, object }
                } else {
                    Edit::Group(Vec::new())
                }
            }
            Edit::Rename { id, name } => match find(doc, id) {
                Some(i) => Edit::Rename {
                    id,
                    name: std::mem::replace(&mut doc.objects[i].name, name),
                },
                None => Edit::Group(Vec::new()),
            },
            Edit::SetVisible { id, visible } => match find(doc, id) {
                Some(i) => Edit::SetVisible {
                    id,
                    visible: std::mem::replace(&mut doc.objects[i].visible, visible),
                },
                None => Edit::Group(Vec::new()),
            },
            Edit::SetTransform { id, transform } => match find(doc, id) {
                Some(i) => Edit::SetTransform {
                    id,
                    transform: std::mem::replace(&mut doc.objects[i].transform, transform),
                },
                None => Edit::Group(Vec::new()),
            },
            Edit::SetLight { index, light } => match doc.lights.get_mut(index) {
                Some(slot) => Edit::SetLight {
                    index,
                    light: std::mem::replace(slot, light),
                },
                None => Edit::Group(Vec::new()),
            },
            Edit::InsertLight { index, light } => {
                let index = index.min(doc.lights.len());
                doc.lights.insert(index, light);
                Edit::RemoveLight { index }
            }
            Edit::RemoveLight { index } => {
                if index < doc.lights.len() {
                    let light = doc.lights.remove(index);
                    Edit::InsertLight { index, light }
                } else {
                    Edit::Group(Vec::new())
                }
            }
            Edit::SetQuality(q) => {
                Edit::SetQuality(Box::new(std::mem::replace(&mut doc.quality, *q)))
            }
            Edit::Voxels { id, delta, frame } => match find(doc, id) {
                Some(i) => match &mut doc.objects[i].kind {
                    ObjectKind::Voxels(v) => {
                        if v.show_frame(frame)
                            && let Some(seq) = v.frames.as_mut()
                        {
                            seq.time_secs = frame as f32 * seq.frame_secs;
                        }
                        Edit::Voxels {
                            id,
                            delta: v.svo.apply_delta(&delta),
                            frame,
                        }
                    }
                    ObjectKind::Mesh(_) | ObjectKind::Krs(_) => Edit::Group(Vec::new()),
                },
                None => Edit::Group(Vec::new()),
            },
            Edit::SetPose { id, overrides } => match rig_of(doc, id) {
                Some(rig) => Edit::SetPose {
                    id,
                    overrides: std::mem::replace(&mut rig.pose_overrides, overrides),
                },
                None => Edit::Group(Vec::new()),
            },
            Edit::SetStretch { id, stretch } => match rig_of(doc, id) {
                Some(rig) => Edit::SetStretch {
                    id,
                    stretch: std::mem::replace(&mut rig.stretch, stretch),
                },
                None => Edit::Group(Vec::new()),
            },
            Edit::SetKrs { id, krs } => match find(doc, id) {
                Some(i) => match &mut doc.objects[i].kind {
                    ObjectKind::Krs(k) => Edit::SetKrs {
                        id,
                        krs: Box::new(std::mem::replace(k, *krs)),
                    },
                    ObjectKind::Voxels(_) | ObjectKind::Mesh(_) => Edit::Group(Vec::new()),
                },
                None => Edit::Group(Vec::new()),
            },
            Edit::SetEnhancement { source, link } => {
                let old = doc
                    .enhancements
                    .iter()
                    .position(|l| l.source == source)
                    .map(|i| Box::new(doc.enhancements.remove(i)));
                if let Some(link) = link {
                    doc.enhancements.push(*link);
                }
                Edit::SetEnhancement { source, link: old }
            }
            Edit::SetVoxelModel { id, model } => match find(doc, id) {
                Some(i) => match &mut doc.objects[i].kind {
                    ObjectKind::Voxels(v) => Edit::SetVoxelModel {
                        id,
                        model: Box::new(std::mem::replace(v, *model)),
                    },
                    ObjectKind::Mesh(_) | ObjectKind::Krs(_) => Edit::Group(Vec::new()),
                },
                None => Edit::Group(Vec::new()),
            },
            Edit::SetPlayback { id, playback } => match rig_of(doc, id) {
                Some(rig) => {
                    let mut playback = playback;
                    // Never a clip that is not there (the clips of this edit's group come first).
                    if playback.clip.is_some_and(|c| c >= rig.clips.len()) {
                        playback.clip = None;
                    }
                    Edit::SetPlayback {
                        id,
                        playback: std::mem::replace(&mut rig.playback, playback),
                    }
                }
                None => Edit::Group(Vec::new()),
            },
            Edit::SetRig { id, rig } => match find(doc, id) {
                Some(i) => match &mut doc.objects[i].kind {
                    ObjectKind::Voxels(v) => Edit::SetRig {
                        id,
                        rig: std::mem::replace(&mut v.rig, rig.map(|r| *r)).map(Box::new),
                    },
                    ObjectKind::Mesh(_) | ObjectKind::Krs(_) => Edit::Group(Vec::new()),
                },
                None => Edit::Group(Vec::new()),
            },
            Edit::SetPalette { id, palette } => match find(doc, id) {
                Some(i) => match &mut doc.objects[i].kind {
                    ObjectKind::Voxels(v) => Edit::SetPalette {
                        id,
                        palette: std::mem::replace(&mut v.palette, palette),
                    },
                    ObjectKind::Mesh(_) | ObjectKind::Krs(_) => Edit::Group(Vec::new()),
                },
                None => Edit::Group(Vec::new()),
            },
            Edit::SetTreeParams { id, params } => {
                let old = doc
                    .tree_builders
                    .iter()
                    .position(|l| l.object == id)
                    .map(|i| Box::new(doc.tree_builders.remove(i).params));
                if let Some(params) = params {
                    doc.tree_builders.push(TreeBuilderLink {
                        object: id,
                        params: *params,
                    });
                }
                Edit::SetTreeParams { id, params: old }
            }
            Edit::SetForests { forests } => Edit::SetForests {
                forests: std::mem::replace(&mut doc.forests, forests),
            },
            Edit::StretchOverrides { id, entries } => match rig_of(doc, id) {
                Some(rig) => {
                    let mut old: Vec<(UVec3, u8)> = entries
                        .into_iter()
                        .map(|(p, code)| (p, rig.stretch_overrides.set(p, code)))
                        .collect();
                    // Reverting in reverse order restores the first old value of a voxel
                    // written twice.
                    old.reverse();
                    Edit::StretchOverrides { id, entries: old }
                }
                None => Edit::Group(Vec::new()),
            },
            Edit::SetClips { id, clips } => match rig_of(doc, id) {
                Some(rig) => {
                    let old = std::mem::replace(&mut rig.clips, clips);
                    // Undoing an added clip must not leave the playhead on a missing clip.
                    if rig.playback.clip.is_some_and(|c| c >= rig.clips.len()) {
                        rig.playback.clip = None;
                    }
                    Edit::SetClips { id, clips: old }
                }
                None => Edit::Group(Vec::new()),
            },
            Edit::SetMotion { id, motion } => match find(doc, id) {
                Some(i) => Edit::SetMotion {
                    id,
                    motion: std::mem::replace(&mut doc.objects[i].motion, motion.map(|m| *m))
                        .map(Box::new),
                },
                None => Edit::Group(Vec::new()),
            },
            Edit::Group(edits) => {
                let mut inverses: Vec<Edit> = edits.into_iter().map(|e| e.apply(doc)).collect();
                inverses.reverse();
                Edit::Group(inverses)
            }
        }
    }
}

/// The rig of voxel object `id`, if it has one.
fn rig_of(doc: &mut Document, id: u64) -> Option<&mut thicket_core::skin::Rig> {
    match &mut doc.objects.iter_mut().find(|o| o.id == id)?.kind {
        ObjectKind::Voxels(v) => v.rig.as_mut(),
        ObjectKind::Mesh(_) | ObjectKind::Krs(_) => None,
    }
}

impl Edit {
    /// Approximate heap bytes the edit holds (for the memory bound of the history).
    #[must_use]
    pub fn heap_bytes(&self) -> usize {
        match self {
            Edit::Insert { object, .. } => match &object.kind {
                ObjectKind::Voxels(v) => v.svo.memory_stats().total_bytes as usize,
                ObjectKind::Mesh(m) => m.model.triangle_count() * 3 * 48,
                ObjectKind::Krs(k) => {
                    std::mem::size_of_val(k.kernels.as_slice())
                        + std::mem::size_of_val(k.mirrors.as_slice())
                        + std::mem::size_of_val(k.empty_zones.as_slice())
                }
            },
            Edit::Voxels { delta, .. } => delta.heap_bytes(),
            Edit::SetPose { overrides, .. } => std::mem::size_of_val(overrides.as_slice()) + 64,
            Edit::SetKrs { krs, .. } => {
                std::mem::size_of_val(krs.kernels.as_slice())
                    + std::mem::size_of_val(krs.mirrors.as_slice())
                    + std::mem::size_of_val(krs.empty_zones.as_slice())
                    + size_of::<KrsObject>()
            }
            Edit::Group(edits) => edits.iter().map(Edit::heap_bytes).sum(),
            Edit::SetQuality(_) => size_of::<Quality>(),
            Edit::SetVoxelModel { model, .. } => model.svo.memory_stats().total_bytes as usize,
            Edit::SetRig { rig, .. } => rig.as_ref().map_or(0, |r| {
                r.skeleton.len() * size_of::<thicket_core::skin::Joint>() + clips_bytes(&r.clips)
            }),
            Edit::StretchOverrides { entries, .. } => entries.capacity() * size_of::<(UVec3, u8)>(),
            Edit::SetClips { clips, .. } => clips_bytes(clips),
            Edit::SetMotion { motion, .. } => motion
                .as_ref()
                .map_or(0, |m| clips_bytes(std::slice::from_ref(&m.clip))),
            Edit::SetTreeParams { .. } => size_of::<TreeParams>() + 256,
            Edit::SetForests { forests } => {
                forests
                    .iter()
                    .map(|f| size_of_val(f) + 8 * (f.sources.len() + f.objects.len()))
                    .sum::<usize>()
                    + 64
            }
            _ => 64,
        }
    }
}

impl Edit {
    /// The voxel objects this edit writes voxels of, each with the inclusive box of the
    /// voxels it writes (a stroke's undo or redo): what a derived enhancement must recompute.
    #[must_use]
    pub fn voxel_boxes(&self) -> Vec<(u64, UVec3, UVec3)> {
        let mut out = Vec::new();
        self.collect_voxel_boxes(&mut out);
        out
    }

    fn collect_voxel_boxes(&self, out: &mut Vec<(u64, UVec3, UVec3)>) {
        match self {
            Edit::Voxels { id, delta, .. } => {
                let mut it = delta.entries.iter().map(|e| e.0);
                if let Some(first) = it.next() {
                    let (lo, hi) = it.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p)));
                    out.push((*id, lo, hi));
                }
            }
            Edit::Group(edits) => edits.iter().for_each(|e| e.collect_voxel_boxes(out)),
            _ => {}
        }
    }

    /// Whether the edit only writes voxels (a stroke): other edits may change what an
    /// enhancement is built from (its settings, the models, the links).
    #[must_use]
    pub fn only_voxels(&self) -> bool {
        match self {
            Edit::Voxels { .. } | Edit::StretchOverrides { .. } => true,
            Edit::Group(edits) => edits.iter().all(Edit::only_voxels),
            _ => false,
        }
    }
}

impl Edit {
    /// A name for the step this edit makes (Edit → History), from its kind alone; the editor
    /// names most steps better (with the object's name or the tool).
    #[must_use]
    pub fn kind_label(&self) -> &'static str {
        match self {
            Edit::Insert { .. } => "Add object",
            Edit::Remove { .. } => "Delete object",
            Edit::Rename { .. } => "Rename",
            Edit::SetVisible { .. } => "Show / hide",
            Edit::SetTransform { .. } => "Move object",
            Edit::SetLight { .. } => "Change light",
            Edit::InsertLight { .. } => "Add light",
            Edit::RemoveLight { .. } => "Delete light",
            Edit::SetQuality(_) => "Change quality",
            Edit::Voxels { .. } => "Voxel edit",
            Edit::SetPose { .. } => "Pose",
            Edit::SetStretch { .. } => "Stretch settings",
            Edit::SetKrs { .. } => "KRS parameters",
            Edit::SetEnhancement { .. } => "Detail enhancement",
            Edit::SetVoxelModel { .. } => "Replace voxel model",
            Edit::SetPalette { .. } => "Set palette",
            Edit::SetTreeParams { .. } => "Tree builder",
            Edit::SetForests { .. } => "Forest",
            Edit::StretchOverrides { .. } => "Stretch paint",
            Edit::SetPlayback { .. } => "Playback",
            Edit::SetRig { .. } => "Skeleton",
            Edit::SetClips { .. } => "Animation clips",
            Edit::SetMotion { .. } => "Transform keys",
            Edit::Group(edits) => main_edit(edits.iter()).map_or("Edit", Edit::kind_label),
        }
    }

    /// [`Edit::kind_label`] of the edit this one undoes (what [`History::push`] records when
    /// the caller gives no name).
    #[must_use]
    pub fn undo_label(&self) -> &'static str {
        match self {
            Edit::Insert { .. } => "Delete object",
            Edit::Remove { .. } => "Add object",
            Edit::InsertLight { .. } => "Delete light",
            Edit::RemoveLight { .. } => "Add light",
            // An inverse group holds the inverses in reverse order.
            Edit::Group(edits) => main_edit(edits.iter().rev()).map_or("Edit", Edit::undo_label),
            other => other.kind_label(),
        }
    }
}

/// Whether `newer` (a revert pushed under the open step's merge key) merges into the open
/// step's revert `older`. Deltas (voxels, stretch overrides) restore only what their own dab
/// changed, so they merge only into a delta of the same model (and frame): the merged step
/// then holds both. Every other edit restores a whole value, and the older revert already
/// restores the value from before the drag, so the newer one merges by being dropped.
fn merges_into(newer: &Edit, older: &Edit) -> bool {
    match (newer, older) {
        (
            Edit::Voxels { id, frame, .. },
            Edit::Voxels {
                id: older_id,
                frame: older_frame,
                ..
            },
        ) => id == older_id && frame == older_frame,
        (Edit::StretchOverrides { id, .. }, Edit::StretchOverrides { id: older_id, .. }) => {
            id == older_id
        }
        (Edit::Voxels { .. } | Edit::StretchOverrides { .. }, _) => false,
        _ => true,
    }
}

/// The edit a group is named after: its first one that is not a side effect (visibility,
/// the playhead).
pub(crate) fn main_edit<'a>(mut edits: impl Iterator<Item = &'a Edit>) -> Option<&'a Edit> {
    edits.find(|e| !matches!(e, Edit::SetVisible { .. } | Edit::SetPlayback { .. }))
}

/// About the heap bytes of animation clips (key times, values, per-channel overhead).
fn clips_bytes(clips: &[AnimationClip]) -> usize {
    clips
        .iter()
        .flat_map(|c| &c.channels)
        .map(|c| c.times.len() * 4 + c.values.len() * 16 + 64)
        .sum()
}

/// Which continuous edits merge into one step while an interaction lasts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MergeKey {
    /// An object's transform.
    Transform(u64),
    /// A light.
    Light(usize),
    /// The quality knobs.
    Quality,
    /// A sculpt stroke on an object: its dabs' undo deltas are concatenated.
    Stroke(u64),
    /// A joint drag (gizmo or inspector) on a rigged object.
    Pose(u64),
    /// A stretch-setting drag on a rigged object.
    Stretch(u64),
    /// A KRS parameter drag on an object.
    Krs(u64),
    /// A stretch-paint stroke on a rigged object: its dabs' old codes are concatenated.
    StretchPaint(u64),
    /// A rest-pose joint drag on a voxel model's skeleton.
    Rig(u64),
    /// A Grow forest slider drag (the forest's first tree).
    Forest(u64),
}

#[derive(Debug)]
struct Step {
    /// What the step did, for Edit → History ("Brush stroke", "Delete Tree").
    label: String,
    /// The edit that leaves state `from` for state `to`.
    revert: Edit,
    /// The state the step applies to.
    from: u64,
    /// The state applying it restores.
    to: u64,
}

/// Undo and redo stacks of inverse edits, bounded in length and in memory; always keeps the
/// latest step.
#[derive(Debug)]
pub struct History {
    undo: Vec<Step>,
    redo: Vec<Step>,
    /// Open merge group: a following edit with this key joins the top step.
    open: Option<MergeKey>,
    /// Identifies the document state; a new edit gets a fresh id, undo/redo restore old ones.
    state: u64,
    next_state: u64,
    saved_state: u64,
    /// Most steps kept.
    pub capacity: usize,
    /// Most bytes the undo steps may hold (the oldest go first; the latest always stays).
    pub max_bytes: usize,
}

/// Default memory bound of the undo history.
pub const DEFAULT_UNDO_BYTES: usize = 512 << 20;

impl Default for History {
    fn default() -> Self {
        Self {
            undo: Vec::new(),
            redo: Vec::new(),
            open: None,
            state: 0,
            next_state: 1,
            saved_state: 0,
            capacity: 200,
            max_bytes: DEFAULT_UNDO_BYTES,
        }
    }
}

impl History {
    /// Records an applied edit by its inverse. With a merge key equal to the open group's, the
    /// step joins the previous one (the first inverse is kept: it restores the state before the
    /// whole drag).
    pub fn push(&mut self, revert: Edit, merge: Option<MergeKey>) {
        let label = revert.undo_label().to_owned();
        self.push_named(revert, merge, label);
    }

    /// [`History::push`] with the step's name for Edit → History (a merged step keeps the
    /// name of its first edit). A voxel or stretch-override delta of another model or frame
    /// than the open step's starts a new step instead: its old values are kept, not dropped.
    pub fn push_named(&mut self, revert: Edit, merge: Option<MergeKey>, label: String) {
        self.redo.clear();
        let new_state = self.next_state;
        self.next_state += 1;
        match (merge, self.open, self.undo.last_mut()) {
            (Some(key), Some(open), Some(top))
                if key == open && merges_into(&revert, &top.revert) =>
            {
                // Voxel deltas only restore what their own dab changed, so a stroke keeps all
                // of them: the later dab's old values go first, so undo ends at the values
                // from before the whole stroke.
                match (revert, &mut top.revert) {
                    (
                        Edit::Voxels {
                            id,
                            delta: newer,
                            frame,
                        },
                        Edit::Voxels {
                            id: top_id,
                            delta: older,
                            frame: top_frame,
                        },
                    ) if id == *top_id && frame == *top_frame => {
                        let mut entries = newer.entries;
                        entries.append(&mut older.entries);
                        older.entries = entries;
                    }
                    (
                        Edit::StretchOverrides { id, entries: newer },
                        Edit::StretchOverrides {
                            id: top_id,
                            entries: older,
                        },
                    ) if id == *top_id => {
                        // Same rule: the later dab's old codes go first.
                        let mut entries = newer;
                        entries.append(older);
                        *older = entries;
                    }
                    _ => {}
                }
                top.from = new_state;
            }
            _ => {
                self.undo.push(Step {
                    label,
                    revert,
                    from: new_state,
                    to: self.state,
                });
            }
        }
        self.enforce_bounds();
        self.state = new_state;
        self.open = merge;
    }

    /// Drops the oldest undo steps beyond the step and memory bounds (never the latest).
    fn enforce_bounds(&mut self) {
        if self.undo.len() > self.capacity.max(1) {
            let excess = self.undo.len() - self.capacity.max(1);
            self.undo.drain(..excess);
        }
        let mut total: usize = self.undo.iter().map(|s| s.revert.heap_bytes()).sum();
        let mut drop = 0;
        while total > self.max_bytes && drop + 1 < self.undo.len() {
            total -= self.undo[drop].revert.heap_bytes();
            drop += 1;
        }
        self.undo.drain(..drop);
    }

    /// Joins the last `n` undo steps into one named `label` (a command made of several edits,
    /// one step for the user). Nothing happens with fewer than `n` steps.
    pub fn join_top(&mut self, n: usize, label: String) {
        if n < 2 || self.undo.len() < n {
            return;
        }
        let steps: Vec<Step> = self.undo.drain(self.undo.len() - n..).collect();
        let (from, to) = (steps[n - 1].from, steps[0].to);
        // Undo reverts the newest edit first.
        let revert = Edit::Group(steps.into_iter().rev().map(|s| s.revert).collect());
        self.undo.push(Step {
            label,
            revert,
            from,
            to,
        });
        self.open = None;
    }

    /// Bytes the undo steps hold.
    #[must_use]
    pub fn undo_bytes(&self) -> usize {
        self.undo.iter().map(|s| s.revert.heap_bytes()).sum()
    }

    /// Closes the open merge group.
    pub fn seal(&mut self) {
        self.open = None;
    }

    /// Reverts the top step.
    pub fn undo(&mut self, doc: &mut Document) -> bool {
        self.open = None;
        let Some(step) = self.undo.pop() else {
            return false;
        };
        let forward = step.revert.apply(doc);
        self.state = step.to;
        self.redo.push(Step {
            label: step.label,
            revert: forward,
            from: step.to,
            to: step.from,
        });
        true
    }

    /// Re-applies the last undone step.
    pub fn redo(&mut self, doc: &mut Document) -> bool {
        self.open = None;
        let Some(step) = self.redo.pop() else {
            return false;
        };
        let backward = step.revert.apply(doc);
        self.state = step.to;
        self.undo.push(Step {
            label: step.label,
            revert: backward,
            from: step.to,
            to: step.from,
        });
        true
    }

    /// The edit undo would apply next.
    #[must_use]
    pub fn next_undo(&self) -> Option<&Edit> {
        self.undo.last().map(|s| &s.revert)
    }

    /// The edit redo would apply next.
    #[must_use]
    pub fn next_redo(&self) -> Option<&Edit> {
        self.redo.last().map(|s| &s.revert)
    }

    /// Steps that can be undone.
    #[must_use]
    pub fn undo_len(&self) -> usize {
        self.undo.len()
    }

    /// Steps that can be redone.
    #[must_use]
    pub fn redo_len(&self) -> usize {
        self.redo.len()
    }

    /// The names of the steps, oldest first, and how many of them are done (the rest can be
    /// redone): the list of Edit → History.
    #[must_use]
    pub fn labels(&self) -> (Vec<&str>, usize) {
        let names = self
            .undo
            .iter()
            .chain(self.redo.iter().rev())
            .map(|s| s.label.as_str())
            .collect();
        (names, self.undo.len())
    }

    /// Identifies the document's content: equal ids mean equal documents (edits get fresh ids;
    /// undo and redo return to earlier ones). Caches key on it.
    #[must_use]
    pub fn state_id(&self) -> u64 {
        self.state
    }

    /// Marks the current state as the saved one.
    pub fn mark_saved(&mut self) {
        self.saved_state = self.state;
    }

    /// Marks the document as differing from every saved state.
    pub fn mark_unsaved(&mut self) {
        self.saved_state = u64::MAX;
    }

    /// Whether the document differs from the saved state.
    #[must_use]
    pub fn is_dirty(&self) -> bool {
        self.state != self.saved_state
    }
}
