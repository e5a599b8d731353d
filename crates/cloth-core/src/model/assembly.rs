//! What an implicit step's linear system is made of, as the force terms
//! see it when they assemble themselves ([`crate::terms::TermAssembly`]):
//! its coefficients ([`SystemTerms`]) and one of its rows ([`Row`]). The
//! assembler is [`crate::system`].

use crate::{Mat3, Vec3};

/// The coefficients of one implicit step's linear system
/// `A = M - c_v D - c_x K`,
/// `b_i = m_i y_i + force (f_i + m_i g) + a_k (K w_k)_i + a_d (D w_d)_i`,
/// with `f` the elastic (undamped) force.
#[derive(Debug, Clone, Copy)]
pub struct SystemTerms<'a> {
    /// Coefficient of `-K` in the matrix, s^2.
    pub c_x: f64,
    /// Coefficient of `-D` in the matrix, s.
    pub c_v: f64,
    /// Coefficient of the elastic and gravity forces in the right-hand side.
    pub force: f64,
    /// Optional `(a_k, w_k)`: adds `a_k K w_k`.
    pub k_times: Option<(f64, &'a [Vec3])>,
    /// Optional `(a_d, w_d)`: adds `a_d D w_d`.
    pub d_times: Option<(f64, &'a [Vec3])>,
    /// Optional `y`: adds `M y`.
    pub mass_times: Option<&'a [Vec3]>,
    /// Optional external forces (wind, self-collision) taken at the start
    /// of the step, N: adds `force * f_ext`.
    pub external: Option<&'a [Vec3]>,
    /// Optional stiffness of forces outside the terms, kept on the
    /// diagonal only: blocks `S_i = -df_i/dx_i` (N/m, positive
    /// semidefinite; self-collision). Adds `c_x S_i` to the matrix and,
    /// with `k_times = (a_k, w_k)`, `-a_k S_i w_k` to the right-hand side.
    pub diag_stiffness: Option<&'a [Mat3]>,
    /// Optional damping of forces outside the terms, kept on the diagonal
    /// only: blocks `C_i = -df_i/dv_i` (N s/m, positive semidefinite;
    /// friction of squeezed particles). Adds `c_v C_i` to the matrix and,
    /// with `d_times = (a_d, w_d)`, `-a_d C_i w_d` to the right-hand side;
    /// the force's constant part goes in `external`.
    pub diag_damping: Option<&'a [Mat3]>,
    /// Of each stitch, whether it has closed
    /// ([`crate::ClothState::stitches_closed`]).
    pub stitches_closed: &'a [bool],
}

impl<'a> SystemTerms<'a> {
    /// `A = M - c_v D - c_x K`, `b = force (f + m g)`, with none of the
    /// optional terms (set those with struct update syntax), the stitches
    /// in `stitches_closed`'s states (empty without seams).
    pub fn new(c_x: f64, c_v: f64, force: f64, stitches_closed: &'a [bool]) -> Self {
        Self {
            c_x,
            c_v,
            force,
            k_times: None,
            d_times: None,
            mass_times: None,
            external: None,
            diag_stiffness: None,
            diag_damping: None,
            stitches_closed,
        }
    }
}

/// One row of the matrix as the parts add to it: the diagonal block is
/// summed in a register until a part writes the row's stored diagonal
/// directly, then stored (no part's order changes the sum).
#[derive(Debug)]
pub struct Row<'r> {
    blocks: &'r mut [Mat3],
    diag_slot: usize,
    diag: Option<Mat3>,
}

impl<'r> Row<'r> {
    pub(crate) fn new(blocks: &'r mut [Mat3], diag_slot: usize) -> Self {
        blocks.iter_mut().for_each(|b| *b = Mat3::zeros());
        Self { blocks, diag_slot, diag: Some(Mat3::zeros()) }
    }

    /// Adds `block` to the diagonal block `A_ii`.
    pub fn add_diag(&mut self, block: &Mat3) {
        match self.diag.as_mut() {
            Some(d) => *d += block,
            None => self.blocks[self.diag_slot] += block,
        }
    }

    /// Adds `block` to the row's stored block `slot` (its position in the
    /// row of the pattern).
    pub fn add(&mut self, slot: usize, block: &Mat3) {
        if slot == self.diag_slot {
            self.store_diag();
        }
        self.blocks[slot] += block;
    }

    /// Subtracts `block` from the row's stored block `slot`.
    pub fn sub(&mut self, slot: usize, block: &Mat3) {
        if slot == self.diag_slot {
            self.store_diag();
        }
        self.blocks[slot] -= block;
    }

    pub(crate) fn store_diag(&mut self) {
        if let Some(d) = self.diag.take() {
            self.blocks[self.diag_slot] = d;
        }
    }
}
