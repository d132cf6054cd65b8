//! The GPU frame keeps its buffers and bind groups (issue 24): a frame that differs from the
//! last only by its camera creates none; a new target size does.

use thicket::gpu::{RenderTarget, Renderer};
use thicket_core::quality::Quality;
use thicket_core::scene::{Document, OrbitCamera};

mod common;
use common::gpu::{context, project};

/// Creations by a frame turned `yaw_deg` from the sample's camera after one from the camera
/// itself, and by a frame of a larger target after them.
fn creations(doc: &Document, two_pass: bool, yaw_deg: f32) -> (u64, u64, u64) {
    let ctx = context();
    let mut r = Renderer::new(&ctx.device, &ctx.queue).expect("renderer");
    r.set_force_two_pass(two_pass);
    let q = Quality::default();
    let small = RenderTarget::new(&ctx.device, 96, 64).expect("target");
    let large = RenderTarget::new(&ctx.device, 128, 96).expect("target");
    let turned = OrbitCamera {
        yaw_deg: doc.camera.yaw_deg + yaw_deg,
        ..doc.camera
    };
    let (dev, queue) = (&ctx.device, &ctx.queue);
    r.render(dev, queue, doc, &small.view(&doc.camera, &q), &small)
        .expect("first frame");
    let first = r.resource_creations();
    r.render_uploaded(dev, queue, doc, &small.view(&turned, &q), &small)
        .expect("turned frame");
    let turned_frame = r.resource_creations() - first;
    r.render_uploaded(dev, queue, doc, &large.view(&turned, &q), &large)
        .expect("larger frame");
    let larger = r.resource_creations() - first - turned_frame;
    assert!(ctx.errors.take().is_none(), "uncaptured GPU error");
    (first, turned_frame, larger)
}

#[test]
fn a_camera_change_creates_no_buffers_or_bind_groups() {
    // Meshes, voxels and shadows; KRS; a skinned model; the two-pass splat path.
    for (name, two_pass) in [
        ("house", false),
        ("tree", false),
        ("cesiumman", false),
        ("house", true),
    ] {
        let doc = project(name);
        let (first, turned, larger) = creations(&doc, two_pass, 10.0);
        eprintln!("{name} (two-pass {two_pass}): first {first}, turned {turned}, larger {larger}");
        assert!(first > 0, "{name}: the first frame creates its resources");
        assert_eq!(turned, 0, "{name}: a camera change created GPU resources");
        assert!(larger > 0, "{name}: a larger target needs larger buffers");
    }
}
