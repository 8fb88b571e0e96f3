//! Keeps `generated/src` equal to what the generator makes of `examples/*.toml`: shared by
//! `cargo codegen` (which writes) and the freshness test (which only compares).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::diag::Diagnostic;
use crate::emit;
use crate::symbolic::{GenerateError, Symbolic};
use crate::validate::load_file;

/// Whether [`sync`] only reports differences or also rewrites `generated/src`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Compare only.
    Check,
    /// Rewrite what differs, delete orphans.
    Write,
}

/// A generated file that differs from what the generator produces now.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Stale {
    /// Expected but absent.
    Missing(PathBuf),
    /// Present with other contents; the first differing line (1-based).
    Changed {
        /// The file.
        path: PathBuf,
        /// First line that differs.
        first_diff_line: usize,
    },
    /// Present in `generated/src` but produced by no description.
    Orphan(PathBuf),
}

/// Why `generated/src` could not be compared or written.
#[derive(Debug, thiserror::Error)]
pub enum SyncError {
    /// A shipped description is invalid.
    #[error("{}", lines(.diagnostics))]
    Invalid {
        /// The description file.
        file: PathBuf,
        /// Every diagnostic found.
        diagnostics: Vec<Diagnostic>,
    },
    /// The generator refuses a shipped description.
    #[error("{}: {source}", .file.display())]
    Generate {
        /// The description file.
        file: PathBuf,
        /// The generator's reason.
        source: GenerateError,
    },
    /// A description's file name is not UTF-8, or is the name of another description's
    /// module, so it names no module of its own.
    #[error("{}: non-UTF-8 file name, or one that another example has", .path.display())]
    FileName {
        /// The file.
        path: PathBuf,
    },
    /// Reading or writing a file or directory failed.
    #[error("{}: {source}", .path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The operating system's reason.
        source: std::io::Error,
    },
}

/// Diagnostics one per line.
fn lines(diagnostics: &[Diagnostic]) -> String {
    diagnostics.iter().map(ToString::to_string).collect::<Vec<_>>().join("\n")
}

/// An I/O error on `path`, for `map_err`.
fn io(path: &Path) -> impl FnOnce(std::io::Error) -> SyncError + '_ {
    move |source| SyncError::Io { path: path.to_path_buf(), source }
}

/// The generated module of one description file, with the header naming `source`.
///
/// # Errors
/// When the description is invalid or cannot be generated.
pub fn render(file: &Path, source: &str) -> Result<String, SyncError> {
    let loaded = load_file(file)
        .map_err(|diagnostics| SyncError::Invalid { file: file.to_path_buf(), diagnostics })?;
    let sys = Symbolic::build(&loaded.mechanism)
        .map_err(|source| SyncError::Generate { file: file.to_path_buf(), source })?;
    Ok(emit::module(&loaded.mechanism, &sys, source))
}

/// The modules of shipped descriptions restricted to some outputs (`blocks::outputs::only`,
/// as `mechgen generate --outputs`), as (module, description, outputs): the module's
/// mechanism takes the module's name. The Stewart platform's forward kinematics alone, its
/// legs reduced to distance rows (`symbolic::legs`), is what `examples/benches/stewart.rs`
/// sets against the motion-control baseline.
const RESTRICTED: &[(&str, &str, &[&str])] =
    &[("stewart_platform", "examples/inputs/stewart.toml", &["platform"])];

/// The modules of shipped descriptions built whole (`Symbolic::build_full`: no closed form
/// substituted), as (module, description). Substituted, the Stewart platform keeps 55 unknowns
/// and is emitted with whole static orders (below `emit::blocks::MIN_UNKNOWNS`); whole, its 91
/// unknowns are solved block by block, the module the block storage's tests
/// (`tests/src/block_solver.rs`, `tests/src/block_orders.rs`) step.
const WHOLE: &[(&str, &str)] = &[("stewart_whole", "examples/inputs/stewart.toml")];

/// The generated module of one description built whole, named `module`.
///
/// # Errors
/// When the description is invalid or cannot be generated.
fn render_whole(file: &Path, source: &str, module: &str) -> Result<String, SyncError> {
    let mut loaded = load_file(file)
        .map_err(|diagnostics| SyncError::Invalid { file: file.to_path_buf(), diagnostics })?;
    module.clone_into(&mut loaded.mechanism.name);
    let sys = Symbolic::build_full(&loaded.mechanism)
        .map_err(|source| SyncError::Generate { file: file.to_path_buf(), source })?;
    Ok(emit::module(
        &loaded.mechanism,
        &sys,
        &format!("{source}, whole (no closed form substituted)"),
    ))
}

/// The generated module of one description restricted to `outputs`, named `module`.
///
/// # Errors
/// When the description is invalid, cannot be generated, or has no such outputs.
fn render_restricted(
    file: &Path,
    source: &str,
    module: &str,
    outputs: &[&str],
) -> Result<String, SyncError> {
    let loaded = load_file(file)
        .map_err(|diagnostics| SyncError::Invalid { file: file.to_path_buf(), diagnostics })?;
    let generate = |source| SyncError::Generate { file: file.to_path_buf(), source };
    let sys = Symbolic::build(&loaded.mechanism).map_err(generate)?;
    let names: Vec<String> = outputs.iter().map(|&o| o.to_owned()).collect();
    let mut only = crate::blocks::outputs::only(&loaded.mechanism, &sys, &names)
        .map_err(|e| generate(GenerateError { message: e.to_string() }))?;
    module.clone_into(&mut only.name);
    let sys = Symbolic::build(&only).map_err(generate)?;
    let source = format!("{source} --outputs {}", outputs.join(","));
    Ok(emit::module(&only, &sys, &source))
}

/// Every file `generated/src` should hold, by file name.
///
/// # Errors
/// The first description that fails.
pub fn expected(root: &Path) -> Result<BTreeMap<String, String>, SyncError> {
    // The descriptions of `examples/` and of `examples/inputs/` (those with input drivers).
    let mut descriptions: Vec<(PathBuf, &str)> = Vec::new();
    for folder in ["examples", "examples/inputs"] {
        let dir = root.join(folder);
        let mut found: Vec<PathBuf> = std::fs::read_dir(&dir)
            .map_err(io(&dir))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "toml") && !p.ends_with("Cargo.toml"))
            .collect();
        found.sort();
        descriptions.extend(found.into_iter().map(|p| (p, folder)));
    }
    let mut files = BTreeMap::new();
    let mut modules = Vec::new();
    for (d, folder) in &descriptions {
        let stem = d
            .file_stem()
            .and_then(|s| s.to_str())
            .filter(|s| !modules.iter().any(|m| m == s))
            .ok_or_else(|| SyncError::FileName { path: d.clone() })?;
        let source = format!("{folder}/{stem}.toml");
        files.insert(format!("{stem}.rs"), render(d, &source)?);
        modules.push(stem.to_owned());
    }
    for &(module, description, outputs) in RESTRICTED {
        if modules.iter().any(|m| m == module) {
            return Err(SyncError::FileName { path: root.join(description) });
        }
        let text = render_restricted(&root.join(description), description, module, outputs)?;
        files.insert(format!("{module}.rs"), text);
        modules.push(module.to_owned());
    }
    for &(module, description) in WHOLE {
        if modules.iter().any(|m| m == module) {
            return Err(SyncError::FileName { path: root.join(description) });
        }
        let text = render_whole(&root.join(description), description, module)?;
        files.insert(format!("{module}.rs"), text);
        modules.push(module.to_owned());
    }
    modules.sort();
    let mut lib = String::from(
        "// @generated by `cargo codegen` from examples/*.toml and examples/inputs/*.toml. Do not \
         edit.\n\n\
         //! Generated per-mechanism solvers, one module per description in `examples/` and\n\
         //! `examples/inputs/`.\n\
         //!\n\
         //! Each module implements [`runtime::Mechanism`] for its mechanism's reduced system\n\
         //! and exposes the plain functions behind it. Regenerate with `cargo codegen`.\n\n\
         #![no_std]\n\n",
    );
    for m in modules {
        lib.push_str(&format!("pub mod {m};\n"));
    }
    files.insert("lib.rs".to_owned(), lib);
    Ok(files)
}

/// Compares `generated/src` with [`expected`] and, in [`Mode::Write`], rewrites it.
///
/// # Errors
/// Generation or I/O failures.
pub fn sync(root: &Path, mode: Mode) -> Result<Vec<Stale>, SyncError> {
    let dir = root.join("generated/src");
    let want = expected(root)?;
    let mut stale = Vec::new();
    for (name, text) in &want {
        let path = dir.join(name);
        match std::fs::read_to_string(&path) {
            Ok(have) if have.replace("\r\n", "\n") == *text => continue,
            Ok(have) => {
                let first_diff_line =
                    have.lines().zip(text.lines()).take_while(|(a, b)| a == b).count() + 1;
                stale.push(Stale::Changed { path: path.clone(), first_diff_line });
            }
            Err(_) => stale.push(Stale::Missing(path.clone())),
        }
        if mode == Mode::Write {
            std::fs::write(&path, text).map_err(io(&path))?;
        }
    }
    let mut present: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map_err(io(&dir))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "rs"))
        .collect();
    present.sort();
    for path in present {
        let name = path.file_name().and_then(|s| s.to_str()).unwrap_or_default();
        if !want.contains_key(name) {
            if mode == Mode::Write {
                std::fs::remove_file(&path).map_err(io(&path))?;
            }
            stale.push(Stale::Orphan(path));
        }
    }
    Ok(stale)
}

/// The workspace root (the parent of this crate's manifest directory).
#[must_use]
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
}
