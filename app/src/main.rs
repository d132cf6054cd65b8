//! The `thicket` binary: parses the command line and hands it to [`thicket::cli::run`].

use std::process::ExitCode;

use clap::Parser as _;

fn main() -> ExitCode {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    let cli = thicket::cli::Cli::parse();
    match thicket::cli::run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // The whole context chain on one line, each cause once.
            eprintln!("error: {}", thicket::cli::error_line(&e));
            ExitCode::FAILURE
        }
    }
}
