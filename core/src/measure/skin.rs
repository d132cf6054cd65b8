//! Hole and bloat metrics for skinned voxel models: the voxel model drawn with a stretch
//! strategy against its source triangle mesh skinned with the same pose, seen by the same
//! cameras (ASVO paper §3.3, §6, Fig. 11), compared per pixel *through the shell*: by depth,
//! not only by coverage.
//!
//! A **hole** is a pixel where the skinned mesh's front surface is nearer than the voxels' by
//! more than a voxel-scaled tolerance, or where the mesh covers and no voxel does: the voxels
//! show something behind where the skin should be (often the model's own back shell, which the
//! old "object id ≠ 0" coverage count took for covered). **Bloat** is the converse: voxels
//! nearer than the mesh by more than the tolerance, or voxels where the mesh is not.
//!
//! The error is split so the stretch strategies can be judged on what they can fix:
//! - *rest*: the counts at the rest pose (voxelization error of the shape);
//! - *misplaced* holes: the surface point the mesh shows there maps back (through its triangle)
//!   to a bind-pose position where no voxel (of the one there and its 26 neighbours) reaches it
//!   even stretched to the box of its skinned corners, or to no voxel at all. The voxels carry
//!   weights that put them elsewhere (the four strongest of the mesh's, quantised; one part's
//!   where faces of two parts meet), so no stretch factor can close these: voxelization error;
//! - *stretch* holes: the rest, beyond the same view's rest-pose holes, per frame.

use std::borrow::Cow;
use std::time::Instant;

use glam::{Mat4, UVec3, Vec3};
use serde::Serialize;

use crate::mesh::{Material, MeshModel, TriangleMesh};
use crate::quality::Quality;
use crate::render::{
    Camera, FrameBuffers, MeshInstance, Projection, RenderError, RenderScene, VoxelInstance,
    render_scene,
};
use crate::scene::{Document, ObjectKind, VoxelModel};
use crate::skin::deform::SkinDeform;
use crate::skin::lbs::{skin_mesh, skin_point};
use crate::skin::stretch::StretchSettings;

/// Silhouette comparison counts (summed over any number of frames): coverage only, the metric
/// before [`ShellCounts`]; kept so reports can show what it misses.
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

/// Per-pixel comparison through the shell (summed over any number of frames and views); see
/// the module doc.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct ShellCounts {
    /// Pixels the skinned mesh covers.
    pub mesh_pixels: u64,
    /// Pixels the voxels cover.
    pub voxel_pixels: u64,
    /// Mesh nearer than the voxels by more than the tolerance, or mesh without voxels.
    pub holes: u64,
    /// Of `holes`, those where voxels do cover the pixel but lie behind the skin (seen through
    /// a gap in the front shell): the holes a coverage count misses.
    pub holes_through: u64,
    /// Of `holes`, those whose surface point no voxel around its bind-pose position can reach:
    /// outside every neighbour's box of skinned corners (grown by the depth tolerance), or no
    /// voxel there at all. The voxels carry weights that put them elsewhere (the four strongest
    /// of the mesh's, quantised; one part's where two parts' faces meet), so no stretch factor
    /// closes these: voxelization error.
    pub holes_misplaced: u64,
    /// Voxels nearer than the mesh by more than the tolerance, or voxels without mesh.
    pub bloat: u64,
}

impl ShellCounts {
    /// Adds another frame's counts.
    pub fn add(&mut self, o: &Self) {
        self.mesh_pixels += o.mesh_pixels;
        self.voxel_pixels += o.voxel_pixels;
        self.holes += o.holes;
        self.holes_through += o.holes_through;
        self.holes_misplaced += o.holes_misplaced;
        self.bloat += o.bloat;
    }

    /// Holes as a fraction of the mesh's pixels.
    #[must_use]
    pub fn hole_fraction(&self) -> f64 {
        self.holes as f64 / self.mesh_pixels.max(1) as f64
    }

    /// Bloat as a fraction of the mesh's pixels.
    #[must_use]
    pub fn bloat_fraction(&self) -> f64 {
        self.bloat as f64 / self.mesh_pixels.max(1) as f64
    }
}

/// Depth tolerance of [`compare_depths`] in voxel edges (or pixels, whichever is larger): a
/// conservative surface voxel reaches up to a voxel diagonal (√3) past the surface it holds,
/// and a splat or LOD node may be drawn at its centre's depth.
pub const DEPTH_TOLERANCE_VOXELS: f32 = 2.0;

/// Counts holes and bloat between a mesh frame and a voxel frame of the same orthographic or
/// perspective camera, with a depth tolerance in world units. `misplaced` decides, for a hole
/// pixel the mesh covers, whether the voxel that should show it went elsewhere.
pub fn compare_depths(
    cam: &Camera,
    mesh: &FrameBuffers,
    voxels: &FrameBuffers,
    tolerance: f32,
    mut misplaced: impl FnMut(usize) -> bool,
) -> ShellCounts {
    let mut s = ShellCounts::default();
    for i in 0..mesh.ids.len().min(voxels.ids.len()) {
        let m = mesh.ids[i].object != 0;
        let v = voxels.ids[i].object != 0;
        s.mesh_pixels += u64::from(m);
        s.voxel_pixels += u64::from(v);
        match (m, v) {
            (true, false) => {
                s.holes += 1;
                s.holes_misplaced += u64::from(misplaced(i));
            }
            (false, true) => s.bloat += 1,
            (true, true) => {
                let dm = cam.view_depth(mesh.depth[i]);
                let dv = cam.view_depth(voxels.depth[i]);
                if dv > dm + tolerance {
                    s.holes += 1;
                    s.holes_through += 1;
                    s.holes_misplaced += u64::from(misplaced(i));
                } else if dv < dm - tolerance {
                    s.bloat += 1;
                }
            }
            (false, false) => {}
        }
    }
    s
}

/// Why a skinned model cannot be measured.
#[derive(Debug, thiserror::Error)]
pub enum MetricsError {
    /// No visible voxel object with a rig.
    #[error(
        "no skinned voxel model in the document (import a skinned glTF, or rig a voxel model with `thicket rig` or the editor's Rig section)"
    )]
    NoSkinnedModel,
    /// The requested clip does not exist.
    #[error("the skinned model has no clip {0:?}")]
    NoClip(String),
    /// A frame count of 0.
    #[error("the number of frames must be at least 1")]
    NoFrames,
    /// A view count of 0.
    #[error("the number of views must be at least 1")]
    NoViews,
    /// Rendering failed.
    #[error(transparent)]
    Render(#[from] RenderError),
}

/// What [`skin_report`] measures.
#[derive(Debug, Clone)]
pub struct ReportSettings {
    /// Frames, evenly spaced over the clip (`t = i · duration / frames`).
    pub frames: u32,
    /// Views, evenly spaced around the model's vertical (world Y) axis, level, orthographic.
    pub views: u32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Clip by name; `None`: the model's playback clip.
    pub clip: Option<String>,
    /// The strategies (with their settings) to compare.
    pub strategies: Vec<StretchSettings>,
    /// Render quality (shadows are switched off: only depth and coverage are compared).
    pub quality: Quality,
}

/// What a skinned model's voxels are measured against.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ReferenceSurface {
    /// The triangle mesh the model was voxelized from, skinned with its own weights: the
    /// voxelization error shows as rest-pose holes and bloat.
    SourceMesh,
    /// A model rigged in Thicket has no source mesh: its own closed skinned surface, the one
    /// the glTF export writes (outward voxel faces, one weight set per lattice corner). At the
    /// rest pose it is the voxels' shell, so every hole or bloat is the drawing's, not the
    /// shape's.
    OwnSurface,
}

/// The surface [`skin_report`] and the editor's hole overlay compare a rigged model against,
/// in the object's own (bind) space, and which one it is: the imported source mesh where the
/// rig has one, else the model's own skinned surface ([`ReferenceSurface::OwnSurface`]), built
/// from the voxels now. `None` without a rig.
#[must_use]
pub fn reference_surface(model: &VoxelModel) -> Option<(Cow<'_, MeshModel>, ReferenceSurface)> {
    let rig = model.rig.as_ref()?;
    if let Some(mesh) = &rig.reference_mesh {
        return Some((Cow::Borrowed(mesh), ReferenceSurface::SourceMesh));
    }
    Some((Cow::Owned(own_surface(model)), ReferenceSurface::OwnSurface))
}

/// The closed skinned surface of `model` as the glTF export writes it in cube mode
/// ([`crate::io::gltf_export::greedy::greedy_quads`]), in the object's own space, as one part.
#[must_use]
pub fn own_surface(model: &VoxelModel) -> MeshModel {
    let quads = crate::io::gltf_export::greedy::greedy_quads(&model.svo);
    let skinned = model.svo.has_skin();
    let mut part = TriangleMesh::default();
    for q in &quads {
        let base = part.positions.len() as u32;
        let color = crate::io::gltf_export::linear(q.key.0);
        for (c, skin) in q.corners().into_iter().zip(q.corner_skins()) {
            part.positions.push(model.origin + c * model.voxel_size);
            part.normals.push(q.normal());
            part.colors.push(color);
            if skinned {
                part.joints.push(skin.joints_u16());
                part.weights.push(skin.blend_weights());
            }
        }
        part.indices
            .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
    }
    MeshModel {
        parts: vec![part],
        materials: vec![Material::default()],
    }
}

/// One view of one strategy.
#[derive(Debug, Clone, Serialize)]
pub struct ViewRow {
    /// Angle of the view around the vertical axis, degrees (0: looking down −Z).
    pub yaw_deg: f32,
    /// Counts at the rest pose.
    pub rest: ShellCounts,
    /// Counts per sampled frame, in the order of [`SkinReport::times`].
    pub frames: Vec<ShellCounts>,
    /// Holes beyond the rest pose's that are not misplaced, summed over frames: per frame
    /// `max(0, holes − misplaced − rest holes)`.
    pub stretch_holes: u64,
    /// Bloat beyond the rest pose's, summed over frames: per frame `max(0, bloat − rest bloat)`.
    pub stretch_bloat: u64,
}

/// One strategy's line of the report.
#[derive(Debug, Clone, Serialize)]
pub struct StrategyRow {
    /// The settings measured.
    pub settings: StretchSettings,
    /// Rest-pose counts summed over views.
    pub rest: ShellCounts,
    /// Posed counts summed over views and frames.
    pub posed: ShellCounts,
    /// [`ViewRow::stretch_holes`] summed over views.
    pub stretch_holes: u64,
    /// [`ViewRow::stretch_bloat`] summed over views.
    pub stretch_bloat: u64,
    /// Per view.
    pub views: Vec<ViewRow>,
    /// The old coverage-only counts over every view and frame (holes there are only pixels no
    /// voxel covers at all).
    pub coverage: Silhouette,
    /// The lowest per-frame coverage IoU.
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
    /// What the voxels were compared against.
    pub reference: ReferenceSurface,
    /// The clip's name (empty for the rest pose).
    pub clip: String,
    /// Times measured, seconds.
    pub times: Vec<f32>,
    /// Depth tolerance used, world units.
    pub tolerance: f32,
    /// Voxel edge in world units.
    pub voxel_world: f32,
    /// Pixel edge in world units (orthographic views).
    pub pixel_world: f32,
    /// One row per strategy, in the order asked.
    pub rows: Vec<StrategyRow>,
}

/// The orthographic cameras of [`skin_report`]: `views` level views around the world Y axis,
/// all framing the sphere `center`, `radius`.
#[must_use]
pub fn ring_cameras(center: Vec3, radius: f32, views: u32, width: u32, height: u32) -> Vec<Camera> {
    let r = radius.max(1e-6);
    let (w, h) = (width.max(1) as f32, height.max(1) as f32);
    let (half_width, half_height) = if w >= h {
        (1.05 * r * w / h, 1.05 * r)
    } else {
        (1.05 * r, 1.05 * r * h / w)
    };
    (0..views)
        .map(|i| {
            let yaw = std::f32::consts::TAU * i as f32 / views as f32;
            let eye = center + Vec3::new(yaw.sin(), 0.0, yaw.cos()) * (3.0 * r);
            Camera::new(
                Mat4::look_at_rh(eye, center, Vec3::Y),
                Projection::Orthographic {
                    half_width,
                    half_height,
                    near: 1.5 * r,
                    far: 4.5 * r,
                },
                width,
                height,
            )
        })
        .collect()
}

/// Everything [`misplaced_hole`] needs about one posed frame.
struct HoleProbe<'a> {
    cam: &'a Camera,
    mesh_fb: &'a FrameBuffers,
    posed: &'a MeshModel,
    reference: &'a MeshModel,
    skinning: &'a [Mat4],
    model: &'a VoxelModel,
    world_from_object: Mat4,
    object_from_world: Mat4,
    tables: &'a crate::skin::deform::SkinTables,
    limit: f32,
}

/// Whether the mesh surface seen at pixel `i` lies out of reach of every voxel around it: maps
/// the pixel's point back to bind space through its triangle and takes the leaf there and its
/// 26 neighbours. Each one's eight corners, skinned with their corner weights (the lattice
/// deformation `Corners` draws, uncapped), span a box; the hole is within stretch's reach when
/// one of those boxes, grown by the depth tolerance, holds the point, and misplaced otherwise
/// (or when there is no leaf at all).
fn misplaced_hole(p: &HoleProbe<'_>, i: usize) -> bool {
    let id = p.mesh_fb.ids[i];
    let (part, tri) = ((id.node >> 32) as usize, (id.node & 0xffff_ffff) as usize);
    let (Some(posed), Some(bind)) = (p.posed.parts.get(part), p.reference.parts.get(part)) else {
        return true;
    };
    let Some(ix) = posed.indices.get(3 * tri..3 * tri + 3) else {
        return true;
    };
    let w = p.cam.width as usize;
    let (x, y) = ((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
    let world = p.cam.unproject(x, y, p.mesh_fb.depth[i]);
    let q = p.object_from_world.transform_point3(world);
    let v = |m: &crate::mesh::TriangleMesh, k: usize| m.positions[ix[k] as usize];
    let bary = barycentric(q, v(posed, 0), v(posed, 1), v(posed, 2));
    let bind_point = v(bind, 0) * bary.x + v(bind, 1) * bary.y + v(bind, 2) * bary.z;
    let model = p.model;
    let cell = ((bind_point - model.origin) / model.voxel_size).floor();
    for dz in -1..=1 {
        for dy in -1..=1 {
            for dx in -1..=1 {
                let c = cell + Vec3::new(dx as f32, dy as f32, dz as f32);
                if c.min_element() < 0.0 || !c.is_finite() {
                    continue;
                }
                let Some(leaf) = leaf_at(&model.svo, c.as_uvec3()) else {
                    continue;
                };
                let Some(skins) = p.tables.leaf_corner_skins(leaf.index) else {
                    continue;
                };
                let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
                for (k, skin) in skins.iter().enumerate() {
                    let bit = |b: usize| if k & b != 0 { 1.0 } else { 0.0 };
                    let corner =
                        model.origin + (c + Vec3::new(bit(1), bit(2), bit(4))) * model.voxel_size;
                    let q = p.world_from_object.transform_point3(skin_point(
                        p.skinning,
                        skin.joints_u16(),
                        skin.blend_weights(),
                        corner,
                    ));
                    lo = lo.min(q);
                    hi = hi.max(q);
                }
                if (world - lo).min_element() >= -p.limit && (hi - world).min_element() >= -p.limit
                {
                    return false;
                }
            }
        }
    }
    true
}

/// The leaf at voxel coordinate `coord`, if there is one.
fn leaf_at(svo: &crate::svo::Svo, coord: UVec3) -> Option<crate::svo::NodeRef> {
    if coord.max_element() >= svo.extent() {
        return None;
    }
    let mut node = svo.root();
    while !svo.is_leaf(&node) {
        let half = svo.node_size(node.level) / 2;
        let local = coord - node.origin;
        let k = u8::from(local.x >= half)
            | u8::from(local.y >= half) << 1
            | u8::from(local.z >= half) << 2;
        node = svo.child(&node, k)?;
    }
    Some(node)
}

/// Barycentric coordinates of `p` projected onto the triangle `a b c`, clamped to the triangle
/// (a point read back from a depth buffer lies on it up to rounding).
fn barycentric(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let (e0, e1, ep) = (b - a, c - a, p - a);
    let (d00, d01, d11) = (e0.dot(e0), e0.dot(e1), e1.dot(e1));
    let (d20, d21) = (ep.dot(e0), ep.dot(e1));
    let den = d00 * d11 - d01 * d01;
    // Degenerate (or NaN) triangles have no barycentric coordinates.
    let well_formed =
        den.abs().partial_cmp(&(f32::EPSILON * d00 * d11)) == Some(std::cmp::Ordering::Greater);
    if !well_formed {
        return Vec3::new(1.0, 0.0, 0.0);
    }
    let v = (d11 * d20 - d01 * d21) / den;
    let w = (d00 * d21 - d01 * d20) / den;
    let b = Vec3::new(1.0 - v - w, v, w).max(Vec3::ZERO);
    let sum = b.x + b.y + b.z;
    if sum > 0.0 { b / sum } else { Vec3::X }
}

/// Largest column length of the linear part: how much the object transform scales.
fn max_scale(m: Mat4) -> f32 {
    m.x_axis
        .truncate()
        .length()
        .max(m.y_axis.truncate().length())
        .max(m.z_axis.truncate().length())
}

/// The silhouettes of the visible rigged voxel models of `doc` seen by `cam`, per pixel: where
/// their reference meshes, skinned with the current pose, cover (first) and where their voxels
/// drawn under `quality` cover (second), without shadows or ambient occlusion (coverage does
/// not depend on them). [`Silhouette::from_coverage`] counts them. `None` when no visible rigged
/// model has a reference mesh, or a render fails.
#[must_use]
pub fn posed_silhouettes(
    doc: &Document,
    cam: &Camera,
    quality: &Quality,
) -> Option<(Vec<bool>, Vec<bool>)> {
    let quality = Quality {
        shadows: false,
        ao_samples: 0,
        ..quality.clone()
    };
    let deforms = crate::render::document_deforms(doc, &quality);
    let pixels = cam.width as usize * cam.height as usize;
    let mut mesh_cov = vec![false; pixels];
    let mut voxel_cov = vec![false; pixels];
    let mut any = false;
    for (o, d) in doc.objects.iter().zip(&deforms) {
        let (ObjectKind::Voxels(v), Some(d)) = (&o.kind, d) else {
            continue;
        };
        let Some(rig) = v.rig.as_ref().filter(|_| o.visible) else {
            continue;
        };
        let Some((reference, _)) = reference_surface(v) else {
            continue;
        };
        let skinning = rig.current_skinning();
        let mesh = MeshModel {
            parts: reference
                .parts
                .iter()
                .map(|p| skin_mesh(&skinning, p))
                .collect(),
            materials: reference.materials.clone(),
        };
        let scene = |voxels: Vec<VoxelInstance<'_>>, meshes: Vec<MeshInstance<'_>>| {
            let s = RenderScene {
                voxels,
                meshes,
                lights: &doc.lights,
                ambient: doc.ambient,
                background: doc.background,
            };
            render_scene(&s, cam, &quality)
                .ok()
                .map(|(_, fb, _)| fb.coverage())
        };
        let mesh_only = scene(
            Vec::new(),
            vec![MeshInstance {
                model: &mesh,
                world_from_object: o.transform.matrix(),
                casts_shadows: false,
                label: 1,
            }],
        )?;
        let voxels_only = scene(
            vec![VoxelInstance {
                svo: &v.svo,
                deform: d.as_ref(),
                casts_shadows: false,
                label: 1,
            }],
            Vec::new(),
        )?;
        for (acc, c) in mesh_cov.iter_mut().zip(mesh_only) {
            *acc |= c;
        }
        for (acc, c) in voxel_cov.iter_mut().zip(voxels_only) {
            *acc |= c;
        }
        any = true;
    }
    any.then_some((mesh_cov, voxel_cov))
}

/// The stretch factor of every node of rigged model `v` (in object `o`) whose pixel id is in
/// `wanted` (the nodes a frame shows): the size of the node's splat this frame (strategy, multiplier, overrides) over the size
/// of the same node placed with no stretch. Both are the renderer's own `NodeDeform`.
pub fn node_stretch_factors(
    o: &crate::scene::Object,
    v: &crate::scene::VoxelModel,
    quality: &crate::quality::Quality,
    wanted: &std::collections::HashSet<u64>,
) -> std::collections::HashMap<u64, f32> {
    use crate::deform::{NodeDeform as _, NodeInfo};
    use crate::skin::{SkinDeform, StretchStrategy};
    let mut out = std::collections::HashMap::new();
    let Some(rig) = &v.rig else {
        return out;
    };
    let settings = crate::render::effective_stretch(rig, quality);
    let deform = |s| crate::render::skin_deform(o, v, rig, quality).with_settings(s);
    let actual = deform(settings);
    let no_overrides = crate::skin::StretchOverrides::default();
    let plain = {
        let mut s = settings;
        s.strategy = StretchStrategy::Off;
        s.multiplier = 1.0;
        // Overrides are part of the stretch: the reference ignores them.
        SkinDeform::new(
            o.transform.matrix(),
            v.object_from_voxel(),
            &rig.skinning_at(rig.playback.clip, rig.playback.time_secs),
            s,
            &no_overrides,
            rig.tables(&v.svo),
        )
    };
    // Half extent of a splat's world box along its largest axis.
    let extent = |d: crate::deform::DeformedNode| {
        let m = d.half_axes_world;
        let rows = m.x_axis.abs() + m.y_axis.abs() + m.z_axis.abs();
        rows.max_element()
    };
    if v.svo.is_empty() {
        return out;
    }
    let mut stack = vec![v.svo.root()];
    while let Some(node) = stack.pop() {
        let id = (u64::from(node.level) << 32) | u64::from(node.index);
        if wanted.contains(&id) {
            let info = NodeInfo { svo: &v.svo, node };
            let base = extent(plain.deform(&info));
            let f = if base > 0.0 {
                extent(actual.deform(&info)) / base
            } else {
                1.0
            };
            out.insert(id, f);
        }
        if !v.svo.is_leaf(&node) {
            stack.extend((0..8).filter_map(|k| v.svo.child(&node, k)));
        }
    }
    out
}

/// Measures the first visible skinned voxel model of `doc` that has a reference mesh: for each
/// of `views` orthographic views around it, at the rest pose and at every sampled frame, the
/// reference mesh skinned with the frame's pose against the voxels drawn with each strategy,
/// compared by depth ([`compare_depths`]; tolerance [`DEPTH_TOLERANCE_VOXELS`] × the larger of
/// a voxel and a pixel). Every view frames the union of the posed mesh over all frames and the
/// rest pose, so a walking character stays in view.
///
/// # Errors
/// [`MetricsError`] when there is nothing to measure, the clip is unknown, a count is 0 or a
/// render fails.
pub fn skin_report(doc: &Document, settings: &ReportSettings) -> Result<SkinReport, MetricsError> {
    if settings.frames == 0 {
        return Err(MetricsError::NoFrames);
    }
    if settings.views == 0 {
        return Err(MetricsError::NoViews);
    }
    let (object, model, rig) = doc
        .objects
        .iter()
        .filter(|o| o.visible)
        .find_map(|o| match &o.kind {
            ObjectKind::Voxels(v) => Some((o, v, v.rig.as_ref()?)),
            ObjectKind::Mesh(_) | ObjectKind::Krs(_) => None,
        })
        .ok_or(MetricsError::NoSkinnedModel)?;
    let (reference, reference_kind) =
        reference_surface(model).ok_or(MetricsError::NoSkinnedModel)?;
    let reference: &MeshModel = &reference;
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
    let object_from_world = world_from_object.inverse();
    let pose_mesh = |skinning: &[Mat4]| MeshModel {
        parts: reference
            .parts
            .iter()
            .map(|p| skin_mesh(skinning, p))
            .collect(),
        materials: reference.materials.clone(),
    };
    // Frame 0 of this list is the rest pose; the sampled frames follow.
    let posed: Vec<(Vec<Mat4>, MeshModel)> = std::iter::once(rig.skinning_at(None, 0.0))
        .chain(times.iter().map(|&t| rig.skinning_at(clip, t)))
        .map(|skinning| {
            let mesh = pose_mesh(&skinning);
            (skinning, mesh)
        })
        .collect();
    let mut bounds: Option<(Vec3, Vec3)> = None;
    for (_, m) in &posed {
        for part in &m.parts {
            for &p in &part.positions {
                let w = world_from_object.transform_point3(p);
                bounds = Some(bounds.map_or((w, w), |(lo, hi)| (lo.min(w), hi.max(w))));
            }
        }
    }
    let (lo, hi) = bounds.unwrap_or((Vec3::ZERO, Vec3::ONE));
    let radius = ((hi - lo).length() * 0.5).max(1e-6);
    let cams = ring_cameras(
        (lo + hi) * 0.5,
        radius,
        settings.views,
        settings.width,
        settings.height,
    );
    let voxel_world = model.voxel_size * max_scale(world_from_object);
    let pixel_world = cams[0].pixel_world_size(1.0);
    let tolerance = DEPTH_TOLERANCE_VOXELS * voxel_world.max(pixel_world);
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
            rest: ShellCounts::default(),
            posed: ShellCounts::default(),
            stretch_holes: 0,
            stretch_bloat: 0,
            views: cams
                .iter()
                .enumerate()
                .map(|(i, _)| ViewRow {
                    yaw_deg: 360.0 * i as f32 / settings.views as f32,
                    rest: ShellCounts::default(),
                    frames: Vec::new(),
                    stretch_holes: 0,
                    stretch_bloat: 0,
                })
                .collect(),
            coverage: Silhouette::default(),
            worst_iou: 1.0,
            draw_ms: 0.0,
            frame_ms: 0.0,
        })
        .collect();
    for (view, cam) in cams.iter().enumerate() {
        for (frame, (skinning, mesh)) in posed.iter().enumerate() {
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
            let (_, mesh_fb, _) = render_scene(&mesh_scene, cam, &quality)?;
            let mesh_cov = mesh_fb.coverage();
            let probe = HoleProbe {
                cam,
                mesh_fb: &mesh_fb,
                posed: mesh,
                reference,
                skinning,
                model,
                world_from_object,
                object_from_world,
                tables: &tables,
                limit: tolerance,
            };
            // Whether a hole pixel is misplaced depends on the view and the pose only: found
            // once for all strategies.
            let mut misplaced: Vec<Option<bool>> = vec![None; mesh_fb.ids.len()];
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
                let (_, fb, stats) = render_scene(&scene, cam, &quality)?;
                let counts = compare_depths(cam, &mesh_fb, &fb, tolerance, |i| {
                    *misplaced[i].get_or_insert_with(|| misplaced_hole(&probe, i))
                });
                let v = &mut row.views[view];
                if frame == 0 {
                    v.rest = counts;
                    row.rest.add(&counts);
                    continue;
                }
                row.frame_ms += t0.elapsed().as_secs_f64() * 1e3;
                row.draw_ms += stats.times.traversal_ms + stats.times.splat_ms;
                let beyond = (counts.holes - counts.holes_misplaced).saturating_sub(v.rest.holes);
                let bloat = counts.bloat.saturating_sub(v.rest.bloat);
                v.stretch_holes += beyond;
                v.stretch_bloat += bloat;
                v.frames.push(counts);
                row.stretch_holes += beyond;
                row.stretch_bloat += bloat;
                row.posed.add(&counts);
                let s = Silhouette::from_coverage(&mesh_cov, &fb.coverage());
                row.worst_iou = row.worst_iou.min(s.iou());
                row.coverage.add(&s);
            }
        }
    }
    let n = f64::from(settings.frames) * f64::from(settings.views);
    for row in &mut rows {
        row.draw_ms /= n;
        row.frame_ms /= n;
    }
    Ok(SkinReport {
        object: object.name.clone(),
        reference: reference_kind,
        clip: clip
            .and_then(|c| rig.clips.get(c))
            .map(|c| c.name.clone())
            .unwrap_or_default(),
        times,
        tolerance,
        voxel_world,
        pixel_world,
        rows,
    })
}

pub mod synthetic;

#[cfg(test)]
mod tests;
