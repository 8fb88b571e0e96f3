//! `mechgen codegen` (hidden): regenerate or check `generated/src`.

use std::io::{self, Write};

use super::common::{EXIT_INVALID, EXIT_OK};

pub(super) fn codegen(check: bool, out: &mut dyn Write, err: &mut dyn Write) -> io::Result<i32> {
    let mode = if check { crate::sync::Mode::Check } else { crate::sync::Mode::Write };
    match crate::sync::sync(&crate::sync::workspace_root(), mode) {
        Ok(stale) => {
            for s in &stale {
                writeln!(out, "{}: {s:?}", if check { "stale" } else { "updated" })?;
            }
            Ok(if check && !stale.is_empty() { EXIT_INVALID } else { EXIT_OK })
        }
        Err(e) => {
            writeln!(err, "error: {e}")?;
            Ok(EXIT_INVALID)
        }
    }
}
