//! The voxel tools on tiled octrees (issue 43): brushes, boxes, fills, flood fills, paste,
//! rotation, hollowing, interior fill and colour replacement give, step by step, the same
//! voxels, node attributes and undo deltas on a tiled octree as on a voxel-by-voxel one, and
//! undoing every step restores the start.

use glam::{IVec3, UVec3, Vec3};
use proptest::prelude::*;

use super::*;

const SIZE: UVec3 = UVec3::splat(32);

fn ink(k: u8) -> Ink {
    Ink {
        color: [40 + 60 * k, 200 - 50 * k, 90, 255],
        material: k % 2,
    }
}

/// A 32³ model holding a solid box of one colour with a differently coloured slab through it.
fn start() -> Svo {
    let mut svo = Svo::new(5, false).expect("depth 5");
    apply_box(
        &mut svo,
        SIZE,
        IVec3::new(2, 3, 1),
        IVec3::new(27, 29, 24),
        ShapeOp::Add,
        ink(0),
        Mirror::default(),
        None,
    );
    apply_box(
        &mut svo,
        SIZE,
        IVec3::new(0, 12, 0),
        IVec3::new(31, 15, 31),
        ShapeOp::Paint,
        ink(1),
        Mirror::default(),
        None,
    );
    svo
}

#[derive(Debug, Clone)]
enum Tool {
    Dab(BrushOp, Vec3, f32, u8),
    Box(ShapeOp, IVec3, IVec3, u8),
    FillBox(UVec3, UVec3, u8),
    Flood(UVec3, u8),
    CopyPaste(UVec3, UVec3, IVec3),
    Rotate(UVec3, UVec3, usize, i32),
    Hollow(u32),
    FillInterior(u8),
    Replace(u8, u8),
    Mirror(usize),
}

fn arb_point() -> impl Strategy<Value = UVec3> {
    (0u32..32, 0u32..32, 0u32..32).prop_map(|(x, y, z)| UVec3::new(x, y, z))
}

fn arb_tool() -> impl Strategy<Value = Tool> {
    let op = prop_oneof![
        Just(BrushOp::Add),
        Just(BrushOp::Remove),
        Just(BrushOp::Paint),
        Just(BrushOp::Smooth)
    ];
    let shape = prop_oneof![
        Just(ShapeOp::Add),
        Just(ShapeOp::Remove),
        Just(ShapeOp::Paint)
    ];
    prop_oneof![
        (op, arb_point(), 0.5f32..7.0, 0u8..3).prop_map(|(o, c, r, k)| Tool::Dab(
            o,
            c.as_vec3() + 0.5,
            r,
            k
        )),
        (shape, arb_point(), arb_point(), 0u8..3).prop_map(|(o, a, b, k)| Tool::Box(
            o,
            a.as_ivec3(),
            b.as_ivec3(),
            k
        )),
        (arb_point(), arb_point(), 0u8..3).prop_map(|(a, b, k)| Tool::FillBox(a, b, k)),
        (arb_point(), 0u8..3).prop_map(|(c, k)| Tool::Flood(c, k)),
        (arb_point(), arb_point(), (-8i32..8, -8i32..8, -8i32..8))
            .prop_map(|(a, b, (x, y, z))| { Tool::CopyPaste(a, b, IVec3::new(x, y, z)) }),
        (arb_point(), arb_point(), 0usize..3, 1i32..4)
            .prop_map(|(a, b, axis, q)| Tool::Rotate(a, b, axis, q)),
        (1u32..3).prop_map(Tool::Hollow),
        (0u8..3).prop_map(Tool::FillInterior),
        (0u8..3, 0u8..3).prop_map(|(a, b)| Tool::Replace(a, b)),
        (0usize..3).prop_map(Tool::Mirror),
    ]
}

/// Runs one tool; returns its undo delta and changed box.
fn run(svo: &mut Svo, tool: &Tool) -> (UndoDelta, Option<(UVec3, UVec3)>) {
    let edit = match tool {
        Tool::Dab(op, c, r, k) => {
            let brush = Brush {
                op: *op,
                radius: *r,
                color: ink(*k).color,
                strength: 0.6,
                ..Brush::default()
            };
            let d = apply_dab(svo, &brush, *c, Vec3::splat(16.0)).expect("valid dab");
            return (d.delta, d.changed);
        }
        Tool::Box(op, a, b, k) => {
            apply_box(svo, SIZE, *a, *b, *op, ink(*k), Mirror::default(), None)
        }
        Tool::FillBox(a, b, k) => fill(svo, &select_box(svo, *a, *b), ink(*k)),
        Tool::Flood(c, k) => fill(
            svo,
            &select_connected(svo, *c, true).expect("under the listing limit"),
            ink(*k),
        ),
        Tool::CopyPaste(a, b, at) => {
            let clip = copy(svo, &select_box(svo, *a, *b));
            paste(svo, SIZE, &clip, a.min(*b).as_ivec3() + *at, false)
        }
        Tool::Rotate(a, b, axis, q) => {
            let sel = select_box(svo, *a, *b);
            let pivot = rotation_pivot(a.min(*b), a.max(*b), *axis);
            let t = SelTransform::Rotate {
                axis: *axis,
                quarter_turns: *q,
            };
            transform_selection(svo, SIZE, &sel, t, pivot).0
        }
        Tool::Hollow(shell) => hollow(svo, SIZE, *shell),
        Tool::FillInterior(k) => fill_interior(svo, SIZE, Some(ink(*k))),
        Tool::Replace(a, b) => replace_color(svo, ink(*a).color, ink(*b).color, None),
        Tool::Mirror(axis) => mirror_model(svo, SIZE, *axis),
    };
    (edit.delta, edit.changed)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]
    /// Property: every tool does the same to a tiled octree as to a voxel-by-voxel one, and
    /// the undo deltas it returns restore the start on both.
    #[test]
    fn the_tools_treat_tiled_and_voxel_by_voxel_octrees_alike(
        tools in proptest::collection::vec(arb_tool(), 1..8),
    ) {
        let tiled_start = start();
        prop_assert!(tiled_start.tile_count() > 0);
        let flat_start = tiled_start.clone().without_tiles();
        let (mut tiled, mut flat) = (tiled_start.clone(), flat_start.clone());
        let (mut undo_tiled, mut undo_flat) = (Vec::new(), Vec::new());
        for tool in &tools {
            let a = run(&mut tiled, tool);
            let b = run(&mut flat, tool);
            prop_assert_eq!(&a, &b, "{:?}", tool);
            prop_assert_eq!(&tiled, &flat, "{:?}", tool);
            prop_assert_eq!(flat.tile_count(), 0);
            undo_tiled.push(a.0);
            undo_flat.push(b.0);
        }
        for (a, b) in undo_tiled.iter().rev().zip(undo_flat.iter().rev()) {
            tiled.apply_delta(a);
            flat.apply_delta(b);
        }
        prop_assert_eq!(&tiled, &tiled_start);
        prop_assert_eq!(&flat, &flat_start);
        prop_assert_eq!(tiled.tile_count(), tiled_start.tile_count());
    }
}

/// A solid ball of radius 13 in the 32³ model, as a solid import makes it: voxels enclosed on
/// all six faces are interior, the shell coloured by position.
fn interior_ball() -> Svo {
    interior_ball_with(false)
}

/// [`interior_ball`], with `skin` rigidly bound to two joints: the half below x = 16 follows
/// joint 0, the rest joint 1, interior voxels included (a rigged solid: its insides tile).
fn interior_ball_with(skin: bool) -> Svo {
    let c = Vec3::splat(16.0);
    let inside = |p: IVec3| {
        p.cmpge(IVec3::ZERO).all()
            && p.cmplt(SIZE.as_ivec3()).all()
            && (p.as_vec3() + 0.5 - c).length() <= 13.0
    };
    let mut voxels = Vec::new();
    for z in 0..32 {
        for y in 0..32 {
            for x in 0..32 {
                let p = IVec3::new(x, y, z);
                if !inside(p) {
                    continue;
                }
                let enclosed = crate::svo::FACE_NEIGHBOURS.iter().all(|&f| inside(p + f));
                let v = if enclosed {
                    Voxel::INTERIOR
                } else {
                    Voxel::new(
                        [(x * 7) as u8, (y * 7) as u8, 200, 255],
                        p.as_vec3() + 0.5 - c,
                    )
                };
                let skin = crate::svo::Skin4 {
                    joints: [u8::from(skin && x >= 16), 0, 0, 0],
                    weights: [if skin { 255 } else { 0 }, 0, 0, 0],
                };
                voxels.push((p.as_uvec3(), Voxel { skin, ..v }));
            }
        }
    }
    Svo::from_voxels(5, skin, voxels).expect("inside the octree")
}

/// No interior voxel is exposed, and none of the mark's parts (its colour, its normal code)
/// has leaked into a voxel that shows.
fn assert_interior_sound(svo: &Svo, tool: &Tool) {
    assert_eq!(
        svo.exposed_interior(),
        None,
        "{tool:?}: an interior voxel is exposed"
    );
    svo.for_each_leaf(|c, v| {
        if !v.is_interior() {
            assert!(
                v.color != [0; 4] && v.normal != crate::svo::INTERIOR_NORMAL,
                "{tool:?}: voxel {c} shows part of the interior mark: {v:?}"
            );
        }
    });
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]
    /// Property: on a solid import's interior, every tool leaves no interior voxel exposed and
    /// no part of the mark in a voxel that shows; tiled and voxel-by-voxel octrees agree; the
    /// undo deltas restore the start. Rigged (`skin`: the interior tiles carry their joint's
    /// weights), no tile is ever one that is drawn: a skinned octree tiles only its interior.
    #[test]
    fn the_tools_keep_a_solid_interior_sound(
        tools in proptest::collection::vec(arb_tool(), 1..8),
        skin in any::<bool>(),
    ) {
        let tiled_start = interior_ball_with(skin);
        prop_assert!(tiled_start.tile_count() > 0 && tiled_start.may_have_interior());
        prop_assert_eq!(tiled_start.has_skin(), skin);
        let flat_start = tiled_start.clone().without_tiles();
        let (mut tiled, mut flat) = (tiled_start.clone(), flat_start.clone());
        let mut undo = Vec::new();
        for tool in &tools {
            let a = run(&mut tiled, tool);
            let b = run(&mut flat, tool);
            prop_assert_eq!(&a, &b, "{:?}", tool);
            prop_assert_eq!(&tiled, &flat, "{:?}", tool);
            assert_interior_sound(&tiled, tool);
            let mut drawn_tiles = 0;
            tiled.for_each_run(|_, height, v| {
                drawn_tiles += usize::from(height > 0 && !v.is_interior());
            });
            if skin {
                prop_assert_eq!(drawn_tiles, 0, "{:?}", tool);
            }
            undo.push(a.0);
        }
        for d in undo.iter().rev() {
            tiled.apply_delta(d);
        }
        prop_assert_eq!(&tiled, &tiled_start);
        prop_assert_eq!(tiled.tile_count(), tiled_start.tile_count());
    }
}

#[test]
fn a_crop_through_an_interior_shows_its_nearest_surface() {
    let ball = interior_ball();
    let cut = resize_canvas(&ball, SIZE, UVec3::new(32, 32, 16), [Anchor::Min; 3]).expect("crop");
    assert_interior_sound(&cut.svo, &Tool::Hollow(0));
    // The cut face shows: every voxel of the top layer that was interior now has the value of
    // its nearest shell voxel in the cropped model.
    let shown = (0..32 * 32)
        .filter(|i| {
            let c = UVec3::new(i % 32, i / 32, 15);
            ball.get(c).is_some_and(|v| v.is_interior())
        })
        .count();
    assert!(shown > 200, "{shown} interior voxels on the cut");
    // A crop wholly inside the interior: every voxel of its outer layer shows what carving the
    // crop out of the ball would, the ball's nearest shell voxel (the ball's shell is all
    // outside the crop, so nothing nearer exists).
    let core = resize_canvas(&ball, SIZE, UVec3::splat(8), [Anchor::Center; 3]).expect("crop");
    assert_interior_sound(&core.svo, &Tool::Hollow(0));
    let mut checked = 0;
    core.svo.for_each_leaf(|c, v| {
        if v.is_interior() {
            return;
        }
        let at = (c.as_ivec3() - core.offset).as_uvec3();
        assert_eq!(Some(v), ball.nearest_surface(at).map(|n| n.1), "{c}");
        checked += 1;
    });
    assert!(checked > 200, "{checked} voxels on the crop's faces");
}

#[test]
fn tools_that_list_every_voxel_refuse_a_model_standing_for_more_and_edits_still_work() {
    // A 1024³ volume holding one tile of 512³ voxels and one voxel beside it: 2^27 + 1 voxels
    // in two records. The tools that go through every voxel refuse it, naming the limit, and
    // change nothing; a box carved into the tile splits only the path to it.
    let v = Voxel::new([90, 160, 60, 255], Vec3::Y);
    let mut svo = Svo::over_listing_limit(v);
    assert!(svo.tile_value_ok(&v));
    assert_eq!(svo.leaf_count(), MAX_LISTED_VOXELS + 1);
    let size = UVec3::splat(1024);
    let start = svo.clone();
    let refused = |e: Option<ToolError>, what: &str| match e {
        Some(ToolError::TooManyVoxels {
            what: w,
            voxels,
            limit,
        }) => {
            assert_eq!(
                (w, voxels, limit),
                (what, MAX_LISTED_VOXELS + 1, MAX_LISTED_VOXELS)
            );
            let text = ToolError::TooManyVoxels {
                what: w,
                voxels,
                limit,
            }
            .to_string();
            assert!(
                text.contains("134,217,729") && text.contains("brushes"),
                "{text}"
            );
        }
        other => panic!("{what}: {other:?}"),
    };
    refused(
        resize_canvas(&svo, size, UVec3::splat(600), [Anchor::Min; 3]).err(),
        "Resize canvas",
    );
    refused(
        shift_content(&mut svo, size, IVec3::X, false).refused,
        "Shift content",
    );
    refused(mirror_model(&mut svo, size, 0).refused, "Mirror model");
    refused(select_color(&svo, v.color).err(), "Select by colour");
    refused(
        select_connected(&svo, UVec3::ZERO, false).err(),
        "Select connected",
    );
    let none = VoxelSelection::default();
    refused(invert(&svo, &none).err(), "Select all / Invert");
    refused(crop_to(&mut svo, &none).refused, "Crop to selection");
    // A box that removes or paints the tile's voxels would write one undo entry each: counted
    // first (the tile at once) and refused like an Add box of as many cells.
    for op in [ShapeOp::Remove, ShapeOp::Paint] {
        let e = apply_box(
            &mut svo,
            size,
            IVec3::ZERO,
            IVec3::splat(400),
            op,
            ink(1),
            Mirror::default(),
            None,
        );
        assert!(
            matches!(
                e.refused,
                Some(ToolError::TooManyCells {
                    cells: 64_481_201, // 401³ solid voxels in the box
                    ..
                })
            ),
            "{op:?}: {:?}",
            e.refused
        );
    }
    assert!(svo == start, "a refused tool changed the model");
    // Edits that follow what they touch still work on it.
    let carve = apply_box(
        &mut svo,
        size,
        IVec3::splat(100),
        IVec3::splat(103),
        ShapeOp::Remove,
        ink(0),
        Mirror::default(),
        None,
    );
    assert!(carve.refused.is_none(), "{:?}", carve.refused);
    assert_eq!(svo.leaf_count(), MAX_LISTED_VOXELS + 1 - 64);
    assert!(svo.get(UVec3::splat(101)).is_none());
}
