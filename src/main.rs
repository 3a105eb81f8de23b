//! Thin command-line front end: parse arguments, call the library, map errors to exit codes
//! (0 success, 1 failure of the work itself, 2 bad input).

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = oesweep::cli::Cli::parse();
    match oesweep::cli::run(cli) {
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            // One line, whatever the paths contain: control characters are escaped.
            let msg: String = e
                .to_string()
                .chars()
                .map(|c| if c.is_control() { c.escape_default().to_string() } else { c.to_string() })
                .collect();
            eprintln!("error: {msg}");
            ExitCode::from(if e.is_bad_input() { 2 } else { 1 })
        }
    }
}
