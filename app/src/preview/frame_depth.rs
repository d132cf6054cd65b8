//! The depth of a frame the view shows ([`FrameDepth`]): the CPU preview hands it over with
//! each image, the GPU viewport reads it back once the view is still (`viewport`), and the
//! view hides its overlay lines where it lies in front of them (`ui::view`).

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec3;
use thicket_core::render::Camera;
use thicket_core::scene::OrbitCamera;

/// The depth of a frame the view shows and what it was drawn from. The view hides its overlay
/// lines (the ground grid, the world axes, the volume box) where this depth lies in front of
/// them, so every kind of object hides them as it is drawn: voxels, meshes, KRS surfaces and
/// posed rigged models alike (CPU preview and GPU viewport).
#[derive(Clone, PartialEq)]
pub struct FrameDepth {
    /// Tells frames apart (a new number for every frame read).
    pub serial: u64,
    /// The document's content key ([`crate::editor::Editor::content_key`]) drawn.
    pub content: (u64, u64),
    /// Its animation key ([`crate::editor::Editor::animation_key`]).
    pub animation: u64,
    /// The camera drawn with.
    pub camera: OrbitCamera,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// NDC depth per pixel, row by row from the top (0 near, 1 far; 1 or more, or not
    /// finite, where nothing was drawn).
    pub depth: Arc<[f32]>,
    /// `camera` at this size, made once: [`FrameDepth::hides`] runs for every sample of every
    /// overlay line.
    projection: Camera,
}

/// Depth-test tolerance in pixel footprints at the point's depth: a line lying on a surface
/// (the volume box on a model's faces, the ground grid under a model standing on it) shows.
pub const DEPTH_TOLERANCE_PX: f32 = 1.5;

impl std::fmt::Debug for FrameDepth {
    // Without the depth values: a whole frame of them would flood any `{:?}` of the status.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FrameDepth")
            .field("serial", &self.serial)
            .field("content", &self.content)
            .field("animation", &self.animation)
            .field("camera", &self.camera)
            .field("width", &self.width)
            .field("height", &self.height)
            .finish_non_exhaustive()
    }
}

impl FrameDepth {
    /// A frame's depth (`depth.len()` must be `width × height`; anything else hides nothing).
    #[must_use]
    pub fn new(
        content: (u64, u64),
        animation: u64,
        camera: OrbitCamera,
        [width, height]: [u32; 2],
        depth: Arc<[f32]>,
    ) -> Self {
        static SERIAL: AtomicU64 = AtomicU64::new(0);
        Self {
            serial: SERIAL.fetch_add(1, Ordering::Relaxed),
            content,
            animation,
            camera,
            width,
            height,
            depth,
            projection: Camera::from_orbit(&camera, width, height),
        }
    }

    /// Whether something the frame drew lies between its eye and world point `p`, by more
    /// than [`DEPTH_TOLERANCE_PX`] pixel footprints. The farthest of the 3×3 pixels around
    /// `p`'s is compared, so a line along a silhouette or on the surface it lies on shows.
    /// Points outside the frame, behind its eye or not finite are not hidden.
    #[must_use]
    pub fn hides(&self, p: Vec3) -> bool {
        let (w, h) = (self.width as usize, self.height as usize);
        if w == 0 || h == 0 || self.depth.len() != w * h {
            return false;
        }
        let cam = &self.projection;
        let p_view = cam.view_from_world.transform_point3(p);
        let d = -p_view.z;
        if !d.is_finite() || (cam.is_perspective() && d <= cam.near()) {
            return false;
        }
        let s = cam.project_view(p_view);
        // Also false for NaN.
        if !(s.x >= 0.0 && s.y >= 0.0 && s.x < w as f32 && s.y < h as f32) {
            return false;
        }
        let (x, y) = (s.x as usize, s.y as usize);
        let mut farthest = f32::NEG_INFINITY;
        for yy in y.saturating_sub(1)..=(y + 1).min(h - 1) {
            for xx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                let v = self.depth[yy * w + xx];
                farthest = if v.is_finite() {
                    farthest.max(v)
                } else {
                    f32::INFINITY
                };
            }
        }
        // Never NaN: finite, or infinite where a pixel drew nothing.
        if farthest >= 1.0 {
            return false;
        }
        let surface = cam.view_depth(farthest);
        surface < d - (cam.pixel_world_size(d) * DEPTH_TOLERANCE_PX + d * 1e-4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat wall of depth `d` over the whole frame, seen by `camera`.
    fn wall(camera: OrbitCamera, [w, h]: [u32; 2], view_depth: f32) -> FrameDepth {
        let cam = Camera::from_orbit(&camera, w, h);
        let d = cam.ndc_depth(view_depth);
        FrameDepth::new((0, 0), 0, camera, [w, h], vec![d; (w * h) as usize].into())
    }

    /// Points on the view axis in front of, on and behind a wall: only the ones behind are
    /// hidden, in perspective and orthographic views alike; points outside the frame, behind
    /// the eye or not finite, and any point of a frame whose depth has the wrong length, are
    /// not.
    #[test]
    fn only_what_lies_behind_the_drawn_depth_is_hidden() {
        for orthographic in [false, true] {
            let camera = OrbitCamera {
                target: Vec3::ZERO,
                yaw_deg: 0.0,
                pitch_deg: 0.0,
                distance: 10.0,
                orthographic,
                ..OrbitCamera::default()
            };
            let eye = camera.eye();
            let forward = (camera.target - eye).normalize_or_zero();
            let frame = wall(camera, [64, 48], 10.0);
            let at = |t: f32| eye + forward * t;
            assert!(!frame.hides(at(5.0)), "{orthographic}: in front");
            assert!(!frame.hides(at(10.0)), "{orthographic}: on the wall");
            assert!(frame.hides(at(12.0)), "{orthographic}: behind");
            assert!(!frame.hides(at(-3.0)), "{orthographic}: behind the eye");
            assert!(!frame.hides(Vec3::NAN), "{orthographic}: NaN");
            let aside = at(12.0) + camera.view_from_world().inverse().x_axis.truncate() * 1e4;
            assert!(!frame.hides(aside), "{orthographic}: outside the frame");
            let short = FrameDepth {
                depth: vec![0.5; 10].into(),
                ..frame.clone()
            };
            assert!(
                !short.hides(at(12.0)),
                "{orthographic}: a depth of the wrong size"
            );
            // Background (1.0 on the CPU, infinite from the GPU) hides nothing.
            for background in [1.0, f32::INFINITY] {
                let empty = FrameDepth {
                    depth: vec![background; 64 * 48].into(),
                    ..frame.clone()
                };
                assert!(!empty.hides(at(12.0)), "{orthographic}: {background}");
            }
        }
    }
}
