//! `mechgen generate`: the specialised Rust module of a description.

use std::io::{self, Write};
use std::path::Path;

use super::common::{EXIT_OK, load, report_invalid};
use crate::diag::Diagnostic;

/// The files of `generate`: the description and `-o`.
pub(super) struct Files<'a> {
    pub(super) file: &'a Path,
    pub(super) output: Option<&'a Path>,
}

pub(super) fn generate(
    files: Files<'_>,
    scalar: crate::emit::Scalar,
    outputs: Option<&[String]>,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<i32> {
    let Files { file, output } = files;
    let mut loaded = match load(file, false, out, err) {
        Ok(l) => l,
        Err(code) => return Ok(code),
    };
    if let Some(names) = outputs {
        match super::common::only_outputs(&loaded.mechanism, names, "--outputs", out, err)? {
            Ok(Some(only)) => loaded.mechanism = only,
            Ok(None) => {}
            Err(code) => return Ok(code),
        }
    }
    let sys = match crate::symbolic::Symbolic::build(&loaded.mechanism) {
        Ok(s) => s,
        Err(e) if !loaded.mechanism.input_drivers().is_empty() => {
            // A valid description the generator cannot emit yet: not invalid input.
            writeln!(err, "error: the generated solver could not be built: {e}")?;
            return Ok(super::common::EXIT_BUILD);
        }
        Err(e) => {
            let d = Diagnostic::error(e.message)
                .entity(format!("mechanism \"{}\"", loaded.mechanism.name));
            return Ok(report_invalid(&[d], false, out, err));
        }
    };
    let text = crate::emit::module_in(&loaded.mechanism, &sys, &file.display().to_string(), scalar);
    let tolerance = loaded.mechanism.solver.tolerance;
    if scalar == crate::emit::Scalar::F32 && tolerance < 1e-5 {
        writeln!(
            err,
            "warning: the description's tolerance {tolerance:e} (the module's TOLERANCE) is \
             below what single precision reaches; set NewtonOptions::tolerance to about 1e-4 \
             (runtime::Real::DEFAULT_TOLERANCE for f32)"
        )?;
    }
    match output {
        Some(path) => crate::output::write_file(path, text.as_bytes())?,
        None => out.write_all(text.as_bytes())?,
    }
    Ok(EXIT_OK)
}
