//! The symbolic system, evaluated numerically, against the generic engine: an interpreted
//! Newton over the reduced equations must reproduce the generic analysis of every shipped
//! example.

use nalgebra::{DMatrix, DVector};

use super::Symbolic;
use crate::generic::Equations;
use crate::testing::{examples, load, load_example, run_generic};

/// Reduced Φ_q as a dense matrix.
fn jacobian(sys: &Symbolic, q: &[f64], t: f64) -> DMatrix<f64> {
    let n = sys.unknowns.len();
    let roots: Vec<_> = sys.jac.iter().flatten().map(|&(_, e)| e).collect();
    let vals = sys.pool.eval(&roots, q, &[], t);
    let mut m = DMatrix::zeros(n, n);
    let mut it = vals.into_iter();
    for (r, row) in sys.jac.iter().enumerate() {
        for &(c, _) in row {
            m[(r, c)] = it.next().unwrap();
        }
    }
    m
}

#[test]
fn interpreted_symbolic_system_matches_the_generic_engine_on_every_example() {
    let files = examples();
    assert!(files.len() >= 18);
    for file in files {
        let loaded = load(&file);
        let mech = &loaded.mechanism;
        let sys = Symbolic::build(mech).unwrap();
        let eq = Equations::new(mech);
        let run = run_generic(mech);
        assert!(run.failure.is_none());
        let frames = run.frames;
        let mut q = sys.reduce(&eq, &eq.initial_estimate()).as_slice().to_vec();
        let n = q.len();
        for f in &frames {
            let t = f.t;
            // A system whose every block was substituted has nothing to solve.
            for _ in 0..if n == 0 { 0 } else { 50 } {
                let phi = DVector::from_vec(sys.pool.eval(&sys.phi, &q, &[], t));
                if phi.amax() <= mech.solver.tolerance {
                    break;
                }
                let dq = jacobian(&sys, &q, t).lu().solve(&phi).unwrap();
                for k in 0..n {
                    q[k] -= dq[k];
                }
            }
            sys.normalise(&mut q);
            let (qd, qdd) = if n == 0 {
                (DVector::zeros(0), DVector::zeros(0))
            } else {
                let lu = jacobian(&sys, &q, t).lu();
                let nu = DVector::from_vec(sys.pool.eval(&sys.nu, &q, &[], t));
                let qd = lu.solve(&nu).unwrap();
                let gamma = DVector::from_vec(sys.pool.eval(&sys.gamma, &q, qd.as_slice(), t));
                (qd.clone(), lu.solve(&gamma).unwrap())
            };
            let [fq, fqd, fqdd] = sys.expand(&eq, &q, qd.as_slice(), qdd.as_slice(), t);
            for (name, ours, theirs) in
                [("q", &fq, &f.q), ("qd", &fqd, &f.qd), ("qdd", &fqdd, &f.qdd)]
            {
                // Both engines converge to max |Φ| ≤ 1e-10 from different iterates; the
                // quantities agree to that order relative to their scale.
                let scale = theirs.amax().max(1.0);
                let diff = (ours - theirs).amax();
                assert!(
                    diff <= 1e-9 * scale,
                    "{}: t = {t}: {name} differs by {diff:e} (scale {scale})",
                    file.display()
                );
            }
        }
    }
}

#[test]
fn ground_fix_and_coordinate_drivers_are_eliminated() {
    let mech = load_example("rssr.toml");
    let sys = Symbolic::build_full(&mech).unwrap();
    // 3 moving bodies × 7 − the coupler's fixed e2.
    assert_eq!(sys.unknowns.len(), 20);
    assert_eq!(sys.rows.len(), 20);
    assert_eq!(sys.eliminated.len(), 1);
    assert_eq!(sys.eliminated[0].equation(), "constraint no_spin");
    let mech = load_example("translation_xyz.toml");
    let sys = Symbolic::build(&mech).unwrap();
    // Three coordinate drivers and three fixed rotations leave e0 alone.
    assert_eq!(sys.unknowns.len(), 1);
}

/// The four-bar's loop holds the coupler's and the rocker's positions through their pins
/// (rows affine in each position with coefficient ±1, whatever the orientations): tearing
/// writes those six positions from the orientations, and Newton runs on the eight Euler
/// parameters alone. The R-S-S-R's loop, quadratic in every unknown it keeps, tears nothing.
#[test]
fn positions_pinned_inside_a_loop_are_torn_from_it() {
    let four_bar = load_example("four_bar.toml");
    let sys = Symbolic::build(&four_bar).unwrap();
    let torn: Vec<_> = sys.derived.iter().filter(|d| d.torn).collect();
    assert_eq!(torn.len(), 6, "the coupler's and the rocker's x, y and z");
    assert!(torn.iter().all(|d| d.coordinate < 3), "positions only");
    assert_eq!(sys.unknowns.len(), 8);
    assert!(sys.unknowns.iter().all(|&(_, c)| c >= 3), "Newton on Euler parameters only");
    let rssr = load_example("rssr.toml");
    let sys = Symbolic::build(&rssr).unwrap();
    assert!(sys.derived.iter().all(|d| !d.torn), "nothing torn from the R-S-S-R's loop");
    assert_eq!(sys.unknowns.len(), 5);
}
