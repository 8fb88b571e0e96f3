//! `mechgen check`: size, rank, mobility and redundant equations of a description, the
//! equations that contradict each other at the initial configuration (exit status 2, as
//! `solve` reports them), and the blocks of its generated system.

use std::io::{self, Write};
use std::path::Path;

use super::args::CheckFormat;
use super::common::{EXIT_OK, EXIT_STOPPED, load};
use crate::blocks::Blocks;
use crate::diag::printable;
use crate::model::{ConstraintKind, DriverCoordinate, DriverTarget, Mechanism};

/// The number of unknowns left once ground bodies, `fix` constraints, coordinate
/// differences against ground and absolute coordinate drivers are eliminated (each removes
/// one unknown and its equation).
fn reduced_unknowns(mech: &Mechanism) -> usize {
    let fixed = mech
        .constraints
        .iter()
        .filter(|c| match c.kind {
            ConstraintKind::Fix { .. } => true,
            ConstraintKind::CoordinateDifference { body_i, body_j, .. } => {
                mech.bodies[body_i.0].ground || mech.bodies[body_j.0].ground
            }
        })
        .count();
    let driven = mech
        .drivers
        .iter()
        .filter(|d| {
            matches!(
                d.target,
                DriverTarget::Absolute {
                    coordinate: DriverCoordinate::X | DriverCoordinate::Y | DriverCoordinate::Z,
                    ..
                }
            )
        })
        .count();
    mech.unknowns().saturating_sub(fixed + driven)
}

pub(super) fn check(
    file: &Path,
    format: CheckFormat,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> io::Result<i32> {
    let json = format == CheckFormat::Json;
    let loaded = match load(file, json, out, err) {
        Ok(l) => l,
        Err(code) => return Ok(code),
    };
    let mech = &loaded.mechanism;
    let (eq, prep) = match super::common::prepared(mech, json, out, err) {
        Ok(p) => p,
        Err(code) => return Ok(code),
    };
    let redundant: Vec<String> =
        prep.redundant.iter().map(|&k| eq.labels()[k].equation()).collect();
    // The first time point as `solve` takes it: only a contradiction is `check`'s to report
    // (the others are the analysis' own failures), and only equations beyond a full rank
    // (redundant ones) can contradict the others.
    let conflict = (!prep.redundant.is_empty())
        .then(|| crate::generic::Analysis::new(&eq, &prep).first_failure())
        .flatten()
        .filter(|f| f.kind == crate::generic::FailureKind::Inconsistent);
    // The generated system's true size and its blocks; the count of eliminated coordinates
    // and no blocks when it cannot be built (its diagnostics belong to `generate`).
    // The blocks are those of the system before its closed forms are substituted (what a
    // block-by-block solver runs); the generated system's Newton runs on what remains.
    let sys = crate::symbolic::Symbolic::build_full(mech);
    let reduced = sys.as_ref().map_or_else(|_| reduced_unknowns(mech), |s| s.unknowns.len());
    let blocks = sys.as_ref().map(|sys| Blocks::of(sys, mech));
    let (substituted, torn) = crate::symbolic::Symbolic::build(mech)
        .map_or((0, 0), |s| (s.derived.len(), s.derived.iter().filter(|d| d.torn).count()));
    let bodies = mech.bodies.len();
    let grounds = mech.bodies.iter().filter(|b| b.ground).count();
    if json {
        let v = serde_json::json!({
            "bodies": bodies,
            "unknowns": eq.unknowns(),
            "equations": eq.equations(),
            "reduced_unknowns": reduced,
            "substituted": substituted,
            "torn": torn,
            "rank": prep.rank,
            "mobility": prep.mobility,
            "drivers": mech.drivers.len(),
            "redundant": redundant,
            "blocks": blocks.as_ref().ok().map(blocks_json),
        });
        let mut v = v;
        if let (Some(f), Some(o)) = (&conflict, v.as_object_mut()) {
            o.insert("error".to_owned(), crate::report::failure_json(f));
        }
        if let (Ok(sys), Some(o)) = (&sys, v.as_object_mut())
            && !sys.legs.is_empty()
        {
            o.insert("reduced_legs".to_owned(), legs_json(mech, sys));
        }
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
    } else {
        writeln!(out, "mechanism {}: {bodies} bodies ({grounds} ground)", printable(&mech.name))?;
        writeln!(out, "unknowns:          {}", eq.unknowns())?;
        writeln!(out, "equations:         {}", eq.equations())?;
        if substituted == 0 {
            writeln!(out, "reduced unknowns:  {reduced} (generated system)")?;
        } else if torn == 0 {
            writeln!(
                out,
                "reduced unknowns:  {reduced} (generated system: {} after {substituted} \
                 substituted by closed-form blocks)",
                reduced - substituted
            )?;
        } else {
            writeln!(
                out,
                "reduced unknowns:  {reduced} (generated system: {} after {substituted} \
                 substituted by closed-form blocks, {torn} of them torn from implicit blocks)",
                reduced - substituted
            )?;
        }
        let at = if prep.assembled {
            "assembled at t = start"
        } else {
            "initial estimates, not assembled"
        };
        writeln!(out, "rank of Φ_q:       {} ({at})", prep.rank)?;
        writeln!(
            out,
            "mobility:          {} (degrees of freedom before the drivers)",
            prep.mobility
        )?;
        writeln!(out, "drivers:           {}", mech.drivers.len())?;
        if redundant.is_empty() {
            writeln!(out, "redundant:         none")?;
        } else {
            writeln!(out, "redundant:         {}", printable(&redundant.join(", ")))?;
        }
        match &blocks {
            Ok(b) => {
                let implicit = b.blocks.len() - b.closed_form();
                let largest = match b.largest_implicit() {
                    0 => String::new(),
                    n => format!(", the largest of {n}"),
                };
                let rotations = match b.rotations() {
                    0 => String::new(),
                    1 => ", 1 of them a rotation".to_owned(),
                    n => format!(", {n} of them rotations"),
                };
                writeln!(
                    out,
                    "blocks:            {} ({} closed form{rotations}, {implicit} implicit{largest})",
                    b.blocks.len(),
                    b.closed_form()
                )?;
                let sizes: Vec<String> =
                    b.sizes().iter().map(|(size, count)| format!("{count} of {size}")).collect();
                writeln!(out, "block sizes:       {}", sizes.join(", "))?;
            }
            Err(e) => writeln!(out, "blocks:            none ({})", printable(&e.to_string()))?,
        }
        if let Ok(sys) = &sys
            && !sys.legs.is_empty()
        {
            writeln!(
                out,
                "reduced legs:      {}, each driver row replaced by a distance row: {}",
                sys.legs.len(),
                printable(&legs_text(mech, sys))
            )?;
        }
        if let Some(f) = &conflict {
            writeln!(out, "inconsistent:      {}", printable(&f.constraints.join(", ")))?;
        }
    }
    if let Some(f) = &conflict {
        writeln!(err, "error: {}", crate::report::failure_text(f))?;
        return Ok(EXIT_STOPPED);
    }
    Ok(EXIT_OK)
}

/// `{ "count", "closed_form", "rotations", "implicit", "largest_implicit", "sizes": [{ "size",
/// "count" }] }` (`rotations`: the closed-form blocks that are a body's orientation about a
/// driven axis).
fn blocks_json(b: &Blocks) -> serde_json::Value {
    let sizes: Vec<serde_json::Value> = b
        .sizes()
        .into_iter()
        .map(|(size, count)| serde_json::json!({ "size": size, "count": count }))
        .collect();
    serde_json::json!({
        "count": b.blocks.len(),
        "closed_form": b.closed_form(),
        "rotations": b.rotations(),
        "implicit": b.blocks.len() - b.closed_form(),
        "largest_implicit": b.largest_implicit(),
        "sizes": sizes,
    })
}

/// `leg1 (cylinder1, rod1: ground to platform), …`: each reduced leg by its driver, its bodies
/// and the bodies it joins.
fn legs_text(mech: &Mechanism, sys: &crate::symbolic::Symbolic) -> String {
    let name = |b: crate::model::BodyId| mech.bodies[b.0].name.as_str();
    sys.legs
        .iter()
        .map(|l| {
            format!(
                "{} ({}, {}: {} to {})",
                mech.drivers[l.driver].name,
                name(l.bodies[0]),
                name(l.bodies[1]),
                name(l.leg.body_i),
                name(l.leg.body_j)
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// `[{ "driver", "bodies": [u, s], "joins": [a, b] }]`: the reduced legs.
fn legs_json(mech: &Mechanism, sys: &crate::symbolic::Symbolic) -> serde_json::Value {
    let name = |b: crate::model::BodyId| mech.bodies[b.0].name.clone();
    sys.legs
        .iter()
        .map(|l| {
            serde_json::json!({
                "driver": mech.drivers[l.driver].name,
                "bodies": [name(l.bodies[0]), name(l.bodies[1])],
                "joins": [name(l.leg.body_i), name(l.leg.body_j)],
            })
        })
        .collect()
}
