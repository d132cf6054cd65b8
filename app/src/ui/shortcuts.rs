//! The keyboard shortcuts' handler: it asks the binding table ([`super::keys`]) for presses
//! by action.

use super::keys::{Act, pressed, presses};
use super::path_prompt::PathPurpose;
use super::{EditorApp, pose, sculpt, view};
use crate::editor::Selection;

/// Esc pressed this frame for the editor, consumed: not while a menu, combo box or other popup
/// is open, which the Esc closes instead (egui's popups close on Esc when they are drawn, after
/// the shortcuts); the next Esc, with nothing open, does what Esc does in the editor.
pub(super) fn consume_escape(ctx: &egui::Context) -> bool {
    !egui::Popup::is_any_open(ctx) && pressed(ctx, Act::Escape)
}

impl EditorApp {
    /// Whether the keyboard belongs to something other than the editor's shortcuts: a focused
    /// text field keeps its own keys (Ctrl+A selects its text, Ctrl+Z undoes typing, Ctrl+V
    /// pastes into it), and an open path entry is modal. Focus is last frame's: the shortcuts
    /// run before the widgets of this frame.
    pub(super) fn keyboard_taken(&self, ctx: &egui::Context) -> bool {
        ctx.text_edit_focused() || self.prompt.is_some()
    }

    pub(super) fn handle_shortcuts(&mut self, ctx: &egui::Context) {
        if self.keyboard_taken(ctx) {
            return;
        }
        // Shift variants first: a shortcut matches Ctrl+Z also when Shift is held.
        for _ in 0..presses(ctx, Act::Redo) {
            self.editor.redo();
        }
        for _ in 0..presses(ctx, Act::Undo) {
            self.editor.undo();
        }
        if pressed(ctx, Act::SaveAs) {
            self.ask_path(PathPurpose::SaveAs);
        }
        if pressed(ctx, Act::Save) {
            self.save(ctx);
        }
        if pressed(ctx, Act::New) {
            self.request_new();
        }
        if pressed(ctx, Act::Open) {
            self.ask_path(PathPurpose::Open);
        }
        if pressed(ctx, Act::Import) {
            self.ask_path(PathPurpose::Import);
        }
        let selected = match self.editor.selection {
            Some(Selection::Object(id)) => Some(id),
            _ => None,
        };
        if pressed(ctx, Act::Duplicate)
            && let Some(id) = selected
        {
            let _ = self.editor.duplicate(id);
        }
        // Single keys only when no widget has the keyboard (a focused slider takes arrows).
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        if pressed(ctx, Act::Help) {
            self.show_shortcuts = !self.show_shortcuts;
        }
        if pressed(ctx, Act::Frame) {
            self.editor.frame_selection();
        }
        if pressed(ctx, Act::Drop) {
            self.drop_selected(ctx);
        }
        if pressed(ctx, Act::Perf) {
            self.perf.open = !self.perf.open;
        }
        if consume_escape(ctx) {
            self.sculpt.active = false;
        }
        if self.pose.joint.is_some() {
            if pressed(ctx, Act::GizmoRotate) {
                self.pose.mode = pose::GizmoMode::Rotate;
            }
            if pressed(ctx, Act::GizmoMove) {
                self.pose.mode = pose::GizmoMode::Translate;
            }
            if pressed(ctx, Act::GizmoScale) {
                self.pose.mode = pose::GizmoMode::Scale;
            }
            if let Some(j) = self.pose.valid_joint(&self.editor) {
                if pressed(ctx, Act::DeleteKey) {
                    self.pose.error = self
                        .editor
                        .delete_joint_key(j.object, j.joint)
                        .err()
                        .map(|e| e.to_string());
                } else if pressed(ctx, Act::SetKey) {
                    self.pose.error = self
                        .editor
                        .set_joint_key(j.object, j.joint)
                        .err()
                        .map(|e| e.to_string());
                }
            }
        }
        if pose::timeline_target(&self.editor).is_some() && pressed(ctx, Act::Play) {
            self.pose.playing = !self.pose.playing;
        }
        // Shift first (a plain shortcut also matches with Shift held); Shift+[ arrives as `{`
        // on layouts where Shift changes the key.
        for (act, grow, double) in [
            (Act::BrushHalve, false, true),
            (Act::BrushDouble, true, true),
            (Act::BrushSmaller, false, false),
            (Act::BrushLarger, true, false),
        ] {
            for _ in 0..presses(ctx, act) {
                self.sculpt.brush.radius =
                    sculpt::step_brush_radius(self.sculpt.brush.radius, grow, double);
            }
        }
        if pressed(ctx, Act::ToggleOrtho) {
            let ortho = !self.editor.doc().camera.orthographic;
            self.view.set_orthographic(&mut self.editor, ortho);
        }
        // Ctrl first: the plain key also matches with Ctrl held.
        for view in [
            view::AxisView::Back,
            view::AxisView::Left,
            view::AxisView::Bottom,
            view::AxisView::Front,
            view::AxisView::Right,
            view::AxisView::Top,
        ] {
            if pressed(ctx, Act::View(view)) {
                self.view.axis_view(&mut self.editor, view);
            }
        }
        if let Some(Selection::Light(i)) = self.editor.selection
            && pressed(ctx, Act::Delete)
        {
            let _ = self.editor.delete_light(i);
        }
        if let Some(id) = selected {
            if pressed(ctx, Act::Delete) {
                let _ = self.editor.delete(id);
            }
            if pressed(ctx, Act::Hide)
                && let Some(visible) = self.editor.object(id).map(|o| o.visible)
            {
                let _ = self.editor.set_visible(id, !visible);
            }
            if pressed(ctx, Act::Rename) {
                self.outliner.start_rename(&self.editor, id);
            }
        }
    }
}
