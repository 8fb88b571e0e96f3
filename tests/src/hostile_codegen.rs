//! Descriptions written as an attacker would (tests/corpus/hostile_codegen, with the verdict
//! each must get in its `expected.toml`): comment break-outs, doc and attribute injection,
//! Markdown code blocks rustdoc would run, bidi and invisible characters, names equal to the
//! emitter's identifiers and to Rust keywords, and a payload that writes a canary file if it
//! ever runs. Each is refused with exit status 1 naming the entity and the field, or generated,
//! checked by clippy with warnings denied, doc-tested and solved on the generated engine, and
//! the canary file never appears.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::Command;

use serde::Deserialize;

/// One corpus case (see `tests/corpus/hostile_codegen/expected.toml`).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Case {
    file: String,
    why: String,
    verdict: String,
    #[serde(default)]
    entity: Option<String>,
    #[serde(default)]
    field: Option<String>,
    #[serde(default)]
    contains: Option<String>,
}

#[derive(Deserialize)]
struct Corpus {
    case: Vec<Case>,
}

/// Runs `mechgen` in process: (exit status, stdout, stderr).
fn mechgen(args: &[OsString]) -> (i32, String, String) {
    let mut argv: Vec<OsString> = vec!["mechgen".into()];
    argv.extend(args.iter().cloned());
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let status = codegen::cli::run(argv, &mut out, &mut err);
    (status, String::from_utf8_lossy(&out).into_owned(), String::from_utf8_lossy(&err).into_owned())
}

fn args(list: &[&dyn AsRef<std::ffi::OsStr>]) -> Vec<OsString> {
    list.iter().map(|a| a.as_ref().to_os_string()).collect()
}

/// Where a case is written: under a file name that is itself hostile where the system allows
/// it (it reaches the generated module's docs through `generate`).
fn hostile_path(dir: &Path, stem: &str) -> PathBuf {
    if cfg!(unix) {
        dir.join(format!("{stem} \"#]] \n#![doc = \"x\"] \r\u{202e}.toml"))
    } else {
        dir.join(format!("{stem}.toml"))
    }
}

/// Runs cargo with `args` on the crate at `dir`; panics with its output when it fails.
fn cargo(dir: &Path, args: &[&str]) -> String {
    let output = Command::new(std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into()))
        .arg(args[0])
        .arg("--manifest-path")
        .arg(dir.join("Cargo.toml"))
        .args(&args[1..])
        .env("CARGO_TARGET_DIR", dir.join("target"))
        .output()
        .expect("cargo runs");
    let (stdout, stderr) =
        (String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    assert!(output.status.success(), "cargo {args:?} fails:\n{stdout}\n{stderr}");
    format!("{stdout}\n{stderr}")
}

#[test]
fn hostile_descriptions_are_refused_or_stay_data() {
    let root = codegen::sync::workspace_root();
    let corpus_dir = root.join("tests/corpus/hostile_codegen");
    let corpus: Corpus =
        toml::from_str(&std::fs::read_to_string(corpus_dir.join("expected.toml")).unwrap())
            .unwrap();
    // Every file of the corpus has a case, and every case a file.
    let mut files: Vec<String> = std::fs::read_dir(&corpus_dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|f| f != "expected.toml")
        .collect();
    files.sort();
    let mut cases: Vec<String> = corpus.case.iter().map(|c| c.file.clone()).collect();
    cases.sort();
    assert_eq!(files, cases);

    let work = std::env::temp_dir().join(format!("mechgen-hostile-codegen-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&work);
    let crate_dir = root.join("target/hostile-codegen");
    std::fs::create_dir_all(crate_dir.join("src")).unwrap();
    std::fs::create_dir_all(&work).unwrap();
    // A payload that runs writes this file; its directory exists, so the write would succeed.
    let canary = work.join("canary");
    let canary_text = canary.to_str().expect("a UTF-8 temporary directory").replace('\\', "/");

    let mut lib = String::from("#![no_std]\n//! Generated modules of hostile descriptions.\n");
    let mut accepted = 0;
    for case in &corpus.case {
        let why = &case.why;
        let text = std::fs::read_to_string(corpus_dir.join(&case.file)).unwrap();
        let stem = case.file.trim_end_matches(".toml");
        let path = hostile_path(&work, stem);
        std::fs::write(&path, text.replace("@CANARY@", &canary_text)).unwrap();
        let (status, out, err) = mechgen(&args(&[&"check", &path, &"--format", &"json"]));
        match case.verdict.as_str() {
            "refused" => {
                assert_eq!(status, 1, "{why}: status {status}\n{out}\n{err}");
                let v: serde_json::Value =
                    serde_json::from_str(&out).unwrap_or_else(|e| panic!("{why}: {e}: {out}"));
                let error = &v["error"];
                assert_eq!(error["kind"], "invalid_input", "{why}: {v}");
                assert_eq!(error["entity"].as_str(), case.entity.as_deref(), "{why}: {error}");
                assert_eq!(error["field"].as_str(), case.field.as_deref(), "{why}: {error}");
                let message = error["message"].as_str().unwrap_or_default();
                let contains = case.contains.as_deref().expect("a refused case says why");
                assert!(message.contains(contains), "{why}: {message:?} lacks {contains:?}");
                continue;
            }
            "accepted" => assert_eq!(status, 0, "{why}: status {status}\n{out}\n{err}"),
            other => panic!("{}: unknown verdict {other:?}", case.file),
        }
        accepted += 1;
        // Solved on the generated engine (no fall-back to the generic one), without error.
        let (status, out, err) =
            mechgen(&args(&[&"solve", &path, &"--engine", &"generated", &"--format", &"json"]));
        assert_eq!(status, 0, "{why}: solve status {status}\n{out}\n{err}");
        let v: serde_json::Value =
            serde_json::from_str(&out).unwrap_or_else(|e| panic!("{why}: {e}: {out}"));
        assert_eq!(v["engine"], "generated", "{why}: {v}");
        assert_eq!(v["steps"].as_array().map(Vec::len), Some(3), "{why}: {v}");
        assert!(!canary.exists(), "{why}: the payload ran in the generated solver");
        // The module `generate` writes, in both precisions, into one crate checked below.
        for float in ["f64", "f32"] {
            let module = format!("{stem}_{float}");
            let file = crate_dir.join(format!("src/{module}.rs"));
            let (status, out, err) =
                mechgen(&args(&[&"generate", &path, &"--float", &float, &"-o", &file]));
            assert_eq!(status, 0, "{why}: generate status {status}\n{out}\n{err}");
            let text = std::fs::read_to_string(&file).unwrap();
            // Docs are whole `///` or `//!` lines; no block doc comment is opened.
            let block =
                |l: &str| l.trim_start().starts_with("/**") || l.trim_start().starts_with("/*!");
            assert!(!text.lines().any(block), "{why}: a block doc comment");
            assert!(!text.contains('\r') && !text.contains('\u{202e}'), "{why}: a raw control");
            lib.push_str(&format!("pub mod {module};\n"));
        }
    }
    assert!(accepted >= 5, "only {accepted} accepted cases: the corpus no longer builds code");
    std::fs::write(crate_dir.join("src/lib.rs"), lib).unwrap();
    let manifest = format!(
        "[package]\nname = \"hostile-codegen\"\nversion = \"0.0.0\"\nedition = \"2024\"\npublish = false\n\n\
         [dependencies]\nruntime = {{ path = {:?} }}\n\n[workspace]\n",
        root.join("runtime").display().to_string()
    );
    std::fs::write(crate_dir.join("Cargo.toml"), manifest).unwrap();
    if let Ok(lock) = std::fs::read_to_string(root.join("Cargo.lock")) {
        std::fs::write(crate_dir.join("Cargo.lock"), lock).unwrap();
    }
    cargo(&crate_dir, &["clippy", "--offline", "--quiet", "--", "-D", "warnings"]);
    // rustdoc finds no doctest: every code block of the docs is `text`, and the descriptions'
    // code blocks are inside a fence they cannot close.
    let doc = cargo(&crate_dir, &["test", "--offline", "--doc"]);
    assert!(doc.contains("running 0 tests"), "{doc}");
    assert!(!canary.exists(), "a payload ran while building, checking or doc-testing");
    let _ = std::fs::remove_dir_all(&work);
}
