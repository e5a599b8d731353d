//! Finite differences the crate's tests check forces and blocks with.

use crate::Vec3;

/// Central differences of `f` at `x` along each axis, step `d`.
pub(crate) fn gradient(f: impl Fn(Vec3) -> f64, x: Vec3, d: f64) -> Vec3 {
    Vec3::from_fn(|a, _| {
        let e = Vec3::ith(a, d);
        (f(x + e) - f(x - e)) / (2.0 * d)
    })
}
