//! Results per time point in the contract's terms (§4), and the three output formats:
//! JSON, CSV and the thesis-style table. Writers stream: each frame is written as soon as it
//! is computed, so the memory used does not grow with the number of time points.

use std::borrow::Cow;
use std::io::{self, Write};

use nalgebra::{DVector, Vector3, Vector4};

use crate::diag::printable;
use crate::generic::{Failure, Frame};
use crate::model::Mechanism;
use crate::model::frame::{g_matrix, rotation};

pub use runtime::step::Suspect;

/// One body's results at one time point (global components throughout).
#[derive(Clone, Debug, PartialEq)]
pub struct BodyResult {
    /// Body name.
    pub name: String,
    /// Origin.
    pub r: [f64; 3],
    /// Euler parameters.
    pub p: [f64; 4],
    /// ṙ.
    pub r_dot: [f64; 3],
    /// ṗ.
    pub p_dot: [f64; 4],
    /// ω = 2 G(p) ṗ (thesis eq. 3.34).
    pub omega: [f64; 3],
    /// r̈.
    pub r_ddot: [f64; 3],
    /// p̈.
    pub p_ddot: [f64; 4],
    /// α = 2 G(p) p̈ (the term 2 Ġ ṗ vanishes identically).
    pub alpha: [f64; 3],
}

/// One point of interest at one time point.
#[derive(Clone, Debug, PartialEq)]
pub struct PointResult {
    /// Point name.
    pub name: String,
    /// r_P = r + A s'.
    pub r: [f64; 3],
    /// v_P = ṙ + ω × s.
    pub v: [f64; 3],
    /// a_P = r̈ + α × s + ω × (ω × s).
    pub a: [f64; 3],
}

/// One joint coordinate at one time point: the angle θ from ref_i to ref_j about axis_i
/// (revolute, cylindrical and screw joints with references) and the translation
/// d = (P_j − P_i)·axis_i (prismatic, cylindrical, screw), each with its two time derivatives.
#[derive(Clone, Debug, PartialEq)]
pub struct JointResult {
    /// Joint name.
    pub name: String,
    /// (θ, θ̇, θ̈); θ in (−π, π] here, unwrapped along the run by [`Unwrap`].
    pub angle: Option<[f64; 3]>,
    /// (d, ḋ, d̈).
    pub translation: Option<[f64; 3]>,
}

/// Everything reported at one time point.
#[derive(Clone, Debug, PartialEq)]
pub struct StepResult {
    /// Time.
    pub t: f64,
    /// Newton iterations.
    pub iterations: u32,
    /// max |Φ_i| at the reported configuration.
    pub residual: f64,
    /// κ̂, the estimate of the condition number of Φ_q there ([`Frame::condition`]).
    pub condition: f64,
    /// The derivatives κ̂ cannot vouch for to six significant digits
    /// ([`runtime::step::suspect`]).
    pub suspect: Suspect,
    /// Every non-ground body, in file order.
    pub bodies: Vec<BodyResult>,
    /// Every point of interest, in file order.
    pub points: Vec<PointResult>,
    /// Every joint with a reported coordinate ([`reported_joints`]), in file order.
    pub joints: Vec<JointResult>,
    /// The equations named redundant from this step on (`joint J4 row 1`), when they differ
    /// from the previous step's (the first step's from those named at the initial
    /// configuration); `None` when they are the same ([`Frame::redundant`]).
    pub redundant: Option<Vec<String>>,
}

/// The joints whose coordinates are reported, with (angle, translation): revolute,
/// cylindrical and screw joints with ref_i and ref_j report θ; prismatic, cylindrical and
/// screw joints report d.
#[must_use]
pub fn reported_joints(mech: &Mechanism) -> Vec<(usize, bool, bool)> {
    use crate::model::JointKind as K;
    mech.joints
        .iter()
        .enumerate()
        .filter_map(|(k, j)| {
            let angle = j.reference.is_some()
                && matches!(j.kind, K::Revolute | K::Cylindrical | K::Screw { .. });
            let translation = matches!(j.kind, K::Prismatic | K::Cylindrical | K::Screw { .. });
            (angle || translation).then_some((k, angle, translation))
        })
        .collect()
}

/// Makes the joint angles of successive steps continuous across turns: each angle is moved by
/// the multiple of 2π that brings it closest to the previous step's (the first stays in
/// (−π, π]).
#[derive(Clone, Debug, Default)]
pub struct Unwrap {
    previous: Vec<Option<f64>>,
}

impl Unwrap {
    /// Unwraps the angles of `s` in place.
    pub fn apply(&mut self, s: &mut StepResult) {
        use std::f64::consts::TAU;
        self.previous.resize(s.joints.len(), None);
        for (j, prev) in s.joints.iter_mut().zip(&mut self.previous) {
            if let Some(a) = j.angle.as_mut() {
                if let Some(p) = *prev {
                    a[0] += TAU * ((p - a[0]) / TAU).round();
                }
                *prev = Some(a[0]);
            }
        }
    }
}

/// The joint coordinates (θ, d and their derivatives) from q, q̇ and q̈.
fn joint_results(
    mech: &Mechanism,
    layout: &[Option<usize>],
    q: &DVector<f64>,
    qd: &DVector<f64>,
    qdd: &DVector<f64>,
) -> Vec<JointResult> {
    use crate::generic::kin::{BodyState, Sk};
    let reported = reported_joints(mech);
    if reported.is_empty() {
        return Vec::new();
    }
    let state = |b: usize| match layout[b] {
        Some(o) => BodyState::new(&q.as_slice()[o..o + 7], &qd.as_slice()[o..o + 7]),
        None => {
            let (r, p) = (mech.bodies[b].r, mech.bodies[b].p);
            BodyState::new(&[r.x, r.y, r.z, p[0], p[1], p[2], p[3]], &[0.0; 7])
        }
    };
    // (u, u̇, ü) of a quantity carried with its Jacobian: ü = u_q q̈ + ü* (kin's module docs).
    let total = |u: &Sk, bodies: [usize; 2]| {
        let mut dd = u.d2;
        for (slot, b) in bodies.iter().enumerate() {
            if let Some(o) = layout[*b] {
                dd += (0..7).map(|c| u.jac[slot][c] * qdd[o + c]).sum::<f64>();
            }
        }
        [u.v, u.d1, dd]
    };
    reported
        .into_iter()
        .map(|(k, angle, translation)| {
            let jt = &mech.joints[k];
            let bodies = [jt.body_i.0, jt.body_j.0];
            let (bi, bj) = (state(bodies[0]), state(bodies[1]));
            let angle = angle.then(|| {
                let (x, y) = crate::generic::joint_angle(jt, &bi, &bj);
                let ([x, xd, xdd], [y, yd, ydd]) = (total(&x, bodies), total(&y, bodies));
                // θ = atan2(y, x); θ̇ r² = x ẏ − y ẋ; θ̈ r² = x ÿ − y ẍ − 2 θ̇ (x ẋ + y ẏ).
                let r2 = x * x + y * y;
                let theta = y.atan2(x);
                let theta = if theta == -std::f64::consts::PI { -theta } else { theta };
                let rate = (x * yd - y * xd) / r2;
                let acc = (x * ydd - y * xdd - 2.0 * rate * (x * xd + y * yd)) / r2;
                [theta, rate, acc]
            });
            let translation =
                translation.then(|| total(&crate::generic::axial_position(jt, &bi, &bj), bodies));
            JointResult { name: jt.name.clone(), angle, translation }
        })
        .collect()
}

/// Where each body's 7 coordinates sit in q (`None` for ground bodies).
#[must_use]
pub fn layout(mech: &Mechanism) -> Vec<Option<usize>> {
    let mut next = 0;
    mech.bodies
        .iter()
        .map(|b| {
            (!b.ground).then(|| {
                next += 7;
                next - 7
            })
        })
        .collect()
}

fn arr3(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

fn arr4(v: &Vector4<f64>) -> [f64; 4] {
    [v[0], v[1], v[2], v[3]]
}

/// Body and point results from the coordinates of one frame, with its condition estimate
/// and the derivatives that estimate cannot vouch for (in double precision, the arithmetic of
/// both engines under `solve`).
#[must_use]
pub fn step_result(mech: &Mechanism, layout: &[Option<usize>], frame: &Frame) -> StepResult {
    let mut s = StepResult::empty();
    step_result_into(mech, layout, frame, &mut s);
    s
}

/// [`step_result`] written over `s`, whose bodies, points and names are reused: what a stream
/// of frames calls, with no allocation per frame but for joints and redundancy changes.
pub fn step_result_into(
    mech: &Mechanism,
    layout: &[Option<usize>],
    frame: &Frame,
    s: &mut StepResult,
) {
    let (q, qd, qdd) = (&frame.q, &frame.qd, &frame.qdd);
    fill(mech, layout, [q, qd, qdd], s);
    (s.t, s.iterations, s.residual) = (frame.t, frame.iterations, frame.residual);
    s.condition = frame.condition;
    s.suspect = runtime::step::suspect(frame.condition, f64::EPSILON);
    s.redundant = frame.redundant.as_ref().map(|rows| {
        let labels = mech.row_labels();
        rows.iter().map(|&k| labels[k].equation()).collect()
    });
}

/// Body and point results from q, q̇ and q̈ (any engine), without a condition estimate (NaN)
/// or suspects.
#[allow(clippy::too_many_arguments)] // The seven inputs are the frame's parts; a struct would only rename them.
#[must_use]
pub fn from_coordinates(
    mech: &Mechanism,
    layout: &[Option<usize>],
    t: f64,
    iterations: u32,
    residual: f64,
    q: &DVector<f64>,
    qd: &DVector<f64>,
    qdd: &DVector<f64>,
) -> StepResult {
    let mut s = StepResult::empty();
    fill(mech, layout, [q, qd, qdd], &mut s);
    (s.t, s.iterations, s.residual) = (t, iterations, residual);
    s
}

impl StepResult {
    /// No bodies, points or joints, every number NaN: a step for [`step_result_into`] to fill.
    #[must_use]
    pub fn empty() -> Self {
        StepResult {
            t: f64::NAN,
            iterations: 0,
            residual: f64::NAN,
            condition: f64::NAN,
            suspect: Suspect::default(),
            bodies: Vec::new(),
            points: Vec::new(),
            joints: Vec::new(),
            redundant: None,
        }
    }
}

/// The origin, Euler parameters, their rates and accelerations and the angular velocity and
/// acceleration of one body.
struct Kin {
    r: Vector3<f64>,
    p: Vector4<f64>,
    rd: Vector3<f64>,
    rdd: Vector3<f64>,
    omega: Vector3<f64>,
    alpha: Vector3<f64>,
}

/// The [`Kin`] of body `b` (at offset `off` of the coordinates, `None` for ground).
fn kin(mech: &Mechanism, b: usize, off: Option<usize>, [q, qd, qdd]: [&DVector<f64>; 3]) -> Kin {
    match off {
        Some(o) => {
            let p: Vector4<f64> = q.fixed_rows::<4>(o + 3).into();
            let g = g_matrix(&p);
            Kin {
                r: q.fixed_rows::<3>(o).into(),
                p,
                rd: qd.fixed_rows::<3>(o).into(),
                rdd: qdd.fixed_rows::<3>(o).into(),
                omega: g * qd.fixed_rows::<4>(o + 3) * 2.0,
                alpha: g * qdd.fixed_rows::<4>(o + 3) * 2.0,
            }
        }
        None => Kin {
            r: mech.bodies[b].r,
            p: mech.bodies[b].p,
            rd: Vector3::zeros(),
            rdd: Vector3::zeros(),
            omega: Vector3::zeros(),
            alpha: Vector3::zeros(),
        },
    }
}

/// The bodies', points' and joints' results from q, q̇ and q̈, written over those of `s`
/// (its other fields are left as they are).
fn fill(
    mech: &Mechanism,
    layout: &[Option<usize>],
    coordinates: [&DVector<f64>; 3],
    s: &mut StepResult,
) {
    let [q, qd, qdd] = coordinates;
    let moving = layout.iter().flatten().count();
    let blank = || BodyResult {
        name: String::new(),
        r: [0.0; 3],
        p: [0.0; 4],
        r_dot: [0.0; 3],
        p_dot: [0.0; 4],
        omega: [0.0; 3],
        r_ddot: [0.0; 3],
        p_ddot: [0.0; 4],
        alpha: [0.0; 3],
    };
    s.bodies.resize_with(moving, blank);
    let moving =
        mech.bodies.iter().enumerate().zip(layout).filter_map(|(b, off)| Some((b, (*off)?)));
    for (((k, b), o), out) in moving.zip(&mut s.bodies) {
        let k = kin(mech, k, Some(o), coordinates);
        out.name.clone_from(&b.name);
        out.r = arr3(&k.r);
        out.p = arr4(&k.p);
        out.r_dot = arr3(&k.rd);
        out.p_dot = arr4(&qd.fixed_rows::<4>(o + 3).into());
        out.omega = arr3(&k.omega);
        out.r_ddot = arr3(&k.rdd);
        out.p_ddot = arr4(&qdd.fixed_rows::<4>(o + 3).into());
        out.alpha = arr3(&k.alpha);
    }
    let blank = || PointResult { name: String::new(), r: [0.0; 3], v: [0.0; 3], a: [0.0; 3] };
    s.points.resize_with(mech.points.len(), blank);
    for (pt, out) in mech.points.iter().zip(&mut s.points) {
        let k = kin(mech, pt.body.0, layout[pt.body.0], coordinates);
        let r = rotation(&k.p) * pt.local;
        out.name.clone_from(&pt.name);
        out.r = arr3(&(k.r + r));
        out.v = arr3(&(k.rd + k.omega.cross(&r)));
        out.a = arr3(&(k.rdd + k.alpha.cross(&r) + k.omega.cross(&k.omega.cross(&r))));
    }
    if mech.joints.is_empty() {
        s.joints.clear();
    } else {
        s.joints = joint_results(mech, layout, q, qd, qdd);
    }
}

/// The output formats of `solve`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// The thesis' report: POSITION / VELOCITY / ACCELERATION / POINTS OF INTEREST.
    Table,
    /// One row per step, one column per scalar.
    Csv,
    /// The contract's §4 object.
    Json,
}

/// A streaming writer of one analysis in one format.
pub struct Writer<W: Write> {
    out: W,
    format: Format,
    steps: usize,
    /// Equations named redundant at the initial configuration (written by `finish` in CSV).
    removed: Vec<String>,
    /// Where the redundant equations changed and what they became (written by `finish` in
    /// CSV).
    changes: Vec<(f64, Vec<String>)>,
    /// Continuity of the joint angles across steps.
    unwrap: Unwrap,
    /// The bodies, points and joints written.
    select: Selection,
    /// One step's text, reused from step to step.
    buf: Vec<u8>,
    /// The JSON keys of the bodies, points and joints in the order JSON writes them.
    keys: Option<JsonKeys>,
    /// The text of the numbers of the step before.
    numbers: Numbers,
}

impl<W: Write> Writer<W> {
    /// Starts the output: the JSON preamble or the CSV header.
    ///
    /// `removed` names the equations the analysis leaves out because they depend on the
    /// others (consistent redundancy, `joint O4 row 2`): JSON lists them as `"removed"` before
    /// the steps (an empty list when there are none), the table says so under its title, and
    /// CSV adds a `# removed: …` comment line after the rows (so that the header stays the
    /// first line).
    ///
    /// # Errors
    /// Returns I/O errors of `out`.
    pub fn begin(
        out: W,
        format: Format,
        mech: &Mechanism,
        engine: &str,
        removed: &[String],
    ) -> io::Result<Self> {
        Self::begin_selected(out, format, mech, engine, removed, Selection::all(mech))
    }

    /// [`Writer::begin`] for the bodies, points and joints of `select` only.
    ///
    /// # Errors
    /// Returns I/O errors of `out`.
    pub fn begin_selected(
        mut out: W,
        format: Format,
        mech: &Mechanism,
        engine: &str,
        removed: &[String],
        select: Selection,
    ) -> io::Result<Self> {
        match format {
            Format::Json => {
                write!(
                    out,
                    "{{\n  \"mechanism\": {},\n  \"engine\": {},\n  \"removed\": {},\n  \"steps\": [",
                    serde_json::to_string(&mech.name)?,
                    serde_json::to_string(engine)?,
                    serde_json::to_string(removed)?
                )?;
            }
            Format::Csv => {
                let header: Vec<Cow<'_, str>> =
                    header(mech, &select).into_iter().map(|h| csv_field(h.into())).collect();
                writeln!(out, "{}", header.join(","))?;
            }
            Format::Table => {
                writeln!(
                    out,
                    "mechgen: kinematic analysis of {} ({} engine)",
                    printable(&mech.name),
                    printable(engine)
                )?;
                if !removed.is_empty() {
                    writeln!(
                        out,
                        "redundant equations (dependent on the ones before them at the initial \
                         configuration): {}",
                        printable(&removed.join(", "))
                    )?;
                }
            }
        }
        Ok(Self {
            out,
            format,
            steps: 0,
            removed: removed.to_vec(),
            changes: Vec::new(),
            unwrap: Unwrap::default(),
            select,
            buf: Vec::new(),
            keys: None,
            numbers: Numbers::default(),
        })
    }

    /// Writes one time point.
    ///
    /// # Errors
    /// Returns I/O errors of `out`.
    pub fn step(&mut self, s: &StepResult) -> io::Result<()> {
        let selected;
        let s = if self.select.all {
            s
        } else {
            selected = self.select.apply(s);
            &selected
        };
        let mut unwrapped;
        let s = if s.joints.iter().any(|j| j.angle.is_some()) {
            unwrapped = s.clone();
            self.unwrap.apply(&mut unwrapped);
            &unwrapped
        } else {
            s
        };
        self.buf.clear();
        match self.format {
            Format::Json => {
                let sep: &[u8] = if self.steps == 0 { b"\n    " } else { b",\n    " };
                self.buf.extend_from_slice(sep);
                if !self.keys.as_ref().is_some_and(|k| k.fits(s)) {
                    self.keys = Some(JsonKeys::new(s));
                }
                let keys = self.keys.as_ref().expect("the keys were just made");
                write_step_json(&mut self.buf, s, keys, &mut self.numbers);
                self.out.write_all(&self.buf)?;
            }
            Format::Csv => {
                write_csv_row(&mut self.buf, s, &mut self.numbers);
                self.out.write_all(&self.buf)?;
                if let Some(r) = &s.redundant {
                    self.changes.push((s.t, r.clone()));
                }
            }
            Format::Table => write_table_step(&mut self.out, s)?,
        }
        self.steps += 1;
        Ok(())
    }

    /// Ends the output with the error, if the analysis stopped early, and returns the sink.
    ///
    /// # Errors
    /// Returns I/O errors of `out`.
    pub fn finish(self, failure: Option<&Failure>) -> io::Result<W> {
        self.close(failure.map(|f| (failure_json(f), failure_text(f))))
    }

    /// Ends the output of a run that broke off for a reason other than the analysis (the
    /// generated solver stopped without a verdict): the error object has `kind`, the
    /// `message`, no time and no equations, so that JSON output stays one valid document.
    ///
    /// # Errors
    /// Returns I/O errors of `out`.
    pub fn finish_broken(self, kind: &str, message: &str) -> io::Result<W> {
        let json = serde_json::json!({
            "kind": kind,
            "t": null,
            "message": message,
            "constraints": [],
        });
        self.close(Some((json, format!("{kind}: {message}"))))
    }

    /// Writes the end of the output with `error` (its JSON object and its line of text).
    fn close(mut self, error: Option<(serde_json::Value, String)>) -> io::Result<W> {
        match self.format {
            Format::Json => {
                let close = if self.steps == 0 { "]" } else { "\n  ]" };
                let error = error.map_or(serde_json::Value::Null, |e| e.0);
                writeln!(
                    self.out,
                    "{close},\n  \"error\": {}\n}}",
                    serde_json::to_string(&error)?
                )?;
            }
            Format::Csv | Format::Table => {
                if self.format == Format::Csv && !self.removed.is_empty() {
                    writeln!(self.out, "# removed: {}", printable(&self.removed.join(", ")))?;
                }
                for (t, r) in &self.changes {
                    writeln!(self.out, "# redundant from t = {t}: {}", redundant_list(r))?;
                }
                if let Some((_, text)) = error {
                    // CSV readers skip comment lines; the table is for people.
                    let lead = if self.format == Format::Csv { "# " } else { "" };
                    writeln!(self.out, "{lead}ANALYSIS STOPPED: {}", printable(&text))?;
                }
            }
        }
        self.out.flush()?;
        Ok(self.out)
    }
}

/// A list of redundant equations for a line of text ("none" when empty).
fn redundant_list(r: &[String]) -> Cow<'static, str> {
    if r.is_empty() { "none".into() } else { printable(&r.join(", ")).into_owned().into() }
}

/// The contract's `error` object of a numerical failure.
#[must_use]
pub fn failure_json(f: &Failure) -> serde_json::Value {
    serde_json::json!({
        "kind": f.kind.as_str(),
        "t": f.t,
        "message": f.message,
        "constraints": f.constraints,
    })
}

/// A one-line account of a numerical failure, safe to show on a terminal ([`printable`]).
#[must_use]
pub fn failure_text(f: &Failure) -> String {
    let mut s = format!("{} at t = {}: {}", f.kind.as_str(), f.t, f.message);
    if !f.constraints.is_empty() {
        s.push_str(&format!(" (involved: {})", f.constraints.join(", ")));
    }
    printable(&s).into_owned()
}

/// The JSON object of one step (contract §4).
#[must_use]
pub fn step_json(s: &StepResult) -> serde_json::Value {
    let bodies: serde_json::Map<String, serde_json::Value> = s
        .bodies
        .iter()
        .map(|b| {
            (
                b.name.clone(),
                serde_json::json!({
                    "r": b.r, "p": b.p, "r_dot": b.r_dot, "p_dot": b.p_dot, "omega": b.omega,
                    "r_ddot": b.r_ddot, "p_ddot": b.p_ddot, "alpha": b.alpha,
                }),
            )
        })
        .collect();
    let points: serde_json::Map<String, serde_json::Value> = s
        .points
        .iter()
        .map(|p| (p.name.clone(), serde_json::json!({ "r": p.r, "v": p.v, "a": p.a })))
        .collect();
    let joints: serde_json::Map<String, serde_json::Value> = s
        .joints
        .iter()
        .map(|j| {
            let mut o = serde_json::Map::new();
            for (q, v) in [("angle", j.angle), ("translation", j.translation)] {
                if let Some([x, xd, xdd]) = v {
                    o.insert(q.to_owned(), x.into());
                    o.insert(format!("{q}_dot"), xd.into());
                    o.insert(format!("{q}_ddot"), xdd.into());
                }
            }
            (j.name.clone(), serde_json::Value::Object(o))
        })
        .collect();
    let suspect: Vec<&str> = s.suspect.names().collect();
    let mut v = serde_json::json!({
        "t": s.t,
        "iterations": s.iterations,
        "residual": s.residual,
        "condition": s.condition,
        "suspect": suspect,
        "bodies": bodies,
        "points": points,
        "joints": joints,
    });
    if let (Some(r), Some(o)) = (&s.redundant, v.as_object_mut()) {
        o.insert("redundant".to_owned(), serde_json::json!(r));
    }
    v
}

const XYZ: [&str; 3] = ["x", "y", "z"];
const E: [&str; 4] = ["e0", "e1", "e2", "e3"];

/// CSV column names: `t`, `iterations`, `residual`, `condition`, `suspect` (the suspect
/// derivatives separated by spaces, empty when none), then `crank.r.x` … `B.a.z`.
#[must_use]
pub fn csv_header(mech: &Mechanism) -> Vec<String> {
    header(mech, &Selection::all(mech))
}

/// The CSV column names of the bodies, points and joints of `select`.
fn header(mech: &Mechanism, select: &Selection) -> Vec<String> {
    let mut h = ["t", "iterations", "residual", "condition", "suspect"].map(str::to_owned).to_vec();
    let moving = mech.bodies.iter().filter(|b| !b.ground);
    for (b, _) in moving.zip(&select.bodies).filter(|(_, on)| **on) {
        for (q, comps) in [
            ("r", &XYZ[..]),
            ("p", &E[..]),
            ("r_dot", &XYZ[..]),
            ("p_dot", &E[..]),
            ("omega", &XYZ[..]),
            ("r_ddot", &XYZ[..]),
            ("p_ddot", &E[..]),
            ("alpha", &XYZ[..]),
        ] {
            h.extend(comps.iter().map(|c| format!("{}.{q}.{c}", b.name)));
        }
    }
    for (p, _) in mech.points.iter().zip(&select.points).filter(|(_, on)| **on) {
        for q in ["r", "v", "a"] {
            h.extend(XYZ.iter().map(|c| format!("{}.{q}.{c}", p.name)));
        }
    }
    let reported = reported_joints(mech).into_iter().zip(&select.joints);
    for ((k, angle, translation), _) in reported.filter(|(_, on)| **on) {
        let name = &mech.joints[k].name;
        for (q, on) in [("angle", angle), ("translation", translation)] {
            if on {
                h.extend(["", "_dot", "_ddot"].iter().map(|d| format!("{name}.{q}{d}")));
            }
        }
    }
    h
}

/// A CSV field as RFC 4180 writes it: in double quotes, with its quotes doubled, when it
/// holds a comma, a quote, a carriage return or a line feed; as it is otherwise.
///
/// ```
/// use codegen::report::csv_field;
///
/// assert_eq!(csv_field("crank.r.x".into()), "crank.r.x");
/// assert_eq!(csv_field("a,\"b\"\nc.r.x".into()), "\"a,\"\"b\"\"\nc.r.x\"");
/// ```
#[must_use]
pub fn csv_field(field: Cow<'_, str>) -> Cow<'_, str> {
    if field.contains([',', '"', '\r', '\n']) {
        Cow::Owned(format!("\"{}\"", field.replace('"', "\"\"")))
    } else {
        field
    }
}

/// Appends `x` in shortest round-trip form (zmij, as JSON writes it; `NaN`, `inf` and `-inf`
/// as `{x:?}` writes them): the fewest significant digits that read back to `x` exactly.
///
/// Where two shortest forms both read back to `x`, zmij does not always pick the one closest
/// to `x`, as `{x:?}` does: 659260010478097.2 for the double `{x:?}` writes 659260010478097.3
/// (0.16 % of random doubles, always in the 16th digit). Both read back to the same double,
/// which is all CSV needs, and zmij writes several times faster.
fn push_number(buf: &mut Vec<u8>, x: f64) {
    if x.is_finite() {
        buf.extend_from_slice(zmij::Buffer::new().format_finite(x).as_bytes());
    } else if x.is_nan() {
        buf.extend_from_slice(b"NaN");
    } else if x > 0.0 {
        buf.extend_from_slice(b"inf");
    } else {
        buf.extend_from_slice(b"-inf");
    }
}

/// Appends the JSON text of `x` as serde_json writes it (zmij's shortest round trip; `null`
/// when not finite).
fn push_json(buf: &mut Vec<u8>, x: f64) {
    if x.is_finite() {
        buf.extend_from_slice(zmij::Buffer::new().format_finite(x).as_bytes());
    } else {
        buf.extend_from_slice(b"null");
    }
}

/// The text of the number last written at each place of a row (the k-th number written
/// since [`row`](Self::row)), so that a place holding the same double as in the row before
/// copies that text instead of formatting the number again: the same double always has the
/// same text. In the R-S-S-R's rows, 43 % of the numbers repeat the row before's (coordinates
/// its joints hold fixed, their zero rates).
#[derive(Clone, Debug, Default)]
struct Numbers {
    places: Vec<Place>,
    next: usize,
}

/// A number's bits and its shortest round-trip text (at most 24 bytes:
/// `-2.2250738585072014e-308`).
#[derive(Clone, Copy, Debug)]
struct Place {
    bits: u64,
    len: usize,
    text: [u8; 24],
}

impl Numbers {
    /// Starts a row: the next number is the first place's.
    fn row(&mut self) {
        self.next = 0;
    }

    /// Appends `x` as [`push_number`] does (CSV).
    fn csv(&mut self, buf: &mut Vec<u8>, x: f64) {
        if x.is_finite() { self.finite(buf, x) } else { push_number(buf, x) }
    }

    /// Appends `x` as [`push_json`] does.
    fn json(&mut self, buf: &mut Vec<u8>, x: f64) {
        if x.is_finite() { self.finite(buf, x) } else { push_json(buf, x) }
    }

    /// Appends the finite `x` in shortest round-trip form (zmij's), taking the text from its
    /// place when the place last held the same double.
    fn finite(&mut self, buf: &mut Vec<u8>, x: f64) {
        let bits = x.to_bits();
        if self.next == self.places.len() {
            // Bits that cannot be `x`'s: the first number at a new place is formatted.
            self.places.push(Place { bits: !bits, len: 0, text: [0; 24] });
        }
        let place = &mut self.places[self.next];
        self.next += 1;
        if place.bits != bits {
            let mut digits = zmij::Buffer::new();
            let text = digits.format_finite(x).as_bytes();
            place.text[..text.len()].copy_from_slice(text);
            (place.bits, place.len) = (bits, text.len());
        }
        // All 24 bytes, then the surplus dropped: a copy of fixed size is written inline,
        // where one of the text's own length calls `memcpy`, which costs more than the copy.
        let end = buf.len() + place.len;
        buf.extend_from_slice(&place.text);
        buf.truncate(end);
    }
}

/// Appends `xs` separated by commas, each led by a comma.
fn push_csv(buf: &mut Vec<u8>, xs: &[f64], numbers: &mut Numbers) {
    for &x in xs {
        buf.push(b',');
        numbers.csv(buf, x);
    }
}

/// Appends one CSV row with its line end.
fn write_csv_row(buf: &mut Vec<u8>, s: &StepResult, numbers: &mut Numbers) {
    numbers.row();
    numbers.csv(buf, s.t);
    buf.push(b',');
    let _ = write!(buf, "{}", s.iterations);
    buf.push(b',');
    numbers.csv(buf, s.residual);
    buf.push(b',');
    numbers.csv(buf, s.condition);
    buf.push(b',');
    for (k, name) in s.suspect.names().enumerate() {
        if k > 0 {
            buf.push(b' ');
        }
        buf.extend_from_slice(name.as_bytes());
    }
    for b in &s.bodies {
        for v in [&b.r[..], &b.p, &b.r_dot, &b.p_dot, &b.omega, &b.r_ddot, &b.p_ddot, &b.alpha] {
            push_csv(buf, v, numbers);
        }
    }
    for p in &s.points {
        for v in [&p.r, &p.v, &p.a] {
            push_csv(buf, v, numbers);
        }
    }
    for j in &s.joints {
        for v in [&j.angle, &j.translation].into_iter().flatten() {
            push_csv(buf, v, numbers);
        }
    }
    buf.push(b'\n');
}

/// The order in which JSON writes the bodies, points and joints of a step (serde_json's map:
/// by name, the last of equal names winning) and their keys as JSON text (`"crank":`).
struct JsonKeys {
    names: [Vec<String>; 3],
    order: [Vec<(usize, String)>; 3],
}

impl JsonKeys {
    fn new(s: &StepResult) -> Self {
        let names = [
            s.bodies.iter().map(|b| b.name.clone()).collect::<Vec<_>>(),
            s.points.iter().map(|p| p.name.clone()).collect(),
            s.joints.iter().map(|j| j.name.clone()).collect(),
        ];
        let order = names.each_ref().map(|names| {
            let mut idx: Vec<usize> = (0..names.len()).collect();
            idx.sort_by(|&a, &b| names[a].cmp(&names[b]));
            let mut kept: Vec<usize> = Vec::with_capacity(idx.len());
            for k in idx {
                match kept.last_mut() {
                    Some(last) if names[*last] == names[k] => *last = k,
                    _ => kept.push(k),
                }
            }
            kept.into_iter()
                .map(|k| {
                    let key = serde_json::to_string(&names[k]).expect("a string serialises");
                    (k, format!("{key}:"))
                })
                .collect()
        });
        Self { names, order }
    }

    /// Whether the step has the names these keys were made from.
    fn fits(&self, s: &StepResult) -> bool {
        self.names[0].iter().eq(s.bodies.iter().map(|b| &b.name))
            && self.names[1].iter().eq(s.points.iter().map(|p| &p.name))
            && self.names[2].iter().eq(s.joints.iter().map(|j| &j.name))
    }
}

/// Appends `"key":[x,y,…]`.
fn push_json_array(buf: &mut Vec<u8>, key: &str, xs: &[f64], numbers: &mut Numbers) {
    buf.extend_from_slice(key.as_bytes());
    buf.push(b'[');
    for (k, &x) in xs.iter().enumerate() {
        if k > 0 {
            buf.push(b',');
        }
        numbers.json(buf, x);
    }
    buf.push(b']');
}

/// Appends the JSON object of one step, byte for byte what `serde_json::to_string` makes of
/// [`step_json`].
fn write_step_json(buf: &mut Vec<u8>, s: &StepResult, keys: &JsonKeys, numbers: &mut Numbers) {
    numbers.row();
    buf.extend_from_slice(b"{\"bodies\":{");
    for (n, (k, key)) in keys.order[0].iter().enumerate() {
        let b = &s.bodies[*k];
        buf.extend_from_slice(if n > 0 { b",".as_slice() } else { b"" });
        buf.extend_from_slice(key.as_bytes());
        push_json_array(buf, "{\"alpha\":", &b.alpha, numbers);
        push_json_array(buf, ",\"omega\":", &b.omega, numbers);
        push_json_array(buf, ",\"p\":", &b.p, numbers);
        push_json_array(buf, ",\"p_ddot\":", &b.p_ddot, numbers);
        push_json_array(buf, ",\"p_dot\":", &b.p_dot, numbers);
        push_json_array(buf, ",\"r\":", &b.r, numbers);
        push_json_array(buf, ",\"r_ddot\":", &b.r_ddot, numbers);
        push_json_array(buf, ",\"r_dot\":", &b.r_dot, numbers);
        buf.push(b'}');
    }
    buf.extend_from_slice(b"},\"condition\":");
    numbers.json(buf, s.condition);
    buf.extend_from_slice(b",\"iterations\":");
    let _ = write!(buf, "{}", s.iterations);
    buf.extend_from_slice(b",\"joints\":{");
    for (n, (k, key)) in keys.order[2].iter().enumerate() {
        let j = &s.joints[*k];
        buf.extend_from_slice(if n > 0 { b",".as_slice() } else { b"" });
        buf.extend_from_slice(key.as_bytes());
        buf.push(b'{');
        let mut first = true;
        for (q, v) in [("angle", j.angle), ("translation", j.translation)] {
            if let Some([x, xd, xdd]) = v {
                // Keys in serde_json's order: q, q_ddot, q_dot.
                for (suffix, value) in [("", x), ("_ddot", xdd), ("_dot", xd)] {
                    if !first {
                        buf.push(b',');
                    }
                    first = false;
                    let _ = write!(buf, "\"{q}{suffix}\":");
                    numbers.json(buf, value);
                }
            }
        }
        buf.push(b'}');
    }
    buf.extend_from_slice(b"},\"points\":{");
    for (n, (k, key)) in keys.order[1].iter().enumerate() {
        let p = &s.points[*k];
        buf.extend_from_slice(if n > 0 { b",".as_slice() } else { b"" });
        buf.extend_from_slice(key.as_bytes());
        push_json_array(buf, "{\"a\":", &p.a, numbers);
        push_json_array(buf, ",\"r\":", &p.r, numbers);
        push_json_array(buf, ",\"v\":", &p.v, numbers);
        buf.push(b'}');
    }
    buf.push(b'}');
    if let Some(r) = &s.redundant {
        buf.extend_from_slice(b",\"redundant\":");
        let _ = serde_json::to_writer(&mut *buf, r);
    }
    buf.extend_from_slice(b",\"residual\":");
    numbers.json(buf, s.residual);
    buf.extend_from_slice(b",\"suspect\":[");
    for (k, name) in s.suspect.names().enumerate() {
        if k > 0 {
            buf.push(b',');
        }
        let _ = write!(buf, "\"{name}\"");
    }
    buf.extend_from_slice(b"],\"t\":");
    numbers.json(buf, s.t);
    buf.push(b'}');
}

/// The bodies, points and joints `solve` writes (`--select`): a flag per moving body, per
/// point and per reported joint ([`reported_joints`]), in file order.
#[derive(Clone, Debug)]
pub struct Selection {
    all: bool,
    bodies: Vec<bool>,
    points: Vec<bool>,
    joints: Vec<bool>,
}

/// A name of `--select` that is no moving body, point or joint of the mechanism.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "`{}` is no moving body, point or joint of the mechanism{}",
    printable(name),
    suggestion.as_deref().map(|c| format!(" (did you mean `{}`?)", printable(c))).unwrap_or_default()
)]
pub struct UnknownName {
    /// The name as given.
    pub name: String,
    /// The nearest name of the mechanism, when one is close.
    pub suggestion: Option<String>,
}

impl Selection {
    /// Every body, point and joint.
    #[must_use]
    pub fn all(mech: &Mechanism) -> Self {
        let moving = mech.bodies.iter().filter(|b| !b.ground).count();
        Self {
            all: true,
            bodies: vec![true; moving],
            points: vec![true; mech.points.len()],
            joints: vec![true; reported_joints(mech).len()],
        }
    }

    /// The moving bodies, points and joints named in `names` (a name selects every one of
    /// them it names: a point and a joint may share a name).
    ///
    /// # Errors
    /// The first name that is no moving body, point or joint of `mech`, with the nearest
    /// such name when one is close.
    pub fn named(mech: &Mechanism, names: &[String]) -> Result<Self, UnknownName> {
        let moving: Vec<&str> =
            mech.bodies.iter().filter(|b| !b.ground).map(|b| b.name.as_str()).collect();
        let points: Vec<&str> = mech.points.iter().map(|p| p.name.as_str()).collect();
        let joints: Vec<&str> = mech.joints.iter().map(|j| j.name.as_str()).collect();
        for name in names {
            if ![&moving, &points, &joints].iter().any(|list| list.contains(&name.as_str())) {
                let all = moving.iter().chain(&points).chain(&joints).copied();
                let suggestion = crate::validate::closest(name, all).map(str::to_owned);
                return Err(UnknownName { name: name.clone(), suggestion });
            }
        }
        let on = |n: &str| names.iter().any(|s| s == n);
        Ok(Self {
            all: false,
            bodies: moving.iter().map(|n| on(n)).collect(),
            points: points.iter().map(|n| on(n)).collect(),
            joints: reported_joints(mech)
                .into_iter()
                .map(|(k, _, _)| on(&mech.joints[k].name))
                .collect(),
        })
    }

    /// The selected part of `s`.
    fn apply(&self, s: &StepResult) -> StepResult {
        fn keep<T: Clone>(items: &[T], flags: &[bool]) -> Vec<T> {
            items.iter().zip(flags).filter(|(_, on)| **on).map(|(x, _)| x.clone()).collect()
        }
        StepResult {
            t: s.t,
            iterations: s.iterations,
            residual: s.residual,
            condition: s.condition,
            suspect: s.suspect,
            bodies: keep(&s.bodies, &self.bodies),
            points: keep(&s.points, &self.points),
            joints: keep(&s.joints, &self.joints),
            redundant: s.redundant.clone(),
        }
    }
}

fn write_table_step(out: &mut impl Write, s: &StepResult) -> io::Result<()> {
    // Names as a terminal shows them safely (the same replacements as diagnostics).
    let bodies: Vec<Cow<'_, str>> = s.bodies.iter().map(|b| printable(&b.name)).collect();
    let points: Vec<Cow<'_, str>> = s.points.iter().map(|p| printable(&p.name)).collect();
    let w = bodies.iter().chain(&points).map(|n| n.chars().count());
    let w = w.chain([5]).max().unwrap_or(5);
    let cells = |vals: &[&[f64]]| {
        vals.iter().flat_map(|v| v.iter()).map(|x| format!(" {x:>13.6}")).collect::<String>()
    };
    let head = |names: &[&str]| names.iter().map(|n| format!(" {n:>13}")).collect::<String>();
    writeln!(out)?;
    writeln!(
        out,
        "-----  TIME = {}  (Newton iterations {}, max |Φ| {:.1e}, condition {:.1e})  -----",
        s.t, s.iterations, s.residual, s.condition
    )?;
    if s.suspect.any() {
        writeln!(
            out,
            "SUSPECT: {} (fewer than 6 significant digits by the condition estimate)",
            s.suspect.names().collect::<Vec<_>>().join(", ")
        )?;
    }
    if let Some(r) = &s.redundant {
        writeln!(out, "redundant equations from here on: {}", redundant_list(r))?;
    }
    writeln!(out, "POSITION")?;
    writeln!(out, "{:<w$}{}", "BODY", head(&["X", "Y", "Z", "e0", "e1", "e2", "e3"]))?;
    for (b, name) in s.bodies.iter().zip(&bodies) {
        writeln!(out, "{name:<w$}{}", cells(&[&b.r, &b.p]))?;
    }
    writeln!(out, "VELOCITY")?;
    writeln!(
        out,
        "{:<w$}{}",
        "BODY",
        head(&["dX", "dY", "dZ", "de0", "de1", "de2", "de3", "w-x", "w-y", "w-z"])
    )?;
    for (b, name) in s.bodies.iter().zip(&bodies) {
        writeln!(out, "{name:<w$}{}", cells(&[&b.r_dot, &b.p_dot, &b.omega]))?;
    }
    writeln!(out, "ACCELERATION")?;
    writeln!(
        out,
        "{:<w$}{}",
        "BODY",
        head(&["ddX", "ddY", "ddZ", "dde0", "dde1", "dde2", "dde3", "dw-x", "dw-y", "dw-z"])
    )?;
    for (b, name) in s.bodies.iter().zip(&bodies) {
        writeln!(out, "{name:<w$}{}", cells(&[&b.r_ddot, &b.p_ddot, &b.alpha]))?;
    }
    if !s.points.is_empty() {
        writeln!(out, "POINTS OF INTEREST")?;
        writeln!(
            out,
            "{:<w$}{}",
            "POINT",
            head(&["X", "Y", "Z", "dX", "dY", "dZ", "ddX", "ddY", "ddZ"])
        )?;
        for (p, name) in s.points.iter().zip(&points) {
            writeln!(out, "{name:<w$}{}", cells(&[&p.r, &p.v, &p.a]))?;
        }
    }
    if !s.joints.is_empty() {
        writeln!(out, "JOINTS")?;
        let wj = s.joints.iter().map(|j| printable(&j.name).chars().count()).chain([5]).max();
        let wj = wj.unwrap_or(5);
        writeln!(
            out,
            "{:<wj$} {:<11}{}",
            "JOINT",
            "COORDINATE",
            head(&["VALUE", "RATE", "ACCEL"])
        )?;
        for j in &s.joints {
            for (q, v) in [("angle", &j.angle), ("translation", &j.translation)] {
                if let Some(v) = v {
                    writeln!(out, "{:<wj$} {q:<11}{}", printable(&j.name), cells(&[v]))?;
                }
            }
        }
    }
    Ok(())
}

/// The quantities [`Differences`] compares, in output order.
const DIFFERENCE_NAMES: [&str; 11] = [
    "r", "p", "r_dot", "p_dot", "omega", "r_ddot", "p_ddot", "alpha", "point_r", "point_v",
    "point_a",
];

/// The largest differences between two runs, accumulated step by step so that neither run is
/// kept: per quantity, the largest absolute difference and the largest magnitude in the first
/// run.
#[derive(Clone, Debug, Default)]
pub struct Differences {
    diff: [f64; 11],
    scale: [f64; 11],
}

impl Differences {
    /// Adds the step `a` of the first run and the step `b` of the second at the same time.
    pub fn add(&mut self, a: &StepResult, b: &StepResult) {
        let values = |s: &StepResult, k: usize| -> Vec<f64> {
            if k < 8 {
                s.bodies
                    .iter()
                    .flat_map(|b| {
                        let v: &[f64] = [
                            &b.r[..],
                            &b.p,
                            &b.r_dot,
                            &b.p_dot,
                            &b.omega,
                            &b.r_ddot,
                            &b.p_ddot,
                            &b.alpha,
                        ][k];
                        v.to_vec()
                    })
                    .collect()
            } else {
                s.points.iter().flat_map(|p| [p.r, p.v, p.a][k - 8]).collect()
            }
        };
        for k in 0..DIFFERENCE_NAMES.len() {
            for (u, v) in values(a, k).into_iter().zip(values(b, k)) {
                self.diff[k] = self.diff[k].max((u - v).abs());
                self.scale[k] = self.scale[k].max(u.abs());
            }
        }
    }

    /// Per quantity, the largest absolute difference and that relative to the largest
    /// magnitude in the first run (absolute when that is zero).
    #[must_use]
    pub fn finish(&self) -> Vec<(&'static str, f64, f64)> {
        DIFFERENCE_NAMES
            .iter()
            .enumerate()
            .map(|(k, &name)| {
                let (diff, scale) = (self.diff[k], self.scale[k]);
                (name, diff, if scale > 0.0 { diff / scale } else { diff })
            })
            .collect()
    }
}

/// Largest absolute and relative differences between two runs ([`Differences`] over their
/// steps in pairs).
#[must_use]
pub fn differences(a: &[StepResult], b: &[StepResult]) -> Vec<(&'static str, f64, f64)> {
    let mut d = Differences::default();
    for (x, y) in a.iter().zip(b) {
        d.add(x, y);
    }
    d.finish()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    /// Numbers at the edges of the layouts (zero, the notation changes, subnormals,
    /// extremes) and random bit patterns.
    fn samples() -> Vec<f64> {
        let mut xs = vec![
            0.0,
            -0.0,
            1.0,
            0.1,
            1e-4,
            9.999999999999999e-5,
            1e-5,
            1.5e-5,
            9.99999e-6,
            1e16,
            9999999999999998.0,
            1.5e16,
            1e300,
            5e-324,
            f64::MIN_POSITIVE,
            f64::MAX,
            f64::MIN,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            123_456_789.0,
            -5372.889999999999,
        ];
        let mut rng = rand::rngs::StdRng::seed_from_u64(16);
        xs.extend((0..200_000).map(|_| f64::from_bits(rng.random::<u64>())));
        xs.extend(
            (0..200_000)
                .map(|_| rng.random_range(-1e3..1e3) * 10f64.powi(rng.random_range(-20..20))),
        );
        xs
    }

    /// The significant digits of a number's text (without sign, point, leading or trailing
    /// zeros and exponent).
    fn significant_digits(text: &str) -> usize {
        let mantissa = text.split(['e', 'E']).next().unwrap_or("");
        let digits: String = mantissa.chars().filter(char::is_ascii_digit).collect();
        digits.trim_start_matches('0').trim_end_matches('0').len()
    }

    /// Whether `text` reads back (by the standard library's correctly rounded parser) to the
    /// very double `x`: the same bits, or NaN for NaN.
    fn reads_back(text: &str, x: f64) -> bool {
        text.parse::<f64>().is_ok_and(|y| y.to_bits() == x.to_bits() || (x.is_nan() && y.is_nan()))
    }

    #[test]
    fn csv_numbers_read_back_exactly_in_the_fewest_digits() {
        let mut buf = Vec::new();
        for x in samples() {
            buf.clear();
            push_number(&mut buf, x);
            let text = std::str::from_utf8(&buf).unwrap();
            assert!(reads_back(text, x), "{text} for {:#x}", x.to_bits());
            // The standard library's `{x:?}` is the shortest round trip: no digit more.
            if x.is_finite() {
                let shortest = format!("{x:?}");
                assert_eq!(
                    significant_digits(text),
                    significant_digits(&shortest),
                    "{text} {shortest}"
                );
            }
        }
    }

    #[test]
    fn json_numbers_are_what_serde_json_writes() {
        let mut buf = Vec::new();
        for x in samples() {
            buf.clear();
            push_json(&mut buf, x);
            let expected = serde_json::to_string(&x).unwrap();
            assert_eq!(std::str::from_utf8(&buf).unwrap(), expected, "{:#x}", x.to_bits());
        }
    }

    /// A step with every kind of entry, names out of order and repeated, and unusual numbers.
    fn awkward_step() -> StepResult {
        let body = |name: &str, x: f64| BodyResult {
            name: name.to_owned(),
            r: [x, -0.0, 1e-7],
            p: [1.0, 0.0, 2e-5, f64::NAN],
            r_dot: [3.0; 3],
            p_dot: [4.5; 4],
            omega: [1e20, -1e-300, 0.1],
            r_ddot: [6.0; 3],
            p_ddot: [7.0; 4],
            alpha: [8.0; 3],
        };
        let point = |name: &str, x: f64| PointResult {
            name: name.to_owned(),
            r: [x, 2.0, 3.0],
            v: [4.0; 3],
            a: [f64::INFINITY, 5.0, 6.0],
        };
        StepResult {
            t: 0.25,
            iterations: 3,
            residual: 1.2e-13,
            condition: 2.5e3,
            suspect: Suspect { velocity: true, acceleration: true },
            bodies: vec![body("z\"q", 1.0), body("crank", 2.0), body("crank", 3.0), body("é", 4.0)],
            points: vec![point("B", 1.0), point("A", 2.0)],
            joints: vec![
                JointResult { name: "O4".into(), angle: Some([1.0, 2.0, 3.0]), translation: None },
                JointResult {
                    name: "C".into(),
                    angle: Some([0.5, 0.25, 0.125]),
                    translation: Some([4.0, 5.0, 6.0]),
                },
                JointResult { name: "P".into(), angle: None, translation: Some([7.0, 8.0, 9.0]) },
            ],
            redundant: Some(vec!["joint \"J4\" row 1".into(), "driver é".into()]),
        }
    }

    #[test]
    fn a_json_step_is_what_serde_json_makes_of_step_json() {
        let s = awkward_step();
        let mut buf = Vec::new();
        write_step_json(&mut buf, &s, &JsonKeys::new(&s), &mut Numbers::default());
        let expected = serde_json::to_string(&step_json(&s)).unwrap();
        assert_eq!(String::from_utf8(buf).unwrap(), expected);
    }

    /// The numbers of a step in CSV column order, after t, iterations, residual, condition
    /// and suspect.
    fn csv_numbers(s: &StepResult) -> Vec<f64> {
        let mut xs = Vec::new();
        for b in &s.bodies {
            for v in [&b.r[..], &b.p, &b.r_dot, &b.p_dot, &b.omega, &b.r_ddot, &b.p_ddot, &b.alpha]
            {
                xs.extend_from_slice(v);
            }
        }
        for p in &s.points {
            xs.extend([p.r, p.v, p.a].iter().flatten());
        }
        for j in &s.joints {
            xs.extend([j.angle, j.translation].iter().flatten().flatten());
        }
        xs
    }

    /// Steps whose every number is one of `samples()` (finite ones when `finite`), in turn.
    fn sample_steps(finite: bool) -> Vec<StepResult> {
        let mut xs = samples().into_iter().filter(|x| !finite || x.is_finite()).cycle();
        let mut next = || xs.next().expect("an endless cycle");
        let template = awkward_step();
        (0..2_000)
            .map(|k| {
                let mut s = template.clone();
                s.t = next();
                s.residual = next();
                s.condition = next();
                s.suspect = Suspect { velocity: k % 2 == 0, acceleration: k % 3 == 0 };
                // Plain names: the CSV test splits at commas.
                for (n, b) in s.bodies.iter_mut().enumerate() {
                    b.name = format!("body{n}");
                    for v in [&mut b.r[..], &mut b.p, &mut b.r_dot, &mut b.p_dot, &mut b.omega] {
                        v.iter_mut().for_each(|x| *x = next());
                    }
                    for v in [&mut b.r_ddot[..], &mut b.p_ddot, &mut b.alpha] {
                        v.iter_mut().for_each(|x| *x = next());
                    }
                }
                for (n, p) in s.points.iter_mut().enumerate() {
                    p.name = format!("point{n}");
                    for v in [&mut p.r, &mut p.v, &mut p.a] {
                        v.iter_mut().for_each(|x| *x = next());
                    }
                }
                for j in &mut s.joints {
                    for v in [&mut j.angle, &mut j.translation].into_iter().flatten() {
                        v.iter_mut().for_each(|x| *x = next());
                    }
                }
                s
            })
            .collect()
    }

    #[test]
    fn every_number_a_csv_row_holds_reads_back_to_the_same_double() {
        // One row's numbers text after another's, as a writer keeps it: every step twice in
        // a row, so that the second copies every number's text from the first.
        let mut numbers = Numbers::default();
        let steps = std::iter::once(awkward_step()).chain(sample_steps(false));
        for s in steps.flat_map(|s| [s.clone(), s]) {
            let mut buf = Vec::new();
            write_csv_row(&mut buf, &s, &mut numbers);
            let text = String::from_utf8(buf).unwrap();
            let row = text.strip_suffix('\n').expect("a line end");
            let fields: Vec<&str> = row.split(',').collect();
            let leading = [s.t, s.residual, s.condition];
            for (field, x) in [fields[0], fields[2], fields[3]].into_iter().zip(leading) {
                assert!(reads_back(field, x), "{field} for {:#x}", x.to_bits());
            }
            assert_eq!(fields[1], s.iterations.to_string());
            assert_eq!(fields[4], s.suspect.names().collect::<Vec<_>>().join(" "));
            let numbers = csv_numbers(&s);
            assert_eq!(fields.len(), 5 + numbers.len());
            for (field, &x) in fields[5..].iter().zip(&numbers) {
                assert!(reads_back(field, x), "{field} for {:#x}", x.to_bits());
            }
        }
    }

    #[test]
    fn every_number_the_json_writer_writes_reads_back_to_the_same_double() {
        // JSON has no NaN or infinity (they are written as null): finite numbers only. The
        // whole document goes through the writer and serde_json's correctly rounded parser
        // (feature float_roundtrip). Every step twice in a row: the second copies the text of
        // the first's numbers.
        let steps: Vec<StepResult> =
            sample_steps(true).into_iter().flat_map(|s| [s.clone(), s]).collect();
        // The writer reads the mechanism's name only; the steps bring their own names.
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/rssr.toml");
        let loaded = crate::validate::load_file(&path);
        let Ok(loaded) = loaded else { panic!("examples/rssr.toml loads") };
        let mech = loaded.mechanism;
        let mut w = Writer::begin(Vec::new(), Format::Json, &mech, "generic", &[]).unwrap();
        for s in &steps {
            w.step(s).unwrap();
        }
        let out = w.finish(None).unwrap();
        let v: serde_json::Value = serde_json::from_slice(&out).expect("one JSON document");
        let written = v["steps"].as_array().expect("steps");
        assert_eq!(written.len(), steps.len());
        let same = |value: &serde_json::Value, x: f64| {
            value.as_f64().is_some_and(|y| y.to_bits() == x.to_bits())
        };
        for (json, s) in written.iter().zip(&steps) {
            for (key, x) in [("t", s.t), ("residual", s.residual), ("condition", s.condition)] {
                assert!(same(&json[key], x), "{key}: {} for {:#x}", json[key], x.to_bits());
            }
            // Repeated names keep the last body of that name, as serde_json's map does.
            for b in &s.bodies {
                let o = &json["bodies"][&b.name];
                let fields = [
                    ("r", &b.r[..]),
                    ("p", &b.p),
                    ("r_dot", &b.r_dot),
                    ("p_dot", &b.p_dot),
                    ("omega", &b.omega),
                    ("r_ddot", &b.r_ddot),
                    ("p_ddot", &b.p_ddot),
                    ("alpha", &b.alpha),
                ];
                for (key, xs) in fields {
                    for (k, &x) in xs.iter().enumerate() {
                        assert!(same(&o[key][k], x), "{}.{key}[{k}]: {}", b.name, o[key][k]);
                    }
                }
            }
            for p in &s.points {
                let o = &json["points"][&p.name];
                for (key, xs) in [("r", p.r), ("v", p.v), ("a", p.a)] {
                    for (k, &x) in xs.iter().enumerate() {
                        assert!(same(&o[key][k], x), "{}.{key}[{k}]: {}", p.name, o[key][k]);
                    }
                }
            }
            for j in &s.joints {
                let o = &json["joints"][&j.name];
                // Angles are made continuous across steps by the writer (`Unwrap`), so only
                // translations are written as they came.
                if let Some([x, xd, xdd]) = j.translation {
                    for (suffix, x) in [("", x), ("_dot", xd), ("_ddot", xdd)] {
                        let key = format!("translation{suffix}");
                        assert!(same(&o[&key], x), "{}.{key}: {}", j.name, o[&key]);
                    }
                }
            }
        }
    }

    /// Writer throughput on the R-S-S-R's frames (`cargo test -p codegen --release --lib
    /// writer_throughput -- --ignored --nocapture`); a measurement, not a check.
    #[test]
    #[ignore = "a benchmark: run it on purpose, in release"]
    fn writer_throughput() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../benches/rssr_revolution.toml");
        let mech = crate::validate::load_file(&path)
            .unwrap_or_else(|_| panic!("the benchmark loads"))
            .mechanism;
        let layout = layout(&mech);
        let eq = crate::generic::Equations::new(&mech);
        let prep = eq.prepare();
        let mut steps = Vec::new();
        crate::generic::Analysis::new(&eq, &prep)
            .run(|f| {
                steps.push(step_result(&mech, &layout, f));
                Ok::<(), ()>(())
            })
            .expect("the run completes");
        // One sink for every pass: after the first, its memory is the process's own, so that
        // the passes time the writers, not the kernel's first touch of fresh pages.
        let mut sink = Vec::with_capacity(1 << 26);
        for format in [Format::Csv, Format::Json] {
            let mut best = f64::INFINITY;
            let mut bytes = 0;
            for _ in 0..5 {
                sink.clear();
                let start = std::time::Instant::now();
                let mut w = Writer::begin(&mut sink, format, &mech, "generic", &[]).unwrap();
                for _ in 0..20 {
                    for s in &steps {
                        w.step(s).unwrap();
                    }
                }
                let out = w.finish(None).unwrap();
                best = best.min(start.elapsed().as_secs_f64());
                bytes = out.len();
            }
            println!(
                "{format:?}: {:.0} MB/s ({bytes} bytes in {best:.3} s)",
                bytes as f64 / best / 1e6
            );
        }
        assert!(!steps.is_empty());
    }
}
