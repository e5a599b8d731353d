//! Building a [`ClothModel`] from a [`ModelSpec`], part by part: the
//! spec's checks, the link laws the material gives, each grid panel's
//! and each mesh panel's particles, links and elements, the seams'
//! stitches, the pins and the clamps they make, the bending elements, and
//! the tables of the finished model (sparsity, triangles, sewn groups,
//! solids). Then what may change a built model: solids and force terms
//! added, another model's constants put in its place.

use super::build_mesh::*;
use super::build_parts::*;
use super::cloth_model::{ClothModel, ForceTerm};
use super::layout::{MeshRange, PanelRange};
use super::links::{BendLaw, BendLink, Compression, StretchLink};
use super::sparsity::{Sparsity, link_pairs};
use super::spec::*;
use crate::colliders::Collider;
use crate::elements::{BendTriple, ElementSet};
use crate::laws::BucklingLaws;
use crate::material::{Compressive, Lattice, Membrane, PATH_CURVATURE_FACTOR};
use crate::seams::{self, Stitch};
use crate::{FieldError, Pin, Vec3};
use std::sync::Arc;

impl ClothModel {
    /// Validates `spec` and builds the model: particle masses from areal
    /// density, links with constants from [`crate::Material::lattice_membrane`]
    /// and [`crate::Material::bend_constants`], rest lengths from the initial
    /// shape, pins, and the sparsity pattern.
    pub fn build(spec: &ModelSpec) -> Result<Self, ModelError> {
        check_spec(spec)?;
        let laws = LinkLaws::of(spec)?;
        let mut parts = Parts::default();
        for (p, panel) in spec.panels.iter().enumerate() {
            parts.add_grid_panel(spec, &laws, p, panel)?;
        }
        let grid_offsets: Vec<usize> = parts.panels.iter().map(|p| p.offset).collect();
        if !spec.meshes.is_empty() {
            check_lattice_on_meshes(spec, laws.path)?;
        }
        let pieces = seams::outline_pieces(&spec.seams, &spec.panels, &grid_offsets, &spec.meshes);
        for (k, panel) in spec.meshes.iter().enumerate() {
            parts.add_mesh_panel(spec, k, panel, &pieces[k])?;
        }
        let stitches = sew(spec, &grid_offsets, &parts.meshes)?;
        let (pins, pinned) = build_pins(spec, &parts.panels, &parts.meshes, &parts.rest_positions)?;
        parts.clamp(&pinned);
        parts.elements.curvatures = bending_elements(spec, &parts, &pinned)?;
        check_wind(spec)?;
        check_strain_limit(spec)?;
        Self::finish(spec, parts, stitches, (pins, pinned))
    }

    /// The model of `parts`, `stitches` and pins: the sparsity pattern and
    /// the per-particle tables, the solids, the stiffest link.
    fn finish(
        spec: &ModelSpec,
        p: Parts,
        stitches: Vec<Stitch>,
        (pins, pinned): (Vec<Pin>, Vec<bool>),
    ) -> Result<Self, ModelError> {
        let Parts { mass, rest_positions, stretch, bend, panels, meshes, triangles, mut elements, drag, .. } = p;
        let n = mass.len();
        // Sparsity pattern and per-row incidence, in a fixed (link) order.
        let link_pairs = link_pairs(&stretch, &bend, &stitches);
        let Sparsity { pattern, inc_ptr, inc, diag_local } = Sparsity::of(n, &link_pairs, &mut elements, &[]);
        let (tri_ptr, tri_of) = triangles_of_particles(n, &triangles);
        let (sewn_ptr, sewn) = sewn_groups(n, &stitches);
        let collision_error = |e: FieldError| ModelError::Collision { field: e.path, message: e.message };
        let colliders = spec.collision.build_colliders().map_err(collision_error)?;
        let mean_link = stretch.iter().map(|l| l.rest).sum::<f64>() / stretch.len().max(1) as f64;
        let self_collision = spec
            .collision
            .build_self_collision(spec.material.tensile_stiffness_n_m, mean_link)
            .map_err(collision_error)?;
        let stiffest_per_mass = stiffest_per_mass(&stretch, &elements, &mass);
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
            c.motion.validate().map_err(|e| fail(&format!("motion.{}", e.path), e.message))?;
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
}

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

/// Of `n` particles, the triangles each is a corner of, as a compressed
/// row list `(ptr, list)`: particle `i`'s are `list[ptr[i]..ptr[i + 1]]`.
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

/// Checks the spec's parts that no later part checks: some panel, the
/// material, gravity, the bending law's model, the orthotropic fields.
fn check_spec(spec: &ModelSpec) -> Result<(), ModelError> {
    if spec.panels.is_empty() && spec.meshes.is_empty() {
        return Err(ModelError::NoPanels);
    }
    spec.material.validate().map_err(|e: FieldError| ModelError::Material { field: e.path, message: e.message })?;
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
            return Err(ModelError::Material { field: field.to_string(), message });
        }
    }
    Ok(())
}

/// How the spec's material becomes links: the membrane lattice, the
/// compressive response, the bending law, the buckling laws (cached by
/// rest length and constants) and the grids' diagonals.
struct LinkLaws {
    damping: bool,
    diagonals: crate::Diagonals,
    /// Choi & Ko's arc-path law: boundary links count in bending for the
    /// part of a cell they border ([`crate::topology::GridLink`]).
    path: bool,
    compressive: Compressive,
    /// The share of the axis links' stiffness Provot's flexion springs take.
    flexion_share: f64,
    membrane: Membrane,
    buckling: std::cell::RefCell<BucklingLaws>,
}

impl LinkLaws {
    fn of(spec: &ModelSpec) -> Result<Self, ModelError> {
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
        let material_err = |e: FieldError| ModelError::Material { field: e.path, message: e.message };
        let membrane = match spec.kind {
            ModelKind::Volino => {
                let nu = spec.material.poisson_ratio.unwrap_or(crate::material::DEFAULT_POISSON_RATIO);
                let damping = spec.material.damping_lattice(nu).map_err(material_err)?;
                // His membrane elements replace the springs: a lattice of zero stiffness.
                Membrane { stiffness: Lattice { axis: 0.0, diagonal: 0.0 }, damping }
            }
            _ => spec.material.lattice_membrane(compressive).map_err(material_err)?,
        };
        Ok(Self {
            damping,
            diagonals,
            path,
            compressive,
            flexion_share,
            membrane,
            buckling: std::cell::RefCell::new(BucklingLaws::default()),
        })
    }
}

/// What the panels add up to, in particle order.
#[derive(Default)]
struct Parts {
    mass: Vec<f64>,
    rest_positions: Vec<Vec3>,
    stretch: Vec<StretchLink>,
    bend: Vec<BendLink>,
    /// Each bend link's middle particle (arc-chord law), for the clamps.
    bend_middle: Vec<Option<u32>>,
    panels: Vec<PanelRange>,
    meshes: Vec<MeshRange>,
    triangles: Vec<[u32; 3]>,
    elements: ElementSet,
    bending_triangles: Vec<BendingTriangle>,
    drag: Vec<f64>,
}

impl Parts {
    /// Grid panel `p`'s particles, links, elements and triangles.
    fn add_grid_panel(
        &mut self,
        spec: &ModelSpec,
        laws: &LinkLaws,
        p: usize,
        panel: &crate::GridPanel,
    ) -> Result<(), ModelError> {
        let LinkLaws { diagonals, path, compressive, flexion_share, ref membrane, damping, .. } = *laws;
        let mut buckling = laws.buckling.borrow_mut();
        let Parts {
            mass,
            rest_positions,
            stretch,
            bend,
            bend_middle,
            panels,
            triangles,
            elements,
            bending_triangles,
            drag,
            ..
        } = self;
        let mesh = panel.mesh_with(diagonals).map_err(|e: FieldError| ModelError::Panel {
            panel: p,
            field: e.path,
            message: e.message,
        })?;
        let offset = mass.len();
        let at = |k: u32| offset as u32 + k;
        let rest_of = |[a, b]: [u32; 2]| (mesh.positions[b as usize] - mesh.positions[a as usize]).norm();
        let degenerate = |rest: f64, values: &[f64]| !(rest > 0.0 && values.iter().all(|v| v.is_finite()));
        let degenerate_err = || ModelError::Panel {
            panel: p,
            field: "size_m".into(),
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
            let (_, v_axis, _) = panel.frame().map_err(|e: FieldError| ModelError::Panel {
                panel: p,
                field: e.path,
                message: e.message,
            })?;
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
        Ok(())
    }

    /// Mesh panel `k`'s particles, links, elements and triangles; `piece`
    /// is its pattern piece's outline where seams sew it.
    fn add_mesh_panel(
        &mut self,
        spec: &ModelSpec,
        k: usize,
        panel: &crate::MeshPanel,
        piece: &[Option<usize>],
    ) -> Result<(), ModelError> {
        let Parts {
            mass,
            rest_positions,
            stretch,
            bend,
            bend_middle,
            meshes,
            triangles,
            elements,
            bending_triangles,
            drag,
            ..
        } = self;
        let err = |e: FieldError| ModelError::Mesh { mesh: k, field: e.path, message: e.message };
        let mesh = panel.resolve_with(&spec.collision.base_dir, piece).map_err(err)?;
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
        let (len, outline_edges, outline_lengths) = (mesh.positions.len(), mesh.outline_edges, mesh.outline_lengths);
        meshes.push(MeshRange { offset, len, edges, outline_edges, outline_lengths });
        Ok(())
    }

    /// The clamps the pins make on bending (see [`clamped`]).
    fn clamp(&mut self, pinned: &[bool]) {
        clamp_bend_links(&mut self.bend, &self.bend_middle, pinned);
        clamp_triples(&mut self.elements.triples, pinned);
        clamp_hinges(&mut self.elements.hinges, pinned);
    }
}

/// The seams' stitches.
fn sew(spec: &ModelSpec, grid_offsets: &[usize], meshes: &[MeshRange]) -> Result<Vec<Stitch>, ModelError> {
    let targets = seams::SeamTargets { panels: &spec.panels, offsets: grid_offsets, meshes };
    let mut stitches = Vec::new();
    let tensile = spec.material.tensile_stiffness_n_m;
    for (seam, s) in spec.seams.iter().enumerate() {
        stitches.extend(seams::stitches(s, &targets, tensile).map_err(|e| ModelError::Seam {
            seam,
            field: e.path,
            message: e.message,
        })?);
    }
    Ok(stitches)
}

/// Volino's bending elements of the parts' bending triangles, clamped by
/// the pins.
fn bending_elements(
    spec: &ModelSpec,
    parts: &Parts,
    pinned: &[bool],
) -> Result<Vec<crate::elements::CurvatureElement>, ModelError> {
    let (bending_triangles, rest_positions) = (&parts.bending_triangles, &parts.rest_positions);
    curvature_elements(bending_triangles, rest_positions, pinned, spec.material.flexural_rigidity_n_m).map_err(
        |panel| match panel.checked_sub(spec.panels.len()) {
            Some(mesh) => {
                ModelError::Mesh { mesh, field: "triangles".into(), message: "a bending triangle is degenerate".into() }
            }
            None => {
                ModelError::Panel { panel, field: "size_m".into(), message: "a bending triangle is degenerate".into() }
            }
        },
    )
}

/// The wind effects need a valid `[wind]`.
fn check_wind(spec: &ModelSpec) -> Result<(), ModelError> {
    if spec.effects.wind || spec.effects.aerodynamics {
        let wind = spec.wind.as_ref().ok_or(ModelError::Wind {
            field: "profile".into(),
            message: "the wind and aerodynamics effects need a [wind] section".into(),
        })?;
        wind.validate().map_err(|e: FieldError| ModelError::Wind { field: e.path, message: e.message })?;
    }
    Ok(())
}

/// The deformation constraints' settings.
fn check_strain_limit(spec: &ModelSpec) -> Result<(), ModelError> {
    if let Some(limit) = spec.strain_limit {
        if !(limit.max_strain.is_finite() && limit.max_strain >= 0.0) {
            return Err(ModelError::StrainLimit {
                field: "max_strain".into(),
                message: format!("must be finite and >= 0, got {}", limit.max_strain),
            });
        }
        if limit.passes == 0 {
            return Err(ModelError::StrainLimit { field: "passes".into(), message: "must be >= 1".into() });
        }
    }
    Ok(())
}

/// The largest `k_s / m` of a stretch link (its lighter end) or membrane
/// corner, 1/s^2.
fn stiffest_per_mass(stretch: &[StretchLink], elements: &ElementSet, mass: &[f64]) -> f64 {
    let links = stretch.iter().map(|l| l.k_s / mass[l.i as usize].min(mass[l.j as usize]));
    // A membrane triangle's corner `k` is held by `C A |g_k|^2` (the
    // diagonal of its stiffness, with the stiffer direction's `C`).
    let corners = elements.membranes.iter().flat_map(|e| {
        let c = e.rest.c.c11.max(e.rest.c.c22);
        (0..3).map(move |k| c * e.rest.area * e.rest.g[k].norm_squared() / mass[e.nodes[k] as usize])
    });
    links.chain(corners).filter(|r| r.is_finite()).fold(0.0, f64::max)
}
