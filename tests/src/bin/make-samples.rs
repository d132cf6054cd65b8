//! Rewrites the sample projects in `projects/` from `../shared/assets`.

use anyhow::Result;
use thicket_core::io::project;
use thicket_tests::samples::{SAMPLES, build};

fn main() -> Result<()> {
    for name in SAMPLES {
        let path = thicket_tests::repo_root()
            .join("projects")
            .join(format!("{name}.thicket.json"));
        let doc = build(name)?;
        project::save(&doc, &path)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
