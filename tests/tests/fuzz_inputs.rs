//! Fuzzing the description loader (TOML and JSON) and the legacy deck importer with proptest:
//! random bytes and random mutations of the shipped examples and decks. Every input must give
//! a description or located errors, without a panic, within a time bound, and with memory
//! bounded by a small multiple of its size (measured by a counting global allocator, which is
//! why this is a test target of its own).
//!
//! The budget is 256 cases per family (under a second in all); a longer campaign runs with
//! `PROPTEST_CASES=100000 cargo test -p tests --test fuzz_inputs` (README, Limits).

use std::time::{Duration, Instant};

use codegen::validate::{Format, load_str};
use counting::peak_of;
use proptest::prelude::*;

mod counting;

/// The most a loader may take for one input: well above the linear passes it makes (a parse
/// tree, a located tree, the description, the model, the diagnostics), far below what an
/// allocation sized by a number in the input (a grid of 10⁷ points, say) would take.
fn memory_bound(input_len: usize) -> usize {
    200 * input_len + (4 << 20)
}

/// A hang shows as a case taking this long (the inputs are at most tens of KiB).
const TIME_BOUND: Duration = Duration::from_secs(2);

/// Runs `f` on `input`, checking time and extra peak memory, and returns its result.
fn bounded<T>(what: &str, input: &str, f: impl FnOnce() -> T) -> T {
    // Timed inside the measurement, so that waiting for another test's measurement is not.
    let ((result, elapsed), extra) = peak_of(|| {
        let started = Instant::now();
        let result = f();
        (result, started.elapsed())
    });
    assert!(elapsed < TIME_BOUND, "{what} took {elapsed:?} on {} bytes", input.len());
    assert!(
        extra <= memory_bound(input.len()),
        "{what} took {extra} bytes on an input of {} bytes",
        input.len()
    );
    result
}

/// Loads `text` as a description; errors must each carry a message and, for files, a place.
fn load(text: &str, format: Format) {
    let result = bounded("load_str", text, || load_str(text, format, Some("fuzz")));
    match result {
        Ok(loaded) => {
            // A valid description must also survive the generic engine's preparation.
            let eq = codegen::generic::Equations::new(&loaded.mechanism);
            let _ = eq.prepare();
        }
        Err(diags) => {
            assert!(!diags.is_empty());
            for d in &diags {
                assert!(!d.message.is_empty());
                assert!(d.entity.is_some(), "no entity: {d:?}");
                assert!(d.line.is_some_and(|l| l >= 1), "no line: {d:?}");
            }
        }
    }
}

fn examples() -> Vec<String> {
    let dir = codegen::sync::workspace_root().join("examples");
    let mut texts: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .map(|p| std::fs::read_to_string(p).unwrap())
        .collect();
    texts.sort();
    texts
}

fn decks() -> Vec<String> {
    let dir = codegen::sync::workspace_root().join("examples/decks");
    let mut texts: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| String::from_utf8_lossy(&std::fs::read(e.unwrap().path()).unwrap()).into_owned())
        .collect();
    texts.sort();
    texts
}

/// The example as JSON with the same structure.
fn as_json(toml_text: &str) -> String {
    let value: toml::Value = toml::from_str(toml_text).unwrap();
    serde_json::to_string_pretty(&value).unwrap()
}

/// Snippets that break things: structure, numbers at the edges, names, and raw bytes.
const SNIPPETS: [&str; 24] = [
    "[",
    "]",
    "{",
    "}",
    "\"",
    "=",
    ",",
    "\n",
    "[[joints]]\n",
    "[[bodies]]\n",
    "nan",
    "inf",
    "-inf",
    "1e308",
    "1e-320",
    "-0.0",
    "99999999999999999999",
    "\u{0}",
    "\u{feff}",
    "é",
    "type = \"screw\"",
    "ground = true",
    "steps = 1000000000",
    "\\",
];

/// One edit of a text: delete a range, insert a snippet, or duplicate a range.
#[derive(Clone, Debug)]
enum Edit {
    Delete(usize, usize),
    Insert(usize, usize),
    Duplicate(usize, usize),
}

fn edits() -> impl Strategy<Value = Vec<Edit>> {
    let edit = prop_oneof![
        (any::<usize>(), 0usize..64).prop_map(|(a, n)| Edit::Delete(a, n)),
        (any::<usize>(), 0..SNIPPETS.len()).prop_map(|(a, k)| Edit::Insert(a, k)),
        (any::<usize>(), 0usize..256).prop_map(|(a, n)| Edit::Duplicate(a, n)),
    ];
    prop::collection::vec(edit, 1..8)
}

/// Applies the edits at char boundaries (positions are taken modulo the length).
fn mutate(text: &str, edits: &[Edit]) -> String {
    let mut s = text.to_owned();
    for e in edits {
        let boundary = |s: &str, at: usize| {
            let mut k = at % (s.len() + 1);
            while !s.is_char_boundary(k) {
                k -= 1;
            }
            k
        };
        match *e {
            Edit::Delete(a, n) => {
                let a = boundary(&s, a);
                let b = boundary(&s, (a + n).min(s.len()));
                s.replace_range(a..b, "");
            }
            Edit::Insert(a, k) => {
                let a = boundary(&s, a);
                s.insert_str(a, SNIPPETS[k]);
            }
            Edit::Duplicate(a, n) => {
                let a = boundary(&s, a);
                let b = boundary(&s, (a + n).min(s.len()));
                let piece = s[a..b].to_owned();
                s.insert_str(b, &piece);
            }
        }
    }
    s
}

proptest! {
    // No failure files: a failing case is printed, minimised, in the test's output.
    #![proptest_config(ProptestConfig {
        cases: std::env::var("PROPTEST_CASES").ok().and_then(|c| c.parse().ok()).unwrap_or(256),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn random_bytes_are_refused_with_located_errors(bytes in prop::collection::vec(any::<u8>(), 0..4096)) {
        let text = String::from_utf8_lossy(&bytes);
        load(&text, Format::Toml);
        load(&text, Format::Json);
        let _ = bounded("young::import", &text, || codegen::young::import(&text, "fuzz").map_err(Box::new));
    }

    #[test]
    fn mutated_examples_load_or_are_refused_with_located_errors(k in 0usize..18, edits in edits()) {
        let texts = examples();
        let text = mutate(&texts[k % texts.len()], &edits);
        load(&text, Format::Toml);
    }

    #[test]
    fn mutated_json_examples_load_or_are_refused_with_located_errors(k in 0usize..18, edits in edits()) {
        let texts = examples();
        let text = mutate(&as_json(&texts[k % texts.len()]), &edits);
        load(&text, Format::Json);
    }

    #[test]
    fn mutated_decks_import_or_are_refused_with_located_errors(k in 0usize..18, edits in edits()) {
        let texts = decks();
        let text = mutate(&texts[k % texts.len()], &edits);
        let result = bounded("young::import", &text, || codegen::young::import(&text, "fuzz").map_err(Box::new));
        if let Err(d) = result {
            prop_assert!(!d.message.is_empty());
            prop_assert!(d.line.is_some_and(|l| l >= 1), "no line: {d:?}");
        }
    }
}
