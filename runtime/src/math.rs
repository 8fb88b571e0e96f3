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

/// (sin x, cos x), with one argument reduction: bit for bit the values of [`sin`] and [`cos`].
#[inline]
#[must_use]
pub fn sin_cos(x: f64) -> (f64, f64) {
    libm::sincos(x)
}

#[cfg(test)]
mod tests;
