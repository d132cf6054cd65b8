//! The GPU view: what the view hands the GPU renderer each frame (the document snapshot, the
//! camera, the size, the voxel regions read from the editor's change feed) through the
//! egui-wgpu paint callback of [`super::viewport`], and the depth it reads back.

use std::time::Instant;

use thicket_core::scene::OrbitCamera;

use super::frame_depth::FrameDepth;
use super::viewport::{FrameKey, ViewportCallback, ViewportLink, paint_callback};
use super::{PREVIEW_STILL, PreviewSettings, RenderKey, Snapshot, render_key};
use crate::editor::{Editor, Redo, RegionChain};

/// Samples per pixel side the GPU view draws with the document's `supersample` when what it
/// draws last changed at `moved_at`: one while that is under [`PREVIEW_STILL`] ago (a moving
/// frame, as the CPU preview's), else the document's.
fn gpu_view_supersample(moved_at: Option<Instant>, now: Instant, supersample: u32) -> u32 {
    if moved_at.is_some_and(|t| now.saturating_duration_since(t) < PREVIEW_STILL) {
        1
    } else {
        supersample
    }
}

/// The view's side of the GPU viewport.
#[derive(Default)]
pub struct GpuView {
    link: Option<ViewportLink>,
    /// What the GPU view last saw drawn (camera, content and animation keys) and when it
    /// changed: while that is under [`PREVIEW_STILL`] ago it draws one sample per pixel.
    motion: Option<((OrbitCamera, RenderKey), Option<Instant>)>,
    /// Voxel edits since the GPU may last have uploaded (see [`ViewportCallback::regions`]).
    regions: RegionChain,
    /// The size in pixels the GPU view last asked for (a depth read back at another size is
    /// of an older frame: the view was resized).
    size_px: [u32; 2],
}

impl GpuView {
    /// Connects the GPU viewport.
    pub fn attach(&mut self, link: ViewportLink) {
        self.link = Some(link);
    }

    /// The GPU viewport's shared status, when one is attached.
    #[must_use]
    pub fn link(&self) -> Option<&ViewportLink> {
        self.link.as_ref()
    }

    /// Draws the view in `rect` with the GPU renderer (a paint callback), handing it the voxel
    /// edits since it may last have uploaded.
    pub fn show(
        &mut self,
        ui: &egui::Ui,
        rect: egui::Rect,
        editor: &Editor,
        snapshot: &mut Snapshot,
        settings: &PreviewSettings,
    ) {
        let want_depth = settings.want_depth;
        let Some(link) = self.link.clone() else {
            return;
        };
        let key = editor.content_key();
        // Voxel edits since the last frame extend the chain the renderer may upload from;
        // anything else breaks it. `prepare` may not run every frame, so the chain is kept
        // (bounded) until the document changes in another way.
        let doc = editor.doc();
        self.regions
            .read(editor.changes(), |c| Redo::for_upload(doc, c));
        let regions = self.regions.ending_at(key).to_vec();
        // Supersampling only once the view is still, as the CPU preview: a moving frame draws
        // one sample per pixel, and the still frame follows PREVIEW_STILL later.
        let drawn = (editor.doc().camera, render_key(editor));
        let now = Instant::now();
        let moved_at = match self.motion {
            Some((d, t)) if d == drawn => t,
            Some(_) => Some(now),
            None => None,
        };
        self.motion = Some((drawn, moved_at));
        let supersample = gpu_view_supersample(moved_at, now, editor.doc().quality.supersample);
        if supersample != editor.doc().quality.supersample {
            ui.ctx().request_repaint_after(PREVIEW_STILL);
        }
        let doc = snapshot.of(editor);
        let ppp = ui.ctx().pixels_per_point();
        let size = rect.size() * ppp * settings.render_scale;
        let size_px = [
            (size.x.round() as u32).max(1),
            (size.y.round() as u32).max(1),
        ];
        let key = FrameKey {
            content: key,
            animation: editor.animation_key(),
            camera: editor.doc().camera,
            size_px,
            supersample,
        };
        // The depth is read on the frame after the one that drew it: one more paint when
        // the view stands still (once per frame key; none when the GPU renderer failed).
        let waiting = {
            let status = link.lock();
            status.error.is_none() && status.depth_read.as_ref() != Some(&key)
        };
        if want_depth && waiting {
            ui.ctx().request_repaint_after(PREVIEW_STILL);
        }
        self.size_px = size_px;
        ui.painter().add(paint_callback(
            rect,
            ViewportCallback {
                key,
                doc,
                regions,
                want_depth,
            },
        ));
    }

    /// The depth of the shown frame once read back, when it was drawn from the current camera
    /// at the size last asked for.
    #[must_use]
    pub fn shown_depth(&self, editor: &Editor) -> Option<FrameDepth> {
        let camera = editor.doc().camera;
        self.link
            .as_ref()
            .and_then(|link| link.lock().depth.clone())
            .filter(|d| d.camera == camera && [d.width, d.height] == self.size_px)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gpu_view_draws_one_sample_while_moving_and_the_documents_when_still() {
        let t0 = Instant::now();
        let soon = t0 + PREVIEW_STILL / 2;
        let later = t0 + PREVIEW_STILL;
        // Never moved (just opened), or still for PREVIEW_STILL: the document's samples.
        assert_eq!(gpu_view_supersample(None, t0, 3), 3);
        assert_eq!(gpu_view_supersample(Some(t0), later, 3), 3);
        // Moved this frame or a moment ago: one sample.
        assert_eq!(gpu_view_supersample(Some(t0), t0, 3), 1);
        assert_eq!(gpu_view_supersample(Some(t0), soon, 3), 1);
        assert_eq!(gpu_view_supersample(Some(t0), soon, 1), 1);
    }
}
