//! The path entry used where no desktop file dialog can open (no xdg portal, no zenity), or when
//! "Native file dialogs" is off: a text field that takes a typed path (Enter accepts, Esc
//! cancels) above a browse list of the field's folder (sub-folders first, then the files this
//! prompt can use) and, for Open and Import, the recent files.
//!
//! The folder is read again only when the field's folder changes, not every frame.

use std::path::{Path, PathBuf};

use egui::Key;

use crate::files;

/// What a path prompt is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PathPurpose {
    Open,
    Import,
    SaveAs,
    ExportVox,
    ExportGltf,
    LoadPalette,
    SavePalette,
}

impl PathPurpose {
    /// The window title (also the native dialog's).
    #[must_use]
    pub fn title(self) -> &'static str {
        match self {
            Self::Open => "Open",
            Self::Import => "Import",
            Self::SaveAs => "Save as",
            Self::ExportVox => "Export MagicaVoxel (.vox)",
            Self::ExportGltf => "Export glTF (.glb or .gltf)",
            Self::LoadPalette => "Load palette (.gpl, .png, .vox)",
            Self::SavePalette => "Save palette (.gpl or .png)",
        }
    }

    /// Whether the prompt names a file to write (the typed file name is kept while browsing).
    #[must_use]
    pub fn writes(self) -> bool {
        matches!(
            self,
            Self::SaveAs | Self::ExportVox | Self::ExportGltf | Self::SavePalette
        )
    }

    /// The file name endings the browse list shows (lower case, without the dot).
    #[must_use]
    pub fn extensions(self) -> Vec<&'static str> {
        match self {
            Self::Open | Self::Import => files::readable_extensions()
                .into_iter()
                .flat_map(|(_, e)| e.iter().copied())
                .collect(),
            Self::SaveAs => vec!["thicket.json"],
            Self::ExportVox => vec!["vox"],
            Self::ExportGltf => vec!["glb", "gltf"],
            Self::LoadPalette => vec!["gpl", "png", "vox"],
            Self::SavePalette => vec!["gpl", "png"],
        }
    }

    fn field_label(self) -> String {
        match self {
            Self::SaveAs => "Project file (.thicket.json):".to_owned(),
            Self::ExportVox => "MagicaVoxel file (.vox):".to_owned(),
            Self::ExportGltf => "glTF file (.glb or .gltf):".to_owned(),
            Self::LoadPalette => "Palette (.gpl, .png or .vox):".to_owned(),
            Self::SavePalette => "Palette (.gpl or .png):".to_owned(),
            Self::Open | Self::Import => format!("File ({}):", readable_list()),
        }
    }
}

/// The readable kinds as one line ("Thicket project: .json; MagicaVoxel: .vox; ...").
#[must_use]
pub fn readable_list() -> String {
    files::readable_extensions()
        .iter()
        .map(|(label, exts)| format!("{label}: .{}", exts.join(", .")))
        .collect::<Vec<_>>()
        .join("; ")
}

/// One row of the browse list.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Entry {
    /// The file or folder name.
    pub name: String,
    /// Its path (the listed folder joined with the name).
    pub path: PathBuf,
    /// A folder (the list descends into it) rather than a file.
    pub is_dir: bool,
    /// The file's size in bytes (0 for folders).
    pub size_bytes: u64,
}

/// The folders and the files ending in one of `extensions` (case-insensitive) in `dir`:
/// folders first, each group sorted by name ignoring case; hidden entries (a leading dot) are
/// left out. Symbolic links are followed to tell folders from files.
///
/// # Errors
/// When `dir` cannot be read (missing, not a folder, no permission).
pub fn list_folder(dir: &Path, extensions: &[&str]) -> std::io::Result<Vec<Entry>> {
    let mut out = Vec::new();
    for item in std::fs::read_dir(dir)? {
        let Ok(item) = item else { continue };
        let name = item.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') {
            continue;
        }
        let path = item.path();
        // `metadata` follows links; an unreadable or dangling entry is left out.
        let Ok(meta) = std::fs::metadata(&path) else {
            continue;
        };
        let is_dir = meta.is_dir();
        let lower = name.to_lowercase();
        if !is_dir && !extensions.iter().any(|e| lower.ends_with(&format!(".{e}"))) {
            continue;
        }
        out.push(Entry {
            name,
            path,
            is_dir,
            size_bytes: if is_dir { 0 } else { meta.len() },
        });
    }
    out.sort_by(|a, b| {
        b.is_dir
            .cmp(&a.is_dir)
            .then_with(|| a.name.to_lowercase().cmp(&b.name.to_lowercase()))
    });
    Ok(out)
}

/// The folder a typed path points into: the text itself when it ends with a separator or names
/// a folder, else its parent; an empty parent (a bare file name) is the current folder, which is
/// where a relative path is resolved when accepted.
#[must_use]
pub fn folder_of(text: &str) -> PathBuf {
    let text = text.trim();
    let path = Path::new(text);
    if text.is_empty() {
        return PathBuf::from(".");
    }
    if text.ends_with(std::path::MAIN_SEPARATOR) || text.ends_with('/') || path.is_dir() {
        return path.to_path_buf();
    }
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// The path the typed text names. A path typed or pasted after the pre-filled folder starts
/// again at its own root (`/home/me/projects/` + `/tmp/x.vox` is `/tmp/x.vox`): the last
/// absolute path in the text wins. An empty folder name never means anything else (`a//b` is
/// `a/b` to the system), so a doubled separator is read as the start of a new path.
#[must_use]
pub fn typed_path(text: &str) -> &str {
    let text = text.trim();
    text.rfind("//").map_or(text, |i| &text[i + 1..])
}

/// The characters selected when a prompt opens, so that typing replaces the pre-filled text: all
/// of it for a file to read (a folder, where a typed or pasted path goes), the file name without
/// its extension for a file to write (the folder and the kind of file are kept).
#[must_use]
pub fn initial_selection(purpose: PathPurpose, text: &str) -> std::ops::Range<usize> {
    let chars = |s: &str| s.chars().count();
    if !purpose.writes() {
        return 0..chars(text);
    }
    let name_at = text.rfind('/').map_or(0, |i| i + 1);
    let name = &text[name_at..];
    let stem_len = name
        .strip_suffix(".thicket.json")
        .or_else(|| name.rfind('.').filter(|&i| i > 0).map(|i| &name[..i]))
        .unwrap_or(name)
        .len();
    let start = chars(&text[..name_at]);
    start..start + chars(&name[..stem_len])
}

/// The text after choosing folder `dir` in the list: the folder with a trailing separator, and
/// for prompts that write a file the typed file name kept (`dir/name`).
#[must_use]
pub fn text_in_folder(purpose: PathPurpose, text: &str, dir: &Path) -> String {
    let text = typed_path(text);
    let typed_name = (!text.ends_with('/') && !Path::new(text).is_dir())
        .then(|| Path::new(text).file_name())
        .flatten();
    match typed_name {
        Some(name) if purpose.writes() => dir.join(name).display().to_string(),
        _ => {
            let mut s = dir.display().to_string();
            if !s.ends_with('/') {
                s.push('/');
            }
            s
        }
    }
}

/// The folder's entries as last read, and for which folder.
#[derive(Debug, Clone)]
struct Listing {
    dir: PathBuf,
    entries: Result<Vec<Entry>, String>,
}

/// An open path prompt.
#[derive(Debug, Clone)]
pub struct PathPrompt {
    /// What the chosen path is for.
    pub purpose: PathPurpose,
    /// The typed path.
    pub text: String,
    listing: Option<Listing>,
    /// The pre-filled text is still to be selected (once the field has the keyboard).
    select_prefill: bool,
}

/// What the prompt's frame decided.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PromptOutcome {
    /// Still open.
    Open,
    /// OK, Enter or a double-click on a file: this path.
    Accept(PathBuf),
    /// Cancel or Esc.
    Cancel,
}

/// Height of the browse list in points (about 10 rows).
const BROWSE_HEIGHT: f32 = 200.0;

/// Most rows shown in the recent-files part.
const RECENT_ROWS: usize = 6;

impl PathPrompt {
    /// A prompt for `purpose` starting with `text` in the field.
    #[must_use]
    pub fn new(purpose: PathPurpose, text: String) -> Self {
        Self {
            purpose,
            text,
            listing: None,
            select_prefill: true,
        }
    }

    /// The folder the list shows, read again when the field's folder changed.
    fn refresh(&mut self) -> &Listing {
        let dir = folder_of(typed_path(&self.text));
        if let Some(current) = self.listing.take_if(|l| l.dir == dir) {
            return self.listing.insert(current);
        }
        let entries = list_folder(&dir, &self.purpose.extensions())
            .map_err(|e| format!("{}: {e}", dir.display()));
        self.listing.insert(Listing { dir, entries })
    }

    /// Draws the prompt as a modal; `recent` are the recent files (shown for Open and Import).
    pub fn ui(&mut self, ctx: &egui::Context, recent: &[PathBuf]) -> PromptOutcome {
        let mut outcome = PromptOutcome::Open;
        egui::Modal::new(egui::Id::unique("path_prompt")).show(ctx, |ui| {
            ui.set_max_width(560.0);
            ui.heading(self.purpose.title());
            ui.label(self.purpose.field_label());
            let edit = ui.add(
                egui::TextEdit::singleline(&mut self.text)
                    .desired_width(540.0)
                    .hint_text("path/to/file"),
            );
            // Enter ends a single-line edit by giving up its focus this frame: read it
            // before focusing the field again (focusing first hid every Enter).
            let enter = edit.lost_focus() && ui.input(|i| i.key_pressed(Key::Enter));
            if !enter && ui.memory(|m| m.focused().is_none()) {
                edit.request_focus();
            }
            // An unfocused field keeps only a cursor, not a selection: select once it is focused.
            if self.select_prefill && edit.has_focus() {
                self.select_prefill = false;
                let range = initial_selection(self.purpose, &self.text);
                let mut state =
                    egui::text_edit::TextEditState::load(ui.ctx(), edit.id).unwrap_or_default();
                state
                    .cursor
                    .set_char_range(Some(egui::text::CCursorRange::two(
                        egui::text::CCursor::new(range.start),
                        egui::text::CCursor::new(range.end),
                    )));
                state.store(ui.ctx(), edit.id);
            }
            if let Some(o) = self.browse_ui(ui) {
                outcome = o;
            }
            if matches!(self.purpose, PathPurpose::Open | PathPurpose::Import)
                && let Some(o) = self.recent_ui(ui, recent)
            {
                outcome = o;
            }
            ui.separator();
            ui.horizontal(|ui| {
                let path = typed_path(&self.text);
                if (ui.button("OK").clicked() || enter) && !path.is_empty() {
                    outcome = PromptOutcome::Accept(PathBuf::from(path));
                }
                if ui.button("Cancel").clicked() || ui.input(|i| i.key_pressed(Key::Escape)) {
                    outcome = PromptOutcome::Cancel;
                }
            });
        });
        outcome
    }

    /// The folder's list: ".." and sub-folders descend, a file click fills the field, a
    /// double-click accepts it.
    fn browse_ui(&mut self, ui: &mut egui::Ui) -> Option<PromptOutcome> {
        let purpose = self.purpose;
        let listing = self.refresh().clone();
        let shown = std::path::absolute(&listing.dir).unwrap_or_else(|_| listing.dir.clone());
        ui.horizontal(|ui| {
            ui.weak("In");
            ui.monospace(shown.display().to_string())
                .on_hover_text("The folder of the typed path; a relative path is resolved from the folder Thicket was started in");
        });
        let mut choice: Option<(PathBuf, bool, bool)> = None;
        egui::Frame::group(ui.style()).show(ui, |ui| {
            // One height for every folder: the modal keeps its size and place while browsing,
            // so OK and the rows do not move under the pointer.
            egui::ScrollArea::vertical()
                .id_salt("path_browse")
                .min_scrolled_height(BROWSE_HEIGHT)
                .max_height(BROWSE_HEIGHT)
                .auto_shrink([false, false])
                .show(ui, |ui| {
                    // Rows as wide as the list: a click anywhere on a row picks it.
                    ui.with_layout(egui::Layout::top_down_justified(egui::Align::LEFT), |ui| {
                        if let Some(parent) = shown.parent()
                            && ui
                                .selectable_label(false, "../")
                                .on_hover_text("The folder above")
                                .clicked()
                        {
                            choice = Some((parent.to_path_buf(), true, false));
                        }
                        match &listing.entries {
                            Err(e) => {
                                ui.colored_label(ui.visuals().error_fg_color, e);
                            }
                            Ok(entries) if entries.is_empty() => {
                                ui.weak(format!(
                                    "No folders or .{} files here",
                                    purpose.extensions().join(", .")
                                ));
                            }
                            Ok(entries) => {
                                for e in entries {
                                    let label = if e.is_dir {
                                        format!("{}/", e.name)
                                    } else {
                                        format!("{}   {}", e.name, files::human_bytes(e.size_bytes))
                                    };
                                    let r = ui.selectable_label(false, label);
                                    if r.double_clicked() {
                                        choice = Some((e.path.clone(), e.is_dir, true));
                                    } else if r.clicked() {
                                        choice = Some((e.path.clone(), e.is_dir, false));
                                    }
                                }
                            }
                        }
                    });
                });
        });
        let (path, is_dir, double) = choice?;
        if is_dir {
            self.text = text_in_folder(purpose, &self.text, &path);
            None
        } else {
            self.text = path.display().to_string();
            double.then_some(PromptOutcome::Accept(path))
        }
    }

    /// The recent files that still exist: a click fills the field, a double-click accepts.
    fn recent_ui(&mut self, ui: &mut egui::Ui, recent: &[PathBuf]) -> Option<PromptOutcome> {
        let existing: Vec<&PathBuf> = recent
            .iter()
            .filter(|p| p.is_file())
            .take(RECENT_ROWS)
            .collect();
        if existing.is_empty() {
            return None;
        }
        ui.weak("Recent");
        let mut outcome = None;
        let layout = egui::Layout::top_down_justified(egui::Align::LEFT);
        ui.with_layout(layout, |ui| {
            for p in existing {
                let r = ui
                    .selectable_label(false, p.display().to_string())
                    .on_hover_text("Click: put in the field; double-click: open");
                if r.double_clicked() {
                    outcome = Some(PromptOutcome::Accept(p.clone()));
                } else if r.clicked() {
                    self.text = p.display().to_string();
                }
            }
        });
        outcome
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_list_shows_folders_first_then_matching_files_by_name() {
        let dir = tempfile::tempdir().unwrap();
        for f in ["b.vox", "A.VOX", "notes.txt", ".hidden.vox", "c.glb"] {
            std::fs::write(dir.path().join(f), b"1234").unwrap();
        }
        std::fs::create_dir(dir.path().join("zeta")).unwrap();
        std::fs::create_dir(dir.path().join("Alpha")).unwrap();
        let names: Vec<String> = list_folder(dir.path(), &["vox"])
            .unwrap()
            .into_iter()
            .map(|e| e.name)
            .collect();
        assert_eq!(names, ["Alpha", "zeta", "A.VOX", "b.vox"]);
        let files = list_folder(dir.path(), &["glb", "gltf"]).unwrap();
        assert_eq!(
            files.last().map(|e| (e.name.as_str(), e.size_bytes)),
            Some(("c.glb", 4))
        );
        assert!(list_folder(&dir.path().join("missing"), &["vox"]).is_err());
    }

    #[test]
    fn a_project_list_matches_the_double_extension() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("house.thicket.json"), b"{}").unwrap();
        std::fs::write(dir.path().join("package.json"), b"{}").unwrap();
        let names: Vec<String> = list_folder(dir.path(), &PathPurpose::SaveAs.extensions())
            .unwrap()
            .into_iter()
            .map(|e| e.name)
            .collect();
        assert_eq!(names, ["house.thicket.json"]);
    }

    #[test]
    fn the_folder_of_a_typed_path() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path().display().to_string();
        assert_eq!(folder_of(""), PathBuf::from("."));
        assert_eq!(folder_of("export.glb"), PathBuf::from("."));
        assert_eq!(folder_of(&d), dir.path());
        assert_eq!(folder_of(&format!("{d}/")), PathBuf::from(format!("{d}/")));
        assert_eq!(folder_of(&format!("{d}/new.vox")), dir.path());
    }

    #[test]
    fn a_path_typed_after_the_prefilled_folder_replaces_it() {
        assert_eq!(
            typed_path(" /home/me/projects/x.vox "),
            "/home/me/projects/x.vox"
        );
        assert_eq!(typed_path("/home/me/projects//tmp/x.vox"), "/tmp/x.vox");
        assert_eq!(typed_path("/home/me/projects//a//tmp/x.vox"), "/tmp/x.vox");
        assert_eq!(typed_path("projects/x.vox"), "projects/x.vox");
        assert_eq!(
            folder_of(typed_path("/home/me/projects//tmp/")),
            Path::new("/tmp/")
        );
        assert_eq!(
            text_in_folder(
                PathPurpose::ExportVox,
                "/home/me//tmp/a.vox",
                Path::new("/b")
            ),
            "/b/a.vox"
        );
    }

    #[test]
    fn the_prefilled_selection_is_the_folder_to_read_or_the_name_to_write() {
        assert_eq!(initial_selection(PathPurpose::Open, "/home/mé/"), 0..9);
        assert_eq!(initial_selection(PathPurpose::Open, ""), 0..0);
        let save = "/home/mé/house.thicket.json";
        assert_eq!(initial_selection(PathPurpose::SaveAs, save), 9..14);
        assert_eq!(initial_selection(PathPurpose::ExportVox, "house.vox"), 0..5);
        assert_eq!(initial_selection(PathPurpose::ExportGltf, "/a/.glb"), 3..7);
    }

    #[test]
    fn choosing_a_folder_keeps_the_file_name_of_a_save() {
        let sub = Path::new("/some/where");
        assert_eq!(
            text_in_folder(PathPurpose::ExportGltf, "out/tree.glb", sub),
            "/some/where/tree.glb"
        );
        assert_eq!(
            text_in_folder(PathPurpose::Open, "out/tree.glb", sub),
            "/some/where/"
        );
        assert_eq!(text_in_folder(PathPurpose::SaveAs, "", sub), "/some/where/");
    }
}
