extern crate std;

use std::vec;

use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

use super::*;

#[test]
fn sin_cos_has_the_bits_of_sin_and_cos() {
    // Arguments across every branch of the argument reduction: tiny, below π/4, moderate,
    // large (the Payne–Hanek path), negative, and the special values.
    let mut rng = StdRng::seed_from_u64(7);
    let mut args = vec![0.0, -0.0, 1e-300, 2e-8, 1.4e-8, 0.7, core::f64::consts::PI, 1e22];
    args.extend([f64::INFINITY, f64::NAN, f64::MIN_POSITIVE]);
    for _ in 0..20_000 {
        let magnitude = 10f64.powf(rng.random_range(-12.0..25.0));
        args.push(if rng.random_range(0.0..1.0) < 0.5 { -magnitude } else { magnitude });
    }
    for x in args {
        let (s, c) = sin_cos(x);
        assert_eq!((s.to_bits(), c.to_bits()), (sin(x).to_bits(), cos(x).to_bits()), "x = {x:e}");
    }
}

#[test]
fn single_precision_functions_are_within_an_ulp_or_two_of_double() {
    // libm's sinf, cosf, sqrtf are correctly rounded or nearly so; compare with the f64
    // versions rounded to f32 over [-100, 100] (2 ulps of f32 allow for either rounding).
    for k in -20_000..=20_000 {
        let x = (f64::from(k) * 0.005) as f32;
        let (s, c) = sin_cos(x);
        assert_eq!((s.to_bits(), c.to_bits()), (sin(x).to_bits(), cos(x).to_bits()));
        let wide = f64::from(x);
        for (got, want) in [(s, wide.sin()), (c, wide.cos()), (sqrt(x.abs()), wide.abs().sqrt())] {
            let ulp = f64::from(f32::EPSILON) * want.abs().max(f64::from(f32::MIN_POSITIVE));
            assert!((f64::from(got) - want).abs() <= 2.0 * ulp, "x = {x}: {got} vs {want}");
        }
    }
}
