//! Rigid bodies that join the cloth's linear solve: what the control
//! gives for each ([`BodyInSolve`]), its checks, and the lever that maps
//! a body's motion to a point's. The solve itself is in `body_solve.rs`.

use crate::{ClothModel, Mat3, Vec3};
use nalgebra::Matrix3x6;

/// A rigid body that joins the cloth's solve for the next step.
#[derive(Debug, Clone, PartialEq)]
pub struct BodyInSolve {
    /// Mass, kg (finite, > 0).
    pub mass_kg: f64,
    /// Inertia tensor about the centre of mass, world axes, kg m^2
    /// (symmetric positive definite).
    pub inertia_kg_m2: Mat3,
    /// Centre of mass at the end of the step on the motion set for its
    /// solids and pins, m (the levers of its particles start there).
    pub com_m: Vec3,
    /// How much faster that motion moves the centre of mass over the step
    /// (mean velocity, m/s) than the body would move without the cloth:
    /// zero when the motion set is the body's free flight. Any motion
    /// will do as the step's guess; the solve corrects it.
    pub ahead_m_s: Vec3,
    /// The same for its mean angular velocity, rad/s.
    pub ahead_rad_s: Vec3,
    /// The model's external solids that are this body's shapes.
    pub solids: Vec<usize>,
    /// The model's external pins attached to it.
    pub pins: Vec<usize>,
}

/// Why a body was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BodyError {
    /// Mass not finite or not positive.
    #[error("body {body}: mass {mass_kg} kg must be finite and > 0")]
    Mass {
        /// The body's index in the list given.
        body: usize,
        /// The mass given.
        mass_kg: f64,
    },
    /// The inertia tensor is not finite, symmetric and positive definite.
    #[error("body {body}: inertia tensor must be finite, symmetric and positive definite")]
    Inertia {
        /// The body.
        body: usize,
    },
    /// The centre of mass or the guess's head start is not finite.
    #[error("body {body}: centre of mass or head start not finite")]
    Com {
        /// The body.
        body: usize,
    },
    /// A solid that is not the model's, not external, or claimed twice.
    #[error("body {body}: solid {solid} is not an external solid of the model, or belongs to another body")]
    Solid {
        /// The body.
        body: usize,
        /// The solid index given.
        solid: usize,
    },
    /// A pin that is not the model's, not external, or claimed twice.
    #[error("body {body}: pin {pin} is not an external pin of the model, or belongs to another body")]
    Pin {
        /// The body.
        body: usize,
        /// The pin index given.
        pin: usize,
    },
}

/// Checks `bodies` against `model`: each solid and pin external and
/// claimed once.
pub(crate) fn check_bodies(model: &ClothModel, bodies: &[BodyInSolve]) -> Result<(), BodyError> {
    let mut solid_taken = vec![false; model.colliders().len()];
    let mut pin_taken = vec![false; model.pins().len()];
    for (body, b) in bodies.iter().enumerate() {
        if !(b.mass_kg.is_finite() && b.mass_kg > 0.0) {
            return Err(BodyError::Mass { body, mass_kg: b.mass_kg });
        }
        let i = &b.inertia_kg_m2;
        let symmetric = (i - i.transpose()).amax() <= 1e-12 * i.amax();
        if !(i.iter().all(|c| c.is_finite()) && symmetric && i.cholesky().is_some()) {
            return Err(BodyError::Inertia { body });
        }
        if ![b.com_m, b.ahead_m_s, b.ahead_rad_s].iter().all(|v| v.iter().all(|c| c.is_finite())) {
            return Err(BodyError::Com { body });
        }
        for &solid in &b.solids {
            let external = model.colliders().get(solid).is_some_and(|c| c.is_external());
            if !external || std::mem::replace(&mut solid_taken[solid], true) {
                return Err(BodyError::Solid { body, solid });
            }
        }
        for &pin in &b.pins {
            let external = model.pins().get(pin).is_some_and(|p| p.is_external());
            if !external || std::mem::replace(&mut pin_taken[pin], true) {
                return Err(BodyError::Pin { body, pin });
            }
        }
    }
    Ok(())
}

/// `J = [I | -[r]x]`: a point at lever `r` from the centre of mass moves
/// by `J (dx, dtheta)`.
pub(crate) fn lever(r: Vec3) -> Matrix3x6<f64> {
    let mut j = Matrix3x6::zeros();
    j.fixed_view_mut::<3, 3>(0, 0).copy_from(&Mat3::identity());
    j.fixed_view_mut::<3, 3>(0, 3).copy_from(&-r.cross_matrix());
    j
}
