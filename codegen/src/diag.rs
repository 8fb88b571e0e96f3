//! Diagnostics about user input: what is wrong, with which entity and field, and where.
//!
//! A [`Diagnostic`] prints on one line through `Display` (`file:line:column: error: …`); with the
//! text it came from, [`render`] shows it as a compiler would: the place, the line with a caret
//! under the offending text and, where the fix is likely, the corrected line.

use std::fmt;
use std::ops::Range;

use serde::Serialize;

/// How serious a diagnostic is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Severity {
    /// The input is refused; nothing is analysed.
    Error,
    /// The input is accepted; the user should look.
    Warning,
}

/// One problem found in a description file or a legacy deck.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Diagnostic {
    /// Error or warning.
    pub severity: Severity,
    /// A sentence saying what is wrong and, where one is likely, the fix.
    pub message: String,
    /// The entity, written as in the file: `joint "O2"`, `body "crank"`, `time`.
    pub entity: Option<String>,
    /// The field within the entity: `axis_i`.
    pub field: Option<String>,
    /// The key path in the document, used to find the place: `joints[0].axis_i`.
    pub path: Option<String>,
    /// The file the input came from, as given on the command line.
    pub file: Option<String>,
    /// 1-based line of the offending text.
    pub line: Option<usize>,
    /// 1-based column (in characters) of the offending text.
    pub column: Option<usize>,
    /// Byte range of the offending text in the file (a key, a value or a table header).
    pub span: Option<Range<usize>>,
    /// The text that likely should replace [`span`](Self::span): `axis_i` for a misspelt
    /// `axsi_i`, `"crank"` for `"crnak"`.
    pub suggestion: Option<String>,
}

impl Diagnostic {
    /// An error with only a message.
    #[must_use]
    pub fn error(message: impl Into<String>) -> Self {
        Self {
            severity: Severity::Error,
            message: message.into(),
            entity: None,
            field: None,
            path: None,
            file: None,
            line: None,
            column: None,
            span: None,
            suggestion: None,
        }
    }

    /// A warning with only a message.
    #[must_use]
    pub fn warning(message: impl Into<String>) -> Self {
        Self { severity: Severity::Warning, ..Self::error(message) }
    }

    /// Names the entity.
    #[must_use]
    pub fn entity(mut self, entity: impl Into<String>) -> Self {
        self.entity = Some(entity.into());
        self
    }

    /// Names the field.
    #[must_use]
    pub fn field(mut self, field: impl Into<String>) -> Self {
        self.field = Some(field.into());
        self
    }

    /// Sets the key path used to locate the diagnostic in the file.
    #[must_use]
    pub fn path(mut self, path: impl Into<String>) -> Self {
        self.path = Some(path.into());
        self
    }

    /// Sets the place in the file.
    #[must_use]
    pub fn at(mut self, file: Option<&str>, line: usize, column: usize) -> Self {
        self.file = file.map(str::to_owned);
        self.line = Some(line);
        self.column = Some(column);
        self
    }

    /// Sets the text that likely should replace the offending text.
    #[must_use]
    pub fn suggest(mut self, replacement: impl Into<String>) -> Self {
        self.suggestion = Some(replacement.into());
        self
    }

    /// The entity and field as a prefix of the message: `joint "O2", field `axis_i`: `.
    fn context(&self) -> String {
        match (&self.entity, &self.field) {
            (Some(e), Some(fl)) => format!("{e}, field `{fl}`: "),
            (Some(e), None) => format!("{e}: "),
            (None, Some(fl)) => format!("field `{fl}`: "),
            (None, None) => String::new(),
        }
    }

    /// The JSON object of the contract's `{ "error": { "kind": "invalid_input", … } }`.
    #[must_use]
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "kind": "invalid_input",
            "message": self.message,
            "entity": self.entity,
            "field": self.field,
            "line": self.line,
            "column": self.column,
        })
    }
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (&self.file, self.line, self.column) {
            (Some(file), Some(line), Some(col)) => write!(f, "{file}:{line}:{col}: ")?,
            (Some(file), _, _) => write!(f, "{file}: ")?,
            (None, Some(line), Some(col)) => write!(f, "{line}:{col}: ")?,
            _ => {}
        }
        f.write_str(match self.severity {
            Severity::Error => "error: ",
            Severity::Warning => "warning: ",
        })?;
        f.write_str(&self.context())?;
        f.write_str(&self.message)
    }
}

/// Renders diagnostics for a person: each one titled with its severity, entity, field and
/// message, then, when `source` is the text the diagnostics were found in and a diagnostic has
/// a span, the file, line and column, the line with a caret under the offending text and, for
/// a likely fix, the line as it would read corrected. A diagnostic without a span prints as
/// its one-line `Display` form. ANSI colours only when `color` is set.
///
/// ```
/// use codegen::diag::{render, Diagnostic};
///
/// let text = "name = \"demo\"\nstpe = 0.1\n";
/// let mut d = Diagnostic::error("unknown field `stpe`: did you mean `step`?")
///     .entity("time")
///     .suggest("step")
///     .at(Some("demo.toml"), 2, 1);
/// d.span = Some(14..18);
/// let shown = render(&[d], Some(text), false);
/// assert!(shown.starts_with("error: time: unknown field `stpe`: did you mean `step`?\n"));
/// assert!(shown.contains(" --> demo.toml:2:1\n"));
/// assert!(shown.contains("2 | stpe = 0.1\n  | ^^^^\n"));
/// assert!(shown.contains("2 + step = 0.1"));
/// ```
#[must_use]
pub fn render(diags: &[Diagnostic], source: Option<&str>, color: bool) -> String {
    use annotate_snippets::{AnnotationKind, Group, Level, Patch, Renderer, Snippet};

    let renderer = if color { Renderer::styled() } else { Renderer::plain() };
    let mut out = String::new();
    for d in diags {
        let located = source.zip(d.span.clone()).filter(|(text, span)| {
            span.start <= span.end
                && span.end <= text.len()
                && text.is_char_boundary(span.start)
                && text.is_char_boundary(span.end)
        });
        let Some((text, span)) = located else {
            out.push_str(&d.to_string());
            out.push('\n');
            continue;
        };
        let span = single_line(text, span);
        let level = match d.severity {
            Severity::Error => Level::ERROR,
            Severity::Warning => Level::WARNING,
        };
        let title = format!("{}{}", d.context(), d.message);
        let path = d.file.as_deref().unwrap_or("<input>");
        let mut report: Vec<Group<'_>> =
            vec![
                level.primary_title(title).element(
                    Snippet::source(text)
                        .path(path)
                        .annotation(AnnotationKind::Primary.span(span.clone())),
                ),
            ];
        if let Some(fix) = &d.suggestion {
            report.push(
                Level::HELP.secondary_title(format!("replace with `{fix}`")).element(
                    Snippet::source(text).path(path).patch(Patch::new(span, fix.as_str())),
                ),
            );
        }
        if !out.is_empty() {
            out.push('\n');
        }
        out.push_str(&renderer.render(&report));
        out.push('\n');
    }
    out
}

/// `text` made safe to show on a terminal: the replacements [`render`] applies to its
/// excerpts (annotate-snippets' `normalize_untrusted_str`: control characters as their
/// Unicode pictures, ␛ for ESC, a tab as four spaces, bidi embeddings and isolates as �, the
/// zero-width joiner removed), and also a line feed as ␤, C1 controls, bidi marks and the
/// other zero-width and invisible format characters as �. Names written into the table and
/// the text outputs go through it, so a name shows the same there as in a diagnostic and
/// can neither move the cursor nor reorder what follows it.
///
/// ```
/// use codegen::diag::printable;
///
/// assert_eq!(printable("crank"), "crank");
/// assert_eq!(printable("a\u{1b}[2Jb\nc\u{202e}d\u{200b}"), "a␛[2Jb␤c�d�");
/// ```
#[must_use]
pub fn printable(text: &str) -> std::borrow::Cow<'_, str> {
    let hidden = |c: char| {
        c == '\n'
            || ('\u{80}'..='\u{9f}').contains(&c)
            || matches!(
                c,
                '\u{ad}'
                    | '\u{61c}'
                    | '\u{180e}'
                    | '\u{200b}'..='\u{200f}'
                    | '\u{2028}'..='\u{202e}'
                    | '\u{2060}'..='\u{206f}'
                    | '\u{feff}'
                    | '\u{fff9}'..='\u{fffb}'
            )
    };
    if !text.chars().any(|c| c.is_control() || hidden(c)) {
        return std::borrow::Cow::Borrowed(text);
    }
    std::borrow::Cow::Owned(
        annotate_snippets::normalize_untrusted_str(text)
            .chars()
            .map(|c| match c {
                '\n' => '␤',
                c if hidden(c) => '\u{fffd}',
                c => c,
            })
            .collect(),
    )
}

/// `span` cut at the end of its first line, and at least one character long where the line
/// has one, so that the caret stays under the offending text.
fn single_line(text: &str, span: Range<usize>) -> Range<usize> {
    let line_end = text[span.start..].find('\n').map_or(text.len(), |k| span.start + k);
    let mut end = span.end.min(line_end);
    if end == span.start && end < line_end {
        end += text[end..].chars().next().map_or(0, char::len_utf8);
    }
    span.start..end
}
