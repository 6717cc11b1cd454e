//! The `dtr` command line: argument parsing and the commands it runs.

mod checkpoint_cmd;
mod commit_journal;
mod digest;
mod import_cmd;
mod info;
pub mod logging;
mod nlos_out;
mod npy_in;
mod optimize_cmd;
mod optimize_files;
pub mod output_set;
mod render_cmd;
mod shard_set;

use clap::{Parser, Subcommand};
use std::path::PathBuf;

#[derive(Parser, Debug)]
#[command(
    name = "dtr",
    version,
    about = "Differentiable transient renderer (Yi et al. 2021) on Embree"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
    /// Warnings only: no progress bars and no summary lines (`DTR_LOG` overrides).
    #[arg(long, short, global = true, conflicts_with = "verbose")]
    pub quiet: bool,
    /// More detail on stderr: -v each stage's settings and timings, -vv everything
    /// (`DTR_LOG` overrides, e.g. `DTR_LOG=debug`).
    #[arg(long, short, global = true, action = clap::ArgAction::Count)]
    pub verbose: u8,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Render a scene's transient to PREFIX.npy and PREFIX.json (plus EXR and previews on request).
    Render(render_cmd::RenderArgs),
    /// Add the shards of one render (`dtr render --shard I/N`) into one output set, as if one
    /// process had rendered it.
    Merge(shard_set::MergeArgs),
    /// Recover scene parameters from a target transient by gradient descent (Adam on adjoint
    /// gradients): writes a log, plots and the scene with the recovered values.
    Optimize(optimize_cmd::OptimizeArgs),
    /// Print a summary of a scene, including every parameter with its name, kind and value.
    Info {
        scene: PathBuf,
        /// Machine-readable JSON instead of text.
        #[arg(long)]
        json: bool,
        /// Override a parameter, as for `render`.
        #[arg(long = "set", value_name = "NAME=VALUE")]
        set: Vec<String>,
    },
    /// Convert a Mitsuba 3 XML scene (the subset in scenes/README.md) to our TOML description:
    /// `dtr import scene.xml -o scene.toml` (`dtr render scene.xml` reads it directly too).
    Import(import_cmd::ImportArgs),
    /// Print a shell completion script: `dtr completions bash > /etc/bash_completion.d/dtr`
    /// (or zsh, fish, elvish, powershell).
    Completions {
        #[arg(value_enum)]
        shell: clap_complete::Shell,
    },
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    logging::init(cli.quiet, cli.verbose);
    ignore_file_size_signal();
    match cli.command {
        Command::Render(args) => render_cmd::run(args),
        Command::Merge(args) => shard_set::run(args),
        Command::Optimize(args) => optimize_cmd::run(args),
        Command::Info { scene, json, set } => info::run(&scene, json, &set),
        Command::Import(args) => import_cmd::run(args),
        Command::Completions { shell } => {
            use clap::CommandFactory;
            let mut script = Vec::new();
            clap_complete::generate(shell, &mut Cli::command(), "dtr", &mut script);
            Ok(write_stdout(&script)?)
        }
    }
}

/// A write past the process's file-size limit (`ulimit -f`) then fails with EFBIG ("File too
/// large"), an output error like a full disk's (exit 3, the earlier output set kept, the
/// staging and lock files removed), instead of raising SIGXFSZ, whose default kills the
/// process with its hidden files left behind (exit 153; an independent sweep, 2026-12-02).
fn ignore_file_size_signal() {
    #[cfg(unix)]
    // SAFETY: setting a signal's disposition to "ignore" has no handler to race with
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
}

/// Writes `bytes` to standard output. A reader that stops early (`dtr info … | head`) is not
/// an error: the rest is dropped and the command still succeeds. Any other failure is an
/// output the file system refused (exit status 3; `dtr info > /dev/full` exited 2, as if its
/// input were bad).
pub(crate) fn write_stdout(bytes: &[u8]) -> Result<(), crate::output::OutputError> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(bytes).and_then(|()| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        r => r.map_err(|e| crate::output::OutputError::io(std::path::Path::new("standard output"), e)),
    }
}

/// The exit status of a failed command:
/// - 1: an internal failure (Embree failed, the renderer produced a value it must never
///   produce; nothing was written);
/// - 2: bad input (usage, the scene, an option, an output that would replace an input, a
///   locked prefix, a checkpoint or shard that does not belong to the render);
/// - 3: an output could not be written (the file system refused: permissions, a full disk, a
///   missing folder that cannot be made);
///
/// and 128 + N when signal N interrupted a render (`output_set`'s signal handler).
pub fn exit_code(e: &anyhow::Error) -> u8 {
    for cause in e.chain() {
        match cause.downcast_ref::<crate::output::OutputError>() {
            Some(crate::output::OutputError::Io { .. }) => return 3,
            Some(_) => return 1,
            None => {}
        }
        match cause.downcast_ref::<crate::Error>() {
            Some(crate::Error::Accel(_)) => return 1,
            Some(crate::Error::Output(crate::output::OutputError::Io { .. })) => return 3,
            Some(crate::Error::Output(_)) => return 1,
            Some(_) => return 2,
            None => {}
        }
    }
    if e.to_string().starts_with("internal error") {
        1
    } else {
        2
    }
}

/// Ends the process at once with `code`, from a signal thread: standard output and error
/// flushed, then `_exit`, which runs no exit handlers. `std::process::exit` ran the C
/// library's exit handlers and static destructors while the rendering threads went on, and
/// Embree's destructor of a mutex one of them held aborted the process instead of the exit
/// with 128 + the signal (`MutexSys::~MutexSys(): Assertion 'ok' failed`; tests/cli_optimize.rs
/// in CI rehearsal 74).
pub(crate) fn exit_from_signal(code: i32) -> ! {
    use std::io::Write;
    let _ = std::io::stdout().flush();
    let _ = std::io::stderr().flush();
    #[cfg(unix)]
    // SAFETY: `_exit` ends the process; nothing after it runs, and it takes no pointers.
    unsafe {
        libc::_exit(code)
    }
    #[cfg(not(unix))]
    std::process::exit(code)
}

/// The `--set` overrides of a command: numbers (a `[[param]]` value, or a number of the
/// description by its dotted path) and other values of fields (a word, a list, a table;
/// `scene::field_set`).
#[derive(Clone, Debug, Default)]
pub struct Sets {
    pub numbers: Vec<(String, f64)>,
    pub texts: Vec<(String, String)>,
}

/// Parses `NAME=VALUE` overrides: a value that reads as a number is one; any other value sets
/// a field of the description as a TOML file would write it (the loader refuses it for a
/// `[[param]]`, `scene::field_set::apply_text`).
pub fn parse_sets(sets: &[String]) -> anyhow::Result<Sets> {
    let mut out = Sets::default();
    for s in sets {
        let (name, value) = s
            .split_once('=')
            .ok_or_else(|| anyhow::anyhow!("--set {s:?}: expected NAME=VALUE, e.g. --set eta=1.33"))?;
        let name = name.trim().to_string();
        // every command that takes --set (render, optimize, info) refuses a repeat alike:
        // optimize ran from the last of two values without a word
        if out.numbers.iter().any(|(n, _)| *n == name) || out.texts.iter().any(|(n, _)| *n == name) {
            anyhow::bail!("--set {name}=… is given more than once; give each parameter once");
        }
        // a whole number beyond 2⁵³ (a 64-bit seed) goes as the TOML integer it is: as a
        // float it lost its last digits and the field refused it ("expected a whole number")
        let exact_integer = value.trim().parse::<i64>().is_ok_and(|i| i.unsigned_abs() > 1 << 53);
        match set_number(value) {
            Some(_) if exact_integer => out.texts.push((name, value.trim().to_string())),
            Some(v) if !v.is_finite() => anyhow::bail!("--set {s:?}: value must be finite"),
            Some(v) => out.numbers.push((name, v)),
            None => out.texts.push((name, value.trim().to_string())),
        }
    }
    Ok(out)
}

/// The number a `--set` value reads as, if it is one: the rule that splits numbers from
/// other values, for [`parse_sets`] and for a render's identity (`shard_set`).
pub(crate) fn set_number(value: &str) -> Option<f64> {
    value.trim().parse::<f64>().ok()
}
