//! Recorded run-time inputs: the CSV file of `solve --inputs` (and `compare`, `bench`).
//!
//! The file has a header row `t`, then for each input driver NAME the columns `NAME`,
//! `NAME.dot` and `NAME.ddot`, in any order; a line whose first non-blank character is `#` is
//! a comment and blank lines are skipped. Every input driver needs its `NAME` column; a missing
//! `NAME.dot` or `NAME.ddot` is estimated from the series by second-order finite differences
//! (the three-point formulas for non-uniform spacing, one-sided at the ends), with a warning.
//! The rows' `t` must increase strictly and become the analysis' time points.
//!
//! Every problem is a [`Diagnostic`] naming the file, the line, the column (the character
//! column of the cell) and the header: the reader never panics and never returns part of a
//! file.

use std::path::Path;

use crate::diag::Diagnostic;
use crate::model::{Law, Mechanism};

/// The largest inputs file read, in bytes (16 MiB, as for descriptions).
pub const MAX_BYTES: u64 = 16 * 1024 * 1024;
/// The most time points (data rows) a file may hold, as for a `[time]` grid.
pub const MAX_ROWS: usize = 10_000_000;
/// The largest magnitude of a cell, as for every number of a description (1e150: the
/// engines' products of such numbers stay finite).
const MAX_MAGNITUDE: f64 = 1e150;

/// A replayed series: the time points and, for every input driver, (s, ṡ, s̈) at each.
#[derive(Clone, Debug, PartialEq)]
pub struct Replay {
    /// The file, for messages.
    pub file: String,
    /// The time points, strictly increasing, at least one.
    pub t: Vec<f64>,
    /// Per driver of the mechanism (file order): its samples when it is an input driver.
    pub series: Vec<Option<Vec<[f64; 3]>>>,
    /// The description's own `[time]` grid, which the replay's rows replace for the analysis
    /// but which a generated solver is still built for (its pivot planning walks it), so that
    /// the solver does not depend on the series replayed.
    pub declared: (f64, f64, usize),
}

impl Replay {
    /// The samples of driver `k`, when it is an input driver.
    #[must_use]
    pub fn series(&self, k: usize) -> Option<&[[f64; 3]]> {
        self.series.get(k).and_then(|s| s.as_deref())
    }
}

/// The reading of an inputs file: the series and the warnings (estimated derivatives).
#[derive(Clone, Debug)]
pub struct Read {
    /// The series.
    pub replay: Replay,
    /// One line per estimated derivative column.
    pub warnings: Vec<String>,
}

/// Reads `path` for the input drivers of `mech`.
///
/// # Errors
/// A diagnostic naming the file (and line, column and header where there is one) when the file
/// cannot be read or is not a valid inputs file.
pub fn read(path: &Path, mech: &Mechanism) -> Result<Read, Box<Diagnostic>> {
    let file = path.display().to_string();
    let fail =
        |message: String| Box::new(Diagnostic::error(message).entity(format!("inputs {file}")));
    let meta = std::fs::metadata(path).map_err(|e| fail(format!("cannot read {file}: {e}")))?;
    if meta.len() > MAX_BYTES {
        return Err(fail(format!(
            "{file} is {} bytes, more than the {MAX_BYTES} an inputs file may have",
            meta.len()
        )));
    }
    let bytes = std::fs::read(path).map_err(|e| fail(format!("cannot read {file}: {e}")))?;
    let text = String::from_utf8(bytes).map_err(|e| {
        fail(format!("{file} is not UTF-8 text (byte {})", e.utf8_error().valid_up_to()))
    })?;
    parse(&text, &file, mech)
}

/// A header cell: its name, 1-based character column.
struct Cell<'a> {
    text: &'a str,
    column: usize,
}

/// The cells of one line, split at commas, trimmed, with their 1-based character columns; a
/// header name may be written in double quotes.
fn cells(line: &str) -> Vec<Cell<'_>> {
    let mut out = Vec::new();
    let mut start = 0;
    for piece in line.split(',') {
        let lead = piece.len() - piece.trim_start().len();
        let column = line[..start + lead].chars().count() + 1;
        let mut text = piece.trim();
        if text.len() >= 2 && text.starts_with('"') && text.ends_with('"') {
            text = &text[1..text.len() - 1];
        }
        out.push(Cell { text, column });
        start += piece.len() + 1;
    }
    out
}

/// Which quantity of which input driver a column holds.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Column {
    Time,
    /// (driver, derivative order 0, 1 or 2).
    Input(usize, usize),
}

/// Parses the text of an inputs file named `file` for the input drivers of `mech`.
///
/// # Errors
/// See [`read`].
pub fn parse(text: &str, file: &str, mech: &Mechanism) -> Result<Read, Box<Diagnostic>> {
    let inputs: Vec<(usize, &str)> = mech
        .drivers
        .iter()
        .enumerate()
        .filter(|(_, d)| d.law == Law::Input)
        .map(|(k, d)| (k, d.name.as_str()))
        .collect();
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(k, l)| (k + 1, l.strip_suffix('\r').unwrap_or(l)))
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let Some((header_line, header)) = lines.next() else {
        let message = "the file is empty: it needs a header row `t,NAME,…`".into();
        return Err(fail(file, 1, 1, None, message));
    };
    let heads = cells(header);
    let columns = header_columns(file, header_line, header, &heads, &inputs)?;
    let mut rows =
        Rows { t: Vec::new(), lines: Vec::new(), values: vec![Vec::new(); mech.drivers.len()] };
    for (line, row) in lines {
        rows.push(file, line, row, &heads, &columns, &inputs)?;
    }
    if rows.t.is_empty() {
        let message = "the file has a header but no rows of values".to_owned();
        return Err(fail(file, header_line, 1, None, message));
    }
    let warnings = estimate_rates(file, &mut rows, &columns, &inputs)?;
    let mut values = rows.values;
    let series = (0..mech.drivers.len())
        .map(|d| inputs.iter().any(|&(k, _)| k == d).then(|| std::mem::take(&mut values[d])))
        .collect();
    Ok(Read {
        replay: Replay {
            file: file.to_owned(),
            t: rows.t,
            series,
            declared: match &mech.time.replay {
                Some(r) => r.declared,
                None => (mech.time.start, mech.time.step, mech.time.count),
            },
        },
        warnings,
    })
}

/// An input file's error at `line` and `column`, under the column `header` if there is one.
fn fail(
    file: &str,
    line: usize,
    column: usize,
    header: Option<&str>,
    message: String,
) -> Box<Diagnostic> {
    let place = match header {
        Some(h) => format!("{file}, line {line}, column {column} (\"{h}\"): "),
        None => format!("{file}, line {line}: "),
    };
    let d = Diagnostic::error(format!("{place}{message}")).entity(format!("inputs {file}"));
    let d = match header {
        Some(h) => d.field(h),
        None => d,
    };
    Box::new(d.at(Some(file), line, column))
}

/// What each header cell names; refuses unknown, duplicate and missing columns.
fn header_columns(
    file: &str,
    header_line: usize,
    header: &str,
    heads: &[Cell<'_>],
    inputs: &[(usize, &str)],
) -> Result<Vec<Column>, Box<Diagnostic>> {
    let mut columns = Vec::with_capacity(heads.len());
    for h in heads {
        let column = if h.text == "t" {
            Column::Time
        } else {
            let (name, order) = match h.text.rsplit_once('.') {
                Some((n, "dot")) => (n, 1),
                Some((n, "ddot")) => (n, 2),
                _ => (h.text, 0),
            };
            let Some(&(d, _)) = inputs.iter().find(|(_, n)| *n == name) else {
                let names: Vec<&str> = inputs.iter().map(|(_, n)| *n).collect();
                let message = format!(
                    "unknown column \"{}\": the columns are `t` and, for the input drivers \
                     ({}), NAME, NAME.dot and NAME.ddot",
                    h.text,
                    names.join(", ")
                );
                return Err(fail(file, header_line, h.column, Some(h.text), message));
            };
            Column::Input(d, order)
        };
        if let Some(first) = columns.iter().position(|c| *c == column) {
            let message = format!("duplicate column \"{}\" (also column {})", h.text, first + 1);
            return Err(fail(file, header_line, h.column, Some(h.text), message));
        }
        columns.push(column);
    }
    let end = header.chars().count() + 1;
    if !columns.contains(&Column::Time) {
        let message = "missing column \"t\": the header row starts with the time".to_owned();
        return Err(fail(file, header_line, end, None, message));
    }
    for &(d, name) in inputs {
        if !columns.contains(&Column::Input(d, 0)) {
            let message =
                format!("missing column \"{name}\": input driver \"{name}\" needs its values");
            return Err(fail(file, header_line, end, Some(name), message));
        }
    }
    Ok(columns)
}

/// The rows read so far: times, their line numbers, and s, ṡ, s̈ per driver (NaN where a
/// column is absent, until [`estimate_rates`] fills it).
struct Rows {
    t: Vec<f64>,
    lines: Vec<usize>,
    values: Vec<Vec<[f64; 3]>>,
}

impl Rows {
    /// Reads the row at `line`: as many cells as the header, finite numbers, t increasing.
    fn push(
        &mut self,
        file: &str,
        line: usize,
        row: &str,
        heads: &[Cell<'_>],
        columns: &[Column],
        inputs: &[(usize, &str)],
    ) -> Result<(), Box<Diagnostic>> {
        let cells = cells(row);
        if cells.len() != heads.len() {
            let message = format!(
                "the row has {} cells where the header has {} columns",
                cells.len(),
                heads.len()
            );
            return Err(fail(file, line, 1, None, message));
        }
        if self.t.len() == MAX_ROWS {
            let message = format!("more than {MAX_ROWS} time points (the limit of a time grid)");
            return Err(fail(file, line, 1, None, message));
        }
        let mut time = f64::NAN;
        let mut row_values = vec![[f64::NAN; 3]; self.values.len()];
        for ((cell, column), head) in cells.iter().zip(columns).zip(heads) {
            let x: f64 = cell.text.parse().map_err(|_| {
                let message = format!("\"{}\" is not a number", cell.text);
                fail(file, line, cell.column, Some(head.text), message)
            })?;
            if !x.is_finite() || x.abs() > MAX_MAGNITUDE {
                let message =
                    format!("{} is not a finite number within ±{MAX_MAGNITUDE:e}", cell.text);
                return Err(fail(file, line, cell.column, Some(head.text), message));
            }
            match *column {
                Column::Time => time = x,
                Column::Input(d, order) => row_values[d][order] = x,
            }
        }
        if let Some(&last) = self.t.last()
            && time <= last
        {
            let at = columns.iter().position(|c| *c == Column::Time).expect("checked");
            let message =
                format!("t = {time:?} does not increase (the previous row has t = {last:?})");
            return Err(fail(file, line, cells[at].column, Some("t"), message));
        }
        self.t.push(time);
        self.lines.push(line);
        for &(d, _) in inputs {
            self.values[d].push(row_values[d]);
        }
        Ok(())
    }
}

/// Fills every absent `NAME.dot` and `NAME.ddot` by second-order finite differences of the
/// series (with a warning each); refuses estimates beyond the magnitude bound.
fn estimate_rates(
    file: &str,
    rows: &mut Rows,
    columns: &[Column],
    inputs: &[(usize, &str)],
) -> Result<Vec<String>, Box<Diagnostic>> {
    let mut warnings = Vec::new();
    for &(d, name) in inputs {
        for (order, suffix) in [(1, "dot"), (2, "ddot")] {
            if columns.contains(&Column::Input(d, order)) {
                continue;
            }
            let f: Vec<f64> = rows.values[d].iter().map(|v| v[order - 1]).collect();
            let estimates = derivative(&rows.t, &f);
            for ((v, x), line) in rows.values[d].iter_mut().zip(estimates).zip(&rows.lines) {
                // Differences over rows very close in t can exceed every bound of the engines.
                if !x.is_finite() || x.abs() > MAX_MAGNITUDE {
                    let message = format!(
                        "the estimated {name}.{suffix} is {x:e}, beyond ±{MAX_MAGNITUDE:e} (rows \
                         too close in t for finite differences): give the column"
                    );
                    return Err(fail(file, *line, 1, Some(name), message));
                }
                v[order] = x;
            }
            warnings.push(format!(
                "{file}: no column \"{name}.{suffix}\": estimated by second-order finite \
                 differences of {}",
                if order == 1 { name.to_owned() } else { format!("{name}.dot") }
            ));
        }
    }
    Ok(warnings)
}

/// df/dt at every t by the three-point second-order formulas for non-uniform spacing (central
/// inside, one-sided at the ends); two points give the difference quotient, one point zero.
#[must_use]
pub fn derivative(t: &[f64], f: &[f64]) -> Vec<f64> {
    let n = t.len();
    match n {
        0 => return Vec::new(),
        1 => return vec![0.0],
        2 => {
            let slope = (f[1] - f[0]) / (t[1] - t[0]);
            return vec![slope, slope];
        }
        _ => {}
    }
    let mut out = Vec::with_capacity(n);
    // Start: f'(t0) ≈ −(2h1 + h2)/(h1(h1 + h2)) f0 + (h1 + h2)/(h1 h2) f1 − h1/(h2(h1 + h2)) f2.
    let (h1, h2) = (t[1] - t[0], t[2] - t[1]);
    out.push(
        -(2.0 * h1 + h2) / (h1 * (h1 + h2)) * f[0] + (h1 + h2) / (h1 * h2) * f[1]
            - h1 / (h2 * (h1 + h2)) * f[2],
    );
    for i in 1..n - 1 {
        // Inside: −h2/(h1(h1 + h2)) f₋ + (h2 − h1)/(h1 h2) f + h1/(h2(h1 + h2)) f₊.
        let (h1, h2) = (t[i] - t[i - 1], t[i + 1] - t[i]);
        out.push(
            -h2 / (h1 * (h1 + h2)) * f[i - 1]
                + (h2 - h1) / (h1 * h2) * f[i]
                + h1 / (h2 * (h1 + h2)) * f[i + 1],
        );
    }
    // End: the start's formula mirrored.
    let (h1, h2) = (t[n - 2] - t[n - 3], t[n - 1] - t[n - 2]);
    out.push(
        h2 / (h1 * (h1 + h2)) * f[n - 3] - (h1 + h2) / (h1 * h2) * f[n - 2]
            + (2.0 * h2 + h1) / (h2 * (h1 + h2)) * f[n - 1],
    );
    out
}

#[cfg(test)]
mod tests;
