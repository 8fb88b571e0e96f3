//! Output files, pipes and channels: `-o` never destroys an input, files appear whole or not
//! at all, a failed run's JSON is one valid document, a closed pipe ends quietly, and names
//! reach CSV and the terminal as data.

use std::io::{self, Write};
use std::path::{Path, PathBuf};

use super::{EXIT_INVALID, EXIT_OK, EXIT_STOPPED, example, mechgen};
use crate::report::{self, Format, Writer};

/// A fresh directory of its own for one test.
fn fresh_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("mechgen-out-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temporary directory");
    dir
}

/// The names of the files in `dir`, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .expect("readable")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn an_output_that_is_an_input_is_refused_and_the_input_kept() {
    let dir = fresh_dir("same");
    let input = dir.join("rssr.toml");
    std::fs::copy(example("rssr.toml"), &input).expect("copied");
    let deck = dir.join("4-bar.deck");
    std::fs::copy(example("decks/4-bar.deck"), &deck).expect("copied");
    let before = std::fs::read(&input).expect("readable");
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(&input, dir.join("link.toml")).expect("symlink");
        std::fs::hard_link(&input, dir.join("hard.toml")).expect("hard link");
    }
    let mut outputs = vec![input.clone(), dir.join(".").join("rssr.toml")];
    if cfg!(unix) {
        outputs.extend([dir.join("link.toml"), dir.join("hard.toml")]);
    }
    let i = input.to_str().unwrap();
    for o in &outputs {
        let o = o.to_str().unwrap();
        for args in [
            vec!["solve", i, "--engine", "generic", "-o", o],
            vec!["generate", i, "-o", o],
            vec!["plot", i, "--point", "B", "-o", o],
            vec!["chart", i, "-o", o, "--repeats", "1"],
        ] {
            let (code, out, err) = mechgen(&args);
            assert_eq!(code, EXIT_INVALID, "{args:?}: {out}{err}");
            assert!(err.contains("is the input file"), "{args:?}: {err}");
            assert_eq!(std::fs::read(&input).expect("readable"), before, "{args:?}");
        }
    }
    let deck_before = std::fs::read(&deck).expect("readable");
    let (code, _, err) =
        mechgen(&["import-young", deck.to_str().unwrap(), "-o", deck.to_str().unwrap()]);
    assert_eq!(code, EXIT_INVALID, "{err}");
    assert_eq!(std::fs::read(&deck).expect("readable"), deck_before);
    // With --format json the refusal is the contract's error object.
    let (code, out, _) = mechgen(&["solve", i, "--engine", "generic", "--format", "json", "-o", i]);
    assert_eq!(code, EXIT_INVALID);
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(v["error"]["kind"], "invalid_input");
    assert_eq!(v["error"]["field"], "--output");
}

#[test]
fn an_output_in_a_missing_directory_is_refused_naming_the_path() {
    let dir = fresh_dir("missing");
    let i = example("rssr.toml");
    let i = i.to_str().unwrap();
    let target = dir.join("no-such-dir").join("out.json");
    let o = target.to_str().unwrap();
    for args in [
        vec!["solve", i, "--engine", "generic", "--format", "json", "-o", o],
        vec!["generate", i, "-o", o],
        vec!["plot", i, "--point", "B", "-o", o],
    ] {
        let (code, _, err) = mechgen(&args);
        assert_eq!(code, EXIT_INVALID, "{args:?}: {err}");
        assert!(err.contains(o), "{args:?}: the path is named: {err}");
        assert!(err.contains("does not exist"), "{args:?}: {err}");
    }
    assert!(!dir.join("no-such-dir").exists(), "no directory is created");
}

#[test]
fn outputs_replace_the_previous_file_whole_and_leave_no_temporary_file() {
    let dir = fresh_dir("replace");
    let i = example("rssr.toml");
    let i = i.to_str().unwrap();
    for (name, args) in [
        ("out.json", vec!["solve", i, "--engine", "generic", "--format", "json"]),
        ("out.rs", vec!["generate", i]),
        ("out.svg", vec!["plot", i, "--point", "B"]),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, "previous").expect("writable");
        let mut with_o = args.clone();
        with_o.extend(["-o", path.to_str().unwrap()]);
        let (code, _, err) = mechgen(&with_o);
        assert_eq!(code, EXIT_OK, "{err}");
        let written = std::fs::read_to_string(&path).expect("readable");
        if name == "out.svg" {
            assert!(written.starts_with("<svg") && written.trim_end().ends_with("</svg>"));
        } else {
            // The file holds exactly what standard output gets.
            let (_, stdout, _) = mechgen(&args);
            assert_eq!(written, stdout, "{name}");
        }
    }
    assert_eq!(listing(&dir), ["out.json", "out.rs", "out.svg"]);
}

#[test]
fn an_output_file_not_committed_leaves_the_previous_file_and_no_temporary_file() {
    let dir = fresh_dir("abandon");
    let path = dir.join("results.json");
    std::fs::write(&path, "previous").expect("writable");
    {
        let mut file = crate::output::OutputFile::create(&path).expect("created");
        file.write_all(&vec![b'x'; 1 << 20]).expect("written");
        // Dropped without commit: a run that failed half-way.
    }
    assert_eq!(std::fs::read_to_string(&path).expect("readable"), "previous");
    assert_eq!(listing(&dir), ["results.json"]);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o640)).expect("chmod");
        crate::output::write_file(&path, b"new").expect("written");
        let mode = std::fs::metadata(&path).expect("exists").permissions().mode();
        assert_eq!(mode & 0o777, 0o640, "the file keeps its permissions");
        assert_eq!(std::fs::read_to_string(&path).expect("readable"), "new");
    }
}

#[test]
fn an_output_file_of_many_chunks_holds_every_byte_written_in_order() {
    // Whole chunks go unbuffered where the file system allows, the rest through the page
    // cache; a flush half-way leaves every later chunk off the page boundaries of the file,
    // so that both paths and the switch between them are taken.
    let dir = fresh_dir("chunks");
    let path = dir.join("long.csv");
    let mut expected = Vec::new();
    let mut file = crate::output::OutputFile::create(&path).expect("created");
    let mut x = 0x9e37_79b9_7f4a_7c15_u64;
    for k in 0..4000 {
        // Rows of 700 to 1,700 bytes of varied text, as a writer hands them over.
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        let len = 700 + usize::try_from(x % 1000).expect("small");
        let row: Vec<u8> = (0..len).map(|i| b'0' + u8::try_from((i + k) % 10).unwrap()).collect();
        file.write_all(&row).expect("written");
        expected.extend_from_slice(&row);
        if k == 2500 {
            file.flush().expect("handed over");
        }
    }
    assert!(expected.len() > 4 * crate::output::CHUNK, "several chunks on either side");
    file.commit().expect("committed");
    let written = std::fs::read(&path).expect("readable");
    assert_eq!(written.len(), expected.len());
    assert!(written == expected, "the file differs from what was written");
    assert_eq!(listing(&dir), ["long.csv"]);
}

/// A writer that takes `room` bytes, then fails as a pipe whose reader has gone does.
struct ClosedPipe {
    room: usize,
}

impl Write for ClosedPipe {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if self.room == 0 {
            return Err(io::ErrorKind::BrokenPipe.into());
        }
        let n = buf.len().min(self.room);
        self.room -= n;
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

#[test]
fn a_closed_pipe_ends_solve_quietly_with_status_0_on_both_engines() {
    let file = example("rssr.toml");
    for engine in ["generic", "generated"] {
        for format in ["table", "csv", "json"] {
            let args = [
                "mechgen",
                "solve",
                file.to_str().unwrap(),
                "--engine",
                engine,
                "--format",
                format,
            ];
            let mut out = ClosedPipe { room: 200 };
            let mut err = Vec::new();
            let code = super::super::run(args.iter().map(Into::into).collect(), &mut out, &mut err);
            let err = String::from_utf8(err).expect("utf-8");
            assert_eq!(code, EXIT_OK, "{engine} {format}: {err}");
            assert!(err.is_empty(), "{engine} {format}: quiet, but said {err:?}");
        }
    }
    // Wrapped in another error, a closed pipe is still recognised.
    let wrapped = io::Error::other(io::Error::from(io::ErrorKind::BrokenPipe));
    assert!(super::super::closed_pipe(&wrapped));
    assert!(!super::super::closed_pipe(&io::Error::from(io::ErrorKind::WriteZero)));
}

#[cfg(unix)]
#[test]
fn a_generated_solver_that_breaks_off_still_ends_the_json_with_its_error() {
    use std::os::unix::fs::PermissionsExt;
    let loaded = crate::validate::load_file(&example("rssr.toml")).expect("valid");
    let mech = &loaded.mechanism;
    let eq = crate::generic::Equations::new(mech);
    let prep = eq.prepare();
    let mut built = crate::engine::build(mech).expect("the RSSR builds");
    // A solver that prints one step of the reduced system (3 bodies: 21 values each of q, q̇,
    // q̈) and dies without a verdict.
    let dir = fresh_dir("broken");
    let script = dir.join("solver.sh");
    let zeros = vec!["0.0"; 63].join(" ");
    std::fs::write(&script, format!("#!/bin/sh\necho \"step 0.0 1 0.0 1.0 {zeros}\"\nexit 7\n"))
        .expect("writable");
    std::fs::set_permissions(&script, std::fs::Permissions::from_mode(0o755)).expect("chmod");
    built.binary = script;
    let mut out = Vec::new();
    let mut err = Vec::new();
    let sink = super::super::common::Sink::Out(io::BufWriter::new(&mut out));
    let writer = Writer::begin(sink, Format::Json, mech, "generated", &[]).expect("begun");
    let analysis = crate::generic::Analysis::new(&eq, &prep);
    let code = super::super::solve::stream(mech, &analysis, Some(&built), writer, &mut err)
        .expect("no I/O error");
    assert_eq!(code, EXIT_STOPPED);
    let v: serde_json::Value = serde_json::from_slice(&out).expect("one valid JSON document");
    assert_eq!(v["steps"].as_array().map(Vec::len), Some(1));
    assert_eq!(v["error"]["kind"], "solver_failed");
    assert!(v["error"]["message"].as_str().unwrap().contains("exit"), "{}", v["error"]);
}

/// Splits CSV text into records of fields as RFC 4180 reads them.
fn parse_csv(text: &str) -> Vec<Vec<String>> {
    let (mut records, mut record, mut field) = (Vec::new(), Vec::new(), String::new());
    let mut chars = text.chars().peekable();
    let mut quoted = false;
    while let Some(c) = chars.next() {
        match (quoted, c) {
            (true, '"') if chars.peek() == Some(&'"') => {
                chars.next();
                field.push('"');
            }
            (true, '"') => quoted = false,
            (true, c) => field.push(c),
            (false, '"') => quoted = true,
            (false, ',') => record.push(std::mem::take(&mut field)),
            (false, '\n') => {
                record.push(std::mem::take(&mut field));
                records.push(std::mem::take(&mut record));
            }
            (false, c) => field.push(c),
        }
    }
    records
}

/// The RSSR with hostile names put straight into the model (whatever names validation
/// accepts, the writers must not trust them): a comma, quotes, CR and LF, an escape
/// sequence that would clear the screen, a bidi override and a zero-width space.
fn hostile_rssr() -> crate::model::Mechanism {
    let mut mech = crate::validate::load_file(&example("rssr.toml")).expect("valid").mechanism;
    mech.name = "rssr\u{1b}]0;owned\u{7}".to_owned();
    let moving: Vec<usize> = (0..mech.bodies.len()).filter(|&k| !mech.bodies[k].ground).collect();
    mech.bodies[moving[0]].name = "cr,\"ank\"".to_owned();
    mech.bodies[moving[1]].name = "coup\r\nler\u{1b}[2J".to_owned();
    mech.bodies[moving[2]].name = "rock\u{202e}er\u{200b}".to_owned();
    mech
}

/// Every result of `mech`'s analysis, through `format`.
fn written(mech: &crate::model::Mechanism, format: Format) -> String {
    let eq = crate::generic::Equations::new(mech);
    let prep = eq.prepare();
    let layout = report::layout(mech);
    let mut writer = Writer::begin(Vec::new(), format, mech, "generic", &[]).expect("begun");
    crate::generic::Analysis::new(&eq, &prep)
        .run(|f| writer.step(&report::step_result(mech, &layout, f)))
        .expect("written");
    String::from_utf8(writer.finish(None).expect("finished")).expect("utf-8")
}

#[test]
fn csv_quotes_names_as_rfc_4180_says() {
    let mech = hostile_rssr();
    let records = parse_csv(&written(&mech, Format::Csv));
    let names = report::csv_header(&mech);
    assert_eq!(records[0], names, "the header reads back as the names");
    assert!(records[0].contains(&"coup\r\nler\u{1b}[2J.omega.y".to_owned()));
    assert_eq!(records.len(), 1 + mech.time.count);
    assert!(records.iter().all(|r| r.len() == names.len()), "no column shifts");
}

#[test]
fn the_table_shows_control_bidi_and_zero_width_characters_as_diagnostics_do() {
    let text = written(&hostile_rssr(), Format::Table);
    let bad = |c: char| {
        (c.is_control() && c != '\n') || matches!(c, '\u{202a}'..='\u{202e}' | '\u{200b}')
    };
    assert!(!text.contains(bad), "raw control characters reach the terminal");
    // The replacements are those of the excerpts of a diagnostic.
    for name in ["coup\r\nler\u{1b}[2J", "rock\u{202e}er\u{200b}"] {
        let shown = crate::diag::printable(name);
        assert!(text.contains(shown.as_ref()), "{shown}");
    }
    assert!(text.contains("␛]0;owned␇"), "the title escape is shown, not obeyed");
    let diag = crate::diag::render(
        &[{
            let mut d = crate::diag::Diagnostic::error("x");
            d.span = Some(0..1);
            d
        }],
        Some("a\u{1b}[2J"),
        false,
    );
    assert!(diag.contains("a␛[2J"), "{diag}");
}

#[test]
fn a_csv_header_line_without_special_characters_is_unquoted() {
    let (code, out, _) = mechgen(&[
        "solve",
        example("rssr.toml").to_str().unwrap(),
        "--engine",
        "generic",
        "--format",
        "csv",
    ]);
    assert_eq!(code, EXIT_OK);
    assert!(!out.lines().next().unwrap().contains('"'));
}

#[test]
fn numeric_command_line_values_out_of_range_are_refused_with_status_1() {
    let i = example("rssr.toml");
    let i = i.to_str().unwrap();
    for (args, named) in [
        (vec!["bench", i, "--repeats", "18446744073709551615"], "--repeats"),
        (vec!["bench", i, "--repeats", "18446744073709551616"], "--repeats"),
        (vec!["bench", i, "--repeats", "0"], "--repeats"),
        (vec!["bench", i, "--tolerance", "nan"], "--tolerance"),
        (vec!["bench", i, "--tolerance=-1e-10"], "--tolerance"),
        (vec!["bench", i, "--tolerance", "inf"], "--tolerance"),
        (vec!["chart", i, "-o", "x.svg", "--repeats", "99999999"], "--repeats"),
        (vec!["scaling", "--bodies", "1000000000000"], "--bodies"),
    ] {
        let (code, _, err) = mechgen(&args);
        assert_eq!(code, EXIT_INVALID, "{args:?}: {err}");
        assert!(err.contains(named), "{args:?}: {err}");
    }
}

#[test]
fn a_law_whose_derivatives_overflow_is_refused_by_every_command() {
    let text = std::fs::read_to_string(example("rssr.toml")).expect("the example").replace(
        "law = { start = 0.0, velocity = 146.6, acceleration = 0.0 }",
        "law = { amplitude = 1e10, frequency = 1e150 }",
    );
    let file = super::temp_file("sinusoid_overflow.toml", &text);
    let f = file.to_str().unwrap();
    for args in [vec!["check", f], vec!["generate", f], vec!["solve", f, "--engine", "generic"]] {
        let (code, _, err) = mechgen(&args);
        assert_eq!(code, EXIT_INVALID, "{args:?}: {err}");
        assert!(err.contains("driver \"motor\""), "{args:?}: {err}");
    }
}
