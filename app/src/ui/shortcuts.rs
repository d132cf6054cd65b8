//! Keyboard shortcuts: the list Help shows and the handler that runs them.

use egui::{Key, KeyboardShortcut, Modifiers};

use super::path_prompt::PathPurpose;
use super::{EditorApp, pose, sculpt, view};
use crate::editor::Selection;

/// Keyboard shortcuts, listed in Help → Keyboard shortcuts.
pub const SHORTCUTS: &[(&str, &str)] = &[
    ("Ctrl+N", "New project"),
    ("Ctrl+O", "Open a project or model"),
    ("Ctrl+S", "Save"),
    ("Ctrl+Shift+S", "Save as"),
    ("Ctrl+I", "Import objects into this project"),
    ("Ctrl+Z", "Undo"),
    ("Ctrl+Shift+Z / Ctrl+Y", "Redo"),
    ("Ctrl+D", "Duplicate the selected object"),
    ("Delete", "Delete the selected object"),
    ("F2", "Rename the selected object"),
    ("H", "Hide / show the selected object"),
    ("End", "Drop the selected object onto whatever is below it"),
    (
        "F",
        "Frame the selection (everything when nothing is selected)",
    ),
    (
        "Drag in the view",
        "Orbit (with the sculpt tool: sculpt; Alt+drag orbits)",
    ),
    ("Middle-drag / Alt+drag", "Orbit"),
    ("Shift+drag / right-drag", "Pan"),
    ("Scroll / pinch", "Zoom"),
    ("Two-finger trackpad scroll", "Orbit (Shift: pan)"),
    (
        "1 / 3 / 7",
        "Front / right / top orthographic view (Ctrl: back / left / bottom; orbiting returns to perspective)",
    ),
    ("5", "Orthographic / perspective projection"),
    ("Click in the view", "Select the object under the pointer"),
    ("S", "Brush tool (see the voxel tool keys below)"),
    ("Click a joint dot", "Select the joint (rigged models)"),
    (
        "R / G / E",
        "Pose gizmo: rotate / move / scale the selected joint",
    ),
    (
        "K / Shift+K",
        "Set / delete the selected joint's key at the playhead",
    ),
    ("Space", "Play / pause the timeline"),
    (
        "Esc",
        "Close the open menu; with none open, the navigate tool",
    ),
    (
        "[ / ]",
        "Brush one voxel smaller / larger (Shift: halve / double; also the stretch brush)",
    ),
    ("F3", "Performance overlay"),
    ("Ctrl+Plus / Ctrl+Minus", "UI scale"),
    ("F1", "This list"),
];

/// How many times `key` with `modifiers` was pressed this frame (key repeats included); the
/// presses are consumed. Fast presses (or a stalled frame) put several in one frame, and a
/// shortcut that steps something must step once per press: `consume_shortcut` answers only
/// whether there was one and drops the rest.
pub(super) fn count_presses(ctx: &egui::Context, modifiers: Modifiers, key: Key) -> usize {
    ctx.input_mut(|i| i.count_and_consume_key(modifiers, key))
}

/// Esc pressed this frame for the editor, consumed: not while a menu, combo box or other popup
/// is open, which the Esc closes instead (egui's popups close on Esc when they are drawn, after
/// the shortcuts); the next Esc, with nothing open, does what Esc does in the editor.
pub(super) fn consume_escape(ctx: &egui::Context) -> bool {
    !egui::Popup::is_any_open(ctx)
        && ctx
            .input_mut(|i| i.consume_shortcut(&KeyboardShortcut::new(Modifiers::NONE, Key::Escape)))
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
        let shortcut = |m: Modifiers, k: Key| KeyboardShortcut::new(m, k);
        let cmd_shift = Modifiers::COMMAND | Modifiers::SHIFT;
        let consume = |s: KeyboardShortcut| ctx.input_mut(|i| i.consume_shortcut(&s));
        // Shift variants first: a shortcut matches Ctrl+Z also when Shift is held.
        let redos =
            count_presses(ctx, cmd_shift, Key::Z) + count_presses(ctx, Modifiers::COMMAND, Key::Y);
        for _ in 0..redos {
            self.editor.redo();
        }
        for _ in 0..count_presses(ctx, Modifiers::COMMAND, Key::Z) {
            self.editor.undo();
        }
        if consume(shortcut(cmd_shift, Key::S)) {
            self.ask_path(PathPurpose::SaveAs);
        }
        if consume(shortcut(Modifiers::COMMAND, Key::S)) {
            self.save(ctx);
        }
        if consume(shortcut(Modifiers::COMMAND, Key::N)) {
            self.request_new();
        }
        if consume(shortcut(Modifiers::COMMAND, Key::O)) {
            self.ask_path(PathPurpose::Open);
        }
        if consume(shortcut(Modifiers::COMMAND, Key::I)) {
            self.ask_path(PathPurpose::Import);
        }
        let selected = match self.editor.selection {
            Some(Selection::Object(id)) => Some(id),
            _ => None,
        };
        if consume(shortcut(Modifiers::COMMAND, Key::D))
            && let Some(id) = selected
        {
            let _ = self.editor.duplicate(id);
        }
        // Single keys only when no widget has the keyboard (a focused slider takes arrows).
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        if consume(shortcut(Modifiers::NONE, Key::F1)) {
            self.show_shortcuts = !self.show_shortcuts;
        }
        if consume(shortcut(Modifiers::NONE, Key::F)) {
            self.editor.frame_selection();
        }
        if consume(shortcut(Modifiers::NONE, Key::End)) {
            self.drop_selected(ctx);
        }
        if consume(shortcut(Modifiers::NONE, Key::F3)) {
            self.perf.open = !self.perf.open;
        }
        if consume(shortcut(Modifiers::NONE, Key::S)) {
            self.sculpt.active = true;
        }
        if consume_escape(ctx) {
            self.sculpt.active = false;
        }
        if self.pose.joint.is_some() {
            if consume(shortcut(Modifiers::NONE, Key::R)) {
                self.pose.mode = pose::GizmoMode::Rotate;
            }
            if consume(shortcut(Modifiers::NONE, Key::G)) {
                self.pose.mode = pose::GizmoMode::Translate;
            }
            if consume(shortcut(Modifiers::NONE, Key::E)) {
                self.pose.mode = pose::GizmoMode::Scale;
            }
            if let Some(j) = self.pose.valid_joint(&self.editor) {
                if consume(shortcut(Modifiers::SHIFT, Key::K)) {
                    self.pose.error = self
                        .editor
                        .delete_joint_key(j.object, j.joint)
                        .err()
                        .map(|e| e.to_string());
                } else if consume(shortcut(Modifiers::NONE, Key::K)) {
                    self.pose.error = self
                        .editor
                        .set_joint_key(j.object, j.joint)
                        .err()
                        .map(|e| e.to_string());
                }
            }
        }
        if pose::timeline_target(&self.editor).is_some()
            && consume(shortcut(Modifiers::NONE, Key::Space))
        {
            self.pose.playing = !self.pose.playing;
        }
        // Shift first (a plain shortcut also matches with Shift held); Shift+[ arrives as `{`
        // on layouts where Shift changes the key.
        for (mods, key, grow, double) in [
            (Modifiers::SHIFT, Key::OpenBracket, false, true),
            (Modifiers::SHIFT, Key::OpenCurlyBracket, false, true),
            (Modifiers::SHIFT, Key::CloseBracket, true, true),
            (Modifiers::SHIFT, Key::CloseCurlyBracket, true, true),
            (Modifiers::NONE, Key::OpenBracket, false, false),
            (Modifiers::NONE, Key::CloseBracket, true, false),
        ] {
            for _ in 0..count_presses(ctx, mods, key) {
                self.sculpt.brush.radius =
                    sculpt::step_brush_radius(self.sculpt.brush.radius, grow, double);
            }
        }
        if consume(shortcut(Modifiers::NONE, Key::Num5)) {
            let ortho = !self.editor.doc().camera.orthographic;
            self.view.set_orthographic(&mut self.editor, ortho);
        }
        for (key, near, far) in [
            (Key::Num1, view::AxisView::Front, view::AxisView::Back),
            (Key::Num3, view::AxisView::Right, view::AxisView::Left),
            (Key::Num7, view::AxisView::Top, view::AxisView::Bottom),
        ] {
            if consume(shortcut(Modifiers::COMMAND, key)) {
                self.view.axis_view(&mut self.editor, far);
            }
            if consume(shortcut(Modifiers::NONE, key)) {
                self.view.axis_view(&mut self.editor, near);
            }
        }
        if let Some(Selection::Light(i)) = self.editor.selection
            && consume(shortcut(Modifiers::NONE, Key::Delete))
        {
            let _ = self.editor.delete_light(i);
        }
        if let Some(id) = selected {
            if consume(shortcut(Modifiers::NONE, Key::Delete)) {
                let _ = self.editor.delete(id);
            }
            if consume(shortcut(Modifiers::NONE, Key::H))
                && let Some(visible) = self.editor.object(id).map(|o| o.visible)
            {
                let _ = self.editor.set_visible(id, !visible);
            }
            if consume(shortcut(Modifiers::NONE, Key::F2)) {
                self.outliner.start_rename(&self.editor, id);
            }
        }
    }
}
