//! Finite-difference checks of every row kind: Φ_q against central differences of Φ at
//! random configurations, ν and γ against differences of Φ along random smooth trajectories.

use nalgebra::{DVector, Vector3, Vector4};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

use super::Equations;
use crate::model::{
    Body, BodyId, Constraint, ConstraintKind, CoordinateName, Driver, DriverCoordinate,
    DriverTarget, Joint, JointId, JointKind, Law, Mechanism, Motion, SolverOptions, TimeGrid,
};

fn unit(rng: &mut StdRng) -> Vector3<f64> {
    loop {
        let v = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        if v.norm() > 0.3 {
            return v.normalize();
        }
    }
}

fn vec3(rng: &mut StdRng) -> Vector3<f64> {
    Vector3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    )
}

fn quat(rng: &mut StdRng) -> Vector4<f64> {
    Vector4::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    )
    .normalize()
}

/// A unit vector ⟂ `a`.
fn perpendicular(rng: &mut StdRng, a: &Vector3<f64>) -> Vector3<f64> {
    let v = unit(rng);
    (v - a * a.dot(&v)).normalize()
}

/// A joint of `kind` between bodies `i` and `j` with random geometry and references.
fn joint(rng: &mut StdRng, name: &str, i: usize, j: usize, kind: JointKind) -> Joint {
    let (ai, aj) = (unit(rng), unit(rng));
    Joint {
        name: name.to_owned(),
        body_i: BodyId(i),
        body_j: BodyId(j),
        point_i: vec3(rng),
        point_j: vec3(rng),
        axis: Some((ai, aj)),
        reference: Some((perpendicular(rng, &ai), perpendicular(rng, &aj))),
        kind,
    }
}

/// Every row kind at once: a ground body with a non-identity placement, two moving bodies,
/// one joint of each type, both constraint kinds and every driver kind with both laws.
/// The equation count is irrelevant here: only Φ and its derivatives are evaluated.
fn zoo(seed: u64) -> Mechanism {
    let mut rng = StdRng::seed_from_u64(seed);
    let body = |rng: &mut StdRng, name: &str, ground| Body {
        name: name.to_owned(),
        ground,
        r: vec3(rng),
        p: quat(rng),
    };
    let bodies = vec![
        body(&mut rng, "g", true),
        body(&mut rng, "a", false),
        body(&mut rng, "b", false),
    ];
    let lead = rng.random_range(0.5..2.0);
    let joints = vec![
        joint(&mut rng, "sph", 1, 2, JointKind::Spherical),
        joint(&mut rng, "uni", 2, 1, JointKind::Universal),
        joint(&mut rng, "rev", 0, 1, JointKind::Revolute),
        joint(&mut rng, "rev2", 1, 2, JointKind::Revolute),
        joint(&mut rng, "cyl", 1, 2, JointKind::Cylindrical),
        joint(&mut rng, "pri", 2, 0, JointKind::Prismatic),
        joint(
            &mut rng,
            "scr",
            1,
            2,
            JointKind::Screw {
                lead,
                d0: 0.3,
                theta0: 0.4,
            },
        ),
        joint(&mut rng, "dst", 1, 2, JointKind::Distance { length: 1.3 }),
    ];
    let poly = Law::Polynomial {
        start: 0.3,
        velocity: 1.7,
        acceleration: -2.1,
    };
    let harm = Law::Harmonic {
        offset: 0.2,
        amplitude: 0.9,
        frequency: 2.3,
        phase: 0.4,
    };
    let driver = |name: &str, target, law| Driver {
        name: name.to_owned(),
        target,
        law,
    };
    let absolute = |c| DriverTarget::Absolute {
        body: BodyId(2),
        coordinate: c,
    };
    let drivers = vec![
        driver(
            "d_rev",
            DriverTarget::Joint {
                joint: JointId(3),
                motion: Motion::Rotation,
            },
            harm,
        ),
        driver(
            "d_cyl_r",
            DriverTarget::Joint {
                joint: JointId(4),
                motion: Motion::Rotation,
            },
            poly,
        ),
        driver(
            "d_cyl_t",
            DriverTarget::Joint {
                joint: JointId(4),
                motion: Motion::Translation,
            },
            harm,
        ),
        driver(
            "d_pri",
            DriverTarget::Joint {
                joint: JointId(5),
                motion: Motion::Translation,
            },
            poly,
        ),
        driver(
            "d_scr",
            DriverTarget::Joint {
                joint: JointId(6),
                motion: Motion::Rotation,
            },
            harm,
        ),
        driver("d_x", absolute(DriverCoordinate::X), poly),
        driver("d_y", absolute(DriverCoordinate::Y), harm),
        driver("d_z", absolute(DriverCoordinate::Z), poly),
        driver("d_rx", absolute(DriverCoordinate::Rx), harm),
        driver("d_ry", absolute(DriverCoordinate::Ry), poly),
        driver("d_rz", absolute(DriverCoordinate::Rz), harm),
    ];
    let constraints = vec![
        Constraint {
            name: "fix".to_owned(),
            kind: ConstraintKind::Fix {
                body: BodyId(1),
                coordinate: CoordinateName::E2,
                value: 0.1,
            },
        },
        Constraint {
            name: "diff".to_owned(),
            kind: ConstraintKind::CoordinateDifference {
                body_i: BodyId(2),
                body_j: BodyId(1),
                coordinate: CoordinateName::Y,
                value: 0.5,
            },
        },
        Constraint {
            name: "diff_ground".to_owned(),
            kind: ConstraintKind::CoordinateDifference {
                body_i: BodyId(0),
                body_j: BodyId(2),
                coordinate: CoordinateName::E3,
                value: 0.5,
            },
        },
    ];
    Mechanism {
        name: "zoo".to_owned(),
        description: None,
        time: TimeGrid {
            start: 0.0,
            step: 0.1,
            count: 2,
        },
        solver: SolverOptions::default(),
        bodies,
        joints,
        constraints,
        drivers,
        points: Vec::new(),
    }
}

/// A random configuration near unit Euler parameters (off the manifold on purpose: the
/// derivatives must be those of Φ as written, everywhere).
fn random_q(rng: &mut StdRng, n: usize) -> DVector<f64> {
    DVector::from_fn(n, |_, _| rng.random_range(-1.0..1.0))
}

#[test]
fn jacobian_matches_central_differences_for_every_row_kind() {
    for seed in 0..20 {
        let mech = zoo(seed);
        let eq = Equations::new(&mech);
        let mut rng = StdRng::seed_from_u64(100 + seed);
        let n = eq.unknowns();
        let q = random_q(&mut rng, n);
        let t = rng.random_range(-1.0..1.0);
        let zero = DVector::zeros(n);
        let jac = eq.evaluate(&q, &zero, t).jac;
        // Central differences have truncation error ~h² and round-off ~ε/h; h = 1e-6 puts
        // both near 1e-10 for these O(1) quantities, so 1e-7 leaves a wide margin.
        let h = 1e-6;
        for c in 0..n {
            let mut qp = q.clone();
            let mut qm = q.clone();
            qp[c] += h;
            qm[c] -= h;
            let fd = (eq.evaluate(&qp, &zero, t).phi - eq.evaluate(&qm, &zero, t).phi) / (2.0 * h);
            for r in 0..eq.equations() {
                let err = (fd[r] - jac[(r, c)]).abs();
                assert!(
                    err <= 1e-7 * (1.0 + fd[r].abs()),
                    "seed {seed}: ∂Φ/∂q of {} column {c}: analytic {}, differences {}",
                    eq.labels()[r].equation(),
                    jac[(r, c)],
                    fd[r]
                );
            }
        }
    }
}

#[test]
fn nu_and_gamma_match_differences_along_smooth_trajectories() {
    for seed in 0..20 {
        let mech = zoo(seed);
        let eq = Equations::new(&mech);
        let mut rng = StdRng::seed_from_u64(200 + seed);
        let n = eq.unknowns();
        // Rates of order 0.3 keep the fast screw phase 2π·d/lead within reach of the differences.
        let q0 = random_q(&mut rng, n);
        let v = random_q(&mut rng, n) * 0.3;
        let a = random_q(&mut rng, n) * 0.3;
        let t0 = rng.random_range(-1.0..1.0);
        let zero = DVector::zeros(n);
        // Along q(τ) = q0 + vτ + aτ²/2, t = t0 + τ: Φ̇ = Φ_q v − ν and Φ̈ = Φ_q a − γ.
        let phi_at = |tau: f64| {
            eq.evaluate(&(&q0 + &v * tau + &a * (0.5 * tau * tau)), &zero, t0 + tau)
                .phi
        };
        let sys = eq.evaluate(&q0, &v, t0);
        // Second differences: truncation ~h², round-off ~ε/h²; h = 1e-4 gives ~1e-8 each.
        let h = 1e-4;
        let (p, z, m) = (phi_at(h), phi_at(0.0), phi_at(-h));
        // First differences with a smaller step: truncation ~1e-10, round-off ~1e-11.
        let h1 = 1e-5;
        let d1 = (phi_at(h1) - phi_at(-h1)) / (2.0 * h1);
        let d2 = (&p - &z * 2.0 + &m) / (h * h);
        let nu = &sys.jac * &v - &d1;
        let gamma = &sys.jac * &a - &d2;
        for r in 0..eq.equations() {
            let label = eq.labels()[r].equation();
            // ν: the first differences are accurate to ~1e-9 on these rows.
            assert!(
                (nu[r] - sys.nu[r]).abs() <= 1e-6 * (1.0 + nu[r].abs()),
                "seed {seed}: ν of {label}: analytic {}, differences {}",
                sys.nu[r],
                nu[r]
            );
            // γ: second differences are accurate to ~1e-7 here; 1e-5 relative is the bound.
            assert!(
                (gamma[r] - sys.gamma[r]).abs() <= 1e-5 * (1.0 + gamma[r].abs()),
                "seed {seed}: γ of {label}: analytic {}, differences {}",
                sys.gamma[r],
                gamma[r]
            );
        }
    }
}
