//! Rewrite rules of the smart constructors and symbolic derivatives.

use super::{ExprPool, Var};

fn q(pool: &mut ExprPool, k: u32) -> super::ExprId {
    pool.var(Var::Q(k))
}

#[test]
fn constants_fold() {
    let mut p = ExprPool::new();
    let (a, b) = (p.constant(2.0), p.constant(3.0));
    let s = p.add(a, b);
    let m = p.mul(s, b);
    assert_eq!(p.as_const(m), Some(15.0));
}

#[test]
fn neutral_elements_vanish() {
    let mut p = ExprPool::new();
    let x = q(&mut p, 0);
    let (zero, one, minus_one) = (p.constant(0.0), p.constant(1.0), p.constant(-1.0));
    assert_eq!(p.add(x, zero), x);
    assert_eq!(p.mul(one, x), x);
    assert_eq!(p.as_const(p.clone().mul(zero, x)), Some(0.0));
    let nx = p.mul(minus_one, x);
    assert_eq!(p.display(nx).to_string(), "-(q0)");
    assert_eq!(p.neg(nx), x);
}

#[test]
fn commutative_operands_share_one_node() {
    let mut p = ExprPool::new();
    let (x, y) = (q(&mut p, 0), q(&mut p, 1));
    assert_eq!(p.mul(x, y), p.clone().mul(y, x));
    assert_eq!(p.add(x, y), p.clone().add(y, x));
    let nx = p.neg(x);
    // (−x)·y and x·(−y) are both −(x·y).
    let a = p.mul(nx, y);
    let ny = p.neg(y);
    let b = p.mul(x, ny);
    assert_eq!(a, b);
}

#[test]
fn a_term_minus_itself_is_zero() {
    let mut p = ExprPool::new();
    let x = q(&mut p, 0);
    let d = p.sub(x, x);
    assert_eq!(p.as_const(d), Some(0.0));
}

#[test]
fn derivative_of_sin_is_cos_times_inner_derivative() {
    let mut p = ExprPool::new();
    let x = q(&mut p, 0);
    let three = p.constant(3.0);
    let inner = p.mul(three, x);
    let e = p.sin(inner);
    let d = p.diff(e, Var::Q(0));
    assert_eq!(p.display(d).to_string(), "3.0 * cos(3.0 * q0)");
}

#[test]
fn derivatives_match_central_differences() {
    // f = x·y·sin(x) + cos(y·t) − x: ∂f/∂x and ∂f/∂t at one point.
    let mut p = ExprPool::new();
    let (x, y, t) = (q(&mut p, 0), q(&mut p, 1), p.var(Var::T));
    let xy = p.mul(x, y);
    let sx = p.sin(x);
    let a = p.mul(xy, sx);
    let yt = p.mul(y, t);
    let c = p.cos(yt);
    let s = p.add(a, c);
    let f = p.sub(s, x);
    let (dx, dt) = (p.diff(f, Var::Q(0)), p.diff(f, Var::T));
    let (x0, y0, t0, h) = (0.7, -1.3, 0.4, 1e-6);
    let at = |x: f64, y: f64, t: f64| p.eval(&[f], &[x, y], &[], t)[0];
    let [gx, gt] = [dx, dt].map(|d| p.eval(&[d], &[x0, y0], &[], t0)[0]);
    // Central differences with h = 1e-6 on O(1) values: error ≈ 1e-10.
    assert!((gx - (at(x0 + h, y0, t0) - at(x0 - h, y0, t0)) / (2.0 * h)).abs() < 1e-8);
    assert!((gt - (at(x0, y0, t0 + h) - at(x0, y0, t0 - h)) / (2.0 * h)).abs() < 1e-8);
}

#[test]
fn children_come_before_parents() {
    let mut p = ExprPool::new();
    let (x, y) = (q(&mut p, 0), q(&mut p, 1));
    let s = p.add(x, y);
    let e = p.sin(s);
    let _ = p.diff(e, Var::Q(1));
    for (k, node) in p.nodes().iter().enumerate() {
        assert!(node.children().all(|c| c.index() < k));
    }
}

#[test]
fn a_fold_that_would_overflow_stays_an_operation_and_evaluates_to_infinity() {
    // 1e10 · (1e150)² is the acceleration amplitude of a sinusoid whose members are each
    // within the description's bound: folding it panicked on the infinite constant.
    let mut p = ExprPool::new();
    let (a, w) = (p.constant(1e10), p.constant(1e150));
    let aw = p.mul(a, w);
    assert_eq!(p.as_const(aw), Some(1e160), "a finite product still folds");
    let aww = p.mul(aw, w);
    assert_eq!(p.as_const(aww), None);
    let t = p.var(Var::T);
    let scaled = p.mul(w, t);
    let twice = p.mul(aw, scaled);
    let big = p.constant(f64::MAX);
    let sum = p.add(big, big);
    assert_eq!(p.as_const(sum), None);
    let values = p.eval(&[aww, twice, sum], &[], &[], 1.0);
    assert!(values.iter().all(|v| v.is_infinite()), "{values:?}");
}
