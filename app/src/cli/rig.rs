//! `thicket rig` and `thicket animate`: a skeleton and clips for a voxel model made in Thicket,
//! from the JSON formats of `docs/skinning.md`.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use clap::{Args, ValueEnum};
use thicket_core::scene::{Document, ObjectKind, VoxelModel};
use thicket_core::skin::author::clips_by_name;
use thicket_core::skin::bind::{BindControl, BindMethod, BindReport, bind};
use thicket_core::skin::{ClipSpec, Rig, SkeletonSpec};

use crate::files::{self, thousands};

/// `thicket rig`.
#[derive(Debug, Args)]
pub struct RigArgs {
    /// The project holding the voxel model.
    pub project: PathBuf,
    /// Name of the voxel object to rig.
    #[arg(long)]
    pub object: String,
    /// The skeleton: `{"joints": [{"name": "hip", "parent": null, "position": [x, y, z]}, ...]}`
    /// with positions in the model's own space (see `thicket info --json`: bounds_min/max).
    #[arg(long, value_name = "SKEL.json")]
    pub skeleton: PathBuf,
    /// How weights are computed: through the model's volume (geodesic), by straight-line
    /// distance (envelope) or one joint per voxel (rigid).
    #[arg(long, value_enum, default_value = "geodesic")]
    pub bind: BindArg,
    /// Where to write the rigged project (not the input).
    #[arg(short, long, value_name = "OUT.thicket.json")]
    pub output: PathBuf,
}

/// `thicket animate`.
#[derive(Debug, Args)]
pub struct AnimateArgs {
    /// The project holding the rigged voxel model.
    pub project: PathBuf,
    /// Name of the rigged voxel object.
    #[arg(long)]
    pub object: String,
    /// The clip: `{"name": "wave", "length": 1.0, "keys": [{"joint": "arm.L", "time": 0.5,
    /// "rotation_deg": [rx, ry, rz], "translation": [x, y, z]}]}`; optional
    /// `"interpolation": "step" | "linear" | "cubic"` and `"loop": true`. A clip of the same name
    /// is replaced; the model then plays it.
    #[arg(long, value_name = "CLIP.json")]
    pub clip: PathBuf,
    /// Where to write the animated project (not the input).
    #[arg(short, long, value_name = "OUT.thicket.json")]
    pub output: PathBuf,
}

/// `--bind`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum BindArg {
    /// Distances through the model's voxels (limbs that touch stay apart).
    Geodesic,
    /// Straight-line distances.
    Envelope,
    /// One joint per voxel.
    Rigid,
}

impl From<BindArg> for BindMethod {
    fn from(b: BindArg) -> Self {
        match b {
            BindArg::Geodesic => Self::Geodesic,
            BindArg::Envelope => Self::Envelope,
            BindArg::Rigid => Self::Rigid,
        }
    }
}

/// Largest skeleton or clip file read (a skeleton of 256 joints is a few tens of KB).
const MAX_SPEC_BYTES: u64 = 16 << 20;

/// Reads a JSON spec of at most [`MAX_SPEC_BYTES`].
fn read_spec<T: serde::de::DeserializeOwned>(path: &Path, what: &str) -> anyhow::Result<T> {
    let shown = path.display();
    let len = std::fs::metadata(path)
        .with_context(|| format!("{shown}: cannot read the {what} file"))?
        .len();
    if len > MAX_SPEC_BYTES {
        anyhow::bail!(
            "{shown}: the {what} file is {} bytes; at most {} are read",
            thousands(len),
            thousands(MAX_SPEC_BYTES)
        );
    }
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{shown}: cannot read the {what} file"))?;
    serde_json::from_str(&text).with_context(|| format!("{shown}: not a valid {what} file"))
}

/// The index of the voxel object `name` in `doc`, or an error naming what the project has.
pub fn voxel_object_index(
    doc: &Document,
    project: &Path,
    name: &str,
    purpose: &str,
) -> anyhow::Result<usize> {
    let project = project.display();
    let Some(index) = doc.objects.iter().position(|o| o.name == name) else {
        let names: Vec<String> = doc
            .objects
            .iter()
            .map(|o| format!("{:?}", o.name))
            .collect();
        anyhow::bail!(
            "{project}: no object named {name:?}; the project has {}",
            if names.is_empty() {
                "no objects".to_owned()
            } else {
                names.join(", ")
            }
        );
    };
    if !matches!(doc.objects[index].kind, ObjectKind::Voxels(_)) {
        anyhow::bail!(
            "{project}: object {name:?} is a {}, not a voxel object; only voxel objects can be \
             {purpose}",
            doc.objects[index].kind_name()
        );
    }
    Ok(index)
}

fn voxels_mut(doc: &mut Document, index: usize) -> &mut VoxelModel {
    match &mut doc.objects[index].kind {
        ObjectKind::Voxels(v) => v,
        _ => unreachable!("voxel_object_index checked the kind"),
    }
}

/// `thicket rig`.
///
/// # Errors
/// A missing object or file, a bad skeleton (naming the file and the joint), a failed binding
/// or write; nothing is written then.
pub fn rig(args: &RigArgs) -> anyhow::Result<()> {
    files::refuse_overwriting_input(&args.project, &args.output)?;
    let mut doc = files::load_document(&args.project)?;
    let index = voxel_object_index(&doc, &args.project, &args.object, "rigged")?;
    let spec: SkeletonSpec = read_spec(&args.skeleton, "skeleton")?;
    let model = voxels_mut(&mut doc, index);
    let skeleton = spec
        .to_skeleton(model.bounds())
        .with_context(|| format!("{}", args.skeleton.display()))?;
    let bar = crate::cli::progress_bar(1000, "binding");
    let report = |f: f32| bar.set_position((f.clamp(0.0, 1.0) * 1000.0) as u64);
    let start = std::time::Instant::now();
    let bound = bind(
        &model.svo,
        model.origin,
        model.voxel_size,
        &skeleton,
        args.bind.into(),
        BindControl {
            progress: Some(&report),
            cancel: None,
        },
    );
    bar.finish_and_clear();
    let (svo, report) = bound.with_context(|| {
        format!(
            "{}: binding object {:?}",
            args.project.display(),
            args.object
        )
    })?;
    let seconds = start.elapsed().as_secs_f64();
    let (clips, dropped) = match &model.rig {
        Some(old) => {
            // Clips left with no channel of the new skeleton's joints go.
            let (mut clips, dropped) = clips_by_name(&old.skeleton, &old.clips, &skeleton);
            clips.retain(|c| !c.channels.is_empty());
            (clips, dropped)
        }
        None => (Vec::new(), 0),
    };
    model.svo = svo;
    let binding = thicket_core::skin::rig::Binding {
        method: report.method,
        skeleton: SkeletonSpec::of_skeleton(&skeleton),
    };
    let mut rig = Rig::new(skeleton, clips);
    rig.binding = Some(binding);
    model.rig = Some(rig);
    files::save_project(&doc, &args.output)?;
    let mut text = format!(
        "wrote {}: object {:?} rigged with {} joints, {} binding of {} voxels in {seconds:.2} s",
        args.output.display(),
        args.object,
        report.dominant.len(),
        report.method.name(),
        thousands(report.voxels),
    );
    text.push_str(&bind_notes(&report));
    if dropped > 0 {
        text.push_str(&format!(
            "; {dropped} clip channel(s) of joints the new skeleton lacks were dropped"
        ));
    }
    text.push('\n');
    crate::cli::write_stdout(&text)
}

/// What a binding report adds to a one-line summary (coarse cells, islands, unused joints).
#[must_use]
pub fn bind_notes(report: &BindReport) -> String {
    let mut text = String::new();
    if report.cell_size > 1 {
        text.push_str(&format!(
            "; distances measured on cells of {0}×{0}×{0} voxels (the model's bounds are large)",
            report.cell_size
        ));
    }
    if report.unreachable_voxels > 0 {
        text.push_str(&format!(
            "; {} voxel(s) no bone reaches through the model (floating parts) were bound by \
             straight-line distance",
            thousands(report.unreachable_voxels)
        ));
    }
    let idle = report.dominant.iter().filter(|&&n| n == 0).count();
    if idle > 0 {
        text.push_str(&format!(
            "; {idle} joint(s) are the strongest influence of no voxel"
        ));
    }
    text
}

/// `thicket animate`.
///
/// # Errors
/// A missing object or file, a model without a skeleton, a bad clip (naming the file and the
/// key), or a failed write; nothing is written then.
pub fn animate(args: &AnimateArgs) -> anyhow::Result<()> {
    files::refuse_overwriting_input(&args.project, &args.output)?;
    let mut doc = files::load_document(&args.project)?;
    let index = voxel_object_index(&doc, &args.project, &args.object, "animated")?;
    let spec: ClipSpec = read_spec(&args.clip, "clip")?;
    let model = voxels_mut(&mut doc, index);
    let Some(rig) = model.rig.as_mut() else {
        anyhow::bail!(
            "{}: object {:?} has no skeleton; give it one with `thicket rig` first",
            args.project.display(),
            args.object
        );
    };
    let clip = spec
        .to_clip(&rig.skeleton)
        .with_context(|| format!("{}", args.clip.display()))?;
    let channels = clip.channels.len();
    let at = match rig.clip_index(&clip.name) {
        Some(i) => {
            rig.clips[i] = clip;
            i
        }
        None => {
            rig.clips.push(clip);
            rig.clips.len() - 1
        }
    };
    rig.playback.clip = Some(at);
    rig.playback.time_secs = 0.0;
    rig.playback.wrap = spec.wrap();
    rig.validate()
        .with_context(|| format!("{}: object {:?}", args.project.display(), args.object))?;
    files::save_project(&doc, &args.output)?;
    crate::cli::write_stdout(&format!(
        "wrote {}: object {:?} plays clip {:?} ({} s, {} key(s) in {channels} channel(s))\n",
        args.output.display(),
        args.object,
        spec.name,
        spec.length,
        spec.keys.len()
    ))
}
