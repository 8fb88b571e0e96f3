//! Memory stays flat with the number of time points (README, Limits): `generate` (whose pivot
//! planning walks the motion) on a grid of 10⁶ points and the generic solve on 2·10⁵ points
//! take no more heap than on 10⁴ points, measured by the counting allocator (a test target of
//! its own for that reason). Each takes about 3 to 7 s at the test profile's opt-level 2; the
//! generic solve of 10⁶ points would take 15 s.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::time::Instant;

use counting::peak_of;

mod counting;

/// A shipped example with the fewest unknowns that still has a pivot order to plan (a bar on a
/// spherical joint turned about global y: 2 unknowns once its closed forms are substituted):
/// among the cheapest to solve at every one of 10⁶ points.
const EXAMPLE: &str = "examples/spherical_joint.toml";

/// Slack allowed between the peaks at 10⁴ points and at the larger grid. Anything kept per time
/// point costs at least 8 bytes a point, so it would show as 1.6 MB or more at 2·10⁵ points;
/// the two runs differ only in file names and numbers printed (a few bytes).
const SLACK: usize = 256 << 10;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The example with its grid changed to `count` points over the same time span, written to a
/// file of its own in the target directory, named by `tag` as well: the tests run in parallel,
/// and one writing a file another is reading made the reader see it empty.
fn with_points(count: usize, tag: &str) -> PathBuf {
    let text = std::fs::read_to_string(root().join(EXAMPLE)).unwrap();
    let mut doc: toml::Table = text.parse().unwrap();
    let time = doc["time"].as_table_mut().unwrap();
    let (start, end) = (time["start"].as_float().unwrap(), time["end"].as_float().unwrap());
    time.remove("step");
    time.insert("steps".into(), toml::Value::Integer(count as i64 - 1));
    assert!(end > start);
    let dir = root().join("target").join("memory-test");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("spherical_{tag}_{count}.toml"));
    std::fs::write(&path, toml::to_string(&doc).unwrap()).unwrap();
    path
}

/// Runs `mechgen ARGS` in process, its standard output discarded; returns the exit status, the
/// peak extra heap and the seconds taken.
fn measured(args: &[&str]) -> (i32, usize, f64) {
    let mut argv: Vec<OsString> = vec!["mechgen".into()];
    argv.extend(args.iter().map(OsString::from));
    let started = Instant::now();
    let (status, peak) = peak_of(|| {
        let mut err = Vec::new();
        let status = codegen::cli::run(argv, &mut std::io::sink(), &mut err);
        assert!(status == 0, "{args:?}: {}", String::from_utf8_lossy(&err));
        status
    });
    (status, peak, started.elapsed().as_secs_f64())
}

/// `mechgen ARGS` (with FILE replaced by the example at each grid size) takes no more heap at
/// `count` points than at 10⁴.
fn flat(args: &[&str], count: usize) {
    let (small, large) = (with_points(10_000, args[0]), with_points(count, args[0]));
    let run = |file: &Path| {
        let file = file.to_str().unwrap();
        let args: Vec<&str> = args.iter().map(|&a| if a == "FILE" { file } else { a }).collect();
        measured(&args)
    };
    let (_, peak_small, _) = run(&small);
    let (_, peak_large, secs) = run(&large);
    eprintln!(
        "{args:?}: peak {peak_small} B at 10⁴ points, {peak_large} B at {count} ({secs:.2} s)"
    );
    assert!(
        peak_large <= peak_small + SLACK,
        "{args:?}: {peak_large} bytes at {count} points against {peak_small} at 10⁴"
    );
}

#[test]
fn generate_takes_the_same_memory_for_any_grid() {
    let out = root().join("target").join("memory-test").join("spherical.rs");
    flat(&["generate", "FILE", "-o", out.to_str().unwrap()], 1_000_000);
}

#[test]
fn the_generic_solve_takes_the_same_memory_for_any_grid() {
    flat(&["solve", "FILE", "--engine", "generic", "--format", "csv"], 200_000);
}
