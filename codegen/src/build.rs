//! Generating solvers from a `build.rs`, the way `prost-build` generates protobuf code.
//!
//! A crate that keeps its mechanism descriptions beside its sources can have cargo regenerate
//! the specialised solvers whenever a description changes, instead of committing them:
//!
//! ```toml
//! # Cargo.toml of the user's crate
//! [dependencies]
//! runtime = { path = "…/runtime" }      # what the generated code calls
//!
//! [build-dependencies]
//! codegen = { path = "…/codegen" }
//! ```
//!
//! ```no_run
//! // build.rs, in `fn main()`: an invalid description fails the build with its diagnostics.
//! codegen::build::Builder::new()
//!     .file("four_bar.toml")
//!     .compile()
//!     .unwrap_or_else(|e| panic!("{e}"));
//! ```
//!
//! The workspace's `examples/build-rs-user` crate does exactly this and tests the generated
//! solver against the closed form of its four-bar.
//!
//! ```text
//! // src/lib.rs: one module per description, named after its `name`.
//! include!(concat!(env!("OUT_DIR"), "/mechgen.rs"));
//!
//! let mut solver = runtime::Solver::new(four_bar::FourBar, four_bar::Q0);
//! ```
//!
//! [`Builder::compile`] writes `OUT_DIR/NAME.rs` for each description (exactly what
//! `mechgen generate` prints) and `OUT_DIR/mechgen.rs`, which declares each of them as a module
//! (`#[path = "…"] pub mod NAME;`), so the generated files keep their module docs. It prints
//! `cargo::rerun-if-changed` for every description and its warnings as `cargo::warning`,
//! each on one line (controls and line breaks escaped),, and rewrites a file only when its contents
//! change, so an unchanged description costs no rebuild. An invalid description fails the
//! build with the same excerpt and caret as `mechgen check`.

use std::path::{Path, PathBuf};

use crate::diag;
use crate::emit;
use crate::symbolic::{GenerateError, Symbolic};
use crate::validate;

/// Generates solvers for a list of description files into a directory (`OUT_DIR` by default).
#[derive(Clone, Debug, Default)]
pub struct Builder {
    /// The description files, each with the outputs its module is restricted to, if any.
    files: Vec<(PathBuf, Option<Vec<String>>)>,
    out_dir: Option<PathBuf>,
    quiet: bool,
}

/// One generated module.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Generated {
    /// The module's name: the description's `name`.
    pub module: String,
    /// The file written.
    pub path: PathBuf,
}

/// Why generation failed.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Neither [`Builder::out_dir`] nor `OUT_DIR` names where to write.
    #[error("OUT_DIR is not set: call out_dir(…) outside a build script")]
    NoOutDir,
    /// A description is invalid: its diagnostics, rendered with their excerpts.
    #[error("{rendered}")]
    Invalid {
        /// The description file.
        file: PathBuf,
        /// Every diagnostic found.
        diagnostics: Vec<diag::Diagnostic>,
        /// The diagnostics as text, with the file's excerpts (no colour).
        rendered: String,
    },
    /// The generator refuses a valid description (e.g. an undriven degree of freedom).
    #[error("{}: {source}", .file.display())]
    Generate {
        /// The description file.
        file: PathBuf,
        /// The generator's reason.
        source: GenerateError,
    },
    /// An output asked of a description is no moving body, point or joint of it.
    #[error("{}: {source}", .file.display())]
    Outputs {
        /// The description file.
        file: PathBuf,
        /// The name and the outputs that exist.
        source: crate::blocks::outputs::UnknownOutput,
    },
    /// Two descriptions have the same `name`, so their modules would collide.
    #[error("{}: a second description named \"{module}\"; module names must differ", .file.display())]
    DuplicateName {
        /// The second description file.
        file: PathBuf,
        /// The name both have.
        module: String,
    },
    /// A path cargo cannot be told about (`rerun-if-changed`, `#[path]`).
    #[error("{}: the path is not UTF-8 or holds control characters", one_line(&.path.display().to_string()))]
    Path {
        /// The path.
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

impl Builder {
    /// A builder with no files, writing into `OUT_DIR`.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a description file (TOML, or JSON by extension), relative to the current
    /// directory, which for a build script is the package's root.
    #[must_use]
    pub fn file(mut self, path: impl AsRef<Path>) -> Self {
        self.files.push((path.as_ref().to_path_buf(), None));
        self
    }

    /// Adds a description file whose module computes only what the named moving bodies,
    /// points and joints need (as `mechgen generate --outputs`): the blocks of the system no
    /// named output depends on are left out, with their bodies, joints, drivers and points.
    #[must_use]
    pub fn file_with_outputs(
        mut self,
        path: impl AsRef<Path>,
        outputs: impl IntoIterator<Item = impl Into<String>>,
    ) -> Self {
        let outputs = outputs.into_iter().map(Into::into).collect();
        self.files.push((path.as_ref().to_path_buf(), Some(outputs)));
        self
    }

    /// Adds several description files.
    #[must_use]
    pub fn files(mut self, paths: impl IntoIterator<Item = impl AsRef<Path>>) -> Self {
        self.files.extend(paths.into_iter().map(|p| (p.as_ref().to_path_buf(), None)));
        self
    }

    /// Writes into `dir` instead of `OUT_DIR`.
    #[must_use]
    pub fn out_dir(mut self, dir: impl AsRef<Path>) -> Self {
        self.out_dir = Some(dir.as_ref().to_path_buf());
        self
    }

    /// Prints no `cargo::` directives (for use outside a build script).
    #[must_use]
    pub fn quiet(mut self) -> Self {
        self.quiet = true;
        self
    }

    /// Validates every description, generates its module and writes the files.
    ///
    /// # Errors
    ///
    /// No output directory (neither [`out_dir`](Self::out_dir) nor `OUT_DIR`); an invalid
    /// description (the message holds every diagnostic with its excerpt); a description the
    /// generator refuses; two descriptions with the same `name`; an I/O failure.
    pub fn compile(self) -> Result<Vec<Generated>, Error> {
        let dir = match self.out_dir {
            Some(dir) => dir,
            None => std::env::var_os("OUT_DIR").map(PathBuf::from).ok_or(Error::NoOutDir)?,
        };
        std::fs::create_dir_all(&dir).map_err(|source| Error::Io { path: dir.clone(), source })?;
        let mut generated: Vec<Generated> = Vec::new();
        for (file, outputs) in &self.files {
            if !self.quiet {
                directive("rerun-if-changed", &path_text(file)?);
            }
            let (module, text, warnings) = generate(file, outputs.as_deref())?;
            if !self.quiet {
                for w in warnings {
                    directive("warning", &w);
                }
            }
            if generated.iter().any(|g| g.module == module) {
                return Err(Error::DuplicateName { file: file.clone(), module });
            }
            let path = dir.join(format!("{module}.rs"));
            write_if_changed(&path, &text)?;
            generated.push(Generated { module, path });
        }
        let mut items: Vec<syn::Item> = Vec::new();
        for g in &generated {
            let path = syn::LitStr::new(&path_text(&g.path)?, proc_macro2::Span::call_site());
            // The name passed validation: `[a-z][a-z0-9_]*` and no keyword.
            let module = syn::Ident::new(&g.module, proc_macro2::Span::call_site());
            items.push(syn::parse_quote! {
                #[path = #path]
                pub mod #module;
            });
        }
        let index = format!(
            "// @generated by codegen::build. Do not edit.\n\
             // One module per description; include with\n\
             // include!(concat!(env!(\"OUT_DIR\"), \"/mechgen.rs\"));\n\n{}",
            prettyplease::unparse(&syn::File { shebang: None, attrs: Vec::new(), items })
        );
        write_if_changed(&dir.join("mechgen.rs"), &index)?;
        Ok(generated)
    }
}

/// Prints the build-script directive `cargo::key=value` on one line: the characters that
/// would end the line or hide in it (controls, line separators, bidi and other invisible
/// characters) are written as `\u{…}`, so the value cannot start another directive.
fn directive(key: &str, value: &str) {
    println!("cargo::{key}={}", one_line(value));
}

/// `value` on one line, as [`directive`] prints it.
fn one_line(value: &str) -> String {
    let mut out = String::with_capacity(value.len());
    for c in value.chars() {
        if crate::validate::names::hidden(c) {
            out.push_str(&format!("\\u{{{:04x}}}", u32::from(c)));
        } else {
            out.push(c);
        }
    }
    out
}

/// A path as UTF-8 text without hidden characters (see [`one_line`]): cargo reads
/// `rerun-if-changed` and `#[path]` takes a string, so any other path is refused.
fn path_text(path: &Path) -> Result<String, Error> {
    match path.to_str() {
        Some(text) if !text.chars().any(crate::validate::names::hidden) => Ok(text.to_owned()),
        _ => Err(Error::Path { path: path.to_path_buf() }),
    }
}

/// The module name and text of one description, restricted to `outputs` when given, and
/// its warnings (one line each).
fn generate(
    file: &Path,
    outputs: Option<&[String]>,
) -> Result<(String, String, Vec<String>), Error> {
    let render_all = |diagnostics: Vec<diag::Diagnostic>, text: Option<&str>| Error::Invalid {
        file: file.to_path_buf(),
        rendered: diag::render(&diagnostics, text, false).trim_end().to_owned(),
        diagnostics,
    };
    let (text, format) = validate::read_file(file).map_err(|d| render_all(d, None))?;
    let loaded = validate::load_str(&text, format, Some(&file.display().to_string()))
        .map_err(|d| render_all(d, Some(&text)))?;
    let generate_error = |source| Error::Generate { file: file.to_path_buf(), source };
    let mut mech = loaded.mechanism;
    let mut sys = Symbolic::build(&mech).map_err(generate_error)?;
    if let Some(names) = outputs {
        let only = crate::blocks::outputs::only(&mech, &sys, names)
            .map_err(|source| Error::Outputs { file: file.to_path_buf(), source })?;
        if only != mech {
            mech = only;
            sys = Symbolic::build(&mech).map_err(generate_error)?;
        }
    }
    let source = file.display().to_string().replace('\\', "/");
    let warnings = loaded.warnings.iter().map(ToString::to_string).collect();
    Ok((mech.name.clone(), emit::module(&mech, &sys, &source), warnings))
}

/// Writes `text` unless the file already holds it (so cargo sees no change).
fn write_if_changed(path: &Path, text: &str) -> Result<(), Error> {
    if std::fs::read_to_string(path).is_ok_and(|have| have == text) {
        return Ok(());
    }
    std::fs::write(path, text).map_err(|source| Error::Io { path: path.to_path_buf(), source })
}

#[cfg(test)]
mod tests;
