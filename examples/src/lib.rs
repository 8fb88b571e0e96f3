//! Shipped mechanism descriptions (`examples/*.toml`) and helpers to find them.

use std::path::PathBuf;

/// The directory holding the shipped example descriptions.
#[must_use]
pub fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}
