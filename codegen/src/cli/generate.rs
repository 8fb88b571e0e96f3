//! `mechgen generate`: the specialised Rust module of a description.

use std::io::{self, Write};
use std::path::Path;

use super::common::{EXIT_OK, load, report_invalid};
use crate::diag::Diagnostic;

pub(super) fn generate(
    file: &Path,
    scalar: crate::emit::Scalar,
    output: Option<&Path>,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<i32> {
    let loaded = match load(file, false, out, err) {
        Ok(l) => l,
        Err(code) => return Ok(code),
    };
    let sys = match crate::symbolic::Symbolic::build(&loaded.mechanism) {
        Ok(s) => s,
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
