//! Per-node skin data for the octree: four joints and unorm8 weights, and how internal nodes
//! merge their children's weights for LOD (ASVO paper §3.3: every node, leaf or internal, is
//! skinned independently when it is drawn).

use serde::{Deserialize, Serialize};

/// Four joint indices and their weights as unorm8 (`weight / 255`), strongest first. The
/// weights of a node made by [`NodeSkin::from_weights`] or [`merge_node_skins`] sum to exactly
/// 255. 12 bytes per node.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(default)]
pub struct NodeSkin {
    /// Skeleton joint indices.
    pub joints: [u16; 4],
    /// Weights in 1/255 units.
    pub weights: [u8; 4],
}

impl Default for NodeSkin {
    fn default() -> Self {
        Self::ROOT
    }
}

impl NodeSkin {
    /// Fully bound to joint 0 (the root): what a node with no weights at all gets.
    pub const ROOT: Self = Self {
        joints: [0; 4],
        weights: [255, 0, 0, 0],
    };

    /// Weights as floats summing to 1 (when the bytes sum to 255).
    #[inline]
    #[must_use]
    pub fn weights_f32(&self) -> [f32; 4] {
        self.weights.map(|w| f32::from(w) * (1.0 / 255.0))
    }

    /// Number of non-zero weights (the paper's W).
    #[inline]
    #[must_use]
    pub fn nonzero_count(&self) -> u32 {
        self.weights.iter().filter(|&&w| w > 0).count() as u32
    }

    /// From `(joint, weight)` pairs (any number, duplicates summed): keeps the four strongest,
    /// renormalises and quantises so the bytes sum to 255. Negative and non-finite weights are
    /// dropped; nothing left gives [`NodeSkin::ROOT`]. Ties go to the lower joint index so the
    /// result is deterministic.
    #[must_use]
    pub fn from_weights(pairs: impl IntoIterator<Item = (u16, f32)>) -> Self {
        let mut acc = Accumulator::default();
        for (j, w) in pairs {
            acc.add(j, w);
        }
        acc.finish()
    }

    /// From one vertex's (or one surface point's) four joints and float weights.
    #[must_use]
    pub fn from_vertex(joints: [u16; 4], weights: [f32; 4]) -> Self {
        Self::from_weights(joints.into_iter().zip(weights))
    }
}

/// Merges the children of an internal node (1–8 of them): sums each joint's weight over the
/// children, keeps the four strongest, renormalises. An empty list gives [`NodeSkin::ROOT`].
#[must_use]
pub fn merge_node_skins(children: &[NodeSkin]) -> NodeSkin {
    let mut acc = Accumulator::default();
    for c in children {
        for k in 0..4 {
            acc.add(c.joints[k], f32::from(c.weights[k]));
        }
    }
    acc.finish()
}

/// Sums weights per joint without allocating for up to 32 distinct joints (8 children × 4),
/// spilling to a `Vec` beyond that.
#[derive(Default)]
struct Accumulator {
    fixed: [(u16, f32); 32],
    len: usize,
    spill: Vec<(u16, f32)>,
}

impl Accumulator {
    fn add(&mut self, joint: u16, w: f32) {
        if !(w.is_finite() && w > 0.0) {
            return;
        }
        if let Some(e) = self.fixed[..self.len].iter_mut().find(|e| e.0 == joint) {
            e.1 += w;
        } else if let Some(e) = self.spill.iter_mut().find(|e| e.0 == joint) {
            e.1 += w;
        } else if self.len < self.fixed.len() {
            self.fixed[self.len] = (joint, w);
            self.len += 1;
        } else {
            self.spill.push((joint, w));
        }
    }

    fn finish(mut self) -> NodeSkin {
        let mut top = [(0u16, 0.0f32); 4];
        let entries = self.fixed[..self.len].iter().chain(self.spill.iter());
        for &(j, w) in entries {
            // Insertion into a sorted top-4: heavier first, lower joint first on ties.
            let better = |a: (u16, f32), b: (u16, f32)| a.1 > b.1 || (a.1 == b.1 && a.0 < b.0);
            if !better((j, w), top[3]) {
                continue;
            }
            top[3] = (j, w);
            let mut k = 3;
            while k > 0 && better(top[k], top[k - 1]) {
                top.swap(k, k - 1);
                k -= 1;
            }
        }
        self.len = 0;
        let sum: f32 = top.iter().map(|e| e.1).sum();
        if !(sum > 0.0 && sum.is_finite()) {
            return NodeSkin::ROOT;
        }
        // Largest-remainder quantisation: floors, then hand the missing units to the largest
        // remainders, so the bytes sum to exactly 255.
        let scaled = top.map(|e| e.1 / sum * 255.0);
        let mut bytes = scaled.map(|s| s.floor().clamp(0.0, 255.0) as u8);
        let mut missing = 255 - bytes.iter().map(|&b| u32::from(b)).sum::<u32>().min(255);
        let mut order = [0usize, 1, 2, 3];
        order.sort_by(|&a, &b| {
            let ra = scaled[a] - scaled[a].floor();
            let rb = scaled[b] - scaled[b].floor();
            rb.total_cmp(&ra).then(a.cmp(&b))
        });
        for &k in order.iter().cycle().take(8) {
            if missing == 0 {
                break;
            }
            if top[k].1 > 0.0 && bytes[k] < 255 {
                bytes[k] += 1;
                missing -= 1;
            }
        }
        let mut joints = top.map(|e| e.0);
        for k in 0..4 {
            if bytes[k] == 0 {
                joints[k] = 0;
            }
        }
        NodeSkin {
            joints,
            weights: bytes,
        }
    }
}
