//! What a glTF file holds that an import leaves out, one line per kind of feature, so that
//! nothing is dropped silently: the CLI prints the lines as warnings and the editor shows them
//! in its import report.
//!
//! Reads only the deserialized JSON (every index through `get`), so it cannot fail or panic on
//! any file the readers accept.

use std::collections::BTreeMap;

use gltf::json;
use gltf::json::animation::Property;
use gltf::json::mesh::{Mode, Semantic};
use gltf::json::validation::Checked;

/// Which importer reads the file: they carry over different things.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Reader {
    /// The static mesh reader ([`super::gltf_mesh`]): no animation at all.
    Static,
    /// The skinned reader (`crate::skin`): joint animation is carried over; its own warnings
    /// name the channels it skips.
    Skinned,
}

/// Extensions whose effect the importers carry over, or that hold only metadata (XMP), which
/// changes nothing an import reads.
const CARRIED_EXTENSIONS: &[&str] = &[
    "KHR_materials_unlit",
    "KHR_mesh_quantization",
    "KHR_xmp",
    "KHR_xmp_json_ld",
    super::gltf_instancing::INSTANCING,
    // Its own line says what is kept.
    super::gltf_instancing::LOD,
];

/// Lines naming what `root` holds that `reader` does not import, with counts and where it is.
/// Empty when everything is carried over.
pub(crate) fn dropped_features(root: &json::Root, reader: Reader) -> Vec<String> {
    let mut out = Vec::new();
    let mesh_name = |i: usize| {
        root.meshes
            .get(i)
            .and_then(|m| m.name.clone())
            .unwrap_or_else(|| format!("mesh {i}"))
    };

    // Morph targets, per mesh.
    let mut morphs: Vec<(String, usize)> = Vec::new();
    let mut lines_points = 0usize;
    let mut extra_uv: BTreeMap<u32, usize> = BTreeMap::new();
    let mut extra_colors = 0usize;
    let mut extra_influences = 0usize;
    for (mi, mesh) in root.meshes.iter().enumerate() {
        let targets = mesh
            .primitives
            .iter()
            .map(|p| p.targets.as_ref().map_or(0, Vec::len))
            .max()
            .unwrap_or(0);
        if targets > 0 {
            morphs.push((mesh_name(mi), targets));
        }
        for p in &mesh.primitives {
            if matches!(
                p.mode,
                Checked::Valid(Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip)
            ) {
                lines_points += 1;
            }
            let uv_used = p
                .material
                .and_then(|m| root.materials.get(m.value()))
                .and_then(|m| m.pbr_metallic_roughness.base_color_texture.as_ref())
                .map_or(0, |t| t.tex_coord);
            for semantic in p.attributes.keys() {
                match semantic {
                    Checked::Valid(Semantic::TexCoords(n)) if *n != uv_used => {
                        *extra_uv.entry(*n).or_default() += 1;
                    }
                    Checked::Valid(Semantic::Colors(n)) if *n > 0 => extra_colors += 1,
                    Checked::Valid(Semantic::Joints(n) | Semantic::Weights(n)) if *n > 0 => {
                        extra_influences += 1;
                    }
                    _ => {}
                }
            }
        }
    }
    if !morphs.is_empty() {
        let total: usize = morphs.iter().map(|m| m.1).sum();
        out.push(format!(
            "{total} morph target(s) on {} mesh(es) ({}): not imported, the base shape is used",
            morphs.len(),
            list(morphs.iter().map(|(n, k)| format!("{n:?} ×{k}")))
        ));
    }
    // The skinned reader names each such primitive itself.
    if lines_points > 0 && reader == Reader::Static {
        out.push(format!(
            "{lines_points} primitive(s) of points or lines: skipped (only triangles become \
             surfaces)"
        ));
    }
    if !extra_uv.is_empty() {
        out.push(format!(
            "extra UV sets ({}): not imported, only the base-colour texture's set is read",
            list(
                extra_uv
                    .iter()
                    .map(|(n, k)| format!("TEXCOORD_{n} on {k} primitive(s)"))
            )
        ));
    }
    if extra_colors > 0 {
        out.push(format!(
            "{extra_colors} extra vertex colour set(s) (COLOR_1 and up): not imported, COLOR_0 \
             is used"
        ));
    }
    if extra_influences > 0 {
        out.push(format!(
            "{extra_influences} extra joint influence set(s) (JOINTS_1/WEIGHTS_1 and up): not \
             imported, the 4 influences of JOINTS_0/WEIGHTS_0 are used"
        ));
    }

    // Texture maps other than base colour: a voxel stores one colour.
    let mut maps: BTreeMap<&str, usize> = BTreeMap::new();
    for m in &root.materials {
        let present = [
            ("normal", m.normal_texture.is_some()),
            ("occlusion", m.occlusion_texture.is_some()),
            ("emissive", m.emissive_texture.is_some()),
            (
                "metallic-roughness",
                m.pbr_metallic_roughness
                    .metallic_roughness_texture
                    .is_some(),
            ),
        ];
        for (name, _) in present.into_iter().filter(|p| p.1) {
            *maps.entry(name).or_default() += 1;
        }
    }
    if !maps.is_empty() {
        out.push(format!(
            "texture maps other than base colour ({}): not imported, a voxel or imported mesh \
             keeps only its base colour",
            list(maps.iter().map(|(n, k)| format!("{n} ×{k}")))
        ));
    }

    // Animation: all of it for the static reader; the skinned reader's own warnings name the
    // channels it skips, but morph-weight channels are counted here with the morph targets.
    let channels: usize = root.animations.iter().map(|a| a.channels.len()).sum();
    if reader == Reader::Static && channels > 0 {
        let names = root
            .animations
            .iter()
            .enumerate()
            .map(|(i, a)| a.name.clone().unwrap_or_else(|| format!("animation {i}")));
        out.push(format!(
            "{} animation(s) with {channels} channel(s) ({}): not imported by the static mesh \
             reader (a skinned file's joint animation is imported with its skin)",
            root.animations.len(),
            list(names.map(|n| format!("{n:?}")))
        ));
    } else if reader == Reader::Skinned {
        let morph_channels = root
            .animations
            .iter()
            .flat_map(|a| &a.channels)
            .filter(|c| matches!(c.target.path, Checked::Valid(Property::MorphTargetWeights)))
            .count();
        if morph_channels > 0 {
            out.push(format!(
                "{morph_channels} animation channel(s) drive morph target weights: not imported"
            ));
        }
    }

    out.extend(super::gltf_instancing::level_of_detail_note(root));

    // Cameras and lights are imported where they can be: `super::gltf_view` says what.
    let ignored: Vec<&String> = root
        .extensions_used
        .iter()
        .filter(|e| !CARRIED_EXTENSIONS.contains(&e.as_str()) && *e != "KHR_lights_punctual")
        .collect();
    if !ignored.is_empty() {
        out.push(format!(
            "extension(s) not supported, ignored: {}",
            list(ignored.iter().map(ToString::to_string))
        ));
    }
    out
}

/// Up to six items joined by commas, then how many more.
fn list(items: impl Iterator<Item = String>) -> String {
    const SHOWN: usize = 6;
    let items: Vec<String> = items.collect();
    let mut s = items
        .iter()
        .take(SHOWN)
        .cloned()
        .collect::<Vec<_>>()
        .join(", ");
    if items.len() > SHOWN {
        s.push_str(&format!(" and {} more", items.len() - SHOWN));
    }
    s
}
