//! The key binding table: every key the editor binds, what it does, and the keys' names. The
//! handlers ask for presses by action (`presses`, `pressed`), never by key, and the
//! shortcut sheet (Help → Keyboard shortcuts, F1) lists this table, so a key is bound here or
//! not at all and the sheet cannot drift from what the keys do.

use egui::{Key, KeyboardShortcut, Modifiers};
use glam::IVec3;

use super::projector::AxisView;
use super::voxel_tools::ToolKind;

/// What a bound key does. Context decides where one key has several meanings (Delete deletes
/// the selected voxels when there are some, else the selected object or light).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Act {
    /// Redo the last undone edit.
    Redo,
    /// Undo the last edit.
    Undo,
    /// File → Save as.
    SaveAs,
    /// File → Save.
    Save,
    /// File → New project.
    New,
    /// File → Open.
    Open,
    /// File → Import.
    Import,
    /// Duplicate the selected object.
    Duplicate,
    /// Delete the selection (voxels, object or light).
    Delete,
    /// Rename the selected object.
    Rename,
    /// Hide or show the selected object.
    Hide,
    /// Drop the selected object onto what is below it.
    Drop,
    /// Frame the selection.
    Frame,
    /// One of the six axis views.
    View(AxisView),
    /// Orthographic / perspective.
    ToggleOrtho,
    /// Close the open menu, cancel a paste or a box, else the navigate tool.
    Escape,
    /// Pose gizmo: rotate.
    GizmoRotate,
    /// Pose gizmo: move.
    GizmoMove,
    /// Pose gizmo: scale.
    GizmoScale,
    /// Key the selected joint at the playhead.
    SetKey,
    /// Delete the selected joint's key at the playhead.
    DeleteKey,
    /// Play / pause the timeline.
    Play,
    /// Brush one voxel smaller.
    BrushSmaller,
    /// Brush one voxel larger.
    BrushLarger,
    /// Brush half the size.
    BrushHalve,
    /// Brush twice the size.
    BrushDouble,
    /// A voxel tool.
    Tool(ToolKind),
    /// The tool adds.
    AddMode,
    /// The tool removes.
    RemoveMode,
    /// The tool paints.
    PaintMode,
    /// Mirror the tool across an axis (0 = X, 1 = Y, 2 = Z).
    Mirror(usize),
    /// Select every voxel of the model.
    SelectAll,
    /// Select no voxel.
    SelectNone,
    /// Invert the voxel selection.
    InvertSelection,
    /// Copy the selected voxels.
    Copy,
    /// Cut the selected voxels.
    Cut,
    /// Paste voxels.
    Paste,
    /// Move the floating paste or the selection one voxel.
    Move(IVec3),
    /// Place the floating paste.
    PlacePaste,
    /// Place the floating paste, growing the canvas.
    PlacePasteGrowing,
    /// Add a voxel model.
    AddModel,
    /// The performance overlay.
    Perf,
    /// The shortcut sheet.
    Help,
}

/// One row of the table: an action, the keys that do it (any of them), and what it does.
#[derive(Debug, Clone, Copy)]
pub struct Binding {
    /// The action the handlers ask for.
    pub act: Act,
    /// The keys, each with its modifiers.
    pub keys: &'static [(Modifiers, Key)],
    /// What it does, as the sheet says it.
    pub what: &'static str,
}

const NONE: Modifiers = Modifiers::NONE;
const SHIFT: Modifiers = Modifiers::SHIFT;
const CMD: Modifiers = Modifiers::COMMAND;
const CMD_SHIFT: Modifiers = Modifiers {
    alt: false,
    ctrl: false,
    shift: true,
    mac_cmd: false,
    command: true,
};

const fn bind(act: Act, keys: &'static [(Modifiers, Key)], what: &'static str) -> Binding {
    Binding { act, keys, what }
}

/// Every key binding, in the sheet's order. Where one key is a prefix of another (Ctrl+Z of
/// Ctrl+Shift+Z), the handlers ask for the one with more modifiers first.
pub const BINDINGS: &[Binding] = &[
    bind(Act::New, &[(CMD, Key::N)], "New project"),
    bind(Act::Open, &[(CMD, Key::O)], "Open a project or model"),
    bind(Act::Save, &[(CMD, Key::S)], "Save"),
    bind(Act::SaveAs, &[(CMD_SHIFT, Key::S)], "Save as"),
    bind(
        Act::Import,
        &[(CMD, Key::I)],
        "Import objects into this project",
    ),
    bind(Act::Undo, &[(CMD, Key::Z)], "Undo"),
    bind(Act::Redo, &[(CMD_SHIFT, Key::Z), (CMD, Key::Y)], "Redo"),
    bind(
        Act::Duplicate,
        &[(CMD, Key::D)],
        "Duplicate the selected object",
    ),
    bind(
        Act::Delete,
        &[(NONE, Key::Delete)],
        "Delete the selected voxels, else the selected object or light",
    ),
    bind(
        Act::Rename,
        &[(NONE, Key::F2)],
        "Rename the selected object",
    ),
    bind(
        Act::Hide,
        &[(NONE, Key::H)],
        "Hide / show the selected object",
    ),
    bind(
        Act::Drop,
        &[(NONE, Key::End)],
        "Drop the selected object onto whatever is below it",
    ),
    bind(
        Act::Frame,
        &[(NONE, Key::F)],
        "Frame the selection (everything when nothing is selected)",
    ),
    bind(
        Act::View(AxisView::Front),
        &[(NONE, Key::Num1)],
        "Front orthographic view (orbiting returns to perspective)",
    ),
    bind(
        Act::View(AxisView::Back),
        &[(CMD, Key::Num1)],
        "Back orthographic view",
    ),
    bind(
        Act::View(AxisView::Right),
        &[(NONE, Key::Num3)],
        "Right orthographic view",
    ),
    bind(
        Act::View(AxisView::Left),
        &[(CMD, Key::Num3)],
        "Left orthographic view",
    ),
    bind(
        Act::View(AxisView::Top),
        &[(NONE, Key::Num7)],
        "Top orthographic view",
    ),
    bind(
        Act::View(AxisView::Bottom),
        &[(CMD, Key::Num7)],
        "Bottom orthographic view",
    ),
    bind(
        Act::ToggleOrtho,
        &[(NONE, Key::Num5)],
        "Orthographic / perspective projection",
    ),
    bind(
        Act::Escape,
        &[(NONE, Key::Escape)],
        "Close the open menu; else cancel the floating paste or the box being drawn; else the navigate tool",
    ),
    bind(Act::Tool(ToolKind::Brush), &[(NONE, Key::S)], "Brush tool"),
    bind(Act::Tool(ToolKind::Voxel), &[(NONE, Key::V)], "Voxel tool"),
    bind(Act::Tool(ToolKind::Box), &[(NONE, Key::B)], "Box tool"),
    bind(Act::Tool(ToolKind::Line), &[(NONE, Key::L)], "Line tool"),
    bind(
        Act::Tool(ToolKind::Extrude),
        &[(NONE, Key::U)],
        "Extrude tool",
    ),
    bind(Act::Tool(ToolKind::Fill), &[(NONE, Key::P)], "Fill tool"),
    bind(
        Act::Tool(ToolKind::Select),
        &[(NONE, Key::M)],
        "Select tool",
    ),
    bind(Act::AddMode, &[(NONE, Key::A)], "Add mode of the tool"),
    bind(
        Act::RemoveMode,
        &[(NONE, Key::D)],
        "Remove mode of the tool",
    ),
    bind(Act::PaintMode, &[(NONE, Key::C)], "Paint mode of the tool"),
    bind(
        Act::Mirror(0),
        &[(SHIFT, Key::X)],
        "Mirror the tool across X",
    ),
    bind(
        Act::Mirror(1),
        &[(SHIFT, Key::Y)],
        "Mirror the tool across Y",
    ),
    bind(
        Act::Mirror(2),
        &[(SHIFT, Key::Z)],
        "Mirror the tool across Z",
    ),
    bind(
        Act::BrushSmaller,
        &[(NONE, Key::OpenBracket)],
        "Brush one voxel smaller (also the stretch brush)",
    ),
    bind(
        Act::BrushLarger,
        &[(NONE, Key::CloseBracket)],
        "Brush one voxel larger",
    ),
    bind(
        Act::BrushHalve,
        &[(SHIFT, Key::OpenBracket), (SHIFT, Key::OpenCurlyBracket)],
        "Brush half the size",
    ),
    bind(
        Act::BrushDouble,
        &[(SHIFT, Key::CloseBracket), (SHIFT, Key::CloseCurlyBracket)],
        "Brush twice the size",
    ),
    bind(
        Act::SelectAll,
        &[(CMD, Key::A)],
        "Select all voxels of the model (voxel tools)",
    ),
    bind(Act::SelectNone, &[(CMD_SHIFT, Key::A)], "Select no voxels"),
    bind(
        Act::InvertSelection,
        &[(CMD_SHIFT, Key::I)],
        "Invert the voxel selection",
    ),
    bind(Act::Copy, &[(CMD, Key::C)], "Copy the selected voxels"),
    bind(Act::Cut, &[(CMD, Key::X)], "Cut the selected voxels"),
    bind(
        Act::Paste,
        &[(CMD, Key::V)],
        "Paste voxels (the paste floats; with the pointer over the model it lands there)",
    ),
    bind(
        Act::Move(IVec3::NEG_X),
        &[(NONE, Key::ArrowLeft)],
        "Move the floating paste or the selection one voxel along -X",
    ),
    bind(
        Act::Move(IVec3::X),
        &[(NONE, Key::ArrowRight)],
        "Move the floating paste or the selection one voxel along +X",
    ),
    bind(
        Act::Move(IVec3::NEG_Z),
        &[(NONE, Key::ArrowUp)],
        "Move the floating paste or the selection one voxel along -Z",
    ),
    bind(
        Act::Move(IVec3::Z),
        &[(NONE, Key::ArrowDown)],
        "Move the floating paste or the selection one voxel along +Z",
    ),
    bind(
        Act::Move(IVec3::Y),
        &[(NONE, Key::PageUp)],
        "Move the floating paste or the selection one voxel up",
    ),
    bind(
        Act::Move(IVec3::NEG_Y),
        &[(NONE, Key::PageDown)],
        "Move the floating paste or the selection one voxel down",
    ),
    bind(
        Act::PlacePaste,
        &[(NONE, Key::Enter)],
        "Place the floating paste",
    ),
    bind(
        Act::PlacePasteGrowing,
        &[(SHIFT, Key::Enter)],
        "Place the floating paste, growing the canvas to keep what reaches outside it",
    ),
    bind(Act::AddModel, &[(CMD_SHIFT, Key::N)], "Add a voxel model"),
    bind(
        Act::GizmoRotate,
        &[(NONE, Key::R)],
        "Pose gizmo: rotate the selected joint",
    ),
    bind(
        Act::GizmoMove,
        &[(NONE, Key::G)],
        "Pose gizmo: move the selected joint",
    ),
    bind(
        Act::GizmoScale,
        &[(NONE, Key::E)],
        "Pose gizmo: scale the selected joint",
    ),
    bind(
        Act::SetKey,
        &[(NONE, Key::K)],
        "Set the selected joint's key at the playhead",
    ),
    bind(
        Act::DeleteKey,
        &[(SHIFT, Key::K)],
        "Delete the selected joint's key at the playhead",
    ),
    bind(
        Act::Play,
        &[(NONE, Key::Space)],
        "Play / pause the timeline",
    ),
    bind(Act::Perf, &[(NONE, Key::F3)], "Performance overlay"),
    bind(Act::Help, &[(NONE, Key::F1)], "This list"),
];

/// What the mouse, the trackpad and the window do (not keys of this table; listed after it).
pub const GESTURES: &[(&str, &str)] = &[
    (
        "Drag in the view",
        "Orbit (with a voxel tool: use the tool; Alt+drag orbits)",
    ),
    ("Middle-drag / Alt+drag", "Orbit"),
    ("Shift+drag / right-drag", "Pan"),
    ("Scroll / pinch", "Zoom"),
    ("Two-finger trackpad scroll", "Orbit (Shift: pan)"),
    ("Click in the view", "Select the object under the pointer"),
    ("Click a joint dot", "Select the joint (rigged models)"),
    (
        "Alt+click",
        "Pick the colour under the pointer (eyedropper)",
    ),
    (
        "Drag the floating paste",
        "Slide it by whole voxels in the model plane facing you",
    ),
    (
        "Drag a selected voxel (Select tool)",
        "Move the selection by whole voxels (one undo step; Esc puts it back)",
    ),
    ("Ctrl+Plus / Ctrl+Minus", "UI scale (the window's zoom)"),
];

/// The binding of `act` (each action is in the table once; `None` for one that is not bound).
#[must_use]
pub fn binding(act: Act) -> Option<&'static Binding> {
    BINDINGS.iter().find(|b| b.act == act)
}

fn keys_of(act: Act) -> &'static [(Modifiers, Key)] {
    binding(act).map_or(&[], |b| b.keys)
}

/// How many times a key of `act` was pressed this frame (key repeats included); the presses
/// are consumed. A burst of presses in one frame counts each.
pub(super) fn presses(ctx: &egui::Context, act: Act) -> usize {
    keys_of(act)
        .iter()
        .map(|&(m, k)| ctx.input_mut(|i| i.count_and_consume_key(m, k)))
        .sum()
}

/// Whether a key of `act` was pressed this frame (consumed; several presses count once, for
/// actions that toggle or open something).
pub(super) fn pressed(ctx: &egui::Context, act: Act) -> bool {
    keys_of(act)
        .iter()
        .any(|&(m, k)| ctx.input_mut(|i| i.consume_shortcut(&KeyboardShortcut::new(m, k))))
}

/// A key's name as the sheet writes it.
fn key_name(key: Key) -> &'static str {
    match key {
        Key::ArrowLeft => "Left",
        Key::ArrowRight => "Right",
        Key::ArrowUp => "Up",
        Key::ArrowDown => "Down",
        Key::OpenBracket => "[",
        Key::CloseBracket => "]",
        Key::OpenCurlyBracket => "{",
        Key::CloseCurlyBracket => "}",
        Key::Escape => "Esc",
        Key::Delete => "Del",
        other => other.name(),
    }
}

/// The first key of `act` as a menu item shows it (`Ctrl+Shift+Z`); empty for an unbound one.
#[must_use]
pub fn shortcut(act: Act) -> String {
    binding(act).map_or_else(String::new, |b| {
        keys_text(&Binding {
            keys: &b.keys[..1],
            ..*b
        })
    })
}

/// The keys of a binding as the sheet writes them: `Ctrl+Shift+Z / Ctrl+Y`.
#[must_use]
pub fn keys_text(b: &Binding) -> String {
    b.keys
        .iter()
        .map(|&(m, k)| {
            let mut s = String::new();
            if m.command || m.ctrl {
                s.push_str("Ctrl+");
            }
            if m.alt {
                s.push_str("Alt+");
            }
            if m.shift {
                s.push_str("Shift+");
            }
            s.push_str(key_name(k));
            s
        })
        .collect::<Vec<_>>()
        .join(" / ")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each action is bound once and no key (with its modifiers) is bound to two actions;
    /// the sheet's key names are the ones an artist reads.
    #[test]
    fn every_action_is_bound_once_and_keys_do_not_collide() {
        for (i, a) in BINDINGS.iter().enumerate() {
            assert!(!a.keys.is_empty(), "{:?} has no key", a.act);
            for b in &BINDINGS[i + 1..] {
                assert_ne!(a.act, b.act, "{:?} is bound twice", a.act);
                for ka in a.keys {
                    for kb in b.keys {
                        assert!(
                            ka != kb,
                            "{:?} and {:?} share {}",
                            a.act,
                            b.act,
                            keys_text(a)
                        );
                    }
                }
            }
        }
        let text = |act| keys_text(binding(act).unwrap());
        assert_eq!(text(Act::Redo), "Ctrl+Shift+Z / Ctrl+Y");
        assert_eq!(text(Act::Move(IVec3::NEG_X)), "Left");
        assert_eq!(text(Act::BrushHalve), "Shift+[ / Shift+{");
        assert_eq!(text(Act::View(AxisView::Back)), "Ctrl+1");
    }
}
