//! The `mechgen` command line (contract §3), as a library function so that tests can run it
//! in process: [`run`] takes the arguments and two writers and returns the exit status.
//!
//! One module per subcommand; `args` is the grammar, `common` what the subcommands share
//! (loading, invalid input, exit statuses, the output file, the generated solver) and `term`
//! the terminal's colour and progress bars.

use std::ffi::OsString;
use std::io::Write;

use clap::Parser;

use crate::diag::{Diagnostic, printable};

mod args;
mod bench;
mod chart;
mod check;
mod codegen;
mod common;
mod compare;
mod generate;
mod import;
mod plot;
mod scaling;
mod solve;
mod term;
#[cfg(test)]
mod tests;

use args::{Cli, Command, wants_json};
pub use common::{EXIT_BUILD, EXIT_INVALID, EXIT_OK, EXIT_STOPPED, closed_pipe};
use common::{output_problem, report_invalid};
pub use term::Terminal;

/// Runs `mechgen` with `args` (including the program name) and returns the exit status.
/// Output is plain: no colour, no progress bars (the form for tests and pipes).
pub fn run(args: Vec<OsString>, out: &mut dyn Write, err: &mut dyn Write) -> i32 {
    run_with(args, out, err, Terminal::default())
}

/// As [`run`], with diagnostics in colour and progress bars on standard error as `terminal`
/// says (the binary passes [`Terminal::detect`]).
pub fn run_with(
    args: Vec<OsString>,
    out: &mut dyn Write,
    err: &mut dyn Write,
    terminal: Terminal,
) -> i32 {
    term::with(terminal, || dispatch(args, out, err))
}

/// Parses the arguments, checks the output file and runs the subcommand; an I/O error that
/// is not a closed pipe is reported as invalid input.
fn dispatch(args: Vec<OsString>, out: &mut dyn Write, err: &mut dyn Write) -> i32 {
    let json = wants_json(&args);
    let cli = match Cli::try_parse_from(&args) {
        Ok(cli) => cli,
        Err(e) => return argument_error(&e, json, out, err),
    };
    if let Some(d) = cli.command.output().and_then(|(o, inputs)| output_problem(o, &inputs)) {
        return report_invalid(&[d], json, out, err);
    }
    match execute(cli.command, out, err) {
        Ok(code) => code,
        Err(e) if closed_pipe(&e) => EXIT_OK,
        Err(e) => {
            let _ = writeln!(err, "error: {}", printable(&e.to_string()));
            EXIT_INVALID
        }
    }
}

/// Reports what clap found wrong with the arguments (help and version are not errors).
fn argument_error(e: &clap::Error, json: bool, out: &mut dyn Write, err: &mut dyn Write) -> i32 {
    use clap::error::ErrorKind;
    if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) {
        let _ = write!(out, "{e}");
        return EXIT_OK;
    }
    if json {
        let d = Diagnostic::error(e.kind().to_string()).entity("command line");
        let _ = writeln!(out, "{}", serde_json::json!({ "error": d.to_json() }));
    }
    let _ = write!(err, "{}", e.render());
    EXIT_INVALID
}

/// Runs one subcommand and returns its exit status.
fn execute(command: Command, out: &mut dyn Write, err: &mut dyn Write) -> std::io::Result<i32> {
    match command {
        Command::Check { file, format } => check::check(&file, format, out, err),
        Command::Solve { file, engine, format, output, inputs, select } => {
            let files =
                solve::Files { file: &file, output: output.as_deref(), inputs: inputs.as_deref() };
            solve::solve(files, engine, format, select.as_deref(), out, err)
        }
        Command::ImportYoung { deck, output } => {
            import::import_young(&deck, output.as_deref(), out, err)
        }
        Command::Generate { file, float, output, outputs } => {
            let files = generate::Files { file: &file, output: output.as_deref() };
            generate::generate(files, float.scalar(), outputs.as_deref(), out, err)
        }
        Command::Chart { file, output, repeats } => chart::chart(&file, &output, repeats, out, err),
        Command::Scaling { bodies, repeats, write } => {
            scaling::scaling(&bodies, repeats, write.as_deref(), out, err)
        }
        Command::Compare { file, format, inputs, reference } => {
            compare::compare(&file, format, inputs.as_deref(), reference, out, err)
        }
        Command::Bench {
            file,
            engine,
            tolerance,
            repeats,
            format,
            float,
            no_predictor,
            dense_lu,
            inputs,
        } => {
            let settings = crate::engine::Settings { predictor: !no_predictor, dense_lu };
            let how = bench::BenchHow { tolerance, repeats, float: float.scalar(), settings };
            bench::bench(&file, engine, &how, format, inputs.as_deref(), out, err)
        }
        Command::Codegen { check } => codegen::codegen(check, out, err),
        Command::Plot { file, point, body, quantity, output } => {
            let target = match (point, body) {
                (Some(p), _) => crate::plot::Target::Point(p),
                (None, b) => crate::plot::Target::Body(b.unwrap_or_default()),
            };
            plot::plot(&file, &target, quantity, &output, out, err)
        }
    }
}
