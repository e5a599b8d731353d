//! Fabric material in physical units and its mapping to per-link constants.
//!
//! ## Why the mapping makes results resolution-independent
//! A grid with spacing `dx x dy` has cells of area `A = dx dy`. Each link
//! family (along u, along v, and the two diagonals) has one link per cell,
//! standing for the cell's area `a = A` (less along a boundary line, where
//! a link borders half a cell: `crate::topology::GridLink`). A link of rest length `L` at
//! angle `theta` to a uniform strain `eps` in direction 0 is strained by
//! `eps cos^2 theta`; summed over the four families, `sum cos^4 = 3/2` for
//! *any* direction on a square grid. So a link stiffness
//! `k = (2/3) E a / L^2` stores the continuum energy density `E eps^2 / 2`
//! per unit area, whatever the grid spacing and strain direction (exact for
//! square cells, close for mildly rectangular ones).
//!
//! ## Flexural rigidity of type-2 links (`bending_law = "arc-chord"`)
//! The same sum for curvature (normal curvature `kappa cos^2 theta`) gives
//! Choi & Ko's pair law `k_b = (2/3) B a / L` (`E = k_b L kappa^2 / 2`,
//! every link standing for a full cell). It reads its chord against the
//! rest length and caps the force by a ramp `c_b (L - d)` (Eq. 11), so a
//! link stores almost no moment below `kappa_s = sqrt(512 B / (C_b L^4))`,
//! which grows as the grid is refined (22/m at `L = 1 cm` for a cotton):
//! the 10 cm Peirce cantilever sags to 46, 60 and 77 degrees at 1, 0.5 and
//! 0.25 cm against the exact 41.5. No ramp slope fixes that: a switch held
//! at a fixed curvature needs `c_b` growing as `L^-6`, a membrane 10^4
//! times stiffer in compression than in tension at 0.25 cm (tried: the
//! linearised step chatters and Newton does not converge), because a chord
//! measured against the rest length cannot tell compression from bending.
//!
//! ## The arc-path law (`bending_law = "arc-path"`, the default)
//! The path through the middle particle can: the type-2 interactions read
//! curvature only (`crate::element_laws::bend_triple_with`), and the
//! ramp's compression moves to the type-1 links: each resists compression
//! with Choi & Ko's buckling law for the strip it stands for, the ramp
//! `c_b (L - d)` with `c_b = (2/3) C_b a / L^2` capped by the arc force
//! of a link of `k_b = (2/3) B a / L` (`crate::Compression::Buckling`; in
//! the matrix without its orthogonal term, negative in compression). The
//! cap matters: a membrane as stiff in compression as in tension cannot
//! wrinkle below the grid's scale, so it neither wraps a ball nor crumples
//! (a free cloth hit by a ball touched it at 4 particles instead of 20).
//! Three particles on a circle
//! of curvature `kappa` with chords `L / 2` read `kappa'^2 = (3/4) kappa^2`
//! for every family (the path is shorter than the arc), hence
//! `k_b = (4/3)(2/3) B a / L = (8/9) B a / L` ([`PATH_CURVATURE_FACTOR`]).
//! Links along a boundary line stand for the part of a cell they border
//! (`crate::topology::GridLink`). The cantilever: 41.8, 41.7 and 41.9
//! degrees at 1, 0.5 and 0.25 cm (`tests/bending.rs`, `cloth study
//! bending`).
//!
//! With either law, a type-2 interaction whose middle particle and one end
//! are pinned (a clamped edge) stands for half the bending of a free one:
//! the pinned half of its span cannot bend, so its constants double.
//! Without that the clamp line is as compliant as a cell's width of free
//! cloth, a first-order error (5 degrees at 1 cm on the cantilever).
//!
//! Provot's linear structural and shear springs use the same `k_s`. His
//! flexion springs (`i+2`, `j+2` only: two families, hence no 2/3) resist
//! bending only through the change of their chord, which is second order
//! in the deflection: no spring constant reproduces a flexural rigidity, so
//! they take the membrane's compressive stiffness `C_b` and the model has
//! no term in `B`. That difference is part of what the models compare.
//!
//! Volino's accurate model uses the continuum constants directly: the
//! membrane's orthotropic plane-stress stiffness from the warp and weft
//! moduli (default `E`), shear modulus (default `E / (2 (1 + nu))`) and
//! Poisson ratio (default 0.3), and a bending element per triangle whose
//! curvature tensor comes from the dihedral angles at its three edges,
//! storing the plate energy `B |kappa|^2 / 2` per unit area
//! ([`crate::element_laws::curvature_stiffness`]: exact for every quadratic
//! deflection of the grid; Peirce's cantilever 41.80 / 41.57 / 41.51
//! degrees at 1 / 0.5 / 0.25 cm against the exact 41.49).

use serde::{Deserialize, Serialize};

/// A fabric, in SI units. See the module docs for how each field maps to
/// per-link constants.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// Mass per unit area, kg/m^2 (cotton: about 0.1).
    pub areal_density_kg_m2: f64,
    /// In-plane tensile stiffness (Young's modulus times thickness), N/m.
    pub tensile_stiffness_n_m: f64,
    /// Flexural rigidity (bending moment per unit width per unit curvature),
    /// N m (cotton: 1e-6 to 1e-4).
    pub flexural_rigidity_n_m: f64,
    /// Compressive stiffness of the membrane before it buckles, N/m: the
    /// slope of Choi & Ko's ramp `c_b` (Eq. 11) on the type-2 links, or on
    /// the type-1 links in compression with the arc-path law (module docs);
    /// Provot's flexion springs. "Of the order of k_s".
    pub buckling_stiffness_n_m: f64,
    /// Viscosity along links (stress per strain rate), N s/m. Used only
    /// when the scene lists the `damping` effect.
    #[serde(default)]
    pub damping_n_s_m: f64,
    /// Viscous drag per unit area, N s/m^3: `f = -drag x area x v` (Provot's
    /// viscous damping). Used only with the `drag` effect.
    #[serde(default)]
    pub drag_n_s_m3: f64,
    /// Volino model: Young's modulus along the warp (panel u), N/m
    /// (default: `tensile_stiffness_n_m`).
    #[serde(default)]
    pub warp_stiffness_n_m: Option<f64>,
    /// Volino model: Young's modulus along the weft (panel v), N/m
    /// (default: `tensile_stiffness_n_m`).
    #[serde(default)]
    pub weft_stiffness_n_m: Option<f64>,
    /// Volino model: in-plane shear modulus, N/m (default `E / (2 (1 + nu))`
    /// with the warp modulus).
    #[serde(default)]
    pub shear_modulus_n_m: Option<f64>,
    /// Volino model: Poisson ratio `nu_uv` (default 0.3).
    #[serde(default)]
    pub poisson_ratio: Option<f64>,
}

/// The arc-path law's type-2 rigidity is `k_b` times this: its halves are
/// chords, so it reads `kappa'^2 = (3/4) kappa^2` (module docs).
pub const PATH_CURVATURE_FACTOR: f64 = 4.0 / 3.0;

/// Per-link constants derived from a [`Material`] for one link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkConstants {
    /// Type-1 spring stiffness `k_s`, N/m.
    pub k_s: f64,
    /// Type-1 damping `k_d`, N s/m.
    pub k_d: f64,
    /// Type-2 interaction flexural rigidity `k_b`, N m^2.
    pub k_b: f64,
    /// Choi & Ko's ramp slope `c_b` (type-2 links, or type-1 links in
    /// compression with the arc-path law), N/m.
    pub c_b: f64,
    /// Provot flexion spring stiffness `k_f`, N/m (axis-aligned links only).
    pub k_flexion: f64,
}

impl Material {
    /// The orthotropic plane-stress stiffness of Volino's membrane.
    pub fn membrane_stiffness(&self) -> crate::element_laws::Matrix3Voigt {
        let e_u = self.warp_stiffness_n_m.unwrap_or(self.tensile_stiffness_n_m);
        let e_v = self.weft_stiffness_n_m.unwrap_or(self.tensile_stiffness_n_m);
        let nu = self.poisson_ratio.unwrap_or(0.3);
        let g = self.shear_modulus_n_m.unwrap_or(e_u / (2.0 * (1.0 + nu)));
        crate::element_laws::Matrix3Voigt::orthotropic(e_u, e_v, g, nu)
    }

    /// Constants for a link of rest length `rest` (m) standing for the area
    /// `area` (m^2) of its panel ([`crate::topology::GridLink`]).
    pub fn link_constants(&self, rest: f64, area: f64) -> LinkConstants {
        let w = 2.0 / 3.0 * area;
        LinkConstants {
            k_s: w * self.tensile_stiffness_n_m / (rest * rest),
            k_d: w * self.damping_n_s_m / (rest * rest),
            k_b: w * self.flexural_rigidity_n_m / rest,
            c_b: w * self.buckling_stiffness_n_m / (rest * rest),
            k_flexion: area * self.buckling_stiffness_n_m / (rest * rest),
        }
    }

    /// Checks every field is finite and in range; names the first bad field.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        let fields = [
            ("areal_density_kg_m2", self.areal_density_kg_m2, false),
            ("tensile_stiffness_n_m", self.tensile_stiffness_n_m, false),
            ("flexural_rigidity_n_m", self.flexural_rigidity_n_m, true),
            ("buckling_stiffness_n_m", self.buckling_stiffness_n_m, true),
            ("damping_n_s_m", self.damping_n_s_m, true),
            ("drag_n_s_m3", self.drag_n_s_m3, true),
        ];
        let optional = [
            ("warp_stiffness_n_m", self.warp_stiffness_n_m),
            ("weft_stiffness_n_m", self.weft_stiffness_n_m),
            ("shear_modulus_n_m", self.shear_modulus_n_m),
        ];
        for (name, value) in optional {
            if let Some(v) = value
                && !(v.is_finite() && v > 0.0)
            {
                return Err((name, format!("must be finite and > 0, got {v}")));
            }
        }
        if let Some(nu) = self.poisson_ratio {
            let e_u = self.warp_stiffness_n_m.unwrap_or(self.tensile_stiffness_n_m);
            let e_v = self.weft_stiffness_n_m.unwrap_or(self.tensile_stiffness_n_m);
            // Plane stress needs nu_uv nu_vu < 1.
            if !(nu.is_finite() && nu >= 0.0 && nu * nu * e_v / e_u < 1.0) {
                return Err(("poisson_ratio", format!("must be >= 0 with nu^2 E_v / E_u < 1, got {nu}")));
            }
        }
        for (name, value, zero_ok) in fields {
            if !value.is_finite() {
                return Err((name, format!("must be finite, got {value}")));
            }
            if value < 0.0 || (!zero_ok && value == 0.0) {
                let need = if zero_ok { ">= 0" } else { "> 0" };
                return Err((name, format!("must be {need}, got {value}")));
            }
        }
        Ok(())
    }
}

impl Default for Material {
    /// A light cotton: 0.1 kg/m^2, E = 200 N/m, B = 1e-5 N m, C_b = E,
    /// D = 0.02 N s/m.
    fn default() -> Self {
        Self {
            areal_density_kg_m2: 0.1,
            tensile_stiffness_n_m: 200.0,
            flexural_rigidity_n_m: 1e-5,
            buckling_stiffness_n_m: 200.0,
            damping_n_s_m: 0.02,
            drag_n_s_m3: 0.0,
            warp_stiffness_n_m: None,
            weft_stiffness_n_m: None,
            shear_modulus_n_m: None,
            poisson_ratio: None,
        }
    }
}
