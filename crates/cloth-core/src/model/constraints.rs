//! Provot's (1995) deformation constraints ("inverse dynamics"): after a
//! step, links stretched beyond `(1 + tau_c) L` are shortened back by
//! moving their ends, so a cloth does not stretch like rubber where it
//! hangs from few points. Only type-1 (structural and shear) links are
//! constrained, and closed stitches, whose rest length is zero, are
//! closed: a sewn seam is a constraint too, and its stitch spring alone
//! lets it gape by its load over its stiffness. Pinned and held particles
//! never move.

use crate::{ClothModel, StrainLimit, Vec3};

/// A closed stitch this short is left as it is, m: rounding, not a gap.
const STITCH_SLACK_M: f64 = 1e-12;

/// What one application did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StrainLimitReport {
    /// Passes run (stops early once no link is too long).
    pub passes: usize,
    /// Link corrections made over all passes.
    pub corrections: usize,
    /// Whether the last pass found nothing to correct: every link within
    /// its limit and every closed stitch closed.
    pub settled: bool,
}

/// Applies `limit` to positions `x` in place, closed stitch by stitch and
/// then link by link in model order (Gauss-Seidel, deterministic; links
/// last: where the passes run out, the stretch is what they bound). Each
/// pass can re-stretch what it fixed earlier, so convergence is linear: `passes`
/// is a cap, and the pass loop stops as soon as no link is too long and no
/// closed stitch (`stitches_closed`, [`crate::ClothState::stitches_closed`])
/// is open. Velocities get the same correction divided by `h`, so `v`
/// stays consistent with the corrected motion. Pinned particles never
/// move, nor those `held` says are held (see [`crate::Control::is_held`]).
pub fn apply_strain_limit(
    model: &ClothModel,
    limit: &StrainLimit,
    held: impl Fn(usize) -> bool,
    stitches_closed: &[bool],
    (x, v): (&mut [Vec3], &mut [Vec3]),
    h: f64,
) -> StrainLimitReport {
    let mut report = StrainLimitReport::default();
    let stretch = 1.0 + limit.max_strain;
    let free = |q: usize| !model.is_pinned(q) && !held(q);
    // Moves the ends of the pair `i`, `j` to `max_len` apart along their
    // line when they are further apart than `slack`; whether it did.
    let shorten = |x: &mut [Vec3], v: &mut [Vec3], [i, j]: [usize; 2], max_len: f64, slack: f64| {
        let xij = x[j] - x[i];
        let d = xij.norm();
        if d <= slack {
            return false;
        }
        // Share of the excess each end takes.
        let (wi, wj) = match (free(i), free(j)) {
            (true, true) => (0.5, 0.5),
            (true, false) => (1.0, 0.0),
            (false, true) => (0.0, 1.0),
            (false, false) => return false,
        };
        let excess = xij * ((d - max_len) / d);
        let (di, dj) = (excess * wi, -excess * wj);
        x[i] += di;
        x[j] += dj;
        v[i] += di / h;
        v[j] += dj / h;
        true
    };
    for _ in 0..limit.passes {
        report.passes += 1;
        let mut corrected = 0;
        for (s, _) in model.stitches().iter().zip(stitches_closed).filter(|(_, closed)| **closed) {
            corrected += usize::from(shorten(x, v, [s.i as usize, s.j as usize], 0.0, STITCH_SLACK_M));
        }
        for l in model.stretch_links() {
            let max_len = stretch * l.rest;
            // A relative slack of 1e-12 keeps rounding from re-correcting a
            // link just set to its limit (and so from burning every pass).
            corrected += usize::from(shorten(x, v, [l.i as usize, l.j as usize], max_len, max_len * (1.0 + 1e-12)));
        }
        report.corrections += corrected;
        if corrected == 0 {
            report.settled = true;
            break;
        }
    }
    report
}
