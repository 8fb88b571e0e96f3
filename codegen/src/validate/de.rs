//! The tree → `desc` types, one entity at a time, so that one bad joint does not hide the
//! problems of the next: every unknown field is reported (and skipped so the entity can be
//! read further), then the first other serde error of each entity.
//!
//! The serde `Deserializer` here walks a [`Node`] and gives every error the span of the
//! innermost key or value it came from, which is what places type errors, unknown fields
//! and unknown enum variants in the file.

use std::fmt;
use std::ops::Range;

use serde::de::{
    self, DeserializeOwned, DeserializeSeed, IntoDeserializer, MapAccess, SeqAccess, Unexpected,
    Visitor,
};

use super::closest;
use super::locate::{Entry, Node, Seg, Value, line_column, path_string};
use crate::desc::{
    BodyDesc, ConstraintDesc, DriverDesc, JointDesc, MechanismDesc, PointDesc, SolverDesc, TimeDesc,
};
use crate::diag::Diagnostic;

/// The keys of a description file's top level, as in [`MechanismDesc`].
pub(super) const TOP_FIELDS: &[&str] = &[
    "name",
    "description",
    "time",
    "solver",
    "bodies",
    "joints",
    "constraints",
    "drivers",
    "points",
];

/// Where diagnostics are placed: the text, its tree and the file name for messages.
pub(super) struct Source<'a> {
    /// The whole text.
    pub(super) text: &'a str,
    /// Its tree (possibly partial, after a syntax error).
    pub(super) root: &'a Node,
    /// The file name, only for messages.
    pub(super) file: Option<&'a str>,
}

impl Source<'_> {
    /// Places `diag` at a byte offset; the entity, field and path follow from the tree unless
    /// the diagnostic already names them.
    pub(super) fn place(&self, mut diag: Diagnostic, offset: usize) -> Diagnostic {
        let segs = self.root.path_near(offset);
        let (entity, prefix) = entity_of(self.root, &segs);
        if diag.entity.is_none() {
            diag.entity = entity;
        }
        if diag.field.is_none() {
            let field = field_of(&segs[prefix..]);
            diag.field = (!field.is_empty()).then_some(field);
        }
        if diag.path.is_none() && !segs.is_empty() {
            diag.path = Some(path_string(&segs));
        }
        if diag.span.is_none() {
            diag.span = Some(self.root.token_span(self.text, offset));
        }
        let (line, column) = line_column(self.text, offset);
        diag.at(self.file, line, column)
    }

    /// Places `diag` at the value its `path` names (or the deepest existing node on the way).
    pub(super) fn place_by_path(&self, mut diag: Diagnostic) -> Diagnostic {
        let segs = super::locate::parse_path(diag.path.as_deref().unwrap_or(""));
        let offset = self.root.offset_of(&segs);
        if diag.span.is_none() {
            diag.span = Some(self.root.token_span(self.text, offset));
        }
        let (line, column) = line_column(self.text, offset);
        diag.at(self.file, line, column)
    }
}

/// The entity that `segs` lies in, written as in messages (`joint "O2"`, `time`), and how
/// many leading segments name it.
pub(super) fn entity_of(root: &Node, segs: &[Seg]) -> (Option<String>, usize) {
    match segs {
        [Seg::Key(section), Seg::Index(k), ..] => {
            let Some(kind) = singular(section) else { return (None, 0) };
            let element = root.get(section).and_then(|s| match &s.value {
                Value::Array(items) => items.get(*k),
                _ => None,
            });
            let name = element.and_then(|e| e.get("name")).and_then(|n| match &n.value {
                Value::Str(s) => Some(s.as_str()),
                _ => None,
            });
            let entity = match name {
                Some(name) => format!("{kind} \"{name}\""),
                None => format!("{section}[{k}]"),
            };
            (Some(entity), 2)
        }
        [Seg::Key(section), ..] if section == "time" || section == "solver" => {
            (Some(section.clone()), 1)
        }
        [Seg::Key(key), ..] if key == "name" || key == "description" => (Some(key.clone()), 0),
        // Any other top-level key (an unknown one, say) belongs to the mechanism as a whole.
        [Seg::Key(_), ..] => (Some(mechanism_entity(root)), 0),
        _ => (None, 0),
    }
}

/// The mechanism as a whole, as messages name it: `mechanism "rssr"`, or `mechanism` when the
/// document has no name yet.
fn mechanism_entity(root: &Node) -> String {
    let name = root.get("name").and_then(|n| match &n.value {
        Value::Str(s) => Some(s.as_str()),
        _ => None,
    });
    name.map_or_else(|| "mechanism".to_owned(), |n| format!("mechanism \"{n}\""))
}

/// The entity kind of an array section: `joints` → `joint`.
pub(super) fn singular(section: &str) -> Option<&'static str> {
    match section {
        "bodies" => Some("body"),
        "joints" => Some("joint"),
        "constraints" => Some("constraint"),
        "drivers" => Some("driver"),
        "points" => Some("point"),
        _ => None,
    }
}

/// The field within an entity: its keys joined by dots, without array indices.
fn field_of(segs: &[Seg]) -> String {
    let keys: Vec<&str> = segs
        .iter()
        .filter_map(|s| match s {
            Seg::Key(k) => Some(k.as_str()),
            Seg::Index(_) => None,
        })
        .collect();
    keys.join(".")
}

/// Reads the whole description, or returns every problem serde finds.
pub(super) fn description(src: &Source<'_>) -> Result<MechanismDesc, Vec<Diagnostic>> {
    let mut errors = Vec::new();
    let root = src.root;
    let Value::Table(entries) = &root.value else {
        let message = "the document must be a table (a JSON object) of sections";
        return Err(vec![src.place(Diagnostic::error(message), root.span.start)]);
    };
    let mut name = None;
    let mut description = None;
    let mut time = None;
    let mut solver = None;
    let mut desc_bodies = Vec::new();
    let mut joints = Vec::new();
    let mut constraints = Vec::new();
    let mut drivers = Vec::new();
    let mut points = Vec::new();
    let mut ctx = Reader { src, errors: &mut errors };
    for Entry { key, key_span, node } in entries {
        match key.as_str() {
            "name" => name = ctx.entity::<String>(node),
            "description" => description = ctx.entity::<Option<String>>(node).flatten(),
            "time" => time = ctx.entity::<TimeDesc>(node),
            "solver" => solver = ctx.entity::<Option<SolverDesc>>(node).flatten(),
            "bodies" => desc_bodies = ctx.section::<BodyDesc>(key, node),
            "joints" => joints = ctx.section::<JointDesc>(key, node),
            "constraints" => constraints = ctx.section::<ConstraintDesc>(key, node),
            "drivers" => drivers = ctx.section::<DriverDesc>(key, node),
            "points" => points = ctx.section::<PointDesc>(key, node),
            _ => {
                let message = unknown_field_message(key, TOP_FIELDS);
                let diag = Diagnostic::error(message)
                    .entity(mechanism_entity(root))
                    .field(key.as_str())
                    .path(key.as_str());
                ctx.errors.push(src.place(diag, key_span.start));
            }
        }
    }
    for (key, found, what) in [
        ("name", root.get("name").is_some(), "`name = \"…\"` (the module name)"),
        ("time", root.get("time").is_some(), "the `[time]` section (start, end, step)"),
    ] {
        if !found {
            let message = format!("missing {what}");
            let diag = Diagnostic::error(message).entity(key).field(key).path(key);
            errors.push(src.place(diag, root.span.start));
        }
    }
    match (name, time) {
        (Some(name), Some(time)) if errors.is_empty() => Ok(MechanismDesc {
            name,
            description,
            time,
            solver,
            bodies: desc_bodies,
            joints,
            constraints,
            drivers,
            points,
        }),
        _ => Err(errors),
    }
}

/// Collects the errors of one pass over the document.
struct Reader<'s, 'a> {
    src: &'s Source<'a>,
    errors: &'s mut Vec<Diagnostic>,
}

impl Reader<'_, '_> {
    /// Reads one entity; every unknown field is reported and dropped, then reading goes on
    /// until it succeeds or fails for another reason.
    fn entity<T: DeserializeOwned>(&mut self, node: &Node) -> Option<T> {
        let mut node = node.clone();
        let before = self.errors.len();
        // Each retry removes one key, so this ends.
        loop {
            match T::deserialize(NodeDe(&node)) {
                Ok(value) => return (self.errors.len() == before).then_some(value),
                Err(e) => {
                    let retry = matches!(e.hint, Hint::UnknownField { .. })
                        && e.span.as_ref().is_some_and(|s| node.remove_key(s));
                    self.errors.push(self.diagnostic(e, node.span.start));
                    if !retry {
                        return None;
                    }
                }
            }
        }
    }

    /// Reads an array section (`[[joints]]`) element by element.
    fn section<T: DeserializeOwned>(&mut self, key: &str, node: &Node) -> Vec<T> {
        match &node.value {
            Value::Array(items) => items.iter().filter_map(|item| self.entity(item)).collect(),
            Value::Null => Vec::new(),
            _ => {
                let message = format!(
                    "`{key}` must be an array of tables: write each entry under `[[{key}]]`"
                );
                let diag = Diagnostic::error(message).field(key).path(key);
                self.errors.push(self.src.place(diag, node.span.start));
                Vec::new()
            }
        }
    }

    fn diagnostic(&self, e: Error, fallback: usize) -> Diagnostic {
        let offset = e.span.as_ref().map_or(fallback, |s| s.start);
        let segs = self.src.root.path_near(offset);
        let field = segs.iter().rev().find_map(|s| match s {
            Seg::Key(k) => Some(k.as_str()),
            Seg::Index(_) => None,
        });
        let diag = match e.hint {
            Hint::UnknownField { field, expected } => {
                let diag = Diagnostic::error(unknown_field_message(&field, expected));
                match closest(&field, expected.iter().copied()) {
                    Some(near) => diag.suggest(near),
                    None => diag,
                }
            }
            Hint::MissingField(missing) => {
                let path = format!("{}.{missing}", path_string(&segs));
                Diagnostic::error(format!("missing field `{missing}`")).field(missing).path(path)
            }
            Hint::UnknownVariant { variant, expected } => {
                let mut message = format!(
                    "unknown value \"{variant}\" for `{}`: expected one of {}",
                    field.unwrap_or("?"),
                    expected.join(", ")
                );
                let near = closest(&variant, expected.iter().copied());
                if let Some(near) = near {
                    message = format!("{message}; did you mean \"{near}\"?");
                }
                let diag = Diagnostic::error(message);
                match near {
                    Some(near) => diag.suggest(format!("\"{near}\"")),
                    None => diag,
                }
            }
            Hint::None => Diagnostic::error(plain(&e.message)),
        };
        let diag = Diagnostic { span: e.span.filter(|s| s.start < s.end), ..diag };
        self.src.place(diag, offset)
    }
}

/// Serde's message in the words of the file format: `expected f64` → `expected a number`,
/// `expected struct TimeDesc` → `expected a table`.
fn plain(message: &str) -> String {
    let mut out = message.to_owned();
    if let Some(k) = out.find("expected struct ") {
        out.truncate(k);
        out.push_str("expected a table");
    }
    for (rust, file) in [
        ("expected f64", "expected a number"),
        ("expected u64", "expected a non-negative integer"),
        ("expected u32", "expected a non-negative integer"),
    ] {
        if out.ends_with(rust) {
            out.truncate(out.len() - rust.len());
            out.push_str(file);
        }
    }
    out
}

/// `unknown field `axsi_i`: did you mean `axis_i`?`, or the list of known fields.
pub(super) fn unknown_field_message(field: &str, expected: &[&str]) -> String {
    match closest(field, expected.iter().copied()) {
        Some(near) => format!("unknown field `{field}`: did you mean `{near}`?"),
        None => format!("unknown field `{field}`: expected one of {}", expected.join(", ")),
    }
}

/// A serde error with the span of the innermost node it came from.
#[derive(Debug)]
pub(super) struct Error {
    message: String,
    span: Option<Range<usize>>,
    hint: Hint,
}

/// The errors worth rewording, with what serde tells about them.
#[derive(Debug)]
enum Hint {
    None,
    UnknownField { field: String, expected: &'static [&'static str] },
    MissingField(&'static str),
    UnknownVariant { variant: String, expected: &'static [&'static str] },
}

impl Error {
    /// Gives the error a span unless an inner node already did.
    fn at(mut self, span: &Range<usize>) -> Self {
        if self.span.is_none() {
            self.span = Some(span.clone());
        }
        self
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Error {}

impl de::Error for Error {
    fn custom<T: fmt::Display>(msg: T) -> Self {
        Self { message: msg.to_string(), span: None, hint: Hint::None }
    }

    fn unknown_field(field: &str, expected: &'static [&'static str]) -> Self {
        Self {
            message: format!("unknown field `{field}`"),
            span: None,
            hint: Hint::UnknownField { field: field.to_owned(), expected },
        }
    }

    fn missing_field(field: &'static str) -> Self {
        Self {
            message: format!("missing field `{field}`"),
            span: None,
            hint: Hint::MissingField(field),
        }
    }

    fn unknown_variant(variant: &str, expected: &'static [&'static str]) -> Self {
        Self {
            message: format!("unknown variant `{variant}`"),
            span: None,
            hint: Hint::UnknownVariant { variant: variant.to_owned(), expected },
        }
    }
}

/// Deserialises from a node.
struct NodeDe<'a>(&'a Node);

impl<'de> de::Deserializer<'de> for NodeDe<'_> {
    type Error = Error;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        let node = self.0;
        let result = match &node.value {
            Value::Table(entries) => {
                visitor.visit_map(MapDe { entries: entries.iter(), next: None })
            }
            Value::Array(items) => {
                let mut seq = SeqDe { items: items.iter(), taken: 0 };
                let value = visitor.visit_seq(&mut seq)?;
                let extra = seq.items.len();
                if extra == 0 {
                    Ok(value)
                } else {
                    let message = format!(
                        "invalid length {}, expected an array of length {}",
                        seq.taken + extra,
                        seq.taken
                    );
                    Err(de::Error::custom(message))
                }
            }
            Value::Str(s) => visitor.visit_str(s),
            Value::Int(i) => visitor.visit_i64(*i),
            Value::Float(x) => visitor.visit_f64(*x),
            Value::Bool(b) => visitor.visit_bool(*b),
            Value::Null => visitor.visit_unit(),
            Value::Datetime => {
                Err(de::Error::invalid_type(Unexpected::Other("a date-time"), &visitor))
            }
        };
        result.map_err(|e| e.at(&node.span))
    }

    fn deserialize_option<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        match self.0.value {
            Value::Null => visitor.visit_none(),
            _ => visitor.visit_some(self),
        }
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _name: &'static str,
        _variants: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, Error> {
        let node = self.0;
        match &node.value {
            Value::Str(s) => {
                let unit: de::value::StrDeserializer<'_, Error> = s.as_str().into_deserializer();
                visitor.visit_enum(unit).map_err(|e| e.at(&node.span))
            }
            _ => self.deserialize_any(visitor),
        }
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string
        bytes byte_buf unit unit_struct newtype_struct seq tuple
        tuple_struct map struct identifier ignored_any
    }
}

struct MapDe<'a> {
    entries: std::slice::Iter<'a, Entry>,
    next: Option<&'a Entry>,
}

impl<'de> MapAccess<'de> for MapDe<'_> {
    type Error = Error;

    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, Error> {
        let Some(entry) = self.entries.next() else { return Ok(None) };
        self.next = Some(entry);
        let key: de::value::StrDeserializer<'_, Error> = entry.key.as_str().into_deserializer();
        seed.deserialize(key).map(Some).map_err(|e| e.at(&entry.key_span))
    }

    fn next_value_seed<V: DeserializeSeed<'de>>(&mut self, seed: V) -> Result<V::Value, Error> {
        let entry = self.next.take().ok_or_else(|| de::Error::custom("a value without a key"))?;
        seed.deserialize(NodeDe(&entry.node)).map_err(|e| e.at(&entry.node.span))
    }
}

struct SeqDe<'a> {
    items: std::slice::Iter<'a, Node>,
    taken: usize,
}

impl<'de> SeqAccess<'de> for SeqDe<'_> {
    type Error = Error;

    fn next_element_seed<T: DeserializeSeed<'de>>(
        &mut self,
        seed: T,
    ) -> Result<Option<T::Value>, Error> {
        let Some(item) = self.items.next() else { return Ok(None) };
        self.taken += 1;
        seed.deserialize(NodeDe(item)).map(Some).map_err(|e| e.at(&item.span))
    }

    fn size_hint(&self) -> Option<usize> {
        Some(self.items.len())
    }
}
