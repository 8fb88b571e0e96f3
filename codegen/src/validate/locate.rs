//! The parsed document as one tree of spanned nodes for both TOML and JSON, and the maps
//! between key paths (`joints[2].axis_i`), byte offsets and 1-based (line, column).
//!
//! Every node and every key keeps the byte range it was read from. A TOML `[[joints]]`
//! element and a `[time]` table span only their header line, so a missing field falls back to
//! the header, which is where a user looks for the table.

use std::ops::Range;

use jsonc_parser::ast;
use jsonc_parser::{CollectOptions, ParseOptions};
use toml::de::{DeTable, DeValue};

use super::Format;

/// A value with the byte range it was read from.
#[derive(Clone, Debug)]
pub(super) struct Node {
    /// Byte range in the text.
    pub(super) span: Range<usize>,
    /// The value.
    pub(super) value: Value,
}

/// The values both formats share.
#[derive(Clone, Debug)]
pub(super) enum Value {
    /// A TOML table or a JSON object, entries in file order.
    Table(Vec<Entry>),
    /// An array.
    Array(Vec<Node>),
    /// A string.
    Str(String),
    /// An integer that fits in i64.
    Int(i64),
    /// A float, possibly NaN or infinite (TOML allows `nan` and `inf`).
    Float(f64),
    /// A boolean.
    Bool(bool),
    /// JSON `null`.
    Null,
    /// A TOML date-time, which no field accepts.
    Datetime,
}

/// One key of a table with its value.
#[derive(Clone, Debug)]
pub(super) struct Entry {
    /// The key as written (unquoted).
    pub(super) key: String,
    /// Byte range of the key.
    pub(super) key_span: Range<usize>,
    /// The value.
    pub(super) node: Node,
}

/// One step of a key path.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) enum Seg {
    /// A table key.
    Key(String),
    /// An array index.
    Index(usize),
}

/// A syntax error: the parser's message and where it points.
#[derive(Clone, Debug)]
pub(super) struct SyntaxError {
    /// The parser's message.
    pub(super) message: String,
    /// Byte offset of the offending text.
    pub(super) offset: usize,
}

/// What a failed parse leaves: the errors and, for TOML, the tree recovered around them
/// (used to name the entity the error is in).
pub(super) struct Unparsed {
    /// The partial tree, when the parser could recover.
    pub(super) partial: Option<Node>,
    /// Every syntax error, in file order.
    pub(super) errors: Vec<SyntaxError>,
}

/// Parses `text` into a tree.
pub(super) fn parse(text: &str, format: Format) -> Result<Node, Unparsed> {
    match format {
        Format::Toml => parse_toml(text),
        Format::Json => parse_json(text),
    }
}

fn parse_toml(text: &str) -> Result<Node, Unparsed> {
    let (table, errors) = DeTable::parse_recoverable(text);
    let span = table.span();
    let root = Node { span, value: toml_table(table.get_ref()) };
    if errors.is_empty() {
        return Ok(root);
    }
    // Only the first error: the parser recovers, but what follows a broken value is mostly
    // read as a cascade of errors that are not there.
    let first = errors
        .iter()
        .map(|e| SyntaxError {
            message: e.message().trim_end().to_owned(),
            offset: e.span().map_or(0, |s| s.start),
        })
        .min_by_key(|e| e.offset);
    Err(Unparsed { partial: Some(root), errors: first.into_iter().collect() })
}

fn toml_table(table: &DeTable<'_>) -> Value {
    let mut entries: Vec<Entry> = table
        .iter()
        .map(|(key, value)| Entry {
            key: key.get_ref().to_string(),
            key_span: key.span(),
            node: toml_node(value.span(), value.get_ref()),
        })
        .collect();
    // The parser keeps keys sorted by name; diagnostics and the de-serialisation order want
    // file order.
    entries.sort_by_key(|e| e.key_span.start);
    Value::Table(entries)
}

fn toml_node(span: Range<usize>, value: &DeValue<'_>) -> Node {
    let value = match value {
        DeValue::String(s) => Value::Str(s.to_string()),
        DeValue::Integer(i) => match i64::from_str_radix(i.as_str(), i.radix()) {
            Ok(i) => Value::Int(i),
            // The parser already refuses integers beyond i64; keep the magnitude otherwise.
            Err(_) => Value::Float(i.as_str().parse().unwrap_or(f64::NAN)),
        },
        // `as_str` is in `f64::from_str` form, `nan` and `inf` with their signs included.
        DeValue::Float(f) => Value::Float(f.as_str().parse().unwrap_or(f64::NAN)),
        DeValue::Boolean(b) => Value::Bool(*b),
        DeValue::Datetime(_) => Value::Datetime,
        DeValue::Array(a) => {
            Value::Array(a.iter().map(|v| toml_node(v.span(), v.get_ref())).collect())
        }
        DeValue::Table(t) => toml_table(t),
    };
    Node { span, value }
}

fn parse_json(text: &str) -> Result<Node, Unparsed> {
    // Plain JSON: the extensions jsonc-parser allows by default are refused, so a file that
    // loads here also loads in any other JSON reader.
    let strict = ParseOptions {
        allow_comments: false,
        allow_loose_object_property_names: false,
        allow_trailing_commas: false,
        allow_missing_commas: false,
        allow_single_quoted_strings: false,
        allow_hexadecimal_numbers: false,
        allow_unary_plus_numbers: false,
        allow_bare_decimal_point_numbers: false,
        allow_non_finite_numbers: false,
        allow_extended_string_escapes: false,
    };
    let parsed =
        jsonc_parser::parse_to_ast(text, &CollectOptions::default(), &strict).map_err(|e| {
            Unparsed {
                partial: None,
                errors: vec![SyntaxError {
                    message: e.kind().to_string(),
                    offset: e.range().start,
                }],
            }
        })?;
    let Some(value) = parsed.value else {
        return Err(Unparsed {
            partial: None,
            errors: vec![SyntaxError { message: "the file holds no JSON value".into(), offset: 0 }],
        });
    };
    let mut errors = Vec::new();
    let root = json_node(&value, &mut errors);
    if errors.is_empty() { Ok(root) } else { Err(Unparsed { partial: Some(root), errors }) }
}

fn json_node(value: &ast::Value<'_>, errors: &mut Vec<SyntaxError>) -> Node {
    let (span, value) = match value {
        ast::Value::StringLit(s) => (s.range, Value::Str(s.value.to_string())),
        ast::Value::NumberLit(n) => (n.range, json_number(n.value)),
        ast::Value::BooleanLit(b) => (b.range, Value::Bool(b.value)),
        ast::Value::NullKeyword(n) => (n.range, Value::Null),
        ast::Value::Array(a) => {
            (a.range, Value::Array(a.elements.iter().map(|v| json_node(v, errors)).collect()))
        }
        ast::Value::Object(o) => {
            let mut entries: Vec<Entry> = Vec::with_capacity(o.properties.len());
            for prop in &o.properties {
                let (key, key_span) = match &prop.name {
                    ast::ObjectPropName::String(s) => (s.value.to_string(), s.range),
                    ast::ObjectPropName::Word(w) => (w.value.to_owned(), w.range),
                };
                // TOML refuses duplicate keys while parsing; JSON readers disagree, so refuse
                // them here rather than silently keep one.
                if entries.iter().any(|e| e.key == key) {
                    errors.push(SyntaxError {
                        message: format!("duplicate key `{key}`"),
                        offset: key_span.start,
                    });
                    continue;
                }
                let key_span = key_span.start..key_span.end;
                entries.push(Entry { key, key_span, node: json_node(&prop.value, errors) });
            }
            (o.range, Value::Table(entries))
        }
    };
    Node { span: span.start..span.end, value }
}

fn json_number(text: &str) -> Value {
    match text.parse::<i64>() {
        Ok(i) => Value::Int(i),
        // JSON numbers are decimal, so `f64::from_str` reads every one the parser accepts.
        Err(_) => Value::Float(text.parse().unwrap_or(f64::NAN)),
    }
}

/// Splits `joints[2].law.start` into keys and indices.
pub(super) fn parse_path(path: &str) -> Vec<Seg> {
    let mut segs = Vec::new();
    for part in path.split('.').filter(|p| !p.is_empty()) {
        let mut pieces = part.split('[');
        if let Some(key) = pieces.next().filter(|k| !k.is_empty()) {
            segs.push(Seg::Key(key.to_owned()));
        }
        for index in pieces {
            if let Ok(k) = index.trim_end_matches(']').parse() {
                segs.push(Seg::Index(k));
            }
        }
    }
    segs
}

/// Writes segments as `joints[2].law.start`.
pub(super) fn path_string(segs: &[Seg]) -> String {
    let mut out = String::new();
    for seg in segs {
        match seg {
            Seg::Key(k) if out.is_empty() => out.push_str(k),
            Seg::Key(k) => {
                out.push('.');
                out.push_str(k);
            }
            Seg::Index(k) => out.push_str(&format!("[{k}]")),
        }
    }
    out
}

impl Node {
    /// The value under `key`, if this is a table that has it.
    pub(super) fn get(&self, key: &str) -> Option<&Node> {
        match &self.value {
            Value::Table(entries) => entries.iter().find(|e| e.key == key).map(|e| &e.node),
            _ => None,
        }
    }

    /// Byte offset of the value at `segs`, or of the deepest node on the way when the path
    /// ends early (a missing field falls back to its table).
    pub(super) fn offset_of(&self, segs: &[Seg]) -> usize {
        let mut node = self;
        for seg in segs {
            let next = match (seg, &node.value) {
                (Seg::Key(k), Value::Table(_)) => node.get(k),
                (Seg::Index(k), Value::Array(items)) => items.get(*k),
                _ => None,
            };
            match next {
                Some(n) => node = n,
                None => break,
            }
        }
        node.span.start
    }

    /// The path of the deepest key or value whose span holds `offset`; for an offset outside
    /// every span (a syntax error), the table or array element whose header comes last before
    /// it, as TOML places everything after a header in that table.
    pub(super) fn path_near(&self, offset: usize) -> Vec<Seg> {
        let mut best = Vec::new();
        let mut path = Vec::new();
        deepest(self, offset, &mut path, &mut best);
        if !best.is_empty() {
            return best;
        }
        let Value::Table(entries) = &self.value else { return best };
        let mut start = 0;
        for entry in entries {
            let mut consider = |segs: Vec<Seg>, at: usize| {
                if at <= offset && at >= start {
                    start = at;
                    best = segs;
                }
            };
            consider(vec![Seg::Key(entry.key.clone())], entry.key_span.start);
            consider(vec![Seg::Key(entry.key.clone())], entry.node.span.start);
            if let Value::Array(items) = &entry.node.value {
                for (k, item) in items.iter().enumerate() {
                    consider(vec![Seg::Key(entry.key.clone()), Seg::Index(k)], item.span.start);
                }
            }
        }
        best
    }

    /// The byte range of the text at `offset`: the smallest key or value that starts there,
    /// else the word (letters, digits, `_`, `.`, `-`, `+`) or the single character there.
    pub(super) fn token_span(&self, text: &str, offset: usize) -> Range<usize> {
        let mut offset = offset.min(text.len());
        while !text.is_char_boundary(offset) {
            offset -= 1;
        }
        let mut best: Option<Range<usize>> = None;
        starting_at(self, offset, &mut best);
        best.unwrap_or_else(|| {
            let rest = &text[offset..];
            let word = |c: char| c.is_alphanumeric() || "_.-+".contains(c);
            let len = match rest.find(|c: char| !word(c)) {
                Some(0) => rest.chars().next().map_or(0, char::len_utf8),
                Some(k) => k,
                None => rest.len(),
            };
            offset..offset + len
        })
    }

    /// Removes the table entry whose key was read from `key_span`; true if one was found.
    pub(super) fn remove_key(&mut self, key_span: &Range<usize>) -> bool {
        match &mut self.value {
            Value::Table(entries) => {
                if let Some(k) = entries.iter().position(|e| e.key_span == *key_span) {
                    entries.remove(k);
                    return true;
                }
                entries.iter_mut().any(|e| e.node.remove_key(key_span))
            }
            Value::Array(items) => items.iter_mut().any(|n| n.remove_key(key_span)),
            _ => false,
        }
    }
}

/// The smallest non-empty key or value span of the tree that starts at `offset`.
fn starting_at(node: &Node, offset: usize, best: &mut Option<Range<usize>>) {
    let consider = |span: &Range<usize>, best: &mut Option<Range<usize>>| {
        if span.start == offset
            && span.end > span.start
            && best.as_ref().is_none_or(|b| span.len() < b.len())
        {
            *best = Some(span.clone());
        }
    };
    consider(&node.span, best);
    match &node.value {
        Value::Table(entries) => {
            for entry in entries {
                consider(&entry.key_span, best);
                starting_at(&entry.node, offset, best);
            }
        }
        Value::Array(items) => items.iter().for_each(|n| starting_at(n, offset, best)),
        _ => {}
    }
}

fn holds(span: &Range<usize>, offset: usize) -> bool {
    span.start <= offset && offset < span.end.max(span.start + 1)
}

fn deepest(node: &Node, offset: usize, path: &mut Vec<Seg>, best: &mut Vec<Seg>) {
    if holds(&node.span, offset) && path.len() >= best.len() {
        best.clone_from(path);
    }
    match &node.value {
        Value::Table(entries) => {
            for entry in entries {
                path.push(Seg::Key(entry.key.clone()));
                if holds(&entry.key_span, offset) && path.len() >= best.len() {
                    best.clone_from(path);
                }
                deepest(&entry.node, offset, path, best);
                path.pop();
            }
        }
        Value::Array(items) => {
            for (k, item) in items.iter().enumerate() {
                path.push(Seg::Index(k));
                deepest(item, offset, path, best);
                path.pop();
            }
        }
        _ => {}
    }
}

/// The 1-based line and column (in characters) of a byte offset.
pub(super) fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line_start = before.rfind('\n').map_or(0, |k| k + 1);
    let line = before.matches('\n').count() + 1;
    let column = before[line_start..].chars().count() + 1;
    (line, column)
}
