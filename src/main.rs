//! The `oesweep` command: the command line of [`oesweep::cli`]. It never switches the test
//! hooks on ([`oesweep::failpoint`]), whatever features the library was built with.

fn main() -> std::process::ExitCode {
    oesweep::cli::main()
}
