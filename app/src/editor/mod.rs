//! Editor state without any UI: the open document, its file, the selection, undo/redo and the
//! commands the panels call. Everything here runs headless, so tests drive the editor through
//! the same commands as the buttons.

pub mod autosave;
mod changes;
mod dope;
mod enhance;
mod forest;
pub mod jobs;
mod krs;
mod motion;
mod pick;
mod pose;
mod pose_keys;
mod rig;
mod sculpt;
mod stretch;
mod undo;
mod voxel_tools;

use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

use thicket_core::quality::{Quality, QualityPreset};
use thicket_core::scene::{Document, Light, Object, ObjectKind, Transform};

pub use changes::{
    Change, ChangeCursor, ChangeEntry, ChangeFeed, ChangesRead, Redo, RegionChain, VoxelRegion,
};
pub use dope::KeyClipboard;
pub use enhance::{EnhanceUpdate, PreparedDocument};
pub use forest::ForestReport;
pub use pick::{Landing, PickKind, SurfacePick};
pub use pose::{JointFrames, joint_frames_in};
pub use pose_keys::{KEY_EPSILON_SECS, MIN_JOINT_SCALE};
pub use rig::{SkeletonTemplate, WeightsOnEdit, bind_job};
pub use sculpt::{VoxelPick, ray_through};
pub use stretch::MAX_STRETCH_OVERRIDE;
pub use undo::{DEFAULT_UNDO_BYTES, Edit, History, MergeKey};
pub use voxel_tools::{
    ClipboardEntry, Floating, MAX_EXTENT, MAX_INITIAL_VOXELS, ModelOp, NewModelSpec, SelectMode,
    ToolOutcome, VoxelSelectionState,
};

/// What the inspector shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Selection {
    /// An object, by id.
    Object(u64),
    /// A light, by index.
    Light(usize),
}

/// How many recent files the File menu keeps.
pub const MAX_RECENT: usize = 10;

/// Why a command was refused. The message is shown to the user as it is.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CommandError {
    /// The object id is not in the document (deleted meanwhile).
    #[error("no object with id {0}")]
    NoObject(u64),
    /// The light index is not in the document.
    #[error("no light number {0}")]
    NoLight(usize),
    /// A value the renderer must not see.
    #[error("{0}")]
    Invalid(String),
}

/// A voxel tool's refusal, shown as it reads.
impl From<thicket_core::sculpt::ToolError> for CommandError {
    fn from(e: thicket_core::sculpt::ToolError) -> Self {
        Self::Invalid(e.to_string())
    }
}

/// The editor's document state.
#[derive(Debug)]
pub struct Editor {
    doc: Document,
    path: Option<PathBuf>,
    /// Width / height of the view, which framing fits (the view sets it every frame).
    pub view_aspect: f32,
    /// The selected object or light, if any.
    pub selection: Option<Selection>,
    history: History,
    /// Files opened or saved, most recent first.
    pub recent: Vec<PathBuf>,
    /// Every change of what a renderer draws (edits, undo, camera, playheads), typed, for the
    /// consumers that redo work after one (see [`ChangeFeed`]).
    changes: ChangeFeed,
    /// Increases whenever the whole document is replaced (New, Open), and whenever content
    /// changes outside the history (a linked enhancement's stale fine model rebuilt): history
    /// state ids may repeat across generations.
    generation: u64,
    /// Increases whenever a rig's playback (clip, time) changes: not an edit, but drawn.
    anim_revision: u64,
    /// Live enhancers of the linked models (derived state, rebuilt when missing).
    enhancers: enhance::Enhancers,
    /// Why the last incremental re-enhancement failed, if it did.
    pub enhance_error: Option<String>,
    /// Selected voxels of one model (editor state, not undone).
    voxel_selection: Option<VoxelSelectionState>,
    /// Copied voxels (kept across New and Open, like a desktop clipboard).
    clipboard: Option<ClipboardEntry>,
    /// A paste being placed.
    floating: Option<Floating>,
    /// The undo depth before [`Editor::lift_selection`] took the floating voxels out of their
    /// model (a drag-to-move in progress).
    lifted: Option<usize>,
}

/// A box of voxels an edit wrote: object id and inclusive voxel bounds.
type VoxelBox = (u64, glam::UVec3, glam::UVec3);

/// What an undo or redo is about to apply: whether it only writes voxels, the boxes it
/// writes and what it changes.
struct HistoryStep {
    only_voxels: bool,
    boxes: Vec<VoxelBox>,
    change: Change,
}

impl HistoryStep {
    fn of(edit: &Edit) -> Self {
        Self {
            only_voxels: edit.only_voxels(),
            boxes: edit.voxel_boxes(),
            change: Change::of(edit),
        }
    }
}

impl Default for Editor {
    fn default() -> Self {
        Self::new(Document::default(), None)
    }
}

impl Editor {
    /// An editor on `doc`, read from `path` if it came from a file.
    #[must_use]
    pub fn new(doc: Document, path: Option<PathBuf>) -> Self {
        let selection = doc.objects.first().map(|o| Selection::Object(o.id));
        Self {
            doc,
            path,
            view_aspect: 1.0,
            selection,
            history: History::default(),
            recent: Vec::new(),
            changes: ChangeFeed::default(),
            generation: 0,
            anim_revision: 0,
            enhancers: enhance::Enhancers::default(),
            enhance_error: None,
            voxel_selection: None,
            clipboard: None,
            floating: None,
            lifted: None,
        }
    }

    /// The document (read-only: every change goes through a command so it can be undone).
    #[must_use]
    pub fn doc(&self) -> &Document {
        &self.doc
    }

    /// The file the document was read from or last saved to.
    #[must_use]
    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    /// A title for the window: file name and a `*` when there are unsaved changes.
    #[must_use]
    pub fn title(&self) -> String {
        let name = self.path.as_deref().and_then(Path::file_name).map_or_else(
            || "untitled".to_owned(),
            |n| n.to_string_lossy().into_owned(),
        );
        let star = if self.is_dirty() { " *" } else { "" };
        format!("{name}{star} — Thicket")
    }

    /// Whether there are edits since the last save or load.
    #[must_use]
    pub fn is_dirty(&self) -> bool {
        self.history.is_dirty()
    }

    /// Changes whenever what a renderer would draw changes.
    #[must_use]
    pub fn revision(&self) -> u64 {
        self.changes.len()
    }

    /// Every change of what a renderer draws, for consumers to read with their own cursor.
    #[must_use]
    pub fn changes(&self) -> &ChangeFeed {
        &self.changes
    }

    /// Changes whenever the whole document is replaced (New / Open) or its content changes
    /// outside the undo history.
    #[must_use]
    pub fn generation(&self) -> u64 {
        self.generation
    }

    /// Identifies the document's content within one generation (see [`History::state_id`]).
    #[must_use]
    pub fn content_key(&self) -> (u64, u64) {
        (self.generation, self.history.state_id())
    }

    /// Records that the document went from content key `from` to the current one by
    /// `change`.
    fn record(&mut self, from: (u64, u64), change: Change) {
        let to = self.content_key();
        self.changes.push(from, to, change);
    }

    /// The undo history.
    #[must_use]
    pub fn history(&self) -> &History {
        &self.history
    }

    /// Replaces the document (New / Open); the history starts afresh.
    pub fn replace_document(&mut self, doc: Document, path: Option<PathBuf>) {
        let before = self.content_key();
        *self = Self {
            recent: std::mem::take(&mut self.recent),
            clipboard: self.clipboard.take(),
            changes: std::mem::take(&mut self.changes),
            generation: self.generation + 1,
            anim_revision: self.anim_revision + 1,
            ..Self::new(doc, path)
        };
        self.record(before, Change::Content);
        if let Some(p) = self.path.clone() {
            self.push_recent(p);
        }
    }

    /// Records that the document was saved to `path`.
    pub fn mark_saved(&mut self, path: PathBuf) {
        self.history.mark_saved();
        self.path = Some(path.clone());
        self.push_recent(path);
    }

    /// Marks the document as changed since its file (a recovered document is unsaved work).
    pub fn mark_modified(&mut self) {
        self.history.mark_unsaved();
    }

    /// Puts `path` at the top of the recent-files list, made absolute: the list is kept between
    /// runs, and a relative path would name another file (or none) from another working folder.
    pub fn push_recent(&mut self, path: PathBuf) {
        let path = std::path::absolute(&path).unwrap_or(path);
        self.recent.retain(|p| p != &path);
        self.recent.insert(0, path);
        self.recent.truncate(MAX_RECENT);
    }

    /// Takes `path` off the recent-files list (File → Recent offers it for a missing file).
    pub fn remove_recent(&mut self, path: &Path) {
        self.recent.retain(|p| p != path);
    }

    /// The selected object, if any.
    #[must_use]
    pub fn selected_object(&self) -> Option<&Object> {
        match self.selection? {
            Selection::Object(id) => self.object(id),
            Selection::Light(_) => None,
        }
    }

    /// An object by id.
    #[must_use]
    pub fn object(&self, id: u64) -> Option<&Object> {
        self.doc.objects.iter().find(|o| o.id == id)
    }

    fn index_of(&self, id: u64) -> Result<usize, CommandError> {
        self.doc
            .objects
            .iter()
            .position(|o| o.id == id)
            .ok_or(CommandError::NoObject(id))
    }

    fn apply(&mut self, edit: Edit, merge: Option<MergeKey>) {
        let label = self.step_label(&edit);
        self.apply_named(edit, merge, label);
    }

    /// [`Editor::apply`] under a name for Edit → History.
    fn apply_named(&mut self, edit: Edit, merge: Option<MergeKey>, label: String) {
        let (before, change) = (self.content_key(), Change::of(&edit));
        let inverse = edit.apply(&mut self.doc);
        self.history.push_named(inverse, merge, label);
        self.record(before, change);
        self.fix_selection();
    }

    /// A name for the step `edit` makes, read before it is applied (with the object's name).
    fn step_label(&self, edit: &Edit) -> String {
        let name = |id: u64| self.object(id).map_or("an object", |o| o.name.as_str());
        match edit {
            Edit::Insert { object, .. } => format!("Add {}", object.name),
            Edit::Remove { index } => match self.doc.objects.get(*index) {
                Some(o) => format!("Delete {}", o.name),
                None => edit.kind_label().to_owned(),
            },
            Edit::Rename { id, name: to } => format!("Rename {} to {to}", name(*id)),
            Edit::SetVisible { id, visible } => {
                format!("{} {}", if *visible { "Show" } else { "Hide" }, name(*id))
            }
            Edit::SetTransform { id, .. } => format!("Move {}", name(*id)),
            // New weights come with a new binding record.
            Edit::SetVoxelModel { id, model } => {
                let old = match self.object(*id).map(|o| &o.kind) {
                    Some(ObjectKind::Voxels(v)) => v.rig.as_ref().and_then(|r| r.binding.as_ref()),
                    _ => None,
                };
                let new = model.rig.as_ref().and_then(|r| r.binding.as_ref());
                if new.is_some() && new != old {
                    "Bind weights".to_owned()
                } else {
                    edit.kind_label().to_owned()
                }
            }
            Edit::Group(edits) => undo::main_edit(edits.iter())
                .map_or_else(|| "Edit".to_owned(), |e| self.step_label(e)),
            _ => edit.kind_label().to_owned(),
        }
    }

    fn fix_selection(&mut self) {
        let valid = match self.selection {
            Some(Selection::Object(id)) => self.object(id).is_some(),
            Some(Selection::Light(i)) => i < self.doc.lights.len(),
            None => true,
        };
        if !valid {
            self.selection = None;
        }
        // Voxel selections and pastes of deleted models go with them.
        if self
            .voxel_selection
            .as_ref()
            .is_some_and(|s| self.object(s.object).is_none())
        {
            self.voxel_selection = None;
        }
        if self
            .floating
            .as_ref()
            .is_some_and(|f| self.object(f.object).is_none())
        {
            self.floating = None;
        }
        if self.floating.is_none() {
            self.lifted = None;
        }
    }

    /// Ends the current interaction (a slider drag): the next edit starts a new undo step.
    pub fn end_interaction(&mut self) {
        self.history.seal();
    }

    /// Undoes the last step; false when there is none. During a move of lifted voxels, undo
    /// cancels the move (the voxels go back where they were).
    pub fn undo(&mut self) -> bool {
        if self.lifted.is_some() {
            self.cancel_floating();
            return true;
        }
        let next = self.history.next_undo().map(HistoryStep::of);
        self.ensure_enhancers_for(next.as_ref());
        let before = self.content_key();
        let done = self.history.undo(&mut self.doc);
        if done {
            self.after_history_step(before, next);
        }
        done
    }

    /// Redoes the last undone step; false when there is none.
    pub fn redo(&mut self) -> bool {
        let next = self.history.next_redo().map(HistoryStep::of);
        self.ensure_enhancers_for(next.as_ref());
        let before = self.content_key();
        let done = self.history.redo(&mut self.doc);
        if done {
            self.after_history_step(before, next);
        }
        done
    }

    /// Undoes or redoes until `done` steps of the history are done (a click in Edit →
    /// History): the same as that many undos or redos one by one. Returns how many it took.
    pub fn go_to_step(&mut self, done: usize) -> usize {
        let mut steps = 0;
        while self.history.undo_len() > done && self.undo() {
            steps += 1;
        }
        while self.history.undo_len() < done && self.redo() {
            steps += 1;
        }
        steps
    }

    /// Before undo / redo writes voxels: the linked enhancements of those models are live
    /// (not for a frame sequence: the step first shows the frame it was made on, and its
    /// enhancer is built from that one afterwards).
    fn ensure_enhancers_for(&mut self, step: Option<&HistoryStep>) {
        if let Some(step) = step {
            for &(id, _, _) in &step.boxes {
                if !self.has_frames(id) {
                    self.ensure_enhancer(id);
                }
            }
        }
    }

    /// After undo / redo applied a step: records what it changed (the boxes it wrote, when it
    /// only wrote voxels of still models: a frame sequence's step first shows the frame it
    /// was made on); linked enhancements follow the voxels it wrote; any other edit may have
    /// changed links or models wholesale, so the live enhancers are rebuilt when next needed.
    fn after_history_step(&mut self, before: (u64, u64), step: Option<HistoryStep>) {
        self.fix_selection();
        let Some(HistoryStep {
            only_voxels,
            boxes,
            change,
        }) = step
        else {
            self.record(before, Change::Content);
            return;
        };
        if !only_voxels {
            self.drop_enhancers();
        }
        let regions = matches!(change, Change::Voxels { .. })
            && !boxes.is_empty()
            && boxes.iter().all(|&(id, ..)| !self.has_frames(id));
        let mut from = before;
        if !regions {
            self.record(from, change);
            from = self.content_key();
        }
        for (id, lo, hi) in boxes {
            if self.has_frames(id) {
                // Built from the frame shown before the step: the step may have shown another.
                self.drop_enhancer(id);
            }
            self.after_voxel_write(from, id, lo, hi, regions);
            from = self.content_key();
        }
    }

    /// Whether object `id` is a frame sequence.
    fn has_frames(&self, id: u64) -> bool {
        self.object(id)
            .is_some_and(|o| matches!(&o.kind, ObjectKind::Voxels(v) if v.frames.is_some()))
    }

    /// Adds an object at the end of the outliner and selects it; returns its id.
    pub fn add_object(&mut self, name: &str, kind: ObjectKind) -> u64 {
        let id = next_id(&self.doc);
        let object = Object {
            id,
            name: name.to_owned(),
            kind,
            ..Object::default()
        };
        let index = self.doc.objects.len();
        self.apply(
            Edit::Insert {
                index,
                object: Box::new(object),
            },
            None,
        );
        self.selection = Some(Selection::Object(id));
        id
    }

    /// Adds every object of another document (Import), keeping their names; returns the new ids.
    pub fn add_objects_from(&mut self, other: Document) -> Vec<u64> {
        let mut ids = Vec::new();
        for mut object in other.objects {
            object.id = next_id(&self.doc);
            ids.push(object.id);
            let index = self.doc.objects.len();
            self.apply(
                Edit::Insert {
                    index,
                    object: Box::new(object),
                },
                None,
            );
        }
        if let Some(&id) = ids.last() {
            self.selection = Some(Selection::Object(id));
        }
        ids
    }

    /// Adds every object of another document as an import an artist can see: the objects keep
    /// their layout among themselves, land on the scene's ground (its lowest point; y = 0 in an
    /// empty scene) beside what is already there on the camera's side (at the camera's target
    /// in an empty scene), are scaled uniformly to a quarter of the scene's size when the two
    /// differ by more than [`IMPORT_SIZE_RATIO`]× (see [`ImportPlacement::reset_scale`]), and
    /// the camera frames them. Returns the new ids and what was done.
    pub fn import_objects(&mut self, mut other: Document) -> ImportPlacement {
        let scene = self.doc.bounds();
        let camera = self.doc.camera;
        let mut placement = ImportPlacement {
            ids: Vec::new(),
            scale: 1.0,
            pivot: Vec3::ZERO,
        };
        if let Some((lo, hi)) = other.bounds() {
            let pivot = Vec3::new(0.5 * (lo.x + hi.x), lo.y, 0.5 * (lo.z + hi.z));
            let size = (hi - lo).length();
            let (scale, dest) = match scene {
                None => (1.0, Vec3::new(camera.target.x, 0.0, camera.target.z)),
                Some((slo, shi)) => {
                    let scene_size = (shi - slo).length();
                    let ratio = scene_size / size;
                    let scale = if size > 0.0
                        && ratio.is_finite()
                        && !(1.0 / IMPORT_SIZE_RATIO..=IMPORT_SIZE_RATIO).contains(&ratio)
                    {
                        IMPORT_FIT_FRACTION * ratio
                    } else {
                        1.0
                    };
                    (
                        scale,
                        beside_scene((slo, shi), scale * half_xz(lo, hi), camera.eye()),
                    )
                }
            };
            for o in &mut other.objects {
                o.transform = scaled_about(o.transform, pivot, dest, scale);
            }
            placement.scale = scale;
            placement.pivot = dest;
        }
        placement.ids = self.add_objects_from(other);
        let bounds = self
            .doc
            .objects
            .iter()
            .filter(|o| placement.ids.contains(&o.id))
            .filter_map(|o| o.world_bounds())
            .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)));
        if let Some((lo, hi)) = bounds {
            let mut camera = self.doc.camera;
            camera.frame_in(lo, hi, self.view_aspect);
            self.set_camera(camera);
        }
        placement
    }

    /// Renames an object. Empty names are refused (the outliner needs something to click).
    ///
    /// # Errors
    /// Unknown id or an empty name.
    pub fn rename(&mut self, id: u64, name: &str) -> Result<(), CommandError> {
        let name = name.trim();
        if name.is_empty() {
            return Err(CommandError::Invalid("a name cannot be empty".into()));
        }
        let index = self.index_of(id)?;
        if self.doc.objects[index].name == name {
            return Ok(());
        }
        self.apply(
            Edit::Rename {
                id,
                name: name.to_owned(),
            },
            None,
        );
        Ok(())
    }

    /// Shows or hides an object.
    ///
    /// # Errors
    /// Unknown id.
    pub fn set_visible(&mut self, id: u64, visible: bool) -> Result<(), CommandError> {
        let index = self.index_of(id)?;
        if self.doc.objects[index].visible != visible {
            self.apply(Edit::SetVisible { id, visible }, None);
        }
        Ok(())
    }

    /// Sets an object's transform after validating it. Consecutive calls during one interaction
    /// (a drag) merge into one undo step.
    ///
    /// # Errors
    /// Unknown id, or a non-finite value / zero scale (the document is left unchanged).
    pub fn set_transform(&mut self, id: u64, transform: Transform) -> Result<(), CommandError> {
        let index = self.index_of(id)?;
        let ctx = format!("object {:?}", self.doc.objects[index].name);
        transform
            .validate(&ctx)
            .map_err(|e| CommandError::Invalid(e.to_string()))?;
        if self.doc.objects[index].transform != transform {
            self.apply(
                Edit::SetTransform { id, transform },
                Some(MergeKey::Transform(id)),
            );
        }
        Ok(())
    }

    /// Deletes an object.
    ///
    /// # Errors
    /// Unknown id.
    pub fn delete(&mut self, id: u64) -> Result<(), CommandError> {
        let index = self.index_of(id)?;
        // Links and builder parameters naming the object go with it (and come back on undo).
        let mut edits: Vec<Edit> = self
            .doc
            .enhancements
            .iter()
            .filter(|l| l.source == id || l.target == id)
            .map(|l| Edit::SetEnhancement {
                source: l.source,
                link: None,
            })
            .collect();
        if self.doc.tree_params_of(id).is_some() {
            edits.push(Edit::SetTreeParams { id, params: None });
        }
        // A forest that loses a tree, a grown object or its terrain cannot be regrown: its
        // link goes (the grown objects stay as plain KRS objects).
        if let Some((i, _)) = self.doc.forest_of(id) {
            let mut forests = self.doc.forests.clone();
            forests.remove(i);
            edits.push(Edit::SetForests { forests });
        }
        if edits.is_empty() {
            self.apply(Edit::Remove { index }, None);
        } else {
            edits.push(Edit::Remove { index });
            self.apply(Edit::Group(edits), None);
        }
        Ok(())
    }

    /// Duplicates an object (placed right after it, named "NAME copy") and selects the copy.
    ///
    /// # Errors
    /// Unknown id.
    pub fn duplicate(&mut self, id: u64) -> Result<u64, CommandError> {
        let index = self.index_of(id)?;
        let mut copy = self.doc.objects[index].clone();
        copy.id = next_id(&self.doc);
        copy.name = format!("{} copy", copy.name);
        let new_id = copy.id;
        self.apply(
            Edit::Insert {
                index: index + 1,
                object: Box::new(copy),
            },
            None,
        );
        self.selection = Some(Selection::Object(new_id));
        Ok(new_id)
    }

    /// Sets a light after validating it; drags merge into one step.
    ///
    /// # Errors
    /// Unknown light, non-finite or zero direction, negative intensity.
    pub fn set_light(&mut self, index: usize, light: Light) -> Result<(), CommandError> {
        let current = self
            .doc
            .lights
            .get(index)
            .ok_or(CommandError::NoLight(index))?;
        validate_light(&light)?;
        if *current != light {
            self.apply(
                Edit::SetLight { index, light },
                Some(MergeKey::Light(index)),
            );
        }
        Ok(())
    }

    /// A light to add next: named "Light N" (a name not in use), a white fill light at half
    /// the default sun's intensity that casts shadows, coming from the default sun's direction
    /// turned 120 degrees about the vertical axis per light already in the scene, so each new
    /// light shows on a side the others do not light (a copy of the sun would only brighten
    /// the frame).
    #[must_use]
    pub fn new_light(&self) -> Light {
        let n = self.doc.lights.len();
        let name = (n + 1..)
            .map(|k| format!("Light {k}"))
            .find(|name| self.doc.lights.iter().all(|l| &l.name != name))
            .unwrap_or_else(|| "Light".to_owned());
        let sun = Light::default();
        let turn = glam::Quat::from_rotation_y(n as f32 * std::f32::consts::TAU / 3.0);
        Light {
            name,
            direction: turn * sun.direction,
            intensity: 0.5 * sun.intensity,
            ..sun
        }
    }

    /// Adds a light at the end of the light list (one undo step) after validating it, and
    /// selects it; returns its index.
    ///
    /// # Errors
    /// Non-finite or zero direction, negative intensity, or a scene that already has
    /// [`thicket_core::scene::MAX_LIGHTS`] lights (the document is left unchanged).
    pub fn add_light(&mut self, light: Light) -> Result<usize, CommandError> {
        validate_light(&light)?;
        if self.doc.lights.len() >= thicket_core::scene::MAX_LIGHTS {
            return Err(CommandError::Invalid(format!(
                "the scene already has {} lights, the most a document may have",
                thicket_core::scene::MAX_LIGHTS
            )));
        }
        let index = self.doc.lights.len();
        self.apply(Edit::InsertLight { index, light }, None);
        self.selection = Some(Selection::Light(index));
        Ok(index)
    }

    /// Adds an imported file's lights at the end of the light list (one undo step each),
    /// leaving the selection alone; lights that do not validate, and those past
    /// [`thicket_core::scene::MAX_LIGHTS`], are skipped. Returns how many were added.
    pub fn import_lights(&mut self, lights: Vec<Light>) -> usize {
        let mut added = 0;
        for light in lights {
            // Past the maximum the document would no longer validate: the rest are skipped.
            if self.doc.lights.len() >= thicket_core::scene::MAX_LIGHTS {
                break;
            }
            if validate_light(&light).is_ok() {
                let index = self.doc.lights.len();
                self.apply(Edit::InsertLight { index, light }, None);
                added += 1;
            }
        }
        added
    }

    /// Deletes a light (one undo step; undo puts it back at its place). Deleting the last
    /// light is allowed: the scene keeps its ambient light, both renderers draw a scene without
    /// lights, and an artist lighting a scene from scratch (or by ambient and baked lighting
    /// alone) expects Delete to work on every light; undo brings it back.
    ///
    /// # Errors
    /// Unknown light.
    pub fn delete_light(&mut self, index: usize) -> Result<(), CommandError> {
        if index >= self.doc.lights.len() {
            return Err(CommandError::NoLight(index));
        }
        // Light selections are indices: the lights after it move up by one.
        let selection = match self.selection {
            Some(Selection::Light(i)) if i == index => None,
            Some(Selection::Light(i)) if i > index => Some(Selection::Light(i - 1)),
            other => other,
        };
        self.apply(Edit::RemoveLight { index }, None);
        self.selection = selection;
        Ok(())
    }

    /// Sets the quality knobs after validating them; drags merge into one step.
    ///
    /// # Errors
    /// A knob out of range (the message names it).
    pub fn set_quality(&mut self, quality: Quality) -> Result<(), CommandError> {
        quality
            .validate()
            .map_err(|e| CommandError::Invalid(e.to_string()))?;
        if self.doc.quality != quality {
            self.apply(Edit::SetQuality(Box::new(quality)), Some(MergeKey::Quality));
        }
        Ok(())
    }

    /// Applies a draft / balanced / final preset (one undo step).
    pub fn apply_quality_preset(&mut self, preset: QualityPreset) {
        let quality = Quality::preset(preset);
        if self.doc.quality != quality {
            self.history.seal();
            self.apply(Edit::SetQuality(Box::new(quality)), None);
        }
    }

    /// Moves the view camera. The view is saved with the document but is not an undoable edit
    /// and does not mark the document as changed (orbiting is not editing).
    pub fn set_camera(&mut self, camera: thicket_core::scene::OrbitCamera) {
        if camera.validate().is_ok() && camera != self.doc.camera {
            self.doc.camera = camera;
            self.record(self.content_key(), Change::Camera);
        }
    }

    /// Frames the selected object (a voxel model with an editable volume: the volume), or
    /// everything when nothing (or a light) is selected.
    pub fn frame_selection(&mut self) {
        let selected = self.selected_object();
        let bounds = selected
            .and_then(|o| o.world_bounds().or_else(|| volume_bounds(o)))
            .or_else(|| self.doc.bounds());
        if let Some((lo, hi)) = bounds {
            let mut camera = self.doc.camera;
            // A KRS object's box is its bounding ball's: frame the ball itself (√3 closer).
            let krs = selected.is_some_and(|o| matches!(o.kind, ObjectKind::Krs(_)));
            if krs {
                camera.frame_sphere((lo + hi) * 0.5, (hi.x - lo.x) * 0.5, self.view_aspect);
            } else {
                camera.frame_in(lo, hi, self.view_aspect);
            }
            self.set_camera(camera);
        }
    }
}

/// An import whose size differs from the scene's by more than this factor is scaled to it.
pub const IMPORT_SIZE_RATIO: f32 = 10.0;
/// The fraction of the scene's size (bounds diagonal) an import out of scale is scaled to.
pub const IMPORT_FIT_FRACTION: f32 = 0.25;

/// How [`Editor::import_objects`] placed an import.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportPlacement {
    /// The new objects.
    pub ids: Vec<u64>,
    /// The uniform scale applied to fit the scene (1 when the sizes were within
    /// [`IMPORT_SIZE_RATIO`]× of each other).
    pub scale: f32,
    /// The point the objects were scaled about: their bottom centre where they landed.
    pub pivot: Vec3,
}

impl ImportPlacement {
    /// Undoes the fit-to-scene scale about the landing point (one undoable transform change
    /// per object still in the document; objects deleted since are left out).
    ///
    /// # Errors
    /// A transform the editor refuses (none for a placement it made).
    pub fn reset_scale(&self, editor: &mut Editor) -> Result<(), CommandError> {
        if self.scale == 1.0 {
            return Ok(());
        }
        let inv = 1.0 / self.scale;
        editor.end_interaction();
        for &id in &self.ids {
            let Some(o) = editor.doc().objects.iter().find(|o| o.id == id) else {
                continue;
            };
            let t = scaled_about(o.transform, self.pivot, self.pivot, inv);
            editor.set_transform(id, t)?;
        }
        editor.end_interaction();
        Ok(())
    }
}

/// Half the horizontal (x–z) diagonal of the box `lo..hi`: how far it reaches sideways from
/// its centre.
pub(crate) fn half_xz(lo: Vec3, hi: Vec3) -> f32 {
    0.5 * Vec2::new(hi.x - lo.x, hi.z - lo.z).length()
}

/// Where a new thing reaching `half_xz` sideways from its centre stands beside the scene's
/// bounds `scene`, on the eye's side with a small gap, so it is not on top of what is there:
/// the point under its centre, at the height of the scene's lowest point.
pub(crate) fn beside_scene(scene: (Vec3, Vec3), half_xz_new: f32, eye: Vec3) -> Vec3 {
    let (slo, shi) = scene;
    let centre = 0.5 * (slo + shi);
    let toward_eye = Vec3::new(eye.x - centre.x, 0.0, eye.z - centre.z)
        .try_normalize()
        .unwrap_or(Vec3::Z);
    let reach = half_xz(slo, shi) * 1.05 + half_xz_new;
    Vec3::new(centre.x, slo.y, centre.z) + toward_eye * reach
}

/// `t` scaled uniformly by `scale` about `from`, which moves to `to`: world points `p` become
/// `to + scale · (p − from)`.
fn scaled_about(mut t: Transform, from: Vec3, to: Vec3, scale: f32) -> Transform {
    t.translation = to + scale * (t.translation - from);
    t.scale *= scale;
    t
}

/// What [`Editor::set_light`] and [`Editor::add_light`] refuse: what `Document::validate`
/// refuses of a light, so a light the editor accepts renders.
fn validate_light(light: &Light) -> Result<(), CommandError> {
    light
        .validate()
        .map_err(|e| CommandError::Invalid(e.to_string()))
}

/// World bounds of a voxel model's editable volume (what an empty new model is framed by).
fn volume_bounds(o: &Object) -> Option<(glam::Vec3, glam::Vec3)> {
    let ObjectKind::Voxels(v) = &o.kind else {
        return None;
    };
    v.volume?;
    let m = o.transform.matrix() * v.object_from_voxel();
    let size = v.volume_size().as_vec3();
    let corners = (0..8).map(|i: u8| {
        m.transform_point3(glam::Vec3::new(
            if i & 1 == 0 { 0.0 } else { size.x },
            if i & 2 == 0 { 0.0 } else { size.y },
            if i & 4 == 0 { 0.0 } else { size.z },
        ))
    });
    let (lo, hi) = corners.fold(
        (
            glam::Vec3::splat(f32::INFINITY),
            glam::Vec3::splat(f32::NEG_INFINITY),
        ),
        |(lo, hi), p| (lo.min(p), hi.max(p)),
    );
    lo.is_finite().then_some((lo, hi))
}

/// A fresh object id: one past the largest in use.
pub(crate) fn next_id(doc: &Document) -> u64 {
    doc.objects.iter().map(|o| o.id).max().map_or(1, |m| m + 1)
}

#[cfg(test)]
mod rig_tests;
#[cfg(test)]
mod tests;
