//! One test per rule: the message, the entity, the field and the place of each diagnostic.
//!
//! Most tests edit one line of [`BASE`], a small valid description, so the expected line is
//! the edited one; tests that need more entities append them after its last line (26).

use approx::assert_relative_eq;

use super::{Format, Loaded, edit_distance, load_file, load_str, validate};
use crate::desc::MechanismDesc;
use crate::diag::{Diagnostic, Severity};
use crate::model::{DriverTarget, JointKind, Law};

/// A slider on a rail, driven in translation: 7 unknowns, 5 + 1 + 1 equations.
const BASE: &str = r#"name = "slider"
[time]
start = 0.0
end = 1.0
step = 0.1
[[bodies]]
name = "ground"
ground = true
[[bodies]]
name = "block"
[[joints]]
name = "rail"
type = "prismatic"
body_i = "ground"
body_j = "block"
point_i = [0.0, 0.0, 0.0]
point_j = [0.0, 0.0, 0.0]
axis_i = [1.0, 0.0, 0.0]
axis_j = [1.0, 0.0, 0.0]
ref_i = [0.0, 1.0, 0.0]
ref_j = [0.0, 1.0, 0.0]
[[drivers]]
name = "push"
joint = "rail"
motion = "translation"
law = { start = 0.0, velocity = 1.0 }
"#;

/// [`BASE`] in JSON.
const BASE_JSON: &str = r#"{
  "name": "slider",
  "time": { "start": 0.0, "end": 1.0, "step": 0.1 },
  "bodies": [
    { "name": "ground", "ground": true },
    { "name": "block" }
  ],
  "joints": [
    {
      "name": "rail",
      "type": "prismatic",
      "body_i": "ground",
      "body_j": "block",
      "point_i": [0.0, 0.0, 0.0],
      "point_j": [0.0, 0.0, 0.0],
      "axis_i": [1.0, 0.0, 0.0],
      "axis_j": [1.0, 0.0, 0.0],
      "ref_i": [0.0, 1.0, 0.0],
      "ref_j": [0.0, 1.0, 0.0]
    }
  ],
  "drivers": [
    { "name": "push", "joint": "rail", "motion": "translation", "law": { "start": 0.0, "velocity": 1.0 } }
  ]
}
"#;

/// A second moving body hinged to the block, with a rotation driver (lines 27–48).
const HINGE: &str = r#"[[bodies]]
name = "arm"
[[joints]]
name = "hinge"
type = "revolute"
body_i = "block"
body_j = "arm"
point_i = [0.0, 0.0, 0.0]
point_j = [0.0, 0.0, 0.0]
axis_i = [0.0, 0.0, 1.0]
axis_j = [0.0, 0.0, 1.0]
ref_i = [1.0, 0.0, 0.0]
ref_j = [1.0, 0.0, 0.0]
[[drivers]]
name = "swing"
joint = "hinge"
motion = "rotation"
law = { offset = 0.0, amplitude = 0.5, frequency = 2.0 }
[[points]]
name = "tip"
body = "arm"
local = [0.3, 0.0, 0.0]
"#;

/// [`BASE`] with each `(from, to)` replacing text that occurs exactly once.
fn edit(edits: &[(&str, &str)]) -> String {
    edit_text(BASE, edits)
}

fn edit_text(text: &str, edits: &[(&str, &str)]) -> String {
    let mut text = text.to_owned();
    for (from, to) in edits {
        assert_eq!(text.matches(from).count(), 1, "`{from}` must occur exactly once");
        text = text.replace(from, to);
    }
    text
}

fn load(toml: &str) -> Result<Loaded, Vec<Diagnostic>> {
    load_str(toml, Format::Toml, Some("test.toml"))
}

fn load_ok(toml: &str) -> Loaded {
    match load(toml) {
        Ok(loaded) => loaded,
        Err(errors) => panic!("expected no errors, got:\n{}", render(&errors)),
    }
}

fn render(diags: &[Diagnostic]) -> String {
    diags.iter().map(|d| format!("{d}\n")).collect()
}

/// Loads `text`, which must fail with an error whose message contains `message`, placed at
/// `line`:`column`; returns that error.
fn check_error_in(
    text: &str,
    format: Format,
    message: &str,
    line: usize,
    column: usize,
) -> Diagnostic {
    let errors = match load_str(text, format, Some("test")) {
        Ok(_) => panic!("expected an error containing {message:?}, but it loaded"),
        Err(errors) => errors,
    };
    let Some(found) = errors.iter().find(|d| d.message.contains(message)) else {
        panic!("no error contains {message:?}; got:\n{}", render(&errors));
    };
    assert_eq!(found.severity, Severity::Error);
    assert_eq!((found.line, found.column), (Some(line), Some(column)), "place of: {found}");
    assert_eq!(found.file.as_deref(), Some("test"));
    found.clone()
}

fn check_error(toml: &str, message: &str, line: usize, column: usize) -> Diagnostic {
    check_error_in(toml, Format::Toml, message, line, column)
}

fn check_json_error(json: &str, message: &str, line: usize, column: usize) -> Diagnostic {
    check_error_in(json, Format::Json, message, line, column)
}

/// Asserts the entity and the field a diagnostic names.
fn assert_names(diag: &Diagnostic, entity: &str, field: &str) {
    assert_eq!(diag.entity.as_deref(), Some(entity), "entity of: {diag}");
    assert_eq!(diag.field.as_deref(), Some(field), "field of: {diag}");
}

// Whole descriptions.

#[test]
fn base_description_loads() {
    let loaded = load_ok(BASE);
    assert!(loaded.warnings.is_empty());
    let m = &loaded.mechanism;
    assert_eq!((m.unknowns(), m.equations()), (7, 7));
    assert_eq!(m.time.count, 11);
}

#[test]
fn base_description_loads_from_json_too() {
    let json = load_str(BASE_JSON, Format::Json, None).expect("valid JSON");
    assert_eq!(json.desc, load_ok(BASE).desc);
}

#[test]
fn contract_example_loads_with_no_errors() {
    // The contract's example, completed to a driven spatial RSSR: 3 moving bodies,
    // 5 + 3 + 3 + 5 joint rows + 1 constraint + 1 driver + 3 normalisations = 21 = 7·3.
    let toml = r#"
name = "rssr"
description = "spatial R-S-S-R"

[time]
start = 0.0
end = 0.042857
step = 0.00035714

[solver]
tolerance = 1e-10
max_iterations = 25

[[bodies]]
name = "ground"
ground = true

[[bodies]]
name = "crank"
r = [0.0, -0.06567, 0.0]
p = [1.0, 0.0, 0.0, 0.0]

[[bodies]]
name = "coupler"
r = [0.0, 0.0, 0.1]

[[bodies]]
name = "rocker"
r = [0.0, 0.4812, 0.1]

[[joints]]
name = "O2"
type = "revolute"
body_i = "ground"
body_j = "crank"
point_i = [0.0, -0.06567, 0.0]
point_j = [0.0, 0.0, 0.0]
axis_i = [0.0, 1.0, 0.0]
axis_j = [0.0, 1.0, 0.0]
ref_i = [0.0, 0.0, 1.0]
ref_j = [0.0, 0.0, 1.0]

[[joints]]
name = "A"
type = "spherical"
body_i = "crank"
body_j = "coupler"
point_i = [0.0, 0.0, 0.1]
point_j = [0.0, 0.0, 0.0]

[[joints]]
name = "B"
type = "spherical"
body_i = "coupler"
body_j = "rocker"
point_i = [0.0, 0.4812, 0.0]
point_j = [0.0, 0.0, 0.0]

[[joints]]
name = "O4"
type = "revolute"
body_i = "rocker"
body_j = "ground"
point_i = [0.0, 0.0, 0.0]
point_j = [0.0, 0.4812, 0.1]
axis_i = [1.0, 0.0, 0.0]
axis_j = [1.0, 0.0, 0.0]

[[constraints]]
name = "no_spin"
type = "fix"
body = "coupler"
coordinate = "e2"
value = 0.0

[[drivers]]
name = "motor"
joint = "O2"
motion = "rotation"
law = { start = 0.0, velocity = 146.6, acceleration = 0.0 }

[[points]]
name = "B"
body = "coupler"
local = [0.0, 0.4812, 0.0]
"#;
    let loaded = load_ok(toml);
    assert!(loaded.warnings.is_empty(), "{}", render(&loaded.warnings));
    let m = &loaded.mechanism;
    assert_eq!((m.unknowns(), m.equations()), (21, 21));
    assert_eq!(m.time.count, 121);
    assert_eq!(m.joints[0].reference.map(|r| r.0.z), Some(1.0));
    assert!(matches!(m.drivers[0].law, Law::Polynomial { velocity, .. } if velocity == 146.6));
}

#[test]
fn second_body_with_hinge_and_harmonic_driver_loads() {
    let loaded = load_ok(&format!("{BASE}{HINGE}"));
    let m = &loaded.mechanism;
    assert_eq!((m.unknowns(), m.equations()), (14, 14));
    let harmonic = Law::Harmonic { offset: 0.0, amplitude: 0.5, frequency: 2.0, phase: 0.0 };
    assert_eq!(m.drivers[1].law, harmonic);
    assert!(matches!(m.drivers[1].target, DriverTarget::Joint { .. }));
    assert_eq!(m.points[0].body.0, 2);
}

#[test]
fn validate_gives_paths_but_no_places() {
    let mut desc: MechanismDesc = toml::from_str(BASE).expect("BASE parses");
    desc.joints[0].axis_i = Some([0.0; 3]);
    let errors = validate(&desc).expect_err("a zero axis is an error");
    assert_eq!(errors.len(), 1, "{}", render(&errors));
    assert_eq!(errors[0].path.as_deref(), Some("joints[0].axis_i"));
    assert_eq!((errors[0].line, errors[0].column), (None, None));
    assert_names(&errors[0], "joint \"rail\"", "axis_i");
}

#[test]
fn load_file_reads_json_by_its_extension() {
    let dir = std::env::temp_dir().join(format!("mechgen-validate-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("slider.json");
    std::fs::write(&path, BASE_JSON).expect("write");
    let loaded = load_file(&path);
    std::fs::remove_dir_all(&dir).expect("cleanup");
    assert_eq!(loaded.expect("valid JSON file").mechanism.name, "slider");
}

#[test]
fn load_file_reports_an_unreadable_file() {
    let errors = load_file(std::path::Path::new("/nonexistent/x.toml")).expect_err("missing");
    assert!(errors[0].message.starts_with("cannot read the file"));
    assert_eq!(errors[0].file.as_deref(), Some("/nonexistent/x.toml"));
}

#[test]
fn all_errors_are_reported_in_file_order() {
    let toml = edit(&[
        ("end = 1.0", "end = -1.0"),
        ("axis_j = [1.0, 0.0, 0.0]", "axis_j = [0.0, 0.0, 0.0]"),
        ("joint = \"rail\"", "joint = \"rial\""),
    ]);
    let errors = load(&toml).expect_err("three errors");
    let places: Vec<_> = errors.iter().map(|d| d.line.unwrap_or(0)).collect();
    assert_eq!(places, [4, 19, 24], "{}", render(&errors));
}

// Syntax and shape (serde) errors.

#[test]
fn toml_syntax_error_has_its_place_and_entity() {
    let d = check_error(
        &edit(&[("axis_j = [1.0, 0.0, 0.0]", "axis_j = [1.0, 0.0 0.0]")]),
        "TOML syntax",
        19,
        16,
    );
    assert_eq!(d.field.as_deref(), Some("axis_j"));
    assert_eq!(d.entity.as_deref(), Some("joint \"rail\""));
}

#[test]
fn toml_syntax_error_in_an_inline_table_points_at_where_it_opens() {
    // The law's inline table is written across lines and lacks a comma on its second line: the
    // error is reported where the parser stops, and the message names line 26, where `{` is.
    let toml = edit(&[(
        "law = { start = 0.0, velocity = 1.0 }",
        "law = { start = 0.0, # the position at t = 0\n  velocity = 1.0 acceleration = 0.0 }",
    )]);
    let errors = load(&toml).expect_err("a comma is missing");
    let d = errors.iter().find(|d| d.message.contains("TOML syntax")).expect("a syntax error");
    assert!(
        d.message.contains("inside the inline table `{ … }` opened at line 26, column 7"),
        "{}",
        render(&errors)
    );
    // A syntax error outside any inline table says nothing about one.
    let toml = edit(&[("axis_j = [1.0, 0.0, 0.0]", "axis_j = [1.0, 0.0 0.0]")]);
    let errors = load(&toml).expect_err("a missing comma");
    assert!(errors.iter().all(|d| !d.message.contains("inline table")), "{}", render(&errors));
}

#[test]
fn json_syntax_error_has_its_place() {
    let json = edit_text(BASE_JSON, &[("\"body_j\": \"block\",", "\"body_j\": \"block\"")]);
    // The parser stops right after the value that lacks its comma.
    check_json_error(&json, "JSON syntax: Expected comma", 13, 24);
}

#[test]
fn json_duplicate_key_is_an_error() {
    let json = edit_text(
        BASE_JSON,
        &[(
            "\"ref_i\": [0.0, 1.0, 0.0],",
            "\"ref_i\": [0.0, 1.0, 0.0], \"ref_i\": [0.0, 1.0, 0.0],",
        )],
    );
    check_json_error(&json, "duplicate key `ref_i`", 18, 33);
}

#[test]
fn unknown_field_suggests_the_nearest_known_one() {
    let d = check_error(
        &edit(&[("axis_i =", "axsi_i =")]),
        "unknown field `axsi_i`: did you mean `axis_i`?",
        18,
        1,
    );
    assert_names(&d, "joint \"rail\"", "axsi_i");
    assert_eq!(d.path.as_deref(), Some("joints[0].axsi_i"));
}

#[test]
fn unknown_field_far_from_all_lists_the_known_ones() {
    let toml = format!("{BASE}colour = \"red\"\n");
    let d = check_error(
        &toml,
        "unknown field `colour`: expected one of name, joint, motion, body",
        27,
        1,
    );
    assert_names(&d, "driver \"push\"", "colour");
}

#[test]
fn every_unknown_field_of_an_entity_is_reported() {
    let toml = edit(&[("axis_i =", "axsi_i ="), ("ref_j =", "rf_j =")]);
    let errors = load(&toml).expect_err("two unknown fields");
    let unknown: Vec<_> =
        errors.iter().filter(|d| d.message.starts_with("unknown field")).collect();
    assert_eq!(unknown.len(), 2, "{}", render(&errors));
    check_error(&toml, "unknown field `rf_j`: did you mean `ref_j`?", 21, 1);
}

#[test]
fn unknown_field_in_json_has_its_place() {
    let json = edit_text(BASE_JSON, &[("\"axis_i\"", "\"axis\"")]);
    let d = check_json_error(&json, "unknown field `axis`: did you mean `axis_i`?", 16, 7);
    assert_names(&d, "joint \"rail\"", "axis");
}

#[test]
fn unknown_field_in_a_law_is_reported_with_the_driver() {
    let d = check_error(
        &edit(&[("velocity = 1.0", "velocty = 1.0")]),
        "did you mean `velocity`?",
        26,
        22,
    );
    assert_names(&d, "driver \"push\"", "law.velocty");
}

#[test]
fn unknown_top_level_key_is_an_error() {
    let d = check_error(
        &edit(&[("name = \"slider\"", "nmae = \"slider\"")]),
        "unknown field `nmae`: did you mean `name`?",
        1,
        1,
    );
    assert_eq!(d.field.as_deref(), Some("nmae"));
}

#[test]
fn unknown_joint_type_suggests_the_nearest() {
    let d = check_error(
        &edit(&[("type = \"prismatic\"", "type = \"prismatik\"")]),
        "unknown value \"prismatik\" for `type`: expected one of spherical",
        13,
        8,
    );
    assert!(d.message.ends_with("did you mean \"prismatic\"?"), "{d}");
    assert_names(&d, "joint \"rail\"", "type");
}

#[test]
fn wrong_type_names_the_field() {
    let d = check_error(
        &edit(&[("start = 0.0\n", "start = \"zero\"\n")]),
        "invalid type: string \"zero\", expected a number",
        3,
        9,
    );
    assert_names(&d, "time", "start");
}

#[test]
fn wrong_array_length_is_an_error() {
    let d = check_error(
        &edit(&[("point_j = [0.0, 0.0, 0.0]", "point_j = [0.0, 0.0, 0.0, 1.0]")]),
        "invalid length 4, expected an array of length 3",
        17,
        11,
    );
    assert_names(&d, "joint \"rail\"", "point_j");
    check_error(
        &edit(&[("point_j = [0.0, 0.0, 0.0]", "point_j = [0.0, 0.0]")]),
        "invalid length 2",
        17,
        11,
    );
}

#[test]
fn missing_serde_field_points_at_the_table_header() {
    let d = check_error(&edit(&[("body_j = \"block\"\n", "")]), "missing field `body_j`", 11, 1);
    assert_names(&d, "joint \"rail\"", "body_j");
    assert_eq!(d.path.as_deref(), Some("joints[0].body_j"));
}

#[test]
fn missing_field_in_json_points_at_the_object() {
    let json = edit_text(BASE_JSON, &[("\"type\": \"prismatic\",", "")]);
    let d = check_json_error(&json, "missing field `type`", 9, 5);
    assert_names(&d, "joint \"rail\"", "type");
}

#[test]
fn errors_in_two_entities_are_both_reported() {
    let toml = format!("{BASE}{HINGE}")
        .replace("type = \"revolute\"", "type = 3")
        .replace("motion = \"translation\"", "motion = \"slide\"");
    let errors = load(&toml).expect_err("two shape errors");
    assert_eq!(errors.len(), 2, "{}", render(&errors));
    check_error(&toml, "unknown value \"slide\" for `motion`", 25, 10);
    check_error(&toml, "invalid type: integer `3`", 31, 8);
}

#[test]
fn missing_time_section_is_an_error() {
    let toml = edit(&[("[time]\nstart = 0.0\nend = 1.0\nstep = 0.1\n", "")]);
    let d = check_error(&toml, "missing the `[time]` section", 1, 1);
    assert_names(&d, "time", "time");
}

#[test]
fn a_section_written_as_a_single_table_is_an_error() {
    let d = check_error(
        &edit(&[("[[drivers]]", "[drivers]")]),
        "`drivers` must be an array of tables",
        22,
        1,
    );
    assert_eq!(d.field.as_deref(), Some("drivers"));
}

#[test]
fn top_fields_match_the_description_type() {
    let desc = MechanismDesc {
        description: Some(String::new()),
        solver: Some(crate::desc::SolverDesc { tolerance: None, max_iterations: None }),
        ..load_ok(&format!("{BASE}{HINGE}\n[[constraints]]\nname = \"c\"\ntype = \"fix\"\nbody = \"arm\"\ncoordinate = \"x\"\nvalue = 0.0\n")).desc
    };
    let json = serde_json::to_value(&desc).expect("serialises");
    let keys: Vec<&str> = json.as_object().expect("an object").keys().map(String::as_str).collect();
    let mut expected = super::de::TOP_FIELDS.to_vec();
    expected.sort_unstable();
    let mut keys = keys;
    keys.sort_unstable();
    assert_eq!(keys, expected);
}

// Names and references.

#[test]
fn mechanism_name_must_be_an_identifier() {
    let d = check_error(
        &edit(&[("name = \"slider\"", "name = \"Slider-2\"")]),
        "must match [a-z][a-z0-9_]*",
        1,
        8,
    );
    assert!(d.message.contains("e.g. \"slider_2\""), "{d}");
    assert_names(&d, "name", "name");
}

#[test]
fn body_names_are_unique() {
    let d = check_error(
        &edit(&[("name = \"block\"", "name = \"ground\"")]),
        "already taken by body \"ground\" (bodies[0])",
        10,
        8,
    );
    assert_names(&d, "body \"ground\"", "name");
}

#[test]
fn joints_constraints_and_drivers_share_one_namespace() {
    let d = check_error(
        &edit(&[("name = \"push\"", "name = \"rail\"")]),
        "already taken by joint \"rail\" (joints[0]): joints, constraints and drivers share",
        23,
        8,
    );
    assert_names(&d, "driver \"rail\"", "name");
}

#[test]
fn point_names_are_unique() {
    let toml = format!(
        "{BASE}{HINGE}[[points]]\nname = \"tip\"\nbody = \"block\"\nlocal = [0.0, 0.0, 0.0]\n"
    );
    let d = check_error(&toml, "already taken by point \"tip\" (points[0])", 50, 8);
    assert_names(&d, "point \"tip\"", "name");
}

#[test]
fn unknown_body_suggests_the_closest_name() {
    let d = check_error(
        &edit(&[("body_j = \"block\"", "body_j = \"blokc\"")]),
        "unknown body \"blokc\": did you mean \"block\"?",
        15,
        10,
    );
    assert_names(&d, "joint \"rail\"", "body_j");
}

#[test]
fn unknown_joint_in_a_driver_suggests_the_closest_name() {
    let d = check_error(
        &edit(&[("joint = \"rail\"", "joint = \"rial\"")]),
        "unknown joint \"rial\": did you mean \"rail\"?",
        24,
        9,
    );
    assert_names(&d, "driver \"push\"", "joint");
}

#[test]
fn joint_needs_two_different_bodies() {
    let d = check_error(
        &edit(&[("body_i = \"ground\"", "body_i = \"block\"")]),
        "body_i and body_j are both \"block\"",
        15,
        10,
    );
    assert_names(&d, "joint \"rail\"", "body_j");
}

#[test]
fn joint_between_two_ground_bodies_is_an_error() {
    let toml = edit(&[("name = \"block\"", "name = \"block\"\nground = true")]);
    check_error(&toml, "\"ground\" and \"block\" are both ground", 16, 10);
}

#[test]
fn at_least_one_body_must_move() {
    let toml = edit(&[("name = \"block\"", "name = \"block\"\nground = true")]);
    let d = check_error(&toml, "there is no moving body", 6, 1);
    assert_eq!(d.entity.as_deref(), Some("mechanism \"slider\""));
}

// Vectors.

#[test]
fn non_finite_vector_component_is_an_error_at_the_component() {
    let d = check_error(
        &edit(&[("point_i = [0.0, 0.0, 0.0]", "point_i = [0.0, nan, 0.0]")]),
        "`point_i[1]` is NaN: every number must be finite",
        16,
        17,
    );
    assert_names(&d, "joint \"rail\"", "point_i");
    assert_eq!(d.path.as_deref(), Some("joints[0].point_i[1]"));
}

#[test]
fn infinite_vector_component_in_json_is_caught_as_non_finite() {
    // JSON has no infinity literal, but 1e999 overflows to it.
    let json =
        edit_text(BASE_JSON, &[("\"point_j\": [0.0, 0.0, 0.0]", "\"point_j\": [0.0, 0.0, 1e999]")]);
    check_json_error(&json, "`point_j[2]` is inf", 15, 29);
}

#[test]
fn absurd_magnitudes_are_errors_at_the_component() {
    // 1e200 is finite, but its square overflows: the rule refuses anything beyond 1e150.
    let d = check_error(
        &edit(&[("point_i = [0.0, 0.0, 0.0]", "point_i = [0.0, -1e200, 0.0]")]),
        "`point_i[1]` = -1e200 is beyond ±1e150: squares and products of such values overflow",
        16,
        17,
    );
    assert_names(&d, "joint \"rail\"", "point_i");
    let json =
        edit_text(BASE_JSON, &[("\"point_j\": [0.0, 0.0, 0.0]", "\"point_j\": [0.0, 0.0, 1e308]")]);
    check_json_error(&json, "`point_j[2]` = 1e308 is beyond ±1e150", 15, 29);
}

#[test]
fn magnitudes_up_to_the_limit_are_accepted() {
    let toml = edit(&[("point_i = [0.0, 0.0, 0.0]", "point_i = [0.0, 1e150, 0.0]")]);
    let found = load_str(&toml, Format::Toml, Some("test"));
    let errors: Vec<String> = match &found {
        Ok(_) => Vec::new(),
        Err(d) => d.iter().map(|d| d.message.clone()).collect(),
    };
    assert!(errors.iter().all(|m| !m.contains("beyond")), "{errors:?}");
}

#[test]
fn zero_axis_is_an_error() {
    let d = check_error(
        &edit(&[("axis_j = [1.0, 0.0, 0.0]", "axis_j = [0.0, 0.0, 0.0]")]),
        "`axis_j` is the zero vector",
        19,
        10,
    );
    assert_names(&d, "joint \"rail\"", "axis_j");
}

#[test]
fn axes_are_normalised_on_load() {
    let loaded = load_ok(&edit(&[
        ("axis_i = [1.0, 0.0, 0.0]", "axis_i = [3.0, 4.0, 0.0]"),
        ("ref_i = [0.0, 1.0, 0.0]", "ref_i = [0.0, 0.0, 2.0]"),
    ]));
    let (axis_i, _) = loaded.mechanism.joints[0].axis.expect("prismatic has axes");
    // Two roundings of O(1) numbers.
    assert_relative_eq!(axis_i, nalgebra::Vector3::new(0.6, 0.8, 0.0), epsilon = 1e-15);
}

#[test]
fn tiny_but_non_zero_axis_is_accepted() {
    load_ok(&edit(&[("axis_i = [1.0, 0.0, 0.0]", "axis_i = [1e-9, 0.0, 0.0]")]));
}

#[test]
fn reference_must_be_perpendicular_to_its_axis() {
    let d = check_error(
        &edit(&[("ref_j = [0.0, 1.0, 0.0]", "ref_j = [0.001, 1.0, 0.0]")]),
        "`ref_j` is not perpendicular to `axis_j`",
        21,
        9,
    );
    assert_names(&d, "joint \"rail\"", "ref_j");
}

#[test]
fn reference_within_1e_6_of_perpendicular_is_accepted() {
    load_ok(&edit(&[("ref_j = [0.0, 1.0, 0.0]", "ref_j = [5e-7, 1.0, 0.0]")]));
}

// Fields per joint type.

#[test]
fn missing_point_is_an_error_not_the_origin() {
    let d = check_error(
        &edit(&[("point_i = [0.0, 0.0, 0.0]\n", "")]),
        "missing `point_i`: a prismatic joint needs it (the joint point on body i, local; it has no default)",
        11,
        1,
    );
    assert_names(&d, "joint \"rail\"", "point_i");
}

#[test]
fn prismatic_joint_needs_its_references() {
    let d = check_error(
        &edit(&[("ref_i = [0.0, 1.0, 0.0]\n", "")]),
        "missing `ref_i`: a prismatic joint needs it",
        11,
        1,
    );
    assert_names(&d, "joint \"rail\"", "ref_i");
}

#[test]
fn field_a_type_does_not_use_is_an_error() {
    let d = check_error(
        &edit(&[("ref_j = [0.0, 1.0, 0.0]", "ref_j = [0.0, 1.0, 0.0]\nlead = 0.01")]),
        "field `lead` is not used by a prismatic joint",
        22,
        8,
    );
    assert_names(&d, "joint \"rail\"", "lead");
}

#[test]
fn spherical_joint_takes_no_axis() {
    let toml = format!(
        "{BASE}[[joints]]\nname = \"ball\"\ntype = \"spherical\"\nbody_i = \"ground\"\nbody_j = \"block\"\npoint_i = [0.0, 0.0, 0.0]\npoint_j = [0.0, 0.0, 0.0]\naxis_i = [0.0, 0.0, 1.0]\n"
    );
    check_error(&toml, "field `axis_i` is not used by a spherical joint", 34, 10);
}

#[test]
fn revolute_references_go_together() {
    let toml = format!("{BASE}{HINGE}").replace("ref_j = [1.0, 0.0, 0.0]\n", "");
    let d = check_error(&toml, "`ref_i` is given without `ref_j`: give both or neither", 29, 1);
    assert_names(&d, "joint \"hinge\"", "ref_j");
}

#[test]
fn revolute_without_references_loads_when_not_rotation_driven() {
    let toml = format!("{BASE}{HINGE}")
        .replace("ref_i = [1.0, 0.0, 0.0]\nref_j = [1.0, 0.0, 0.0]\n", "")
        .replace("joint = \"hinge\"\nmotion = \"rotation\"", "body = \"arm\"\ncoordinate = \"rz\"");
    let loaded = load_ok(&toml);
    assert_eq!(loaded.mechanism.joints[1].reference, None);
}

const SCREW: &str = r#"[[bodies]]
name = "nut"
r = [0.0, 0.0, 0.5]
p = [0.7071067811865476, 0.0, 0.0, 0.7071067811865476]
[[joints]]
name = "thread"
type = "screw"
body_i = "ground"
body_j = "nut"
point_i = [0.0, 0.0, 0.0]
point_j = [0.0, 0.0, 0.0]
axis_i = [0.0, 0.0, 1.0]
axis_j = [0.0, 0.0, 1.0]
ref_i = [1.0, 0.0, 0.0]
ref_j = [1.0, 0.0, 0.0]
lead = 0.002
[[drivers]]
name = "turn"
joint = "thread"
motion = "rotation"
law = { velocity = 1.0 }
"#;

#[test]
fn screw_stores_its_initial_offset_and_angle() {
    let loaded = load_ok(&format!("{BASE}{SCREW}"));
    let JointKind::Screw { lead, d0, theta0 } = loaded.mechanism.joints[1].kind else {
        panic!("a screw joint");
    };
    assert_eq!(lead, 0.002);
    // The nut sits 0.5 up the axis, turned a quarter turn: a few roundings of O(1) numbers.
    assert_relative_eq!(d0, 0.5, epsilon = 1e-14);
    assert_relative_eq!(theta0, std::f64::consts::FRAC_PI_2, epsilon = 1e-14);
}

#[test]
fn screw_angle_of_a_half_turn_is_plus_pi() {
    let toml = format!("{BASE}{SCREW}").replace(
        "p = [0.7071067811865476, 0.0, 0.0, 0.7071067811865476]",
        "p = [0.0, 0.0, 0.0, 1.0]",
    );
    let JointKind::Screw { theta0, .. } = load_ok(&toml).mechanism.joints[1].kind else {
        panic!("a screw joint");
    };
    // A(p) maps x to −x up to rounding, which may give either sign of a zero sine.
    assert_relative_eq!(theta0.abs(), std::f64::consts::PI, epsilon = 1e-14);
    assert!(theta0 > -std::f64::consts::PI);
}

#[test]
fn screw_with_zero_lead_is_a_revolute() {
    let toml = format!("{BASE}{SCREW}").replace("lead = 0.002", "lead = 0.0");
    let d =
        check_error(&toml, "`lead` = 0 locks the slide, which makes this a revolute joint", 42, 8);
    assert_names(&d, "joint \"thread\"", "lead");
}

#[test]
fn screw_needs_a_lead() {
    let toml = format!("{BASE}{SCREW}").replace("lead = 0.002\n", "");
    check_error(&toml, "missing `lead`: a screw joint needs it", 31, 1);
}

#[test]
fn screw_lead_must_be_finite() {
    let toml = format!("{BASE}{SCREW}").replace("lead = 0.002", "lead = inf");
    check_error(&toml, "`lead` is inf: it must be finite", 42, 8);
}

const ROD: &str = r#"[[bodies]]
name = "bob"
r = [0.0, -1.0, 0.0]
[[joints]]
name = "rod"
type = "distance"
body_i = "ground"
body_j = "bob"
point_i = [0.0, 0.0, 0.0]
point_j = [0.0, 0.0, 0.0]
[[constraints]]
name = "plane"
type = "fix"
body = "bob"
coordinate = "z"
value = 0.0
[[constraints]]
name = "tilt_x"
type = "fix"
body = "bob"
coordinate = "e1"
value = 0.0
[[constraints]]
name = "tilt_y"
type = "fix"
body = "bob"
coordinate = "e2"
value = 0.0
[[constraints]]
name = "spin"
type = "fix"
body = "bob"
coordinate = "e3"
value = 0.0
[[drivers]]
name = "sweep"
body = "bob"
coordinate = "x"
law = { velocity = 0.1 }
"#;

#[test]
fn distance_is_taken_from_the_initial_estimates() {
    let toml = format!("{BASE}{ROD}");
    let m = load_ok(&toml).mechanism;
    assert_eq!(m.joints[1].kind, JointKind::Distance { length: 1.0 });
}

#[test]
fn distance_needs_distinct_points_when_not_given() {
    let toml = format!("{BASE}{ROD}").replace("r = [0.0, -1.0, 0.0]\n", "");
    let d = check_error(&toml, "the points coincide at the initial estimates", 29, 1);
    assert_names(&d, "joint \"rod\"", "distance");
}

#[test]
fn given_distance_must_be_positive() {
    let toml = format!("{BASE}{ROD}").replace(
        "point_j = [0.0, 0.0, 0.0]\n[[constraints]]",
        "point_j = [0.0, 0.0, 0.0]\ndistance = -1.0\n[[constraints]]",
    );
    let d = check_error(&toml, "`distance` = -1 must be > 0", 37, 12);
    assert_names(&d, "joint \"rod\"", "distance");
}

// Bodies.

#[test]
fn euler_parameters_far_from_unit_are_an_error() {
    let d = check_error(
        &edit(&[("name = \"block\"", "name = \"block\"\np = [2.0, 0.0, 0.0, 0.0]")]),
        "|p| = 2 is not 1",
        11,
        5,
    );
    assert_names(&d, "body \"block\"", "p");
}

#[test]
fn euler_parameters_slightly_off_give_a_warning_and_are_normalised() {
    let loaded =
        load_ok(&edit(&[("name = \"block\"", "name = \"block\"\np = [1.001, 0.0, 0.0, 0.0]")]));
    assert_eq!(loaded.warnings.len(), 1);
    let w = &loaded.warnings[0];
    assert_eq!(w.severity, Severity::Warning);
    assert!(w.message.contains("differs from 1 by 1.0e-3"), "{w}");
    assert_eq!((w.line, w.column), (Some(11), Some(5)));
    assert_names(w, "body \"block\"", "p");
    assert_eq!(loaded.mechanism.bodies[1].p, nalgebra::Vector4::new(1.0, 0.0, 0.0, 0.0));
}

#[test]
fn euler_parameters_must_be_finite() {
    check_error(
        &edit(&[("name = \"block\"", "name = \"block\"\np = [1.0, 0.0, -inf, 0.0]")]),
        "`p[2]` is -inf",
        11,
        16,
    );
}

#[test]
fn body_position_must_be_finite() {
    check_error(
        &edit(&[("name = \"block\"", "name = \"block\"\nr = [nan, 0.0, 0.0]")]),
        "`r[0]` is NaN",
        11,
        6,
    );
}

#[test]
fn ground_body_is_placed_by_r_and_p() {
    let loaded = load_ok(&edit(&[("ground = true", "ground = true\nr = [1.0, 2.0, 3.0]")]));
    assert_eq!(loaded.mechanism.bodies[0].r, nalgebra::Vector3::new(1.0, 2.0, 3.0));
}

// Constraints.

const FIX: &str = "[[constraints]]\nname = \"hold\"\ntype = \"fix\"\nbody = \"block\"\ncoordinate = \"y\"\nvalue = 0.0\n";

#[test]
fn fix_on_a_ground_body_is_an_error() {
    let toml = format!("{BASE}{FIX}").replace("body = \"block\"", "body = \"ground\"");
    let d =
        check_error(&toml, "body \"ground\" is ground: its coordinates are already fixed", 30, 8);
    assert_names(&d, "constraint \"hold\"", "body");
}

#[test]
fn fix_takes_body_not_body_i() {
    let toml = format!("{BASE}{FIX}").replace("body = \"block\"", "body_i = \"block\"");
    check_error(&toml, "field `body_i` is not used by a fix constraint", 30, 10);
    check_error(&toml, "missing `body`: a fix constraint needs the body it fixes", 27, 1);
}

#[test]
fn fixed_euler_parameter_must_lie_in_minus_one_to_one() {
    let toml = format!("{BASE}{FIX}")
        .replace("coordinate = \"y\"\nvalue = 0.0", "coordinate = \"e1\"\nvalue = 1.5");
    check_error(&toml, "`value` = 1.5 for e1: an Euler parameter lies in [−1, 1]", 32, 9);
}

#[test]
fn constraint_value_must_be_finite() {
    let toml = format!("{BASE}{FIX}").replace("value = 0.0", "value = nan");
    let d = check_error(&toml, "`value` is NaN: it must be finite", 32, 9);
    assert_names(&d, "constraint \"hold\"", "value");
}

const DIFFERENCE: &str = "[[constraints]]\nname = \"same_height\"\ntype = \"coordinate_difference\"\nbody_i = \"block\"\nbody_j = \"arm\"\ncoordinate = \"z\"\nvalue = 0.0\n";

#[test]
fn coordinate_difference_takes_two_bodies_not_body() {
    let toml = format!("{BASE}{HINGE}{DIFFERENCE}").replace(
        "body_i = \"block\"\nbody_j = \"arm\"\ncoordinate",
        "body = \"block\"\nbody_j = \"arm\"\ncoordinate",
    );
    check_error(&toml, "field `body` is not used by a coordinate_difference constraint", 52, 8);
    check_error(&toml, "missing `body_i`: a coordinate_difference constraint needs it", 49, 1);
}

#[test]
fn coordinate_difference_needs_two_distinct_bodies() {
    let toml = format!("{BASE}{HINGE}{DIFFERENCE}")
        .replace("body_j = \"arm\"\ncoordinate", "body_j = \"block\"\ncoordinate");
    check_error(&toml, "body_i and body_j are both \"block\"", 53, 10);
}

#[test]
fn coordinate_difference_between_ground_bodies_is_an_error() {
    let toml = format!("{BASE}{HINGE}{DIFFERENCE}\n[[bodies]]\nname = \"base\"\nground = true\n")
        .replace(
            "body_i = \"block\"\nbody_j = \"arm\"\ncoordinate",
            "body_i = \"ground\"\nbody_j = \"base\"\ncoordinate",
        );
    check_error(&toml, "\"ground\" and \"base\" are both ground", 53, 10);
}

// Drivers.

#[test]
fn driver_cannot_be_both_joint_and_absolute() {
    let d = check_error(
        &edit(&[("joint = \"rail\"", "joint = \"rail\"\nbody = \"block\"")]),
        "either a joint driver (`joint`, `motion`) or an absolute one",
        25,
        8,
    );
    assert_names(&d, "driver \"push\"", "body");
}

#[test]
fn driver_needs_a_joint_or_a_body() {
    check_error(
        &edit(&[("joint = \"rail\"\nmotion = \"translation\"\n", "")]),
        "missing `joint`, `body` or `point`",
        22,
        1,
    );
}

#[test]
fn joint_driver_needs_a_motion() {
    check_error(
        &edit(&[("motion = \"translation\"\n", "")]),
        "missing `motion` (rotation or translation)",
        22,
        1,
    );
}

#[test]
fn joint_driver_takes_no_coordinate() {
    check_error(
        &edit(&[("motion = \"translation\"", "motion = \"translation\"\ncoordinate = \"x\"")]),
        "field `coordinate` is not used by a joint driver",
        26,
        14,
    );
}

#[test]
fn prismatic_joint_cannot_be_driven_in_rotation() {
    let d = check_error(
        &edit(&[("motion = \"translation\"", "motion = \"rotation\"")]),
        "joint \"rail\" is a prismatic joint, which cannot be driven in rotation",
        25,
        10,
    );
    assert_names(&d, "driver \"push\"", "motion");
}

#[test]
fn revolute_joint_cannot_be_driven_in_translation() {
    let toml =
        format!("{BASE}{HINGE}").replace("motion = \"rotation\"", "motion = \"translation\"");
    check_error(
        &toml,
        "joint \"hinge\" is a revolute joint, which cannot be driven in translation",
        43,
        10,
    );
}

#[test]
fn rotation_driver_needs_the_joint_references() {
    let toml =
        format!("{BASE}{HINGE}").replace("ref_i = [1.0, 0.0, 0.0]\nref_j = [1.0, 0.0, 0.0]\n", "");
    let d = check_error(
        &toml,
        "joint \"hinge\" has no `ref_i`/`ref_j`, which driver \"swing\" needs",
        40,
        9,
    );
    assert_names(&d, "driver \"swing\"", "joint");
}

#[test]
fn absolute_driver_on_a_ground_body_is_an_error() {
    let toml = edit(&[(
        "joint = \"rail\"\nmotion = \"translation\"",
        "body = \"ground\"\ncoordinate = \"x\"",
    )]);
    let d = check_error(&toml, "body \"ground\" is ground: it cannot be driven", 24, 8);
    assert_names(&d, "driver \"push\"", "body");
}

#[test]
fn absolute_driver_needs_a_coordinate_and_no_motion() {
    let toml = edit(&[("joint = \"rail\"", "body = \"block\"")]);
    check_error(&toml, "field `motion` is not used by an absolute driver", 25, 10);
    check_error(&toml, "missing `coordinate` (x, y, z, rx, ry, rz, e1, e2 or e3)", 22, 1);
}

#[test]
fn driving_a_constraint_is_an_error() {
    let toml = format!("{BASE}{FIX}").replace("joint = \"rail\"", "joint = \"hold\"");
    check_error(&toml, "\"hold\" is a constraint, not a joint", 24, 9);
}

#[test]
fn law_cannot_mix_the_two_forms() {
    let d = check_error(
        &edit(&[("velocity = 1.0", "velocity = 1.0, amplitude = 2.0")]),
        "the law mixes the polynomial form",
        26,
        7,
    );
    assert_names(&d, "driver \"push\"", "law");
}

#[test]
fn law_cannot_be_empty() {
    check_error(
        &edit(&[("law = { start = 0.0, velocity = 1.0 }", "law = {}")]),
        "the law is empty",
        26,
        7,
    );
}

#[test]
fn harmonic_law_needs_a_frequency() {
    let d = check_error(
        &edit(&[("law = { start = 0.0, velocity = 1.0 }", "law = { amplitude = 1.0 }")]),
        "missing `law.frequency`: the harmonic law needs amplitude and frequency",
        26,
        7,
    );
    assert_names(&d, "driver \"push\"", "law.frequency");
}

#[test]
fn law_members_must_be_finite() {
    let d = check_error(
        &edit(&[("velocity = 1.0", "velocity = inf")]),
        "`law.velocity` is inf",
        26,
        33,
    );
    assert_eq!(d.path.as_deref(), Some("drivers[0].law.velocity"));
}

#[test]
fn law_members_in_json_have_their_place() {
    let json = edit_text(BASE_JSON, &[("\"velocity\": 1.0", "\"velocity\": 1.0, \"phase\": 0.0")]);
    check_json_error(&json, "the law mixes the polynomial form", 23, 72);
}

// Points of interest.

#[test]
fn point_needs_a_known_body() {
    let toml = format!("{BASE}{HINGE}").replace("body = \"arm\"", "body = \"amr\"");
    let d = check_error(&toml, "unknown body \"amr\": did you mean \"arm\"?", 47, 8);
    assert_names(&d, "point \"tip\"", "body");
}

#[test]
fn point_coordinates_must_be_finite() {
    let toml =
        format!("{BASE}{HINGE}").replace("local = [0.3, 0.0, 0.0]", "local = [0.3, 0.0, inf]");
    check_error(&toml, "`local[2]` is inf", 48, 20);
}

// Time grid.

#[test]
fn step_must_be_positive() {
    let d = check_error(
        &edit(&[("step = 0.1", "step = 0.0")]),
        "`step` = 0 must be finite and > 0",
        5,
        8,
    );
    assert_names(&d, "time", "step");
    check_error(
        &edit(&[("step = 0.1", "step = -0.1")]),
        "`step` = -0.1 must be finite and > 0",
        5,
        8,
    );
}

#[test]
fn end_must_not_precede_start() {
    let d =
        check_error(&edit(&[("end = 1.0", "end = -1.0")]), "end = -1 is before start = 0", 4, 7);
    assert_names(&d, "time", "end");
}

#[test]
fn time_bounds_must_be_finite() {
    check_error(&edit(&[("start = 0.0\n", "start = -inf\n")]), "`start` is -inf", 3, 9);
}

#[test]
fn step_and_steps_exclude_each_other() {
    check_error(
        &edit(&[("step = 0.1", "step = 0.1\nsteps = 10")]),
        "give either `step` (the spacing) or `steps`",
        6,
        9,
    );
    check_error(&edit(&[("step = 0.1\n", "")]), "missing `step` (the spacing) or `steps`", 2, 1);
}

#[test]
fn end_is_included_within_a_thousandth_of_a_step() {
    let count = |end: &str| load_ok(&edit(&[("end = 1.0", end)])).mechanism.time.count;
    assert_eq!(count("end = 0.99995"), 11);
    assert_eq!(count("end = 0.9998"), 10);
    assert_eq!(count("end = 0.0"), 1);
}

#[test]
fn steps_gives_steps_plus_one_time_points() {
    let time = load_ok(&edit(&[("step = 0.1", "steps = 4")])).mechanism.time;
    assert_eq!((time.count, time.step), (5, 0.25));
}

#[test]
fn steps_must_be_at_least_one() {
    check_error(
        &edit(&[("step = 0.1", "steps = 0")]),
        "`steps` = 0: the grid needs at least 1 interval",
        5,
        9,
    );
}

#[test]
fn steps_need_an_end_after_the_start() {
    check_error(
        &edit(&[("step = 0.1", "steps = 4"), ("end = 1.0", "end = 0.0")]),
        "with `steps`, end must be after start",
        4,
        7,
    );
}

#[test]
fn more_than_ten_million_time_points_is_an_error() {
    let d = check_error(
        &edit(&[("step = 0.1", "step = 1e-8")]),
        "the grid has 100000001 time points, more than the 10000000 allowed",
        5,
        8,
    );
    assert_names(&d, "time", "step");
    check_error(
        &edit(&[("step = 0.1", "steps = 10000000")]),
        "the grid has 10000001 time points",
        5,
        9,
    );
    load_ok(&edit(&[("step = 0.1", "steps = 9999999")]));
}

#[test]
fn negative_steps_is_a_type_error() {
    check_error(
        &edit(&[("step = 0.1", "steps = -3")]),
        "invalid value: integer `-3`, expected a non-negative integer",
        5,
        9,
    );
}

// Solver.

#[test]
fn solver_tolerance_must_be_positive() {
    let toml = format!("{BASE}[solver]\ntolerance = 0.0\n");
    let d = check_error(&toml, "`tolerance` = 0 must be finite and > 0", 28, 13);
    assert_names(&d, "solver", "tolerance");
}

#[test]
fn solver_iterations_must_be_between_one_and_ten_thousand() {
    check_error(
        &format!("{BASE}[solver]\nmax_iterations = 0\n"),
        "`max_iterations` = 0 must be between 1 and 10000",
        28,
        18,
    );
    check_error(
        &format!("{BASE}[solver]\nmax_iterations = 20000\n"),
        "`max_iterations` = 20000",
        28,
        18,
    );
}

#[test]
fn solver_defaults_apply() {
    let m = load_ok(&format!("{BASE}[solver]\nmax_iterations = 40\n")).mechanism;
    assert_eq!((m.solver.tolerance, m.solver.max_iterations), (1e-10, 40));
}

// Counting.

#[test]
fn fewer_equations_than_unknowns_says_how_many_are_missing() {
    let toml = edit(&[(
        "[[drivers]]\nname = \"push\"\njoint = \"rail\"\nmotion = \"translation\"\nlaw = { start = 0.0, velocity = 1.0 }\n",
        "",
    )]);
    let d = check_error(
        &toml,
        "7 unknowns (7 per moving body) but only 6 equations: 1 driver or constraint is missing",
        1,
        1,
    );
    assert_eq!(d.entity.as_deref(), Some("mechanism \"slider\""));
    let toml = format!("{BASE}[[bodies]]\nname = \"loose\"\n");
    check_error(
        &toml,
        "14 unknowns (7 per moving body) but only 8 equations: 6 drivers or constraints are missing",
        22,
        1,
    );
}

#[test]
fn a_link_between_two_spherical_joints_is_named_with_the_distance_fix() {
    // The R-S-S-R without its spin constraint: the coupler turns freely about the line A–B.
    let rssr = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/rssr.toml"),
    )
    .unwrap();
    let spin = "[[constraints]]\nname = \"no_spin\"\ntype = \"fix\"\nbody = \"coupler\"\n\
                coordinate = \"e2\"\nvalue = 0.0\n";
    let toml = edit_text(&rssr, &[(spin, "")]);
    let errors = load(&toml).expect_err("one equation is missing");
    let message = &errors.iter().find(|d| d.message.contains("missing")).unwrap().message;
    assert!(message.contains("1 driver or constraint is missing"), "{message}");
    assert!(
        message.contains(
            "body \"coupler\" spins idly about the line through its spherical joints \"A\" and \"B\""
        ),
        "{message}"
    );
    assert!(message.contains("`distance` joint between \"crank\" and \"rocker\""), "{message}");
    // A missing driver elsewhere does not blame a body.
    let undriven = edit(&[(
        "[[drivers]]\nname = \"push\"\njoint = \"rail\"\nmotion = \"translation\"\nlaw = { start = 0.0, velocity = 1.0 }\n",
        "",
    )]);
    let errors = load(&undriven).expect_err("the driver is missing");
    assert!(errors.iter().all(|d| !d.message.contains("spins idly")), "{}", render(&errors));
}

#[test]
fn more_equations_than_unknowns_is_not_an_error_here() {
    load_ok(&format!("{BASE}{FIX}"));
}

// Helpers.

#[test]
fn edit_distance_counts_insertions_deletions_and_substitutions() {
    assert_eq!(edit_distance("axis_i", "axis_i"), 0);
    assert_eq!(edit_distance("axsi_i", "axis_i"), 2);
    assert_eq!(edit_distance("revolut", "revolute"), 1);
    assert_eq!(edit_distance("", "abc"), 3);
    assert_eq!(edit_distance("kitten", "sitting"), 3);
}
