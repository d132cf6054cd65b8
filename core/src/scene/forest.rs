//! A forest in a document: KRS objects grown from the artist's own trees ([`crate::krs::forest`]),
//! linked to them so the forest can be regrown when the trees or the settings change.
//!
//! The trees stay in the document, hidden (the forest's first cell draws each of them); the
//! grown objects are derived from them and replaced on every regrowth; a terrain the forest
//! stands on keeps its own mirrors and takes the forest's after them.

use serde::{Deserialize, Serialize};

use super::{Document, ObjectKind, Transform};
use crate::krs::forest::{ForestGround, ForestParams, ForestTree, grow_forest};
use crate::krs::{Kernel, KrsObject};

/// A forest grown from trees in the document.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct ForestLink {
    /// The trees it grows from (KRS objects the tree builder made), hidden while the forest
    /// stands.
    pub sources: Vec<u64>,
    /// The grown objects: for tree t and row parity p, entry `t · rows + p` (rows = 1 for one
    /// tree, 2 for a union).
    pub objects: Vec<u64>,
    /// The KRS terrain the forest stands on, sharing its mirrors.
    pub terrain: Option<u64>,
    /// How many of the terrain's mirrors are its own (the rest are the forest's).
    pub terrain_mirrors: usize,
    /// How the forest is grown.
    pub params: ForestParams,
}

/// What growing a forest would write into a document.
#[derive(Debug, Clone, PartialEq)]
pub struct ForestPlan {
    /// The grown objects in [`ForestLink::objects`] order: name, KRS, transform.
    pub objects: Vec<(String, KrsObject, Transform)>,
    /// The terrain with the forest's mirrors (id, new KRS).
    pub terrain: Option<(u64, KrsObject)>,
    /// The link to store (its `objects` filled in when the objects get their ids).
    pub link: ForestLink,
    /// Trees in all.
    pub total: u64,
    /// Distance between neighbouring trees along x and z.
    pub spacing: [f32; 2],
    /// Crowns wider than the spacing.
    pub crowns_overlap: bool,
}

impl Document {
    /// The forest that object `id` belongs to (as a source tree, a grown object or its
    /// terrain), with its index in [`Document::forests`].
    #[must_use]
    pub fn forest_of(&self, id: u64) -> Option<(usize, &ForestLink)> {
        self.forests.iter().enumerate().find(|(_, l)| {
            l.sources.contains(&id) || l.objects.contains(&id) || l.terrain == Some(id)
        })
    }

    /// Plans growing (or regrowing) a forest from the trees `sources` on `terrain` (a KRS
    /// object) with `params`. A forest already grown from the same first tree is replaced: its
    /// terrain goes back to its own mirrors first.
    ///
    /// # Errors
    /// A missing object, one that is not a tree the builder made (its parameters are saved
    /// with it), a tree given twice, a grown forest object given as a tree, a terrain that is
    /// not a KRS object, or whatever [`grow_forest`] refuses; the message names the object.
    pub fn plan_forest(
        &self,
        sources: &[u64],
        terrain: Option<u64>,
        params: &ForestParams,
    ) -> Result<ForestPlan, String> {
        let previous = sources
            .first()
            .and_then(|s| self.forests.iter().find(|l| l.sources.first() == Some(s)));
        let name = |id: u64| {
            self.objects
                .iter()
                .find(|o| o.id == id)
                .map_or_else(|| format!("object id {id}"), |o| format!("{:?}", o.name))
        };
        let mut trees = Vec::with_capacity(sources.len());
        for (i, &id) in sources.iter().enumerate() {
            let o = self
                .objects
                .iter()
                .find(|o| o.id == id)
                .ok_or_else(|| format!("no object with id {id}"))?;
            if sources[..i].contains(&id) {
                return Err(format!("{:?} is given twice", o.name));
            }
            if self
                .forests
                .iter()
                .any(|l| l.objects.contains(&id) || l.terrain == Some(id))
            {
                return Err(format!(
                    "{:?} is part of a grown forest, not a tree: grow from the trees it came from",
                    o.name
                ));
            }
            let Some(params) = self.tree_params_of(id) else {
                return Err(match o.kind {
                    ObjectKind::Krs(_) => format!(
                        "{:?} is not a tree the tree builder made (a forest grows from trees whose fork positions are saved with them)",
                        o.name
                    ),
                    _ => format!("{:?} is not a KRS tree", o.name),
                });
            };
            let (ObjectKind::Krs(k), Some(placed)) = (&o.kind, o.krs_in_world()) else {
                return Err(format!(
                    "{:?} has a non-uniform scale: a KRS tree takes a uniform one",
                    o.name
                ));
            };
            trees.push((k, placed.world_from_object, params.route[0], o));
        }
        let ground = match terrain {
            Some(id) => {
                let o = self
                    .objects
                    .iter()
                    .find(|o| o.id == id)
                    .ok_or_else(|| format!("no terrain object with id {id}"))?;
                if sources.contains(&id) {
                    return Err(format!(
                        "{:?} cannot be both a tree and the terrain",
                        o.name
                    ));
                }
                let (ObjectKind::Krs(k), Some(placed)) = (&o.kind, o.krs_in_world()) else {
                    return Err(format!("{:?} is not a KRS terrain", o.name));
                };
                // A terrain that carries an earlier forest's mirrors goes back to its own.
                let own = self
                    .forests
                    .iter()
                    .find(|l| l.terrain == Some(id))
                    .map_or(k.mirrors.len(), |l| l.terrain_mirrors.min(k.mirrors.len()));
                let mut base = k.clone();
                base.mirrors.truncate(own);
                base.kernels.truncate(own + 1);
                Some((id, base, placed.world_from_object, own))
            }
            None => None,
        };
        let forest_trees: Vec<ForestTree<'_>> = trees
            .iter()
            .map(|(k, placement, base, _)| ForestTree {
                object: k,
                placement: *placement,
                base: *base,
            })
            .collect();
        let forest = grow_forest(
            &forest_trees,
            params,
            ground.as_ref().map(|(_, k, placement, _)| ForestGround {
                object: k,
                placement: *placement,
            }),
        )
        .map_err(|e| match e {
            crate::krs::forest::ForestError::Krs(crate::krs::KrsError::Unbounded { object })
                if object < sources.len() =>
            {
                format!(
                    "{} is unbounded: a forest repeats a bounded tree",
                    name(sources[object])
                )
            }
            other => other.to_string(),
        })?;
        let rows = if sources.len() > 1 { 2 } else { 1 };
        let objects = forest
            .trees
            .iter()
            .enumerate()
            .map(|(i, g)| {
                let (_, _, _, o) = &trees[g.source];
                let label = if rows == 1 {
                    format!("{} forest", o.name)
                } else {
                    format!(
                        "{} forest ({} rows)",
                        o.name,
                        if g.row == 0 { "even" } else { "odd" }
                    )
                };
                let mut transform = o.transform;
                transform.translation += g.translation;
                let mut grown = g.object.clone();
                // Clearings and paths cut into the previous growth stay (§6.4).
                if let Some(ObjectKind::Krs(k)) = previous
                    .and_then(|l| l.objects.get(i))
                    .and_then(|id| self.objects.iter().find(|o| o.id == *id))
                    .map(|o| &o.kind)
                {
                    grown.empty_zones.clone_from(&k.empty_zones);
                }
                (label, grown, transform)
            })
            .collect();
        Ok(ForestPlan {
            objects,
            terrain: ground
                .as_ref()
                .zip(forest.ground)
                .map(|((id, ..), k)| (*id, k)),
            link: ForestLink {
                sources: sources.to_vec(),
                objects: previous.map(|l| l.objects.clone()).unwrap_or_default(),
                terrain,
                terrain_mirrors: ground.as_ref().map_or(0, |g| g.3),
                params: *params,
            },
            total: forest.total,
            spacing: forest.spacing,
            crowns_overlap: forest.crowns_overlap,
        })
    }

    /// Writes a planned forest (what `thicket forest` does; the editor applies the same plan
    /// as undoable edits): the grown objects replace an earlier growth's (keeping their ids
    /// where there are as many), the terrain takes the forest's mirrors, the trees are hidden.
    /// Returns the grown objects' ids.
    pub fn apply_forest(&mut self, plan: ForestPlan) -> Vec<u64> {
        let mut link = plan.link;
        let old = std::mem::take(&mut link.objects);
        // A previous growth of the same trees on another terrain: give that one its own back.
        if let Some(i) = self
            .forests
            .iter()
            .position(|l| l.sources.first() == link.sources.first())
        {
            let prev = self.forests.remove(i);
            if let Some(t) = prev.terrain
                && Some(t) != link.terrain
                && let Some(ObjectKind::Krs(k)) = self
                    .objects
                    .iter_mut()
                    .find(|o| o.id == t)
                    .map(|o| &mut o.kind)
            {
                k.mirrors.truncate(prev.terrain_mirrors);
                k.kernels.truncate(prev.terrain_mirrors + 1);
                k.kernels.resize(k.mirrors.len() + 1, Kernel::Empty);
            }
        }
        let mut ids = Vec::with_capacity(plan.objects.len());
        for (i, (name, krs, transform)) in plan.objects.into_iter().enumerate() {
            let existing = old
                .get(i)
                .and_then(|id| self.objects.iter_mut().find(|o| o.id == *id));
            let id = match existing {
                Some(o) => {
                    o.kind = ObjectKind::Krs(krs);
                    o.transform = transform;
                    o.id
                }
                None => {
                    let id = self.add(name, ObjectKind::Krs(krs));
                    if let Some(o) = self.objects.iter_mut().find(|o| o.id == id) {
                        o.transform = transform;
                    }
                    id
                }
            };
            ids.push(id);
        }
        for id in old.iter().skip(ids.len()) {
            self.objects.retain(|o| o.id != *id);
        }
        if let Some((id, krs)) = plan.terrain
            && let Some(o) = self.objects.iter_mut().find(|o| o.id == id)
        {
            o.kind = ObjectKind::Krs(krs);
        }
        for o in &mut self.objects {
            if link.sources.contains(&o.id) {
                o.visible = false;
            }
        }
        link.objects.clone_from(&ids);
        self.forests.push(link);
        ids
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::krs::forest::ForestParams;
    use crate::krs::{EmptyZone, Material, TreeParams, presets};
    use crate::scene::TreeBuilderLink;

    fn doc() -> (Document, u64, u64) {
        let mut doc = Document::default();
        let tree = doc.add("Tree", ObjectKind::Krs(presets::tree()));
        doc.tree_builders.push(TreeBuilderLink {
            object: tree,
            params: TreeParams::default(),
        });
        let ground = doc.add(
            "Terrain",
            ObjectKind::Krs(presets::folded_ground(Material::default(), 3, 4.0, 1)),
        );
        (doc, tree, ground)
    }

    fn krs(doc: &Document, id: u64) -> &KrsObject {
        match &doc
            .objects
            .iter()
            .find(|o| o.id == id)
            .expect("object")
            .kind
        {
            ObjectKind::Krs(k) => k,
            _ => panic!("KRS"),
        }
    }

    #[test]
    fn regrowing_keeps_ids_and_clearings_and_moving_off_the_terrain_restores_it() {
        let (mut doc, tree, ground) = doc();
        let own = krs(&doc, ground).clone();
        let params = ForestParams {
            trees: [8, 8],
            area: [80.0, 80.0],
            ..ForestParams::default()
        };
        let plan = doc
            .plan_forest(&[tree], Some(ground), &params)
            .expect("plan");
        assert_eq!(plan.total, 64);
        let ids = doc.apply_forest(plan);
        assert_eq!(ids.len(), 1);
        assert!(!doc.objects[0].visible, "the tree is hidden");
        assert_eq!(krs(&doc, ground).mirrors.len(), 3 + 6);
        // A clearing cut into the forest survives a regrowth with another seed.
        let zone = EmptyZone {
            centre: Vec3::new(20.0, 0.0, 20.0),
            radius: 9.0,
        };
        if let Some(ObjectKind::Krs(k)) = doc
            .objects
            .iter_mut()
            .find(|o| o.id == ids[0])
            .map(|o| &mut o.kind)
        {
            k.empty_zones.push(zone);
        }
        let before = krs(&doc, ids[0]).mirrors.clone();
        let plan = doc
            .plan_forest(&[tree], Some(ground), &ForestParams { seed: 9, ..params })
            .expect("plan");
        assert_eq!(doc.apply_forest(plan), ids, "the grown object keeps its id");
        assert_ne!(krs(&doc, ids[0]).mirrors, before, "regrown");
        assert_eq!(krs(&doc, ids[0]).empty_zones, vec![zone]);
        assert_eq!(doc.forests.len(), 1);
        // Regrown on flat ground: the terrain gets its own mirrors back.
        let plan = doc.plan_forest(&[tree], None, &params).expect("plan");
        doc.apply_forest(plan);
        assert_eq!(krs(&doc, ground), &own);
        assert_eq!(doc.forests[0].terrain, None);
        doc.validate().expect("a valid document");
        // Grown objects and terrains are not trees.
        let err = doc.plan_forest(&[ids[0]], None, &params).unwrap_err();
        assert!(err.contains("part of a grown forest"), "{err}");
        let err = doc.plan_forest(&[tree], Some(tree), &params).unwrap_err();
        assert!(err.contains("both a tree and the terrain"), "{err}");
        let err = doc.plan_forest(&[tree, tree], None, &params).unwrap_err();
        assert!(err.contains("given twice"), "{err}");
    }
}
