//! Objects → `.vox`: world grid, splitting into ≤ 256³ models, palette quantisation, chunks,
//! atomic write.

use std::collections::{BTreeMap, HashMap};
use std::io::Write;
use std::path::{Path, PathBuf};

use glam::{DMat4, DVec3};

use super::chunks::{write_chunk, write_dict};
use super::{MAX_MODEL_EDGE, VoxError, mv_cell_from_yup};
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
    /// Models written (objects larger than 256 in a dimension become several).
    pub models: usize,
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
    let mut chosen = Vec::new();
    for o in objects {
        match &o.kind {
            ObjectKind::Voxels(v) if o.visible && !v.svo.is_empty() => {
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
            _ => report.skipped.push(o.name.clone()),
        }
    }
    if chosen.is_empty() {
        return Err(VoxError::NothingToExport {
            path: path.to_owned(),
        });
    }
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

    // Global material table: name → index, "diffuse" = 0.
    let mut material_names: Vec<String> = vec!["diffuse".into()];
    let mut per_object_cells: Vec<(String, CellMap)> = Vec::new();
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
        let grid_from_voxel = DMat4::from_scale(DVec3::splat(1.0 / unit))
            * o.transform.matrix().as_dmat4()
            * v.object_from_voxel().as_dmat4();
        let mut cells = CellMap::new();
        let mut failure = None;
        v.svo.for_each_leaf(|c, vox| {
            if failure.is_some() {
                return;
            }
            let base = c.as_dvec3();
            let mut lo = DVec3::INFINITY;
            let mut hi = DVec3::NEG_INFINITY;
            for k in 0..8u32 {
                let corner =
                    base + DVec3::new(f64::from(k & 1), f64::from((k >> 1) & 1), f64::from(k >> 2));
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
        per_object_cells.push((o.name.clone(), cells));
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
    for (_, cells) in &per_object_cells {
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

    // Split each object into ≤ 256³ blocks of its MagicaVoxel-space bounding box.
    let edge = i64::from(MAX_MODEL_EDGE);
    let mut models: Vec<([u32; 3], Vec<[u8; 4]>)> = Vec::new();
    let mut placements: Vec<(String, [i64; 3], usize)> = Vec::new();
    for (name, cells) in &per_object_cells {
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
        for (part, (block, mut voxels)) in blocks.into_iter().enumerate() {
            voxels.sort_unstable();
            let size =
                [0, 1, 2].map(|a| u32::from(voxels.iter().map(|v| v[a]).max().unwrap_or(0)) + 1);
            let block_min = [0, 1, 2].map(|a| lo[a] + block[a] * edge);
            // Import places voxel v at pivot + (v - floor(size / 2)); choose the pivot so that
            // voxel (0,0,0) lands on block_min.
            let translation = [0, 1, 2].map(|a| block_min[a] + i64::from(size[a] / 2));
            if translation.iter().any(|t| i32::try_from(*t).is_err()) {
                return Err(VoxError::Object {
                    path: path.to_owned(),
                    object: name.clone(),
                    detail: format!("translation {translation:?} does not fit .vox's 32-bit range"),
                });
            }
            let label = if parts == 1 {
                name.clone()
            } else {
                format!("{name} (part {} of {parts})", part + 1)
            };
            report.voxels += voxels.len() as u64;
            placements.push((label, translation, models.len()));
            models.push((size, voxels));
        }
    }
    report.models = models.len();

    let mut main = Vec::new();
    for (size, voxels) in &models {
        let mut c = Vec::with_capacity(12);
        for s in size {
            c.extend_from_slice(&s.to_le_bytes());
        }
        write_chunk(&mut main, b"SIZE", &c);
        let mut c = Vec::with_capacity(4 + voxels.len() * 4);
        c.extend_from_slice(&(voxels.len() as u32).to_le_bytes());
        for v in voxels {
            c.extend_from_slice(v);
        }
        write_chunk(&mut main, b"XYZI", &c);
    }
    // Scene graph: root nTRN (0) → nGRP (1) → per model nTRN (2 + 2k) → nSHP (3 + 2k).
    write_transform(&mut main, 0, &[], 1, u32::MAX, None);
    let mut group = Vec::new();
    group.extend_from_slice(&1u32.to_le_bytes());
    write_dict(&mut group, &[]);
    group.extend_from_slice(&(placements.len() as u32).to_le_bytes());
    for k in 0..placements.len() {
        group.extend_from_slice(&(2 + 2 * k as u32).to_le_bytes());
    }
    write_chunk(&mut main, b"nGRP", &group);
    for (k, (name, t, model)) in placements.iter().enumerate() {
        let id = 2 + 2 * k as u32;
        let t = format!("{} {} {}", t[0], t[1], t[2]);
        write_transform(&mut main, id, &[("_name", name)], id + 1, 0, Some(&t));
        let mut shape = Vec::new();
        shape.extend_from_slice(&(id + 1).to_le_bytes());
        write_dict(&mut shape, &[]);
        shape.extend_from_slice(&1u32.to_le_bytes());
        shape.extend_from_slice(&(*model as u32).to_le_bytes());
        write_dict(&mut shape, &[]);
        write_chunk(&mut main, b"nSHP", &shape);
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

fn write_transform(
    out: &mut Vec<u8>,
    id: u32,
    attributes: &[(&str, &str)],
    child: u32,
    layer: u32,
    translation: Option<&str>,
) {
    let mut c = Vec::new();
    c.extend_from_slice(&id.to_le_bytes());
    write_dict(&mut c, attributes);
    c.extend_from_slice(&child.to_le_bytes());
    c.extend_from_slice(&u32::MAX.to_le_bytes());
    c.extend_from_slice(&layer.to_le_bytes());
    c.extend_from_slice(&1u32.to_le_bytes());
    match translation {
        Some(t) => write_dict(&mut c, &[("_t", t)]),
        None => write_dict(&mut c, &[]),
    }
    write_chunk(out, b"nTRN", &c);
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
