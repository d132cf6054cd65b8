//! Every file Thicket writes, Thicket reads: a property test over the fuzz corpus and the
//! samples. Each input that an import, an enhancement, a glTF export or a `.vox` export
//! accepts is written, and the written file must be read back by the reader `thicket info`
//! uses for it (project loader, glTF reader, `.vox` importer), and the document it gives must
//! validate. Mutated inputs come from the fuzz harness, so odd but accepted values (extreme
//! coordinates, degenerate triangles, stray colours) reach the writers.

use std::path::Path;

use crate::enhance::{Control, EnhanceSettings};
use crate::io::error::ImportLimits;
use crate::io::fuzz::{case_rng, mutate};
use crate::io::gltf_export::{GltfExportOptions, export_gltf};
use crate::io::vox::{VoxExportOptions, VoxImportOptions, export_vox_bytes, import_vox_bytes};
use crate::io::{gltf_mesh, obj, project};
use crate::mesh::MeshModel;
use crate::scene::{Document, MeshObject, ObjectKind, VoxelModel};
use crate::voxelize::{Resolution, VoxelizeSettings, voxelize};

const NO_PROGRESS: &dyn Fn(f32) -> bool = &|_| true;

fn asset(relative: &str) -> Vec<u8> {
    std::fs::read(
        concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/assets/").to_owned() + relative,
    )
    .expect("asset")
}

/// What each writer did with the accepted inputs.
#[derive(Debug, Default)]
struct Tally {
    imports: u64,
    gltf_exports: u64,
    vox_exports: u64,
    enhanced: u64,
    refused_by_writer: u64,
    /// The writers' refusals, label and message (printed, so the reason is seen).
    refusals: Vec<String>,
}

/// Writes `doc` as a project, a GLB and (when it has voxels) a `.vox`, and reads each back.
/// A writer may refuse (with an error, e.g. a budget); what it writes must read back.
fn write_and_read_back(doc: &Document, label: &str, dir: &Path, tally: &mut Tally) {
    doc.validate()
        .unwrap_or_else(|e| panic!("{label}: accepted input gave an invalid document: {e}"));
    let path = dir.join("rt.thicket.json");
    project::save(doc, &path).unwrap_or_else(|e| panic!("{label}: save: {e}"));
    let loaded = project::load(&path).unwrap_or_else(|e| panic!("{label}: project: {e}"));
    assert_eq!(loaded.objects.len(), doc.objects.len(), "{label}");

    let glb = dir.join("rt.glb");
    let options = GltfExportOptions {
        resolution: 24,
        ..GltfExportOptions::default()
    };
    match export_gltf(doc, &glb, &options, NO_PROGRESS) {
        Ok(report) => {
            let bytes = std::fs::read(&glb).unwrap();
            let back =
                gltf_mesh::import_gltf_slice_with(&bytes, None, &glb, &ImportLimits::default())
                    .unwrap_or_else(|e| panic!("{label}: Thicket cannot read its own glTF: {e}"));
            assert_eq!(back.triangle_count() as u64, report.triangles, "{label}");
            tally.gltf_exports += 1;
        }
        Err(e) => {
            tally.refused_by_writer += 1;
            tally.refusals.push(format!("{label}: {e}"));
        }
    }

    let has_voxels = doc
        .objects
        .iter()
        .any(|o| o.visible && matches!(&o.kind, ObjectKind::Voxels(v) if !v.svo.is_empty()));
    if has_voxels {
        let vox = Path::new("rt.vox");
        match export_vox_bytes(&doc.objects, vox, &VoxExportOptions::default()) {
            Ok((bytes, report)) => {
                let back = import_vox_bytes(&bytes, vox, &VoxImportOptions::default())
                    .unwrap_or_else(|e| panic!("{label}: Thicket cannot read its own .vox: {e}"));
                let cells: u64 = back
                    .objects
                    .iter()
                    .filter_map(|o| match &o.kind {
                        ObjectKind::Voxels(v) => Some(v.svo.leaf_count()),
                        _ => None,
                    })
                    .sum();
                assert_eq!(cells, report.voxels, "{label}: .vox cells read back");
                let mut again = Document::default();
                back.add_to(&mut again);
                again
                    .validate()
                    .unwrap_or_else(|e| panic!("{label}: its .vox reads as invalid: {e}"));
                tally.vox_exports += 1;
            }
            Err(e) => {
                tally.refused_by_writer += 1;
                tally.refusals.push(format!("{label}: {e}"));
            }
        }
    }
}

/// A mesh as `thicket import` makes a project of it (surface voxels at depth 5), and as the
/// editor keeps it (a mesh object).
fn imported(model: &MeshModel) -> Option<Document> {
    let settings = VoxelizeSettings {
        resolution: Resolution::Depth(5),
        ..VoxelizeSettings::default()
    };
    let v = voxelize(model, &settings, NO_PROGRESS).ok()?;
    let mut doc = Document::default();
    doc.add(
        "imported",
        ObjectKind::Voxels(VoxelModel {
            svo: v.svo,
            voxel_size: v.voxel_size,
            origin: v.origin,
            ..VoxelModel::default()
        }),
    );
    doc.add(
        "mesh",
        ObjectKind::Mesh(MeshObject {
            model: model.clone(),
            casts_shadows: true,
        }),
    );
    doc.validate().is_ok().then_some(doc)
}

/// The first voxel object enhanced ×2, as `thicket enhance` adds it.
fn enhanced(doc: &Document) -> Option<Document> {
    let v = doc.objects.iter().find_map(|o| match &o.kind {
        ObjectKind::Voxels(v) if !v.svo.is_empty() && v.svo.leaf_count() < 20_000 => Some(v),
        _ => None,
    })?;
    let (fine, _) = v
        .enhanced(&EnhanceSettings::default(), Control::default())
        .ok()?;
    let mut out = Document::default();
    out.add("enhanced", ObjectKind::Voxels(fine));
    Some(out)
}

#[test]
fn every_accepted_input_writes_files_thicket_reads() {
    let dir = tempfile::tempdir().unwrap();
    let mut tally = Tally::default();
    let limits = ImportLimits::default();
    // Mutated meshes that the readers accept (glTF and OBJ corpora of the fuzz targets).
    let gltf_corpus = vec![
        asset("static/Box.glb"),
        gltf_mesh::tests::textured_glb(),
        crate::io::gltf_instancing::tests::instanced_lod_glb(),
    ];
    let obj_files = obj::tests::cube_files(obj::tests::CUBE_MTL.as_bytes());
    let obj_corpus = vec![obj::tests::CUBE_OBJ.as_bytes().to_vec()];
    let cases = crate::io::fuzz::cases_from_env(10_000) / 10;
    for case in 0..cases {
        let bytes = mutate(&gltf_corpus, &mut case_rng(0x52_7470, case));
        if let Ok(model) =
            gltf_mesh::import_gltf_slice_with(&bytes, None, Path::new("m.glb"), &limits)
            && let Some(doc) = imported(&model)
        {
            tally.imports += 1;
            write_and_read_back(&doc, &format!("glTF case {case}"), dir.path(), &mut tally);
        }
        let bytes = mutate(&obj_corpus, &mut case_rng(0x52_7471, case));
        if let Ok(model) = obj::import_obj_slice_with(
            &bytes,
            &obj_files,
            Path::new("m.obj"),
            &obj::ObjOptions::default(),
            &limits,
        ) && let Some(doc) = imported(&model)
        {
            tally.imports += 1;
            write_and_read_back(&doc, &format!("OBJ case {case}"), dir.path(), &mut tally);
        }
    }
    // Mutated .vox files the importer accepts, and their enhancement.
    let vox_corpus = vec![
        asset("vox/dot_vox/axes.vox"),
        asset("vox/dot_vox/placeholder.vox"),
        asset("vox/mmmm/chr_army1.vox"),
    ];
    for case in 0..cases {
        let bytes = mutate(&vox_corpus, &mut case_rng(0x52_7472, case));
        let Ok(scene) = import_vox_bytes(&bytes, Path::new("m.vox"), &VoxImportOptions::default())
        else {
            continue;
        };
        let mut doc = Document::default();
        scene.add_to(&mut doc);
        tally.imports += 1;
        write_and_read_back(&doc, &format!(".vox case {case}"), dir.path(), &mut tally);
        if case % 4 == 0
            && let Some(fine) = enhanced(&doc)
        {
            tally.enhanced += 1;
            write_and_read_back(
                &fine,
                &format!("enhanced .vox case {case}"),
                dir.path(),
                &mut tally,
            );
        }
    }
    // The samples as they ship.
    let projects = concat!(env!("CARGO_MANIFEST_DIR"), "/../projects");
    for name in ["mixed", "tree", "critter", "coral"] {
        let doc = project::load(Path::new(&format!("{projects}/{name}.thicket.json"))).unwrap();
        write_and_read_back(&doc, name, dir.path(), &mut tally);
    }
    eprintln!("round trips: {cases} cases per corpus: {tally:?}");
    // Every path was exercised, and the writers wrote far more than they refused.
    assert!(tally.imports > cases / 10, "{tally:?}");
    assert!(tally.enhanced > 0, "{tally:?}");
    assert!(tally.gltf_exports > tally.imports, "{tally:?}");
    assert!(tally.vox_exports > tally.imports / 2, "{tally:?}");
    assert!(
        tally.refused_by_writer * 10 < tally.gltf_exports,
        "{tally:?}"
    );
}
