//! The view's overlay lines (the ground grid, the world axes, the voxel tools' volume box) and
//! where they are hidden: behind the depth of the frame shown ([`FrameDepth::hides`]) or, while
//! no frame matches the scene, behind voxels found by rays ([`behind_voxels`]). Each line is
//! sampled and split where it goes behind something ([`unhidden_parts_by`]); the split is
//! cached per camera, view, scene and frame (`OverlayDepth`).

use std::collections::HashMap;

use glam::Vec3;
use thicket_core::scene::{Object, ObjectKind, OrbitCamera};

use super::projector::Projector;
use crate::editor::Editor;
use crate::preview::frame_depth::FrameDepth;

/// What decides where overlay lines are hidden: content and animation keys, camera, view
/// rectangle and the shown frame's [`FrameDepth::serial`].
type OverlayKey = ((u64, u64), u64, OrbitCamera, egui::Rect, Option<u64>);

/// Overlay lines split into their parts in front of what is drawn, for one camera, view
/// rectangle, scene (content and pose) and shown frame: a still view tests nothing again.
#[derive(Debug, Default)]
pub(super) struct OverlayDepth {
    key: Option<OverlayKey>,
    parts: HashMap<[u32; 6], Vec<(Vec3, Vec3)>>,
}

impl OverlayDepth {
    /// The parts of segment `a`–`b` not hidden behind the shown `frame`'s depth
    /// ([`FrameDepth::hides`]) or, without one, behind voxels ([`unhidden_parts`]), cached.
    pub(super) fn parts(
        &mut self,
        proj: &Projector,
        editor: &Editor,
        frame: Option<&FrameDepth>,
        a: Vec3,
        b: Vec3,
    ) -> &[(Vec3, Vec3)] {
        let key = (
            editor.content_key(),
            editor.animation_key(),
            proj.camera,
            proj.rect,
            frame.map(|f| f.serial),
        );
        if self.key != Some(key) {
            self.key = Some(key);
            self.parts.clear();
        }
        let bits = [a.x, a.y, a.z, b.x, b.y, b.z].map(f32::to_bits);
        self.parts.entry(bits).or_insert_with(|| match frame {
            Some(f) => unhidden_parts_by(proj, |p| f.hides(p), a, b),
            None => unhidden_parts(proj, editor, a, b),
        })
    }
}

/// Whether a voxel of a visible voxel model lies between the viewer and world point `p`: an
/// overlay line there is hidden. A point on a voxel's surface is not hidden by it. The
/// overlays use this only while no shown frame's depth matches the scene
/// ([`super::view::View::shown_depth`]). Rigged models hide nothing here: a ray through a
/// posed model costs milliseconds (the pose is worked out for every ray), too slow for the
/// hundreds of rays a moving view casts each frame.
#[must_use]
pub fn behind_voxels(proj: &Projector, editor: &Editor, p: Vec3) -> bool {
    let camera = &proj.camera;
    let eye = camera.eye();
    let (origin, dist) = if camera.orthographic {
        // Parallel rays from the eye's plane.
        let forward = (camera.target - eye).normalize_or_zero();
        let depth = (p - eye).dot(forward);
        (p - forward * depth, depth)
    } else {
        (eye, eye.distance(p))
    };
    let ahead = dist > 0.0; // false for NaN as well
    if !ahead || !dist.is_finite() {
        return false;
    }
    let unrigged = |o: &Object| match &o.kind {
        ObjectKind::Voxels(v) => v.rig.is_none() && editor.voxel_pickable(o),
        ObjectKind::Mesh(_) | ObjectKind::Krs(_) => false,
    };
    editor
        .pick_voxel_where(origin, (p - origin) / dist, unrigged)
        .is_some_and(|hit| hit.t < dist - (dist * 1e-4 + hit.voxel_size_world * 0.01))
}

/// View points between the samples of an overlay line (finer where visibility changes).
const OVERLAY_SAMPLE_POINTS: f32 = 12.0;

/// The parts of world segment `a`–`b` not hidden behind voxels ([`behind_voxels`]): see
/// [`unhidden_parts_by`]. The overlays use this while no frame's depth matches the scene.
#[must_use]
pub fn unhidden_parts(proj: &Projector, editor: &Editor, a: Vec3, b: Vec3) -> Vec<(Vec3, Vec3)> {
    unhidden_parts_by(proj, |p| behind_voxels(proj, editor, p), a, b)
}

/// The parts of world segment `a`–`b` where `hidden` is false, in order: sampled every
/// `OVERLAY_SAMPLE_POINTS` view points, and where two samples disagree the edge is found by
/// bisection to about a view point. Empty when the segment is all behind the camera or all
/// hidden.
#[must_use]
pub fn unhidden_parts_by(
    proj: &Projector,
    hidden: impl Fn(Vec3) -> bool,
    a: Vec3,
    b: Vec3,
) -> Vec<(Vec3, Vec3)> {
    let Some([sa, sb]) = proj.segment(a, b) else {
        return Vec::new();
    };
    let length = sa.distance(sb);
    let n = (length / OVERLAY_SAMPLE_POINTS).ceil().clamp(1.0, 256.0) as u32;
    let bisections = (length / n as f32).max(1.0).log2().ceil() as u32;
    let point = |s: f32| a + (b - a) * s;
    // Points outside the view are not drawn: no ray for them.
    let shown = |s: f32| {
        let p = point(s);
        proj.to_screen(p).is_none_or(|q| !proj.rect.contains(q)) || !hidden(p)
    };
    let mut parts = Vec::new();
    let (mut prev_s, mut prev_shown) = (0.0, shown(0.0));
    let mut start = prev_shown.then_some(0.0);
    for i in 1..=n {
        let s = i as f32 / n as f32;
        let now = shown(s);
        if now != prev_shown {
            let (mut lo, mut hi) = (prev_s, s);
            for _ in 0..bisections {
                let mid = 0.5 * (lo + hi);
                if shown(mid) == prev_shown {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let edge = 0.5 * (lo + hi);
            match start.take() {
                Some(s0) => parts.push((point(s0), point(edge))),
                None => start = Some(edge),
            }
        }
        (prev_s, prev_shown) = (s, now);
    }
    if let Some(s0) = start {
        parts.push((point(s0), b));
    }
    parts
}

/// A ground grid on y = 0 around the camera target, spaced by a power of ten that suits the
/// viewing distance, and the world axes.
pub(super) fn grid(camera: &OrbitCamera, line: &impl Fn(Vec3, Vec3, egui::Stroke)) {
    let spacing = 10f32.powf((camera.distance * 0.2).max(1e-6).log10().floor());
    let n = 10i32;
    let cx = (camera.target.x / spacing).round() * spacing;
    let cz = (camera.target.z / spacing).round() * spacing;
    let stroke = egui::Stroke::new(1.0, egui::Color32::from_white_alpha(28));
    let half = n as f32 * spacing;
    for i in -n..=n {
        let o = i as f32 * spacing;
        line(
            Vec3::new(cx + o, 0.0, cz - half),
            Vec3::new(cx + o, 0.0, cz + half),
            stroke,
        );
        line(
            Vec3::new(cx - half, 0.0, cz + o),
            Vec3::new(cx + half, 0.0, cz + o),
            stroke,
        );
    }
    let axis_len = spacing * 2.0;
    for (dir, color) in [
        (Vec3::X, egui::Color32::from_rgb(220, 70, 70)),
        (Vec3::Y, egui::Color32::from_rgb(70, 200, 70)),
        (Vec3::Z, egui::Color32::from_rgb(70, 120, 230)),
    ] {
        line(Vec3::ZERO, dir * axis_len, egui::Stroke::new(2.0, color));
    }
}
