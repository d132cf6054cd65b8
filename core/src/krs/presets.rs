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

/// The tree-builder parameters of [`tree`]: the builder's defaults.
#[must_use]
pub fn tree_params() -> TreeParams {
    TreeParams::default()
}

/// The default tree: 7 branches on the route, a leaf pair, 2^8 leaves.
pub fn tree() -> KrsObject {
    // The default parameters are valid by construction; fall back to an empty object rather
    // than panic if someone edits them badly.
    let mut obj = tree_params().build().unwrap_or_default();
    obj.name = "tree".to_owned();
    obj.texturing = bark_texture();
    obj
}

/// The tree-builder parameters of [`bush`].
#[must_use]
pub fn bush_params() -> TreeParams {
    TreeParams {
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
    }
}

/// A low, wide bush: short trunk, wide fork angles, many leaves.
pub fn bush() -> KrsObject {
    let mut obj = bush_params().build().unwrap_or_default();
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
        let normal = random_fold_normal(&mut rng, 0.05..0.14);
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

/// The tree-builder parameters of [`coral`] (the distortion is the object's, not the builder's).
#[must_use]
pub fn coral_params() -> TreeParams {
    let pink = Material::new(Vec3::new(0.85, 0.35, 0.4), 6);
    TreeParams {
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
    }
}

/// Coral: straight, wide-forking capsule branches with round tips, slightly distorted.
pub fn coral() -> KrsObject {
    let mut obj = coral_params().build().unwrap_or_default();
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

/// A uniform draw from `−half..half`, or 0 without drawing when `half` is not positive (so a
/// zero jitter leaves the generator's sequence for the draws after it).
pub(super) fn symmetric(rng: &mut Pcg32, half: f32) -> f32 {
    if half > 0.0 {
        rng.random_range(-half..half)
    } else {
        0.0
    }
}

/// A ground fold's mirror normal: any azimuth, tilted out of the horizontal by an amount drawn
/// from `tilt`, up or down.
fn random_fold_normal(rng: &mut Pcg32, tilt: std::ops::Range<f32>) -> Vec3 {
    let azimuth: f32 = rng.random_range(0.0..TAU);
    let tilt: f32 = rng.random_range(tilt) * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    tilted_normal(azimuth, tilt)
}

/// The unit normal at `azimuth` around y (0 = +x, π/2 = +z), tilted by `tilt` out of the
/// horizontal (a mirror whose plane leans from the vertical).
pub(super) fn tilted_normal(azimuth: f32, tilt: f32) -> Vec3 {
    Vec3::new(
        azimuth.cos() * tilt.cos(),
        tilt.sin(),
        azimuth.sin() * tilt.cos(),
    )
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

/// The presets the tree builder makes (tree, bush, coral) with their builder parameters:
/// building them gives the preset's kernels and mirrors, so the editor's builder can open the
/// preset with them.
#[must_use]
pub fn builder_presets() -> [(&'static str, TreeParams); 3] {
    [
        ("tree", tree_params()),
        ("bush", bush_params()),
        ("coral", coral_params()),
    ]
}

/// The tree-builder parameters of the preset named `name` ([`all`]) when the builder makes it
/// ([`builder_presets`]).
#[must_use]
pub fn builder_params(name: &str) -> Option<TreeParams> {
    builder_presets()
        .into_iter()
        .find(|(n, _)| *n == name)
        .map(|(_, p)| p)
}

/// A battered rock (§7.1, Fig. 7) from planar kernels and 14 reflection levels: four half-space
/// kernels cut a polyhedron in the octant that three axis folds and three axis swaps (R0–R5,
/// applied last) make of space, as in [`rock`]; then eight mirrors through points near the
/// centre, at orientations drawn from `seed` (R6–R13, applied first), each keep one side of the
/// rock and mirror it onto the other. Every such fold leaves a crease where the kept side meets
/// its image, so the surface is many facets meeting at ridges and valleys — the paper's
/// "battered rock" — and no two seeds give the same rock. Smooth shading (Algorithm 2) rounds
/// the creases, the distortion bends the facets and hides the octant symmetry, and triplanar
/// texture (unfolded coordinates) keeps the mirrored facets from repeating their pattern.
///
/// The kernels are evaluated only after the octant folds (K4 and above are empty), so every
/// kernel instance is a bounded piece and the rock is about one unit across its centre.
pub fn battered_rock(seed: u64) -> KrsObject {
    let stone = Material::new(Vec3::new(0.5, 0.47, 0.43), 4);
    let mut rng = Pcg32::seed_from_u64(seed);
    let s = 1.0 / 2f32.sqrt();
    let mut mirrors = vec![
        MirrorPlane::new(Vec3::new(s, -s, 0.0), 0.0),
        MirrorPlane::new(Vec3::new(0.0, s, -s), 0.0),
        MirrorPlane::new(Vec3::new(s, -s, 0.0), 0.0),
        MirrorPlane::new(Vec3::Z, 0.0),
        MirrorPlane::new(Vec3::Y, 0.0),
        MirrorPlane::new(Vec3::X, 0.0),
    ];
    for _ in 0..BATTERING_MIRRORS {
        let normal = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
        .normalize_or(Vec3::X);
        // Through a point up to a quarter of the radius from the centre: the kept half and its
        // image stretch or squash the rock along the normal by twice that.
        mirrors.push(MirrorPlane::new(normal, rng.random_range(-0.22..0.22)));
    }
    let mut plane = |offset: f32| {
        let n = Vec3::new(
            -rng.random_range(0.6..1.0),
            -rng.random_range(0.6..1.0),
            -rng.random_range(0.6..1.0),
        );
        Kernel::InfinitePlane(PlaneKernel {
            normal: n.normalize_or(-Vec3::ONE),
            offset,
            material: stone,
        })
    };
    let mut kernels = vec![plane(0.95), plane(0.9), plane(1.0), plane(0.85)];
    kernels.resize(mirrors.len() + 1, Kernel::Empty);
    let yaw = rng.random_range(0.0..TAU);
    KrsObject {
        name: "battered rock".to_owned(),
        kernels,
        mirrors,
        world_from_object: Similarity {
            translation: Vec3::new(0.0, 0.55, 0.0),
            rotation: Quat::from_euler(glam::EulerRot::YXZ, yaw, 0.35, 0.2),
            scale: 1.0,
        },
        distortion: Some(Distortion {
            amplitude: 0.07,
            frequency: 1.6,
            seed: seed as u32,
        }),
        texturing: Texturing {
            mode: TextureMode::Triplanar,
            pattern: Pattern::Bark,
            scale: 2.5,
            contrast: 0.45,
            sharpness: 4.0,
        },
        empty_zones: Vec::new(),
    }
}

/// The near-centre mirrors of [`battered_rock`] (its other six are the octant folds).
pub const BATTERING_MIRRORS: usize = 8;

/// How [`scatter_mirrors`] places copies of a piece side by side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scatter {
    /// Number of mirrors (2^count copies).
    pub count: usize,
    /// Largest azimuth jitter (radians) of a mirror normal from the x or z axis (they
    /// alternate), for the first [`Scatter::fine_levels`] mirrors; a tenth of it after.
    pub jitter: f32,
    /// Largest tilt (radians) of a mirror normal out of the horizontal, for the first
    /// `fine_levels` mirrors; a quarter of it after. A ground folded by tilted mirrors rises and
    /// falls; a piece standing on it leans by up to twice the tilt per fold.
    pub tilt: f32,
    /// Mirrors whose jitter and tilt are not reduced.
    pub fine_levels: usize,
    /// The gap between neighbouring copies, as a fraction of the piece's radius: a uniform draw
    /// from `gap.0..gap.1` (equal values: no draw, a regular spacing).
    pub gap: (f32, f32),
    /// Seed of the draws.
    pub seed: u64,
    /// No draws at all: normals exactly along x and z, tilts of `+tilt` and `−tilt` in turn,
    /// the mean gap. The copies stand on a regular lattice (every symmetry in plain view).
    pub regular: bool,
}

impl Default for Scatter {
    fn default() -> Self {
        Self {
            count: 10,
            jitter: 0.05,
            tilt: 0.04,
            fine_levels: 6,
            gap: (0.05, 0.4),
            seed: 42,
            regular: false,
        }
    }
}

impl Scatter {
    /// The same placement without its draws ([`Scatter::regular`]): symmetry hiding by
    /// unaligned mirrors off, the ground still folded as steeply.
    #[must_use]
    pub fn aligned(self) -> Self {
        Self {
            regular: true,
            ..self
        }
    }
}

/// Mirrors that multiply a piece bounded by the ball `(centre, radius)` into 2^count copies
/// side by side (the forest's placement, §7.2): each mirror lies just beyond every copy made so
/// far along its normal, so kernel separation holds between copies (none is clipped).
pub fn scatter_mirrors(ball: (Vec3, f32), scatter: &Scatter) -> Vec<MirrorPlane> {
    let (centre, radius) = ball;
    let mut rng = Pcg32::seed_from_u64(scatter.seed);
    let mut centres = vec![centre];
    let mut mirrors = Vec::with_capacity(scatter.count);
    for i in 0..scatter.count {
        let (jitter, tilt) = if i < scatter.fine_levels {
            (scatter.jitter, scatter.tilt)
        } else {
            (0.1 * scatter.jitter, 0.25 * scatter.tilt)
        };
        let base = if i % 2 == 0 { 0.0 } else { FRAC_PI_2 };
        let (azimuth, tilt) = if scatter.regular {
            // Alternate the sign per pair, so x and z both get a rise and a fall.
            let sign = if (i / 2) % 2 == 0 { 1.0 } else { -1.0 };
            (base, sign * tilt)
        } else {
            let azimuth = base + symmetric(&mut rng, jitter);
            (azimuth, symmetric(&mut rng, tilt))
        };
        let normal = tilted_normal(azimuth, tilt);
        let reach = centres
            .iter()
            .map(|c| c.dot(normal))
            .fold(f32::NEG_INFINITY, f32::max);
        let gap = if scatter.regular {
            0.5 * (scatter.gap.0 + scatter.gap.1)
        } else if scatter.gap.1 > scatter.gap.0 {
            rng.random_range(scatter.gap.0..scatter.gap.1)
        } else {
            scatter.gap.0
        };
        let mirror = MirrorPlane::new(normal, reach + radius * (1.0 + gap));
        let reflected: Vec<Vec3> = centres.iter().map(|c| mirror.reflect_point(*c)).collect();
        centres.extend(reflected);
        mirrors.push(mirror);
    }
    mirrors
}

/// `object` with `mirrors` appended as its coarsest levels (empty kernels): 2^len copies.
#[must_use]
pub fn with_extra_mirrors(mut object: KrsObject, mirrors: &[MirrorPlane]) -> KrsObject {
    object.mirrors.extend_from_slice(mirrors);
    object
        .kernels
        .resize(object.mirrors.len() + 1, Kernel::Empty);
    object
}

/// A KRS ground: the plane y = 0 folded by `fine` small tilted mirrors of its own around the
/// origin (bumps between the copies of a piece of radius `radius` standing there; the origin
/// stays on their kept side, so the ground under the piece is untouched), textured as soil.
/// [`on_terrain`] and the forest grower ([`super::forest`]) add shared mirrors after these.
#[must_use]
pub fn folded_ground(ground: Material, fine: usize, radius: f32, seed: u64) -> KrsObject {
    let mut rng = Pcg32::seed_from_u64(seed ^ 0x9e37_79b9);
    let mut mirrors = Vec::with_capacity(fine);
    for i in 0..fine {
        let normal = random_fold_normal(&mut rng, 0.06..0.16);
        // Beyond the trunk or stem (a fifth of the radius), growing per level.
        let offset = radius * rng.random_range(0.2..0.5) * 1.5f32.powi(i as i32);
        mirrors.push(MirrorPlane::new(normal, offset));
    }
    let mut kernels = vec![Kernel::InfinitePlane(PlaneKernel {
        normal: Vec3::Y,
        offset: 0.0,
        material: ground,
    })];
    kernels.resize(mirrors.len() + 1, Kernel::Empty);
    KrsObject {
        name: "terrain".to_owned(),
        kernels,
        mirrors,
        texturing: Texturing {
            mode: TextureMode::Triplanar,
            pattern: Pattern::Bark,
            scale: 0.8,
            contrast: 0.35,
            sharpness: 4.0,
        },
        ..KrsObject::default()
    }
}

/// A piece (a tree, a grass tuft, a coral; object space = world space, standing on y = 0 at
/// the origin) scattered over a KRS terrain by **shared reflections** (§7.2: a forest's extra
/// reflections "identical to those of the terrain"): the terrain is the ground plane y = 0,
/// folded first by `fine` small mirrors of its own around the origin (bumps between the
/// copies; the origin stays on their kept side, so the ground under the piece is untouched) and
/// then by the same mirrors as the piece. Each copy of the piece and the ground under it are
/// images of the originals under the same isometry, so every copy stands on the terrain exactly,
/// on slopes as well (leaning with them). The terrain takes the piece's distortion too, so the
/// warp moves both alike.
///
/// # Errors
/// The piece fails validation or is unbounded.
pub fn on_terrain(
    piece: KrsObject,
    ground: Material,
    scatter: &Scatter,
    fine: usize,
) -> Result<KrsScene, super::object::KrsError> {
    let prepared = KrsScene {
        objects: vec![piece.clone()],
    }
    .prepare()?;
    let ball = prepared.objects[0]
        .bound_world
        .ok_or(super::object::KrsError::Unbounded { object: 0 })?;
    let shared = scatter_mirrors(ball, scatter);
    let mut terrain = folded_ground(ground, fine, ball.1, scatter.seed);
    terrain.distortion = piece.distortion;
    let terrain = with_extra_mirrors(terrain, &shared);
    Ok(KrsScene {
        objects: vec![terrain, with_extra_mirrors(piece, &shared)],
    })
}
