//! Large generated modules, split into helper functions, in both precisions, pass rustc and
//! clippy with warnings denied, as the committed (unsplit) modules do in CI.

use std::process::Command;

use codegen::emit::{Scalar, module_in, module_with_static_orders};
use codegen::symbolic::Symbolic;
use codegen::testing::load_toml;

#[test]
fn split_modules_pass_clippy_with_warnings_denied_in_f64_and_f32() {
    let root = codegen::sync::workspace_root();
    let dir = root.join("target/split-modules");
    std::fs::create_dir_all(dir.join("src")).expect("target/ is writable");
    // A chain of 30 links and 10 R-S-S-R loops: big enough that the residuals, the Jacobian,
    // the LU factors and the solves are all split into helpers (CHUNK_OPS), with parts of a
    // solve whose factors are all constants; smaller ones split less and missed two clippy
    // errors (a self-assignment and an unused argument) that these have. Both are factored
    // block by block (`emit::blocks`), so each is also emitted with its static pivot orders.
    let cases =
        [("chain", codegen::scale::chain(30, 2)), ("loops", codegen::scale::rssr_loops(10, 2))];
    let mut lib = String::from("#![no_std]\n//! Split generated modules, checked by clippy.\n");
    let mut helpers = 0;
    for (name, text) in &cases {
        let mech = load_toml(text);
        // The whole systems: substituted, the loops would fall below the block-by-block bound.
        let sys = Symbolic::build_full(&mech).expect("generates");
        for scalar in [Scalar::F64, Scalar::F32] {
            let blocks = module_in(&mech, &sys, name, scalar);
            assert!(blocks.contains("static BLOCKS"), "{name}: factored block by block");
            let orders = module_with_static_orders(&mech, &sys, name, scalar);
            assert!(orders.contains("fn factor_0"), "{name}: static orders");
            for (module, how) in [(blocks, "blocks"), (orders, "orders")] {
                helpers += module.matches("#[inline(never)]").count();
                let file = format!("{name}_{how}_{}", scalar.name());
                std::fs::write(dir.join(format!("src/{file}.rs")), module).expect("writable");
                lib.push_str(&format!("pub mod {file};\n"));
            }
        }
    }
    // The same chain substituted whole (no unknowns): its output functions are split into
    // parts that pass substituted coordinates to each other through the array `kept`. And
    // three explicit arms, with laws and with inputs, whose alike arms share one `expand`.
    let arms = codegen::scale::arms(3, 4, 2);
    let arms_inputs: String = arms
        .lines()
        .map(|l| {
            if l.starts_with("law = {") { "law = \"input\"\n".to_owned() } else { format!("{l}\n") }
        })
        .collect();
    let explicit = [
        ("chain_explicit", cases[0].1.as_str(), "let mut kept = "),
        ("arms", arms.as_str(), "fn expand_shared_0("),
        ("arms_inputs", arms_inputs.as_str(), "fn expand_shared_0("),
    ];
    for (name, text, marker) in explicit {
        let mech = load_toml(text);
        let sys = Symbolic::build(&mech).expect("generates");
        assert!(sys.unknowns.is_empty(), "{name} is explicit");
        for scalar in [Scalar::F64, Scalar::F32] {
            let module = module_in(&mech, &sys, name, scalar);
            assert!(module.contains(marker), "{name}: {marker}");
            helpers += module.matches("#[inline(never)]").count();
            let file = format!("{name}_{}", scalar.name());
            std::fs::write(dir.join(format!("src/{file}.rs")), module).expect("writable");
            lib.push_str(&format!("pub mod {file};\n"));
        }
    }
    assert!(helpers >= 100, "only {helpers} split helpers: the test no longer checks splitting");
    std::fs::write(dir.join("src/lib.rs"), lib).expect("writable");
    let manifest = format!(
        "[package]\nname = \"split-modules\"\nversion = \"0.0.0\"\nedition = \"2024\"\npublish = false\n\n\
         [dependencies]\nruntime = {{ path = {:?} }}\n\n[workspace]\n",
        root.join("runtime").display().to_string()
    );
    std::fs::write(dir.join("Cargo.toml"), manifest).expect("writable");
    if let Ok(lock) = std::fs::read_to_string(root.join("Cargo.lock")) {
        std::fs::write(dir.join("Cargo.lock"), lock).expect("writable");
    }
    let output = Command::new(std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into()))
        .args(["clippy", "--offline", "--quiet", "--manifest-path"])
        .arg(dir.join("Cargo.toml"))
        .args(["--", "-D", "warnings"])
        .env("CARGO_TARGET_DIR", dir.join("target"))
        .output()
        .expect("cargo runs");
    assert!(
        output.status.success(),
        "clippy refuses a split module:\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
}

/// A static order long enough to be split (`emit::lu`: `factor_0` into helpers that read the
/// factors of earlier parts back from `jac`, then U's rows scaled by their reciprocal pivots
/// in the last part; `solve_0` through a scratch array) factors and solves as the generic
/// engine's LU does: the run of ten R-S-S-R loops, whole (200 unknowns), agrees with the generic
/// engine's at every frame.
#[test]
fn split_static_orders_solve_as_the_generic_engine() {
    let mech = load_toml(&format!(
        "{}\n[solver]\ntolerance = 1e-12\n",
        codegen::scale::rssr_loops(10, 20)
    ));
    let sys = Symbolic::build_full(&mech).expect("generates");
    let module = module_with_static_orders(&mech, &sys, "split_orders", Scalar::F64);
    for helper in ["fn factor_0_1(", "fn solve_0_1("] {
        assert!(module.contains(helper), "the static order is split: {helper}");
    }
    // Every frame, to `block_solver::AGREEMENT` (1e-10 of each quantity's scale).
    crate::block_solver::agrees_with_generic(&mech, &sys, &module);
}
