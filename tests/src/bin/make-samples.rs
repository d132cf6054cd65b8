//! Rewrites the sample projects in `projects/` from `../shared/assets`: all of them, or only
//! those named on the command line (`make-samples terrain`).

use anyhow::Result;
use thicket_core::io::project;
use thicket_tests::samples::{SAMPLES, build};

fn main() -> Result<()> {
    let only: Vec<String> = std::env::args().skip(1).collect();
    if let Some(bad) = only.iter().find(|n| !SAMPLES.contains(&n.as_str())) {
        anyhow::bail!("unknown sample {bad:?}; known: {}", SAMPLES.join(", "));
    }
    for name in SAMPLES
        .into_iter()
        .filter(|n| only.is_empty() || only.iter().any(|o| o == n))
    {
        let path = thicket_tests::repo_root()
            .join("projects")
            .join(format!("{name}.thicket.json"));
        let doc = build(name)?;
        project::save(&doc, &path)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
