//! Rewrites the sample projects in `projects/` from `../shared/assets`: all of them, or only
//! those named on the command line (`make-samples terrain`).

use anyhow::Result;
use thicket_core::io::project;
use thicket_tests::samples::{SAMPLES, build};

fn main() -> Result<()> {
    let only: Vec<String> = std::env::args().skip(1).collect();
    for name in SAMPLES {
        if !only.is_empty() && !only.iter().any(|n| n == name) {
            continue;
        }
        let path = thicket_tests::repo_root()
            .join("projects")
            .join(format!("{name}.thicket.json"));
        let doc = build(name)?;
        project::save(&doc, &path)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
