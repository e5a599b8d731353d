//! The immutable cloth model: particles, links grouped by law, pins, the
//! effects a scene asked for, and the system matrix's sparsity pattern.

use super::build_mesh::*;
use super::build_parts::*;
use super::sparsity::{Sparsity, link_pairs};
use super::spec::*;
use crate::colliders::{Collider, SelfCollision};
use crate::elements::{BendTriple, ElementSet};
use crate::material::{Lattice, Membrane, PATH_CURVATURE_FACTOR};
use crate::seams::{self, Stitch};
use crate::terms::ForceTerm;
use crate::{
    LinkType, Material, Pin, Vec3, Wind,
    laws::{BucklingLaw, BucklingLaws, ScalarLaw, bilinear_spring, linear_spring},
};
use cloth_linalg::{Aggregation, BlockPattern, Multigrid, SMOOTHED_MIN_NODES};
use std::sync::Arc;

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
    /// Choi & Ko's buckling law ([`BendingLaw::ArcChord`]).
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

/// A bending link: Choi & Ko's type-2 pair ([`BendingLaw::ArcChord`]) or
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

/// Where a panel's particles live in the model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PanelRange {
    /// Index of the panel's particle (0, 0).
    pub offset: usize,
    /// Particles along u.
    pub nx: usize,
    /// Particles along v.
    pub ny: usize,
}

/// Where a mesh panel's particles live in the model.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshRange {
    /// Index of the mesh's vertex 0.
    pub offset: usize,
    /// Number of vertices.
    pub len: usize,
    /// The mesh's edges (local indices): the graph its multigrid
    /// aggregates follow.
    pub edges: Vec<[u32; 2]>,
    /// A pattern piece's vertices along each outline edge (local indices).
    pub outline_edges: Vec<Vec<u32>>,
    /// Each outline edge's length, m.
    pub outline_lengths: Vec<f64>,
}

/// An immutable cloth model. Build one with [`ClothModel::build`].
#[derive(Debug, Clone)]
pub struct ClothModel {
    colliders: Vec<Collider>,
    contact_thickness: f64,
    self_collision: Option<SelfCollision>,
    mass: Vec<f64>,
    /// The largest `k_s / m` of a stretch link (its lighter end), 1/s^2.
    stiffest_per_mass: f64,
    rest_positions: Vec<Vec3>,
    stretch: Vec<StretchLink>,
    bend: Vec<BendLink>,
    stitches: Vec<Stitch>,
    pins: Vec<Pin>,
    pinned: Vec<bool>,
    effects: Effects,
    material: Material,
    kind: ModelKind,
    strain_limit: Option<StrainLimit>,
    wind: Option<Wind>,
    panels: Vec<PanelRange>,
    meshes: Vec<MeshRange>,
    triangles: Vec<[u32; 3]>,
    /// The triangles of each particle, in triangle order: `tri_of[tri_ptr[i]..tri_ptr[i + 1]]`.
    tri_ptr: Vec<usize>,
    tri_of: Vec<u32>,
    /// Each sewn particle's group (the particles stitches join it to,
    /// directly or through others, itself included; empty if unsewn):
    /// `sewn[sewn_ptr[i]..sewn_ptr[i + 1]]`.
    sewn_ptr: Vec<usize>,
    sewn: Vec<u32>,
    elements: ElementSet,
    drag: Vec<f64>,
    inc_ptr: Vec<usize>,
    inc: Vec<Incidence>,
    pattern: BlockPattern,
    diag_local: Vec<u32>,
    /// Force terms added from outside ([`ClothModel::with_force_term`]).
    extra_terms: Vec<Arc<dyn ForceTerm>>,
}

impl ClothModel {
    /// Validates `spec` and builds the model: particle masses from areal
    /// density, links with constants from [`Material::lattice_membrane`]
    /// and [`Material::bend_constants`],
    /// rest lengths from the initial shape, pins, and the sparsity pattern.
    pub fn build(spec: &ModelSpec) -> Result<Self, ModelError> {
        if spec.panels.is_empty() && spec.meshes.is_empty() {
            return Err(ModelError::NoPanels);
        }
        spec.material.validate().map_err(|(field, message)| ModelError::Material { field, message })?;
        if let Some(g) = spec.effects.gravity
            && g.iter().any(|c| !c.is_finite())
        {
            return Err(ModelError::Gravity([g.x, g.y, g.z]));
        }
        if let Some(law) = spec.bending_law
            && spec.kind != ModelKind::ChoiKo
        {
            return Err(ModelError::BendingLaw(law.name(), spec.kind.name()));
        }
        if spec.kind != ModelKind::Volino {
            let m = &spec.material;
            let orthotropic = [
                ("warp_stiffness_n_m", m.warp_stiffness_n_m),
                ("weft_stiffness_n_m", m.weft_stiffness_n_m),
                ("poisson_ratio", m.poisson_ratio),
            ];
            if let Some((field, _)) = orthotropic.iter().find(|(_, v)| v.is_some()) {
                let message = format!(
                    "only the volino model's membrane is orthotropic; {}'s lattice takes \
                     tensile_stiffness_n_m and shear_modulus_n_m (its Poisson ratio follows from them)",
                    spec.kind.name()
                );
                return Err(ModelError::Material { field, message });
            }
        }
        let mut mass = Vec::new();
        let mut rest_positions = Vec::new();
        let mut stretch = Vec::new();
        let mut bend = Vec::new();
        let mut bend_middle = Vec::new();
        let mut panels = Vec::new();
        let mut triangles = Vec::new();
        let mut elements = ElementSet::default();
        let mut bending_triangles = Vec::new();
        let mut drag = Vec::new();
        let mut buckling = BucklingLaws::default();
        let damping = spec.effects.damping;
        // Volino's bending triangles are exact on parallelogram pairs as they stand.
        let diagonals =
            if spec.kind == ModelKind::Volino { crate::Diagonals::Uniform } else { crate::Diagonals::Alternating };
        // In bending, the arc-path law counts boundary links for the part of
        // a cell they border (topology::GridLink); the paper's, a full cell.
        let path = spec.kind == ModelKind::ChoiKo && spec.bending_law.unwrap_or_default() == BendingLaw::ArcPath;
        let compressive = compressive_response(spec, path);
        // Provot's flexion springs take this share of the axis links' stiffness (`crate::material` docs).
        let flexion_share = if spec.kind == ModelKind::Provot && spec.effects.bending {
            let (c_b, e) = (spec.material.buckling_stiffness_n_m, spec.material.tensile_stiffness_n_m);
            c_b / (e + c_b)
        } else {
            0.0
        };
        let material_err = |(field, message)| ModelError::Material { field, message };
        let membrane = match spec.kind {
            ModelKind::Volino => {
                let nu = spec.material.poisson_ratio.unwrap_or(crate::material::DEFAULT_POISSON_RATIO);
                let damping = spec.material.damping_lattice(nu).map_err(material_err)?;
                // His membrane elements replace the springs: a lattice of zero stiffness.
                Membrane { stiffness: Lattice { axis: 0.0, diagonal: 0.0 }, damping }
            }
            _ => spec.material.lattice_membrane(compressive).map_err(material_err)?,
        };
        for (p, panel) in spec.panels.iter().enumerate() {
            let mesh = panel.mesh_with(diagonals).map_err(|(field, message)| ModelError::Panel {
                panel: p,
                field,
                message,
            })?;
            let offset = mass.len();
            let at = |k: u32| offset as u32 + k;
            let rest_of = |[a, b]: [u32; 2]| (mesh.positions[b as usize] - mesh.positions[a as usize]).norm();
            let degenerate = |rest: f64, values: &[f64]| !(rest > 0.0 && values.iter().all(|v| v.is_finite()));
            let degenerate_err = || ModelError::Panel {
                panel: p,
                field: "size_m",
                message: format!("{:?} m gives links of zero or non-finite length or stiffness", panel.size_m),
            };
            let area = |link: &crate::topology::GridLink| if path { link.area } else { mesh.cell_area };
            for link in &mesh.sequential {
                let rest = rest_of(link.ends);
                // Every model's membrane lattice counts boundary links for the part of a cell they border.
                let share = if link.diagonal { 0.0 } else { flexion_share };
                let k_s = (1.0 - share) * membrane.stiffness.link(link.diagonal, rest, link.area);
                let k_d = membrane.damping.link(link.diagonal, rest, link.area);
                let k_b = spec.material.bend_constants(rest, area(link)).k_b;
                if degenerate(rest, &[k_s, k_d, k_b]) {
                    return Err(degenerate_err());
                }
                stretch.push(StretchLink {
                    i: at(link.ends[0]),
                    j: at(link.ends[1]),
                    rest,
                    // Zero for Volino: his links stay for damping and limits.
                    k_s,
                    compression: match spec.kind {
                        ModelKind::ChoiKo if path => {
                            Compression::Buckling(buckling.law(rest, k_b, compressive.ratio * k_s))
                        }
                        ModelKind::ChoiKo | ModelKind::Volino => Compression::Linear(0.0),
                        ModelKind::Provot => Compression::Linear(k_s),
                    },
                    k_d: if damping { k_d } else { 0.0 },
                });
            }
            if spec.kind == ModelKind::Volino {
                let (_, v_axis, _) =
                    panel.frame().map_err(|(field, message)| ModelError::Panel { panel: p, field, message })?;
                let (membranes, triangles) =
                    volino_elements(&mesh.positions, &mesh.triangles, &spec.material, &|_| v_axis, p, offset as u32)
                        .ok_or_else(degenerate_err)?;
                elements.membranes.extend(membranes);
                if spec.effects.bending {
                    bending_triangles.extend(triangles);
                }
            } else if spec.effects.bending {
                let links = if spec.kind == ModelKind::Provot { &mesh.flexion } else { &mesh.interlaced };
                for link in links {
                    let rest = rest_of(link.ends);
                    let c = spec.material.bend_constants(rest, area(link));
                    if degenerate(rest, &[c.k_b, c.c_b]) {
                        return Err(degenerate_err());
                    }
                    let [i, j] = link.ends.map(at);
                    match (spec.kind, link.middle) {
                        (ModelKind::Provot, _) => {
                            let k = flexion_share * membrane.stiffness.link(false, rest, link.area);
                            bend.push(BendLink { i, j, law: BendLaw::Flexion { rest, k } })
                        }
                        (_, Some(m)) if path => elements.triples.push(BendTriple {
                            nodes: [i, at(m), j],
                            rest,
                            k_b: PATH_CURVATURE_FACTOR * c.k_b,
                        }),
                        _ => {
                            bend.push(BendLink { i, j, law: BendLaw::Buckling(buckling.law(rest, c.k_b, c.c_b)) });
                            bend_middle.push(link.middle.map(at));
                        }
                    }
                }
            }
            // A wrapped panel's cells wind inward (u x v points at the
            // axis): its surface triangles are turned to face out, so the
            // outside of a skirt is its front.
            let outward = |t: &[u32; 3]| if panel.wrap_u { [t[0], t[2], t[1]] } else { *t };
            triangles.extend(mesh.triangles.iter().map(|t| outward(t).map(at)));
            mass.extend(mesh.area_share.iter().map(|a| a * spec.material.areal_density_kg_m2));
            if spec.effects.drag {
                drag.extend(mesh.area_share.iter().map(|a| a * spec.material.drag_n_s_m3));
            }
            rest_positions.extend_from_slice(&mesh.positions);
            panels.push(PanelRange { offset, nx: panel.particles[0], ny: panel.particles[1] });
        }
        let mut meshes = Vec::new();
        if !spec.meshes.is_empty() {
            check_lattice_on_meshes(spec, path)?;
        }
        let grid_offsets: Vec<usize> = panels.iter().map(|p| p.offset).collect();
        let pieces = seams::outline_pieces(&spec.seams, &spec.panels, &grid_offsets, &spec.meshes);
        for (k, panel) in spec.meshes.iter().enumerate() {
            let err = |(field, message)| ModelError::Mesh { mesh: k, field, message };
            let mesh = panel.resolve_with(&spec.collision.base_dir, &pieces[k]).map_err(err)?;
            let offset = mass.len();
            let index = spec.panels.len() + k;
            let parts = mesh_parts(spec, &mesh, index, offset as u32).map_err(err)?;
            stretch.extend(parts.stretch);
            bend.extend_from_slice(&parts.flexion);
            bend_middle.extend(parts.flexion.iter().map(|_| None));
            elements.hinges.extend(parts.hinges);
            elements.membranes.extend(parts.membranes);
            bending_triangles.extend(parts.bending);
            triangles.extend(mesh.triangles.iter().map(|t| t.map(|q| q + offset as u32)));
            let area_share = &parts.topology.area_share;
            mass.extend(area_share.iter().map(|a| a * spec.material.areal_density_kg_m2));
            if spec.effects.drag {
                drag.extend(area_share.iter().map(|a| a * spec.material.drag_n_s_m3));
            }
            rest_positions.extend_from_slice(&mesh.positions);
            let edges = parts.topology.edges.iter().map(|e| e.ends).collect();
            let (len, outline_edges, outline_lengths) =
                (mesh.positions.len(), mesh.outline_edges, mesh.outline_lengths);
            meshes.push(MeshRange { offset, len, edges, outline_edges, outline_lengths });
        }
        let n = mass.len();
        let targets = seams::SeamTargets { panels: &spec.panels, offsets: &grid_offsets, meshes: &meshes };
        let mut stitches = Vec::new();
        let tensile = spec.material.tensile_stiffness_n_m;
        for (seam, s) in spec.seams.iter().enumerate() {
            stitches.extend(seams::stitches(s, &targets, tensile).map_err(|(field, message)| ModelError::Seam {
                seam,
                field,
                message,
            })?);
        }
        let (pins, pinned) = build_pins(spec, &panels, &meshes, &rest_positions)?;
        clamp_bend_links(&mut bend, &bend_middle, &pinned);
        clamp_triples(&mut elements.triples, &pinned);
        clamp_hinges(&mut elements.hinges, &pinned);
        elements.curvatures =
            curvature_elements(&bending_triangles, &rest_positions, &pinned, spec.material.flexural_rigidity_n_m)
                .map_err(|panel| match panel.checked_sub(spec.panels.len()) {
                    Some(mesh) => ModelError::Mesh {
                        mesh,
                        field: "triangles",
                        message: "a bending triangle is degenerate".into(),
                    },
                    None => {
                        ModelError::Panel { panel, field: "size_m", message: "a bending triangle is degenerate".into() }
                    }
                })?;
        if spec.effects.wind || spec.effects.aerodynamics {
            let wind = spec.wind.as_ref().ok_or(ModelError::Wind {
                field: "profile",
                message: "the wind and aerodynamics effects need a [wind] section".into(),
            })?;
            wind.validate().map_err(|(field, message)| ModelError::Wind { field, message })?;
        }
        if let Some(limit) = spec.strain_limit {
            if !(limit.max_strain.is_finite() && limit.max_strain >= 0.0) {
                return Err(ModelError::StrainLimit {
                    field: "max_strain",
                    message: format!("must be finite and >= 0, got {}", limit.max_strain),
                });
            }
            if limit.passes == 0 {
                return Err(ModelError::StrainLimit { field: "passes", message: "must be >= 1".into() });
            }
        }

        // Sparsity pattern and per-row incidence, in a fixed (link) order.
        let link_pairs = link_pairs(&stretch, &bend, &stitches);
        let Sparsity { pattern, inc_ptr, inc, diag_local } = Sparsity::of(n, &link_pairs, &mut elements, &[]);
        let (tri_ptr, tri_of) = triangles_of_particles(n, &triangles);
        let (sewn_ptr, sewn) = sewn_groups(n, &stitches);
        let collision_error = |(field, message)| ModelError::Collision { field, message };
        let colliders = spec.collision.build_colliders().map_err(collision_error)?;
        let mean_link = stretch.iter().map(|l| l.rest).sum::<f64>() / stretch.len().max(1) as f64;
        let self_collision = spec
            .collision
            .build_self_collision(spec.material.tensile_stiffness_n_m, mean_link)
            .map_err(collision_error)?;
        let links = stretch.iter().map(|l| l.k_s / mass[l.i as usize].min(mass[l.j as usize]));
        // A membrane triangle's corner `k` is held by `C A |g_k|^2` (the
        // diagonal of its stiffness, with the stiffer direction's `C`).
        let masses = &mass;
        let corners = elements.membranes.iter().flat_map(|e| {
            let c = e.rest.c.c11.max(e.rest.c.c22);
            (0..3).map(move |k| c * e.rest.area * e.rest.g[k].norm_squared() / masses[e.nodes[k] as usize])
        });
        let stiffest_per_mass = links.chain(corners).filter(|r| r.is_finite()).fold(0.0, f64::max);
        Ok(Self {
            colliders,
            contact_thickness: spec.collision.thickness(),
            self_collision,
            stiffest_per_mass,
            mass,
            rest_positions,
            stretch,
            bend,
            stitches,
            pins,
            pinned,
            effects: spec.effects,
            material: spec.material,
            kind: spec.kind,
            strain_limit: spec.strain_limit,
            wind: spec.wind.clone(),
            panels,
            meshes,
            triangles,
            tri_ptr,
            tri_of,
            sewn_ptr,
            sewn,
            elements,
            drag,
            inc_ptr,
            inc,
            pattern,
            diag_local,
            extra_terms: Vec::new(),
        })
    }

    /// The same model with `solids` added after the scene's colliders (a
    /// rigid-body engine's colliders, whose indices start at
    /// `colliders().len()` before the call). Each is checked as a scene
    /// collider would be.
    pub fn with_solids(mut self, solids: impl IntoIterator<Item = Collider>) -> Result<Self, ModelError> {
        for c in solids {
            let field = |name: &str| format!("solids[{}].{name}", self.colliders.len());
            let fail = |name: &str, message: String| ModelError::Collision { field: field(name), message };
            if !(c.friction.is_finite() && c.friction >= 0.0) {
                return Err(fail("friction", format!("must be finite and >= 0, got {}", c.friction)));
            }
            let anchor = &c.anchor;
            if !(anchor.position.iter().chain(anchor.rotation.coords.iter()).all(|v| v.is_finite())) {
                return Err(fail("anchor", "must be finite".into()));
            }
            if !c.spin_rad_s.iter().all(|v| v.is_finite()) {
                return Err(fail("spin_rad_s", "must be finite".into()));
            }
            c.motion.validate().map_err(|(f, m)| fail(&format!("motion.{f}"), m))?;
            self.colliders.push(c);
        }
        Ok(self)
    }

    /// Adds a force of the caller's own ([`ForceTerm`]): every integrator
    /// then applies it. The explicit ones and vertex solvers take its
    /// forces and blocks as they take the built-in terms'; the implicit
    /// steps assemble it from its Jacobian ([`ForceTerm::jacobian`]) at the
    /// step's positions, its force taken without velocity and its damping
    /// through the step's velocity term, the sparsity pattern growing by
    /// the pairs it couples ([`ForceTerm::coupled_pairs`]). Its energy joins
    /// the elastic energy that the energy monitor and Newton's line search
    /// see.
    pub fn with_force_term(mut self, term: Arc<dyn ForceTerm>) -> Self {
        let pairs = term.coupled_pairs(&self);
        self.extra_terms.push(term);
        if pairs.iter().any(|&[i, j]| self.pattern.slot(i, j).is_none()) {
            let extra: Vec<[usize; 2]> = self.extra_terms.iter().flat_map(|t| t.coupled_pairs(&self)).collect();
            let links = link_pairs(&self.stretch, &self.bend, &self.stitches);
            let n = self.particle_count();
            let Sparsity { pattern, inc_ptr, inc, diag_local } = Sparsity::of(n, &links, &mut self.elements, &extra);
            (self.pattern, self.inc_ptr, self.inc, self.diag_local) = (pattern, inc_ptr, inc, diag_local);
        }
        self
    }

    /// The force terms added from outside.
    pub fn extra_terms(&self) -> &[Arc<dyn ForceTerm>] {
        &self.extra_terms
    }

    /// What `other` differs in beyond its constants, if anything: the
    /// particles (count, masses, rest shape), links and their rest lengths,
    /// stitches, pins, solids, elements and effects must all be the same for
    /// a running simulation to take it in place of this one between steps
    /// (its state, contacts and solver's structure then still fit).
    pub fn structure_differs(&self, other: &ClothModel) -> Option<&'static str> {
        let bits = |a: &[f64], b: &[f64]| a.iter().map(|v| v.to_bits()).eq(b.iter().map(|v| v.to_bits()));
        let points = |a: &[Vec3], b: &[Vec3]| {
            a.iter()
                .flat_map(|p| p.iter())
                .map(|v| v.to_bits())
                .eq(b.iter().flat_map(|p| p.iter()).map(|v| v.to_bits()))
        };
        let e = (&self.elements, &other.elements);
        if !bits(&self.mass, &other.mass) {
            Some("particles or masses")
        } else if !points(&self.rest_positions, &other.rest_positions) {
            Some("rest shape")
        } else if self.link_count() != other.link_count()
            || (0..self.link_count()).any(|k| self.link_ends(k) != other.link_ends(k))
            || !self.stretch.iter().zip(&other.stretch).all(|(a, b)| a.rest.to_bits() == b.rest.to_bits())
        {
            Some("links")
        } else if self.stitches().len() != other.stitches().len() {
            Some("stitches")
        } else if !self.pins.iter().map(|p| p.particle).eq(other.pins.iter().map(|p| p.particle)) {
            Some("pins")
        } else if self.colliders().len() != other.colliders().len() {
            Some("solids")
        } else if (e.0.membranes.len(), e.0.curvatures.len(), e.0.triples.len(), e.0.hinges.len())
            != (e.1.membranes.len(), e.1.curvatures.len(), e.1.triples.len(), e.1.hinges.len())
        {
            Some("elements")
        } else if self.effects() != other.effects() {
            Some("effects")
        } else {
            None
        }
    }

    /// Number of particles.
    pub fn particle_count(&self) -> usize {
        self.mass.len()
    }
    /// The largest stiffness per mass of a stretch link, `k_s / m` with
    /// `m` its lighter end's mass, or of a membrane triangle's corner,
    /// `C A |g|^2 / m`, 1/s^2: `h^2` times it is how large a step `h` is
    /// for the material (the square of the stiffest natural frequency
    /// times the step).
    pub fn stiffest_per_mass(&self) -> f64 {
        self.stiffest_per_mass
    }
    /// Particle masses, kg.
    pub fn masses(&self) -> &[f64] {
        &self.mass
    }
    /// Initial positions (which define rest lengths), m.
    pub fn rest_positions(&self) -> &[Vec3] {
        &self.rest_positions
    }
    /// Type-1 links.
    pub fn stretch_links(&self) -> &[StretchLink] {
        &self.stretch
    }
    /// Type-2 links (empty when bending is off).
    pub fn bend_links(&self) -> &[BendLink] {
        &self.bend
    }
    /// The seams' stitches (empty without seams).
    pub fn stitches(&self) -> &[Stitch] {
        &self.stitches
    }
    /// Total number of links: type-1, type-2 (or flexion) and stitches.
    pub fn link_count(&self) -> usize {
        self.stretch.len() + self.bend.len() + self.stitches.len()
    }
    /// Endpoints of link `k` (stretch links first, then bend links, then
    /// stitches) and its type.
    pub fn link_ends(&self, k: usize) -> (usize, usize, LinkType) {
        let (ns, nb) = (self.stretch.len(), self.bend.len());
        if k < ns {
            (self.stretch[k].i as usize, self.stretch[k].j as usize, LinkType::Sequential)
        } else if k < ns + nb {
            let l = &self.bend[k - ns];
            (l.i as usize, l.j as usize, LinkType::Interlaced)
        } else {
            let s = &self.stitches[k - ns - nb];
            (s.i as usize, s.j as usize, LinkType::Seam)
        }
    }
    /// The longest step a fixed-step explicit integrator can take with
    /// this model's stitches, s (infinite without seams). A stitch ties two
    /// particles by a spring `k` and a dashpot `c`; their relative motion,
    /// of reduced mass `mu = m_i m_j / (m_i + m_j)`, is stable under
    /// explicit Euler steps only for `h < 2 mu / c` and `h < 2 sqrt(mu / k)`.
    /// (The default dashpot makes this microseconds: sewn garments are for
    /// the implicit integrators.)
    pub fn explicit_stitch_step_limit(&self) -> f64 {
        let mut limit = f64::INFINITY;
        for s in &self.stitches {
            let (mi, mj) = (self.mass[s.i as usize], self.mass[s.j as usize]);
            let mu = mi * mj / (mi + mj);
            limit = limit.min(2.0 * mu / s.dashpot(true)).min(2.0 * (mu / s.k).sqrt());
        }
        limit
    }
    /// Closes every stitch whose gap at `x` is within `pull / k` (the
    /// closed law's linear range); `closed` holds one flag per stitch, and a
    /// closed stitch stays closed (see [`crate::seams`]).
    pub fn close_stitches(&self, x: &[Vec3], closed: &mut [bool]) {
        for (s, c) in self.stitches.iter().zip(closed) {
            *c = *c || (x[s.j as usize] - x[s.i as usize]).norm() <= s.pull / s.k;
        }
    }
    /// Widest gap of a stitch at positions `x`, m (0 without seams): how
    /// far the seams are from closed.
    pub fn max_seam_gap(&self, x: &[Vec3]) -> f64 {
        self.stitches.iter().map(|s| (x[s.j as usize] - x[s.i as usize]).norm()).fold(0.0, f64::max)
    }
    /// Links a task of [`ClothModel::max_stretch_ratio`] takes at least:
    /// a ratio is a few nanoseconds, so small cloths stay on one thread.
    const STRETCH_CHUNK: usize = 4096;
    /// Largest type-1 link length over rest length at positions `x`
    /// (the stretch measure of `summary.json`, the studies and the tests).
    /// In parallel: a maximum is the same in any order (`cloth run` takes
    /// it after every step, 9% of a symplectic-Euler run on one thread).
    pub fn max_stretch_ratio(&self, x: &[Vec3]) -> f64 {
        use rayon::prelude::*;
        let ratio = |l: &StretchLink| (x[l.j as usize] - x[l.i as usize]).norm() / l.rest;
        self.stretch.par_iter().with_min_len(Self::STRETCH_CHUNK).map(ratio).reduce(|| 0.0, f64::max)
    }
    /// The most stretched link at `x`: its length over its rest length
    /// and its particles (the first such link on a tie); `None` without
    /// links. Same result whatever the thread count.
    pub fn most_stretched(&self, x: &[Vec3]) -> Option<(f64, usize, usize)> {
        use rayon::prelude::*;
        let ratio = |(k, l): (usize, &StretchLink)| ((x[l.j as usize] - x[l.i as usize]).norm() / l.rest, k);
        let larger = |a: (f64, usize), b: (f64, usize)| {
            if b.0 > a.0 || (b.0 == a.0 && b.1 < a.1) || a.0.is_nan() { b } else { a }
        };
        let stretch = self.stretch.par_iter().enumerate().with_min_len(Self::STRETCH_CHUNK).map(ratio);
        let (ratio, k) = stretch.reduce(|| (f64::NEG_INFINITY, usize::MAX), larger);
        self.stretch.get(k).map(|l| (ratio, l.i as usize, l.j as usize))
    }
    /// Pins.
    pub fn pins(&self) -> &[Pin] {
        &self.pins
    }
    /// Whether particle `i` is pinned.
    pub fn is_pinned(&self, i: usize) -> bool {
        self.pinned[i]
    }
    /// The effects this model computes.
    pub fn effects(&self) -> &Effects {
        &self.effects
    }
    /// The material.
    pub fn material(&self) -> &Material {
        &self.material
    }
    /// The discretisation.
    pub fn kind(&self) -> ModelKind {
        self.kind
    }
    /// The wind, if the model has a wind effect.
    pub fn wind(&self) -> Option<&Wind> {
        self.wind.as_ref().filter(|_| self.effects.wind || self.effects.aerodynamics)
    }
    /// Solids the cloth collides with.
    pub fn colliders(&self) -> &[Collider] {
        &self.colliders
    }
    /// Distance kept between particles and solid surfaces, m.
    pub fn contact_thickness(&self) -> f64 {
        self.contact_thickness
    }
    /// Self-collision parameters, if self-collision is on.
    pub fn self_collision(&self) -> Option<&SelfCollision> {
        self.self_collision.as_ref()
    }
    /// Deformation constraints, if the model has them.
    pub fn strain_limit(&self) -> Option<StrainLimit> {
        self.strain_limit
    }
    /// Panels, in particle order.
    pub fn panels(&self) -> &[PanelRange] {
        &self.panels
    }
    /// Drag coefficient `c_i` of particle `i`, N s/m (0 without the drag effect).
    #[inline]
    pub fn drag(&self, i: usize) -> f64 {
        self.drag.get(i).copied().unwrap_or(0.0)
    }
    /// Whether the model has drag.
    pub fn has_drag(&self) -> bool {
        !self.drag.is_empty()
    }
    /// Membrane and bending triangles (Volino model; empty otherwise).
    pub fn elements(&self) -> &ElementSet {
        &self.elements
    }
    /// Surface triangles (two per grid cell), for output.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }
    /// The surface triangles (indices into [`ClothModel::triangles`]) that
    /// have particle `i` as a corner, in increasing order.
    pub fn particle_triangles(&self, i: usize) -> &[u32] {
        &self.tri_of[self.tri_ptr[i]..self.tri_ptr[i + 1]]
    }
    /// The particles sewn to particle `i`, directly or through other
    /// stitches, with `i` itself (sorted); empty if `i` is not sewn. The
    /// corner where a waist seam meets two side seams is four particles
    /// at one point of the garment.
    pub fn sewn_with(&self, i: usize) -> &[u32] {
        &self.sewn[self.sewn_ptr[i]..self.sewn_ptr[i + 1]]
    }
    /// Whether particles `a` and `b` never repel each other in
    /// self-collision: they share a link, or are sewn together, or one is
    /// linked to a particle sewn to the other (a stitched point of the
    /// garment stands for all its particles: [`ClothModel::sewn_with`]).
    pub fn never_repel(&self, a: usize, b: usize) -> bool {
        let next_to = |p: usize, q: usize| self.incidence(p).iter().any(|inc| inc.other as usize == q);
        let near = |p: usize, q: usize| self.sewn_with(p).iter().any(|&m| m as usize == q || next_to(m as usize, q));
        next_to(a, b) || near(a, b) || near(b, a)
    }
    /// Links incident to particle `i`, in link order.
    pub fn incidence(&self, i: usize) -> &[Incidence] {
        &self.inc[self.inc_ptr[i]..self.inc_ptr[i + 1]]
    }
    /// The system matrix's sparsity pattern.
    pub fn pattern(&self) -> &BlockPattern {
        &self.pattern
    }
    /// Where each mesh panel's particles are.
    pub fn meshes(&self) -> &[MeshRange] {
        &self.meshes
    }

    /// The multigrid preconditioner's hierarchy for this model's system
    /// matrix: 2 x 2 grid nodes per aggregate and level (fewer CG
    /// iterations than 3 x 3 for the same work on the 75 x 75 hanging
    /// cloth: 22 vs 28), down to at most 40 nodes solved densely. The
    /// smoother is damped for the largest element (links 2, triangles and
    /// Choi & Ko's triples 3, bending triangles 6 nodes), so the cycle is positive
    /// definite. A seam's two sides share their first-level aggregates
    /// ([`ClothModel::sew_aggregates`]). A model without solids (its matrix
    /// solved once a step, no contact passes) of at least
    /// [`SMOOTHED_MIN_NODES`] particles gets a smoothed first level
    /// ([`Multigrid::smoothed`]): 19.4 -> 7.6 CG a step on the 513 x 513
    /// hanging cloth.
    pub fn multigrid(&self) -> Multigrid {
        let nodes = self.elements().largest_element().max(2);
        let mut levels = self.grid_aggregations(2, 40);
        if let Some(first) = levels.first_mut() {
            self.sew_aggregates(first);
        }
        let stitched: Vec<(usize, usize)> = self.stitches.iter().map(|s| (s.i as usize, s.j as usize)).collect();
        let smoothed = self.colliders.is_empty() && self.pattern.n() >= SMOOTHED_MIN_NODES;
        let hierarchy =
            if smoothed { Multigrid::smoothed(&self.pattern, &levels) } else { Multigrid::new(&self.pattern, &levels) };
        hierarchy.expect("grid aggregates fit the model").for_element_size(nodes).with_pairs(&stitched)
    }

    /// A multigrid hierarchy of aggregates: each level groups `factor x
    /// factor` nodes of every grid panel (of the previous level's grid) and
    /// up to `factor^2` neighbours of every mesh panel's graph
    /// ([`cloth_linalg::graph_aggregation`]), until at most `max_coarse`
    /// nodes remain or a level stops shrinking. Aggregates never span two
    /// panels.
    pub fn grid_aggregations(&self, factor: usize, max_coarse: usize) -> Vec<Aggregation> {
        let factor = factor.max(2);
        let mut dims: Vec<(usize, usize)> = self.panels.iter().map(|p| (p.nx, p.ny)).collect();
        let mut graphs: Vec<(usize, Vec<[u32; 2]>)> = self.meshes.iter().map(|m| (m.len, m.edges.clone())).collect();
        let mut levels = Vec::new();
        loop {
            let n: usize = dims.iter().map(|(a, b)| a * b).sum::<usize>() + graphs.iter().map(|g| g.0).sum::<usize>();
            let coarse_dims: Vec<(usize, usize)> =
                dims.iter().map(|&(nx, ny)| (nx.div_ceil(factor), ny.div_ceil(factor))).collect();
            let coarse_graphs: Vec<_> = graphs
                .iter()
                .map(|(len, edges)| cloth_linalg::graph_aggregation(*len, edges, factor * factor))
                .collect();
            let n_coarse: usize = coarse_dims.iter().map(|(a, b)| a * b).sum::<usize>()
                + coarse_graphs.iter().map(|g| g.n_coarse).sum::<usize>();
            if n <= max_coarse || n_coarse == n {
                return levels;
            }
            let mut coarse_of = Vec::with_capacity(n);
            let mut offset = 0u32;
            for (&(nx, ny), &(cnx, cny)) in dims.iter().zip(&coarse_dims) {
                for j in 0..ny {
                    for i in 0..nx {
                        coarse_of.push(offset + ((j / factor) * cnx + i / factor) as u32);
                    }
                }
                offset += (cnx * cny) as u32;
            }
            for g in &coarse_graphs {
                coarse_of.extend(g.coarse_of.iter().map(|&a| offset + a));
                offset += g.n_coarse as u32;
            }
            levels.push(Aggregation { coarse_of, n_coarse });
            dims = coarse_dims;
            graphs = coarse_graphs.into_iter().map(|g| (g.n_coarse, g.coarse_edges)).collect();
        }
    }

    /// Puts each stitch's two particles in one aggregate of `level` (the
    /// first level of [`ClothModel::grid_aggregations`]): a stitch is the
    /// stiffest coupling of the system, and with the sides of a seam in
    /// aggregates of their own panels the V-cycle barely reduced the error
    /// across it (a 41 x 41 sheet sewn from two halves took 146 CG
    /// iterations a step where the whole sheet takes 31). A particle moves
    /// to its partner's aggregate only if its own keeps other members, so
    /// no aggregate empties and the coarse grids keep their shape.
    pub fn sew_aggregates(&self, level: &mut Aggregation) {
        let mut members = vec![0u32; level.n_coarse];
        for &a in &level.coarse_of {
            members[a as usize] += 1;
        }
        for s in &self.stitches {
            let (i, j) = (s.i as usize, s.j as usize);
            let (ai, aj) = (level.coarse_of[i], level.coarse_of[j]);
            if ai == aj {
                continue;
            }
            let (from, to, moved) = if members[aj as usize] > 1 {
                (aj, ai, j)
            } else if members[ai as usize] > 1 {
                (ai, aj, i)
            } else {
                continue;
            };
            level.coarse_of[moved] = to;
            members[from as usize] -= 1;
            members[to as usize] += 1;
        }
    }

    /// Offset of the diagonal block within row `i`.
    pub fn diag_local(&self, i: usize) -> usize {
        self.diag_local[i] as usize
    }
}

/// Of `n` particles, the triangles each is a corner of, as a compressed
/// row list `(ptr, list)`: particle `i`'s are `list[ptr[i]..ptr[i + 1]]`.
/// [`ClothModel::sewn_with`]'s groups for `n` particles: the components
/// of the graph of `stitches`, as CSR (union-find, each group sorted).
fn sewn_groups(n: usize, stitches: &[Stitch]) -> (Vec<usize>, Vec<u32>) {
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn root(parent: &mut [u32], mut a: u32) -> u32 {
        while parent[a as usize] != a {
            parent[a as usize] = parent[parent[a as usize] as usize];
            a = parent[a as usize];
        }
        a
    }
    let mut sewn = vec![false; n];
    for s in stitches {
        let (a, b) = (root(&mut parent, s.i), root(&mut parent, s.j));
        parent[a.max(b) as usize] = a.min(b);
        sewn[s.i as usize] = true;
        sewn[s.j as usize] = true;
    }
    let roots: Vec<u32> = (0..n as u32).map(|i| root(&mut parent, i)).collect();
    let mut members: std::collections::BTreeMap<u32, Vec<u32>> = std::collections::BTreeMap::new();
    for i in (0..n).filter(|&i| sewn[i]) {
        members.entry(roots[i]).or_default().push(i as u32);
    }
    let mut ptr = vec![0usize; n + 1];
    let mut list = Vec::new();
    for i in 0..n {
        if sewn[i] {
            list.extend_from_slice(&members[&roots[i]]);
        }
        ptr[i + 1] = list.len();
    }
    (ptr, list)
}

fn triangles_of_particles(n: usize, triangles: &[[u32; 3]]) -> (Vec<usize>, Vec<u32>) {
    let mut ptr = vec![0usize; n + 1];
    for &k in triangles.iter().flatten() {
        ptr[k as usize + 1] += 1;
    }
    for i in 0..n {
        ptr[i + 1] += ptr[i];
    }
    let mut fill = ptr.clone();
    let mut list = vec![0u32; ptr[n]];
    for (t, tri) in triangles.iter().enumerate() {
        for &k in tri {
            list[fill[k as usize]] = t as u32;
            fill[k as usize] += 1;
        }
    }
    (ptr, list)
}
