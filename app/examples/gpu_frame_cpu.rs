//! The CPU cost of one GPU frame (issue 24): how long `Renderer::render_uploaded` keeps the
//! calling thread when only the camera changes — scene refresh, uniform uploads, bind groups,
//! encoding and submission — without the GPU's own time. Readback is asynchronous and the
//! device is drained between frames, outside the timed region, so the GPU's work (lavapipe
//! runs it on the CPU) never overlaps a timed frame.
//!
//! `cargo run -p thicket --example gpu_frame_cpu -- [FRAMES] [WIDTHxHEIGHT] [PROJECT…]`
//! (defaults: 40 frames, 320x240, the house, mixed, cesiumman, tree and forest samples) prints
//! per project the median and fastest frame in milliseconds.

use std::path::Path;
use std::time::Instant;

use thicket::gpu::{GpuContext, RenderTarget, Renderer};
use thicket_core::quality::Quality;
use thicket_core::scene::OrbitCamera;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let frames: usize = args.first().map_or(Ok(40), |s| s.parse())?;
    let (w, h) = match args.get(1) {
        Some(s) => {
            let (a, b) = s
                .split_once('x')
                .ok_or_else(|| anyhow::anyhow!("size is WIDTHxHEIGHT"))?;
            (a.parse()?, b.parse()?)
        }
        None => (320, 240),
    };
    let names: Vec<String> = if args.len() > 2 {
        args[2..].to_vec()
    } else {
        ["house", "mixed", "cesiumman", "tree", "forest"]
            .iter()
            .map(|s| (*s).to_owned())
            .collect()
    };
    let ctx = GpuContext::new_headless(wgpu::PowerPreference::HighPerformance)?;
    println!("adapter: {}", ctx.describe());
    let q = Quality::default();
    for name in names {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../projects")
            .join(format!("{name}.thicket.json"));
        let doc = thicket::files::load_document(&path)?;
        let mut r = Renderer::new(&ctx.device, &ctx.queue)?;
        let target = RenderTarget::new(&ctx.device, w, h)?;
        r.render(
            &ctx.device,
            &ctx.queue,
            &doc,
            &target.view(&doc.camera, &q),
            &target,
        )?;
        r.set_async_readback(true);
        let mut times = Vec::with_capacity(frames);
        for i in 0..frames {
            let cam = OrbitCamera {
                yaw_deg: doc.camera.yaw_deg + i as f32 * 3.0,
                ..doc.camera
            };
            let t0 = Instant::now();
            r.render_uploaded(
                &ctx.device,
                &ctx.queue,
                &doc,
                &target.view(&cam, &q),
                &target,
            )?;
            times.push(t0.elapsed().as_secs_f64() * 1e3);
            ctx.device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| anyhow::anyhow!("{e}"))?;
        }
        times.sort_by(f64::total_cmp);
        println!(
            "{name:10} {w}x{h}: median {:.3} ms, fastest {:.3} ms ({frames} frames)",
            times[times.len() / 2],
            times[0]
        );
    }
    Ok(())
}
