//! The thesis' legacy input decks (YOUNG) → descriptions, and descriptions → readable TOML.
//!
//! A deck is a free-format stream of whitespace-separated numbers (the program reads it with
//! Pascal `READ`, so line breaks do not matter): a header of 12 counts
//! `NBODY NDRIVE NPOINT NSPHER NUNIVE NREVOL NCYLIN NTRANS NSCREW NSIMPL NSIMP2 NGROUN`, then
//! the records of each kind in a fixed order (numbered 1 to 13 as in
//! `tests/reference/young-program.md` §2.4), ending with the time line `Ti Te dT`. Anything
//! after the time line is ignored; the thesis' decks carry free-text comments there.
//!
//! The mapping follows the contract (`docs/contract.md` §2):
//!
//! | record | tokens | becomes |
//! |---|---|---|
//! | 1 body | `x y z e0 e1 e2 e3` | `bodyK` with `r = [x, y, z]`, `p = [e0, e1, e2, e3]` |
//! | 2 driver | `body dir C B A` | `driverK`, absolute: `coordinate` x, y, z, rx, ry, rz; `law = { start = C, velocity = B, acceleration = A }` |
//! | 3 point | `body ξ η ζ` | `pointK` |
//! | 4 spherical | `i j Pi Pj` | `sphericalK` |
//! | 5–7 universal, revolute, cylindrical | `i j Pi Pj Qi Qj` | `axis = Q − P` |
//! | 8 translational | `i j Pi Pj Qi Qj Hi Hj` | `prismaticK`, `axis = Q − P`, `ref = H − P` |
//! | 9 screw | `i j Pi Pj Si Sj Ui Uj α` | `screwK`, `axis = S`, `ref = U` (no `− P`), `lead = 2π·α` |
//! | 10 simplified | `body dir c` | `simplifiedK`, `fix` of x, y, z, or e1, e2, e3 = sin(c/2) |
//! | 11 distance | `bodyI bodyJ dir D` | `differenceK`, `coordinate_difference` of x, y, z, e1, e2, e3 with the raw D |
//! | 12 grounded | `body x y z α β δ` | that body gets `ground = true`, `r = [x, y, z]`, `p` from the angles |
//! | 13 time | `Ti Te dT` | `[time]` start, end, step |
//!
//! Joints are numbered per type in deck order. Differences such as `Q − P` are taken from the
//! deck's decimal text and rounded once, so `−0.05 − (−0.0475)` gives `−0.0025`, where plain
//! `f64` subtraction gives `−0.0025000000000000022`: the two differ by about an ulp, which does
//! not change the mechanism, but the first is what the deck means and reads better.
//!
//! The distance constraint keeps its raw value for directions 4–6 because YOUNG subtracts Euler
//! parameters directly there (young-program.md §5.8), while simplified constraints and grounded
//! bodies take the thesis' sin(c/2) (§5.7).
//!
//! A grounded body's angles α, β, δ give `e_k = sin(angle/2)` for the vector part, as YOUNG's six
//! simplified constraints do, and `e0 = +√(1 − e1² − e2² − e3²)`. YOUNG leaves the sign of e0 to
//! the body's initial estimate; the positive root is chosen here because a ground body has no
//! initial estimate to take it from, and both signs describe the same orientation. The body
//! record of a grounded body is then not used. Every thesis deck uses zero angles.
//!
//! YOUNG's hard limits (10 bodies, 3 joints of each type, …) and its equation-count check are
//! not applied: the description format has no such limits, and `validate` counts equations.

use std::path::Path;

use crate::desc::MechanismDesc;
use crate::diag::Diagnostic;
use records::Parser;

mod layout;
mod lex;
mod records;
mod toml;

pub use toml::to_toml;
#[cfg(test)]
mod tests;

/// Counts above this are refused before anything is read for them; the thesis' program
/// allows at most 70 equations, so any real deck is far below it.
const MAX_COUNT: i64 = 100_000;

/// The header's counts, in deck order.
const COUNT_NAMES: [&str; 12] = [
    "NBODY", "NDRIVE", "NPOINT", "NSPHER", "NUNIVE", "NREVOL", "NCYLIN", "NTRANS", "NSCREW",
    "NSIMPL", "NSIMP2", "NGROUN",
];

/// Parses a legacy deck into the equivalent description.
///
/// `name` names the deck, usually its file stem (`"4-bar"`). It is quoted in the description's
/// `description` and, sanitised as by [`name_from_path`] (`"4-bar"` → `"four_bar"`), becomes the
/// description's `name`. Entities are named `body1`, `revolute1`, `simplified1`, `driver1`,
/// `point1`, … as the contract's §2 says.
///
/// # Errors
///
/// Returns a [`Diagnostic`] for the first token that cannot be read: a token that is not a
/// number (or not an integer where YOUNG reads one), a count that is negative or above 100,000,
/// a body number out of range, a direction outside 1–6, a body grounded twice, ground angles
/// that no unit Euler parameters satisfy, or a deck that ends early. The diagnostic names the
/// record (`revolute joint 2 (record 6)`) as its entity, the field (`Qi.y`), the token's index
/// in its message, and the token's line and column.
#[expect(
    clippy::result_large_err,
    reason = "the contract's API returns the crate's Diagnostic by value; it is built once, on failure"
)]
pub fn import(deck: &str, name: &str) -> Result<MechanismDesc, Diagnostic> {
    Parser::new(deck).deck(name).map_err(|diag| *diag)
}

/// Reads the deck at `path` and imports it as [`import`] does, naming the description with
/// [`name_from_path`] and saying in its `description` which file it came from.
///
/// # Errors
///
/// Returns a [`Diagnostic`] when the file cannot be read, or the diagnostic of [`import`] with
/// the file set to `path`. Bytes that are not UTF-8 are read as U+FFFD, so binary input gives
/// an ordinary bad-token diagnostic.
#[expect(
    clippy::result_large_err,
    reason = "the same Diagnostic as `import` returns, with the file set"
)]
pub fn import_file(path: &Path) -> Result<MechanismDesc, Diagnostic> {
    let shown = path.display().to_string();
    let bytes = crate::validate::read_bounded(path, "deck")
        .map_err(|message| Diagnostic::error(message).entity("deck").at(Some(&shown), 1, 1))?;
    let text = String::from_utf8_lossy(&bytes);
    let mut desc = import(&text, &name_from_path(path)).map_err(|mut diag| {
        diag.file = Some(shown.clone());
        diag
    })?;
    let file_name = path.file_name().map_or(shown.clone(), |f| f.to_string_lossy().into_owned());
    desc.description = Some(format!("Imported from the YOUNG deck {file_name}"));
    Ok(desc)
}

/// The description name for a deck file: its stem, lowercased, with every run of other
/// characters than `a-z0-9` turned into one `_`.
///
/// A leading number is spelled out when a word follows it (`4-bar` → `four_bar`,
/// `5body` → `five_body`); otherwise the name gets the prefix `ex_` (`2-6-1` → `ex_2_6_1`).
/// An empty result becomes `mechanism`.
#[must_use]
pub fn name_from_path(path: &Path) -> String {
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    sanitise(&stem)
}

/// Makes `raw` a valid description name (`[a-z][a-z0-9_]*`), as described at
/// [`name_from_path`].
fn sanitise(raw: &str) -> String {
    let mut name = String::new();
    for c in raw.chars() {
        let c = c.to_ascii_lowercase();
        if c.is_ascii_lowercase() || c.is_ascii_digit() {
            name.push(c);
        } else if !name.is_empty() && !name.ends_with('_') {
            name.push('_');
        }
    }
    while name.ends_with('_') {
        name.pop();
    }
    if name.is_empty() {
        return "mechanism".to_owned();
    }
    if !name.starts_with(|c: char| c.is_ascii_digit()) {
        return name;
    }
    let digits = name.find(|c: char| !c.is_ascii_digit()).unwrap_or(name.len());
    let rest = name[digits..].trim_start_matches('_');
    let word_follows = rest.starts_with(|c: char| c.is_ascii_lowercase());
    match number_word(&name[..digits]) {
        Some(word) if word_follows => format!("{word}_{rest}"),
        _ => format!("ex_{name}"),
    }
}

/// The English word for a small number written in digits.
fn number_word(digits: &str) -> Option<&'static str> {
    const WORDS: [&str; 13] = [
        "zero", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten",
        "eleven", "twelve",
    ];
    digits.parse::<usize>().ok().and_then(|n| WORDS.get(n).copied())
}
