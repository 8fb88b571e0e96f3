//! The elementary functions generated code needs, which `core` lacks under `no_std`
//! (provided by `libm`, a port of musl's implementations, accurate to about 1 ulp), for
//! either [`Real`] type.

use crate::Real;

/// sin x.
#[inline]
#[must_use]
pub fn sin<R: Real>(x: R) -> R {
    x.sin()
}

/// cos x.
#[inline]
#[must_use]
pub fn cos<R: Real>(x: R) -> R {
    x.cos()
}

/// √x.
#[inline]
#[must_use]
pub fn sqrt<R: Real>(x: R) -> R {
    x.sqrt()
}

/// (sin x, cos x), with one argument reduction: bit for bit the values of [`sin`] and [`cos`].
#[inline]
#[must_use]
pub fn sin_cos<R: Real>(x: R) -> (R, R) {
    x.sin_cos()
}

#[cfg(test)]
mod tests;
