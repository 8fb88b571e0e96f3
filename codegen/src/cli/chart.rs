//! `mechgen chart`: speed against accuracy of every engine and setting (SVG).

use std::io::{self, Write};
use std::path::Path;

use super::common::{EXIT_INVALID, EXIT_OK, EXIT_STOPPED};
use super::term;
use crate::diag::printable;

pub(super) fn chart(
    file: &Path,
    output: &Path,
    repeats: usize,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<i32> {
    // Input drivers need a recorded series, which only solve, compare and bench take.
    let loaded = match super::common::load_replayed(file, None, false, out, err)? {
        Ok(l) => l,
        Err(code) => return Ok(code),
    };
    let mech = &loaded.mechanism;
    let bar = term::bar(crate::chart::mark_count() as u64, "marks");
    let measured = crate::chart::measure_with(mech, repeats, &mut |series, tolerance| {
        bar.set_message(format!("{series} {tolerance:.0e}"));
        bar.inc(1);
    });
    bar.finish_and_clear();
    let (marks, skipped) = match measured {
        Ok(m) => m,
        Err(e) => {
            writeln!(err, "error: {e}")?;
            return Ok(EXIT_STOPPED);
        }
    };
    writeln!(
        out,
        "{:<24} {:>9} {:>12} {:>10} {:>12}",
        "series", "tolerance", "ns/step", "iter/step", "max rel err"
    )?;
    for m in &marks {
        writeln!(
            out,
            "{:<24} {:>9.0e} {:>12.0} {:>10.2} {:>12.2e}",
            m.series, m.tolerance, m.ns_per_step, m.iterations, m.error
        )?;
    }
    for s in &skipped {
        writeln!(err, "note: no mark for {s} (the run failed)")?;
    }
    let title = format!("{}: speed against accuracy ({} time points)", mech.name, mech.time.count);
    if let Err(e) = crate::chart::draw(&marks, &title, output) {
        writeln!(err, "error: {e}")?;
        return Ok(EXIT_INVALID);
    }
    writeln!(out, "wrote {}", printable(&output.display().to_string()))?;
    Ok(EXIT_OK)
}
