//! Rigging voxel models made in Thicket: skeleton authoring in the rest pose (joints placed
//! at the middle of the model's thickness, chains, branches, mirrored chains, templates fitted
//! to the model), binding (automatic weights, see `thicket_core::skin::bind`), weight painting
//! and clip management. Every change is one undo step.

use glam::Vec3;
use thicket_core::scene::{ObjectKind, VoxelModel};
use thicket_core::skin::author::clips_by_name;
use thicket_core::skin::bind::{BindControl, BindMethod, BindReport, bind};
use thicket_core::skin::rig::Binding;
use thicket_core::skin::{AnimationClip, JointSpec, Rig, Skeleton, SkeletonSpec, Skin4};
use thicket_core::svo::Voxel;

use super::{CommandError, Edit, Editor, MergeKey};

/// A starting skeleton fitted to a model's bounds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SkeletonTemplate {
    /// Hip, spine, neck, head; arms and legs as `.L` / `.R` chains (the model faces -Z, its
    /// left is +X as in glTF).
    Biped,
    /// Hip and chest along Z, neck and head in front, four legs, a tail.
    Quadruped,
    /// A single chain of five joints along the model's longest axis (a tail, a tentacle).
    Chain,
}

impl SkeletonTemplate {
    /// Every template, for menus.
    pub const ALL: [Self; 3] = [Self::Biped, Self::Quadruped, Self::Chain];

    /// The menu label.
    #[must_use]
    pub fn label(self) -> &'static str {
        match self {
            Self::Biped => "Biped",
            Self::Quadruped => "Quadruped",
            Self::Chain => "Chain",
        }
    }

    /// The template's joints for a model whose own-space bounds are `lo..hi`.
    #[must_use]
    pub fn fit(self, lo: Vec3, hi: Vec3) -> SkeletonSpec {
        let size = hi - lo;
        // `at(x, y, z)`: fractions of the bounds.
        let at = |x: f32, y: f32, z: f32| (lo + size * Vec3::new(x, y, z)).to_array();
        let j = |name: &str, parent: Option<&str>, p: [f32; 3]| JointSpec {
            name: name.into(),
            parent: parent.map(Into::into),
            position: p,
        };
        let joints = match self {
            Self::Biped => vec![
                j("hip", None, at(0.5, 0.5, 0.5)),
                j("spine", Some("hip"), at(0.5, 0.65, 0.5)),
                j("neck", Some("spine"), at(0.5, 0.8, 0.5)),
                j("head", Some("neck"), at(0.5, 0.9, 0.5)),
                j("arm.L", Some("spine"), at(0.7, 0.78, 0.5)),
                j("forearm.L", Some("arm.L"), at(0.85, 0.62, 0.5)),
                j("hand.L", Some("forearm.L"), at(0.95, 0.48, 0.5)),
                j("arm.R", Some("spine"), at(0.3, 0.78, 0.5)),
                j("forearm.R", Some("arm.R"), at(0.15, 0.62, 0.5)),
                j("hand.R", Some("forearm.R"), at(0.05, 0.48, 0.5)),
                j("leg.L", Some("hip"), at(0.6, 0.45, 0.5)),
                j("shin.L", Some("leg.L"), at(0.6, 0.22, 0.5)),
                j("foot.L", Some("shin.L"), at(0.6, 0.03, 0.5)),
                j("leg.R", Some("hip"), at(0.4, 0.45, 0.5)),
                j("shin.R", Some("leg.R"), at(0.4, 0.22, 0.5)),
                j("foot.R", Some("shin.R"), at(0.4, 0.03, 0.5)),
            ],
            Self::Quadruped => vec![
                j("hip", None, at(0.5, 0.6, 0.75)),
                j("chest", Some("hip"), at(0.5, 0.6, 0.3)),
                j("neck", Some("chest"), at(0.5, 0.75, 0.15)),
                j("head", Some("neck"), at(0.5, 0.85, 0.03)),
                j("tail", Some("hip"), at(0.5, 0.65, 0.9)),
                j("tail.end", Some("tail"), at(0.5, 0.7, 1.0)),
                j("front_leg.L", Some("chest"), at(0.75, 0.45, 0.3)),
                j("front_shin.L", Some("front_leg.L"), at(0.75, 0.2, 0.3)),
                j("front_foot.L", Some("front_shin.L"), at(0.75, 0.03, 0.3)),
                j("front_leg.R", Some("chest"), at(0.25, 0.45, 0.3)),
                j("front_shin.R", Some("front_leg.R"), at(0.25, 0.2, 0.3)),
                j("front_foot.R", Some("front_shin.R"), at(0.25, 0.03, 0.3)),
                j("back_leg.L", Some("hip"), at(0.75, 0.45, 0.75)),
                j("back_shin.L", Some("back_leg.L"), at(0.75, 0.2, 0.75)),
                j("back_foot.L", Some("back_shin.L"), at(0.75, 0.03, 0.75)),
                j("back_leg.R", Some("hip"), at(0.25, 0.45, 0.75)),
                j("back_shin.R", Some("back_leg.R"), at(0.25, 0.2, 0.75)),
                j("back_foot.R", Some("back_shin.R"), at(0.25, 0.03, 0.75)),
            ],
            Self::Chain => {
                let axis = if size.x >= size.y && size.x >= size.z {
                    0
                } else if size.y >= size.z {
                    1
                } else {
                    2
                };
                (0..5)
                    .map(|k| {
                        let mut f = [0.5f32; 3];
                        f[axis] = 0.05 + 0.9 * k as f32 / 4.0;
                        let name = format!("chain.{k:03}");
                        let parent = (k > 0).then(|| format!("chain.{:03}", k - 1));
                        JointSpec {
                            name,
                            parent,
                            position: at(f[0], f[1], f[2]),
                        }
                    })
                    .collect()
            }
        };
        SkeletonSpec { joints }
    }
}

/// Name for a mirrored joint: `.L` ↔ `.R` (also `_L`/`_R`, `Left`/`Right`); `None` when the
/// name has no side.
#[must_use]
fn mirrored_name(name: &str) -> Option<String> {
    for (a, b) in [(".L", ".R"), ("_L", "_R"), ("Left", "Right")] {
        if let Some(stem) = name.strip_suffix(a) {
            return Some(format!("{stem}{b}"));
        }
        if let Some(stem) = name.strip_suffix(b) {
            return Some(format!("{stem}{a}"));
        }
    }
    None
}

/// `base` if `taken` says it is free, else the first free of `base.001`, `base.002`, … (as
/// Blender names copies).
fn unique_name(base: &str, taken: impl Fn(&str) -> bool) -> String {
    if !taken(base) {
        return base.to_owned();
    }
    (1..)
        .map(|k| format!("{base}.{k:03}"))
        .find(|n| !taken(n))
        .unwrap_or_else(|| base.to_owned())
}

/// What to do with the weights when the skeleton changes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WeightsOnEdit {
    /// Keep every voxel's weights on the joints of the same name (a removed joint's weight
    /// goes to its nearest surviving ancestor); the panel then offers to bind again.
    Keep,
    /// Compute the weights again with this method.
    Rebind(BindMethod),
}

impl Editor {
    fn voxel_model(&self, id: u64) -> Result<&VoxelModel, CommandError> {
        let o = self.object(id).ok_or(CommandError::NoObject(id))?;
        match &o.kind {
            ObjectKind::Voxels(v) => Ok(v),
            _ => Err(CommandError::Invalid(format!(
                "{:?} is a {}: only voxel models can be rigged",
                o.name,
                o.kind_name()
            ))),
        }
    }

    /// The skeleton of voxel model `id` as joint positions in its own space (empty when it has
    /// none).
    ///
    /// # Errors
    /// No such object, or not a voxel model.
    pub fn skeleton_spec(&self, id: u64) -> Result<SkeletonSpec, CommandError> {
        Ok(self
            .voxel_model(id)?
            .rig
            .as_ref()
            .map(|r| SkeletonSpec::of_skeleton(&r.skeleton))
            .unwrap_or_default())
    }

    /// Gives voxel model `id` the skeleton `spec` (one undo step, merged while `merge` is set
    /// and the same drag goes on). Clips, pose overrides and stretch settings follow the joints
    /// by name. An empty spec removes the rig.
    ///
    /// # Errors
    /// No such model, or a spec [`SkeletonSpec::to_skeleton`] refuses (the reason names the
    /// joint); a binding failure.
    pub fn set_skeleton(
        &mut self,
        id: u64,
        spec: &SkeletonSpec,
        weights: WeightsOnEdit,
        merge: Option<MergeKey>,
    ) -> Result<Option<BindReport>, CommandError> {
        self.set_skeleton_renaming(id, spec, weights, merge, &[])
    }

    /// [`Editor::set_skeleton`] where joints `old → new` of `renames` are renamed, not replaced:
    /// their weights, keys and overrides go with them.
    fn set_skeleton_renaming(
        &mut self,
        id: u64,
        spec: &SkeletonSpec,
        weights: WeightsOnEdit,
        merge: Option<MergeKey>,
        renames: &[(String, String)],
    ) -> Result<Option<BindReport>, CommandError> {
        let model = self.voxel_model(id)?;
        if spec.joints.is_empty() {
            if model.rig.is_none() {
                return Ok(None);
            }
            let mut plain = model.clone();
            plain.rig = None;
            plain.svo = strip_skin(&model.svo)?;
            self.apply(
                Edit::SetVoxelModel {
                    id,
                    model: Box::new(plain),
                },
                None,
            );
            return Ok(None);
        }
        if let Some(old) = &model.rig
            && !has_native_frames(&old.skeleton)
        {
            return Err(CommandError::Invalid(
                "this skeleton came with the imported file and its joints have rotated or \
                 scaled frames that its clips are written against: rename its joints here, or \
                 edit the skeleton in the tool it came from (or delete every joint to start \
                 a skeleton of Thicket's own)"
                    .into(),
            ));
        }
        let skeleton = spec
            .to_skeleton(model.bounds())
            .map_err(|e| CommandError::Invalid(e.to_string()))?;
        let mut old_rig = model.rig.clone();
        if let Some(r) = &mut old_rig {
            for (from, to) in renames {
                rename_in_rig(r, from, to);
            }
        }
        let rig = rig_for(old_rig.as_ref(), skeleton);
        match weights {
            WeightsOnEdit::Rebind(method) => {
                let (svo, report) = bind(
                    &model.svo,
                    model.origin,
                    model.voxel_size,
                    &rig.skeleton,
                    method,
                    BindControl::default(),
                )
                .map_err(|e| CommandError::Invalid(e.to_string()))?;
                let mut next = model.clone();
                next.svo = svo;
                next.rig = Some(bound_rig(rig, method));
                self.apply(
                    Edit::SetVoxelModel {
                        id,
                        model: Box::new(next),
                    },
                    None,
                );
                Ok(Some(report))
            }
            WeightsOnEdit::Keep => {
                let old = old_rig.as_ref().map(|r| &r.skeleton);
                let remap = old.map(|old| joint_remap(old, &rig.skeleton));
                let identity = remap
                    .as_ref()
                    .is_none_or(|m| m.iter().enumerate().all(|(i, &j)| i == usize::from(j)));
                let skinned = model.svo.has_skin();
                if !skinned {
                    // A model's first skeleton: its voxels get (empty) weights, which draw as
                    // bound to the root until the model is bound.
                    let mut next = model.clone();
                    next.svo = map_voxels(&model.svo, true, |_| Skin4::default())?;
                    next.rig = Some(rig);
                    self.apply(
                        Edit::SetVoxelModel {
                            id,
                            model: Box::new(next),
                        },
                        None,
                    );
                } else if identity {
                    self.apply(
                        Edit::SetRig {
                            id,
                            rig: Some(Box::new(rig)),
                        },
                        merge,
                    );
                } else {
                    let mut next = model.clone();
                    next.svo = match &remap {
                        Some(m) => remap_skin(&model.svo, m)?,
                        None => model.svo.clone(),
                    };
                    next.rig = Some(rig);
                    self.apply(
                        Edit::SetVoxelModel {
                            id,
                            model: Box::new(next),
                        },
                        None,
                    );
                }
                Ok(None)
            }
        }
    }

    /// Adds a joint at `position` (the model's own space) under `parent` (a root when `None`)
    /// and returns its index. The name is `name`, made unique, or "root" / "bone.NNN".
    ///
    /// # Errors
    /// See [`Editor::set_skeleton`].
    pub fn add_joint(
        &mut self,
        id: u64,
        parent: Option<usize>,
        position: Vec3,
        name: Option<&str>,
    ) -> Result<usize, CommandError> {
        let mut spec = self.skeleton_spec(id)?;
        let parent_name = match parent {
            Some(p) => Some(
                spec.joints
                    .get(p)
                    .ok_or_else(|| CommandError::Invalid(format!("no joint {p}")))?
                    .name
                    .clone(),
            ),
            None => None,
        };
        let base = name.unwrap_or(if spec.joints.is_empty() {
            "root"
        } else {
            "bone"
        });
        let name = unique_name(base, |n| spec.joints.iter().any(|j| j.name == n));
        spec.joints.push(JointSpec {
            name: name.clone(),
            parent: parent_name,
            position: position.to_array(),
        });
        self.set_skeleton_finding(id, &spec, &name, &[])
    }

    /// Moves joint `joint` to `position` in the rest pose (the model's own space); a drag
    /// merges into one undo step.
    ///
    /// # Errors
    /// See [`Editor::set_skeleton`].
    pub fn move_joint(
        &mut self,
        id: u64,
        joint: usize,
        position: Vec3,
    ) -> Result<(), CommandError> {
        let mut spec = self.skeleton_spec(id)?;
        let j = spec
            .joints
            .get_mut(joint)
            .ok_or_else(|| CommandError::Invalid(format!("no joint {joint}")))?;
        j.position = position.to_array();
        self.set_skeleton(id, &spec, WeightsOnEdit::Keep, Some(MergeKey::Rig(id)))
            .map(|_| ())
    }

    /// Renames joint `joint` (children, clips and weights follow).
    ///
    /// # Errors
    /// An empty or taken name; see [`Editor::set_skeleton`].
    pub fn rename_joint(&mut self, id: u64, joint: usize, name: &str) -> Result<(), CommandError> {
        let rig = self.rig_or_err(id)?;
        let name = name.trim();
        let old = rig
            .skeleton
            .joints
            .get(joint)
            .ok_or_else(|| CommandError::Invalid(format!("no joint {joint}")))?
            .name
            .clone();
        if old == name {
            return Ok(());
        }
        if name.is_empty() {
            return Err(CommandError::Invalid("a joint needs a name".into()));
        }
        if rig.skeleton.find(name).is_some() {
            return Err(CommandError::Invalid(format!(
                "joint {name:?} is named twice: choose another name"
            )));
        }
        // Only the name changes: joint frames (an imported rig's rotated ones too), weights,
        // keys and overrides stay as they are.
        let mut rig = rig.clone();
        rename_in_rig(&mut rig, &old, name);
        self.apply(
            Edit::SetRig {
                id,
                rig: Some(Box::new(rig)),
            },
            None,
        );
        Ok(())
    }

    /// Makes `parent` (or no joint) the parent of `joint`; returns the joint's new index.
    ///
    /// # Errors
    /// A cycle (a joint under its own descendant); see [`Editor::set_skeleton`].
    pub fn reparent_joint(
        &mut self,
        id: u64,
        joint: usize,
        parent: Option<usize>,
    ) -> Result<usize, CommandError> {
        let mut spec = self.skeleton_spec(id)?;
        if joint >= spec.joints.len() || parent.is_some_and(|p| p >= spec.joints.len()) {
            return Err(CommandError::Invalid(format!("no joint {joint}")));
        }
        spec.joints[joint].parent = parent.map(|p| spec.joints[p].name.clone());
        let name = spec.joints[joint].name.clone();
        // Parents come first: moving a joint under a later one changes its index.
        self.set_skeleton_finding(id, &spec, &name, &[])
    }

    /// Deletes joint `joint`; its children move up to its parent and its voxels' weight goes
    /// to its parent (deleting the last joint removes the rig).
    ///
    /// # Errors
    /// See [`Editor::set_skeleton`].
    pub fn delete_joint(&mut self, id: u64, joint: usize) -> Result<(), CommandError> {
        let mut spec = self.skeleton_spec(id)?;
        if joint >= spec.joints.len() {
            return Err(CommandError::Invalid(format!("no joint {joint}")));
        }
        let removed = spec.joints.remove(joint);
        for j in &mut spec.joints {
            if j.parent.as_deref() == Some(removed.name.as_str()) {
                j.parent.clone_from(&removed.parent);
            }
        }
        self.set_skeleton(id, &spec, WeightsOnEdit::Keep, None)
            .map(|_| ())
    }

    /// Mirrors joint `joint` and the chain below it across the model's centre in X, naming the
    /// copies `.R` for `.L` (and back; a name without a side gets `.L`, its copy `.R`). The
    /// copy hangs from the mirror of the chain's parent when there is one, else the same
    /// parent. Returns the copy of `joint`.
    ///
    /// # Errors
    /// A copy whose name is taken; see [`Editor::set_skeleton`].
    pub fn mirror_chain(&mut self, id: u64, joint: usize) -> Result<usize, CommandError> {
        let model = self.voxel_model(id)?;
        let (lo, hi) = model
            .bounds()
            .ok_or_else(|| CommandError::Invalid("the model has no voxels".into()))?;
        let centre_x = 0.5 * (lo.x + hi.x);
        let mut spec = self.skeleton_spec(id)?;
        if joint >= spec.joints.len() {
            return Err(CommandError::Invalid(format!("no joint {joint}")));
        }
        let chain = spec.subtree(joint);
        // Names without a side get one first (renamed: their weights and keys go with them).
        let mut renames = Vec::new();
        for &c in &chain {
            if mirrored_name(&spec.joints[c].name).is_none() {
                let named = format!("{}.L", spec.joints[c].name);
                let old = std::mem::replace(&mut spec.joints[c].name, named.clone());
                for j in &mut spec.joints {
                    if j.parent.as_deref() == Some(old.as_str()) {
                        j.parent = Some(named.clone());
                    }
                }
                renames.push((old, named));
            }
        }
        let mut copies = Vec::new();
        for &c in &chain {
            let src = &spec.joints[c];
            let name = mirrored_name(&src.name).unwrap_or_else(|| format!("{}.R", src.name));
            if spec.joints.iter().any(|j| j.name == name) {
                return Err(CommandError::Invalid(format!(
                    "joint {name:?} exists already: delete or rename it to mirror {:?}",
                    src.name
                )));
            }
            let parent = src.parent.as_ref().map(|p| {
                let m = mirrored_name(p);
                match m {
                    Some(m) if spec.joints.iter().any(|j| j.name == m) => m,
                    Some(m) if chain.iter().any(|&k| spec.joints[k].name == *p) => m,
                    _ => p.clone(),
                }
            });
            let [x, y, z] = src.position;
            copies.push(JointSpec {
                name,
                parent,
                position: [2.0 * centre_x - x, y, z],
            });
        }
        let first = copies[0].name.clone();
        spec.joints.extend(copies);
        self.set_skeleton_finding(id, &spec, &first, &renames)
    }

    /// Sets the skeleton (keeping the weights, joints `renames` renamed) and returns the index
    /// of joint `name` in it.
    fn set_skeleton_finding(
        &mut self,
        id: u64,
        spec: &SkeletonSpec,
        name: &str,
        renames: &[(String, String)],
    ) -> Result<usize, CommandError> {
        self.set_skeleton_renaming(id, spec, WeightsOnEdit::Keep, None, renames)?;
        self.rig(id)
            .and_then(|r| r.skeleton.find(name))
            .ok_or_else(|| CommandError::Invalid(format!("joint {name:?} was not added")))
    }

    /// Replaces the skeleton of model `id` with `template` fitted to its bounds.
    ///
    /// # Errors
    /// An empty model; see [`Editor::set_skeleton`].
    pub fn apply_skeleton_template(
        &mut self,
        id: u64,
        template: SkeletonTemplate,
    ) -> Result<(), CommandError> {
        let (lo, hi) = self
            .voxel_model(id)?
            .bounds()
            .ok_or_else(|| CommandError::Invalid("the model has no voxels to fit".into()))?;
        self.set_skeleton(id, &template.fit(lo, hi), WeightsOnEdit::Keep, None)
            .map(|_| ())
    }

    /// Binds model `id` to its skeleton now (one undo step); for large models the UI runs
    /// [`bind_job`] on a worker and calls [`Editor::finish_bind`].
    ///
    /// # Errors
    /// No skeleton; a binding failure.
    pub fn bind_now(&mut self, id: u64, method: BindMethod) -> Result<BindReport, CommandError> {
        let model = self.voxel_model(id)?.clone();
        let bound = bind_job(&model, method, BindControl::default())?;
        self.finish_bind(id, &model, bound)
    }

    /// Applies a finished binding of `source` (the model as it was when the binding started)
    /// to object `id`, when the model has not changed meanwhile.
    ///
    /// # Errors
    /// The model changed while binding ran (bind again).
    pub fn finish_bind(
        &mut self,
        id: u64,
        source: &VoxelModel,
        bound: (thicket_core::svo::Svo, BindReport, BindMethod),
    ) -> Result<BindReport, CommandError> {
        let model = self.voxel_model(id)?;
        if model.svo != source.svo
            || model.rig.as_ref().map(|r| &r.skeleton) != source.rig.as_ref().map(|r| &r.skeleton)
        {
            return Err(CommandError::Invalid(
                "the model or its skeleton changed while binding ran: bind again".into(),
            ));
        }
        let (svo, report, method) = bound;
        let mut next = model.clone();
        next.svo = svo;
        next.rig = next.rig.take().map(|r| bound_rig(r, method));
        self.apply(
            Edit::SetVoxelModel {
                id,
                model: Box::new(next),
            },
            None,
        );
        Ok(report)
    }

    /// The point at the middle of the model's thickness under a ray (world space): halfway
    /// between where the ray enters the first run of solid voxels and where it leaves it, in
    /// the model's own space. `None` when the ray misses the model.
    #[must_use]
    pub fn mid_thickness(&self, id: u64, origin: Vec3, dir: Vec3) -> Option<Vec3> {
        let o = self.object(id)?;
        let ObjectKind::Voxels(v) = &o.kind else {
            return None;
        };
        let object_from_world = o.transform.matrix().inverse();
        let voxel_from_object = v.object_from_voxel().inverse();
        let m = voxel_from_object * object_from_world;
        let ro = m.transform_point3(origin);
        let rd = m.transform_vector3(dir);
        let (enter, leave) = solid_run(&v.svo, ro, rd)?;
        let mid = ro + rd * (0.5 * (enter + leave));
        Some(v.object_from_voxel().transform_point3(mid))
    }

    /// Paints the weight of `joint` on the voxels of rigged model `id` within `radius` voxels
    /// of `centre` (voxel space): `amount` in -1..=1 moves each voxel's weight toward 1
    /// (positive) or 0 (negative) by that fraction with a smooth falloff, the other joints
    /// renormalised; `smooth` averages with the neighbours instead. One undo step per stroke
    /// (dabs merge). Returns the voxels changed.
    ///
    /// # Errors
    /// No rig, or a joint out of range.
    pub fn paint_weights(
        &mut self,
        id: u64,
        joint: usize,
        centre: Vec3,
        radius: f32,
        amount: f32,
        smooth: bool,
    ) -> Result<usize, CommandError> {
        let model = self.voxel_model(id)?;
        let rig = model
            .rig
            .as_ref()
            .ok_or_else(|| CommandError::Invalid("weights need a skeleton: add joints".into()))?;
        if joint >= rig.skeleton.len() || !model.svo.has_skin() {
            return Err(CommandError::Invalid(
                "bind the model before painting weights".into(),
            ));
        }
        let outcome = self.write_voxels(id, Some(MergeKey::Stroke(id)), |svo, _| {
            let changes =
                thicket_core::skin::paint::weight_dab(svo, joint, centre, radius, amount, smooth);
            let r = svo
                .apply_changes(changes)
                .map_err(|e| CommandError::Invalid(e.to_string()))?;
            Ok(thicket_core::sculpt::ToolEdit {
                changed: r.changed,
                delta: r.delta,
                clipped: 0,
                refused: None,
            })
        })?;
        Ok(outcome.voxels)
    }

    /// The clip names of rigged model `id`.
    #[must_use]
    pub fn clip_names(&self, id: u64) -> Vec<String> {
        self.rig(id)
            .map(|r| r.clips.iter().map(|c| c.name.clone()).collect())
            .unwrap_or_default()
    }

    /// Renames clip `clip` of rigged model `id` (one undo step).
    ///
    /// # Errors
    /// No rig or clip; an empty name or one another clip has.
    pub fn rename_clip(&mut self, id: u64, clip: usize, name: &str) -> Result<(), CommandError> {
        let mut clips = self.rig_or_err(id)?.clips.clone();
        let name = name.trim();
        if name.is_empty() {
            return Err(CommandError::Invalid("a clip needs a name".into()));
        }
        if clips
            .iter()
            .enumerate()
            .any(|(i, c)| i != clip && c.name == name)
        {
            return Err(CommandError::Invalid(format!(
                "a clip is named {name:?} already"
            )));
        }
        let c = clips
            .get_mut(clip)
            .ok_or_else(|| CommandError::Invalid(format!("no clip {clip}")))?;
        if c.name == name {
            return Ok(());
        }
        c.name = name.to_owned();
        self.apply(Edit::SetClips { id, clips }, None);
        Ok(())
    }

    /// Copies clip `clip` as "NAME.copy" (made unique) after the last clip; returns its index.
    ///
    /// # Errors
    /// No rig or clip.
    pub fn duplicate_clip(&mut self, id: u64, clip: usize) -> Result<usize, CommandError> {
        let mut clips = self.rig_or_err(id)?.clips.clone();
        let mut copy = clips
            .get(clip)
            .cloned()
            .ok_or_else(|| CommandError::Invalid(format!("no clip {clip}")))?;
        copy.name = unique_name(&format!("{}.copy", copy.name), |n| {
            clips.iter().any(|c| c.name == n)
        });
        clips.push(copy);
        let index = clips.len() - 1;
        self.apply(Edit::SetClips { id, clips }, None);
        Ok(index)
    }

    /// Deletes clip `clip` (one undo step); the playhead moves to the rest pose when it played.
    ///
    /// # Errors
    /// No rig or clip.
    pub fn delete_clip(&mut self, id: u64, clip: usize) -> Result<(), CommandError> {
        let rig = self.rig_or_err(id)?;
        if clip >= rig.clips.len() {
            return Err(CommandError::Invalid(format!("no clip {clip}")));
        }
        let mut playback = rig.playback;
        let mut clips = rig.clips.clone();
        clips.remove(clip);
        playback.clip = match playback.clip {
            Some(c) if c == clip => None,
            Some(c) if c > clip => Some(c - 1),
            other => other,
        };
        // The playhead follows its clip to its new index (or to the rest pose), in the same
        // undo step: undoing the delete plays the clip that played before.
        self.apply(
            Edit::Group(vec![
                Edit::SetClips { id, clips },
                Edit::SetPlayback { id, playback },
            ]),
            None,
        );
        self.anim_revision += 1;
        Ok(())
    }

    /// Sets clip `clip`'s length (at least its last key's time: keys are never cut).
    ///
    /// # Errors
    /// No rig or clip; a length that is not finite and positive, or shorter than the last key.
    pub fn set_clip_length(
        &mut self,
        id: u64,
        clip: usize,
        length_secs: f32,
    ) -> Result<(), CommandError> {
        self.set_clip_length_merged(id, clip, length_secs, None)
    }

    /// [`Editor::set_clip_length`] as part of a drag: calls with `Some(key)` until
    /// [`Editor::end_interaction`] are one undo step.
    ///
    /// # Errors
    /// As [`Editor::set_clip_length`].
    pub fn set_clip_length_merged(
        &mut self,
        id: u64,
        clip: usize,
        length_secs: f32,
        merge: Option<MergeKey>,
    ) -> Result<(), CommandError> {
        let mut clips = self.rig_or_err(id)?.clips.clone();
        let c = clips
            .get_mut(clip)
            .ok_or_else(|| CommandError::Invalid(format!("no clip {clip}")))?;
        let last = c.last_key_time();
        if !(length_secs.is_finite() && length_secs > 0.0) || length_secs < last {
            return Err(CommandError::Invalid(format!(
                "clip length {length_secs} s: must be positive and at least the last key's \
                 time, {last} s"
            )));
        }
        c.duration_secs = length_secs;
        self.apply(Edit::SetClips { id, clips }, merge);
        Ok(())
    }

    /// Adds an empty clip `name` (made unique) of `length_secs` and plays it; returns its index.
    ///
    /// # Errors
    /// No rig; a length that is not positive and finite.
    pub fn new_clip(
        &mut self,
        id: u64,
        name: &str,
        length_secs: f32,
    ) -> Result<usize, CommandError> {
        let rig = self.rig_or_err(id)?;
        if !(length_secs.is_finite() && length_secs > 0.0) {
            return Err(CommandError::Invalid(format!(
                "clip length {length_secs} s must be positive"
            )));
        }
        let name = name.trim();
        if name.is_empty() {
            return Err(CommandError::Invalid("a clip needs a name".into()));
        }
        let mut clips = rig.clips.clone();
        let name = unique_name(name, |n| clips.iter().any(|c| c.name == n));
        clips.push(AnimationClip {
            name,
            duration_secs: length_secs,
            ..AnimationClip::default()
        });
        let index = clips.len() - 1;
        self.apply(Edit::SetClips { id, clips }, None);
        let mut playback = self.rig_or_err(id)?.playback;
        playback.clip = Some(index);
        playback.time_secs = 0.0;
        self.set_playback(id, playback)?;
        Ok(index)
    }
}

/// Binds `model` to its skeleton (for a worker thread): the octree with weights, the report
/// and the method, for [`Editor::finish_bind`].
///
/// # Errors
/// No skeleton, or the binding's refusal (cancelled included).
pub fn bind_job(
    model: &VoxelModel,
    method: BindMethod,
    control: BindControl<'_>,
) -> Result<(thicket_core::svo::Svo, BindReport, BindMethod), CommandError> {
    let rig = model
        .rig
        .as_ref()
        .ok_or_else(|| CommandError::Invalid("add joints (or a template) before binding".into()))?;
    let (svo, report) = bind(
        &model.svo,
        model.origin,
        model.voxel_size,
        &rig.skeleton,
        method,
        control,
    )
    .map_err(|e| CommandError::Invalid(e.to_string()))?;
    Ok((svo, report, method))
}

/// A rig for `skeleton` that keeps what `old` had for joints of the same names: clips, pose
/// overrides, playback, stretch settings and overrides, the binding record.
fn rig_for(old: Option<&Rig>, skeleton: Skeleton) -> Rig {
    let Some(old) = old else {
        let mut rig = Rig::new(skeleton, Vec::new());
        rig.playback.wrap = thicket_core::skin::Wrap::Loop;
        return rig;
    };
    let by_name = |j: usize| {
        old.skeleton
            .joints
            .get(j)
            .and_then(|o| skeleton.find(&o.name))
    };
    let (clips, _) = clips_by_name(&old.skeleton, &old.clips, &skeleton);
    let pose_overrides = old
        .pose_overrides
        .iter()
        .filter_map(|o| {
            Some(thicket_core::skin::JointOverride {
                joint: by_name(o.joint)?,
                ..*o
            })
        })
        .collect();
    Rig {
        skeleton,
        clips,
        playback: old.playback,
        pose_overrides,
        stretch: old.stretch,
        stretch_overrides: old.stretch_overrides.clone(),
        reference_mesh: old.reference_mesh.clone(),
        binding: old.binding.clone(),
        ..Rig::default()
    }
}

/// Renames joint `from` to `to` in a rig: the skeleton and the binding record (clips, overrides
/// and weights address joints by index and follow).
fn rename_in_rig(rig: &mut Rig, from: &str, to: &str) {
    for j in &mut rig.skeleton.joints {
        if j.name == from {
            to.clone_into(&mut j.name);
        }
    }
    if let Some(binding) = &mut rig.binding {
        for j in &mut binding.skeleton.joints {
            if j.name == from {
                to.clone_into(&mut j.name);
            }
            if j.parent.as_deref() == Some(from) {
                j.parent = Some(to.to_owned());
            }
        }
    }
}

/// Whether every joint's frame is what [`SkeletonSpec::to_skeleton`] makes: a pure translation
/// with no attachment. Imported skeletons with rotated or scaled frames are not rebuilt from joint
/// positions (their clips are written against those frames).
fn has_native_frames(skeleton: &Skeleton) -> bool {
    skeleton.joints.iter().all(|j| {
        let bind_is_translation = j.inverse_bind.x_axis.abs_diff_eq(glam::Vec4::X, 1e-5)
            && j.inverse_bind.y_axis.abs_diff_eq(glam::Vec4::Y, 1e-5)
            && j.inverse_bind.z_axis.abs_diff_eq(glam::Vec4::Z, 1e-5);
        j.rest.rotation.abs_diff_eq(glam::Quat::IDENTITY, 1e-5)
            && j.rest.scale.abs_diff_eq(Vec3::ONE, 1e-5)
            && j.parent_from_attachment == glam::Mat4::IDENTITY
            && bind_is_translation
    })
}

fn bound_rig(mut rig: Rig, method: BindMethod) -> Rig {
    rig.binding = Some(Binding {
        method,
        skeleton: SkeletonSpec::of_skeleton(&rig.skeleton),
    });
    rig
}

/// For each old joint index, the new index of the joint of the same name, else of its nearest
/// ancestor that survives, else 0.
fn joint_remap(old: &Skeleton, new: &Skeleton) -> Vec<u8> {
    (0..old.len())
        .map(|mut j| {
            for _ in 0..=old.len() {
                if let Some(n) = new.find(&old.joints[j].name) {
                    return n as u8;
                }
                match old.joints[j].parent {
                    Some(p) => j = p,
                    None => break,
                }
            }
            0
        })
        .collect()
}

fn map_voxels(
    svo: &thicket_core::svo::Svo,
    has_skin: bool,
    f: impl Fn(Skin4) -> Skin4,
) -> Result<thicket_core::svo::Svo, CommandError> {
    // Every voxel is rebuilt with its new weights: refused, as binding is, for a model standing
    // for more voxels than the tools go through one by one.
    if let Some(voxels) = svo.too_many_to_list() {
        return Err(CommandError::Invalid(format!(
            "changing the rig rewrites each voxel's weights one by one, and this model stands \
             for {} voxels, more than {}; rig the model at a larger voxel size",
            crate::files::thousands(voxels),
            crate::files::thousands(thicket_core::svo::MAX_LISTED_VOXELS)
        )));
    }
    thicket_core::svo::Svo::from_voxels(
        svo.depth(),
        has_skin,
        svo.leaves().into_iter().map(|(c, v)| {
            (
                c,
                Voxel {
                    skin: f(v.skin),
                    ..v
                },
            )
        }),
    )
    .map_err(|e| CommandError::Invalid(e.to_string()))
}

fn remap_skin(
    svo: &thicket_core::svo::Svo,
    remap: &[u8],
) -> Result<thicket_core::svo::Svo, CommandError> {
    map_voxels(svo, true, |s| {
        let infl: Vec<(u16, f32)> = s
            .influences()
            .map(|(j, w)| {
                (
                    u16::from(remap.get(usize::from(j)).copied().unwrap_or(0)),
                    w,
                )
            })
            .collect();
        Skin4::from_influences(&infl)
    })
}

fn strip_skin(svo: &thicket_core::svo::Svo) -> Result<thicket_core::svo::Svo, CommandError> {
    map_voxels(svo, false, |_| Skin4::default())
}

/// Where a voxel-space ray enters and leaves the first run of solid voxels (ray parameters).
fn solid_run(svo: &thicket_core::svo::Svo, ro: Vec3, rd: Vec3) -> Option<(f32, f32)> {
    let (lo, hi) = svo.bounds()?;
    let (blo, bhi) = (lo.as_vec3(), (hi + 1).as_vec3());
    let inv = rd.recip();
    let t0 = (blo - ro) * inv;
    let t1 = (bhi - ro) * inv;
    let tmin = t0.min(t1).max_element().max(0.0);
    let tmax = t0.max(t1).min_element();
    if tmin.is_nan() || tmax.is_nan() || tmin > tmax {
        return None;
    }
    // Amanatides–Woo traversal from the box entry.
    let start = ro + rd * (tmin + 1e-4);
    let mut cell = start.floor().as_ivec3();
    let step = rd.signum().as_ivec3();
    let next_boundary = (cell.as_vec3() + step.max(glam::IVec3::ZERO).as_vec3() - ro) * inv;
    let mut t_max = Vec3::select(rd.cmpeq(Vec3::ZERO), Vec3::INFINITY, next_boundary);
    let t_delta = Vec3::select(rd.cmpeq(Vec3::ZERO), Vec3::INFINITY, inv.abs());
    let mut t = tmin;
    let mut enter = None;
    let max_steps = 3 * (svo.extent() as usize + 2);
    for _ in 0..max_steps {
        let inside = cell.cmpge(lo.as_ivec3()).all() && cell.cmple(hi.as_ivec3()).all();
        let solid = inside && svo.get(cell.as_uvec3()).is_some();
        match (enter, solid) {
            (None, true) => enter = Some(t),
            (Some(e), false) => return Some((e, t)),
            _ => {}
        }
        if t > tmax {
            break;
        }
        let axis = if t_max.x < t_max.y && t_max.x < t_max.z {
            0
        } else if t_max.y < t_max.z {
            1
        } else {
            2
        };
        t = t_max[axis];
        cell[axis] += step[axis];
        t_max[axis] += t_delta[axis];
    }
    enter.map(|e| (e, t))
}
