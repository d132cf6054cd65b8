//! `thicket forest`: grow a forest from trees of a project (§7.2), as the editor's Grow forest
//! panel does: more reflections with empty kernel sets, shared with a KRS terrain when one is
//! given, several trees interleaved so no tree stands beside its own mirror image.

use std::path::PathBuf;

use anyhow::Context as _;
use clap::Args;
use thicket_core::krs::forest::ForestParams;
use thicket_core::scene::Document;

use crate::files::{self, thousands};

/// `thicket forest`.
#[derive(Debug, Args)]
pub struct ForestArgs {
    /// The project holding the tree(s).
    pub project: PathBuf,
    /// A tree to grow from (a KRS object made by the tree builder); give it two or more times
    /// for a union of different trees, interleaved so no tree stands beside its mirror image.
    #[arg(long = "object", value_name = "TREE", required = true)]
    pub objects: Vec<String>,
    /// Trees along x and z. One tree: powers of two (e.g. 64x64). K trees: x is K times a
    /// power of two, z twice one (3 trees: 48x32).
    #[arg(long, value_name = "NXxNZ", value_parser = parse_trees)]
    pub trees: [u32; 2],
    /// Extent of the forest along x and z in world units (the spacing is area / trees).
    #[arg(long, value_name = "X,Z", value_parser = parse_area)]
    pub area: [f32; 2],
    /// Largest azimuth jitter of a mirror off its axis, radians (0 to 0.5): rows stop lining up.
    #[arg(long, default_value_t = ForestParams::default().jitter)]
    pub jitter: f32,
    /// Largest change of a gap between trees, as a fraction of the spacing (0 to 0.45).
    #[arg(long, default_value_t = ForestParams::default().spread)]
    pub spread: f32,
    /// Largest tilt of a mirror out of the vertical on a terrain, radians (0 to 0.3): the
    /// ground rises and falls, the trees lean with it.
    #[arg(long, default_value_t = ForestParams::default().tilt)]
    pub tilt: f32,
    /// Amplitude of the Lipschitz warp that bends every tree differently (world units; 0 =
    /// none).
    #[arg(long, default_value_t = 0.0)]
    pub warp: f32,
    /// Frequency of the warp (cycles per world unit).
    #[arg(long, default_value_t = ForestParams::default().warp_frequency)]
    pub warp_frequency: f32,
    /// Seed of the draws.
    #[arg(long, default_value_t = ForestParams::default().seed)]
    pub seed: u64,
    /// A KRS terrain to stand the forest on: it takes the forest's reflections after its own,
    /// so every trunk stands on it (one tree only).
    #[arg(long, value_name = "TERRAIN")]
    pub on: Option<String>,
    /// Where to write the project with the forest (not the input).
    #[arg(short, long, value_name = "OUT.thicket.json")]
    pub output: PathBuf,
}

fn parse_trees(s: &str) -> Result<[u32; 2], String> {
    let (x, z) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("{s:?}: give the trees as NXxNZ, e.g. 64x64"))?;
    let n = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| format!("{s:?}: {v:?} is not a whole number of trees"))
    };
    Ok([n(x)?, n(z)?])
}

fn parse_area(s: &str) -> Result<[f32; 2], String> {
    let (x, z) = s
        .split_once(',')
        .ok_or_else(|| format!("{s:?}: give the area as X,Z, e.g. 200,200"))?;
    let n = |v: &str| {
        v.trim()
            .parse::<f32>()
            .map_err(|_| format!("{s:?}: {v:?} is not a number"))
    };
    Ok([n(x)?, n(z)?])
}

/// The id of the object named `name`, or an error naming what the project has.
fn object_id(doc: &Document, project: &std::path::Path, name: &str) -> anyhow::Result<u64> {
    doc.objects
        .iter()
        .find(|o| o.name == name)
        .map(|o| o.id)
        .with_context(|| {
            let names: Vec<String> = doc
                .objects
                .iter()
                .map(|o| format!("{:?}", o.name))
                .collect();
            format!(
                "{}: no object named {name:?}; the project has {}",
                project.display(),
                names.join(", ")
            )
        })
}

/// Runs `thicket forest`.
///
/// # Errors
/// Unreadable project, unknown objects, a tree the builder did not make, bad parameters (one
/// message naming them), an unwritable output.
pub fn forest(args: &ForestArgs) -> anyhow::Result<()> {
    files::refuse_overwriting_input(&args.project, &args.output)?;
    let mut doc = files::load_document(&args.project)?;
    let sources = args
        .objects
        .iter()
        .map(|n| object_id(&doc, &args.project, n))
        .collect::<anyhow::Result<Vec<u64>>>()?;
    let terrain = args
        .on
        .as_deref()
        .map(|n| object_id(&doc, &args.project, n))
        .transpose()?;
    let params = ForestParams {
        trees: args.trees,
        area: args.area,
        jitter: args.jitter,
        spread: args.spread,
        tilt: args.tilt,
        warp: args.warp,
        warp_frequency: args.warp_frequency,
        seed: args.seed,
    };
    let plan = doc
        .plan_forest(&sources, terrain, &params)
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.project.display()))?;
    let (total, spacing, overlap) = (plan.total, plan.spacing, plan.crowns_overlap);
    let ids = doc.apply_forest(plan);
    files::save_project(&doc, &args.output)?;
    let mut text = format!(
        "wrote {}: {} trees placed ({} × {} spacing {:.2} × {:.2}) in {} object(s)",
        args.output.display(),
        thousands(total),
        args.trees[0],
        args.trees[1],
        spacing[0],
        spacing[1],
        ids.len()
    );
    if let Some(t) = &args.on {
        text.push_str(&format!(", standing on {t:?}"));
    }
    if overlap {
        text.push_str("; the crowns are wider than the spacing and meet between the trees");
    }
    text.push('\n');
    crate::cli::write_stdout(&text)
}
