//! Diagnostics about user input: what is wrong, with which entity and field, and where.

use std::fmt;

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
        match (&self.entity, &self.field) {
            (Some(e), Some(fl)) => write!(f, "{e}, field `{fl}`: ")?,
            (Some(e), None) => write!(f, "{e}: ")?,
            (None, Some(fl)) => write!(f, "field `{fl}`: ")?,
            (None, None) => {}
        }
        f.write_str(&self.message)
    }
}
