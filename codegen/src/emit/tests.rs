//! Emission details: literals, precedence, names.

use super::syntax::literal;
use super::type_name;

#[test]
fn type_names_are_upper_camel_case() {
    assert_eq!(type_name("rssr"), "Rssr");
    assert_eq!(type_name("four_bar"), "FourBar");
    assert_eq!(type_name("ex_2_6_1"), "Ex261");
}

#[test]
fn literals_round_trip_and_avoid_approx_constant() {
    let show = |v: f64| {
        let e = literal(v);
        quote::quote!(#e).to_string()
    };
    assert_eq!(show(1.0), "1.0");
    assert_eq!(show(1e-20), "1e-20");
    assert_eq!(show(std::f64::consts::PI), "core :: f64 :: consts :: PI");
    // 3.1416 is not π, but clippy's approx_constant would reject its decimal form.
    // (Parsed from text: clippy rejects the literal in this file too, which is the point.)
    let near_pi: f64 = "3.1416".parse().unwrap();
    assert_eq!(show(near_pi), format!("f64 :: from_bits ({})", near_pi.to_bits()));
    assert_eq!(show(0.06567), "0.06567");
}

/// Binary arithmetic operators in a piece of emitted (prettyplease-printed) code.
fn binary_operations(code: &str) -> usize {
    [" + ", " - ", " * ", " / "].iter().map(|op| code.matches(op).count()).sum()
}

/// The top-level functions of an emitted module: (name, text).
fn functions(module: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut current: Option<(String, String)> = None;
    for line in module.lines() {
        if let Some(rest) = line.strip_prefix("pub fn ").or_else(|| line.strip_prefix("fn ")) {
            let name = rest.split('(').next().unwrap_or_default().to_owned();
            current = Some((name, String::new()));
        }
        if let Some((_, text)) = &mut current {
            text.push_str(line);
            text.push('\n');
            if line == "}" {
                out.extend(current.take());
            }
        }
    }
    out
}

/// A chain of 30 links (scale.rs) and its reduced system, kept whole (210 unknowns; built
/// with its closed forms substituted it has none): large enough to be split.
fn chain_30() -> (crate::model::Mechanism, crate::symbolic::Symbolic) {
    let text = crate::scale::chain(30, 2);
    let mech =
        crate::validate::load_str(&text, crate::validate::Format::Toml, None).unwrap().mechanism;
    let sys = crate::symbolic::Symbolic::build_full(&mech).unwrap();
    (mech, sys)
}

/// The operations of the parts of `name` in an emitted module.
fn split_operations(module: &str, name: &str) -> usize {
    let prefix = format!("{name}_");
    functions(module)
        .iter()
        .filter(|(f, _)| f.strip_prefix(&prefix).is_some_and(|k| k.parse::<usize>().is_ok()))
        .map(|(_, code)| binary_operations(code))
        .sum()
}

#[test]
fn an_explicit_chain_is_emitted_in_parts_whose_size_grows_linearly() {
    // Driven chains are substituted whole: each link's coordinates are expressions of the
    // link's before it. Split, the parts must read the earlier links' coordinates back (the
    // array `kept`) rather than compute them again, which would make the module grow as the
    // square of the length.
    let ops = |links: usize| {
        let text = crate::scale::chain(links, 2);
        let mech = crate::validate::load_str(&text, crate::validate::Format::Toml, None)
            .unwrap()
            .mechanism;
        let sys = crate::symbolic::Symbolic::build(&mech).unwrap();
        assert!(sys.unknowns.is_empty(), "{links} links: {} unknowns", sys.unknowns.len());
        let module = super::module(&mech, &sys, "a test");
        assert!(module.contains("kept: &mut [f64;"), "{links} links: no part reads `kept`");
        split_operations(&module, "expand")
    };
    let (short, long) = (ops(40), ops(80));
    // Twice the links, twice the operations, up to the first link's (which reads no earlier
    // link) and the parts' reads of `kept`: 10 % margin. Quadratic growth would give 4.
    let ratio = long as f64 / short as f64;
    assert!((1.8..=2.2).contains(&ratio), "{short} → {long} operations: ratio {ratio}");
}

#[test]
fn large_mechanisms_are_emitted_as_bounded_functions() {
    let (mech, sys) = chain_30();
    // With the static orders, γ is one whole-system function (a module solved block by block
    // writes it block by block, `emit::shared`), which without splitting takes far more than
    // the bound.
    let whole = super::module_with_static_orders(&mech, &sys, "a test", super::Scalar::F64);
    let total: usize = functions(&whole)
        .iter()
        .filter(|(name, _)| name.starts_with("acceleration_rhs_"))
        .map(|(_, code)| binary_operations(code))
        .sum();
    assert!(total > 4 * super::CHUNK_OPS, "{total}");
    // A part closes after the output or LU step that crosses CHUNK_OPS, and no single output
    // or step of a chain takes more than CHUNK_OPS operations: no function exceeds twice it.
    for module in [whole, super::module(&mech, &sys, "a test")] {
        for (name, code) in &functions(&module) {
            let ops = binary_operations(code);
            assert!(ops <= 2 * super::CHUNK_OPS, "{name} has {ops} operations");
        }
        let helpers = module.matches("#[inline(never)]").count();
        assert!(helpers >= 10, "{helpers} helpers");
    }
}

#[test]
fn a_split_module_is_rewritten_to_single_precision_throughout() {
    // The f32 rewrite works item by item, so the split helpers must come out in f32 too,
    // with the array `kept` of an explicit chain's parts.
    let (mech, sys) = chain_30();
    let explicit = crate::symbolic::Symbolic::build(&mech).unwrap();
    for (sys, marker) in [(sys, "[f32; N]"), (explicit, "kept: &mut [f32;")] {
        let module = super::module_in(&mech, &sys, "a test", super::Scalar::F32);
        assert!(module.matches("#[inline(never)]").count() >= 3);
        // Code lines only: doc comments may name f64 in prose.
        let code: Vec<&str> =
            module.lines().filter(|l| !l.trim_start().starts_with("//")).collect();
        let leaks: Vec<&&str> = code.iter().filter(|l| l.contains("f64")).collect();
        assert!(leaks.is_empty(), "{} lines keep f64, e.g. {:?}", leaks.len(), leaks.first());
        assert!(code.iter().any(|l| l.contains(marker)), "{marker}");
    }
}

#[test]
fn every_constant_the_module_defines_is_a_reserved_type_name() {
    // The unit struct shares the value namespace with the constants: a mechanism whose type
    // name equals one of them is refused by validation, which needs the list to be complete.
    let (mech, sys) = chain_30();
    let module = super::module(&mech, &sys, "chain");
    let mut constants = 0;
    for line in module.lines() {
        if let Some(rest) = line.strip_prefix("pub const ").filter(|r| !r.starts_with("fn ")) {
            let name = rest.split(':').next().unwrap_or_default();
            constants += 1;
            if !name.contains('_') {
                assert!(
                    crate::validate::names::RESERVED_TYPE_NAMES.contains(&name),
                    "{name} is missing from RESERVED_TYPE_NAMES"
                );
            }
        }
    }
    assert!(constants >= 10, "{constants} constants: the module's layout changed");
}

#[test]
fn documentation_is_one_line_per_attribute_and_the_description_is_fenced() {
    let (mut mech, sys) = chain_30();
    mech.description = Some("a\n```rust\n*/ fn x() {}\r\u{202e}".to_owned());
    let module = super::module(&mech, &sys, "a\nb");
    assert!(!module.lines().any(|l| l.trim_start().starts_with("/*")), "a block comment");
    assert!(!module.contains(['\r', '\u{202e}']), "a raw control character");
    // The fence is longer than the description's run of three backticks.
    assert!(
        module.contains(
            "//! ````text\n//! a\n//! ```rust\n//! */ fn x() {}\n//! \\u{202e}\n//! ````"
        )
    );
    assert!(module.contains("//! Generated by mechgen from a\\u{000a}b."), "{module}");
}

/// The golden fixtures: each `fixtures/<case>/input.toml` must generate exactly
/// `fixtures/<case>/expected.rs` (as prost-build keeps its expected output). A change to the
/// emitter shows up here as a readable diff of a small module; after checking it, run
/// `UPDATE_EXPECT=1 cargo test -p codegen golden` to write the new expected files.
#[test]
fn golden_fixtures_generate_their_expected_modules() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src/emit/fixtures");
    let update = std::env::var_os("UPDATE_EXPECT").is_some_and(|v| v == "1");
    let mut cases: Vec<_> = std::fs::read_dir(&root)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("input.toml").is_file())
        .collect();
    cases.sort();
    assert!(cases.len() >= 2, "{} fixtures in {}", cases.len(), root.display());
    let mut stale = Vec::new();
    for case in &cases {
        let name = case.file_name().unwrap().to_string_lossy().into_owned();
        let mech = crate::validate::load_file(&case.join("input.toml")).unwrap().mechanism;
        let sys = crate::symbolic::Symbolic::build(&mech).unwrap();
        let source = format!("fixtures/{name}/input.toml");
        let actual = super::module(&mech, &sys, &source);
        let expected_path = case.join("expected.rs");
        if update {
            std::fs::write(&expected_path, &actual).unwrap();
            continue;
        }
        let expected = std::fs::read_to_string(&expected_path).unwrap_or_default();
        if actual != expected {
            let line = actual.lines().zip(expected.lines()).position(|(a, e)| a != e);
            stale.push(format!("{name} (first difference at line {})", line.map_or(0, |l| l + 1)));
        }
    }
    assert!(stale.is_empty(), "changed: {stale:?}; rerun with UPDATE_EXPECT=1 to accept");
}
