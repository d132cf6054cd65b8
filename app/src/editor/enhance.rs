//! Detail enhancement kept in step with sculpting: a coarse voxel model linked to the object
//! holding its enhancement ([`EnhancementLink`] in the document, with its settings). After
//! every dab, undo or redo that writes the coarse model's voxels, only the region the edit can
//! influence is re-enhanced (core's `Enhancer::update_box_changes`, equal to a full
//! recompute) and the same few fine voxels are written into the linked object.
//!
//! The fine model is derived data: its changes are not undo steps of their own (undoing a
//! stroke re-enhances the restored region). The `Enhancer` with its caches lives here, not in
//! the document; it is rebuilt from the coarse model when missing (after an edit that
//! changed a link or a model wholesale). A document being opened gets its enhancers on the
//! open job's worker thread ([`PreparedDocument`]), so the first dab after Open does not pay a
//! full enhancement on the UI thread.

use std::collections::HashMap;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use glam::{IVec3, UVec3};
use thicket_core::enhance::{Control, EnhanceSettings, Enhancer};
use thicket_core::scene::{Document, EnhancementLink, ObjectKind, VoxelModel};

use super::{Change, CommandError, Edit, Editor, Selection};

/// The live enhancers of the linked models, by source id.
#[derive(Default)]
pub struct Enhancers {
    by_source: HashMap<u64, Enhancer>,
    /// What the last incremental update did, for the inspector.
    pub last: Option<EnhanceUpdate>,
    /// Enhancers built in full by edits (on the editor's thread) since the document was
    /// installed.
    rebuilds: u64,
}

/// A document with the live enhancers of its enhancement links, built where it was loaded (the
/// open job's worker thread), to install with [`Editor::replace_document_prepared`].
pub struct PreparedDocument {
    doc: Document,
    enhancers: Vec<(u64, Enhancer)>,
}

impl std::fmt::Debug for PreparedDocument {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PreparedDocument")
            .field("objects", &self.doc.objects.len())
            .field(
                "enhancers",
                &self.enhancers.iter().map(|(s, _)| s).collect::<Vec<_>>(),
            )
            .finish()
    }
}

impl PreparedDocument {
    /// Builds the enhancer of every enhancement link of `doc` (what the first dab on a linked
    /// model would otherwise build), and, as `Editor::ensure_enhancer` does, replaces a
    /// stored fine model that differs from what its link's settings make of the coarse model.
    /// A link whose enhancement fails is left to the first dab, which reports the error;
    /// `cancel` stops early (the remaining links are then built by their first dab).
    #[must_use]
    pub fn new(mut doc: Document, cancel: Option<&AtomicBool>) -> Self {
        let mut enhancers = Vec::new();
        for link in doc.enhancements.clone() {
            let index = |id: u64| doc.objects.iter().position(|o| o.id == id);
            let (Some(si), Some(ti)) = (index(link.source), index(link.target)) else {
                continue;
            };
            let ObjectKind::Voxels(coarse) = &doc.objects[si].kind else {
                continue;
            };
            let control = Control {
                progress: None,
                cancel,
            };
            let Ok(e) = Enhancer::with_control(&coarse.svo, &link.settings, control) else {
                continue;
            };
            if let ObjectKind::Voxels(fine) = &mut doc.objects[ti].kind
                && fine.svo != *e.fine()
            {
                fine.svo = e.fine().clone();
            }
            enhancers.push((link.source, e));
        }
        Self { doc, enhancers }
    }

    /// The document.
    #[must_use]
    pub fn doc(&self) -> &Document {
        &self.doc
    }

    /// How many enhancers were built.
    #[must_use]
    pub fn enhancer_count(&self) -> usize {
        self.enhancers.len()
    }
}

impl std::fmt::Debug for Enhancers {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Enhancers")
            .field("sources", &self.by_source.keys().collect::<Vec<_>>())
            .field("last", &self.last)
            .finish()
    }
}

/// One incremental re-enhancement after an edit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnhanceUpdate {
    /// The coarse model.
    pub source: u64,
    /// Coarse cells recomputed.
    pub cells: u64,
    /// Fine voxels written (changed or removed).
    pub fine_changes: usize,
    /// Wall time of the update in milliseconds.
    pub millis: f64,
    /// Whether the enhancer had to be rebuilt in full first.
    pub rebuilt: bool,
}

impl Editor {
    /// Links voxel model `source` to a new object holding `fine`, its enhancement with
    /// `settings`, placed like the source; the source is hidden, so the view shows the fine
    /// model while strokes edit the coarse one. One undo step. `enhancer` (the one that made
    /// `fine`) is kept for the incremental updates. Returns the new object's id.
    ///
    /// # Errors
    /// Unknown source, not a voxel model, invalid settings, or a model already linked.
    pub fn add_enhancement(
        &mut self,
        source: u64,
        settings: EnhanceSettings,
        fine: VoxelModel,
        enhancer: Option<Enhancer>,
    ) -> Result<u64, CommandError> {
        let index = self.index_of(source)?;
        let o = &self.doc.objects[index];
        if !matches!(o.kind, ObjectKind::Voxels(_)) {
            return Err(CommandError::Invalid(format!(
                "{:?} is not a voxel model: only voxel models can be enhanced",
                o.name
            )));
        }
        if let Some(l) = self.doc.enhancement_into(source) {
            return Err(CommandError::Invalid(format!(
                "{:?} is the enhancement of object id {}: enhance that model instead",
                o.name, l.source
            )));
        }
        settings
            .validate()
            .map_err(|e| CommandError::Invalid(e.to_string()))?;
        let name = format!("{} enhanced", o.name);
        let transform = o.transform;
        // The enhancement moves as its source does.
        let motion = o.motion.clone();
        let was_visible = o.visible;
        let target = super::next_id(&self.doc);
        let mut edits = Vec::new();
        // Re-enhancing an already linked model replaces its enhancement object.
        if let Some(old) = self.doc.enhancement_of(source).map(|l| l.target)
            && let Ok(i) = self.index_of(old)
        {
            edits.push(Edit::Remove { index: i });
        }
        let object = thicket_core::scene::Object {
            id: target,
            name,
            visible: true,
            transform,
            kind: ObjectKind::Voxels(fine),
            motion,
        };
        let index = self.doc.objects.len() - edits.len();
        edits.push(Edit::Insert {
            index,
            object: Box::new(object),
        });
        if was_visible {
            edits.push(Edit::SetVisible {
                id: source,
                visible: false,
            });
        }
        edits.push(Edit::SetEnhancement {
            source,
            link: Some(Box::new(EnhancementLink {
                source,
                target,
                settings,
            })),
        });
        self.history.seal();
        self.apply(Edit::Group(edits), None);
        self.enhancers.by_source.remove(&source);
        if let Some(e) = enhancer {
            self.enhancers.by_source.insert(source, e);
        }
        self.selection = Some(Selection::Object(target));
        Ok(target)
    }

    /// Replaces the enhancement of linked model `source` by `fine`, made with new `settings`
    /// (the inspector's Re-enhance). One undo step.
    ///
    /// # Errors
    /// No link for `source`, its target is gone, or invalid settings.
    pub fn replace_enhancement(
        &mut self,
        source: u64,
        settings: EnhanceSettings,
        fine: VoxelModel,
        enhancer: Option<Enhancer>,
    ) -> Result<(), CommandError> {
        let link = self.doc.enhancement_of(source).cloned().ok_or_else(|| {
            CommandError::Invalid(format!("object id {source} has no enhancement to replace"))
        })?;
        self.index_of(link.target)?;
        settings
            .validate()
            .map_err(|e| CommandError::Invalid(e.to_string()))?;
        self.history.seal();
        self.apply(
            Edit::Group(vec![
                Edit::SetVoxelModel {
                    id: link.target,
                    model: Box::new(fine),
                },
                Edit::SetEnhancement {
                    source,
                    link: Some(Box::new(EnhancementLink { settings, ..link })),
                },
            ]),
            None,
        );
        self.enhancers.by_source.remove(&source);
        if let Some(e) = enhancer {
            self.enhancers.by_source.insert(source, e);
        }
        Ok(())
    }

    /// Stops keeping `source`'s enhancement up to date (both objects stay, the enhancement
    /// becomes an ordinary model that can be sculpted itself). One undo step.
    ///
    /// # Errors
    /// No link for `source`.
    pub fn unlink_enhancement(&mut self, source: u64) -> Result<(), CommandError> {
        if self.doc.enhancement_of(source).is_none() {
            return Err(CommandError::Invalid(format!(
                "object id {source} has no enhancement link"
            )));
        }
        self.history.seal();
        self.apply(Edit::SetEnhancement { source, link: None }, None);
        self.enhancers.by_source.remove(&source);
        Ok(())
    }

    /// What the last incremental re-enhancement did.
    #[must_use]
    pub fn last_enhance_update(&self) -> Option<EnhanceUpdate> {
        self.enhancers.last
    }

    /// How many times an edit had to build a linked model's enhancer in full (on the thread
    /// that called the edit: the UI thread in the editor) since the document was installed.
    #[must_use]
    pub fn enhancer_rebuilds(&self) -> u64 {
        self.enhancers.rebuilds
    }

    /// Replaces the document as [`Editor::replace_document`] does, keeping the enhancers
    /// `prepared` built for it, so strokes on its linked models update incrementally from the
    /// first dab.
    pub fn replace_document_prepared(
        &mut self,
        prepared: PreparedDocument,
        path: Option<std::path::PathBuf>,
    ) {
        let PreparedDocument { doc, enhancers } = prepared;
        self.replace_document(doc, path);
        for (source, e) in enhancers {
            if self
                .doc
                .enhancement_of(source)
                .is_some_and(|l| &l.settings == e.settings())
            {
                self.enhancers.by_source.insert(source, e);
            }
        }
    }

    /// Forgets every live enhancer (they are rebuilt from the document when next needed).
    pub(super) fn drop_enhancers(&mut self) {
        self.enhancers.by_source.clear();
    }

    /// Forgets the live enhancer of linked model `source` (its octree was swapped: a frame
    /// sequence's undo shows the frame the edit was made on).
    pub(super) fn drop_enhancer(&mut self, source: u64) {
        self.enhancers.by_source.remove(&source);
    }

    /// Builds the live enhancer of linked model `source` from its coarse model when there is
    /// none, *before* an edit, so the edit's update is incremental; a stored fine model that
    /// differs from what the link's settings make of the coarse model is replaced (it was made
    /// elsewhere or from other voxels).
    pub(super) fn ensure_enhancer(&mut self, source: u64) {
        let Some(link) = self.doc.enhancement_of(source).cloned() else {
            return;
        };
        if self
            .enhancers
            .by_source
            .get(&source)
            .is_some_and(|e| e.settings() == &link.settings)
        {
            return;
        }
        let (Ok(si), Ok(ti)) = (self.index_of(source), self.index_of(link.target)) else {
            return;
        };
        let ObjectKind::Voxels(coarse) = &self.doc.objects[si].kind else {
            return;
        };
        self.enhancers.rebuilds += 1;
        match Enhancer::new(&coarse.svo, &link.settings) {
            Ok(e) => {
                if let ObjectKind::Voxels(fine) = &mut self.doc.objects[ti].kind
                    && fine.svo != *e.fine()
                {
                    fine.svo = e.fine().clone();
                    // Not an edit (no history step), but what is drawn changed: a renderer or
                    // cache keyed on the content key must not keep the old fine model, even
                    // when the edit that follows writes nothing or is undone.
                    let before = self.content_key();
                    self.generation += 1;
                    self.record(
                        before,
                        Change::Voxels {
                            object: link.target,
                            region: None,
                        },
                    );
                }
                self.enhancers.by_source.insert(source, e);
            }
            Err(e) => {
                self.enhance_error = Some(format!("detail enhancement of object id {source}: {e}"));
            }
        }
    }

    /// Re-enhances the region of linked model `source` around the coarse voxels `lo..=hi`
    /// (just written) and patches the linked object with the fine voxels that changed. Returns
    /// the fine box written, or `None` when `source` has no live link.
    pub(super) fn sync_enhancement(
        &mut self,
        source: u64,
        lo: UVec3,
        hi: UVec3,
    ) -> Result<Option<(UVec3, UVec3)>, CommandError> {
        let Some(link) = self.doc.enhancement_of(source).cloned() else {
            return Ok(None);
        };
        let (Ok(si), Ok(ti)) = (self.index_of(source), self.index_of(link.target)) else {
            // A link to a deleted object: nothing to keep in step.
            self.enhancers.by_source.remove(&source);
            return Ok(None);
        };
        let ObjectKind::Voxels(coarse) = &self.doc.objects[si].kind else {
            return Ok(None);
        };
        let coarse_ext = coarse.svo.extent();
        let start = Instant::now();
        let err = |e: thicket_core::enhance::EnhanceError| {
            CommandError::Invalid(format!("detail enhancement of object id {source}: {e}"))
        };
        let mut rebuilt = false;
        let enhancer = match self.enhancers.by_source.remove(&source) {
            Some(e) if e.settings() == &link.settings => e,
            _ => {
                rebuilt = true;
                self.enhancers.rebuilds += 1;
                Enhancer::new(&coarse.svo, &link.settings).map_err(err)?
            }
        };
        let mut enhancer = enhancer;
        let changes = enhancer
            .update_box_changes(&coarse.svo, lo, hi)
            .map_err(err)?;
        let cells = enhancer.stats().candidate_cells;
        let ObjectKind::Voxels(fine) = &mut self.doc.objects[ti].kind else {
            return Err(CommandError::Invalid(format!(
                "the enhancement of object id {source} (object id {}) is not a voxel model",
                link.target
            )));
        };
        let n = changes.len();
        let mut whole = false;
        if rebuilt && fine.svo != *enhancer.fine() {
            // The stored fine model was not made from this coarse model with these settings
            // (an older file, or a model edited elsewhere): take the enhancer's, whole.
            fine.svo = enhancer.fine().clone();
            whole = true;
        } else {
            fine.svo
                .apply_changes(changes)
                .map_err(|e| CommandError::Invalid(e.to_string()))?;
        }
        let f = link.settings.factor;
        let r = enhancer.dependency_radius();
        let fine_ext = fine.svo.extent();
        self.enhancers.by_source.insert(source, enhancer);
        let lo_c = lo.as_ivec3() - IVec3::splat(r as i32);
        let hi_c = (hi + UVec3::splat(r)).min(UVec3::splat(coarse_ext.saturating_sub(1)));
        let fine_lo = (lo_c.max(IVec3::ZERO).as_uvec3()) * f;
        let fine_hi = ((hi_c + 1) * f - 1).min(UVec3::splat(fine_ext - 1));
        self.enhancers.last = Some(EnhanceUpdate {
            source,
            cells,
            fine_changes: n,
            millis: start.elapsed().as_secs_f64() * 1e3,
            rebuilt,
        });
        if whole {
            return Ok(Some((UVec3::ZERO, UVec3::splat(fine_ext - 1))));
        }
        Ok(Some((fine_lo, fine_hi)))
    }
}
