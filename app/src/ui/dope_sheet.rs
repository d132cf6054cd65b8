//! The dope sheet under the timeline: one row per keyed joint of the playing clip, a diamond per
//! key, a ruler with the clip's frames and the playhead. Click a key to select it (Shift adds or
//! removes), drag a box over keys to select them, drag selected keys in time (snapped to the
//! clip's frames unless Snap is off; one undo step on release), click or drag the ruler to move
//! the playhead. Buttons copy, paste at the playhead, delete, select all, and set the selected
//! joints' interpolation; the clip's frame rate is chosen here too.

use thicket_core::skin::{Interpolation, KeyRef};

use crate::editor::{Editor, KEY_EPSILON_SECS, KeyClipboard};

/// Width of the joint-name column, points.
const NAME_WIDTH: f32 = 120.0;
/// Height of a joint row and of the ruler, points.
const ROW_HEIGHT: f32 = 18.0;
/// Rows shown before the sheet scrolls.
const MAX_ROWS: usize = 8;
/// How close (points) the pointer must be to a key to grab it.
const KEY_GRAB_PX: f32 = 7.0;
/// Frame rates offered.
const FRAME_RATES: [f32; 7] = [12.0, 24.0, 25.0, 30.0, 48.0, 50.0, 60.0];

const KEY_COLOR: egui::Color32 = egui::Color32::from_gray(200);
const SELECTED_COLOR: egui::Color32 = egui::Color32::from_rgb(255, 210, 60);
const PLAYHEAD_COLOR: egui::Color32 = egui::Color32::from_rgb(90, 160, 255);

/// A drag of selected keys in progress.
#[derive(Debug, Clone, Copy)]
struct KeyDrag {
    /// The key under the pointer when the drag started.
    grab: KeyRef,
    /// Pointer x when the drag started.
    start_x: f32,
    /// The shift (seconds) the keys would get if dropped now.
    dt: f32,
}

/// The dope sheet's state.
#[derive(Debug)]
pub struct DopeSheet {
    /// Shown under the timeline.
    pub open: bool,
    /// Selected keys of the playing clip.
    pub selected: Vec<KeyRef>,
    /// Keys copied with Copy.
    pub clipboard: Option<KeyClipboard>,
    /// Dragged keys land on the clip's frames.
    pub snap: bool,
    /// The ruler moved the playhead this frame.
    pub scrubbed: bool,
    drag: Option<KeyDrag>,
    /// Where a box selection started.
    box_start: Option<egui::Pos2>,
    /// The clip (object, index) the selection belongs to.
    clip: Option<(u64, usize)>,
    /// Why the last edit was refused.
    pub error: Option<String>,
}

impl Default for DopeSheet {
    fn default() -> Self {
        Self {
            open: false,
            selected: Vec::new(),
            clipboard: None,
            snap: true,
            scrubbed: false,
            drag: None,
            box_start: None,
            clip: None,
            error: None,
        }
    }
}

fn is_selected(selected: &[KeyRef], k: KeyRef) -> bool {
    selected
        .iter()
        .any(|s| s.joint == k.joint && (s.time_secs - k.time_secs).abs() < KEY_EPSILON_SECS)
}

fn interpolation_label(i: Interpolation) -> &'static str {
    match i {
        Interpolation::Step => "Step",
        Interpolation::Linear => "Linear",
        Interpolation::CubicSpline => "Cubic",
    }
}

/// Draws the dope sheet of rigged model `id`'s playing clip and applies its edits; moves the
/// playhead in `playback` when the ruler is used.
#[allow(clippy::too_many_lines)] // the header's commands, one after another
pub fn dope_sheet_ui(
    ui: &mut egui::Ui,
    editor: &mut Editor,
    sheet: &mut DopeSheet,
    id: u64,
    playback: &mut thicket_core::skin::Playback,
) {
    sheet.scrubbed = false;
    let Ok((clip_index, clip)) = editor.playing_clip(id) else {
        return;
    };
    if sheet.clip != Some((id, clip_index)) {
        sheet.selected.clear();
        sheet.drag = None;
        sheet.clip = Some((id, clip_index));
    }
    let clip = clip.clone();
    let Some(rig) = editor.rig(id) else { return };
    let names: Vec<String> = rig.skeleton.joints.iter().map(|j| j.name.clone()).collect();
    let keys = clip.keys();
    // Keys deleted or moved elsewhere (undo, the timeline's buttons) leave the selection.
    sheet
        .selected
        .retain(|s| keys.iter().any(|k| is_selected(&[*s], *k)));
    let mut joints: Vec<usize> = keys.iter().map(|k| k.joint).collect();
    joints.dedup();
    let selected_joints: Vec<usize> = {
        let mut j: Vec<usize> = sheet.selected.iter().map(|k| k.joint).collect();
        j.sort_unstable();
        j.dedup();
        j
    };

    // Header: frame rate, snap, selection commands.
    ui.horizontal(|ui| {
        ui.strong("Dope sheet")
            .on_hover_text("Keys of every joint in this clip");
        let mut rate = clip.frame_rate;
        egui::ComboBox::from_id_salt("dope_frame_rate")
            .selected_text(format!("{rate} fps"))
            .show_ui(ui, |ui| {
                for r in FRAME_RATES {
                    ui.selectable_value(&mut rate, r, format!("{r} fps"));
                }
            })
            .response
            .on_hover_text("The clip's frame rate: keys snap to its frames and the timeline counts them (glTF stores seconds, so the export is unchanged)");
        if rate != clip.frame_rate {
            sheet.error = editor
                .set_clip_frame_rate(id, clip_index, rate)
                .err()
                .map(|e| e.to_string());
        }
        ui.checkbox(&mut sheet.snap, "Snap")
            .on_hover_text("Dragged keys and the ruler's playhead land on whole frames");
        if ui
            .add_enabled(!keys.is_empty(), egui::Button::new("Select all"))
            .on_hover_text("Select every key of the clip")
            .clicked()
        {
            sheet.selected.clone_from(&keys);
        }
        let any = !sheet.selected.is_empty();
        if ui
            .add_enabled(any, egui::Button::new("Copy"))
            .on_hover_text("Copy the selected keys (they paste onto joints of the same names)")
            .clicked()
        {
            match editor.copy_keys(id, &sheet.selected) {
                Ok(c) => sheet.clipboard = Some(c),
                Err(e) => sheet.error = Some(e.to_string()),
            }
        }
        if ui
            .add_enabled(sheet.clipboard.is_some(), egui::Button::new("Paste at playhead"))
            .on_hover_text("Paste the copied keys with their spacing, the first at the playhead")
            .clicked()
            && let Some(c) = &sheet.clipboard
        {
            let at = clip.wrap_time(playback.time_secs, playback.wrap);
            let at = if playback.wrap == thicket_core::skin::Wrap::Clamp {
                playback.time_secs.max(0.0)
            } else {
                at
            };
            match editor.paste_keys(id, c, at) {
                Ok(written) => {
                    sheet.selected = written;
                    sheet.error = None;
                }
                Err(e) => sheet.error = Some(e.to_string()),
            }
        }
        if ui
            .add_enabled(any, egui::Button::new("Delete keys"))
            .on_hover_text("Delete the selected keys (the clip keeps its length)")
            .clicked()
        {
            sheet.error = editor
                .delete_keys(id, &sheet.selected)
                .err()
                .map(|e| e.to_string());
            sheet.selected.clear();
        }
        let current = selected_joints
            .iter()
            .map(|&j| clip.joint_interpolation(j))
            .reduce(|a, b| if a == b { a } else { None })
            .flatten();
        let mut chosen = current;
        ui.add_enabled_ui(any, |ui| {
            egui::ComboBox::from_id_salt("dope_interpolation")
                .selected_text(match current {
                    Some(i) => interpolation_label(i),
                    None if any => "Mixed",
                    None => "Interpolation",
                })
                .show_ui(ui, |ui| {
                    for i in [
                        Interpolation::Step,
                        Interpolation::Linear,
                        Interpolation::CubicSpline,
                    ] {
                        ui.selectable_value(&mut chosen, Some(i), interpolation_label(i));
                    }
                })
                .response
                .on_hover_text("Interpolation of the selected keys' joints: glTF keeps one per channel, so every key of those joints follows; keyed values stay");
        });
        if chosen != current
            && let Some(i) = chosen
        {
            sheet.error = editor
                .set_keys_interpolation(id, &selected_joints, i)
                .err()
                .map(|e| e.to_string());
        }
        ui.weak(format!("{} of {} key(s) selected", sheet.selected.len(), keys.len()));
    });
    if let Some(e) = &sheet.error {
        ui.colored_label(ui.visuals().error_fg_color, e);
    }
    if joints.is_empty() {
        ui.weak("No keys yet: pose a joint and Set key (K), or turn Auto-key on.");
        return;
    }

    let shown_rows = joints.len().min(MAX_ROWS) + 1;
    egui::ScrollArea::vertical()
        .id_salt("dope_rows")
        .min_scrolled_height(ROW_HEIGHT * shown_rows as f32)
        .max_height(ROW_HEIGHT * shown_rows as f32)
        .show(ui, |ui| {
            let view = Tracks {
                clip: &clip,
                keys: &keys,
                joints: &joints,
                names: &names,
                selected_joints: &selected_joints,
            };
            tracks_ui(ui, editor, sheet, id, playback, &view);
        });
}

/// What the tracks draw: the playing clip and its keys, by joint.
struct Tracks<'a> {
    clip: &'a thicket_core::skin::AnimationClip,
    keys: &'a [KeyRef],
    /// Keyed joints, one row each.
    joints: &'a [usize],
    names: &'a [String],
    selected_joints: &'a [usize],
}

/// The ruler and one row per keyed joint, with their interaction.
#[allow(clippy::too_many_lines)] // one layout: ruler, rows, picking, dragging, drawing
fn tracks_ui(
    ui: &mut egui::Ui,
    editor: &mut Editor,
    sheet: &mut DopeSheet,
    id: u64,
    playback: &mut thicket_core::skin::Playback,
    view: &Tracks<'_>,
) {
    let Tracks {
        clip,
        keys,
        joints,
        names,
        selected_joints,
    } = *view;
    let rows = joints.len();
    // Time axis: the clip's length (or its last key, if later) across the track.
    let span = clip.duration_secs.max(clip.last_key_time()).max(1e-3);
    let width = ui.available_width();
    let (rect, _) = ui.allocate_exact_size(
        egui::vec2(width, ROW_HEIGHT * (rows as f32 + 1.0)),
        egui::Sense::hover(),
    );
    let track = egui::Rect::from_min_max(
        egui::pos2(rect.left() + NAME_WIDTH, rect.top()),
        egui::pos2(rect.right() - 8.0, rect.bottom()),
    );
    let x_of = |t: f32| track.left() + t / span * track.width();
    let t_of = |x: f32| (x - track.left()) / track.width() * span;
    let painter = ui.painter_at(rect);
    let visuals = ui.visuals().clone();
    painter.rect_filled(rect, 2.0, visuals.extreme_bg_color);

    // Ruler: frames as ticks (labels every whole second), click or drag to move the playhead.
    let ruler = egui::Rect::from_min_size(track.min, egui::vec2(track.width(), ROW_HEIGHT));
    let ruler_response = ui
        .interact(
            ruler,
            ui.scope_id().with("dope_ruler"),
            egui::Sense::click_and_drag(),
        )
        .on_hover_text("Click or drag to move the playhead");
    let fps = clip.frame_rate.max(1.0);
    let frames = (span * fps).ceil() as u32;
    // At most about one tick per 6 points.
    let every = (((frames as f32) * 6.0 / track.width().max(1.0)).ceil() as u32).max(1);
    // Frame numbers at least 40 points apart, on multiples of the tick step.
    let label_every = {
        let px_per_frame = track.width() / (span * fps).max(1.0);
        let want = (40.0 / px_per_frame).ceil().max(1.0) as u32;
        want.div_ceil(every) * every
    };
    for f in (0..=frames).step_by(every as usize) {
        let x = x_of(f as f32 / fps);
        let labelled = f % label_every == 0;
        let h = if labelled { 8.0 } else { 4.0 };
        painter.line_segment(
            [
                egui::pos2(x, ruler.bottom() - h),
                egui::pos2(x, ruler.bottom()),
            ],
            egui::Stroke::new(1.0, visuals.weak_text_color()),
        );
        if labelled && x < track.right() - 16.0 {
            painter.text(
                egui::pos2(x + 2.0, ruler.top()),
                egui::Align2::LEFT_TOP,
                format!("{f}"),
                egui::FontId::monospace(10.0),
                visuals.weak_text_color(),
            );
        }
    }
    if let Some(p) = ruler_response.interact_pointer_pos()
        && (ruler_response.clicked() || ruler_response.dragged())
    {
        let t = t_of(p.x).clamp(0.0, span);
        playback.time_secs = if sheet.snap { clip.snap_to_frame(t) } else { t };
        sheet.scrubbed = true;
    }

    // Rows: names and keys.
    let row_top = |r: usize| track.top() + ROW_HEIGHT * (r as f32 + 1.0);
    let shown = joints;
    for (r, &j) in shown.iter().enumerate() {
        let y = row_top(r);
        if r % 2 == 1 {
            painter.rect_filled(
                egui::Rect::from_min_max(
                    egui::pos2(rect.left(), y),
                    egui::pos2(rect.right(), y + ROW_HEIGHT),
                ),
                0.0,
                visuals.faint_bg_color,
            );
        }
        let name = names.get(j).map_or("?", String::as_str);
        painter.text(
            egui::pos2(rect.left() + 4.0, y + ROW_HEIGHT / 2.0),
            egui::Align2::LEFT_CENTER,
            name,
            egui::FontId::proportional(12.0),
            // Joints with selected keys are named in the selection's colour.
            if selected_joints.contains(&j) {
                SELECTED_COLOR
            } else {
                visuals.text_color()
            },
        );
    }
    let key_pos = |k: KeyRef| {
        let r = shown.iter().position(|&j| j == k.joint)?;
        Some(egui::pos2(x_of(k.time_secs), row_top(r) + ROW_HEIGHT / 2.0))
    };

    // Interaction over the key rows.
    let rows_rect = egui::Rect::from_min_max(
        egui::pos2(track.left() - KEY_GRAB_PX, row_top(0)),
        egui::pos2(track.right() + KEY_GRAB_PX, rect.bottom()),
    );
    let response = ui.interact(
        rows_rect,
        ui.scope_id().with("dope_keys"),
        egui::Sense::click_and_drag(),
    );
    response.widget_info(|| egui::WidgetInfo::labeled(egui::Role::Canvas, true, "Dope sheet keys"));
    let hit = |p: egui::Pos2| {
        keys.iter()
            .copied()
            .filter_map(|k| Some((k, key_pos(k)?.distance(p))))
            .filter(|(_, d)| *d <= KEY_GRAB_PX)
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(k, _)| k)
    };
    let shift = ui.input(|i| i.modifiers.shift);
    if response.clicked()
        && let Some(p) = response.interact_pointer_pos()
    {
        match hit(p) {
            Some(k) if shift => {
                if is_selected(&sheet.selected, k) {
                    sheet.selected.retain(|s| !is_selected(&[*s], k));
                } else {
                    sheet.selected.push(k);
                }
            }
            Some(k) => sheet.selected = vec![k],
            None if !shift => sheet.selected.clear(),
            None => {}
        }
    }
    // A drag is recognised only after the pointer has moved: what it grabbed is under the
    // point where the button went down.
    if response.drag_started()
        && let Some(p) = ui
            .input(|i| i.pointer.press_origin())
            .or(response.interact_pointer_pos())
    {
        match hit(p) {
            Some(k) => {
                if !is_selected(&sheet.selected, k) {
                    if !shift {
                        sheet.selected.clear();
                    }
                    sheet.selected.push(k);
                }
                sheet.drag = Some(KeyDrag {
                    grab: k,
                    start_x: p.x,
                    dt: 0.0,
                });
            }
            None => sheet.box_start = Some(p),
        }
    }
    if let (Some(drag), Some(p)) = (&mut sheet.drag, response.interact_pointer_pos()) {
        let raw = drag.grab.time_secs + (p.x - drag.start_x) / track.width() * span;
        let landed = if sheet.snap {
            clip.snap_to_frame(raw)
        } else {
            raw
        };
        drag.dt = landed - drag.grab.time_secs;
    }
    let box_rect = sheet
        .box_start
        .zip(response.interact_pointer_pos())
        .map(|(a, b)| egui::Rect::from_two_pos(a, b));
    if response.drag_stopped() {
        if let Some(drag) = sheet.drag.take()
            && drag.dt != 0.0
        {
            match editor.move_keys(id, &sheet.selected, drag.dt) {
                Ok(moved) => {
                    sheet.selected = moved;
                    sheet.error = None;
                }
                Err(e) => sheet.error = Some(e.to_string()),
            }
        }
        if let (Some(_), Some(b)) = (sheet.box_start.take(), box_rect) {
            if !shift {
                sheet.selected.clear();
            }
            for k in keys {
                if key_pos(*k).is_some_and(|p| b.contains(p)) && !is_selected(&sheet.selected, *k) {
                    sheet.selected.push(*k);
                }
            }
        }
    }

    // Keys (moved ones where they would land), the box, the playhead.
    let dt = sheet.drag.map_or(0.0, |d| d.dt);
    for &k in keys {
        let selected = is_selected(&sheet.selected, k);
        let k = if selected {
            KeyRef {
                time_secs: (k.time_secs + dt).max(0.0),
                ..k
            }
        } else {
            k
        };
        let Some(c) = key_pos(k) else { continue };
        key_diamond(
            &painter,
            c,
            5.0,
            if selected { SELECTED_COLOR } else { KEY_COLOR },
        );
    }
    if let Some(b) = box_rect.filter(|_| sheet.box_start.is_some()) {
        painter.rect_stroke(
            b,
            0.0,
            egui::Stroke::new(1.0, SELECTED_COLOR),
            egui::StrokeKind::Inside,
        );
    }
    let playhead = clip.wrap_time(playback.time_secs, playback.wrap);
    let x = x_of(playhead);
    painter.line_segment(
        [egui::pos2(x, rect.top()), egui::pos2(x, rect.bottom())],
        egui::Stroke::new(1.5, PLAYHEAD_COLOR),
    );
}

/// A key drawn as a diamond of half-diagonal `r` at `c`.
pub(super) fn key_diamond(painter: &egui::Painter, c: egui::Pos2, r: f32, fill: egui::Color32) {
    painter.add(egui::Shape::convex_polygon(
        vec![
            c + egui::vec2(0.0, -r),
            c + egui::vec2(r, 0.0),
            c + egui::vec2(0.0, r),
            c + egui::vec2(-r, 0.0),
        ],
        fill,
        egui::Stroke::new(1.0, egui::Color32::BLACK),
    ));
}
