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

    use crate::mechanism::{BODIES, N};

    /// The inputs of every input driver at one instant, `[s, ṡ, s̈]` each.
    type Inputs = [[Real; 3]; INPUTS];

    /// The number of input drivers: none.
    pub(crate) const INPUTS: usize = 0;

    /// The mechanism (it has no inputs).
    pub(crate) fn generated(_t: Real, _u: &Inputs) -> Generated {
        Generated
    }

    /// Sets the inputs: there are none.
    pub(crate) fn aim(_m: &mut Generated, _t0: Real, _u0: &Inputs, _t1: Real, _u1: &Inputs) {}

    /// The module's `expand`.
    pub(crate) fn expand(
        _m: &Generated,
        q: &[Real; N],
        qd: &[Real; N],
        qdd: &[Real; N],
        t: Real,
        out: &mut [[[Real; 7]; 3]; BODIES],
    ) {
        crate::mechanism::expand(q, qd, qdd, t, out);
    }
}

/// The key of the cache entry: none here.
mod key {
    /// Printed by `key`.
    pub(crate) const KEY: &str = "workspace-example";
}

fn main() {
    driver::main();
}
