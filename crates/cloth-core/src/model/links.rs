//! The model's links: type-1 (stretch) links with their law in
//! compression, type-2 (bend) links, and each particle's view of its links
//! in its matrix row.

use crate::laws::{BucklingLaw, ScalarLaw, bilinear_spring, linear_spring};

/// How a type-1 link resists compression.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Compression {
    /// A linear spring of this stiffness, N/m: 0 for Choi & Ko's
    /// tension-only spring under the paper's pair law (its type-2 links hold
    /// the compression) and for Volino's (the membrane does), `k_s` for
    /// Provot's linear spring.
    Linear(f64),
    /// Choi & Ko's buckling law (Eq. 11) for the strip the link stands for,
    /// under the arc-path law: the ramp `c_b (L - d)` capped by the arc
    /// force `|f_b(d)|` of a link of flexural rigidity `k_b`, so a
    /// compressed link yields once its strip buckles (the Euler-like load
    /// `12 k_b / L^2`) instead of holding the membrane flat.
    Buckling(BucklingLaw),
}

/// A type-1 link: a spring in tension with its own law in compression
/// ([`Compression`]) and directional damping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StretchLink {
    /// First particle.
    pub i: u32,
    /// Second particle.
    pub j: u32,
    /// Rest length, m.
    pub rest: f64,
    /// Stiffness in tension, N/m.
    pub k_s: f64,
    /// The law below the rest length.
    pub compression: Compression,
    /// Damping, N s/m (0 when the damping effect is off).
    pub k_d: f64,
}

impl StretchLink {
    /// The spring law at chord `d` (m).
    #[inline]
    pub fn eval(&self, d: f64) -> ScalarLaw {
        match self.compression {
            Compression::Buckling(law) if d < self.rest => law.eval(d),
            Compression::Buckling(_) => linear_spring(d, self.rest, self.k_s),
            Compression::Linear(k_c) => bilinear_spring(d, self.rest, self.k_s, k_c),
        }
    }
}

/// The law of a bending link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BendLaw {
    /// Choi & Ko's buckling law ([`crate::BendingLaw::ArcChord`]).
    Buckling(BucklingLaw),
    /// Provot's linear flexion spring.
    Flexion {
        /// Rest length, m.
        rest: f64,
        /// Stiffness, N/m.
        k: f64,
    },
}

impl BendLaw {
    /// The law at chord `d` (m).
    #[inline]
    pub fn eval(&self, d: f64) -> ScalarLaw {
        match self {
            BendLaw::Buckling(b) => b.eval(d),
            BendLaw::Flexion { rest, k } => linear_spring(d, *rest, *k),
        }
    }
}

/// A bending link: Choi & Ko's type-2 pair ([`crate::BendingLaw::ArcChord`]) or
/// Provot's flexion spring.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BendLink {
    /// First particle.
    pub i: u32,
    /// Second particle.
    pub j: u32,
    /// The law with its constants.
    pub law: BendLaw,
}

impl BendLink {
    /// The law at chord `d` (m).
    #[inline]
    pub fn eval(&self, d: f64) -> ScalarLaw {
        self.law.eval(d)
    }
}

/// One link incident to a particle, as seen from that particle's matrix row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Incidence {
    /// Link index (stretch links first, then bend links).
    pub link: u32,
    /// The other particle.
    pub other: u32,
    /// Whether this particle is the link's `i` (the link's force is then `+f`).
    pub first: bool,
    /// Offset of block `(row, other)` within the row's stored blocks.
    pub slot: u32,
}
