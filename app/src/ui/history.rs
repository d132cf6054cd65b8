//! Edit → History: the undo steps by name, oldest first, the current one marked; a click goes
//! back (or forward) to a step, exactly as that many undos (or redos) would.

use super::EditorApp;

impl EditorApp {
    /// The History window, while open.
    pub(super) fn history_window(&mut self, ctx: &egui::Context) {
        if !self.show_history {
            return;
        }
        let mut open = true;
        let mut go_to = None;
        egui::Window::new("History")
            .open(&mut open)
            .default_width(240.0)
            .show(ctx, |ui| go_to = history_ui(ui, self.editor.history()));
        self.show_history = open;
        if let Some(done) = go_to {
            let steps = self.editor.go_to_step(done);
            if steps > 0 {
                self.status = format!("History: {steps} step(s)");
            }
        }
    }
}

/// The list of steps; returns how many steps the clicked entry has done (0: the start).
fn history_ui(ui: &mut egui::Ui, history: &crate::editor::History) -> Option<usize> {
    let (labels, done) = history.labels();
    let mut go_to = None;
    ui.weak("Click a step to go back or forward to it.");
    egui::ScrollArea::vertical()
        .max_height(420.0)
        .auto_shrink([false, true])
        .show(ui, |ui| {
            let start = ui
                .selectable_label(done == 0, "Start")
                .on_hover_text("The document before the first step listed");
            if start.clicked() {
                go_to = Some(0);
            }
            for (i, label) in labels.iter().enumerate() {
                let text = egui::RichText::new(format!("{}. {label}", i + 1));
                // Steps after the current one are undone: redo brings them back.
                let text = if i < done { text } else { text.weak() };
                let r = ui.selectable_label(i + 1 == done, text);
                if r.clicked() {
                    go_to = Some(i + 1);
                }
            }
        });
    if labels.is_empty() {
        ui.weak("No edits yet.");
    }
    go_to
}
