//! Rank decisions do not depend on the unit of length (issue 11.9): the four-bar and the
//! R-S-S-R with every length scaled by 10⁻³, 10⁵ and 10⁶ give the same `check` verdict (rank,
//! mobility, redundant equations) as at their own scale, and both engines solve them with
//! results equal to the unit results scaled.

use crate::harness::mechgen;
use std::path::{Path, PathBuf};

use toml::{Table, Value};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// `value` (a number or an array of numbers) times `s`.
fn times(value: &mut Value, s: f64) {
    match value {
        Value::Float(x) => *x *= s,
        Value::Integer(i) => *value = Value::Float(*i as f64 * s),
        Value::Array(a) => a.iter_mut().for_each(|v| times(v, s)),
        other => panic!("not a number: {other}"),
    }
}

/// The description `text` with every length times `s`: body positions, joint and point
/// locations, translational constraints and the laws of translational drivers. Axes and
/// reference directions are directions and Euler parameters are dimensionless; both stay.
/// The Newton tolerance stays unless the round-off of the scaled coordinates exceeds it: the
/// four-bar's coordinates of up to 8.5 `s` carry half an ulp each, up to 2⁻⁵³ · 2⁴ `s` ≈ 1.8·10⁻¹⁵
/// `s` (1.2·10⁻¹⁰ m at `s` = 10⁵), and a joint's residual sums a few of them (four or more where
/// the generated solver writes positions torn from the loop as sums of pins, the loop's rows
/// then adding those sums), so the tolerance becomes at least 10⁻¹⁴ `s`: about five such
/// roundings. It cannot be scaled with `s` outright: it also bounds the dimensionless rows,
/// which do not scale. (10⁻¹⁵ `s`, below one rounding of the largest coordinate, left the
/// torn four-bar's Newton at a residual of 2⁻³³ ≈ 1.16·10⁻¹⁰ against 10⁻¹⁰ at `s` = 10⁵.)
pub(crate) fn scaled(text: &str, s: f64) -> String {
    let mut doc: Table = text.parse().unwrap();
    let tables = |doc: &Table, key: &str| -> Vec<Table> {
        doc.get(key)
            .and_then(Value::as_array)
            .map_or_else(Vec::new, |a| a.iter().map(|v| v.as_table().unwrap().clone()).collect())
    };
    let translational = |t: &Table| {
        matches!(t.get("coordinate").and_then(Value::as_str), Some("x" | "y" | "z"))
            || t.get("motion").and_then(Value::as_str) == Some("translation")
    };
    let put = |doc: &mut Table, key: &str, items: Vec<Table>| {
        if !items.is_empty() {
            doc.insert(key.into(), Value::Array(items.into_iter().map(Value::Table).collect()));
        }
    };
    let mut bodies = tables(&doc, "bodies");
    for b in &mut bodies {
        if let Some(r) = b.get_mut("r") {
            times(r, s);
        }
    }
    let mut joints = tables(&doc, "joints");
    for j in &mut joints {
        for key in ["point_i", "point_j", "lead"] {
            if let Some(v) = j.get_mut(key) {
                times(v, s);
            }
        }
    }
    let mut constraints = tables(&doc, "constraints");
    for c in &mut constraints {
        if translational(c) {
            times(c.get_mut("value").unwrap(), s);
        }
    }
    let mut drivers = tables(&doc, "drivers");
    for d in &mut drivers {
        if translational(d) {
            let law = d.get_mut("law").unwrap().as_table_mut().unwrap();
            for (key, v) in law.iter_mut() {
                // A sinusoid's frequency and phase are not lengths.
                if !matches!(key.as_str(), "frequency" | "phase") {
                    times(v, s);
                }
            }
        }
    }
    let mut points = tables(&doc, "points");
    for p in &mut points {
        times(p.get_mut("local").unwrap(), s);
    }
    put(&mut doc, "bodies", bodies);
    put(&mut doc, "joints", joints);
    put(&mut doc, "constraints", constraints);
    put(&mut doc, "drivers", drivers);
    put(&mut doc, "points", points);
    let solver = doc.entry("solver").or_insert_with(|| Value::Table(Table::new()));
    let solver = solver.as_table_mut().unwrap();
    let tolerance = solver.get("tolerance").and_then(Value::as_float).unwrap_or(1e-10);
    solver.insert("tolerance".into(), Value::Float(tolerance.max(1e-14 * s)));
    toml::to_string(&doc).unwrap()
}

/// `example` scaled by `s`, written to the target directory.
fn write_scaled(example: &str, s: f64) -> PathBuf {
    let text = std::fs::read_to_string(codegen::testing::example(example)).unwrap();
    let dir = root().join("target").join("scale-test");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{s:e}_{example}"));
    std::fs::write(&path, scaled(&text, s)).unwrap();
    path
}

/// The quantities of a solve's JSON output as (name, value, unit of length or not), in order.
fn quantities(json: &str) -> Vec<(String, f64, bool)> {
    let v: serde_json::Value = serde_json::from_str(json).unwrap();
    assert!(v["error"].is_null(), "the analysis stopped: {}", v["error"]);
    let mut out = Vec::new();
    for (k, step) in v["steps"].as_array().unwrap().iter().enumerate() {
        for (group, lengths) in
            [("bodies", &["r", "r_dot", "r_ddot"][..]), ("points", &["r", "v", "a"])]
        {
            for (name, entity) in step[group].as_object().unwrap() {
                for (quantity, values) in entity.as_object().unwrap() {
                    for (i, x) in values.as_array().unwrap().iter().enumerate() {
                        out.push((
                            format!("step {k} {group} {name} {quantity}[{i}]"),
                            x.as_f64().unwrap(),
                            lengths.contains(&quantity.as_str()),
                        ));
                    }
                }
            }
        }
    }
    out
}

/// The kind of a quantity named by [`quantities`]: its group and quantity (`bodies r`).
fn kind(name: &str) -> String {
    let words: Vec<&str> = name.split(' ').collect();
    format!("{} {}", words[2], words[4].split('[').next().unwrap())
}

/// The largest magnitude of each kind of quantity over all steps and entities, so that
/// differences are measured relative to the size of the quantity in the mechanism, not to a
/// component that stays at zero (the crank's origin on its axis, say).
fn magnitudes(q: &[(String, f64, bool)]) -> std::collections::BTreeMap<String, f64> {
    let mut m = std::collections::BTreeMap::new();
    for (name, x, _) in q {
        let e = m.entry(kind(name)).or_insert(0.0_f64);
        *e = e.max(x.abs());
    }
    m
}

/// Scaling every length by these factors changes no rank decision and, on both engines, no
/// result beyond the scaling.
const SCALES: [f64; 3] = [1e-3, 1e5, 1e6];

/// The same `check` verdict at every scale, and results equal to the unit results scaled.
fn invariant(example: &str) {
    let unit = write_scaled(example, 1.0);
    let unit = unit.to_str().unwrap();
    let (status, check_unit, err) = mechgen(&["check", unit, "--format", "json"]);
    assert_eq!(status, 0, "{err}");
    let solved_unit: Vec<_> = ["generic", "generated"]
        .iter()
        .map(|engine| {
            let (status, out, err) =
                mechgen(&["solve", unit, "--engine", engine, "--format", "json"]);
            assert_eq!(status, 0, "{example} on the {engine} engine: {err}");
            quantities(&out)
        })
        .collect();
    for s in SCALES {
        let path = write_scaled(example, s);
        let file = path.to_str().unwrap();
        let (status, check, err) = mechgen(&["check", file, "--format", "json"]);
        assert_eq!((status, &check), (0, &check_unit), "{example} scaled by {s:e}: {err}");
        for (engine, reference) in ["generic", "generated"].iter().zip(&solved_unit) {
            let (status, out, err) =
                mechgen(&["solve", file, "--engine", engine, "--format", "json"]);
            assert_eq!(status, 0, "{example} scaled by {s:e} on the {engine} engine: {err}");
            let got = quantities(&out);
            assert_eq!(got.len(), reference.len(), "{example} scaled by {s:e}, {engine}");
            let sizes = magnitudes(reference);
            for ((name, x, length), (_, x0, _)) in got.iter().zip(reference) {
                let expected = if *length { x0 * s } else { *x0 };
                let size = sizes[&kind(name)];
                let size = if *length { size * s } else { size };
                // Both runs meet a Newton tolerance of 1e-10 on lengths of order 1 (1e-8 on
                // lengths of 10⁶, see `scaled`), so positions agree to about 1e-10 relative
                // where a step is accepted without a further iteration (measured: 1.5e-10 for
                // the R-S-S-R, 2.4e-12 for the four-bar) and velocities and accelerations,
                // solved at those positions, as well; 1e-9 of the quantity's size leaves a
                // factor of about 7 over the worst measured.
                assert!(
                    (x - expected).abs() <= 1e-9 * size,
                    "{example} scaled by {s:e}, {engine}: {name} = {x:e}, expected {expected:e}"
                );
            }
        }
    }
}

#[test]
fn the_four_bar_is_the_same_at_every_scale() {
    invariant("four_bar.toml");
}

#[test]
fn the_rssr_is_the_same_at_every_scale() {
    invariant("rssr.toml");
}
