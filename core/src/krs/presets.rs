//! Ready-made KRS objects: tree, bush, grass tuft, rock (planar kernels, §7.1), terrain, coral,
//! the sponge of Fig. 9 and a forest (extra reflections with empty kernels, §7.2).
//!
//! Every preset is deterministic; the random-looking choices come from a fixed-seed PCG.

use std::f32::consts::{FRAC_PI_2, TAU};

use glam::{Quat, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg32;

use super::distort::Distortion;
use super::kernel::{
    CapsuleKernel, Kernel, KernelBound, Material, PlaneKernel, SphereKernel, TorusKernel,
};
use super::mirror::MirrorPlane;
use super::object::{KrsObject, KrsScene, Similarity};
use super::shade::{Pattern, TextureMode, Texturing};
use super::tree::{LeafParams, TreeParams};

fn bark_texture() -> Texturing {
    Texturing {
        mode: TextureMode::KernelParam,
        pattern: Pattern::Bark,
        scale: 6.0,
        contrast: 0.5,
        ..Texturing::default()
    }
}

/// The default tree: 7 branches on the route, a leaf pair, 2^8 leaves.
pub fn tree() -> KrsObject {
    let params = TreeParams::default();
    // The default parameters are valid by construction; fall back to an empty object rather
    // than panic if someone edits them badly.
    let mut obj = params.build().unwrap_or_default();
    obj.name = "tree".to_owned();
    obj.texturing = bark_texture();
    obj
}

/// A low, wide bush: short trunk, wide fork angles, many leaves.
pub fn bush() -> KrsObject {
    let params = TreeParams {
        route: vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.0, 0.3, 0.0),
            Vec3::new(0.25, 0.6, 0.05),
            Vec3::new(0.5, 0.8, 0.15),
            Vec3::new(0.7, 0.95, 0.2),
            Vec3::new(0.85, 1.05, 0.3),
            Vec3::new(0.95, 1.12, 0.35),
        ],
        bends: vec![
            Vec3::ZERO,
            Vec3::new(-0.04, 0.0, 0.0),
            Vec3::new(0.0, 0.03, 0.03),
        ],
        widths: vec![0.06, 0.04, 0.03, 0.02, 0.014, 0.01],
        fork_normals: vec![
            Vec3::new(1.0, 0.1, 0.2),
            Vec3::new(0.2, 0.0, 1.0),
            Vec3::new(1.0, 0.3, -0.4),
            Vec3::new(-0.3, 0.2, 1.0),
            Vec3::new(1.0, 0.0, 0.5),
        ],
        bark: Material::new(Vec3::new(0.28, 0.2, 0.12), 1),
        leaf: Some(LeafParams {
            radius: 0.07,
            offset: Vec3::new(0.05, 0.04, 0.0),
            ..LeafParams::default()
        }),
        forest_mirrors: Vec::new(),
    };
    let mut obj = params.build().unwrap_or_default();
    obj.name = "bush".to_owned();
    obj
}

/// A grass tuft: one curved blade fanned by reflections through (nearly) vertical planes, then
/// clumped by a few offset mirrors: 2^8 blades.
pub fn grass_tuft() -> KrsObject {
    let green = Material::new(Vec3::new(0.2, 0.45, 0.1), 3);
    let blade = Kernel::ToroidalCapsule(TorusKernel {
        centre: Vec3::new(0.9, 0.0, 0.0),
        // axis × start_dir = +Y: the blade rises from the origin and curls outward.
        axis: Vec3::NEG_Z,
        start_dir: Vec3::new(-1.0, 0.0, 0.0),
        major_radius: 0.9,
        minor_radius: 0.008,
        sweep_radians: 0.55,
        material: green,
    });
    let mut rng = Pcg32::seed_from_u64(7);
    let mut kernels = vec![blade];
    let mut mirrors = Vec::new();
    for i in 0..8 {
        let azimuth = GOLDEN * i as f32 + rng.random_range(-0.2..0.2);
        let tilt = rng.random_range(-0.08..0.08);
        let normal = Vec3::new(azimuth.cos(), tilt, azimuth.sin());
        // The first mirrors fan the blade around the stem; the last two spread clumps apart.
        let offset = if i < 6 {
            rng.random_range(-0.01..0.01)
        } else {
            0.06 + 0.05 * (i - 5) as f32
        };
        mirrors.push(MirrorPlane::new(normal, offset));
        kernels.push(if i == 3 {
            // A shorter, straighter blade among the others.
            Kernel::Capsule(CapsuleKernel {
                start: Vec3::ZERO,
                end: Vec3::new(0.05, 0.3, 0.02),
                radius: 0.007,
                material: green,
            })
        } else {
            Kernel::Empty
        });
    }
    KrsObject {
        name: "grass tuft".to_owned(),
        kernels,
        mirrors,
        ..KrsObject::default()
    }
}

const GOLDEN: f32 = 2.399_963;

/// A rock from planar kernels (§7.1): three orthogonal mirrors through the centre fold space
/// into one octant and three diagonal mirrors permute its axes, so each half-space kernel whose
/// outward normal points into the folded octant cuts a bounded polyhedron; their union is the
/// faceted rock, rotated off the axes and warped by a Lipschitz-bounded distortion.
pub fn rock() -> KrsObject {
    let stone = Material::new(Vec3::new(0.45, 0.43, 0.4), 4);
    let s = 1.0 / 2f32.sqrt();
    // Algorithm 1 applies the highest index first: octant folds are R5, R4, R3 (normals +X, +Y,
    // +Z: points end with every coordinate ≤ 0), then axis swaps R2, R1, R0 keep the octant.
    let mirrors = vec![
        MirrorPlane::new(Vec3::new(s, -s, 0.0), 0.0),
        MirrorPlane::new(Vec3::new(0.0, s, -s), 0.0),
        MirrorPlane::new(Vec3::new(s, -s, 0.0), 0.0),
        MirrorPlane::new(Vec3::Z, 0.0),
        MirrorPlane::new(Vec3::Y, 0.0),
        MirrorPlane::new(Vec3::X, 0.0),
    ];
    let plane = |n: Vec3, offset: f32| {
        Kernel::InfinitePlane(PlaneKernel {
            normal: n.normalize_or(-Vec3::ONE),
            offset,
            material: stone,
        })
    };
    let kernels = vec![
        plane(Vec3::new(-1.0, -0.8, -0.9), 0.95),
        plane(Vec3::new(-0.7, -1.0, -0.85), 0.9),
        plane(Vec3::new(-0.9, -0.75, -1.0), 1.0),
        plane(Vec3::new(-1.0, -1.0, -0.6), 0.92),
        Kernel::Empty,
        Kernel::Empty,
        Kernel::Empty,
    ];
    KrsObject {
        name: "rock".to_owned(),
        kernels,
        mirrors,
        world_from_object: Similarity {
            translation: Vec3::new(0.0, 0.6, 0.0),
            rotation: Quat::from_euler(glam::EulerRot::YXZ, 0.4, 0.3, 0.2),
            scale: 1.0,
        },
        distortion: Some(Distortion {
            amplitude: 0.06,
            frequency: 1.5,
            seed: 11,
        }),
        texturing: Texturing {
            mode: TextureMode::Triplanar,
            pattern: Pattern::Bark,
            scale: 3.0,
            contrast: 0.3,
            ..Texturing::default()
        },
        empty_zones: Vec::new(),
    }
}

/// Terrain: a ground half-space folded by tilted, nearly vertical mirrors whose spacing grows
/// per level, so each fold adds a ridge at a larger scale (a 3D Lévy-like surface).
pub fn terrain() -> KrsObject {
    let soil = Material::new(Vec3::new(0.35, 0.4, 0.22), 5);
    let mut rng = Pcg32::seed_from_u64(3);
    let levels = 14;
    let mut mirrors = Vec::new();
    let mut kernels = vec![Kernel::InfinitePlane(PlaneKernel {
        normal: Vec3::Y,
        offset: 0.0,
        material: soil,
    })];
    for i in 0..levels {
        let azimuth: f32 = rng.random_range(0.0..TAU);
        let tilt: f32 =
            rng.random_range(0.05..0.14) * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
        let normal = Vec3::new(
            azimuth.cos() * tilt.cos(),
            tilt.sin(),
            azimuth.sin() * tilt.cos(),
        );
        let spacing = 1.5 * 1.45f32.powi(i);
        mirrors.push(MirrorPlane::new(
            normal,
            spacing * rng.random_range(0.5..1.0),
        ));
        kernels.push(Kernel::Empty);
    }
    KrsObject {
        name: "terrain".to_owned(),
        kernels,
        mirrors,
        texturing: Texturing {
            mode: TextureMode::Triplanar,
            pattern: Pattern::Checker,
            scale: 0.5,
            contrast: 0.25,
            ..Texturing::default()
        },
        ..KrsObject::default()
    }
}

/// Coral: straight, wide-forking capsule branches with round tips, slightly distorted.
pub fn coral() -> KrsObject {
    let pink = Material::new(Vec3::new(0.85, 0.35, 0.4), 6);
    let params = TreeParams {
        route: vec![
            Vec3::ZERO,
            Vec3::new(0.0, 0.25, 0.0),
            Vec3::new(0.15, 0.45, 0.05),
            Vec3::new(0.32, 0.6, 0.12),
            Vec3::new(0.45, 0.72, 0.2),
            Vec3::new(0.55, 0.8, 0.3),
        ],
        bends: Vec::new(),
        widths: vec![0.06, 0.05, 0.042, 0.036, 0.03],
        fork_normals: vec![
            Vec3::new(1.0, -0.2, 0.3),
            Vec3::new(0.3, 0.1, 1.0),
            Vec3::new(1.0, 0.2, -0.6),
            Vec3::new(-0.4, 0.0, 1.0),
        ],
        bark: pink,
        leaf: Some(LeafParams {
            radius: 0.045,
            offset: Vec3::new(0.0, 0.02, 0.0),
            mirror_normal: Vec3::X,
            material: pink,
        }),
        forest_mirrors: Vec::new(),
    };
    let mut obj = params.build().unwrap_or_default();
    obj.name = "coral".to_owned();
    obj.distortion = Some(Distortion {
        amplitude: 0.01,
        frequency: 4.0,
        seed: 5,
    });
    obj
}

/// The sponge of Fig. 9: overlapping balls on a lattice doubled by axis mirrors (8×8×8), with
/// tunnels between them; best seen with ambient occlusion.
pub fn sponge() -> KrsObject {
    let m = Material::new(Vec3::new(0.8, 0.7, 0.45), 7);
    let mut kernels = vec![Kernel::Sphere(SphereKernel {
        centre: Vec3::splat(0.5),
        radius: 0.58,
        material: m,
    })];
    let mut mirrors = Vec::new();
    for level in 0..3 {
        let c = (1 << level) as f32;
        for (j, axis) in [Vec3::X, Vec3::Y, Vec3::Z].into_iter().enumerate() {
            // Slightly unaligned mirrors: the lattice warps and pores vary in size.
            let tilt = 0.03 * ((3 * level + j) as f32 * 2.4).sin();
            let axis = (axis + Vec3::new(tilt, -tilt, 0.5 * tilt)).normalize_or(axis);
            mirrors.push(MirrorPlane::new(axis, c));
            kernels.push(Kernel::Empty);
        }
    }
    // A few small balls at coarser levels break the lattice's regularity.
    kernels[4] = Kernel::Sphere(SphereKernel {
        centre: Vec3::new(1.0, 1.0, 0.4),
        radius: 0.3,
        material: m,
    });
    kernels[7] = Kernel::Sphere(SphereKernel {
        centre: Vec3::new(2.0, 0.6, 2.0),
        radius: 0.45,
        material: m,
    });
    KrsObject {
        name: "sponge".to_owned(),
        kernels,
        mirrors,
        ..KrsObject::default()
    }
}

/// Number of extra reflections the forest preset adds to the tree.
pub const FOREST_MIRRORS: usize = 17;

/// The forest: the default tree multiplied by 17 extra reflections with empty kernels
/// (2^17 trees on a jittered, unaligned grid; ≥ 2^24 kernel instances). The mirrors are placed
/// so each level's trees lie on the kept side (kernel separation holds between trees).
pub fn forest() -> KrsObject {
    forest_with_mirrors(FOREST_MIRRORS)
}

/// The forest with `count` extra reflections (2^count trees; the mirror placement of
/// [`forest`], whose first `count` mirrors these are). `count = 0` is the tree alone. Benchmarks
/// use it to grow n with a fixed view.
pub fn forest_with_mirrors(count: usize) -> KrsObject {
    let mut params = TreeParams::default();
    // Horizontal reach of one tree around its origin, from its kernel instances' bounds.
    let tree_radius = params
        .build()
        .ok()
        .and_then(|o| KrsScene { objects: vec![o] }.prepare().ok())
        .map_or(7.0, |scene| {
            let obj = &scene.objects[0];
            obj.instances(1 << 12)
                .iter()
                .filter_map(|i| match obj.object.kernels[i.kernel].bound() {
                    KernelBound::Sphere(c, r) => {
                        let c = i.world_from_kernel.transform_point3(c);
                        Some(Vec3::new(c.x, 0.0, c.z).length() + r)
                    }
                    _ => None,
                })
                .fold(0.0f32, f32::max)
        });
    let mut rng = Pcg32::seed_from_u64(42);
    // Track tree origins (x, z) to place each mirror just beyond the current set.
    let mut origins = vec![Vec3::ZERO];
    for i in 0..count {
        let base = if i % 2 == 0 { 0.0 } else { FRAC_PI_2 };
        // Unaligned mirrors hide symmetry locally; at large scales a tilt would open wide gaps
        // between tree rows, so the jitter shrinks there.
        let jitter = if i < 6 { 0.05 } else { 0.004 };
        let angle = base + rng.random_range(-jitter..jitter);
        let normal = Vec3::new(angle.cos(), 0.0, angle.sin());
        let reach = origins
            .iter()
            .map(|o| o.dot(normal))
            .fold(f32::NEG_INFINITY, f32::max);
        let gap = rng.random_range(0.02..0.3) * tree_radius;
        let mirror = MirrorPlane::new(normal, reach + tree_radius + gap);
        let reflected: Vec<Vec3> = origins.iter().map(|o| mirror.reflect_point(*o)).collect();
        origins.extend(reflected);
        params.forest_mirrors.push(mirror);
    }
    let mut obj = params.build().unwrap_or_default();
    obj.name = "forest".to_owned();
    obj.texturing = bark_texture();
    obj
}

/// The forest on a ground plane, as a two-object scene.
pub fn forest_scene() -> KrsScene {
    let ground = KrsObject {
        name: "ground".to_owned(),
        kernels: vec![Kernel::InfinitePlane(PlaneKernel {
            normal: Vec3::Y,
            offset: 0.0,
            material: Material::new(Vec3::new(0.3, 0.35, 0.2), 5),
        })],
        ..KrsObject::default()
    };
    KrsScene {
        objects: vec![forest(), ground],
    }
}

/// All single-object presets with their names.
pub fn all() -> Vec<(&'static str, KrsObject)> {
    vec![
        ("tree", tree()),
        ("bush", bush()),
        ("grass tuft", grass_tuft()),
        ("rock", rock()),
        ("terrain", terrain()),
        ("coral", coral()),
        ("sponge", sponge()),
        ("forest", forest()),
    ]
}
