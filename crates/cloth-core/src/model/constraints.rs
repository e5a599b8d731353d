//! Provot's (1995) deformation constraints ("inverse dynamics"): after a
//! step, links stretched beyond `(1 + tau_c) L` are shortened back by
//! moving their ends, so a cloth does not stretch like rubber where it
//! hangs from few points. Only type-1 (structural and shear) links are
//! constrained, and closed stitches, whose rest length is zero, are
//! closed: a sewn seam is a constraint too, and its stitch spring alone
//! lets it gape by its load over its stiffness. Pinned and held particles
//! never move.

use crate::model::fast_projection::{Bounds, ProjectionReport, ProjectionScratch, SolidBound, fast_projection};
use crate::{ClothModel, StrainLimit, Vec3};

/// A closed stitch this short is left as it is, m: rounding, not a gap.
const STITCH_SLACK_M: f64 = 1e-12;
/// A link this far over its limit, relative, is left as it is: rounding
/// keeps a link just set to its limit from being corrected again (and so
/// from burning every pass).
const LINK_SLACK: f64 = 1e-12;

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

/// How far past the deformation constraints' limit, as a share of the
/// limit's length, a link may be after a step before a run reports it:
/// 1% (a link of the 10% limit reported beyond 1.111 times its rest
/// length). Where the passes settle, links end within `1e-12` of the limit.
pub const OVER_LIMIT_TOLERANCE: f64 = 0.01;

/// A link the deformation constraints left longer than their limit allows
/// (see [`over_stretched`]): where the passes ran out, or solids, pins or
/// impact zones held its ends apart.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OverStretch {
    /// The link's particles.
    pub link: [usize; 2],
    /// Its length over its rest length.
    pub ratio: f64,
    /// The limit's length over the rest length, `1 + max_strain`.
    pub limit_ratio: f64,
}

impl StrainLimit {
    /// The longest a link may be over its rest length, `1 + max_strain`.
    pub fn limit_ratio(&self) -> f64 {
        1.0 + self.max_strain
    }

    /// The length over rest length beyond which a run reports a link as
    /// past the limit ([`over_stretched`]): the limit ratio times
    /// `1 + OVER_LIMIT_TOLERANCE`.
    pub fn reported_ratio(&self) -> f64 {
        self.limit_ratio() * (1.0 + OVER_LIMIT_TOLERANCE)
    }
}

/// The most stretched link at positions `x` when it is longer than
/// [`StrainLimit::reported_ratio`] times its rest length; `None` when it
/// is not, or when `model` has no deformation constraints. The same link
/// for any thread count ([`ClothModel::most_stretched`]).
pub fn over_stretched(model: &ClothModel, x: &[Vec3]) -> Option<OverStretch> {
    let limit = model.strain_limit()?;
    let (ratio, i, j) = model.most_stretched(x)?;
    let limit_ratio = limit.limit_ratio();
    (ratio > limit.reported_ratio()).then_some(OverStretch { link: [i, j], ratio, limit_ratio })
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
/// With `limit.projections > 0`, that many fast projections
/// (Goldenthal et al. 2007) come first: every violated link at once.
/// For the workspace's tests (`cloth_core::testing`); the step calls the
/// two passes with its own scratch.
#[cfg(feature = "testing")]
pub fn apply_strain_limit(
    model: &ClothModel,
    limit: &StrainLimit,
    held: impl Fn(usize) -> bool,
    stitches_closed: &[bool],
    (x, v): (&mut [Vec3], &mut [Vec3]),
    h: f64,
) -> StrainLimitReport {
    project_strain_limit(model, limit, &held, (stitches_closed, &[]), (x, v), h, &mut ProjectionScratch::default());
    apply_strain_limit_with(model, limit, held, stitches_closed, (x, v), h, &mut Vec::new())
}

/// Whether the constraints may move particle `q`: neither pinned nor
/// held (see [`crate::Control::is_held`]).
fn movable(model: &ClothModel, held: &impl Fn(usize) -> bool, q: usize) -> bool {
    !model.is_pinned(q) && !held(q)
}

/// `limit.projections` fast projections of the links over `limit` and
/// the open closed stitches, keeping particles within the bounds of the
/// solids near them (`solids`), moving neither pinned particles nor those
/// `held` says are held; velocities get each move over `h`.
pub(crate) fn project_strain_limit(
    model: &ClothModel,
    limit: &StrainLimit,
    held: &impl Fn(usize) -> bool,
    (stitches_closed, solids): (&[bool], &[SolidBound]),
    (x, v): (&mut [Vec3], &mut [Vec3]),
    h: f64,
    scratch: &mut ProjectionScratch,
) -> ProjectionReport {
    if limit.projections == 0 {
        return ProjectionReport::default();
    }
    let bounds = Bounds {
        stretch: limit.limit_ratio(),
        slack: LINK_SLACK,
        stitch_slack_m: STITCH_SLACK_M,
        stitches_closed,
        solids,
    };
    fast_projection(model, &bounds, |q| movable(model, held, q), (x, v), h, limit.projections, scratch)
}

/// `apply_strain_limit` with its scratch: one bit per stretch link,
/// set while the link may need a correction. A pass looks only at the
/// links whose bit is set: a link whose ends have not moved since it was
/// last found within its limit is within it still, so the passes do what
/// full passes do, bit for bit, and after the first they touch only the
/// neighbourhood of the last corrections.
pub(crate) fn apply_strain_limit_with(
    model: &ClothModel,
    limit: &StrainLimit,
    held: impl Fn(usize) -> bool,
    stitches_closed: &[bool],
    (x, v): (&mut [Vec3], &mut [Vec3]),
    h: f64,
    dirty: &mut Vec<u64>,
) -> StrainLimitReport {
    let mut report = StrainLimitReport::default();
    let links = model.stretch_links();
    dirty.clear();
    dirty.resize(links.len().div_ceil(64), u64::MAX);
    if let Some(last) = dirty.last_mut().filter(|_| !links.len().is_multiple_of(64)) {
        *last = (1 << (links.len() % 64)) - 1;
    }
    // Every stretch link at particle `p` may need a look again.
    let touch = |dirty: &mut [u64], p: usize| {
        for inc in model.incidence(p) {
            let l = inc.link as usize;
            if l < links.len() {
                dirty[l / 64] |= 1 << (l % 64);
            }
        }
    };
    let stretch = limit.limit_ratio();
    let free = |q: usize| movable(model, &held, q);
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
            let ends = [s.i as usize, s.j as usize];
            if shorten(x, v, ends, 0.0, STITCH_SLACK_M) {
                corrected += 1;
                ends.iter().for_each(|&p| touch(dirty, p));
            }
        }
        // The set bits in link order: a link set behind the scan waits for
        // the next pass, as a full pass would reach it only then.
        for word in 0..dirty.len() {
            let mut from = 0;
            while from < 64 {
                let ahead = dirty[word] & (u64::MAX << from);
                if ahead == 0 {
                    break;
                }
                let bit = ahead.trailing_zeros() as usize;
                dirty[word] &= !(1 << bit);
                from = bit + 1;
                let l = &links[word * 64 + bit];
                let (max_len, ends) = (stretch * l.rest, [l.i as usize, l.j as usize]);
                if shorten(x, v, ends, max_len, max_len * (1.0 + LINK_SLACK)) {
                    corrected += 1;
                    ends.iter().for_each(|&p| touch(dirty, p));
                }
            }
        }
        report.corrections += corrected;
        if corrected == 0 {
            report.settled = true;
            break;
        }
    }
    report
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{GridPanel, ModelSpec};

    /// Full passes over every link, as Provot's method states them: what
    /// the passes over the links that may need a correction must match.
    fn full_passes(
        model: &ClothModel,
        limit: &StrainLimit,
        held: impl Fn(usize) -> bool,
        (x, v): (&mut [Vec3], &mut [Vec3]),
        h: f64,
    ) -> StrainLimitReport {
        let mut report = StrainLimitReport::default();
        let free = |q: usize| !model.is_pinned(q) && !held(q);
        for _ in 0..limit.passes {
            report.passes += 1;
            let mut corrected = 0;
            for l in model.stretch_links() {
                let (i, j, max_len) = (l.i as usize, l.j as usize, (1.0 + limit.max_strain) * l.rest);
                let xij = x[j] - x[i];
                let d = xij.norm();
                let (wi, wj) = match (free(i), free(j)) {
                    (true, true) => (0.5, 0.5),
                    (true, false) => (1.0, 0.0),
                    (false, true) => (0.0, 1.0),
                    (false, false) => continue,
                };
                if d <= max_len * (1.0 + 1e-12) {
                    continue;
                }
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
                report.settled = true;
                break;
            }
        }
        report
    }

    /// The passes that look only at links whose ends moved give the full
    /// passes' positions, velocities and counts bit for bit, on a sheet
    /// of 11 x 9 particles (its links fill several words of bits, the last
    /// one in part) shaken far past its limit, two corners held, for budgets that stop before,
    /// at and after it settles (185 passes).
    #[test]
    fn passes_over_moved_links_match_full_passes_bit_for_bit() {
        let model = ClothModel::build(&ModelSpec {
            panels: vec![GridPanel {
                particles: [11, 9],
                size_m: [0.2, 0.16],
                origin_m: [0.0, 0.0, 0.0],
                u_axis: [1.0, 0.0, 0.0],
                v_axis: [0.0, 1.0, 0.0],
                wrap_u: false,
            }],
            ..ModelSpec::default()
        })
        .unwrap();
        assert!(!model.stretch_links().len().is_multiple_of(64) && model.stretch_links().len() > 128);
        let mut seed = 7_u64;
        let mut noise = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        };
        let x0: Vec<Vec3> =
            model.rest_positions().iter().map(|p| p + Vec3::new(noise(), noise(), noise()) * 0.008).collect();
        let v0: Vec<Vec3> = (0..x0.len()).map(|_| Vec3::new(noise(), noise(), noise())).collect();
        let held = |i: usize| i == 0 || i == 98;
        let h = 1.0 / 90.0;
        let mut dirty = Vec::new();
        let mut settled_at = None;
        for passes in [1, 2, 5, 20, 2000] {
            let limit = StrainLimit { max_strain: 0.1, passes, projections: 0 };
            let (mut xa, mut va) = (x0.clone(), v0.clone());
            let (mut xb, mut vb) = (x0.clone(), v0.clone());
            let full = full_passes(&model, &limit, held, (&mut xa, &mut va), h);
            let sparse = apply_strain_limit_with(&model, &limit, held, &[], (&mut xb, &mut vb), h, &mut dirty);
            assert_eq!(full, sparse, "{passes} passes");
            let bits = |p: &[Vec3]| p.iter().flat_map(|q| q.iter().map(|c| c.to_bits())).collect::<Vec<_>>();
            assert_eq!((bits(&xa), bits(&va)), (bits(&xb), bits(&vb)), "{passes} passes");
            settled_at = settled_at.or(full.settled.then_some(full.passes));
        }
        // The budgets cover a run that settles after several passes.
        assert!(settled_at.is_some_and(|p| p > 5), "settled after {settled_at:?} passes");
    }

    /// A strip with the limit on reports its longest link once it is past
    /// the limit by more than the tolerance, and only then: at the limit
    /// and just inside the tolerance nothing; without the constraints
    /// nothing, however stretched. The link named is the stretched one.
    #[test]
    fn over_stretched_names_the_link_past_the_limit() {
        let strip = |strain_limit| {
            ClothModel::build(&ModelSpec {
                panels: vec![GridPanel {
                    particles: [5, 2],
                    size_m: [0.4, 0.1],
                    origin_m: [0.0, 0.0, 0.0],
                    u_axis: [1.0, 0.0, 0.0],
                    v_axis: [0.0, 1.0, 0.0],
                    wrap_u: false,
                }],
                strain_limit,
                ..ModelSpec::default()
            })
            .unwrap()
        };
        let model = strip(Some(StrainLimit { max_strain: 0.1, passes: 1, projections: 0 }));
        // Particles 2 and 3 (a 0.1 m link along the strip) pulled apart:
        // the link between them takes the stretch `s`.
        let pulled = |s: f64| -> Vec<Vec3> {
            let mut x = model.rest_positions().to_vec();
            for (k, p) in x.iter_mut().enumerate() {
                if k % 5 >= 3 {
                    p.x += 0.1 * (s - 1.0);
                }
            }
            x
        };
        let edge = 1.1 * (1.0 + OVER_LIMIT_TOLERANCE);
        assert_eq!(over_stretched(&model, &pulled(1.1)), None);
        assert_eq!(over_stretched(&model, &pulled(edge * (1.0 - 1e-9))), None);
        let over = over_stretched(&model, &pulled(1.2)).expect("a link at 1.2 is past the limit");
        assert_eq!(over.link, [2, 3]);
        assert!((over.ratio - 1.2).abs() < 1e-12 && (over.limit_ratio - 1.1).abs() < 1e-15, "{over:?}");
        assert!(over_stretched(&model, &pulled(edge * (1.0 + 1e-9))).is_some());
        assert_eq!(over_stretched(&strip(None), &pulled(3.0)), None);
    }
}
