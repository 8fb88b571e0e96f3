//! `mechgen import-young`: a legacy YOUNG deck as a description.

use std::io::{self, Write};
use std::path::Path;

use super::common::{EXIT_OK, report_invalid};
use crate::young;

pub(super) fn import_young(
    deck: &Path,
    output: Option<&Path>,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<i32> {
    let desc = match young::import_file(deck) {
        Ok(d) => d,
        Err(d) => return Ok(report_invalid(&[d], false, out, err)),
    };
    let file_name = deck
        .file_name()
        .map_or_else(|| deck.display().to_string(), |f| f.to_string_lossy().into_owned());
    let toml =
        young::to_toml(&desc, &format!("Imported by mechgen from the YOUNG deck {file_name}."));
    match output {
        Some(path) => crate::output::write_file(path, toml.as_bytes())?,
        None => out.write_all(toml.as_bytes())?,
    }
    Ok(EXIT_OK)
}
