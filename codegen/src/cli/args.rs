//! The command line's grammar (clap): subcommands, options and the checks on their values.

use std::ffi::OsString;
use std::path::{Path, PathBuf};

use clap::{Parser, Subcommand, ValueEnum};

use super::plot;
use crate::validate;

#[derive(Parser, Debug)]
#[command(name = "mechgen", version, about = "Kinematic analysis of spatial mechanisms")]
pub(super) struct Cli {
    #[command(subcommand)]
    pub(super) command: Command,
}

#[derive(Subcommand, Debug)]
pub(super) enum Command {
    /// Validate a description; print its size, rank, mobility and redundant equations.
    Check {
        /// The description file (TOML, or JSON by extension).
        file: PathBuf,
        /// Output format.
        #[arg(long, value_enum, default_value_t = CheckFormat::Text)]
        format: CheckFormat,
    },
    /// Kinematic analysis over the time grid.
    Solve {
        /// The description file.
        file: PathBuf,
        /// The engine (default: generated if it can be built, else generic).
        #[arg(long, value_enum)]
        engine: Option<Engine>,
        /// Output format.
        #[arg(long, value_enum, default_value_t = SolveFormat::Table)]
        format: SolveFormat,
        /// Write the results here instead of standard output.
        #[arg(short = 'o', long = "output")]
        output: Option<PathBuf>,
        /// Recorded inputs (CSV: `t`, then NAME, NAME.dot, NAME.ddot per input driver): the
        /// time points come from the file.
        #[arg(long)]
        inputs: Option<PathBuf>,
        /// Write only these moving bodies, points and joints (names separated by commas).
        #[arg(long, value_delimiter = ',')]
        select: Option<Vec<String>>,
    },
    /// Run both engines; report the largest difference of every output quantity and the
    /// time per step of each.
    Compare {
        /// The description file.
        file: PathBuf,
        /// Output format.
        #[arg(long, value_enum, default_value_t = CheckFormat::Text)]
        format: CheckFormat,
        /// Recorded inputs (CSV: `t`, then NAME, NAME.dot, NAME.ddot per input driver): the
        /// time points come from the file.
        #[arg(long)]
        inputs: Option<PathBuf>,
        /// Also solve the description in double-double arithmetic and report each engine's
        /// largest error against that reference.
        #[arg(long)]
        reference: bool,
    },
    /// Time the analysis: ns per time step (min and median over repeats), Newton
    /// iterations per step.
    Bench {
        /// The description file.
        file: PathBuf,
        /// The engine, or both side by side.
        #[arg(long, value_enum, default_value_t = BenchEngine::Both)]
        engine: BenchEngine,
        /// Newton tolerance on max |Φ_i| (default: the description's).
        #[arg(long, value_parser = tolerance_value)]
        tolerance: Option<f64>,
        /// Whole passes over the grid to time.
        #[arg(long, default_value_t = 20, value_parser = repeats_value)]
        repeats: usize,
        /// Output format.
        #[arg(long, value_enum, default_value_t = CheckFormat::Text)]
        format: CheckFormat,
        /// Floating-point type of the generated solver.
        #[arg(long, value_enum, default_value_t = Float::F64)]
        float: Float,
        /// Start every Newton solve from the last position instead of the Taylor predictor.
        #[arg(long)]
        no_predictor: bool,
        /// Factor the generated solver's Jacobian by dense LU only (no static pivot orders).
        #[arg(long)]
        dense_lu: bool,
        /// Recorded inputs (CSV: `t`, then NAME, NAME.dot, NAME.ddot per input driver): the
        /// time points come from the file.
        #[arg(long)]
        inputs: Option<PathBuf>,
    },
    /// Chart speed against accuracy: one mark per engine and setting (SVG).
    Chart {
        /// The description file.
        file: PathBuf,
        /// The SVG file to write.
        #[arg(short = 'o', long = "output")]
        output: PathBuf,
        /// Whole passes over the grid timed per mark.
        #[arg(long, default_value_t = 10, value_parser = repeats_value)]
        repeats: usize,
    },
    /// Scaling study: generation time, generated lines, build time and ns per step for
    /// chains and multi-loop mechanisms of the given sizes (bodies).
    #[command(hide = true)]
    Scaling {
        /// Body counts to measure.
        #[arg(long, value_delimiter = ',', default_value = "5,20,50,100", value_parser = bodies_value)]
        bodies: Vec<usize>,
        /// Whole passes timed per engine.
        #[arg(long, default_value_t = 3, value_parser = repeats_value)]
        repeats: usize,
        /// Also write each description into this directory.
        #[arg(long)]
        write: Option<PathBuf>,
    },
    /// Plot one quantity of a point or a body against time, and the path of a point or of a
    /// body's origin in a 3D projection (SVG; generic engine).
    Plot {
        /// The description file.
        file: PathBuf,
        /// The point of interest to plot.
        #[arg(long, required_unless_present = "body", conflicts_with = "body")]
        point: Option<String>,
        /// The moving body to plot (its frame's origin and orientation).
        #[arg(long)]
        body: Option<String>,
        /// The quantity: r, v, a (points and bodies); p, omega, alpha (bodies).
        #[arg(long, value_enum, default_value_t = plot::PlotQuantity::R)]
        quantity: plot::PlotQuantity,
        /// The SVG file to write.
        #[arg(short = 'o', long = "output")]
        output: PathBuf,
    },
    /// Emit the specialised Rust module of a description.
    Generate {
        /// The description file.
        file: PathBuf,
        /// Floating-point type of the module.
        #[arg(long, value_enum, default_value_t = Float::F64)]
        float: Float,
        /// Write the module here instead of standard output.
        #[arg(short = 'o', long = "output")]
        output: Option<PathBuf>,
        /// Generate only what these moving bodies, points and joints need (names separated by
        /// commas): the blocks no named output depends on are left out of the module.
        #[arg(long, value_delimiter = ',')]
        outputs: Option<Vec<String>>,
    },
    /// Regenerate `generated/src` from `examples/*.toml` (`--check`: only compare).
    #[command(hide = true)]
    Codegen {
        /// Report stale files and exit 1 instead of writing.
        #[arg(long)]
        check: bool,
    },
    /// Convert a legacy YOUNG input deck to a description (TOML on standard output).
    ImportYoung {
        /// The deck.
        deck: PathBuf,
        /// Write the description here instead of standard output.
        #[arg(short = 'o', long = "output")]
        output: Option<PathBuf>,
    },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub(super) enum CheckFormat {
    Text,
    Json,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub(super) enum SolveFormat {
    Table,
    Csv,
    Json,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub(super) enum BenchEngine {
    Generic,
    Generated,
    Both,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub(super) enum Float {
    F64,
    F32,
}

impl Float {
    pub(super) fn scalar(self) -> crate::emit::Scalar {
        match self {
            Float::F64 => crate::emit::Scalar::F64,
            Float::F32 => crate::emit::Scalar::F32,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub(super) enum Engine {
    Generic,
    Generated,
}

/// The most whole passes over the grid `bench`, `chart` and `scaling` time: the median of
/// 10,000 passes is as good as any, and more only delays the answer.
const MAX_REPEATS: usize = 10_000;

/// A whole number in `range`, or the reason it is not.
fn whole_in(
    text: &str,
    range: std::ops::RangeInclusive<usize>,
    why: &str,
) -> Result<usize, String> {
    let n: usize = text.trim().parse().map_err(|_| {
        format!("`{text}` is not a whole number from {} to {}", range.start(), range.end())
    })?;
    if range.contains(&n) {
        Ok(n)
    } else {
        Err(format!("{n} is not from {} to {}: {why}", range.start(), range.end()))
    }
}

/// `--repeats`: 1 to [`MAX_REPEATS`].
fn repeats_value(text: &str) -> Result<usize, String> {
    whole_in(text, 1..=MAX_REPEATS, "more passes only delay the answer")
}

/// `scaling --bodies`: 1 to the most moving bodies a description may have.
fn bodies_value(text: &str) -> Result<usize, String> {
    whole_in(text, 1..=validate::MAX_BODIES, "descriptions hold at most that many moving bodies")
}

/// `--tolerance`: finite, > 0 and at most the largest number a description may hold, as the
/// description's own `solver.tolerance`.
fn tolerance_value(text: &str) -> Result<f64, String> {
    let max = validate::MAX_MAGNITUDE;
    match text.trim().parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 && x <= max => Ok(x),
        Ok(x) => Err(format!("{x} is not a tolerance: it must be finite, > 0 and at most {max:e}")),
        Err(_) => Err(format!("`{text}` is not a number")),
    }
}

/// Whether the user asked for JSON anywhere on the command line (so that even argument
/// errors are reported as the contract's JSON error object).
pub(super) fn wants_json(args: &[OsString]) -> bool {
    args.windows(2).any(|w| w[0] == "--format" && w[1] == "json")
        || args.iter().any(|a| a == "--format=json")
}

impl Command {
    /// The `-o` file of the command and the files it reads, when it has one.
    pub(super) fn output(&self) -> Option<(&Path, Vec<&Path>)> {
        match self {
            Self::Solve { file, output: Some(o), inputs: Some(i), .. } => Some((o, vec![file, i])),
            Self::Solve { file, output: Some(o), .. }
            | Self::Generate { file, output: Some(o), .. }
            | Self::ImportYoung { deck: file, output: Some(o) } => Some((o, vec![file])),
            Self::Chart { file, output, .. } | Self::Plot { file, output, .. } => {
                Some((output, vec![file]))
            }
            _ => None,
        }
    }
}
