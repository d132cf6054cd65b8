//! `thicket tradeoff`: sweep quality knobs on a project against a high-quality reference and
//! write `report.json`, `report.csv` and `tradeoff.png` (time vs error and work vs error, each
//! with its Pareto front marked).
//!
//! The plot is drawn with plotters' bitmap backend and its pure-Rust `ab_glyph` text, with the
//! Ubuntu Light font egui already ships (`epaint_default_fonts`): no fontconfig or freetype.

use std::path::Path;
use std::sync::Once;

use anyhow::{Context as _, anyhow};
use plotters::prelude::*;
use thicket_core::measure::{SweepPoint, SweepReport, SweepSettings, reference_quality, sweep};
use thicket_core::quality::QualityPreset;
use thicket_core::render::{
    Camera, FrameBuffers, FrameStats, PixelId, RenderError, RgbaImage, View,
};
use thicket_core::scene::Document;

/// Plot size in pixels.
pub const PLOT_SIZE: (u32, u32) = (1200, 520);

fn register_font() -> anyhow::Result<()> {
    static ONCE: Once = Once::new();
    let mut result = Ok(());
    ONCE.call_once(|| {
        result = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            epaint_default_fonts::UBUNTU_LIGHT,
        )
        .map_err(|_| anyhow!("the bundled plot font does not load"));
    });
    result
}

/// Tick values for a log axis over `lo..=hi`: the finest "nice" mantissas (1-1.5-2-3-5-…)
/// that give at most `max` ticks, so a narrow range (one decade or less, e.g. frame times of
/// 1.3 to 2.7 ms) still gets labels and a wide one does not crowd them. Falls back to evenly
/// spaced values when no nice mantissa falls in the range.
#[must_use]
pub fn log_ticks(lo: f64, hi: f64, max: usize) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && hi > lo) || max == 0 {
        return Vec::new();
    }
    const MANTISSAS: [&[f64]; 5] = [
        &[1.0, 1.2, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0],
        &[1.0, 1.5, 2.0, 3.0, 5.0, 7.0],
        &[1.0, 2.0, 5.0],
        &[1.0, 3.0],
        &[1.0],
    ];
    let ticks_with = |mantissas: &[f64], decade_stride: i32| -> Vec<f64> {
        let (k_lo, k_hi) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
        let mut v = Vec::new();
        for k in (k_lo..=k_hi).filter(|k| k.rem_euclid(decade_stride) == 0) {
            for m in mantissas {
                let t = m * 10f64.powi(k);
                // Relative slack: 1e-9 keeps a tick that is the range's own end.
                if t >= lo * (1.0 - 1e-9) && t <= hi * (1.0 + 1e-9) {
                    v.push(t);
                }
            }
        }
        v
    };
    let mut best = Vec::new();
    for m in MANTISSAS {
        let v = ticks_with(m, 1);
        if v.len() <= max {
            best = v;
            break;
        }
    }
    let mut stride = 2;
    while best.is_empty() || best.len() > max {
        let v = ticks_with(&[1.0], stride);
        if v.len() <= max || stride > 64 {
            best = v;
            break;
        }
        stride *= 2;
    }
    if best.len() < 2 {
        // A range narrower than the gap between nice mantissas: evenly spaced values.
        let n = max.clamp(2, 5);
        best = (0..n)
            .map(|i| lo + (hi - lo) * (i as f64 + 0.5) / n as f64)
            .collect();
    }
    best
}

/// A short axis label: `850`, `1.5`, `0.25`, `12k`, `1.2M`.
#[must_use]
pub fn compact_number(v: f64) -> String {
    fn trim(s: String) -> String {
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_owned()
        } else {
            s
        }
    }
    let a = v.abs();
    if !v.is_finite() {
        format!("{v}")
    } else if a >= 1e6 {
        trim(format!("{:.2}", v / 1e6)) + "M"
    } else if a >= 1e4 {
        trim(format!("{:.0}", v / 1e3)) + "k"
    } else if a >= 1e3 {
        trim(format!("{:.1}", v / 1e3)) + "k"
    } else if a >= 100.0 {
        format!("{v:.0}")
    } else if a >= 10.0 {
        trim(format!("{v:.1}"))
    } else if a >= 0.1 {
        trim(format!("{v:.2}"))
    } else {
        trim(format!("{v:.4}"))
    }
}

fn preset_name(p: &SweepPoint) -> Option<&'static str> {
    p.setting.preset.map(|p| match p {
        QualityPreset::Draft => "draft",
        QualityPreset::Balanced => "balanced",
        QualityPreset::Final => "final",
    })
}

/// The spread of a point's render times (fastest, slowest), when it has more than one render.
fn time_spread(p: &SweepPoint) -> Option<(f64, f64)> {
    (p.times_ms.len() > 1 && p.time_min_ms > 0.0 && p.time_max_ms >= p.time_min_ms)
        .then_some((p.time_min_ms, p.time_max_ms))
}

/// Draws one panel: `x(p)` against RMSE, every point, the front joined by a line, presets
/// named; `spread(p)`, where given, is drawn as a horizontal error bar (a noisy cost).
fn panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    x_desc: &str,
    points: &[SweepPoint],
    x: impl Fn(&SweepPoint) -> f64,
    spread: impl Fn(&SweepPoint) -> Option<(f64, f64)>,
    on_front: impl Fn(&SweepPoint) -> bool,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("drawing the plot: {e:?}");
    let xs: Vec<f64> = points
        .iter()
        .flat_map(|p| {
            let (lo, hi) = spread(p).unwrap_or((x(p), x(p)));
            [x(p), lo, hi]
        })
        .filter(|v| *v > 0.0)
        .collect();
    let (x_lo, x_hi) = xs.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &v| {
        (lo.min(v), hi.max(v))
    });
    let (x_lo, x_hi) = if x_lo.is_finite() && x_hi > 0.0 {
        (x_lo * 0.8, x_hi * 1.25)
    } else {
        (0.1, 1.0)
    };
    let y_hi = points
        .iter()
        .map(|p| p.error.rmse)
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max)
        .max(1e-4)
        * 1.15;
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(64)
        .build_cartesian_2d(
            (x_lo..x_hi)
                .log_scale()
                .with_key_points(log_ticks(x_lo, x_hi, 6)),
            0.0..y_hi,
        )
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc("RMSE vs reference")
        .x_label_formatter(&|v| compact_number(*v))
        // One light line between labelled ones: ten made the grid read as a texture.
        .max_light_lines(1)
        .y_label_formatter(&|v| format!("{v:.3}"))
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(err)?;
    let bars: Vec<(f64, f64, f64, f64)> = points
        .iter()
        .filter(|p| x(p) > 0.0)
        .filter_map(|p| spread(p).map(|(lo, hi)| (p.error.rmse, lo, x(p), hi)))
        .collect();
    if !bars.is_empty() {
        chart
            .draw_series(bars.iter().map(|&(y, lo, mid, hi)| {
                ErrorBar::new_horizontal(y, lo, mid, hi, BLACK.mix(0.45).stroke_width(1), 6)
            }))
            .map_err(err)?
            .label("min-max of the renders")
            .legend(|(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], BLACK.mix(0.45).stroke_width(1))
            });
    }
    let others = points.iter().filter(|p| !on_front(p) && x(p) > 0.0);
    chart
        .draw_series(others.map(|p| Circle::new((x(p), p.error.rmse), 4, BLUE.mix(0.6).filled())))
        .map_err(err)?;
    let mut front: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| on_front(p) && x(p) > 0.0)
        .map(|p| (x(p), p.error.rmse))
        .collect();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    chart
        .draw_series(LineSeries::new(front.iter().copied(), RED.stroke_width(2)))
        .map_err(err)?
        .label("Pareto front")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(2)));
    chart
        .draw_series(
            front
                .iter()
                .map(|&(a, b)| Circle::new((a, b), 5, RED.filled())),
        )
        .map_err(err)?;
    for p in points.iter().filter(|p| x(p) > 0.0) {
        if let Some(name) = preset_name(p) {
            chart
                .draw_series([EmptyElement::at((x(p), p.error.rmse))
                    + Circle::new((0, 0), 8, BLACK.stroke_width(2))
                    + Text::new(name, (10, -18), ("sans-serif", 15).into_font())])
                .map_err(err)?;
        }
    }
    chart
        .configure_series_labels()
        // The front falls from upper left to lower right: the upper right is where no point is.
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(err)?;
    Ok(())
}

/// Draws the two-panel plot of a sweep into an image.
///
/// # Errors
/// The font does not load or plotters fails to draw.
pub fn plot(report: &SweepReport, title: &str) -> anyhow::Result<RgbaImage> {
    register_font()?;
    let (w, h) = PLOT_SIZE;
    let mut rgb = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        root.fill(&WHITE)
            .map_err(|e| anyhow!("drawing the plot: {e:?}"))?;
        let mut root = root
            .titled(title, ("sans-serif", 22))
            .map_err(|e| anyhow!("drawing the plot: {e:?}"))?;
        let dropped = report.dropped_knobs();
        if !dropped.is_empty() {
            root = root
                .titled(
                    &format!("no effect at this size, left out: {}", dropped.join(", ")),
                    ("sans-serif", 15),
                )
                .map_err(|e| anyhow!("drawing the plot: {e:?}"))?;
        }
        let (left, right) = root.split_horizontally(w / 2);
        panel(
            &left,
            "time vs error",
            "median frame time, bars min-max (ms, log)",
            &report.points,
            |p| p.time_ms,
            time_spread,
            |p| p.on_time_front,
        )?;
        panel(
            &right,
            "work vs error (deterministic)",
            "work units: nodes, triangles, KRS steps, shading reads (log)",
            &report.points,
            |p| p.work as f64,
            |_| None,
            |p| p.on_work_front,
        )?;
        root.present()
            .map_err(|e| anyhow!("drawing the plot: {e:?}"))?;
    }
    let mut img = RgbaImage::new(w, h);
    for (o, i) in img.pixels.chunks_exact_mut(4).zip(rgb.chunks_exact(3)) {
        o.copy_from_slice(&[i[0], i[1], i[2], 255]);
    }
    Ok(img)
}

/// Writes `bytes` to `path` through a temporary sibling, so a failure leaves no partial file.
fn write_atomic(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    crate::files::write_through_temporary(path, |tmp| {
        std::fs::write(tmp, bytes).with_context(|| format!("writing {}", path.display()))
    })
}

/// The files [`write_outputs`] writes into its directory.
pub const OUTPUT_FILES: [&str; 3] = ["report.json", "report.csv", "tradeoff.png"];

/// Which renderer drew a sweep's settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SweepRenderer {
    /// The CPU reference renderer.
    Cpu,
    /// The GPU renderer (the reference image is still the CPU's).
    Gpu,
}

impl SweepRenderer {
    fn key(self) -> &'static str {
        match self {
            Self::Cpu => "cpu",
            Self::Gpu => "gpu",
        }
    }

    fn title(self) -> &'static str {
        match self {
            Self::Cpu => "CPU renderer",
            Self::Gpu => "GPU renderer vs CPU reference",
        }
    }
}

/// Writes `report.json`, `report.csv` and `tradeoff.png` into `dir` (created if missing).
///
/// # Errors
/// The directory or a file cannot be written, or the plot fails.
pub fn write_outputs(
    report: &SweepReport,
    project_name: &str,
    renderer: SweepRenderer,
    dir: &Path,
) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let json = serde_json::json!({
        "project": project_name,
        "renderer": renderer.key(),
        "error_metric_for_fronts": "rmse",
        "report": report,
    });
    let mut text = serde_json::to_string_pretty(&json).context("encoding report.json")?;
    text.push('\n');
    let [json_name, csv_name, png_name] = OUTPUT_FILES;
    write_atomic(&dir.join(json_name), text.as_bytes())?;
    write_atomic(&dir.join(csv_name), report.to_csv().as_bytes())?;
    let title = format!(
        "{project_name}: {}x{}, {}, median of {} render(s), reference {:.0} ms",
        report.width,
        report.height,
        renderer.title(),
        report.repeats,
        report.reference_time_ms
    );
    let img = plot(report, &title)?;
    crate::files::write_png(&img, &dir.join(png_name))
}

/// [`thicket_core::measure::sweep()`] with the GPU renderer drawing every setting, measured against
/// the CPU reference renderer's image at [`reference_quality`]: the reference stays the one
/// every GPU image is tested against, so a GPU-only difference shows up as error instead of
/// cancelling out. Times are wall time of the GPU frame plus its two read-backs (image and
/// G-buffer); the reference time is the CPU's. Work is counted from the GPU's own counters
/// (nodes per level for the view and the shadow map, triangles, covered pixels and the
/// shading taps they imply).
///
/// # Errors
/// A GPU failure (device, limits, read-back) or a sweep error, with what and where.
pub fn gpu_sweep(
    ctx: &crate::gpu::GpuContext,
    doc: &Document,
    (width, height): (u32, u32),
    settings: &SweepSettings,
    progress: impl FnMut(usize, usize, &str),
) -> anyhow::Result<SweepReport> {
    use crate::gpu::{GpuError, RenderTarget, Renderer, read_rgba8};
    let camera = Camera::from_orbit(&doc.camera, width, height);
    let shadow_lights = doc.lights.iter().filter(|l| l.casts_shadows).count();
    let reference = reference_quality();
    let mut renderer = Renderer::new(&ctx.device, &ctx.queue)?;
    // The reference is drawn `repeats` times on the CPU: one renderer keeps its buffers.
    let mut cpu = thicket_core::render::Renderer::new();
    let target = RenderTarget::new(&ctx.device, width, height)?;
    let backend = |e: GpuError| RenderError::Backend {
        renderer: "GPU",
        message: e.to_string(),
    };
    let report = sweep(
        settings,
        &reference,
        &camera,
        shadow_lights,
        |q| {
            if *q == reference {
                let mut req = View::new(width, height);
                req.quality = q.clone();
                cpu.render_document(doc, &req)?;
                return Ok(cpu.take_frame());
            }
            let view = View {
                width,
                height,
                camera: None,
                quality: q.clone(),
            };
            let stats = renderer
                .render(&ctx.device, &ctx.queue, doc, &view, &target)
                .map_err(backend)?;
            let pixels = read_rgba8(&ctx.device, &ctx.queue, &target).map_err(backend)?;
            let g = renderer
                .read_gbuffer(&ctx.device, &ctx.queue)
                .map_err(backend)?;
            if let Some(e) = ctx.errors.take() {
                return Err(backend(e));
            }
            let fb = frame_buffers_of(&g);
            let frame_stats = FrameStats {
                levels: stats.levels.clone(),
                shadow_levels: stats.shadow_levels.clone(),
                triangles: stats.triangles,
                triangles_rasterised: stats.triangles,
                covered_pixels: fb.covered_pixels() as u64,
                ..FrameStats::default()
            };
            let image = RgbaImage {
                width,
                height,
                pixels,
            };
            Ok((image, fb, frame_stats))
        },
        progress,
    )?;
    Ok(report)
}

/// The GPU G-buffer as the CPU's frame buffers (what the error metrics read): coverage from
/// depth, since the GPU G-buffer carries no object ids (every covered pixel reports object 1).
fn frame_buffers_of(g: &crate::gpu::GBuffer) -> FrameBuffers {
    let ids = g
        .depth
        .iter()
        .map(|d| PixelId {
            object: u32::from(d.is_finite()),
            node: 0,
        })
        .collect();
    FrameBuffers {
        width: g.width,
        height: g.height,
        depth: g
            .depth
            .iter()
            .map(|d| if d.is_finite() { *d } else { 1.0 })
            .collect(),
        ids,
        normal: g.normal.clone(),
        albedo: g.albedo.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_ticks_label_narrow_and_wide_ranges() {
        // Frame times within one decade still get several labels.
        let t = log_ticks(1.28, 2.75, 6);
        assert!(t.len() >= 3 && t.len() <= 6, "{t:?}");
        assert!(t.iter().all(|v| (1.28..=2.75).contains(v)), "{t:?}");
        // Five decades: no more than asked for, all inside, increasing.
        let t = log_ticks(3_000.0, 900_000_000.0, 6);
        assert!(t.len() >= 2 && t.len() <= 6, "{t:?}");
        assert!(t.windows(2).all(|w| w[0] < w[1]), "{t:?}");
        // A very narrow range falls back to evenly spaced values.
        let t = log_ticks(1.61, 1.65, 6);
        assert!(
            t.len() >= 2 && t.iter().all(|v| (1.61..=1.65).contains(v)),
            "{t:?}"
        );
        assert!(log_ticks(0.0, 1.0, 6).is_empty() && log_ticks(2.0, 1.0, 6).is_empty());
    }

    #[test]
    fn compact_numbers_are_short() {
        for (v, s) in [
            (850.0, "850"),
            (1.5, "1.5"),
            (2.0, "2"),
            (0.25, "0.25"),
            (1500.0, "1.5k"),
            (12_000.0, "12k"),
            (1_200_000.0, "1.2M"),
            (0.0012, "0.0012"),
        ] {
            assert_eq!(compact_number(v), s);
        }
    }
}
