//! The preview layer: what draws the view's image, behind one interface fed by the editor's
//! document snapshot, its change feed and the view's camera and settings.
//!
//! | module | what |
//! |---|---|
//! | [`gpu`] | the GPU view: the frame key, the voxel regions to upload, the depth read back |
//! | [`viewport`] | the egui-wgpu bridge: the paint callback and the renderer's resources |
//! | [`cpu`] | the CPU preview: scheduler, worker, refinement, kept shadow maps |
//! | [`analysis`] | hole / bloat and stretch overlays of the CPU preview's frame |
//! | [`frame_depth`] | the shown frame's depth, which hides overlay lines behind what it drew |
//!
//! `ui::view` keeps input → editor commands and painting the overlays.

pub mod analysis;
pub mod cpu;
pub mod frame_depth;
pub mod gpu;
pub mod viewport;

use std::hash::{Hash as _, Hasher as _};
use std::sync::Arc;
use std::time::Duration;

use thicket_core::scene::Document;

pub use cpu::{
    CPU_PREVIEW_MIN_SCALE, CPU_PREVIEW_SCALE, CpuPreview, PREVIEW_MOTION_BUDGET_MS, ShadowWork,
    moving_scale,
};
pub use gpu::GpuView;

use crate::editor::Editor;
use frame_depth::FrameDepth;

/// How long what the CPU preview draws must stay the same before it refines to full
/// resolution.
pub const PREVIEW_STILL: Duration = Duration::from_millis(150);

/// What a renderer draws: the document's content key and its animation key.
pub(crate) type RenderKey = ((u64, u64), u64);

/// What the renderers draw of the editor's document: its content and its playheads (the camera
/// is not in it: orbiting draws the same document).
pub(crate) fn render_key(editor: &Editor) -> RenderKey {
    (editor.content_key(), editor.animation_key())
}

/// The content key the CPU preview gives its shadow cache for a render key.
fn preview_content_hash(key: RenderKey) -> u64 {
    let mut h = std::hash::DefaultHasher::new();
    key.hash(&mut h);
    h.finish()
}

/// The document as the renderers see it, for one content and animation key (cloned when
/// either changes).
#[derive(Default)]
pub struct Snapshot {
    kept: Option<(RenderKey, Arc<Document>)>,
}

impl Snapshot {
    /// The editor's document, shared with the renderers.
    pub fn of(&mut self, editor: &Editor) -> Arc<Document> {
        let key = render_key(editor);
        match &self.kept {
            Some((k, doc)) if *k == key => Arc::clone(doc),
            _ => {
                // The renderer reads the document after this frame's UI (in `prepare`, or on
                // the preview's worker): it gets its own copy, made only when the content
                // changed (a dab, an edit, undo, a new playhead time).
                let doc = Arc::new(editor.doc().clone());
                self.kept = Some((key, Arc::clone(&doc)));
                doc
            }
        }
    }
}

/// What the view asks of the preview each frame.
#[derive(Debug, Clone, PartialEq)]
pub struct PreviewSettings {
    /// Fraction of the view's pixels drawn.
    pub render_scale: f32,
    /// The CPU preview's time budget per frame while what it draws keeps changing
    /// ([`moving_scale`]); `None`: always half resolution.
    pub motion_budget_ms: Option<f64>,
    /// The hole / bloat overlay (CPU preview).
    pub holes: bool,
    /// The stretch heat map (CPU preview).
    pub stretch: bool,
    /// The weight heat map of (object, joint) (CPU preview).
    pub weights: Option<(u64, usize)>,
    /// Read the GPU frame's depth back once the view stands still (for overlay lines).
    pub want_depth: bool,
}

/// The view's image: the GPU view or the CPU preview, and the document snapshot both draw.
#[derive(Default)]
pub struct Preview {
    snapshot: Snapshot,
    /// The CPU preview.
    pub cpu: CpuPreview,
    /// The GPU view.
    pub gpu: GpuView,
}

impl Preview {
    /// Draws the view's image in `rect` with the CPU preview (`cpu`) or the GPU; returns
    /// whether the selection's outline was drawn from the image's pixels (CPU only).
    pub fn show(
        &mut self,
        ui: &egui::Ui,
        rect: egui::Rect,
        editor: &Editor,
        cpu: bool,
        settings: &PreviewSettings,
    ) -> bool {
        if cpu {
            self.cpu
                .show(ui, rect, editor, &mut self.snapshot, settings)
        } else {
            self.gpu
                .show(ui, rect, editor, &mut self.snapshot, settings);
            // The CPU preview's buffers are of no use while the GPU draws.
            self.cpu.release_buffers();
            false
        }
    }

    /// The depth of the frame shown, when it shows the editor's scene (content and pose):
    /// the CPU preview's image (drawn from its own camera, which lags an orbit by the time a
    /// preview render takes, as the image itself does), or the GPU viewport's once read back
    /// for the current camera and view size. `None` while the frame shows an older scene (a
    /// stroke in progress); the overlays then test voxels by rays.
    #[must_use]
    pub fn shown_depth(&self, editor: &Editor, cpu: bool) -> Option<FrameDepth> {
        let frame = if cpu {
            self.cpu.shown_depth()
        } else {
            self.gpu.shown_depth(editor)
        };
        frame.filter(|d| d.content == editor.content_key() && d.animation == editor.animation_key())
    }

    /// The document the shown image was drawn from, for overlays that follow the pose (the
    /// skeleton): the CPU preview's, which lags playback; `None` with the GPU viewport (it
    /// draws the current document in the same frame).
    #[must_use]
    pub fn shown_pose_document(&self, cpu: bool) -> Option<Arc<Document>> {
        if cpu { self.cpu.shown_document() } else { None }
    }
}
