//! The document: objects (voxel models, meshes, KRS), their transforms, lights, the camera and
//! the quality settings. Renderers read it; it knows nothing about them.
//!
//! Every struct is `#[serde(default)]` so files written by older versions load. Large payloads
//! (octrees, meshes) are `#[serde(skip)]` here and stored in the project's `.bin` file by
//! [`crate::io::project`].

use glam::{Mat4, Quat, Vec3};
use serde::{Deserialize, Serialize};

pub mod bake;
pub mod forest;
pub mod motion;

/// Re-exported: documents check it (it belongs with the KRS).
pub use crate::krs::MAX_KRS_LEVELS;
pub use bake::bake_shown_pose;
pub use forest::{ForestLink, ForestPlan};
pub use motion::ObjectMotion;

use crate::enhance::{Control, EnhanceError, EnhanceSettings, EnhanceStats, Enhancer};
use crate::krs::{EmptyZone, KrsObject, Similarity};
use crate::mesh::MeshModel;
use crate::quality::Quality;
use crate::skin::Rig;
use crate::svo::Svo;

/// Current project file format version.
///
/// * 1: the first format.
/// * 2: voxel models may hold a frame sequence ([`VoxelModel::frames`], with a `"frames"`
///   payload in the `.bin`). Version 1 files load unchanged (they have no frames).
/// * 3: octree payloads store tiles (`SVO2`: one record per stored leaf or tile, see
///   `io::project`). Older files (`SVO1`, one record per voxel) load unchanged, their uniform
///   regions becoming tiles in memory.
/// * 4: octree payloads may hold interior voxels (`SVO3`, the layout of `SVO2`; a record with
///   the interior mark's normal code and no colour is `Voxel::INTERIOR`). Older payloads load
///   with that code read as the −Z normal it decodes to.
pub const FORMAT_VERSION: u32 = 4;

/// A value in the document that a renderer must not see.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SceneError {
    /// A non-finite or out-of-range number, with where it is.
    #[error("{what} of {context} is invalid: {detail}")]
    Invalid {
        /// What (e.g. "transform.scale").
        what: String,
        /// Which object / light.
        context: String,
        /// What is wrong.
        detail: String,
    },
}

fn invalid(what: &str, context: impl std::fmt::Display, detail: impl Into<String>) -> SceneError {
    SceneError::Invalid {
        what: what.to_owned(),
        context: context.to_string(),
        detail: detail.into(),
    }
}

/// A validation context written only when an error shows it: a renderer validates its document
/// every frame, and formatting each object's name cost allocations while nothing was wrong.
struct LazyContext<F>(F);

impl<F: Fn(&mut std::fmt::Formatter<'_>) -> std::fmt::Result> std::fmt::Display for LazyContext<F> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        (self.0)(f)
    }
}

fn lazy_context<F: Fn(&mut std::fmt::Formatter<'_>) -> std::fmt::Result>(
    write: F,
) -> LazyContext<F> {
    LazyContext(write)
}

/// Translation, rotation, non-uniform scale.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Transform {
    /// World-space translation.
    pub translation: Vec3,
    /// Rotation (unit quaternion).
    pub rotation: Quat,
    /// Per-axis scale (non-zero).
    pub scale: Vec3,
}

impl Default for Transform {
    fn default() -> Self {
        Self {
            translation: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            scale: Vec3::ONE,
        }
    }
}

impl Transform {
    /// `world_from_object`.
    #[must_use]
    pub fn matrix(&self) -> Mat4 {
        Mat4::from_scale_rotation_translation(self.scale, self.rotation, self.translation)
    }

    /// Finite values, a normalisable rotation and non-zero scale.
    ///
    /// # Errors
    /// What is wrong, naming `context`.
    pub fn validate(&self, context: impl std::fmt::Display) -> Result<(), SceneError> {
        if !self.translation.is_finite() {
            return Err(invalid(
                "transform.translation",
                context,
                format!("{} is not finite", self.translation),
            ));
        }
        if !self.rotation.is_finite() || self.rotation.length() < 1e-6 {
            return Err(invalid(
                "transform.rotation",
                context,
                format!("{} is not a rotation", self.rotation),
            ));
        }
        if !self.scale.is_finite() || self.scale.abs().min_element() < 1e-12 {
            return Err(invalid(
                "transform.scale",
                context,
                format!("{} must be finite and non-zero", self.scale),
            ));
        }
        Ok(())
    }
}

/// A voxel model: an octree plus how its voxels map to the object's space.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct VoxelModel {
    /// The voxels (stored in the `.bin` payload).
    #[serde(skip)]
    pub svo: Svo,
    /// Edge length of one voxel in object units.
    pub voxel_size: f32,
    /// Object-space position of voxel (0,0,0)'s minimum corner.
    pub origin: Vec3,
    /// Names of material ids (index = `Voxel::material`), from the source file.
    pub material_names: Vec<String>,
    /// Skeleton, clips and animation state when the model is skinned (its leaves then carry
    /// [`crate::svo::Skin4`] weights indexing the rig's joints, and voxel space maps through
    /// [`VoxelModel::object_from_voxel`] to the skeleton's bind-pose mesh space). `None`: a
    /// rigid model. (Omitted from the JSON when `None`, so rigid models save as before.)
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rig: Option<Rig>,
    /// The editable volume in voxels per axis, from voxel (0,0,0): edits are clipped to it and
    /// the editor draws it. `None` (imported models): the whole octree cube. At most the
    /// octree's extent on each axis (see [`VoxelModel::volume_size`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub volume: Option<glam::UVec3>,
    /// The model's palette (sRGB RGBA, in order): MagicaVoxel's 255 colours for an imported
    /// `.vox`, or the artist's own. Empty: the palette panel shows the model's colours only.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub palette: Vec<[u8; 4]>,
    /// A flip-book animation (an animated MagicaVoxel file): several octrees of which one is
    /// shown at a time. The shown frame is this model's own [`VoxelModel::svo`] and
    /// [`VoxelModel::origin`], so renderers and editing tools see it with no change; the other
    /// frames wait in the sequence. `None`: a still model. (Omitted from the JSON when `None`.)
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frames: Option<FrameSequence>,
}

/// One frame of a [`FrameSequence`] while it is not shown.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct VoxelFrame {
    /// The frame's voxels.
    pub svo: Svo,
    /// Object-space position of the frame's voxel (0,0,0) (frames may differ in size and place).
    pub origin: Vec3,
}

/// The frames of a flip-book voxel animation and its playhead (see [`VoxelModel::frames`]).
///
/// Frame `shown`'s slot in [`FrameSequence::frames`] is an empty placeholder: its voxels are the
/// model's `svo` and `origin`, swapped in and out by [`VoxelModel::show_frame`] (no copy).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct FrameSequence {
    /// How long each frame is shown, in seconds.
    pub frame_secs: f32,
    /// The playhead in seconds; the sequence loops.
    pub time_secs: f32,
    /// Index of the frame held in the model's `svo` and `origin`.
    pub shown: usize,
    /// Every frame in order, the shown one as an empty placeholder (stored in the `.bin`).
    #[serde(skip)]
    pub frames: Vec<VoxelFrame>,
}

/// MagicaVoxel plays animations at about 10 frames per second and its files store no rate: the
/// frame length given to imported animations.
pub const DEFAULT_FRAME_SECS: f32 = 0.1;

impl Default for FrameSequence {
    fn default() -> Self {
        Self {
            frame_secs: DEFAULT_FRAME_SECS,
            time_secs: 0.0,
            shown: 0,
            frames: Vec::new(),
        }
    }
}

impl FrameSequence {
    /// Number of frames.
    #[must_use]
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Whether there are no frames (never true in a valid document).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// Length of one loop in seconds.
    #[must_use]
    pub fn duration_secs(&self) -> f32 {
        self.frame_secs * self.frames.len() as f32
    }

    /// The frame shown at `time_secs` (looping; negative times count back from the end).
    #[must_use]
    pub fn frame_at(&self, time_secs: f32) -> usize {
        let n = self.frames.len();
        if n == 0 || self.frame_secs.is_nan() || self.frame_secs <= 0.0 || !time_secs.is_finite() {
            return 0;
        }
        let k = (f64::from(time_secs) / f64::from(self.frame_secs)).floor();
        // Exact for any count a document can hold; rem_euclid keeps it in 0..n.
        (k.rem_euclid(n as f64) as usize).min(n - 1)
    }
}

impl Default for VoxelModel {
    fn default() -> Self {
        Self {
            svo: Svo::default(),
            voxel_size: 1.0,
            origin: Vec3::ZERO,
            material_names: Vec::new(),
            rig: None,
            volume: None,
            palette: Vec::new(),
            frames: None,
        }
    }
}

impl VoxelModel {
    /// This model enhanced (see [`crate::enhance`]). The result covers the same space: voxel
    /// size divided by the factor, same origin, same material names (fragment `i` of coarse
    /// voxel `c` is fine voxel `c·F + i`). Skin weights are not carried over (fragments have
    /// none). (Here rather than in `enhance`, which works on plain octrees below the document.)
    ///
    /// # Errors
    /// See [`Enhancer::with_control`].
    pub fn enhanced(
        &self,
        settings: &EnhanceSettings,
        control: Control<'_>,
    ) -> Result<(VoxelModel, EnhanceStats), EnhanceError> {
        let e = Enhancer::with_control(&self.svo, settings, control)?;
        let stats = e.stats();
        Ok((self.with_enhanced(e.into_fine(), settings.factor), stats))
    }

    /// The model that an enhancement by `factor` of this one gives, with `fine` as its octree:
    /// voxels `factor` times smaller at the same origin, the same material names. The fine
    /// octree carries no joint weights, so the result is static (no rig, volume, palette or
    /// frames).
    #[must_use]
    pub fn with_enhanced(&self, fine: Svo, factor: u32) -> VoxelModel {
        VoxelModel {
            svo: fine,
            voxel_size: self.voxel_size / factor as f32,
            origin: self.origin,
            material_names: self.material_names.clone(),
            rig: None,
            volume: None,
            palette: Vec::new(),
            frames: None,
        }
    }

    /// The editable volume in voxels per axis: [`VoxelModel::volume`] clamped to the octree,
    /// or the whole octree cube.
    #[must_use]
    pub fn volume_size(&self) -> glam::UVec3 {
        let extent = glam::UVec3::splat(self.svo.extent());
        self.volume
            .map_or(extent, |v| v.clamp(glam::UVec3::ONE, extent))
    }

    /// Number of frames: 1 for a still model.
    #[must_use]
    pub fn frame_count(&self) -> usize {
        self.frames.as_ref().map_or(1, |f| f.len().max(1))
    }

    /// Frame `index`'s voxels and origin (the shown frame is the model's own); `None` past the
    /// end. A still model has one frame.
    #[must_use]
    pub fn frame(&self, index: usize) -> Option<(&Svo, Vec3)> {
        match &self.frames {
            Some(f) if index != f.shown => f.frames.get(index).map(|fr| (&fr.svo, fr.origin)),
            Some(f) if index >= f.len() => None,
            None if index > 0 => None,
            _ => Some((&self.svo, self.origin)),
        }
    }

    /// Shows frame `index` (swaps it into [`VoxelModel::svo`] and [`VoxelModel::origin`]);
    /// returns whether the shown frame changed. Out-of-range indices and still models are left
    /// as they are.
    pub fn show_frame(&mut self, index: usize) -> bool {
        let Some(seq) = self.frames.as_mut() else {
            return false;
        };
        if index == seq.shown || index >= seq.frames.len() || seq.shown >= seq.frames.len() {
            return false;
        }
        let old = seq.shown;
        // The shown frame goes back to its slot, the new one comes out of its slot.
        std::mem::swap(&mut self.svo, &mut seq.frames[old].svo);
        std::mem::swap(&mut self.origin, &mut seq.frames[old].origin);
        std::mem::swap(&mut self.svo, &mut seq.frames[index].svo);
        std::mem::swap(&mut self.origin, &mut seq.frames[index].origin);
        seq.shown = index;
        true
    }

    /// Moves a frame sequence's playhead to `time_secs` and shows the frame there; returns
    /// whether the shown frame changed. No effect on a still model or a non-finite time.
    pub fn set_frame_time(&mut self, time_secs: f32) -> bool {
        let Some(seq) = self.frames.as_mut() else {
            return false;
        };
        if !time_secs.is_finite() {
            return false;
        }
        seq.time_secs = time_secs;
        let index = seq.frame_at(time_secs);
        self.show_frame(index)
    }

    /// `object_from_voxel`: maps voxel coordinates (voxel `c` spans `[c, c+1)`) to object space.
    #[must_use]
    pub fn object_from_voxel(&self) -> Mat4 {
        Mat4::from_translation(self.origin) * Mat4::from_scale(Vec3::splat(self.voxel_size))
    }

    /// Object-space bounds as the model is shown: for a skinned model, posed by its rig's
    /// current playback state (see [`crate::skin::rig::posed_bounds`]), otherwise
    /// [`VoxelModel::bounds`].
    #[must_use]
    pub fn posed_bounds(&self) -> Option<(Vec3, Vec3)> {
        match &self.rig {
            Some(rig) => crate::skin::rig::posed_bounds(
                &self.svo,
                self.object_from_voxel(),
                &rig.current_skinning(),
            ),
            None => self.bounds(),
        }
    }

    /// Object-space bounds of the solid voxels (for a skinned model: in the bind pose).
    #[must_use]
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        self.svo.bounds().map(|(lo, hi)| {
            (
                self.origin + lo.as_vec3() * self.voxel_size,
                self.origin + (hi + 1).as_vec3() * self.voxel_size,
            )
        })
    }
}

/// A triangle mesh object (for example a ground plane or a prop).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct MeshObject {
    /// The mesh (stored in the `.bin` payload).
    #[serde(skip)]
    pub model: MeshModel,
    /// Whether it casts shadows.
    pub casts_shadows: bool,
}

/// What an object is.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type")]
#[allow(
    clippy::large_enum_variant,
    reason = "a handful of objects per document; boxing would only add indirection"
)]
pub enum ObjectKind {
    /// A sparse voxel octree model.
    Voxels(VoxelModel),
    /// A triangle mesh.
    Mesh(MeshObject),
    /// A kernel-reflection sequence (procedural: stored as parameters in the project JSON, no
    /// binary payload). Placed by the object's transform composed with the KRS's own
    /// `world_from_object`; the transform's scale must be uniform and positive.
    Krs(KrsObject),
}

impl Default for ObjectKind {
    fn default() -> Self {
        Self::Voxels(VoxelModel::default())
    }
}

/// One object in the scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Object {
    /// Stable id, unique in the document.
    pub id: u64,
    /// Display name.
    pub name: String,
    /// Hidden objects are neither rendered nor exported by default.
    pub visible: bool,
    /// `world_from_object`.
    pub transform: Transform,
    /// The payload.
    pub kind: ObjectKind,
    /// Keyed transforms (rigid per-object animation); `transform` is then the transform at
    /// the motion's clock ([`Document::apply_motion`]). Omitted from the JSON when `None`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub motion: Option<ObjectMotion>,
}

impl Default for Object {
    fn default() -> Self {
        Self {
            id: 0,
            name: String::new(),
            visible: true,
            transform: Transform::default(),
            kind: ObjectKind::default(),
            motion: None,
        }
    }
}

impl Object {
    /// The clock of the object's keyed transform: a rigged voxel model's rig playhead and
    /// wrap (one timeline moves the figure and its bones), else the motion's own playhead,
    /// else 0 s, looping.
    #[must_use]
    pub fn motion_clock(&self) -> (f32, crate::skin::Wrap) {
        if let ObjectKind::Voxels(VoxelModel { rig: Some(r), .. }) = &self.kind {
            return (r.playback.time_secs, r.playback.wrap);
        }
        self.motion
            .as_ref()
            .map_or((0.0, crate::skin::Wrap::Loop), |m| (m.time_secs, m.wrap))
    }

    /// A short word for the kind, for listings.
    #[must_use]
    pub fn kind_name(&self) -> &'static str {
        match self.kind {
            ObjectKind::Voxels(_) => "voxels",
            ObjectKind::Mesh(_) => "mesh",
            ObjectKind::Krs(_) => "krs",
        }
    }

    /// For a KRS object: its KRS with `world_from_object` composed with the object's transform,
    /// ready for [`crate::krs::KrsScene::prepare`]. `None` for other kinds, or when the transform
    /// is not a similarity (non-uniform or non-positive scale; [`Document::validate`] refuses
    /// those).
    #[must_use]
    pub fn krs_in_world(&self) -> Option<KrsObject> {
        let ObjectKind::Krs(k) = &self.kind else {
            return None;
        };
        let (placed, zone) = self.krs_placement(k)?;
        let mut out = k.clone();
        out.world_from_object = placed;
        // Empty zones are in the KRS's world; carry them along with the object.
        for z in &mut out.empty_zones {
            *z = zone(*z);
        }
        Some(out)
    }

    /// How this object's transform places the KRS `k`: the composed transform, and where an
    /// empty zone of `k` lands in the world. `None` unless the transform is a similarity.
    fn krs_placement(
        &self,
        k: &KrsObject,
    ) -> Option<(Similarity, impl Fn(EmptyZone) -> EmptyZone)> {
        let s = uniform_scale(self.transform.scale)?;
        let t = self.transform;
        let rotation = Quat::from_vec4(glam::Vec4::from(t.rotation).try_normalize()?);
        let inner = k.world_from_object;
        let placed = Similarity {
            translation: t.translation + rotation * (s * inner.translation),
            rotation: rotation * inner.rotation,
            scale: s * inner.scale,
        };
        let zone = move |z: EmptyZone| EmptyZone {
            centre: t.translation + rotation * (s * z.centre),
            radius: z.radius * s,
        };
        Some((placed, zone))
    }

    /// World-space bounds, if the object has any geometry.
    #[must_use]
    pub fn world_bounds(&self) -> Option<(Vec3, Vec3)> {
        let (lo, hi) = match &self.kind {
            ObjectKind::Voxels(v) => v.posed_bounds()?,
            ObjectKind::Mesh(m) => m.model.bounds()?,
            ObjectKind::Krs(_) => {
                // The bounding ball is already in world space once the transform is composed;
                // unbounded KRS (half-space kernels: terrain, ground) have no bounds.
                let k = self.krs_in_world()?;
                let (c, r) = crate::krs::KrsScene { objects: vec![k] }
                    .prepare()
                    .ok()?
                    .objects
                    .first()?
                    .bound_world?;
                return Some((c - Vec3::splat(r), c + Vec3::splat(r)));
            }
        };
        Some(transform_bounds(&self.transform.matrix(), lo, hi))
    }
}

/// The eight corners of the box `lo..hi`.
#[must_use]
pub fn box_corners(lo: Vec3, hi: Vec3) -> [Vec3; 8] {
    std::array::from_fn(|k| {
        Vec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        )
    })
}

/// The axis-aligned bounds of the box `lo..hi` moved by `m`.
#[must_use]
pub fn transform_bounds(m: &Mat4, lo: Vec3, hi: Vec3) -> (Vec3, Vec3) {
    box_corners(lo, hi)
        .map(|c| m.transform_point3(c))
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        })
}

/// Most lights a document may have. Thicket's lights are directional (suns): a handful light
/// any scene, while each one costs every shaded pixel a term (and, casting shadows, a shadow
/// map of up to 1 GiB at the largest `shadow_map_size`). A file can declare thousands for a
/// few bytes each (glTF `KHR_lights_punctual`, a project's JSON), so validation refuses more
/// than this instead of letting one small file make every frame thousands of passes long;
/// 256 is far above what a lit scene uses and small enough that shading stays bounded.
pub const MAX_LIGHTS: usize = 256;

/// A directional light (the sun).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Light {
    /// Display name.
    pub name: String,
    /// Direction the light travels (from the light toward the scene).
    pub direction: Vec3,
    /// Linear RGB colour.
    pub color: Vec3,
    /// Multiplier on `color`.
    pub intensity: f32,
    /// Whether it casts shadows.
    pub casts_shadows: bool,
}

impl Light {
    /// Checks what a renderer needs of a light: a finite, non-zero direction and a finite,
    /// non-negative colour and intensity.
    ///
    /// # Errors
    /// [`SceneError::Invalid`] naming the light.
    pub fn validate(&self) -> Result<(), SceneError> {
        let ctx = lazy_context(|f| write!(f, "light {:?}", self.name));
        if !self.direction.is_finite() || self.direction.length_squared() < 1e-12 {
            return Err(invalid("direction", &ctx, "must be finite and non-zero"));
        }
        if !self.color.is_finite()
            || self.color.min_element() < 0.0
            || !self.intensity.is_finite()
            || self.intensity < 0.0
        {
            return Err(invalid(
                "colour/intensity",
                &ctx,
                "must be finite and non-negative",
            ));
        }
        Ok(())
    }
}

impl Default for Light {
    fn default() -> Self {
        Self {
            name: "Sun".into(),
            direction: Vec3::new(-0.4, -1.0, -0.3),
            color: Vec3::ONE,
            intensity: 1.0,
            casts_shadows: true,
        }
    }
}

/// An orbit camera: looks at `target` from `distance` along yaw/pitch.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct OrbitCamera {
    /// Point orbited around.
    pub target: Vec3,
    /// Rotation about +Y in degrees (0 looks along -Z).
    pub yaw_deg: f32,
    /// Elevation in degrees (positive looks down on the target).
    pub pitch_deg: f32,
    /// Eye distance from the target.
    pub distance: f32,
    /// Vertical field of view in degrees.
    pub fov_y_deg: f32,
    /// Near clip distance.
    pub near: f32,
    /// Far clip distance.
    pub far: f32,
    /// Parallel projection (axis views, aligning voxels): the view is
    /// [`OrbitCamera::ortho_half_height`] × 2 units tall, the height a perspective view shows
    /// at the target, so switching keeps the framing and zooming (the distance) works alike.
    /// Near and far are then signed depths along the view axis and `near` may be negative.
    /// (Omitted from the JSON when off, so perspective documents save as before.)
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub orthographic: bool,
}

impl Default for OrbitCamera {
    fn default() -> Self {
        Self {
            target: Vec3::ZERO,
            yaw_deg: 30.0,
            pitch_deg: 20.0,
            distance: 5.0,
            fov_y_deg: 45.0,
            near: 0.05,
            far: 1000.0,
            orthographic: false,
        }
    }
}

impl OrbitCamera {
    /// Half the view height in world units of the orthographic projection:
    /// `distance · tan(fov_y / 2)`.
    #[must_use]
    pub fn ortho_half_height(&self) -> f32 {
        self.distance * (self.fov_y_deg.to_radians() * 0.5).tan()
    }

    /// The unit direction from a world point towards the eye: towards the eye position in
    /// perspective, the view axis's back direction in orthographic projection.
    #[must_use]
    pub fn toward_eye(&self, p: Vec3) -> Vec3 {
        if self.orthographic {
            (self.eye() - self.target).normalize_or_zero()
        } else {
            (self.eye() - p).normalize_or_zero()
        }
    }

    /// Eye position in world space.
    #[must_use]
    pub fn eye(&self) -> Vec3 {
        let (yaw, pitch) = (self.yaw_deg.to_radians(), self.pitch_deg.to_radians());
        let back = Vec3::new(
            yaw.sin() * pitch.cos(),
            pitch.sin(),
            yaw.cos() * pitch.cos(),
        );
        self.target + back * self.distance
    }

    /// `view_from_world` (right-handed, Y up, looking down -Z).
    #[must_use]
    pub fn view_from_world(&self) -> Mat4 {
        let up = if self.pitch_deg.abs() > 89.9 {
            Vec3::Z
        } else {
            Vec3::Y
        };
        Mat4::look_at_rh(self.eye(), self.target, up)
    }

    /// `clip_from_view` for an aspect ratio (width / height), depth 0..1 (wgpu convention).
    #[must_use]
    pub fn clip_from_view(&self, aspect: f32) -> Mat4 {
        if self.orthographic {
            let hh = self.ortho_half_height();
            let hw = hh * aspect;
            Mat4::orthographic_rh(-hw, hw, -hh, hh, self.near, self.far)
        } else {
            Mat4::perspective_rh(self.fov_y_deg.to_radians(), aspect, self.near, self.far)
        }
    }

    /// `clip_from_world`.
    #[must_use]
    pub fn clip_from_world(&self, aspect: f32) -> Mat4 {
        self.clip_from_view(aspect) * self.view_from_world()
    }

    /// Places the camera so a bounding box fills a square view, keeping yaw and pitch.
    pub fn frame(&mut self, lo: Vec3, hi: Vec3) {
        self.frame_in(lo, hi, 1.0);
    }

    /// Places the camera so a bounding box fills a view of `aspect` (width / height), keeping
    /// yaw and pitch: the box's bounding sphere fits the narrower of the two fields of view.
    pub fn frame_in(&mut self, lo: Vec3, hi: Vec3, aspect: f32) {
        self.frame_sphere((lo + hi) * 0.5, (hi - lo).length() * 0.5, aspect);
    }

    /// Places the camera so a sphere fills a view of `aspect` (width / height), keeping yaw
    /// and pitch: it fits the narrower of the two fields of view.
    pub fn frame_sphere(&mut self, center: Vec3, radius: f32, aspect: f32) {
        let radius = radius.max(1e-3);
        let half_y = self.fov_y_deg.to_radians() * 0.5;
        let aspect = if aspect.is_finite() && aspect > 0.0 {
            aspect
        } else {
            1.0
        };
        let half = half_y.min((half_y.tan() * aspect).atan());
        self.target = center;
        self.distance = radius / half.sin() * 1.05;
        self.near = (self.distance - radius * 1.5).max(self.distance * 1e-3);
        self.far = self.distance + radius * 4.0;
    }

    /// Sets the near and far planes around the box `lo..hi` as seen from the eye: far just past
    /// its farthest corner, near just before its nearest point (or, with the eye inside it, a
    /// small fraction of the far distance, so a camera close to a wall still draws the wall).
    /// The near / far ratio stays at most 10^5, within what a 24-bit or f32 depth resolves.
    /// An orthographic camera's planes enclose the whole box along the view axis (its depth
    /// is linear, so precision does not depend on where the planes lie).
    pub fn fit_clip(&mut self, lo: Vec3, hi: Vec3) {
        if !(lo.is_finite() && hi.is_finite()) || lo.cmpgt(hi).any() {
            return;
        }
        let eye = self.eye();
        let corners = box_corners(lo, hi).into_iter();
        if self.orthographic {
            // Signed depths along the view axis: the whole box between the planes, wherever
            // the eye is (a parallel view has no point of view to stand in front of).
            let forward = (self.target - eye).normalize_or_zero();
            let (d_lo, d_hi) = corners
                .map(|c| (c - eye).dot(forward))
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), d| {
                    (a.min(d), b.max(d))
                });
            let margin = 0.02 * (d_hi - d_lo) + 1e-3 * self.distance.max(1e-3);
            let (near, far) = (d_lo - margin, d_hi.max(self.distance) + margin);
            if near.is_finite() && far.is_finite() && far > near {
                self.near = near;
                self.far = far;
            }
            return;
        }
        let nearest = (eye.clamp(lo, hi) - eye).length();
        let farthest = corners.map(|c| (c - eye).length()).fold(0.0_f32, f32::max);
        let far = (farthest * 1.05).max(self.distance * 1.05).max(1e-3);
        let near = (nearest * 0.9).max(far * 1e-5);
        if near.is_finite() && far.is_finite() && far > near {
            self.near = near;
            self.far = far;
        }
    }

    /// Finite values, positive distances, a usable field of view.
    ///
    /// # Errors
    /// [`SceneError::Invalid`] naming the first bad field (`camera.far`, …) and its value.
    pub fn validate(&self) -> Result<(), SceneError> {
        self.check().map_err(|(field, detail)| SceneError::Invalid {
            what: format!("camera.{field}"),
            context: "document".to_owned(),
            detail,
        })
    }

    /// The first field a renderer cannot use, by name, and what is wrong with its value: the
    /// words [`OrbitCamera::validate`] and a command-line option's refusal share.
    ///
    /// # Errors
    /// `(field, detail)`, e.g. `("far", "inf must be finite and beyond near (0.001)")`.
    pub fn check(&self) -> Result<(), (&'static str, String)> {
        let finite = |field: &'static str, v: f32| {
            if v.is_finite() {
                Ok(())
            } else {
                Err((field, format!("{v} must be a finite number")))
            }
        };
        if !self.target.is_finite() {
            return Err(("target", format!("{} must be finite", self.target)));
        }
        finite("yaw_deg", self.yaw_deg)?;
        finite("pitch_deg", self.pitch_deg)?;
        if !(self.distance.is_finite() && self.distance > 0.0) {
            return Err((
                "distance",
                format!("{} must be finite and above 0", self.distance),
            ));
        }
        if !(self.fov_y_deg > 0.1 && self.fov_y_deg < 179.0) {
            return Err((
                "fov_y_deg",
                format!("{} must be between 0.1 and 179 degrees", self.fov_y_deg),
            ));
        }
        finite("near", self.near)?;
        if !self.orthographic && self.near <= 0.0 {
            return Err((
                "near",
                format!("{} must be above 0 for a perspective camera", self.near),
            ));
        }
        if !(self.far.is_finite() && self.far > self.near) {
            return Err((
                "far",
                format!(
                    "{} must be finite and beyond near ({})",
                    self.far, self.near
                ),
            ));
        }
        Ok(())
    }
}

/// The whole document.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Document {
    /// File format version ([`FORMAT_VERSION`] when written by this build).
    pub format_version: u32,
    /// Objects in outliner order.
    pub objects: Vec<Object>,
    /// Lights.
    pub lights: Vec<Light>,
    /// Linear RGB ambient light.
    pub ambient: Vec3,
    /// Linear RGB background colour.
    pub background: Vec3,
    /// The view camera.
    pub camera: OrbitCamera,
    /// Render quality.
    pub quality: Quality,
    /// Detail enhancement kept up to date by the editor: which voxel model is enhanced into
    /// which object, with what settings. (Omitted from the JSON when empty, so documents
    /// without it save as before and older files load.)
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub enhancements: Vec<EnhancementLink>,
    /// Tree-builder parameters of KRS objects built by the editor's tree builder, so reopening
    /// a tree keeps editing it from its parameters. (Omitted from the JSON when empty.)
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub tree_builders: Vec<TreeBuilderLink>,
    /// Forests grown from trees of the document ([`ForestLink`]), so they can be regrown.
    /// (Omitted from the JSON when empty.)
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub forests: Vec<ForestLink>,
}

/// A voxel model (`source`, the coarse one the artist edits) and the object that holds its
/// detail enhancement (`target`), with the settings that made it. A link naming an object that
/// no longer exists is ignored.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct EnhancementLink {
    /// Id of the coarse voxel model.
    pub source: u64,
    /// Id of the voxel model holding the enhancement.
    pub target: u64,
    /// The settings of the enhancement.
    pub settings: EnhanceSettings,
}

/// The tree-builder parameters a KRS object was last built from.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TreeBuilderLink {
    /// Id of the KRS object.
    pub object: u64,
    /// The parameters.
    pub params: crate::krs::TreeParams,
}

impl Default for Document {
    fn default() -> Self {
        Self {
            format_version: FORMAT_VERSION,
            objects: Vec::new(),
            lights: vec![Light::default()],
            ambient: Vec3::splat(0.25),
            background: Vec3::new(0.2, 0.22, 0.25),
            camera: OrbitCamera::default(),
            quality: Quality::default(),
            enhancements: Vec::new(),
            tree_builders: Vec::new(),
            forests: Vec::new(),
        }
    }
}

impl Document {
    /// Sets every animated object's transform to its motion at its clock: a rigged voxel
    /// model's rig playhead (and wrap), else the motion's own; `at_secs` overrides both (a
    /// render at a given time).
    pub fn apply_motion(&mut self, at_secs: Option<f32>) {
        for o in &mut self.objects {
            let (t, wrap) = o.motion_clock();
            let Some(m) = &o.motion else { continue };
            o.transform = m.transform_at(at_secs.unwrap_or(t), wrap, &o.transform);
        }
    }

    /// Adds an object with a fresh id; returns the id.
    pub fn add(&mut self, name: impl Into<String>, kind: ObjectKind) -> u64 {
        let id = self.objects.iter().map(|o| o.id).max().map_or(1, |m| m + 1);
        self.objects.push(Object {
            id,
            name: name.into(),
            kind,
            ..Object::default()
        });
        id
    }

    /// The enhancement link whose source is voxel model `id`.
    #[must_use]
    pub fn enhancement_of(&self, id: u64) -> Option<&EnhancementLink> {
        self.enhancements.iter().find(|l| l.source == id)
    }

    /// The enhancement link whose target is object `id`.
    #[must_use]
    pub fn enhancement_into(&self, id: u64) -> Option<&EnhancementLink> {
        self.enhancements.iter().find(|l| l.target == id)
    }

    /// The tree-builder parameters KRS object `id` was built from.
    #[must_use]
    pub fn tree_params_of(&self, id: u64) -> Option<&crate::krs::TreeParams> {
        self.tree_builders
            .iter()
            .find(|l| l.object == id)
            .map(|l| &l.params)
    }

    /// Looks an object up by name.
    #[must_use]
    pub fn object_by_name(&self, name: &str) -> Option<&Object> {
        self.objects.iter().find(|o| o.name == name)
    }

    /// World bounds of every visible object.
    #[must_use]
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        self.objects
            .iter()
            .filter(|o| o.visible)
            .filter_map(Object::world_bounds)
            .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
    }

    /// Checks every number a renderer will read.
    ///
    /// # Errors
    /// The first invalid value, naming the object or light.
    pub fn validate(&self) -> Result<(), SceneError> {
        for o in &self.objects {
            // The object's name is formatted only for an error: this runs on every load.
            validate_object(o).map_err(|e| match e {
                SceneError::Invalid { what, detail, .. } => SceneError::Invalid {
                    what,
                    context: format!("object {:?} (id {})", o.name, o.id),
                    detail,
                },
            })?;
        }
        if self.lights.len() > MAX_LIGHTS {
            return Err(invalid(
                "lights",
                "document",
                format!(
                    "{} lights, more than the {MAX_LIGHTS} a document may have; remove lights \
                     (a few suns light any scene)",
                    self.lights.len()
                ),
            ));
        }
        for l in &self.lights {
            l.validate()?;
        }
        if !self.ambient.is_finite() || !self.background.is_finite() {
            return Err(invalid("ambient/background", "document", "not finite"));
        }
        if self.ambient.min_element() < 0.0 {
            return Err(invalid(
                "ambient",
                "document",
                format!("{} must be non-negative (a light colour)", self.ambient),
            ));
        }
        self.camera.validate()?;
        self.quality
            .validate()
            .map_err(|e| invalid("quality", "document", e.to_string()))?;
        for l in &self.enhancements {
            let ctx = lazy_context(|f| write!(f, "enhancement of object id {}", l.source));
            if l.source == l.target {
                return Err(invalid(
                    "target",
                    &ctx,
                    "a model cannot hold its own enhancement",
                ));
            }
            l.settings
                .validate()
                .map_err(|e| invalid("settings", &ctx, e.to_string()))?;
        }
        for t in &self.tree_builders {
            t.params.validate().map_err(|e| {
                invalid(
                    "tree_builders",
                    format!("KRS object id {}", t.object),
                    e.to_string(),
                )
            })?;
        }
        for f in &self.forests {
            crate::krs::forest::check_params(&f.params, f.sources.len()).map_err(|e| {
                invalid(
                    "forests",
                    format!("the forest grown from object ids {:?}", f.sources),
                    e.to_string(),
                )
            })?;
        }
        if let Some(id) = repeated_id(&self.objects) {
            return Err(invalid(
                "id",
                "document",
                format!("object id {id} is used twice"),
            ));
        }
        Ok(())
    }
}

/// The smallest object id used twice, if any: pairwise for a few objects (no allocation: a
/// renderer validates its document every frame), sorted for many.
fn repeated_id(objects: &[Object]) -> Option<u64> {
    if objects.len() <= 64 {
        let mut repeated: Option<u64> = None;
        for (i, a) in objects.iter().enumerate() {
            if objects[i + 1..].iter().any(|b| b.id == a.id) {
                repeated = Some(repeated.map_or(a.id, |r| r.min(a.id)));
            }
        }
        return repeated;
    }
    let mut ids: Vec<u64> = objects.iter().map(|o| o.id).collect();
    ids.sort_unstable();
    ids.windows(2).find(|w| w[0] == w[1]).map(|w| w[0])
}

/// A frame sequence the renderers and exporters can trust: at least one frame, a positive
/// finite frame length, a finite playhead, the shown frame in range with an empty placeholder
/// in its slot, finite origins, and no rig (a skinned model animates by its clips).
fn validate_frames(v: &VoxelModel, f: &FrameSequence, ctx: &str) -> Result<(), SceneError> {
    if f.frames.is_empty() {
        return Err(invalid(
            "frames",
            ctx,
            "a frame sequence needs at least one frame",
        ));
    }
    if !(f.frame_secs.is_finite() && f.frame_secs > 0.0) {
        return Err(invalid(
            "frames.frame_secs",
            ctx,
            format!("{} must be a positive number of seconds", f.frame_secs),
        ));
    }
    if !f.time_secs.is_finite() {
        return Err(invalid("frames.time_secs", ctx, "not finite"));
    }
    if f.shown >= f.frames.len() {
        return Err(invalid(
            "frames.shown",
            ctx,
            format!("frame {} of {} does not exist", f.shown, f.frames.len()),
        ));
    }
    if !f.frames[f.shown].svo.is_empty() {
        return Err(invalid(
            "frames",
            ctx,
            "the shown frame's slot must be empty (its voxels are the model's own)",
        ));
    }
    if f.frames.iter().any(|fr| !fr.origin.is_finite()) {
        return Err(invalid("frames.origin", ctx, "not finite"));
    }
    if v.rig.is_some() {
        return Err(invalid(
            "frames",
            ctx,
            "a skinned model cannot also be a frame sequence",
        ));
    }
    Ok(())
}

/// The common scale of a uniform, positive per-axis scale (relative tolerance 1e-6).
fn uniform_scale(scale: Vec3) -> Option<f32> {
    let s = scale.x;
    let tol = 1e-6 * s.abs();
    (s.is_finite() && s > 0.0 && (scale.y - s).abs() <= tol && (scale.z - s).abs() <= tol)
        .then_some(s)
}

/// Checks one object's numbers; the error's context is filled in by [`Document::validate`].
fn validate_object(o: &Object) -> Result<(), SceneError> {
    let ctx = "the object";
    o.transform.validate(ctx)?;
    check_world_extent(o, ctx)?;
    if let Some(m) = &o.motion {
        m.validate().map_err(|e| invalid("motion", ctx, e))?;
    }
    match &o.kind {
        ObjectKind::Voxels(v) => {
            if !(v.voxel_size.is_finite() && v.voxel_size > 0.0) {
                return Err(invalid(
                    "voxel_size",
                    ctx,
                    format!("{} must be positive", v.voxel_size),
                ));
            }
            if !v.origin.is_finite() {
                return Err(invalid("origin", ctx, "not finite"));
            }
            if let Some(f) = &v.frames {
                validate_frames(v, f, ctx)?;
            }
            if let Some(rig) = &v.rig {
                rig.validate()
                    .map_err(|e| invalid("rig", ctx, e.to_string()))?;
                if !v.svo.has_skin() {
                    return Err(invalid(
                        "rig",
                        ctx,
                        "the model has a rig but its voxels carry no skin weights",
                    ));
                }
            }
        }
        ObjectKind::Mesh(m) => {
            m.model
                .validate()
                .map_err(|(part, e)| invalid("mesh", ctx, format!("part {part}: {e}")))?;
        }
        ObjectKind::Krs(k) => validate_krs(o, k, ctx)?,
    }
    Ok(())
}

fn validate_krs(o: &Object, k: &KrsObject, ctx: &str) -> Result<(), SceneError> {
    if uniform_scale(o.transform.scale).is_none() {
        return Err(invalid(
            "transform.scale",
            ctx,
            format!(
                "{} must be uniform and positive for a KRS object: distance estimates stay \
                 exact only under similarities (scale the KRS uniformly, or rebuild it)",
                o.transform.scale
            ),
        ));
    }
    if k.mirrors.len() > MAX_KRS_LEVELS {
        return Err(invalid(
            "krs.mirrors",
            ctx,
            format!(
                "{} mirrors exceed the limit of {MAX_KRS_LEVELS} reflection levels",
                k.mirrors.len()
            ),
        ));
    }
    check_texturing(&k.texturing, ctx)?;
    // Validate the KRS as the renderer will see it (transform composed), so a product of
    // scales that overflows is caught too. Placing moves only the transform and the empty
    // zones, so the kernels and mirrors are checked as they are, and nothing is copied: the
    // renderer validates its document every frame.
    check_krs_magnitudes(k, ctx)?;
    let checked = match o.krs_placement(k) {
        Some((placed, zone)) => k.check_placed(0, placed, zone),
        None => k.check_placed(0, k.world_from_object, |z| z),
    };
    checked.map_err(|e| {
        // The KRS error counts objects within a KRS scene; here the context names the object.
        let msg = e.to_string();
        let detail = msg
            .strip_prefix("KRS object 0")
            .map_or(msg.as_str(), |rest| {
                rest.trim_start_matches([',', ':', ' '])
            });
        invalid("krs", ctx, detail)
    })?;
    Ok(())
}

/// Largest coordinate or length a placed KRS may hold. The tracer squares differences of
/// positions and sums three of them (`length_squared`, dot products): with |x| ≤ 1e18 that is at
/// most 3 × (2e18)² ≈ 1.2e37, below `f32::MAX` (3.4e38), so no distance overflows to infinity.
/// The same bound as every other world coordinate ([`MAX_WORLD_COORDINATE`]).
pub const MAX_KRS_MAGNITUDE: f32 = MAX_WORLD_COORDINATE;

/// Largest coordinate any object may reach in the world: the bound the mesh and glTF readers
/// enforce on positions ([`crate::mesh::MAX_POSITION`]). Checking it here, where the project
/// loader and every editor command validate, means nothing valid exports a coordinate that a
/// reader (Thicket's or another's) refuses; the glTF writer checks its output against it too.
pub const MAX_WORLD_COORDINATE: f32 = crate::mesh::MAX_POSITION;

/// The object's reach within ±[`MAX_WORLD_COORDINATE`]: a voxel model's whole canvas (so any
/// voxel painted into it stays in range) and every frame's, a mesh's vertices, each moved by the
/// transform. O(1) for voxels, one pass over the vertices for a mesh (as its own validation).
fn check_world_extent(o: &Object, ctx: &str) -> Result<(), SceneError> {
    let m = o.transform.matrix();
    let fits = |(lo, hi): (Vec3, Vec3)| {
        let within = |v: Vec3| v.is_finite() && v.abs().max_element() <= MAX_WORLD_COORDINATE;
        within(lo) && within(hi)
    };
    let refuse = |what: &str, (lo, hi): (Vec3, Vec3)| {
        invalid(
            what,
            ctx,
            format!(
                "the object reaches {lo} to {hi} in the world, beyond ±{MAX_WORLD_COORDINATE:e} \
                 units, which glTF readers (Thicket's included) refuse and where squared \
                 distances overflow; move it nearer the origin or make it smaller"
            ),
        )
    };
    if !fits((o.transform.translation, o.transform.translation)) {
        let t = o.transform.translation;
        return Err(refuse("transform.translation", (t, t)));
    }
    match &o.kind {
        ObjectKind::Voxels(v) => {
            let canvas = |origin: Vec3, extent: u32| {
                let far = origin + Vec3::splat(extent as f32 * v.voxel_size);
                transform_bounds(&m, origin, far)
            };
            let own = canvas(v.origin, v.svo.extent());
            if !fits(own) {
                return Err(refuse("origin/voxel_size", own));
            }
            if let Some(f) = &v.frames {
                for fr in &f.frames {
                    let b = canvas(fr.origin, fr.svo.extent().max(v.svo.extent()));
                    if !fits(b) {
                        return Err(refuse("frames.origin", b));
                    }
                }
            }
        }
        ObjectKind::Mesh(mesh) => {
            if let Some((lo, hi)) = mesh.model.bounds() {
                let b = transform_bounds(&m, lo, hi);
                if !fits(b) {
                    return Err(refuse("transform", b));
                }
            }
        }
        // Checked after the transform by `check_krs_magnitudes`, kernel by kernel.
        ObjectKind::Krs(_) => {}
    }
    Ok(())
}

/// Every position and length of the placed KRS (kernels, mirror offsets) within
/// ±[`MAX_KRS_MAGNITUDE`].
fn check_krs_magnitudes(k: &KrsObject, ctx: &str) -> Result<(), SceneError> {
    use crate::krs::Kernel;
    let ok = |v: f32| v.abs() <= MAX_KRS_MAGNITUDE;
    let ok3 = |v: Vec3| v.abs().max_element() <= MAX_KRS_MAGNITUDE;
    for (i, kernel) in k.kernels.iter().enumerate() {
        let fine = match kernel {
            Kernel::Empty => true,
            Kernel::Sphere(s) => ok3(s.centre) && ok(s.radius),
            Kernel::InfinitePlane(p) => ok(p.offset),
            Kernel::Capsule(c) => ok3(c.start) && ok3(c.end) && ok(c.radius),
            Kernel::RoundedBox(b) => ok3(b.centre) && ok3(b.half_extents) && ok(b.rounding),
            Kernel::TorusSegment(t) | Kernel::ToroidalCapsule(t) => {
                ok3(t.centre) && ok(t.major_radius) && ok(t.minor_radius)
            }
        };
        if !fine {
            return Err(invalid(
                &format!("krs.kernels[{i}]"),
                ctx,
                format!(
                    "a position or radius (after the object's transform) exceeds \
                     {MAX_KRS_MAGNITUDE:e}; its square would overflow in the renderer"
                ),
            ));
        }
    }
    for (i, m) in k.mirrors.iter().enumerate() {
        if !ok(m.offset) {
            return Err(invalid(
                &format!("krs.mirrors[{i}].offset"),
                ctx,
                format!("{} exceeds {MAX_KRS_MAGNITUDE:e}", m.offset),
            ));
        }
    }
    Ok(())
}

/// Texturing values the shader can use without producing NaN: a finite pattern scale within
/// ±1e6 (positions times the scale stay finite), contrast in [0, 1], and a triplanar sharpness in
/// [0, 64] (|n|^64 of the largest normal component, ≥ 1/√3, stays above f32's normal range, so
/// the blend weights never all vanish).
fn check_texturing(t: &crate::krs::Texturing, ctx: &str) -> Result<(), SceneError> {
    let checks = [
        ("krs.texturing.scale", t.scale, -1e6, 1e6, "-1e6..=1e6"),
        ("krs.texturing.contrast", t.contrast, 0.0, 1.0, "0..=1"),
        ("krs.texturing.sharpness", t.sharpness, 0.0, 64.0, "0..=64"),
    ];
    for (what, v, lo, hi, range) in checks {
        if !(v.is_finite() && (lo..=hi).contains(&v)) {
            return Err(invalid(what, ctx, format!("{v} is outside {range}")));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A KRS rock beside the defaults, with `edit` applied to its KRS.
    fn krs_doc_with(edit: impl FnOnce(&mut KrsObject)) -> Document {
        let mut doc = Document::default();
        let mut k = crate::krs::presets::rock();
        edit(&mut k);
        doc.add("Rock", ObjectKind::Krs(k));
        doc
    }

    #[test]
    fn infinite_texturing_is_refused() {
        assert!(krs_doc_with(|_| {}).validate().is_ok());
        for (field, edit) in [
            (
                "scale",
                (|k: &mut KrsObject| k.texturing.scale = f32::INFINITY) as fn(&mut _),
            ),
            ("contrast", |k: &mut KrsObject| {
                k.texturing.contrast = f32::INFINITY;
            }),
            ("sharpness", |k: &mut KrsObject| {
                k.texturing.sharpness = f32::INFINITY;
            }),
        ] {
            let e = krs_doc_with(edit).validate().unwrap_err().to_string();
            assert!(
                e.contains(&format!("krs.texturing.{field}")) && e.contains("Rock"),
                "{e}"
            );
        }
    }

    #[test]
    fn kernel_radii_whose_squares_overflow_are_refused() {
        let e = krs_doc_with(|k| {
            for kernel in &mut k.kernels {
                if let crate::krs::Kernel::Sphere(s) = kernel {
                    s.radius = 3e38;
                }
                if let crate::krs::Kernel::Capsule(c) = kernel {
                    c.radius = 3e38;
                }
                if let crate::krs::Kernel::RoundedBox(b) = kernel {
                    b.rounding = 3e38;
                }
                if let crate::krs::Kernel::TorusSegment(t)
                | crate::krs::Kernel::ToroidalCapsule(t) = kernel
                {
                    t.minor_radius = 3e38;
                }
                if let crate::krs::Kernel::InfinitePlane(p) = kernel {
                    p.offset = 3e38;
                }
            }
        })
        .validate()
        .unwrap_err()
        .to_string();
        assert!(e.contains("krs.kernels[") && e.contains("overflow"), "{e}");
    }

    #[test]
    fn negative_light_colour_and_ambient_are_refused() {
        let mut doc = Document::default();
        doc.lights.push(Light {
            color: Vec3::new(1.0, -0.5, 1.0),
            ..Light::default()
        });
        let e = doc.validate().unwrap_err().to_string();
        assert!(e.contains("non-negative") && e.contains("light"), "{e}");
        let doc = Document {
            ambient: Vec3::new(-0.1, 0.2, 0.2),
            ..Document::default()
        };
        let e = doc.validate().unwrap_err().to_string();
        assert!(e.contains("ambient") && e.contains("non-negative"), "{e}");
    }

    #[test]
    fn more_lights_than_the_maximum_are_refused_in_one_line() {
        let mut doc = Document {
            lights: vec![Light::default(); MAX_LIGHTS],
            ..Document::default()
        };
        doc.validate().expect("the maximum itself is allowed");
        doc.lights.push(Light::default());
        let e = doc.validate().unwrap_err().to_string();
        assert_eq!(
            e,
            "lights of document is invalid: 257 lights, more than the 256 a document may have; \
             remove lights (a few suns light any scene)"
        );
    }

    #[test]
    fn an_invalid_camera_names_the_field_and_its_value() {
        let mut doc = Document::default();
        doc.camera.fov_y_deg = 500.0;
        let e = doc.validate().unwrap_err().to_string();
        assert_eq!(
            e,
            "camera.fov_y_deg of document is invalid: 500 must be between 0.1 and 179 degrees"
        );
        let mut doc = Document::default();
        doc.camera.far = f32::INFINITY;
        let e = doc.validate().unwrap_err().to_string();
        assert!(
            e.starts_with("camera.far of document is invalid: inf must be finite"),
            "{e}"
        );
        assert!(!e.contains('{') && !e.contains("OrbitCamera"), "{e}");
        doc.camera.far = 10.0;
        doc.camera.target.y = f32::NAN;
        let e = doc.validate().unwrap_err().to_string();
        assert!(
            e.starts_with("camera.target of document is invalid: ["),
            "{e}"
        );
        assert!(e.contains("NaN") && !e.contains("Vec3("), "{e}");
    }

    #[test]
    fn the_documented_minimum_epsilon_scale_is_accepted() {
        let mut doc = Document::default();
        doc.quality.krs_epsilon_scale = 0.01;
        doc.validate().expect("0.01 is the documented minimum");
        doc.quality.krs_over_relaxation = 1.95;
        doc.validate().expect("1.95 is the documented maximum");
        doc.quality.krs_epsilon_scale = 0.0099;
        assert!(doc.validate().is_err());
    }

    #[test]
    fn the_clip_range_follows_a_close_camera() {
        // The house-sized box seen from far, then from one unit in front of its wall.
        let (lo, hi) = (Vec3::splat(-32.0), Vec3::splat(32.0));
        let mut camera = OrbitCamera {
            distance: 200.0,
            near: 150.0,
            ..OrbitCamera::default()
        };
        camera.fit_clip(lo, hi);
        let eye = camera.eye();
        let nearest = (eye.clamp(lo, hi) - eye).length();
        assert!(
            camera.near <= nearest && camera.near > 0.5 * nearest,
            "{camera:?}"
        );
        assert!(camera.far >= (eye - lo).length().max((eye - hi).length()));
        // Target at the wall's centre, eye one unit outside it: the wall is in front of near.
        camera.target = Vec3::new(0.0, 0.0, 32.0);
        camera.yaw_deg = 0.0;
        camera.pitch_deg = 0.0;
        camera.distance = 1.0;
        camera.fit_clip(lo, hi);
        assert!(camera.near < 1.0 && camera.near > 0.0, "{camera:?}");
        assert!(camera.far > 64.0 && camera.far / camera.near <= 1.0e5 * 1.001);
        camera.validate().unwrap();
        // Inside the box: near is a small fraction of far, never zero.
        camera.target = Vec3::ZERO;
        camera.distance = 3.0;
        camera.fit_clip(lo, hi);
        assert!(camera.near > 0.0 && camera.near < 0.01, "{camera:?}");
        camera.validate().unwrap();
        // Bad boxes change nothing.
        let before = camera;
        camera.fit_clip(Vec3::NAN, hi);
        camera.fit_clip(hi, lo);
        assert_eq!(camera, before);
    }

    #[test]
    fn validation_names_the_bad_object() {
        let mut doc = Document::default();
        doc.add("Rock", ObjectKind::Voxels(VoxelModel::default()));
        doc.validate().unwrap();
        doc.objects[0].transform.translation.x = f32::NAN;
        let e = doc.validate().unwrap_err().to_string();
        assert!(e.contains("Rock") && e.contains("translation"), "{e}");
        doc.objects[0].transform = Transform {
            scale: Vec3::new(1.0, 0.0, 1.0),
            ..Transform::default()
        };
        assert!(doc.validate().unwrap_err().to_string().contains("scale"));
    }

    /// The readers' coordinate bound is the documents' bound: an object that reaches past
    /// ±1e18 in the world is refused however it gets there (translation, origin, voxel size,
    /// scale of a mesh, a frame's origin), and one just inside is accepted.
    #[test]
    fn objects_stay_within_the_coordinates_readers_accept() {
        let mut doc = Document::default();
        let svo = Svo::new(4, false).unwrap();
        doc.add(
            "Rock",
            ObjectKind::Voxels(VoxelModel {
                svo,
                ..VoxelModel::default()
            }),
        );
        // 16 voxels of 1e16 from 1e17: the canvas ends at 2.6e17, inside.
        if let ObjectKind::Voxels(v) = &mut doc.objects[0].kind {
            v.voxel_size = 1e16;
            v.origin = Vec3::splat(1e17);
        }
        doc.validate().unwrap();
        let refused = |doc: &Document, what: &str| {
            let e = doc.validate().unwrap_err().to_string();
            assert!(
                e.contains("Rock") && e.contains(what) && e.contains("beyond ±1e18"),
                "{e}"
            );
        };
        // A voxel size that carries the far corner of the canvas past the bound.
        if let ObjectKind::Voxels(v) = &mut doc.objects[0].kind {
            v.voxel_size = 1e17;
        }
        refused(&doc, "origin/voxel_size");
        if let ObjectKind::Voxels(v) = &mut doc.objects[0].kind {
            v.voxel_size = 1.0;
            v.origin = Vec3::new(0.0, -2e18, 0.0);
        }
        refused(&doc, "origin/voxel_size");
        if let ObjectKind::Voxels(v) = &mut doc.objects[0].kind {
            v.origin = Vec3::ZERO;
        }
        doc.objects[0].transform.translation = Vec3::new(0.0, 0.0, 1e19);
        refused(&doc, "translation");
        doc.objects[0].transform.translation = Vec3::ZERO;
        doc.objects[0].transform.scale = Vec3::splat(1e17);
        refused(&doc, "origin/voxel_size");

        // A mesh whose vertices are fine alone but not once scaled.
        let mut mesh = Document::default();
        let mut model = crate::mesh::MeshModel::default();
        model.parts.push(crate::mesh::TriangleMesh {
            positions: vec![Vec3::ZERO, Vec3::X * 1e4, Vec3::Y * 1e4],
            indices: vec![0, 1, 2],
            ..crate::mesh::TriangleMesh::default()
        });
        model.materials.push(crate::mesh::Material::default());
        mesh.add(
            "Rock",
            ObjectKind::Mesh(MeshObject {
                model,
                casts_shadows: true,
            }),
        );
        mesh.objects[0].transform.scale = Vec3::splat(1e13);
        mesh.validate().unwrap();
        mesh.objects[0].transform.scale = Vec3::splat(1e15);
        refused(&mesh, "transform");
    }

    #[test]
    fn camera_frames_a_box() {
        let mut cam = OrbitCamera::default();
        cam.frame(Vec3::splat(-1.0), Vec3::splat(1.0));
        let clip = cam.clip_from_world(1.0);
        for k in 0..8 {
            let c = Vec3::new(
                if k & 1 == 0 { -1.0 } else { 1.0 },
                if k & 2 == 0 { -1.0 } else { 1.0 },
                if k & 4 == 0 { -1.0 } else { 1.0 },
            );
            let p = clip.project_point3(c);
            assert!(
                p.x.abs() <= 1.0 && p.y.abs() <= 1.0 && (0.0..=1.0).contains(&p.z),
                "{p}"
            );
        }
    }

    #[test]
    fn krs_objects_validate_and_compose_their_transform() {
        let mut doc = Document::default();
        let id = doc.add("Tree", ObjectKind::Krs(crate::krs::presets::tree()));
        doc.validate().unwrap();
        let local = doc.objects[0].world_bounds().unwrap();
        let o = &mut doc.objects[0];
        assert_eq!(o.kind_name(), "krs");
        o.transform = Transform {
            translation: Vec3::new(5.0, 1.0, -2.0),
            rotation: Quat::from_rotation_y(1.1),
            scale: Vec3::splat(2.0),
        };
        doc.validate().unwrap();
        // The composed KRS is the original moved by the transform: distances scale by 2.
        let o = &doc.objects[0];
        let ObjectKind::Krs(k) = &o.kind else {
            unreachable!()
        };
        let world = crate::krs::KrsScene {
            objects: vec![o.krs_in_world().unwrap()],
        }
        .prepare()
        .unwrap();
        let plain = crate::krs::KrsScene {
            objects: vec![k.clone()],
        }
        .prepare()
        .unwrap();
        for p in [Vec3::new(0.3, 1.0, 0.2), Vec3::new(-1.0, 3.0, 0.5)] {
            let q = o.transform.matrix().transform_point3(p);
            let (a, b) = (world.distance(q), 2.0 * plain.distance(p));
            assert!((a - b).abs() < 1e-4 * b.abs().max(1.0), "{a} vs {b}");
        }
        let moved = o.world_bounds().unwrap();
        let size = |(lo, hi): (Vec3, Vec3)| (hi - lo).x;
        assert!(
            (size(moved) - 2.0 * size(local)).abs() < 1e-3,
            "{moved:?} {local:?}"
        );

        // Non-uniform scale, a zero mirror normal and too many levels are refused, naming the
        // object.
        doc.objects[0].transform.scale = Vec3::new(1.0, 1.0, 3.0);
        let e = doc.validate().unwrap_err().to_string();
        assert!(e.contains("Tree") && e.contains("uniform"), "{e}");
        doc.objects[0].transform.scale = Vec3::splat(-1.0);
        assert!(doc.validate().unwrap_err().to_string().contains("uniform"));
        doc.objects[0].transform = Transform::default();
        if let ObjectKind::Krs(k) = &mut doc.objects[0].kind {
            k.mirrors[2].normal = Vec3::ZERO;
        }
        let e = doc.validate().unwrap_err().to_string();
        assert!(
            e.contains("Tree") && e.contains("mirror 2") && e.contains("zero length"),
            "{e}"
        );
        if let ObjectKind::Krs(k) = &mut doc.objects[0].kind {
            k.mirrors = vec![crate::krs::MirrorPlane::default(); MAX_KRS_LEVELS + 1];
            k.kernels = vec![crate::krs::Kernel::Empty; MAX_KRS_LEVELS + 2];
        }
        let e = doc.validate().unwrap_err().to_string();
        assert!(e.contains("limit"), "{e}");
        assert_eq!(doc.objects[0].id, id);
    }

    #[test]
    fn old_files_with_missing_fields_load() {
        let doc: Document = serde_json::from_str(
            r#"{"format_version":1,"objects":[{"name":"a","kind":{"type":"Voxels"}}]}"#,
        )
        .unwrap();
        assert_eq!(doc.objects[0].name, "a");
        assert!(doc.objects[0].visible);
        assert_eq!(doc.quality, Quality::default());
    }
}
