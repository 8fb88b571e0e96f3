//! Hostile and invalid inputs (tests/corpus/hostile, with the verdict each must get in its
//! `expected.toml`), plus inputs too large to commit, made here: every one is refused with
//! exit status 1 and a message naming the entity and the place, never a panic or a hang.

use crate::harness::mechgen;
use std::path::{Path, PathBuf};

use serde::Deserialize;

/// One corpus case (see `tests/corpus/hostile/expected.toml`).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Case {
    file: String,
    why: String,
    #[serde(default)]
    command: Option<String>,
    contains: String,
    #[serde(default)]
    entity: Option<String>,
    #[serde(default)]
    at: Option<String>,
    #[serde(default)]
    line: Option<u64>,
    #[serde(default)]
    column: Option<u64>,
}

#[derive(Deserialize)]
struct Corpus {
    case: Vec<Case>,
}

fn corpus_dir() -> PathBuf {
    codegen::sync::workspace_root().join("tests/corpus/hostile")
}

/// Line and column (1-based, in characters) of the first occurrence of `needle` in the file.
fn place_of(path: &Path, needle: &str) -> (u64, u64) {
    let text = String::from_utf8_lossy(&std::fs::read(path).unwrap()).into_owned();
    let at = text.find(needle).unwrap_or_else(|| panic!("{needle:?} not in {}", path.display()));
    let before = &text[..at];
    let line = 1 + before.matches('\n').count();
    let column = 1 + before.rsplit('\n').next().unwrap_or("").chars().count();
    (line as u64, column as u64)
}

/// The contract's JSON error object of a `check --format json` that must fail with status 1.
fn refused(path: &Path) -> serde_json::Value {
    let shown = path.to_str().unwrap();
    let (status, out, err) = mechgen(&["check", shown, "--format", "json"]);
    assert_eq!(status, 1, "{shown}: status {status}\n{out}\n{err}");
    let v: serde_json::Value =
        serde_json::from_str(&out).unwrap_or_else(|e| panic!("{shown}: {e}: {out}"));
    assert_eq!(v["error"]["kind"], "invalid_input", "{shown}: {v}");
    v["error"].clone()
}

#[test]
fn every_corpus_file_is_refused_as_its_case_says() {
    let dir = corpus_dir();
    let corpus: Corpus =
        toml::from_str(&std::fs::read_to_string(dir.join("expected.toml")).unwrap()).unwrap();
    // Every file of the corpus has a case, and every case a file.
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|f| f != "expected.toml")
        .collect();
    files.sort();
    let mut cases: Vec<String> = corpus.case.iter().map(|c| c.file.clone()).collect();
    cases.sort();
    assert_eq!(files, cases);

    for case in &corpus.case {
        let path = dir.join(&case.file);
        let shown = path.to_str().unwrap();
        let why = &case.why;
        if case.command.as_deref() == Some("import-young") {
            let (status, out, err) = mechgen(&["import-young", shown]);
            assert_eq!(status, 1, "{why}: {out}{err}");
            assert!(err.contains(&case.contains), "{why}: {err}");
            if let Some(entity) = &case.entity {
                assert!(err.contains(entity.as_str()), "{why}: {err}");
            }
            continue;
        }
        let error = refused(&path);
        let message = error["message"].as_str().unwrap_or_default();
        assert!(message.contains(&case.contains), "{why}: {message:?} lacks {:?}", case.contains);
        if let Some(entity) = &case.entity {
            assert_eq!(error["entity"].as_str(), Some(entity.as_str()), "{why}: {error}");
        }
        let expected = match &case.at {
            Some(needle) => {
                let (l, c) = place_of(&path, needle);
                (Some(l), Some(c))
            }
            None => (case.line, case.column),
        };
        if let Some(line) = expected.0 {
            assert_eq!(error["line"].as_u64(), Some(line), "{why}: {error}");
        }
        if let Some(column) = expected.1 {
            assert_eq!(error["column"].as_u64(), Some(column), "{why}: {error}");
        }
        // `solve` refuses the same input before analysing anything, and writes no number.
        let (status, out, err) = mechgen(&["solve", shown, "--engine", "generic"]);
        assert_eq!(status, 1, "{why}: solve {out}{err}");
        assert!(!out.contains("NaN") && !out.contains("inf"), "{why}: {out}");
    }
}

#[test]
fn a_file_larger_than_the_limit_is_refused_without_reading_it_all() {
    let path = std::env::temp_dir().join(format!("mechgen-huge-{}.toml", std::process::id()));
    // 17 MiB of comment lines: valid TOML, but above the 16 MiB limit.
    let line = format!("#{}\n", "x".repeat(1023));
    std::fs::write(&path, line.repeat(17 * 1024)).unwrap();
    let error = refused(&path);
    std::fs::remove_file(&path).unwrap();
    assert_eq!(error["entity"], "file");
    assert!(error["message"].as_str().unwrap().contains("larger than 16 MiB"), "{error}");
    #[cfg(unix)]
    {
        // An endless device ends at the limit too, instead of filling the memory.
        let error = refused(Path::new("/dev/zero"));
        assert!(error["message"].as_str().unwrap().contains("larger than 16 MiB"), "{error}");
    }
}

#[test]
fn a_directory_or_a_missing_file_is_refused_with_the_reason() {
    let error = refused(&corpus_dir());
    assert!(error["message"].as_str().unwrap().starts_with("cannot read the file"), "{error}");
    let error = refused(&corpus_dir().join("no-such-file.toml"));
    assert!(error["message"].as_str().unwrap().starts_with("cannot read the file"), "{error}");
}

#[test]
fn more_bodies_than_the_limit_are_refused_before_any_analysis() {
    // 501 moving bodies, each fixed in place by six coordinate constraints (so the count of
    // equations is not the problem): one more than the 500 allowed.
    let mut text = String::from("name = \"crowd\"\n[time]\nstart = 0.0\nend = 1.0\nsteps = 1\n");
    for k in 0..501 {
        text.push_str(&format!(
            "[[bodies]]\nname = \"b{k}\"\nr = [0.0, 0.0, 0.0]\np = [1.0, 0.0, 0.0, 0.0]\n"
        ));
    }
    for k in 0..501 {
        for c in ["x", "y", "z", "rx", "ry", "rz"] {
            text.push_str(&format!(
                "[[drivers]]\nname = \"d{k}{c}\"\nbody = \"b{k}\"\ncoordinate = \"{c}\"\nlaw = {{ start = 0.0, velocity = 0.0, acceleration = 0.0 }}\n"
            ));
        }
    }
    let path = std::env::temp_dir().join(format!("mechgen-crowd-{}.toml", std::process::id()));
    std::fs::write(&path, text).unwrap();
    let started = std::time::Instant::now();
    let error = refused(&path);
    std::fs::remove_file(&path).unwrap();
    assert!(error["message"].as_str().unwrap().contains("at most 500 moving bodies"), "{error}");
    assert_eq!(error["entity"], "mechanism \"crowd\"");
    // Refused by counting, not by trying: well under the seconds a 3,507-unknown SVD takes.
    assert!(started.elapsed().as_secs_f64() < 5.0, "{:?}", started.elapsed());
}
