//! Block decompositions against the structure the equations have by construction: driven open
//! chains (one orientation block and three closed-form position blocks per link), independent
//! arms (no block spans two arms), the R-S-S-R (one loop block), and random block-triangular
//! structures with their rows and columns shuffled (the planted blocks are found again).

use std::collections::BTreeSet;

use proptest::prelude::*;
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};

use super::{Blocks, Kind, Part, StructurallySingular, matching, triangular};
use crate::model::{Mechanism, RowLabel};
use crate::symbolic::Symbolic;
use crate::testing::{load_example, load_toml};

/// The equations of every block involve only its own unknowns and those of earlier blocks, and
/// the blocks partition the rows and the unknowns.
fn assert_lower_triangular(pattern: &[Vec<usize>], n: usize, blocks: &[Part]) {
    let mut block_of_column = vec![usize::MAX; n];
    for (b, (rows, columns)) in blocks.iter().enumerate() {
        assert_eq!(rows.len(), columns.len(), "block {b} is square");
        for &c in columns {
            assert_eq!(block_of_column[c], usize::MAX, "column {c} in one block");
            block_of_column[c] = b;
        }
    }
    assert!(block_of_column.iter().all(|&b| b != usize::MAX), "every column in a block");
    let rows: BTreeSet<usize> = blocks.iter().flat_map(|(r, _)| r.iter().copied()).collect();
    assert_eq!(rows.len(), pattern.len(), "every row in exactly one block");
    assert_eq!(blocks.iter().map(|(r, _)| r.len()).sum::<usize>(), pattern.len());
    for (b, (rows, _)) in blocks.iter().enumerate() {
        for &r in rows {
            for &c in &pattern[r] {
                assert!(
                    block_of_column[c] <= b,
                    "row {r} of block {b} uses column {c} of a later block"
                );
            }
        }
    }
}

/// The decomposition of a description's reduced system, checked triangular.
fn decompose(mech: &Mechanism) -> (Symbolic, Blocks) {
    let sys = Symbolic::build_full(mech).expect("the system builds");
    let blocks = Blocks::of(&sys, mech);
    let pattern: Vec<Vec<usize>> =
        sys.jac.iter().map(|row| row.iter().map(|&(c, _)| c).collect()).collect();
    let parts: Vec<_> =
        blocks.blocks.iter().map(|b| (b.rows.clone(), b.unknowns.clone())).collect();
    assert_lower_triangular(&pattern, sys.unknowns.len(), &parts);
    (sys, blocks)
}

/// `body.coordinate` for every unknown of a block.
fn unknown_names(mech: &Mechanism, sys: &Symbolic, unknowns: &[usize]) -> BTreeSet<String> {
    const NAMES: [&str; 7] = ["x", "y", "z", "e0", "e1", "e2", "e3"];
    unknowns
        .iter()
        .map(|&k| {
            let (b, c) = sys.unknowns[k];
            format!("{}.{}", mech.bodies[b.0].name, NAMES[c])
        })
        .collect()
}

/// The equations of a block, as `mechgen check` names them.
fn row_names(sys: &Symbolic, rows: &[usize]) -> BTreeSet<String> {
    rows.iter().map(|&r| sys.rows[r].equation()).collect()
}

fn set(names: &[String]) -> BTreeSet<String> {
    names.iter().cloned().collect()
}

/// Every link `(joint, driver, body)` of driven open chains must give, in this order or after
/// the blocks of the link before it: the orientation block of four (the joint's two axis rows
/// hold a_j ∥ a_i with body i known, the driver sets the angle, the normalisation |p| = 1),
/// a rotation about the joint's axis in closed form; then x, y and z each alone from the
/// joint's coincident rows, closed form (they enter those rows with coefficient 1). No block
/// is implicit.
fn assert_driven_links(mech: &Mechanism, links: &[(String, String, String)]) {
    let (sys, blocks) = decompose(mech);
    assert_eq!(blocks.blocks.len(), 4 * links.len());
    assert_eq!(blocks.closed_form(), 4 * links.len());
    assert_eq!(blocks.rotations(), links.len());
    assert_eq!(blocks.largest_implicit(), 0);
    for (joint, driver, body) in links {
        let orientation = set(&["e0", "e1", "e2", "e3"].map(|e| format!("{body}.{e}")));
        let found = blocks
            .blocks
            .iter()
            .position(|b| unknown_names(mech, &sys, &b.unknowns) == orientation)
            .unwrap_or_else(|| panic!("{body}: no block of its four Euler parameters"));
        let block = &blocks.blocks[found];
        let Kind::Rotation(rotation) = block.kind else {
            panic!("{body}: its orientation block is {:?}, not a rotation", block.kind)
        };
        assert_eq!(mech.bodies[rotation.body.0].name, *body);
        assert_eq!(mech.joints[rotation.joint].name, *joint);
        assert!(!rotation.linear, "{body}: a joint angle's row is quadratic");
        let rows = set(&[
            format!("joint {joint} row 4"),
            format!("joint {joint} row 5"),
            format!("driver {driver}"),
            format!("body {body} normalisation"),
        ]);
        assert_eq!(row_names(&sys, &block.rows), rows, "{body}");
        for (k, axis) in ["x", "y", "z"].iter().enumerate() {
            let at = blocks
                .blocks
                .iter()
                .position(|b| {
                    unknown_names(mech, &sys, &b.unknowns) == set(&[format!("{body}.{axis}")])
                })
                .unwrap_or_else(|| panic!("{body}.{axis}: not a block of its own"));
            let block = &blocks.blocks[at];
            assert_eq!(block.kind, Kind::ClosedForm, "{body}.{axis}");
            assert_eq!(
                row_names(&sys, &block.rows),
                set(&[format!("joint {joint} row {}", k + 1)])
            );
            // The point of body j on the joint depends on its orientation.
            assert!(at > found, "{body}.{axis} is solved after the orientation");
        }
    }
}

#[test]
fn a_driven_chain_is_one_orientation_block_and_three_closed_form_positions_per_link() {
    let n = 8;
    let mech = load_toml(&crate::scale::chain(n, 3));
    let links: Vec<_> =
        (1..=n).map(|k| (format!("hinge{k}"), format!("motor{k}"), format!("link{k}"))).collect();
    assert_driven_links(&mech, &links);
}

#[test]
fn ten_independent_arms_decompose_arm_by_arm() {
    let mech = load_toml(&crate::scale::arms(10, 6, 3));
    let links: Vec<_> = (1..=10)
        .flat_map(|a| {
            (1..=6).map(move |k| {
                (format!("arm{a}_joint{k}"), format!("arm{a}_motor{k}"), format!("arm{a}_link{k}"))
            })
        })
        .collect();
    assert_driven_links(&mech, &links);
}

#[test]
fn the_rssr_is_one_loop_block_and_its_driven_parts() {
    let mech = load_example("rssr.toml");
    let (sys, blocks) = decompose(&mech);
    // O2 places the crank's origin (its point_j is [0, 0, 0]), A the coupler's and O4 the
    // rocker's: nine closed-form coordinates. The crank's orientation is O2's axis rows, the
    // motor and its normalisation; the loop is what is left: the coupler's e0, e1, e3 (e2 is
    // fixed) and the rocker's four Euler parameters, held by B, O4's axis rows and the two
    // normalisations.
    assert_eq!(blocks.sizes().into_iter().collect::<Vec<_>>(), [(1, 9), (4, 1), (7, 1)]);
    assert_eq!(blocks.closed_form(), 10);
    assert_eq!(blocks.rotations(), 1);
    assert_eq!(blocks.largest_implicit(), 7);
    // Exactly one implicit block: the loop.
    let implicit: Vec<_> = blocks.blocks.iter().filter(|b| b.kind == Kind::Implicit).collect();
    assert_eq!(implicit.len(), 1);
    assert_eq!(implicit[0].unknowns.len(), 7);
    // The crank's orientation: an absolute rotation about z (the motor), linear in its
    // Euler parameters.
    let crank = blocks.blocks.iter().find_map(|b| match b.kind {
        Kind::Rotation(r) => Some(r),
        _ => None,
    });
    let crank = crank.expect("the crank's orientation is a rotation block");
    assert_eq!(mech.bodies[crank.body.0].name, "crank");
    assert!(crank.linear);
    let closed: BTreeSet<String> = blocks
        .blocks
        .iter()
        .filter(|b| b.kind == Kind::ClosedForm)
        .flat_map(|b| unknown_names(&mech, &sys, &b.unknowns))
        .collect();
    let positions: Vec<String> = ["crank", "coupler", "rocker"]
        .iter()
        .flat_map(|b| ["x", "y", "z"].map(|c| format!("{b}.{c}")))
        .collect();
    assert_eq!(closed, set(&positions));
    let the_loop = blocks.blocks.iter().find(|b| b.unknowns.len() == 7).expect("the loop");
    let unknowns: Vec<String> = ["coupler.e0", "coupler.e1", "coupler.e3"]
        .into_iter()
        .map(str::to_owned)
        .chain(["e0", "e1", "e2", "e3"].map(|e| format!("rocker.{e}")))
        .collect();
    assert_eq!(unknown_names(&mech, &sys, &the_loop.unknowns), set(&unknowns));
    let rows: Vec<String> = ["joint B row 1", "joint B row 2", "joint B row 3", "joint O4 row 4"]
        .into_iter()
        .chain(["joint O4 row 5", "body coupler normalisation", "body rocker normalisation"])
        .map(str::to_owned)
        .collect();
    assert_eq!(row_names(&sys, &the_loop.rows), set(&rows));
    assert!(sys.rows.iter().all(|r| r.kind != RowLabel::CONSTRAINT), "no_spin is eliminated");
}

#[test]
fn a_scalar_row_nonlinear_in_its_unknown_is_implicit() {
    // Body "slider" moves along x only (y, z and its orientation fixed) and a distance joint
    // holds its origin 1 from ground's: (x − 0)² + 0.5² − 1 = 0 is one block of one equation,
    // quadratic in x.
    let text = "name = \"quadratic\"\n[time]\nstart = 0.0\nend = 0.1\nsteps = 2\n\n\
        [[bodies]]\nname = \"ground\"\nground = true\n\n\
        [[bodies]]\nname = \"slider\"\nr = [0.8, 0.5, 0.0]\n\n\
        [[joints]]\nname = \"rod\"\ntype = \"distance\"\nbody_i = \"ground\"\nbody_j = \"slider\"\n\
        point_i = [0.0, 0.0, 0.0]\npoint_j = [0.0, 0.0, 0.0]\ndistance = 1.0\n\n\
        [[drivers]]\nname = \"lift\"\nbody = \"slider\"\ncoordinate = \"y\"\n\
        law = { start = 0.5, velocity = 0.1 }\n"
        .to_owned()
        + &["z", "e1", "e2", "e3"]
            .map(|c| {
                format!(
                    "\n[[constraints]]\nname = \"hold_{c}\"\ntype = \"fix\"\nbody = \"slider\"\n\
                     coordinate = \"{c}\"\nvalue = 0.0\n"
                )
            })
            .concat();
    let mech = load_toml(&text);
    let (sys, blocks) = decompose(&mech);
    let x = blocks
        .blocks
        .iter()
        .find(|b| unknown_names(&mech, &sys, &b.unknowns) == set(&["slider.x".to_owned()]))
        .expect("x alone");
    assert_eq!(row_names(&sys, &x.rows), set(&["joint rod".to_owned()]));
    assert_eq!(x.kind, Kind::Implicit);
}

#[test]
fn a_structure_without_a_perfect_matching_is_refused() {
    // Rows 0 and 1 both involve column 0 only.
    let pattern = vec![vec![0], vec![0], vec![0, 1, 2]];
    assert_eq!(
        triangular(&pattern, 3),
        Err(StructurallySingular { rows: 3, unknowns: 3, matched: 2 })
    );
}

/// A planted block: its rows and columns after the shuffle.
type Planted = (BTreeSet<usize>, BTreeSet<usize>);

/// A random block-lower-triangular structure: the planted blocks `(rows, columns)` in order,
/// and the pattern with its rows and columns shuffled. Each diagonal block holds its diagonal
/// and a cycle (entry (i, i + 1 mod size)), so it is irreducible, plus random entries; below the
/// diagonal blocks entries are random, above none.
fn planted(sizes: &[usize], seed: u64) -> (Vec<Vec<usize>>, Vec<Planted>) {
    let mut rng = StdRng::seed_from_u64(seed);
    let n: usize = sizes.iter().sum();
    let mut start = vec![0];
    for s in sizes {
        start.push(start.last().unwrap() + s);
    }
    let mut dense = vec![vec![false; n]; n];
    for (b, &s) in sizes.iter().enumerate() {
        let o = start[b];
        for i in 0..s {
            dense[o + i][o + i] = true;
            dense[o + i][o + (i + 1) % s] = true;
            for j in 0..s {
                if rng.random_bool(0.3) {
                    dense[o + i][o + j] = true;
                }
            }
            for cell in &mut dense[o + i][..o] {
                if rng.random_bool(0.15) {
                    *cell = true;
                }
            }
        }
    }
    let mut row_perm: Vec<usize> = (0..n).collect();
    let mut col_perm: Vec<usize> = (0..n).collect();
    row_perm.shuffle(&mut rng);
    col_perm.shuffle(&mut rng);
    // Planted row i becomes row row_perm[i], planted column j column col_perm[j].
    let mut pattern = vec![Vec::new(); n];
    for (i, row) in dense.iter().enumerate() {
        let mut columns: Vec<usize> = (0..n).filter(|&j| row[j]).map(|j| col_perm[j]).collect();
        columns.sort_unstable();
        pattern[row_perm[i]] = columns;
    }
    let blocks = sizes
        .iter()
        .enumerate()
        .map(|(b, _)| {
            let range = start[b]..start[b + 1];
            (range.clone().map(|i| row_perm[i]).collect(), range.map(|j| col_perm[j]).collect())
        })
        .collect();
    (pattern, blocks)
}

proptest! {
    // No failure files: a failing case is printed, minimised, in the test's output.
    #![proptest_config(ProptestConfig {
        cases: 200,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn shuffled_block_triangular_structures_give_back_their_planted_blocks(
        sizes in prop::collection::vec(1usize..6, 1..15),
        seed in any::<u64>(),
    ) {
        let (pattern, planted) = planted(&sizes, seed);
        let n = pattern.len();
        let rows_of = matching(&pattern, n);
        for (c, r) in rows_of.iter().enumerate() {
            let r = r.expect("a perfect matching exists (the planted diagonal)");
            prop_assert!(pattern[r].contains(&c), "matched entry ({r}, {c}) is a structural non-zero");
        }
        let found = triangular(&pattern, n).expect("structurally regular");
        assert_lower_triangular(&pattern, n, &found);
        // The irreducible blocks of a structure are unique, whatever the matching and order.
        let found: BTreeSet<(BTreeSet<usize>, BTreeSet<usize>)> = found
            .into_iter()
            .map(|(r, c)| (r.into_iter().collect(), c.into_iter().collect()))
            .collect();
        let planted: BTreeSet<_> = planted.into_iter().collect();
        prop_assert_eq!(found, planted);
    }
}

#[test]
fn a_greedy_pairing_that_blocks_a_row_is_augmented() {
    // Greedy pairs row 0 with column 0 and leaves row 1 nothing; the augmenting path
    // row 1 → column 0 → row 0 → column 1 gives the only perfect matching.
    assert_eq!(matching(&[vec![0, 1], vec![0]], 2), [Some(1), Some(0)]);
    // A staircase whose greedy start is wrong at every step: row k involves columns k and k + 1,
    // the last row only column 0 ... which is taken; the unique perfect matching pairs row k
    // with column k + 1 and the last row with column 0.
    let n = 2000;
    let pattern: Vec<Vec<usize>> =
        (0..n).map(|k| if k + 1 < n { vec![k, k + 1] } else { vec![0] }).collect();
    let rows_of = matching(&pattern, n);
    assert_eq!(rows_of[0], Some(n - 1));
    assert!((1..n).all(|c| rows_of[c] == Some(c - 1)));
    // Column k + 1 (row k) depends on column k only: n blocks of one, in the one order that
    // makes the structure lower triangular, column 0 (the last row) first.
    let blocks = triangular(&pattern, n).expect("a perfect matching");
    assert_eq!(blocks[0], (vec![n - 1], vec![0]));
    assert!((1..n).all(|c| blocks[c] == (vec![c - 1], vec![c])));
}

/// The closed form of every rotation block (the emitted coefficients, evaluated, then
/// `runtime::rotation::about_axis`), at random orientations of the known body, random times
/// and random predictions, zeroes the block's own four rows: the normalisation, the two
/// parallel-axis rows and the driver's row, evaluated from their expressions.
#[test]
fn a_rotation_blocks_closed_form_satisfies_its_four_rows() {
    let mut rng = StdRng::seed_from_u64(16);
    let unit = |rng: &mut StdRng| {
        let e: [f64; 4] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let n = e.iter().map(|v| v * v).sum::<f64>().sqrt();
        e.map(|v| v / n)
    };
    let texts = [
        crate::scale::chain(4, 3),
        crate::scale::arms(2, 6, 3),
        std::fs::read_to_string(crate::testing::example("rssr.toml")).expect("the example"),
    ];
    let mut checked = 0;
    for text in texts {
        let mech = load_toml(&text);
        let mut sys = Symbolic::build_full(&mech).expect("the system builds");
        let blocks = Blocks::of(&sys, &mech);
        for block in &blocks.blocks {
            let Kind::Rotation(rotation) = block.kind else { continue };
            let coefficients = rotation.coefficients(&mut sys, &mech);
            let first = rotation.first_unknown(&sys);
            let rows: Vec<_> = block.rows.iter().map(|&r| sys.phi[r]).collect();
            for _ in 0..50 {
                let mut q = sys.initial_estimate(&mech);
                let known = unit(&mut rng);
                for (c, source) in sys.coords[rotation.known.0][3..].iter().enumerate() {
                    if let crate::symbolic::Source::Unknown(k) = *source {
                        q[k] = known[c];
                    }
                }
                let t = rng.random_range(-1.0..1.0);
                let k = sys.pool.eval(&coefficients, &q, &[], t);
                let k: [f64; 11] = k.try_into().expect("eleven coefficients");
                let previous = unit(&mut rng);
                let e = runtime::rotation::about_axis(&k, rotation.linear, &previous)
                    .expect("a driven revolute reaches every angle");
                q[first..first + 4].copy_from_slice(&e);
                for (r, v) in block.rows.iter().zip(sys.pool.eval(&rows, &q, &[], t)) {
                    // Rows of unit vectors and unit quaternions: round-off of a few dozen
                    // products.
                    assert!(v.abs() < 1e-14, "{}: {} = {v}", mech.name, sys.rows[*r].equation());
                }
                checked += 1;
            }
        }
    }
    // Four links, twelve arm links and the R-S-S-R's crank, fifty states each.
    assert_eq!(checked, 50 * (4 + 12 + 1));
}
