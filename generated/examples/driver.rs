//! The driver of every solver `mechgen` builds (`codegen/src/engine/driver.rs`), compiled
//! here against the committed `generated::rssr` so that rustc, clippy and rustfmt check it
//! as the workspace's own code. mechgen writes the same three sibling modules next to it in
//! each generated crate (`codegen::engine::cache`); this one runs the RSSR:
//! `cargo run -p generated --example driver -- run`.

#[path = "../../codegen/src/engine/driver.rs"]
mod driver;

/// The generated module.
mod mechanism {
    pub(crate) use generated::rssr::*;
}

/// What the driver reads about the module, as mechgen writes it for the RSSR in `f64`.
mod config {
    /// The floating-point type the module was generated in.
    pub(crate) type Real = f64;

    /// The generated mechanism.
    pub(crate) use crate::mechanism::Rssr as Generated;
}

/// The key of the cache entry: none here.
mod key {
    /// Printed by `key`.
    pub(crate) const KEY: &str = "workspace-example";
}

fn main() {
    driver::main();
}
