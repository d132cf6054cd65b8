//! `thicket bench`: renders a project N times with the CPU reference renderer or the GPU
//! renderer and reports frame times, frames per second, per-pass milliseconds (CPU stage
//! timers; GPU timestamp queries when the adapter has them) and the traversal counters.
//!
//! Both renderers are timed the same way: one warm-up frame (two for the CPU while orbiting,
//! so that its shadow cache holds the map), then `frames` frames, each timed
//! on the CPU clock from the call to its return (the GPU frame waits for its counters, so the
//! time includes the GPU work). The GPU renders with the scene uploaded once, as the editor
//! does between edits.

use std::time::Instant;

use serde::Serialize;
use thicket_core::quality::Quality;
use thicket_core::render::{Renderer as CpuRenderer, ShadowCache, View};
use thicket_core::scene::{Document, OrbitCamera};

use crate::gpu::splat_bw::SplatBandwidth;
use crate::gpu::{AtomicPath, GpuContext, GpuError, RenderTarget, Renderer};

/// Counters for one octree level (view traversal), as both renderers count them.
pub type BenchLevel = thicket_core::render::LevelStats;

/// One bench run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BenchReport {
    /// "cpu" or "gpu".
    pub renderer: &'static str,
    /// The GPU adapter and driver, or the CPU thread count.
    pub device: String,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Timed frames.
    pub frames: u32,
    /// Mean wall milliseconds per frame.
    pub mean_ms: f64,
    /// Median wall milliseconds per frame.
    pub median_ms: f64,
    /// Fastest frame.
    pub min_ms: f64,
    /// 1000 / mean.
    pub fps: f64,
    /// Mean milliseconds per pass (stage timers on the CPU, timestamps on the GPU).
    pub pass_ms: Vec<(String, f64)>,
    /// Whether `pass_ms` comes from GPU timestamp queries.
    pub gpu_timestamps: bool,
    /// View traversal counters of the last frame, per level.
    pub levels: Vec<BenchLevel>,
    /// Splats drawn for the view.
    pub splats: u64,
    /// Shadow-map traversal totals of the last frame that rendered its maps, summed over every
    /// light's map: what each added shadow-casting light costs. The GPU draws full maps; the
    /// CPU's uncached frames draw casters only where the frame's shading reads the map, its
    /// cached ones full maps. While orbiting, the CPU reuses its maps, so this is the warm-up's
    /// or the last frame that missed the cache.
    pub shadow: BenchLevel,
    /// Triangles submitted.
    pub triangles: u64,
    /// The GPU splat path ("Key64" or "TwoPass32"); empty for the CPU.
    pub atomic_path: String,
    /// KRS sphere-tracing counters of the last frame (zero without KRS objects).
    pub krs: BenchKrs,
    /// The view's voxel pass against a same-size buffer copy (GPU, 64-bit splat path, when
    /// asked for).
    pub splat_bandwidth: Option<SplatBandwidth>,
    /// GPU: chunks the voxel pools were split into to fit the storage binding limit (1 for a
    /// scene under the limit); 0 for the CPU.
    pub pool_chunks: usize,
    /// GPU: bytes of the per-frame buffers and textures after the last frame
    /// (`Renderer::frame_bytes`: grows with the image and with `supersample`²); 0 for the CPU.
    pub frame_bytes: u64,
    /// Degrees the camera's yaw turned before each timed frame (0: one fixed view).
    pub orbit_deg: f32,
    /// CPU: shadow maps taken from the shadow cache instead of rendered, over the timed frames
    /// (the cache is used only while orbiting, as by the editor's CPU preview); 0 for the GPU.
    pub shadow_maps_reused: u32,
}

/// What a bench run renders, at what size, how many times and how the camera moves: the same
/// for both renderers.
#[derive(Clone, Copy)]
pub struct BenchSetup<'a> {
    /// The document.
    pub doc: &'a Document,
    /// The view of the warm-up frame.
    pub camera: OrbitCamera,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Quality knobs.
    pub quality: &'a Quality,
    /// Timed frames (after the warm-up; at least one).
    pub frames: u32,
    /// Degrees the camera's yaw turns before each timed frame (0: one fixed view).
    pub orbit_deg: f32,
}

impl BenchSetup<'_> {
    /// The camera of timed frame `i` (0 = warm-up).
    fn camera_at(&self, i: u32) -> OrbitCamera {
        OrbitCamera {
            yaw_deg: self.camera.yaw_deg + self.orbit_deg * i as f32,
            ..self.camera
        }
    }
}

/// KRS counters of one frame, the same on both renderers.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct BenchKrs {
    /// Primary rays traced.
    pub rays: u64,
    /// Rays that hit.
    pub hits: u64,
    /// Distance evaluations of primary rays.
    pub steps: u64,
    /// Most evaluations of one ray (GPU only; `None` on the CPU).
    pub max_steps: Option<u64>,
    /// Rays that ran out of steps.
    pub exhausted: u64,
    /// Shadow rays through the KRS.
    pub shadow_rays: u64,
    /// Their distance evaluations.
    pub shadow_steps: u64,
    /// KRS ambient-occlusion evaluations.
    pub ao_evals: u64,
}

fn summarise(times_ms: &mut [f64]) -> (f64, f64, f64) {
    times_ms.sort_by(f64::total_cmp);
    let n = times_ms.len().max(1) as f64;
    let mean = times_ms.iter().sum::<f64>() / n;
    let median = times_ms.get(times_ms.len() / 2).copied().unwrap_or(0.0);
    let min = times_ms.first().copied().unwrap_or(0.0);
    (mean, median, min)
}

/// Times `setup.frames` CPU frames (after one warm-up frame, two while orbiting). While orbiting
/// (a non-zero `orbit_deg`) shadow maps come from a [`ShadowCache`], as in the editor's CPU
/// preview.
///
/// # Errors
/// When the document cannot be rendered.
pub fn bench_cpu(setup: &BenchSetup<'_>) -> anyhow::Result<BenchReport> {
    let req = |i: u32| View {
        width: setup.width,
        height: setup.height,
        camera: Some(setup.camera_at(i)),
        quality: setup.quality.clone(),
    };
    // One renderer for every frame, as the editor's preview keeps one: its buffers are made
    // by the warm-up frame and reused by the timed ones.
    let mut renderer = CpuRenderer::new();
    let mut cache = ShadowCache::new();
    // The document does not change during the bench: one content key for every frame. The
    // counters are copied out (a few levels) so the renderer is free for the next frame.
    let mut frame = |i: u32| {
        let frame = if setup.orbit_deg == 0.0 {
            renderer.render_document(setup.doc, &req(i))
        } else {
            renderer.render_document_cached(setup.doc, &req(i), &mut cache, 0)
        };
        frame.map(|f| f.stats.clone())
    };
    // The traversal of the last frame that drew shadow maps (a reused map has none).
    let drawn = |st: &thicket_core::render::FrameStats| {
        st.shadow_levels
            .iter()
            .any(|l| l.visited > 0)
            .then(|| level_totals(&st.shadow_levels))
    };
    let mut shadow = drawn(&frame(0)?).unwrap_or_default();
    if setup.orbit_deg != 0.0 {
        // The first frame of a content key keeps no map (see `ShadowCache`); the second draws
        // the one the orbit then reuses. Both are warm-up, so the timed frames are the orbit.
        if let Some(s) = drawn(&frame(0)?) {
            shadow = s;
        }
    }
    let frames = setup.frames;
    let mut times = Vec::with_capacity(frames as usize);
    let mut stage = [0.0f64; 7];
    let mut last = None;
    let mut shadow_maps_reused = 0;
    for i in 1..=frames.max(1) {
        let t0 = Instant::now();
        let stats = frame(i)?;
        times.push(t0.elapsed().as_secs_f64() * 1e3);
        shadow_maps_reused += stats.shadow_maps_reused;
        if let Some(s) = drawn(&stats) {
            shadow = s;
        }
        let t = &stats.times;
        for (acc, v) in stage.iter_mut().zip([
            t.shadow_ms,
            t.triangles_ms,
            t.traversal_ms,
            t.splat_ms,
            t.krs_ms,
            t.resolve_ms,
            t.shade_ms,
        ]) {
            *acc += v;
        }
        last = Some(stats);
    }
    let n = times.len() as f64;
    let (mean, median, min) = summarise(&mut times);
    let stats = last.unwrap_or_default();
    let names = [
        "shadow",
        "triangles",
        "traversal",
        "splat",
        "krs",
        "resolve",
        "shade",
    ];
    Ok(BenchReport {
        orbit_deg: setup.orbit_deg,
        shadow_maps_reused,
        pool_chunks: 0,
        frame_bytes: 0,
        renderer: "cpu",
        device: format!("CPU, {} threads (rayon)", rayon_threads()),
        width: setup.width,
        height: setup.height,
        frames: times.len() as u32,
        mean_ms: mean,
        median_ms: median,
        min_ms: min,
        fps: if mean > 0.0 { 1e3 / mean } else { 0.0 },
        pass_ms: names
            .iter()
            .zip(stage)
            .map(|(n_, v)| ((*n_).to_owned(), v / n))
            .collect(),
        gpu_timestamps: false,
        levels: stats.levels.clone(),
        splats: stats.splats(),
        shadow,
        triangles: stats.triangles,
        atomic_path: String::new(),
        splat_bandwidth: None,
        krs: BenchKrs {
            rays: stats.krs.rays,
            hits: stats.krs.hits,
            steps: stats.krs.steps,
            max_steps: None,
            exhausted: stats.krs.exhausted,
            shadow_rays: stats.krs.shadow_rays,
            shadow_steps: stats.krs.shadow_steps,
            ao_evals: stats.krs.ao_evals,
        },
    })
}

/// Counters summed over levels.
fn level_totals(levels: &[BenchLevel]) -> BenchLevel {
    levels
        .iter()
        .fold(BenchLevel::default(), |t, l| BenchLevel {
            visited: t.visited + l.visited,
            split: t.split + l.split,
            splatted: t.splatted + l.splatted,
            frustum_culled: t.frustum_culled + l.frustum_culled,
            occlusion_culled: t.occlusion_culled + l.occlusion_culled,
            cubes: t.cubes + l.cubes,
        })
}

fn rayon_threads() -> usize {
    std::thread::available_parallelism().map_or(1, std::num::NonZero::get)
}

/// Times `setup.frames` GPU frames on a headless device (after one warm-up that uploads the
/// scene; the camera turns as for [`bench_cpu`], and the shadow maps are drawn every frame);
/// then, when `splat_repeats > 0`, the frames splat voxels and the 64-bit splat path is in
/// use, measures the splat pass's bandwidth against a buffer copy with that many repeats
/// ([`Renderer::measure_splat_bandwidth`]).
///
/// # Errors
/// [`GpuError`] when there is no adapter or the frame fails.
pub fn bench_gpu(
    setup: &BenchSetup<'_>,
    force_two_pass: bool,
    splat_repeats: u32,
    binding_limit: Option<u64>,
) -> Result<BenchReport, GpuError> {
    let BenchSetup {
        doc,
        camera,
        width,
        height,
        quality,
        frames,
        orbit_deg,
    } = *setup;
    let ctx = GpuContext::new_headless_with_binding_limit(
        wgpu::PowerPreference::HighPerformance,
        binding_limit,
    )?;
    let mut r = Renderer::new(&ctx.device, &ctx.queue)?;
    r.set_force_two_pass(force_two_pass);
    let target = RenderTarget::new(&ctx.device, width, height)?;
    let view = |camera: OrbitCamera| View {
        width,
        height,
        camera: Some(camera),
        quality: quality.clone(),
    };
    r.render(&ctx.device, &ctx.queue, doc, &view(camera), &target)?;
    let mut times = Vec::with_capacity(frames as usize);
    let mut pass: Vec<(String, f64)> = Vec::new();
    let mut last = None;
    for i in 1..=frames.max(1) {
        let cam = setup.camera_at(i);
        let t0 = Instant::now();
        let stats = r.render_uploaded(&ctx.device, &ctx.queue, doc, &view(cam), &target)?;
        times.push(t0.elapsed().as_secs_f64() * 1e3);
        for (name, ms) in &stats.pass_ms {
            match pass.iter_mut().find(|(n, _)| n == name) {
                Some((_, acc)) => *acc += ms,
                None => pass.push(((*name).to_owned(), *ms)),
            }
        }
        last = Some(stats);
    }
    // Only a frame that splats voxels has a splat pass to measure (a KRS-only scene has none).
    let splats = last.as_ref().is_some_and(|s| s.splats > 0);
    let splat_bandwidth = if splat_repeats > 0 && splats && r.atomic_path() == AtomicPath::Key64 {
        let (_, bw) = r.measure_splat_bandwidth(
            &ctx.device,
            &ctx.queue,
            doc,
            &view(camera),
            &target,
            splat_repeats,
        )?;
        Some(bw)
    } else {
        None
    };
    if let Some(e) = ctx.errors.take() {
        return Err(e);
    }
    let n = times.len() as f64;
    for (_, v) in &mut pass {
        *v /= n;
    }
    let (mean, median, min) = summarise(&mut times);
    let stats = last.unwrap_or_default();
    Ok(BenchReport {
        orbit_deg,
        shadow_maps_reused: 0,
        pool_chunks: r.pool_chunks(),
        frame_bytes: r.frame_bytes(),
        renderer: "gpu",
        device: ctx.describe(),
        width,
        height,
        frames: times.len() as u32,
        mean_ms: mean,
        median_ms: median,
        min_ms: min,
        fps: if mean > 0.0 { 1e3 / mean } else { 0.0 },
        pass_ms: pass,
        gpu_timestamps: stats.gpu_timestamps,
        levels: stats.levels.clone(),
        splats: stats.splats,
        shadow: level_totals(&stats.shadow_levels),
        triangles: stats.triangles,
        atomic_path: format!("{:?}", stats.atomic_path),
        splat_bandwidth,
        krs: BenchKrs {
            rays: stats.krs.rays,
            hits: stats.krs.hits,
            steps: stats.krs.steps,
            max_steps: Some(stats.krs.max_steps),
            exhausted: stats.krs.exhausted,
            shadow_rays: stats.krs.shadow_rays,
            shadow_steps: stats.krs.shadow_steps,
            ao_evals: stats.krs.ao_evals,
        },
    })
}

/// The text report.
#[must_use]
pub fn format_report(project: &str, r: &BenchReport) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{project}: {} renderer on {}, {}x{}, {} frames",
        r.renderer, r.device, r.width, r.height, r.frames
    );
    let _ = writeln!(
        s,
        "  frame: mean {:.2} ms, median {:.2} ms, min {:.2} ms, {:.1} fps",
        r.mean_ms, r.median_ms, r.min_ms, r.fps
    );
    if r.orbit_deg != 0.0 {
        let cache = if r.renderer == "cpu" {
            format!(
                "; shadow maps reused from the shadow cache: {}",
                r.shadow_maps_reused
            )
        } else {
            String::new()
        };
        let _ = writeln!(s, "  orbit: yaw {:+}° a frame{cache}", r.orbit_deg);
    }
    if !r.atomic_path.is_empty() {
        let _ = writeln!(
            s,
            "  splat path: {}; voxel pools in {} chunk(s); frame buffers {}",
            r.atomic_path,
            r.pool_chunks,
            thicket_core::budget::human(r.frame_bytes)
        );
    }
    let source = match (r.renderer, r.gpu_timestamps) {
        ("gpu", true) => "GPU timestamp queries",
        ("gpu", false) => "not available: the adapter has no timestamp queries",
        _ => "CPU stage timers",
    };
    let _ = writeln!(s, "  passes, mean ms ({source}):");
    for (name, ms) in &r.pass_ms {
        let _ = writeln!(s, "    {name:<14} {ms:>9.3}");
    }
    let _ = writeln!(
        s,
        "  splats {}, triangles {}; view traversal per level (visited / split / splatted / frustum culled / occluded):",
        r.splats, r.triangles
    );
    for (i, l) in r.levels.iter().enumerate() {
        let _ = writeln!(
            s,
            "    {i:>2}: {:>9} {:>9} {:>9} {:>9} {:>9}",
            l.visited, l.split, l.splatted, l.frustum_culled, l.occlusion_culled
        );
    }
    if r.shadow.visited > 0 {
        let t = &r.shadow;
        let _ = writeln!(
            s,
            "  shadow maps (all lights): {} nodes visited, {} split, {} splatted, {} frustum culled, {} occluded",
            t.visited, t.split, t.splatted, t.frustum_culled, t.occlusion_culled
        );
    }
    if let Some(b) = &r.splat_bandwidth {
        format_splat_bandwidth(&mut s, b);
    }
    let k = &r.krs;
    if k.rays > 0 {
        let per_ray = k.steps as f64 / k.rays as f64;
        let max = k.max_steps.map_or(String::new(), |m| format!(", max {m}"));
        let _ = writeln!(
            s,
            "  KRS: {} rays, {} hits, {} steps ({per_ray:.1} per ray{max}), {} exhausted; {} shadow rays ({} steps), {} AO evaluations",
            k.rays, k.hits, k.steps, k.exhausted, k.shadow_rays, k.shadow_steps, k.ao_evals
        );
    }
    s
}

fn format_splat_bandwidth(s: &mut String, b: &SplatBandwidth) {
    use std::fmt::Write as _;
    let x = &b.bytes;
    let _ = writeln!(
        s,
        "  splat bandwidth (view voxel pass vs copy_buffer_to_buffer of the same bytes; median of {}, {}):",
        b.repeats, b.timing
    );
    let _ = writeln!(
        s,
        "    bytes {} = queue reads {} + queue writes {} + inner records {} + key atomics {} ({} px) + occlusion tiles {} ({} builds)",
        b.total_bytes,
        x.queue_reads,
        x.queue_writes,
        x.inner_reads,
        x.key_atomics,
        b.splat_pixels,
        x.occlusion,
        b.occlusion.builds
    );
    let _ = writeln!(
        s,
        "    splat pass {:.3} GB/s, copy {:.3} GB/s, ratio {:.3} (wall: splat {:.3} ms, copy {:.3} ms)",
        b.splat_gb_per_s, b.copy_gb_per_s, b.ratio, b.splat_wall_ms, b.copy_wall_ms
    );
    if let (Some(sp), Some(cp)) = (b.splat_timestamp_ms, b.copy_timestamp_ms) {
        let used = if b.timing == "timestamps" {
            "used"
        } else {
            "not used: a CPU device's timestamps do not time compute work"
        };
        let _ = writeln!(
            s,
            "    timestamps: splat {sp:.3} ms, copy {cp:.3} ms ({used})"
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summary_of_frame_times() {
        let mut t = vec![3.0, 1.0, 2.0, 10.0];
        let (mean, median, min) = summarise(&mut t);
        assert!((mean - 4.0).abs() < 1e-12);
        assert!((median - 3.0).abs() < 1e-12);
        assert!((min - 1.0).abs() < 1e-12);
    }
}
