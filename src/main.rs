//! Thin command-line front end: parse arguments, call the library, map errors to exit codes
//! (0 success, 1 failure of the work itself, 2 bad input).

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = oesweep::cli::Cli::parse();
    match oesweep::cli::run(cli) {
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(if e.is_bad_input() { 2 } else { 1 })
        }
    }
}
