//! `mechgen plot`: one quantity of a point or a body against time, and the point's path.

use std::io::{self, Write};
use std::path::Path;

use clap::ValueEnum;

use super::common::{EXIT_INVALID, EXIT_OK, EXIT_STOPPED, report_invalid};
use super::term;
use crate::diag::Diagnostic;
use crate::generic::Analysis;
use crate::plot::{Quantity, Target, Trace};
use crate::report;

/// The quantity to plot, as written on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub(super) enum PlotQuantity {
    /// Position (m): r_P of a point, the origin of a body.
    R,
    /// Velocity (m/s).
    V,
    /// Acceleration (m/s²).
    A,
    /// Euler parameters of a body.
    P,
    /// Angular velocity of a body (rad/s).
    Omega,
    /// Angular acceleration of a body (rad/s²).
    Alpha,
}

impl From<PlotQuantity> for Quantity {
    fn from(q: PlotQuantity) -> Self {
        match q {
            PlotQuantity::R => Self::R,
            PlotQuantity::V => Self::V,
            PlotQuantity::A => Self::A,
            PlotQuantity::P => Self::P,
            PlotQuantity::Omega => Self::Omega,
            PlotQuantity::Alpha => Self::Alpha,
        }
    }
}

/// The invalid-input diagnostic for a target that is not in the mechanism, if it is not.
fn unknown_target(mech: &crate::model::Mechanism, target: &Target) -> Option<Diagnostic> {
    let (kind, name, names): (&str, &str, Vec<&str>) = match target {
        Target::Point(name) => {
            ("point", name, mech.points.iter().map(|p| p.name.as_str()).collect())
        }
        Target::Body(name) => (
            "body",
            name,
            mech.bodies.iter().filter(|b| !b.ground).map(|b| b.name.as_str()).collect(),
        ),
    };
    if names.contains(&name) {
        return None;
    }
    let hint = match crate::validate::closest(name, names.iter().copied()) {
        Some(near) => format!("did you mean \"{near}\"?"),
        None if names.is_empty() => format!("the mechanism has no {kind} to plot"),
        None => format!("expected one of {}", names.join(", ")),
    };
    let what = if kind == "body" { "moving body" } else { kind };
    Some(
        Diagnostic::error(format!("no {what} \"{name}\": {hint}"))
            .entity("command line")
            .field(format!("--{kind}")),
    )
}

/// Runs the generic analysis and writes the chart; exit 2 (after drawing the time points
/// computed) when the analysis stops.
pub(super) fn plot(
    file: &Path,
    target: &Target,
    quantity: PlotQuantity,
    output: &Path,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<i32> {
    // Input drivers need a recorded series, which only solve, compare and bench take.
    let loaded = match super::common::load_replayed(file, None, false, out, err)? {
        Ok(l) => l,
        Err(code) => return Ok(code),
    };
    let mech = &loaded.mechanism;
    if let Some(d) = unknown_target(mech, target) {
        return Ok(report_invalid(&[d], false, out, err));
    }
    let quantity = Quantity::from(quantity);
    if matches!(target, Target::Point(_))
        && matches!(quantity, Quantity::P | Quantity::Omega | Quantity::Alpha)
    {
        let d = Diagnostic::error("a point has no orientation: plot r, v or a of a point")
            .entity("command line")
            .field("--quantity");
        return Ok(report_invalid(&[d], false, out, err));
    }
    let (eq, prep) = match super::common::prepared(mech, false, out, err) {
        Ok(p) => p,
        Err(code) => return Ok(code),
    };
    let layout = report::layout(mech);
    let mut trace = Trace::new(mech.time.count);
    let bar = term::bar(mech.time.count as u64, "analysis");
    let run = Analysis::new(&eq, &prep).run(|frame| {
        bar.inc(1);
        trace.push(&report::step_result(mech, &layout, frame), target, quantity)
    });
    bar.finish_and_clear();
    trace.close();
    let failure = match run {
        Ok(r) => r.failure,
        Err(message) => {
            writeln!(err, "error: {message}")?;
            return Ok(EXIT_INVALID);
        }
    };
    let name = match target {
        Target::Point(n) => format!("point {n}"),
        Target::Body(n) => format!("body {n}"),
    };
    let title = format!("{}: {name}", mech.name);
    let with_path = matches!(target, Target::Point(_)) || quantity == Quantity::R;
    if let Err(e) = crate::plot::draw(&trace, target, quantity, &title, with_path, output) {
        writeln!(err, "error: {e}")?;
        return Ok(if failure.is_some() { EXIT_STOPPED } else { EXIT_INVALID });
    }
    let shown = crate::diag::printable(&output.display().to_string()).into_owned();
    writeln!(out, "wrote {shown} ({} time points)", trace.t.len())?;
    if let Some(f) = &failure {
        writeln!(err, "error: {}", report::failure_text(f))?;
        return Ok(EXIT_STOPPED);
    }
    Ok(EXIT_OK)
}

#[cfg(test)]
mod tests;
