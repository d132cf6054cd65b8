//! Per-frame counters and stage timings.

use serde::{Deserialize, Serialize};

/// Counters for one octree level of the breadth-first traversal.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct LevelStats {
    /// Nodes taken from the queue at this level.
    pub visited: u64,
    /// Nodes whose children went into the next level's queue.
    pub split: u64,
    /// Nodes drawn as one splat.
    pub splatted: u64,
    /// Of the splatted, nodes drawn as their exact box (`Quality::cube_pixel_threshold`).
    #[serde(default)]
    pub cubes: u64,
    /// Nodes outside the view frustum.
    pub frustum_culled: u64,
    /// Nodes behind the hierarchical depth (paper §8.1.2).
    pub occlusion_culled: u64,
}

impl LevelStats {
    pub(crate) fn add(&mut self, o: &Self) {
        self.visited += o.visited;
        self.split += o.split;
        self.splatted += o.splatted;
        self.cubes += o.cubes;
        self.frustum_culled += o.frustum_culled;
        self.occlusion_culled += o.occlusion_culled;
    }
}

/// Milliseconds per stage.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct StageTimes {
    /// Octree traversal (projection, LOD, culling) for the view.
    pub traversal_ms: f64,
    /// Writing splats into depth + id for the view.
    pub splat_ms: f64,
    /// Triangle rasterisation for the view.
    pub triangles_ms: f64,
    /// Depth + id → G-buffer.
    pub resolve_ms: f64,
    /// Deferred Phong (including shadow-map lookups).
    pub shade_ms: f64,
    /// Rendering the shadow map(s): traversal, splats and triangles from the light.
    pub shadow_ms: f64,
    /// Sphere tracing KRS objects into the view (tile cones and primary rays).
    pub krs_ms: f64,
    /// Whole frame.
    pub total_ms: f64,
}

/// Lookups the shading pass made: what the shadow filter and AO knobs cost per pixel.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ShadingStats {
    /// Shadow-map reads: one per PCF tap, plus the tile bounds read to decide a whole filter
    /// window at once (where no shadow edge is near, a window costs those reads alone).
    pub shadow_taps: u64,
    /// Screen-space ambient-occlusion samples (depth-buffer reads).
    pub ao_taps: u64,
}

/// What a frame cost.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameStats {
    /// View traversal counters, index = octree level (0 = root).
    pub levels: Vec<LevelStats>,
    /// Shadow-map traversal counters, summed over lights.
    pub shadow_levels: Vec<LevelStats>,
    /// Triangles submitted for the view (before clipping and culling).
    pub triangles: u64,
    /// Triangles that produced at least one fragment candidate (passed clipping, bbox test).
    pub triangles_rasterised: u64,
    /// Pixels covered in the final image.
    pub covered_pixels: u64,
    /// View pixels written by rectangle splats (one key each).
    #[serde(default)]
    pub rect_pixels: u64,
    /// View pixels of exact cubes' rectangles: each a ray–box test unless already covered
    /// nearer (a key where it hits).
    #[serde(default)]
    pub cube_pixels: u64,
    /// The same for the shadow maps drawn this frame (not those reused from a cache).
    #[serde(default)]
    pub shadow_cube_pixels: u64,
    /// Stage timings.
    pub times: StageTimes,
    /// KRS sphere-tracing counters.
    pub krs: super::krs::KrsStats,
    /// Shading-pass lookups (`None` from a renderer that does not count them).
    #[serde(default)]
    pub shading: Option<ShadingStats>,
    /// Shadow maps taken from a [`super::ShadowCache`] instead of rendered (their traversal is
    /// then not in `shadow_levels`).
    #[serde(default)]
    pub shadow_maps_reused: u32,
    /// Cached shadow maps drawn again only where an edit changed them
    /// ([`super::ShadowCache::note_change`]); their traversal is in `shadow_levels`.
    #[serde(default)]
    pub shadow_maps_patched: u32,
    /// Texels those patches drew (the rest of each map was kept).
    #[serde(default)]
    pub shadow_texels_patched: u64,
}

impl FrameStats {
    /// View traversal totals over all levels.
    #[must_use]
    pub fn totals(&self) -> LevelStats {
        let mut t = LevelStats::default();
        for l in &self.levels {
            t.add(l);
        }
        t
    }

    /// Splats drawn for the view.
    #[must_use]
    pub fn splats(&self) -> u64 {
        self.totals().splatted
    }

    /// Nodes visited for the view.
    #[must_use]
    pub fn nodes_visited(&self) -> u64 {
        self.totals().visited
    }

    /// Zeroes every counter, keeping the level lists' allocations.
    pub(crate) fn reset(&mut self) {
        let mut levels = std::mem::take(&mut self.levels);
        let mut shadow_levels = std::mem::take(&mut self.shadow_levels);
        levels.clear();
        shadow_levels.clear();
        *self = Self {
            levels,
            shadow_levels,
            ..Self::default()
        };
    }

    pub(crate) fn merge_levels(into: &mut Vec<LevelStats>, from: &[LevelStats]) {
        if into.len() < from.len() {
            into.resize(from.len(), LevelStats::default());
        }
        for (a, b) in into.iter_mut().zip(from) {
            a.add(b);
        }
    }
}
