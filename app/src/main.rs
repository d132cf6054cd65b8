//! The `thicket` binary: parses the command line and hands it to [`thicket::cli::run`].

use std::process::ExitCode;

use clap::Parser as _;

fn main() -> ExitCode {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    // A bad value (`--size 12`) exits 1 like every other error a command reports; clap's own
    // status otherwise (0 for --help and --version, 2 for a malformed command line).
    let cli = match thicket::cli::Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return ExitCode::from(thicket::cli::parse_error_exit_code(&e));
        }
    };
    match thicket::cli::run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // The whole context chain on one line, each cause once.
            eprintln!("error: {}", thicket::cli::error_line(&e));
            ExitCode::FAILURE
        }
    }
}
