//! Editing KRS objects: parameters go through core's validation before they reach the document
//! (a refused value leaves it unchanged and says why), and presets replace the whole object.

use thicket_core::krs::{KrsObject, TreeParams, presets};
use thicket_core::scene::{MAX_KRS_LEVELS, ObjectKind};

use super::{CommandError, Edit, Editor, MergeKey};

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

    /// Replaces KRS object `id` with one of core's presets ([`presets::all`]) (the object's own
    /// transform still places it); one undo step.
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
        self.history.seal();
        let result = if self.doc.tree_params_of(id).is_some() {
            // A preset is not a built tree: the builder's parameters go with the old shape,
            // in the same step.
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
                    Edit::SetTreeParams { id, params: None },
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

    /// Rebuilds KRS object `id` from tree-builder parameters (paper section 7.2), keeping the
    /// object's name, texturing and placement; calls during one drag merge into one undo step.
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
