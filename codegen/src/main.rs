//! The `mechgen` binary: see `codegen::cli`.

use std::io::Write;

fn main() {
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
