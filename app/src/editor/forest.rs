//! Growing a forest from the artist's own trees in the editor: the document's plan
//! ([`Document::plan_forest`]) written as one undoable step (a slider drag merges its regrowths
//! into one step), regrown in place (the grown objects keep their ids), or removed (the trees
//! shown again, the terrain back to its own mirrors).

use thicket_core::krs::forest::ForestParams;
use thicket_core::krs::{Kernel, KrsObject};
use thicket_core::scene::{Document, ForestLink, Object, ObjectKind};

use super::{CommandError, Edit, Editor, MergeKey, next_id};

/// What a growth placed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForestReport {
    /// Trees in all.
    pub total: u64,
    /// Distance between neighbouring trees along x and z.
    pub spacing: [f32; 2],
    /// The crowns are wider than the spacing (neighbours meet).
    pub crowns_overlap: bool,
}

/// The terrain `id` of `doc` with only its own `own` mirrors.
fn own_terrain(doc: &Document, id: u64, own: usize) -> Option<KrsObject> {
    let ObjectKind::Krs(k) = &doc.objects.iter().find(|o| o.id == id)?.kind else {
        return None;
    };
    let mut k = k.clone();
    k.mirrors.truncate(own);
    k.kernels.truncate(own + 1);
    k.kernels.resize(k.mirrors.len() + 1, Kernel::Empty);
    Some(k)
}

impl Editor {
    /// The forest object `id` belongs to (as a tree, a grown object or the terrain).
    #[must_use]
    pub fn forest_of(&self, id: u64) -> Option<&ForestLink> {
        self.doc().forest_of(id).map(|(_, l)| l)
    }

    /// Grows a forest from the trees `sources` (KRS objects the tree builder made) on the KRS
    /// `terrain` when given, or regrows the forest already grown from the same first tree: one
    /// undo step; calls during one slider drag merge into it. The trees are hidden (the
    /// forest's first cell draws them), the grown objects keep their ids across regrowths.
    ///
    /// # Errors
    /// What [`Document::plan_forest`] refuses (the message names the object or parameter);
    /// nothing is changed then.
    pub fn grow_forest(
        &mut self,
        sources: &[u64],
        terrain: Option<u64>,
        params: &ForestParams,
    ) -> Result<ForestReport, CommandError> {
        let plan = self
            .doc()
            .plan_forest(sources, terrain, params)
            .map_err(CommandError::Invalid)?;
        let report = ForestReport {
            total: plan.total,
            spacing: plan.spacing,
            crowns_overlap: plan.crowns_overlap,
        };
        let doc = self.doc();
        let previous = doc.forest_of(sources[0]).map(|(i, l)| (i, l.clone()));
        let old_ids = previous
            .as_ref()
            .map(|(_, l)| l.objects.clone())
            .unwrap_or_default();
        let mut edits = Vec::new();
        // Objects of the previous growth beyond the new count go (from the back, so indices
        // hold).
        let mut gone: Vec<usize> = old_ids
            .iter()
            .skip(plan.objects.len())
            .filter_map(|id| doc.objects.iter().position(|o| o.id == *id))
            .collect();
        gone.sort_unstable_by(|a, b| b.cmp(a));
        let mut len = doc.objects.len() - gone.len();
        edits.extend(gone.into_iter().map(|index| Edit::Remove { index }));
        let mut id_next = next_id(doc);
        let mut ids = Vec::with_capacity(plan.objects.len());
        for (i, (name, krs, transform)) in plan.objects.into_iter().enumerate() {
            match old_ids
                .get(i)
                .filter(|id| doc.objects.iter().any(|o| o.id == **id))
            {
                Some(&id) => {
                    edits.push(Edit::SetKrs {
                        id,
                        krs: Box::new(krs),
                    });
                    edits.push(Edit::SetTransform { id, transform });
                    ids.push(id);
                }
                None => {
                    let id = id_next;
                    id_next += 1;
                    edits.push(Edit::Insert {
                        index: len,
                        object: Box::new(Object {
                            id,
                            name,
                            kind: ObjectKind::Krs(krs),
                            transform,
                            ..Object::default()
                        }),
                    });
                    len += 1;
                    ids.push(id);
                }
            }
        }
        // A terrain the previous growth stood on, and not this one, gets its own mirrors back.
        if let Some((_, prev)) = &previous
            && let Some(t) = prev.terrain
            && Some(t) != terrain
            && let Some(k) = own_terrain(doc, t, prev.terrain_mirrors)
        {
            edits.push(Edit::SetKrs {
                id: t,
                krs: Box::new(k),
            });
        }
        if let Some((id, krs)) = plan.terrain {
            edits.push(Edit::SetKrs {
                id,
                krs: Box::new(krs),
            });
        }
        // Trees of the previous growth left out of this one are shown again; this one's hidden.
        for o in &doc.objects {
            let now = sources.contains(&o.id);
            let before = previous
                .as_ref()
                .is_some_and(|(_, l)| l.sources.contains(&o.id));
            if now && o.visible {
                edits.push(Edit::SetVisible {
                    id: o.id,
                    visible: false,
                });
            } else if before && !now && !o.visible {
                edits.push(Edit::SetVisible {
                    id: o.id,
                    visible: true,
                });
            }
        }
        let mut forests = doc.forests.clone();
        let mut link = plan.link;
        link.objects = ids;
        match previous {
            Some((i, _)) => forests[i] = link,
            None => forests.push(link),
        }
        edits.push(Edit::SetForests { forests });
        self.apply_named(
            Edit::Group(edits),
            Some(MergeKey::Forest(sources[0])),
            "Grow forest".to_owned(),
        );
        Ok(report)
    }

    /// Frames the forest object `id` belongs to: the box of its first tree stretched over the
    /// grid (the grown objects' bounding balls are far looser than the trees they hold).
    pub fn frame_forest(&mut self, id: u64) {
        let Some(link) = self.forest_of(id).cloned() else {
            return;
        };
        let Some((lo, hi)) = self.object(link.sources[0]).and_then(|o| o.world_bounds()) else {
            return;
        };
        let p = link.params;
        let reach = glam::Vec3::new(
            p.area[0] * (1.0 - 1.0 / p.trees[0].max(1) as f32),
            0.0,
            p.area[1] * (1.0 - 1.0 / p.trees[1].max(1) as f32),
        );
        // A cell of margin: jitter and spread move the outer trees by up to a third of one.
        let margin = glam::Vec3::new(
            p.area[0] / p.trees[0].max(1) as f32,
            0.0,
            p.area[1] / p.trees[1].max(1) as f32,
        );
        let mut camera = self.doc().camera;
        camera.frame_in(lo - margin, hi + reach + margin, self.view_aspect);
        self.set_camera(camera);
    }

    /// Removes the forest object `id` belongs to: its grown objects go, its trees are shown
    /// again, its terrain goes back to its own mirrors; one undo step.
    ///
    /// # Errors
    /// `id` belongs to no forest.
    pub fn remove_forest(&mut self, id: u64) -> Result<(), CommandError> {
        let doc = self.doc();
        let Some((i, link)) = doc.forest_of(id).map(|(i, l)| (i, l.clone())) else {
            return Err(CommandError::Invalid(format!(
                "{:?} belongs to no forest",
                self.object(id).map_or("the object", |o| o.name.as_str())
            )));
        };
        let mut edits = Vec::new();
        let mut gone: Vec<usize> = link
            .objects
            .iter()
            .filter_map(|id| doc.objects.iter().position(|o| o.id == *id))
            .collect();
        gone.sort_unstable_by(|a, b| b.cmp(a));
        edits.extend(gone.into_iter().map(|index| Edit::Remove { index }));
        if let Some(t) = link.terrain
            && let Some(k) = own_terrain(doc, t, link.terrain_mirrors)
        {
            edits.push(Edit::SetKrs {
                id: t,
                krs: Box::new(k),
            });
        }
        for o in &doc.objects {
            if link.sources.contains(&o.id) && !o.visible {
                edits.push(Edit::SetVisible {
                    id: o.id,
                    visible: true,
                });
            }
        }
        let mut forests = doc.forests.clone();
        forests.remove(i);
        edits.push(Edit::SetForests { forests });
        self.history.seal();
        self.apply_named(Edit::Group(edits), None, "Remove forest".to_owned());
        self.history.seal();
        Ok(())
    }
}
