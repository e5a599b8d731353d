//! What a built model answers: its particles and masses, links and
//! stitches, pins, effects, solids, elements and triangles, the sparsity
//! pattern and the multigrid hierarchy its grids give.

use super::cloth_model::ClothModel;
use super::layout::{MeshRange, PanelRange};
use super::links::{BendLink, Incidence, StretchLink};
use super::spec::{Effects, ModelKind, StrainLimit};
use crate::colliders::{Collider, SelfCollision};
use crate::elements::ElementSet;
use crate::seams::Stitch;
use crate::{LinkType, Material, Pin, Vec3, Wind};
use cloth_linalg::{Aggregation, BlockPattern, Multigrid, SMOOTHED_MIN_NODES};

impl ClothModel {
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
    /// The gap within which stitch `s` closes, m: its closed law's linear
    /// range `pull / k` (a tenth of the spacing by default), or half the
    /// contact thickness where that is wider, since two particles that
    /// close are touching. With the linear range alone the reach shrank
    /// with the mesh: at twice the one-piece's Table-1 count a strap's
    /// corner stitch, which carries more than its sewing pull, stayed
    /// 2.2 mm open for the whole walk.
    pub fn stitch_closing_gap(&self, s: &Stitch) -> f64 {
        (s.pull / s.k).max(0.5 * self.contact_thickness)
    }
    /// Closes every stitch whose gap at `x` is within its
    /// [`ClothModel::stitch_closing_gap`]; `closed` holds one flag per
    /// stitch, and a closed stitch stays closed (see [`crate::SeamSpec`]).
    pub fn close_stitches(&self, x: &[Vec3], closed: &mut [bool]) {
        for (s, c) in self.stitches.iter().zip(closed) {
            *c = *c || (x[s.j as usize] - x[s.i as usize]).norm() <= self.stitch_closing_gap(s);
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
