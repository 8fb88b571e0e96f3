//! The thesis' legacy input decks (YOUNG) → descriptions, and descriptions → readable TOML.
//!
//! A deck is a free-format stream of whitespace-separated numbers (the program reads it with
//! Pascal `READ`, so line breaks do not matter): a header of 12 counts
//! `NBODY NDRIVE NPOINT NSPHER NUNIVE NREVOL NCYLIN NTRANS NSCREW NSIMPL NSIMP2 NGROUN`, then
//! the records of each kind in a fixed order (numbered 1 to 13 as in
//! `tests/reference/young-program.md` §2.4), ending with the time line `Ti Te dT`. Anything
//! after the time line is ignored; the thesis' decks carry free-text comments there.
//!
//! The mapping follows the contract (`docs/contract.md` §2):
//!
//! | record | tokens | becomes |
//! |---|---|---|
//! | 1 body | `x y z e0 e1 e2 e3` | `bodyK` with `r = [x, y, z]`, `p = [e0, e1, e2, e3]` |
//! | 2 driver | `body dir C B A` | `driverK`, absolute: `coordinate` x, y, z, rx, ry, rz; `law = { start = C, velocity = B, acceleration = A }` |
//! | 3 point | `body ξ η ζ` | `pointK` |
//! | 4 spherical | `i j Pi Pj` | `sphericalK` |
//! | 5–7 universal, revolute, cylindrical | `i j Pi Pj Qi Qj` | `axis = Q − P` |
//! | 8 translational | `i j Pi Pj Qi Qj Hi Hj` | `prismaticK`, `axis = Q − P`, `ref = H − P` |
//! | 9 screw | `i j Pi Pj Si Sj Ui Uj α` | `screwK`, `axis = S`, `ref = U` (no `− P`), `lead = 2π·α` |
//! | 10 simplified | `body dir c` | `simplifiedK`, `fix` of x, y, z, or e1, e2, e3 = sin(c/2) |
//! | 11 distance | `bodyI bodyJ dir D` | `differenceK`, `coordinate_difference` of x, y, z, e1, e2, e3 with the raw D |
//! | 12 grounded | `body x y z α β δ` | that body gets `ground = true`, `r = [x, y, z]`, `p` from the angles |
//! | 13 time | `Ti Te dT` | `[time]` start, end, step |
//!
//! Joints are numbered per type in deck order. Differences such as `Q − P` are taken from the
//! deck's decimal text and rounded once, so `−0.05 − (−0.0475)` gives `−0.0025`, where plain
//! `f64` subtraction gives `−0.0025000000000000022`: the two differ by about an ulp, which does
//! not change the mechanism, but the first is what the deck means and reads better.
//!
//! The distance constraint keeps its raw value for directions 4–6 because YOUNG subtracts Euler
//! parameters directly there (young-program.md §5.8), while simplified constraints and grounded
//! bodies take the thesis' sin(c/2) (§5.7).
//!
//! A grounded body's angles α, β, δ give `e_k = sin(angle/2)` for the vector part, as YOUNG's six
//! simplified constraints do, and `e0 = +√(1 − e1² − e2² − e3²)`. YOUNG leaves the sign of e0 to
//! the body's initial estimate; the positive root is chosen here because a ground body has no
//! initial estimate to take it from, and both signs describe the same orientation. The body
//! record of a grounded body is then not used. Every thesis deck uses zero angles.
//!
//! YOUNG's hard limits (10 bodies, 3 joints of each type, …) and its equation-count check are
//! not applied: the description format has no such limits, and `validate` counts equations.

use std::f64::consts::TAU;
use std::path::Path;

use crate::desc::{
    BodyDesc, ConstraintDesc, ConstraintType, CoordinateName, DriverCoordinate, DriverDesc,
    JointDesc, JointType, LawDesc, MechanismDesc, Motion, PointDesc, TimeDesc,
};
use crate::diag::Diagnostic;

mod layout;
#[cfg(test)]
mod tests;

/// Counts above this are refused before anything is read for them; the thesis' program
/// allows at most 70 equations, so any real deck is far below it.
const MAX_COUNT: i64 = 100_000;

/// The header's counts, in deck order.
const COUNT_NAMES: [&str; 12] = [
    "NBODY", "NDRIVE", "NPOINT", "NSPHER", "NUNIVE", "NREVOL", "NCYLIN", "NTRANS", "NSCREW",
    "NSIMPL", "NSIMP2", "NGROUN",
];

/// Parses a legacy deck into the equivalent description.
///
/// `name` names the deck, usually its file stem (`"4-bar"`). It is quoted in the description's
/// `description` and, sanitised as by [`name_from_path`] (`"4-bar"` → `"four_bar"`), becomes the
/// description's `name`. Entities are named `body1`, `revolute1`, `simplified1`, `driver1`,
/// `point1`, … as the contract's §2 says.
///
/// # Errors
///
/// Returns a [`Diagnostic`] for the first token that cannot be read: a token that is not a
/// number (or not an integer where YOUNG reads one), a count that is negative or above 100,000,
/// a body number out of range, a direction outside 1–6, a body grounded twice, ground angles
/// that no unit Euler parameters satisfy, or a deck that ends early. The diagnostic names the
/// record (`revolute joint 2 (record 6)`) as its entity, the field (`Qi.y`), the token's index
/// in its message, and the token's line and column.
#[expect(
    clippy::result_large_err,
    reason = "the contract's API returns the crate's Diagnostic by value; it is built once, on failure"
)]
pub fn import(deck: &str, name: &str) -> Result<MechanismDesc, Diagnostic> {
    Parser::new(deck).deck(name).map_err(|diag| *diag)
}

/// Reads the deck at `path` and imports it as [`import`] does, naming the description with
/// [`name_from_path`] and saying in its `description` which file it came from.
///
/// # Errors
///
/// Returns a [`Diagnostic`] when the file cannot be read, or the diagnostic of [`import`] with
/// the file set to `path`. Bytes that are not UTF-8 are read as U+FFFD, so binary input gives
/// an ordinary bad-token diagnostic.
#[expect(
    clippy::result_large_err,
    reason = "the same Diagnostic as `import` returns, with the file set"
)]
pub fn import_file(path: &Path) -> Result<MechanismDesc, Diagnostic> {
    let shown = path.display().to_string();
    let bytes = crate::validate::read_bounded(path, "deck")
        .map_err(|message| Diagnostic::error(message).entity("deck").at(Some(&shown), 1, 1))?;
    let text = String::from_utf8_lossy(&bytes);
    let mut desc = import(&text, &name_from_path(path)).map_err(|mut diag| {
        diag.file = Some(shown.clone());
        diag
    })?;
    let file_name = path.file_name().map_or(shown.clone(), |f| f.to_string_lossy().into_owned());
    desc.description = Some(format!("Imported from the YOUNG deck {file_name}"));
    Ok(desc)
}

/// The description name for a deck file: its stem, lowercased, with every run of other
/// characters than `a-z0-9` turned into one `_`.
///
/// A leading number is spelled out when a word follows it (`4-bar` → `four_bar`,
/// `5body` → `five_body`); otherwise the name gets the prefix `ex_` (`2-6-1` → `ex_2_6_1`).
/// An empty result becomes `mechanism`.
#[must_use]
pub fn name_from_path(path: &Path) -> String {
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    sanitise(&stem)
}

/// Makes `raw` a valid description name (`[a-z][a-z0-9_]*`), as described at
/// [`name_from_path`].
fn sanitise(raw: &str) -> String {
    let mut name = String::new();
    for c in raw.chars() {
        let c = c.to_ascii_lowercase();
        if c.is_ascii_lowercase() || c.is_ascii_digit() {
            name.push(c);
        } else if !name.is_empty() && !name.ends_with('_') {
            name.push('_');
        }
    }
    while name.ends_with('_') {
        name.pop();
    }
    if name.is_empty() {
        return "mechanism".to_owned();
    }
    if !name.starts_with(|c: char| c.is_ascii_digit()) {
        return name;
    }
    let digits = name.find(|c: char| !c.is_ascii_digit()).unwrap_or(name.len());
    let rest = name[digits..].trim_start_matches('_');
    let word_follows = rest.starts_with(|c: char| c.is_ascii_lowercase());
    match number_word(&name[..digits]) {
        Some(word) if word_follows => format!("{word}_{rest}"),
        _ => format!("ex_{name}"),
    }
}

/// The English word for a small number written in digits.
fn number_word(digits: &str) -> Option<&'static str> {
    const WORDS: [&str; 13] = [
        "zero", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten",
        "eleven", "twelve",
    ];
    digits.parse::<usize>().ok().and_then(|n| WORDS.get(n).copied())
}

/// A whitespace-separated token of the deck and where it starts.
#[derive(Clone, Copy, Debug)]
struct Token<'a> {
    text: &'a str,
    /// 1-based position in the token stream.
    index: usize,
    /// 1-based line.
    line: usize,
    /// 1-based column, in characters.
    column: usize,
}

/// Splits the deck into tokens on demand, keeping track of lines and columns.
#[derive(Clone)]
struct Lexer<'a> {
    src: &'a str,
    /// Byte offset of the first unread character.
    pos: usize,
    line: usize,
    column: usize,
    /// Tokens handed out so far.
    count: usize,
}

impl<'a> Lexer<'a> {
    fn new(src: &'a str) -> Self {
        // A byte-order mark is not part of the first token, and editors do not count it as a
        // column.
        let src = src.strip_prefix('\u{feff}').unwrap_or(src);
        Self { src, pos: 0, line: 1, column: 1, count: 0 }
    }

    /// The next token, or `None` at the end of the deck (then `line`, `column` are the end).
    fn next_token(&mut self) -> Option<Token<'a>> {
        let rest = &self.src[self.pos..];
        let blank = rest.find(|c: char| !c.is_whitespace()).unwrap_or(rest.len());
        for c in rest[..blank].chars() {
            if c == '\n' {
                self.line += 1;
                self.column = 1;
            } else {
                self.column += 1;
            }
        }
        self.pos += blank;
        let rest = &self.src[self.pos..];
        if rest.is_empty() {
            return None;
        }
        let len = rest.find(char::is_whitespace).unwrap_or(rest.len());
        let text = &rest[..len];
        self.count += 1;
        let token = Token { text, index: self.count, line: self.line, column: self.column };
        self.column += text.chars().count();
        self.pos += len;
        Some(token)
    }
}

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
struct Parser<'a> {
    lexer: Lexer<'a>,
    /// NBODY, once the header is read.
    nbody: usize,
}

impl<'a> Parser<'a> {
    fn new(deck: &'a str) -> Self {
        Self { lexer: Lexer::new(deck), nbody: 0 }
    }

    /// The whole deck, up to and including the time line.
    fn deck(&mut self, name: &str) -> Parsed<MechanismDesc> {
        let header = Record::named("header (the 12 counts)");
        let mut counts = [0; 12];
        for (count, field) in counts.iter_mut().zip(COUNT_NAMES) {
            *count = self.count(&header, field)?;
        }
        let [
            nbody,
            ndrive,
            npoint,
            nspher,
            nunive,
            nrevol,
            ncylin,
            ntrans,
            nscrew,
            nsimpl,
            nsimp2,
            ngroun,
        ] = counts;
        self.nbody = nbody;
        if let Some((field, message, line)) = layout::mismatch(self.lexer.src, &counts) {
            return Err(Box::new(
                Diagnostic::error(message).entity(header.entity).field(field).at(None, line, 1),
            ));
        }

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

        let mut points = Vec::new();
        for k in 1..=npoint {
            let rec = Record::new("point of interest", k, 3);
            let body = self.body(&rec, "body")?;
            let local = self.vec3(&rec, "")?;
            points.push(PointDesc { name: format!("point{k}"), body: body_name(body), local });
        }

        let mut joints = Vec::new();
        for k in 1..=nspher {
            let rec = Record::new("spherical joint", k, 4);
            let mut joint = self.joint_ends(&rec, JointType::Spherical, k)?;
            joint.point_i = Some(self.vec3(&rec, "Pi")?);
            joint.point_j = Some(self.vec3(&rec, "Pj")?);
            joints.push(joint);
        }
        let axial = [
            (nunive, JointType::Universal, "universal joint", 5),
            (nrevol, JointType::Revolute, "revolute joint", 6),
            (ncylin, JointType::Cylindrical, "cylindrical joint", 7),
            (ntrans, JointType::Prismatic, "translational joint", 8),
        ];
        for (count, kind, what, number) in axial {
            for k in 1..=count {
                let rec = Record::new(what, k, number);
                let mut joint = self.joint_ends(&rec, kind, k)?;
                let pi = self.vec3_read(&rec, "Pi")?;
                let pj = self.vec3_read(&rec, "Pj")?;
                joint.point_i = Some(pi.value);
                joint.point_j = Some(pj.value);
                joint.axis_i = Some(minus(&self.vec3_read(&rec, "Qi")?, &pi));
                joint.axis_j = Some(minus(&self.vec3_read(&rec, "Qj")?, &pj));
                if kind == JointType::Prismatic {
                    joint.ref_i = Some(minus(&self.vec3_read(&rec, "Hi")?, &pi));
                    joint.ref_j = Some(minus(&self.vec3_read(&rec, "Hj")?, &pj));
                }
                joints.push(joint);
            }
        }
        for k in 1..=nscrew {
            let rec = Record::new("screw joint", k, 9);
            let mut joint = self.joint_ends(&rec, JointType::Screw, k)?;
            joint.point_i = Some(self.vec3(&rec, "Pi")?);
            joint.point_j = Some(self.vec3(&rec, "Pj")?);
            // YOUNG uses these four vectors as given: the `− P` is commented out in IN_SCREW.
            joint.axis_i = Some(self.vec3(&rec, "Si")?);
            joint.axis_j = Some(self.vec3(&rec, "Sj")?);
            joint.ref_i = Some(self.vec3(&rec, "Ui")?);
            joint.ref_j = Some(self.vec3(&rec, "Uj")?);
            joint.lead = Some(TAU * self.real(&rec, "alpha")?);
            joints.push(joint);
        }

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

        let mut grounded_by = vec![None; nbody];
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
            let angle_token = self.peek_place();
            let e = [
                (self.real(&rec, "alpha")? / 2.0).sin(),
                (self.real(&rec, "beta")? / 2.0).sin(),
                (self.real(&rec, "delta")? / 2.0).sin(),
            ];
            let vector_part = e.iter().map(|x| x * x).sum::<f64>();
            // Each sin² is exact to a few ulps, so a sum above 1 by more than 1e-12 cannot be
            // rounding: no unit Euler parameters have that vector part.
            if vector_part > 1.0 + 1e-12 {
                return Err(Box::new(Diagnostic::error(format!(
                    "token {}: the angles give e1² + e2² + e3² = {vector_part}, above 1, which no \
                     orientation has; YOUNG fixes e_k = sin(angle/2) for each angle separately",
                    angle_token.0
                ))
                .entity(rec.entity)
                .field("alpha")
                .at(None, angle_token.1, angle_token.2)));
            }
            let e0 = (1.0 - vector_part).max(0.0).sqrt();
            let ground = &mut bodies[body - 1];
            ground.ground = true;
            ground.r = Some(r);
            ground.p = Some([e0, e[0], e[1], e[2]]);
        }

        let rec = Record::named("time line (record 13)");
        let time = TimeDesc {
            start: self.real(&rec, "Ti")?,
            end: self.real(&rec, "Te")?,
            step: Some(self.real(&rec, "dT")?),
            steps: None,
        };

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

/// The exact difference of two decimal numbers, rounded once to the nearest `f64`; `None`
/// when either is not a plain decimal (`-1.5e-3`) or the exact difference does not fit an
/// `i128` mantissa.
fn decimal_difference(a: &str, b: &str) -> Option<f64> {
    let (ma, ea) = decimal(a)?;
    let (mb, eb) = decimal(b)?;
    let e = ea.min(eb);
    let scaled = |m: i128, from: i32| {
        let shift = u32::try_from(from.checked_sub(e)?).ok()?;
        m.checked_mul(10_i128.checked_pow(shift)?)
    };
    let d = scaled(ma, ea)?.checked_sub(scaled(mb, eb)?)?;
    // Rust parses decimal text to the correctly rounded f64.
    format!("{d}e{e}").parse().ok()
}

/// A decimal number `m·10^e` from text such as `-0.0475`, `1.`, `.5` or `2.5E-3`.
fn decimal(text: &str) -> Option<(i128, i32)> {
    let (mantissa, exponent) = match text.find(['e', 'E']) {
        Some(at) => (&text[..at], text[at + 1..].parse::<i32>().ok()?),
        None => (text, 0),
    };
    let (negative, digits) = match mantissa.strip_prefix('-') {
        Some(digits) => (true, digits),
        None => (false, mantissa.strip_prefix('+').unwrap_or(mantissa)),
    };
    let (whole, fraction) = digits.split_once('.').unwrap_or((digits, ""));
    let all_digits = |s: &str| s.bytes().all(|b| b.is_ascii_digit());
    if whole.len() + fraction.len() == 0 || !all_digits(whole) || !all_digits(fraction) {
        return None;
    }
    let significant = format!("{whole}{fraction}");
    let significant = significant.trim_start_matches('0');
    // An i128 holds any 38-digit number; 30 leaves room for aligning two exponents.
    if significant.len() > 30 {
        return None;
    }
    let m: i128 = if significant.is_empty() { 0 } else { significant.parse().ok()? };
    let e = exponent.checked_sub(i32::try_from(fraction.len()).ok()?)?;
    Some((if negative { -m } else { m }, e))
}

/// A token quoted for a message, shortened when long and with control characters escaped.
fn shown(text: &str) -> String {
    const MAX_CHARS: usize = 24;
    let mut out: String = text.chars().take(MAX_CHARS).flat_map(char::escape_debug).collect();
    if text.chars().nth(MAX_CHARS).is_some() {
        out.push('…');
    }
    format!("`{out}`")
}

/// Writes a description as readable TOML, in the layout of the contract's example: top-level
/// keys, `[time]`, `[solver]`, then `[[bodies]]`, `[[joints]]`, `[[constraints]]`,
/// `[[drivers]]` and `[[points]]` in order, vectors and laws inline.
///
/// `comment` is written first, each line prefixed with `# ` (nothing when it is empty).
/// Floats are written in Rust's shortest round-trip form, so
/// `toml::from_str::<MechanismDesc>(&to_toml(&d, c)) == d` for every description whose numbers
/// are finite (non-finite ones are written as TOML's `nan` and `inf`).
#[must_use]
pub fn to_toml(desc: &MechanismDesc, comment: &str) -> String {
    let mut w = TomlWriter::default();
    for line in comment.lines() {
        w.out.push('#');
        if !line.is_empty() {
            w.out.push(' ');
            w.out.push_str(line);
        }
        w.out.push('\n');
    }
    if !comment.is_empty() {
        w.out.push('\n');
    }
    w.string("name", &desc.name);
    if let Some(description) = &desc.description {
        w.string("description", description);
    }

    w.header("[time]");
    w.float("start", desc.time.start);
    w.float("end", desc.time.end);
    if let Some(step) = desc.time.step {
        w.float("step", step);
    }
    if let Some(steps) = desc.time.steps {
        w.raw("steps", &steps.to_string());
    }

    if let Some(solver) = &desc.solver {
        w.header("[solver]");
        if let Some(tolerance) = solver.tolerance {
            w.float("tolerance", tolerance);
        }
        if let Some(max_iterations) = solver.max_iterations {
            w.raw("max_iterations", &max_iterations.to_string());
        }
    }

    for body in &desc.bodies {
        w.header("[[bodies]]");
        w.string("name", &body.name);
        if body.ground {
            w.raw("ground", "true");
        }
        w.opt_vec("r", body.r.as_ref().map(|v| &v[..]));
        w.opt_vec("p", body.p.as_ref().map(|v| &v[..]));
    }

    for joint in &desc.joints {
        w.header("[[joints]]");
        w.string("name", &joint.name);
        w.string("type", joint.kind.as_str());
        w.string("body_i", &joint.body_i);
        w.string("body_j", &joint.body_j);
        let vectors = [
            ("point_i", &joint.point_i),
            ("point_j", &joint.point_j),
            ("axis_i", &joint.axis_i),
            ("axis_j", &joint.axis_j),
            ("ref_i", &joint.ref_i),
            ("ref_j", &joint.ref_j),
        ];
        for (key, value) in vectors {
            w.opt_vec(key, value.as_ref().map(|v| &v[..]));
        }
        if let Some(lead) = joint.lead {
            w.float("lead", lead);
        }
        if let Some(distance) = joint.distance {
            w.float("distance", distance);
        }
    }

    for constraint in &desc.constraints {
        w.header("[[constraints]]");
        w.string("name", &constraint.name);
        w.string(
            "type",
            match constraint.kind {
                ConstraintType::Fix => "fix",
                ConstraintType::CoordinateDifference => "coordinate_difference",
            },
        );
        for (key, value) in [
            ("body", &constraint.body),
            ("body_i", &constraint.body_i),
            ("body_j", &constraint.body_j),
        ] {
            if let Some(value) = value {
                w.string(key, value);
            }
        }
        w.string("coordinate", constraint.coordinate.as_str());
        w.float("value", constraint.value);
    }

    for driver in &desc.drivers {
        w.header("[[drivers]]");
        w.string("name", &driver.name);
        if let Some(joint) = &driver.joint {
            w.string("joint", joint);
        }
        if let Some(motion) = driver.motion {
            w.string(
                "motion",
                match motion {
                    Motion::Rotation => "rotation",
                    Motion::Translation => "translation",
                },
            );
        }
        if let Some(body) = &driver.body {
            w.string("body", body);
        }
        if let Some(point) = &driver.point {
            w.string("point", point);
        }
        if let Some(coordinate) = driver.coordinate {
            w.string("coordinate", coordinate.as_str());
        }
        let law = &driver.law;
        if law.input {
            w.string("law", "input");
            continue;
        }
        let members = [
            ("start", law.start),
            ("velocity", law.velocity),
            ("acceleration", law.acceleration),
            ("offset", law.offset),
            ("amplitude", law.amplitude),
            ("frequency", law.frequency),
            ("phase", law.phase),
        ];
        let inline: Vec<String> = members
            .iter()
            .filter_map(|(key, value)| value.map(|v| format!("{key} = {}", toml_float(v))))
            .collect();
        let table = if inline.is_empty() {
            "{}".to_owned()
        } else {
            format!("{{ {} }}", inline.join(", "))
        };
        w.raw("law", &table);
    }

    for point in &desc.points {
        w.header("[[points]]");
        w.string("name", &point.name);
        w.string("body", &point.body);
        w.opt_vec("local", Some(&point.local[..]));
    }
    w.out
}

/// Accumulates the TOML text; writing to a `String` cannot fail, so no method returns a
/// `Result`.
#[derive(Default)]
struct TomlWriter {
    out: String,
}

impl TomlWriter {
    /// A blank line, then a table header.
    fn header(&mut self, header: &str) {
        self.out.push('\n');
        self.out.push_str(header);
        self.out.push('\n');
    }

    /// `key = value` with the value written as given.
    fn raw(&mut self, key: &str, value: &str) {
        self.out.push_str(key);
        self.out.push_str(" = ");
        self.out.push_str(value);
        self.out.push('\n');
    }

    fn string(&mut self, key: &str, value: &str) {
        self.raw(key, &toml_string(value));
    }

    fn float(&mut self, key: &str, value: f64) {
        self.raw(key, &toml_float(value));
    }

    /// `key = [a, b, c]` when the vector is present.
    fn opt_vec(&mut self, key: &str, value: Option<&[f64]>) {
        if let Some(value) = value {
            let items: Vec<String> = value.iter().map(|&x| toml_float(x)).collect();
            self.raw(key, &format!("[{}]", items.join(", ")));
        }
    }
}

/// A float in TOML syntax that parses back to the same `f64`: Rust's `{:?}` gives the
/// shortest round-trip form and always a `.` or an exponent (`0.0`, `1.19e-7`), which TOML
/// reads as a float.
fn toml_float(x: f64) -> String {
    if x.is_nan() {
        "nan".to_owned()
    } else if x.is_infinite() {
        if x > 0.0 { "inf" } else { "-inf" }.to_owned()
    } else {
        format!("{x:?}")
    }
}

/// A TOML basic string: quotes, backslashes and control characters escaped.
fn toml_string(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\t' => out.push_str("\\t"),
            '\r' => out.push_str("\\r"),
            c if c.is_control() => out.push_str(&format!("\\u{:04X}", u32::from(c))),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}
