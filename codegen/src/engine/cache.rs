//! The cache of built solvers: one entry per generated crate, verified before it is run.
//!
//! Layout under the cache directory:
//! - `runtime-HASH/`: the `runtime` crate's sources as embedded in mechgen when it was built
//!   (so building needs no checkout), HASH naming their content;
//! - `KEY/`: one generated crate (manifest, lock file, `src/`), its binary `solver` and
//!   `solver.hash`, the hash of the key and the binary's bytes;
//! - `target/`: cargo's shared build directory (a build cache only: entries keep their own
//!   copy of their binary).
//!
//! - `described/DESCRIPTION`: the description index, one small JSON file per description
//!   and setting that names the KEY of its module (see [`Described`]);
//!
//! KEY hashes everything that decides the binary: the generated module, the driver and the
//! step control, the float type, the manifest, the lock file, the runtime's sources, the
//! compiler flags the cache chooses for this processor ([`build_flags`]) and mechgen's
//! version. An entry is used only when its recorded hash matches its binary and
//! the binary, asked for its key, prints KEY; anything else is rebuilt.
//!
//! DESCRIPTION hashes what decides the module before it is generated: the validated model
//! (every number of the description, its own `[time]` grid and solver options), the float
//! type and mechgen's [`fingerprint`]. A run whose DESCRIPTION is indexed and whose KEY
//! verifies skips generation; any doubt (no index file, an unreadable one, an entry that does
//! not verify) generates the module as before, and the build rewrites the index.

use std::ffi::OsString;
use std::hash::{DefaultHasher, Hasher};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;
use std::sync::atomic::{AtomicUsize, Ordering};

use super::{BuildFailure, ConfigError, EngineError, SolverProcess};

mod embedded {
    include!(concat!(env!("OUT_DIR"), "/embedded.rs"));
}

/// Changes whenever the way entries are built changes (cargo's arguments, the layout), so
/// that entries of an older recipe are never taken for current ones.
const RECIPE: &str = "mechgen-cache 2: cargo build --release --offline; solver + solver.hash";

/// A 64-bit hash of `parts`, each prefixed by its length, as 16 hex digits. It detects
/// accidents (a stale, truncated or swapped file), not attacks: whoever can write the cache
/// can run code as the user anyway.
fn hash(parts: &[&[u8]]) -> String {
    let mut h = DefaultHasher::new();
    for p in parts {
        h.write_usize(p.len());
        h.write(p);
    }
    format!("{:016x}", h.finish())
}

/// The hash of the embedded runtime sources and their manifest.
fn runtime_hash() -> &'static str {
    static HASH: OnceLock<String> = OnceLock::new();
    HASH.get_or_init(|| {
        let mut parts: Vec<&[u8]> = vec![embedded::RUNTIME_MANIFEST.as_bytes()];
        for (path, text) in embedded::RUNTIME_FILES {
            parts.push(path.as_bytes());
            parts.push(text.as_bytes());
        }
        hash(&parts)
    })
}

/// What identifies this mechgen as a generator: its version, the hash of its own sources
/// (the generator, the driver), manifest and lock file taken when it was built, the
/// runtime's sources and the cache's recipe. Two binaries with the same fingerprint generate
/// the same module from the same model.
pub fn fingerprint() -> &'static str {
    static FINGERPRINT: OnceLock<String> = OnceLock::new();
    FINGERPRINT.get_or_init(|| {
        hash(&[
            RECIPE.as_bytes(),
            env!("CARGO_PKG_VERSION").as_bytes(),
            embedded::GENERATOR_HASH.as_bytes(),
            runtime_hash().as_bytes(),
            build_flags().unwrap_or_default().as_bytes(),
        ])
    })
}

/// The compiler flags the cache builds solvers with, unless the user set their own through
/// `RUSTFLAGS` or `CARGO_ENCODED_RUSTFLAGS` (which then win): the instruction set of this
/// machine's processor family where it is one of the x86-64 levels above the baseline. They
/// are passed as `build.rustflags`, added to any the user's cargo configuration sets.
///
/// A solver binary is built here and run here only, so it may use every instruction this
/// processor has. `x86-64-v3` (AVX2, FMA, BMI1/2 and the rest of the level) makes the R-S-S-R
/// step about 9 % faster than the baseline x86-64 (150 against 165 ns, BENCHMARKS.md) and
/// runs on every x86-64 processor since about 2015 that has those features; the level, not
/// `native`, is chosen so that the flags name a documented set the detection below proves
/// present. The flags are part of every key and of the [`fingerprint`], so that a cache
/// directory moved to a machine without them builds its solvers again rather than running
/// instructions the processor lacks. Elsewhere the baseline is kept.
fn build_flags() -> Option<&'static str> {
    if std::env::var_os("RUSTFLAGS").is_some()
        || std::env::var_os("CARGO_ENCODED_RUSTFLAGS").is_some()
    {
        return None;
    }
    #[cfg(target_arch = "x86_64")]
    {
        // Every feature of the level (the macro takes literal names only).
        macro_rules! detected {
            ($($feature:tt),*) => { true $(&& std::arch::is_x86_feature_detected!($feature))* };
        }
        let v3 = detected!(
            "avx",
            "avx2",
            "bmi1",
            "bmi2",
            "f16c",
            "fma",
            "lzcnt",
            "movbe",
            "xsave",
            "cmpxchg16b",
            "popcnt",
            "sse3",
            "ssse3",
            "sse4.1",
            "sse4.2"
        );
        if v3 {
            return Some("-Ctarget-cpu=x86-64-v3");
        }
    }
    None
}

/// The index entry of one description: the cache entry of its module and what a run needs
/// to know of the module without generating it.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub(super) struct Described {
    /// The KEY of the module's entry.
    pub(super) key: String,
    /// Size of the reduced system.
    pub(super) unknowns: usize,
    /// The equations left out as redundant.
    pub(super) removed: Vec<String>,
    /// The driver indices of the module's input drivers.
    pub(super) inputs: Vec<usize>,
}

/// The description index of the cache `cache`, for one description key.
pub(super) struct Index {
    path: PathBuf,
    cache: PathBuf,
}

impl Index {
    /// The index file of the description whose canonical text is `model` (the validated
    /// model, debug-printed: floats in shortest round-trip form), generated in `real` by the
    /// mechgen of fingerprint `fingerprint`.
    pub(super) fn new(cache: PathBuf, model: &str, real: &str, fingerprint: &str) -> Index {
        let key = hash(&[
            b"mechgen-described 1",
            fingerprint.as_bytes(),
            real.as_bytes(),
            model.as_bytes(),
        ]);
        Index { path: cache.join("described").join(key), cache }
    }

    /// The indexed entry, when the index names one and its solver verifies (its recorded
    /// hash and its answer to `key`); `None` otherwise, and the caller generates.
    pub(super) fn lookup(&self) -> Option<(Described, PathBuf)> {
        let text = std::fs::read(&self.path).ok()?;
        let Ok(described) = serde_json::from_slice::<Described>(&text) else {
            log::warn!("description index {} unreadable; generating", self.path.display());
            return None;
        };
        // A key is 16 hex digits: anything else cannot name an entry inside the cache.
        if described.key.len() != 16 || !described.key.bytes().all(|b| b.is_ascii_hexdigit()) {
            return None;
        }
        let recipe =
            Recipe { cache: self.cache.clone(), key: described.key.clone(), files: Vec::new() };
        match recipe.defect() {
            None => {
                log::info!("description index hit: {} (no generation)", recipe.dir().display());
                Some((described, recipe.binary()))
            }
            Some(why) => {
                log::info!("description index names an unusable entry ({why}); generating");
                None
            }
        }
    }

    /// Removes this description's index file (tests clean up after themselves).
    #[cfg(test)]
    pub(super) fn forget(&self) {
        let _ = std::fs::remove_file(&self.path);
    }

    /// Records `described` for this description (a failure to write only costs the next
    /// run a generation).
    pub(super) fn record(&self, described: &Described) {
        let text = serde_json::to_vec(described).expect("plain data serialises");
        if let Err(e) = write_if_changed(&self.path, &text) {
            log::warn!("cannot write the description index {}: {e}", self.path.display());
        }
    }
}

/// Where built solvers are cached: `$MECHGEN_CACHE`; else `target/mechgen-cache` in the
/// checkout mechgen was built from, while that checkout exists; else `mechgen` in the user's
/// cache directory (`$XDG_CACHE_HOME`, `~/.cache`, `~/Library/Caches` or `%LOCALAPPDATA%`).
///
/// # Errors
/// [`EngineError::Config`] when `MECHGEN_CACHE` is set but empty, or when no directory can
/// be chosen.
pub fn cache_dir() -> Result<PathBuf, EngineError> {
    choose_cache_dir(&crate::sync::workspace_root(), |name| std::env::var_os(name))
}

/// [`cache_dir`] for a checkout at `root` and the environment `var`.
pub(super) fn choose_cache_dir(
    root: &Path,
    var: impl Fn(&str) -> Option<OsString>,
) -> Result<PathBuf, EngineError> {
    if let Some(dir) = var("MECHGEN_CACHE") {
        if dir.is_empty() {
            return Err(ConfigError::EmptyCache.into());
        }
        return std::path::absolute(&dir)
            .map_err(|source| ConfigError::BadCache { dir: dir.into(), source }.into());
    }
    // The checkout is recognised by its own files, so that a moved or deleted one is never
    // recreated by the cache's `create_dir_all`.
    if root.join("Cargo.toml").is_file() && root.join("runtime/Cargo.toml").is_file() {
        return Ok(root.join("target/mechgen-cache"));
    }
    let absolute = |name: &str| var(name).map(PathBuf::from).filter(|p| p.is_absolute());
    let user = if cfg!(windows) {
        absolute("LOCALAPPDATA")
    } else if cfg!(target_os = "macos") {
        absolute("HOME").map(|h| h.join("Library/Caches"))
    } else {
        absolute("XDG_CACHE_HOME").or_else(|| absolute("HOME").map(|h| h.join(".cache")))
    };
    user.map(|dir| dir.join("mechgen"))
        .ok_or_else(|| ConfigError::NoCacheDir { checkout: root.to_path_buf() }.into())
}

/// The driver program of every generated solver (`src/driver.rs`; see its module docs).
const DRIVER: &str = include_str!("driver.rs");

/// The generated crate's `main.rs`: the driver and the modules it reads.
const MAIN: &str = "//! A generated solver (written by mechgen; do not edit): see `driver.rs`.\n\n\
                    mod config;\nmod driver;\nmod key;\nmod mechanism;\n\n\
                    fn main() {\n    driver::main();\n}\n";

/// What the driver needs to know of a module beyond its type names.
#[derive(Clone, Copy, Debug)]
pub(super) struct Shape {
    /// Whether it has input drivers.
    pub(super) inputs: bool,
    /// Whether it left rows out as redundant (`dropped_residuals`).
    pub(super) dropped: bool,
}

/// The generated crate's `config.rs`: what the driver reads about the module, the
/// mechanism's type `type_name`, the floating-point type `real`, and its [`Shape`].
fn config(type_name: &str, real: &str, shape: Shape) -> String {
    let inputs = shape.inputs;
    let head = format!(
        "//! What the driver reads about the generated module (written by mechgen).\n\n\
         /// The floating-point type the module was generated in.\n\
         pub type Real = {real};\n\n\
         /// The generated mechanism.\n\
         pub use crate::mechanism::{type_name} as Generated;\n\n\
         use crate::mechanism::{{BODIES, N}};\n\n\
         /// The inputs of every input driver at one instant, `[s, ṡ, s̈]` each.\n\
         type Inputs = [[Real; 3]; INPUTS];\n\n"
    );
    let body = if inputs {
        "/// The number of input drivers.\n\
         pub const INPUTS: usize = crate::mechanism::INPUTS;\n\n\
         /// The mechanism standing at `t` with inputs `u`.\n\
         pub fn generated(t: Real, u: &Inputs) -> Generated {\n    \
             Generated::new(t, &crate::mechanism::Inputs::from_array(*u))\n}\n\n\
         /// Sets the inputs to `u0` at `t0` and `u1` at `t1`.\n\
         pub fn aim(m: &mut Generated, t0: Real, u0: &Inputs, t1: Real, u1: &Inputs) {\n    \
             runtime::input::Driven::segment_mut(m).set(t0, *u0, t1, *u1);\n}\n\n\
         /// The module's `expand` at the inputs of `m` at `t`.\n\
         pub fn expand(m: &Generated, q: &[Real; N], qd: &[Real; N], qdd: &[Real; N], t: Real, \
         out: &mut [[[Real; 7]; 3]; BODIES]) {\n    \
             crate::mechanism::expand(q, qd, qdd, t, &m.inputs(t), out);\n}\n"
    } else {
        "/// The number of input drivers: none.\n\
         pub const INPUTS: usize = 0;\n\n\
         /// The mechanism (it has no inputs).\n\
         pub fn generated(_t: Real, _u: &Inputs) -> Generated {\n    \
             Generated\n}\n\n\
         /// Sets the inputs: there are none.\n\
         pub fn aim(_m: &mut Generated, _t0: Real, _u0: &Inputs, _t1: Real, _u1: &Inputs) {}\n\n\
         /// The module's `expand`.\n\
         pub fn expand(_m: &Generated, q: &[Real; N], qd: &[Real; N], qdd: &[Real; N], t: Real, \
         out: &mut [[[Real; 7]; 3]; BODIES]) {\n    \
             crate::mechanism::expand(q, qd, qdd, t, out);\n}\n"
    };
    head + body + &dropped(shape)
}

/// The part of `config.rs` about the rows the module left out as redundant: their number, the
/// balanced-unit factors of the rows and `dropped`, their residuals.
fn dropped(shape: Shape) -> String {
    let call = if shape.inputs {
        "crate::mechanism::dropped_residuals(q, qd, qdd, t, &m.inputs(t), out);"
    } else {
        "crate::mechanism::dropped_residuals(q, qd, qdd, t, out);"
    };
    let m = if shape.inputs { "m" } else { "_m" };
    if shape.dropped {
        format!(
            "\n/// The number of rows the module left out as redundant.\n\
             pub const DROPPED: usize = crate::mechanism::DROPPED;\n\n\
             /// Their equations.\n\
             pub const DROPPED_EQUATIONS: [&str; DROPPED] = crate::mechanism::DROPPED_EQUATIONS;\n\n\
             /// The balanced-unit factors of the kept rows.\n\
             pub const ROW_FACTORS: [Real; N] = crate::mechanism::ROW_FACTORS;\n\n\
             /// The balanced-unit factors of the rows left out.\n\
             pub const DROPPED_ROW_FACTORS: [Real; DROPPED] = crate::mechanism::DROPPED_ROW_FACTORS;\n\n\
             /// The residuals `[Φ_i, Φ̇_i, Φ̈_i]` of the rows left out.\n\
             pub fn dropped({m}: &Generated, q: &[Real; N], qd: &[Real; N], qdd: &[Real; N], t: Real, \
             out: &mut [[Real; 3]; DROPPED]) {{\n    {call}\n}}\n"
        )
    } else {
        "\n/// The number of rows the module left out as redundant: none.\n\
         pub const DROPPED: usize = 0;\n\n\
         /// Their equations: none.\n\
         pub const DROPPED_EQUATIONS: [&str; DROPPED] = [];\n\n\
         /// The balanced-unit factors of the kept rows (unused without rows left out).\n\
         pub const ROW_FACTORS: [Real; N] = [1.0; N];\n\n\
         /// The balanced-unit factors of the rows left out: none.\n\
         pub const DROPPED_ROW_FACTORS: [Real; DROPPED] = [];\n\n\
         /// The residuals of the rows left out: there are none.\n\
         pub fn dropped(_m: &Generated, _q: &[Real; N], _qd: &[Real; N], _qdd: &[Real; N], _t: Real, \
         _out: &mut [[Real; 3]; DROPPED]) {}\n"
            .to_owned()
    }
}

/// How to build one generated crate, and where its entry lies.
pub(super) struct Recipe {
    cache: PathBuf,
    key: String,
    /// The entry's source files (relative path, text), `src/key.rs` and the lock excepted.
    files: Vec<(&'static str, String)>,
}

impl std::fmt::Debug for Recipe {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recipe").field("cache", &self.cache).field("key", &self.key).finish()
    }
}

impl Recipe {
    /// The recipe of the crate made of `module` (whose mechanism is the type `type_name`, in
    /// floating-point type `real`) and the driver, in the cache `cache`.
    pub(super) fn new(
        cache: PathBuf,
        module: &str,
        type_name: &str,
        real: &str,
        shape: Shape,
    ) -> Recipe {
        let config = config(type_name, real, shape);
        let manifest = |package: &str| {
            format!(
                "[package]\nname = \"{package}\"\nversion = \"0.0.0\"\nedition = \"2024\"\n\
                 publish = false\n\n[dependencies]\nruntime = {{ path = \"../runtime-{}\" }}\n\n\
                 [profile.release]\ncodegen-units = 1\npanic = \"abort\"\n\n[workspace]\n",
                runtime_hash()
            )
        };
        let key = hash(&[
            RECIPE.as_bytes(),
            env!("CARGO_PKG_VERSION").as_bytes(),
            real.as_bytes(),
            module.as_bytes(),
            DRIVER.as_bytes(),
            MAIN.as_bytes(),
            config.as_bytes(),
            manifest("").as_bytes(),
            embedded::WORKSPACE_LOCK.as_bytes(),
            runtime_hash().as_bytes(),
            build_flags().unwrap_or_default().as_bytes(),
        ]);
        let files = vec![
            ("Cargo.toml", manifest(&format!("mechgen-gen-{key}"))),
            ("src/main.rs", MAIN.to_owned()),
            ("src/driver.rs", DRIVER.to_owned()),
            ("src/config.rs", config),
            ("src/mechanism.rs", module.to_owned()),
            (
                "src/key.rs",
                format!(
                    "//! The key of the cache entry this solver was built for.\n\n\
                     /// Printed by `key`, so that mechgen can tell this binary is the entry's.\n\
                     pub const KEY: &str = \"{key}\";\n"
                ),
            ),
        ];
        Recipe { cache, key, files }
    }

    fn dir(&self) -> PathBuf {
        self.cache.join(&self.key)
    }

    /// The entry's KEY.
    pub(super) fn key(&self) -> &str {
        &self.key
    }

    /// The entry's copy of its binary: the program that is run.
    pub(super) fn binary(&self) -> PathBuf {
        self.dir().join(format!("solver{}", std::env::consts::EXE_SUFFIX))
    }

    fn record(&self) -> PathBuf {
        self.dir().join("solver.hash")
    }

    fn package(&self) -> String {
        format!("mechgen-gen-{}", self.key)
    }

    /// What cargo builds, before it is copied into the entry.
    fn target_binary(&self) -> PathBuf {
        self.cache.join("target/release").join(format!(
            "{}{}",
            self.package(),
            std::env::consts::EXE_SUFFIX
        ))
    }

    /// The record of a binary: its bytes bound to this entry's key, so that neither another
    /// entry's binary nor its record passes here.
    fn binary_hash(&self, bytes: &[u8]) -> String {
        hash(&[self.key.as_bytes(), bytes])
    }

    /// Why the entry cannot be used as it is: `None` when it is verified, `Some("")` when it
    /// was never built, else the reason.
    fn defect(&self) -> Option<String> {
        let binary = self.binary();
        let Ok(bytes) = std::fs::read(&binary) else {
            return Some(String::new());
        };
        let recorded = std::fs::read_to_string(self.record()).unwrap_or_default();
        if recorded.trim() != self.binary_hash(&bytes) {
            return Some(format!(
                "the cached solver {} does not match its recorded hash",
                binary.display()
            ));
        }
        match self.probe() {
            Ok(()) => None,
            Err(why) => Some(format!("the cached solver {} {why}", binary.display())),
        }
    }

    /// Runs the binary in `key` mode and checks that it names this entry.
    fn probe(&self) -> Result<(), String> {
        let child = Command::new(self.binary())
            .arg("key")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|e| format!("does not run ({e})"))?;
        let mut child = SolverProcess(child);
        let mut line = String::new();
        let stdout = child.0.stdout.take().expect("piped");
        // One line only: a binary that is not a solver of this recipe may print without end.
        let _ = BufReader::new(stdout).read_line(&mut line);
        let expected = format!("key {}", self.key);
        if line.trim_end() == expected {
            Ok(())
        } else {
            Err(format!("is not this entry's solver (asked for its key, it printed {line:?})"))
        }
    }

    /// Makes the entry usable: verified as it is, or rebuilt. `notes` receives what was
    /// found wrong and repaired.
    pub(super) fn ensure(&self, notes: &mut Vec<String>) -> Result<(), EngineError> {
        // One process at a time checks and builds an entry: another mechgen building the
        // same solver waits here, then finds it verified.
        let lock_path = self.dir().join(".lock");
        let lock = std::fs::create_dir_all(self.dir())
            .and_then(|()| std::fs::File::options().create(true).append(true).open(&lock_path))
            .map_err(|e| {
                EngineError::Build(BuildFailure {
                    reason: format!("{}: {e}", lock_path.display()),
                    fix: "set MECHGEN_CACHE to a writable directory".to_owned(),
                })
            })?;
        // Where the file system cannot lock, concurrent builds only repeat work: every file
        // is put in place by a rename.
        let _ = lock.lock();
        let verified = self.verify_or_build(notes);
        drop(lock);
        verified
    }

    fn verify_or_build(&self, notes: &mut Vec<String>) -> Result<(), EngineError> {
        match self.defect() {
            None => {
                log::info!("cache hit: {} (verified)", self.dir().display());
                return Ok(());
            }
            Some(why) if why.is_empty() => {
                log::info!("cache miss: building {}", self.dir().display());
            }
            Some(why) => {
                log::warn!("cache entry {} unusable: {why}; rebuilding it", self.key);
                notes.push(format!("{why}; rebuilding it"));
            }
        }
        let start = std::time::Instant::now();
        self.build(notes)?;
        log::info!("built {} in {:.1} s", self.package(), start.elapsed().as_secs_f64());
        match self.defect() {
            None => Ok(()),
            Some(why) => Err(EngineError::Build(BuildFailure {
                reason: format!("{why} right after it was built"),
                fix: format!(
                    "check that {} is on a file system that allows running programs, or set \
                     MECHGEN_CACHE to a directory that is",
                    self.cache.display()
                ),
            })),
        }
    }

    /// Writes the sources, builds them with cargo and puts the binary into the entry (by a
    /// rename, so that a solver starting meanwhile runs either the old file or the new one),
    /// then its record.
    fn build(&self, notes: &mut Vec<String>) -> Result<(), EngineError> {
        let io = |path: &Path, e: std::io::Error| {
            EngineError::Build(BuildFailure {
                reason: format!("{}: {e}", path.display()),
                fix: "set MECHGEN_CACHE to a writable directory with free space".to_owned(),
            })
        };
        let dir = self.dir();
        let runtime = self.cache.join(format!("runtime-{}", runtime_hash()));
        let mut restored = false;
        let runtime_files = std::iter::once(("Cargo.toml", embedded::RUNTIME_MANIFEST))
            .chain(embedded::RUNTIME_FILES.iter().copied());
        for (path, text) in runtime_files {
            let path = runtime.join(path);
            let existed = path.exists();
            restored |=
                write_if_changed(&path, text.as_bytes()).map_err(|e| io(&path, e))? && existed;
        }
        if restored {
            notes.push(format!(
                "the cache's copy of the runtime ({}) had been changed; restored it",
                runtime.display()
            ));
        }
        for (path, text) in &self.files {
            let path = dir.join(path);
            write_if_changed(&path, text.as_bytes()).map_err(|e| io(&path, e))?;
        }
        // The lock file is written anew before every build, so that versions never drift
        // from mechgen's lock; a corrupt one is said.
        let lock = dir.join("Cargo.lock");
        if let Ok(bytes) = std::fs::read(&lock)
            && !is_lock_file(&bytes)
        {
            notes.push(format!(
                "the cache's lock file {} was corrupt; rewrote it from mechgen's",
                lock.display()
            ));
            std::fs::remove_file(&lock).map_err(|e| io(&lock, e))?;
        }
        if !embedded::WORKSPACE_LOCK.is_empty() {
            write_if_changed(&lock, embedded::WORKSPACE_LOCK.as_bytes())
                .map_err(|e| io(&lock, e))?;
        }
        if self.target_binary().exists() {
            // Cargo trusts its own outputs by their times: make it compile this crate again
            // rather than copy a binary that may be what went wrong.
            self.touch_main().map_err(|e| io(&dir.join("src/main.rs"), e))?;
        }
        self.cargo_build(notes)?;
        let built = self.target_binary();
        let tmp = temporary(&self.binary());
        std::fs::copy(&built, &tmp).map_err(|e| io(&built, e))?;
        std::fs::rename(&tmp, self.binary()).map_err(|e| io(&self.binary(), e))?;
        let bytes = std::fs::read(self.binary()).map_err(|e| io(&self.binary(), e))?;
        write_if_changed(&self.record(), self.binary_hash(&bytes).as_bytes())
            .map_err(|e| io(&self.record(), e))?;
        Ok(())
    }

    fn touch_main(&self) -> std::io::Result<()> {
        std::fs::File::options()
            .write(true)
            .open(self.dir().join("src/main.rs"))?
            .set_modified(std::time::SystemTime::now())
    }

    /// `cargo build`, offline first. When crates are missing from cargo's cache, fetches
    /// exactly those the lock file pins and builds again; any other failure may come from a
    /// corrupted build of the runtime or its dependencies, so those are cleaned and the
    /// build is tried once more.
    fn cargo_build(&self, notes: &mut Vec<String>) -> Result<(), EngineError> {
        let build = ["build", "--release", "--offline", "--quiet"];
        let Err(mut failure) = self.cargo(&build)? else { return Ok(()) };
        if needs_download(&failure) {
            log::warn!("offline build failed for want of crates; fetching them");
            notes.push(format!(
                "fetching the crates the generated solver needs ({}) into cargo's cache, at \
                 the versions mechgen's lock file pins",
                embedded::RUNTIME_DEPENDENCIES.join(", ")
            ));
            if let Err(fetch) = self.cargo(&["fetch", "--quiet"])? {
                return Err(EngineError::Build(BuildFailure {
                    reason: format!("cargo could not download them:\n{}", excerpt(&fetch)),
                    fix: download_fix(),
                }));
            }
            failure = match self.cargo(&build)? {
                Ok(()) => return Ok(()),
                Err(f) => f,
            };
        }
        log::warn!("the build failed; cleaning the cache's build of the runtime and retrying");
        notes.push(format!(
            "the build failed ({}); cleaning the cache's build of the runtime and building again",
            failure.lines().find(|l| l.starts_with("error")).unwrap_or("cargo failed").trim()
        ));
        let mut clean = vec!["clean", "--release", "--offline", "--quiet", "-p", "runtime"];
        for dep in embedded::RUNTIME_DEPENDENCIES {
            clean.extend(["-p", dep]);
        }
        // A failed clean leaves the second build to say what is wrong.
        let _ = self.cargo(&clean)?;
        let _ = self.touch_main();
        match self.cargo(&build)? {
            Ok(()) => Ok(()),
            Err(f) if needs_download(&f) => Err(EngineError::Build(BuildFailure {
                reason: format!("crates are missing from cargo's cache:\n{}", excerpt(&f)),
                fix: download_fix(),
            })),
            Err(f) => Err(EngineError::Build(BuildFailure {
                reason: format!("cargo failed:\n{}", excerpt(&f)),
                fix: "this is a bug in mechgen's generator or its build of the solver: please \
                      report it with the description; meanwhile `--engine generic` analyses \
                      the description without building anything"
                    .to_owned(),
            })),
        }
    }

    /// Runs cargo on the entry's manifest with the cache's build directory: `Ok(Err(stderr))`
    /// when cargo fails.
    fn cargo(&self, args: &[&str]) -> Result<Result<(), String>, EngineError> {
        let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
        log::debug!("running {} {}", Path::new(&cargo).display(), args.join(" "));
        let mut command = Command::new(&cargo);
        command.args(args);
        if let Some(flags) = build_flags() {
            // As configuration, not `RUSTFLAGS`: cargo appends it to the rustflags of the
            // user's own configuration files (a linker choice, say) where the variable would
            // replace them. After the subcommand, which stays cargo's first argument.
            command.arg("--config").arg(format!("build.rustflags = [\"{flags}\"]"));
        }
        let output = command
            .arg("--manifest-path")
            .arg(self.dir().join("Cargo.toml"))
            .env("CARGO_TARGET_DIR", self.cache.join("target"))
            .stdin(Stdio::null())
            .output()
            .map_err(|e| {
                EngineError::Build(BuildFailure {
                    reason: format!("cannot start cargo ({}): {e}", Path::new(&cargo).display()),
                    fix: "install Rust's cargo (for example with rustup), or set CARGO to the \
                          cargo program"
                        .to_owned(),
                })
            })?;
        Ok(if output.status.success() {
            Ok(())
        } else {
            Err(String::from_utf8_lossy(&output.stderr).into_owned())
        })
    }
}

/// Whether cargo failed for want of a crate it may not download (offline mode).
fn needs_download(stderr: &str) -> bool {
    let s = stderr.to_lowercase();
    s.contains("offline") || s.contains("failed to download") || s.contains("no matching package")
}

fn download_fix() -> String {
    format!(
        "the generated solver needs the crates {} in cargo's cache: run mechgen again with \
         network access (it fetches the versions its lock file pins), or run `cargo fetch` \
         once in a mechgen checkout",
        embedded::RUNTIME_DEPENDENCIES.join(", ")
    )
}

/// Cargo's output, at most 40 lines, indented under the message.
fn excerpt(stderr: &str) -> String {
    let lines: Vec<&str> = stderr.trim_end().lines().collect();
    let mut text: Vec<String> = lines.iter().take(40).map(|l| format!("  {l}")).collect();
    if lines.len() > 40 {
        text.push(format!("  … ({} more lines)", lines.len() - 40));
    }
    text.join("\n")
}

/// Whether `bytes` parse as a lock file (TOML with a `version` or `package` table).
fn is_lock_file(bytes: &[u8]) -> bool {
    std::str::from_utf8(bytes)
        .ok()
        .and_then(|t| t.parse::<toml::Table>().ok())
        .is_some_and(|t| t.contains_key("version") || t.contains_key("package"))
}

/// A name beside `path` for writing before a rename, unique to this process and call.
fn temporary(path: &Path) -> PathBuf {
    static COUNT: AtomicUsize = AtomicUsize::new(0);
    let name = path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let n = COUNT.fetch_add(1, Ordering::Relaxed);
    path.with_file_name(format!(".{name}.{}.{n}.tmp", std::process::id()))
}

/// Writes `bytes` to `path` unless it already holds them, through a temporary file and a
/// rename, so that a concurrent reader (another mechgen, cargo) never sees part of it.
/// Returns whether it wrote.
fn write_if_changed(path: &Path, bytes: &[u8]) -> std::io::Result<bool> {
    if std::fs::read(path).is_ok_and(|t| t == bytes) {
        return Ok(false);
    }
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent)?;
    }
    let tmp = temporary(path);
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(&tmp, path)?;
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An environment of the given variables only.
    fn env(vars: &[(&str, &str)]) -> impl Fn(&str) -> Option<OsString> {
        let vars: Vec<(String, OsString)> =
            vars.iter().map(|(k, v)| ((*k).to_owned(), OsString::from(v))).collect();
        move |name| vars.iter().find(|(k, _)| k == name).map(|(_, v)| v.clone())
    }

    #[test]
    fn an_empty_mechgen_cache_is_an_error_naming_it() {
        let root = crate::sync::workspace_root();
        match choose_cache_dir(&root, env(&[("MECHGEN_CACHE", "")])) {
            Err(e @ EngineError::Config(ConfigError::EmptyCache)) => {
                assert!(e.to_string().contains("MECHGEN_CACHE is set but empty"), "{e}")
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn the_checkout_holds_the_cache_while_it_exists() {
        let root = crate::sync::workspace_root();
        let dir = choose_cache_dir(&root, env(&[("HOME", "/home/someone")])).unwrap();
        assert_eq!(dir, root.join("target/mechgen-cache"));
    }

    #[test]
    fn a_deleted_checkout_is_never_recreated_and_the_user_cache_is_used() {
        // A checkout path that does not exist, as for an installed binary whose source
        // folder was moved or deleted.
        let gone =
            std::env::temp_dir().join(format!("mechgen-gone-{}/checkout", std::process::id()));
        let dir = choose_cache_dir(&gone, env(&[("HOME", "/home/someone")])).unwrap();
        assert!(!dir.starts_with(&gone), "{}", dir.display());
        if cfg!(target_os = "linux") {
            assert_eq!(dir, Path::new("/home/someone/.cache/mechgen"));
            let xdg = env(&[("HOME", "/home/someone"), ("XDG_CACHE_HOME", "/var/cache/u")]);
            assert_eq!(choose_cache_dir(&gone, xdg).unwrap(), Path::new("/var/cache/u/mechgen"));
        }
        match choose_cache_dir(&gone, env(&[])) {
            Err(e @ EngineError::Config(ConfigError::NoCacheDir { .. })) => {
                let m = e.to_string();
                assert!(m.contains("set MECHGEN_CACHE"), "{m}");
                assert!(m.contains(&gone.display().to_string()), "{m}");
            }
            other => panic!("{other:?}"),
        }
        assert!(!gone.parent().unwrap().exists(), "nothing was created under the old checkout");
    }

    #[test]
    fn a_lock_file_is_recognised_and_garbage_is_not() {
        assert!(
            is_lock_file(embedded::WORKSPACE_LOCK.as_bytes())
                || embedded::WORKSPACE_LOCK.is_empty()
        );
        assert!(!is_lock_file(b"garbage [[["));
        assert!(!is_lock_file(&[0xff, 0xfe, 0x00]));
        assert!(!is_lock_file(b"title = \"not a lock\""));
    }

    #[test]
    fn every_runtime_source_file_is_embedded() {
        // The embedded copy must build on its own: its modules' files are all there.
        let root = crate::sync::workspace_root().join("runtime");
        let mut on_disk = Vec::new();
        let mut stack = vec![root.join("src")];
        while let Some(dir) = stack.pop() {
            for e in std::fs::read_dir(&dir).unwrap() {
                let p = e.unwrap().path();
                if p.is_dir() {
                    stack.push(p);
                } else {
                    let rel = p.strip_prefix(&root).unwrap().to_string_lossy().replace('\\', "/");
                    on_disk.push(rel);
                }
            }
        }
        on_disk.sort();
        let mut embedded: Vec<&str> = embedded::RUNTIME_FILES.iter().map(|(p, _)| *p).collect();
        embedded.sort_unstable();
        assert_eq!(embedded, on_disk);
        for (path, text) in embedded::RUNTIME_FILES {
            assert_eq!(std::fs::read_to_string(root.join(path)).unwrap(), *text, "{path}");
        }
    }
}
