//! Renders the house sample once at 800×600 from a few voxels off its wall (`close`, the
//! default) or from the project's camera (`project`), with exact cubes (`cubes`, the default)
//! or the paper's rectangles (`rectangles`), printing counts and stage times: a fixed workload
//! for `valgrind --tool=callgrind` instruction counts of the exact-cube cost.
//!
//! `cargo run --release -p thicket-core --example cube_profile -- [close|project]
//! [cubes|rectangles]`

use thicket_core::render::{View, render_document};

use thicket_core::quality::Quality;

fn main() {
    let mut args = std::env::args().skip(1);
    let view = args.next().unwrap_or_else(|| "close".to_owned());
    let mode = args.next().unwrap_or_else(|| "cubes".to_owned());
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../projects/house.thicket.json");
    let house = match thicket_core::io::project::load(&path) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("{}: {e}", path.display());
            std::process::exit(1);
        }
    };
    let Some(close) = thicket_core::render::scenes::house_close_up(&house) else {
        eprintln!("the house has no bounds");
        std::process::exit(1);
    };
    let camera = match view.as_str() {
        "close" => close,
        "project" => house.camera,
        other => {
            eprintln!("unknown view {other:?}: use close or project");
            std::process::exit(2);
        }
    };
    let quality = match mode.as_str() {
        "cubes" => Quality::default(),
        "rectangles" => Quality {
            cube_pixel_threshold: 1e6,
            ..Quality::default()
        },
        other => {
            eprintln!("unknown mode {other:?}: use cubes or rectangles");
            std::process::exit(2);
        }
    };
    let req = View {
        width: 800,
        height: 600,
        camera: Some(camera),
        quality,
    };
    match render_document(&house, &req) {
        Ok((_, _, st)) => println!(
            "{view} {mode}: {} splats ({} cubes), {} rectangle px, {} cube px, {} shadow cube px, \
             times {:?}",
            st.splats(),
            st.totals().cubes,
            st.rect_pixels,
            st.cube_pixels,
            st.shadow_cube_pixels,
            st.times
        ),
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    }
}
