//! `Builder` writing into a temporary directory.

use std::path::PathBuf;

use super::Builder;
use crate::testing::example;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("mechgen-build-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn compile_writes_each_module_and_an_index_that_declares_them() {
    let dir = temp_dir("index");
    let generated = Builder::new()
        .files([example("rssr.toml"), example("four_bar.toml")])
        .out_dir(&dir)
        .quiet()
        .compile()
        .expect("both shipped examples generate");
    let modules: Vec<&str> = generated.iter().map(|g| g.module.as_str()).collect();
    assert_eq!(modules, ["rssr", "four_bar"]);
    let rssr = std::fs::read_to_string(dir.join("rssr.rs")).expect("rssr.rs written");
    assert!(rssr.contains("pub struct Rssr;"));
    let index = std::fs::read_to_string(dir.join("mechgen.rs")).expect("index written");
    let rssr_path = dir.join("rssr.rs");
    assert!(index.contains(&format!("#[path = {:?}]\npub mod rssr;", rssr_path.to_str().unwrap())));
    assert!(index.contains("pub mod four_bar;"));
}

#[test]
fn an_unchanged_description_leaves_the_files_untouched() {
    let dir = temp_dir("unchanged");
    let build = || Builder::new().file(example("rssr.toml")).out_dir(&dir).quiet().compile();
    build().expect("generates");
    let path = dir.join("rssr.rs");
    let before = std::fs::metadata(&path).and_then(|m| m.modified()).expect("mtime");
    std::thread::sleep(std::time::Duration::from_millis(20));
    build().expect("generates again");
    let after = std::fs::metadata(&path).and_then(|m| m.modified()).expect("mtime");
    assert_eq!(before, after, "no rewrite, so cargo sees no change");
}

#[test]
fn an_invalid_description_fails_with_the_excerpt() {
    let dir = temp_dir("invalid");
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string(example("rssr.toml")).unwrap();
    let file = dir.join("typo.toml");
    std::fs::write(&file, text.replacen("axis_i", "axsi_i", 1)).unwrap();
    let e = Builder::new().file(&file).out_dir(dir.join("out")).quiet().compile().unwrap_err();
    let super::Error::Invalid { file: named, diagnostics, .. } = &e else { panic!("{e:?}") };
    assert_eq!(named, &file);
    assert_eq!(diagnostics.len(), 1, "{diagnostics:?}");
    let message = e.to_string();
    assert!(message.contains("unknown field `axsi_i`: did you mean `axis_i`?"), "{message}");
    assert!(message.contains("| ^^^^^^"), "{message}");
    assert!(!dir.join("out/mechgen.rs").exists());
}

#[test]
fn two_descriptions_with_one_name_are_refused() {
    let dir = temp_dir("twice");
    let e = Builder::new()
        .files([example("rssr.toml"), example("rssr.toml")])
        .out_dir(&dir)
        .quiet()
        .compile()
        .unwrap_err();
    assert!(matches!(&e, super::Error::DuplicateName { module, .. } if module == "rssr"), "{e:?}");
    assert!(e.to_string().contains("a second description named \"rssr\""), "{e}");
}

#[test]
fn a_directive_stays_on_one_line_whatever_the_message_holds() {
    // A body name with line breaks and directives after them, as a warning would quote it.
    let hostile =
        "body \"x\ncargo::rustc-cfg=evil\r\ncargo:rustc-link-arg=-x\u{2028}\u{85}\u{202e}\"";
    let line = super::one_line(hostile);
    assert!(!line.contains(['\n', '\r', '\u{2028}', '\u{85}', '\u{202e}']), "{line}");
    assert!(line.contains("\\u{000a}cargo::rustc-cfg=evil"), "{line}");
    // A path holding a line break is refused, not written into a directive.
    let e = super::path_text(std::path::Path::new("a\ncargo::rustc-cfg=evil.toml")).unwrap_err();
    assert!(e.to_string().contains("control characters"), "{e}");
}
