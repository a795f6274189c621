//! Helpers shared by the command-line tests.

use std::process::{Command, Output};

/// Run the pegtwin binary with `args`.
pub fn pegtwin(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pegtwin"))
        .args(args)
        .output()
        .expect("pegtwin runs")
}

/// Its standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}
