//! The `thicket` command line: `thicket [PROJECT]` opens the editor; subcommands work on files
//! without a window. Outputs are written only after the work succeeded (the savers are atomic),
//! so a failed command leaves nothing behind.

use std::io::Write as _;
use std::path::PathBuf;

use anyhow::Context as _;
use clap::{Args, Parser, Subcommand};

use crate::files::{self, DocumentInfo, human_bytes, memory_budget, thousands, thousands_u128};

pub mod forest;
pub mod rig;
pub mod view_args;

pub use view_args::{CameraArg, ImageSize, QualityArg, ViewArgs, parse_error_exit_code};

/// Thicket: sculpt voxel models, pose and skin them, grow procedural trees, export assets.
///
/// Without a subcommand, opens the editor (on PROJECT if given, else on the first sample
/// project in `projects/`).
#[derive(Debug, Parser)]
#[command(name = "thicket", version, args_conflicts_with_subcommands = true)]
pub struct Cli {
    /// Project (or any supported file) to open in the editor.
    pub project: Option<PathBuf>,

    /// What to do instead of opening the editor.
    #[command(subcommand)]
    pub command: Option<Command>,
}

/// An error and its causes on one line, each said once: a cause whose text an outer message
/// already contains (a `{source}` in a `thiserror` message, or a context that quotes it) is
/// not repeated. `error: a.vox: truncated: …`.
#[must_use]
pub fn error_line(error: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in error.chain() {
        let text = cause.to_string();
        let text = text.trim();
        if text.is_empty() || line.contains(text) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(text);
    }
    line
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Describe a file: objects, voxel counts, dimensions, bytes per voxel, triangles.
    ///
    /// Reads .thicket.json projects, .vox, .glb/.gltf and .obj files.
    Info(InfoArgs),
    /// Write the visible voxel objects of a project (or any supported file) as MagicaVoxel .vox.
    ///
    /// Models larger than 256 voxels in a dimension are split; colours are quantised to the
    /// 255-entry palette (the report says how far).
    ExportVox(ExportVoxArgs),
    /// Turn a mesh (.glb/.gltf/.obj) or a .vox file into a project.
    ///
    /// Meshes are voxelized (surface by default, `--solid` fills closed meshes); .vox models
    /// come in as they are, placed by their scene graph.
    Import(ImportArgs),
    /// Render a project with the CPU reference renderer (or the GPU renderer, `--gpu`) to a PNG.
    Render(RenderArgs),
    /// Time N frames of a project: frame times, fps, per-pass milliseconds, counters.
    ///
    /// The CPU reference renderer by default; `--gpu` for the GPU renderer (per-pass times from
    /// timestamp queries when the adapter has them); `--compare` runs both in one process and
    /// prints the CPU/GPU ratio.
    Bench(BenchArgs),
    /// Enhance a voxel object: coarse voxels become fine, deterministic fragments (Smith 2011).
    ///
    /// Adds the result as a new object "NAME (enhanced)" (replacing an earlier one of that
    /// name) and hides the coarse original, so renders and exports show the fine model while
    /// the coarse one stays editable; `--replace` swaps the object in place instead. The
    /// project records the link with its settings, so the editor re-enhances the fine model
    /// where strokes change the coarse one. See docs/enhance.md for the rules and options.
    Enhance(EnhanceArgs),
    /// Measure the speed/accuracy trade: render a high-quality reference, then each setting of
    /// the given quality knobs, varied from the project's own quality (as the editor's sweep
    /// does); write report.json, report.csv and tradeoff.png to a directory.
    Tradeoff(TradeoffArgs),
    /// Export a project (or any supported file) as glTF 2.0: OUT.glb, or OUT.gltf + OUT.bin.
    ///
    /// Voxel models become their exposed faces greedy-merged into quads (`cubes`) or a smooth
    /// closed surface (`smooth`); KRS objects a closed mesh of their distance field, or with
    /// `instances` one mesh per kernel drawn once per kernel instance; meshes are written as
    /// they are. The file is written atomically, only when the export succeeded.
    Export(ExportArgs),
    /// Start a project with one new voxel model (for scripts; the editor's File → New project).
    ///
    /// The model stands on the ground grid, centred on the origin; its volume is the given
    /// extent, which the editor draws and clips edits to.
    New(NewArgs),
    /// Measure a skinned model's holes and bloat per stretch strategy over its clip.
    ///
    /// The voxels are drawn with each strategy and compared with the source mesh (for a model
    /// rigged in Thicket, its own skinned surface, as Export writes it) skinned with the same
    /// pose from the same cameras (views around the model), pixel by pixel by depth:
    /// holes are pixels where the skin is nearer than the voxels by more than two voxels (or no
    /// voxel covers), bloat the converse. Rest-pose error and stretch error are reported
    /// apart.
    SkinReport(SkinReportArgs),
    /// Give a voxel model a skeleton and bind its voxels to it (automatic weights).
    ///
    /// The skeleton file names joints at positions in the model's own space; weights are
    /// computed on the voxels (geodesic through the model by default). An existing rig is
    /// replaced; its clips are kept for the joints whose names the new skeleton has.
    Rig(rig::RigArgs),
    /// Add a keyframed clip to a rigged voxel model (rotations as Euler degrees relative to the
    /// rest pose); the model then plays it.
    Animate(rig::AnimateArgs),
    /// Grow a forest from trees of a project (KRS objects made by the tree builder): more
    /// reflections with empty kernel sets repeat the tree over an area, shared with a KRS
    /// terrain when `--on` names one, several trees interleaved so none stands beside its
    /// own mirror image. Prints the number of trees placed.
    Forest(forest::ForestArgs),
}

/// `thicket skin-report`.
#[derive(Debug, Args)]
pub struct SkinReportArgs {
    /// The project holding a skinned voxel model (made by `thicket import` of a skinned glTF,
    /// or rigged with `thicket rig` or the editor).
    #[arg(required_unless_present = "cylinder", conflicts_with = "cylinder")]
    pub project: Option<PathBuf>,
    /// Measure the synthetic bending cylinder instead of a project (radius 0.4, length 2, two
    /// joints, bent 90° at t = 1 s of its 2 s clip), voxelized at this octree depth.
    #[arg(long, value_name = "DEPTH", value_parser = clap::value_parser!(u8).range(3..=10))]
    pub cylinder: Option<u8>,
    /// Frames, evenly spaced over the clip (the rest pose is measured on top).
    #[arg(long, default_value_t = 10)]
    pub frames: u32,
    /// Views, evenly spaced around the model (level, orthographic).
    #[arg(long, default_value_t = 6)]
    pub views: u32,
    /// Image size as WIDTHxHEIGHT.
    #[arg(long, default_value = "400x400", value_parser = ImageSize::parse)]
    pub size: ImageSize,
    /// Clip by name (default: the project's).
    #[arg(long)]
    pub clip: Option<String>,
    /// Print the per-view lines too (JSON always has them).
    #[arg(long)]
    pub per_view: bool,
    /// Cap on the scalar stretch factors (`Thesis`, `Adaptive`; `Corners` boxes are not
    /// capped), 1..=16; default the settings' 4.
    #[arg(long)]
    pub max_factor: Option<f32>,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
    /// Most memory the report may need, e.g. 4G or 512M (default: the smallest of half this
    /// machine's physical memory and this process's address-space and cgroup limits): loading
    /// the project and one frame at --size, each estimated before the work.
    #[arg(long, value_name = "SIZE", value_parser = thicket_core::budget::parse_bytes)]
    pub memory_limit: Option<u64>,
}

/// `thicket bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// The project (or any supported file) to render.
    pub project: PathBuf,
    /// Time the GPU renderer instead of the CPU reference renderer.
    #[arg(long, conflicts_with = "compare")]
    pub gpu: bool,
    /// Time both renderers, one after the other, and print the ratio.
    #[arg(long)]
    pub compare: bool,
    /// GPU: use the two-pass 32-bit splat path even when 64-bit atomics exist.
    #[arg(long)]
    pub two_pass: bool,
    /// Timed frames (after one warm-up frame).
    #[arg(long, default_value_t = 20)]
    pub frames: u32,
    /// Image size, camera and quality overrides.
    #[command(flatten)]
    pub view: ViewArgs,
    /// Print machine-readable JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Animation time in seconds for skinned models and frame sequences (animated .vox)
    /// (default: the project's playhead).
    #[arg(long)]
    pub time: Option<f32>,
    /// Animation clip of skinned models, by name (default: the project's).
    #[arg(long)]
    pub clip: Option<String>,
    /// GPU: repeats of the splat-bandwidth measurement (the view's voxel pass against a
    /// buffer copy of the same bytes); 0 skips it.
    #[arg(long, default_value_t = 5)]
    pub splat_repeats: u32,
    /// GPU: request this `max_storage_buffer_binding_size` (bytes) when below the adapter's,
    /// so the voxel pools are split into more chunks (to measure what chunking costs).
    #[arg(long, value_name = "BYTES")]
    pub binding_limit: Option<u64>,
    /// Most memory one CPU frame may need, e.g. 4G or 512M (default: the smallest of half this
    /// machine's physical memory and this process's address-space and cgroup limits). A larger
    /// request is refused before it allocates, with its estimate.
    #[arg(long, value_name = "SIZE", value_parser = thicket_core::budget::parse_bytes)]
    pub memory_limit: Option<u64>,
    /// Turn the camera's yaw by this many degrees before each timed frame, as when orbiting in
    /// the editor; the CPU renderer then keeps its shadow maps in a shadow cache, as its
    /// preview does.
    #[arg(
        long,
        value_name = "DEGREES",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub orbit: f32,
    /// Bake every skinned model's shown pose (after `--time` and `--clip`) into a rigid voxel
    /// model without its rig before timing: the static reference that skinning's cost is
    /// measured against (same pose, same voxel size; see `docs/skinning.md`).
    #[arg(long)]
    pub no_rig: bool,
}

/// Enhancement operator for `thicket enhance`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum EnhanceMethodArg {
    /// Recursive subdivision (power-of-two factors).
    Subdivide,
    /// Direct resampling with a stored random probe pattern (any factor).
    Resample,
}

/// Colour rule for `thicket enhance`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum EnhanceColorArg {
    /// Weighted average of same-material contributors.
    Blend,
    /// The strongest same-material contributor.
    Nearest,
}

/// `thicket enhance`.
#[derive(Debug, Args)]
pub struct EnhanceArgs {
    /// The project holding the coarse voxel object.
    pub project: PathBuf,
    /// Name of the voxel object to enhance.
    #[arg(long)]
    pub object: String,
    /// Recursive subdivision or direct resampling.
    #[arg(long, value_enum, default_value = "subdivide")]
    pub method: EnhanceMethodArg,
    /// Fragments per voxel edge (subdivide: 2, 4, 8, 16, 32, 64; resample: 1..=64).
    #[arg(long)]
    pub factor: u32,
    /// Threshold everywhere. Subdivide: solid voxels among 4 (1..=4, default 2); resample:
    /// fraction of probes that must hit (default 0.25).
    #[arg(long)]
    pub threshold: Option<f32>,
    /// Alternating thresholds EVEN,ODD by the parity of the fragment's altitude (the paper's
    /// strata, e.g. 3,4).
    #[arg(long, value_name = "EVEN,ODD", conflicts_with = "threshold")]
    pub strata: Option<String>,
    /// Per-material threshold MATERIAL=THRESHOLD (repeatable); other materials use
    /// --threshold or its default.
    #[arg(
        long = "material-threshold",
        value_name = "MATERIAL=THRESHOLD",
        conflicts_with = "strata"
    )]
    pub material_threshold: Vec<String>,
    /// Resample: probes per fragment (default 16).
    #[arg(long)]
    pub probes: Option<u32>,
    /// Resample: probe spread in coarse voxels (default 1.0).
    #[arg(long)]
    pub spread: Option<f32>,
    /// Resample: seed of the probe pattern (default 1).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Colour rule.
    #[arg(long, value_enum, default_value = "blend")]
    pub color: EnhanceColorArg,
    /// Bake random-walk ("snowflake") lighting into the fragment colours.
    #[arg(long)]
    pub lighting: bool,
    /// Lighting: direction toward the sun as X,Y,Z (Y up; default: the document's first light).
    #[arg(long, value_name = "X,Y,Z", requires = "lighting")]
    pub sun: Option<String>,
    /// Lighting: sun and sky particles per fragment (default 8 each).
    #[arg(long, requires = "lighting")]
    pub particles: Option<u32>,
    /// Lighting: seed of the walks (default 7).
    #[arg(long, requires = "lighting")]
    pub light_seed: Option<u64>,
    /// Replace the object with its enhancement (same name and id) instead of adding one.
    #[arg(long)]
    pub replace: bool,
    /// The project to write (NAME.thicket.json; its payload NAME.thicket.HASH.bin is written beside it).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Most memory the enhancement may need, e.g. 4G or 512M (default: the smallest of half this
    /// machine's physical memory and this process's address-space and cgroup limits). A larger
    /// request is refused before it starts, with its estimate.
    #[arg(long, value_name = "SIZE", value_parser = thicket_core::budget::parse_bytes)]
    pub memory_limit: Option<u64>,
}

/// `thicket tradeoff`.
#[derive(Debug, Args)]
pub struct TradeoffArgs {
    /// The project (or any supported file) to measure.
    pub project: PathBuf,
    /// The directory for report.json, report.csv and tradeoff.png (created if missing).
    #[arg(short, long)]
    pub output: PathBuf,
    /// A knob and its values as NAME=V1,V2,... (repeatable); default: the knobs the CPU
    /// renderer reads (LOD threshold, shadow map size, PCF radius, AO samples).
    #[arg(long = "knob", value_name = "NAME=V1,V2,...", value_parser = view_args::parse_knob_values)]
    pub knobs: Vec<thicket_core::measure::KnobValues>,
    /// Image size as WIDTHxHEIGHT; the default is the editor's 800x800 view, where the presets
    /// are used. A knob that draws the same image at every value at this size is reported as
    /// having no effect and left out of the plot.
    #[arg(long, default_value = "800x800", value_parser = ImageSize::parse)]
    pub size: ImageSize,
    /// Renders per setting; the reported time is their median, with their min-max spread.
    #[arg(long, default_value_t = 3)]
    pub frames: usize,
    /// Render every combination of the knob values instead of one knob at a time.
    #[arg(long)]
    pub grid: bool,
    /// Leave the draft / balanced / final presets out of the sweep.
    #[arg(long)]
    pub no_presets: bool,
    /// Draw every setting with the GPU renderer (the reference stays the CPU reference
    /// renderer's image, so GPU-only differences count as error).
    #[arg(long)]
    pub gpu: bool,
    /// The most memory the sweep's CPU frames may need, e.g. 2G or 512MiB (default: the smallest of
    /// half this machine's physical memory and this process's address-space and cgroup limits). A
    /// sweep estimated over it is refused before it starts.
    #[arg(long, value_name = "SIZE", value_parser = thicket_core::budget::parse_bytes)]
    pub memory_limit: Option<u64>,
}

/// How `thicket export` meshes voxel models and KRS objects.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ExportModeArg {
    /// Exposed voxel faces, greedy-merged per colour and material; KRS objects as a closed mesh
    /// of their distance field at --resolution.
    Cubes,
    /// A smooth closed surface through the voxel centres; KRS objects as in cubes.
    Smooth,
    /// KRS objects as one mesh per kernel drawn once per kernel instance
    /// (EXT_mesh_gpu_instancing); voxel models as in cubes.
    Instances,
}

/// `thicket export`.
#[derive(Debug, Args)]
pub struct ExportArgs {
    /// The project (or any supported file) to export.
    pub project: PathBuf,
    /// The file to write: .glb, or .gltf (a .bin with the same stem is written beside it).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Export only this object (by name); default: every visible object.
    #[arg(long)]
    pub object: Option<String>,
    /// How voxel models and KRS objects become triangles.
    #[arg(long, value_enum, default_value = "cubes")]
    pub mode: ExportModeArg,
    /// KRS meshing resolution: cells along the longest side of each KRS object.
    #[arg(long, default_value_t = 256)]
    pub resolution: u32,
    /// Store colours in a palette texture instead of COLOR_0 vertex colours.
    #[arg(long)]
    pub palette_texture: bool,
    /// Add N coarser levels of detail (MSFT_lod), each at half the resolution of the one
    /// before: per static voxel model (cubes mode) and per KRS mesh or instanced prototype
    /// (cubes and smooth modes; the distance field meshed at --resolution / 2^k). Default:
    /// none, except instanced KRS prototypes (a forest's tree), which get 3 and an impostor.
    #[arg(long, value_name = "N")]
    pub lod: Option<u8>,
    /// Leave out the impostor (crossed quads textured with pictures of the prototype) that is
    /// the coarsest level of detail of an instanced KRS prototype.
    #[arg(long)]
    pub no_impostor: bool,
    /// Split each instanced prototype's placements into about N grid cells (one node per cell
    /// and copy, so a viewer culls and picks a level of detail per cell); default: one cell per
    /// 512 placements, at most 256.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub cells: Option<u32>,
    /// KRS objects: the reflection level where the instanced prototype ends (mirrors above it
    /// become EXT_mesh_gpu_instancing placements); default: the deepest level whose mirrors
    /// above only place copies. A level past an object's mirrors writes it as one mesh.
    #[arg(long, value_name = "K")]
    pub instance_level: Option<usize>,
    /// Write unbounded KRS objects (ground plane, terrain) as this patch instead of the area
    /// the other objects cover plus a margin.
    #[arg(long, value_name = "MINX,MINZ,MAXX,MAXZ", value_parser = parse_bounds)]
    pub bounds: Option<[f32; 4]>,
    /// Most instances one KRS object may have.
    #[arg(long, default_value_t = 1 << 20, value_name = "N")]
    pub max_instances: usize,
    /// Most triangles the whole export may have (checked before meshing).
    #[arg(long, default_value_t = 1 << 26, value_name = "N")]
    pub max_triangles: u64,
    /// Write the document's lights (KHR_lights_punctual) and camera: `auto` writes them for a
    /// whole-scene export and leaves them out with --object (that object alone, like Blender's
    /// "Selected objects" and the editor's Export dialog); `on` / `off` decide either way.
    #[arg(long, value_enum, default_value = "auto")]
    pub lights_camera: LightsCameraArg,
    /// How an instanced KRS object's placements are written: `gpu`, EXT_mesh_gpu_instancing
    /// (compact; readers without the extension refuse the file, Blender 3.4 among them);
    /// `nodes`, a node per placement sharing the mesh (every reader; no levels of detail for
    /// them); `auto`, nodes up to 4,096 placements, else gpu.
    #[arg(long, value_enum, default_value = "gpu")]
    pub instancing: InstancingArg,
    /// No instancing at all: bake every placement's copy into plain meshes, for tools that
    /// read neither EXT_mesh_gpu_instancing nor shared meshes; refused before meshing the
    /// copies when they would pass --max-triangles (overrides --instancing).
    #[arg(long)]
    pub flatten: bool,
    /// Most memory reading the input may need, e.g. 4G or 512M (default: the smallest of half
    /// this machine's physical memory and this process's address-space and cgroup limits),
    /// estimated before it is read; the meshing is bounded by --max-triangles.
    #[arg(long, value_name = "SIZE", value_parser = thicket_core::budget::parse_bytes)]
    pub memory_limit: Option<u64>,
}

/// `thicket export --instancing`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum InstancingArg {
    /// EXT_mesh_gpu_instancing.
    Gpu,
    /// A node per placement.
    Nodes,
    /// Nodes for a few placements, else gpu.
    Auto,
}

/// `thicket export --lights-camera`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum LightsCameraArg {
    /// With a whole-scene export, not with --object.
    Auto,
    /// Always.
    On,
    /// Never.
    Off,
}

/// `MINX,MINZ,MAXX,MAXZ` as four finite numbers with MIN < MAX.
fn parse_bounds(text: &str) -> Result<[f32; 4], String> {
    let values: Vec<f32> = text
        .split(',')
        .map(|v| v.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{text:?}: {e}; expected MINX,MINZ,MAXX,MAXZ"))?;
    let [x0, z0, x1, z1] = values[..] else {
        return Err(format!(
            "{text:?}: expected four numbers MINX,MINZ,MAXX,MAXZ, got {}",
            values.len()
        ));
    };
    if !(values.iter().all(|v| v.is_finite()) && x0 < x1 && z0 < z1) {
        return Err(format!(
            "{text:?}: the numbers must be finite with MINX < MAXX and MINZ < MAXZ"
        ));
    }
    Ok([x0, z0, x1, z1])
}

/// Initial content of `thicket new`'s model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum NewFillArg {
    /// No voxels.
    Empty,
    /// One layer of voxels on the volume's floor.
    Slab,
    /// The whole volume solid.
    Solid,
}

/// `thicket new`.
#[derive(Debug, Args)]
pub struct NewArgs {
    /// The project to write (NAME.thicket.json; its payload NAME.thicket.HASH.bin is written beside it).
    pub output: PathBuf,
    /// Voxels per axis as X,Y,Z (each 1 to 2097152, the octree's limit).
    #[arg(long, default_value = "32,32,32", value_parser = parse_extent)]
    pub extent: glam::UVec3,
    /// Edge of one voxel in metres.
    #[arg(long, default_value_t = 0.1)]
    pub voxel_size: f32,
    /// What the volume holds at first.
    #[arg(long, value_enum, default_value_t = NewFillArg::Empty)]
    pub fill: NewFillArg,
    /// The model's name.
    #[arg(long, default_value = "Model")]
    pub name: String,
}

/// Parses `X,Y,Z` voxel counts.
fn parse_extent(s: &str) -> Result<glam::UVec3, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let [x, y, z] = parts.as_slice() else {
        return Err(format!(
            "{s:?} is not X,Y,Z (three voxel counts separated by commas)"
        ));
    };
    let n = |v: &str| {
        v.parse::<u32>()
            .map_err(|_| format!("{v:?} in {s:?} is not a whole number of voxels"))
    };
    Ok(glam::UVec3::new(n(x)?, n(y)?, n(z)?))
}

/// `thicket import`.
#[derive(Debug, Args)]
pub struct ImportArgs {
    /// The file to import (.glb, .gltf, .obj or .vox).
    pub input: PathBuf,
    /// The project to write (NAME.thicket.json; its payload NAME.thicket.HASH.bin is written beside it).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Octree depth: the longest side of each object (each glTF node with a mesh, or the whole
    /// file with --merge) spans 2^N voxels (default 7).
    #[arg(long, conflicts_with = "voxel_size")]
    pub depth: Option<u8>,
    /// Voxel edge length in the file's world units, one size for every object.
    #[arg(long)]
    pub voxel_size: Option<f32>,
    /// Import only the glTF node(s) of this name (repeatable); by default every node with a
    /// mesh becomes its own object.
    #[arg(long = "node", value_name = "NAME", conflicts_with = "merge")]
    pub nodes: Vec<String>,
    /// One voxel grid for the whole glTF scene (its nodes merged in world space) instead of one
    /// object per node.
    #[arg(long)]
    pub merge: bool,
    /// Voxelize huge flat planes (ground, water) too; by default they are imported as mesh
    /// objects, with a warning.
    #[arg(long)]
    pub voxelize_planes: bool,
    /// Fill the inside of closed meshes instead of voxelizing only the surface.
    #[arg(long)]
    pub solid: bool,
    /// Import a skinned glTF as a static model (by default its skeleton and clips come along
    /// and the voxels carry joint weights).
    #[arg(long)]
    pub no_skin: bool,
    /// A base-colour texture (PNG or JPEG) for an OBJ whose materials name none, e.g. one
    /// shipped without its .mtl (OBJ only).
    #[arg(long, value_name = "PATH")]
    pub texture: Option<PathBuf>,
    /// Most memory the voxelization may need, e.g. 4G or 512M (default: the smallest of half this
    /// machine's physical memory and this process's address-space and cgroup limits). A larger
    /// request is refused before it voxelizes, with its estimate.
    #[arg(long, value_name = "SIZE", value_parser = thicket_core::budget::parse_bytes)]
    pub memory_limit: Option<u64>,
}

/// `thicket render`.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// The project (or any supported file) to render.
    pub project: PathBuf,
    /// The PNG to write.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Image size, camera and quality overrides.
    #[command(flatten)]
    pub view: ViewArgs,
    /// Print frame statistics (per level, splats, culling, stage times).
    #[arg(long)]
    pub stats: bool,
    /// Animation time in seconds for skinned models and frame sequences (animated .vox)
    /// (default: the project's playhead).
    #[arg(long)]
    pub time: Option<f32>,
    /// Animation clip of skinned models, by name (default: the project's).
    #[arg(long)]
    pub clip: Option<String>,
    /// Render with the GPU renderer (wgpu; any adapter, including a software one).
    #[arg(long)]
    pub gpu: bool,
    /// Render a turntable of N frames instead of one image: the camera orbits 360 degrees
    /// about the target in N equal steps, written as OUTPUT's stem + `_000.png`, `_001.png`, ...
    #[arg(long, value_name = "N")]
    pub turntable: Option<u32>,
    /// Most memory one CPU frame may need, e.g. 4G or 512M (default: the smallest of half this
    /// machine's physical memory and this process's address-space and cgroup limits). A larger
    /// request is refused before it allocates, with its estimate.
    #[arg(long, value_name = "SIZE", value_parser = thicket_core::budget::parse_bytes)]
    pub memory_limit: Option<u64>,
}

/// Most frames a turntable may have.
const MAX_TURNTABLE_FRAMES: u32 = 3600;

/// `thicket export-vox`.
#[derive(Debug, Args)]
pub struct ExportVoxArgs {
    /// The project to export.
    pub project: PathBuf,
    /// The .vox file to write (written atomically, only when the export succeeded).
    #[arg(short, long)]
    pub output: PathBuf,
    /// World length of one .vox voxel (default: the smallest voxel edge among the exported
    /// objects, so the finest keeps one cell per voxel; objects with larger voxels fill
    /// several cells each).
    #[arg(long, value_name = "SIZE")]
    pub grid_unit: Option<f32>,
    /// Most memory the export may need, e.g. 4G or 512M (default: the smallest of half this
    /// machine's physical memory and this process's address-space and cgroup limits). A larger
    /// request is refused before any voxel is placed, with its estimate.
    #[arg(long, value_name = "SIZE", value_parser = thicket_core::budget::parse_bytes)]
    pub memory_limit: Option<u64>,
}

/// `thicket info`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// The file to describe.
    pub file: PathBuf,
    /// Print machine-readable JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Add a per-object memory report (octree structure, attributes, free slots, textures).
    #[arg(long)]
    pub memory: bool,
    /// List each rigged model's joints with the voxels each is the strongest influence of.
    #[arg(long)]
    pub joints: bool,
    /// Most memory reading the file may need, e.g. 4G or 512M (default: the smallest of half
    /// this machine's physical memory and this process's address-space and cgroup limits). It
    /// is estimated before the work (a mesh's vertices with every instance, a .vox scene
    /// graph's copies, a project's payload) and a larger request is refused with its estimate.
    #[arg(long, value_name = "SIZE", value_parser = thicket_core::budget::parse_bytes)]
    pub memory_limit: Option<u64>,
}

/// Runs a parsed command line.
///
/// # Errors
/// Any failure, with a message that names the file and the problem; the caller prints it and
/// exits with a non-zero code.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        None => crate::ui::run_editor(cli.project),
        Some(Command::Info(args)) => info(&args),
        Some(Command::ExportVox(args)) => export_vox(&args),
        Some(Command::Import(args)) => import(&args),
        Some(Command::Render(args)) => render(&args),
        Some(Command::SkinReport(args)) => skin_report(&args),
        Some(Command::New(args)) => new_project(&args),
        Some(Command::Bench(args)) => bench(&args),
        Some(Command::Enhance(args)) => enhance(&args),
        Some(Command::Tradeoff(args)) => tradeoff(&args),
        Some(Command::Export(args)) => export(&args),
        Some(Command::Rig(args)) => rig::rig(&args),
        Some(Command::Forest(args)) => forest::forest(&args),
        Some(Command::Animate(args)) => rig::animate(&args),
    }
}

/// Parses "A,B,..." into exactly `N` finite numbers for option `flag`.
fn parse_floats<const N: usize>(flag: &str, text: &str) -> anyhow::Result<[f32; N]> {
    let parts: Vec<f32> = text
        .split(',')
        .map(|p| p.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("{flag} {text:?}: expected {N} comma-separated numbers"))?;
    let arr: [f32; N] = parts
        .try_into()
        .map_err(|_| anyhow::anyhow!("{flag} {text:?}: expected {N} comma-separated numbers"))?;
    anyhow::ensure!(
        arr.iter().all(|v| v.is_finite()),
        "{flag} {text:?}: numbers must be finite"
    );
    Ok(arr)
}

/// The settings `thicket enhance` asks for; options of the other method are refused so a typo
/// does not silently do nothing.
fn enhance_settings(
    args: &EnhanceArgs,
    doc: &thicket_core::scene::Document,
) -> anyhow::Result<thicket_core::enhance::EnhanceSettings> {
    use thicket_core::enhance::{
        ColorMode, EnhanceSettings, MaterialThreshold, Method, ThresholdPattern,
    };
    let mut s = EnhanceSettings {
        factor: args.factor,
        ..EnhanceSettings::default()
    };
    s.method = match args.method {
        EnhanceMethodArg::Subdivide => {
            for (flag, given) in [
                ("--probes", args.probes.is_some()),
                ("--spread", args.spread.is_some()),
                ("--seed", args.seed.is_some()),
            ] {
                anyhow::ensure!(!given, "{flag} applies to --method resample, not subdivide");
            }
            Method::Subdivide
        }
        EnhanceMethodArg::Resample => Method::Resample,
    };
    let default_threshold = match s.method {
        Method::Subdivide => 2.0,
        Method::Resample => 0.25,
    };
    let base = args.threshold.unwrap_or(default_threshold);
    let pattern = if let Some(text) = &args.strata {
        let [even, odd] = parse_floats::<2>("--strata", text)?;
        ThresholdPattern::Alternating { even, odd }
    } else if !args.material_threshold.is_empty() {
        let mut materials = Vec::new();
        for kv in &args.material_threshold {
            let (m, t) = kv.split_once('=').with_context(|| {
                format!("--material-threshold {kv:?}: expected MATERIAL=THRESHOLD, e.g. 2=3")
            })?;
            let material = m.trim().parse::<u8>().with_context(|| {
                format!("--material-threshold {kv:?}: material {m:?} is not an id 0..=255")
            })?;
            let threshold = t.trim().parse::<f32>().with_context(|| {
                format!("--material-threshold {kv:?}: threshold {t:?} is not a number")
            })?;
            materials.push(MaterialThreshold {
                material,
                threshold,
            });
        }
        ThresholdPattern::PerMaterial {
            default: base,
            materials,
        }
    } else {
        ThresholdPattern::Constant { value: base }
    };
    match s.method {
        Method::Subdivide => s.subdivide.threshold = pattern,
        Method::Resample => {
            let r = &mut s.resample;
            r.threshold = pattern;
            r.probe_count = args.probes.unwrap_or(r.probe_count);
            r.spread = args.spread.unwrap_or(r.spread);
            r.seed = args.seed.unwrap_or(r.seed);
        }
    }
    s.color = match args.color {
        EnhanceColorArg::Blend => ColorMode::Blend,
        EnhanceColorArg::Nearest => ColorMode::Nearest,
    };
    if args.lighting {
        let l = &mut s.lighting;
        l.enabled = true;
        if let Some(text) = &args.sun {
            l.sun_direction = parse_floats::<3>("--sun", text)?;
        } else if let Some(light) = doc.lights.first() {
            // Lights store the direction light travels; the walks go toward the sun.
            l.sun_direction = (-light.direction).to_array();
        }
        if let Some(n) = args.particles {
            l.sun_particles = n;
            l.sky_particles = n;
        }
        l.seed = args.light_seed.unwrap_or(l.seed);
    }
    Ok(s)
}

fn enhance(args: &EnhanceArgs) -> anyhow::Result<()> {
    use thicket_core::enhance::Control;
    use thicket_core::scene::ObjectKind;
    files::refuse_overwriting_input(&args.project, &args.output)?;
    let mut doc = files::load_document_within(&args.project, args.memory_limit)?;
    let project = args.project.display();
    let index = rig::voxel_object_index(&doc, &args.project, &args.object, "enhanced")?;
    let ObjectKind::Voxels(model) = &doc.objects[index].kind else {
        unreachable!("voxel_object_index checked the kind");
    };
    let settings = enhance_settings(args, &doc)
        .with_context(|| format!("{project}: enhancing object {:?}", args.object))?;
    // Settings the estimate refuses are left to the enhancer, which says why.
    if let Ok(e) = thicket_core::enhance::estimate(&model.svo, &settings) {
        memory_budget(args.memory_limit).check(
            &format!(
                "{project}: enhancing object {:?} x{} into about {} voxels",
                args.object,
                args.factor,
                thousands(e.fine_voxels)
            ),
            e.peak_bytes,
            "use a smaller --factor, or raise the limit with --memory-limit",
        )?;
    }
    let bar = progress_bar(1000, "enhancing");
    let report = |f: f32| bar.set_position((f.clamp(0.0, 1.0) * 1000.0) as u64);
    let result = model.enhanced(
        &settings,
        Control {
            progress: Some(&report),
            cancel: None,
        },
    );
    bar.finish_and_clear();
    let coarse_voxels = model.svo.leaf_count();
    let (fine, stats) =
        result.with_context(|| format!("{project}: enhancing object {:?}", args.object))?;
    let fragments = fine.svo.leaf_count();
    let depth = fine.svo.depth();
    let source = doc.objects[index].id;
    let name = if args.replace {
        doc.objects[index].kind = ObjectKind::Voxels(fine);
        // The coarse model is gone: nothing is left for a link to follow.
        doc.enhancements
            .retain(|l| l.source != source && l.target != source);
        args.object.clone()
    } else {
        let name = format!("{} (enhanced)", args.object);
        let transform = doc.objects[index].transform;
        doc.objects[index].visible = false;
        let id = match doc.objects.iter().position(|o| o.name == name) {
            Some(i) => {
                doc.objects[i].kind = ObjectKind::Voxels(fine);
                doc.objects[i].id
            }
            None => doc.add(name.clone(), ObjectKind::Voxels(fine)),
        };
        if let Some(o) = doc.objects.iter_mut().find(|o| o.id == id) {
            o.transform = transform;
            o.visible = true;
        }
        // The editor keeps the fine model in step with strokes on the coarse one.
        doc.enhancements.retain(|l| l.source != source);
        doc.enhancements.push(thicket_core::scene::EnhancementLink {
            source,
            target: id,
            settings: settings.clone(),
        });
        name
    };
    files::save_project(&doc, &args.output)?;
    write_stdout(&format!(
        "wrote {}: object {name:?} with {} fragments (shell) from {} coarse voxels, factor {}, \
         depth {depth}, {:.2} s\n",
        args.output.display(),
        thousands(fragments),
        thousands(coarse_voxels),
        settings.factor,
        stats.seconds
    ))
}

fn export(args: &ExportArgs) -> anyhow::Result<()> {
    use thicket_core::io::gltf_export::{
        ColorMode, ExportMode, GltfExportOptions, MAX_RESOLUTION, export_gltf,
    };
    if !(2..=MAX_RESOLUTION).contains(&args.resolution) {
        anyhow::bail!(
            "--resolution {}: must be between 2 and {MAX_RESOLUTION}",
            args.resolution
        );
    }
    files::refuse_overwriting_input(&args.project, &args.output)?;
    // A .gltf brings its buffer, OUT.bin, beside it.
    if args
        .output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf"))
    {
        files::refuse_overwriting_input(&args.project, &args.output.with_extension("bin"))?;
    }
    let doc = files::load_document_within(&args.project, args.memory_limit)?;
    let options = GltfExportOptions {
        mode: match args.mode {
            ExportModeArg::Cubes => ExportMode::Cubes,
            ExportModeArg::Smooth => ExportMode::Smooth,
            ExportModeArg::Instances => ExportMode::Instances,
        },
        colors: if args.palette_texture {
            ColorMode::PaletteTexture
        } else {
            ColorMode::VertexColors
        },
        object: args.object.clone(),
        resolution: args.resolution,
        lod_levels: args.lod.unwrap_or(0),
        instanced_lod_levels: args
            .lod
            .unwrap_or(GltfExportOptions::default().instanced_lod_levels),
        impostor: !args.no_impostor,
        cells: args.cells,
        instance_level: args.instance_level,
        bounds: args.bounds,
        max_instances: args.max_instances,
        max_triangles: args.max_triangles,
        lights_and_camera: match args.lights_camera {
            LightsCameraArg::Auto => args.object.is_none(),
            LightsCameraArg::On => true,
            LightsCameraArg::Off => false,
        },
        instancing: match args.instancing {
            _ if args.flatten => thicket_core::io::gltf_export::Instancing::Flatten,
            InstancingArg::Gpu => thicket_core::io::gltf_export::Instancing::Gpu,
            InstancingArg::Nodes => thicket_core::io::gltf_export::Instancing::Nodes,
            InstancingArg::Auto => thicket_core::io::gltf_export::Instancing::Auto,
        },
        ..GltfExportOptions::default()
    };
    // The memory budget becomes a triangle limit, checked before meshing as --max-triangles is.
    let budget = memory_budget(args.memory_limit);
    let fixed = thicket_core::io::gltf_export::export_fixed_bytes(&doc, &options);
    budget.check(
        "exporting the voxel models",
        fixed,
        "export fewer objects (--object), or raise the limit with --memory-limit",
    )?;
    let by_memory = thicket_core::io::gltf_export::triangle_limit_for_memory(
        &doc,
        &options,
        budget.limit_bytes,
    )
    .unwrap_or(0);
    let memory_bound = by_memory < options.max_triangles;
    let options = GltfExportOptions {
        max_triangles: by_memory,
        ..options
    };
    let bar = progress_bar(1000, "exporting");
    let result = export_gltf(&doc, &args.output, &options, &|f| {
        bar.set_position((f.clamp(0.0, 1.0) * 1000.0) as u64);
        true
    });
    bar.finish_and_clear();
    let report = match result {
        Err(e @ thicket_core::io::gltf_export::GltfExportError::TooLarge { .. })
            if memory_bound =>
        {
            // The core's advice names --max-triangles, which cannot help here.
            let said = e
                .to_string()
                .replace(" or raise the limit (--max-triangles)", "");
            anyhow::bail!(
                "{said}; the limit is {} triangles here because each needs about {} bytes and \
                 the memory limit is {} ({}): raise it with --memory-limit",
                thousands(by_memory),
                thicket_core::io::gltf_export::export_triangle_bytes(&doc, &options),
                human_bytes(budget.limit_bytes),
                budget.source
            )
        }
        other => other?,
    };
    let mut text = format!(
        "wrote {}: {} object(s), {} triangles, {} vertices, {}\n",
        report
            .files
            .iter()
            .map(|f| f.display().to_string())
            .collect::<Vec<_>>()
            .join(" + "),
        report.objects,
        thousands(report.triangles),
        thousands(report.vertices),
        human_bytes(report.bytes)
    );
    // A pose set by hand (overrides) is not an animation: the file carries the clips only.
    for o in doc
        .objects
        .iter()
        .filter(|o| o.visible && args.object.as_ref().is_none_or(|name| *name == o.name))
    {
        if let thicket_core::scene::ObjectKind::Voxels(v) = &o.kind
            && let Some(rig) = &v.rig
            && !rig.pose_overrides.is_empty()
        {
            text.push_str(&format!(
                "  {:?}: the pose overrides of {} joint(s) are not keyed and are not in the \
                 file (key them in the editor: Set key, or Bake the pose into the clip)\n",
                o.name,
                rig.pose_overrides.len()
            ));
        }
    }
    for f in &report.voxel_faces {
        text.push_str(&format!(
            "  {:?}: {} exposed faces merged into {} quads ({} triangles instead of {})",
            f.object,
            thousands(f.exposed),
            thousands(f.quads),
            thousands(f.quads * 2),
            thousands(f.exposed * 2)
        ));
        if f.sealed > 0 {
            text.push_str(&format!(
                "; {} faces toward sealed cavities left out",
                thousands(f.sealed)
            ));
        }
        text.push('\n');
    }
    let how = report.placements.map(|(how, _)| how);
    let as_nodes = how == Some(thicket_core::io::gltf_export::Instancing::Nodes);
    let flat = how == Some(thicket_core::io::gltf_export::Instancing::Flatten);
    for k in &report.instanced {
        text.push_str(&format!(
            "  {:?}: prototype (reflection levels 0..={}) of {} triangles drawn {} times \
             ({} mirrored, from a mirrored copy of the mesh), {} in {} \
             cells ({}×{} grid, {} nodes){}\n",
            k.object,
            k.level,
            thousands(k.prototype_triangles),
            thousands(k.instances),
            thousands(k.mirrored),
            if flat {
                "baked into plain meshes"
            } else if as_nodes {
                "a node per placement"
            } else {
                "EXT_mesh_gpu_instancing"
            },
            k.cells[0] * k.cells[1],
            k.cells[0],
            k.cells[1],
            k.cell_nodes,
            if k.impostor && !as_nodes && !flat {
                "; coarsest level: an impostor"
            } else {
                ""
            }
        ));
    }
    match report.placements {
        Some((thicket_core::io::gltf_export::Instancing::Nodes, n)) => text.push_str(&format!(
            "  {} placements written as a node each (every glTF reader; no levels of detail \
             for them)\n",
            thousands(n as u64)
        )),
        Some((thicket_core::io::gltf_export::Instancing::Flatten, n)) => text.push_str(&format!(
            "  {} placements baked into plain meshes (--flatten: every tool reads them; no \
             levels of detail)\n",
            thousands(n as u64)
        )),
        Some((_, n)) => text.push_str(&format!(
            "  {} placements written with EXT_mesh_gpu_instancing (a reader without it refuses \
             the file, Blender 3.4 among them: --instancing nodes writes a node each)\n",
            thousands(n as u64)
        )),
        None => {}
    }
    for l in &report.levels_of_detail {
        text.push_str(&format!(
            "  {:?}: levels of detail (MSFT_lod): {} triangles\n",
            l.object,
            l.triangles
                .iter()
                .map(|&t| thousands(t))
                .collect::<Vec<_>>()
                .join(" → ")
        ));
    }
    for (name, lo, hi) in &report.patches {
        text.push_str(&format!(
            "  {name:?}: unbounded, written as the patch x {:.2}..{:.2}, z {:.2}..{:.2} \
             (heights {:.2}..{:.2}; --bounds to choose)\n",
            lo.x, hi.x, lo.z, hi.z, lo.y, hi.y
        ));
    }
    if report.lights > 0 || report.camera {
        text.push_str(&format!(
            "  {} light(s) (KHR_lights_punctual){}\n",
            report.lights,
            if report.camera { " and the camera" } else { "" }
        ));
    }
    if !report.animated.is_empty() {
        text.push_str(&format!(
            "  keyed transforms written as node animations: {}\n",
            report.animated.join(", ")
        ));
    }
    for (name, why) in &report.motion_left_out {
        text.push_str(&format!(
            "  warning: the keyed transform of {name:?} is not in the file: {why}\n"
        ));
    }
    if !report.skipped.is_empty() {
        text.push_str(&format!(
            "  skipped (hidden or empty): {}\n",
            report.skipped.join(", ")
        ));
    }
    write_stdout(&text)
}

fn new_project(args: &NewArgs) -> anyhow::Result<()> {
    use thicket_core::sculpt::model_ops::InitialFill;
    let mut editor = crate::editor::Editor::default();
    let spec = crate::editor::NewModelSpec {
        name: args.name.clone(),
        size: args.extent,
        voxel_size: args.voxel_size,
        fill: match args.fill {
            NewFillArg::Empty => InitialFill::Empty,
            NewFillArg::Slab => InitialFill::GroundSlab { height: 1 },
            NewFillArg::Solid => InitialFill::SolidBox,
        },
        ..crate::editor::NewModelSpec::default()
    };
    editor.add_voxel_model(&spec)?;
    let doc = editor.doc();
    files::save_project(doc, &args.output)?;
    let voxels: u64 = doc
        .objects
        .iter()
        .filter_map(|o| match &o.kind {
            thicket_core::scene::ObjectKind::Voxels(v) => Some(v.svo.leaf_count()),
            _ => None,
        })
        .sum();
    println!(
        "wrote {}: {:?}, {}×{}×{} voxels of {} m, {} solid",
        args.output.display(),
        spec.name,
        args.extent.x,
        args.extent.y,
        args.extent.z,
        args.voxel_size,
        files::thousands(voxels)
    );
    Ok(())
}

/// Refuses a CPU frame whose estimated peak memory is over the budget, before it allocates.
fn check_render_budget(
    doc: &thicket_core::scene::Document,
    (width, height): (u32, u32),
    camera: thicket_core::scene::OrbitCamera,
    quality: &thicket_core::quality::Quality,
    limit: Option<u64>,
) -> anyhow::Result<()> {
    let request = thicket_core::render::View {
        width,
        height,
        camera: Some(camera),
        quality: quality.clone(),
    };
    memory_budget(limit).check(
        &format!("rendering {width}x{height}"),
        thicket_core::render::estimate_peak_bytes(doc, &request),
        "lower --size or --quality shadow_map_size, or raise the limit with --memory-limit",
    )?;
    Ok(())
}

/// Refuses an import whose voxelization is estimated to need more memory than the budget,
/// before it starts. A mesh the estimate cannot plan is left to the voxelizer, which says why.
fn check_voxelize_budget(
    args: &ImportArgs,
    model: &thicket_core::mesh::MeshModel,
    settings: &thicket_core::voxelize::VoxelizeSettings,
) -> anyhow::Result<()> {
    let Ok(e) = thicket_core::voxelize::estimate(model, settings) else {
        return Ok(());
    };
    check_estimate(args, &args.input.display().to_string(), &e)
}

/// Refuses an estimate over the budget, naming `what` is voxelized.
fn check_estimate(
    args: &ImportArgs,
    what: &str,
    e: &thicket_core::voxelize::VoxelEstimate,
) -> anyhow::Result<()> {
    memory_budget(args.memory_limit).check(
        &format!(
            "{what}: voxelizing about {} voxels",
            thousands((e.surface_voxels + e.interior_voxels).round() as u64)
        ),
        e.peak_bytes,
        "use a smaller --depth or a larger --voxel-size, or raise the limit with --memory-limit",
    )?;
    Ok(())
}

fn import(args: &ImportArgs) -> anyhow::Result<()> {
    use thicket_core::voxelize::{Mode, Resolution, VoxelizeSettings, voxelize};
    let options = files::MeshOptions {
        texture: args.texture.clone(),
        memory_limit: args.memory_limit,
        ..files::MeshOptions::default()
    };
    files::refuse_overwriting_input(&args.input, &args.output)?;
    // Before any branch: the .vox and skinned paths would otherwise ignore the texture.
    files::check_options(&args.input, &options)?;
    let is_vox = args
        .input
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("vox"));
    let is_gltf = files::FileKind::from_path(&args.input) == Some(files::FileKind::Gltf);
    if !args.nodes.is_empty() && !is_gltf {
        anyhow::bail!(
            "--node: {} is not a glTF file; only glTF scenes have nodes to pick",
            args.input.display()
        );
    }
    let settings = VoxelizeSettings {
        resolution: match (args.depth, args.voxel_size) {
            (_, Some(s)) => Resolution::VoxelSize(s),
            (d, None) => Resolution::Depth(d.unwrap_or(7)),
        },
        mode: if args.solid {
            Mode::Solid
        } else {
            Mode::Surface
        },
        ..VoxelizeSettings::default()
    };
    let mut notes = String::new();
    let doc = if is_vox {
        files::load_document_within(&args.input, args.memory_limit)?
    } else if let Some(skinned) = (!args.no_skin)
        .then(|| files::load_skinned(&args.input))
        .transpose()?
        .flatten()
    {
        if !args.nodes.is_empty() {
            anyhow::bail!(
                "--node: {} is skinned and imports as one skinned object; add --no-skin to \
                 pick nodes of a static import",
                args.input.display()
            );
        }
        check_voxelize_budget(args, &skinned.mesh, &settings)?;
        let bar = progress_bar(1000, "voxelizing the bind pose");
        let result = thicket_core::io::voxelize_skinned(&skinned, &settings, &|f| {
            bar.set_position((f.clamp(0.0, 1.0) * 1000.0) as u64);
            true
        });
        bar.finish_and_clear();
        let v = result.with_context(|| format!("{}: voxelizing", args.input.display()))?;
        notes.push_str(&solid_fallback_note(&v.stats));
        let rig = v.model.rig.as_ref();
        notes.push_str(
            "skinned: imported as one skinned object (its joints place its meshes, so the \
             scene's nodes are not split into objects; --no-skin imports them one object each)\n",
        );
        notes.push_str(&format!(
            "skinned: {} joints, {} clip(s){}\n",
            skinned.skeleton.len(),
            skinned.clips.len(),
            rig.and_then(|r| r.clips.first())
                .map(|c| format!(" (playing {:?}, {:.2} s)", c.name, c.duration_secs))
                .unwrap_or_default()
        ));
        // The importer's warnings already say how many vertex weights it repaired.
        for w in &skinned.warnings {
            notes.push_str(&format!("warning: {w}\n"));
        }
        let mut doc = thicket_core::scene::Document::default();
        doc.add(
            files::object_name_for(&args.input),
            thicket_core::scene::ObjectKind::Voxels(v.model),
        );
        if let Some((lo, hi)) = doc.bounds() {
            doc.camera.frame(lo, hi);
        }
        skinned.view.apply_to_new_document(&mut doc);
        doc
    } else {
        let files::MeshImport {
            model,
            notes: dropped,
            view,
            nodes,
            ..
        } = files::load_mesh_imported(&args.input, &options)?;
        for line in &dropped {
            notes.push_str(&format!("warning: {line}\n"));
        }
        let mut doc = if is_gltf && !args.merge {
            import_nodes(args, &settings, &model, &nodes, &mut notes)?
        } else {
            check_voxelize_budget(args, &model, &settings)?;
            let bar = progress_bar(1000, "voxelizing");
            let result = voxelize(&model, &settings, &|f| {
                bar.set_position((f.clamp(0.0, 1.0) * 1000.0) as u64);
                true
            });
            bar.finish_and_clear();
            let v = result.with_context(|| format!("{}: voxelizing", args.input.display()))?;
            notes.push_str(&solid_fallback_note(&v.stats));
            let mut doc = thicket_core::scene::Document::default();
            doc.add(
                files::object_name_for(&args.input),
                thicket_core::scene::ObjectKind::Voxels(files::voxel_model(v, &model)),
            );
            doc
        };
        if let Some((lo, hi)) = doc.bounds() {
            doc.camera.frame(lo, hi);
        }
        // The voxels keep the mesh's world coordinates, so the file's camera and lights fit.
        view.apply_to_new_document(&mut doc);
        doc
    };
    files::save_project(&doc, &args.output)?;
    finish_import(args, &doc, &notes)
}

/// Prints an import's notes and what it wrote.
fn finish_import(
    args: &ImportArgs,
    doc: &thicket_core::scene::Document,
    notes: &str,
) -> anyhow::Result<()> {
    let voxels: u64 = doc
        .objects
        .iter()
        .map(|o| match &o.kind {
            thicket_core::scene::ObjectKind::Voxels(v) => v.svo.leaf_count(),
            thicket_core::scene::ObjectKind::Mesh(_) | thicket_core::scene::ObjectKind::Krs(_) => 0,
        })
        .sum();
    write_stdout(&format!(
        "{notes}wrote {}: {} object(s), {} voxels\n",
        args.output.display(),
        doc.objects.len(),
        thousands(voxels)
    ))
}

/// A static glTF scene as one object per node with a mesh (see `thicket_core::io::gltf_nodes`):
/// each voxelized at its own `--depth` (or the shared world `--voxel-size`), except huge flat
/// planes, which stay meshes unless `--voxelize-planes`. Every object's estimate, and all of
/// them together (each result stays in memory while the next is voxelized), is checked against
/// the memory budget before any voxelizes.
fn import_nodes(
    args: &ImportArgs,
    settings: &thicket_core::voxelize::VoxelizeSettings,
    model: &thicket_core::mesh::MeshModel,
    nodes: &[thicket_core::io::GltfNode],
    notes: &mut String,
) -> anyhow::Result<thicket_core::scene::Document> {
    use thicket_core::io::gltf_nodes::{Placement, node_objects};
    use thicket_core::scene::{Document, MeshObject, ObjectKind};
    use thicket_core::voxelize::{Resolution, VoxelizeSettings, estimate, voxelize};
    let pick = (!args.nodes.is_empty()).then_some(args.nodes.as_slice());
    let objects = node_objects(model, nodes, pick)
        .with_context(|| format!("--node: {}", args.input.display()))?;
    let file = args.input.display().to_string();
    if objects.is_empty() {
        anyhow::bail!("{file}: the scene has no node with triangles to import");
    }
    // Settings and estimates first: nothing voxelizes unless everything fits.
    let mut plans: Vec<Option<VoxelizeSettings>> = Vec::with_capacity(objects.len());
    let mut total: Option<thicket_core::voxelize::VoxelEstimate> = None;
    for o in &objects {
        if o.huge_flat_plane && !args.voxelize_planes {
            let (lo, hi) = o.world_bounds;
            let size = hi - lo;
            notes.push_str(&format!(
                "warning: node {:?} is a huge flat plane ({} x {} x {}, much larger than the \
                 rest of the scene): imported as a mesh object, not voxelized \
                 (--voxelize-planes voxelizes it)\n",
                o.name,
                short(size.x),
                short(size.y),
                short(size.z)
            ));
            plans.push(None);
            continue;
        }
        let object_settings = VoxelizeSettings {
            resolution: match settings.resolution {
                Resolution::VoxelSize(s) => Resolution::VoxelSize(s / o.world_per_object_unit),
                depth @ Resolution::Depth(_) => depth,
            },
            ..settings.clone()
        };
        if let Ok(e) = estimate(&o.model, &object_settings) {
            check_estimate(args, &format!("{file}: node {:?}", o.name), &e)?;
            let t = total.get_or_insert(thicket_core::voxelize::VoxelEstimate {
                surface_voxels: 0.0,
                interior_voxels: 0.0,
                peak_bytes: 0,
            });
            t.surface_voxels += e.surface_voxels;
            t.interior_voxels += e.interior_voxels;
            t.peak_bytes = t.peak_bytes.saturating_add(e.peak_bytes);
        }
        plans.push(Some(object_settings));
    }
    if let Some(t) = &total
        && objects.len() > 1
    {
        check_estimate(
            args,
            &format!("{file}: {} objects together", objects.len()),
            t,
        )?;
    }
    let mut doc = Document::default();
    let bar = progress_bar(1000, "voxelizing");
    let count = objects.len().max(1) as f32;
    for (i, (o, plan)) in objects.into_iter().zip(plans).enumerate() {
        let kind = match plan {
            None => ObjectKind::Mesh(MeshObject {
                model: o.model,
                casts_shadows: true,
            }),
            Some(object_settings) => {
                let v = voxelize(&o.model, &object_settings, &|f| {
                    let done = (i as f32 + f.clamp(0.0, 1.0)) / count;
                    bar.set_position((done * 1000.0) as u64);
                    true
                })
                .with_context(|| format!("{file}: node {:?}: voxelizing", o.name))?;
                let fallback = solid_fallback_note(&v.stats);
                if !fallback.is_empty() {
                    notes.push_str(&format!("node {:?}: {fallback}", o.name));
                }
                ObjectKind::Voxels(files::voxel_model(v, &o.model))
            }
        };
        let placed = match o.placement {
            Placement::Node => "the node's transform",
            Placement::ScaleBaked => "the node's translation and rotation, its scale baked in",
            Placement::WorldBaked | Placement::Skinned => "baked in world space",
        };
        let voxels = match &kind {
            ObjectKind::Voxels(v) => format!(
                "{} voxels of {}",
                thousands(v.svo.leaf_count()),
                short(v.voxel_size * o.world_per_object_unit)
            ),
            _ => "a mesh".to_owned(),
        };
        notes.push_str(&format!(
            "object {:?}: {voxels}; placed by {placed}\n",
            o.name
        ));
        doc.add(o.name, kind);
        if let Some(added) = doc.objects.last_mut() {
            added.transform = o.transform;
        }
    }
    bar.finish_and_clear();
    Ok(doc)
}

/// A length for messages: four significant digits, no trailing zeros.
fn short(x: f32) -> String {
    let text = format!("{x:.4}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text.is_empty() || text == "-" {
        "0".to_owned()
    } else {
        text.to_owned()
    }
}

/// The warning for a `--solid` import of an open mesh (empty when it was filled).
fn solid_fallback_note(stats: &thicket_core::voxelize::VoxelizeStats) -> String {
    if !stats.solid_fell_back {
        return String::new();
    }
    format!(
        "warning: the mesh is open ({} voxel column(s) enter it without leaving; {} boundary \
         edge(s)): --solid needs a closed mesh, so only its surface was voxelized\n",
        thousands(stats.open_columns),
        thousands(stats.boundary_edges)
    )
}

/// Sets the playhead (and clip, by name) of every skinned model of `doc`, the playhead of
/// every frame sequence (which then shows the frame at that time) and of every keyed
/// transform (the object moves there).
///
/// # Errors
/// A non-finite time, a clip name no skinned model has (listing the names it has), a clip
/// given for a document without skinned models, or a time given for a document with no
/// skinned model, frame sequence or keyed transform.
pub fn set_playback(
    doc: &mut thicket_core::scene::Document,
    time: Option<f32>,
    clip: Option<&str>,
) -> anyhow::Result<()> {
    if time.is_none() && clip.is_none() {
        return Ok(());
    }
    if let Some(t) = time
        && !t.is_finite()
    {
        anyhow::bail!("--time {t}: must be a finite number of seconds");
    }
    let (mut rigged, mut sequences) = (0, 0);
    let moving = doc.objects.iter().filter(|o| o.motion.is_some()).count();
    for o in &mut doc.objects {
        if let (Some(t), Some(m)) = (time, o.motion.as_mut()) {
            m.time_secs = t;
        }
        let thicket_core::scene::ObjectKind::Voxels(v) = &mut o.kind else {
            continue;
        };
        if let Some(t) = time
            && v.frames.is_some()
        {
            sequences += 1;
            v.set_frame_time(t);
        }
        let Some(rig) = v.rig.as_mut() else {
            continue;
        };
        rigged += 1;
        if let Some(name) = clip {
            let index = rig.clip_index(name).with_context(|| {
                let names: Vec<&str> = rig.clips.iter().map(|c| c.name.as_str()).collect();
                format!(
                    "--clip {name:?}: object {:?} has no such clip (it has {names:?})",
                    o.name
                )
            })?;
            rig.playback.clip = Some(index);
        }
        if let Some(t) = time {
            rig.playback.time_secs = t;
        }
    }
    if clip.is_some() && rigged == 0 {
        anyhow::bail!("--clip: the document has no skinned model");
    }
    if rigged == 0 && sequences == 0 && moving == 0 {
        anyhow::bail!(
            "--time: the document has no skinned model, frame sequence or keyed transform"
        );
    }
    doc.apply_motion(None);
    Ok(())
}

/// The document's quality with `--quality KEY=VALUE` overrides, and its camera with a
/// `--camera YAW,PITCH,DISTANCE` override (whose near and far planes then enclose the scene),
/// from text as given on a command line: the typed [`ViewArgs`] path for callers that hold
/// strings.
///
/// # Errors
/// A malformed or out-of-range `--quality` or `--camera` value.
pub fn view_options(
    doc: &thicket_core::scene::Document,
    quality_args: &[String],
    camera_arg: Option<&String>,
) -> anyhow::Result<(
    thicket_core::quality::Quality,
    thicket_core::scene::OrbitCamera,
)> {
    let quality = quality_args
        .iter()
        .map(|kv| QualityArg::parse(kv).map_err(|e| anyhow::anyhow!("--quality {kv:?}: {e}")))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let camera = camera_arg
        .map(|c| CameraArg::parse(c).map_err(|e| anyhow::anyhow!("--camera {c:?}: {e}")))
        .transpose()?;
    view_args::view_from(doc, &quality, camera)
}

/// The files `thicket render` writes: OUTPUT, or a turntable's numbered frames beside it.
fn render_outputs(args: &RenderArgs) -> anyhow::Result<Vec<std::path::PathBuf>> {
    let Some(frames) = args.turntable else {
        return Ok(vec![args.output.clone()]);
    };
    if !(1..=MAX_TURNTABLE_FRAMES).contains(&frames) {
        anyhow::bail!("--turntable {frames}: give 1 to {MAX_TURNTABLE_FRAMES} frames");
    }
    let stem = args
        .output
        .file_stem()
        .and_then(|s| s.to_str())
        .with_context(|| format!("{}: not a file name", args.output.display()))?;
    let digits = ((frames - 1).max(1).ilog10() as usize + 1).max(3);
    Ok((0..frames)
        .map(|i| {
            args.output
                .with_file_name(format!("{stem}_{i:0digits$}.png"))
        })
        .collect())
}

fn render(args: &RenderArgs) -> anyhow::Result<()> {
    let outputs = render_outputs(args)?;
    for output in &outputs {
        files::refuse_overwriting_input(&args.project, output)?;
    }
    let mut doc = files::load_document_within(&args.project, args.memory_limit)?;
    set_playback(&mut doc, args.time, args.clip.as_deref())?;
    let ImageSize { width, height } = args.view.size;
    let (quality, camera) = args.view.apply(&doc)?;
    if !args.gpu {
        check_render_budget(&doc, (width, height), camera, &quality, args.memory_limit)?;
    }
    // One GPU context, or one CPU renderer (its frame buffers kept), for every frame of a
    // turntable.
    let gpu = if args.gpu {
        Some(crate::gpu::GpuContext::new_headless(
            wgpu::PowerPreference::HighPerformance,
        )?)
    } else {
        None
    };
    let mut backend = match gpu.as_ref() {
        Some(ctx) => RenderBackend::Gpu(ctx),
        None => RenderBackend::Cpu(Box::default()),
    };
    let frames = outputs.len();
    for (i, path) in outputs.iter().enumerate() {
        let mut cam = camera;
        cam.yaw_deg = camera.yaw_deg + 360.0 * i as f32 / frames as f32;
        render_one(
            args,
            &mut backend,
            &doc,
            cam,
            &quality,
            (width, height),
            path,
        )?;
    }
    Ok(())
}

/// What `thicket render` draws with, kept over a turntable's frames.
enum RenderBackend<'a> {
    Gpu(&'a crate::gpu::GpuContext),
    Cpu(Box<thicket_core::render::Renderer>),
}

/// Renders one frame of `doc` from `camera` with `backend` and writes it to `output`
/// (atomically).
fn render_one(
    args: &RenderArgs,
    backend: &mut RenderBackend<'_>,
    doc: &thicket_core::scene::Document,
    camera: thicket_core::scene::OrbitCamera,
    quality: &thicket_core::quality::Quality,
    (width, height): (u32, u32),
    output: &std::path::Path,
) -> anyhow::Result<()> {
    use std::borrow::Cow;
    use thicket_core::render::{RgbaImage, View};
    // One view for either renderer.
    let view = View {
        width,
        height,
        camera: Some(camera),
        quality: quality.clone(),
    };
    let (image, stats_json) = match backend {
        RenderBackend::Gpu(ctx) => {
            let (pixels, stats) = crate::gpu::render_with_context(ctx, doc, &view)
                .with_context(|| format!("{}: rendering on the GPU", args.project.display()))?;
            let json = serde_json::json!({
                "device": ctx.describe(),
                "atomic_path": format!("{:?}", stats.atomic_path),
                "splats": stats.splats,
                "triangles": stats.triangles,
                "queue_overflow": stats.queue_overflow,
                "levels": stats.levels.iter().map(|l| serde_json::json!({
                    "visited": l.visited, "split": l.split, "splatted": l.splatted,
                    "frustum_culled": l.frustum_culled,
                })).collect::<Vec<_>>(),
                "pass_ms": stats.pass_ms.iter().map(|(n, ms)| serde_json::json!([n, ms])).collect::<Vec<_>>(),
                "gpu_timestamps": stats.gpu_timestamps,
                "total_ms": stats.total_ms,
                "krs": {
                    "rays": stats.krs.rays, "hits": stats.krs.hits, "steps": stats.krs.steps,
                    "max_steps": stats.krs.max_steps, "exhausted": stats.krs.exhausted,
                    "shadow_rays": stats.krs.shadow_rays, "shadow_steps": stats.krs.shadow_steps,
                    "ao_evals": stats.krs.ao_evals,
                },
            });
            (
                Cow::Owned(RgbaImage {
                    width,
                    height,
                    pixels,
                }),
                json,
            )
        }
        RenderBackend::Cpu(renderer) => {
            let request = view;
            let frame = renderer
                .render_document(doc, &request)
                .with_context(|| format!("{}: rendering", args.project.display()))?;
            (
                Cow::Borrowed(frame.image),
                serde_json::to_value(frame.stats).context("encoding the statistics")?,
            )
        }
    };
    let mut stats_json = stats_json;
    if args.stats
        && let Some(map) = stats_json.as_object_mut()
    {
        // Symmetry hiding (KRS §5) measured on the image written: see
        // `thicket_core::krs::repetition` (1 = an exact repeat in view, about 0 = none).
        let r = thicket_core::krs::repetition::visible_repetition(
            &image.pixels,
            image.width,
            image.height,
        );
        map.insert(
            "repetition".to_owned(),
            serde_json::json!({
                "translation": r.translation, "mirror": r.mirror, "score": r.score(),
            }),
        );
    }
    // Through a temporary sibling, so a failed write leaves no partial PNG and no `.tmp`.
    files::write_png(&image, output)?;
    let mut text = format!("wrote {} ({width}x{height})\n", output.display());
    if args.stats {
        text.push_str(
            &serde_json::to_string_pretty(&stats_json).context("encoding the statistics")?,
        );
        text.push('\n');
    }
    write_stdout(&text)
}

fn bench(args: &BenchArgs) -> anyhow::Result<()> {
    use crate::bench::{BenchSetup, bench_cpu, bench_gpu, format_report};
    let mut doc = files::load_document_within(&args.project, args.memory_limit)?;
    set_playback(&mut doc, args.time, args.clip.as_deref())?;
    if args.no_rig {
        remove_rigs(&mut doc)?;
    }
    let ImageSize { width, height } = args.view.size;
    if width == 0 || height == 0 {
        anyhow::bail!(
            "--size \"{}\": both edges must be at least 1 pixel",
            args.view.size
        );
    }
    if args.frames == 0 {
        anyhow::bail!("--frames 0: time at least one frame");
    }
    if !args.orbit.is_finite() {
        anyhow::bail!("--orbit {}: give a finite number of degrees", args.orbit);
    }
    let (quality, camera) = args.view.apply(&doc)?;
    if !args.gpu {
        check_render_budget(&doc, (width, height), camera, &quality, args.memory_limit)?;
    }
    let name = args.project.display().to_string();
    let setup = BenchSetup {
        doc: &doc,
        camera,
        width,
        height,
        quality: &quality,
        frames: args.frames,
        orbit_deg: args.orbit,
    };
    let run_gpu = || {
        bench_gpu(
            &setup,
            args.two_pass,
            args.splat_repeats,
            args.binding_limit,
        )
        .with_context(|| format!("{name}: GPU bench"))
    };
    let run_cpu = || bench_cpu(&setup).with_context(|| format!("{name}: CPU bench"));
    let reports = if args.compare {
        vec![run_cpu()?, run_gpu()?]
    } else if args.gpu {
        vec![run_gpu()?]
    } else {
        vec![run_cpu()?]
    };
    let ratio = (reports.len() == 2 && reports[1].mean_ms > 0.0)
        .then(|| reports[0].mean_ms / reports[1].mean_ms);
    let text = if args.json {
        let mut s = serde_json::to_string_pretty(&serde_json::json!({
            "project": name,
            "runs": reports,
            "cpu_over_gpu_frame_time": ratio,
        }))
        .context("encoding the report as JSON")?;
        s.push('\n');
        s
    } else {
        let mut s: String = reports.iter().map(|r| format_report(&name, r)).collect();
        if let Some(r) = ratio {
            s.push_str(&format!(
                "CPU/GPU frame time: {r:.2} (CPU {:.2} ms, GPU {:.2} ms, same process)\n",
                reports[0].mean_ms, reports[1].mean_ms
            ));
        }
        s
    };
    write_stdout(&text)
}

/// `--no-rig`: every skinned model becomes the rigid model of its shown pose
/// ([`thicket_core::scene::bake::bake_shown_pose`]).
fn remove_rigs(doc: &mut thicket_core::scene::Document) -> anyhow::Result<()> {
    let mut rigged = 0;
    for o in &mut doc.objects {
        let thicket_core::scene::ObjectKind::Voxels(v) = &mut o.kind else {
            continue;
        };
        if v.rig.is_none() {
            continue;
        }
        rigged += 1;
        *v = thicket_core::scene::bake::bake_shown_pose(v).with_context(|| {
            format!(
                "--no-rig: object {:?} cannot be baked (it is empty, or its pose throws voxels to a non-finite place or beyond the deepest octree)",
                o.name
            )
        })?;
    }
    if rigged == 0 {
        anyhow::bail!("--no-rig: the project has no skinned model");
    }
    Ok(())
}

fn tradeoff(args: &TradeoffArgs) -> anyhow::Result<()> {
    use thicket_core::measure::{SweepSettings, sweep_document};
    for name in crate::tradeoff::OUTPUT_FILES {
        files::refuse_overwriting_input(&args.project, &args.output.join(name))?;
    }
    let doc = files::load_document_within(&args.project, args.memory_limit)?;
    let ImageSize { width, height } = args.size;
    let knobs = if args.knobs.is_empty() {
        thicket_core::measure::default_knobs()
    } else {
        args.knobs.clone()
    };
    let settings = SweepSettings {
        // From the project's own quality, as the editor's sweep: a project saved at the final
        // preset is swept from there (every sample is saved at balanced).
        base: doc.quality.clone(),
        knobs,
        grid: args.grid,
        presets: !args.no_presets,
        repeats: args.frames,
    };
    if let Ok(bytes) =
        thicket_core::measure::estimate_sweep_peak_bytes(&doc, width, height, &settings)
    {
        memory_budget(args.memory_limit).check(
            &format!("{}: sweeping at {width}x{height}", args.project.display()),
            bytes,
            "lower --size or leave out the largest --knob values, or raise the limit with \
             --memory-limit",
        )?;
    }
    let bar = progress_bar(1, "reference");
    let progress = |done: usize, total: usize, label: &str| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
        bar.set_message(label.to_owned());
    };
    let report = if args.gpu {
        let ctx = crate::gpu::GpuContext::new_headless(wgpu::PowerPreference::HighPerformance)?;
        crate::tradeoff::gpu_sweep(&ctx, &doc, (width, height), &settings, progress)
    } else {
        sweep_document(&doc, width, height, &settings, progress).map_err(anyhow::Error::from)
    }
    .with_context(|| format!("{}: sweeping", args.project.display()))?;
    bar.finish_and_clear();
    let name = files::object_name_for(&args.project);
    let renderer = if args.gpu {
        crate::tradeoff::SweepRenderer::Gpu
    } else {
        crate::tradeoff::SweepRenderer::Cpu
    };
    crate::tradeoff::write_outputs(&report, &name, renderer, &args.output)?;
    let mut text = format!(
        "wrote {}/report.json, report.csv, tradeoff.png: {} settings at {width}x{height} on the \
         {} renderer, reference {:.1} ms (CPU)\n",
        args.output.display(),
        report.points.len(),
        if args.gpu { "GPU" } else { "CPU" },
        report.reference_time_ms
    );
    if !report.knobs.is_empty() {
        text.push_str("knobs at this size:\n");
        for k in &report.knobs {
            text.push_str(&format!("  {}\n", k.summary()));
        }
    }
    text.push_str(&presets_summary(&report));
    for p in &report.points {
        text.push_str(&format!(
            "  {:<40} {:>9.1} ms ({:.1}-{:.1}) {:>12} work  rmse {:.5}  holes {:>6} bloat {:>6}{}\n",
            short_label(&p.setting.label),
            p.time_ms,
            p.time_min_ms,
            p.time_max_ms,
            p.work,
            p.error.rmse,
            p.error.holes,
            p.error.bloat,
            match (p.on_time_front, p.on_work_front) {
                (true, true) => "  front (time, work)",
                (true, false) => "  front (time)",
                (false, true) => "  front (work)",
                (false, false) => "",
            }
        ));
    }
    write_stdout(&text)
}

/// A merged setting's label for the table: its first two names and how many more drew the
/// same quality (report.json and report.csv keep the whole label).
fn short_label(label: &str) -> String {
    let names: Vec<&str> = label.split(" / ").collect();
    if names.len() <= 2 {
        label.to_owned()
    } else {
        format!("{} / {} (+{} same)", names[0], names[1], names.len() - 2)
    }
}

/// Where the presets sit in a sweep: their order in work, error and time, and for each preset
/// off the work front the setting that beats it.
fn presets_summary(report: &thicket_core::measure::SweepReport) -> String {
    use thicket_core::quality::QualityPreset::{Balanced, Draft, Final};
    let points = [Draft, Balanced, Final].map(|q| report.preset_point(q));
    let [Some(d), Some(b), Some(f)] = points else {
        return String::new();
    };
    let yes = |ordered: bool| if ordered { "yes" } else { "no" };
    let mut s = format!(
        "presets: work draft < balanced < final: {}; error draft > balanced > final: {}; \
         median time draft < balanced < final: {}\n",
        yes(d.work < b.work && b.work < f.work),
        yes(d.error.rmse > b.error.rmse && b.error.rmse > f.error.rmse),
        yes(d.time_ms < b.time_ms && b.time_ms < f.time_ms),
    );
    for (name, p) in [("draft", d), ("balanced", b), ("final", f)] {
        let Some(i) = report.points.iter().position(|q| std::ptr::eq(q, p)) else {
            continue;
        };
        match report.work_dominator(i) {
            None => s.push_str(&format!("  {name}: on the work front\n")),
            Some(by) => s.push_str(&format!(
                "  {name}: off the work front, beaten by {} ({} work, rmse {:.5})\n",
                by.setting.label, by.work, by.error.rmse
            )),
        }
    }
    s
}

fn skin_report(args: &SkinReportArgs) -> anyhow::Result<()> {
    use thicket_core::measure::skin::{ReportSettings, skin_report};
    use thicket_core::skin::{StretchSettings, StretchStrategy};
    let (doc, source) = match (&args.cylinder, &args.project) {
        (Some(depth), _) => (
            thicket_core::measure::skin::synthetic::bending_cylinder_document(*depth)
                .context("voxelizing the bending cylinder")?,
            format!("bending cylinder at depth {depth}"),
        ),
        (None, Some(project)) => (
            files::load_document_within(project, args.memory_limit)?,
            project.display().to_string(),
        ),
        (None, None) => anyhow::bail!("give a project or --cylinder DEPTH"),
    };
    let ImageSize { width, height } = args.size;
    check_render_budget(
        &doc,
        (width, height),
        doc.camera,
        &doc.quality,
        args.memory_limit,
    )?;
    let strategies = [
        StretchStrategy::Off,
        StretchStrategy::Thesis,
        StretchStrategy::Corners,
        StretchStrategy::Adaptive,
    ]
    .map(|strategy| StretchSettings {
        strategy,
        max_factor: args
            .max_factor
            .unwrap_or(StretchSettings::default().max_factor),
        ..StretchSettings::default()
    })
    .to_vec();
    for s in &strategies {
        s.validate()
            .map_err(|e| anyhow::anyhow!("--max-factor: {e}"))?;
    }
    let report = skin_report(
        &doc,
        &ReportSettings {
            frames: args.frames,
            views: args.views,
            width,
            height,
            clip: args.clip.clone(),
            strategies,
            quality: doc.quality.clone(),
        },
    )
    .with_context(|| format!("{source}: skin report"))?;
    let text = if args.json {
        let mut s = serde_json::to_string_pretty(&report).context("encoding the report")?;
        s.push('\n');
        s
    } else {
        format_skin_report(&report, width, height, args.per_view)
    };
    write_stdout(&text)
}

/// The `skin-report` table: per strategy the rest-pose counts (voxelization error of the
/// shape), the posed counts over every frame and view with their holes split into misplaced
/// (voxelization: wrong weights) and stretch (beyond the rest pose), and the old coverage-only
/// holes for comparison; with `per_view`, one line per strategy and view.
#[must_use]
pub fn format_skin_report(
    report: &thicket_core::measure::skin::SkinReport,
    width: u32,
    height: u32,
    per_view: bool,
) -> String {
    let views = report.rows.first().map_or(0, |r| r.views.len());
    let reference = match report.reference {
        thicket_core::measure::skin::ReferenceSurface::SourceMesh => "its skinned source mesh",
        thicket_core::measure::skin::ReferenceSurface::OwnSurface => {
            "its own skinned surface (rigged in Thicket: no source mesh)"
        }
    };
    let mut s = format!(
        "{} / clip {:?} against {reference}: {} frames + rest, {views} views at \
         {width}x{height}; voxel {:.4}, pixel {:.4}, depth tolerance {:.4} (world units)\n",
        report.object,
        report.clip,
        report.times.len(),
        report.voxel_world,
        report.pixel_world,
        report.tolerance,
    );
    s.push_str(&format!(
        "{} mesh pixels at rest, {} posed\n",
        thousands(report.rows.first().map_or(0, |r| r.rest.mesh_pixels)),
        thousands(report.rows.first().map_or(0, |r| r.posed.mesh_pixels))
    ));
    s.push_str(
        "strategy    rest holes  rest bloat | holes     through   misplaced  stretch   bloat      bloat %  stretch bloat | coverage holes  frame ms\n",
    );
    for r in &report.rows {
        s.push_str(&format!(
            "{:<10}  {:>10}  {:>10} | {:>8}  {:>8}  {:>9}  {:>7}  {:>9}  {:>6.2}%  {:>13} | {:>14}  {:>8.2}\n",
            format!("{:?}", r.settings.strategy),
            thousands(r.rest.holes),
            thousands(r.rest.bloat),
            thousands(r.posed.holes),
            thousands(r.posed.holes_through),
            thousands(r.posed.holes_misplaced),
            thousands(r.stretch_holes),
            thousands(r.posed.bloat),
            100.0 * r.posed.bloat_fraction(),
            thousands(r.stretch_bloat),
            thousands(r.coverage.holes),
            r.frame_ms
        ));
    }
    if per_view {
        s.push_str("strategy    view  rest holes  rest bloat | holes     misplaced  stretch   bloat      stretch bloat\n");
        for r in &report.rows {
            for v in &r.views {
                let mut posed = thicket_core::measure::skin::ShellCounts::default();
                for f in &v.frames {
                    posed.add(f);
                }
                s.push_str(&format!(
                    "{:<10}  {:>4.0}  {:>10}  {:>10} | {:>8}  {:>9}  {:>7}  {:>9}  {:>13}\n",
                    format!("{:?}", r.settings.strategy),
                    v.yaw_deg,
                    thousands(v.rest.holes),
                    thousands(v.rest.bloat),
                    thousands(posed.holes),
                    thousands(posed.holes_misplaced),
                    thousands(v.stretch_holes),
                    thousands(posed.bloat),
                    thousands(v.stretch_bloat),
                ));
            }
        }
    }
    s
}

fn export_vox(args: &ExportVoxArgs) -> anyhow::Result<()> {
    use thicket_core::io::vox::{VoxExportOptions, estimate_vox_export, export_vox_with};
    files::refuse_overwriting_input(&args.project, &args.output)?;
    if let Some(unit) = args.grid_unit
        && !(unit.is_finite() && unit > 0.0)
    {
        anyhow::bail!("--grid-unit {unit}: give a positive length");
    }
    let doc = files::load_document_within(&args.project, args.memory_limit)?;
    let options = VoxExportOptions {
        grid_unit: args.grid_unit,
        ..VoxExportOptions::default()
    };
    // The cost is known from voxel counts and transforms: refused before any cell is built.
    // Objects the estimate refuses (nothing to export, bad transforms) are left to the
    // exporter, which says why.
    if let Ok(e) = estimate_vox_export(&doc.objects, &args.output, &options) {
        let project = args.project.display();
        if e.cells > options.max_voxels {
            // The unit that brings the count under the limit (cells shrink with its cube).
            let suggested = e.grid_unit * (e.cells as f64 / options.max_voxels as f64).cbrt();
            anyhow::bail!(
                "{project}: the export would write about {} .vox voxels at a grid unit of {}, \
                 more than the limit of {}; give a larger --grid-unit (about {} or more)",
                thousands(e.cells),
                short(e.grid_unit as f32),
                thousands(options.max_voxels),
                short((suggested * 1.01) as f32)
            );
        }
        memory_budget(args.memory_limit).check(
            &format!(
                "{project}: exporting about {} .vox voxels",
                thousands(e.cells)
            ),
            e.peak_bytes,
            "give a larger --grid-unit, or raise the limit with --memory-limit",
        )?;
    }
    let report = export_vox_with(&doc.objects, &args.output, &options)?;
    let mut text = format!(
        "wrote {}: {} voxels in {} model(s) placed {} time(s), {} palette colours",
        args.output.display(),
        thousands(report.voxels),
        report.models,
        report.placements,
        report.palette_colors
    );
    if !report.exact_colors {
        text.push_str(&format!(
            " ({} distinct colours quantised; largest channel error {})",
            report.distinct_colors, report.max_channel_error
        ));
    }
    if !report.skipped.is_empty() {
        text.push_str(&format!(
            "; skipped (hidden, mesh or empty): {}",
            report.skipped.join(", ")
        ));
    }
    text.push('\n');
    write_stdout(&text)
}

fn info(args: &InfoArgs) -> anyhow::Result<()> {
    let info = files::info(&args.file, args.memory_limit)?;
    let text = if args.json {
        let mut s = serde_json::to_string_pretty(&info).context("encoding the report as JSON")?;
        s.push('\n');
        s
    } else {
        format_info(&info, args.memory, args.joints)
    };
    write_stdout(&text)
}

/// Writes to stdout; a closed pipe (`thicket info x | head`) is not an error.
pub(crate) fn write_stdout(text: &str) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
            Err(e).context("writing to standard output")
        }
        _ => Ok(()),
    }
}

fn fmt_size(v: [f32; 3]) -> String {
    format!("{:.3} × {:.3} × {:.3}", v[0], v[1], v[2])
}

/// The text report of `thicket info`.
#[must_use]
pub fn format_info(info: &DocumentInfo, memory: bool, joints: bool) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(s, "{} ({})", info.file, info.format);
    if let Some(count) = &info.counted {
        format_counted(&mut s, count);
        return s;
    }
    let _ = writeln!(
        s,
        "  {} object(s), {} voxels, {} triangles, {} light(s), {} in memory",
        info.objects.len(),
        thousands(info.total_voxels),
        thousands(info.total_triangles as u64),
        info.lights,
        human_bytes(info.total_bytes)
    );
    if let (Some(models), Some(voxels)) = (info.source.stored_models, info.source.stored_voxels) {
        let _ = writeln!(
            s,
            "  the file stores {} voxels in {models} model(s); its scene graph places them as {} object(s)",
            thousands(voxels),
            info.objects.len()
        );
    }
    if let (Some(nodes), Some(instances)) = (info.source.instanced_nodes, info.source.instances) {
        let _ = writeln!(
            s,
            "  the file places {} instance(s) on {nodes} node(s) with EXT_mesh_gpu_instancing; \
             each is a copy of its node's mesh in the triangles above",
            thousands(instances)
        );
    }
    if let Some(size) = info.world_size {
        let _ = writeln!(s, "  world size: {}", fmt_size(size));
    }
    for o in &info.objects {
        let hidden = if o.visible { "" } else { ", hidden" };
        let _ = writeln!(s, "  [{}] {:?} ({}{hidden})", o.id, o.name, o.kind);
        if let Some(voxels) = o.voxels {
            let _ = write!(s, "      {} voxels", thousands(voxels));
            if let Some(d) = o.dimensions_voxels {
                let _ = write!(s, ", {} × {} × {} voxels", d[0], d[1], d[2]);
            }
            if let (Some(depth), Some(extent)) = (o.depth, o.extent) {
                let _ = write!(s, ", depth {depth} ({extent}³)");
            }
            if let Some(vs) = o.voxel_size {
                let _ = write!(s, ", voxel size {vs}");
            }
            if let Some(bpv) = o.bytes_per_voxel {
                let _ = write!(s, ", {bpv:.2} bytes/voxel");
            }
            s.push('\n');
            if let Some(frames) = &o.frame_voxels {
                let counts: Vec<String> = frames.iter().map(|&n| thousands(n)).collect();
                let _ = writeln!(
                    s,
                    "      {} frames (voxels per frame: {})",
                    frames.len(),
                    counts.join(", ")
                );
            }
        }
        if let (Some(t), Some(v)) = (o.triangles, o.vertices) {
            let _ = writeln!(
                s,
                "      {} triangles, {} vertices, {} material(s)",
                thousands(t as u64),
                thousands(v as u64),
                o.materials
            );
        }
        if let Some(k) = &o.krs {
            let _ = writeln!(
                s,
                "      KRS: {} kernel instances, {} mirrors, {} kernel sets ({} non-empty: {}){}{}",
                thousands_u128(k.kernel_instances),
                k.mirrors,
                k.kernel_sets,
                k.kernels.len(),
                summarise_kinds(&k.kernels),
                if k.distorted { ", distorted" } else { "" },
                if k.empty_zones > 0 {
                    format!(", {} empty zone(s)", k.empty_zones)
                } else {
                    String::new()
                }
            );
        }
        if let Some(size) = o.world_size {
            let _ = writeln!(s, "      world size {}", fmt_size(size));
        }
        if let (Some(lo), Some(hi)) = (o.bounds_min, o.bounds_max) {
            let _ = writeln!(
                s,
                "      own-space bounds [{:.4}, {:.4}, {:.4}] .. [{:.4}, {:.4}, {:.4}]",
                lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
            );
        }
        if let Some(list) = &o.joints {
            let _ = writeln!(s, "      skeleton: {} joint(s)", list.len());
            if joints {
                for j in list {
                    let _ = writeln!(
                        s,
                        "        {:?}{} at [{:.4}, {:.4}, {:.4}]: strongest influence of {} voxels",
                        j.name,
                        j.parent
                            .as_ref()
                            .map_or(String::new(), |p| format!(" (child of {p:?})")),
                        j.position[0],
                        j.position[1],
                        j.position[2],
                        thousands(j.dominant_voxels)
                    );
                }
            }
        }
        if memory {
            let m = &o.memory;
            let _ = writeln!(
                s,
                "      memory: {} total = {} structure + {} attributes + {} textures + {} free slots",
                human_bytes(m.total_bytes),
                human_bytes(m.structure_bytes),
                human_bytes(m.payload_bytes),
                human_bytes(m.texture_bytes),
                human_bytes(m.free_bytes)
            );
            if m.tiles > 0 {
                let _ = writeln!(
                    s,
                    "      tiles: {} stand for {} voxels stored once each",
                    thousands(m.tiles),
                    thousands(m.tile_voxels)
                );
            }
            if m.interior_voxels > 0 {
                let _ = writeln!(
                    s,
                    "      interior: {} voxels enclosed, their attributes found when an edit \
                     exposes them",
                    thousands(m.interior_voxels)
                );
            }
        }
    }
    s
}

/// The report of a glTF file too large to import: what it holds, counted without building.
fn format_counted(s: &mut String, count: &thicket_core::io::GltfCount) {
    use std::fmt::Write as _;
    let split = if count.flat_normal_vertices > 0 {
        format!(
            " (and up to {} more where flat normals split them)",
            thousands(count.flat_normal_vertices)
        )
    } else {
        String::new()
    };
    let _ = writeln!(
        s,
        "  counted from the file, not built: {} triangles, {} vertices{split} in {} mesh(es); \
         an import would need up to {}",
        thousands(count.triangles),
        thousands(count.vertices),
        count.meshes.len(),
        human_bytes(count.bytes)
    );
    if count.instances > 0 {
        let _ = writeln!(
            s,
            "  the file places {} instance(s) on {} node(s) with EXT_mesh_gpu_instancing",
            thousands(count.instances),
            thousands(count.instanced_nodes)
        );
    }
    if let Some(why) = &count.refused {
        let _ = writeln!(s, "  not imported: {why}");
    }
    for m in &count.meshes {
        let name = if m.name.is_empty() {
            String::new()
        } else {
            format!(" {:?}", m.name)
        };
        let _ = writeln!(
            s,
            "  mesh {}{name}: {} triangles, {} vertices; {} node(s) draw {} cop{}",
            m.index,
            thousands(m.triangles),
            thousands(m.vertices),
            thousands(m.nodes),
            thousands(m.copies),
            if m.copies == 1 { "y" } else { "ies" }
        );
    }
    for line in &count.report {
        let _ = writeln!(s, "  note: {line}");
    }
}

/// `["Sphere", "Capsule", "Capsule"]` → `Sphere, 2 x Capsule` (first-seen order).
fn summarise_kinds(kinds: &[&str]) -> String {
    let mut counts: Vec<(&str, usize)> = Vec::new();
    for k in kinds {
        match counts.iter_mut().find(|(name, _)| name == k) {
            Some((_, n)) => *n += 1,
            None => counts.push((k, 1)),
        }
    }
    counts
        .iter()
        .map(|(name, n)| {
            if *n == 1 {
                (*name).to_owned()
            } else {
                format!("{n} x {name}")
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// A progress bar on stderr for long work; indicatif hides it when stderr is not a terminal.
#[must_use]
pub fn progress_bar(len: u64, message: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(len);
    if let Ok(style) = indicatif::ProgressStyle::with_template(
        "{msg:>12} [{bar:40}] {percent:>3}% ({elapsed}, ETA {eta})",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message(message.to_owned());
    bar
}

#[cfg(test)]
mod tests {

    #[derive(Debug, thiserror::Error)]
    #[error("{path}: reading failed: {source}")]
    struct Wrapped {
        path: String,
        source: std::io::Error,
    }

    #[test]
    fn an_error_chain_says_each_cause_once() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file or directory");
        let e = anyhow::Error::new(Wrapped {
            path: "a.vox".into(),
            source: io,
        });
        assert_eq!(
            error_line(&e),
            "a.vox: reading failed: No such file or directory"
        );
        // A context that adds something keeps both; one that repeats the cause drops it.
        let e = e.context("opening the project");
        assert_eq!(
            error_line(&e),
            "opening the project: a.vox: reading failed: No such file or directory"
        );
        let plain = anyhow::anyhow!("inner problem").context("outer");
        assert_eq!(error_line(&plain), "outer: inner problem");
    }

    use super::*;
    use clap::CommandFactory as _;

    #[test]
    fn cli_definition_is_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn parses_editor_and_info_forms() {
        let cli = Cli::try_parse_from(["thicket"]).unwrap();
        assert!(cli.project.is_none() && cli.command.is_none());
        let cli = Cli::try_parse_from(["thicket", "p.thicket.json"]).unwrap();
        assert_eq!(cli.project, Some(PathBuf::from("p.thicket.json")));
        let cli = Cli::try_parse_from(["thicket", "info", "x.vox", "--json", "--memory"]).unwrap();
        match cli.command {
            Some(Command::Info(a)) => assert!(a.json && a.memory && a.file.ends_with("x.vox")),
            other => panic!("{other:?}"),
        }
        assert!(Cli::try_parse_from(["thicket", "info"]).is_err());
    }

    #[test]
    fn parses_export() {
        let cli = Cli::try_parse_from([
            "thicket",
            "export",
            "p.thicket.json",
            "-o",
            "out.glb",
            "--object",
            "Tree",
            "--mode",
            "smooth",
            "--resolution",
            "512",
        ])
        .unwrap();
        match cli.command {
            Some(Command::Export(a)) => {
                assert_eq!(a.output, PathBuf::from("out.glb"));
                assert_eq!(a.object.as_deref(), Some("Tree"));
                assert_eq!(a.mode, ExportModeArg::Smooth);
                assert_eq!(a.resolution, 512);
                assert!(!a.palette_texture);
            }
            other => panic!("{other:?}"),
        }
        let cli = Cli::try_parse_from(["thicket", "export", "p", "-o", "x", "--mode", "instances"])
            .unwrap();
        assert!(
            matches!(cli.command, Some(Command::Export(a)) if a.mode == ExportModeArg::Instances)
        );
        assert!(
            Cli::try_parse_from(["thicket", "export", "p", "-o", "x", "--mode", "blobs"]).is_err()
        );
        assert!(Cli::try_parse_from(["thicket", "export", "p"]).is_err());
    }
}
