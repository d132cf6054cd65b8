//! The solid import against the surface import of one mesh (issue 43's bars), side by side in
//! one run: import time (best of N, the two imports alternating), the import's peak heap,
//! octree memory, the saved `.bin` payload, the CPU frame (best of N, nodes visited) from one
//! camera, a sphere of radius 32 voxels carved into each (the voxels it reveals, memory after
//! it, and its time against the same carve into the solid stored voxel by voxel, no tiles),
//! and the glTF export's scene in cubes and smooth modes (time, peak heap, triangles).
//!
//! `cargo run --release -p thicket-core --example solid_import -- [DEPTH] [RUNS] [MESH.obj]`
//! (defaults 9, 3 and ../shared/assets/static/spot/spot_triangulated.obj).

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use glam::{UVec3, Vec3};
use thicket_core::io::gltf_export::{ExportMode, GltfExportOptions, build_scene};
use thicket_core::io::project;
use thicket_core::io::vox::{VoxExportOptions, export_vox_bytes};
use thicket_core::render::{View, render_document};
use thicket_core::scene::{Document, ObjectKind, VoxelModel};
use thicket_core::svo::Svo;
use thicket_core::voxelize::{Mode, Resolution, VoxelizeSettings, Voxelized, voxelize};

/// The system allocator, counting the bytes live and their peak.
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

// `GlobalAlloc` is an unsafe trait: every call is forwarded to the system allocator unchanged;
// only counters are added (as `thicket_core::io::fuzz` does for the tests).
#[allow(unsafe_code)]
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: forwarded with the caller's layout, which meets `alloc`'s contract.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            let now = LIVE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
            PEAK.fetch_max(now, Ordering::Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        // SAFETY: `ptr` was allocated by `System` with `layout` (every allocation goes there).
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// `f`'s result and the most heap it held above what was live before it.
fn peak_heap<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let base = LIVE.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    let out = f();
    (out, PEAK.load(Ordering::Relaxed).saturating_sub(base))
}

fn best<T>(runs: usize, mut f: impl FnMut() -> T) -> (Duration, T) {
    let mut out = None;
    let mut best = Duration::MAX;
    for _ in 0..runs.max(1) {
        let t = Instant::now();
        let r = f();
        best = best.min(t.elapsed());
        out = Some(r);
    }
    (
        best,
        out.unwrap_or_else(|| unreachable!("at least one run")),
    )
}

fn doc_of(v: &Voxelized) -> Document {
    let mut doc = Document::default();
    doc.add(
        "Model",
        ObjectKind::Voxels(VoxelModel {
            svo: v.svo.clone(),
            voxel_size: v.voxel_size,
            origin: v.origin,
            ..VoxelModel::default()
        }),
    );
    let (lo, hi) = v.svo.bounds().unwrap_or((UVec3::ZERO, UVec3::ONE));
    let centre = v.origin + (lo.as_vec3() + hi.as_vec3() + 1.0) * 0.5 * v.voxel_size;
    let half = (hi - lo + 1).as_vec3() * 0.5 * v.voxel_size;
    doc.camera.frame(centre - half, centre + half);
    doc
}

fn payload_bytes(doc: &Document) -> u64 {
    let dir = std::env::temp_dir().join(format!("solid_import_{}", std::process::id()));
    let _ = std::fs::create_dir_all(&dir);
    let json = dir.join("m.thicket.json");
    let bytes = project::save(doc, &json)
        .ok()
        .and_then(|()| std::fs::metadata(project::bin_path_for(&json)).ok())
        .map_or(0, |m| m.len());
    let _ = std::fs::remove_dir_all(&dir);
    bytes
}

/// Carves a sphere of radius `r` around the surface voxel nearest the top of the bounds'
/// centre column; returns the voxels removed and revealed.
fn carve(svo: &mut Svo, r: f32) -> (u64, u64) {
    let (lo, hi) = svo.bounds().unwrap_or((UVec3::ZERO, UVec3::ZERO));
    let mid = (lo + hi) / 2;
    let top = (lo.z..=hi.z)
        .rev()
        .find(|&z| svo.get(UVec3::new(mid.x, mid.y, z)).is_some())
        .unwrap_or(mid.z);
    let c = Vec3::new(mid.x as f32, mid.y as f32, top as f32) + 0.5;
    let ri = r.ceil() as u32;
    let a = (c.as_uvec3()).saturating_sub(UVec3::splat(ri));
    let b = (c.as_uvec3() + ri).min(UVec3::splat(svo.extent() - 1));
    let e = svo
        .edit_existing(a, b, |p, v| {
            ((p.as_vec3() + 0.5 - c).length() > r).then_some(v)
        })
        .unwrap_or_default();
    let removed = e
        .delta
        .entries
        .iter()
        .filter(|x| x.1.is_some() && svo.get(x.0).is_none())
        .count();
    let revealed = e
        .delta
        .entries
        .iter()
        .filter(|x| x.1.is_some_and(|v| v.is_interior()) && svo.get(x.0).is_some())
        .count();
    (removed as u64, revealed as u64)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let depth: u8 = args
        .first()
        .map_or(9, |s| s.parse().expect("an octree depth"));
    let runs: usize = args.get(1).map_or(3, |s| s.parse().expect("a run count"));
    let mesh = args.get(2).map_or_else(
        || {
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../../shared/assets/static/spot/spot_triangulated.obj")
        },
        PathBuf::from,
    );
    let model = match thicket_core::io::import_obj(&mesh) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("{}: {e}", mesh.display());
            std::process::exit(1);
        }
    };
    let import = |mode| {
        let settings = VoxelizeSettings {
            resolution: Resolution::Depth(depth),
            mode,
            max_voxels: u64::MAX / 4,
            ..VoxelizeSettings::default()
        };
        match voxelize(&model, &settings, &|_| true) {
            Ok(v) => v,
            Err(e) => {
                eprintln!("depth {depth}, {mode:?}: {e}");
                std::process::exit(1);
            }
        }
    };
    let (_, heap_surface) = peak_heap(|| import(Mode::Surface));
    let (_, heap_solid) = peak_heap(|| import(Mode::Solid));
    // Alternately, so that a slow spell of a shared machine falls on both.
    let (mut t_surface, mut t_solid) = (Duration::MAX, Duration::MAX);
    let (mut surface, mut solid) = (None, None);
    for _ in 0..runs.max(1) {
        let (t, v) = best(1, || import(Mode::Surface));
        (t_surface, surface) = (t_surface.min(t), Some(v));
        let (t, v) = best(1, || import(Mode::Solid));
        (t_solid, solid) = (t_solid.min(t), Some(v));
    }
    let (Some(surface), Some(solid)) = (surface, solid) else {
        unreachable!("at least one run")
    };
    let mib = |b: u64| b as f64 / (1024.0 * 1024.0);
    let (ms, md) = (surface.svo.memory_stats(), solid.svo.memory_stats());
    println!("{} at depth {depth}, best of {runs}:", mesh.display());
    println!(
        "  import: surface {:.3} s, solid {:.3} s ({:.2}x)",
        t_surface.as_secs_f64(),
        t_solid.as_secs_f64(),
        t_solid.as_secs_f64() / t_surface.as_secs_f64()
    );
    println!(
        "  import peak heap: surface {:.1} MiB, solid {:.1} MiB ({:.2}x)",
        mib(heap_surface as u64),
        mib(heap_solid as u64),
        heap_solid as f64 / heap_surface as f64
    );
    println!(
        "  voxels: surface {}, solid {} ({} marked interior, {} tiles)",
        ms.leaves, md.leaves, solid.stats.interior_marked, md.tiles
    );
    println!(
        "  memory: surface {:.2} MiB, solid {:.2} MiB ({:.2}x)",
        mib(ms.total_bytes),
        mib(md.total_bytes),
        md.total_bytes as f64 / ms.total_bytes as f64
    );
    let (ds, dd) = (doc_of(&surface), doc_of(&solid));
    let (ps, pd) = (payload_bytes(&ds), payload_bytes(&dd));
    println!(
        "  payload (.bin): surface {:.2} MiB, solid {:.2} MiB ({:.2}x)",
        mib(ps),
        mib(pd),
        pd as f64 / ps as f64
    );
    let view = View::new(800, 600);
    let frame = |d: &Document| {
        best(runs, || {
            render_document(d, &view).map_or(0, |(_, _, s)| s.nodes_visited())
        })
    };
    let (fs, ns) = frame(&ds);
    let (fd, nd) = frame(&dd);
    println!(
        "  CPU frame 800x600 (balanced): surface {:.1} ms ({ns} nodes), solid {:.1} ms \
         ({nd} nodes), {:.2}x",
        fs.as_secs_f64() * 1e3,
        fd.as_secs_f64() * 1e3,
        fd.as_secs_f64() / fs.as_secs_f64()
    );
    let (t_tiled, (removed, revealed, after)) = best(runs, || {
        let mut s = solid.svo.clone();
        let (a, b) = carve(&mut s, 32.0);
        (a, b, s.memory_stats().total_bytes)
    });
    // The voxel-by-voxel octree of a depth-10 solid needs gigabytes: compared up to 2^26.
    let (t_flat, _) = if md.leaves <= 1 << 26 {
        let flat = solid.svo.clone().without_tiles();
        best(runs, || {
            let mut s = flat.clone();
            carve(&mut s, 32.0)
        })
    } else {
        (Duration::ZERO, (0, 0))
    };
    let against = if t_flat.is_zero() {
        "voxel by voxel not compared: over 2^26 voxels".to_owned()
    } else {
        format!(
            "against {:.1} ms voxel by voxel ({:.2}x)",
            t_flat.as_secs_f64() * 1e3,
            t_tiled.as_secs_f64() / t_flat.as_secs_f64()
        )
    };
    println!(
        "  carve r=32: {removed} voxels removed, {revealed} revealed; memory {:.2} -> {:.2} MiB \
         (+{:.1} B per revealed voxel); {:.1} ms {against}",
        mib(md.total_bytes),
        mib(after),
        (after as f64 - md.total_bytes as f64) / revealed.max(1) as f64,
        t_tiled.as_secs_f64() * 1e3,
    );
    // Exports: the GLB each mode writes (built, not written), its time and peak heap. The
    // solid has the surface's outside, so the same quads; what it costs is the question.
    for mode in [ExportMode::Cubes, ExportMode::Smooth] {
        let options = GltfExportOptions {
            mode,
            ..GltfExportOptions::default()
        };
        let export = |d: &Document| {
            build_scene(d, Path::new("spot.glb"), &options, &|_| true)
                .map_or(0, |(_, report)| report.triangles)
        };
        let (tri_s, heap_s) = peak_heap(|| export(&ds));
        let (tri_d, heap_d) = peak_heap(|| export(&dd));
        let (es, _) = best(runs, || export(&ds));
        let (ed, _) = best(runs, || export(&dd));
        println!(
            "  export {mode:?}: surface {:.3} s {:.1} MiB ({tri_s} triangles), solid {:.3} s \
             {:.1} MiB ({tri_d} triangles): {:.2}x time, {:.2}x heap",
            es.as_secs_f64(),
            mib(heap_s as u64),
            ed.as_secs_f64(),
            mib(heap_d as u64),
            ed.as_secs_f64() / es.as_secs_f64(),
            heap_d as f64 / heap_s as f64
        );
    }
    // The `.vox` export (MagicaVoxel has no interior: every voxel is written, the solid's inside
    // with the colour exposing it would give).
    let vox = |d: &Document| {
        export_vox_bytes(
            &d.objects,
            Path::new("spot.vox"),
            &VoxExportOptions::default(),
        )
        .map_or(0, |(bytes, _)| bytes.len())
    };
    let (vs, bs) = best(runs, || vox(&ds));
    let (vd, bd) = best(runs, || vox(&dd));
    println!(
        "  export .vox: surface {:.3} s ({:.1} MiB), solid {:.3} s ({:.1} MiB): {:.2}x time",
        vs.as_secs_f64(),
        mib(bs as u64),
        vd.as_secs_f64(),
        mib(bd as u64),
        vd.as_secs_f64() / vs.as_secs_f64()
    );
    let (tn, found) = best(1, || solid.svo.nearest_surfaces().is_some());
    println!(
        "  of which the interior's nearest surface voxels (all at once): {:.3} s ({found})",
        tn.as_secs_f64()
    );
}
