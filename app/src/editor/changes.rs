//! The change feed: every change of what a renderer draws, recorded once, typed, in order.
//!
//! The editor records a [`Change`] wherever the document (or its camera, playheads or derived
//! content) changes. Each consumer (the GPU upload, the CPU preview's shadow cache) keeps its
//! own [`ChangeCursor`] and reads what came after it with [`ChangeFeed::read`]: reading is not
//! destructive, so two consumers see the same changes and each sees each change once. The feed
//! keeps the last [`ChangeFeed::CAPACITY`] changes; a consumer that fell further behind (a view
//! not drawn for a long while) is told it lagged and redoes its work in full, as after an
//! unknown change.
//!
//! Content keys ([`super::Editor::content_key`]) name document states; the feed names the
//! steps between them: each entry says the state it started from and the state it ended in,
//! so a consumer holding the document at `from` knows what to redo to reach `to`.

use std::collections::VecDeque;

use glam::UVec3;
use thicket_core::scene::{Document, ObjectKind};

use super::Edit;

/// What one change did, as precisely as the code that made it knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Change {
    /// Voxels of a model changed: inside `region` (inclusive voxel bounds) and nothing else
    /// when it is known; anywhere in the model otherwise (a frame sequence's shown frame
    /// swapped, with its origin; an enhancement rebuilt).
    Voxels {
        /// The voxel model.
        object: u64,
        /// Minimum and maximum changed voxel, when known.
        region: Option<(UVec3, UVec3)>,
    },
    /// What a model's playhead or joints do changed (pose overrides, stretch settings, a
    /// rig's clip or time, a frame sequence's time between two frames): the joint matrices
    /// move, no per-voxel data changed.
    Pose {
        /// The rigged model or frame sequence.
        object: u64,
    },
    /// A rigged model's per-voxel skin data may have changed (skeleton, weights, clips, stretch
    /// overrides).
    Rig {
        /// The rigged model.
        object: u64,
    },
    /// A KRS object's kernels, mirror planes or tree parameters.
    Krs {
        /// The KRS object.
        object: u64,
    },
    /// The lights.
    Lights,
    /// The view camera.
    Camera,
    /// The quality settings.
    Quality,
    /// Anything else (objects added, removed, moved or hidden, a new document, an undo of
    /// several kinds of edit): everything may have changed.
    Content,
}

impl Change {
    /// The change an edit makes when applied (an undo applies an edit's inverse, which
    /// changes the same things).
    #[must_use]
    pub fn of(edit: &Edit) -> Self {
        match edit {
            Edit::Voxels { id, .. } => Self::Voxels {
                object: *id,
                region: None,
            },
            Edit::SetPose { id, .. }
            | Edit::SetStretch { id, .. }
            | Edit::SetPlayback { id, .. } => Self::Pose { object: *id },
            Edit::SetRig { id, .. }
            | Edit::SetClips { id, .. }
            | Edit::StretchOverrides { id, .. } => Self::Rig { object: *id },
            Edit::SetKrs { id, .. } | Edit::SetTreeParams { id, .. } => Self::Krs { object: *id },
            Edit::SetLight { .. } | Edit::InsertLight { .. } | Edit::RemoveLight { .. } => {
                Self::Lights
            }
            Edit::SetQuality(_) => Self::Quality,
            Edit::Group(edits) => edits
                .iter()
                .map(Self::of)
                .reduce(Self::joined)
                .unwrap_or(Self::Content),
            _ => Self::Content,
        }
    }

    /// One change that covers both: the same change, a model's rig with its pose, or
    /// [`Change::Content`].
    #[must_use]
    pub fn joined(self, other: Self) -> Self {
        match (self, other) {
            (a, b) if a == b => a,
            (Self::Pose { object: a } | Self::Rig { object: a }, Self::Rig { object: b })
            | (Self::Rig { object: a }, Self::Pose { object: b })
                if a == b =>
            {
                Self::Rig { object: a }
            }
            (Self::Voxels { object: a, .. }, Self::Voxels { object: b, .. }) if a == b => {
                Self::Voxels {
                    object: a,
                    region: None,
                }
            }
            _ => Self::Content,
        }
    }
}

/// One recorded change: the document went from content key `from` to `to` by `change`
/// (the same key when the content did not change: a camera move, a playhead).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChangeEntry {
    /// Its place in the feed (the first change is 0).
    pub seq: u64,
    /// The content key before.
    pub from: (u64, u64),
    /// The content key after.
    pub to: (u64, u64),
    /// What changed.
    pub change: Change,
}

/// Where one consumer stands in the feed: the next change it has not read.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ChangeCursor {
    next: u64,
}

/// What a consumer reads: the changes after its cursor, or that some of them are gone.
#[derive(Debug)]
pub enum ChangesRead<'a> {
    /// The changes since the last read, oldest first (possibly none).
    Changes(std::collections::vec_deque::Iter<'a, ChangeEntry>),
    /// Changes the consumer had not read were dropped: redo everything.
    Lagged,
}

/// The editor's recorded changes (see the module's docs).
#[derive(Debug, Clone, Default)]
pub struct ChangeFeed {
    entries: VecDeque<ChangeEntry>,
    next_seq: u64,
}

impl ChangeFeed {
    /// Changes kept for consumers that have not read them yet.
    pub const CAPACITY: usize = 1024;

    /// Records a change from content key `from` to `to`.
    pub fn push(&mut self, from: (u64, u64), to: (u64, u64), change: Change) {
        if self.entries.len() == Self::CAPACITY {
            self.entries.pop_front();
        }
        self.entries.push_back(ChangeEntry {
            seq: self.next_seq,
            from,
            to,
            change,
        });
        self.next_seq += 1;
    }

    /// How many changes were ever recorded: it changes whenever anything drawn changes.
    #[must_use]
    pub fn len(&self) -> u64 {
        self.next_seq
    }

    /// Whether no change was ever recorded.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.next_seq == 0
    }

    /// A cursor after every change recorded so far (a consumer that starts from the current
    /// state).
    #[must_use]
    pub fn cursor_at_end(&self) -> ChangeCursor {
        ChangeCursor {
            next: self.next_seq,
        }
    }

    /// The changes after `cursor`, which moves past them.
    pub fn read(&self, cursor: &mut ChangeCursor) -> ChangesRead<'_> {
        let first = self.entries.front().map_or(self.next_seq, |e| e.seq);
        let start = cursor.next;
        cursor.next = self.next_seq;
        // Before the oldest change kept, or past the newest: a cursor of another feed (an
        // editor replaced wholesale) knows nothing of this one either.
        if start < first || start > self.next_seq {
            return ChangesRead::Lagged;
        }
        // At most the entries' length: `start` lies in `first..=next_seq`.
        let skip = usize::try_from(start - first).unwrap_or(self.entries.len());
        ChangesRead::Changes(self.entries.range(skip..))
    }
}

/// What one consumer must redo after a change.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Redo {
    /// The voxels of `object` inside `lo..=hi` (inclusive voxel coordinates).
    Region {
        /// The voxel model.
        object: u64,
        /// Minimum changed voxel.
        lo: UVec3,
        /// Maximum changed voxel.
        hi: UVec3,
    },
    /// Nothing the consumer holds changed (a hidden model's voxels; a pose, for a renderer
    /// that reads joints every frame).
    Nothing,
    /// Everything.
    All,
}

impl Redo {
    /// What a renderer that uploads the visible models (the GPU view) redoes after a change:
    /// a visible model's voxel box; nothing for a hidden model's voxels, a pose or a camera
    /// move (frames read joints and the camera themselves); everything else in full.
    #[must_use]
    pub fn for_upload(doc: &Document, change: &Change) -> Self {
        let hidden = |id: u64| doc.objects.iter().any(|o| o.id == id && !o.visible);
        match *change {
            Change::Voxels { object, .. } if hidden(object) => Self::Nothing,
            Change::Voxels {
                object,
                region: Some((lo, hi)),
            } => Self::Region { object, lo, hi },
            Change::Pose { .. } | Change::Camera => Self::Nothing,
            _ => Self::All,
        }
    }

    /// What shadow maps kept between frames (the CPU preview's) redo after a change: a
    /// visible rigid model's voxel box is patched; a hidden model's edit changes nothing drawn;
    /// a camera move keeps the maps; anything else (a skinned model, whose voxels are drawn
    /// elsewhere than their box; a pose; a light) redraws them whole.
    #[must_use]
    pub fn for_shadow_maps(doc: &Document, change: &Change) -> Self {
        match *change {
            Change::Voxels { object, region } => {
                let Some(o) = doc.objects.iter().find(|o| o.id == object) else {
                    return Self::All;
                };
                match (&o.kind, region) {
                    _ if !o.visible => Self::Nothing,
                    (ObjectKind::Voxels(v), Some((lo, hi))) if v.rig.is_none() => {
                        Self::Region { object, lo, hi }
                    }
                    _ => Self::All,
                }
            }
            Change::Camera => Self::Nothing,
            _ => Self::All,
        }
    }
}

/// Voxel edits between two content keys: from state `from` to state `to` only the voxels of
/// `object` inside `lo..=hi` changed, or, when the box is empty (`lo > hi` on some axis),
/// nothing the consumer holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct VoxelRegion {
    /// The content key before the first edit.
    pub from: (u64, u64),
    /// The content key after the last edit.
    pub to: (u64, u64),
    /// The voxel model (meaningless for an empty box).
    pub object: u64,
    /// Minimum changed voxel.
    pub lo: UVec3,
    /// Maximum changed voxel.
    pub hi: UVec3,
}

impl VoxelRegion {
    /// Whether the box holds no voxel.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.lo.cmpgt(self.hi).any()
    }
}

/// One consumer's reading of the feed as a chain of voxel regions (each starting at the state
/// the one before ends in): a consumer that holds the document at one region's `from` state
/// brings it to the chain's end by redoing the regions from there on. Any change the consumer
/// must redo in full empties the chain.
#[derive(Debug, Clone, Default)]
pub struct RegionChain {
    regions: Vec<VoxelRegion>,
    cursor: ChangeCursor,
}

impl RegionChain {
    /// Regions kept: beyond them the oldest go (a consumer that far behind redoes all).
    pub const MAX_LEN: usize = 64;

    /// A chain that reads the changes after the feed's current end.
    #[must_use]
    pub fn from_end(feed: &ChangeFeed) -> Self {
        Self {
            regions: Vec::new(),
            cursor: feed.cursor_at_end(),
        }
    }

    /// Reads the changes since the last read, asking `redo` what each means to the consumer.
    /// Consecutive regions of one model read together merge into one box; a region already
    /// read stays as it is, since the consumer may hold the document at its end state.
    pub fn read(&mut self, feed: &ChangeFeed, redo: impl FnMut(&Change) -> Redo) {
        self.read_merging(feed, redo, false);
    }

    /// [`RegionChain::read`] for a consumer that [takes](RegionChain::take) the regions each
    /// time it redoes its work and holds no state in between (a shadow cache patched when a
    /// render starts): every region since the last take may merge.
    pub fn read_until_taken(&mut self, feed: &ChangeFeed, redo: impl FnMut(&Change) -> Redo) {
        self.read_merging(feed, redo, true);
    }

    fn read_merging(
        &mut self,
        feed: &ChangeFeed,
        mut redo: impl FnMut(&Change) -> Redo,
        across_reads: bool,
    ) {
        let entries = match feed.read(&mut self.cursor) {
            ChangesRead::Changes(entries) => entries,
            ChangesRead::Lagged => {
                self.regions.clear();
                return;
            }
        };
        // Regions before this index were read earlier: never merged into.
        let mut fresh = if across_reads { 0 } else { self.regions.len() };
        for e in entries {
            let (object, lo, hi) = match redo(&e.change) {
                Redo::All => {
                    self.regions.clear();
                    fresh = 0;
                    continue;
                }
                Redo::Nothing if e.from == e.to => continue,
                Redo::Nothing => (u64::MAX, UVec3::MAX, UVec3::ZERO),
                Redo::Region { object, lo, hi } => (object, lo, hi),
            };
            let next = VoxelRegion {
                from: e.from,
                to: e.to,
                object,
                lo,
                hi,
            };
            let mergeable = self.regions.len() > fresh;
            match self.regions.last_mut() {
                Some(last) if last.to == e.from => {
                    if mergeable && next.is_empty() {
                        last.to = next.to;
                    } else if mergeable && (last.is_empty() || last.object == next.object) {
                        *last = VoxelRegion {
                            from: last.from,
                            lo: last.lo.min(next.lo),
                            hi: last.hi.max(next.hi),
                            ..next
                        };
                    } else {
                        self.regions.push(next);
                    }
                }
                _ => {
                    self.regions.clear();
                    fresh = 0;
                    self.regions.push(next);
                }
            }
            if self.regions.len() > Self::MAX_LEN {
                self.regions.remove(0);
                fresh = fresh.saturating_sub(1);
            }
        }
    }

    /// The regions, oldest first; emptied first unless they end at content key `key` (a
    /// change the feed did not describe).
    pub fn ending_at(&mut self, key: (u64, u64)) -> &[VoxelRegion] {
        if self.regions.last().is_some_and(|r| r.to != key) {
            self.regions.clear();
        }
        &self.regions
    }

    /// Takes the regions (a consumer that redoes them once, such as a shadow cache).
    pub fn take(&mut self) -> Vec<VoxelRegion> {
        std::mem::take(&mut self.regions)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seqs(feed: &ChangeFeed, cursor: &mut ChangeCursor) -> Option<Vec<u64>> {
        match feed.read(cursor) {
            ChangesRead::Changes(it) => Some(it.map(|e| e.seq).collect()),
            ChangesRead::Lagged => None,
        }
    }

    #[test]
    fn each_cursor_reads_each_change_once_and_a_lagging_one_is_told() {
        let mut feed = ChangeFeed::default();
        let (mut a, mut b) = (feed.cursor_at_end(), feed.cursor_at_end());
        assert_eq!(seqs(&feed, &mut a), Some(vec![]));
        feed.push((0, 0), (0, 1), Change::Lights);
        feed.push((0, 1), (0, 1), Change::Camera);
        assert_eq!(seqs(&feed, &mut a), Some(vec![0, 1]));
        feed.push((0, 1), (0, 2), Change::Quality);
        assert_eq!(seqs(&feed, &mut a), Some(vec![2]));
        assert_eq!(seqs(&feed, &mut a), Some(vec![]));
        // The other consumer still sees all three, once.
        assert_eq!(seqs(&feed, &mut b), Some(vec![0, 1, 2]));
        assert_eq!(seqs(&feed, &mut b), Some(vec![]));
        // Past the capacity, a consumer that did not read is told it lagged, then reads on.
        for k in 0..ChangeFeed::CAPACITY as u64 + 1 {
            feed.push((0, k), (0, k + 1), Change::Content);
        }
        assert_eq!(seqs(&feed, &mut b), None);
        feed.push((9, 9), (9, 9), Change::Camera);
        let last = feed.len() - 1;
        assert_eq!(seqs(&feed, &mut b), Some(vec![last]));
        // A cursor from a longer feed is told it lagged, then reads on from here.
        let mut ahead = ChangeCursor {
            next: feed.len() + 5,
        };
        assert_eq!(seqs(&feed, &mut ahead), None);
        assert_eq!(seqs(&feed, &mut ahead), Some(vec![]));
        // A cursor exactly at the oldest kept change reads them all.
        let mut c = ChangeCursor {
            next: feed.entries.front().map(|e| e.seq).unwrap(),
        };
        assert_eq!(
            seqs(&feed, &mut c).map(|s| s.len()),
            Some(ChangeFeed::CAPACITY)
        );
    }

    fn region(object: u64, lo: u32, hi: u32) -> Change {
        Change::Voxels {
            object,
            region: Some((UVec3::splat(lo), UVec3::splat(hi))),
        }
    }

    /// The GPU's reading: regions of model 1 (model 2 is hidden), poses read every frame.
    fn gpu_redo(c: &Change) -> Redo {
        match *c {
            Change::Voxels {
                object: 1,
                region: Some((lo, hi)),
            } => Redo::Region { object: 1, lo, hi },
            Change::Voxels { object: 2, .. } | Change::Pose { .. } | Change::Camera => {
                Redo::Nothing
            }
            _ => Redo::All,
        }
    }

    #[test]
    fn a_chain_merges_one_models_regions_and_breaks_on_what_it_must_redo() {
        let mut feed = ChangeFeed::default();
        let mut chain = RegionChain::from_end(&feed);
        feed.push((0, 0), (0, 1), region(1, 4, 5));
        feed.push((0, 1), (0, 2), region(1, 2, 3));
        // A hidden model's edit and a pose carry the chain on; a camera move is no step.
        feed.push((0, 2), (0, 3), region(2, 0, 9));
        feed.push((0, 3), (0, 3), Change::Camera);
        feed.push((0, 3), (0, 4), Change::Pose { object: 1 });
        chain.read(&feed, gpu_redo);
        let merged = VoxelRegion {
            from: (0, 0),
            to: (0, 4),
            object: 1,
            lo: UVec3::splat(2),
            hi: UVec3::splat(5),
        };
        assert_eq!(chain.ending_at((0, 4)), &[merged]);
        // A light breaks it; the next region starts a new chain.
        feed.push((0, 4), (0, 5), Change::Lights);
        feed.push((0, 5), (0, 6), region(1, 7, 7));
        chain.read(&feed, gpu_redo);
        assert_eq!(chain.ending_at((0, 6)).len(), 1);
        assert_eq!(chain.ending_at((0, 6))[0].from, (0, 5));
        // A chain that does not end at the current state is not used.
        assert!(chain.ending_at((0, 7)).is_empty());
        // Reading again without new changes changes nothing.
        feed.push((0, 7), (0, 8), region(1, 1, 1));
        chain.read(&feed, gpu_redo);
        chain.read(&feed, gpu_redo);
        assert_eq!(chain.take().len(), 1);
        assert!(chain.take().is_empty());
        // A region read earlier is not merged into: a consumer may hold its end state (the
        // GPU drew the stroke, then the stroke is undone).
        feed.push((0, 8), (0, 9), region(1, 2, 2));
        chain.read(&feed, gpu_redo);
        feed.push((0, 9), (0, 10), region(1, 3, 3));
        feed.push((0, 10), (0, 11), Change::Pose { object: 1 });
        chain.read(&feed, gpu_redo);
        let read = chain.ending_at((0, 11)).to_vec();
        assert_eq!(
            read.iter().map(|r| (r.from, r.to)).collect::<Vec<_>>(),
            [((0, 8), (0, 9)), ((0, 9), (0, 11))]
        );
        // A consumer that holds no state between takes merges across reads.
        let mut taken = RegionChain::from_end(&feed);
        feed.push((0, 11), (0, 12), region(1, 2, 2));
        taken.read_until_taken(&feed, gpu_redo);
        feed.push((0, 12), (0, 13), region(1, 4, 4));
        taken.read_until_taken(&feed, gpu_redo);
        let merged = taken.take();
        assert_eq!(merged.len(), 1, "{merged:?}");
        assert_eq!(
            (merged[0].from, merged[0].to, merged[0].lo, merged[0].hi),
            ((0, 11), (0, 13), UVec3::splat(2), UVec3::splat(4))
        );
    }

    #[test]
    fn groups_join_to_the_narrowest_change_that_covers_them() {
        let pose = Change::Pose { object: 3 };
        let rig = Change::Rig { object: 3 };
        assert_eq!(pose.joined(pose), pose);
        assert_eq!(pose.joined(rig), rig);
        assert_eq!(rig.joined(pose), rig);
        assert_eq!(
            pose.joined(Change::Pose { object: 4 }),
            Change::Content,
            "two models' poses"
        );
        let a = Change::Voxels {
            object: 1,
            region: Some((UVec3::ZERO, UVec3::ONE)),
        };
        assert_eq!(
            a.joined(Change::Voxels {
                object: 1,
                region: Some((UVec3::splat(5), UVec3::splat(6))),
            }),
            Change::Voxels {
                object: 1,
                region: None
            }
        );
        assert_eq!(Change::Lights.joined(Change::Quality), Change::Content);
    }
}
