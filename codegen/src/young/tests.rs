use std::path::{Path, PathBuf};

use super::{import, name_from_path, to_toml};
use crate::desc::{
    BodyDesc, ConstraintType, CoordinateName, DriverCoordinate, JointType, LawDesc, MechanismDesc,
    SolverDesc, TimeDesc,
};
use crate::diag::Diagnostic;

/// The thesis' 18 decks, shipped beside the examples (copies of
/// `tests/reference/seed-examples/*.deck`).
fn deck_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/decks")
}

/// Every shipped deck as (file name, text), sorted by file name.
fn seed_decks() -> Vec<(String, String)> {
    let mut decks: Vec<(String, String)> = std::fs::read_dir(deck_dir())
        .expect("examples/decks exists")
        .map(|entry| entry.expect("readable directory entry").path())
        .filter(|path| path.extension().is_some_and(|ext| ext == "deck"))
        .map(|path| {
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            let text = std::fs::read_to_string(&path).expect("readable deck");
            (name, text)
        })
        .collect();
    decks.sort();
    decks
}

fn import_seed(file: &str) -> MechanismDesc {
    let text = std::fs::read_to_string(deck_dir().join(file)).expect("readable deck");
    import(&text, Path::new(file).file_stem().unwrap().to_str().unwrap()).expect("deck imports")
}

/// Imports `deck`, which must fail, and returns the diagnostic.
fn import_error(deck: &str) -> Diagnostic {
    match import(deck, "bad") {
        Ok(desc) => panic!("the deck imported as {desc:#?}"),
        Err(diag) => diag,
    }
}

/// The diagnostic as the command line prints it.
fn check_error(deck: &str, expected: &str) {
    assert_eq!(import_error(deck).to_string(), expected);
}

#[test]
fn all_eighteen_seed_decks_import() {
    let decks = seed_decks();
    assert_eq!(decks.len(), 18);
    for (file, text) in &decks {
        let stem = file.trim_end_matches(".deck");
        let desc = import(text, stem).unwrap_or_else(|d| panic!("{file}: {d}"));
        assert_eq!(desc.name, name_from_path(Path::new(file)));
        assert_eq!(
            desc.description.as_deref(),
            Some(&*format!("Imported from the YOUNG deck {stem}"))
        );
    }
}

#[test]
fn import_file_names_the_file_in_the_description_and_in_errors() {
    let desc = super::import_file(&deck_dir().join("4-bar.deck")).unwrap();
    assert_eq!(desc.name, "four_bar");
    assert_eq!(desc.description.as_deref(), Some("Imported from the YOUNG deck 4-bar.deck"));

    let missing = deck_dir().join("no-such.deck");
    let diag = super::import_file(&missing).unwrap_err();
    assert_eq!(diag.file, Some(missing.display().to_string()));
    assert!(diag.message.starts_with("cannot read the deck: "), "{}", diag.message);

    // Bytes that are not UTF-8 become U+FFFD and then an ordinary bad token.
    let binary = std::env::temp_dir().join(format!("young-binary-{}.deck", std::process::id()));
    std::fs::write(&binary, b"1 0 0 \xff\xfe 0").unwrap();
    let diag = super::import_file(&binary).unwrap_err();
    std::fs::remove_file(&binary).unwrap();
    assert_eq!(diag.file, Some(binary.display().to_string()));
    assert_eq!((diag.line, diag.column), (Some(1), Some(7)));
    assert_eq!(diag.message, "token 4 `\u{fffd}\u{fffd}` is not an integer");
}

#[test]
fn toml_round_trip_is_exact_for_every_seed_deck() {
    for (file, text) in seed_decks() {
        let desc = import(&text, &file).unwrap();
        let toml_text = to_toml(&desc, &format!("Imported from the YOUNG deck {file}."));
        let back: MechanismDesc =
            toml::from_str(&toml_text).unwrap_or_else(|e| panic!("{file}: {e}\n{toml_text}"));
        assert_eq!(back, desc, "{file}");
    }
}

#[test]
fn rssr_imports_as_the_contract_maps_it() {
    let d = import_seed("rssr.deck");
    assert_eq!(d.name, "rssr");
    assert_eq!(
        d.time,
        TimeDesc { start: 0.000000119, end: 0.04, step: Some(0.0035717333), steps: None }
    );
    let names: Vec<&str> = d.bodies.iter().map(|b| b.name.as_str()).collect();
    assert_eq!(names, ["body1", "body2", "body3", "body4"]);
    assert_eq!(
        d.bodies[0],
        BodyDesc {
            name: "body1".into(),
            ground: true,
            r: Some([0.0; 3]),
            p: Some([1.0, 0.0, 0.0, 0.0])
        }
    );
    assert_eq!(d.bodies[3].r, Some([-0.0475, 0.49977, 0.0]));
    assert!(d.bodies[1..].iter().all(|b| !b.ground));

    let joints: Vec<(&str, JointType, &str, &str)> = d
        .joints
        .iter()
        .map(|j| (j.name.as_str(), j.kind, j.body_i.as_str(), j.body_j.as_str()))
        .collect();
    assert_eq!(
        joints,
        [
            ("spherical1", JointType::Spherical, "body2", "body3"),
            ("spherical2", JointType::Spherical, "body3", "body4"),
            ("revolute1", JointType::Revolute, "body1", "body2"),
            ("revolute2", JointType::Revolute, "body4", "body1"),
        ]
    );
    let o2 = &d.joints[2];
    assert_eq!(o2.point_i, Some([0.0, -0.06567, 0.0]));
    assert_eq!(o2.axis_i, Some([0.0, -0.03433, 0.0]));
    assert_eq!(o2.axis_j, Some([0.0, 0.1, 0.0]));
    assert_eq!((o2.ref_i, o2.ref_j, o2.lead), (None, None, None));
    let o4 = &d.joints[3];
    assert_eq!(o4.axis_j, Some([-0.0025, 0.0, 0.0]));

    assert_eq!(d.constraints.len(), 1);
    let no_spin = &d.constraints[0];
    assert_eq!(
        (no_spin.name.as_str(), no_spin.kind, no_spin.body.as_deref(), no_spin.coordinate),
        ("simplified1", ConstraintType::Fix, Some("body3"), CoordinateName::E2)
    );
    assert_eq!(no_spin.value, 0.0);

    let motor = &d.drivers[0];
    assert_eq!(motor.name, "driver1");
    assert_eq!(
        (motor.body.as_deref(), motor.coordinate),
        (Some("body2"), Some(DriverCoordinate::Ry))
    );
    assert_eq!((&motor.joint, motor.motion), (&None, None));
    assert_eq!(
        motor.law,
        LawDesc {
            start: Some(0.0),
            velocity: Some(146.6),
            acceleration: Some(0.0),
            ..LawDesc::default()
        }
    );
    let points: Vec<(&str, &str, [f64; 3])> =
        d.points.iter().map(|p| (p.name.as_str(), p.body.as_str(), p.local)).collect();
    assert_eq!(points, [("point1", "body3", [0.0; 3]), ("point2", "body3", [0.0, 0.4812, 0.0])]);
}

#[test]
fn five_body_prismatic_references_are_h_minus_p_and_the_difference_is_raw() {
    let d = import_seed("5body.deck");
    let kinds: Vec<(&str, JointType)> =
        d.joints.iter().map(|j| (j.name.as_str(), j.kind)).collect();
    assert_eq!(
        kinds,
        [
            ("spherical1", JointType::Spherical),
            ("revolute1", JointType::Revolute),
            ("revolute2", JointType::Revolute),
            ("cylindrical1", JointType::Cylindrical),
            ("prismatic1", JointType::Prismatic),
        ]
    );
    let slide = &d.joints[4];
    assert_eq!((slide.body_i.as_str(), slide.body_j.as_str()), ("body4", "body5"));
    assert_eq!(slide.point_j, Some([0.2, 0.0, 0.0]));
    assert_eq!(slide.axis_i, Some([1.0, 0.0, 0.0]));
    assert_eq!(slide.axis_j, Some([1.2, 0.0, 0.0]));
    assert_eq!(slide.ref_i, Some([0.0, 1.0, 0.0]));
    assert_eq!(slide.ref_j, Some([0.0, 0.0, 1.0]));
    let same_x = &d.constraints[0];
    assert_eq!(same_x.kind, ConstraintType::CoordinateDifference);
    assert_eq!(
        (same_x.body_i.as_deref(), same_x.body_j.as_deref()),
        (Some("body3"), Some("body4"))
    );
    assert_eq!(
        (same_x.body.as_deref(), same_x.coordinate, same_x.value),
        (None, CoordinateName::X, 0.0)
    );
    assert!(d.bodies[4].ground);
    assert_eq!(d.drivers[0].law.start, Some(1.52));
    assert_eq!(d.drivers[0].law.velocity, Some(-6.2831852));
}

#[test]
fn screw_vectors_are_used_as_given_and_the_lead_is_two_pi_alpha() {
    let deck = "2 1 0 0 0 0 0 0 1 0 0 1
        0 0 0 1 0 0 0   0 2 0 1 0 0 0
        2 5 0 1.047 0
        1 2  1 1 1  2 2 2  0 1 0  0 2 0  1 0 0  0 0 1  0.5
        1 0 0 0 0 0 0
        0 3 1";
    let screw = &import(deck, "screw").unwrap().joints[0];
    assert_eq!(screw.name, "screw1");
    assert_eq!(screw.kind, JointType::Screw);
    assert_eq!(screw.point_i, Some([1.0; 3]));
    assert_eq!(screw.point_j, Some([2.0; 3]));
    assert_eq!(screw.axis_i, Some([0.0, 1.0, 0.0]));
    assert_eq!(screw.axis_j, Some([0.0, 2.0, 0.0]));
    assert_eq!(screw.ref_i, Some([1.0, 0.0, 0.0]));
    assert_eq!(screw.ref_j, Some([0.0, 0.0, 1.0]));
    assert_eq!(screw.lead, Some(std::f64::consts::PI));
}

#[test]
fn differences_of_deck_decimals_are_rounded_once() {
    use super::lex::decimal_difference;
    assert_eq!(decimal_difference("-0.05", "-0.0475"), Some(-0.0025));
    assert_eq!(decimal_difference("1.4", "0.4"), Some(1.0));
    assert_eq!(decimal_difference("2.5E-3", ".5e-3"), Some(0.002));
    assert_eq!(decimal_difference("+1.", "-1"), Some(2.0));
    assert_eq!(decimal_difference("0", "-0"), Some(0.0));
    // Exponents too far apart, too many digits or no plain decimal: the caller falls back to
    // f64 subtraction.
    assert_eq!(decimal_difference("1e30", "1e-30"), None);
    assert_eq!(decimal_difference("0e2147483647", "0e-2147483648"), None);
    assert_eq!(decimal_difference("0.1234567890123456789012345678901", "0"), None);
    assert_eq!(decimal_difference("1e", "0"), None);
    assert_eq!(decimal_difference(".", "0"), None);
    assert_eq!(decimal_difference("inf", "0"), None);
    let deck = "2 0 0 0 0 1 0 0 0 0 0 0  0 0 0 1 0 0 0  0 0 0 1 0 0 0
        1 2  0 0 0  0.1 0.1 0.1  1e30 0 0  0.3 0.1 0.1  0 1 1";
    let axes = import(deck, "far").unwrap().joints[0].clone();
    assert_eq!(axes.axis_i, Some([1e30, 0.0, 0.0]));
    assert_eq!(axes.axis_j, Some([0.2, 0.0, 0.0]));
}

#[test]
fn universal_axes_are_q_minus_p() {
    let d = import_seed("2-2-1.deck");
    let cross = &d.joints[0];
    assert_eq!((cross.name.as_str(), cross.kind), ("universal1", JointType::Universal));
    assert_eq!(cross.point_j, Some([0.0, -1.0, 0.0]));
    assert_eq!(cross.axis_i, Some([0.0, 0.0, 1.0]));
    assert_eq!(cross.axis_j, Some([-1.0, 0.0, 0.0]));
    assert_eq!((cross.ref_i, cross.ref_j), (None, None));
}

#[test]
fn angles_become_sines_of_half_angles_in_fixes_and_grounds_but_stay_raw_in_differences() {
    let deck = "2 1 0 0 0 0 0 0 0 3 3 1
        0 0 0 1 0 0 0   1 2 3 1 0 0 0
        2 6 0.5 0.25 0.125
        2 4 1.0   2 5 -0.5   2 3 7.5
        2 1 4 0.3   2 1 6 -0.2   1 2 2 1.5
        1  1 2 3  0.2 0.4 0.6
        0 1 0.1";
    let d = import(deck, "angles").unwrap();
    let fixes: Vec<(&str, CoordinateName, f64)> =
        d.constraints.iter().map(|c| (c.name.as_str(), c.coordinate, c.value)).collect();
    assert_eq!(
        fixes,
        [
            ("simplified1", CoordinateName::E1, 0.5_f64.sin()),
            ("simplified2", CoordinateName::E2, (-0.25_f64).sin()),
            ("simplified3", CoordinateName::Z, 7.5),
            ("difference1", CoordinateName::E1, 0.3),
            ("difference2", CoordinateName::E3, -0.2),
            ("difference3", CoordinateName::Y, 1.5),
        ]
    );
    assert_eq!(d.drivers[0].coordinate, Some(DriverCoordinate::Rz));
    assert_eq!(
        d.drivers[0].law,
        LawDesc {
            start: Some(0.5),
            velocity: Some(0.25),
            acceleration: Some(0.125),
            ..LawDesc::default()
        }
    );
    let ground = &d.bodies[0];
    assert!(ground.ground);
    assert_eq!(ground.r, Some([1.0, 2.0, 3.0]));
    let e = [0.1_f64.sin(), 0.2_f64.sin(), 0.3_f64.sin()];
    let e0 = (1.0 - e.iter().map(|x| x * x).sum::<f64>()).sqrt();
    assert_eq!(ground.p, Some([e0, e[0], e[1], e[2]]));
}

#[test]
fn everything_after_the_time_line_is_ignored() {
    let deck = "1 0 0 0 0 0 0 0 0 6 0 0\n0 0 0 1 0 0 0\n1 1 0 1 2 0 1 3 0 1 4 0 1 5 0 1 6 0\n0 3 1\n\
                first line: 1 body, no driver … ±∞ \u{0}\u{7f} 1.2.3\n";
    let d = import(deck, "static").unwrap();
    assert_eq!(d.time, TimeDesc { start: 0.0, end: 3.0, step: Some(1.0), steps: None });
    assert_eq!(d.constraints.len(), 6);
}

#[test]
fn line_breaks_do_not_matter() {
    for (file, text) in seed_decks() {
        let one_line = text.split_whitespace().collect::<Vec<_>>().join(" ");
        assert_eq!(import(&one_line, &file), import(&text, &file), "{file}");
    }
}

#[test]
fn names_from_paths_are_sanitised() {
    let cases = [
        ("2-6-1.deck", "ex_2_6_1"),
        ("4-bar.deck", "four_bar"),
        ("5body.deck", "five_body"),
        ("rssr.deck", "rssr"),
        ("decks/RSSR.DECK", "rssr"),
        ("/tmp/My Deck (v2).txt", "my_deck_v2"),
        ("__x__", "x"),
        ("100-bar", "ex_100_bar"),
        ("Ação.deck", "a_o"),
        ("---", "mechanism"),
        ("", "mechanism"),
    ];
    for (path, expected) in cases {
        assert_eq!(name_from_path(Path::new(path)), expected, "{path}");
    }
    assert_eq!(import("0 0 0 0 0 0 0 0 0 0 0 0 0 1 1", "4-bar").unwrap().name, "four_bar");
}

#[test]
fn a_bad_token_names_the_record_the_token_and_its_place() {
    check_error(
        "2 0 0 0 0 2 0 0 0 0 0 0\n0 0 0 1 0 0 0\n0 0 0 1 0 0 0\n1 2 0 0 0 0 0 0 1 0 0 1 0 0\n\
         2 1 0 0 0 0 0 0 0 0x1 0 0 0 0\n0 1 1",
        "5:19: error: revolute joint 2 (record 6), field `Qi.y`: token 50 `0x1` is not a number",
    );
}

#[test]
fn a_real_where_an_integer_belongs_is_refused() {
    check_error(
        "1 0 1.0 0 0 0 0 0 0 0 0 0",
        "1:5: error: header (the 12 counts), field `NPOINT`: token 3 `1.0` is not an integer; \
         YOUNG reads counts, body numbers and directions as integers",
    );
}

#[test]
fn a_truncated_deck_says_what_was_expected_at_its_end() {
    check_error(
        "1 0 0 0 0 0 0 0 0 0 0 0\n0 0 0 1 0 0 0\n0 3",
        "3:4: error: time line (record 13), field `dT`: the deck ends where token 22 (a number) \
         was expected; check the header's counts against the records",
    );
}

#[test]
fn negative_and_huge_counts_are_refused_before_reading_records() {
    check_error(
        "1 0 0 -2 0 0 0 0 0 0 0 0",
        "1:7: error: header (the 12 counts), field `NSPHER`: token 4: the count -2 is negative",
    );
    check_error(
        "1 0 0 0 0 0 0 0 0 0 0 100001",
        "1:23: error: header (the 12 counts), field `NGROUN`: token 12: the count 100001 is \
         above the limit of 100000",
    );
    check_error(
        "99999999999999999999999 0",
        "1:1: error: header (the 12 counts), field `NBODY`: token 1 `99999999999999999999999` \
         is too large an integer",
    );
}

#[test]
fn a_body_number_out_of_range_is_refused() {
    check_error(
        "2 0 1 0 0 0 0 0 0 0 0 0\n0 0 0 1 0 0 0  0 0 0 1 0 0 0\n3 0 0 0\n0 1 1",
        "3:1: error: point of interest 1 (record 3), field `body`: token 27: there is no body 3; \
         the deck has bodies 1 to 2",
    );
    check_error(
        "0 0 1 0 0 0 0 0 0 0 0 0 1 0 0 0",
        "1:25: error: point of interest 1 (record 3), field `body`: token 13: there is no body 1; \
         the deck has no bodies",
    );
    check_error(
        "1 0 0 0 0 0 0 0 0 1 0 0 0 0 0 1 0 0 0 0 1 0",
        "1:39: error: simplified constraint 1 (record 10), field `body`: token 20: there is no \
         body 0; the deck has only body 1",
    );
}

#[test]
fn a_direction_outside_one_to_six_is_refused() {
    check_error(
        "1 1 0 0 0 0 0 0 0 0 0 0\n0 0 0 1 0 0 0\n1 7 0 1 0\n0 1 1",
        "3:3: error: driver 1 (record 2), field `dir`: token 21: the direction 7 is not one of \
         1 to 6 (x, y, z, rotation about x, y, z)",
    );
    check_error(
        "2 0 0 0 0 0 0 0 0 0 1 0\n0 0 0 1 0 0 0 0 0 0 1 0 0 0\n1 2 0 0\n0 1 1",
        "3:5: error: distance constraint 1 (record 11), field `dir`: token 29: the direction 0 \
         is not one of 1 to 6 (x, y, z, rotation about x, y, z)",
    );
}

#[test]
fn grounding_a_body_twice_is_refused() {
    check_error(
        "1 0 0 0 0 0 0 0 0 0 0 2\n0 0 0 1 0 0 0\n1 0 0 0 0 0 0\n1 0 0 0 0 0 0\n0 1 1",
        "4:1: error: grounded body 2 (record 12), field `body`: token 27: body 1 is already \
         grounded by grounded body 1",
    );
}

#[test]
fn ground_angles_that_no_orientation_has_are_refused() {
    let diag =
        import_error("1 0 0 0 0 0 0 0 0 0 0 1\n0 0 0 1 0 0 0\n1 0 0 0 3.14159 3.14159 0\n0 1 1");
    assert_eq!(diag.entity.as_deref(), Some("grounded body 1 (record 12)"));
    assert_eq!(diag.field.as_deref(), Some("alpha"));
    assert_eq!((diag.line, diag.column), (Some(3), Some(9)));
    // The sum is 2 − O(1e-11); its last digits depend on the platform's sine.
    assert!(
        diag.message.starts_with("token 24: the angles give e1² + e2² + e3² = 1.99999"),
        "{}",
        diag.message
    );
    assert!(diag.message.contains("above 1, which no orientation has"), "{}", diag.message);
}

#[test]
fn non_finite_numbers_are_refused() {
    for (value, column) in [("inf", 25), ("NaN", 25), ("1e999", 25)] {
        let diag = import_error(&format!("1 0 0 0 0 0 0 0 0 0 0 0 {value} 0 0 1 0 0 0 0 1 1"));
        assert_eq!((diag.line, diag.column), (Some(1), Some(column)), "{value}");
        assert_eq!(diag.entity.as_deref(), Some("body 1 (record 1)"));
        assert_eq!(diag.field.as_deref(), Some("x"));
        assert!(diag.message.contains("is not a finite number"), "{}", diag.message);
    }
}

#[test]
fn empty_and_blank_input_is_a_truncated_header() {
    for deck in ["", " \n\t\r\n", "\u{feff}"] {
        let diag = import_error(deck);
        assert_eq!(diag.entity.as_deref(), Some("header (the 12 counts)"));
        assert_eq!(diag.field.as_deref(), Some("NBODY"));
        assert!(diag.message.starts_with("the deck ends where token 1 (an integer)"));
    }
}

#[test]
fn long_and_binary_tokens_are_shortened_and_escaped_in_messages() {
    let garbage = format!("\u{1}\u{fffd}{}", "x".repeat(1000));
    assert_eq!(
        import_error(&garbage).message,
        "token 1 `\\u{1}\u{fffd}xxxxxxxxxxxxxxxxxxxxxx…` is not an integer"
    );
}

#[test]
fn columns_count_characters_not_bytes() {
    let diag = import_error("ü  ");
    assert_eq!((diag.line, diag.column), (Some(1), Some(1)));
    let diag = import_error("1 0 0 0 0 0 0 0 0 0 0 0 \n ééé é");
    assert_eq!((diag.line, diag.column), (Some(2), Some(2)));
    let diag = import_error("1 0 0 0 0 0 0 0 0 0 0 0 \n 0 ééé é");
    assert_eq!((diag.line, diag.column), (Some(2), Some(4)));
}

/// A small xorshift generator, so that the garbage below is the same on every run.
struct XorShift(u64);

impl XorShift {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
}

#[test]
fn no_input_makes_the_importer_panic() {
    let mut rng = XorShift(0x9e37_79b9_7f4a_7c15);
    // Random bytes, read as the command line reads a file.
    for len in 0..200 {
        let bytes: Vec<u8> = (0..len).map(|_| rng.next().to_le_bytes()[0]).collect();
        let _ = import(&String::from_utf8_lossy(&bytes), "garbage");
    }
    // Every seed deck cut at every token, and with every token replaced by something else.
    let replacements = ["-1", "0", "7", "100001", "1.5", "x", "1e999", "-0", "3"];
    for (file, text) in seed_decks() {
        let tokens: Vec<&str> = text.split_whitespace().collect();
        for cut in 0..tokens.len() {
            let head = tokens[..cut].join(" ");
            let diag = import(&head, &file);
            // The time line is the last record every seed deck reads, and every deck has
            // comments or nothing after it, so any cut before its end must be an error.
            let ends_early = cut < tokens.len();
            assert!(diag.is_err() || !ends_early, "{file} cut at {cut} imported");
            for replacement in replacements {
                let mut changed = tokens.clone();
                changed[cut] = replacement;
                let _ = import(&changed.join(" "), &file);
            }
        }
    }
}

#[test]
fn toml_floats_round_trip_exactly() {
    let values = [
        0.0,
        -0.0,
        0.1 + 0.2,
        1.0 / 3.0,
        1e-7,
        1.19e-7,
        -2.5e-300,
        5e-324,
        1e16,
        123_456_789_012_345_680.0,
        f64::MAX,
        f64::MIN_POSITIVE,
        -6.2831852,
    ];
    for &x in &values {
        let mut desc = import("0 0 0 0 0 0 0 0 0 0 0 0 0 1 1", "floats").unwrap();
        desc.time.start = x;
        let back: MechanismDesc = toml::from_str(&to_toml(&desc, "")).unwrap();
        assert_eq!(back.time.start.to_bits(), x.to_bits(), "{x:?}");
    }
}

#[test]
fn toml_writes_every_optional_field_and_escapes_strings() {
    let mut desc = import_seed("rssr.deck");
    desc.description =
        Some("quotes \" backslash \\ tab \t newline \n bell \u{7} del \u{7f} é".into());
    desc.time = TimeDesc { start: 0.0, end: 1.0, step: None, steps: Some(40) };
    desc.solver = Some(SolverDesc { tolerance: Some(1e-12), max_iterations: Some(7) });
    desc.joints[2].ref_i = Some([0.0, 0.0, 1.0]);
    desc.joints[2].ref_j = Some([0.0, 0.0, 1.0]);
    desc.joints[0].kind = JointType::Distance;
    desc.joints[0].distance = Some(0.25);
    desc.drivers[0].body = None;
    desc.drivers[0].coordinate = None;
    desc.drivers[0].joint = Some("revolute1".into());
    desc.drivers[0].motion = Some(crate::desc::Motion::Rotation);
    desc.drivers[0].law = LawDesc {
        offset: Some(0.5),
        amplitude: Some(1.0),
        frequency: Some(2.0),
        phase: Some(-0.5),
        ..LawDesc::default()
    };
    let mut second = desc.drivers[0].clone();
    second.name = "idle".into();
    second.motion = Some(crate::desc::Motion::Translation);
    second.law = LawDesc::default();
    desc.drivers.push(second);
    let text = to_toml(&desc, "first line\n\nthird line");
    assert!(text.starts_with("# first line\n#\n# third line\n\nname = \"rssr\"\n"), "{text}");
    assert!(
        text.contains("law = { offset = 0.5, amplitude = 1.0, frequency = 2.0, phase = -0.5 }")
    );
    assert!(text.contains("law = {}"));
    assert!(text.contains("\n[solver]\ntolerance = 1e-12\nmax_iterations = 7\n"), "{text}");
    let back: MechanismDesc = toml::from_str(&text).unwrap_or_else(|e| panic!("{e}\n{text}"));
    assert_eq!(back, desc);
}

#[test]
fn toml_layout_follows_the_contract_example() {
    let desc = import_seed("2-3-1.deck");
    let expected = r#"# Imported from the YOUNG deck 2-3-1.deck.

name = "ex_2_3_1"
description = "Imported from the YOUNG deck 2-3-1"

[time]
start = 0.0
end = 6.0
step = 1.0

[[bodies]]
name = "body1"
ground = true
r = [0.0, 0.0, 0.0]
p = [1.0, 0.0, 0.0, 0.0]

[[bodies]]
name = "body2"
r = [0.0, 1.0, 0.0]
p = [1.0, 0.0, 0.0, 0.0]

[[joints]]
name = "revolute1"
type = "revolute"
body_i = "body1"
body_j = "body2"
point_i = [0.0, 0.0, 0.0]
point_j = [0.0, -1.0, 0.0]
axis_i = [1.0, 0.0, 0.0]
axis_j = [-1.0, 0.0, 0.0]

[[drivers]]
name = "driver1"
body = "body2"
coordinate = "rx"
law = { start = 0.0, velocity = 1.047, acceleration = 0.0 }
"#;
    assert_eq!(to_toml(&desc, "Imported from the YOUNG deck 2-3-1.deck."), expected);
}

/// Each seed deck, the name [`name_from_path`] gives its import, and the shipped example that
/// describes the same mechanism with meaningful names.
const SHIPPED_EXAMPLES: [(&str, &str, &str); 18] = [
    ("1-1-1.deck", "ex_1_1_1", "static_body.toml"),
    ("1-2-1.deck", "ex_1_2_1", "static_body_offset.toml"),
    ("1-3-1.deck", "ex_1_3_1", "translation_y.toml"),
    ("1-3-2.deck", "ex_1_3_2", "translation_x.toml"),
    ("1-3-3.deck", "ex_1_3_3", "translation_xy.toml"),
    ("1-3-4.deck", "ex_1_3_4", "translation_xyz.toml"),
    ("1-4-1.deck", "ex_1_4_1", "rotation_about_x.toml"),
    ("1-4-2.deck", "ex_1_4_2", "rotation_about_y.toml"),
    ("1-4-3.deck", "ex_1_4_3", "rotation_about_y_short.toml"),
    ("2-1-1.deck", "ex_2_1_1", "spherical_joint.toml"),
    ("2-2-1.deck", "ex_2_2_1", "universal_joint.toml"),
    ("2-3-1.deck", "ex_2_3_1", "revolute_joint.toml"),
    ("2-4-1.deck", "ex_2_4_1", "cylindrical_joint.toml"),
    ("2-5-1.deck", "ex_2_5_1", "prismatic_joint.toml"),
    ("2-6-1.deck", "ex_2_6_1", "screw_joint.toml"),
    ("4-bar.deck", "four_bar", "four_bar.toml"),
    ("5body.deck", "five_body", "slider_crank_5body.toml"),
    ("rssr.deck", "rssr", "rssr.toml"),
];

/// Where `name` stands in `names`, for comparing references up to renaming.
fn position_of<'a>(names: impl IntoIterator<Item = &'a String>, name: &str) -> Option<usize> {
    names.into_iter().position(|n| n == name)
}

/// Checks that `shipped` is `imported` with other entity names: the same entities in the same
/// order with the same numbers, every reference to a body or joint pointing at the entity in
/// the same position. The names and the description may differ.
fn assert_same_up_to_names(shipped: &MechanismDesc, imported: &MechanismDesc, file: &str) {
    assert_eq!(shipped.time, imported.time, "{file}: time");
    assert_eq!(shipped.solver, imported.solver, "{file}: solver");
    let body =
        |desc: &MechanismDesc, name: &str| position_of(desc.bodies.iter().map(|b| &b.name), name);
    let body_opt =
        |desc: &MechanismDesc, name: &Option<String>| name.as_deref().map(|n| body(desc, n));

    assert_eq!(shipped.bodies.len(), imported.bodies.len(), "{file}: bodies");
    for (k, (s, i)) in shipped.bodies.iter().zip(&imported.bodies).enumerate() {
        assert_eq!((s.ground, s.r, s.p), (i.ground, i.r, i.p), "{file}: body {k}");
    }

    assert_eq!(shipped.joints.len(), imported.joints.len(), "{file}: joints");
    for (k, (s, i)) in shipped.joints.iter().zip(&imported.joints).enumerate() {
        let ends = |desc: &MechanismDesc, j: &crate::desc::JointDesc| {
            (body(desc, &j.body_i), body(desc, &j.body_j))
        };
        assert_eq!(ends(shipped, s), ends(imported, i), "{file}: joint {k} bodies");
        let numbers = |j: &crate::desc::JointDesc| {
            (j.kind, j.point_i, j.point_j, j.axis_i, j.axis_j, j.ref_i, j.ref_j, j.lead, j.distance)
        };
        assert_eq!(numbers(s), numbers(i), "{file}: joint {k}");
    }

    assert_eq!(shipped.constraints.len(), imported.constraints.len(), "{file}: constraints");
    for (k, (s, i)) in shipped.constraints.iter().zip(&imported.constraints).enumerate() {
        let numbers = |desc: &MechanismDesc, c: &crate::desc::ConstraintDesc| {
            let bodies =
                (body_opt(desc, &c.body), body_opt(desc, &c.body_i), body_opt(desc, &c.body_j));
            (c.kind, bodies, c.coordinate, c.value)
        };
        assert_eq!(numbers(shipped, s), numbers(imported, i), "{file}: constraint {k}");
    }

    assert_eq!(shipped.drivers.len(), imported.drivers.len(), "{file}: drivers");
    for (k, (s, i)) in shipped.drivers.iter().zip(&imported.drivers).enumerate() {
        let numbers = |desc: &MechanismDesc, d: &crate::desc::DriverDesc| {
            let joint =
                d.joint.as_deref().map(|n| position_of(desc.joints.iter().map(|j| &j.name), n));
            (joint, d.motion, body_opt(desc, &d.body), d.coordinate, d.law.clone())
        };
        assert_eq!(numbers(shipped, s), numbers(imported, i), "{file}: driver {k}");
    }

    assert_eq!(shipped.points.len(), imported.points.len(), "{file}: points");
    for (k, (s, i)) in shipped.points.iter().zip(&imported.points).enumerate() {
        assert_eq!(
            (body(shipped, &s.body), s.local),
            (body(imported, &i.body), i.local),
            "{file}: point {k}"
        );
    }
}

#[test]
fn shipped_examples_are_their_decks_with_meaningful_names() {
    let examples = deck_dir().join("..");
    for (deck, import_name, example) in SHIPPED_EXAMPLES {
        assert_eq!(name_from_path(Path::new(deck)), import_name);
        let imported = import_seed(deck);
        assert_eq!(imported.name, import_name);
        let text = std::fs::read_to_string(examples.join(example)).expect("readable example");
        let shipped: MechanismDesc =
            toml::from_str(&text).unwrap_or_else(|e| panic!("{example}: {e}"));
        assert_eq!(shipped.name, example.trim_end_matches(".toml"), "{example}: name is the stem");
        assert!(text.starts_with("# "), "{example} starts with a comment block");
        assert_same_up_to_names(&shipped, &imported, example);
    }
    // Every deck has its example, and every shipped deck is in the table.
    let decks: Vec<String> = seed_decks().into_iter().map(|(file, _)| file).collect();
    let listed: Vec<&str> = SHIPPED_EXAMPLES.iter().map(|(deck, _, _)| *deck).collect();
    assert_eq!(decks, listed);
}

#[test]
fn every_seed_deck_imports_as_a_valid_description() {
    for (file, text) in seed_decks() {
        let desc = import(&text, &file).unwrap();
        if let Err(errors) = crate::validate::validate(&desc) {
            let errors: Vec<String> = errors.iter().map(ToString::to_string).collect();
            panic!("{file}:\n{}", errors.join("\n"));
        }
    }
}

#[test]
fn every_shipped_example_loads_and_validates() {
    let examples = deck_dir().join("..");
    for (_, _, example) in SHIPPED_EXAMPLES {
        if let Err(errors) = crate::validate::load_file(&examples.join(example)) {
            let errors: Vec<String> = errors.iter().map(ToString::to_string).collect();
            panic!("{example}:\n{}", errors.join("\n"));
        }
    }
}

/// The 4-bar deck with its header's `NREVOL` (the sixth count) replaced by `nrevol`.
fn four_bar_with_nrevol(nrevol: usize, drop_revolute: bool) -> String {
    let text = std::fs::read_to_string(deck_dir().join("4-bar.deck")).expect("readable deck");
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let mut header: Vec<String> = lines[0].split_whitespace().map(str::to_owned).collect();
    assert_eq!(header[5], "2", "the 4-bar deck has two revolute joints");
    header[5] = nrevol.to_string();
    lines[0] = header.join(" ");
    if drop_revolute {
        // The second revolute record is the last line of 14 numbers.
        let last = lines.iter().rposition(|l| l.split_whitespace().count() == 14).unwrap();
        lines.remove(last);
    }
    lines.join("\n")
}

#[test]
fn a_header_that_counts_too_many_records_is_refused_with_both_counts() {
    // The 4-bar has one universal and two revolute joints: three lines of 14 numbers.
    let d = import_error(&four_bar_with_nrevol(3, false));
    assert_eq!(d.entity.as_deref(), Some("header (the 12 counts)"), "{d}");
    assert!(d.message.contains("NREVOL = 3 (revolute joints)"), "{d}");
    assert!(d.message.contains("say 4 such records together of 14 numbers"), "{d}");
    assert!(d.message.contains("the deck's lines hold 3"), "{d}");
    // One record removed, the header unchanged: the header says 3, the lines 2.
    let d = import_error(&four_bar_with_nrevol(2, true));
    assert!(d.message.contains("say 3 such records together"), "{d}");
    assert!(d.message.contains("the deck's lines hold 2"), "{d}");
}

#[test]
fn a_header_that_counts_too_few_records_is_refused_with_both_counts() {
    let d = import_error(&four_bar_with_nrevol(1, false));
    assert!(d.message.contains("NREVOL = 1 (revolute joints)"), "{d}");
    assert!(d.message.contains("say 2 such records together"), "{d}");
    assert!(d.message.contains("the deck's lines hold 3"), "{d}");
    // A simplified constraint too few would turn the last one into the time line.
    let text = std::fs::read_to_string(deck_dir().join("1-1-1.deck")).expect("readable deck");
    let mut header: Vec<&str> = text.lines().next().unwrap().split_whitespace().collect();
    assert_eq!(header[9], "6", "1-1-1 has six simplified constraints");
    header[9] = "5";
    let deck = text.replacen(text.lines().next().unwrap(), &header.join(" "), 1);
    let d = import_error(&deck);
    assert_eq!(d.field.as_deref(), Some("NSIMPL"), "{d}");
    assert!(d.message.contains("NSIMPL = 5 (simplified constraints) says 5 such records"), "{d}");
    assert!(d.message.contains("the deck's lines hold 6"), "{d}");
}
