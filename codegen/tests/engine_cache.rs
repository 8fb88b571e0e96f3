//! The generated engine's cache and build, through the `mechgen` binary: entries are
//! verified before they run, what is broken is rebuilt with a note, a build that cannot
//! succeed exits with status 3, and no solver outlives mechgen. Everything here runs offline:
//! download failures are played by a stand-in for cargo.
#![cfg(unix)]

use std::io::{BufRead, BufReader};
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

/// The workspace's examples.
fn example(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples").join(name)
}

/// A scratch directory of this test binary, emptied.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("engine-cache").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The cache that tests share when each damages only its own mechanism's entry: the runtime
/// is compiled once for all of them (and kept between runs).
fn shared_cache() -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join("engine-cache/shared")
}

/// `mechgen ARGS` with `MECHGEN_CACHE=cache` and the extra environment `env`.
fn mechgen(cache: &Path, args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_mechgen"));
    cmd.args(args).env("MECHGEN_CACHE", cache).stdin(Stdio::null());
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().unwrap()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// `solve FILE --engine generated --format csv`, which must succeed: (stdout, stderr).
fn solve(cache: &Path, file: &Path) -> (String, String) {
    let file = file.to_str().unwrap();
    let out = mechgen(cache, &["solve", file, "--engine", "generated", "--format", "csv"], &[]);
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    (stdout, stderr)
}

/// The cache entry whose module defines the solver type `ty` (every example names its
/// own), in a cache that holds one entry of it.
fn entry_of(cache: &Path, ty: &str) -> PathBuf {
    let needle = format!("pub struct {ty};");
    std::fs::read_dir(cache)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|dir| {
            std::fs::read_to_string(dir.join("src/mechanism.rs")).is_ok_and(|t| t.contains(&needle))
        })
        .unwrap_or_else(|| panic!("no entry for {ty} in {}", cache.display()))
}

/// The cache entry `mechgen solve --engine generated file` uses, as its log says (found by
/// the description index, verified, or built). The shared
/// cache may hold older entries of the same mechanism (every change to the generator or the
/// driver changes the keys), which a search by type could find instead.
fn entry_used(cache: &Path, file: &Path) -> PathBuf {
    let args = ["solve", file.to_str().unwrap(), "--engine", "generated", "--format", "csv"];
    let out = mechgen(cache, &args, &[("MECHGEN_LOG", "info")]);
    let stderr = text(&out.stderr);
    stderr
        .lines()
        .find_map(|l| {
            let rest = l
                .split_once("description index hit: ")
                .or_else(|| l.split_once("cache hit: "))
                .or_else(|| l.split_once("cache miss: building "))?
                .1;
            Some(PathBuf::from(
                rest.trim_end_matches(" (verified)").trim_end_matches(" (no generation)"),
            ))
        })
        .unwrap_or_else(|| panic!("no cache entry logged: {stderr}"))
}

/// Removes every entry of `ty`, so that the next solve builds it.
fn forget(cache: &Path, ty: &str) {
    let Ok(entries) = std::fs::read_dir(cache) else { return };
    let needle = format!("pub struct {ty};");
    for dir in entries.map(|e| e.unwrap().path()) {
        if std::fs::read_to_string(dir.join("src/mechanism.rs")).is_ok_and(|t| t.contains(&needle))
        {
            std::fs::remove_dir_all(&dir).unwrap();
        }
    }
}

/// An executable shell script at `path`.
fn script(path: &Path, body: &str) {
    std::fs::write(path, format!("#!/bin/sh\n{body}\n")).unwrap();
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o755)).unwrap();
}

/// The cargo that runs these tests.
fn real_cargo() -> String {
    std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned())
}

#[test]
fn a_garbage_binary_in_an_entry_is_rebuilt() {
    let cache = shared_cache();
    let file = example("revolute_joint.toml");
    let (expected, _) = solve(&cache, &file);
    let entry = entry_used(&cache, &file);
    std::fs::write(entry.join("solver"), "garbage").unwrap();
    let (stdout, stderr) = solve(&cache, &file);
    assert!(stderr.contains("does not match its recorded hash; rebuilding it"), "{stderr}");
    assert_eq!(stdout, expected);
    // Unchanged bytes that cannot be executed: the hash matches, running it fails.
    std::fs::set_permissions(entry.join("solver"), std::fs::Permissions::from_mode(0o644)).unwrap();
    let (stdout, stderr) = solve(&cache, &file);
    assert!(stderr.contains("does not run"), "{stderr}");
    assert_eq!(stdout, expected);
    let (_, stderr) = solve(&cache, &file);
    assert!(!stderr.contains("note:"), "a repaired entry is used as it is: {stderr}");
}

#[test]
fn another_mechanisms_binary_in_an_entry_is_detected_and_rebuilt() {
    let cache = shared_cache();
    let (_, _) = solve(&cache, &example("spherical_joint.toml"));
    let (expected, _) = solve(&cache, &example("prismatic_joint.toml"));
    let other = entry_used(&cache, &example("spherical_joint.toml"));
    let entry = entry_used(&cache, &example("prismatic_joint.toml"));
    // The binary and its record, both copied: the record binds the binary to its own entry.
    for name in ["solver", "solver.hash"] {
        std::fs::copy(other.join(name), entry.join(name)).unwrap();
    }
    let (stdout, stderr) = solve(&cache, &example("prismatic_joint.toml"));
    assert!(stderr.contains("does not match its recorded hash; rebuilding it"), "{stderr}");
    assert_eq!(stdout, expected, "the prismatic joint's results, not the spherical joint's");
}

#[test]
fn a_corrupt_lock_file_is_rewritten_with_a_note() {
    let cache = shared_cache();
    let file = example("screw_joint.toml");
    let (expected, _) = solve(&cache, &file);
    let entry = entry_used(&cache, &file);
    std::fs::write(entry.join("Cargo.lock"), "garbage [[[").unwrap();
    // A build is needed for the lock file to matter.
    std::fs::remove_file(entry.join("solver")).unwrap();
    let (stdout, stderr) = solve(&cache, &file);
    assert!(stderr.contains("Cargo.lock was corrupt; rewrote it"), "{stderr}");
    assert_eq!(stdout, expected);
    let lock = std::fs::read_to_string(entry.join("Cargo.lock")).unwrap();
    assert!(lock.contains("name = \"libm\""), "{lock}");
}

#[test]
fn a_corrupt_runtime_build_is_cleaned_with_a_note() {
    let cache = scratch("corrupt-rlib");
    let (_, _) = solve(&cache, &example("rotation_about_x.toml"));
    let deps = cache.join("target/release/deps");
    let mut damaged = 0;
    for e in std::fs::read_dir(&deps).unwrap() {
        let p = e.unwrap().path();
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        if name.starts_with("libruntime-") && (name.ends_with(".rlib") || name.ends_with(".rmeta"))
        {
            std::fs::write(&p, "garbage").unwrap();
            damaged += 1;
        }
    }
    assert!(damaged > 0, "the runtime's build is in {}", deps.display());
    let (expected, _) =
        solve(&scratch("corrupt-rlib-reference"), &example("rotation_about_y.toml"));
    let (stdout, stderr) = solve(&cache, &example("rotation_about_y.toml"));
    assert!(stderr.contains("cleaning the cache's build of the runtime"), "{stderr}");
    assert_eq!(stdout, expected);
}

#[test]
fn an_empty_mechgen_cache_is_refused() {
    let file = example("revolute_joint.toml");
    let file = file.to_str().unwrap();
    for engine in [&["--engine", "generated"][..], &[]] {
        let args = [&["solve", file][..], engine].concat();
        let out = mechgen(Path::new(""), &args, &[]);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(stderr.contains("MECHGEN_CACHE is set but empty"), "{stderr}");
    }
    let out = mechgen(Path::new(""), &["solve", file, "--engine", "generic"], &[]);
    assert_eq!(out.status.code(), Some(0), "the generic engine needs no cache");
}

#[test]
fn a_build_that_fails_exits_3_and_the_default_engine_falls_back() {
    let dir = scratch("broken-build");
    let cargo = dir.join("cargo");
    script(&cargo, "echo 'error: could not compile `mechgen-gen` (stand-in)' >&2\nexit 101");
    let cargo = cargo.to_str().unwrap();
    let cache = dir.join("cache");
    let file = example("revolute_joint.toml");
    let file = file.to_str().unwrap();
    for args in [
        &["solve", file, "--engine", "generated"][..],
        &["compare", file],
        &["bench", file, "--engine", "generated", "--repeats", "1"],
    ] {
        let out = mechgen(&cache, args, &[("CARGO", cargo)]);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(3), "{args:?}: {stderr}");
        assert!(stderr.contains("the generated solver could not be built"), "{stderr}");
        assert!(stderr.contains("could not compile `mechgen-gen` (stand-in)"), "{stderr}");
        assert!(stderr.contains("fix: "), "{stderr}");
    }
    let out = mechgen(
        &cache,
        &["solve", file, "--engine", "generated", "--format", "json"],
        &[("CARGO", cargo)],
    );
    assert_eq!(out.status.code(), Some(3));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["error"]["kind"], "build_failed", "{v}");
    let out = mechgen(&cache, &["solve", file], &[("CARGO", cargo)]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(
        stderr
            .contains("warning: using the generic engine: the generated solver could not be built"),
        "{stderr}"
    );
    assert!(stderr.contains("fix: "), "{stderr}");
    assert!(text(&out.stdout).contains("(generic engine)"));
}

#[test]
fn missing_crates_are_fetched_then_built_offline() {
    let dir = scratch("fetch");
    let log = dir.join("log");
    let marker = dir.join("fetched");
    // Plays an empty registry: an offline build fails until `fetch` has run; the rest is
    // the real cargo (whose registry does hold the crates).
    let cargo = dir.join("cargo");
    script(
        &cargo,
        &format!(
            "echo \"$1\" >> '{log}'\n\
             if [ \"$1\" = fetch ]; then touch '{marker}'; exit 0; fi\n\
             if [ \"$1\" = build ] && [ ! -e '{marker}' ]; then\n\
             echo 'error: failed to download `libm v0.2.16`' >&2\n\
             echo 'Caused by: attempting to make an HTTP request, but --offline was specified' >&2\n\
             exit 101\nfi\nexec '{}' \"$@\"",
            real_cargo(),
            log = log.display(),
            marker = marker.display()
        ),
    );
    let cache = shared_cache();
    forget(&cache, "TranslationY");
    let file = example("translation_y.toml");
    let out = mechgen(
        &cache,
        &["solve", file.to_str().unwrap(), "--engine", "generated"],
        &[("CARGO", cargo.to_str().unwrap())],
    );
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(text(&out.stdout).contains("(generated engine)"));
    assert!(stderr.contains("fetching the crates the generated solver needs (libm)"), "{stderr}");
    let calls = std::fs::read_to_string(&log).unwrap();
    assert_eq!(calls.lines().collect::<Vec<_>>(), ["build", "fetch", "build"]);
}

#[test]
fn a_failed_download_exits_3_saying_how_to_fetch() {
    let dir = scratch("no-network");
    let cargo = dir.join("cargo");
    script(
        &cargo,
        "if [ \"$1\" = fetch ]; then echo 'error: failed to get `libm` (no network)' >&2; \
         exit 101; fi\n\
         echo 'error: attempting to make an HTTP request, but --offline was specified' >&2\n\
         exit 101",
    );
    let file = example("revolute_joint.toml");
    let out = mechgen(
        &dir.join("cache"),
        &["solve", file.to_str().unwrap(), "--engine", "generated"],
        &[("CARGO", cargo.to_str().unwrap())],
    );
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    assert!(stderr.contains("failed to get `libm` (no network)"), "{stderr}");
    assert!(stderr.contains("run `cargo fetch` once in a mechgen checkout"), "{stderr}");
}

#[test]
fn a_copied_binary_builds_from_its_embedded_runtime() {
    // mechgen copied elsewhere and run from elsewhere: the solver's crate depends on the
    // runtime copy inside the cache, never on the checkout's `runtime/`.
    let dir = scratch("installed");
    let binary = dir.join("mechgen");
    std::fs::copy(env!("CARGO_BIN_EXE_mechgen"), &binary).unwrap();
    let cache = dir.join("cache");
    let out = Command::new(&binary)
        .args(["solve", example("translation_x.toml").to_str().unwrap(), "--engine", "generated"])
        .env("MECHGEN_CACHE", &cache)
        .current_dir(&dir)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let manifest =
        std::fs::read_to_string(entry_of(&cache, "TranslationX").join("Cargo.toml")).unwrap();
    let checkout = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
    assert!(manifest.contains("path = \"../runtime-"), "{manifest}");
    assert!(!manifest.contains(&checkout.display().to_string()), "{manifest}");
}

/// The processes whose command line mentions `needle` (Linux's /proc).
#[cfg(target_os = "linux")]
fn processes_mentioning(needle: &str) -> Vec<String> {
    std::fs::read_dir("/proc")
        .unwrap()
        .filter_map(|e| {
            let pid = e.ok()?.file_name().into_string().ok()?;
            pid.parse::<u32>().ok()?;
            let cmdline = std::fs::read(format!("/proc/{pid}/cmdline")).ok()?;
            let cmdline = text(&cmdline).replace('\0', " ");
            cmdline.contains(needle).then(|| format!("{pid}: {cmdline}"))
        })
        .collect()
}

#[cfg(target_os = "linux")]
#[test]
fn a_closed_pipe_ends_mechgen_and_its_solver_quietly() {
    let dir = scratch("pipe");
    // The R-S-S-R over 100,000 time points: its solver would compute for a while.
    let long = std::fs::read_to_string(example("rssr.toml"))
        .unwrap()
        .replace("step = 0.0035717333", "step = 4e-7")
        .replace("name = \"rssr\"", "name = \"rssr_pipe\"");
    let file = dir.join("rssr_long.toml");
    std::fs::write(&file, long).unwrap();
    let cache = shared_cache();
    for engine in ["generated", "generic"] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_mechgen"))
            .args(["solve", file.to_str().unwrap(), "--engine", engine, "--format", "csv"])
            .env("MECHGEN_CACHE", &cache)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // `| head -3`: three lines read, then the pipe closed.
        let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
        for _ in 0..3 {
            lines.next().unwrap().unwrap();
        }
        drop(lines);
        let out = child.wait_with_output().unwrap();
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{engine}: {stderr}");
        assert!(stderr.is_empty(), "{engine}: a closed pipe is not reported: {stderr}");
    }
    // Other tests run in the same cache: only this mechanism's entry is looked for.
    let entry = entry_used(&cache, &file);
    let solvers = processes_mentioning(&entry.display().to_string());
    assert!(solvers.is_empty(), "solvers outlived mechgen: {solvers:?}");
}
