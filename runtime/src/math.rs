//! The elementary functions generated code needs, which `core` lacks under `no_std`
//! (provided by `libm`, a port of musl's implementations, accurate to about 1 ulp).

/// sin x.
#[inline]
#[must_use]
pub fn sin(x: f64) -> f64 {
    libm::sin(x)
}

/// cos x.
#[inline]
#[must_use]
pub fn cos(x: f64) -> f64 {
    libm::cos(x)
}

/// √x.
#[inline]
#[must_use]
pub fn sqrt(x: f64) -> f64 {
    libm::sqrt(x)
}
