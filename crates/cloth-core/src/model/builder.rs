//! A typed builder for [`ClothModel`]: the Rust way to describe a cloth,
//! producing the same [`ModelSpec`] a scene file does.
//!
//! ```
//! use cloth_core::{ClothModel, Edge, GridPanel, Material, ModelKind};
//!
//! let model = ClothModel::builder()
//!     .panel(GridPanel::flat([21, 21], [1.0, 1.0]).origin([0.0, 0.0, 1.0]))
//!     .material(Material { tensile_stiffness_n_m: 500.0, ..Material::default() })
//!     .kind(ModelKind::Provot)
//!     .gravity([0.0, 0.0, -9.81])
//!     .bending()
//!     .damping()
//!     .pin_edge(0, Edge::JMax)
//!     .build()?;
//! assert_eq!(model.particle_count(), 21 * 21);
//! assert_eq!(model.pins().len(), 21);
//!
//! // A pattern piece: a trapezoid meshed to 5 cm edges, its top edge pinned.
//! use cloth_core::{MeshPanel, PatternPiece};
//! let piece = PatternPiece {
//!     outline_m: vec![[0.0, 0.0], [0.6, 0.0], [0.5, 0.5], [0.1, 0.5]],
//!     edge_length_m: 0.05,
//!     lines_m: vec![],
//!     u_axis: [1.0, 0.0, 0.0],
//!     v_axis: [0.0, 0.0, -1.0],
//!     cylinder_radius_m: None,
//!     cone: None,
//! };
//! let skirt = ClothModel::builder().mesh(MeshPanel::from_pattern(piece)).pin_vertices(0, [], [0]).build()?;
//! assert!(skirt.particle_count() > 100 && skirt.pins().len() == 13);
//! # Ok::<(), cloth_core::ModelError>(())
//! ```

use crate::colliders::{ColliderSpec, SelfCollisionSpec};
use crate::terms::ForceTerm;
use crate::{
    BendingLaw, ClothModel, Edge, Effect, EffectValues, GridPanel, Material, MeshPanel, ModelError, ModelKind,
    ModelSpec, PinSpec, SeamSpec, StrainLimit, Vec3, Wind,
};
use std::path::PathBuf;
use std::sync::Arc;

impl ClothModel {
    /// A builder with no panels, the default [`Material`], Choi & Ko's
    /// model and no effects: gravity, bending and the rest are switched on
    /// one by one, as a scene lists them.
    pub fn builder() -> ModelBuilder {
        ModelBuilder::default()
    }
}

impl GridPanel {
    /// A flat panel of `particles = [nx, ny]` spanning `size_m` (m) along
    /// +x and +y, particle (0, 0) at the origin.
    pub fn flat(particles: [usize; 2], size_m: [f64; 2]) -> Self {
        Self { particles, size_m, origin_m: [0.0; 3], u_axis: [1.0, 0.0, 0.0], v_axis: [0.0, 1.0, 0.0], wrap_u: false }
    }

    /// Moves particle (0, 0) (the axis point when wrapped) to `origin_m`, m.
    pub fn origin(mut self, origin_m: [f64; 3]) -> Self {
        self.origin_m = origin_m;
        self
    }

    /// The directions of increasing i and j (normalised and made
    /// orthogonal when the model is built).
    pub fn axes(mut self, u_axis: [f64; 3], v_axis: [f64; 3]) -> Self {
        self.u_axis = u_axis;
        self.v_axis = v_axis;
        self
    }

    /// Wraps the panel along u into a cylinder around v: `size_m[0]` is
    /// then the circumference.
    pub fn wrapped(mut self) -> Self {
        self.wrap_u = true;
        self
    }
}

/// Builds a [`ModelSpec`] step by step; [`ModelBuilder::build`] checks it
/// and builds the model, with the same errors a scene file gets.
#[derive(Debug, Clone, Default)]
pub struct ModelBuilder {
    spec: ModelSpec,
    terms: Vec<Arc<dyn ForceTerm>>,
}

impl ModelBuilder {
    /// Adds a panel (particles are numbered panel after panel).
    pub fn panel(mut self, panel: GridPanel) -> Self {
        self.spec.panels.push(panel);
        self
    }

    /// Adds a flat panel in the xy plane: [`GridPanel::flat`].
    pub fn grid(self, particles: [usize; 2], size_m: [f64; 2]) -> Self {
        self.panel(GridPanel::flat(particles, size_m))
    }

    /// The fabric, shared by all panels.
    pub fn material(mut self, material: Material) -> Self {
        self.spec.material = material;
        self
    }

    /// The discretisation: Choi & Ko's links (default), Provot's springs
    /// or Volino's triangles.
    pub fn kind(mut self, kind: ModelKind) -> Self {
        self.spec.kind = kind;
        self
    }

    /// How Choi & Ko's type-2 links read bending (default arc-path).
    pub fn bending_law(mut self, law: BendingLaw) -> Self {
        self.spec.bending_law = Some(law);
        self
    }

    /// Switches on `effect` with its default values (gravity along `-z`
    /// at 9.81 m/s^2, the default constraints; see [`EffectValues`]).
    pub fn effect(self, effect: Effect) -> Self {
        self.effect_with(effect, &EffectValues::default())
    }

    /// Switches on `effect` with `values`.
    pub fn effect_with(mut self, effect: Effect, values: &EffectValues) -> Self {
        effect.switch_on(&mut self.spec, values);
        self
    }

    /// Uniform gravity, m/s^2.
    pub fn gravity(mut self, g_m_s2: [f64; 3]) -> Self {
        self.spec.effects.gravity = Some(Vec3::from(g_m_s2));
        self
    }

    /// Bending and compression resistance (Choi & Ko's type-2 links,
    /// Provot's flexion springs, Volino's bending triangles).
    pub fn bending(self) -> Self {
        self.effect(Effect::Bending)
    }

    /// Directional damping along the links (`material.damping_n_s_m`).
    pub fn damping(self) -> Self {
        self.effect(Effect::Damping)
    }

    /// Viscous drag on every particle (`material.drag_n_s_m3`).
    pub fn drag(self) -> Self {
        self.effect(Effect::Drag)
    }

    /// The air's motion and coefficients, for [`ModelBuilder::wind`] and
    /// [`ModelBuilder::aerodynamics`].
    pub fn air(mut self, air: Wind) -> Self {
        self.spec.wind = Some(air);
        self
    }

    /// Provot's viscous fluid force along the normals (needs
    /// [`ModelBuilder::air`]).
    pub fn wind(self) -> Self {
        self.effect(Effect::Wind)
    }

    /// Aerodynamic drag and lift on triangles (needs [`ModelBuilder::air`]).
    pub fn aerodynamics(self) -> Self {
        self.effect(Effect::Aerodynamics)
    }

    /// Provot's deformation constraints.
    pub fn strain_limit(mut self, limit: StrainLimit) -> Self {
        self.spec.strain_limit = Some(limit);
        self
    }

    /// Pins grid nodes `[i, j]` of panel `panel` where they start.
    pub fn pin_nodes(self, panel: usize, nodes: impl IntoIterator<Item = [usize; 2]>) -> Self {
        self.pin(PinSpec { panel, nodes: nodes.into_iter().collect(), ..PinSpec::default() })
    }

    /// Adds a mesh panel: an OBJ file, listed triangles or a pattern piece
    /// (particles follow every grid panel's).
    pub fn mesh(mut self, mesh: MeshPanel) -> Self {
        self.spec.meshes.push(mesh);
        self
    }

    /// Pins vertices of mesh panel `mesh` where they start, and every vertex
    /// on the pattern's `outline_edges`.
    pub fn pin_vertices(
        self,
        mesh: usize,
        vertices: impl IntoIterator<Item = usize>,
        outline_edges: impl IntoIterator<Item = usize>,
    ) -> Self {
        self.pin(PinSpec {
            mesh: Some(mesh),
            vertices: vertices.into_iter().collect(),
            outline_edges: outline_edges.into_iter().collect(),
            ..PinSpec::default()
        })
    }

    /// Pins a whole edge of panel `panel` where it starts.
    pub fn pin_edge(self, panel: usize, edge: Edge) -> Self {
        self.pin(PinSpec { panel, edge: Some(edge), ..PinSpec::default() })
    }

    /// Adds a set of pins with its own path.
    pub fn pin(mut self, pins: PinSpec) -> Self {
        self.spec.pins.push(pins);
        self
    }

    /// Adds a solid the cloth collides with.
    pub fn collider(mut self, collider: ColliderSpec) -> Self {
        self.spec.collision.colliders.push(collider);
        self
    }

    /// Distance kept between the particles and solid surfaces, m (default
    /// 0.005).
    pub fn contact_thickness(mut self, thickness_m: f64) -> Self {
        self.spec.collision.thickness_m = Some(thickness_m);
        self
    }

    /// Turns self-collision on.
    pub fn self_collision(mut self, spec: SelfCollisionSpec) -> Self {
        self.spec.collision.self_collision = Some(spec);
        self
    }

    /// The directory relative mesh paths of colliders start from.
    pub fn mesh_dir(mut self, dir: impl Into<PathBuf>) -> Self {
        self.spec.collision.base_dir = dir.into();
        self
    }

    /// Sews two panel edges together.
    pub fn seam(mut self, seam: SeamSpec) -> Self {
        self.spec.seams.push(seam);
        self
    }

    /// Adds a force of the caller's own: see [`ClothModel::with_force_term`].
    pub fn force_term(mut self, term: Arc<dyn ForceTerm>) -> Self {
        self.terms.push(term);
        self
    }

    /// The description built so far.
    pub fn spec(&self) -> &ModelSpec {
        &self.spec
    }

    /// Checks the description and builds the model; errors name the field
    /// as a scene file would (`panels[0].particles`).
    pub fn build(&self) -> Result<ClothModel, ModelError> {
        let model = ClothModel::build(&self.spec)?;
        Ok(self.terms.iter().cloned().fold(model, ClothModel::with_force_term))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;

    const HANG: &str = r#"
[simulation]
integrator = "bdf2"
model = "provot"
dt_s = 0.01
duration_s = 0.1
effects = ["gravity", "bending", "damping", "drag"]
[material]
areal_density_kg_m2 = 0.2
tensile_stiffness_n_m = 500.0
flexural_rigidity_n_m = 1e-5
buckling_stiffness_n_m = 500.0
damping_n_s_m = 0.05
drag_n_s_m3 = 0.3
[[panels]]
particles = [9, 7]
size_m = [0.8, 0.6]
origin_m = [0.0, 0.0, 1.0]
[[pins]]
nodes = [[8, 6]]
[[pins]]
edge = "i_min"
"#;

    fn built_in_code() -> ModelBuilder {
        ClothModel::builder()
            .panel(GridPanel::flat([9, 7], [0.8, 0.6]).origin([0.0, 0.0, 1.0]))
            .material(Material {
                areal_density_kg_m2: 0.2,
                tensile_stiffness_n_m: 500.0,
                flexural_rigidity_n_m: 1e-5,
                buckling_stiffness_n_m: 500.0,
                damping_n_s_m: 0.05,
                drag_n_s_m3: 0.3,
                ..Material::default()
            })
            .kind(ModelKind::Provot)
            .gravity([0.0, 0.0, -9.81])
            .bending()
            .damping()
            .drag()
            .pin_nodes(0, [[8, 6]])
            .pin_edge(0, Edge::IMin)
    }

    #[test]
    fn the_builder_describes_the_model_a_scene_file_does() {
        let scene = Scene::parse(HANG, &[]).unwrap();
        assert_eq!(built_in_code().spec(), &scene.model_spec());
    }

    #[test]
    fn a_cloth_built_in_code_moves_as_the_same_scene_file_bit_for_bit() {
        let scene = Scene::parse(HANG, &[]).unwrap();
        let (from_file, config) = scene.build().unwrap();
        let mut file_sim = config.simulation(from_file);
        let mut code_sim = crate::Simulation::builder(built_in_code().build().unwrap())
            .integrator(crate::IntegratorKind::Bdf2)
            .build();
        for _ in 0..10 {
            file_sim.step(config.dt_s).unwrap();
            code_sim.step(0.01).unwrap();
        }
        assert_eq!(file_sim.state().x, code_sim.state().x);
        // The cloth fell: the test compares a moving state.
        let sag = 1.0 - code_sim.state().x.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
        assert!(sag > 0.01, "lowest point only {sag} m below the pins");
    }

    /// A wrapped panel's surface triangles face away from its axis, whatever
    /// its axes, so a skirt's outside is drawn as its front; a flat panel's
    /// face along `u x v`.
    #[test]
    fn a_wrapped_panels_triangles_face_out() {
        for (u, v) in [([1.0, 0.0, 0.0], [0.0, 0.0, -1.0]), ([0.0, 1.0, 0.0], [0.0, 0.0, 1.0])] {
            let panel = GridPanel::flat([12, 4], [1.0, 0.3]).axes(u, v).origin([0.2, -0.1, 1.0]).wrapped();
            let model = ClothModel::builder().panel(panel).build().unwrap();
            let (x, axis) = (model.rest_positions(), Vec3::from(v));
            for t in model.triangles() {
                let [a, b, c] = t.map(|k| x[k as usize]);
                let centroid = (a + b + c) / 3.0;
                let rel = centroid - Vec3::new(0.2, -0.1, 1.0);
                let radial = rel - axis * axis.dot(&rel);
                assert!((b - a).cross(&(c - a)).dot(&radial) > 0.0, "{t:?} faces the axis");
            }
        }
        let flat = ClothModel::builder().grid([3, 3], [1.0, 1.0]).build().unwrap();
        let x = flat.rest_positions();
        for t in flat.triangles() {
            let [a, b, c] = t.map(|k| x[k as usize]);
            assert!((b - a).cross(&(c - a)).z > 0.0);
        }
    }

    #[test]
    fn a_bad_panel_built_in_code_names_its_field() {
        let err = ClothModel::builder().grid([1, 5], [1.0, 1.0]).build().unwrap_err();
        assert!(err.to_string().starts_with("panels[0].particles"), "{err}");
        let err = ClothModel::builder().grid([3, 3], [1.0, 1.0]).pin_nodes(0, [[5, 0]]).build().unwrap_err();
        assert!(err.to_string().contains("pins[0]"), "{err}");
    }
}
