//! Fabric material in physical units and its mapping to per-link constants.
//!
//! ## The lattice
//! A grid with spacing `L` has cells of area `A = L^2`. Each link family
//! (along u, along v, and the two diagonals) has one link per cell,
//! standing for the cell's area `a = A` (less along a boundary line, where
//! a link borders half a cell: `crate::topology::GridLink`). Under a
//! uniform strain `eps`, a link along `n` is strained by `n . eps n`, so
//! axis links of per-area stiffness `K1` and diagonals of `K2` ([`Lattice`])
//! store `W / A = K1 (e11^2 + e22^2) / 2 + K2 (s+^2 + s-^2)`, `s+- =
//! (e11 + e22) / 2 +- e12`: the plane-stress stiffness `C11 = C22 = K1 +
//! K2`, `C12 = K2`, and shear modulus `G = K2`. Uniaxial tension along u
//! (`s22 = 0`) contracts the grid by `nu = K2 / (K1 + K2)` and meets the
//! modulus `K1 + K2 - K2^2 / (K1 + K2)`. Per link, `k = K1 a / L^2` on an
//! axis and `k = 2 K2 a / L^2` on a diagonal of rest length `L`.
//!
//! ## Three lattices, one material
//! `tensile_stiffness_n_m` is `E`, the modulus of a strip in uniaxial
//! tension, free to contract sideways; `shear_modulus_n_m` is `G`, as a
//! picture frame measures it (simple shear, no normal strain; default
//! `E / (2 (1 + nu))`, `nu = 0.3`); `damping_n_s_m` is `D`, the stress per
//! strain rate of the same strip. Two constants per lattice meet `E` and
//! `G` exactly; the Poisson ratio then follows (Cauchy's relation `C12 =
//! C66` of central-force lattices: 0.34 at the default `G`). Each model
//! resists compression differently ([`Compressive`]), so each solves its
//! own `K1`, `K2` ([`Material::lattice_membrane`]):
//! - the picture frame stretches one diagonal and compresses the other:
//!   `G = (K2 + K2c) / 2`, with `K2c = r K2 + K2x` (type-1 links resisting
//!   compression with `r` times their tension stiffness, compression-only
//!   links adding `K2x`);
//! - the uniaxial strip stretches the axis links along it and the
//!   diagonals, and compresses the axis links across it (`K1c = r K1 +
//!   K1x`): `E = K1 + K2 - K2^2 / (K1c + K2)`, a quadratic in `K1` with one
//!   positive root.
//!
//! `choi-ko` (arc-path law): type-1 links resist compression with Choi &
//! Ko's ramp `c_b = (C_b / E) k_s` until the strip they stand for buckles,
//! `r = C_b / E` (the default `C_b = E` makes the membrane linear before it
//! buckles, `K1 = 0.746 E`, `K2 = G`; the old mapping `k = (2/3) E a / L^2`
//! on every link was the uniaxial *strain* modulus, 11% soft in uniaxial
//! stress, and with `E = 20 N/m`, `C_b = E / 10` the bottom of a hanging
//! strip moved 35% too far). `provot`: linear springs, `r = 1`; his flexion springs (`i+2`,
//! `j+2`) are linear too, so they are part of the membrane: they take the
//! share `C_b / (E + C_b)` of the axis stiffness `K1` and the structural
//! springs the rest (half each at `C_b = E`). Their resistance to bending
//! is second order in the deflection, so `provot` has no term in `B`.
//! `volino`: the continuum constants directly (module end).
//!
//! Measured (`tests/material.rs`, `E = 200 N/m`, 0.5% strain, 1 and 2 cm
//! grids): the hanging strip's sag within 1.3% of `rho g L^2 / (2 E)`, the
//! picture frame's energy within 0.05% of `G gamma^2 / 2`, the strip's
//! longitudinal oscillation within 1% of the continuum frequency and decay
//! rate `D q^2 / (2 rho)`, for `choi-ko`, `provot` and `volino`. Limits:
//! the constants are for square cells (rectangular ones are close when
//! mild); a lattice is anisotropic unless `G = 3E/8`, so a strip cut on
//! the bias measures `1 / E45 = 1 / (2 (K1 + 2 K2)) + 1 / (4 K2)` (2% off
//! `E` at the default `G`); at finite strain the models part by their
//! strain measures (Volino's Green strain is 4.8% stiffer at 5%); a
//! compressed link buckles once its strip does, so compression moduli hold
//! only below that (0.6% at 1 cm for a light cotton). For `choi-ko` that
//! includes the compression across a strip in tension: once its axis links
//! across buckle, `K1c` is lost and the uniaxial modulus `K1 + K2 K1c /
//! (K1c + K2)` falls from `E` to `K1` (0.746 `E`). A hanging strip then
//! sags 13% too far at 5% strain with `B = 1e-5 N m`, and 32% at any
//! strain with `B` of 1e-7 N m or less (`docs/results/grid-stretch.md`).
//! This is the paper's lattice and is kept; `volino` is the model whose
//! membrane stays exact under stretch. The arc-chord law
//! (the paper's) carries compression on type-2 links across two cells
//! (`K1x = (2/3) C_b`, `K2x = C_b / 3`, `r = 0`; `C_b > 6 G` leaves no
//! tension diagonal and is an error), which buckle at a fraction of the
//! strip's strain: its strip sags 3% (1 cm) and 23% (2 cm) too far and
//! its oscillation decays 32% and 116% too fast.
//!
//! The damping lattice: shear viscosity `K2d = D G / E` on the diagonals,
//! and `K1d = D - K2d (1 - nu_s)` on the axes, so a strip stretching at
//! `e11'` while its stiffness contracts it at `nu_s e11'` meets the stress
//! `D e11'` (`nu_s` the lattice's contraction, Volino's Poisson ratio for
//! his links, which carry his damping; his strip's decay measures 1.1%
//! slow, cause not isolated).
//!
//! ## Flexural rigidity of type-2 links (`bending_law = "arc-chord"`)
//! Over the four link families `sum cos^4 theta = 3/2` for any direction
//! on a square grid; for curvature (normal curvature `kappa cos^2 theta`,
//! each family standing for the whole area) that gives Choi & Ko's pair law `k_b = (2/3) B a / L` (`E = k_b L kappa^2 / 2`,
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
//! Provot's flexion springs resist bending only through the change of
//! their chord, which is second order in the deflection: no spring
//! constant reproduces a flexural rigidity (see "Three lattices" for their
//! constant). That difference is part of what the models compare.
//!
//! Volino's accurate model uses the continuum constants directly: the
//! membrane's orthotropic plane-stress stiffness from the warp and weft
//! moduli (default `E`), shear modulus (default `E / (2 (1 + nu))`) and
//! Poisson ratio (default 0.3; warp, weft and Poisson ratio are his
//! model's only: the lattices reject them), and a bending element per triangle whose
//! curvature tensor comes from the dihedral angles at its three edges,
//! storing the plate energy `B |kappa|^2 / 2` per unit area
//! ([`crate::element_laws::curvature_stiffness`]: exact for every quadratic
//! deflection, on the grid and on irregular meshes; Peirce's cantilever on the grid 41.80 / 41.57 / 41.51
//! degrees at 1 / 0.5 / 0.25 cm against the exact 41.49).

use crate::FieldError;
use serde::{Deserialize, Serialize};

/// The shear modulus of a spring lattice on triangles: `3E/8` (Poisson
/// ratio 1/3), N/m for `E` in N/m.
pub(crate) fn triangle_lattice_shear_modulus(e: f64) -> f64 {
    3.0 / 8.0 * e
}

/// A fabric, in SI units. See the module docs for how each field maps to
/// per-link constants.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// Mass per unit area, kg/m^2 (cotton: about 0.1).
    pub areal_density_kg_m2: f64,
    /// In-plane tensile stiffness (Young's modulus times thickness), N/m:
    /// the modulus of a strip in uniaxial tension, every model (module docs).
    pub tensile_stiffness_n_m: f64,
    /// Flexural rigidity (bending moment per unit width per unit curvature),
    /// N m (cotton: 1e-6 to 1e-4).
    pub flexural_rigidity_n_m: f64,
    /// Compressive stiffness of the membrane before it buckles, N/m: the
    /// slope of Choi & Ko's ramp `c_b` (Eq. 11) on the type-2 links, or on
    /// the type-1 links in compression with the arc-path law (`C_b = E`: as
    /// stiff as in tension); Provot's flexion springs take the share
    /// `C_b / (E + C_b)` of the axis links' stiffness (module docs). "Of
    /// the order of k_s".
    pub buckling_stiffness_n_m: f64,
    /// Viscosity: a strip's stress per strain rate in uniaxial extension,
    /// N s/m, on the links' directions (Choi & Ko's directional damping; its
    /// lattice in the module docs). Used only when the scene lists the
    /// `damping` effect.
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
    /// In-plane shear modulus as a picture frame measures it, N/m, every
    /// model (default `E / (2 (1 + nu))` with the warp modulus; module docs).
    #[serde(default)]
    pub shear_modulus_n_m: Option<f64>,
    /// Volino model: Poisson ratio `nu_uv` (default 0.3).
    #[serde(default)]
    pub poisson_ratio: Option<f64>,
}

/// The arc-path law's type-2 rigidity is `k_b` times this: its halves are
/// chords, so it reads `kappa'^2 = (3/4) kappa^2` (module docs).
pub(crate) const PATH_CURVATURE_FACTOR: f64 = 4.0 / 3.0;

/// Poisson ratio when the scene gives none.
pub(crate) const DEFAULT_POISSON_RATIO: f64 = 0.3;

/// Per-area stiffness (or viscosity) of a square grid's link families:
/// a uniform strain `eps` stores (module docs, "The lattice")
/// `W / A = axis (e11^2 + e22^2) / 2 + diagonal (s+^2 + s-^2)` with
/// `s+- = (e11 + e22) / 2 +- e12` the strains of the two diagonals.
/// N/m for stiffness, N s/m for damping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lattice {
    /// Links along u and v.
    pub axis: f64,
    /// Each diagonal family.
    pub diagonal: f64,
}

impl Lattice {
    /// The constant of one link of rest length `rest` (m) standing for
    /// `area` (m^2): `axis a / L^2` along u or v, `2 diagonal a / L^2` on a
    /// diagonal (its energy `k L^2 s^2 / 2` per `a` is `diagonal s^2`).
    pub fn link(&self, diagonal: bool, rest: f64, area: f64) -> f64 {
        let per_area = if diagonal { 2.0 * self.diagonal } else { self.axis };
        per_area * area / (rest * rest)
    }
}

/// How a lattice model's links resist compression before they buckle,
/// against its tension lattice (module docs, "Three lattices"): the type-1
/// links with `ratio` times their tension stiffness, plus links that act
/// in compression only (Provot's flexion springs, Choi & Ko's type-2
/// ramps) adding `axis` and `diagonal` per area.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Compressive {
    /// Compression stiffness of a type-1 link over its tension stiffness.
    pub ratio: f64,
    /// Compression-only stiffness along u and v, per area, N/m.
    pub axis: f64,
    /// Compression-only stiffness of each diagonal family, per area, N/m.
    pub diagonal: f64,
}

/// A lattice model's membrane: tension and damping lattices.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Membrane {
    /// Stiffness in tension, N/m.
    pub stiffness: Lattice,
    /// Damping, N s/m.
    pub damping: Lattice,
}

/// Bending constants derived from a [`Material`] for one link
/// ([`Material::bend_constants`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BendConstants {
    /// Flexural rigidity `k_b` of a type-2 interaction (or of the strip a
    /// type-1 link stands for), N m^2.
    pub k_b: f64,
    /// Choi & Ko's ramp slope `c_b` on a type-2 link (arc-chord law), N/m.
    pub c_b: f64,
}

impl Material {
    /// Young's modulus along the warp (panel u), N/m.
    pub fn warp_modulus(&self) -> f64 {
        self.warp_stiffness_n_m.unwrap_or(self.tensile_stiffness_n_m)
    }

    /// In-plane shear modulus, N/m: `shear_modulus_n_m`, else
    /// `E / (2 (1 + nu))` with the warp modulus and the Poisson ratio.
    pub fn shear_modulus(&self) -> f64 {
        let nu = self.poisson_ratio.unwrap_or(DEFAULT_POISSON_RATIO);
        self.shear_modulus_n_m.unwrap_or(self.warp_modulus() / (2.0 * (1.0 + nu)))
    }

    /// The orthotropic plane-stress stiffness of Volino's membrane.
    pub fn membrane_stiffness(&self) -> crate::element_laws::Matrix3Voigt {
        let e_v = self.weft_stiffness_n_m.unwrap_or(self.tensile_stiffness_n_m);
        let nu = self.poisson_ratio.unwrap_or(DEFAULT_POISSON_RATIO);
        crate::element_laws::Matrix3Voigt::orthotropic(self.warp_modulus(), e_v, self.shear_modulus(), nu)
    }

    /// The membrane of a lattice model whose links resist compression as
    /// `compressive`: uniaxial tension modulus `E` and picture-frame shear
    /// modulus `G` (module docs, "Three lattices"). Errors name the field
    /// that leaves no lattice with positive constants.
    pub fn lattice_membrane(&self, compressive: Compressive) -> Result<Membrane, FieldError> {
        let (e, g, c) = (self.tensile_stiffness_n_m, self.shear_modulus(), compressive);
        // Picture frame: one diagonal stretched, one compressed: G = (K2 + K2c) / 2.
        let k2 = (2.0 * g - c.diagonal) / (1.0 + c.ratio);
        if k2 <= 0.0 {
            let message = format!(
                "{} N/m: the compression-only diagonals alone give a shear modulus of {} N/m, above G = {g} N/m",
                self.buckling_stiffness_n_m,
                c.diagonal / 2.0
            );
            return Err(FieldError::new("buckling_stiffness_n_m", message));
        }
        // Uniaxial tension: (K1 + K2 - E)(K1c + K2) = K2^2 with K1c = r K1 + a,
        // the quadratic r K1^2 + qb K1 + qc = 0; qc < 0 leaves one positive root.
        let qb = c.axis + k2 + c.ratio * (k2 - e);
        let qc = (k2 - e) * (c.axis + k2) - k2 * k2;
        let root = (qb * qb - 4.0 * c.ratio * qc).sqrt();
        let k1 = if qb > 0.0 { -2.0 * qc / (qb + root) } else { (root - qb) / (2.0 * c.ratio) };
        if !(qc < 0.0 && k1.is_finite() && k1 > 0.0) {
            return Err(FieldError::new(
                "shear_modulus_n_m",
                format!(
                    "G = {g} N/m with E = {e} N/m and buckling_stiffness_n_m = {} N/m leaves no lattice \
                     with positive link stiffness",
                    self.buckling_stiffness_n_m
                ),
            ));
        }
        let stiffness = Lattice { axis: k1, diagonal: k2 };
        // `-e22 / e11` under uniaxial tension along u.
        let lateral_contraction = k2 / (c.ratio * k1 + c.axis + k2);
        Ok(Membrane { stiffness, damping: self.damping_lattice(lateral_contraction)? })
    }

    /// The damping lattice of a membrane that contracts by `lateral` under
    /// uniaxial tension: shear viscosity `D G / E` on the diagonals, and
    /// axis links such that a strip stretching at `e11'` (and contracting
    /// at `lateral e11'`) meets the stress `D e11'` (module docs).
    pub fn damping_lattice(&self, lateral: f64) -> Result<Lattice, FieldError> {
        let d = self.damping_n_s_m;
        let diagonal = d * self.shear_modulus() / self.tensile_stiffness_n_m;
        let axis = d - diagonal * (1.0 - lateral);
        if d > 0.0 && axis <= 0.0 {
            return Err(FieldError::new(
                "shear_modulus_n_m",
                format!("G / E = {} leaves the damping lattice no axial viscosity", diagonal / d),
            ));
        }
        Ok(Lattice { axis, diagonal })
    }

    /// Bending constants of a link of rest length `rest` (m) standing for
    /// the area `area` (m^2) of its panel (a grid link):
    /// flexural rigidity `k_b = (2/3) B a / L`, N m^2 (also the strip a
    /// type-1 link stands for, capping its compression with the arc-path
    /// law); Choi & Ko's type-2 ramp `c_b = (2/3) C_b a / L^2`, N/m.
    pub fn bend_constants(&self, rest: f64, area: f64) -> BendConstants {
        let w = 2.0 / 3.0 * area;
        BendConstants {
            k_b: w * self.flexural_rigidity_n_m / rest,
            c_b: w * self.buckling_stiffness_n_m / (rest * rest),
        }
    }

    /// Checks every field is finite and in range; names the first bad field.
    pub fn validate(&self) -> Result<(), FieldError> {
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
                return Err(FieldError::new(name, format!("must be finite and > 0, got {v}")));
            }
        }
        if let Some(nu) = self.poisson_ratio {
            let e_u = self.warp_stiffness_n_m.unwrap_or(self.tensile_stiffness_n_m);
            let e_v = self.weft_stiffness_n_m.unwrap_or(self.tensile_stiffness_n_m);
            // Plane stress needs nu_uv nu_vu < 1.
            if !(nu.is_finite() && nu >= 0.0 && nu * nu * e_v / e_u < 1.0) {
                return Err(FieldError::new(
                    "poisson_ratio",
                    format!("must be >= 0 with nu^2 E_v / E_u < 1, got {nu}"),
                ));
            }
        }
        for (name, value, zero_ok) in fields {
            if !value.is_finite() {
                return Err(FieldError::new(name, format!("must be finite, got {value}")));
            }
            if value < 0.0 || (!zero_ok && value == 0.0) {
                let need = if zero_ok { ">= 0" } else { "> 0" };
                return Err(FieldError::new(name, format!("must be {need}, got {value}")));
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
