//! The emitted LU's arithmetic on values known when generated.

use super::*;

fn shown(v: &Val) -> String {
    let e = v.expr(Prec::Sum);
    quote::quote!(#e).to_string()
}

fn run(name: &str) -> Val {
    let name = ident(name);
    Val::Run(parse_quote!(#name), Prec::Atom)
}

#[test]
fn constant_folding_is_exact() {
    let (x, y) = (run("x"), run("y"));
    // Constants combine as the run time would combine them.
    let third = Val::Const(1.0).div(&Val::Const(3.0));
    assert_eq!(shown(&third), shown(&Val::Const(1.0 / 3.0)));
    // ±1 factors vanish, and subtracting a negation adds.
    assert_eq!(shown(&Val::Const(1.0).mul(&x)), "x");
    assert_eq!(shown(&x.mul(&Val::Const(-1.0))), "- x");
    assert_eq!(shown(&y.sub(&Val::Const(-1.0).mul(&x))), "y + x");
    assert_eq!(shown(&x.negated().negated()), "x");
    // Other constants stay factors, with parentheses where precedence needs them.
    assert_eq!(shown(&Val::Const(2.0).mul(&y.sub(&x))), "2.0 * (y - x)");
    assert_eq!(shown(&y.sub(&x).negated().mul(&x)), "- (y - x) * x");
}

#[test]
fn a_binding_has_no_enclosing_parentheses() {
    let (x, y) = (run("x"), run("y"));
    // −(−(x y)) keeps the parentheses of the inner operand; the binding drops them.
    let twice = x.mul(&y).negated().negated();
    assert_eq!(shown(&twice), "(x * y)");
    let e = twice.binding();
    assert_eq!(quote::quote!(#e).to_string(), "x * y");
    let e = y.sub(&x).binding();
    assert_eq!(quote::quote!(#e).to_string(), "y - x");
}
