//! Baraff & Witkin's (1998) constraint filter for conjugate gradients.
//!
//! Each particle `i` has a projector `S_i` onto its free directions and a
//! prescribed value `z_i` for its constrained components:
//! `S_i = I` (free), `I - n n^T` (one constrained direction `n`),
//! `I - n n^T - m m^T` (two), `0` (fixed). The unknown is kept at
//! `x_i = S_i x_i + (I - S_i) z_i`; residuals and search directions are
//! multiplied by `S` every iteration, so the constrained components never move.

use crate::{Mat3, Vec3};

/// What a particle's unknown is allowed to do.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Constraint {
    /// No constraint.
    Free,
    /// The component along `normal` is prescribed (e.g. a contact).
    OneDirection {
        /// Constrained direction; need not be normalised, must be non-zero.
        normal: Vec3,
    },
    /// The components along `n` and `m` are prescribed; motion stays free
    /// along `n x m` (e.g. a particle sliding on a rail).
    TwoDirections {
        /// First constrained direction, non-zero.
        n: Vec3,
        /// Second constrained direction, not parallel to `n`.
        m: Vec3,
    },
    /// All three components are prescribed (a pin).
    Fixed,
}

/// Why a constraint could not be added.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FilterError {
    /// The particle index is outside the filter.
    #[error("constraint on particle {index} but the filter has {n} particles")]
    OutOfRange {
        /// Offending particle index.
        index: usize,
        /// Number of particles.
        n: usize,
    },
    /// A constraint direction is zero, non-finite, or two directions are parallel.
    #[error("constraint on particle {index} has a zero, non-finite or parallel direction")]
    DegenerateDirection {
        /// Offending particle index.
        index: usize,
    },
    /// The prescribed value is not finite.
    #[error("constraint on particle {index} prescribes a non-finite value")]
    NonFinite {
        /// Offending particle index.
        index: usize,
    },
}

#[derive(Debug, Clone)]
struct Entry {
    index: usize,
    /// Projector onto the free directions.
    s: Mat3,
    /// Prescribed part, `(I - S) z`.
    z: Vec3,
}

/// The set of constrained particles of one linear solve.
///
/// Only constrained particles are stored, so filtering costs O(constrained).
#[derive(Debug, Clone, Default)]
pub struct ConstraintFilter {
    n: usize,
    entries: Vec<Entry>,
    /// `slot[i]` is the entry of particle `i`, or `usize::MAX` when free.
    slot: Vec<usize>,
}

impl ConstraintFilter {
    /// A filter for `n` particles, all free.
    pub fn new(n: usize) -> Self {
        Self { n, entries: Vec::new(), slot: vec![usize::MAX; n] }
    }

    /// Number of particles.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Makes every particle free again (keeps the allocation).
    pub fn clear(&mut self) {
        for e in &self.entries {
            self.slot[e.index] = usize::MAX;
        }
        self.entries.clear();
    }

    /// Whether particle `i` has no constraint.
    pub fn is_free(&self, i: usize) -> bool {
        self.slot.get(i).is_none_or(|&s| s == usize::MAX)
    }

    /// Number of constrained particles.
    pub fn constrained_count(&self) -> usize {
        self.entries.len()
    }

    /// Constrains particle `index`, replacing any earlier constraint on it.
    /// `value` is the prescribed unknown; only its constrained components are used.
    pub fn set(&mut self, index: usize, constraint: Constraint, value: Vec3) -> Result<(), FilterError> {
        if index >= self.n {
            return Err(FilterError::OutOfRange { index, n: self.n });
        }
        if !value.iter().all(|v| v.is_finite()) {
            return Err(FilterError::NonFinite { index });
        }
        let degenerate = FilterError::DegenerateDirection { index };
        let unit = |v: Vec3| -> Result<Vec3, FilterError> {
            let len = v.norm();
            if len.is_finite() && len > 1e-300 { Ok(v / len) } else { Err(degenerate.clone()) }
        };
        let s = match constraint {
            Constraint::Free => {
                self.remove(index);
                return Ok(());
            }
            Constraint::OneDirection { normal } => {
                let n = unit(normal)?;
                Mat3::identity() - n * n.transpose()
            }
            Constraint::TwoDirections { n, m } => {
                let n = unit(n)?;
                let m_perp = m - n * n.dot(&m);
                if m_perp.norm() <= 1e-9 * m.norm() {
                    return Err(degenerate);
                }
                let m = unit(m_perp)?;
                Mat3::identity() - n * n.transpose() - m * m.transpose()
            }
            Constraint::Fixed => Mat3::zeros(),
        };
        let entry = Entry { index, s, z: value - s * value };
        match self.slot[index] {
            usize::MAX => {
                self.slot[index] = self.entries.len();
                self.entries.push(entry);
            }
            k => self.entries[k] = entry,
        }
        Ok(())
    }

    fn remove(&mut self, index: usize) {
        let k = self.slot[index];
        if k == usize::MAX {
            return;
        }
        self.slot[index] = usize::MAX;
        self.entries.swap_remove(k);
        if let Some(moved) = self.entries.get(k) {
            self.slot[moved.index] = k;
        }
    }

    /// The projector `S_i` of particle `i`.
    pub fn projector(&self, i: usize) -> Mat3 {
        match self.slot[i] {
            usize::MAX => Mat3::identity(),
            k => self.entries[k].s,
        }
    }

    /// The prescribed part `(I - S_i) z_i` of particle `i` (zero when free).
    pub fn prescribed(&self, i: usize) -> Vec3 {
        match self.slot[i] {
            usize::MAX => Vec3::zeros(),
            k => self.entries[k].z,
        }
    }

    /// `v <- S v`: removes the constrained components.
    pub fn project(&self, v: &mut [Vec3]) {
        for e in &self.entries {
            v[e.index] = e.s * v[e.index];
        }
    }

    /// `x <- S x + (I - S) z`: sets the constrained components to their
    /// prescribed values and keeps the free ones.
    pub fn impose(&self, x: &mut [Vec3]) {
        for e in &self.entries {
            x[e.index] = e.s * x[e.index] + e.z;
        }
    }

    /// Sets every prescribed value to zero and keeps the constraints: the
    /// filter of a correction to an unknown that already meets them (a
    /// Newton correction keeps the constrained components where they are).
    pub fn zero_prescribed(&mut self) {
        self.entries.iter_mut().for_each(|e| e.z = Vec3::zeros());
    }

    /// Iterates over `(particle, projector, prescribed part)` of the constrained particles.
    pub fn iter(&self) -> impl Iterator<Item = (usize, &Mat3, &Vec3)> {
        self.entries.iter().map(|e| (e.index, &e.s, &e.z))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_zeroed_filter_keeps_its_constraints() {
        let mut f = ConstraintFilter::new(3);
        f.set(0, Constraint::OneDirection { normal: Vec3::z() }, Vec3::new(1.0, 2.0, 3.0)).unwrap();
        f.set(2, Constraint::Fixed, Vec3::new(4.0, 5.0, 6.0)).unwrap();
        let before: Vec<Mat3> = (0..3).map(|i| f.projector(i)).collect();
        f.zero_prescribed();
        assert!((0..3).all(|i| f.projector(i) == before[i] && f.prescribed(i) == Vec3::zeros()));
        assert_eq!(f.constrained_count(), 2);
    }

    #[test]
    fn projectors_have_the_right_rank() {
        let mut f = ConstraintFilter::new(4);
        f.set(1, Constraint::OneDirection { normal: Vec3::new(0.0, 0.0, 2.0) }, Vec3::zeros()).unwrap();
        f.set(2, Constraint::TwoDirections { n: Vec3::x(), m: Vec3::new(1.0, 1.0, 0.0) }, Vec3::zeros()).unwrap();
        f.set(3, Constraint::Fixed, Vec3::new(1.0, 2.0, 3.0)).unwrap();
        let trace = |i| f.projector(i).trace();
        assert_eq!([trace(0), trace(1), trace(2), trace(3)], [3.0, 2.0, 1.0, 0.0]);
        // Two directions x and (x+y) leave z free.
        assert!((f.projector(2) - Vec3::z() * Vec3::z().transpose()).norm() < 1e-15);
        assert_eq!(f.prescribed(3), Vec3::new(1.0, 2.0, 3.0));
    }

    #[test]
    fn impose_keeps_free_components() {
        let mut f = ConstraintFilter::new(2);
        f.set(0, Constraint::OneDirection { normal: Vec3::z() }, Vec3::new(9.0, 9.0, -1.0)).unwrap();
        let mut x = vec![Vec3::new(1.0, 2.0, 3.0), Vec3::new(4.0, 5.0, 6.0)];
        f.impose(&mut x);
        assert_eq!(x[0], Vec3::new(1.0, 2.0, -1.0));
        assert_eq!(x[1], Vec3::new(4.0, 5.0, 6.0));
    }

    #[test]
    fn rejects_bad_constraints() {
        let mut f = ConstraintFilter::new(2);
        assert!(matches!(f.set(5, Constraint::Fixed, Vec3::zeros()), Err(FilterError::OutOfRange { .. })));
        assert!(matches!(
            f.set(0, Constraint::OneDirection { normal: Vec3::zeros() }, Vec3::zeros()),
            Err(FilterError::DegenerateDirection { .. })
        ));
        assert!(matches!(
            f.set(0, Constraint::TwoDirections { n: Vec3::x(), m: Vec3::x() * 2.0 }, Vec3::zeros()),
            Err(FilterError::DegenerateDirection { .. })
        ));
        assert!(matches!(
            f.set(0, Constraint::Fixed, Vec3::new(f64::NAN, 0.0, 0.0)),
            Err(FilterError::NonFinite { .. })
        ));
    }

    #[test]
    fn free_and_clear_release_particles() {
        let mut f = ConstraintFilter::new(3);
        f.set(0, Constraint::Fixed, Vec3::zeros()).unwrap();
        f.set(2, Constraint::Fixed, Vec3::zeros()).unwrap();
        f.set(0, Constraint::Free, Vec3::zeros()).unwrap();
        assert_eq!(f.constrained_count(), 1);
        assert_eq!(f.projector(0), Mat3::identity());
        assert_eq!(f.projector(2), Mat3::zeros());
        f.clear();
        assert_eq!(f.constrained_count(), 0);
        assert_eq!(f.projector(2), Mat3::identity());
    }
}
