//! [`Real`]: the floating-point type a mechanism is solved in, `f64` or `f32`.
//!
//! Everything in this crate is generic over it, with `f64` the default, so that a generated
//! module can be emitted in single precision where its accuracy is enough (a control loop that
//! needs positions to 1e-5 of the link lengths, on a processor whose `f32` is twice as fast).
//! The constants that depend on the precision, the default pivot ratio and Newton tolerance,
//! are associated constants here, derived from each type's machine epsilon.

use core::fmt::{Debug, Display, LowerExp};
use core::iter::Sum;
use core::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

/// A floating-point type the runtime can solve in: implemented for `f64` and `f32` only.
pub trait Real:
    Copy
    + PartialEq
    + PartialOrd
    + Debug
    + Display
    + LowerExp
    + Default
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
    + Sum
    + for<'a> Sum<&'a Self>
    + Send
    + Sync
    + 'static
{
    /// 0.
    const ZERO: Self;
    /// 1.
    const ONE: Self;
    /// The difference between 1 and the next larger representable number.
    const EPSILON: Self;
    /// +∞.
    const INFINITY: Self;
    /// Not a number.
    const NAN: Self;
    /// The default pivot ratio of LU ([`lu::DEFAULT_PIVOT_RATIO`](crate::lu::DEFAULT_PIVOT_RATIO)
    /// for `f64`): a matrix whose smallest |pivot| is at most this fraction of its largest is
    /// singular.
    ///
    /// About ε^¾ (1e-12 for `f64`, 1e-5 for `f32`): a solve with such pivots keeps at most a
    /// quarter of the digits.
    const DEFAULT_PIVOT_RATIO: Self;
    /// The default Newton tolerance on max |Φ_i|: 1e-10 for `f64`, about 5·10⁵ ε, and 1e-4 for
    /// `f32`, about 840 ε (single precision carries 7 digits, so a residual of unit size
    /// cannot be pushed much closer to its rounding error).
    const DEFAULT_TOLERANCE: Self;

    /// |x|.
    #[must_use]
    fn abs(self) -> Self;
    /// Whether x is neither infinite nor NaN.
    #[must_use]
    fn is_finite(self) -> bool;
    /// Whether x is NaN.
    #[must_use]
    fn is_nan(self) -> bool;
    /// √x (libm).
    #[must_use]
    fn sqrt(self) -> Self;
    /// sin x (libm).
    #[must_use]
    fn sin(self) -> Self;
    /// cos x (libm).
    #[must_use]
    fn cos(self) -> Self;
    /// (sin x, cos x) with one argument reduction (libm): bit for bit [`Real::sin`] and
    /// [`Real::cos`].
    #[must_use]
    fn sin_cos(self) -> (Self, Self);
    /// The angle of the point (x, y) = (`x`, `self`) in (−π, π] (libm's atan2).
    #[must_use]
    fn atan2(self, x: Self) -> Self;
    /// The larger of x and y (the other one when one is NaN).
    #[must_use]
    fn max(self, y: Self) -> Self;
    /// x rounded to this type.
    #[must_use]
    fn from_f64(x: f64) -> Self;
    /// x, exactly, as `f64`.
    #[must_use]
    fn to_f64(self) -> f64;
}

/// Implements [`Real`] for a primitive float type with its libm functions and defaults.
macro_rules! real {
    ($t:ident, $sqrt:path, $sin:path, $cos:path, $sin_cos:path, $atan2:path, $ratio:expr, $tolerance:expr) => {
        impl Real for $t {
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            const EPSILON: Self = $t::EPSILON;
            const INFINITY: Self = $t::INFINITY;
            const NAN: Self = $t::NAN;
            const DEFAULT_PIVOT_RATIO: Self = $ratio;
            const DEFAULT_TOLERANCE: Self = $tolerance;

            #[inline]
            fn abs(self) -> Self {
                $t::abs(self)
            }
            #[inline]
            fn is_finite(self) -> bool {
                $t::is_finite(self)
            }
            #[inline]
            fn is_nan(self) -> bool {
                $t::is_nan(self)
            }
            #[inline]
            fn sqrt(self) -> Self {
                $sqrt(self)
            }
            #[inline]
            fn sin(self) -> Self {
                $sin(self)
            }
            #[inline]
            fn cos(self) -> Self {
                $cos(self)
            }
            #[inline]
            fn sin_cos(self) -> (Self, Self) {
                $sin_cos(self)
            }
            #[inline]
            fn atan2(self, x: Self) -> Self {
                $atan2(self, x)
            }
            #[inline]
            fn max(self, y: Self) -> Self {
                $t::max(self, y)
            }
            #[inline]
            fn from_f64(x: f64) -> Self {
                // The nearest value of this type (exact for f64).
                x as $t
            }
            #[inline]
            fn to_f64(self) -> f64 {
                f64::from(self)
            }
        }
    };
}

real!(f64, libm::sqrt, libm::sin, libm::cos, libm::sincos, libm::atan2, 1e-12, 1e-10);
real!(f32, libm::sqrtf, libm::sinf, libm::cosf, libm::sincosf, libm::atan2f, 1e-5, 1e-4);
