//! [`Projector`]: world points to view points, for everything the view paints over the image
//! (overlays, gizmos, the voxel tools' previews), and the named [`AxisView`]s. One module that
//! every UI file imports, so no two UI files import each other for them.

use glam::{Mat4, Vec3};
use thicket_core::scene::OrbitCamera;

/// Maps world points to view points for the overlays.
#[derive(Debug, Clone, Copy)]
pub struct Projector {
    /// The camera's `clip_from_world` for the view's aspect ratio.
    pub clip_from_world: Mat4,
    /// The view rectangle.
    pub rect: egui::Rect,
    /// The camera.
    pub camera: OrbitCamera,
}

impl Projector {
    /// The projector of `camera` into `rect`.
    #[must_use]
    pub fn new(camera: OrbitCamera, rect: egui::Rect) -> Self {
        Self {
            clip_from_world: camera.clip_from_world(rect.aspect_ratio().max(1e-3)),
            rect,
            camera,
        }
    }

    /// The view point of a world point, `None` behind the camera.
    #[must_use]
    pub fn to_screen(&self, p: Vec3) -> Option<egui::Pos2> {
        let clip = self.clip_from_world * p.extend(1.0);
        // A parallel view has no behind: every point projects (clip w is 1).
        if !self.camera.orthographic && clip.w <= self.camera.near * 0.5 {
            return None;
        }
        let ndc = clip.truncate() / clip.w;
        let pos = egui::pos2(
            self.rect.left() + (ndc.x * 0.5 + 0.5) * self.rect.width(),
            self.rect.top() + (0.5 - ndc.y * 0.5) * self.rect.height(),
        );
        (pos.x.is_finite() && pos.y.is_finite()).then_some(pos)
    }

    /// The visible part of a world segment in view points: clipped at the near plane (a
    /// perspective segment reaching behind the eye keeps the part in front instead of
    /// vanishing), `None` when all of it is behind.
    #[must_use]
    pub fn segment(&self, a: Vec3, b: Vec3) -> Option<[egui::Pos2; 2]> {
        if self.camera.orthographic {
            return Some([self.to_screen(a)?, self.to_screen(b)?]);
        }
        let (ca, cb) = (
            self.clip_from_world * a.extend(1.0),
            self.clip_from_world * b.extend(1.0),
        );
        let w_min = self.camera.near * 0.5;
        let (ta, tb) = (ca.w - w_min, cb.w - w_min);
        if ta <= 0.0 && tb <= 0.0 {
            return None;
        }
        // Move the end behind the plane onto it (w is linear along the segment).
        let cut = |behind: Vec3, front: Vec3, t_behind: f32, t_front: f32| {
            behind + (front - behind) * (t_behind / (t_behind - t_front)) * 1.0001
        };
        let (a, b) = if ta <= 0.0 {
            (cut(a, b, ta, tb), b)
        } else if tb <= 0.0 {
            (a, cut(b, a, tb, ta))
        } else {
            (a, b)
        };
        Some([self.to_screen(a)?, self.to_screen(b)?])
    }

    /// World units per view point at the depth of `p` (to keep handles a constant size).
    #[must_use]
    pub fn world_per_point(&self, p: Vec3) -> f32 {
        if self.camera.orthographic {
            return 2.0 * self.camera.ortho_half_height() / self.rect.height().max(1.0);
        }
        let eye = self.camera.eye();
        let forward = (self.camera.target - eye).normalize_or_zero();
        let depth = (p - eye).dot(forward).max(self.camera.near);
        2.0 * depth * (self.camera.fov_y_deg.to_radians() * 0.5).tan() / self.rect.height().max(1.0)
    }

    /// The camera position.
    #[must_use]
    pub fn eye(&self) -> Vec3 {
        self.camera.eye()
    }

    /// Unit direction from a world point towards the viewer (the view axis in an
    /// orthographic view): which side of a face or handle the camera sees.
    #[must_use]
    pub fn toward_eye(&self, p: Vec3) -> Vec3 {
        self.camera.toward_eye(p)
    }
}

/// A named axis view.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AxisView {
    /// Looking along -Z (from +Z).
    Front,
    /// Looking along +Z.
    Back,
    /// Looking along -X (from +X).
    Right,
    /// Looking along +X.
    Left,
    /// Looking down.
    Top,
    /// Looking up.
    Bottom,
}

impl AxisView {
    /// All views with their menu labels (their keys are in `ui::keys`' binding table).
    pub const ALL: [(AxisView, &'static str); 6] = [
        (AxisView::Front, "Front"),
        (AxisView::Back, "Back"),
        (AxisView::Right, "Right"),
        (AxisView::Left, "Left"),
        (AxisView::Top, "Top"),
        (AxisView::Bottom, "Bottom"),
    ];

    /// (yaw, pitch) in degrees.
    #[must_use]
    pub fn angles(self) -> (f32, f32) {
        match self {
            AxisView::Front => (0.0, 0.0),
            AxisView::Back => (180.0, 0.0),
            AxisView::Right => (90.0, 0.0),
            AxisView::Left => (270.0, 0.0),
            AxisView::Top => (0.0, 90.0),
            AxisView::Bottom => (0.0, -90.0),
        }
    }
}
