//! Analysis overlays over the CPU preview's frame: the hole / bloat overlay of rigged models
//! against their skinned reference meshes (computed by `thicket_core::measure::skin`) and the
//! stretch heat map, with their legends, and the weight heat map of a joint.

use std::collections::HashMap;

use thicket_core::measure::skin::{Silhouette, node_stretch_factors, posed_silhouettes};
use thicket_core::render::{Camera, PixelId, View};
use thicket_core::scene::{Document, ObjectKind};

/// Stretch factors of the rigged-model pixels of the shown CPU preview (the heat map's).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StretchStats {
    /// Pixels of rigged models.
    pub pixels: u64,
    /// Smallest factor seen.
    pub min: f32,
    /// Mean factor over the pixels.
    pub mean: f32,
    /// Largest factor seen.
    pub max: f32,
}

/// Factor at the blue end of the heat map's scale.
pub const STRETCH_SCALE_MIN: f32 = 0.5;

/// Factor at the red end of the heat map's scale.
pub const STRETCH_SCALE_MAX: f32 = 2.5;

/// Hole overlay colours, chosen against the selection outline's orange and against models'
/// own colours (skin tones, blue textures): magenta where the skinned mesh shows and no voxel
/// does, yellow where voxels cover more.
const HOLE_COLOR: egui::Color32 = egui::Color32::from_rgb(255, 0, 255);
const BLOAT_COLOR: egui::Color32 = egui::Color32::from_rgb(255, 230, 0);

/// The hole / bloat overlay of a preview frame drawn for `req`: magenta where the skinned
/// reference meshes of the visible rigged models cover and their voxels do not, yellow where
/// the voxels cover more ([`posed_silhouettes`]), and the counts.
pub fn hole_overlay(doc: &Document, req: &View) -> Option<(egui::ColorImage, Silhouette)> {
    let cam = Camera::from_orbit(&req.orbit_camera(doc), req.width, req.height);
    let (mesh, voxels) = posed_silhouettes(doc, &cam, &req.quality)?;
    let size = [req.width as usize, req.height as usize];
    let mut image = egui::ColorImage::filled(size, egui::Color32::TRANSPARENT);
    let bloat = egui::Color32::from_rgba_unmultiplied(
        BLOAT_COLOR.r(),
        BLOAT_COLOR.g(),
        BLOAT_COLOR.b(),
        170,
    );
    for ((px, &m), &v) in image.pixels.iter_mut().zip(&mesh).zip(&voxels) {
        if m && !v {
            *px = HOLE_COLOR;
        } else if v && !m {
            *px = bloat;
        }
    }
    Some((image, Silhouette::from_coverage(&mesh, &voxels)))
}

/// The stretch heat map of a preview frame: each pixel of a visible rigged model coloured by
/// its node's stretch factor ([`node_stretch_factors`]); other pixels transparent.
pub fn stretch_overlay(
    doc: &Document,
    req: &View,
    ids: &[PixelId],
    size: [usize; 2],
) -> Option<(egui::ColorImage, StretchStats)> {
    let mut wanted: HashMap<u32, std::collections::HashSet<u64>> = HashMap::new();
    for id in ids {
        let Some(o) = (id.object as usize)
            .checked_sub(1)
            .and_then(|i| doc.objects.get(i))
        else {
            continue;
        };
        if let ObjectKind::Voxels(v) = &o.kind
            && v.rig.is_some()
        {
            wanted.entry(id.object).or_default().insert(id.node);
        }
    }
    if wanted.is_empty() {
        return None;
    }
    let factors: HashMap<u32, HashMap<u64, f32>> = wanted
        .iter()
        .filter_map(|(&label, nodes)| {
            let o = &doc.objects[label as usize - 1];
            let ObjectKind::Voxels(v) = &o.kind else {
                return None;
            };
            Some((label, node_stretch_factors(o, v, &req.quality, nodes)))
        })
        .collect();
    let mut image = egui::ColorImage::filled(size, egui::Color32::TRANSPARENT);
    let mut stats = StretchStats {
        min: f32::INFINITY,
        max: f32::NEG_INFINITY,
        ..StretchStats::default()
    };
    let mut sum = 0.0f64;
    for (px, id) in image.pixels.iter_mut().zip(ids) {
        let Some(f) = factors.get(&id.object).and_then(|m| m.get(&id.node)) else {
            continue;
        };
        let c = stretch_color(*f);
        *px = egui::Color32::from_rgba_unmultiplied(c.r(), c.g(), c.b(), 200);
        stats.pixels += 1;
        stats.min = stats.min.min(*f);
        stats.max = stats.max.max(*f);
        sum += f64::from(*f);
    }
    if stats.pixels == 0 {
        return None;
    }
    stats.mean = (sum / stats.pixels as f64) as f32;
    Some((image, stats))
}

/// Heat-map colour of a stretch factor: blue at [`STRETCH_SCALE_MIN`], green at 1, yellow,
/// red at [`STRETCH_SCALE_MAX`] and above.
#[must_use]
pub fn stretch_color(factor: f32) -> egui::Color32 {
    let stops: [(f32, [u8; 3]); 4] = [
        (STRETCH_SCALE_MIN, [40, 90, 255]),
        (1.0, [40, 200, 80]),
        (1.75, [250, 220, 40]),
        (STRETCH_SCALE_MAX, [240, 40, 30]),
    ];
    let f = if factor.is_finite() {
        factor
    } else {
        STRETCH_SCALE_MAX
    };
    let f = f.clamp(STRETCH_SCALE_MIN, STRETCH_SCALE_MAX);
    let k = stops
        .windows(2)
        .position(|w| f <= w[1].0)
        .unwrap_or(stops.len() - 2);
    let ((a, ca), (b, cb)) = (stops[k], stops[k + 1]);
    let t = ((f - a) / (b - a)).clamp(0.0, 1.0);
    let mix =
        |i: usize| (f32::from(ca[i]) + t * (f32::from(cb[i]) - f32::from(ca[i]))).round() as u8;
    egui::Color32::from_rgb(mix(0), mix(1), mix(2))
}

/// The hole overlay's legend, at the view's bottom right (the stretch legend sits at its
/// bottom left).
pub fn hole_legend_ui(ui: &egui::Ui, rect: egui::Rect) {
    let painter = ui.painter_at(rect);
    let font = egui::FontId::proportional(11.0);
    let rows = [
        (HOLE_COLOR, "Hole: mesh shows, no voxel"),
        (BLOAT_COLOR, "Bloat: voxel beyond the mesh"),
    ];
    let width = 190.0;
    let origin = rect.right_bottom() + egui::vec2(-width - 12.0, -52.0);
    let backdrop = egui::Rect::from_min_size(origin, egui::vec2(width, 42.0));
    painter.rect_filled(backdrop, 3.0, egui::Color32::from_black_alpha(160));
    for (i, (color, text)) in rows.into_iter().enumerate() {
        let y = origin.y + 8.0 + 16.0 * i as f32;
        let swatch =
            egui::Rect::from_min_size(egui::pos2(origin.x + 8.0, y), egui::vec2(12.0, 12.0));
        painter.rect_filled(swatch, 2.0, color);
        painter.text(
            egui::pos2(swatch.max.x + 6.0, y + 6.0),
            egui::Align2::LEFT_CENTER,
            text,
            font.clone(),
            egui::Color32::from_gray(220),
        );
    }
}

/// The heat map's colour legend in the view's lower left corner, with the frame's range.
pub fn stretch_legend_ui(ui: &egui::Ui, rect: egui::Rect, stats: StretchStats) {
    let painter = ui.painter_at(rect);
    let bar = egui::Rect::from_min_size(
        rect.left_bottom() + egui::vec2(12.0, -58.0),
        egui::vec2(180.0, 12.0),
    );
    let backdrop = egui::Rect::from_min_max(
        bar.min - egui::vec2(6.0, 22.0),
        bar.max + egui::vec2(84.0, 26.0),
    );
    painter.rect_filled(backdrop, 3.0, egui::Color32::from_black_alpha(160));
    let steps = 36;
    for i in 0..steps {
        let t0 = i as f32 / steps as f32;
        let t1 = (i + 1) as f32 / steps as f32;
        let f = STRETCH_SCALE_MIN + (t0 + t1) * 0.5 * (STRETCH_SCALE_MAX - STRETCH_SCALE_MIN);
        let r = egui::Rect::from_min_max(
            egui::pos2(bar.min.x + t0 * bar.width(), bar.min.y),
            egui::pos2(bar.min.x + t1 * bar.width(), bar.max.y),
        );
        painter.rect_filled(r, 0.0, stretch_color(f));
    }
    let font = egui::FontId::proportional(11.0);
    let text = egui::Color32::from_gray(220);
    painter.text(
        bar.left_top() - egui::vec2(0.0, 4.0),
        egui::Align2::LEFT_BOTTOM,
        "Stretch factor",
        font.clone(),
        text,
    );
    for f in [STRETCH_SCALE_MIN, 1.0, 2.0, STRETCH_SCALE_MAX] {
        let x = bar.min.x
            + (f - STRETCH_SCALE_MIN) / (STRETCH_SCALE_MAX - STRETCH_SCALE_MIN) * bar.width();
        painter.text(
            egui::pos2(x, bar.max.y + 2.0),
            egui::Align2::CENTER_TOP,
            format!("{f:.1}"),
            font.clone(),
            text,
        );
    }
    painter.text(
        egui::pos2(bar.max.x + 18.0, bar.center().y),
        egui::Align2::LEFT_CENTER,
        format!(
            "min {:.2}\nmean {:.2}\nmax {:.2}",
            stats.min, stats.mean, stats.max
        ),
        font,
        text,
    );
}

/// Colour of a joint weight in the heat map: blue at 0, green, yellow, red at 1 (as Blender's
/// weight paint).
#[must_use]
pub fn weight_color(w: f32) -> egui::Color32 {
    let stops: [[f32; 3]; 4] = [
        [30.0, 60.0, 255.0],
        [40.0, 200.0, 80.0],
        [250.0, 220.0, 40.0],
        [240.0, 40.0, 30.0],
    ];
    let f = w.clamp(0.0, 1.0) * 3.0;
    let k = (f.floor() as usize).min(2);
    let t = f - k as f32;
    let c = |i: usize| (stops[k][i] + t * (stops[k + 1][i] - stops[k][i])).round() as u8;
    egui::Color32::from_rgb(c(0), c(1), c(2))
}

/// The heat map of joint `joint`'s weight over the pixels of object `id` in a preview frame
/// (`labels` are document indices + 1, `nodes` `level << 32 | pool index`); other pixels are
/// transparent. `None` when no pixel shows the object.
#[must_use]
pub fn weight_overlay(
    doc: &thicket_core::scene::Document,
    labels: &[u32],
    nodes: &[u64],
    size: [usize; 2],
    id: u64,
    joint: usize,
) -> Option<egui::ColorImage> {
    let index = doc.objects.iter().position(|o| o.id == id)?;
    let thicket_core::scene::ObjectKind::Voxels(v) = &doc.objects[index].kind else {
        return None;
    };
    let label = index as u32 + 1;
    let depth = u64::from(v.svo.depth());
    let (leaf, inner) = (v.svo.leaf_skin(), v.svo.inner_skin());
    let mut image = egui::ColorImage::filled(size, egui::Color32::TRANSPARENT);
    let mut any = false;
    for ((px, &l), &node) in image.pixels.iter_mut().zip(labels).zip(nodes) {
        if l != label {
            continue;
        }
        let (level, i) = (node >> 32, (node & 0xffff_ffff) as usize);
        let skin = if level == depth {
            leaf.get(i)
        } else {
            inner.get(i)
        };
        let w = skin.map_or(0.0, |s| {
            if s.is_empty() {
                if joint == 0 { 1.0 } else { 0.0 }
            } else {
                s.influences()
                    .filter(|&(k, _)| usize::from(k) == joint)
                    .map(|(_, w)| w)
                    .sum()
            }
        });
        let c = weight_color(w);
        *px = egui::Color32::from_rgba_unmultiplied(c.r(), c.g(), c.b(), 215);
        any = true;
    }
    any.then_some(image)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stretch_colours_run_blue_green_red_and_clamp() {
        let blue = stretch_color(STRETCH_SCALE_MIN);
        let green = stretch_color(1.0);
        let red = stretch_color(STRETCH_SCALE_MAX);
        assert!(blue.b() > blue.r() && blue.b() > blue.g());
        assert!(green.g() > green.r() && green.g() > green.b());
        assert!(red.r() > red.g() && red.r() > red.b());
        assert_eq!(stretch_color(0.01), blue);
        assert_eq!(stretch_color(99.0), red);
        assert_eq!(stretch_color(f32::NAN), red);
        // Between stops the colour moves monotonically toward the next one.
        assert!(stretch_color(1.4).r() > green.r());
    }
}
