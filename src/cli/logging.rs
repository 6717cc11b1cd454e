//! What `dtr` says on stderr besides its errors: warnings, the summary line of each command,
//! progress bars, and with `--verbose` the settings and timings of each stage. Messages go
//! through the `log` facade (the library logs too), printed by `env_logger`.
//!
//! | flags | level | shown |
//! |---|---|---|
//! | `--quiet` | warn | warnings only: no progress bars, no summary lines |
//! | (none) | info | warnings, summary lines, progress bars on a terminal |
//! | `-v` | debug | also each stage's settings, sample counts and timings |
//! | `-vv` | trace | everything |
//!
//! The environment variable [`LOG_ENV`] (`env_logger`'s syntax, e.g. `DTR_LOG=debug`)
//! overrides the flags. Errors are printed by `main` whatever the level.

use log::{Level, LevelFilter};
use std::io::Write;

/// Environment variable that overrides `--quiet` / `--verbose` (e.g. `DTR_LOG=debug`).
pub const LOG_ENV: &str = "DTR_LOG";

/// The level the flags ask for.
pub fn level(quiet: bool, verbose: u8) -> LevelFilter {
    match (quiet, verbose) {
        (true, _) => LevelFilter::Warn,
        (false, 0) => LevelFilter::Info,
        (false, 1) => LevelFilter::Debug,
        (false, _) => LevelFilter::Trace,
    }
}

/// Installs the logger for this process (a second call does nothing).
pub fn init(quiet: bool, verbose: u8) {
    let mut b = env_logger::Builder::new();
    b.filter_level(level(quiet, verbose))
        .parse_env(env_logger::Env::new().filter(LOG_ENV))
        .format(|f, r| match r.level() {
            Level::Info => writeln!(f, "{}", r.args()),
            Level::Warn => writeln!(f, "warning: {}", r.args()),
            Level::Error => writeln!(f, "error: {}", r.args()),
            Level::Debug => writeln!(f, "debug: {}", r.args()),
            Level::Trace => writeln!(f, "trace: {}: {}", r.target(), r.args()),
        });
    let _ = b.try_init();
}

/// Whether summary lines and progress bars are wanted (the level is info or finer).
pub fn chatty() -> bool {
    log::log_enabled!(Level::Info)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_map_to_levels() {
        assert_eq!(level(true, 0), LevelFilter::Warn);
        assert_eq!(level(true, 2), LevelFilter::Warn);
        assert_eq!(level(false, 0), LevelFilter::Info);
        assert_eq!(level(false, 1), LevelFilter::Debug);
        assert_eq!(level(false, 3), LevelFilter::Trace);
    }
}
