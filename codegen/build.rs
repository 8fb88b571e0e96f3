//! Embeds what the generated engine needs to build solvers wherever `mechgen` runs, with or
//! without this checkout: the `runtime` crate's sources, a stand-alone manifest for them and
//! the workspace's lock file (which pins the runtime's dependencies).

use std::fmt::Write as _;
use std::hash::Hasher as _;
use std::path::{Path, PathBuf};

fn main() {
    let manifest_dir =
        PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets it"));
    let root = manifest_dir.parent().expect("codegen lies inside the workspace").to_path_buf();
    let runtime = root.join("runtime");
    let lock = root.join("Cargo.lock");
    for path in [
        runtime.join("src"),
        runtime.join("Cargo.toml"),
        root.join("Cargo.toml"),
        lock.clone(),
        manifest_dir.join("src"),
        manifest_dir.join("Cargo.toml"),
    ] {
        println!("cargo:rerun-if-changed={}", path.display());
    }
    let mut files = Vec::new();
    collect(&runtime.join("src"), &mut files);
    files.sort();

    let mut out = String::from(
        "/// The runtime crate's source files: path relative to the crate root, text.\n\
         pub(crate) const RUNTIME_FILES: &[(&str, &str)] = &[\n",
    );
    for file in &files {
        let relative = file.strip_prefix(&runtime).expect("under runtime/");
        let relative: Vec<String> =
            relative.components().map(|c| c.as_os_str().to_string_lossy().into_owned()).collect();
        writeln!(out, "    ({:?}, include_str!({:?})),", relative.join("/"), utf8(file)).unwrap();
    }
    out.push_str("];\n");

    let runtime_manifest = read(&runtime.join("Cargo.toml"));
    let workspace_manifest = read(&root.join("Cargo.toml"));
    let dependencies = section(&runtime_manifest, "[dependencies]");
    for line in &dependencies {
        assert!(
            !line.contains("workspace"),
            "runtime/Cargo.toml: the generated engine copies the runtime's [dependencies] into a \
             crate of its own, so they cannot inherit from the workspace: `{line}`"
        );
    }
    let edition = section(&workspace_manifest, "[workspace.package]")
        .into_iter()
        .find(|l| l.starts_with("edition"))
        .expect("the workspace sets the edition");
    let version = std::env::var("CARGO_PKG_VERSION").expect("cargo sets it");
    let manifest = format!(
        "[package]\nname = \"runtime\"\nversion = \"{version}\"\n{edition}\npublish = false\n\n\
         [dependencies]\n{}\n",
        dependencies.join("\n")
    );
    writeln!(
        out,
        "/// A stand-alone manifest for [`RUNTIME_FILES`] (the runtime's own inherits from the \
         workspace).\npub(crate) const RUNTIME_MANIFEST: &str = {manifest:?};"
    )
    .unwrap();
    let names: Vec<String> = dependencies
        .iter()
        .filter_map(|l| l.split('=').next())
        .map(|n| format!("{:?}", n.trim()))
        .collect();
    writeln!(
        out,
        "/// The packages the runtime depends on.\npub(crate) const RUNTIME_DEPENDENCIES: &[&str] \
         = &[{}];",
        names.join(", ")
    )
    .unwrap();
    let lock_text =
        if lock.is_file() { format!("include_str!({:?})", utf8(&lock)) } else { "\"\"".to_owned() };
    writeln!(
        out,
        "/// The workspace's `Cargo.lock` (empty when there was none): generated solvers build \
         with the versions it pins.\npub(crate) const WORKSPACE_LOCK: &str = {lock_text};"
    )
    .unwrap();

    // What decides the modules this mechgen generates: its own sources (the generator, the
    // driver), its manifest and the lock file (the formatter's version). Any change to them
    // changes the hash, so the cache never takes an older mechgen's module for this one's.
    let mut sources = Vec::new();
    collect(&manifest_dir.join("src"), &mut sources);
    sources.sort();
    sources.push(manifest_dir.join("Cargo.toml"));
    if lock.is_file() {
        sources.push(lock.clone());
    }
    let mut hasher = std::hash::DefaultHasher::new();
    for file in &sources {
        let relative = file.strip_prefix(&root).expect("inside the workspace");
        let bytes = std::fs::read(file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        for part in [relative.to_string_lossy().as_bytes(), &bytes] {
            hasher.write_usize(part.len());
            hasher.write(part);
        }
    }
    writeln!(
        out,
        "/// A hash of mechgen's own sources, manifest and lock file: the generator's fingerprint.\n\
         pub(crate) const GENERATOR_HASH: &str = \"{:016x}\";",
        hasher.finish()
    )
    .unwrap();

    let dest =
        PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets it")).join("embedded.rs");
    std::fs::write(&dest, out).unwrap_or_else(|e| panic!("{}: {e}", dest.display()));
}

/// Every file below `dir`.
fn collect(dir: &Path, files: &mut Vec<PathBuf>) {
    let entries = std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    for entry in entries {
        let path = entry.unwrap_or_else(|e| panic!("{}: {e}", dir.display())).path();
        if path.is_dir() {
            collect(&path, files);
        } else {
            files.push(path);
        }
    }
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn utf8(path: &Path) -> &str {
    path.to_str().unwrap_or_else(|| panic!("{}: the path is not UTF-8", path.display()))
}

/// The non-empty, non-comment lines of a TOML section, up to the next header.
fn section(text: &str, header: &str) -> Vec<String> {
    text.lines()
        .map(str::trim)
        .skip_while(|l| *l != header)
        .skip(1)
        .take_while(|l| !l.starts_with('['))
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .map(str::to_owned)
        .collect()
}
