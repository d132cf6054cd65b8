//! The voxel modelling tools in the view: voxel, box, line, face extrude, flood fill and select
//! (the MagicaVoxel set), their previews of the exact voxels before release, the selection
//! outline, the floating paste, and the model's volume box and editing grid.
//!
//! Tools act on the selected voxel model (or the model under the pointer). Where no voxel is
//! under the pointer they aim at the inside of the model's volume box — its floor and back walls
//! as seen from the camera — so the first voxel of an empty model can be placed. A drag stays on
//! the plane it started on, so a run of voxels or a box's rectangle does not climb toward the
//! camera over the voxels it has just added.

use glam::{DVec3, IVec3, Mat4, UVec3, Vec2, Vec3};
use thicket_core::scene::ObjectKind;
use thicket_core::sculpt::select::{SurfaceView, select_in_rect};
use thicket_core::sculpt::shapes::{self, Ink, Mirror, ShapeOp};

use super::projector::Projector;
use crate::editor::{Editor, SelectMode};

/// Most voxels a preview draws one by one (beyond it: their bounding box).
const MAX_PREVIEW_CELLS: usize = 4096;

/// Most selection faces the outline draws (beyond it: the selection's bounding box).
const MAX_OUTLINE_FACES: usize = 60_000;

/// Colour of the selection outline and fill.
const SELECTION_OUTLINE: egui::Color32 = egui::Color32::from_rgb(255, 200, 40);

/// Which voxel tool the primary button uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ToolKind {
    /// The sphere / cube brushes (add, remove, paint, smooth) with continuous strokes.
    #[default]
    Brush,
    /// Single voxels; a drag paints a run on the plane it started on.
    Voxel,
    /// Drag a rectangle on a face, release, move to set the height, click to commit.
    Box,
    /// Press at one end, release at the other.
    Line,
    /// Drag a connected same-colour face region out (or in).
    Extrude,
    /// Flood fill the connected region of one colour.
    Fill,
    /// Select voxels: drag a rectangle, or click for a colour / connected region.
    Select,
}

impl ToolKind {
    /// Every tool with its tool-bar label and tooltip (its key is in the binding table,
    /// `keys::BINDINGS`, which refers to these tools).
    pub const ALL: [(ToolKind, &'static str, &'static str); 7] = [
        (
            ToolKind::Brush,
            "Brush",
            "Sphere / cube brush strokes: add, remove, paint, smooth",
        ),
        (
            ToolKind::Voxel,
            "Voxel",
            "Single voxels; drag to paint a run on one plane",
        ),
        (
            ToolKind::Box,
            "Box",
            "Drag a rectangle on a face, release, move the pointer to set the height, click to commit (Esc cancels)",
        ),
        (
            ToolKind::Line,
            "Line",
            "Press at one end and release at the other",
        ),
        (
            ToolKind::Extrude,
            "Extrude",
            "Push / pull: drag a flat same-colour face region out or in",
        ),
        (
            ToolKind::Fill,
            "Fill",
            "Flood fill: Paint recolours the connected region of one colour, Remove deletes it, Add puts a layer on its face",
        ),
        (
            ToolKind::Select,
            "Select",
            "Drag a rectangle to select (Shift adds, Ctrl removes); click selects a colour or a connected part",
        ),
    ];

    /// The tool-bar label.
    #[must_use]
    pub fn label(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|t| t.0 == self)
            .map_or("Brush", |t| t.1)
    }
}

/// What a click of the select tool selects.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ClickSelect {
    /// Every voxel of the clicked colour.
    #[default]
    Color,
    /// The clicked voxel's connected part (of its colour).
    Connected,
}

/// A voxel model's frame for the tools.
#[derive(Debug, Clone, Copy)]
pub struct ModelFrame {
    /// The voxel model.
    pub object: u64,
    /// `world_from_voxel`.
    pub world_from_voxel: Mat4,
    /// `voxel_from_world`.
    pub voxel_from_world: Mat4,
    /// The editable volume in voxels.
    pub size: UVec3,
}

impl ModelFrame {
    /// The frame of voxel model `id`, if it is one with an invertible transform.
    #[must_use]
    pub fn of(editor: &Editor, id: u64) -> Option<Self> {
        let o = editor.object(id)?;
        let ObjectKind::Voxels(v) = &o.kind else {
            return None;
        };
        let world_from_voxel = o.transform.matrix() * v.object_from_voxel();
        let voxel_from_world = world_from_voxel.inverse();
        voxel_from_world.is_finite().then_some(Self {
            object: id,
            world_from_voxel,
            voxel_from_world,
            size: v.volume_size(),
        })
    }

    /// A world ray in voxel space (same parameter in both spaces).
    #[must_use]
    pub fn ray(&self, origin_in_world: Vec3, dir_in_world: Vec3) -> (Vec3, Vec3) {
        (
            self.voxel_from_world.transform_point3(origin_in_world),
            self.voxel_from_world.transform_vector3(dir_in_world),
        )
    }

    /// A voxel-space point in the world.
    #[must_use]
    pub fn world(&self, p: Vec3) -> Vec3 {
        self.world_from_voxel.transform_point3(p)
    }
}

/// Where a tool aims.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ToolTarget {
    /// The solid voxel under the pointer, if any.
    pub solid: Option<UVec3>,
    /// Unit axis pointing back toward the viewer (the face hit, or the volume wall's inside).
    pub normal: IVec3,
    /// The empty cell where Add puts a voxel: in front of the face hit, or against the wall.
    pub front: IVec3,
}

impl ToolTarget {
    /// The cell an operation acts on: `front` for Add, the solid voxel otherwise.
    #[must_use]
    pub fn cell(&self, op: ShapeOp) -> Option<IVec3> {
        match op {
            ShapeOp::Add => Some(self.front),
            ShapeOp::Remove | ShapeOp::Paint => self.solid.map(|c| c.as_ivec3()),
        }
    }
}

/// The inside of the volume box `[0, size]` where a voxel-space ray leaves it (its floor and
/// back walls as the camera sees them): the cell there and the wall's inward normal.
#[must_use]
pub fn volume_hit(size: UVec3, origin: Vec3, dir: Vec3) -> Option<(IVec3, IVec3)> {
    let (o, d) = (origin.as_dvec3(), dir.as_dvec3());
    if !o.is_finite() || !d.is_finite() || d.length_squared() == 0.0 {
        return None;
    }
    let hi = size.as_dvec3();
    let inv = d.recip();
    let t0 = (DVec3::ZERO - o) * inv;
    let t1 = (hi - o) * inv;
    let (tmin, tmax) = (t0.min(t1), t0.max(t1));
    let enter = tmin.max_element().max(0.0);
    let exit = tmax.min_element();
    let opens = exit > enter; // false for NaN as well
    if !opens || !exit.is_finite() {
        return None;
    }
    // The exit axis is the one whose far slab ends first.
    let axis = (0..3)
        .filter(|&a| d[a] != 0.0)
        .min_by(|&a, &b| tmax[a].total_cmp(&tmax[b]))?;
    let p = o + d * exit;
    let mut cell = p.floor().as_ivec3();
    let mut normal = IVec3::ZERO;
    if d[axis] > 0.0 {
        normal[axis] = -1;
        cell[axis] = size.as_ivec3()[axis] - 1;
    } else {
        normal[axis] = 1;
        cell[axis] = 0;
    }
    cell = cell.clamp(IVec3::ZERO, size.as_ivec3() - 1);
    Some((cell, normal))
}

/// The cell where a voxel-space ray crosses the middle of layer `coord` across `axis`.
#[must_use]
pub fn plane_cell(origin: Vec3, dir: Vec3, axis: usize, coord: i32) -> Option<IVec3> {
    let plane = f64::from(coord) + 0.5;
    let (o, d) = (origin.as_dvec3(), dir.as_dvec3());
    if d[axis].abs() < 1e-12 {
        return None;
    }
    let t = (plane - o[axis]) / d[axis];
    let ahead = t > 0.0; // false for NaN as well
    if !ahead || !t.is_finite() {
        return None;
    }
    let p = o + d * t;
    let mut c = p.floor();
    c[axis] = f64::from(coord);
    // Far-off hits of grazing rays would overflow i32.
    (c.abs().max_element() < 1.0e9).then(|| c.as_ivec3())
}

/// Parameter along the line `start + s * axis_dir` closest to a voxel-space ray (for the box
/// height and the extrude distance), or `None` when the ray runs along the line.
#[must_use]
pub fn line_param(origin: Vec3, dir: Vec3, start: Vec3, axis_dir: Vec3) -> Option<f32> {
    let d = dir.try_normalize()?;
    let a = axis_dir.try_normalize()?;
    let w = start - origin;
    let b = a.dot(d);
    let denom = 1.0 - b * b;
    if denom < 1e-6 {
        return None;
    }
    let s = (b * w.dot(d) - w.dot(a)) / denom;
    s.is_finite().then_some(s / axis_dir.length())
}

fn axis_of(normal: IVec3) -> usize {
    normal.abs().max_position()
}

/// A drag or a two-step gesture in progress.
#[derive(Debug, Clone, PartialEq)]
enum Gesture {
    /// The voxel tool's run on one plane.
    Run {
        object: u64,
        axis: usize,
        coord: i32,
        last: IVec3,
    },
    /// The box tool's rectangle (pressed) and then its height (released, not yet clicked).
    Box {
        object: u64,
        a: IVec3,
        b: IVec3,
        normal: IVec3,
        height: i32,
        sizing_height: bool,
    },
    /// The line tool, from `a` to `b`.
    Line { object: u64, a: IVec3, b: IVec3 },
    /// Push / pull of a face region.
    Extrude {
        object: u64,
        seed: UVec3,
        normal: IVec3,
        face: Vec<UVec3>,
        distance: i32,
    },
    /// A selection rectangle in view points.
    Marquee { start: egui::Pos2, now: egui::Pos2 },
}

/// Paste cells that fall outside the model's volume.
const CLIPPED_COLOR: egui::Color32 = egui::Color32::from_rgb(255, 70, 70);

/// The voxel tools' settings and the gesture in progress.
#[derive(Debug, Clone)]
pub struct VoxelTools {
    /// What shape tools do: add, remove or paint.
    pub op: ShapeOp,
    /// Flood fill stays in the clicked voxel's plane.
    pub fill_plane_only: bool,
    /// A select rectangle takes every voxel inside it (not only the visible surface).
    pub select_through: bool,
    /// What a click of the select tool selects.
    pub click_select: ClickSelect,
    /// Enter grows the canvas to hold a paste that reaches outside it (else it clips, and
    /// Shift+Enter grows).
    pub grow_canvas_on_paste: bool,
    gesture: Option<Gesture>,
    /// A drag of the floating paste in progress.
    paste_drag: Option<PasteDrag>,
    /// A press on a selected voxel with the Select tool: the grab, until the drag moves a
    /// voxel's width and lifts the selection.
    selection_grab: Option<PasteDrag>,
}

/// A drag of the floating paste: it slides in the model plane that faces the camera most,
/// through the point where the drag grabbed it, by whole voxels.
#[derive(Debug, Clone, Copy)]
struct PasteDrag {
    /// The paste's corner when the drag started.
    at: IVec3,
    /// The axis the plane is normal to.
    axis: usize,
    /// The grabbed point (voxel space).
    grab: Vec3,
}

impl Default for VoxelTools {
    fn default() -> Self {
        Self {
            op: ShapeOp::Add,
            fill_plane_only: false,
            select_through: false,
            click_select: ClickSelect::Color,
            grow_canvas_on_paste: false,
            gesture: None,
            paste_drag: None,
            selection_grab: None,
        }
    }
}

/// The state a tool reads each frame.
pub struct ToolInput<'a> {
    /// The view's pointer response.
    pub response: &'a egui::Response,
    /// The pointer's world ray (unit direction), if the pointer is over the view.
    pub ray: Option<(Vec3, Vec3)>,
    /// The projector of the view.
    pub proj: &'a Projector,
    /// The ink of Add and Paint.
    pub ink: Ink,
    /// Mirror copies.
    pub mirror: Mirror,
}

impl VoxelTools {
    /// Whether a gesture is in progress (Esc cancels it first).
    #[must_use]
    pub fn busy(&self) -> bool {
        self.gesture.is_some()
    }

    /// Drops the gesture in progress.
    pub fn cancel(&mut self) {
        self.gesture = None;
    }

    /// The model the tools act on: the selected voxel model, else the one under the pointer.
    fn active_model(editor: &Editor, ray: Option<(Vec3, Vec3)>) -> Option<ModelFrame> {
        let id = editor.selected_voxel_model().or_else(|| {
            ray.and_then(|(o, d)| editor.pick_voxel(o, d))
                .map(|p| p.object)
        })?;
        ModelFrame::of(editor, id)
    }

    /// Where the pointer aims in model `frame`: the solid voxel hit, else the volume's wall.
    #[must_use]
    pub fn target(editor: &Editor, frame: &ModelFrame, ray: (Vec3, Vec3)) -> Option<ToolTarget> {
        let (o, d) = frame.ray(ray.0, ray.1);
        let obj = editor.object(frame.object)?;
        let ObjectKind::Voxels(v) = &obj.kind else {
            return None;
        };
        if let Some(hit) = v.svo.raycast(o.as_dvec3(), d.as_dvec3(), f64::INFINITY)
            && hit.coord.cmplt(frame.size).all()
        {
            return Some(ToolTarget {
                solid: Some(hit.coord),
                normal: hit.normal,
                front: hit.coord.as_ivec3() + hit.normal,
            });
        }
        let (cell, normal) = volume_hit(frame.size, o, d)?;
        Some(ToolTarget {
            solid: None,
            normal,
            front: cell,
        })
    }

    /// Drags the floating paste with the primary button (any tool, Navigate too): a drag
    /// that starts on the paste slides it by whole voxels in the model plane facing the
    /// camera. With the Select tool (`select_tool`), a drag that starts on a selected voxel
    /// moves the selection the same way: once it has moved a voxel the selected voxels lift
    /// out of the model and float ([`Editor::lift_selection`]), and the release writes them
    /// there (one undo step). Returns whether the drag is the paste's or the selection's (the
    /// view then does not orbit and the tool does not act).
    pub fn drag_paste(
        &mut self,
        response: &egui::Response,
        editor: &mut Editor,
        ray: Option<(Vec3, Vec3)>,
        select_tool: bool,
    ) -> bool {
        if select_tool && self.drag_selection(response, editor, ray) {
            return true;
        }
        let Some(f) = editor.floating().cloned() else {
            self.paste_drag = None;
            return false;
        };
        let Some(frame) = ModelFrame::of(editor, f.object) else {
            return false;
        };
        // Grabbed where the button goes down (a drag is recognised only after the pointer
        // has moved, which would shift the grab).
        let (plain, pressed) = response
            .ctx
            .input(|i| (i.modifiers.is_none(), i.pointer.primary_pressed()));
        if pressed
            && response.hovered()
            && plain
            && let Some((o, d)) = ray.map(|(o, d)| frame.ray(o, d))
        {
            let lo = f.at.as_vec3();
            let hi = lo + f.clip.size.as_vec3();
            if let Some(t) = ray_box(o, d, lo, hi) {
                let grab = o + d * t;
                let axis = (0..3)
                    .max_by(|&a, &b| d[a].abs().total_cmp(&d[b].abs()))
                    .unwrap_or(1);
                self.paste_drag = Some(PasteDrag {
                    at: f.at,
                    axis,
                    grab,
                });
            }
        }
        let Some(drag) = self.paste_drag else {
            return false;
        };
        if !response.ctx.input(|i| i.pointer.primary_down()) {
            self.paste_drag = None;
            // A moved selection lands where it was let go.
            if editor.is_lifted() {
                let _ = editor.drop_lifted();
            }
            return true;
        }
        if let Some((o, d)) = ray.map(|(o, d)| frame.ray(o, d))
            && d[drag.axis].abs() > 1e-6
        {
            let t = (drag.grab[drag.axis] - o[drag.axis]) / d[drag.axis];
            let mut delta = (o + d * t - drag.grab).round().as_ivec3();
            delta[drag.axis] = 0;
            editor.place_floating(drag.at + delta);
        }
        true
    }

    /// The Select tool's press on a selected voxel and the drag after it, up to the lift (then
    /// the floating paste's drag carries on). See [`VoxelTools::drag_paste`].
    fn drag_selection(
        &mut self,
        response: &egui::Response,
        editor: &mut Editor,
        ray: Option<(Vec3, Vec3)>,
    ) -> bool {
        let (plain, pressed, down) = response.ctx.input(|i| {
            (
                i.modifiers.is_none(),
                i.pointer.primary_pressed(),
                i.pointer.primary_down(),
            )
        });
        if pressed && response.hovered() && plain && editor.floating().is_none() {
            self.selection_grab = None;
            let grab = editor.voxel_selection().and_then(|sel| {
                let frame = ModelFrame::of(editor, sel.object)?;
                let target = Self::target(editor, &frame, ray?)?;
                let cell = target.solid.filter(|c| sel.cells.contains(*c))?;
                let (o, d) = frame.ray(ray?.0, ray?.1);
                let t = ray_box(o, d, cell.as_vec3(), cell.as_vec3() + Vec3::ONE)?;
                let axis = (0..3)
                    .max_by(|&a, &b| d[a].abs().total_cmp(&d[b].abs()))
                    .unwrap_or(1);
                let at = sel.cells.bounds().map_or(IVec3::ZERO, |b| b.0.as_ivec3());
                Some(PasteDrag {
                    at,
                    axis,
                    grab: o + d * t,
                })
            });
            self.selection_grab = grab;
        }
        let Some(grab) = self.selection_grab else {
            return false;
        };
        if !down {
            // Released before it moved a voxel: nothing to move.
            self.selection_grab = None;
            return true;
        }
        let object = editor.voxel_selection().map(|s| s.object);
        let Some(frame) = object.and_then(|id| ModelFrame::of(editor, id)) else {
            self.selection_grab = None;
            return false;
        };
        if let Some((o, d)) = ray.map(|(o, d)| frame.ray(o, d))
            && d[grab.axis].abs() > 1e-6
        {
            let t = (grab.grab[grab.axis] - o[grab.axis]) / d[grab.axis];
            let mut delta = (o + d * t - grab.grab).round().as_ivec3();
            delta[grab.axis] = 0;
            if delta != IVec3::ZERO && editor.lift_selection().is_ok() {
                // The floating paste's drag takes over from the same grab.
                self.selection_grab = None;
                self.paste_drag = Some(grab);
                editor.place_floating(grab.at + delta);
            }
        }
        true
    }

    /// Runs the tool for this frame: starts, continues, commits or cancels its gesture. Returns
    /// a status message when something was done or refused.
    pub fn handle(
        &mut self,
        kind: ToolKind,
        input: &ToolInput<'_>,
        editor: &mut Editor,
    ) -> Option<Result<String, String>> {
        let r = input.response;
        let (pressed, down, released, clicked) = r.ctx.input(|i| {
            (
                i.pointer.primary_pressed(),
                i.pointer.primary_down(),
                i.pointer.primary_released(),
                i.pointer.primary_clicked(),
            )
        });
        let modifiers = r.ctx.input(|i| i.modifiers);
        let hovered = r.hovered() || r.is_pointer_button_down_on();
        // A shape gesture keeps the model it started on; a marquee works on the active one.
        let frame = match self.gesture.as_ref().and_then(gesture_object) {
            Some(id) => ModelFrame::of(editor, id),
            None => Self::active_model(editor, input.ray),
        };
        // Alt+click picks the colour under the pointer (the eyedropper) in the toolbar instead.
        if modifiers.alt {
            return None;
        }
        match kind {
            ToolKind::Brush => None,
            ToolKind::Select => self.select(input, editor, frame, pressed, down, released, clicked),
            _ => {
                let frame = frame?;
                let target = input.ray.and_then(|ray| Self::target(editor, &frame, ray));
                self.shape(
                    kind, input, editor, &frame, target, hovered, pressed, down, released,
                )
            }
        }
    }

    #[allow(clippy::too_many_arguments)] // the pointer's four states and the tool's context
    fn shape(
        &mut self,
        kind: ToolKind,
        input: &ToolInput<'_>,
        editor: &mut Editor,
        frame: &ModelFrame,
        target: Option<ToolTarget>,
        hovered: bool,
        pressed: bool,
        down: bool,
        released: bool,
    ) -> Option<Result<String, String>> {
        let op = self.op;
        let ray_v = input.ray.map(|(o, d)| frame.ray(o, d));
        let report =
            |what: &str, r: Result<crate::editor::ToolOutcome, crate::editor::CommandError>| {
                Some(r.map(|o| o.message(what)).map_err(|e| e.to_string()))
            };
        match (&mut self.gesture, kind) {
            (None, _) if pressed && hovered => {
                let t = target?;
                match kind {
                    ToolKind::Voxel => {
                        let c = t.cell(op)?;
                        editor.begin_stroke();
                        let axis = axis_of(t.normal);
                        self.gesture = Some(Gesture::Run {
                            object: frame.object,
                            axis,
                            coord: c[axis],
                            last: c,
                        });
                        return report(
                            "Voxel",
                            editor.shape_cells(
                                frame.object,
                                &[c],
                                op,
                                input.ink,
                                input.mirror,
                                true,
                            ),
                        );
                    }
                    ToolKind::Box => {
                        let c = t.cell(op)?;
                        self.gesture = Some(Gesture::Box {
                            object: frame.object,
                            a: c,
                            b: c,
                            normal: t.normal,
                            height: 1,
                            sizing_height: false,
                        });
                    }
                    ToolKind::Line => {
                        let c = t.cell(op)?;
                        self.gesture = Some(Gesture::Line {
                            object: frame.object,
                            a: c,
                            b: c,
                        });
                    }
                    ToolKind::Extrude => {
                        let seed = t.solid?;
                        let face = editor.face_region(frame.object, seed, t.normal);
                        if face.is_empty() {
                            return None;
                        }
                        self.gesture = Some(Gesture::Extrude {
                            object: frame.object,
                            seed,
                            normal: t.normal,
                            face,
                            distance: 0,
                        });
                    }
                    ToolKind::Fill => {
                        let seed = t.solid?;
                        let plane = self.fill_plane_only.then(|| axis_of(t.normal));
                        return report(
                            "Fill",
                            editor.flood_fill(frame.object, seed, t.normal, plane, op, input.ink),
                        );
                    }
                    ToolKind::Brush | ToolKind::Select => {}
                }
                None
            }
            (
                Some(Gesture::Run {
                    object,
                    axis,
                    coord,
                    last,
                }),
                _,
            ) => {
                if !down {
                    self.gesture = None;
                    editor.end_interaction();
                    return None;
                }
                let (object, axis, coord) = (*object, *axis, *coord);
                let c = match op {
                    ShapeOp::Add => ray_v.and_then(|(o, d)| plane_cell(o, d, axis, coord))?,
                    // Remove and paint follow the surface under the pointer.
                    ShapeOp::Remove | ShapeOp::Paint => target?.solid?.as_ivec3(),
                };
                if c == *last {
                    return None;
                }
                // Every cell between the last one and this one, so a fast drag leaves no gaps.
                let cells = shapes::line_cells(*last, c);
                *last = c;
                report(
                    "Voxel",
                    editor.shape_cells(object, &cells, op, input.ink, input.mirror, true),
                )
            }
            (
                Some(Gesture::Box {
                    object,
                    a,
                    b,
                    normal,
                    height,
                    sizing_height,
                }),
                _,
            ) => {
                let axis = axis_of(*normal);
                if *sizing_height {
                    // Height: where the pointer ray passes the normal line through the far corner.
                    if let Some((o, d)) = ray_v {
                        let start = b.as_vec3() + 0.5;
                        if let Some(s) = line_param(o, d, start, normal.as_vec3()) {
                            let h = s.round() as i32;
                            *height = if h >= 0 { h + 1 } else { h - 1 };
                        }
                    }
                    if pressed && hovered {
                        let (lo, hi) = box_corners(*a, *b, *normal, *height);
                        let object = *object;
                        self.gesture = None;
                        return report(
                            "Box",
                            editor.shape_box(object, lo, hi, op, input.ink, input.mirror),
                        );
                    }
                    return None;
                }
                if let Some((o, d)) = ray_v
                    && let Some(c) = plane_cell(o, d, axis, a[axis])
                {
                    *b = c;
                }
                if released || !down {
                    *sizing_height = true;
                }
                None
            }
            (Some(Gesture::Line { object, a, b }), _) => {
                if let Some(t) = target
                    && let Some(c) = t.cell(op)
                {
                    *b = c;
                }
                if released || !down {
                    let (object, a, b) = (*object, *a, *b);
                    self.gesture = None;
                    let cells = shapes::line_cells(a, b);
                    return report(
                        "Line",
                        editor.shape_cells(object, &cells, op, input.ink, input.mirror, false),
                    );
                }
                None
            }
            (
                Some(Gesture::Extrude {
                    object,
                    seed,
                    normal,
                    distance,
                    ..
                }),
                _,
            ) => {
                if let Some((o, d)) = ray_v {
                    let start = seed.as_vec3() + 0.5 + normal.as_vec3() * 0.5;
                    if let Some(s) = line_param(o, d, start, normal.as_vec3()) {
                        *distance = s.round() as i32;
                    }
                }
                if released || !down {
                    let (object, seed, normal, distance) = (*object, *seed, *normal, *distance);
                    self.gesture = None;
                    return report(
                        "Extrude",
                        editor.extrude_face(object, seed, normal, distance),
                    );
                }
                None
            }
            _ => None,
        }
    }

    #[allow(clippy::too_many_arguments)] // the pointer's four states and the tool's context
    fn select(
        &mut self,
        input: &ToolInput<'_>,
        editor: &mut Editor,
        frame: Option<ModelFrame>,
        pressed: bool,
        down: bool,
        released: bool,
        clicked: bool,
    ) -> Option<Result<String, String>> {
        let r = input.response;
        let modifiers = r.ctx.input(|i| i.modifiers);
        let mode = if modifiers.shift {
            SelectMode::Add
        } else if modifiers.command {
            SelectMode::Subtract
        } else {
            SelectMode::Replace
        };
        let pos = r.interact_pointer_pos().or_else(|| r.hover_pos());
        match &mut self.gesture {
            None if pressed && (r.hovered() || r.is_pointer_button_down_on()) => {
                let p = pos?;
                self.gesture = Some(Gesture::Marquee { start: p, now: p });
                None
            }
            Some(Gesture::Marquee { start, now }) => {
                if let Some(p) = pos {
                    *now = p;
                }
                if !(released || clicked || !down) {
                    return None;
                }
                let (start, now) = (*start, *now);
                self.gesture = None;
                let frame = frame?;
                if start.distance(now) < 4.0 {
                    // A click: colour or connected part under the pointer.
                    let t = input
                        .ray
                        .and_then(|ray| Self::target(editor, &frame, ray))?;
                    let Some(at) = t.solid else {
                        if mode == SelectMode::Replace {
                            editor.clear_voxel_selection();
                        }
                        return Some(Ok("Selection cleared".into()));
                    };
                    let result = match self.click_select {
                        ClickSelect::Color => editor.select_color_at(frame.object, at, mode),
                        ClickSelect::Connected => {
                            editor.select_connected_at(frame.object, at, true, mode)
                        }
                    };
                    return Some(
                        result
                            .map(|n| format!("{n} voxels selected"))
                            .map_err(|e| e.to_string()),
                    );
                }
                let rect = egui::Rect::from_two_pos(start, now);
                let to_ndc = |p: egui::Pos2| {
                    Vec2::new(
                        (p.x - input.proj.rect.left()) / input.proj.rect.width() * 2.0 - 1.0,
                        1.0 - (p.y - input.proj.rect.top()) / input.proj.rect.height() * 2.0,
                    )
                };
                let (a, b) = (to_ndc(rect.left_bottom()), to_ndc(rect.right_top()));
                let clip_from_voxel = input.proj.clip_from_world * frame.world_from_voxel;
                let cam = input.proj.camera;
                let view = if cam.orthographic {
                    SurfaceView::Direction(
                        frame
                            .voxel_from_world
                            .transform_vector3(cam.target - cam.eye()),
                    )
                } else {
                    SurfaceView::Eye(frame.voxel_from_world.transform_point3(cam.eye()))
                };
                let surface = (!self.select_through).then_some(view);
                let cells = {
                    let o = editor.object(frame.object)?;
                    let ObjectKind::Voxels(v) = &o.kind else {
                        return None;
                    };
                    select_in_rect(&v.svo, frame.size, clip_from_voxel, a, b, surface)
                };
                Some(match cells {
                    Ok(cells) => editor
                        .select_voxels(frame.object, cells, mode)
                        .map(|n| format!("{n} voxels selected"))
                        .map_err(|e| e.to_string()),
                    Err(e) => Err(e.to_string()),
                })
            }
            _ => None,
        }
    }

    /// The cells the gesture in progress would write (for the preview), in voxel space, and
    /// whether they are removed (drawn red) rather than added or painted.
    fn preview_cells(&self, editor: &Editor) -> Option<(u64, PreviewShape)> {
        match self.gesture.as_ref()? {
            Gesture::Run { .. } | Gesture::Marquee { .. } => None,
            Gesture::Box {
                object,
                a,
                b,
                normal,
                height,
                sizing_height,
            } => {
                let h = if *sizing_height { *height } else { 1 };
                let (lo, hi) = box_corners(*a, *b, *normal, h);
                Some((*object, PreviewShape::Box(lo, hi)))
            }
            Gesture::Line { object, a, b } => {
                Some((*object, PreviewShape::Cells(shapes::line_cells(*a, *b))))
            }
            Gesture::Extrude {
                object,
                face,
                normal,
                distance,
                ..
            } => {
                let _ = editor;
                Some((
                    *object,
                    PreviewShape::Cells(shapes::extrude_cells(face, *normal, *distance)),
                ))
            }
        }
    }

    /// Draws the tool's preview (the exact voxels the gesture writes), the hover target, the
    /// marquee, the selection outline and the floating paste.
    pub fn paint(
        &self,
        kind: ToolKind,
        painter: &egui::Painter,
        proj: &Projector,
        editor: &Editor,
        input_ray: Option<(Vec3, Vec3)>,
        active: bool,
    ) {
        paint_selection(painter, proj, editor);
        if let Some(f) = editor.floating()
            && let Some(frame) = ModelFrame::of(editor, f.object)
        {
            // Cells outside the volume in red: a plain commit would drop them.
            let size = frame.size.as_ivec3();
            let (inside, outside): (Vec<IVec3>, Vec<IVec3>) =
                thicket_core::sculpt::select::paste_cells(&f.clip, f.at)
                    .into_iter()
                    .partition(|c| c.min_element() >= 0 && c.cmplt(size).all());
            paint_cells(
                painter,
                proj,
                &frame,
                &inside,
                egui::Color32::from_rgb(80, 200, 255),
            );
            if !outside.is_empty() {
                paint_any_cells(painter, proj, &frame, &outside, CLIPPED_COLOR);
                let text = if self.grow_canvas_on_paste {
                    format!(
                        "{} voxel(s) outside the volume (red): Enter grows the canvas",
                        outside.len()
                    )
                } else {
                    format!(
                        "{} voxel(s) outside the volume (red): Enter drops them, \
                         Shift+Enter grows the canvas",
                        outside.len()
                    )
                };
                let galley = painter.layout(
                    text,
                    egui::FontId::proportional(14.0),
                    CLIPPED_COLOR,
                    proj.rect.width() - 24.0,
                );
                let at = proj.rect.left_bottom() + egui::vec2(8.0, -12.0 - galley.size().y);
                painter.rect_filled(
                    egui::Rect::from_min_size(at, galley.size()).expand(4.0),
                    3.0,
                    egui::Color32::from_black_alpha(200),
                );
                painter.galley(at, galley, CLIPPED_COLOR);
            }
        }
        if !active {
            return;
        }
        if let Some(Gesture::Marquee { start, now }) = &self.gesture {
            let rect = egui::Rect::from_two_pos(*start, *now);
            painter.rect_filled(
                rect,
                0.0,
                egui::Color32::from_rgba_unmultiplied(255, 200, 40, 30),
            );
            painter.rect_stroke(
                rect,
                0.0,
                egui::Stroke::new(1.0, SELECTION_OUTLINE),
                egui::StrokeKind::Middle,
            );
        }
        let color = match self.op {
            ShapeOp::Add => egui::Color32::WHITE,
            ShapeOp::Remove => egui::Color32::from_rgb(255, 80, 80),
            ShapeOp::Paint => egui::Color32::from_rgb(120, 255, 120),
        };
        if let Some((object, shape)) = self.preview_cells(editor)
            && let Some(frame) = ModelFrame::of(editor, object)
        {
            match shape {
                PreviewShape::Box(lo, hi) => {
                    let lo = lo.max(IVec3::ZERO);
                    let hi = hi.min(frame.size.as_ivec3() - 1);
                    if lo.cmple(hi).all() {
                        cuboid(
                            painter,
                            proj,
                            &frame,
                            lo.as_vec3(),
                            (hi + 1).as_vec3(),
                            color,
                            2.0,
                        );
                        let n = (hi - lo + 1).as_i64vec3();
                        if let Some(p) = proj.to_screen(frame.world((hi + 1).as_vec3())) {
                            painter.text(
                                p,
                                egui::Align2::LEFT_BOTTOM,
                                format!("{}×{}×{}", n.x, n.y, n.z),
                                egui::FontId::proportional(13.0),
                                color,
                            );
                        }
                    }
                }
                PreviewShape::Cells(cells) => paint_cells(painter, proj, &frame, &cells, color),
            }
            return;
        }
        // Hover: the cell the next click acts on.
        if kind != ToolKind::Brush
            && kind != ToolKind::Select
            && let Some(frame) = Self::active_model(editor, input_ray)
            && let Some(t) = input_ray.and_then(|ray| Self::target(editor, &frame, ray))
            && let Some(c) = t.cell(self.op)
        {
            cuboid(
                painter,
                proj,
                &frame,
                c.as_vec3(),
                (c + 1).as_vec3(),
                color,
                1.5,
            );
        }
    }
}

enum PreviewShape {
    Box(IVec3, IVec3),
    Cells(Vec<IVec3>),
}

fn gesture_object(g: &Gesture) -> Option<u64> {
    match g {
        Gesture::Run { object, .. }
        | Gesture::Box { object, .. }
        | Gesture::Line { object, .. }
        | Gesture::Extrude { object, .. } => Some(*object),
        Gesture::Marquee { .. } => None,
    }
}

/// The box between rectangle corners `a`, `b` (on one layer) grown `height` layers along
/// `normal` (negative: into the surface).
#[must_use]
pub fn box_corners(a: IVec3, b: IVec3, normal: IVec3, height: i32) -> (IVec3, IVec3) {
    let far = if height >= 0 {
        b + normal * (height - 1).max(0)
    } else {
        b + normal * (height + 1)
    };
    (a.min(b).min(far), a.max(b).max(far))
}

/// Draws the edges of the voxel-space box `[lo, hi]`.
fn cuboid(
    painter: &egui::Painter,
    proj: &Projector,
    frame: &ModelFrame,
    lo: Vec3,
    hi: Vec3,
    color: egui::Color32,
    width: f32,
) {
    let corner = |i: u8| {
        frame.world(Vec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        ))
    };
    for (i, j) in CUBE_EDGES {
        if let (Some(a), Some(b)) = (proj.to_screen(corner(i)), proj.to_screen(corner(j))) {
            painter.line_segment([a, b], egui::Stroke::new(width, color));
        }
    }
}

const CUBE_EDGES: [(u8, u8); 12] = [
    (0, 1),
    (2, 3),
    (4, 5),
    (6, 7),
    (0, 2),
    (1, 3),
    (4, 6),
    (5, 7),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

/// Draws each cell's edges (or, for many cells, their bounding box), clipped to the volume.
fn paint_cells(
    painter: &egui::Painter,
    proj: &Projector,
    frame: &ModelFrame,
    cells: &[IVec3],
    color: egui::Color32,
) {
    let size = frame.size.as_ivec3();
    let inside: Vec<IVec3> = cells
        .iter()
        .copied()
        .filter(|c| c.min_element() >= 0 && c.cmplt(size).all())
        .collect();
    paint_any_cells(painter, proj, frame, &inside, color);
}

/// [`paint_cells`] without the volume's clip: cells outside it too (a paste's clipped part).
fn paint_any_cells(
    painter: &egui::Painter,
    proj: &Projector,
    frame: &ModelFrame,
    inside: &[IVec3],
    color: egui::Color32,
) {
    if inside.len() > MAX_PREVIEW_CELLS {
        let lo = inside.iter().fold(IVec3::MAX, |a, c| a.min(*c));
        let hi = inside.iter().fold(IVec3::MIN, |a, c| a.max(*c));
        cuboid(
            painter,
            proj,
            frame,
            lo.as_vec3(),
            (hi + 1).as_vec3(),
            color,
            2.0,
        );
        return;
    }
    for &c in inside {
        cuboid(
            painter,
            proj,
            frame,
            c.as_vec3(),
            (c + 1).as_vec3(),
            color,
            1.0,
        );
    }
}

/// The voxel selection: its boundary faces that face the camera, filled and outlined.
fn paint_selection(painter: &egui::Painter, proj: &Projector, editor: &Editor) {
    let Some(sel) = editor.voxel_selection() else {
        return;
    };
    let Some(frame) = ModelFrame::of(editor, sel.object) else {
        return;
    };
    let cam = proj.camera;
    let eye = frame.voxel_from_world.transform_point3(cam.eye());
    let view_back = frame
        .voxel_from_world
        .transform_vector3(cam.eye() - cam.target);
    // Towards the viewer from a point (the view axis in an orthographic view).
    let toward_eye = |p: Vec3| if cam.orthographic { view_back } else { eye - p };
    let cells = &sel.cells;
    let mut faces = 0usize;
    let fill = egui::Color32::from_rgba_unmultiplied(255, 200, 40, 70);
    let stroke = egui::Stroke::new(1.0, SELECTION_OUTLINE);
    if cells.len() <= MAX_OUTLINE_FACES {
        for c in cells.iter() {
            for axis in 0..3 {
                for sign in [-1i32, 1] {
                    let mut n = IVec3::ZERO;
                    n[axis] = sign;
                    let nb = c.as_ivec3() + n;
                    if nb.min_element() >= 0 && cells.contains(nb.as_uvec3()) {
                        continue;
                    }
                    // Only faces turned toward the eye.
                    let face_center = c.as_vec3() + 0.5 + n.as_vec3() * 0.5;
                    if toward_eye(face_center).dot(n.as_vec3()) <= 0.0 {
                        continue;
                    }
                    faces += 1;
                    if faces > MAX_OUTLINE_FACES {
                        break;
                    }
                    let quad = face_quad(c.as_vec3(), axis, sign);
                    let pts: Option<Vec<egui::Pos2>> = quad
                        .iter()
                        .map(|p| proj.to_screen(frame.world(*p)))
                        .collect();
                    if let Some(pts) = pts {
                        painter.add(egui::Shape::convex_polygon(pts, fill, stroke));
                    }
                }
            }
        }
    }
    if let Some((lo, hi)) = cells.bounds() {
        cuboid(
            painter,
            proj,
            &frame,
            lo.as_vec3(),
            (hi + 1).as_vec3(),
            SELECTION_OUTLINE,
            1.0,
        );
    }
}

/// The four corners of the face of cell `c` across `axis` on the `sign` side.
fn face_quad(c: Vec3, axis: usize, sign: i32) -> [Vec3; 4] {
    let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
    let mut base = c;
    if sign > 0 {
        base[axis] += 1.0;
    }
    let mut du = Vec3::ZERO;
    du[u] = 1.0;
    let mut dw = Vec3::ZERO;
    dw[w] = 1.0;
    [base, base + du, base + du + dw, base + dw]
}

/// The active voxel model's volume box and an editing grid on its floor (every voxel up to 64
/// per axis, else every 8th or coarser), drawn with `line` (world-space ends; the view hides
/// the parts behind voxels).
pub fn paint_volume(editor: &Editor, line: &impl Fn(Vec3, Vec3, egui::Stroke)) {
    let Some(id) = editor.selected_voxel_model() else {
        return;
    };
    let Some(frame) = ModelFrame::of(editor, id) else {
        return;
    };
    let size = frame.size;
    let faint = egui::Stroke::new(
        1.0,
        egui::Color32::from_rgba_unmultiplied(180, 190, 210, 60),
    );
    let edge = egui::Stroke::new(
        1.0,
        egui::Color32::from_rgba_unmultiplied(200, 210, 230, 140),
    );
    let hi = size.as_vec3();
    let corner = |i: u8| {
        frame.world(Vec3::new(
            if i & 1 == 0 { 0.0 } else { hi.x },
            if i & 2 == 0 { 0.0 } else { hi.y },
            if i & 4 == 0 { 0.0 } else { hi.z },
        ))
    };
    for (i, j) in CUBE_EDGES {
        line(corner(i), corner(j), edge);
    }
    let step = |n: u32| {
        let mut s = 1;
        while n / s > 64 {
            s *= 2;
        }
        s
    };
    let (sx, sz) = (step(size.x), step(size.z));
    let floor = |a: Vec3, b: Vec3| line(frame.world(a), frame.world(b), faint);
    let mut x = 0;
    while x <= size.x {
        floor(
            Vec3::new(x as f32, 0.0, 0.0),
            Vec3::new(x as f32, 0.0, size.z as f32),
        );
        x += sx;
    }
    let mut z = 0;
    while z <= size.z {
        floor(
            Vec3::new(0.0, 0.0, z as f32),
            Vec3::new(size.x as f32, 0.0, z as f32),
        );
        z += sz;
    }
}

/// Where a ray (voxel space) enters the box `lo..hi`, as its parameter (0 when it starts
/// inside); `None` when it misses.
fn ray_box(o: Vec3, d: Vec3, lo: Vec3, hi: Vec3) -> Option<f32> {
    let (mut t0, mut t1) = (0.0f32, f32::INFINITY);
    for a in 0..3 {
        if d[a].abs() < 1e-12 {
            if o[a] < lo[a] || o[a] > hi[a] {
                return None;
            }
            continue;
        }
        let (ta, tb) = ((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    (t0 <= t1).then_some(t0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ray_from_above_hits_the_volume_floor() {
        let size = UVec3::new(8, 4, 6);
        let (cell, normal) =
            volume_hit(size, Vec3::new(2.5, 10.0, 3.5), Vec3::new(0.0, -1.0, 0.0)).unwrap();
        assert_eq!((cell, normal), (IVec3::new(2, 0, 3), IVec3::Y));
        // From the front (+Z looking -Z) the back wall at z = 0 is hit.
        let (cell, normal) =
            volume_hit(size, Vec3::new(1.5, 2.5, 20.0), Vec3::new(0.0, 0.0, -1.0)).unwrap();
        assert_eq!((cell, normal), (IVec3::new(1, 2, 0), IVec3::Z));
        // From below, looking up, the ceiling.
        let (cell, normal) =
            volume_hit(size, Vec3::new(7.5, -3.0, 5.5), Vec3::new(0.0, 1.0, 0.0)).unwrap();
        assert_eq!((cell, normal), (IVec3::new(7, 3, 5), IVec3::NEG_Y));
        // A ray that misses the box, and degenerate rays.
        assert!(volume_hit(size, Vec3::new(20.0, 10.0, 3.0), Vec3::NEG_Y).is_none());
        assert!(volume_hit(size, Vec3::ZERO, Vec3::ZERO).is_none());
        assert!(volume_hit(size, Vec3::NAN, Vec3::Y).is_none());
    }

    #[test]
    fn plane_cells_and_line_parameters() {
        // A ray down through y = 2.5 at x = 3.2, z = 1.7.
        let c = plane_cell(Vec3::new(3.2, 9.0, 1.7), Vec3::NEG_Y, 1, 2).unwrap();
        assert_eq!(c, IVec3::new(3, 2, 1));
        // Parallel to the plane, or the plane behind the ray.
        assert!(plane_cell(Vec3::ZERO, Vec3::X, 1, 2).is_none());
        assert!(plane_cell(Vec3::new(0.0, 9.0, 0.0), Vec3::Y, 1, 2).is_none());
        // The line x = 0.5, z = 0.5 along +Y; a ray along +X at height 4.
        let s = line_param(
            Vec3::new(-5.0, 4.0, 0.5),
            Vec3::X,
            Vec3::new(0.5, 0.5, 0.5),
            Vec3::Y,
        )
        .unwrap();
        assert!((s - 3.5).abs() < 1e-4, "{s}");
        assert!(line_param(Vec3::ZERO, Vec3::Y, Vec3::ZERO, Vec3::Y).is_none());
    }

    #[test]
    fn box_corners_grow_along_the_normal() {
        let (lo, hi) = box_corners(IVec3::new(4, 0, 1), IVec3::new(1, 0, 3), IVec3::Y, 3);
        assert_eq!((lo, hi), (IVec3::new(1, 0, 1), IVec3::new(4, 2, 3)));
        let (lo, hi) = box_corners(IVec3::new(2, 5, 2), IVec3::new(2, 5, 2), IVec3::Y, -2);
        assert_eq!((lo, hi), (IVec3::new(2, 4, 2), IVec3::new(2, 5, 2)));
        let (lo, hi) = box_corners(IVec3::ZERO, IVec3::ZERO, IVec3::NEG_X, 1);
        assert_eq!((lo, hi), (IVec3::ZERO, IVec3::ZERO));
    }
}
