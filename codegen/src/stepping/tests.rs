//! Step control on a model engine: a body sliding along x at unit speed, which cannot pass a
//! wall at `t_wall` (every attempt at or beyond it is rejected), far from t = 0, where
//! sub-steps fall below the spacing of floating-point time.

use super::{MAX_HALVINGS, Point, Rejection, Trouble, advance, first};

/// Attempts allowed per test: halving to 2⁻²⁰ and climbing back takes a few hundred at
/// most, so a step control that cycles without progress hits this bound instead of hanging.
const ATTEMPTS: u32 = 100_000;

/// A body at x = t − origin, unable to pass `wall`; `coarse` rounds every time to f32, as
/// a single-precision generated solver does.
struct Slider {
    origin: f64,
    wall: f64,
    coarse: bool,
    attempts: u32,
}

impl super::Engine for Slider {
    fn attempt(&mut self, t: f64) -> Result<Point, Rejection> {
        self.attempts += 1;
        assert!(self.attempts <= ATTEMPTS, "the step control does not terminate");
        #[allow(clippy::cast_possible_truncation)] // The rounding to f32 is the point.
        let t = if self.coarse { f64::from(t as f32) } else { t };
        if t >= self.wall {
            return Err(Rejection {
                trouble: Trouble::NoConvergence,
                message: format!("the wall at t = {}", self.wall),
                point: None,
                body: None,
            });
        }
        let mut q = vec![0.0; 7];
        q[0] = t - self.origin;
        q[3] = 1.0;
        let mut qd = vec![0.0; 7];
        qd[0] = 1.0;
        Ok(Point { t, q, qd, qdd: vec![0.0; 7], iterations: 1, residual: 0.0, pivot_ratio: 1.0 })
    }

    fn accept(&mut self, _: &Point) {}
}

/// Runs the grid `origin + k·step` (k = 0, 1, …) until the analysis stops; returns the stop's
/// grid time and message, and the last time reached.
fn run(engine: &mut Slider, step: f64) -> (f64, String, f64) {
    let mut a = first(engine, engine.origin).expect("the first point is before the wall");
    for k in 1..1000 {
        let t = engine.origin + f64::from(k) * step;
        match advance(engine, &a, t) {
            Ok((b, _)) => a = b,
            Err(stop) => {
                assert_eq!(stop.trouble, Trouble::NoConvergence, "{}", stop.message);
                return (stop.t, stop.message, a.t);
            }
        }
    }
    panic!("the wall was passed");
}

#[test]
fn a_wall_near_t_zero_stops_at_the_smallest_sub_step() {
    let mut e = Slider { origin: 0.0, wall: 0.1, coarse: false, attempts: 0 };
    let (t, message, last) = run(&mut e, 0.03);
    // The wall lies between the grid times 0.09 and 0.12.
    assert!((t - 0.12).abs() < 1e-12 && (last - 0.09).abs() < 1e-12, "{t} {last}");
    assert!(message.contains(&format!("2^-{MAX_HALVINGS}")), "{message}");
}

#[test]
fn sub_steps_below_the_spacing_of_t_stop_instead_of_cycling() {
    // At 1e12 the spacing of f64 is 1.2e-4, so sub-steps of 0.03/2⁹ no longer move t; at
    // 1e17 it is 16, so a grid step of 32 can be halved once.
    for (origin, step) in [(1e12, 0.03), (1e17, 32.0)] {
        let wall = origin + 3.5 * step;
        let mut e = Slider { origin, wall, coarse: false, attempts: 0 };
        let (t, message, last) = run(&mut e, step);
        assert_eq!(t, origin + 4.0 * step, "stops at the grid time past the wall");
        assert_eq!(last, origin + 3.0 * step, "every grid time before the wall is reached");
        assert!(message.contains("no longer change"), "{message}");
        assert!(e.attempts < 1000, "{} attempts at t = {origin}", e.attempts);
    }
}

#[test]
fn an_engine_that_rounds_t_to_single_precision_cannot_stall_the_step_control() {
    // In f32 the spacing at 1e5 is 0.0078: the engine rounds a sub-step of 0.03/8 back onto
    // its start although t + h differs from t in f64.
    let origin = 1e5;
    let mut e = Slider { origin, wall: origin + 0.1, coarse: true, attempts: 0 };
    let (_, message, _) = run(&mut e, 0.03);
    assert!(message.contains("no longer change"), "{message}");
    assert!(e.attempts < 1000, "{} attempts", e.attempts);
}
