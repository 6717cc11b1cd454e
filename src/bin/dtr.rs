//! `dtr`: the difftransient command line. See `dtr --help`.

use clap::Parser;
use difftransient::cli::{Cli, exit_code, run};
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            // 1 internal, 2 bad input, 3 output failed (cli::exit_code); clap's usage errors are 2
            ExitCode::from(exit_code(&e))
        }
    }
}
