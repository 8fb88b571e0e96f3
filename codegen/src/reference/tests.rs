use super::*;
use crate::generic::{Analysis, Equations};
use crate::testing;

/// sin and cos against 40-digit values (mpmath at 50 digits, split into the nearest double and
/// the nearest double to the rest), and sin² + cos² = 1, across the quadrants the reduction by
/// π/2 lands in; and division, which the reference writes itself.
#[test]
fn sin_and_cos_are_accurate_to_double_double_precision() {
    // sin 0.5 = 0.4794255386042030002732879352155713880818, cos 0.5 =
    // 0.8775825618903727161162815826038296519916; as double-double (hi + lo).
    let (s, c) = Dd::from(0.5).sin_cos();
    let sin_half = TwoFloat::new_add(0.479_425_538_604_203, -5.103_969_860_556_013e-18);
    let cos_half = TwoFloat::new_add(0.877_582_561_890_372_8, -4.262_314_986_428e-17);
    // The literals carry 33 digits: agreement to 1e-31 is about what they can show.
    assert!((s.0 - sin_half).abs().hi() < 1e-31, "{s:?}");
    assert!((c.0 - cos_half).abs().hi() < 1e-31, "{c:?}");
    for x in [-7.0, -2.0, 0.3, 1.6, 3.2, 4.8, 100.0] {
        let (s, c) = Dd::from(x).sin_cos();
        let one = (s.0 * s.0 + c.0 * c.0 - 1.0).abs().hi();
        // A few units of the double-double ε (4.9e-32) from the series and the squares.
        assert!(one < 1e-30, "sin² + cos² − 1 = {one:e} at {x}");
        // The double-precision functions are within 1 ulp of the truth.
        assert!((s.to_f64() - x.sin()).abs() <= 2.3e-16 * x.sin().abs().max(1e-300), "{x}");
        assert!((c.to_f64() - x.cos()).abs() <= 2.3e-16 * x.cos().abs().max(1e-300), "{x}");
    }
    for (a, b) in [(1.0, 3.0), (0.3, 0.7), (-2.5, 1e-3), (1e10, -7.0)] {
        let (a, b) = (Dd::from(a) + Dd::from(a * 1e-17), Dd::from(b));
        let back = ((a / b) * b - a).abs().to_f64() / a.abs().to_f64();
        // Three double digits of quotient: the product's own round-off, a few ε of double-double.
        assert!(back < 1e-31, "{a:?} / {b:?}: {back:e}");
    }
}

/// The R-S-S-R's loop closure in double-double, independent of the reference's solver.
///
/// The crank turns about the global y axis through O2 by θ = ω t, carrying A to
/// (ρ sin θ, 0, ρ cos θ); the rocker turns about the global x axis through O4 by φ, carrying B
/// to O4 + (0, −b cos φ − c sin φ, −b sin φ + c cos φ) with O4 = (−0.0475, a, 0) and
/// b, c = 0.01857, 0.1; the coupler keeps |B − A| = L. Expanded, |B − A|² = L² reads
/// G(θ, φ) = P cos φ + Q sin φ − K = 0 with P = 2ab + 2ρc cos θ, Q = 2ac − 2ρb cos θ and
/// K = ρ² + a² + b² + c² − L²; φ̇ = −G_θ θ̇ / G_φ and
/// φ̈ = −(G_θθ θ̇² + 2 G_θφ θ̇ φ̇ + G_φφ φ̇²) / G_φ.
struct Rssr {
    omega: Dd,
}

impl Rssr {
    const RHO: f64 = 0.1;
    const A: f64 = 0.49977;
    const B: f64 = 0.01857;
    const C: f64 = 0.1;
    const L: f64 = 0.4812;

    /// G and its partial derivatives (G_θ, G_φ, G_θθ, G_θφ, G_φφ) at (θ, φ).
    fn g(theta: Dd, phi: Dd) -> [Dd; 6] {
        let d = Dd::from;
        let (st, ct) = theta.sin_cos();
        let (sp, cp) = phi.sin_cos();
        let (rho, a, b, c, l) = (d(Self::RHO), d(Self::A), d(Self::B), d(Self::C), d(Self::L));
        let two = d(2.0);
        let p = two * a * b + two * rho * c * ct;
        let q = two * a * c - two * rho * b * ct;
        let k = rho * rho + a * a + b * b + c * c - l * l;
        let (p1, q1) = (-(two * rho * c * st), two * rho * b * st);
        let (p2, q2) = (-(two * rho * c * ct), two * rho * b * ct);
        [
            p * cp + q * sp - k,
            p1 * cp + q1 * sp,
            -(p * sp) + q * cp,
            p2 * cp + q2 * sp,
            -(p1 * sp) + q1 * cp,
            -(p * cp) - q * sp,
        ]
    }

    /// θ, θ̇ and φ, φ̇, φ̈ at `t`, φ the root of G nearest `phi0` (scalar Newton to round-off).
    fn at(&self, t: f64, phi0: f64) -> (Dd, Dd, [Dd; 3]) {
        let theta = self.omega * Dd::from(t);
        let mut phi = Dd::from(phi0);
        for _ in 0..8 {
            let [g, _, g_phi, ..] = Self::g(theta, phi);
            phi = phi - g / g_phi;
        }
        let w = self.omega;
        let [_, gt, gp, gtt, gtp, gpp] = Self::g(theta, phi);
        let phid = -(gt * w) / gp;
        let phidd = -(gtt * w * w + Dd::from(2.0) * gtp * w * phid + gpp * phid * phid) / gp;
        (theta, w, [phi, phid, phidd])
    }
}

#[test]
fn the_reference_meets_the_rssr_closed_form_to_double_double_precision() {
    let path = crate::sync::workspace_root().join("benches/rssr_revolution.toml");
    let mech = testing::load(&path).mechanism;
    let eq = Equations::new(&mech);
    let prep = eq.prepare();
    let reference = Reference::new(&eq).expect("the R-S-S-R reduces");
    let rssr = Rssr { omega: Dd::from(146.6) };
    let body = |name: &str| {
        let b = mech.bodies.iter().position(|b| b.name == name).expect(name);
        eq.offset(BodyId(b)).expect("moving")
    };
    let (coupler, rocker) = (body("coupler"), body("rocker"));
    let mut worst = [0.0_f64; 3];
    let (mut residual, mut rates, mut checked) = (0.0_f64, 0.0_f64, 0);
    Analysis::new(&eq, &prep)
        .run(|f| {
            // Every seventh of the 1001 time points: 143 across the revolution.
            if f.index % 7 != 0 {
                return Ok::<(), ()>(());
            }
            let r = reference.solve(f.index, f.t, &f.q).expect("the reference converges");
            residual = residual.max(r.residual);
            rates = rates.max(r.rate_residuals[0]).max(r.rate_residuals[1]);
            let [q, qd, qdd] = &r.parts;
            let phi0 = 2.0 * f.q[rocker + 4].atan2(f.q[rocker + 3]);
            let (theta, w, [phi, phid, phidd]) = rssr.at(f.t, phi0);
            // The coupler's origin is A: (ρ sin θ, 0, ρ cos θ) and its rates.
            let rho = Dd::from(Rssr::RHO);
            let (st, ct) = theta.sin_cos();
            let a = [rho * st, Dd::default(), rho * ct];
            let ad = [rho * ct * w, Dd::default(), -(rho * st * w)];
            let add = [-(rho * st * w * w), Dd::default(), -(rho * ct * w * w)];
            // The rocker's Euler parameters: (cos φ/2, sin φ/2, 0, 0) and their rates.
            let (s2, c2) = (phi * Dd::from(0.5)).sin_cos();
            let h = Dd::from(0.5);
            let quarter = Dd::from(0.25);
            let p = [c2, s2];
            let pd = [-(h * s2 * phid), h * c2 * phid];
            let pdd = [
                -(quarter * c2 * phid * phid) - h * s2 * phidd,
                -(quarter * s2 * phid * phid) + h * c2 * phidd,
            ];
            let gap = |x: &[Dd], o: usize, want: &[Dd]| {
                want.iter()
                    .enumerate()
                    .map(|(k, w)| (x[o + k] - *w).abs().to_f64())
                    .fold(0.0, f64::max)
            };
            // Relative to each level's scale: |A| = 0.1, |Ȧ| = 14.7, |Ä| = 2149.
            worst[0] = worst[0].max(gap(q, coupler, &a) / 0.1).max(gap(q, rocker + 3, &p));
            worst[1] = worst[1].max(gap(qd, coupler, &ad) / 14.66).max(gap(qd, rocker + 3, &pd));
            worst[2] =
                worst[2].max(gap(qdd, coupler, &add) / 2149.0).max(gap(qdd, rocker + 3, &pdd));
            checked += 1;
            Ok(())
        })
        .expect("the sink does not fail");
    println!(
        "R-S-S-R reference vs closed form at {checked} points: q {:e}, q̇ {:e}, q̈ {:e}; residual {residual:e}, rate residuals {rates:e}",
        worst[0], worst[1], worst[2]
    );
    assert_eq!(checked, 143);
    // The reference's own residual is at the double-double round-off of evaluating Φ.
    assert!(residual < 1e-29, "residual {residual:e}");
    assert!(rates < 1e-27, "rate residuals {rates:e}");
    for (level, w) in ["q", "q̇", "q̈"].iter().zip(worst) {
        assert!(w < 1e-25, "{level}: the reference is {w:e} from the closed form");
    }
}
