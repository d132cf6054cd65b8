//! Tests for skinned drawing: the deformer against the rigid path, culling bounds, extremes,
//! and hole/bloat metrics on the real assets.

use std::sync::{Arc, OnceLock};

use glam::{Mat4, Quat, Vec3};

use super::*;
use crate::deform::{NodeDeform, NodeInfo};
use crate::io::{import_skinned, voxelize_skinned};
use crate::measure::skin::{ReportSettings, Silhouette, skin_report};
use crate::quality::Quality;
use crate::render::{Camera, RenderScene, View, VoxelInstance, render_document, render_scene};
use crate::scene::{Document, ObjectKind, VoxelModel};
use crate::voxelize::{Resolution, VoxelizeSettings};

const RIGGED_FIGURE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/assets/skinned/RiggedFigure.glb"
);
/// A skinned voxel document of an asset at octree `depth`, framed by its camera (also used by
/// the skinned-export tests).
pub(crate) fn skinned_doc(path: &str, depth: u8) -> Document {
    skinned_doc_in(path, depth, crate::voxelize::Mode::Surface)
}

/// [`skinned_doc`] voxelized in `mode` (a solid fills the inside).
pub(crate) fn skinned_doc_in(path: &str, depth: u8, mode: crate::voxelize::Mode) -> Document {
    let import = import_skinned(path).expect("asset imports");
    let v = voxelize_skinned(
        &import,
        &VoxelizeSettings {
            resolution: Resolution::Depth(depth),
            mode,
            ..VoxelizeSettings::default()
        },
        &|_| true,
    )
    .expect("voxelizes");
    let mut doc = Document::default();
    doc.add("Figure", ObjectKind::Voxels(v.model));
    if let Some((lo, hi)) = doc.bounds() {
        doc.camera.frame(lo, hi);
    }
    doc
}

fn rigged_figure() -> &'static Document {
    static DOC: OnceLock<Document> = OnceLock::new();
    DOC.get_or_init(|| skinned_doc(RIGGED_FIGURE, 7))
}

fn model_of(doc: &Document) -> (&VoxelModel, &Rig) {
    match &doc.objects[0].kind {
        ObjectKind::Voxels(v) => (v, v.rig.as_ref().expect("rig")),
        ObjectKind::Mesh(_) | ObjectKind::Krs(_) => panic!("not voxels"),
    }
}

fn quality() -> Quality {
    Quality {
        shadows: false,
        ..Quality::default()
    }
}

#[test]
fn identity_skinning_with_s_one_draws_exactly_the_rigid_model() {
    // A sphere whose every voxel is bound to one joint left at identity.
    let svo = crate::render::scenes::sphere_shell(6, 0.9).expect("sphere");
    let leaves: Vec<_> = svo
        .leaves()
        .into_iter()
        .map(|(c, mut v)| {
            v.skin = crate::svo::Skin4::ROOT;
            (c, v)
        })
        .collect();
    let skinned_svo = crate::svo::Svo::from_voxels(6, true, leaves).expect("svo");
    let ObjectKind::Voxels(mut model) = crate::render::scenes::voxel_object(skinned_svo, 1.0)
    else {
        unreachable!()
    };
    let rigid = Document {
        objects: vec![crate::scene::Object {
            id: 1,
            kind: ObjectKind::Voxels(model.clone()),
            ..crate::scene::Object::default()
        }],
        ..Document::default()
    };
    let (sk, _) = Skeleton::new(vec![Joint::default()]).expect("one joint");
    let mut rig = Rig::new(sk, Vec::new());
    rig.stretch.strategy = StretchStrategy::Off;
    model.rig = Some(rig);
    let mut skinned = rigid.clone();
    skinned.objects[0].kind = ObjectKind::Voxels(model);
    skinned.objects[0].transform.translation = Vec3::new(0.1, 0.0, 0.0);
    let mut rigid = rigid;
    rigid.objects[0].transform.translation = Vec3::new(0.1, 0.0, 0.0);
    let req = View {
        quality: quality(),
        ..View::new(96, 96)
    };
    let (a, fa, _) = render_document(&rigid, &req).expect("rigid");
    let (b, fb, _) = render_document(&skinned, &req).expect("skinned");
    assert!(fa.covered_pixels() > 800, "{}", fa.covered_pixels());
    assert_eq!(fa.coverage(), fb.coverage(), "same silhouette");
    let differing = crate::measure::image::count_differing(&a, &b, 2).expect("same size");
    assert!(differing <= 10, "{differing} pixels differ");
}

/// World AABB of a drawn box.
fn world_aabb(d: crate::deform::DeformedNode) -> (Vec3, Vec3) {
    let a = d.half_axes_world;
    let he = glam::Mat3::from_cols(a.x_axis.abs(), a.y_axis.abs(), a.z_axis.abs()) * Vec3::ONE;
    (d.center_world - he, d.center_world + he)
}

#[test]
fn subtree_bounds_contain_every_leaf_splat_and_every_descendant_centre() {
    let doc = rigged_figure();
    let (model, rig) = model_of(doc);
    let svo = &model.svo;
    let settings = |strategy, multiplier| StretchSettings {
        strategy,
        multiplier,
        ..StretchSettings::default()
    };
    let cases = [
        settings(StretchStrategy::Off, 1.0),
        settings(StretchStrategy::Thesis, 1.0),
        settings(StretchStrategy::Corners, 1.0),
        settings(StretchStrategy::Corners, 1.5),
        settings(StretchStrategy::Adaptive, 1.0),
        settings(StretchStrategy::Adaptive, 1.5),
    ];
    for t in [0.3f32, 0.9] {
        for case in cases {
            let deform = SkinDeform::for_rig(
                rig,
                svo,
                Mat4::IDENTITY,
                model.object_from_voxel(),
                Some(0),
                t,
            )
            .with_settings(case);
            let mut stack = vec![svo.root()];
            let (mut checked, mut leaves) = (0, 0);
            while let Some(n) = stack.pop() {
                if svo.is_leaf(&n) {
                    continue;
                }
                stack.extend((0..8).filter_map(|k| svo.child(&n, k)));
                if n.level < 2 || n.level % 2 == 1 && n.level + 1 < svo.depth() {
                    continue;
                }
                let info = NodeInfo { svo, node: n };
                let (lo, hi) = world_aabb(deform.subtree_bounds(&info).expect("internal node"));
                let tol = 1e-4 * (hi - lo).max_element();
                let mut sub = vec![n];
                while let Some(d) = sub.pop() {
                    sub.extend((0..8).filter_map(|k| svo.child(&d, k)));
                    let drawn = deform.deform(&NodeInfo { svo, node: d });
                    let (dl, dh) = if svo.is_leaf(&d) {
                        leaves += 1;
                        world_aabb(drawn)
                    } else {
                        (drawn.center_world, drawn.center_world)
                    };
                    assert!(
                        dl.cmpge(lo - tol).all() && dh.cmple(hi + tol).all(),
                        "{case:?}, t = {t}: node at level {} escapes its ancestor at level {}: \
                         {dl}..{dh} outside {lo}..{hi}",
                        d.level,
                        n.level
                    );
                }
                checked += 1;
            }
            assert!(
                checked > 20 && leaves > 1000,
                "{checked} nodes, {leaves} leaves"
            );
        }
    }
}

/// The bounds are the joints' boxes of the node, not padded by the node's size: at the level
/// above the leaves their mean volume is under a third of the old box of `½ · size · (1 + grow / 2)`
/// per joint (grow = `max_factor`, 3× the node's edge at the default 4).
#[test]
fn subtree_bounds_are_far_tighter_than_the_padded_joint_boxes() {
    let doc = rigged_figure();
    let (model, rig) = model_of(doc);
    let svo = &model.svo;
    let settings = StretchSettings {
        strategy: StretchStrategy::Adaptive,
        ..StretchSettings::default()
    };
    let skinning = rig.skinning_at(Some(0), 0.9);
    let deform = SkinDeform::for_rig(
        rig,
        svo,
        Mat4::IDENTITY,
        model.object_from_voxel(),
        Some(0),
        0.9,
    )
    .with_settings(settings);
    let tables = rig.tables(svo);
    let grow = settings.max_factor.max(1.0) * settings.multiplier;
    let (mut new_volume, mut old_volume, mut n) = (0.0f64, 0.0f64, 0);
    let mut stack = vec![svo.root()];
    while let Some(node) = stack.pop() {
        if svo.is_leaf(&node) {
            continue;
        }
        stack.extend((0..8).filter_map(|k| svo.child(&node, k)));
        if node.level + 1 != svo.depth() {
            continue;
        }
        let info = NodeInfo { svo, node };
        let (lo, hi) = world_aabb(deform.subtree_bounds(&info).expect("internal node"));
        new_volume += f64::from((hi - lo).x * (hi - lo).y * (hi - lo).z);
        let half = 0.5 * info.size_voxels() as f32;
        let (mut olo, mut ohi) = world_aabb(deform.deform(&info));
        for &j in tables.subtree_joints(node.index) {
            let m = skinning[usize::from(j)] * model.object_from_voxel();
            let c = m.transform_point3(info.center_voxel());
            let a = glam::Mat3::from_mat4(m);
            let rows =
                glam::Mat3::from_cols(a.x_axis.abs(), a.y_axis.abs(), a.z_axis.abs()) * Vec3::ONE;
            let he = rows * half * (1.0 + 0.5 * grow);
            olo = olo.min(c - he);
            ohi = ohi.max(c + he);
        }
        old_volume += f64::from((ohi - olo).x * (ohi - olo).y * (ohi - olo).z);
        n += 1;
    }
    assert!(n > 100, "{n}");
    let ratio = new_volume / old_volume;
    assert!(ratio < 0.3, "mean volume ratio {ratio:.3} over {n} nodes");
}

#[test]
fn occlusion_culling_never_removes_a_visible_skinned_voxel() {
    let mut doc = rigged_figure().clone();
    let ObjectKind::Voxels(v) = &mut doc.objects[0].kind else {
        unreachable!()
    };
    v.rig.as_mut().expect("rig").playback.time_secs = 0.6;
    let mut q = quality();
    let req = |q: &Quality| View {
        quality: q.clone(),
        ..View::new(160, 160)
    };
    let (_, culled, stats) = render_document(&doc, &req(&q)).expect("render");
    q.occlusion_culling = false;
    let (_, full, _) = render_document(&doc, &req(&q)).expect("render");
    assert!(stats.totals().occlusion_culled > 0, "culling was exercised");
    assert_eq!(
        culled.coverage(),
        full.coverage(),
        "culling changed the silhouette"
    );
}

#[test]
fn extreme_poses_render_without_nan() {
    let doc = rigged_figure();
    let (model, rig) = model_of(doc);
    let mut rig = rig.clone();
    rig.playback.clip = None;
    // A joint turned 180°, another scaled to zero, a third with a huge translation.
    rig.pose_overrides = vec![
        JointOverride {
            joint: 3,
            rotation: Some(Quat::from_rotation_x(std::f32::consts::PI)),
            ..JointOverride::default()
        },
        JointOverride {
            joint: 6,
            translation: Some(Vec3::splat(1e6)),
            mode: OverrideMode::Relative,
            ..JointOverride::default()
        },
    ];
    let mut pose = rig.current_pose();
    pose.locals[8].scale = Vec3::ZERO;
    let mut m = JointMatrices::default();
    rig.skeleton.compute_matrices(&pose, &mut m);
    let cam = Camera::from_orbit(&doc.camera, 96, 96);
    for strategy in [
        StretchStrategy::Off,
        StretchStrategy::Thesis,
        StretchStrategy::Corners,
        StretchStrategy::Adaptive,
    ] {
        let deform = SkinDeform::new(
            Mat4::IDENTITY,
            model.object_from_voxel(),
            &m.skinning,
            StretchSettings {
                strategy,
                ..StretchSettings::default()
            },
            &rig.stretch_overrides,
            rig.tables(&model.svo),
        );
        let scene = RenderScene {
            voxels: vec![VoxelInstance {
                svo: &model.svo,
                deform: &deform,
                casts_shadows: true,
                label: 1,
            }],
            meshes: Vec::new(),
            lights: &doc.lights,
            ambient: doc.ambient,
            background: doc.background,
        };
        let (img, fb, _) = render_scene(&scene, &cam, &Quality::default()).expect("renders");
        assert!(fb.covered_pixels() > 100, "{strategy:?}");
        assert!(fb.depth.iter().all(|d| !d.is_nan()), "{strategy:?}");
        assert!(fb.normal.iter().all(|n| n.is_finite()), "{strategy:?}");
        assert_eq!(img.pixels.len(), 96 * 96 * 4);
    }
}

#[test]
fn adaptive_is_one_where_the_figure_moves_rigidly() {
    let doc = rigged_figure();
    let (model, rig) = model_of(doc);
    let tables = rig.tables(&model.svo);
    // The whole figure carried rigidly: every joint gets the same rotation and translation.
    let rigid =
        Mat4::from_rotation_translation(Quat::from_rotation_y(0.8), Vec3::new(1.0, 2.0, 3.0));
    let skinning = vec![rigid; rig.skeleton.len()];
    let deform = SkinDeform::new(
        Mat4::IDENTITY,
        model.object_from_voxel(),
        &skinning,
        StretchSettings {
            strategy: StretchStrategy::Adaptive,
            min_factor: 0.0,
            ..StretchSettings::default()
        },
        &rig.stretch_overrides,
        Arc::clone(&tables),
    );
    // Leaves reached by a traversal, so their pool indices (for the corner table) are real.
    let svo = &model.svo;
    let mut stack = vec![svo.root()];
    let mut checked = 0;
    let voxel = model.voxel_size;
    while let Some(nd) = stack.pop() {
        stack.extend((0..8).filter_map(|k| svo.child(&nd, k)));
        if !svo.is_leaf(&nd) {
            continue;
        }
        let d = deform.deform(&NodeInfo { svo, node: nd });
        let edge = d.half_axes_world.x_axis.length() * 2.0;
        assert!(
            (edge - voxel).abs() < voxel * 1e-3,
            "rigid motion must leave S = 1, got edge {edge} for voxel {voxel}"
        );
        checked += 1;
    }
    assert!(checked > 1000, "{checked}");
}

#[test]
fn silhouette_counts() {
    let mesh = [true, true, false, false];
    let vox = [true, false, true, false];
    let s = Silhouette::from_coverage(&mesh, &vox);
    assert_eq!(
        (s.mesh_pixels, s.voxel_pixels, s.holes, s.bloat),
        (2, 2, 1, 1)
    );
    assert!((s.iou() - 1.0 / 3.0).abs() < 1e-12);
    assert_eq!(Silhouette::default().iou(), 1.0);
}

#[test]
fn a_document_without_skin_has_nothing_to_report() {
    let doc = crate::render::scenes::sphere_document(4, 0.8).expect("doc");
    let e = skin_report(
        &doc,
        &ReportSettings {
            frames: 2,
            views: 6,
            width: 8,
            height: 8,
            clip: None,
            strategies: vec![StretchSettings::default()],
            quality: Quality::default(),
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("no skinned voxel model"), "{e}");
}

/// Every node of an octree (root first).
fn all_nodes(svo: &crate::svo::Svo) -> Vec<crate::svo::NodeRef> {
    let mut out = Vec::new();
    let mut stack = vec![svo.root()];
    while let Some(nd) = stack.pop() {
        stack.extend((0..8).filter_map(|k| svo.child(&nd, k)));
        out.push(nd);
    }
    out
}

#[test]
fn lattice_corners_skinned_once_per_frame_equal_each_corner_skinned_with_its_own_weights() {
    // The deformer skins every lattice point once per frame and reads a node's corners from
    // there; skinning each corner of each node with its own weights is the definition. Same
    // points, same weights, same arithmetic: the boxes must be bit-identical.
    use super::stretch::{aabb, containing_factor, skin_corners, voxel_corners};
    let doc = rigged_figure();
    let (model, rig) = model_of(doc);
    let svo = &model.svo;
    let clip = rig.playback.clip.or(Some(0));
    let skinning = rig.skinning_at(clip, 0.4);
    let tables = rig.tables(svo);
    let world_from_voxel: Vec<Mat4> = skinning
        .iter()
        .map(|s| *s * model.object_from_voxel())
        .collect();
    let mut bent = 0;
    for strategy in [StretchStrategy::Adaptive, StretchStrategy::Corners] {
        let settings = StretchSettings {
            strategy,
            min_factor: 0.0,
            max_factor: 16.0,
            ..StretchSettings::default()
        };
        let deform = SkinDeform::new(
            Mat4::IDENTITY,
            model.object_from_voxel(),
            &skinning,
            settings,
            &rig.stretch_overrides,
            Arc::clone(&tables),
        );
        for nd in all_nodes(svo) {
            let info = NodeInfo { svo, node: nd };
            let got = deform.deform(&info);
            let corner_skins = if svo.is_leaf(&nd) {
                tables
                    .leaf_corner_skins(nd.index)
                    .expect("a node of the octree")
            } else {
                tables
                    .inner_corner_skins(nd.index)
                    .expect("a node of the octree")
            };
            let half = 0.5 * info.size_voxels() as f32;
            let c = info.center_voxel();
            let skinned = skin_corners(&world_from_voxel, &voxel_corners(c, half), &corner_skins);
            let skin = info.voxel().skin;
            let blended =
                lbs::blend_matrix(&world_from_voxel, skin.joints_u16(), skin.blend_weights());
            let want = if strategy == StretchStrategy::Corners {
                let (lo, hi) = aabb(&skinned);
                ((lo + hi) * 0.5, glam::Mat3::from_diagonal((hi - lo) * 0.5))
            } else {
                let linear = glam::Mat3::from_mat4(blended);
                let f = containing_factor(&skinned, half, blended.transform_point3(c), linear)
                    .expect("the figure's frames do not collapse")
                    .clamp(0.0, 16.0);
                bent += usize::from(f > 1.01);
                (blended.transform_point3(c), linear * (f * half))
            };
            assert_eq!(got.center_world, want.0, "{strategy:?} {nd:?}");
            assert_eq!(got.half_axes_world, want.1, "{strategy:?} {nd:?}");
            // The node is in the memo now: its normals go through the kept normal matrix.
            for n in [Vec3::X, Vec3::new(0.0, -0.6, 0.8)] {
                assert_eq!(
                    deform.normal_to_world(&info, n),
                    lbs::transform_normal(glam::Mat3::from_mat4(blended), n),
                    "{strategy:?} {nd:?}"
                );
            }
        }
    }
    assert!(bent > 50, "the pose must stretch some voxels: {bent}");
}

#[test]
fn a_deformer_reusing_the_rigs_scratch_places_nodes_as_a_fresh_one_frame_after_frame() {
    // `for_rig` takes the memo and corner points of the previous deformer from the rig; a
    // stale entry (last frame's pose, or other settings) must never be read back.
    let doc = rigged_figure();
    let (model, rig) = model_of(doc);
    let svo = &model.svo;
    let clip = rig.playback.clip.or(Some(0));
    let nodes = all_nodes(svo);
    let mut compared = 0;
    let mut moved = 0;
    let mut last: Option<Vec<crate::deform::DeformedNode>> = None;
    for (t, strategy) in [
        (0.0, StretchStrategy::Adaptive),
        (0.5, StretchStrategy::Adaptive),
        (0.5, StretchStrategy::Corners),
        (0.5, StretchStrategy::Thesis),
        (0.9, StretchStrategy::Adaptive),
    ] {
        let settings = StretchSettings {
            strategy,
            ..rig.stretch
        };
        let reused =
            SkinDeform::for_rig(rig, svo, Mat4::IDENTITY, model.object_from_voxel(), clip, t)
                .with_settings(settings);
        let fresh = SkinDeform::new(
            Mat4::IDENTITY,
            model.object_from_voxel(),
            &rig.skinning_at(clip, t),
            settings,
            &rig.stretch_overrides,
            rig.tables(svo),
        );
        let mut boxes = Vec::with_capacity(nodes.len());
        // Twice: the second pass reads the memo.
        for _ in 0..2 {
            boxes.clear();
            for &nd in &nodes {
                let info = NodeInfo { svo, node: nd };
                let (a, b) = (reused.deform(&info), fresh.deform(&info));
                assert_eq!(a, b, "t {t} {strategy:?} {nd:?}");
                assert_eq!(
                    reused.subtree_bounds(&info),
                    fresh.subtree_bounds(&info),
                    "t {t} {strategy:?} {nd:?}"
                );
                let n = Vec3::new(0.6, 0.0, 0.8);
                assert_eq!(
                    reused.normal_to_world(&info, n),
                    fresh.normal_to_world(&info, n)
                );
                boxes.push(a);
                compared += 1;
            }
        }
        if let Some(prev) = &last {
            moved += prev.iter().zip(&boxes).filter(|(p, b)| p != b).count();
        }
        last = Some(boxes);
        drop(reused);
    }
    assert!(compared > 10_000, "{compared}");
    // The frames differ (so a stale memo would have been caught).
    assert!(moved > nodes.len(), "{moved}");
}

#[test]
fn corner_tables_hold_the_merged_weights_of_the_leaves_touching_each_corner() {
    // An independent definition, cell by cell: a corner's weights merge the weights of the
    // (up to eight) leaves around its lattice point; an internal node's corner that touches
    // no leaf moves with the node's own weights. Every corner's entry names that point and
    // those weights.
    let doc = rigged_figure();
    let (model, rig) = model_of(doc);
    let svo = &model.svo;
    let tables = rig.tables(svo);
    let extent = 1u32 << svo.depth();
    let around = |p: glam::UVec3| -> Vec<crate::svo::Skin4> {
        let mut skins = Vec::new();
        for k in 0..8u32 {
            let d = glam::UVec3::new(k & 1, (k >> 1) & 1, (k >> 2) & 1);
            // The cells whose corner `p` is: `p - d` for each offset, inside the octree.
            if (p.cmpge(d)).all()
                && (p - d).cmplt(glam::UVec3::splat(extent)).all()
                && let Some(v) = svo.get(p - d)
            {
                skins.push(v.skin);
            }
        }
        skins
    };
    let (mut leaves, mut inner, mut own_corners) = (0, 0, 0);
    for nd in all_nodes(svo) {
        let info = NodeInfo { svo, node: nd };
        let (corners, ids) = if svo.is_leaf(&nd) {
            leaves += 1;
            (
                tables
                    .leaf_corner_skins(nd.index)
                    .expect("a node of the octree"),
                tables.leaf_corner_points[nd.index as usize],
            )
        } else {
            inner += 1;
            (
                tables
                    .inner_corner_skins(nd.index)
                    .expect("a node of the octree"),
                tables.inner_corner_points[nd.index as usize],
            )
        };
        let size = info.size_voxels();
        for k in 0..8u32 {
            let p = nd.origin + glam::UVec3::new(k & 1, (k >> 1) & 1, (k >> 2) & 1) * size;
            let skins = around(p);
            let want = if skins.is_empty() {
                own_corners += 1;
                info.voxel().skin
            } else {
                crate::svo::Skin4::merge(&skins)
            };
            assert_eq!(corners[k as usize], want, "{nd:?} corner {k}");
            assert_eq!(
                tables.corner_points[ids[k as usize] as usize],
                (p, want),
                "{nd:?} corner {k}"
            );
        }
    }
    assert!(
        leaves > 1000 && inner > 100,
        "{leaves} leaves, {inner} inner"
    );
    assert!(own_corners > 0, "some internal corner touches no leaf");
}

/// The stored nodes of an octree, a tile's virtual nodes left out.
fn stored_nodes(svo: &crate::svo::Svo) -> Vec<crate::svo::NodeRef> {
    let mut out = Vec::new();
    let mut stack = vec![svo.root()];
    while let Some(nd) = stack.pop() {
        if !svo.is_tile(&nd) {
            stack.extend((0..8).filter_map(|k| svo.child(&nd, k)));
        }
        out.push(nd);
    }
    out
}

#[test]
fn a_skinned_solids_interior_tiles_leave_every_stored_nodes_tables_as_voxel_by_voxel() {
    // A tile touches the lattice only on its boundary, with the count of its voxels there, and
    // lends its subtree joints the weights of those points: every node the tiled octree stores
    // gets the corner weights and subtree joints its node in the leaf-only octree gets. On a
    // rigidly bound solid (limbs' insides tile) and a solid CesiumMan (interior voxels carry
    // their nearest surface's weights, so fewer tile).
    let cesium = model_of(&skinned_doc_in(
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../shared/assets/skinned/CesiumMan.glb"
        ),
        6,
        crate::voxelize::Mode::Solid,
    ))
    .0
    .svo
    .clone();
    let figure = model_of(&crate::render::scenes::rigid_solid_figure())
        .0
        .svo
        .clone();
    for (name, tiled, least) in [("figure", figure, 100), ("CesiumMan", cesium, 5)] {
        assert!(
            tiled.tile_count() >= least,
            "{name}: {} tiles",
            tiled.tile_count()
        );
        let flat = tiled.clone().without_tiles();
        assert_eq!(flat.tile_count(), 0);
        assert!(flat == tiled, "{name}: the same voxels");
        let (a, b) = (SkinTables::build(&flat), SkinTables::build(&tiled));
        let by_place: std::collections::HashMap<_, _> = all_nodes(&flat)
            .into_iter()
            .map(|n| ((n.level, n.origin), n))
            .collect();
        let mut checked = 0;
        for n in stored_nodes(&tiled) {
            let m = by_place[&(n.level, n.origin)];
            if tiled.is_leaf(&n) {
                assert_eq!(
                    b.leaf_corner_skins(n.index),
                    a.leaf_corner_skins(m.index),
                    "{name} {n:?}"
                );
            } else {
                assert_eq!(
                    b.inner_corner_skins(n.index),
                    a.inner_corner_skins(m.index),
                    "{name} {n:?}"
                );
                assert_eq!(
                    b.subtree_joint_weights(n.index),
                    a.subtree_joint_weights(m.index),
                    "{name} {n:?}"
                );
            }
            checked += 1;
        }
        eprintln!(
            "{name}: {} tiles for {} voxels; corner points {} -> {}, {checked} nodes",
            tiled.tile_count(),
            tiled.memory_stats().tile_voxels,
            a.corner_points.len(),
            b.corner_points.len()
        );
        assert!(b.corner_points.len() < a.corner_points.len(), "{name}");
    }
}
