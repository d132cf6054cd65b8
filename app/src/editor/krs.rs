//! Editing KRS objects: parameters go through core's validation before they reach the document
//! (a refused value leaves it unchanged and says why), and presets replace the whole object.

use glam::Vec3;
use thicket_core::krs::{KrsObject, TreeParams, presets};
use thicket_core::scene::{MAX_KRS_LEVELS, Object, ObjectKind};

use super::{CommandError, Edit, Editor, MergeKey, Selection, beside_scene, half_xz, next_id};

impl Editor {
    /// The KRS parameters of object `id`, when it is a KRS object.
    #[must_use]
    pub fn krs(&self, id: u64) -> Option<&KrsObject> {
        match &self.object(id)?.kind {
            ObjectKind::Krs(k) => Some(k),
            ObjectKind::Voxels(_) | ObjectKind::Mesh(_) => None,
        }
    }

    /// Sets the parameters of KRS object `id` after core's validation; what is stored is the
    /// validated copy (mirror normals and kernel directions normalised, keeping their planes).
    /// Calls during one interaction (a drag) merge into one undo step.
    ///
    /// # Errors
    /// Unknown object, not a KRS object, or invalid parameters (the message names the kernel or
    /// mirror and the field).
    pub fn set_krs(&mut self, id: u64, krs: &KrsObject) -> Result<(), CommandError> {
        let o = self.object(id).ok_or(CommandError::NoObject(id))?;
        let ObjectKind::Krs(current) = &o.kind else {
            return Err(CommandError::Invalid(format!(
                "{:?} is not a KRS object",
                o.name
            )));
        };
        if krs.mirrors.len() > MAX_KRS_LEVELS {
            return Err(CommandError::Invalid(format!(
                "{:?}: at most {MAX_KRS_LEVELS} mirror levels",
                o.name
            )));
        }
        // Core labels errors with an object index; the editor names the object instead.
        let validated = krs.validated(0).map_err(|e| {
            CommandError::Invalid(e.to_string().replacen(
                "KRS object 0",
                &format!("KRS object {:?}", o.name),
                1,
            ))
        })?;
        // Texturing and magnitudes are checked where the document is (the renderer refuses a
        // document that fails them): the object as it would be, on its own.
        let mut candidate = o.clone();
        candidate.kind = ObjectKind::Krs(validated.clone());
        let alone = thicket_core::scene::Document {
            objects: vec![candidate],
            ..thicket_core::scene::Document::default()
        };
        alone
            .validate()
            .map_err(|e| CommandError::Invalid(e.to_string()))?;
        if *current != validated {
            self.apply(
                Edit::SetKrs {
                    id,
                    krs: Box::new(validated),
                },
                Some(MergeKey::Krs(id)),
            );
        }
        Ok(())
    }

    /// Adds KRS object `krs` named `name` beside what the scene already holds (on the eye's
    /// side of the scene's bounds, at the height it was made at; at its own origin in a scene
    /// without bounds, or when it has none itself, like a terrain: the rock's half-spaces have
    /// no bounding ball but a box found by probing), selects it and frames it.
    /// `params`, the tree-builder parameters that build it (a tree, bush or coral preset), are
    /// stored with it in the same undo step, so the builder opens it. Returns its id.
    pub fn add_krs_object(
        &mut self,
        name: &str,
        krs: KrsObject,
        params: Option<TreeParams>,
    ) -> u64 {
        let id = next_id(&self.doc);
        let mut object = Object {
            id,
            name: name.to_owned(),
            kind: ObjectKind::Krs(krs),
            ..Object::default()
        };
        // A KRS object with half-space kernels (the rock) has no bounding ball: probe its box.
        let bounds = object.world_bounds().or_else(|| {
            let k = object.krs_in_world()?;
            let scene = thicket_core::krs::KrsScene { objects: vec![k] }
                .prepare()
                .ok()?;
            thicket_core::io::gltf_export::krs_region(scene.objects.first()?).ok()
        });
        if let (Some(scene), Some((lo, hi))) = (self.doc.bounds(), bounds) {
            let dest = beside_scene(scene, half_xz(lo, hi), self.doc.camera.eye());
            let centre = 0.5 * (lo + hi);
            object.transform.translation += Vec3::new(dest.x - centre.x, 0.0, dest.z - centre.z);
        }
        let insert = Edit::Insert {
            index: self.doc.objects.len(),
            object: Box::new(object),
        };
        self.history.seal();
        match params {
            Some(params) => self.apply(
                Edit::Group(vec![
                    insert,
                    Edit::SetTreeParams {
                        id,
                        params: Some(Box::new(params)),
                    },
                ]),
                None,
            ),
            None => self.apply(insert, None),
        }
        self.history.seal();
        self.selection = Some(Selection::Object(id));
        self.frame_selection();
        id
    }

    /// Replaces KRS object `id` with one of core's presets ([`presets::all`]) (the object's own
    /// transform still places it); one undo step. A preset the tree builder makes (tree, bush,
    /// coral) brings its builder parameters; any other drops the object's.
    ///
    /// # Errors
    /// Unknown object, not a KRS object, or an unknown preset name.
    pub fn apply_krs_preset(&mut self, id: u64, preset: &str) -> Result<(), CommandError> {
        let Some((_, mut k)) = presets::all().into_iter().find(|(n, _)| *n == preset) else {
            return Err(CommandError::Invalid(format!(
                "no KRS preset named {preset:?}"
            )));
        };
        if let Some(current) = self.krs(id) {
            k.name.clone_from(&current.name);
        }
        let params = presets::builder_params(preset);
        self.history.seal();
        let result = if self.doc.tree_params_of(id).is_some() || params.is_some() {
            // The builder's parameters follow the shape, in the same step: the preset's own
            // when the builder makes it, none otherwise (they would build the old shape).
            self.krs(id).ok_or(CommandError::NoObject(id))?;
            let validated = k
                .validated(0)
                .map_err(|e| CommandError::Invalid(e.to_string()))?;
            self.apply(
                Edit::Group(vec![
                    Edit::SetKrs {
                        id,
                        krs: Box::new(validated),
                    },
                    Edit::SetTreeParams {
                        id,
                        params: params.map(Box::new),
                    },
                ]),
                None,
            );
            Ok(())
        } else {
            self.set_krs(id, &k)
        };
        self.history.seal();
        result
    }

    /// Rebuilds KRS object `id` from tree-builder parameters (paper section 7.2): the builder
    /// makes the kernels and mirrors; the object keeps its name, texturing, distortion, empty
    /// zones and placement. Calls during one drag merge into one undo step.
    ///
    /// # Errors
    /// Unknown object, not a KRS object, or parameters the builder or core's validation
    /// refuses (the message names the parameter).
    pub fn build_tree(&mut self, id: u64, params: &TreeParams) -> Result<(), CommandError> {
        let current = self.krs(id).ok_or_else(|| match self.object(id) {
            Some(o) => CommandError::Invalid(format!("{:?} is not a KRS object", o.name)),
            None => CommandError::NoObject(id),
        })?;
        let mut built = params
            .build()
            .map_err(|e| CommandError::Invalid(format!("tree builder: {e}")))?;
        built.name.clone_from(&current.name);
        built.texturing = current.texturing;
        built.distortion = current.distortion;
        built.empty_zones.clone_from(&current.empty_zones);
        built.world_from_object = current.world_from_object;
        let name = self.object(id).map(|o| o.name.clone()).unwrap_or_default();
        let validated = built.validated(0).map_err(|e| {
            CommandError::Invalid(e.to_string().replacen(
                "KRS object 0",
                &format!("KRS object {name:?}"),
                1,
            ))
        })?;
        // The parameters are saved with the object, so reopening it keeps editing the tree.
        // Both always go in the step: a drag keeps only its first step's inverse.
        if self.krs(id) != Some(&validated) || self.doc.tree_params_of(id) != Some(params) {
            self.apply(
                Edit::Group(vec![
                    Edit::SetKrs {
                        id,
                        krs: Box::new(validated),
                    },
                    Edit::SetTreeParams {
                        id,
                        params: Some(Box::new(params.clone())),
                    },
                ]),
                Some(MergeKey::Krs(id)),
            );
        }
        Ok(())
    }

    /// The tree-builder parameters KRS object `id` was last built from, if any.
    #[must_use]
    pub fn tree_params(&self, id: u64) -> Option<&TreeParams> {
        self.doc.tree_params_of(id)
    }
}
