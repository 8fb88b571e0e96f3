//! The character set of names and descriptions, and the words a mechanism may not be named.
//!
//! Names (of the mechanism, bodies, joints, constraints, drivers and points) reach generated
//! code only inside string constants, and messages, tables and CSV headers show them to
//! people; so a name is 1 to [`MAX_NAME_CHARS`] characters, none of them a control character
//! (C0, DEL, C1), a line or paragraph separator, or an invisible format character (bidi
//! controls, zero-width characters, the byte-order mark and the rest of Unicode's category
//! Cf), which would make two names look alike or a line read in another order.
//!
//! The mechanism's name is also a Rust module name and, in upper camel case, the name of the
//! generated type (`four_bar` → `FourBar`): besides `[a-z][a-z0-9_]*` it may not be a Rust
//! keyword or reserved word, the name of a crate the generated code refers to, or a name
//! whose type name is one the generated module defines or relies on from the prelude.
//!
//! A description is free text and may hold any printable character, tabs and line breaks; it
//! is refused only for other control characters, line and paragraph separators and bidi
//! controls (which rustc refuses in comments, and which mislead readers of the generated
//! code). It reaches generated code only as documentation built from escaped string literals.

/// The most characters a name may have.
pub const MAX_NAME_CHARS: usize = 64;

/// Rust's strict and reserved keywords of every edition.
const KEYWORDS: [&str; 51] = [
    "as", "async", "await", "break", "const", "continue", "crate", "dyn", "else", "enum", "extern",
    "false", "fn", "for", "if", "impl", "in", "let", "loop", "match", "mod", "move", "mut", "pub",
    "ref", "return", "self", "static", "struct", "super", "trait", "true", "type", "unsafe", "use",
    "where", "while", "abstract", "become", "box", "do", "final", "macro", "override", "priv",
    "typeof", "unsized", "virtual", "yield", "try", "gen",
];

/// Crates the generated code names by path (`runtime::…`, `core::…`), which a module of the
/// same name would shadow at the crate root where `codegen::build` declares it.
const CRATES: [&str; 4] = ["alloc", "core", "runtime", "std"];

/// Type names the generated module defines (its constants share the value namespace with the
/// unit struct), and prelude names it uses; `emit` has a test that every constant it emits
/// is here.
pub const RESERVED_TYPE_NAMES: [&str; 33] = [
    "N",
    "BODIES",
    "POINTS",
    "JOINTS",
    "UNKNOWNS",
    "EQUATIONS",
    "TOLERANCE",
    "Q0",
    "Self",
    "Option",
    "Some",
    "None",
    "Result",
    "Ok",
    "Err",
    "Clone",
    "Copy",
    "Debug",
    "Default",
    "Send",
    "Sync",
    "Sized",
    "Drop",
    "Fn",
    "FnMut",
    "FnOnce",
    "Eq",
    "PartialEq",
    "Ord",
    "PartialOrd",
    "Hash",
    "Iterator",
    "From",
];

/// Whether `c` is a bidi control: embeddings, overrides, isolates and marks.
fn is_bidi(c: char) -> bool {
    matches!(c, '\u{061C}' | '\u{200E}' | '\u{200F}' | '\u{202A}'..='\u{202E}' | '\u{2066}'..='\u{2069}')
}

/// Whether `c` is in Unicode's category Cf (format characters: invisible, they change how
/// the text around them is shown or joined), as of Unicode 15.1.
fn is_format(c: char) -> bool {
    matches!(
        c,
        '\u{00AD}'
            | '\u{0600}'..='\u{0605}'
            | '\u{061C}'
            | '\u{06DD}'
            | '\u{070F}'
            | '\u{0890}'..='\u{0891}'
            | '\u{08E2}'
            | '\u{180E}'
            | '\u{200B}'..='\u{200F}'
            | '\u{202A}'..='\u{202E}'
            | '\u{2060}'..='\u{2064}'
            | '\u{2066}'..='\u{206F}'
            | '\u{FEFF}'
            | '\u{FFF9}'..='\u{FFFB}'
            | '\u{110BD}'
            | '\u{110CD}'
            | '\u{13430}'..='\u{1343F}'
            | '\u{1BCA0}'..='\u{1BCA3}'
            | '\u{1D173}'..='\u{1D17A}'
            | '\u{E0001}'
            | '\u{E0020}'..='\u{E007F}'
    )
}

/// Whether `c` is a line or paragraph separator (U+2028, U+2029).
fn is_separator(c: char) -> bool {
    matches!(c, '\u{2028}' | '\u{2029}')
}

/// Whether `c` cannot be shown as it is in a name or a comment: a control character, a
/// format character or a line or paragraph separator.
#[must_use]
pub fn hidden(c: char) -> bool {
    c.is_control() || is_format(c) || is_separator(c)
}

/// `U+202E`.
fn code_point(c: char) -> String {
    format!("U+{:04X}", u32::from(c))
}

/// Why `name` is not a valid name, if it is not.
pub fn name_problem(name: &str) -> Option<String> {
    let count = name.chars().count();
    if count == 0 {
        return Some("a name must not be empty".to_owned());
    }
    if count > MAX_NAME_CHARS {
        return Some(format!("a name has at most {MAX_NAME_CHARS} characters, this one {count}"));
    }
    let (k, c) = name.chars().enumerate().find(|&(_, c)| hidden(c))?;
    let what = if c.is_control() {
        "a control character"
    } else if is_bidi(c) {
        "a bidi control"
    } else if is_separator(c) {
        "a line or paragraph separator"
    } else {
        "an invisible format character"
    };
    Some(format!(
        "character {} of the name is {what} ({}): names are printable text without control or \
         invisible characters",
        k + 1,
        code_point(c)
    ))
}

/// Why the mechanism's name, already known to match `[a-z][a-z0-9_]*`, cannot name the
/// generated module and type, if it cannot; `type_name` is its upper camel case.
pub fn mechanism_name_problem(name: &str, type_name: &str) -> Option<String> {
    if name.len() > MAX_NAME_CHARS {
        return Some(format!(
            "the name has at most {MAX_NAME_CHARS} characters, this one {}",
            name.len()
        ));
    }
    if KEYWORDS.contains(&name) {
        return Some(format!(
            "\"{name}\" is a Rust keyword and cannot name the generated module, e.g. \"{name}_mechanism\""
        ));
    }
    if CRATES.contains(&name) {
        return Some(format!(
            "\"{name}\" is the name of a crate the generated code uses, e.g. \"{name}_mechanism\""
        ));
    }
    if RESERVED_TYPE_NAMES.contains(&type_name) {
        return Some(format!(
            "the generated type would be named `{type_name}`, which the generated module \
             defines or uses already, e.g. \"{name}_mechanism\""
        ));
    }
    None
}

/// Why an input driver's name cannot name the field of the generated module's `Inputs` that
/// holds it, if it cannot: it must be a lower-case identifier (`[a-z][a-z0-9_]*`) and no Rust
/// keyword.
pub fn input_name_problem(name: &str) -> Option<String> {
    let mut chars = name.chars();
    let identifier = chars.next().is_some_and(|c| c.is_ascii_lowercase())
        && chars.all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_');
    if !identifier {
        return Some(
            "an input driver's name names the field of the generated `Inputs` that holds its \
             value: it must be a lower-case identifier ([a-z][a-z0-9_]*), e.g. \"crank_angle\""
                .to_owned(),
        );
    }
    if KEYWORDS.contains(&name) {
        return Some(format!(
            "\"{name}\" is a Rust keyword and cannot name the field of the generated `Inputs` \
             that holds this input, e.g. \"{name}_input\""
        ));
    }
    (name.len() > MAX_NAME_CHARS)
        .then(|| format!("a name has at most {MAX_NAME_CHARS} characters, this one {}", name.len()))
}

/// Why `text` cannot be a description, if it cannot.
pub fn description_problem(text: &str) -> Option<String> {
    let (k, c) = text.chars().enumerate().find(|&(_, c)| {
        (c.is_control() && !matches!(c, '\t' | '\n' | '\r')) || is_bidi(c) || is_separator(c)
    })?;
    let what = if is_bidi(c) {
        "a bidi control, which would make the generated code read in another order than it runs"
    } else if is_separator(c) {
        "a line or paragraph separator: write a newline"
    } else {
        "a control character: a description is printable text, tabs and newlines"
    };
    Some(format!("character {} of the description is {} {what}", k + 1, code_point(c)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn printable_names_pass_and_invisible_ones_do_not() {
        for ok in ["O2", "crank", "b ar", "Kurbel Ü", "θ₁", "*/", "\"#", "n", "self"] {
            assert_eq!(name_problem(ok), None, "{ok:?}");
        }
        for (bad, why) in [
            ("", "empty"),
            ("a\nb", "control"),
            ("a\rb", "control"),
            ("a\u{7f}", "control"),
            ("a\u{85}", "control"),
            ("a\u{202e}b", "bidi"),
            ("a\u{200b}b", "invisible"),
            ("\u{feff}a", "invisible"),
            ("a\u{2028}", "separator"),
        ] {
            let message = name_problem(bad).unwrap_or_else(|| panic!("{bad:?} accepted"));
            assert!(message.contains(why), "{bad:?}: {message}");
        }
        let long = "x".repeat(MAX_NAME_CHARS + 1);
        assert!(name_problem(&long).is_some_and(|m| m.contains("at most 64")));
        assert_eq!(name_problem(&"x".repeat(MAX_NAME_CHARS)), None);
    }

    #[test]
    fn descriptions_keep_printable_text_and_line_breaks() {
        assert_eq!(description_problem("a\tb\r\nc\rd */ \"# `x` \u{200d}"), None);
        assert!(description_problem("a\u{202e}b").is_some_and(|m| m.contains("bidi")));
        assert!(description_problem("a\u{1b}[2J").is_some_and(|m| m.contains("U+001B")));
        assert!(description_problem("a\u{2029}").is_some_and(|m| m.contains("separator")));
    }

    #[test]
    fn mechanism_names_that_would_break_the_module_are_refused() {
        assert!(mechanism_name_problem("self", "Self").is_some());
        assert!(mechanism_name_problem("fn", "Fn").is_some());
        assert!(mechanism_name_problem("runtime", "Runtime").is_some());
        assert!(mechanism_name_problem("q_0", "Q0").is_some());
        assert!(mechanism_name_problem("some", "Some").is_some());
        assert_eq!(mechanism_name_problem("four_bar", "FourBar"), None);
        assert_eq!(mechanism_name_problem("bodies", "Bodies"), None);
    }
}
