//! `mechgen scaling` (hidden): generation time, generated lines, build time and speed of
//! growing mechanisms.

use std::io::{self, Write};
use std::path::Path;

use super::common::{EXIT_OK, report_invalid, time_generic};
use crate::generic::Equations;
use crate::validate;

pub(super) fn scaling(
    sizes: &[usize],
    repeats: usize,
    dump: Option<&Path>,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<i32> {
    writeln!(
        out,
        "| mechanism | bodies | unknowns (reduced) | generate (s) | lines | build (s) | generic ns/step | generated ns/step | speedup |"
    )?;
    writeln!(out, "|---|---|---|---|---|---|---|---|---|")?;
    for &n in sizes {
        for text in [crate::scale::chain(n, 20), crate::scale::rssr_loops(n.div_ceil(3), 20)] {
            let loaded = match validate::load_str(&text, validate::Format::Toml, None) {
                Ok(l) => l,
                Err(d) => return Ok(report_invalid(&d, false, out, err)),
            };
            let mech = &loaded.mechanism;
            if let Some(dir) = dump {
                std::fs::create_dir_all(dir)?;
                std::fs::write(dir.join(format!("{}.toml", mech.name)), &text)?;
            }
            let start = std::time::Instant::now();
            let sys = match crate::symbolic::Symbolic::build(mech) {
                Ok(s) => s,
                Err(e) => {
                    writeln!(err, "{}: {e}", mech.name)?;
                    continue;
                }
            };
            let module = crate::emit::module(mech, &sys, "scaling");
            let generate = start.elapsed().as_secs_f64();
            let lines = module.lines().count();
            let start = std::time::Instant::now();
            let built =
                match crate::engine::build_module(mech, &module, &sys, crate::emit::Scalar::F64) {
                    Ok(b) => b,
                    Err(e) => {
                        writeln!(err, "{}: {e}", mech.name)?;
                        continue;
                    }
                };
            let build = start.elapsed().as_secs_f64();
            let eq = Equations::new(mech);
            let prep = eq.prepare();
            let generic = time_generic(&eq, &prep, mech.solver.tolerance, repeats, true)
                .map_or(f64::NAN, |r| r.1);
            let generated = crate::engine::bench(&built, mech.solver.tolerance, repeats)
                .map_or(f64::NAN, |r| r.1);
            writeln!(
                out,
                "| {} | {} | {} ({}) | {generate:.2} | {lines} | {build:.1} | {generic:.0} | {generated:.0} | {:.1} |",
                mech.name,
                mech.bodies.len() - 1,
                eq.unknowns(),
                sys.unknowns.len(),
                generic / generated
            )?;
            out.flush()?;
        }
    }
    Ok(EXIT_OK)
}
