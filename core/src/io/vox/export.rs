//! Objects → `.vox`: world grid, splitting into ≤ 256³ models, palette quantisation, chunks,
//! atomic write.

use std::collections::{BTreeMap, HashMap};
use std::io::Write;
use std::path::{Path, PathBuf};

use glam::{DMat4, DVec3};

use super::chunks::{write_chunk, write_dict};
use super::{
    IMat3, MAX_COORD, MAX_MODEL_EDGE, VoxError, decode_rotation, imat_apply, mv_cell_from_yup,
};
use crate::scene::{Object, ObjectKind, VoxelModel};

/// MagicaVoxel-space cell → (sRGB colour, index into the export's material table).
type CellMap = HashMap<[i64; 3], ([u8; 4], u16)>;

/// Settings for [`export_vox_with`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VoxExportOptions {
    /// World length of one `.vox` voxel. `None`: the smallest voxel edge among the exported
    /// objects (voxel size × smallest scale), so the finest object keeps one cell per voxel.
    pub grid_unit: Option<f32>,
    /// Most cells the export may write (objects with larger voxels than the grid fill several).
    pub max_voxels: u64,
}

impl Default for VoxExportOptions {
    fn default() -> Self {
        Self {
            grid_unit: None,
            max_voxels: super::DEFAULT_MAX_VOXELS,
        }
    }
}

/// What an export wrote.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct VoxExportReport {
    /// Models written: each distinct block of voxels once (objects larger than 256 in a
    /// dimension become several blocks; equal blocks, also turned, are one model placed again).
    pub models: usize,
    /// Shape nodes written: one per object, or per 256³ block of a larger object.
    pub placements: usize,
    /// Voxels written.
    pub voxels: u64,
    /// Palette entries used (at most 255).
    pub palette_colors: usize,
    /// Distinct (colour, material) pairs in the input.
    pub distinct_colors: usize,
    /// True when every voxel kept its exact colour (at most 255 distinct pairs).
    pub exact_colors: bool,
    /// Largest per-channel difference (0–255) between a voxel's colour and its palette entry.
    pub max_channel_error: u8,
    /// Names of objects left out (hidden, meshes, empty).
    pub skipped: Vec<String>,
}

/// Writes the visible voxel objects to `path` with the default options.
///
/// # Errors
/// A [`VoxError`] naming the file; on any error nothing is written (the file is written to a
/// temporary sibling and renamed over `path` only when complete).
pub fn export_vox(objects: &[Object], path: &Path) -> Result<VoxExportReport, VoxError> {
    export_vox_with(objects, path, &VoxExportOptions::default())
}

/// Writes the visible voxel objects to `path`.
///
/// # Errors
/// See [`export_vox`].
pub fn export_vox_with(
    objects: &[Object],
    path: &Path,
    options: &VoxExportOptions,
) -> Result<VoxExportReport, VoxError> {
    let (bytes, report) = export_vox_bytes(objects, path, options)?;
    write_atomic(path, &bytes)?;
    Ok(report)
}

/// The objects an export writes: visible voxel objects with voxels, checked; the others'
/// names go to `skipped`.
fn choose_objects<'a>(
    objects: &'a [Object],
    path: &Path,
    skipped: &mut Vec<String>,
) -> Result<Vec<(&'a Object, &'a VoxelModel)>, VoxError> {
    let object_error = |o: &Object, detail: String| VoxError::Object {
        path: path.to_owned(),
        object: o.name.clone(),
        detail,
    };
    let mut chosen = Vec::new();
    for o in objects {
        match &o.kind {
            ObjectKind::Voxels(v)
                if o.visible
                    && (0..v.frame_count())
                        .filter_map(|i| v.frame(i))
                        .any(|(svo, _)| !svo.is_empty()) =>
            {
                o.transform
                    .validate(&o.name)
                    .map_err(|e| object_error(o, e.to_string()))?;
                if !(v.voxel_size.is_finite() && v.voxel_size > 0.0 && v.origin.is_finite()) {
                    return Err(object_error(
                        o,
                        format!(
                            "voxel size {} and origin {} must be finite (size positive)",
                            v.voxel_size, v.origin
                        ),
                    ));
                }
                chosen.push((o, v));
            }
            _ => skipped.push(o.name.clone()),
        }
    }
    if chosen.is_empty() {
        return Err(VoxError::NothingToExport {
            path: path.to_owned(),
        });
    }
    Ok(chosen)
}

/// The world length of one `.vox` cell: the option's, else the smallest voxel edge.
fn grid_unit(
    chosen: &[(&Object, &VoxelModel)],
    path: &Path,
    options: &VoxExportOptions,
) -> Result<f64, VoxError> {
    let unit = options.grid_unit.map_or_else(
        || {
            chosen
                .iter()
                .map(|(o, v)| {
                    f64::from(v.voxel_size) * f64::from(o.transform.scale.abs().min_element())
                })
                .fold(f64::INFINITY, f64::min)
        },
        f64::from,
    );
    if !(unit.is_finite() && unit > 0.0) {
        return Err(VoxError::Object {
            path: path.to_owned(),
            object: "(all)".into(),
            detail: format!("grid unit {unit} must be finite and positive"),
        });
    }
    Ok(unit)
}

/// Cells the export fills, counted as the writer counts them (before overlapping cells
/// merge): per voxel, its transformed box's extent in grid cells along each axis, rounded,
/// at least one.
fn estimate_cells(chosen: &[(&Object, &VoxelModel)], unit: f64) -> u64 {
    let mut cells = 0u64;
    for (o, v) in chosen {
        let m = o.transform.matrix().as_dmat4();
        let per_voxel = f64::from(v.voxel_size) / unit;
        let cells_per_voxel: f64 = (0..3)
            .map(|axis| {
                let extent: f64 = (0..3).map(|c| m.col(c)[axis].abs()).sum::<f64>() * per_voxel;
                extent.round().max(1.0)
            })
            .product();
        let leaves: u64 = (0..v.frame_count())
            .filter_map(|i| v.frame(i))
            .map(|(svo, _)| svo.leaf_count())
            .sum();
        // Saturating: an absurd scale says "too many", not a wrapped small number.
        let object_cells = (leaves as f64 * cells_per_voxel).min(u64::MAX as f64) as u64;
        cells = cells.saturating_add(object_cells);
    }
    cells
}

/// Peak heap per cell of an export: the cell map's entry and hash-table slack while it grows
/// (about 113 bytes at a resize), the block lists and the models written (4 bytes each, with
/// growth), and the encoded `XYZI` data.
pub const VOX_EXPORT_BYTES_PER_CELL: u64 = 144;

/// What an export will cost, known before any cell is built (see [`estimate_vox_export`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VoxExportEstimate {
    /// The grid unit the export will use.
    pub grid_unit: f64,
    /// Cells it will fill (voxels larger than the unit fill several).
    pub cells: u64,
    /// Estimated peak heap in bytes.
    pub peak_bytes: u64,
}

/// Estimates an export of `objects` with `options` from the voxel counts and transforms alone.
///
/// # Errors
/// As [`export_vox`] for the objects themselves (nothing to export, invalid transforms or
/// voxel sizes, a bad grid unit); `path` only names the target.
pub fn estimate_vox_export(
    objects: &[Object],
    path: &Path,
    options: &VoxExportOptions,
) -> Result<VoxExportEstimate, VoxError> {
    let chosen = choose_objects(objects, path, &mut Vec::new())?;
    let unit = grid_unit(&chosen, path, options)?;
    let cells = estimate_cells(&chosen, unit);
    // One frame's interior search at a time (`Svo::nearest_surfaces`).
    let nearest = chosen
        .iter()
        .flat_map(|(_, v)| (0..v.frame_count()).filter_map(|i| v.frame(i)))
        .filter_map(|(svo, _)| svo.nearest_surfaces_bytes())
        .max()
        .unwrap_or(0);
    Ok(VoxExportEstimate {
        grid_unit: unit,
        cells,
        peak_bytes: cells
            .saturating_mul(VOX_EXPORT_BYTES_PER_CELL)
            .saturating_add(nearest)
            .saturating_add(1 << 20),
    })
}

/// Encodes the visible voxel objects as `.vox` bytes; `path` only names the target in errors.
///
/// # Errors
/// See [`export_vox`].
pub fn export_vox_bytes(
    objects: &[Object],
    path: &Path,
    options: &VoxExportOptions,
) -> Result<(Vec<u8>, VoxExportReport), VoxError> {
    let object_error = |o: &Object, detail: String| VoxError::Object {
        path: path.to_owned(),
        object: o.name.clone(),
        detail,
    };
    let mut report = VoxExportReport::default();
    let chosen = choose_objects(objects, path, &mut report.skipped)?;
    let unit = grid_unit(&chosen, path, options)?;
    // Known before any cell is built: refused here, not after millions of cells.
    let cells = estimate_cells(&chosen, unit);
    if cells > options.max_voxels {
        return Err(VoxError::Object {
            path: path.to_owned(),
            object: "(all)".into(),
            detail: format!(
                "the export would write about {cells} voxels at a grid unit of {unit}, more \
                 than the limit of {}; choose a larger grid unit",
                options.max_voxels
            ),
        });
    }

    // Global material table: name → index, "diffuse" = 0.
    let mut material_names: Vec<String> = vec!["diffuse".into()];
    // Per object, the cells of each frame (one for a still model).
    let mut per_object_cells: Vec<(String, Vec<CellMap>)> = Vec::new();
    let mut total_cells = 0u64;
    for (o, v) in &chosen {
        let local_materials: Vec<u16> = v
            .material_names
            .iter()
            .map(|n| {
                if let Some(k) = material_names.iter().position(|m| m == n) {
                    k as u16
                } else {
                    material_names.push(n.clone());
                    (material_names.len() - 1) as u16
                }
            })
            .collect();
        let mut frames = Vec::with_capacity(v.frame_count());
        for (svo, origin) in (0..v.frame_count()).filter_map(|i| v.frame(i)) {
            if !origin.is_finite() {
                return Err(object_error(
                    o,
                    format!("a frame's origin {origin} is not finite"),
                ));
            }
            let object_from_voxel = glam::Mat4::from_translation(origin)
                * glam::Mat4::from_scale(glam::Vec3::splat(v.voxel_size));
            let grid_from_voxel = DMat4::from_scale(DVec3::splat(1.0 / unit))
                * o.transform.matrix().as_dmat4()
                * object_from_voxel.as_dmat4();
            let mut cells = CellMap::new();
            let mut failure = None;
            // MagicaVoxel has no interior voxels: each is written with the colour exposing it
            // would give (its nearest voxel that is not interior), found for all of them at
            // once (`Svo::nearest_surfaces`), or one by one past its size.
            let nearest = svo.nearest_surfaces();
            svo.for_each_leaf(|c, vox| {
                if failure.is_some() {
                    return;
                }
                let vox = if vox.is_interior() {
                    match &nearest {
                        Some(n) => n.get(c).and_then(|q| svo.get(q)),
                        None => svo.nearest_surface(c).map(|(_, v)| v),
                    }
                    .unwrap_or(vox)
                } else {
                    vox
                };
                let base = c.as_dvec3();
                let mut lo = DVec3::INFINITY;
                let mut hi = DVec3::NEG_INFINITY;
                for k in 0..8u32 {
                    let corner = base
                        + DVec3::new(f64::from(k & 1), f64::from((k >> 1) & 1), f64::from(k >> 2));
                    let p = grid_from_voxel.transform_point3(corner);
                    lo = lo.min(p);
                    hi = hi.max(p);
                }
                // A voxel fills the grid cells whose centres its (transformed) box covers; at
                // least the nearest one, so no voxel disappears.
                let a = lo.round();
                let b = hi.round().max(a + 1.0);
                if a.abs().max_element() > f64::from(1 << 30)
                    || b.abs().max_element() > f64::from(1 << 30)
                {
                    failure = Some(format!(
                        "a voxel lands at {a} grid cells from the origin, beyond the .vox range"
                    ));
                    return;
                }
                let n = (b - a).element_product();
                total_cells += n as u64;
                if total_cells > options.max_voxels {
                    failure = Some(format!(
                        "the export would write more than {} voxels (grid unit {unit}); \
                     choose a larger grid unit",
                        options.max_voxels
                    ));
                    return;
                }
                let material = local_materials
                    .get(usize::from(vox.material))
                    .copied()
                    .unwrap_or(0);
                for z in a.z as i64..b.z as i64 {
                    for y in a.y as i64..b.y as i64 {
                        for x in a.x as i64..b.x as i64 {
                            cells.insert(mv_cell_from_yup([x, y, z]), (vox.color, material));
                        }
                    }
                }
            });
            if let Some(detail) = failure {
                return Err(object_error(o, detail));
            }
            frames.push(cells);
        }
        per_object_cells.push((o.name.clone(), frames));
    }
    if material_names.len() > 256 {
        return Err(VoxError::Object {
            path: path.to_owned(),
            object: "(all)".into(),
            detail: format!(
                "{} material names; .vox holds at most 256",
                material_names.len()
            ),
        });
    }

    let mut counts: HashMap<([u8; 4], u16), u64> = HashMap::new();
    for cells in per_object_cells.iter().flat_map(|(_, frames)| frames) {
        for key in cells.values() {
            *counts.entry(*key).or_insert(0) += 1;
        }
    }
    let mut keys: Vec<(([u8; 4], u16), u64)> = counts.into_iter().collect();
    keys.sort_unstable();
    let kept = model_palette(&chosen).and_then(|order| palette_in_order(order, &keys));
    let retained = kept.is_some();
    let palette = kept.unwrap_or_else(|| build_palette(&keys));
    report.distinct_colors = keys.len();
    report.palette_colors = if retained {
        palette
            .index
            .values()
            .collect::<std::collections::HashSet<_>>()
            .len()
    } else {
        palette.entries.len()
    };
    report.exact_colors = palette.exact;
    report.max_channel_error = palette.max_channel_error;

    // Split each object into ≤ 256³ blocks of its MagicaVoxel-space bounding box; a block
    // whose voxels equal a model already written (under one of the 48 grid rotations) places
    // that model again instead of writing a copy, as MagicaVoxel does for instances.
    let edge = i64::from(MAX_MODEL_EDGE);
    let mut table = ModelTable::default();
    let mut placements: Vec<Placement> = Vec::new();
    for (name, frames) in &per_object_cells {
        if frames.len() > 1 {
            placements.push(animated_placement(
                name,
                frames,
                &palette,
                &mut table,
                &mut report,
                path,
            )?);
            continue;
        }
        let Some(cells) = frames.first() else {
            continue;
        };
        let lo = cells
            .keys()
            .fold([i64::MAX; 3], |m, c| [0, 1, 2].map(|a| m[a].min(c[a])));
        let mut blocks: BTreeMap<[i64; 3], Vec<[u8; 4]>> = BTreeMap::new();
        for (c, key) in cells {
            let rel = [0, 1, 2].map(|a| c[a] - lo[a]);
            let block = rel.map(|r| r.div_euclid(edge));
            let local = rel.map(|r| r.rem_euclid(edge) as u8);
            let index = palette.index.get(key).copied().unwrap_or(0);
            blocks
                .entry(block)
                .or_default()
                .push([local[0], local[1], local[2], index + 1]);
        }
        let parts = blocks.len();
        for (part, (block, voxels)) in blocks.into_iter().enumerate() {
            let block_min = [0, 1, 2].map(|a| lo[a] + block[a] * edge);
            let label = if parts == 1 {
                name.clone()
            } else {
                format!("{name} (part {} of {parts})", part + 1)
            };
            report.voxels += voxels.len() as u64;
            let key = table.place(voxels, block_min);
            check_translation(&key, name, path)?;
            placements.push(Placement {
                name: label,
                keys: vec![key],
            });
        }
    }
    report.models = table.models.len();
    report.placements = placements.len();

    let mut main = Vec::new();
    for m in &table.models {
        let mut c = Vec::with_capacity(12);
        for s in m.size {
            c.extend_from_slice(&s.to_le_bytes());
        }
        write_chunk(&mut main, b"SIZE", &c);
        let mut c = Vec::with_capacity(4 + m.voxels.len() * 4);
        c.extend_from_slice(&(m.voxels.len() as u32).to_le_bytes());
        for v in &m.voxels {
            c.extend_from_slice(v);
        }
        write_chunk(&mut main, b"XYZI", &c);
    }
    // Scene graph: root nTRN (0) → nGRP (1) → per placement nTRN (2 + 2k) → nSHP (3 + 2k).
    write_transform(&mut main, 0, &[], 1, u32::MAX, &[]);
    let mut group = Vec::new();
    group.extend_from_slice(&1u32.to_le_bytes());
    write_dict(&mut group, &[]);
    group.extend_from_slice(&(placements.len() as u32).to_le_bytes());
    for k in 0..placements.len() {
        group.extend_from_slice(&(2 + 2 * k as u32).to_le_bytes());
    }
    write_chunk(&mut main, b"nGRP", &group);
    for (k, placement) in placements.iter().enumerate() {
        let id = 2 + 2 * k as u32;
        write_placement(&mut main, id, placement);
    }
    let mut layer = Vec::new();
    layer.extend_from_slice(&0u32.to_le_bytes());
    write_dict(&mut layer, &[]);
    layer.extend_from_slice(&u32::MAX.to_le_bytes());
    write_chunk(&mut main, b"LAYR", &layer);
    let mut rgba = Vec::with_capacity(1024);
    for i in 0..256 {
        let c = palette.entries.get(i).map_or([0, 0, 0, 255], |e| e.0);
        rgba.extend_from_slice(&if i == 255 { [0; 4] } else { c });
    }
    write_chunk(&mut main, b"RGBA", &rgba);
    for (i, (_, material)) in palette.entries.iter().enumerate() {
        let name = &material_names[usize::from(*material)];
        if name == "diffuse" {
            continue;
        }
        let mut c = Vec::new();
        c.extend_from_slice(&(i as u32 + 1).to_le_bytes());
        let ty = format!("_{name}");
        write_dict(&mut c, &[("_type", &ty)]);
        write_chunk(&mut main, b"MATL", &c);
    }

    let mut out = Vec::with_capacity(20 + main.len());
    out.extend_from_slice(b"VOX ");
    out.extend_from_slice(&150u32.to_le_bytes());
    out.extend_from_slice(b"MAIN");
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&(main.len() as u32).to_le_bytes());
    out.extend_from_slice(&main);
    Ok((out, report))
}

/// `_t` with the model's voxels around it within ±[`MAX_COORD`], where the importer (and
/// MagicaVoxel's float positions) stay exact: what is written can be read back.
fn check_translation(key: &Keyframe, name: &str, path: &Path) -> Result<(), VoxError> {
    let reach = i64::from(MAX_MODEL_EDGE);
    if key
        .translation
        .iter()
        .any(|t| t.saturating_abs().saturating_add(reach) > MAX_COORD)
    {
        return Err(VoxError::Object {
            path: path.to_owned(),
            object: name.to_owned(),
            detail: format!(
                "translation {:?} voxels would place voxels beyond ±{MAX_COORD}, where .vox \
                 positions stop being exact and readers (Thicket's included) refuse them; move \
                 the object nearer the origin or export with a larger grid unit (--grid-unit)",
                key.translation
            ),
        });
    }
    Ok(())
}

/// An animated object as one placement with a keyframe per frame (MagicaVoxel 0.99.7's
/// layout). Each frame must fit one model (256³); an empty frame is refused, since a shape's
/// frame must name a model.
fn animated_placement(
    name: &str,
    frames: &[CellMap],
    palette: &Palette,
    table: &mut ModelTable,
    report: &mut VoxExportReport,
    path: &Path,
) -> Result<Placement, VoxError> {
    let object_error = |detail: String| VoxError::Object {
        path: path.to_owned(),
        object: name.to_owned(),
        detail,
    };
    let edge = i64::from(MAX_MODEL_EDGE);
    let mut keys = Vec::with_capacity(frames.len());
    for (f, cells) in frames.iter().enumerate() {
        if cells.is_empty() {
            return Err(object_error(format!(
                "frame {f} of {} is empty; a .vox animation frame needs at least one voxel",
                frames.len()
            )));
        }
        let lo = cells
            .keys()
            .fold([i64::MAX; 3], |m, c| [0, 1, 2].map(|a| m[a].min(c[a])));
        let hi = cells
            .keys()
            .fold([i64::MIN; 3], |m, c| [0, 1, 2].map(|a| m[a].max(c[a])));
        if (0..3).any(|a| hi[a] - lo[a] >= edge) {
            return Err(object_error(format!(
                "frame {f} spans {}×{}×{} voxels; an animation frame must fit one \
                 {MAX_MODEL_EDGE}³ model",
                hi[0] - lo[0] + 1,
                hi[1] - lo[1] + 1,
                hi[2] - lo[2] + 1
            )));
        }
        let voxels: Vec<[u8; 4]> = cells
            .iter()
            .map(|(c, key)| {
                let index = palette.index.get(key).copied().unwrap_or(0);
                let l = [0, 1, 2].map(|a| (c[a] - lo[a]) as u8);
                [l[0], l[1], l[2], index + 1]
            })
            .collect();
        report.voxels += voxels.len() as u64;
        let mut key = table.place(voxels, lo);
        key.frame = f as u32;
        check_translation(&key, name, path)?;
        keys.push(key);
    }
    Ok(Placement {
        name: name.to_owned(),
        keys,
    })
}

/// Writes a transform node whose frames are `frames` (each a frame dictionary; none: one
/// empty frame).
fn write_transform(
    out: &mut Vec<u8>,
    id: u32,
    attributes: &[(&str, &str)],
    child: u32,
    layer: u32,
    frames: &[Vec<(&str, String)>],
) {
    let mut c = Vec::new();
    c.extend_from_slice(&id.to_le_bytes());
    write_dict(&mut c, attributes);
    c.extend_from_slice(&child.to_le_bytes());
    c.extend_from_slice(&u32::MAX.to_le_bytes());
    c.extend_from_slice(&layer.to_le_bytes());
    c.extend_from_slice(&(frames.len().max(1) as u32).to_le_bytes());
    if frames.is_empty() {
        write_dict(&mut c, &[]);
    }
    for f in frames {
        let entries: Vec<(&str, &str)> = f.iter().map(|(k, v)| (*k, v.as_str())).collect();
        write_dict(&mut c, &entries);
    }
    write_chunk(out, b"nTRN", &c);
}

/// Writes a placement as a transform node `id` and its shape node `id + 1`. A placement with
/// one key is static (no `_f`); with several, the transform's frames and the shape's models
/// carry `_f`, as MagicaVoxel 0.99.7 writes an animation.
fn write_placement(out: &mut Vec<u8>, id: u32, placement: &Placement) {
    let animated = placement.keys.len() > 1;
    let frames: Vec<Vec<(&str, String)>> = placement
        .keys
        .iter()
        .map(|k| {
            let mut f = Vec::new();
            if animated {
                f.push(("_f", k.frame.to_string()));
            }
            if k.rotation != IDENTITY_ROTATION {
                f.push(("_r", k.rotation.to_string()));
            }
            let t = k.translation;
            f.push(("_t", format!("{} {} {}", t[0], t[1], t[2])));
            f
        })
        .collect();
    write_transform(out, id, &[("_name", &placement.name)], id + 1, 0, &frames);
    let mut shape = Vec::new();
    shape.extend_from_slice(&(id + 1).to_le_bytes());
    write_dict(&mut shape, &[]);
    shape.extend_from_slice(&(placement.keys.len() as u32).to_le_bytes());
    for k in &placement.keys {
        shape.extend_from_slice(&(k.model as u32).to_le_bytes());
        if animated {
            write_dict(&mut shape, &[("_f", &k.frame.to_string())]);
        } else {
            write_dict(&mut shape, &[]);
        }
    }
    write_chunk(out, b"nSHP", &shape);
}

/// The rotation byte of the identity (`_r` is then omitted).
const IDENTITY_ROTATION: u8 = 4;

/// A model as written: its size and voxels `[x, y, z, file colour index]`, sorted, with at
/// least one voxel at 0 on each axis.
#[derive(Debug, Clone, PartialEq, Eq)]
struct FileModel {
    size: [u32; 3],
    voxels: Vec<[u8; 4]>,
}

impl FileModel {
    /// A model from voxels in any order and position within a 256³ block; also returns the
    /// shift that moved the voxels' minimum to 0.
    fn normalised(mut voxels: Vec<[u8; 4]>) -> (Self, [u8; 3]) {
        let min = [0, 1, 2].map(|a| voxels.iter().map(|v| v[a]).min().unwrap_or(0));
        for v in &mut voxels {
            for a in 0..3 {
                v[a] -= min[a];
            }
        }
        voxels.sort_unstable();
        let size = [0, 1, 2].map(|a| u32::from(voxels.iter().map(|v| v[a]).max().unwrap_or(0)) + 1);
        (Self { size, voxels }, min)
    }

    /// The model turned by rotation `r` as import places it (voxel `v` centred at
    /// `R · (v + ½ − floor(size / 2))`), normalised; also the smallest doubled centre
    /// coordinate per axis, which locates the turned voxels.
    fn rotated(&self, r: &IMat3) -> (Vec<[u8; 4]>, [i64; 3]) {
        let pivot = self.size.map(|s| i64::from(s / 2));
        let centres: Vec<([i64; 3], u8)> = self
            .voxels
            .iter()
            .map(|v| {
                let c2 = [0, 1, 2].map(|a| 2 * (i64::from(v[a]) - pivot[a]) + 1);
                (imat_apply(r, c2), v[3])
            })
            .collect();
        let min = centres
            .iter()
            .fold([i64::MAX; 3], |m, (c, _)| [0, 1, 2].map(|a| m[a].min(c[a])));
        // Centres are odd, so differences are even; within a 256³ model they fit a byte.
        let mut out: Vec<[u8; 4]> = centres
            .iter()
            .map(|(c, i)| {
                let n = [0, 1, 2].map(|a| ((c[a] - min[a]) / 2) as u8);
                [n[0], n[1], n[2], *i]
            })
            .collect();
        out.sort_unstable();
        (out, min)
    }

    /// What equal models (under any rotation) share: voxel count, sorted edges, and an
    /// order-free hash of each voxel's colour with the sorted distances of its centre from the
    /// box centre (a turn permutes and negates those coordinates), so distinct shapes almost
    /// never meet in one bucket and the 48-way comparison runs only for true copies.
    fn invariant(&self) -> (usize, [u32; 3], u64) {
        let mut edges = self.size;
        edges.sort_unstable();
        let size = self.size.map(i64::from);
        let shape = self.voxels.iter().fold(0u64, |acc, v| {
            let mut d = [0, 1, 2].map(|a| (2 * i64::from(v[a]) + 1 - size[a]).unsigned_abs());
            d.sort_unstable();
            let key = d[0] | (d[1] << 9) | (d[2] << 18) | (u64::from(v[3]) << 27);
            acc.wrapping_add(mix64(key))
        });
        (self.voxels.len(), edges, shape)
    }
}

/// splitmix64's finaliser: spreads the bits of `x` (for an order-free sum of hashes).
fn mix64(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

/// One frame of a placement: which model, turned and moved how.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Keyframe {
    /// Frame index (`_f`).
    frame: u32,
    /// Index of the model in the file.
    model: usize,
    /// `_t`: where the model's pivot lands.
    translation: [i64; 3],
    /// `_r`, [`IDENTITY_ROTATION`] for none.
    rotation: u8,
}

/// One `nTRN` → `nSHP` pair.
struct Placement {
    name: String,
    keys: Vec<Keyframe>,
}

/// The models an export writes, each once, and an index to find a block's equal among them.
#[derive(Default)]
struct ModelTable {
    models: Vec<FileModel>,
    by_invariant: HashMap<(usize, [u32; 3], u64), Vec<usize>>,
}

impl ModelTable {
    /// Places a block's voxels (`[x, y, z, index]` relative to `block_min`, a MagicaVoxel cell):
    /// reuses a written model that some rotation turns into them, or adds them as a new model.
    /// Returns the keyframe (frame 0) that puts them back where they were.
    fn place(&mut self, voxels: Vec<[u8; 4]>, block_min: [i64; 3]) -> Keyframe {
        let (model, shift) = FileModel::normalised(voxels);
        let at = [0, 1, 2].map(|a| block_min[a] + i64::from(shift[a]));
        let invariant = model.invariant();
        let candidates = self.by_invariant.entry(invariant).or_default();
        for &k in candidates.iter() {
            let existing = &self.models[k];
            for byte in rotation_bytes() {
                let Some(r) = decode_rotation(byte) else {
                    continue;
                };
                let (turned, min2) = existing.rotated(&r);
                if turned == model.voxels {
                    // Import puts the turned voxel with the smallest doubled centre `min2` at
                    // cell `(min2 + 2T - 1) / 2`, which must be `at`.
                    return Keyframe {
                        frame: 0,
                        model: k,
                        translation: [0, 1, 2].map(|a| (2 * at[a] + 1 - min2[a]) / 2),
                        rotation: byte,
                    };
                }
            }
        }
        let k = self.models.len();
        candidates.push(k);
        let translation = [0, 1, 2].map(|a| at[a] + i64::from(model.size[a] / 2));
        self.models.push(model);
        Keyframe {
            frame: 0,
            model: k,
            translation,
            rotation: IDENTITY_ROTATION,
        }
    }
}

/// The 48 valid rotation bytes, identity first.
fn rotation_bytes() -> impl Iterator<Item = u8> {
    std::iter::once(IDENTITY_ROTATION)
        .chain((0u8..128).filter(|&b| b != IDENTITY_ROTATION && decode_rotation(b).is_some()))
}

/// A palette of at most 255 (colour, material) entries and where each input key went.
pub(crate) struct Palette {
    pub(crate) entries: Vec<([u8; 4], u16)>,
    /// Input key → 0-based entry.
    pub(crate) index: HashMap<([u8; 4], u16), u8>,
    pub(crate) exact: bool,
    pub(crate) max_channel_error: u8,
}

/// The palette shared by every exported model that has one (an imported `.vox`'s, or the
/// artist's); None when there is none or two models disagree.
fn model_palette<'a>(chosen: &[(&Object, &'a VoxelModel)]) -> Option<&'a [[u8; 4]]> {
    let mut found: Option<&'a [[u8; 4]]> = None;
    for (_, v) in chosen {
        if v.palette.is_empty() {
            continue;
        }
        match found {
            None => found = Some(&v.palette),
            Some(p) if p == v.palette.as_slice() => {}
            Some(_) => return None,
        }
    }
    found
}

/// The model's palette in its own order (its first 255 entries) when every exported colour is
/// in it and no colour is used with two materials, so import → export keeps every voxel's
/// index. A colour listed twice maps to its first entry. Unused entries keep their colour with
/// the default material.
pub(crate) fn palette_in_order(
    order: &[[u8; 4]],
    keys: &[(([u8; 4], u16), u64)],
) -> Option<Palette> {
    let order = &order[..order.len().min(255)];
    let mut material: Vec<Option<u16>> = vec![None; order.len()];
    let mut index = HashMap::with_capacity(keys.len());
    for ((c, m), _) in keys {
        let i = order.iter().position(|e| e == c)?;
        match material[i] {
            Some(x) if x != *m => return None,
            _ => material[i] = Some(*m),
        }
        index.insert((*c, *m), i as u8);
    }
    Some(Palette {
        entries: order
            .iter()
            .zip(&material)
            .map(|(c, m)| (*c, m.unwrap_or(0)))
            .collect(),
        index,
        exact: true,
        max_channel_error: 0,
    })
}

/// Exact when there are at most 255 keys; otherwise a weighted median cut on RGBA to 255 boxes
/// (deterministic: keys arrive sorted, ties break toward the first box and lower values), each
/// key mapped to the nearest box mean and each entry given its keys' most common material.
pub(crate) fn build_palette(keys: &[(([u8; 4], u16), u64)]) -> Palette {
    if keys.len() <= 255 {
        return Palette {
            entries: keys.iter().map(|k| k.0).collect(),
            index: keys
                .iter()
                .enumerate()
                .map(|(i, k)| (k.0, i as u8))
                .collect(),
            exact: true,
            max_channel_error: 0,
        };
    }
    let mut colours: BTreeMap<[u8; 4], u64> = BTreeMap::new();
    for ((c, _), n) in keys {
        *colours.entry(*c).or_insert(0) += n;
    }
    let mut boxes: Vec<Vec<([u8; 4], u64)>> = vec![colours.into_iter().collect()];
    let widest = |b: &[([u8; 4], u64)]| -> (u8, usize) {
        let mut best = (0u8, 0usize);
        for ch in 0..4 {
            let lo = b.iter().map(|e| e.0[ch]).min().unwrap_or(0);
            let hi = b.iter().map(|e| e.0[ch]).max().unwrap_or(0);
            if hi - lo > best.0 {
                best = (hi - lo, ch);
            }
        }
        best
    };
    while boxes.len() < 255 {
        let mut pick: Option<(usize, u8, usize)> = None;
        for (i, b) in boxes.iter().enumerate() {
            if b.len() < 2 {
                continue;
            }
            let (range, ch) = widest(b);
            if pick.is_none_or(|p| range > p.1) {
                pick = Some((i, range, ch));
            }
        }
        let Some((i, _, ch)) = pick else { break };
        let mut b = std::mem::take(&mut boxes[i]);
        b.sort_unstable_by_key(|e| (e.0[ch], e.0));
        let total: u64 = b.iter().map(|e| e.1).sum();
        let mut acc = 0u64;
        let mut split = 1;
        for (k, e) in b.iter().enumerate() {
            acc += e.1;
            if acc * 2 >= total {
                split = k + 1;
                break;
            }
        }
        let split = split.clamp(1, b.len() - 1);
        let upper = b.split_off(split);
        boxes[i] = b;
        boxes.push(upper);
    }
    let means: Vec<[u8; 4]> = boxes
        .iter()
        .map(|b| {
            let total: u64 = b.iter().map(|e| e.1).sum::<u64>().max(1);
            [0, 1, 2, 3].map(|ch| {
                let s: u64 = b.iter().map(|e| u64::from(e.0[ch]) * e.1).sum();
                ((s + total / 2) / total).min(255) as u8
            })
        })
        .collect();
    let nearest = |c: [u8; 4]| -> usize {
        let mut best = (u32::MAX, 0usize);
        for (i, m) in means.iter().enumerate() {
            let d: u32 = (0..4)
                .map(|ch| (i32::from(c[ch]) - i32::from(m[ch])).unsigned_abs().pow(2))
                .sum();
            if d < best.0 {
                best = (d, i);
            }
        }
        best.1
    };
    let mut index = HashMap::with_capacity(keys.len());
    let mut votes: Vec<BTreeMap<u16, u64>> = vec![BTreeMap::new(); means.len()];
    let mut max_err = 0u8;
    for ((c, m), n) in keys {
        let e = nearest(*c);
        index.insert((*c, *m), e as u8);
        *votes[e].entry(*m).or_insert(0) += n;
        for ch in 0..4 {
            max_err = max_err.max(c[ch].abs_diff(means[e][ch]));
        }
    }
    let entries = means
        .iter()
        .zip(&votes)
        .map(|(c, v)| {
            // Most common material; ties toward the lower id (BTreeMap order, strict >).
            let mut best = (0u16, 0u64);
            for (&m, &n) in v {
                if n > best.1 {
                    best = (m, n);
                }
            }
            (*c, best.0)
        })
        .collect();
    Palette {
        entries,
        index,
        exact: false,
        max_channel_error: max_err,
    }
}

/// Writes `bytes` to a temporary sibling, syncs it, renames it over `path` and syncs the
/// directory, so `path` is either the old file or the complete new one. The temporary file is
/// removed on failure.
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), VoxError> {
    let io = |action, source| VoxError::Io {
        path: path.to_owned(),
        action,
        source,
    };
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf);
    let file_name = path
        .file_name()
        .map_or_else(|| "export.vox".into(), |n| n.to_string_lossy().into_owned());
    let tmp = dir.join(format!(".{file_name}.tmp-{}", std::process::id()));
    let result = (|| {
        let mut f =
            std::fs::File::create(&tmp).map_err(|e| io("creating the temporary file", e))?;
        f.write_all(bytes)
            .map_err(|e| io("writing the temporary file", e))?;
        f.sync_all()
            .map_err(|e| io("syncing the temporary file", e))?;
        drop(f);
        std::fs::rename(&tmp, path).map_err(|e| io("renaming the temporary file", e))
    })();
    if result.is_err() {
        // Best effort: the error that matters is the one returned.
        let _ = std::fs::remove_file(&tmp);
        return result;
    }
    // Make the rename durable; not every platform can open a directory, which is harmless.
    if let Ok(d) = std::fs::File::open(&dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

#[cfg(test)]
mod palette_tests {
    use std::path::Path;

    use glam::{UVec3, Vec3};

    use super::super::{VoxImportOptions, import_vox_bytes};
    use super::*;
    use crate::svo::{Svo, Voxel};

    fn raw_indices(bytes: &[u8]) -> (Vec<u32>, Vec<u8>) {
        let d = dot_vox::load_bytes(bytes).unwrap();
        let palette = d
            .palette
            .iter()
            .flat_map(|c| [c.r, c.g, c.b, c.a])
            .collect();
        let mut idx: Vec<u32> = d
            .models
            .iter()
            .flat_map(|m| m.voxels.iter().map(|v| u32::from(v.i)))
            .collect();
        idx.sort_unstable();
        (idx, palette)
    }

    fn export(objects: &[Object]) -> Vec<u8> {
        export_vox_bytes(objects, Path::new("mem.vox"), &VoxExportOptions::default())
            .unwrap()
            .0
    }

    fn import(bytes: &[u8]) -> Vec<Object> {
        import_vox_bytes(bytes, Path::new("mem.vox"), &VoxImportOptions::default())
            .unwrap()
            .objects
    }

    #[test]
    fn a_models_palette_order_survives_export_and_import() {
        // 255 distinct colours in a scrambled order; the voxels use three of them.
        let palette: Vec<[u8; 4]> = (0..255u32)
            .map(|i| {
                let k = (i * 97) % 255;
                [k as u8, (k * 3) as u8, (255 - k) as u8, 255]
            })
            .collect();
        let used = [palette[200], palette[3], palette[77]];
        let voxels = used
            .iter()
            .enumerate()
            .map(|(i, &c)| (UVec3::new(i as u32, 0, 0), Voxel::new(c, Vec3::Y)));
        let obj = Object {
            name: "m".into(),
            kind: ObjectKind::Voxels(VoxelModel {
                svo: Svo::from_voxels(3, false, voxels).unwrap(),
                palette: palette.clone(),
                ..VoxelModel::default()
            }),
            ..Object::default()
        };
        let (bytes, report) = export_vox_bytes(
            std::slice::from_ref(&obj),
            Path::new("mem.vox"),
            &VoxExportOptions::default(),
        )
        .unwrap();
        assert_eq!(report.palette_colors, 3);
        assert!(report.exact_colors);
        let (idx, _) = raw_indices(&bytes);
        // Every voxel's file index is its colour's position in the model palette (1-based in
        // the file; dot_vox reports it 0-based).
        let mut expect = vec![200u32, 3, 77];
        expect.sort_unstable();
        let zero_based = expect.clone();
        let one_based: Vec<u32> = expect.iter().map(|i| i + 1).collect();
        assert!(idx == zero_based || idx == one_based, "{idx:?}");
        let back = import(&bytes);
        let ObjectKind::Voxels(m) = &back[0].kind else {
            panic!("a voxel object")
        };
        assert_eq!(m.palette, palette);
        // Without a palette the colours are packed from index 1 as before.
        let mut plain = obj;
        if let ObjectKind::Voxels(m) = &mut plain.kind {
            m.palette.clear();
        }
        let (idx, _) = raw_indices(&export(&[plain.clone()]));
        assert!(idx.iter().all(|&i| i <= 3), "{idx:?}");
        // A colour missing from the palette: the packed palette is used instead.
        if let ObjectKind::Voxels(m) = &mut plain.kind {
            m.palette = palette[..100].to_vec();
        }
        let (idx, _) = raw_indices(&export(&[plain]));
        assert!(idx.iter().all(|&i| i <= 3), "{idx:?}");
    }

    #[test]
    fn import_then_export_keeps_the_file_palette_and_indices() {
        for rel in [
            "mmmm/chr_army1.vox",
            "mmmm/obj_house4.vox",
            "dot_vox/placeholder.vox",
        ] {
            let path = format!(
                "{}/../../shared/assets/vox/{rel}",
                env!("CARGO_MANIFEST_DIR")
            );
            let original = std::fs::read(&path).unwrap();
            let objects = import(&original);
            let ObjectKind::Voxels(m) = &objects[0].kind else {
                panic!("a voxel object")
            };
            assert_eq!(m.palette.len(), 255, "{rel}");
            let again = export(&objects);
            let (a_idx, a_pal) = raw_indices(&original);
            let (b_idx, b_pal) = raw_indices(&again);
            assert_eq!(a_pal[..255 * 4], b_pal[..255 * 4], "{rel}: palette order");
            assert_eq!(a_idx, b_idx, "{rel}: voxel indices");
        }
    }
}
