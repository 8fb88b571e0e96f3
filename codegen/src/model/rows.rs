//! What each equation row is: the row layout both engines share (joint rows in file order,
//! then constraints, then drivers, then one Euler-parameter normalisation per moving body).

use super::Mechanism;

/// The entity an equation belongs to, for labels and error reports.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RowLabel {
    /// `joint "O4"`-style entity kind: [`RowLabel::JOINT`], [`RowLabel::CONSTRAINT`],
    /// [`RowLabel::DRIVER`] or [`RowLabel::BODY`] (a normalisation).
    pub kind: &'static str,
    /// The entity's name.
    pub name: String,
    /// 1-based row within the entity (joints have several).
    pub row: usize,
    /// Number of rows of the entity.
    pub rows: usize,
}

impl RowLabel {
    /// The kind of a joint's rows.
    pub const JOINT: &'static str = "joint";
    /// The kind of a constraint's row.
    pub const CONSTRAINT: &'static str = "constraint";
    /// The kind of a driver's row.
    pub const DRIVER: &'static str = "driver";
    /// The kind of a body's normalisation pᵀp − 1 = 0.
    pub const BODY: &'static str = "body";

    /// `joint O4 row 2`, `driver motor`, `body crank normalisation`.
    #[must_use]
    pub fn equation(&self) -> String {
        match self.kind {
            Self::BODY => format!("body {} normalisation", self.name),
            _ if self.rows > 1 => format!("{} {} row {}", self.kind, self.name, self.row),
            _ => format!("{} {}", self.kind, self.name),
        }
    }

    /// `joint O4`: the entity without the row.
    #[must_use]
    pub fn entity(&self) -> String {
        format!("{} {}", self.kind, self.name)
    }

    /// Whether the row is a body's normalisation.
    #[must_use]
    pub fn is_normalisation(&self) -> bool {
        self.kind == Self::BODY
    }
}

impl Mechanism {
    /// The label of every equation, in row order.
    #[must_use]
    pub fn row_labels(&self) -> Vec<RowLabel> {
        let mut labels = Vec::with_capacity(self.equations());
        let mut push = |kind: &'static str, name: &str, rows: usize| {
            for row in 1..=rows {
                labels.push(RowLabel { kind, name: name.to_owned(), row, rows });
            }
        };
        for joint in &self.joints {
            push(RowLabel::JOINT, &joint.name, joint.kind.equations());
        }
        for c in &self.constraints {
            push(RowLabel::CONSTRAINT, &c.name, 1);
        }
        for d in &self.drivers {
            push(RowLabel::DRIVER, &d.name, 1);
        }
        for b in self.bodies.iter().filter(|b| !b.ground) {
            push(RowLabel::BODY, &b.name, 1);
        }
        labels
    }

    /// The row of the first constraint: the number of joint rows.
    #[must_use]
    pub fn first_constraint_row(&self) -> usize {
        self.joints.iter().map(|j| j.kind.equations()).sum()
    }

    /// The row of the first driver.
    #[must_use]
    pub fn first_driver_row(&self) -> usize {
        self.first_constraint_row() + self.constraints.len()
    }
}
