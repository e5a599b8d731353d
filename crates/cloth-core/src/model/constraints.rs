//! Provot's (1995) deformation constraints ("inverse dynamics"): after a
//! step, links stretched beyond `(1 + tau_c) L` are shortened back by
//! moving their ends, so a cloth does not stretch like rubber where it
//! hangs from few points. Only type-1 (structural and shear) links are
//! constrained; pinned and held particles never move.

use crate::{ClothModel, StrainLimit, Vec3};

/// What one application did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StrainLimitReport {
    /// Passes run (stops early once no link is too long).
    pub passes: usize,
    /// Link corrections made over all passes.
    pub corrections: usize,
}

/// Applies `limit` to positions `x` in place, link by link in model order
/// (Gauss-Seidel, deterministic). Each pass can re-stretch links fixed
/// earlier in it, so convergence is linear: `passes` is a cap, and the pass
/// loop stops as soon as no link is too long. Velocities get the same correction
/// divided by `h`, so `v` stays consistent with the corrected motion.
/// Pinned particles never move, nor those `held` says are held (see
/// [`crate::Control::is_held`]).
pub fn apply_strain_limit(
    model: &ClothModel,
    limit: &StrainLimit,
    held: impl Fn(usize) -> bool,
    x: &mut [Vec3],
    v: &mut [Vec3],
    h: f64,
) -> StrainLimitReport {
    let mut report = StrainLimitReport::default();
    let stretch = 1.0 + limit.max_strain;
    for _ in 0..limit.passes {
        report.passes += 1;
        let mut corrected = 0;
        for l in model.stretch_links() {
            let (i, j) = (l.i as usize, l.j as usize);
            let xij = x[j] - x[i];
            let d = xij.norm();
            let max_len = stretch * l.rest;
            // A relative slack of 1e-12 keeps rounding from re-correcting a
            // link just set to its limit (and so from burning every pass).
            if d <= max_len * (1.0 + 1e-12) {
                continue;
            }
            let free = |q: usize| !model.is_pinned(q) && !held(q);
            let (free_i, free_j) = (free(i), free(j));
            // Share of the excess each end takes.
            let (wi, wj) = match (free_i, free_j) {
                (true, true) => (0.5, 0.5),
                (true, false) => (1.0, 0.0),
                (false, true) => (0.0, 1.0),
                (false, false) => continue,
            };
            let excess = xij * ((d - max_len) / d);
            let (di, dj) = (excess * wi, -excess * wj);
            x[i] += di;
            x[j] += dj;
            v[i] += di / h;
            v[j] += dj / h;
            corrected += 1;
        }
        report.corrections += corrected;
        if corrected == 0 {
            break;
        }
    }
    report
}
