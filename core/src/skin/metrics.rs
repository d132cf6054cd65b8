//! Hole and bloat metrics for skinned voxel models: the voxel model drawn with a stretch
//! strategy against its source triangle mesh skinned with the same pose, seen by the same
//! camera (ASVO paper §3.3, §6, Fig. 11). *Holes* are pixels inside the mesh's silhouette that
//! no voxel covers; *bloat* is pixels voxels cover outside it.

use std::time::Instant;

use glam::{Mat4, Vec3};
use serde::Serialize;

use super::deform::SkinDeform;
use super::lbs::skin_mesh;
use super::stretch::StretchSettings;
use crate::mesh::MeshModel;
use crate::render::{
    Camera, MeshInstance, Quality, RenderError, RenderScene, VoxelInstance, render_scene,
};
use crate::scene::{Document, ObjectKind, OrbitCamera};

/// Silhouette comparison counts (summed over any number of frames).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct Silhouette {
    /// Pixels inside the skinned mesh's silhouette.
    pub mesh_pixels: u64,
    /// Pixels the voxels cover.
    pub voxel_pixels: u64,
    /// Mesh pixels the voxels miss.
    pub holes: u64,
    /// Voxel pixels outside the mesh.
    pub bloat: u64,
}

impl Silhouette {
    /// Compares two coverage masks of the same size (mesh first).
    #[must_use]
    pub fn from_coverage(mesh: &[bool], voxels: &[bool]) -> Self {
        let mut s = Self::default();
        for (&m, &v) in mesh.iter().zip(voxels) {
            s.mesh_pixels += u64::from(m);
            s.voxel_pixels += u64::from(v);
            s.holes += u64::from(m && !v);
            s.bloat += u64::from(v && !m);
        }
        s
    }

    /// Adds another frame's counts.
    pub fn add(&mut self, o: &Self) {
        self.mesh_pixels += o.mesh_pixels;
        self.voxel_pixels += o.voxel_pixels;
        self.holes += o.holes;
        self.bloat += o.bloat;
    }

    /// Intersection over union of the two silhouettes (1 when both are empty).
    #[must_use]
    pub fn iou(&self) -> f64 {
        let union = self.mesh_pixels + self.bloat;
        if union == 0 {
            return 1.0;
        }
        (self.mesh_pixels - self.holes.min(self.mesh_pixels)) as f64 / union as f64
    }

    /// Holes as a fraction of the mesh's silhouette.
    #[must_use]
    pub fn hole_fraction(&self) -> f64 {
        self.holes as f64 / self.mesh_pixels.max(1) as f64
    }

    /// Bloat as a fraction of the mesh's silhouette.
    #[must_use]
    pub fn bloat_fraction(&self) -> f64 {
        self.bloat as f64 / self.mesh_pixels.max(1) as f64
    }
}

/// Why a skinned model cannot be measured.
#[derive(Debug, thiserror::Error)]
pub enum MetricsError {
    /// No voxel object with a rig and a reference mesh.
    #[error(
        "no skinned voxel model with its source mesh in the document (import a skinned glTF to make one)"
    )]
    NoSkinnedModel,
    /// The requested clip does not exist.
    #[error("the skinned model has no clip {0:?}")]
    NoClip(String),
    /// A frame count of 0.
    #[error("the number of frames must be at least 1")]
    NoFrames,
    /// Rendering failed.
    #[error(transparent)]
    Render(#[from] RenderError),
}

/// What [`skin_report`] measures.
#[derive(Debug, Clone)]
pub struct ReportSettings {
    /// Frames, evenly spaced over the clip (`t = i · duration / frames`).
    pub frames: u32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Clip by name; `None`: the model's playback clip.
    pub clip: Option<String>,
    /// The strategies (with their settings) to compare.
    pub strategies: Vec<StretchSettings>,
    /// Render quality (shadows are switched off: only coverage is compared).
    pub quality: Quality,
}

/// One strategy's line of the report.
#[derive(Debug, Clone, Serialize)]
pub struct StrategyRow {
    /// The settings measured.
    pub settings: StretchSettings,
    /// Counts summed over every frame.
    pub total: Silhouette,
    /// The lowest per-frame IoU.
    pub worst_iou: f64,
    /// Mean voxel traversal + splat time per frame, milliseconds.
    pub draw_ms: f64,
    /// Mean wall time of the whole voxel frame (incl. resolve and shading), milliseconds.
    pub frame_ms: f64,
}

/// The whole report.
#[derive(Debug, Clone, Serialize)]
pub struct SkinReport {
    /// The measured object's name.
    pub object: String,
    /// The clip's name (empty for the rest pose).
    pub clip: String,
    /// Times measured, seconds.
    pub times: Vec<f32>,
    /// One row per strategy, in the order asked.
    pub rows: Vec<StrategyRow>,
}

/// Measures the first visible skinned voxel model of `doc` that has a reference mesh: for each
/// frame, the reference mesh skinned with the frame's pose and the voxels drawn with each
/// strategy, from the document camera's direction, framed on the union of the posed mesh over
/// all frames (so a walking character stays in view).
///
/// # Errors
/// [`MetricsError`] when there is nothing to measure, the clip is unknown or a render fails.
pub fn skin_report(doc: &Document, settings: &ReportSettings) -> Result<SkinReport, MetricsError> {
    if settings.frames == 0 {
        return Err(MetricsError::NoFrames);
    }
    let (object, model, rig, reference) = doc
        .objects
        .iter()
        .filter(|o| o.visible)
        .find_map(|o| match &o.kind {
            ObjectKind::Voxels(v) => {
                let rig = v.rig.as_ref()?;
                Some((o, v, rig, rig.reference_mesh.as_ref()?))
            }
            ObjectKind::Mesh(_) | ObjectKind::Krs(_) => None,
        })
        .ok_or(MetricsError::NoSkinnedModel)?;
    let clip = match &settings.clip {
        Some(name) => Some(
            rig.clip_index(name)
                .ok_or_else(|| MetricsError::NoClip(name.clone()))?,
        ),
        None => rig.playback.clip,
    };
    let duration = clip
        .and_then(|c| rig.clips.get(c))
        .map_or(0.0, |c| c.duration_secs);
    let times: Vec<f32> = (0..settings.frames)
        .map(|i| duration * i as f32 / settings.frames as f32)
        .collect();
    let world_from_object = object.transform.matrix();
    let posed: Vec<(Vec<Mat4>, MeshModel)> = times
        .iter()
        .map(|&t| {
            let skinning = rig.skinning_at(clip, t);
            let mesh = MeshModel {
                parts: reference
                    .parts
                    .iter()
                    .map(|p| skin_mesh(&skinning, p))
                    .collect(),
                materials: reference.materials.clone(),
            };
            (skinning, mesh)
        })
        .collect();
    // Frame the union of every posed mesh.
    let mut bounds: Option<(Vec3, Vec3)> = None;
    for (_, m) in &posed {
        for part in &m.parts {
            for &p in &part.positions {
                let w = world_from_object.transform_point3(p);
                bounds = Some(bounds.map_or((w, w), |(lo, hi)| (lo.min(w), hi.max(w))));
            }
        }
    }
    let mut orbit: OrbitCamera = doc.camera;
    if let Some((lo, hi)) = bounds {
        orbit.frame(lo, hi);
    }
    let cam = Camera::from_orbit(&orbit, settings.width, settings.height);
    let quality = Quality {
        shadows: false,
        ..settings.quality.clone()
    };
    let tables = rig.tables(&model.svo);
    let mut rows: Vec<StrategyRow> = settings
        .strategies
        .iter()
        .map(|&s| StrategyRow {
            settings: s,
            total: Silhouette::default(),
            worst_iou: 1.0,
            draw_ms: 0.0,
            frame_ms: 0.0,
        })
        .collect();
    for (skinning, mesh) in &posed {
        let mesh_scene = RenderScene {
            voxels: Vec::new(),
            meshes: vec![MeshInstance {
                model: mesh,
                world_from_object,
                casts_shadows: false,
                label: 1,
            }],
            lights: &doc.lights,
            ambient: doc.ambient,
            background: doc.background,
        };
        let (_, mesh_fb, _) = render_scene(&mesh_scene, &cam, &quality)?;
        let mesh_cov = mesh_fb.coverage();
        for row in &mut rows {
            let deform = SkinDeform::new(
                world_from_object,
                model.object_from_voxel(),
                skinning,
                row.settings,
                &rig.stretch_overrides,
                std::sync::Arc::clone(&tables),
            );
            let scene = RenderScene {
                voxels: vec![VoxelInstance {
                    svo: &model.svo,
                    deform: &deform,
                    casts_shadows: false,
                    label: 1,
                }],
                meshes: Vec::new(),
                lights: &doc.lights,
                ambient: doc.ambient,
                background: doc.background,
            };
            let t0 = Instant::now();
            let (_, fb, stats) = render_scene(&scene, &cam, &quality)?;
            row.frame_ms += t0.elapsed().as_secs_f64() * 1e3;
            row.draw_ms += stats.times.traversal_ms + stats.times.splat_ms;
            let s = Silhouette::from_coverage(&mesh_cov, &fb.coverage());
            row.worst_iou = row.worst_iou.min(s.iou());
            row.total.add(&s);
        }
    }
    let n = f64::from(settings.frames);
    for row in &mut rows {
        row.draw_ms /= n;
        row.frame_ms /= n;
    }
    Ok(SkinReport {
        object: object.name.clone(),
        clip: clip
            .and_then(|c| rig.clips.get(c))
            .map(|c| c.name.clone())
            .unwrap_or_default(),
        times,
        rows,
    })
}
