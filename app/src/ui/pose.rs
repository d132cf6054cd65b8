//! The pose tool: the skeleton drawn over the view, joint picking (tree or view), a transform
//! gizmo (axis rings to rotate, axis arrows to move) whose drag is one undo step, the joint's
//! override values, the stretch settings, and the timeline that plays and scrubs clips.

use glam::{Quat, Vec3};
use thicket_core::scene::ObjectKind;
use thicket_core::skin::{JointOverride, OverrideMode, StretchStrategy, Wrap};

use super::projector::Projector;
use crate::editor::{Editor, JointFrames, Selection};

/// Gizmo ring radius / arrow length in view points.
const GIZMO_PX: f32 = 70.0;
/// How close (points) the pointer must be to a handle or a joint dot to grab it.
const GRAB_PX: f32 = 8.0;
/// Segments of a rotation ring.
const RING_SEGMENTS: usize = 48;

const AXIS_COLORS: [egui::Color32; 3] = [
    egui::Color32::from_rgb(230, 80, 80),
    egui::Color32::from_rgb(90, 210, 90),
    egui::Color32::from_rgb(80, 140, 240),
];
const AXIS_NAMES: [&str; 3] = ["X", "Y", "Z"];

/// What the gizmo does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GizmoMode {
    /// Rings about the joint's own axes.
    Rotate,
    /// Arrows along the axes of the joint's parent frame (where its translation lives).
    Translate,
    /// Square-ended handles along the joint's own axes: dragging one stretches the joint
    /// (and everything below it) along that axis.
    Scale,
    /// Arrows along the model's own axes that move the joint's rest position (the skeleton
    /// itself, not a pose): the gizmo while the Rig section's Place joints is on.
    Rest,
    /// Arrows along the model's own axes that move an IK target for the joint: its parent and
    /// grandparent turn so the joint follows (Move with IK on).
    Ik,
}

/// Where an IK limb's middle joint (knee, elbow) bends toward.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IkPole {
    /// The way it bends now.
    AsNow,
    /// Toward the model's +X, −X, +Y, −Y, +Z or −Z.
    Axis(usize, bool),
}

impl IkPole {
    /// Every choice, in menu order.
    pub const ALL: [Self; 7] = [
        Self::AsNow,
        Self::Axis(2, true),
        Self::Axis(2, false),
        Self::Axis(0, true),
        Self::Axis(0, false),
        Self::Axis(1, true),
        Self::Axis(1, false),
    ];

    /// The menu label.
    #[must_use]
    pub fn label(self) -> &'static str {
        match self {
            Self::AsNow => "as it bends now",
            Self::Axis(0, true) => "+X",
            Self::Axis(0, false) => "-X",
            Self::Axis(1, true) => "+Y",
            Self::Axis(1, false) => "-Y",
            Self::Axis(2, true) => "+Z (front)",
            Self::Axis(_, _) => "-Z (back)",
        }
    }
}

/// A joint of a rigged object.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct JointRef {
    /// The object id.
    pub object: u64,
    /// The joint index in its skeleton.
    pub joint: usize,
}

/// A gizmo drag in progress: everything is measured from where it started, so the joint
/// follows the pointer without accumulating error.
#[derive(Debug, Clone, Copy)]
struct GizmoDrag {
    joint: JointRef,
    axis: usize,
    mode: GizmoMode,
    /// The joint's override when the drag started.
    base: Option<JointOverride>,
    start: egui::Pos2,
    /// The joint on the screen when the drag started.
    center: egui::Pos2,
    /// +1 when the ring's axis points toward the viewer (a counter-clockwise drag on the
    /// screen is then a positive rotation), -1 otherwise.
    sign: f32,
    /// Translate: the arrow on the screen (points) and the local translation it stands for.
    arrow_px: egui::Vec2,
    arrow_local: f32,
    /// Rest: the joint's rest position (model space) when the drag started. IK: the joint's
    /// world position when the drag started.
    rest_start: Vec3,
}

/// The pose tool's state.
#[derive(Debug)]
pub struct PoseTool {
    /// The selected joint.
    pub joint: Option<JointRef>,
    /// Rotate or translate.
    pub mode: GizmoMode,
    /// Draw skeletons over the view.
    pub show_skeleton: bool,
    /// The timeline is playing.
    pub playing: bool,
    /// Advance the clip by one of its frames per drawn frame instead of by the wall
    /// clock (every pose is shown, in slow motion when frames are slow).
    pub step_every_frame: bool,
    /// The UI time of the last playing frame (None while paused).
    last_tick: Option<f64>,
    drag: Option<GizmoDrag>,
    /// Why the last pose / stretch / playback change was refused.
    pub error: Option<String>,
    /// The joint the inspector's joint list last scrolled to: a joint picked in the view is
    /// scrolled into the list once, and the list is then free to scroll.
    listed: Option<JointRef>,
    /// Rig setup (skeleton authoring, binding, weights, clips): see `ui::rig_panel`.
    pub rig: super::rig_setup::RigSetup,
    /// The last binding's summary, shown in the Rig section.
    pub rig_report: Option<String>,
    /// Auto-key: every finished gizmo drag keys the joint at the playhead.
    pub auto_key: bool,
    /// The dope sheet under the timeline.
    pub dope: super::dope_sheet::DopeSheet,
    /// Move drags the selected joint as an IK target (two bones above it turn).
    pub ik: bool,
    /// Where IK limbs bend.
    pub ik_pole: IkPole,
    /// Whether the last IK drag's target was within reach.
    pub ik_reached: Option<bool>,
    /// The joints the last paint drew, per object (world positions, every joint in order):
    /// clicks pick the dots where they were drawn, and tests check the skeleton follows the
    /// image's pose.
    pub painted: Vec<(u64, Vec<Vec3>)>,
}

impl Default for PoseTool {
    fn default() -> Self {
        Self {
            joint: None,
            mode: GizmoMode::Rotate,
            show_skeleton: true,
            playing: false,
            step_every_frame: false,
            last_tick: None,
            drag: None,
            error: None,
            listed: None,
            rig: super::rig_setup::RigSetup::default(),
            rig_report: None,
            auto_key: false,
            dope: super::dope_sheet::DopeSheet::default(),
            ik: false,
            ik_pole: IkPole::AsNow,
            ik_reached: None,
            painted: Vec::new(),
        }
    }
}

/// The time one frame of a frame sequence (an animated `.vox`) advances with "Every frame"
/// (30 frames per second); a clip advances by one of its own frames.
pub const FRAME_STEP_SECS: f32 = 1.0 / 30.0;

/// The most clip time one frame advances by the wall clock: after a stall (a blocking dialog,
/// a suspended window) the clip goes on from where it was instead of jumping.
const MAX_PLAYBACK_STEP_SECS: f64 = 1.0;

/// Clip seconds to advance this frame: the UI time since the last playing frame (frames are
/// dropped when drawing is slow, so the clip keeps real time; 0 on the first frame), or one
/// `frame_secs` per frame when given (every frame shown, "Every frame").
#[must_use]
pub fn playback_step(last_tick: &mut Option<f64>, now: f64, frame_secs: Option<f32>) -> f32 {
    let elapsed = last_tick.map_or(0.0, |t| (now - t).clamp(0.0, MAX_PLAYBACK_STEP_SECS));
    *last_tick = Some(now);
    frame_secs.unwrap_or(elapsed as f32)
}

/// A drawn handle: its axis and its polyline on the screen.
struct Handle {
    axis: usize,
    points: Vec<egui::Pos2>,
}

/// Distance in points from `p` to a polyline.
pub(super) fn distance_to_polyline(p: egui::Pos2, points: &[egui::Pos2]) -> f32 {
    points
        .windows(2)
        .map(|w| {
            let (a, b) = (w[0], w[1]);
            let ab = b - a;
            let t = ((p - a).dot(ab) / ab.length_sq().max(1e-6)).clamp(0.0, 1.0);
            p.distance(a + ab * t)
        })
        .fold(f32::INFINITY, f32::min)
}

impl PoseTool {
    /// The selected joint, when it still exists in the document.
    #[must_use]
    pub fn valid_joint(&self, editor: &Editor) -> Option<JointRef> {
        let j = self.joint?;
        (editor.rig(j.object)?.skeleton.len() > j.joint).then_some(j)
    }

    /// Whether a gizmo drag is in progress.
    #[must_use]
    pub fn dragging(&self) -> bool {
        self.drag.is_some()
    }

    /// What the gizmo does now: [`GizmoMode::Rest`] while joints are being placed (the
    /// skeleton is being edited), else the chosen mode.
    #[must_use]
    pub fn active_mode(&self) -> GizmoMode {
        if self.rig.placing {
            GizmoMode::Rest
        } else if self.ik && self.mode == GizmoMode::Translate {
            GizmoMode::Ik
        } else {
            self.mode
        }
    }

    fn handles(&self, frames: &JointFrames, joint: usize, proj: &Projector) -> Vec<Handle> {
        let (Some(w), Some(parent)) = (
            frames.world_from_joint.get(joint),
            frames.world_from_parent.get(joint),
        ) else {
            return Vec::new();
        };
        let p = w.w_axis.truncate();
        let size = GIZMO_PX * proj.world_per_point(p);
        let mut out = Vec::new();
        for axis in 0..3 {
            match self.active_mode() {
                GizmoMode::Rotate => {
                    let Some(a) = w.col(axis).truncate().try_normalize() else {
                        continue;
                    };
                    let (u, v) = a.any_orthonormal_pair();
                    let points: Option<Vec<egui::Pos2>> = (0..=RING_SEGMENTS)
                        .map(|i| {
                            let t = i as f32 / RING_SEGMENTS as f32 * std::f32::consts::TAU;
                            proj.to_screen(p + size * (t.cos() * u + t.sin() * v))
                        })
                        .collect();
                    if let Some(points) = points {
                        out.push(Handle { axis, points });
                    }
                }
                GizmoMode::Scale => {
                    let Some(d) = w.col(axis).truncate().try_normalize() else {
                        continue;
                    };
                    if let (Some(a), Some(b)) = (proj.to_screen(p), proj.to_screen(p + d * size)) {
                        out.push(Handle {
                            axis,
                            points: vec![a, b],
                        });
                    }
                }
                GizmoMode::Translate | GizmoMode::Rest | GizmoMode::Ik => {
                    let frame = if matches!(self.active_mode(), GizmoMode::Rest | GizmoMode::Ik) {
                        frames.world_from_object
                    } else {
                        *parent
                    };
                    let Some(d) = frame.col(axis).truncate().try_normalize() else {
                        continue;
                    };
                    if let (Some(a), Some(b)) = (proj.to_screen(p), proj.to_screen(p + d * size)) {
                        out.push(Handle {
                            axis,
                            points: vec![a, b],
                        });
                    }
                }
            }
        }
        out
    }

    /// Handles the gizmo: a drag that starts on a handle moves the selected joint (one undo
    /// step). Returns whether the gizmo owns the pointer this frame (the view then does not
    /// orbit).
    pub fn interact(
        &mut self,
        ui: &egui::Ui,
        response: &egui::Response,
        editor: &mut Editor,
        proj: &Projector,
    ) -> bool {
        let Some(sel) = self.valid_joint(editor) else {
            self.drag = None;
            return false;
        };
        if response.drag_started_by(egui::PointerButton::Primary)
            && !ui.input(|i| i.modifiers.alt || i.modifiers.shift)
            && let Some(start) = ui.input(|i| i.pointer.press_origin())
            && let Some(frames) = editor.joint_frames(sel.object)
        {
            let grabbed = self
                .handles(&frames, sel.joint, proj)
                .into_iter()
                .map(|h| (distance_to_polyline(start, &h.points), h))
                .filter(|(d, _)| *d <= GRAB_PX)
                .min_by(|a, b| a.0.total_cmp(&b.0));
            if let Some((_, h)) = grabbed
                && let Some(p) = frames.position(sel.joint)
                && let Some(center) = proj.to_screen(p)
            {
                let w = frames.world_from_joint[sel.joint];
                let mode = self.active_mode();
                let parent = if matches!(mode, GizmoMode::Rest | GizmoMode::Ik) {
                    frames.world_from_object
                } else {
                    frames.world_from_parent[sel.joint]
                };
                let axis_world = w.col(h.axis).truncate();
                let sign = if axis_world.dot(proj.toward_eye(p)) >= 0.0 {
                    1.0
                } else {
                    -1.0
                };
                let parent_axis = parent.col(h.axis).truncate();
                let size = GIZMO_PX * proj.world_per_point(p);
                // The arrow is `size` world units long; a unit of local translation moves the
                // joint by the parent axis's length.
                let (arrow_px, arrow_local) = match mode {
                    GizmoMode::Translate | GizmoMode::Rest | GizmoMode::Ik
                        if parent_axis.length_squared() > 1e-24 =>
                    {
                        (
                            h.points.last().map_or(egui::Vec2::ZERO, |e| *e - center),
                            size / parent_axis.length(),
                        )
                    }
                    // Scale: dragging the handle's length once more doubles the axis.
                    GizmoMode::Scale => (
                        h.points.last().map_or(egui::Vec2::ZERO, |e| *e - center),
                        1.0,
                    ),
                    _ => (egui::Vec2::ZERO, 0.0),
                };
                // A new drag is a new undo step.
                editor.end_interaction();
                let rest_start = if mode == GizmoMode::Ik {
                    p
                } else {
                    editor
                        .skeleton_spec(sel.object)
                        .ok()
                        .and_then(|s| s.joints.get(sel.joint).map(|j| Vec3::from(j.position)))
                        .unwrap_or(Vec3::ZERO)
                };
                self.drag = Some(GizmoDrag {
                    joint: sel,
                    axis: h.axis,
                    mode,
                    base: editor.joint_override(sel.object, sel.joint),
                    start,
                    center,
                    sign,
                    arrow_px,
                    arrow_local,
                    rest_start,
                });
            }
        }
        let Some(drag) = self.drag else {
            return false;
        };
        if !ui.input(|i| i.pointer.primary_down()) {
            self.drag = None;
            // Auto-key: a finished drag keys the joint at the playhead (its own undo step); a
            // rest-pose drag edits the skeleton, not the pose.
            editor.end_interaction();
            if self.auto_key && drag.mode != GizmoMode::Rest {
                let JointRef { object, joint } = drag.joint;
                editor.end_interaction();
                // IK posed the two joints above the dragged one: those are keyed.
                let keyed: Vec<usize> = if drag.mode == GizmoMode::Ik {
                    let parents = editor.joint_frames(object).map(|f| f.parents);
                    let parent =
                        |j: usize| parents.as_ref().and_then(|p| p.get(j).copied().flatten());
                    parent(joint)
                        .into_iter()
                        .flat_map(|m| [parent(m), Some(m)])
                        .flatten()
                        .collect()
                } else {
                    vec![joint]
                };
                self.error = editor
                    .set_joint_keys(object, &keyed)
                    .err()
                    .map(|e| e.to_string());
            }
            return true;
        }
        let Some(pointer) = ui.input(|i| i.pointer.interact_pos()) else {
            return true;
        };
        let JointRef { object, joint } = drag.joint;
        let mut e_k = Vec3::ZERO;
        e_k[drag.axis] = 1.0;
        let result = match drag.mode {
            GizmoMode::Rotate => {
                let a0 = (drag.start - drag.center).angle();
                let a1 = (pointer - drag.center).angle();
                // Screen y points down: a counter-clockwise turn lowers the angle.
                let mut screen = a1 - a0;
                if screen > std::f32::consts::PI {
                    screen -= std::f32::consts::TAU;
                } else if screen < -std::f32::consts::PI {
                    screen += std::f32::consts::TAU;
                }
                let theta = -screen * drag.sign;
                editor.rotate_joint(object, joint, drag.base, Quat::from_axis_angle(e_k, theta))
            }
            GizmoMode::Translate => {
                let len2 = drag.arrow_px.length_sq();
                if len2 < 1.0 {
                    Ok(())
                } else {
                    let along = (pointer - drag.start).dot(drag.arrow_px) / len2;
                    editor.translate_joint(object, joint, drag.base, e_k * along * drag.arrow_local)
                }
            }
            GizmoMode::Ik => {
                let len2 = drag.arrow_px.length_sq();
                let frames = editor.joint_frames(object);
                match frames {
                    Some(f) if len2 >= 1.0 => {
                        let along = (pointer - drag.start).dot(drag.arrow_px) / len2;
                        let axis = f
                            .world_from_object
                            .col(drag.axis)
                            .truncate()
                            .normalize_or_zero();
                        // `arrow_local` is the arrow's length over the axis column's: in world
                        // units the arrow is `arrow_local * |axis column|` long.
                        let length = drag.arrow_local
                            * f.world_from_object.col(drag.axis).truncate().length();
                        let target = drag.rest_start + axis * along * length;
                        let pole = self.pole_world(&f, joint);
                        editor
                            .pose_ik(object, joint, target, pole)
                            .map(|reached| self.ik_reached = Some(reached))
                    }
                    _ => Ok(()),
                }
            }
            GizmoMode::Rest => {
                let len2 = drag.arrow_px.length_sq();
                if len2 < 1.0 {
                    Ok(())
                } else {
                    let along = (pointer - drag.start).dot(drag.arrow_px) / len2;
                    let to = drag.rest_start + e_k * along * drag.arrow_local;
                    editor.move_joint(object, joint, to)
                }
            }
            GizmoMode::Scale => {
                let len2 = drag.arrow_px.length_sq();
                if len2 < 1.0 {
                    Ok(())
                } else {
                    let along = (pointer - drag.start).dot(drag.arrow_px) / len2;
                    let f = (1.0 + along * drag.arrow_local).max(crate::editor::MIN_JOINT_SCALE);
                    let mut factor = Vec3::ONE;
                    factor[drag.axis] = f;
                    editor.scale_joint(object, joint, drag.base, factor)
                }
            }
        };
        self.error = result.err().map(|e| e.to_string());
        true
    }

    /// The IK pole for a limb ending at `end`: `None` (bend as now), or a point far along the
    /// chosen model axis from the middle joint.
    fn pole_world(&self, frames: &JointFrames, end: usize) -> Option<Vec3> {
        let IkPole::Axis(axis, positive) = self.ik_pole else {
            return None;
        };
        let mid = frames.parents.get(end).copied().flatten()?;
        let upper = frames.parents.get(mid).copied().flatten()?;
        let (a, b, c) = (
            frames.position(upper)?,
            frames.position(mid)?,
            frames.position(end)?,
        );
        let reach = (b - a).length() + (c - b).length();
        let dir = frames
            .world_from_object
            .col(axis)
            .truncate()
            .normalize_or_zero();
        Some(b + dir * if positive { 4.0 } else { -4.0 } * reach)
    }

    /// The joint whose dot is under `pointer`, over every visible rigged object.
    #[must_use]
    pub fn pick_joint(
        &self,
        editor: &Editor,
        proj: &Projector,
        pointer: egui::Pos2,
    ) -> Option<JointRef> {
        if !self.show_skeleton {
            return None;
        }
        let mut best: Option<(f32, JointRef)> = None;
        for o in editor.doc().objects.iter().filter(|o| o.visible) {
            let Some(frames) = editor.joint_frames(o.id) else {
                continue;
            };
            // Where the last paint drew the dots (the shown image's pose), else the editor's.
            let n = frames.world_from_joint.len();
            let positions: Vec<Vec3> = self
                .painted
                .iter()
                .find(|(id, p)| *id == o.id && p.len() == n)
                .map_or_else(
                    || (0..n).filter_map(|j| frames.position(j)).collect(),
                    |(_, p)| p.clone(),
                );
            for (j, p) in positions.into_iter().enumerate() {
                let Some(s) = proj.to_screen(p) else {
                    continue;
                };
                let d = s.distance(pointer);
                if d <= GRAB_PX && best.is_none_or(|(bd, _)| d < bd) {
                    best = Some((
                        d,
                        JointRef {
                            object: o.id,
                            joint: j,
                        },
                    ));
                }
            }
        }
        best.map(|(_, j)| j)
    }

    /// Selects joint `joint` of object `object` (the view, the joint list and new joints).
    pub fn select_joint(&mut self, object: u64, joint: usize) {
        let j = JointRef { object, joint };
        self.joint = Some(j);
        self.listed = None;
    }

    /// Draws every visible skeleton and the selected joint's gizmo.
    ///
    /// Bones and joint dots are drawn posed as `shown` (the document the view's image was drawn
    /// from, which lags the editor's pose while the CPU preview catches up with playback),
    /// else as the editor's document; the selected joint's gizmo follows the editor's pose.
    pub fn paint(
        &mut self,
        painter: &egui::Painter,
        editor: &Editor,
        shown: Option<&thicket_core::scene::Document>,
        proj: &Projector,
    ) {
        self.painted.clear();
        if !self.show_skeleton {
            return;
        }
        let selected = self.valid_joint(editor);
        for o in editor.doc().objects.iter().filter(|o| o.visible) {
            let Some(current) = editor.joint_frames(o.id) else {
                continue;
            };
            // The image's pose, unless its skeleton has other joints (one was added or deleted
            // since it was drawn: the dots must stay clickable as the editor numbers them).
            let frames = shown
                .and_then(|doc| crate::editor::joint_frames_in(doc, o.id))
                .filter(|f| f.parents == current.parents)
                .unwrap_or(current);
            self.painted.push((
                o.id,
                (0..frames.world_from_joint.len())
                    .filter_map(|j| frames.position(j))
                    .collect(),
            ));
            let is_selected_object = editor.selection == Some(Selection::Object(o.id));
            let bone = if is_selected_object {
                egui::Color32::from_rgb(255, 200, 120)
            } else {
                egui::Color32::from_gray(170)
            };
            let screen: Vec<Option<egui::Pos2>> = (0..frames.world_from_joint.len())
                .map(|j| frames.position(j).and_then(|p| proj.to_screen(p)))
                .collect();
            for (j, parent) in frames.parents.iter().enumerate() {
                if let (Some(a), Some(Some(b))) =
                    (screen[j], parent.and_then(|p| screen.get(p).copied()))
                {
                    painter.line_segment([b, a], egui::Stroke::new(2.0, bone));
                }
            }
            for (j, s) in screen.iter().enumerate() {
                let Some(s) = *s else { continue };
                let this = JointRef {
                    object: o.id,
                    joint: j,
                };
                if selected == Some(this) {
                    painter.circle_filled(s, 5.5, egui::Color32::from_rgb(255, 230, 60));
                } else {
                    painter.circle_filled(s, 3.5, bone);
                }
            }
        }
        let Some(sel) = selected else { return };
        let Some(frames) = editor.joint_frames(sel.object) else {
            return;
        };
        let active = self.drag.map(|d| d.axis);
        for h in self.handles(&frames, sel.joint, proj) {
            let width = if active == Some(h.axis) { 3.5 } else { 2.0 };
            let stroke = egui::Stroke::new(width, AXIS_COLORS[h.axis]);
            painter.add(egui::Shape::line(h.points.clone(), stroke));
            if matches!(
                self.active_mode(),
                GizmoMode::Translate | GizmoMode::Rest | GizmoMode::Ik
            ) && let (Some(a), Some(b)) = (h.points.first(), h.points.last())
            {
                let dir = (*b - *a).normalized();
                let side = egui::vec2(-dir.y, dir.x) * 5.0;
                painter.add(egui::Shape::convex_polygon(
                    vec![*b + dir * 10.0, *b + side, *b - side],
                    AXIS_COLORS[h.axis],
                    egui::Stroke::NONE,
                ));
            }
            if self.active_mode() == GizmoMode::Scale
                && let Some(b) = h.points.last()
            {
                painter.rect_filled(
                    egui::Rect::from_center_size(*b, egui::vec2(9.0, 9.0)),
                    1.0,
                    AXIS_COLORS[h.axis],
                );
            }
        }
        if let (Some(p), Some(rig)) = (frames.position(sel.joint), editor.rig(sel.object))
            && let Some(s) = proj.to_screen(p)
        {
            painter.text(
                s + egui::vec2(8.0, -8.0),
                egui::Align2::LEFT_BOTTOM,
                &rig.skeleton.joints[sel.joint].name,
                egui::FontId::proportional(12.0),
                egui::Color32::from_rgb(255, 230, 60),
            );
        }
    }
}

fn joint_label(name: &str, j: usize) -> String {
    if name.is_empty() {
        format!("joint {j}")
    } else {
        name.to_owned()
    }
}

/// The Pose and Stretch sections of the inspector for a rigged voxel model.
pub fn rig_inspector_ui(ui: &mut egui::Ui, editor: &mut Editor, tool: &mut PoseTool, id: u64) {
    let Some(rig) = editor.rig(id).cloned() else {
        return;
    };
    if let Some(e) = &tool.error {
        ui.colored_label(ui.visuals().error_fg_color, format!("Refused: {e}"));
    }
    egui::CollapsingHeader::new("Pose")
        .default_open(true)
        .show(ui, |ui| {
            ui.horizontal(|ui| {
                ui.checkbox(&mut tool.show_skeleton, "Show skeleton")
                    .on_hover_text("Draw the joints and bones over the view");
                ui.separator();
                ui.selectable_value(&mut tool.mode, GizmoMode::Rotate, "Rotate")
                    .on_hover_text("Gizmo rings turn the joint about its own axes (R)");
                ui.selectable_value(&mut tool.mode, GizmoMode::Translate, "Move")
                    .on_hover_text("Gizmo arrows move the joint in its parent's frame (G)");
                ui.selectable_value(&mut tool.mode, GizmoMode::Scale, "Scale joint")
                    .on_hover_text(
                        "Gizmo handles stretch the joint along its own axes (E); its children follow",
                    );
            });
            ui.horizontal(|ui| {
                if ui
                    .checkbox(&mut tool.ik, "IK (2 bones)")
                    .on_hover_text(
                        "With Move, the arrows drag the selected joint (a foot, a hand) as a target: \
                         its parent and grandparent turn so it follows (two-bone IK); the bones \
                         keep their lengths. Auto-key keys the two turned joints.",
                    )
                    .changed()
                    && tool.ik
                {
                    tool.mode = GizmoMode::Translate;
                }
                ui.add_enabled_ui(tool.ik, |ui| {
                    ui.label("bend toward");
                    egui::ComboBox::from_id_salt("ik_pole")
                        .selected_text(tool.ik_pole.label())
                        .show_ui(ui, |ui| {
                            for p in IkPole::ALL {
                                ui.selectable_value(&mut tool.ik_pole, p, p.label());
                            }
                        })
                        .response
                        .on_hover_text("Where the knee or elbow points (the pole): the model's own axes, or the way it bends now");
                });
                if tool.ik && tool.ik_reached == Some(false) {
                    ui.colored_label(
                        ui.visuals().warn_fg_color,
                        "target out of reach: the limb points at it",
                    );
                }
            });
            ui.weak(format!(
                "{} joints, {} override(s). Click a joint here or its dot in the view, then drag a gizmo handle.",
                rig.skeleton.len(),
                rig.pose_overrides.len()
            ));
            let depth = |mut j: usize| {
                let mut d = 0;
                while let Some(p) = rig.skeleton.joints[j].parent {
                    if p >= j || d > 64 {
                        break;
                    }
                    j = p;
                    d += 1;
                }
                d
            };
            egui::ScrollArea::vertical()
                .id_salt("joint_tree")
                .max_height(220.0)
                .show(ui, |ui| {
                    for (j, joint) in rig.skeleton.joints.iter().enumerate() {
                        let this = JointRef { object: id, joint: j };
                        let posed = rig.pose_overrides.iter().any(|o| o.joint == j);
                        let label = format!(
                            "{}{}",
                            joint_label(&joint.name, j),
                            if posed { " (posed)" } else { "" }
                        );
                        ui.horizontal(|ui| {
                            ui.add_space(12.0 * depth(j) as f32);
                            let selected = tool.joint == Some(this);
                            let row = ui
                                .selectable_label(selected, label)
                                .on_hover_text(format!(
                                    "Select joint {j}; drag its gizmo in the view"
                                ));
                            if row.clicked() {
                                tool.joint = Some(this);
                                tool.listed = Some(this);
                            } else if selected && tool.listed != Some(this) {
                                // Picked in the view: bring its row into the list's view.
                                row.scroll_to_me(Some(egui::Align::Center));
                                tool.listed = Some(this);
                            }
                        });
                    }
                });
            if let Some(sel) = tool.valid_joint(editor).filter(|s| s.object == id) {
                joint_ui(ui, editor, tool, sel);
            }
            if ui
                .add_enabled(!rig.pose_overrides.is_empty(), egui::Button::new("Reset pose"))
                .on_hover_text("Remove every joint override (undoable)")
                .clicked()
            {
                tool.error = editor.clear_pose(id, None).err().map(|e| e.to_string());
            }
        });
    egui::CollapsingHeader::new("Stretch")
        .default_open(true)
        .show(ui, |ui| stretch_ui(ui, editor, tool, id));
}

fn joint_ui(ui: &mut egui::Ui, editor: &mut Editor, tool: &mut PoseTool, sel: JointRef) {
    let current = editor.joint_override(sel.object, sel.joint);
    let mut o = current.unwrap_or(JointOverride {
        joint: sel.joint,
        mode: OverrideMode::Relative,
        ..JointOverride::default()
    });
    let name = editor
        .rig(sel.object)
        .map(|r| joint_label(&r.skeleton.joints[sel.joint].name, sel.joint))
        .unwrap_or_default();
    ui.separator();
    ui.strong(format!("Joint: {name}"));
    let mut changed = false;
    egui::Grid::new("joint_override")
        .num_columns(2)
        .show(ui, |ui| {
            ui.label("Mode")
                .on_hover_text("How the override combines with the clip");
            ui.horizontal(|ui| {
                changed |= ui
                    .selectable_value(&mut o.mode, OverrideMode::Relative, "On top of clip")
                    .on_hover_text(
                        "Rotation after the clip's, translation added: the clip keeps playing",
                    )
                    .changed();
                changed |= ui
                    .selectable_value(&mut o.mode, OverrideMode::Replace, "Replace clip")
                    .on_hover_text("The override's values replace the clip's for this joint")
                    .changed();
            });
            ui.end_row();
            ui.label("Rotation deg")
                .on_hover_text("Override rotation as X, Y, Z Euler angles in degrees");
            let q = o.rotation.unwrap_or(Quat::IDENTITY);
            let (x, y, z) = q.to_euler(glam::EulerRot::XYZ);
            let mut e = Vec3::new(x, y, z) * 180.0 / std::f32::consts::PI;
            let mut rot_changed = false;
            ui.horizontal(|ui| {
                for (k, c) in [&mut e.x, &mut e.y, &mut e.z].into_iter().enumerate() {
                    rot_changed |= ui
                        .add(
                            egui::DragValue::new(c)
                                .speed(0.5)
                                .range(-360.0..=360.0)
                                .prefix(format!("{} ", AXIS_NAMES[k].to_lowercase())),
                        )
                        .on_hover_text("Degrees; drag or type a number")
                        .changed();
                }
            });
            if rot_changed {
                let r = e * std::f32::consts::PI / 180.0;
                o.rotation = Some(Quat::from_euler(glam::EulerRot::XYZ, r.x, r.y, r.z));
                changed = true;
            }
            ui.end_row();
            ui.label("Translation")
                .on_hover_text("Override translation in the parent's frame");
            let mut t = o.translation.unwrap_or(Vec3::ZERO);
            let mut t_changed = false;
            ui.horizontal(|ui| {
                for (k, c) in [&mut t.x, &mut t.y, &mut t.z].into_iter().enumerate() {
                    t_changed |= ui
                        .add(
                            egui::DragValue::new(c)
                                .speed(0.005)
                                .prefix(format!("{} ", AXIS_NAMES[k].to_lowercase())),
                        )
                        .on_hover_text("Units of the skeleton; drag or type a number")
                        .changed();
                }
            });
            if t_changed {
                o.translation = Some(t);
                changed = true;
            }
            ui.end_row();
        });
    if changed {
        tool.error = editor
            .set_joint_override(sel.object, o)
            .err()
            .map(|e| e.to_string());
    }
    if ui
        .add_enabled(current.is_some(), egui::Button::new("Reset joint"))
        .on_hover_text("Remove this joint's override (undoable)")
        .clicked()
    {
        tool.error = editor
            .clear_pose(sel.object, Some(sel.joint))
            .err()
            .map(|e| e.to_string());
    }
}

const STRATEGIES: [(StretchStrategy, &str, &str); 4] = [
    (
        StretchStrategy::Off,
        "Off",
        "Voxels keep their size: shows the holes skinning opens",
    ),
    (
        StretchStrategy::Thesis,
        "Thesis",
        "S = min(2, number of bone weights) (paper 3.3): static, doubles voxels near joints",
    ),
    (
        StretchStrategy::Corners,
        "Corners",
        "Box around the eight skinned voxel corners: hole-free, some bloat",
    ),
    (
        StretchStrategy::Adaptive,
        "Adaptive",
        "From this frame's deformation around each voxel: grows only where the surface stretches",
    ),
];

fn stretch_ui(ui: &mut egui::Ui, editor: &mut Editor, tool: &mut PoseTool, id: u64) {
    let Some(rig) = editor.rig(id) else { return };
    let mut s = rig.stretch;
    let overrides = rig.stretch_overrides.len();
    let mut changed = false;
    egui::Grid::new("stretch").num_columns(2).show(ui, |ui| {
        ui.label("Strategy")
            .on_hover_text("How skinned voxels are enlarged to close holes");
        let current = STRATEGIES
            .iter()
            .find(|(k, _, _)| *k == s.strategy)
            .map_or("?", |(_, n, _)| n);
        egui::ComboBox::from_id_salt("stretch_strategy")
            .selected_text(current)
            .show_ui(ui, |ui| {
                for (k, name, tip) in STRATEGIES {
                    changed |= ui
                        .selectable_value(&mut s.strategy, k, name)
                        .on_hover_text(tip)
                        .changed();
                }
            })
            .response
            .on_hover_text("How skinned voxels are enlarged to close holes");
        ui.end_row();
        let mut f = |ui: &mut egui::Ui, label: &str, v: &mut f32, tip: &str| {
            ui.label(label).on_hover_text(tip);
            changed |= ui
                .add(egui::DragValue::new(v).speed(0.01).range(0.0..=16.0))
                .on_hover_text(tip)
                .changed();
            ui.end_row();
        };
        f(
            ui,
            "Multiplier",
            &mut s.multiplier,
            "Multiplier on every stretch factor of this model (above 0, at most 16)",
        );
        f(
            ui,
            "Min factor",
            &mut s.min_factor,
            "Lower bound on a voxel's stretch factor (0 to 16, at most the max)",
        );
        f(
            ui,
            "Max factor",
            &mut s.max_factor,
            "Upper bound on a voxel's stretch factor (at least the min, at most 16)",
        );
    });
    ui.weak(format!(
        "{overrides} voxel(s) with a painted stretch override"
    ))
    .on_hover_text("Paint them with the tool bar's Stretch paint brush (Sculpt tool)");
    if ui
        .add_enabled(overrides > 0, egui::Button::new("Clear overrides"))
        .on_hover_text("Remove every painted stretch override of this model (undoable)")
        .clicked()
    {
        tool.error = editor
            .clear_stretch_overrides(id)
            .err()
            .map(|e| e.to_string());
    }
    if changed {
        tool.error = editor.set_stretch(id, s).err().map(|e| e.to_string());
    }
}

/// The animated object the timeline drives: the selection when it is rigged or a frame
/// sequence, else the first such object.
#[must_use]
pub fn timeline_target(editor: &Editor) -> Option<u64> {
    let animated = |id: u64| {
        editor.rig(id).is_some() || editor.frames(id).is_some() || editor.motion(id).is_some()
    };
    if let Some(Selection::Object(id)) = editor.selection
        && animated(id)
    {
        return Some(id);
    }
    editor
        .doc()
        .objects
        .iter()
        .find(|o| {
            o.motion.is_some()
                || matches!(&o.kind, ObjectKind::Voxels(v) if v.rig.is_some() || v.frames.is_some())
        })
        .map(|o| o.id)
}

/// The timeline of a frame sequence (an animated `.vox`): play / pause, start, scrub slider,
/// the frame shown and the frame rate. Advances the playhead while playing; the sequence loops.
fn frames_timeline_ui(ui: &mut egui::Ui, editor: &mut Editor, tool: &mut PoseTool, id: u64) {
    let Some(seq) = editor.frames(id) else { return };
    let (count, frame_secs) = (seq.len(), seq.frame_secs);
    let mut t = seq.time_secs;
    let duration = seq.duration_secs();
    let name = object_name(editor, id);
    ui.horizontal(|ui| {
        timeline_title_ui(ui, &format!("Frames of {name}"), &name);
        if transport_ui(ui, tool, true, "the frames") {
            t = 0.0;
        }
        if tool.playing {
            let now = ui.input(|i| i.time);
            let step = playback_step(
                &mut tool.last_tick,
                now,
                tool.step_every_frame.then_some(FRAME_STEP_SECS),
            );
            // "Every frame" shows each frame of the sequence in turn.
            let step = if tool.step_every_frame { frame_secs } else { step };
            t = (t + step).rem_euclid(duration.max(1e-6));
            ui.ctx().request_repaint();
        } else {
            tool.last_tick = None;
        }
        ui.checkbox(&mut tool.step_every_frame, "Every frame")
            .on_hover_text("Show each frame for one drawn frame instead of by the clock");
        let mut scrub = t.rem_euclid(duration.max(1e-6));
        let width = (ui.available_width() - 170.0).max(80.0);
        ui.spacing_mut().slider_width = width;
        if ui
            .add(egui::Slider::new(&mut scrub, 0.0..=duration.max(1e-3)).show_value(false))
            .on_hover_text("Scrub: drag to any frame")
            .changed()
        {
            t = scrub;
            tool.playing = false;
        }
        // The playhead moves before the label is drawn, so the label names the frame shown.
        if editor.frames(id).is_some_and(|f| f.time_secs != t) {
            tool.error = editor.set_frame_time(id, t).err().map(|e| e.to_string());
        }
        let shown = editor.frames(id).map_or(0, |f| f.shown);
        ui.monospace(format!(
            "frame {} / {count} at {:.0} fps",
            shown + 1,
            1.0 / frame_secs
        ))
        .on_hover_text("The frame shown / frames in the sequence; the file's frame rate, or MagicaVoxel's 10 fps");
    });
}

/// Object `id`'s name (empty when it is gone).
fn object_name(editor: &Editor, id: u64) -> String {
    editor
        .object(id)
        .map(|o| o.name.clone())
        .unwrap_or_default()
}

/// A timeline's title: "Timeline" (with `hover`) and the object's name.
fn timeline_title_ui(ui: &mut egui::Ui, hover: &str, name: &str) {
    ui.strong("Timeline").on_hover_text(hover);
    ui.label(name);
}

/// Play / Pause (enabled when `playable`; Space toggles it too) and Start; returns whether
/// Start was clicked. `what` names what plays, for the tooltips.
fn transport_ui(ui: &mut egui::Ui, tool: &mut PoseTool, playable: bool, what: &str) -> bool {
    if ui
        .add_enabled(
            playable,
            egui::Button::new(if tool.playing { "Pause" } else { "Play" }),
        )
        .on_hover_text(format!("Play or pause {what} (Space)"))
        .clicked()
    {
        tool.playing = !tool.playing;
    }
    let start = ui
        .add_enabled(playable, egui::Button::new("Start"))
        .on_hover_text("Go to 0 s")
        .clicked();
    if start {
        tool.playing = false;
    }
    start
}

/// A typed or dragged playhead time (0 s to an hour); returns whether it changed.
fn time_field_ui(ui: &mut egui::Ui, t: &mut f32, hover: &str) -> bool {
    ui.add(
        egui::DragValue::new(t)
            .range(0.0..=3600.0)
            .speed(0.01)
            .suffix(" s"),
    )
    .on_hover_text(hover)
    .changed()
}

/// The Loop checkbox over `wrap`.
fn loop_ui(ui: &mut egui::Ui, wrap: &mut Wrap, hover: &str) {
    let mut loop_on = *wrap == Wrap::Loop;
    if ui
        .checkbox(&mut loop_on, "Loop")
        .on_hover_text(hover)
        .changed()
    {
        *wrap = if loop_on { Wrap::Loop } else { Wrap::Clamp };
    }
}

/// Advances `t` while playing (by the clock, or one frame of `frame_secs` per drawn frame
/// with Every frame); past `duration` it loops, or holds the end and stops.
fn advance_playhead(
    ui: &egui::Ui,
    tool: &mut PoseTool,
    t: &mut f32,
    duration: f32,
    wrap: Wrap,
    frame_secs: f32,
) {
    if !tool.playing {
        tool.last_tick = None;
        return;
    }
    let now = ui.input(|i| i.time);
    *t += playback_step(
        &mut tool.last_tick,
        now,
        tool.step_every_frame.then_some(frame_secs),
    );
    if *t > duration {
        if wrap == Wrap::Loop {
            *t = t.rem_euclid(duration.max(1e-6));
        } else {
            *t = duration;
            tool.playing = false;
        }
    }
    ui.ctx().request_repaint();
}

/// The timeline of an unrigged object's keyed transform: play / pause, start, loop, a scrub
/// slider with the keys as diamonds, and the time. A rigged model's keys follow its clip's
/// timeline instead.
fn motion_timeline_ui(ui: &mut egui::Ui, editor: &mut Editor, tool: &mut PoseTool, id: u64) {
    let Some(m) = editor.motion(id) else { return };
    let (mut t, mut wrap) = (m.time_secs, m.wrap);
    let duration = m.clip.duration_secs.max(0.0);
    let fps = m.clip.frame_rate.max(1.0);
    let keys = editor.object_key_times(id);
    let name = object_name(editor, id);
    ui.horizontal(|ui| {
        timeline_title_ui(ui, &format!("The keyed transform of {name}"), &name);
        let playable = duration > 0.0;
        if transport_ui(ui, tool, playable, "the object's motion") {
            t = 0.0;
        }
        loop_ui(ui, &mut wrap, "Repeat the motion (otherwise hold its last key)");
        if !playable {
            tool.playing = false;
        }
        advance_playhead(ui, tool, &mut t, duration, wrap, 1.0 / fps);
        ui.checkbox(&mut tool.step_every_frame, "Every frame")
            .on_hover_text("Advance one frame per drawn frame instead of by the clock");
        if time_field_ui(
            ui,
            &mut t,
            "Type or drag the playhead's time (past the last key to key the object there: move it, then Key transform)",
        ) {
            tool.playing = false;
        }
        let mut scrub = t.clamp(0.0, duration);
        ui.spacing_mut().slider_width = (ui.available_width() - 200.0).max(80.0);
        let slider = ui
            .add_enabled(
                playable,
                egui::Slider::new(&mut scrub, 0.0..=duration.max(1e-3)).show_value(false),
            )
            .on_hover_text("Scrub: drag to any time");
        if slider.changed() {
            t = scrub;
            tool.playing = false;
        }
        if duration > 0.0 {
            let rail = slider.rect;
            let inset = rail.height() / 2.5;
            for k in &keys {
                let x = rail.left() + inset + (k / duration).clamp(0.0, 1.0) * (rail.width() - 2.0 * inset);
                super::dope_sheet::key_diamond(
                    ui.painter(),
                    egui::pos2(x, rail.center().y),
                    4.5,
                    egui::Color32::from_rgb(255, 210, 60),
                );
            }
        }
        ui.monospace(format!("{:.2} / {:.2} s  frame {}", t, duration, (t * fps).round()))
            .on_hover_text("Playhead / length of the motion (its last key)");
    });
    if editor
        .motion(id)
        .is_some_and(|m| m.time_secs != t || m.wrap != wrap)
    {
        tool.error = editor
            .set_motion_time(id, t, wrap)
            .err()
            .map(|e| e.to_string());
    }
}

/// The timeline: clip picker, play / pause, scrub slider and time. Advances the playhead while
/// playing. A frame sequence gets its own, simpler timeline.
pub fn timeline_ui(ui: &mut egui::Ui, editor: &mut Editor, tool: &mut PoseTool, id: u64) {
    if editor.rig(id).is_none() && editor.frames(id).is_some() {
        frames_timeline_ui(ui, editor, tool, id);
        return;
    }
    if editor.rig(id).is_none() && editor.motion(id).is_some() {
        motion_timeline_ui(ui, editor, tool, id);
        return;
    }
    let Some(rig) = editor.rig(id) else { return };
    let mut playback = rig.playback;
    let clips: Vec<(String, f32)> = rig
        .clips
        .iter()
        .map(|c| (c.name.clone(), c.duration_secs.max(0.0)))
        .collect();
    let name = object_name(editor, id);
    let clip_label = |c: Option<usize>| match c {
        None => "Rest pose".to_owned(),
        Some(i) => clips.get(i).map_or_else(
            || format!("clip {i}"),
            |(n, _)| {
                if n.is_empty() {
                    format!("clip {i}")
                } else {
                    n.clone()
                }
            },
        ),
    };
    let duration = playback
        .clip
        .and_then(|c| clips.get(c))
        .map_or(0.0, |(_, d)| *d);
    let frame_rate = playback
        .clip
        .and_then(|c| rig.clips.get(c))
        .map_or(thicket_core::skin::keys::DEFAULT_FRAME_RATE, |c| {
            c.frame_rate
        })
        .max(1.0);
    ui.horizontal(|ui| {
        timeline_title_ui(ui, &format!("Animation of {name}"), &name);
        egui::ComboBox::from_id_salt("timeline_clip")
            .selected_text(clip_label(playback.clip))
            .show_ui(ui, |ui| {
                ui.selectable_value(&mut playback.clip, None, "Rest pose")
                    .on_hover_text("The skeleton's rest pose plus the overrides");
                for i in 0..clips.len() {
                    ui.selectable_value(&mut playback.clip, Some(i), clip_label(Some(i)))
                        .on_hover_text("Play this clip under the overrides");
                }
            })
            .response
            .on_hover_text("Which clip plays");
        let has_clip = playback.clip.is_some() && duration > 0.0;
        if transport_ui(ui, tool, has_clip, "the clip") {
            playback.time_secs = 0.0;
        }
        loop_ui(
            ui,
            &mut playback.wrap,
            "Repeat the clip (otherwise hold its last frame)",
        );
        ui.checkbox(&mut tool.step_every_frame, "Every frame")
            .on_hover_text(format!(
                "Advance one frame of the clip ({:.3} s at {} fps) per drawn frame (every pose shown, slow motion when frames are slow) instead of by the clock",
                1.0 / frame_rate,
                frame_rate
            ));
        if !has_clip {
            tool.playing = false;
        }
        let wrap = playback.wrap;
        advance_playhead(
            ui,
            tool,
            &mut playback.time_secs,
            duration,
            wrap,
            1.0 / frame_rate,
        );
        let mut t = playback.time_secs.clamp(0.0, duration);
        // Room for the time and frame readout after the slider.
        let width = (ui.available_width() - 200.0).max(80.0);
        ui.spacing_mut().slider_width = width;
        let slider = ui
            .add_enabled(
                has_clip,
                egui::Slider::new(&mut t, 0.0..=duration.max(1e-3)).show_value(false),
            )
            .on_hover_text("Scrub: drag to any time of the clip");
        if slider.changed() {
            playback.time_secs = t;
            tool.playing = false;
        }
        paint_keys(ui, editor, tool, id, slider.rect, duration);
        ui.monospace(format!(
            "{:.2} / {:.2} s  frame {}",
            t,
            duration,
            (t * frame_rate).round()
        ))
        .on_hover_text(format!("Playhead / clip length; frame at {frame_rate} fps"));
    });
    keys_ui(ui, editor, tool, id, &mut playback);
    if tool.dope.open && playback.clip.is_some() {
        super::dope_sheet::dope_sheet_ui(ui, editor, &mut tool.dope, id, &mut playback);
        if tool.dope.scrubbed {
            tool.playing = false;
        }
    }
    if playback != editor.rig(id).map_or(playback, |r| r.playback) {
        tool.error = editor
            .set_playback(id, playback)
            .err()
            .map(|e| e.to_string());
    }
}

/// Draws the selected joint's keys as diamonds on the scrub slider (other joints' keys of the
/// clip as small ticks).
fn paint_keys(
    ui: &egui::Ui,
    editor: &Editor,
    tool: &PoseTool,
    id: u64,
    rail: egui::Rect,
    duration: f32,
) {
    if duration <= 0.0 {
        return;
    }
    let Some(rig) = editor.rig(id) else {
        return;
    };
    let Some(clip) = rig.playback.clip.and_then(|c| rig.clips.get(c)) else {
        return;
    };
    // The slider's handle keeps its centre this far inside the rail's ends.
    let inset = rail.height() / 2.5;
    let x_of = |t: f32| {
        rail.left() + inset + (t / duration).clamp(0.0, 1.0) * (rail.width() - 2.0 * inset)
    };
    let painter = ui.painter();
    let y = rail.center().y;
    let selected = tool
        .valid_joint(editor)
        .filter(|j| j.object == id)
        .map(|j| j.joint);
    for c in clip.channels.iter().filter(|c| Some(c.joint) != selected) {
        for &t in &c.times {
            let x = x_of(t);
            painter.line_segment(
                [egui::pos2(x, y + 4.0), egui::pos2(x, y + 8.0)],
                egui::Stroke::new(1.0, egui::Color32::from_gray(120)),
            );
        }
    }
    if let Some(j) = selected {
        for t in editor.joint_key_times(id, j) {
            super::dope_sheet::key_diamond(
                painter,
                egui::pos2(x_of(t), y),
                5.0,
                egui::Color32::from_rgb(255, 210, 60),
            );
        }
    }
}

/// The key row under the timeline: the playhead's time (any time, also past the clip's end),
/// Set key / Delete key for the selected joint, and how many keys it has.
fn keys_ui(
    ui: &mut egui::Ui,
    editor: &mut Editor,
    tool: &mut PoseTool,
    id: u64,
    playback: &mut thicket_core::skin::Playback,
) {
    ui.horizontal(|ui| {
        ui.label("Time").on_hover_text("The playhead in seconds");
        if time_field_ui(
            ui,
            &mut playback.time_secs,
            "Type or drag the playhead's time (with Loop off, past the clip's end to add keys there)",
        ) {
            tool.playing = false;
        }
        let joint = tool
            .valid_joint(editor)
            .filter(|j| j.object == id)
            .map(|j| j.joint);
        let name = joint
            .and_then(|j| editor.rig(id).map(|r| joint_label(&r.skeleton.joints[j].name, j)))
            .unwrap_or_else(|| "no joint selected".to_owned());
        let keys = joint.map(|j| editor.joint_key_times(id, j)).unwrap_or_default();
        let on_key = editor.key_time(id).is_ok_and(|(_, at)| {
            keys.iter()
                .any(|k| (k - at).abs() < crate::editor::KEY_EPSILON_SECS)
        });
        if ui
            .add_enabled(joint.is_some(), egui::Button::new("Set key"))
            .on_hover_text(format!(
                "Store the pose of {name} at the playhead as a key of the clip (on the rest pose a clip \"Pose\" is added) (K)"
            ))
            .clicked()
            && let Some(j) = joint
        {
            tool.error = editor.set_joint_key(id, j).err().map(|e| e.to_string());
        }
        if ui
            .add_enabled(on_key, egui::Button::new("Delete key"))
            .on_hover_text(format!("Remove the keys of {name} at the playhead (Shift+K)"))
            .clicked()
            && let Some(j) = joint
        {
            tool.error = editor.delete_joint_key(id, j).err().map(|e| e.to_string());
        }
        ui.checkbox(&mut tool.auto_key, "Auto-key")
            .on_hover_text("Key the joint at the playhead whenever a gizmo drag ends");
        ui.toggle_value(&mut tool.dope.open, "Dope sheet")
            .on_hover_text("Every joint's keys over time: select, drag in time, copy / paste, delete, interpolation, frame rate");
        ui.weak(format!("{name}: {} key(s) in this clip", keys.len()))
            .on_hover_text("Keys of the selected joint, drawn as diamonds on the timeline");
    });
}

#[cfg(test)]
mod playback_tests {
    use super::*;

    #[test]
    fn playback_follows_the_clock_and_drops_frames_when_slow() {
        let mut tick = None;
        // The first playing frame starts the clock.
        assert_eq!(playback_step(&mut tick, 10.0, None), 0.0);
        // Slow frames (0.3 s apart) advance the clip by 0.3 s each: real time, not a cap.
        assert!((playback_step(&mut tick, 10.3, None) - 0.3).abs() < 1e-6);
        assert!((playback_step(&mut tick, 10.6, None) - 0.3).abs() < 1e-6);
        // A stall of a minute moves the clip by the cap, not a minute.
        assert_eq!(
            playback_step(&mut tick, 70.6, None) as f64,
            MAX_PLAYBACK_STEP_SECS
        );
        // A clock that goes back (a new context) does not play backwards.
        assert_eq!(playback_step(&mut tick, 5.0, None), 0.0);
        // Every frame: one fixed step, whatever the clock.
        assert_eq!(
            playback_step(&mut tick, 9.0, Some(FRAME_STEP_SECS)),
            FRAME_STEP_SECS
        );
        assert_eq!(
            playback_step(&mut tick, 9.001, Some(FRAME_STEP_SECS)),
            FRAME_STEP_SECS
        );
    }
}
