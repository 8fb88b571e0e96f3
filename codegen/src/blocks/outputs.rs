//! Only what is asked: the part of a mechanism that the requested outputs depend on.
//!
//! An output (a point of interest, a moving body, a joint's coordinates) reads the
//! coordinates of one or two bodies. In the block-lower-triangular form of the reduced system
//! ([`Blocks`]) the unknowns of a block are fixed by that block and the blocks before it that
//! its equations involve, and by nothing after it; the blocks that the outputs' unknowns
//! transitively depend on are a closed, square system of their own, and every other block can
//! be left out without changing a single value of the ones kept.
//!
//! The part kept is returned as a mechanism: the bodies those blocks solve for, the bodies
//! their equations read (even when those carry no unknown: a driven or fixed body), and every
//! joint, constraint, driver and point whose bodies are all kept. Keeping whole bodies needs
//! a fixed point: a kept body's other coordinates bring in their own blocks, and with them
//! perhaps further bodies. An entity whose bodies are all kept has all its equations in the
//! kept blocks (each equation is matched to an unknown it involves, which belongs to a kept
//! body and so to a kept block), so the kept mechanism's reduced system is exactly the kept
//! blocks, with the same equations and the same solution.

use std::collections::BTreeSet;

use super::Blocks;
use crate::model::{
    BodyId, ConstraintKind, DriverTarget, JointId, Leg, Mechanism, PointId, RowLabel,
};
use crate::symbolic::Symbolic;

/// A requested output that the mechanism does not have.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "no moving body, point or joint is named \"{name}\"{}; outputs: {}",
    .suggestion.as_ref().map(|s| format!(" (did you mean \"{s}\"?)")).unwrap_or_default(),
    .known.join(", ")
)]
pub struct UnknownOutput {
    /// The name asked for.
    pub name: String,
    /// The nearest name that exists, when one is close.
    pub suggestion: Option<String>,
    /// Every output name the mechanism has: moving bodies, points, joints.
    pub known: Vec<String>,
}

/// The moving bodies each joint, constraint and driver of `mech` involves; a driver whose row
/// the generator replaced by a leg's distance row (`symbolic::legs`) involves the bodies the
/// leg joins, not the leg's own, and is kept as that distance when the leg is left out.
struct Entities {
    joints: Vec<Vec<BodyId>>,
    constraints: Vec<Vec<BodyId>>,
    drivers: Vec<Vec<BodyId>>,
    legs: Vec<Option<Leg>>,
}

impl Entities {
    fn of(mech: &Mechanism, sys: &Symbolic) -> Self {
        let moving = |bodies: &[BodyId]| -> Vec<BodyId> {
            bodies.iter().copied().filter(|b| !mech.bodies[b.0].ground).collect()
        };
        let joints: Vec<Vec<BodyId>> =
            mech.joints.iter().map(|j| moving(&[j.body_i, j.body_j])).collect();
        let constraints = mech
            .constraints
            .iter()
            .map(|c| match c.kind {
                ConstraintKind::Fix { body, .. } => moving(&[body]),
                ConstraintKind::CoordinateDifference { body_i, body_j, .. } => {
                    moving(&[body_i, body_j])
                }
            })
            .collect();
        let drivers = mech
            .drivers
            .iter()
            .map(|d| match d.target {
                DriverTarget::Joint { joint, .. } => joints[joint.0].clone(),
                DriverTarget::Absolute { body, .. } => moving(&[body]),
                DriverTarget::Point { point, .. } => moving(&[mech.points[point.0].body]),
                DriverTarget::Leg(leg) => moving(&[leg.body_i, leg.body_j]),
            })
            .collect();
        let mut entities = Entities { joints, constraints, drivers, legs: Vec::new() };
        entities.legs = vec![None; mech.drivers.len()];
        for reduced in &sys.legs {
            let leg = reduced.leg;
            entities.drivers[reduced.driver] = moving(&[leg.body_i, leg.body_j]);
            entities.legs[reduced.driver] = Some(leg);
        }
        entities
    }

    /// The bodies of the entity a row of the reduced system belongs to.
    fn of_row<'a>(&'a self, mech: &Mechanism, label: &RowLabel) -> &'a [BodyId] {
        let at = |k: Option<usize>, bodies: &'a [Vec<BodyId>]| {
            k.map_or(&[][..], |k| bodies[k].as_slice())
        };
        match label.kind {
            RowLabel::JOINT => {
                at(mech.joints.iter().position(|j| j.name == label.name), &self.joints)
            }
            RowLabel::CONSTRAINT => {
                at(mech.constraints.iter().position(|c| c.name == label.name), &self.constraints)
            }
            RowLabel::DRIVER => {
                at(mech.drivers.iter().position(|d| d.name == label.name), &self.drivers)
            }
            // A normalisation involves its own body, which is kept with its unknowns.
            _ => &[],
        }
    }
}

/// The names `outputs` may take: the moving bodies, the points and the joints, in file order.
#[must_use]
pub fn output_names(mech: &Mechanism) -> Vec<String> {
    let bodies = mech.bodies.iter().filter(|b| !b.ground).map(|b| b.name.clone());
    let points = mech.points.iter().map(|p| p.name.clone());
    bodies.chain(points).chain(mech.joints.iter().map(|j| j.name.clone())).collect()
}

/// The part of `mech` (whose reduced system is `sys`) that the outputs `names` depend on: a
/// name selects the moving body, the point or the joint (its coordinates) of that name, as
/// `solve --select` does. The mechanism is returned whole when nothing can be left out.
///
/// # Errors
/// The first name that is no moving body, point or joint of `mech`.
pub fn only(
    mech: &Mechanism,
    sys: &Symbolic,
    names: &[String],
) -> Result<Mechanism, UnknownOutput> {
    // What depends on what is read from the blocks before their closed forms are substituted
    // (`symbolic::substitute`): a substituted coordinate's block is no longer among them.
    let full = if sys.derived.is_empty() { None } else { Symbolic::build_full(mech).ok() };
    let sys = full.as_ref().unwrap_or(sys);
    let entities = Entities::of(mech, sys);
    let mut wanted: BTreeSet<BodyId> = BTreeSet::new();
    for name in names {
        let mut found = false;
        for (k, b) in mech.bodies.iter().enumerate() {
            if !b.ground && b.name == *name {
                wanted.insert(BodyId(k));
                found = true;
            }
        }
        for p in mech.points.iter().filter(|p| p.name == *name) {
            wanted.extend([p.body].into_iter().filter(|b| !mech.bodies[b.0].ground));
            found = true;
        }
        for (k, j) in mech.joints.iter().enumerate() {
            if j.name == *name {
                wanted.extend(&entities.joints[k]);
                found = true;
            }
        }
        if !found {
            let known = output_names(mech);
            let suggestion =
                crate::validate::closest(name, known.iter().map(String::as_str)).map(str::to_owned);
            return Err(UnknownOutput { name: name.clone(), suggestion, known });
        }
    }
    let kept = kept_bodies(mech, sys, &entities, wanted);
    Ok(restrict(mech, &entities, &kept))
}

/// The fixed point of the bodies to keep, from the bodies the outputs read: the bodies of the
/// blocks their unknowns depend on, and the bodies the equations of those blocks involve.
fn kept_bodies(
    mech: &Mechanism,
    sys: &Symbolic,
    entities: &Entities,
    mut bodies: BTreeSet<BodyId>,
) -> BTreeSet<BodyId> {
    let blocks = Blocks::of(sys, mech);
    let n = sys.unknowns.len();
    let mut block_of = vec![0; n];
    for (b, block) in blocks.blocks.iter().enumerate() {
        for &k in &block.unknowns {
            block_of[k] = b;
        }
    }
    let mut kept_blocks = vec![false; blocks.blocks.len()];
    loop {
        let before = bodies.len();
        // Every unknown of a kept body, and the blocks those depend on, transitively.
        let mut stack: Vec<usize> = (0..n)
            .filter(|&k| bodies.contains(&sys.unknowns[k].0))
            .map(|k| block_of[k])
            .filter(|&b| !kept_blocks[b])
            .collect();
        while let Some(b) = stack.pop() {
            if std::mem::replace(&mut kept_blocks[b], true) {
                continue;
            }
            let block = &blocks.blocks[b];
            for &k in &block.unknowns {
                bodies.insert(sys.unknowns[k].0);
            }
            for &r in &block.rows {
                bodies.extend(entities.of_row(mech, &sys.rows[r]));
                for &(c, _) in &sys.jac[r] {
                    if !kept_blocks[block_of[c]] {
                        stack.push(block_of[c]);
                    }
                }
            }
        }
        if bodies.len() == before {
            return bodies;
        }
    }
}

/// `mech` with the moving bodies outside `kept`, and every entity and point that involves
/// one of them, left out; ids renumbered.
fn restrict(mech: &Mechanism, entities: &Entities, kept: &BTreeSet<BodyId>) -> Mechanism {
    let keeps = |bodies: &[BodyId]| bodies.iter().all(|b| kept.contains(b));
    let body_kept = |k: usize| mech.bodies[k].ground || kept.contains(&BodyId(k));
    // New ids of the bodies, joints and points kept.
    let renumber = |flags: Vec<bool>| -> Vec<Option<usize>> {
        let mut next = 0;
        flags
            .into_iter()
            .map(|on| {
                on.then(|| {
                    next += 1;
                    next - 1
                })
            })
            .collect()
    };
    let body_id = renumber((0..mech.bodies.len()).map(body_kept).collect());
    let joint_id = renumber(entities.joints.iter().map(|b| keeps(b)).collect());
    let point_id = renumber(mech.points.iter().map(|p| body_kept(p.body.0)).collect());
    let body = |b: BodyId| BodyId(body_id[b.0].expect("a kept entity's bodies are kept"));
    let mut out = mech.clone();
    out.bodies =
        (0..mech.bodies.len()).filter(|&k| body_kept(k)).map(|k| mech.bodies[k].clone()).collect();
    out.joints = mech
        .joints
        .iter()
        .zip(&joint_id)
        .filter(|(_, id)| id.is_some())
        .map(|(j, _)| {
            let mut j = j.clone();
            (j.body_i, j.body_j) = (body(j.body_i), body(j.body_j));
            j
        })
        .collect();
    out.constraints = mech
        .constraints
        .iter()
        .zip(&entities.constraints)
        .filter(|(_, b)| keeps(b))
        .map(|(c, _)| {
            let mut c = c.clone();
            match &mut c.kind {
                ConstraintKind::Fix { body: b, .. } => *b = body(*b),
                ConstraintKind::CoordinateDifference { body_i, body_j, .. } => {
                    (*body_i, *body_j) = (body(*body_i), body(*body_j));
                }
            }
            c
        })
        .collect();
    out.drivers = mech
        .drivers
        .iter()
        .zip(&entities.drivers)
        .zip(&entities.legs)
        .filter(|((_, b), _)| keeps(b))
        .map(|((d, _), leg)| {
            let mut d = d.clone();
            let leg_of =
                |leg: &Leg| Leg { body_i: body(leg.body_i), body_j: body(leg.body_j), ..*leg };
            match &mut d.target {
                DriverTarget::Joint { joint, .. } => match (joint_id[joint.0], leg) {
                    (Some(id), _) => *joint = JointId(id),
                    // The leg's bodies are left out: its driver is the distance it holds.
                    (None, Some(leg)) => d.target = DriverTarget::Leg(leg_of(leg)),
                    (None, None) => unreachable!("a kept driver's joint has its bodies kept"),
                },
                DriverTarget::Leg(leg) => *leg = leg_of(leg),
                DriverTarget::Absolute { body: b, .. } => *b = body(*b),
                DriverTarget::Point { point, .. } => {
                    *point = PointId(point_id[point.0].expect("its point's body is kept"));
                }
            }
            d
        })
        .collect();
    // A replayed series is kept per driver: the kept drivers' series, in their new order.
    if let Some(replay) = &mech.time.replay {
        let mut replay = (**replay).clone();
        replay.series = replay
            .series
            .into_iter()
            .zip(&entities.drivers)
            .filter(|(_, b)| keeps(b))
            .map(|(series, _)| series)
            .collect();
        out.time.replay = Some(std::sync::Arc::new(replay));
    }
    out.points = mech
        .points
        .iter()
        .filter(|p| body_kept(p.body.0))
        .map(|p| {
            let mut p = p.clone();
            p.body = body(p.body);
            p
        })
        .collect();
    out
}
