//! The Trade-off panel (View → Trade-off): the quality sweep of `thicket tradeoff` run on the
//! current view in the background, plotted as cost against error with the Pareto front and
//! the presets marked; clicking a point makes its setting the document's quality.
//!
//! The panel only holds settings and the last report. Running and cancelling go through the
//! app's background job (status bar progress and Cancel), so a sweep can never run beside
//! another job that changes the document.

use egui_plot::{
    GridMark, HoverPosition, Legend, Line, MarkerShape, Plot, PlotPoint, PlotTransform, Points,
    Text,
};
use thicket_core::measure::{KnobValues, SweepPoint, SweepReport, SweepSettings, default_knobs};
use thicket_core::quality::{Quality, QualityPreset};

use crate::editor::Editor;
use crate::files::thousands;
use crate::tradeoff::{compact_number, log_ticks};

/// [`TradeoffPanel::size_px`] that means "the view's own render size in pixels".
pub const VIEW_SIZE: u32 = 0;

/// The image size when the view's size is not known yet (no frame drawn): the editor's
/// typical 800 x 800 view.
const FALLBACK_SIZE_PX: u32 = 800;

/// A click selects the nearest point within this many points of the screen.
const PICK_RADIUS: f32 = 14.0;

/// Which cost the plot puts on its x axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CostAxis {
    /// Median wall time of the renders (what the user waits for; noisy on a busy machine).
    Time,
    /// The renderer's deterministic work count (nodes, triangles, shading taps).
    Work,
}

/// What the panel asks the app to do.
#[derive(Debug, Clone)]
pub enum PanelAction {
    /// Start a sweep in the background.
    Run(Box<SweepJob>),
    /// Make this the document's quality (one undo step).
    Apply(Box<Quality>, String),
    /// Stop the running sweep.
    Cancel,
}

pub use crate::editor::jobs::SweepJob;

/// The panel's state.
pub struct TradeoffPanel {
    /// Whether the window is open.
    pub open: bool,
    /// Longest image edge of the sweep in pixels (the view's aspect ratio is kept), or
    /// [`VIEW_SIZE`]: the view's own render size, where the presets are actually used.
    pub size_px: u32,
    /// Renders per setting (the time is their median).
    pub repeats: usize,
    /// The knobs and whether each is swept.
    pub knobs: Vec<(KnobValues, bool)>,
    /// Also measure the draft / balanced / final presets.
    pub presets: bool,
    /// The x axis of the plot.
    pub axis: CostAxis,
    report: Option<(SweepReport, u64)>,
    /// Where the plot drew last frame (to pick the clicked point, and for tests).
    transform: Option<PlotTransform>,
    /// Index of the point last applied.
    applied: Option<usize>,
    /// UI time and fraction when the running sweep's progress was first seen (for the
    /// remaining-time estimate).
    started: Option<(f64, f32)>,
}

impl Default for TradeoffPanel {
    fn default() -> Self {
        Self {
            open: false,
            size_px: VIEW_SIZE,
            repeats: 3,
            knobs: default_knobs().into_iter().map(|k| (k, true)).collect(),
            presets: true,
            axis: CostAxis::Time,
            report: None,
            transform: None,
            applied: None,
            started: None,
        }
    }
}

impl TradeoffPanel {
    /// The last finished sweep.
    #[must_use]
    pub fn report(&self) -> Option<&SweepReport> {
        self.report.as_ref().map(|(r, _)| r)
    }

    /// Stores a finished sweep (of the editor at `revision`).
    pub fn set_report(&mut self, report: SweepReport, revision: u64) {
        self.report = Some((report, revision));
        self.applied = None;
        self.transform = None;
    }

    /// The index of the point applied last (cleared by a new report).
    #[must_use]
    pub fn applied(&self) -> Option<usize> {
        self.applied
    }

    /// Where point `index` of the report was drawn in the last frame (screen points).
    #[must_use]
    pub fn point_screen_pos(&self, index: usize) -> Option<egui::Pos2> {
        let (report, _) = self.report.as_ref()?;
        let p = report.points.get(index)?;
        let t = self.transform.as_ref()?;
        Some(t.position_from_point(&plot_point(p, self.axis)?))
    }

    /// The sweep's image size for a view that renders `view_size_px` pixels: the view's own
    /// size with [`VIEW_SIZE`], else the panel's longest edge at the view's aspect ratio.
    #[must_use]
    pub fn image_size(&self, view_size_px: egui::Vec2) -> (u32, u32) {
        let known = view_size_px.x.is_finite()
            && view_size_px.y.is_finite()
            && view_size_px.x >= 1.0
            && view_size_px.y >= 1.0;
        if self.size_px == VIEW_SIZE {
            return if known {
                (
                    (view_size_px.x.round() as u32).clamp(8, 4096),
                    (view_size_px.y.round() as u32).clamp(8, 4096),
                )
            } else {
                (FALLBACK_SIZE_PX, FALLBACK_SIZE_PX)
            };
        }
        let aspect = if known {
            (view_size_px.x / view_size_px.y).clamp(0.25, 4.0)
        } else {
            1.0
        };
        let edge = self.size_px.max(8) as f32;
        let (width, height) = if aspect >= 1.0 {
            (edge, (edge / aspect).round().max(1.0))
        } else {
            ((edge * aspect).round().max(1.0), edge)
        };
        (width as u32, height as u32)
    }

    /// The sweep the Run button starts: the current view at the panel's size
    /// ([`TradeoffPanel::image_size`]).
    #[must_use]
    pub fn job(&self, editor: &Editor, view_size_px: egui::Vec2) -> SweepJob {
        let (width, height) = self.image_size(view_size_px);
        let doc = editor.doc();
        SweepJob {
            doc: doc.clone(),
            width,
            height,
            settings: SweepSettings {
                base: doc.quality.clone(),
                knobs: self
                    .knobs
                    .iter()
                    .filter(|(_, on)| *on)
                    .map(|(k, _)| k.clone())
                    .collect(),
                grid: false,
                presets: self.presets,
                repeats: self.repeats.max(1),
            },
            revision: editor.revision(),
        }
    }

    /// Draws the window when open. `running`: the sweep job's progress when one runs (`Some(None)`
    /// while it cannot tell); `busy`: any background job runs.
    pub fn ui(
        &mut self,
        ctx: &egui::Context,
        editor: &Editor,
        view_size_px: egui::Vec2,
        running: Option<Option<f32>>,
        busy: bool,
    ) -> Option<PanelAction> {
        if !self.open {
            return None;
        }
        let mut open = self.open;
        let mut action = None;
        egui::Window::new("Trade-off")
            .open(&mut open)
            .default_width(560.0)
            .default_pos(egui::pos2(320.0, 90.0))
            .show(ctx, |ui| {
                action = self.contents_ui(ui, editor, view_size_px, running, busy);
            });
        self.open = open;
        action
    }

    fn contents_ui(
        &mut self,
        ui: &mut egui::Ui,
        editor: &Editor,
        view_size_px: egui::Vec2,
        running: Option<Option<f32>>,
        busy: bool,
    ) -> Option<PanelAction> {
        let mut action = None;
        ui.label(
            "Renders the current view with each setting and compares it with a high-quality \
             reference render. Click a point to use its setting.",
        );
        ui.horizontal(|ui| {
            ui.label("Size");
            let mut follow = self.size_px == VIEW_SIZE;
            if ui
                .checkbox(&mut follow, "View's")
                .on_hover_text(
                    "Render at the view's own size, where the presets are used (slower than a \
                     small sweep, but a knob that changes nothing at a small size may matter \
                     here)",
                )
                .changed()
            {
                self.size_px = if follow { VIEW_SIZE } else { 256 };
            }
            if self.size_px == VIEW_SIZE {
                let (w, h) = self.image_size(view_size_px);
                ui.weak(format!("{w} x {h} px"));
            } else {
                ui.add(
                    egui::DragValue::new(&mut self.size_px)
                        .range(16..=2048)
                        .suffix(" px"),
                )
                .on_hover_text(
                    "Longest edge of the sweep's images; the view's aspect ratio is kept",
                );
            }
            ui.label("Renders");
            ui.add(egui::DragValue::new(&mut self.repeats).range(1..=9))
                .on_hover_text("Renders per setting; the time is their median");
            ui.checkbox(&mut self.presets, "Presets")
                .on_hover_text("Also measure the draft, balanced and final presets");
        });
        ui.horizontal_wrapped(|ui| {
            ui.label("Knobs");
            for (k, on) in &mut self.knobs {
                let spec = thicket_core::quality::KnobSpec::named(&k.name);
                ui.checkbox(on, knob_label(&k.name)).on_hover_text(format!(
                    "{}{}Values: {} ({})",
                    spec.map_or("", |s| s.doc),
                    if spec.is_some() { "\n" } else { "" },
                    k.values.join(", "),
                    k.name
                ));
            }
        });
        ui.horizontal(|ui| {
            match running {
                Some(fraction) => {
                    match fraction {
                        Some(f) => {
                            let now = ui.input(|i| i.time);
                            let (t0, f0) = *self.started.get_or_insert((now, f));
                            ui.add(
                                egui::ProgressBar::new(f)
                                    .desired_width(160.0)
                                    .show_percentage(),
                            );
                            ui.weak(remaining_text(now - t0, f - f0, 1.0 - f));
                        }
                        None => {
                            ui.spinner();
                        }
                    }
                    if ui
                        .button("Cancel")
                        .on_hover_text("Stop the sweep; the last report stays")
                        .clicked()
                    {
                        action = Some(PanelAction::Cancel);
                    }
                }
                None => {
                    self.started = None;
                    let any_knob = self.knobs.iter().any(|(_, on)| *on) || self.presets;
                    if ui
                        .add_enabled(!busy && any_knob, egui::Button::new("Run sweep"))
                        .on_hover_text(
                            "Render the current view with each setting (in the background)",
                        )
                        .on_disabled_hover_text(
                            "Another job is running, or nothing is selected to sweep",
                        )
                        .clicked()
                    {
                        action = Some(PanelAction::Run(Box::new(self.job(editor, view_size_px))));
                    }
                }
            }
            ui.separator();
            ui.label("Cost");
            ui.selectable_value(&mut self.axis, CostAxis::Time, "Time")
                .on_hover_text("Median wall time per render (noisy when the machine is busy)");
            ui.selectable_value(&mut self.axis, CostAxis::Work, "Work")
                .on_hover_text(
                    "Deterministic work count: octree nodes visited, triangles, shading taps",
                );
        });
        let Some((report, revision)) = &self.report else {
            ui.weak("No sweep yet.");
            return action;
        };
        if *revision != editor.revision() {
            ui.colored_label(
                ui.visuals().warn_fg_color,
                "The document or the view changed since this sweep: run it again for current figures.",
            );
        }
        ui.label(format!(
            "{} settings at {} x {} px; reference {:.1} ms",
            report.points.len(),
            report.width,
            report.height,
            report.reference_time_ms
        ));
        let dropped = report.dropped_knobs();
        if !dropped.is_empty() {
            ui.label(format!(
                "No effect at this size, left out: {}",
                dropped
                    .iter()
                    .map(|d| knob_label(d))
                    .collect::<Vec<_>>()
                    .join(", ")
            ))
            .on_hover_text(
                report
                    .knobs
                    .iter()
                    .map(|k| k.summary())
                    .collect::<Vec<_>>()
                    .join("\n"),
            );
        }
        let picked = self.plot_ui(ui);
        if let Some(i) = picked.or_else(|| self.table_ui(ui)) {
            let p = &self.report.as_ref()?.0.points[i];
            self.applied = Some(i);
            action = Some(PanelAction::Apply(
                Box::new(p.setting.quality.clone()),
                p.setting.label.clone(),
            ));
        }
        action
    }

    /// The plot; returns the point clicked.
    fn plot_ui(&mut self, ui: &mut egui::Ui) -> Option<usize> {
        let (report, _) = self.report.as_ref()?;
        let axis = self.axis;
        let on_front = |p: &SweepPoint| match axis {
            CostAxis::Time => p.on_time_front,
            CostAxis::Work => p.on_work_front,
        };
        let xy: Vec<Option<[f64; 2]>> = report
            .points
            .iter()
            .map(|p| plot_point(p, axis).map(|pp| [pp.x, pp.y]))
            .collect();
        // Series of (position, label); the labels name the point under the pointer.
        let series = |front: bool| -> (Vec<[f64; 2]>, Vec<String>) {
            let mut v: Vec<([f64; 2], String)> = report
                .points
                .iter()
                .zip(&xy)
                .filter(|(p, _)| on_front(p) == front)
                .filter_map(|(p, xy)| Some(((*xy)?, p.setting.label.clone())))
                .collect();
            v.sort_by(|a, b| a.0[0].total_cmp(&b.0[0]));
            v.into_iter().unzip()
        };
        let (front, front_labels) = series(true);
        let (others, other_labels) = series(false);
        let mut presets: Vec<(PlotPoint, &'static str)> = report
            .points
            .iter()
            .zip(&xy)
            .filter_map(|(p, xy)| {
                Some((
                    PlotPoint::new(xy.as_ref()?[0], xy.as_ref()?[1]),
                    preset_name(p)?,
                ))
            })
            .collect();
        // By cost: neighbours' names go on opposite sides of their rings (above, below,
        // above), so presets close in cost (draft and balanced) never write over each other.
        presets.sort_by(|a, b| a.0.x.total_cmp(&b.0.x));
        let applied = self.applied.and_then(|i| xy.get(i).copied().flatten());
        // The time's spread over the renders, on the log axis the points use.
        let spreads: Vec<[[f64; 2]; 2]> = match axis {
            CostAxis::Time => report
                .points
                .iter()
                .zip(&xy)
                .filter(|(p, _)| p.times_ms.len() > 1 && p.time_min_ms > 0.0)
                .filter_map(|(p, xy)| {
                    let y = (*xy)?[1];
                    Some([[p.time_min_ms.log10(), y], [p.time_max_ms.log10(), y]])
                })
                .collect(),
            CostAxis::Work => Vec::new(),
        };
        // Preset names sit up and to the right of their ring, not on it: an offset of a few
        // percent of the data's extent (the plot's bounds follow the data).
        let extent = |k: usize| {
            let (lo, hi) = xy
                .iter()
                .flatten()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                    (lo.min(p[k]), hi.max(p[k]))
                });
            if hi > lo { hi - lo } else { 1.0 }
        };
        let label_offset = (0.02 * extent(0), 0.05 * extent(1));
        let x_label = match axis {
            CostAxis::Time => "median time per render (ms, log scale)",
            CostAxis::Work => "work units (log scale)",
        };
        let response = Plot::new("tradeoff_plot")
            .height(260.0)
            .legend(Legend::default())
            .allow_drag(false)
            .allow_zoom(false)
            .allow_scroll(false)
            .allow_boxed_zoom(false)
            .allow_double_click_reset(false)
            .x_axis_label(x_label)
            .y_axis_label("RMSE vs reference")
            .include_y(0.0)
            .x_grid_spacer(|input| {
                let (lo, hi) = input.bounds;
                log_ticks(10f64.powf(lo), 10f64.powf(hi), 6)
                    .into_iter()
                    .map(|v| GridMark {
                        value: v.log10(),
                        step_size: (hi - lo).max(1e-9) / 6.0,
                    })
                    .collect()
            })
            .x_axis_formatter(|mark, _| compact_number(10f64.powf(mark.value)))
            .label_formatter(move |hover| {
                let HoverPosition::NearDataPoint {
                    plot_name,
                    position,
                    index,
                } = *hover
                else {
                    return None;
                };
                let label = match plot_name {
                    "Pareto front" => front_labels.get(index)?,
                    "other settings" => other_labels.get(index)?,
                    _ => return None,
                };
                let cost = compact_number(10f64.powf(position.x));
                let unit = match axis {
                    CostAxis::Time => "ms",
                    CostAxis::Work => "work",
                };
                Some(format!("{label}\n{cost} {unit}, RMSE {:.5}", position.y))
            })
            .show(ui, |plot| {
                for bar in spreads {
                    plot.line(
                        Line::new("min-max of the renders", bar.to_vec())
                            .color(egui::Color32::from_gray(150))
                            .width(1.0),
                    );
                }
                plot.points(
                    Points::new("other settings", others)
                        .radius(4.0)
                        .color(egui::Color32::from_rgb(110, 150, 230)),
                );
                plot.line(
                    Line::new("Pareto front", front.clone())
                        .color(egui::Color32::from_rgb(230, 80, 70))
                        .width(2.0),
                );
                plot.points(
                    Points::new("Pareto front", front)
                        .radius(5.0)
                        .color(egui::Color32::from_rgb(230, 80, 70)),
                );
                for (k, (pos, name)) in presets.into_iter().enumerate() {
                    plot.points(
                        Points::new("presets", vec![[pos.x, pos.y]])
                            .shape(MarkerShape::Circle)
                            .filled(false)
                            .radius(9.0)
                            .color(egui::Color32::from_gray(230)),
                    );
                    let (dy, anchor) = if k % 2 == 0 {
                        (label_offset.1, egui::Align2::LEFT_BOTTOM)
                    } else {
                        (-label_offset.1, egui::Align2::LEFT_TOP)
                    };
                    let at = PlotPoint::new(pos.x + label_offset.0, pos.y + dy);
                    plot.text(
                        Text::new("presets", at, name)
                            .anchor(anchor)
                            .color(egui::Color32::from_gray(230)),
                    );
                }
                if let Some([x, y]) = applied {
                    plot.points(
                        Points::new("applied", vec![[x, y]])
                            .shape(MarkerShape::Diamond)
                            .radius(7.0)
                            .color(egui::Color32::from_rgb(250, 210, 80)),
                    );
                }
            });
        self.transform = Some(response.transform);
        if !response.response.clicked() {
            return None;
        }
        let pos = response.response.interact_pointer_pos()?;
        let t = &response.transform;
        xy.iter()
            .enumerate()
            .filter_map(|(i, xy)| {
                let [x, y] = (*xy)?;
                let d = t.position_from_point(&PlotPoint::new(x, y)).distance(pos);
                (d <= PICK_RADIUS).then_some((i, d))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i)
    }

    /// The points as a table with a Use button each; returns the row whose button was clicked.
    fn table_ui(&self, ui: &mut egui::Ui) -> Option<usize> {
        let (report, _) = self.report.as_ref()?;
        let mut chosen = None;
        egui::CollapsingHeader::new("Settings")
            .default_open(false)
            .show(ui, |ui| {
                egui::ScrollArea::vertical()
                    .max_height(220.0)
                    .show(ui, |ui| {
                        egui::Grid::new("tradeoff_points")
                            .striped(true)
                            .show(ui, |ui| {
                                for h in ["Setting", "ms", "Work", "RMSE", "Front", ""] {
                                    ui.strong(h);
                                }
                                ui.end_row();
                                for (i, p) in report.points.iter().enumerate() {
                                    ui.label(&p.setting.label);
                                    ui.label(format!("{:.2}", p.time_ms)).on_hover_text(format!(
                                        "Median of {} render(s); {:.2} to {:.2} ms",
                                        p.times_ms.len(),
                                        p.time_min_ms,
                                        p.time_max_ms
                                    ));
                                    ui.label(thousands(p.work));
                                    ui.label(format!("{:.5}", p.error.rmse));
                                    ui.label(match (p.on_time_front, p.on_work_front) {
                                        (true, true) => "time, work",
                                        (true, false) => "time",
                                        (false, true) => "work",
                                        (false, false) => "",
                                    });
                                    if ui
                                        .small_button("Use")
                                        .on_hover_text(
                                            "Make this the document's quality (undoable)",
                                        )
                                        .clicked()
                                    {
                                        chosen = Some(i);
                                    }
                                    ui.end_row();
                                }
                            });
                    });
            });
        chosen
    }
}

/// A point's plot position: log10 of its cost, and its RMSE; `None` when either is not a
/// positive finite number (a log axis cannot show it).
fn plot_point(p: &SweepPoint, axis: CostAxis) -> Option<PlotPoint> {
    let cost = match axis {
        CostAxis::Time => p.time_ms,
        CostAxis::Work => p.work as f64,
    };
    (cost > 0.0 && cost.is_finite() && p.error.rmse.is_finite())
        .then(|| PlotPoint::new(cost.log10(), p.error.rmse))
}

/// A knob's readable name (the inspector's label), or its identifier when it has none.
fn knob_label(name: &str) -> &str {
    thicket_core::quality::KnobSpec::named(name).map_or(name, |s| s.label)
}

/// "about 1 min 10 s left" from the time `elapsed` since progress was first seen, the
/// fraction `done` since then and the fraction `left`; "estimating…" until there is some.
#[must_use]
pub fn remaining_text(elapsed: f64, done: f32, left: f32) -> String {
    if done <= 0.0 || elapsed <= 0.5 {
        return "estimating the time left…".to_owned();
    }
    let secs = (elapsed * f64::from(left) / f64::from(done)).round() as u64;
    match secs {
        0..=59 => format!("about {secs} s left"),
        _ => format!("about {} min {} s left", secs / 60, secs % 60),
    }
}

fn preset_name(p: &SweepPoint) -> Option<&'static str> {
    p.setting.preset.map(|p| match p {
        QualityPreset::Draft => "draft",
        QualityPreset::Balanced => "balanced",
        QualityPreset::Final => "final",
    })
}

#[cfg(test)]
mod tests {
    use super::remaining_text;

    #[test]
    fn the_time_left_follows_the_rate_so_far() {
        // A quarter done in 30 s: three quarters left take 90 s.
        assert_eq!(remaining_text(30.0, 0.25, 0.75), "about 1 min 30 s left");
        assert_eq!(remaining_text(10.0, 0.5, 0.5), "about 10 s left");
        // No progress yet, or too early to tell.
        assert_eq!(remaining_text(10.0, 0.0, 1.0), "estimating the time left…");
        assert_eq!(remaining_text(0.2, 0.1, 0.9), "estimating the time left…");
    }
}
