//! Description → model: every rule of the contract's Validation section, with places.
//!
//! Loading goes in three passes, each reporting every problem it finds before the next runs:
//! 1. syntax: the text becomes a tree of spanned nodes (`locate`), for TOML and JSON alike;
//! 2. shape: each entity of the tree becomes its `desc` type (`de`), so an unknown field, a
//!    wrong type or an unknown `type = "revolut"` is reported with its line and column, and one
//!    bad joint does not hide the next;
//! 3. meaning: the rules (`rules`) check references, vectors, the fields each joint type
//!    needs, drivers, laws, the time grid and the equation count, and build the
//!    `model::Mechanism`. Their diagnostics carry a key path (`joints[2].axis_i`), which the
//!    tree turns into the line and column of the value, or of the entity's table when the
//!    field is absent.
//!
//! Every diagnostic names the entity (`joint "O2"`, `time`), the field and the path; the two
//! rules about the whole mechanism (no moving body, fewer equations than unknowns) name
//! `mechanism "NAME"` and point at `[[bodies]]` and `[[drivers]]`. Errors come in file order;
//! warnings never make loading fail.

mod de;
mod locate;
pub mod names;
mod rules;

// The command line bounds its own numbers by these.
#[cfg(feature = "cli")]
pub(crate) use rules::{MAX_BODIES, MAX_MAGNITUDE};
#[cfg(test)]
mod tests;

use std::fmt::Write as _;
use std::path::Path;

use crate::desc::MechanismDesc;
use crate::diag::{Diagnostic, Severity};
use crate::model;

/// The input syntax.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// TOML, the main format.
    Toml,
    /// JSON with the same structure.
    Json,
}

/// A validated mechanism with the warnings found on the way.
#[derive(Clone, Debug)]
pub struct Loaded {
    /// The validated model.
    pub mechanism: model::Mechanism,
    /// The description as written.
    pub desc: MechanismDesc,
    /// Warnings (for example a `p` normalised by more than 1e-6), in file order.
    pub warnings: Vec<Diagnostic>,
}

/// Reads and validates a file; the format follows the extension (`.json` → JSON, anything
/// else TOML). Errors carry file, line and column.
///
/// # Errors
///
/// Every problem found, in file order: an unreadable file, syntax, unknown or mistyped fields,
/// and every rule of the contract's Validation section.
pub fn load_file(path: &Path) -> Result<Loaded, Vec<Diagnostic>> {
    let (text, format) = read_file(path)?;
    load_str(&text, format, Some(&path.display().to_string()))
}

/// Reads a description file's text ([`MAX_FILE_BYTES`] at most, UTF-8) and tells its format by
/// the extension (`.json` → JSON, anything else TOML), for callers that keep the text, for
/// example to show diagnostics with [`crate::diag::render`].
///
/// # Errors
///
/// The file cannot be read, is too large or is not UTF-8; the one diagnostic names the file
/// (and the line and column of the first byte that is not UTF-8).
pub fn read_file(path: &Path) -> Result<(String, Format), Vec<Diagnostic>> {
    let name = path.display().to_string();
    let text = read_text(path).map_err(|(message, place)| {
        let mut diag = Diagnostic::error(message).entity("file");
        diag.file = Some(name.clone());
        if let Some((line, column)) = place {
            (diag.line, diag.column) = (Some(line), Some(column));
        }
        vec![diag]
    })?;
    let json = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("json"));
    Ok((text, if json { Format::Json } else { Format::Toml }))
}

/// The largest description file accepted, in bytes (16 MiB).
///
/// A description of `rules::MAX_BODIES` bodies with a joint and a point each takes well under
/// 1 MiB; the bound keeps a mistaken argument (a log, a disk image) from being read into memory.
pub const MAX_FILE_BYTES: u64 = 16 << 20;

/// Reads at most [`MAX_FILE_BYTES`] of a file, without reading more from a larger file or a
/// device.
/// `what` names the input in messages ("file", "deck").
pub(crate) fn read_bounded(path: &Path, what: &str) -> Result<Vec<u8>, String> {
    use std::io::Read;
    let file = std::fs::File::open(path).map_err(|e| format!("cannot read the {what}: {e}"))?;
    let mut bytes = Vec::new();
    file.take(MAX_FILE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| format!("cannot read the {what}: {e}"))?;
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Err(format!(
            "the {what} is larger than {} MiB, the most an input may have",
            MAX_FILE_BYTES >> 20
        ));
    }
    Ok(bytes)
}

/// Reads a description file as UTF-8 text ([`read_bounded`]); an error carries the line and
/// column of the first byte that is not UTF-8, if that is the problem.
fn read_text(path: &Path) -> Result<String, (String, Option<(usize, usize)>)> {
    let bytes = read_bounded(path, "file").map_err(|m| (m, None))?;
    String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        let valid = &e.as_bytes()[..at];
        let line = 1 + valid.iter().filter(|&&b| b == b'\n').count();
        let start = valid.iter().rposition(|&b| b == b'\n').map_or(0, |k| k + 1);
        let column = 1 + String::from_utf8_lossy(&valid[start..]).chars().count();
        let message = format!(
            "the file is not UTF-8 text: byte 0x{:02x} at line {line}, column {column} (is it a \
             binary file?)",
            e.as_bytes()[at]
        );
        (message, Some((line, column)))
    })
}

/// Reads and validates a description given as text; `file` is only used in messages.
///
/// # Errors
///
/// As [`load_file`].
pub fn load_str(text: &str, format: Format, file: Option<&str>) -> Result<Loaded, Vec<Diagnostic>> {
    let root = match locate::parse(text, format) {
        Ok(root) => root,
        Err(unparsed) => return Err(syntax_errors(text, format, file, unparsed)),
    };
    let src = de::Source { text, root: &root, file };
    let desc = de::description(&src).map_err(in_file_order)?;
    let (mechanism, diags) = rules::check(&desc);
    let diags = diags.into_iter().map(|d| src.place_by_path(d)).collect();
    finish(mechanism, desc, in_file_order(diags))
}

/// Validates an already parsed description. No places are known: `line` and `column` stay
/// `None`, and `path` says where the problem is.
///
/// # Errors
///
/// Every rule of the contract's Validation section that `desc` breaks.
pub fn validate(desc: &MechanismDesc) -> Result<Loaded, Vec<Diagnostic>> {
    let (mechanism, diags) = rules::check(desc);
    finish(mechanism, desc.clone(), diags)
}

fn finish(
    mechanism: Option<model::Mechanism>,
    desc: MechanismDesc,
    diags: Vec<Diagnostic>,
) -> Result<Loaded, Vec<Diagnostic>> {
    let (errors, warnings): (Vec<_>, Vec<_>) =
        diags.into_iter().partition(|d| d.severity == Severity::Error);
    match mechanism {
        Some(mechanism) if errors.is_empty() => Ok(Loaded { mechanism, desc, warnings }),
        _ => Err(errors),
    }
}

fn syntax_errors(
    text: &str,
    format: Format,
    file: Option<&str>,
    unparsed: locate::Unparsed,
) -> Vec<Diagnostic> {
    let empty = locate::Node { span: 0..0, value: locate::Value::Table(Vec::new()) };
    let root = unparsed.partial.as_ref().unwrap_or(&empty);
    let src = de::Source { text, root, file };
    let syntax = match format {
        Format::Toml => "TOML",
        Format::Json => "JSON",
    };
    let diags = unparsed.errors.into_iter().map(|e| {
        let mut message = format!("{syntax} syntax: {}", e.message);
        if format == Format::Toml
            && let Some(open) = open_inline_table(text, e.offset)
        {
            let (line, column) = locate::line_column(text, open);
            let _ = write!(
                message,
                " (inside the inline table `{{ … }}` opened at line {line}, column {column}; \
                 an inline table is written on one line, with `,` between its keys)"
            );
        }
        let diag = Diagnostic::error(message);
        // The entity and field come from the tree recovered around the error; a path into
        // it may name elements that are not in the file, so none is given.
        let placed = src.place(diag, e.offset);
        // Outside every entity (a stray bracket at the top level), the file itself is named.
        let entity = placed.entity.clone().or_else(|| Some("file".to_owned()));
        Diagnostic { path: None, entity, ..placed }
    });
    in_file_order(diags.collect())
}

/// The byte offset of the innermost TOML inline table `{` still open at byte `offset` of
/// `text` (strings and comments skipped), so that a syntax error inside a table written across
/// lines also points at the line where the table opens.
fn open_inline_table(text: &str, offset: usize) -> Option<usize> {
    let mut open = Vec::new();
    let mut chars = text.char_indices().take_while(|&(i, _)| i < offset).peekable();
    while let Some((i, c)) = chars.next() {
        match c {
            '{' => open.push(i),
            '}' => {
                open.pop();
            }
            '#' => while chars.next_if(|&(_, c)| c != '\n').is_some() {},
            '"' | '\'' => {
                // A basic string honours `\` escapes; a literal string does not. Multi-line
                // strings are skipped by the same rule, one delimiter at a time.
                let mut escaped = false;
                for (_, s) in chars.by_ref() {
                    if escaped {
                        escaped = false;
                    } else if s == '\\' && c == '"' {
                        escaped = true;
                    } else if s == c {
                        break;
                    }
                }
            }
            _ => {}
        }
    }
    open.pop()
}

/// Sorts located diagnostics by place; the sort is stable, so problems found at the same
/// place (several missing fields of one table) keep the order the rules found them in.
fn in_file_order(mut diags: Vec<Diagnostic>) -> Vec<Diagnostic> {
    diags.sort_by_key(|d| (d.line.unwrap_or(usize::MAX), d.column.unwrap_or(usize::MAX)));
    diags
}

/// The candidate nearest to `name` within edit distance 2 (and nearer than a rewrite of the
/// whole name), for "did you mean" hints; ties go to the first in order.
pub(crate) fn closest<'a>(
    name: &str,
    candidates: impl IntoIterator<Item = &'a str>,
) -> Option<&'a str> {
    let len = name.chars().count();
    candidates
        .into_iter()
        .map(|c| (edit_distance(name, c), c))
        .filter(|&(d, c)| d > 0 && d <= 2 && d < len.max(c.chars().count()))
        .min_by_key(|&(d, _)| d)
        .map(|(_, c)| c)
}

/// Levenshtein distance in characters.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let above = row[j + 1];
            row[j + 1] = (diagonal + usize::from(ca != cb)).min(row[j] + 1).min(above + 1);
            diagonal = above;
        }
    }
    row[b.len()]
}
