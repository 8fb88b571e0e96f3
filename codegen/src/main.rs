//! The `mechgen` binary: see `codegen::cli`.

use std::io::Write;

fn main() {
    // What the tool does (cache hits, builds and their duration, fall-backs), on standard
    // error, only when asked: `MECHGEN_LOG=info`, `debug` or `codegen::engine=debug`.
    if std::env::var_os("MECHGEN_LOG").is_some() {
        env_logger::Builder::from_env(env_logger::Env::new().filter("MECHGEN_LOG")).init();
    }
    let args = std::env::args_os().collect();
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let code = codegen::cli::run_with(
        args,
        &mut out,
        &mut std::io::stderr(),
        codegen::cli::Terminal::detect(),
    );
    let _ = out.flush();
    std::process::exit(code);
}
