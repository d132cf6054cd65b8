//! Watertight skinned export (issue 21): the exported cube surface must stay closed in every
//! pose. These tests skin the written file with an implementation of their own — the `gltf`
//! crate's parser, glTF's node hierarchy, animation sampling (STEP, LINEAR with slerp,
//! CUBICSPLINE), inverse bind matrices and the file's `JOINTS_0` / `WEIGHTS_0` — and share
//! nothing with `core::skin` but the file, so a bug in the project's skinning cannot hide one in
//! the export.
//!
//! Two ways a posed voxel surface opens:
//! * a *shared position*: vertices of different quads at one bind-pose point skin apart when
//!   they carry different weights;
//! * a *T-junction*: a vertex lying inside another quad's edge skins off that edge when the
//!   edge's own end points do not move the way the vertex does.
//!
//! `cargo test -p thicket-core --lib io::gltf_export::watertight_tests::the_cesiumman_sample -- \
//! --nocapture` prints both figures for the editor's CesiumMan sample (depth 8) at 0.6 s.

use std::collections::HashMap;
use std::path::Path;

use glam::{Mat4, Quat, UVec3, Vec3, Vec4};

use super::greedy::{Quad, count_faces, greedy_quads};
use super::{GltfExportOptions, export_gltf};
use crate::scene::{Document, ObjectKind, Transform};
use crate::skin::{
    AnimationClip, Channel, Interpolation, Joint, Property, Rig, Skeleton, Skin4, SkinTables,
};
use crate::svo::{Svo, Voxel};

const CESIUM_MAN: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/assets/skinned/CesiumMan.glb"
);
const RIGGED_FIGURE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/assets/skinned/RiggedFigure.glb"
);

/// One animation channel as the file stores it.
struct FileChannel {
    node: usize,
    property: gltf::animation::Property,
    interpolation: gltf::animation::Interpolation,
    times: Vec<f32>,
    /// xyz (translation, scale) or xyzw (rotation); three per key for CUBICSPLINE.
    values: Vec<Vec4>,
}

/// A skinned mesh read straight from a glTF file: everything needed to pose it.
struct FileSkin {
    /// Bind-pose positions of every vertex of the skinned mesh (all primitives, in order).
    positions: Vec<Vec3>,
    joints: Vec<[u16; 4]>,
    weights: Vec<[f32; 4]>,
    /// Triangles as indices into `positions`.
    triangles: Vec<[usize; 3]>,
    /// Per node: parent and rest transform (TRS; a matrix node is never animated).
    parents: Vec<Option<usize>>,
    rest: Vec<(Vec3, Quat, Vec3)>,
    matrices: Vec<Option<Mat4>>,
    /// Per skin joint: its node and inverse bind matrix.
    joint_nodes: Vec<usize>,
    inverse_bind: Vec<Mat4>,
    /// The first animation's channels.
    channels: Vec<FileChannel>,
}

impl FileSkin {
    fn read(path: &Path) -> Self {
        let (doc, buffers, _) = gltf::import(path).expect("the export parses as glTF");
        let data = |b: gltf::Buffer<'_>| Some(&buffers[b.index()][..]);
        let node = doc
            .nodes()
            .find(|n| n.skin().is_some() && n.mesh().is_some())
            .expect("a skinned mesh node");
        let skin = node.skin().expect("skin");
        let mesh = node.mesh().expect("mesh");
        let mut positions = Vec::new();
        let mut joints = Vec::new();
        let mut weights = Vec::new();
        let mut triangles = Vec::new();
        for p in mesh.primitives() {
            let r = p.reader(data);
            let base = positions.len();
            positions.extend(r.read_positions().expect("POSITION").map(Vec3::from_array));
            joints.extend(r.read_joints(0).expect("JOINTS_0").into_u16());
            weights.extend(r.read_weights(0).expect("WEIGHTS_0").into_f32());
            let idx: Vec<u32> = r.read_indices().expect("indices").into_u32().collect();
            triangles.extend(
                idx.chunks_exact(3)
                    .map(|t| [0, 1, 2].map(|k| base + t[k] as usize)),
            );
        }
        assert_eq!(joints.len(), positions.len());
        assert_eq!(weights.len(), positions.len());
        let n = doc.nodes().len();
        let mut parents = vec![None; n];
        let mut rest = vec![(Vec3::ZERO, Quat::IDENTITY, Vec3::ONE); n];
        let mut matrices = vec![None; n];
        for nd in doc.nodes() {
            for c in nd.children() {
                parents[c.index()] = Some(nd.index());
            }
            match nd.transform() {
                gltf::scene::Transform::Matrix { matrix } => {
                    matrices[nd.index()] = Some(Mat4::from_cols_array_2d(&matrix));
                }
                gltf::scene::Transform::Decomposed {
                    translation,
                    rotation,
                    scale,
                } => {
                    rest[nd.index()] = (
                        Vec3::from_array(translation),
                        Quat::from_array(rotation),
                        Vec3::from_array(scale),
                    );
                }
            }
        }
        let joint_nodes: Vec<usize> = skin.joints().map(|j| j.index()).collect();
        let inverse_bind: Vec<Mat4> = skin
            .reader(data)
            .read_inverse_bind_matrices()
            .expect("inverse bind matrices")
            .map(|m| Mat4::from_cols_array_2d(&m))
            .collect();
        assert_eq!(inverse_bind.len(), joint_nodes.len());
        let mut channels = Vec::new();
        if let Some(anim) = doc.animations().next() {
            for ch in anim.channels() {
                let r = ch.reader(data);
                let times: Vec<f32> = r.read_inputs().expect("key times").collect();
                let values: Vec<Vec4> = match r.read_outputs().expect("key values") {
                    gltf::animation::util::ReadOutputs::Translations(it)
                    | gltf::animation::util::ReadOutputs::Scales(it) => {
                        it.map(|v| Vec3::from_array(v).extend(0.0)).collect()
                    }
                    gltf::animation::util::ReadOutputs::Rotations(it) => {
                        it.into_f32().map(Vec4::from_array).collect()
                    }
                    gltf::animation::util::ReadOutputs::MorphTargetWeights(_) => continue,
                };
                channels.push(FileChannel {
                    node: ch.target().node().index(),
                    property: ch.target().property(),
                    interpolation: ch.sampler().interpolation(),
                    times,
                    values,
                });
            }
        }
        Self {
            positions,
            joints,
            weights,
            triangles,
            parents,
            rest,
            matrices,
            joint_nodes,
            inverse_bind,
            channels,
        }
    }

    /// glTF §3.11 sampling: clamped to the key range, STEP holds, LINEAR lerps (slerps
    /// rotations), CUBICSPLINE is the Hermite spline over (in-tangent, value, out-tangent).
    fn sample(ch: &FileChannel, t: f32) -> Vec4 {
        use gltf::animation::Interpolation as I;
        let cubic = ch.interpolation == I::CubicSpline;
        let value = |k: usize| {
            if cubic {
                ch.values[3 * k + 1]
            } else {
                ch.values[k]
            }
        };
        let last = ch.times.len() - 1;
        if t <= ch.times[0] {
            return value(0);
        }
        if t >= ch.times[last] {
            return value(last);
        }
        let k = ch.times.partition_point(|&x| x <= t) - 1;
        let dt = ch.times[k + 1] - ch.times[k];
        let s = if dt > 0.0 {
            (t - ch.times[k]) / dt
        } else {
            0.0
        };
        let rotation = ch.property == gltf::animation::Property::Rotation;
        match ch.interpolation {
            I::Step => value(k),
            I::Linear if rotation => {
                let a = Quat::from_vec4(value(k)).normalize();
                let mut b = Quat::from_vec4(value(k + 1)).normalize();
                if a.dot(b) < 0.0 {
                    b = -b;
                }
                Vec4::from(a.slerp(b, s))
            }
            I::Linear => value(k).lerp(value(k + 1), s),
            I::CubicSpline => {
                let (p0, m0) = (ch.values[3 * k + 1], ch.values[3 * k + 2] * dt);
                let (p1, m1) = (ch.values[3 * (k + 1) + 1], ch.values[3 * (k + 1)] * dt);
                let (s2, s3) = (s * s, s * s * s);
                let v = p0 * (2.0 * s3 - 3.0 * s2 + 1.0)
                    + m0 * (s3 - 2.0 * s2 + s)
                    + p1 * (-2.0 * s3 + 3.0 * s2)
                    + m1 * (s3 - s2);
                if rotation {
                    Vec4::from(Quat::from_vec4(v).normalize())
                } else {
                    v
                }
            }
        }
    }

    /// `world_from_joint · inverse_bind` per skin joint at clip time `t`.
    fn joint_matrices(&self, t: f32) -> Vec<Mat4> {
        let mut trs = self.rest.clone();
        for ch in &self.channels {
            let v = Self::sample(ch, t);
            let slot = &mut trs[ch.node];
            match ch.property {
                gltf::animation::Property::Translation => slot.0 = v.truncate(),
                gltf::animation::Property::Rotation => slot.1 = Quat::from_vec4(v).normalize(),
                gltf::animation::Property::Scale => slot.2 = v.truncate(),
                gltf::animation::Property::MorphTargetWeights => {}
            }
        }
        let local: Vec<Mat4> = (0..trs.len())
            .map(|i| {
                self.matrices[i].unwrap_or_else(|| {
                    let (t, r, s) = trs[i];
                    Mat4::from_scale_rotation_translation(s, r.normalize(), t)
                })
            })
            .collect();
        let world = |mut i: usize| {
            let mut m = local[i];
            while let Some(p) = self.parents[i] {
                m = local[p] * m;
                i = p;
            }
            m
        };
        self.joint_nodes
            .iter()
            .zip(&self.inverse_bind)
            .map(|(&n, ibm)| world(n) * *ibm)
            .collect()
    }

    /// Every vertex skinned at `t` with its own joints and weights.
    fn skinned(&self, t: f32) -> Vec<Vec3> {
        let m = self.joint_matrices(t);
        (0..self.positions.len())
            .map(|i| {
                let mut blend = Mat4::ZERO;
                for k in 0..4 {
                    blend += m[usize::from(self.joints[i][k])] * self.weights[i][k];
                }
                blend.transform_point3(self.positions[i])
            })
            .collect()
    }

    fn duration(&self) -> f32 {
        self.channels
            .iter()
            .filter_map(|c| c.times.last().copied())
            .fold(0.0, f32::max)
    }

    /// The edge of one voxel in bind-pose file units: the shortest axis-aligned triangle edge
    /// (one voxel as long as any face is left unmerged, as on the characters).
    fn bind_voxel_size(&self) -> f32 {
        let mut best = f32::INFINITY;
        for t in &self.triangles {
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                let d = self.positions[b] - self.positions[a];
                let nonzero = d.to_array().iter().filter(|c| c.abs() > 0.0).count();
                if nonzero == 1 {
                    best = best.min(d.abs().max_element());
                }
            }
        }
        best
    }
}

/// How far a posed export is from closed.
#[derive(Debug, Default)]
struct Cracks {
    /// Distinct bind-pose positions where two or more triangle corners meet.
    shared: usize,
    /// Of them, those whose vertices end up more than one (posed) voxel apart.
    over_one_voxel: usize,
    /// Largest distance between two vertices of one shared position.
    max_shared: f32,
    /// (vertex, edge) pairs where the vertex lies strictly inside the edge at bind pose.
    t_junctions: usize,
    /// Largest distance of such a vertex from its posed edge.
    max_t_junction: f32,
    /// Diagonal of the posed mesh's bounding box.
    model_size: f32,
    /// One voxel's edge in posed units.
    voxel: f32,
}

fn distance_to_segment(p: Vec3, a: Vec3, b: Vec3) -> f32 {
    let ab = b - a;
    let s = if ab.length_squared() > 0.0 {
        ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    p.distance(a + ab * s)
}

fn diagonal(points: &[Vec3]) -> f32 {
    let (lo, hi) = points
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        });
    lo.distance(hi)
}

fn cracks(file: &FileSkin, t: f32) -> Cracks {
    let posed = file.skinned(t);
    let model_size = diagonal(&posed);
    // A voxel's posed edge: the bind edge times the joints' typical scale (the median cube
    // root of their determinants; 1 for rigid joints), so the unit does not change with how
    // the pose happens to stretch the bounding box.
    let mut scales: Vec<f32> = file
        .joint_matrices(t)
        .iter()
        .map(|m| glam::Mat3::from_mat4(*m).determinant().abs().cbrt())
        .collect();
    scales.sort_by(f32::total_cmp);
    let voxel = file.bind_voxel_size() * scales[scales.len() / 2];
    let mut out = Cracks {
        model_size,
        voxel,
        ..Cracks::default()
    };
    // Triangle corners by bind-pose position: (corners, the distinct vertices they use). A
    // welded export holds one vertex where equal ones met, so the corners count the meeting.
    let mut at: HashMap<[u32; 3], (usize, Vec<usize>)> = HashMap::new();
    for &i in file.triangles.iter().flatten() {
        let entry = at
            .entry(file.positions[i].to_array().map(f32::to_bits))
            .or_default();
        entry.0 += 1;
        if !entry.1.contains(&i) {
            entry.1.push(i);
        }
    }
    for (_, group) in at.values().filter(|g| g.0 > 1) {
        out.shared += 1;
        let mut spread = 0.0f32;
        for (k, &a) in group.iter().enumerate() {
            for &b in &group[k + 1..] {
                spread = spread.max(posed[a].distance(posed[b]));
            }
        }
        out.max_shared = out.max_shared.max(spread);
        if spread > voxel {
            out.over_one_voxel += 1;
        }
    }
    // Axis-aligned edges by the line they lie on: (axis, the other two coordinates) →
    // (lowest and highest coordinate along the axis, end vertices).
    type Edge = (f32, f32, usize, usize);
    let mut lines: HashMap<(usize, [u32; 2]), Vec<Edge>> = HashMap::new();
    for tri in &file.triangles {
        for (a, b) in [(tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])] {
            let (pa, pb) = (file.positions[a], file.positions[b]);
            let same: Vec<usize> = (0..3).filter(|&k| pa[k] == pb[k]).collect();
            if same.len() != 2 {
                continue;
            }
            let axis = 3 - same[0] - same[1];
            let key = (axis, [pa[same[0]].to_bits(), pa[same[1]].to_bits()]);
            let (lo, hi) = (pa[axis].min(pb[axis]), pa[axis].max(pb[axis]));
            lines.entry(key).or_default().push((lo, hi, a, b));
        }
    }
    for (i, p) in file.positions.iter().enumerate() {
        for axis in 0..3 {
            let (o1, o2) = ((axis + 1) % 3, (axis + 2) % 3);
            let (s0, s1) = (o1.min(o2), o1.max(o2));
            let Some(edges) = lines.get(&(axis, [p[s0].to_bits(), p[s1].to_bits()])) else {
                continue;
            };
            for &(lo, hi, a, b) in edges {
                if lo < p[axis] && p[axis] < hi {
                    out.t_junctions += 1;
                    let gap = distance_to_segment(posed[i], posed[a], posed[b]);
                    out.max_t_junction = out.max_t_junction.max(gap);
                }
            }
        }
    }
    out
}

/// Worst crack figures over `samples` times spread over the clip (0 and the end included).
fn worst_cracks(file: &FileSkin, samples: usize) -> Cracks {
    let d = file.duration();
    let mut worst = Cracks::default();
    for k in 0..samples {
        let t = d * k as f32 / (samples - 1).max(1) as f32;
        let c = cracks(file, t);
        if c.max_shared.max(c.max_t_junction) / c.model_size
            >= worst.max_shared.max(worst.max_t_junction) / worst.model_size.max(f32::MIN_POSITIVE)
        {
            worst = c;
        }
    }
    worst
}

fn assert_closed(path: &Path, what: &str) {
    let file = FileSkin::read(path);
    assert!(!file.channels.is_empty(), "{what}: the export is animated");
    // The cause, checked directly: one (JOINTS_0, WEIGHTS_0) per bind-pose position.
    let mut skin_at: HashMap<[u32; 3], ([u16; 4], [u32; 4])> = HashMap::new();
    for (i, p) in file.positions.iter().enumerate() {
        let skin = (file.joints[i], file.weights[i].map(f32::to_bits));
        let first = *skin_at
            .entry(p.to_array().map(f32::to_bits))
            .or_insert(skin);
        assert_eq!(
            first, skin,
            "{what}: two vertices at {p} carry different weights"
        );
    }
    let c = worst_cracks(&file, 7);
    eprintln!("{what}: {c:?}");
    assert!(c.shared > 1000, "{what}: {c:?}");
    let tolerance = 1e-4 * c.model_size;
    assert!(
        c.max_shared <= tolerance,
        "{what}: vertices of one bind-pose position separate by {} ({:.2} voxels; model {}): {c:?}",
        c.max_shared,
        c.max_shared / c.voxel,
        c.model_size
    );
    assert!(
        c.max_t_junction <= tolerance,
        "{what}: a vertex inside another quad's edge leaves it by {}: {c:?}",
        c.max_t_junction
    );
}

fn skinned_doc(path: &str, depth: u8) -> Document {
    let mut doc = crate::skin::deform_tests::skinned_doc(path, depth);
    // A placement, so the skeleton's root node carries a transform too.
    doc.objects[0].transform = Transform {
        translation: Vec3::new(1.0, -2.0, 0.5),
        rotation: Quat::from_rotation_y(0.7),
        scale: Vec3::splat(1.5),
    };
    doc
}

fn export(doc: &Document, dir: &Path, name: &str) -> std::path::PathBuf {
    let path = dir.join(name);
    export_gltf(doc, &path, &GltfExportOptions::default(), &|_| true).expect("exports");
    path
}

#[test]
fn cesium_man_stays_closed_while_it_walks() {
    let dir = tempfile::tempdir().expect("temp dir");
    let doc = skinned_doc(CESIUM_MAN, 6);
    assert_closed(&export(&doc, dir.path(), "cesium.glb"), "CesiumMan");
}

#[test]
fn rigged_figure_stays_closed_while_it_moves() {
    let dir = tempfile::tempdir().expect("temp dir");
    let doc = skinned_doc(RIGGED_FIGURE, 6);
    assert_closed(&export(&doc, dir.path(), "figure.glb"), "RiggedFigure");
}

/// A bar of 8×2×2 voxels: the left half bound to joint 0, the right half to joint 1 (a hinge
/// at x = 4, bent 90° by the clip). Per-voxel weights tear it open at the hinge.
fn hinged_bar() -> Document {
    let leaves = (0..32u32).map(|i| {
        let c = UVec3::new(i % 8, (i / 8) % 2, i / 16);
        let mut v = Voxel::new([200, 200, 200, 255], Vec3::Y);
        v.skin = Skin4 {
            joints: [u8::from(c.x >= 4), 0, 0, 0],
            weights: [255, 0, 0, 0],
        };
        (c, v)
    });
    let svo = Svo::from_voxels(3, true, leaves).expect("bar");
    let hinge = Vec3::new(4.0, 0.0, 0.0);
    let (skeleton, _) = Skeleton::new(vec![
        Joint {
            name: "left".to_owned(),
            ..Joint::default()
        },
        Joint {
            name: "right".to_owned(),
            parent: Some(0),
            rest: crate::skin::Transform {
                translation: hinge,
                ..crate::skin::Transform::IDENTITY
            },
            inverse_bind: Mat4::from_translation(-hinge),
            ..Joint::default()
        },
    ])
    .expect("skeleton");
    let bend = Quat::from_rotation_z(std::f32::consts::FRAC_PI_2);
    let clip = AnimationClip {
        name: "bend".to_owned(),
        duration_secs: 1.0,
        channels: vec![Channel {
            joint: 1,
            property: Property::Rotation,
            interpolation: Interpolation::Linear,
            times: vec![0.0, 1.0],
            values: vec![Vec4::from(Quat::IDENTITY), Vec4::from(bend)],
        }],
        ..AnimationClip::default()
    };
    let rig = Rig::new(skeleton, vec![clip]);
    let mut doc = Document::default();
    doc.add(
        "bar",
        ObjectKind::Voxels(crate::scene::VoxelModel {
            svo,
            voxel_size: 1.0,
            origin: Vec3::ZERO,
            material_names: Vec::new(),
            rig: Some(rig),
            volume: None,
            palette: Vec::new(),
            frames: None,
        }),
    );
    doc
}

#[test]
fn a_hinged_bar_bends_without_tearing_at_the_hinge() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = export(&hinged_bar(), dir.path(), "bar.glb");
    let file = FileSkin::read(&path);
    let c = cracks(&file, 1.0);
    eprintln!("bar at 90°: {c:?}");
    assert!(
        c.max_shared <= 1e-4 * c.model_size && c.max_t_junction <= 1e-4 * c.model_size,
        "the bar tears at its hinge: {c:?}"
    );
    // And it does bend: the far end has swung round the hinge.
    let posed = file.skinned(1.0);
    let far = file
        .positions
        .iter()
        .position(|p| p.x == 8.0)
        .expect("a vertex at the far end");
    assert!(posed[far].y > 3.0, "{:?}", posed[far]);
}

/// A figure boxed in voxels and rigged natively (skeleton spec, geodesic binding, a clip of
/// Euler keys, as `thicket rig` and `thicket animate` make it): two legs swinging and bending
/// under a body with arms.
fn natively_rigged_figure() -> Document {
    use crate::render::scenes::{BoxFigure, box_figure};
    box_figure(&BoxFigure {
        name: "figure",
        boxes: &[
            ([2, 0, 2], [6, 12, 6]),
            ([9, 0, 2], [13, 12, 6]),
            ([1, 12, 1], [14, 26, 7]),
            ([14, 14, 3], [22, 17, 5]),
        ],
        depth: 5,
        voxel_size: 0.05,
        origin: Vec3::new(-0.35, 0.0, -0.2),
        interior: false,
        color: |_| [180, 90, 60, 255],
        joints: &[
            ("hip", None, [7.5, 12.0, 4.0]),
            ("chest", Some("hip"), [7.5, 22.0, 4.0]),
            ("arm", Some("chest"), [14.0, 15.5, 4.0]),
            ("hand", Some("arm"), [21.0, 15.5, 4.0]),
            ("leg.R", Some("hip"), [4.0, 11.0, 4.0]),
            ("shin.R", Some("leg.R"), [4.0, 6.0, 4.0]),
            ("leg.L", Some("hip"), [11.0, 11.0, 4.0]),
            ("shin.L", Some("leg.L"), [11.0, 6.0, 4.0]),
        ],
        method: crate::skin::bind::BindMethod::Geodesic,
        keys: &[
            ("leg.R", 0.0, [30.0, 0.0, 0.0]),
            ("leg.R", 0.5, [-30.0, 0.0, 0.0]),
            ("leg.L", 0.0, [-30.0, 0.0, 0.0]),
            ("leg.L", 0.5, [30.0, 0.0, 0.0]),
            ("shin.R", 0.25, [45.0, 0.0, 0.0]),
            ("shin.L", 0.75, [45.0, 0.0, 0.0]),
            ("arm", 0.5, [0.0, 20.0, -60.0]),
        ],
        interpolation: crate::skin::author::KeyInterpolation::Cubic,
    })
}

#[test]
fn a_natively_rigged_figure_stays_closed_while_it_walks() {
    let dir = tempfile::tempdir().expect("temp dir");
    let doc = natively_rigged_figure();
    assert_closed(&export(&doc, dir.path(), "native.glb"), "native figure");
}

/// Merged weights of the leaves touching each lattice point, by brute force: the definition
/// the export's corner weights must follow.
fn lattice_skins(svo: &Svo) -> HashMap<UVec3, Skin4> {
    let mut around: HashMap<UVec3, Vec<Skin4>> = HashMap::new();
    svo.for_each_leaf(|c, v| {
        for k in 0..8u32 {
            let p = c + UVec3::new(k & 1, (k >> 1) & 1, (k >> 2) & 1);
            around.entry(p).or_default().push(v.skin);
        }
    });
    around
        .into_iter()
        .map(|(p, s)| (p, Skin4::merge(&s)))
        .collect()
}

/// The lattice point of a quad at (u, v) in its slice.
fn lattice_point(q: &Quad, u: u32, v: u32) -> UVec3 {
    let a = usize::from(q.axis);
    let mut p = UVec3::ZERO;
    p[a] = q.layer;
    p[(a + 1) % 3] = u;
    p[(a + 2) % 3] = v;
    p
}

#[test]
fn quads_carry_lattice_weights_and_merge_only_where_they_are_equal() {
    let doc = skinned_doc(CESIUM_MAN, 6);
    let ObjectKind::Voxels(model) = &doc.objects[0].kind else {
        panic!("voxels")
    };
    let lattice = lattice_skins(&model.svo);
    // The editor's `Corners` stretch strategy derives its corner weights the same way.
    let tables = SkinTables::build(&model.svo);
    let mut stack = vec![model.svo.root()];
    let mut leaves = 0;
    while let Some(n) = stack.pop() {
        if model.svo.is_leaf(&n) {
            let corners = tables
                .leaf_corner_skins(n.index)
                .expect("a leaf of the octree");
            for (k, c) in corners.iter().enumerate() {
                let k = k as u32;
                let p = n.origin + UVec3::new(k & 1, (k >> 1) & 1, (k >> 2) & 1);
                assert_eq!(lattice[&p], *c, "corner {p} of leaf {}", n.origin);
            }
            leaves += 1;
            continue;
        }
        stack.extend((0..8).filter_map(|k| model.svo.child(&n, k)));
    }
    assert!(leaves > 1000);
    let quads = greedy_quads(&model.svo);
    let mut merged = 0;
    for q in &quads {
        let s = q.skins;
        let ends = [
            (q.u, q.v),
            (q.u + q.width, q.v),
            (q.u + q.width, q.v + q.height),
        ];
        for (k, &(u, v)) in ends.iter().chain(&[(q.u, q.v + q.height)]).enumerate() {
            assert_eq!(s[k], lattice[&lattice_point(q, u, v)], "{q:?}");
        }
        if q.width * q.height > 1 {
            merged += 1;
            for v in q.v..=q.v + q.height {
                for u in q.u..=q.u + q.width {
                    assert_eq!(
                        lattice[&lattice_point(q, u, v)],
                        s[0],
                        "merged quad {q:?} covers a lattice point with other weights"
                    );
                }
            }
        }
    }
    assert!(merged > 0, "some quads merge");
    let faces = count_faces(&model.svo);
    eprintln!(
        "CesiumMan depth 6: {} outward faces ({} sealed left out) → {} quads ({merged} merged), \
         {:.3}×",
        faces.exposed,
        faces.sealed,
        quads.len(),
        faces.exposed as f64 / quads.len() as f64
    );
}

/// Exposed faces by brute force: each solid voxel's faces toward an empty voxel that a flood
/// fill from outside the grid reaches (six-connected), as (voxel, axis, positive).
fn outward_faces(svo: &Svo) -> std::collections::BTreeSet<([u32; 3], u8, bool)> {
    let n = i64::from(svo.extent()) + 2;
    let solid: std::collections::HashSet<UVec3> = svo.leaves().into_iter().map(|l| l.0).collect();
    // Cells of a grid one larger on every side, so the flood starts outside.
    let idx = |x: i64, y: i64, z: i64| ((z * n + y) * n + x) as usize;
    let is_solid = |x: i64, y: i64, z: i64| {
        (1..n - 1).contains(&x)
            && (1..n - 1).contains(&y)
            && (1..n - 1).contains(&z)
            && solid.contains(&UVec3::new(x as u32 - 1, y as u32 - 1, z as u32 - 1))
    };
    let mut outside = vec![false; (n * n * n) as usize];
    let mut queue = vec![(0i64, 0i64, 0i64)];
    outside[0] = true;
    while let Some((x, y, z)) = queue.pop() {
        for d in [
            (1, 0, 0),
            (-1, 0, 0),
            (0, 1, 0),
            (0, -1, 0),
            (0, 0, 1),
            (0, 0, -1),
        ] {
            let (a, b, c) = (x + d.0, y + d.1, z + d.2);
            if a < 0 || b < 0 || c < 0 || a >= n || b >= n || c >= n {
                continue;
            }
            if !outside[idx(a, b, c)] && !is_solid(a, b, c) {
                outside[idx(a, b, c)] = true;
                queue.push((a, b, c));
            }
        }
    }
    let mut out = std::collections::BTreeSet::new();
    for c in &solid {
        for axis in 0..3u8 {
            for positive in [false, true] {
                let mut p = c.as_i64vec3() + 1;
                p[usize::from(axis)] += if positive { 1 } else { -1 };
                if outside[idx(p.x, p.y, p.z)] {
                    out.insert((c.to_array(), axis, positive));
                }
            }
        }
    }
    out
}

/// The unit faces a quad covers, as (voxel behind it, axis, positive).
fn covered(q: &Quad) -> impl Iterator<Item = ([u32; 3], u8, bool)> + '_ {
    let a = usize::from(q.axis);
    (0..q.height).flat_map(move |dv| {
        (0..q.width).map(move |du| {
            let mut c = [0u32; 3];
            c[(a + 1) % 3] = q.u + du;
            c[(a + 2) % 3] = q.v + dv;
            c[a] = if q.positive { q.layer - 1 } else { q.layer };
            (c, q.axis, q.positive)
        })
    })
}

fn assert_only_outward_faces(svo: &Svo, what: &str) -> usize {
    let want = outward_faces(svo);
    let mut got = std::collections::BTreeSet::new();
    for q in greedy_quads(svo) {
        for f in covered(&q) {
            assert!(got.insert(f), "{what}: two quads cover {f:?}");
        }
    }
    let extra: Vec<_> = got.difference(&want).take(5).collect();
    let missing: Vec<_> = want.difference(&got).take(5).collect();
    assert!(
        extra.is_empty() && missing.is_empty(),
        "{what}: {} faces exported, {} face outside; sealed or solid-facing faces written: \
         {extra:?}; outward faces missing: {missing:?}",
        got.len(),
        want.len()
    );
    let counts = count_faces(svo);
    assert_eq!(counts.exposed, want.len() as u64, "{what}");
    counts.sealed as usize
}

#[test]
fn no_exported_face_lies_between_solid_voxels_or_inside_a_sealed_cavity() {
    // A 6³ box with a sealed 4³ cavity: 96 faces face the cavity, 216 the outside.
    let shell: Vec<UVec3> = (0..216u32)
        .map(|i| UVec3::new(i % 6, (i / 6) % 6, i / 36))
        .filter(|c| c.min_element() == 0 || c.max_element() == 5)
        .map(|c| c + 1)
        .collect();
    let svo = Svo::from_voxels(
        4,
        false,
        shell
            .iter()
            .map(|&c| (c, Voxel::new([9, 9, 9, 255], Vec3::Y))),
    )
    .expect("shell");
    assert_eq!(assert_only_outward_faces(&svo, "sealed box"), 96);
    assert_eq!(greedy_quads(&svo).len(), 6, "six outer walls");
    // A hole in one wall opens the cavity: its faces are outward again.
    let mut open = svo.clone();
    open.remove(UVec3::new(3, 3, 1)).expect("in range");
    assert_eq!(assert_only_outward_faces(&open, "open box"), 0);
    // The surface-voxelized characters: a closed shell around an empty inside.
    for (path, name) in [(CESIUM_MAN, "CesiumMan"), (RIGGED_FIGURE, "RiggedFigure")] {
        let doc = crate::skin::deform_tests::skinned_doc(path, 6);
        let ObjectKind::Voxels(model) = &doc.objects[0].kind else {
            panic!("voxels")
        };
        let sealed = assert_only_outward_faces(&model.svo, name);
        eprintln!("{name} depth 6: {sealed} sealed faces left out");
    }
}

/// The editor's CesiumMan sample (depth 8) exported as it ships: no shared position opens and
/// no T-junction gap appears at t = 0.6 s (mid-stride). Prints the figures quoted in
/// docs/export.md.
#[test]
fn the_cesiumman_sample_exports_without_cracks_mid_stride() {
    let t = 0.6f32;
    let dir = tempfile::tempdir().expect("temp dir");
    let project = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../projects/cesiumman.thicket.json"
    );
    let doc = crate::io::project::load(Path::new(project)).expect("the sample loads");
    let path = dir.path().join("cesiumman.glb");
    let report =
        export_gltf(&doc, &path, &GltfExportOptions::default(), &|_| true).expect("exports");
    for f in &report.voxel_faces {
        println!(
            "{:?}: {} outward faces ({} sealed left out) merged into {} quads ({:.3}×)",
            f.object,
            f.exposed,
            f.sealed,
            f.quads,
            f.exposed as f64 / f.quads as f64
        );
    }
    let file = FileSkin::read(&path);
    let c = cracks(&file, t);
    println!(
        "{}: t = {t} s: {} shared positions, {} ({:.2} %) separate by more than one voxel \
         ({:.5}); largest {:.3e} ({:.2} voxels, {:.2e} of the model's {:.3}); {} T-junctions, \
         largest gap {:.3e} ({:.2} voxels); {} triangles",
        path.display(),
        c.shared,
        c.over_one_voxel,
        100.0 * c.over_one_voxel as f64 / c.shared.max(1) as f64,
        c.voxel,
        c.max_shared,
        c.max_shared / c.voxel,
        c.max_shared / c.model_size,
        c.model_size,
        c.t_junctions,
        c.max_t_junction,
        c.max_t_junction / c.voxel,
        file.triangles.len()
    );
    assert!(c.shared > 10_000, "{} shared positions", c.shared);
    assert_eq!(c.over_one_voxel, 0);
    assert!(c.max_shared <= 1e-4 * c.model_size, "{}", c.max_shared);
    assert!(
        c.max_t_junction <= 1e-4 * c.model_size,
        "{}",
        c.max_t_junction
    );
}
