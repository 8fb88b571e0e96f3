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
