//! The layers of ARCHITECTURE.md ("The model and the generator"), enforced: a module may use
//! the modules of its own layer and of the layers below it, never one above. The test reads
//! the crate's sources (not its tests) and fails on any upward `crate::…` path.

use std::path::{Path, PathBuf};

/// The layers, bottom first.
const LAYERS: [(&str, &[&str]); 6] = [
    ("foundations", &["desc", "diag", "expr"]),
    ("model", &["model", "validate", "young", "inputs"]),
    ("interpreted engine", &["stepping", "generic", "report"]),
    ("symbolic builder", &["symbolic", "blocks", "pivot", "reference"]),
    ("generator", &["emit", "sync", "build"]),
    (
        "tool",
        &["engine", "scale", "output", "draw", "chart", "plot", "cli", "testing", "layers", "main"],
    ),
];

/// Upward paths tolerated for now, each with the reason: `(module, used module)`. None.
const EXCEPTIONS: [(&str, &str); 0] = [];

/// The layer of a top-level module.
fn layer(module: &str) -> Option<usize> {
    LAYERS.iter().position(|(_, modules)| modules.contains(&module))
}

/// Every source file under `dir`, test files (`tests.rs`, `tests/`) left out.
fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("the source directory") {
        let path = entry.expect("a directory entry").path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        if path.is_dir() {
            if name != "tests" {
                sources(&path, out);
            }
        } else if path.extension().is_some_and(|e| e == "rs") && name != "tests.rs" {
            out.push(path);
        }
    }
}

/// The top-level modules a line of code names through `crate::` (`crate::a::…` and
/// `crate::{a, b::…}`); comments are not code.
fn used_modules(line: &str) -> Vec<String> {
    let code = line.split("//").next().unwrap_or_default();
    let mut used = Vec::new();
    for (at, _) in code.match_indices("crate::") {
        let rest = &code[at + "crate::".len()..];
        let names: Vec<&str> = match rest.strip_prefix('{') {
            Some(group) => group.split('}').next().unwrap_or_default().split(',').collect(),
            None => vec![rest],
        };
        for name in names {
            let name: String = name
                .trim()
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            if !name.is_empty() {
                used.push(name);
            }
        }
    }
    used
}

#[test]
fn no_module_uses_a_module_of_a_layer_above_it() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    files.sort();
    let mut upward = Vec::new();
    for file in &files {
        let relative = file.strip_prefix(&src).expect("under src");
        let first = relative.iter().next().and_then(|c| c.to_str()).unwrap_or_default();
        let module = first.trim_end_matches(".rs");
        if module == "lib" {
            continue;
        }
        let own = layer(module).unwrap_or_else(|| panic!("{module}: no layer in LAYERS"));
        let text = std::fs::read_to_string(file).expect("readable source");
        for (k, line) in text.lines().enumerate() {
            for used in used_modules(line) {
                let Some(theirs) = layer(&used) else { continue };
                if theirs > own && !EXCEPTIONS.contains(&(module, used.as_str())) {
                    upward.push(format!(
                        "{}:{}: {module} ({}) uses {used} ({})",
                        relative.display(),
                        k + 1,
                        LAYERS[own].0,
                        LAYERS[theirs].0
                    ));
                }
            }
        }
    }
    assert!(upward.is_empty(), "upward dependencies:\n{}", upward.join("\n"));
}

#[test]
fn the_scan_sees_grouped_and_plain_paths_but_not_comments() {
    assert_eq!(used_modules("use crate::{emit, model::Mechanism};"), ["emit", "model"]);
    assert_eq!(used_modules("let x = crate::generic::scaling::length_scale(m);"), ["generic"]);
    assert!(used_modules("// see crate::emit").is_empty());
}
