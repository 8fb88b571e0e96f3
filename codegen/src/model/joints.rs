//! The joint types described by data, in one table: the fields each type reads, the
//! equation rows it contributes (their forms, in the order both engines write them), the
//! columns of the joint table of `docs/format.md` and the record of a YOUNG deck that holds
//! it. Validation takes the needs and the row counts from here, the deck importer the
//! records, and a test checks the documentation's table against it.
//!
//! The generic engine (`generic`) and the symbolic builder (`symbolic`) write the rows
//! themselves, one function per type in the same order and with the same names, as two
//! independent derivations whose agreement is tested; they follow [`JointSpec::rows`].

use super::{JointKind, JointType};

/// Whether a joint type takes a field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Need {
    /// The field must be given.
    Required,
    /// The field may be given (references: both or neither).
    Optional,
    /// Giving the field is an error.
    Unused,
}

/// The record of a YOUNG deck (`young`) that describes joints of one type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DeckRecord {
    /// The record number of `tests/reference/young-program.md` §2.4.
    pub number: usize,
    /// What the record is called in messages (`translational joint`).
    pub what: &'static str,
}

/// One joint type: what it reads and what it contributes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct JointSpec {
    /// The type (its spelling in files is `desc`'s, [`JointType::as_str`]).
    pub ty: JointType,
    /// `axis_i`, `axis_j` (the two points are required by every type).
    pub axes: Need,
    /// `ref_i`, `ref_j`.
    pub refs: Need,
    /// `lead`.
    pub lead: Need,
    /// `distance`.
    pub distance: Need,
    /// The equation rows in order, each as the form it sets to zero (d = P_j − P_i; a, the
    /// axes; b_i, c_i, the body-i normals of axis_i; x, y, φ of the screw in `generic`).
    pub rows: &'static [&'static str],
    /// The "extra keys" column of the documentation's joint table.
    pub keys: &'static str,
    /// The "equations" column of the documentation's joint table.
    pub equations: &'static str,
    /// The YOUNG record of this type, in the deck's order; `None` when decks have none.
    pub deck: Option<DeckRecord>,
}

use Need::{Optional as O, Required as R, Unused as U};

/// d = 0, component by component.
const COINCIDENT: [&str; 3] = ["d_x = 0", "d_y = 0", "d_z = 0"];

/// Every joint type, in the order of `JointType` and of a YOUNG deck's records.
pub const JOINT_TYPES: [JointSpec; 7] = [
    JointSpec {
        ty: JointType::Spherical,
        axes: U,
        refs: U,
        lead: U,
        distance: U,
        rows: &COINCIDENT,
        keys: "none",
        equations: "d = 0 (eq. 4.11)",
        deck: Some(DeckRecord { number: 4, what: "spherical joint" }),
    },
    JointSpec {
        ty: JointType::Universal,
        axes: R,
        refs: U,
        lead: U,
        distance: U,
        rows: &[COINCIDENT[0], COINCIDENT[1], COINCIDENT[2], "a_i·a_j = 0"],
        keys: "`axis_i`, `axis_j` (the cross-pin axes, ⟂ at assembly)",
        equations: "d = 0; a_i·a_j = 0 (eq. 4.14–4.19)",
        deck: Some(DeckRecord { number: 5, what: "universal joint" }),
    },
    JointSpec {
        ty: JointType::Revolute,
        axes: R,
        refs: O,
        lead: U,
        distance: U,
        rows: &[COINCIDENT[0], COINCIDENT[1], COINCIDENT[2], "b_i·a_j = 0", "c_i·a_j = 0"],
        keys: "`axis_i`, `axis_j`; `ref_i`, `ref_j` when driven",
        equations: "d = 0; b_i·a_j = 0, c_i·a_j = 0 (axes parallel, eq. 4.20–4.25)",
        deck: Some(DeckRecord { number: 6, what: "revolute joint" }),
    },
    JointSpec {
        ty: JointType::Cylindrical,
        axes: R,
        refs: O,
        lead: U,
        distance: U,
        rows: &["b_i·a_j = 0", "c_i·a_j = 0", "b_i·d = 0", "c_i·d = 0"],
        keys: "`axis_i`, `axis_j`; `ref_i`, `ref_j` when rotation-driven",
        equations: "b_i·a_j = 0, c_i·a_j = 0; b_i·d = 0, c_i·d = 0 (eq. 4.26–4.31)",
        deck: Some(DeckRecord { number: 7, what: "cylindrical joint" }),
    },
    JointSpec {
        ty: JointType::Prismatic,
        axes: R,
        refs: R,
        lead: U,
        distance: U,
        rows: &["b_i·a_j = 0", "c_i·a_j = 0", "b_i·d = 0", "c_i·d = 0", "ref_i·ref_j = 0"],
        keys: "`axis_i`, `axis_j`, `ref_i`, `ref_j`",
        equations: "cylindrical; ref_i·ref_j = 0 in global components (eq. 4.32–4.38)",
        deck: Some(DeckRecord { number: 8, what: "translational joint" }),
    },
    JointSpec {
        ty: JointType::Screw,
        axes: R,
        refs: R,
        lead: R,
        distance: U,
        rows: &["b_i·a_j = 0", "c_i·a_j = 0", "b_i·d = 0", "c_i·d = 0", "x sin φ − y cos φ = 0"],
        keys: "`axis_i`, `axis_j`, `ref_i`, `ref_j`, `lead`",
        equations: "cylindrical; x sin φ − y cos φ = 0 (below)",
        deck: Some(DeckRecord { number: 9, what: "screw joint" }),
    },
    JointSpec {
        ty: JointType::Distance,
        axes: U,
        refs: U,
        lead: U,
        distance: O,
        rows: &["(d·d − L²)/(2L) = 0"],
        keys: "`distance` (optional: from the initial estimates)",
        equations: "(d·d − L²)/(2L) = 0, so \\|d\\| = L",
        deck: None,
    },
];

impl JointType {
    /// The type's entry of [`JOINT_TYPES`].
    #[must_use]
    pub fn spec(self) -> &'static JointSpec {
        &JOINT_TYPES[self as usize]
    }
}

impl JointKind {
    /// The type of the joint, without its data.
    #[must_use]
    pub fn joint_type(&self) -> JointType {
        match self {
            Self::Spherical => JointType::Spherical,
            Self::Universal => JointType::Universal,
            Self::Revolute => JointType::Revolute,
            Self::Cylindrical => JointType::Cylindrical,
            Self::Prismatic => JointType::Prismatic,
            Self::Screw { .. } => JointType::Screw,
            Self::Distance { .. } => JointType::Distance,
        }
    }

    /// The type's entry of [`JOINT_TYPES`].
    #[must_use]
    pub fn spec(&self) -> &'static JointSpec {
        self.joint_type().spec()
    }
}

/// The documentation's row for one joint type, as `docs/format.md` prints it.
#[must_use]
pub fn docs_row(spec: &JointSpec) -> String {
    format!("| `{}` | {} | {} | {} |", spec.ty.as_str(), spec.keys, spec.rows.len(), spec.equations)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The table is indexed by `JointType as usize`, so its order must be the enum's.
    #[test]
    fn the_table_is_in_the_order_of_the_type() {
        for (k, spec) in JOINT_TYPES.iter().enumerate() {
            assert_eq!(spec.ty as usize, k, "{}", spec.ty.as_str());
            assert_eq!(spec.ty.spec().ty, spec.ty);
        }
    }

    /// The joint table of docs/format.md is the table's, row for row.
    #[test]
    fn the_format_docs_joint_table_is_the_table() {
        let docs = include_str!("../../../docs/format.md");
        let start = docs.find("| type | extra keys | rows | equations |").expect("joint table");
        let rows: Vec<&str> =
            docs[start..].lines().skip(2).take_while(|l| l.starts_with('|')).collect();
        let expected: Vec<String> = JOINT_TYPES.iter().map(docs_row).collect();
        assert_eq!(rows, expected, "docs/format.md's joint table differs from model::JOINT_TYPES");
    }
}
