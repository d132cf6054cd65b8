//! Voxel modelling commands: new models, the shape tools (voxel, box, line, extrude, fill), the
//! voxel selection with copy / paste and transforms, palettes and whole-model operations.
//!
//! Every command is one undo step that holds only the voxels it touched ([`Edit::Voxels`]);
//! the operations that change the volume itself (resize canvas) keep the old model instead.
//! The voxel selection, the clipboard and a floating paste are editor state, not document
//! state: like the object selection they are not undone, and every operation on them acts on
//! the voxels that are solid when it runs.

use glam::{IVec3, UVec3, Vec3};
use thicket_core::scene::{ObjectKind, Transform, VoxelModel};
use thicket_core::sculpt::model_ops::{self, Anchor, InitialFill};
use thicket_core::sculpt::palette;
use thicket_core::sculpt::select::{self, Clipboard, SelTransform, VoxelSelection};
use thicket_core::sculpt::shapes::{self, Ink, Mirror, ShapeOp, ToolEdit};
use thicket_core::svo::{MAX_DEPTH, Svo};

use super::{CommandError, Edit, Editor, MergeKey, Selection};

/// Most voxels a new model may start with (a solid box or slab is built in memory at once).
pub const MAX_INITIAL_VOXELS: u64 = 1 << 27;

/// The largest extent per axis of a voxel model: the octree's limit.
pub const MAX_EXTENT: u32 = 1 << MAX_DEPTH;

/// What File → New project and Edit → Add voxel model ask for.
#[derive(Debug, Clone, PartialEq)]
pub struct NewModelSpec {
    /// Object name.
    pub name: String,
    /// Extent in voxels per axis.
    pub size: UVec3,
    /// Edge of one voxel in metres (world units).
    pub voxel_size: f32,
    /// What the volume holds at first.
    pub fill: InitialFill,
    /// Colour of the initial fill (sRGB).
    pub color: [u8; 4],
}

impl Default for NewModelSpec {
    fn default() -> Self {
        Self {
            name: "Model".into(),
            size: UVec3::splat(32),
            voxel_size: 0.1,
            fill: InitialFill::Empty,
            color: [200, 200, 200, 255],
        }
    }
}

impl NewModelSpec {
    /// Checks the request before anything is allocated.
    ///
    /// # Errors
    /// An empty name, an extent of 0 or beyond the octree's limit (named), a voxel size that is
    /// not finite and positive, or an initial fill of more than [`MAX_INITIAL_VOXELS`].
    pub fn validate(&self) -> Result<(), CommandError> {
        if self.name.trim().is_empty() {
            return Err(CommandError::Invalid("a model needs a name".into()));
        }
        if self.size.min_element() == 0 || self.size.max_element() > MAX_EXTENT {
            return Err(CommandError::Invalid(format!(
                "extent {}×{}×{} voxels is out of range: each axis must be 1 to {MAX_EXTENT} \
                 (2^{MAX_DEPTH}, the octree's limit)",
                self.size.x, self.size.y, self.size.z
            )));
        }
        if !(self.voxel_size.is_finite() && self.voxel_size > 0.0) {
            return Err(CommandError::Invalid(format!(
                "voxel size {} m must be a positive number",
                self.voxel_size
            )));
        }
        let world = self.size.as_vec3() * self.voxel_size;
        if !world.is_finite() || world.max_element() > 1.0e7 {
            return Err(CommandError::Invalid(format!(
                "the model would be {} m across: keep it under 10,000 km (smaller voxels or \
                 extent)",
                world.max_element()
            )));
        }
        let filled = match self.fill {
            InitialFill::Empty => 0,
            InitialFill::GroundSlab { height } => {
                u64::from(self.size.x) * u64::from(height.min(self.size.y)) * u64::from(self.size.z)
            }
            InitialFill::SolidBox => {
                u64::from(self.size.x) * u64::from(self.size.y) * u64::from(self.size.z)
            }
        };
        if filled > MAX_INITIAL_VOXELS {
            return Err(CommandError::Invalid(format!(
                "the initial fill would be {filled} voxels, more than the {MAX_INITIAL_VOXELS} a \
                 new model may start with: start empty or with a thinner slab"
            )));
        }
        Ok(())
    }

    /// The model, its voxel (0,0,0) placed so the volume stands on the ground (y = 0) centred
    /// on `center_xz` (snapped to the voxel grid).
    ///
    /// # Errors
    /// See [`NewModelSpec::validate`].
    pub fn build(&self, center_xz: Vec3) -> Result<VoxelModel, CommandError> {
        self.validate()?;
        let ink = Ink {
            color: self.color,
            material: 0,
        };
        let svo = model_ops::new_model(self.size, self.fill, ink)?;
        let half = (self.size.as_vec3() * 0.5).floor() * self.voxel_size;
        let snap = |v: f32| (v / self.voxel_size).round() * self.voxel_size;
        let origin = Vec3::new(snap(center_xz.x) - half.x, 0.0, snap(center_xz.z) - half.z);
        Ok(VoxelModel {
            svo,
            voxel_size: self.voxel_size,
            origin,
            volume: Some(self.size),
            ..VoxelModel::default()
        })
    }
}

/// What a voxel command did, for the status bar.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ToolOutcome {
    /// Inclusive box of changed voxels.
    pub changed: Option<(UVec3, UVec3)>,
    /// Voxels written (including re-estimated normals).
    pub voxels: usize,
    /// Cells the tool asked for outside the model's volume (dropped).
    pub clipped: u64,
}

impl ToolOutcome {
    /// A line for the status bar: what changed and what was clipped.
    #[must_use]
    pub fn message(&self, what: &str) -> String {
        let mut s = if self.changed.is_some() {
            format!("{what}: {} voxels changed", self.voxels)
        } else {
            format!("{what}: nothing changed")
        };
        if self.clipped > 0 {
            s.push_str(&format!(
                " ({} cells outside the model's volume were clipped)",
                self.clipped
            ));
        }
        s
    }
}

/// The voxel selection of one model.
#[derive(Debug, Clone, PartialEq)]
pub struct VoxelSelectionState {
    /// The voxel model.
    pub object: u64,
    /// The selected cells.
    pub cells: VoxelSelection,
    /// Axis and doubled-coordinate pivot of the last quarter turn of these cells. Successive
    /// turns reuse it (a fresh pivot from the turned bounds could shift odd-by-even selections
    /// by a voxel each turn), so four turns give back the cells exactly; moves carry it along.
    pub turn_pivot: Option<(usize, IVec3)>,
}

/// How a new selection combines with the current one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SelectMode {
    /// Replace it.
    #[default]
    Replace,
    /// Add to it (Shift).
    Add,
    /// Remove from it (Ctrl).
    Subtract,
}

/// Copied voxels and the voxel size they were copied at.
#[derive(Debug, Clone, PartialEq)]
pub struct ClipboardEntry {
    /// The voxels, relative to the copied selection's minimum corner.
    pub clip: Clipboard,
    /// Where that corner was in the source model.
    pub origin: UVec3,
    /// Voxel edge of the source model (object units).
    pub voxel_size: f32,
}

/// A paste not yet written: moved with the arrow keys, committed with Enter.
#[derive(Debug, Clone, PartialEq)]
pub struct Floating {
    /// The voxel model it goes into.
    pub object: u64,
    /// Its voxels.
    pub clip: Clipboard,
    /// Where its minimum corner goes.
    pub at: IVec3,
}

/// A whole-model operation (Model menu).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ModelOp {
    /// Move every voxel by an offset (voxels leaving the volume wrap round when `wrap`).
    Shift {
        /// Voxels per axis.
        offset: IVec3,
        /// Wrap round instead of dropping.
        wrap: bool,
    },
    /// Mirror the whole model across the volume's centre.
    Mirror(usize),
    /// Keep a shell of this many voxels, remove the inside.
    Hollow(u32),
    /// Fill enclosed empty cells (with the neighbours' colour, or `ink`).
    FillInterior(Option<Ink>),
}

impl Editor {
    /// The voxel model `id`'s editable volume in voxels per axis.
    #[must_use]
    pub fn volume_of(&self, id: u64) -> Option<UVec3> {
        match &self.object(id)?.kind {
            ObjectKind::Voxels(v) => Some(v.volume_size()),
            ObjectKind::Mesh(_) | ObjectKind::Krs(_) => None,
        }
    }

    /// The voxel at `c` of model `id`, if it is solid.
    #[must_use]
    pub fn voxel_at(&self, id: u64, c: UVec3) -> Option<thicket_core::svo::Voxel> {
        match &self.object(id)?.kind {
            ObjectKind::Voxels(v) => v.svo.get(c),
            ObjectKind::Mesh(_) | ObjectKind::Krs(_) => None,
        }
    }

    /// The selected object when it is a voxel model.
    #[must_use]
    pub fn selected_voxel_model(&self) -> Option<u64> {
        let o = self.selected_object()?;
        matches!(o.kind, ObjectKind::Voxels(_)).then_some(o.id)
    }

    /// Adds a new voxel model (Edit → Add voxel model) standing on the ground where the camera
    /// looks, selects it and, when it is the only object, frames it. Returns its id.
    ///
    /// # Errors
    /// See [`NewModelSpec::validate`].
    pub fn add_voxel_model(&mut self, spec: &NewModelSpec) -> Result<u64, CommandError> {
        let target = self.doc.camera.target;
        let model = spec.build(Vec3::new(target.x, 0.0, target.z))?;
        let lone = self.doc.objects.is_empty();
        let bounds = (
            model.origin,
            model.origin + model.volume_size().as_vec3() * model.voxel_size,
        );
        let id = self.add_object(spec.name.trim(), ObjectKind::Voxels(model));
        if lone {
            let mut camera = self.doc.camera;
            camera.frame_in(bounds.0, bounds.1, self.view_aspect);
            // Room for the grid around the model and for zooming in.
            camera.near = camera.distance * 1e-3;
            camera.far = camera.distance * 20.0;
            self.set_camera(camera);
        }
        self.voxel_selection = None;
        Ok(id)
    }

    /// Writes voxels of model `id` with `f(svo, volume)`: refuses enhancement targets, keeps a
    /// linked enhancement in step and records the region for the renderer's incremental
    /// upload. With `merge`, consecutive calls of one interaction are one undo step.
    pub(super) fn write_voxels(
        &mut self,
        id: u64,
        merge: Option<MergeKey>,
        f: impl FnOnce(&mut Svo, UVec3) -> Result<ToolEdit, CommandError>,
    ) -> Result<ToolOutcome, CommandError> {
        self.write_voxels_named(id, merge, "Voxel edit", f)
    }

    /// [`Editor::write_voxels`] under a name for Edit → History.
    pub(super) fn write_voxels_named(
        &mut self,
        id: u64,
        merge: Option<MergeKey>,
        label: &str,
        f: impl FnOnce(&mut Svo, UVec3) -> Result<ToolEdit, CommandError>,
    ) -> Result<ToolOutcome, CommandError> {
        let index = self.index_of(id)?;
        if let Some(l) = self.doc.enhancement_into(id) {
            let source = self
                .object(l.source)
                .map_or("its source", |o| o.name.as_str());
            return Err(CommandError::Invalid(format!(
                "{:?} is the detail enhancement of {source:?} and follows it: edit {source:?}, \
                 or unlink the enhancement in the inspector to edit this one",
                self.doc.objects[index].name
            )));
        }
        self.ensure_enhancer(id);
        let ObjectKind::Voxels(v) = &mut self.doc.objects[index].kind else {
            return Err(CommandError::Invalid(format!(
                "{:?} is not a voxel model: only voxel models can be edited voxel by voxel",
                self.doc.objects[index].name
            )));
        };
        let volume = v.volume_size();
        let frame = v.frames.as_ref().map_or(0, |f| f.shown);
        let edit = f(&mut v.svo, volume)?;
        // A refused tool changed nothing; its reason is the user's to read.
        if let Some(e) = edit.refused {
            return Err(e.into());
        }
        let outcome = ToolOutcome {
            changed: edit.changed,
            voxels: edit.delta.entries.len(),
            clipped: edit.clipped,
        };
        if edit.delta.is_empty() {
            return Ok(outcome);
        }
        let before = self.content_key();
        self.history.push_named(
            Edit::Voxels {
                id,
                delta: edit.delta,
                frame,
            },
            merge,
            label.to_owned(),
        );
        self.after_voxel_edit(before, id, edit.changed);
        Ok(outcome)
    }

    /// Applies a shape tool's cells (voxel, line, a run of a drag) to model `id`. `stroke`:
    /// part of a drag that is one undo step (see [`Editor::begin_stroke`]).
    ///
    /// # Errors
    /// Unknown id, not a voxel model, or an enhancement target.
    pub fn shape_cells(
        &mut self,
        id: u64,
        cells: &[IVec3],
        op: ShapeOp,
        ink: Ink,
        mirror: Mirror,
        stroke: bool,
    ) -> Result<ToolOutcome, CommandError> {
        let mask = self.mask_for(id);
        let label = format!("{} voxels", op_word(op));
        let merge = stroke.then_some(MergeKey::Stroke(id));
        self.write_voxels_named(id, merge, &label, |svo, size| {
            Ok(shapes::apply_cells(
                svo,
                size,
                cells,
                op,
                ink,
                mirror,
                mask.as_ref(),
            ))
        })
    }

    /// The box tool: every cell between corners `a` and `b` (inclusive, any order).
    ///
    /// # Errors
    /// Unknown id, not a voxel model, or an enhancement target.
    pub fn shape_box(
        &mut self,
        id: u64,
        a: IVec3,
        b: IVec3,
        op: ShapeOp,
        ink: Ink,
        mirror: Mirror,
    ) -> Result<ToolOutcome, CommandError> {
        let mask = self.mask_for(id);
        let label = format!("{} box", op_word(op));
        self.write_voxels_named(id, None, &label, |svo, size| {
            Ok(shapes::apply_box(
                svo,
                size,
                a,
                b,
                op,
                ink,
                mirror,
                mask.as_ref(),
            ))
        })
    }

    /// Flood fill from solid voxel `seed`: the connected region of its colour (in its plane
    /// across `plane_axis` when given) is painted with `ink` (Paint) or removed (Remove); Add
    /// puts one layer on the region's exposed face along `normal`.
    ///
    /// # Errors
    /// Unknown id, not a voxel model, or an enhancement target.
    pub fn flood_fill(
        &mut self,
        id: u64,
        seed: UVec3,
        normal: IVec3,
        plane_axis: Option<usize>,
        op: ShapeOp,
        ink: Ink,
    ) -> Result<ToolOutcome, CommandError> {
        let mask = self.mask_for(id);
        let label = format!("Fill ({})", op_word(op).to_lowercase());
        self.write_voxels_named(id, None, &label, |svo, size| {
            Ok(match op {
                ShapeOp::Add => {
                    let face = shapes::face_region(svo, size, seed, normal);
                    let cells = shapes::extrude_cells(&face, normal, 1);
                    shapes::apply_cells(
                        svo,
                        size,
                        &cells,
                        op,
                        ink,
                        Mirror::default(),
                        mask.as_ref(),
                    )
                }
                ShapeOp::Remove | ShapeOp::Paint => {
                    let region = shapes::flood_region(svo, size, seed, plane_axis);
                    let cells: Vec<IVec3> = region.iter().map(|c| c.as_ivec3()).collect();
                    shapes::apply_cells(
                        svo,
                        size,
                        &cells,
                        op,
                        ink,
                        Mirror::default(),
                        mask.as_ref(),
                    )
                }
            })
        })
    }

    /// Face extrude / push-pull: the connected same-colour face region under solid voxel
    /// `seed` facing `normal` moves out (`distance > 0`) or in.
    ///
    /// # Errors
    /// Unknown id, not a voxel model, or an enhancement target.
    pub fn extrude_face(
        &mut self,
        id: u64,
        seed: UVec3,
        normal: IVec3,
        distance: i32,
    ) -> Result<ToolOutcome, CommandError> {
        let mask = self.mask_for(id);
        self.write_voxels_named(id, None, "Extrude", |svo, size| {
            let face = shapes::face_region(svo, size, seed, normal);
            Ok(shapes::extrude(
                svo,
                size,
                &face,
                normal,
                distance,
                mask.as_ref(),
            ))
        })
    }

    /// The exposed same-colour face region under solid voxel `seed` facing `normal` (what the
    /// extrude tool moves); empty when there is none.
    #[must_use]
    pub fn face_region(&self, id: u64, seed: UVec3, normal: IVec3) -> Vec<UVec3> {
        match self.object(id).map(|o| &o.kind) {
            Some(ObjectKind::Voxels(v)) => {
                shapes::face_region(&v.svo, v.volume_size(), seed, normal)
            }
            _ => Vec::new(),
        }
    }

    /// The selection of model `id` that limits the tools, if it has one.
    fn mask_for(&self, id: u64) -> Option<VoxelSelection> {
        self.voxel_selection
            .as_ref()
            .filter(|s| s.object == id && !s.cells.is_empty())
            .map(|s| s.cells.clone())
    }

    // ------------------------------------------------------------------ selection

    /// The voxel selection, if any voxel is selected.
    #[must_use]
    pub fn voxel_selection(&self) -> Option<&VoxelSelectionState> {
        self.voxel_selection
            .as_ref()
            .filter(|s| !s.cells.is_empty())
    }

    /// The solid voxels of model `id`'s octree, for the selection functions.
    fn svo_of(&self, id: u64) -> Result<&Svo, CommandError> {
        let o = self.object(id).ok_or(CommandError::NoObject(id))?;
        match &o.kind {
            ObjectKind::Voxels(v) => Ok(&v.svo),
            ObjectKind::Mesh(_) | ObjectKind::Krs(_) => Err(CommandError::Invalid(format!(
                "{:?} is not a voxel model: only voxels can be selected",
                o.name
            ))),
        }
    }

    /// Sets, extends or reduces the voxel selection of model `id`. Returns the number of
    /// selected voxels.
    ///
    /// # Errors
    /// Unknown id or not a voxel model.
    pub fn select_voxels(
        &mut self,
        id: u64,
        cells: VoxelSelection,
        mode: SelectMode,
    ) -> Result<usize, CommandError> {
        self.svo_of(id)?;
        let current = self
            .voxel_selection
            .take()
            .filter(|s| s.object == id)
            .map(|s| s.cells)
            .unwrap_or_default();
        let cells = match mode {
            SelectMode::Replace => cells,
            SelectMode::Add => current.union(&cells),
            SelectMode::Subtract => current.difference(&cells),
        };
        let n = cells.len();
        self.selection = Some(Selection::Object(id));
        self.voxel_selection = Some(VoxelSelectionState {
            object: id,
            cells,
            turn_pivot: None,
        });
        Ok(n)
    }

    /// Every solid voxel of model `id`.
    ///
    /// # Errors
    /// Unknown id or not a voxel model.
    pub fn select_all_voxels(&mut self, id: u64) -> Result<usize, CommandError> {
        let svo = self.svo_of(id)?;
        let all = select::invert(svo, &VoxelSelection::default())?;
        self.select_voxels(id, all, SelectMode::Replace)
    }

    /// Every voxel of the colour of solid voxel `at` (Select by colour).
    ///
    /// # Errors
    /// Unknown id, not a voxel model, or `at` is empty.
    pub fn select_color_at(
        &mut self,
        id: u64,
        at: UVec3,
        mode: SelectMode,
    ) -> Result<usize, CommandError> {
        let svo = self.svo_of(id)?;
        let v = svo
            .get(at)
            .ok_or_else(|| CommandError::Invalid(format!("voxel {at} is empty")))?;
        let cells = select::select_color(svo, v.color)?;
        self.select_voxels(id, cells, mode)
    }

    /// The voxels 6-connected to solid voxel `at` (of its colour when `same_color`).
    ///
    /// # Errors
    /// Unknown id, not a voxel model, or `at` is empty.
    pub fn select_connected_at(
        &mut self,
        id: u64,
        at: UVec3,
        same_color: bool,
        mode: SelectMode,
    ) -> Result<usize, CommandError> {
        let svo = self.svo_of(id)?;
        if svo.get(at).is_none() {
            return Err(CommandError::Invalid(format!("voxel {at} is empty")));
        }
        let cells = select::select_connected(svo, at, same_color)?;
        self.select_voxels(id, cells, mode)
    }

    /// Clears the voxel selection (and drops a floating paste).
    pub fn clear_voxel_selection(&mut self) {
        self.voxel_selection = None;
    }

    /// Replaces the selection by the model's other solid voxels.
    ///
    /// # Errors
    /// No voxel model selected.
    pub fn invert_voxel_selection(&mut self) -> Result<usize, CommandError> {
        let id = self.selection_model()?;
        let current = self.current_cells(id);
        let cells = select::invert(self.svo_of(id)?, &current)?;
        self.select_voxels(id, cells, SelectMode::Replace)
    }

    /// Grows (`true`) or shrinks the selection by one voxel.
    ///
    /// # Errors
    /// No voxel model selected.
    pub fn grow_voxel_selection(&mut self, grow: bool) -> Result<usize, CommandError> {
        let id = self.selection_model()?;
        let current = self.current_cells(id);
        let cells = if grow {
            select::grow(self.svo_of(id)?, &current)
        } else {
            select::shrink(&current)
        };
        self.select_voxels(id, cells, SelectMode::Replace)
    }

    /// The model the selection commands act on: the one with a voxel selection, else the
    /// selected voxel model.
    fn selection_model(&self) -> Result<u64, CommandError> {
        self.voxel_selection()
            .map(|s| s.object)
            .or_else(|| self.selected_voxel_model())
            .ok_or_else(|| CommandError::Invalid("select a voxel model first".into()))
    }

    fn current_cells(&self, id: u64) -> VoxelSelection {
        self.voxel_selection
            .as_ref()
            .filter(|s| s.object == id)
            .map(|s| s.cells.clone())
            .unwrap_or_default()
    }

    fn require_selection(&self) -> Result<(u64, VoxelSelection), CommandError> {
        self.voxel_selection()
            .map(|s| (s.object, s.cells.clone()))
            .ok_or_else(|| {
                CommandError::Invalid(
                    "no voxels are selected: use the Select tool (M) or Select > All".into(),
                )
            })
    }

    /// Deletes the selected voxels.
    ///
    /// # Errors
    /// No voxel selection.
    pub fn delete_selected_voxels(&mut self) -> Result<ToolOutcome, CommandError> {
        let (id, cells) = self.require_selection()?;
        self.write_voxels_named(id, None, "Delete selected voxels", |svo, _| {
            Ok(select::delete(svo, &cells))
        })
    }

    /// Paints the selected voxels with `ink`.
    ///
    /// # Errors
    /// No voxel selection.
    pub fn fill_selected_voxels(&mut self, ink: Ink) -> Result<ToolOutcome, CommandError> {
        let (id, cells) = self.require_selection()?;
        self.write_voxels_named(id, None, "Fill selection", |svo, _| {
            Ok(select::fill(svo, &cells, ink))
        })
    }

    /// Copies the selected voxels to the clipboard; returns how many.
    ///
    /// # Errors
    /// No voxel selection.
    pub fn copy_voxels(&mut self) -> Result<usize, CommandError> {
        let (id, cells) = self.require_selection()?;
        let o = self.object(id).ok_or(CommandError::NoObject(id))?;
        let ObjectKind::Voxels(v) = &o.kind else {
            return Err(CommandError::Invalid("not a voxel model".into()));
        };
        let clip = select::copy(&v.svo, &cells);
        let n = clip.voxels.len();
        let origin = cells.bounds().map_or(UVec3::ZERO, |b| b.0);
        self.clipboard = Some(ClipboardEntry {
            clip,
            origin,
            voxel_size: v.voxel_size,
        });
        Ok(n)
    }

    /// Copies, then deletes the selected voxels.
    ///
    /// # Errors
    /// No voxel selection.
    pub fn cut_voxels(&mut self) -> Result<ToolOutcome, CommandError> {
        self.copy_voxels()?;
        self.delete_selected_voxels()
    }

    /// The clipboard, if something was copied.
    #[must_use]
    pub fn clipboard(&self) -> Option<&ClipboardEntry> {
        self.clipboard.as_ref()
    }

    /// Starts a paste into voxel model `id`: the clipboard floats at the place it was copied
    /// from (clamped into the volume) until [`Editor::commit_floating`].
    ///
    /// # Errors
    /// Empty clipboard, not a voxel model, or a voxel size that differs from the clipboard's
    /// (the paste would change the voxels' size; it is refused rather than resampled).
    pub fn start_paste(&mut self, id: u64) -> Result<(), CommandError> {
        let entry = self.clipboard.clone().ok_or_else(|| {
            CommandError::Invalid("the clipboard is empty: copy voxels first".into())
        })?;
        let o = self.object(id).ok_or(CommandError::NoObject(id))?;
        let ObjectKind::Voxels(v) = &o.kind else {
            return Err(CommandError::Invalid(format!(
                "{:?} is not a voxel model: voxels paste into voxel models",
                o.name
            )));
        };
        let ratio = entry.voxel_size / v.voxel_size;
        // NaN (a zero voxel size) fails the comparison too.
        let same_size = (ratio - 1.0).abs() <= 1e-4;
        if !same_size {
            return Err(CommandError::Invalid(format!(
                "the copied voxels are {} units, {:?}'s are {}: pasting would change their size; \
                 paste into a model with the same voxel size (or resize this one's voxels)",
                entry.voxel_size, o.name, v.voxel_size
            )));
        }
        let size = v.volume_size().as_ivec3();
        let extent = entry.clip.size.as_ivec3();
        let at = entry
            .origin
            .as_ivec3()
            .min((size - extent).max(IVec3::ZERO));
        self.floating = Some(Floating {
            object: id,
            clip: entry.clip,
            at,
        });
        Ok(())
    }

    /// The paste in progress.
    #[must_use]
    pub fn floating(&self) -> Option<&Floating> {
        self.floating.as_ref()
    }

    /// Starts a paste ([`Editor::start_paste`]) whose bottom sits on cell `at` (voxel
    /// coordinates of model `id`): the paste centred on it across, its lowest layer in it (a
    /// paste at the pointer: `at` is the empty cell in front of the face under it).
    ///
    /// # Errors
    /// As [`Editor::start_paste`].
    pub fn start_paste_at(&mut self, id: u64, at: IVec3) -> Result<(), CommandError> {
        self.start_paste(id)?;
        if let Some(f) = &mut self.floating {
            let size = f.clip.size.as_ivec3();
            f.at = at - IVec3::new(size.x / 2, 0, size.z / 2);
        }
        Ok(())
    }

    /// Puts the floating paste's minimum corner at `at` (a drag).
    pub fn place_floating(&mut self, at: IVec3) {
        if let Some(f) = &mut self.floating {
            f.at = at;
        }
    }

    /// Moves the floating paste.
    pub fn move_floating(&mut self, by: IVec3) {
        if let Some(f) = &mut self.floating {
            f.at = f.at.saturating_add(by);
        }
    }

    /// Writes the floating paste (one undo step) and selects what it wrote.
    ///
    /// # Errors
    /// No paste in progress, or its model is gone.
    pub fn commit_floating(&mut self) -> Result<ToolOutcome, CommandError> {
        let f = self
            .floating
            .take()
            .ok_or_else(|| CommandError::Invalid("nothing is being pasted".into()))?;
        let lifted = self.lifted.take();
        let outcome = self.write_voxels_named(f.object, None, "Paste", |svo, size| {
            Ok(select::paste(svo, size, &f.clip, f.at, false))
        })?;
        // Voxels lifted for a move: taking them out and writing them back is one step.
        if let Some(before) = lifted {
            let n = self.history.undo_len().saturating_sub(before);
            self.history.join_top(n, "Move voxels".into());
        }
        let size = self.volume_of(f.object).unwrap_or(UVec3::ZERO).as_ivec3();
        let cells = select::paste_cells(&f.clip, f.at)
            .into_iter()
            .filter(|c| c.min_element() >= 0 && c.cmplt(size).all())
            .map(|c| c.as_uvec3());
        self.select_voxels(
            f.object,
            VoxelSelection::from_cells(cells),
            SelectMode::Replace,
        )?;
        Ok(outcome)
    }

    /// How many voxels of the floating paste lie outside its model's volume (a commit clips
    /// them; [`Editor::commit_floating_growing`] keeps them).
    #[must_use]
    pub fn floating_outside(&self) -> usize {
        let Some(f) = &self.floating else { return 0 };
        let size = self.volume_of(f.object).unwrap_or(UVec3::ZERO).as_ivec3();
        select::paste_cells(&f.clip, f.at)
            .iter()
            .filter(|c| c.min_element() < 0 || c.cmpge(size).any())
            .count()
    }

    /// Writes the floating paste after growing its model's canvas just enough to hold all of
    /// it (the model keeps its place in the world): the resize and the paste are one undo step.
    /// Without voxels outside it is [`Editor::commit_floating`].
    ///
    /// # Errors
    /// No paste in progress, its model is gone or linked to an enhancement, or the grown
    /// canvas would be larger than [`MAX_EXTENT`] (nothing is changed then).
    pub fn commit_floating_growing(&mut self) -> Result<ToolOutcome, CommandError> {
        let f = self
            .floating
            .clone()
            .ok_or_else(|| CommandError::Invalid("nothing is being pasted".into()))?;
        let size = self
            .volume_of(f.object)
            .ok_or(CommandError::NoObject(f.object))?
            .as_ivec3();
        let cells = select::paste_cells(&f.clip, f.at);
        let (lo, hi) = cells.iter().fold((IVec3::ZERO, size), |(lo, hi), c| {
            (lo.min(*c), hi.max(*c + 1))
        });
        if lo == IVec3::ZERO && hi == size {
            return self.commit_floating();
        }
        let grown = hi - lo;
        if grown.max_element() > MAX_EXTENT as i32 {
            return Err(CommandError::Invalid(format!(
                "the canvas would grow to {}×{}×{}: each axis holds at most {MAX_EXTENT}",
                grown.x, grown.y, grown.z
            )));
        }
        let steps = self.history.undo_len();
        // Grow past the top first (the minimum corner stays), then below the bottom (the
        // maximum corner stays): together the volume spans lo..hi.
        if hi != size {
            self.resize_canvas(f.object, hi.as_uvec3(), [Anchor::Min; 3])?;
        }
        if lo != IVec3::ZERO {
            let anchor = [0, 1, 2].map(|a| if lo[a] < 0 { Anchor::Max } else { Anchor::Min });
            self.resize_canvas(f.object, grown.as_uvec3(), anchor)?;
        }
        self.floating = Some(Floating { at: f.at - lo, ..f });
        let outcome = self.commit_floating()?;
        let n = self.history.undo_len() - steps;
        self.history.join_top(n, "Paste (canvas grown)".into());
        Ok(outcome)
    }

    /// Drops the floating paste. Voxels lifted for a move ([`Editor::lift_selection`]) go back
    /// where they were (the lift is undone).
    pub fn cancel_floating(&mut self) {
        self.floating = None;
        if let Some(before) = self.lifted.take()
            && self.history.undo_len() > before
        {
            self.undo();
        }
    }

    /// Starts moving the selected voxels (a drag in the view): they leave the model and float
    /// at their own place, as a paste does, without touching the clipboard. [`Editor::drop_lifted`]
    /// writes them where the float is; the removal and the write are one undo step.
    ///
    /// # Errors
    /// No voxel selection, or a paste already floating.
    pub fn lift_selection(&mut self) -> Result<(), CommandError> {
        if self.floating.is_some() {
            return Err(CommandError::Invalid(
                "a paste is floating: place it (Enter) or cancel it (Esc) first".into(),
            ));
        }
        let (id, cells) = self.require_selection()?;
        let o = self.object(id).ok_or(CommandError::NoObject(id))?;
        let ObjectKind::Voxels(v) = &o.kind else {
            return Err(CommandError::Invalid("not a voxel model".into()));
        };
        let clip = select::copy(&v.svo, &cells);
        let at = cells.bounds().map_or(UVec3::ZERO, |b| b.0).as_ivec3();
        let before = self.history.undo_len();
        self.history.seal();
        self.delete_selected_voxels()?;
        self.floating = Some(Floating {
            object: id,
            clip,
            at,
        });
        self.lifted = Some(before);
        Ok(())
    }

    /// Whether the floating voxels were lifted out of their model for a move.
    #[must_use]
    pub fn is_lifted(&self) -> bool {
        self.lifted.is_some() && self.floating.is_some()
    }

    /// Writes voxels lifted by [`Editor::lift_selection`] where they float now and selects
    /// them: the lift and the write become one undo step, "Move voxels" (voxels dragged
    /// outside the volume are clipped, as a paste's are).
    ///
    /// # Errors
    /// Nothing lifted, or its model is gone.
    pub fn drop_lifted(&mut self) -> Result<ToolOutcome, CommandError> {
        if self.lifted.is_none() {
            return Err(CommandError::Invalid("no voxels are being moved".into()));
        }
        self.commit_floating()
    }

    /// The doubled-coordinate pivot a quarter turn of `cells` uses: the last turn's about the
    /// same axis (so four turns give the cells back), else the cells' centre.
    fn turn_pivot_for(&self, t: SelTransform, cells: &VoxelSelection) -> IVec3 {
        let (lo, hi) = cells.bounds().unwrap_or((UVec3::ZERO, UVec3::ZERO));
        let axis = match t {
            SelTransform::Rotate { axis, .. } => axis.min(2),
            SelTransform::Move(_) | SelTransform::Flip(_) => 1,
        };
        match self.voxel_selection.as_ref().and_then(|s| s.turn_pivot) {
            Some((a, p)) if a == axis => p,
            _ => select::rotation_pivot(lo, hi, axis),
        }
    }

    /// How many selected voxels a move, flip or turn would push outside the model's volume
    /// (a plain [`Editor::transform_selected_voxels`] clips them), and the box from the volume's
    /// origin that would hold them all. `None` without a selection.
    #[must_use]
    pub fn transform_outside(&self, t: SelTransform) -> Option<(usize, IVec3, IVec3)> {
        let sel = self.voxel_selection.as_ref()?;
        let size = self.volume_of(sel.object)?.as_ivec3();
        let pivot2 = self.turn_pivot_for(t, &sel.cells);
        let landed = select::transformed_cells(&sel.cells, t, pivot2);
        let (mut lo, mut hi) = (glam::I64Vec3::ZERO, size.as_i64vec3());
        let mut outside = 0;
        for c in &landed {
            if c.min_element() < 0 || c.cmpge(size.as_i64vec3()).any() {
                outside += 1;
            }
            lo = lo.min(*c);
            hi = hi.max(*c + 1);
        }
        let clamp = |v: glam::I64Vec3| {
            v.clamp(
                glam::I64Vec3::splat(-(1 << 30)),
                glam::I64Vec3::splat(1 << 30),
            )
            .as_ivec3()
        };
        Some((outside, clamp(lo), clamp(hi)))
    }

    /// [`Editor::transform_selected_voxels`] after growing the canvas just enough to keep every
    /// voxel it moves (the model keeps its place in the world): the resize and the transform
    /// are one undo step. Without voxels pushed outside it is the plain transform.
    ///
    /// # Errors
    /// No voxel selection, a model linked to an enhancement, or a grown canvas larger than
    /// [`MAX_EXTENT`] per axis (nothing is changed then).
    pub fn transform_selected_voxels_growing(
        &mut self,
        t: SelTransform,
    ) -> Result<ToolOutcome, CommandError> {
        let (id, cells) = self.require_selection()?;
        let Some((outside, lo, hi)) = self.transform_outside(t) else {
            return self.transform_selected_voxels(t);
        };
        if outside == 0 {
            return self.transform_selected_voxels(t);
        }
        let size = self
            .volume_of(id)
            .ok_or(CommandError::NoObject(id))?
            .as_ivec3();
        let grown = hi - lo;
        if grown.max_element() > MAX_EXTENT as i32 {
            return Err(CommandError::Invalid(format!(
                "the canvas would grow to {}×{}×{}: each axis holds at most {MAX_EXTENT}",
                grown.x, grown.y, grown.z
            )));
        }
        let pivot = self.voxel_selection.as_ref().and_then(|s| s.turn_pivot);
        let steps = self.history.undo_len();
        if hi != size {
            self.resize_canvas(id, hi.max(size).as_uvec3(), [Anchor::Min; 3])?;
        }
        if lo != IVec3::ZERO {
            let anchor = [0, 1, 2].map(|a| if lo[a] < 0 { Anchor::Max } else { Anchor::Min });
            self.resize_canvas(id, grown.as_uvec3(), anchor)?;
        }
        // The resize dropped the selection; it comes back where the growth below moved it.
        let shift = (-lo).max(IVec3::ZERO).as_uvec3();
        self.select_voxels(
            id,
            VoxelSelection::from_cells(cells.iter().map(|c| c + shift)),
            SelectMode::Replace,
        )?;
        if let Some(s) = &mut self.voxel_selection {
            s.turn_pivot = pivot.map(|(a, p)| (a, p + 2 * shift.as_ivec3()));
        }
        let outcome = self.transform_selected_voxels(t)?;
        let n = self.history.undo_len() - steps;
        self.history
            .join_top(n, "Transform selected voxels (canvas grown)".into());
        Ok(outcome)
    }

    /// Moves, flips or rotates the selected voxels (one undo step); the selection follows.
    /// Rotations turn about the selection's centre.
    ///
    /// # Errors
    /// No voxel selection.
    pub fn transform_selected_voxels(
        &mut self,
        t: SelTransform,
    ) -> Result<ToolOutcome, CommandError> {
        let (id, cells) = self.require_selection()?;
        let axis = match t {
            SelTransform::Rotate { axis, .. } => axis.min(2),
            SelTransform::Move(_) | SelTransform::Flip(_) => 1,
        };
        let last = self.voxel_selection.as_ref().and_then(|s| s.turn_pivot);
        let pivot2 = self.turn_pivot_for(t, &cells);
        let turn_pivot = match t {
            SelTransform::Rotate { .. } => Some((axis, pivot2)),
            SelTransform::Move(d) => last.map(|(a, p)| (a, p + 2 * d)),
            SelTransform::Flip(_) => None,
        };
        let mut moved = None;
        let label = match t {
            SelTransform::Move(_) => "Move selected voxels",
            SelTransform::Flip(_) => "Flip selected voxels",
            SelTransform::Rotate { .. } => "Rotate selected voxels",
        };
        let outcome = self.write_voxels_named(id, None, label, |svo, size| {
            let (edit, sel) = select::transform_selection(svo, size, &cells, t, pivot2);
            moved = Some(sel);
            Ok(edit)
        })?;
        if let Some(sel) = moved {
            self.voxel_selection = Some(VoxelSelectionState {
                object: id,
                cells: sel,
                turn_pivot,
            });
        }
        Ok(outcome)
    }

    /// Deletes every voxel outside the selection.
    ///
    /// # Errors
    /// No voxel selection.
    pub fn crop_to_selection(&mut self) -> Result<ToolOutcome, CommandError> {
        let (id, cells) = self.require_selection()?;
        self.write_voxels_named(id, None, "Crop to selection", |svo, _| {
            Ok(select::crop_to(svo, &cells))
        })
    }

    /// Copies the selected voxels into a new voxel model of their size, at the same place in
    /// the world; returns its id.
    ///
    /// # Errors
    /// No voxel selection.
    pub fn selection_to_new_object(&mut self) -> Result<u64, CommandError> {
        let (id, cells) = self.require_selection()?;
        let o = self.object(id).ok_or(CommandError::NoObject(id))?;
        let ObjectKind::Voxels(v) = &o.kind else {
            return Err(CommandError::Invalid("not a voxel model".into()));
        };
        let clip = select::copy(&v.svo, &cells);
        let (lo, _) = cells.bounds().unwrap_or((UVec3::ZERO, UVec3::ZERO));
        let depth = model_ops::depth_for(clip.size.max(UVec3::ONE))?;
        let mut svo = Svo::from_voxels(depth, v.svo.has_skin(), clip.voxels.iter().copied())
            .map_err(|e| CommandError::Invalid(e.to_string()))?;
        // Where the selection cut through an interior, what cutting it out would show.
        svo.settle_interior_from(Some((&v.svo, lo.as_ivec3())));
        let model = VoxelModel {
            svo,
            voxel_size: v.voxel_size,
            origin: v.origin + lo.as_vec3() * v.voxel_size,
            material_names: v.material_names.clone(),
            rig: v.rig.clone(),
            volume: Some(clip.size.max(UVec3::ONE)),
            palette: v.palette.clone(),
            frames: None,
        };
        let name = format!("{} (part)", o.name);
        let transform: Transform = o.transform;
        let new_id = self.add_object(&name, ObjectKind::Voxels(model));
        if transform != Transform::default() {
            self.set_transform(new_id, transform)?;
        }
        self.voxel_selection = None;
        Ok(new_id)
    }

    // ------------------------------------------------------------------ palette

    /// Replaces colour `from` by `to` in model `id` (inside the selection when there is one).
    ///
    /// # Errors
    /// Unknown id, not a voxel model, or an enhancement target.
    pub fn replace_color(
        &mut self,
        id: u64,
        from: [u8; 4],
        to: [u8; 4],
    ) -> Result<ToolOutcome, CommandError> {
        let mask = self.mask_for(id);
        let steps = self.history.undo_len();
        let outcome = self.write_voxels_named(id, None, "Replace colour", |svo, _| {
            Ok(palette::replace_color(svo, from, to, mask.as_ref()))
        })?;
        // The palette entry follows, so the panel shows the new colour in its place: the
        // same undo step.
        if let Some(ObjectKind::Voxels(v)) = self.object(id).map(|o| &o.kind)
            && let Some(i) = v.palette.iter().position(|c| *c == from)
        {
            let mut p = v.palette.clone();
            p[i] = to;
            self.set_palette(id, p)?;
            if self.history.undo_len() == steps + 2 {
                self.history.join_top(2, "Replace colour".into());
            }
        }
        Ok(outcome)
    }

    /// Replaces model `id`'s palette (at most 256 entries).
    ///
    /// # Errors
    /// Unknown id, not a voxel model, or more than 256 colours.
    pub fn set_palette(&mut self, id: u64, palette: Vec<[u8; 4]>) -> Result<(), CommandError> {
        if palette.len() > 256 {
            return Err(CommandError::Invalid(format!(
                "a palette holds at most 256 colours, not {}",
                palette.len()
            )));
        }
        let o = self.object(id).ok_or(CommandError::NoObject(id))?;
        let ObjectKind::Voxels(v) = &o.kind else {
            return Err(CommandError::Invalid(format!(
                "{:?} is not a voxel model",
                o.name
            )));
        };
        if v.palette == palette {
            return Ok(());
        }
        self.apply(Edit::SetPalette { id, palette }, None);
        Ok(())
    }

    // ------------------------------------------------------------------ model operations

    /// Applies a whole-model operation to model `id` (one undo step of the voxels it changed).
    ///
    /// # Errors
    /// Unknown id, not a voxel model, an enhancement target, or a bad argument.
    pub fn model_op(&mut self, id: u64, op: ModelOp) -> Result<ToolOutcome, CommandError> {
        if let ModelOp::Mirror(a) = op
            && a > 2
        {
            return Err(CommandError::Invalid(format!("axis {a} is not X, Y or Z")));
        }
        if op == ModelOp::Hollow(0) {
            return Err(CommandError::Invalid(
                "a hollow shell must be at least one voxel thick".into(),
            ));
        }
        let label = match op {
            ModelOp::Shift { .. } => "Shift content",
            ModelOp::Mirror(_) => "Mirror model",
            ModelOp::Hollow(_) => "Hollow",
            ModelOp::FillInterior(_) => "Fill interior",
        };
        self.write_voxels_named(id, None, label, |svo, size| {
            Ok(match op {
                ModelOp::Shift { offset, wrap } => {
                    model_ops::shift_content(svo, size, offset, wrap)
                }
                ModelOp::Mirror(axis) => model_ops::mirror_model(svo, size, axis),
                ModelOp::Hollow(shell) => model_ops::hollow(svo, size, shell),
                ModelOp::FillInterior(ink) => model_ops::fill_interior(svo, size, ink),
            })
        })
    }

    /// Grows or shrinks model `id`'s volume to `new_size` about `anchor` (the content keeps its
    /// place in the world). Returns how many voxels fell outside and were removed.
    ///
    /// # Errors
    /// Unknown id, not a voxel model, an enhancement link, or a size beyond the octree limit.
    pub fn resize_canvas(
        &mut self,
        id: u64,
        new_size: UVec3,
        anchor: [Anchor; 3],
    ) -> Result<u64, CommandError> {
        let index = self.index_of(id)?;
        if self.doc.enhancement_of(id).is_some() || self.doc.enhancement_into(id).is_some() {
            return Err(CommandError::Invalid(
                "this model is linked to a detail enhancement: unlink it in the inspector \
                 before resizing the canvas"
                    .into(),
            ));
        }
        let ObjectKind::Voxels(v) = &self.doc.objects[index].kind else {
            return Err(CommandError::Invalid(
                "only voxel models have a canvas".into(),
            ));
        };
        if new_size.min_element() == 0 || new_size.max_element() > MAX_EXTENT {
            return Err(CommandError::Invalid(format!(
                "extent {}×{}×{} is out of range: each axis must be 1 to {MAX_EXTENT} (2^{MAX_DEPTH})",
                new_size.x, new_size.y, new_size.z
            )));
        }
        let resized = model_ops::resize_canvas(&v.svo, v.volume_size(), new_size, anchor)?;
        let model = VoxelModel {
            svo: resized.svo,
            voxel_size: v.voxel_size,
            // The content stays where it was in the world: the origin moves against the offset.
            origin: v.origin - resized.offset.as_vec3() * v.voxel_size,
            material_names: v.material_names.clone(),
            rig: v.rig.clone(),
            volume: Some(new_size),
            palette: v.palette.clone(),
            // Other frames of a frame sequence keep their own voxels and origins.
            frames: v.frames.clone(),
        };
        self.apply_named(
            Edit::SetVoxelModel {
                id,
                model: Box::new(model),
            },
            None,
            "Resize canvas".into(),
        );
        self.voxel_selection = None;
        Ok(resized.dropped)
    }
}

/// The verb of a shape operation, for step names.
fn op_word(op: ShapeOp) -> &'static str {
    match op {
        ShapeOp::Add => "Add",
        ShapeOp::Remove => "Remove",
        ShapeOp::Paint => "Paint",
    }
}
