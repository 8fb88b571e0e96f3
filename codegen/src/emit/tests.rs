//! Emission details: literals, precedence, names.

use super::{literal, type_name};

#[test]
fn type_names_are_upper_camel_case() {
    assert_eq!(type_name("rssr"), "Rssr");
    assert_eq!(type_name("four_bar"), "FourBar");
    assert_eq!(type_name("ex_2_6_1"), "Ex261");
}

#[test]
fn literals_round_trip_and_avoid_approx_constant() {
    let show = |v: f64| {
        let e = literal(v);
        quote::quote!(#e).to_string()
    };
    assert_eq!(show(1.0), "1.0");
    assert_eq!(show(1e-20), "1e-20");
    assert_eq!(show(std::f64::consts::PI), "core :: f64 :: consts :: PI");
    // 3.1416 is not π, but clippy's approx_constant would reject its decimal form.
    // (Parsed from text: clippy rejects the literal in this file too, which is the point.)
    let near_pi: f64 = "3.1416".parse().unwrap();
    assert_eq!(show(near_pi), format!("f64 :: from_bits ({})", near_pi.to_bits()));
    assert_eq!(show(0.06567), "0.06567");
}
