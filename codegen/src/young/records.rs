//! The deck's records, read in YOUNG's order into a description (the table of the module
//! docs of `young`).

use std::f64::consts::TAU;

use super::lex::{Lexer, Token, decimal_difference, shown};
use super::{COUNT_NAMES, MAX_COUNT, layout, sanitise};
use crate::desc::{
    BodyDesc, ConstraintDesc, ConstraintType, CoordinateName, DriverCoordinate, DriverDesc,
    JointDesc, JointType, LawDesc, MechanismDesc, PointDesc, TimeDesc,
};
use crate::diag::Diagnostic;
use crate::model::{JOINT_TYPES, Need};

/// The record being read, for diagnostics: `revolute joint 2 (record 6)`.
struct Record {
    entity: String,
}

impl Record {
    /// The `k`-th item (1-based) of the record kind `what`, number `number` in the read order.
    fn new(what: &str, k: usize, number: usize) -> Self {
        Self { entity: format!("{what} {k} (record {number})") }
    }

    fn named(entity: &str) -> Self {
        Self { entity: entity.to_owned() }
    }
}

/// A parse result; the diagnostic is boxed to keep the `Ok` path small.
type Parsed<T> = Result<T, Box<Diagnostic>>;

/// Reads the records of a deck in YOUNG's order.
pub(super) struct Parser<'a> {
    lexer: Lexer<'a>,
    /// NBODY, once the header is read.
    nbody: usize,
}

impl<'a> Parser<'a> {
    pub(super) fn new(deck: &'a str) -> Self {
        Self { lexer: Lexer::new(deck), nbody: 0 }
    }

    /// The whole deck, up to and including the time line.
    pub(super) fn deck(&mut self, name: &str) -> Parsed<MechanismDesc> {
        let counts = self.header()?;
        let [nbody, ndrive, npoint, joint_counts @ .., nsimpl, nsimp2, ngroun] = counts;
        let mut bodies = self.bodies(nbody)?;
        let drivers = self.drivers(ndrive)?;
        let points = self.points(npoint)?;
        let mut joints = Vec::new();
        let decked = JOINT_TYPES.iter().filter_map(|spec| Some((spec.ty, spec.deck?)));
        for ((kind, record), count) in decked.zip(joint_counts) {
            for k in 1..=count {
                joints.push(self.joint(Record::new(record.what, k, record.number), kind, k)?);
            }
        }
        let mut constraints = self.simplified(nsimpl)?;
        constraints.extend(self.differences(nsimp2)?);
        self.grounded(ngroun, &mut bodies)?;
        let time = self.time()?;
        Ok(MechanismDesc {
            name: sanitise(name),
            description: Some(format!("Imported from the YOUNG deck {name}")),
            time,
            solver: None,
            bodies,
            joints,
            constraints,
            drivers,
            points,
        })
    }

    /// The 12 counts, checked against the deck's lines ([`layout`]).
    fn header(&mut self) -> Parsed<[usize; 12]> {
        let header = Record::named("header (the 12 counts)");
        let mut counts = [0; 12];
        for (count, field) in counts.iter_mut().zip(COUNT_NAMES) {
            *count = self.count(&header, field)?;
        }
        self.nbody = counts[0];
        if let Some((field, message, line)) = layout::mismatch(self.lexer.src, &counts) {
            return Err(Box::new(
                Diagnostic::error(message).entity(header.entity).field(field).at(None, line, 1),
            ));
        }
        Ok(counts)
    }

    /// Records 1: `x y z e0 e1 e2 e3`.
    fn bodies(&mut self, nbody: usize) -> Parsed<Vec<BodyDesc>> {
        let mut bodies = Vec::new();
        for k in 1..=nbody {
            let rec = Record::new("body", k, 1);
            let r = self.vec3(&rec, "")?;
            let p = [
                self.real(&rec, "e0")?,
                self.real(&rec, "e1")?,
                self.real(&rec, "e2")?,
                self.real(&rec, "e3")?,
            ];
            bodies.push(BodyDesc { name: body_name(k), ground: false, r: Some(r), p: Some(p) });
        }
        Ok(bodies)
    }

    /// Records 2: `body dir C B A`, absolute drivers with a polynomial law.
    fn drivers(&mut self, ndrive: usize) -> Parsed<Vec<DriverDesc>> {
        let mut drivers = Vec::new();
        for k in 1..=ndrive {
            let rec = Record::new("driver", k, 2);
            let body = self.body(&rec, "body")?;
            let coordinate = match self.direction(&rec, "dir")? {
                1 => DriverCoordinate::X,
                2 => DriverCoordinate::Y,
                3 => DriverCoordinate::Z,
                4 => DriverCoordinate::Rx,
                5 => DriverCoordinate::Ry,
                _ => DriverCoordinate::Rz,
            };
            let law = LawDesc {
                start: Some(self.real(&rec, "C")?),
                velocity: Some(self.real(&rec, "B")?),
                acceleration: Some(self.real(&rec, "A")?),
                ..LawDesc::default()
            };
            drivers.push(DriverDesc {
                name: format!("driver{k}"),
                joint: None,
                motion: None,
                body: Some(body_name(body)),
                point: None,
                coordinate: Some(coordinate),
                law,
            });
        }
        Ok(drivers)
    }

    /// Records 3: `body ξ η ζ`.
    fn points(&mut self, npoint: usize) -> Parsed<Vec<PointDesc>> {
        let mut points = Vec::new();
        for k in 1..=npoint {
            let rec = Record::new("point of interest", k, 3);
            let body = self.body(&rec, "body")?;
            let local = self.vec3(&rec, "")?;
            points.push(PointDesc { name: format!("point{k}"), body: body_name(body), local });
        }
        Ok(points)
    }

    /// Records 4 to 9: `i j Pi Pj`, then `Qi Qj` (axes Q − P) for the types with axes, `Hi Hj`
    /// (references H − P) for the translational joint; the screw's `Si Sj Ui Uj α`.
    fn joint(&mut self, rec: Record, kind: JointType, k: usize) -> Parsed<JointDesc> {
        let mut joint = self.joint_ends(&rec, kind, k)?;
        if kind == JointType::Screw {
            joint.point_i = Some(self.vec3(&rec, "Pi")?);
            joint.point_j = Some(self.vec3(&rec, "Pj")?);
            // YOUNG uses these four vectors as given: the `− P` is commented out in IN_SCREW.
            joint.axis_i = Some(self.vec3(&rec, "Si")?);
            joint.axis_j = Some(self.vec3(&rec, "Sj")?);
            joint.ref_i = Some(self.vec3(&rec, "Ui")?);
            joint.ref_j = Some(self.vec3(&rec, "Uj")?);
            joint.lead = Some(TAU * self.real(&rec, "alpha")?);
            return Ok(joint);
        }
        let spec = kind.spec();
        let pi = self.vec3_read(&rec, "Pi")?;
        let pj = self.vec3_read(&rec, "Pj")?;
        joint.point_i = Some(pi.value);
        joint.point_j = Some(pj.value);
        if spec.axes == Need::Required {
            joint.axis_i = Some(minus(&self.vec3_read(&rec, "Qi")?, &pi));
            joint.axis_j = Some(minus(&self.vec3_read(&rec, "Qj")?, &pj));
        }
        if spec.refs == Need::Required {
            joint.ref_i = Some(minus(&self.vec3_read(&rec, "Hi")?, &pi));
            joint.ref_j = Some(minus(&self.vec3_read(&rec, "Hj")?, &pj));
        }
        Ok(joint)
    }

    /// Records 10: `body dir c`, a `fix` of x, y, z, or of e1, e2, e3 = sin(c/2).
    fn simplified(&mut self, nsimpl: usize) -> Parsed<Vec<ConstraintDesc>> {
        let mut constraints = Vec::new();
        for k in 1..=nsimpl {
            let rec = Record::new("simplified constraint", k, 10);
            let body = self.body(&rec, "body")?;
            let dir = self.direction(&rec, "dir")?;
            let c = self.real(&rec, "value")?;
            // An angle c about a global axis fixes that Euler parameter at sin(c/2).
            let value = if dir <= 3 { c } else { (c / 2.0).sin() };
            constraints.push(ConstraintDesc {
                name: format!("simplified{k}"),
                kind: ConstraintType::Fix,
                body: Some(body_name(body)),
                body_i: None,
                body_j: None,
                coordinate: coordinate_name(dir),
                value,
            });
        }
        Ok(constraints)
    }

    /// Records 11: `bodyI bodyJ dir D`, a `coordinate_difference` with the raw D.
    fn differences(&mut self, nsimp2: usize) -> Parsed<Vec<ConstraintDesc>> {
        let mut constraints = Vec::new();
        for k in 1..=nsimp2 {
            let rec = Record::new("distance constraint", k, 11);
            let body_i = self.body(&rec, "bodyI")?;
            let body_j = self.body(&rec, "bodyJ")?;
            let dir = self.direction(&rec, "dir")?;
            let value = self.real(&rec, "value")?;
            constraints.push(ConstraintDesc {
                name: format!("difference{k}"),
                kind: ConstraintType::CoordinateDifference,
                body: None,
                body_i: Some(body_name(body_i)),
                body_j: Some(body_name(body_j)),
                coordinate: coordinate_name(dir),
                value,
            });
        }
        Ok(constraints)
    }

    /// Records 12: `body x y z α β δ`; the body becomes ground, placed there.
    fn grounded(&mut self, ngroun: usize, bodies: &mut [BodyDesc]) -> Parsed<()> {
        let mut grounded_by = vec![None; bodies.len()];
        for k in 1..=ngroun {
            let rec = Record::new("grounded body", k, 12);
            let (body, token) = self.body_token(&rec, "body")?;
            if let Some(first) = grounded_by[body - 1] {
                return Err(self.error(
                    &rec,
                    "body",
                    &token,
                    format!(
                        "token {}: body {body} is already grounded by grounded body {first}",
                        token.index
                    ),
                ));
            }
            grounded_by[body - 1] = Some(k);
            let r = self.vec3(&rec, "")?;
            let p = self.ground_angles(&rec)?;
            let ground = &mut bodies[body - 1];
            ground.ground = true;
            ground.r = Some(r);
            ground.p = Some(p);
        }
        Ok(())
    }

    /// `α β δ` of a grounded body: e_k = sin(angle/2) and e0 = +√(1 − e1² − e2² − e3²).
    fn ground_angles(&mut self, rec: &Record) -> Parsed<[f64; 4]> {
        let angle_token = self.peek_place();
        let e = [
            (self.real(rec, "alpha")? / 2.0).sin(),
            (self.real(rec, "beta")? / 2.0).sin(),
            (self.real(rec, "delta")? / 2.0).sin(),
        ];
        let vector_part = e.iter().map(|x| x * x).sum::<f64>();
        // Each sin² is exact to a few ulps, so a sum above 1 by more than 1e-12 cannot be
        // rounding: no unit Euler parameters have that vector part.
        if vector_part > 1.0 + 1e-12 {
            return Err(Box::new(
                Diagnostic::error(format!(
                    "token {}: the angles give e1² + e2² + e3² = {vector_part}, above 1, which no \
                     orientation has; YOUNG fixes e_k = sin(angle/2) for each angle separately",
                    angle_token.0
                ))
                .entity(rec.entity.clone())
                .field("alpha")
                .at(None, angle_token.1, angle_token.2),
            ));
        }
        let e0 = (1.0 - vector_part).max(0.0).sqrt();
        Ok([e0, e[0], e[1], e[2]])
    }

    /// Record 13: `Ti Te dT`.
    fn time(&mut self) -> Parsed<TimeDesc> {
        let rec = Record::named("time line (record 13)");
        Ok(TimeDesc {
            start: self.real(&rec, "Ti")?,
            end: self.real(&rec, "Te")?,
            step: Some(self.real(&rec, "dT")?),
            steps: None,
        })
    }

    /// The bodies `i j` that start every joint record, as a joint with no other fields.
    fn joint_ends(&mut self, rec: &Record, kind: JointType, k: usize) -> Parsed<JointDesc> {
        let i = self.body(rec, "i")?;
        let j = self.body(rec, "j")?;
        Ok(JointDesc {
            name: format!("{}{k}", kind.as_str()),
            kind,
            body_i: body_name(i),
            body_j: body_name(j),
            point_i: None,
            point_j: None,
            axis_i: None,
            axis_j: None,
            ref_i: None,
            ref_j: None,
            lead: None,
            distance: None,
        })
    }

    /// The next token, or an error saying that the deck ends where `what` was expected.
    fn token(&mut self, rec: &Record, field: &str, what: &str) -> Parsed<Token<'a>> {
        self.lexer.next_token().ok_or_else(|| {
            Box::new(
                Diagnostic::error(format!(
                    "the deck ends where token {} ({what}) was expected; check the header's counts \
                 against the records",
                    self.lexer.count + 1
                ))
                .entity(rec.entity.clone())
                .field(field)
                .at(None, self.lexer.line, self.lexer.column),
            )
        })
    }

    /// The index, line and column of the next token, or of the end of the deck, without
    /// consuming it.
    fn peek_place(&self) -> (usize, usize, usize) {
        let mut lexer = self.lexer.clone();
        match lexer.next_token() {
            Some(t) => (t.index, t.line, t.column),
            None => (lexer.count + 1, lexer.line, lexer.column),
        }
    }

    /// An error at `token`.
    fn error(
        &self,
        rec: &Record,
        field: &str,
        token: &Token<'_>,
        message: String,
    ) -> Box<Diagnostic> {
        Box::new(Diagnostic::error(message).entity(rec.entity.clone()).field(field).at(
            None,
            token.line,
            token.column,
        ))
    }

    /// An integer token (counts, body numbers and directions are Pascal integers).
    fn integer(&mut self, rec: &Record, field: &str) -> Parsed<(i64, Token<'a>)> {
        let token = self.token(rec, field, "an integer")?;
        match token.text.parse::<i64>() {
            Ok(value) => Ok((value, token)),
            Err(_) => {
                let digits = token.text.trim_start_matches(['+', '-']);
                let why = if !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit()) {
                    "is too large an integer"
                } else if token.text.parse::<f64>().is_ok() {
                    "is not an integer; YOUNG reads counts, body numbers and directions as \
                     integers"
                } else {
                    "is not an integer"
                };
                Err(self.error(
                    rec,
                    field,
                    &token,
                    format!("token {} {} {why}", token.index, shown(token.text)),
                ))
            }
        }
    }

    /// A count of the header: 0 to [`MAX_COUNT`].
    fn count(&mut self, rec: &Record, field: &str) -> Parsed<usize> {
        let (value, token) = self.integer(rec, field)?;
        let problem = if value < 0 {
            format!("the count {value} is negative")
        } else if value > MAX_COUNT {
            format!("the count {value} is above the limit of {MAX_COUNT}")
        } else {
            return usize::try_from(value).map_err(|_| {
                self.error(
                    rec,
                    field,
                    &token,
                    format!("token {}: the count {value} is too large", token.index),
                )
            });
        };
        Err(self.error(rec, field, &token, format!("token {}: {problem}", token.index)))
    }

    /// A body number, 1 to NBODY, and its token.
    fn body_token(&mut self, rec: &Record, field: &str) -> Parsed<(usize, Token<'a>)> {
        let (value, token) = self.integer(rec, field)?;
        match usize::try_from(value) {
            Ok(body) if (1..=self.nbody).contains(&body) => Ok((body, token)),
            _ => {
                let range = match self.nbody {
                    0 => "the deck has no bodies".to_owned(),
                    1 => "the deck has only body 1".to_owned(),
                    n => format!("the deck has bodies 1 to {n}"),
                };
                Err(self.error(
                    rec,
                    field,
                    &token,
                    format!("token {}: there is no body {value}; {range}", token.index),
                ))
            }
        }
    }

    /// A body number, 1 to NBODY.
    fn body(&mut self, rec: &Record, field: &str) -> Parsed<usize> {
        self.body_token(rec, field).map(|(body, _)| body)
    }

    /// A direction code, 1 to 6 (x, y, z, rotation about x, y, z).
    fn direction(&mut self, rec: &Record, field: &str) -> Parsed<u8> {
        let (value, token) = self.integer(rec, field)?;
        match u8::try_from(value) {
            Ok(dir @ 1..=6) => Ok(dir),
            _ => Err(self.error(
                rec,
                field,
                &token,
                format!(
                    "token {}: the direction {value} is not one of 1 to 6 (x, y, z, rotation \
                     about x, y, z)",
                    token.index
                ),
            )),
        }
    }

    /// A finite real number.
    fn real(&mut self, rec: &Record, field: &str) -> Parsed<f64> {
        self.real_read(rec, field).map(|(value, _)| value)
    }

    /// A finite real number and the text it was read from.
    fn real_read(&mut self, rec: &Record, field: &str) -> Parsed<(f64, &'a str)> {
        let token = self.token(rec, field, "a number")?;
        let problem = match token.text.parse::<f64>() {
            Ok(value) if value.is_finite() => return Ok((value, token.text)),
            Ok(_) => "is not a finite number",
            Err(_) => "is not a number",
        };
        let message = format!("token {} {} {problem}", token.index, shown(token.text));
        Err(self.error(rec, field, &token, message))
    }

    /// Three reals, fields `{prefix}.x`, `.y`, `.z` (or `x`, `y`, `z` for an empty prefix).
    fn vec3(&mut self, rec: &Record, prefix: &str) -> Parsed<[f64; 3]> {
        self.vec3_read(rec, prefix).map(|read| read.value)
    }

    /// Three reals and the text they were read from.
    fn vec3_read(&mut self, rec: &Record, prefix: &str) -> Parsed<Read3<'a>> {
        let mut read = Read3 { value: [0.0; 3], text: [""; 3] };
        for k in 0..3 {
            let axis = ["x", "y", "z"][k];
            let field =
                if prefix.is_empty() { axis.to_owned() } else { format!("{prefix}.{axis}") };
            (read.value[k], read.text[k]) = self.real_read(rec, &field)?;
        }
        Ok(read)
    }
}

/// A vector read from the deck, with the tokens it came from.
struct Read3<'a> {
    value: [f64; 3],
    text: [&'a str; 3],
}

/// The name of body `k` (1-based).
fn body_name(k: usize) -> String {
    format!("body{k}")
}

/// The coordinate of direction code 1–6 in simplified and distance constraints.
fn coordinate_name(dir: u8) -> CoordinateName {
    match dir {
        1 => CoordinateName::X,
        2 => CoordinateName::Y,
        3 => CoordinateName::Z,
        4 => CoordinateName::E1,
        5 => CoordinateName::E2,
        _ => CoordinateName::E3,
    }
}

/// `a − b`, computed from the decimal tokens where possible, so that the deck's
/// `Q − P = −0.05 − (−0.0475)` becomes `−0.0025` and not `−0.0025000000000000022`.
fn minus(a: &Read3<'_>, b: &Read3<'_>) -> [f64; 3] {
    std::array::from_fn(|k| {
        decimal_difference(a.text[k], b.text[k]).unwrap_or(a.value[k] - b.value[k])
    })
}
