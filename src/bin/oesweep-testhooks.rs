//! `oesweep-testhooks`: the `oesweep` command with the test hooks of [`oesweep::failpoint`]
//! switched on, for the tests that inject a panic or pause a run (`OESWEEP_FAILPOINT`). Built
//! only with the `failpoints` feature, which the test suite turns on for itself (the package's
//! dev-dependency on itself); `cargo build` and `cargo install` never build it, and the
//! `oesweep` binary never reads the variable, whichever cargo command ran last.

fn main() -> std::process::ExitCode {
    oesweep::failpoint::enable();
    oesweep::cli::main()
}
