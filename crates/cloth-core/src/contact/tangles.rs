//! Whether a run has tangled, step by step: the cloth passing through
//! itself (a crossing that outlasts a few steps, which the contact response
//! did not undo) or through a solid (a particle deeper inside than the
//! contact thickness, where the response keeps particles outside). What a
//! run reports and, strictly, stops on; the physics does not read it.

use super::crossings::{Crossing, CrossingCheck};
use super::projection::Inside;
use crate::{ClothModel, Vec3};

/// Steps a crossing must last to count as a tangle: the continuous
/// response undoes a passing one within a step or two.
pub const LASTING_STEPS: u64 = 5;

/// What the state after one step holds.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TangleCounts {
    /// Mesh edges through triangles of the cloth (stitched and adjacent
    /// elements left out).
    pub self_crossings: usize,
    /// Particles inside a solid deeper than the contact thickness.
    pub deep_in_solids: usize,
    /// The deepest any particle is inside a solid, m (0: none inside;
    /// particles allowed to start inside not counted until they come out).
    pub deepest_in_solid_m: f64,
}

/// The first sign of a tangle of one kind.
#[derive(Debug, Clone, PartialEq)]
pub enum TangleEvent {
    /// A crossing present after [`LASTING_STEPS`] steps in a row.
    LastingCrossing {
        /// The step after which it was first seen, and its time, s.
        since: (u64, f64),
        /// The step after which it had lasted, and its time, s.
        at: (u64, f64),
        /// The edge `[a, b]` that passes through the triangle.
        edge: [u32; 2],
        /// The triangle's corners.
        triangle: [u32; 3],
        /// All crossings present then.
        crossings: usize,
    },
    /// Particles deeper inside a solid than the contact thickness.
    ThroughSolid {
        /// The step and its time, s.
        at: (u64, f64),
        /// The particles, in order (the first ones when many).
        particles: Vec<usize>,
        /// How many there are.
        count: usize,
        /// The solid the deepest is in (index among the model's colliders).
        solid: usize,
        /// The deepest, m.
        depth_m: f64,
        /// The contact thickness, m.
        thickness_m: f64,
    },
}

/// Particles a [`TangleEvent::ThroughSolid`] lists.
const LISTED: usize = 8;

/// Watches a run for tangles: crossings kept from step to step with the
/// step each was first seen, the particles allowed to be inside a solid.
#[derive(Debug, Clone)]
pub struct TangleWatch {
    check: CrossingCheck,
    /// The crossings after the last step, sorted, with when each began.
    open: Vec<(Crossing, (u64, f64))>,
    next: Vec<(Crossing, (u64, f64))>,
    /// Particles inside a solid at the start, not counted until they leave.
    started_inside: Vec<bool>,
    /// How deep each particle is inside a solid after the step, m.
    depth: Vec<f64>,
    reported_crossing: bool,
    reported_solid: bool,
}

impl TangleWatch {
    /// A watch for `model`; `started_inside` lists the particles a scene
    /// allowed to start inside a solid, not counted until they come out.
    pub fn new(model: &ClothModel, started_inside: &[Inside]) -> Self {
        let mut inside = vec![false; model.particle_count()];
        for i in started_inside {
            inside[i.particle] = true;
        }
        Self {
            check: CrossingCheck::new(model),
            open: Vec::new(),
            next: Vec::new(),
            depth: vec![0.0; inside.len()],
            started_inside: inside,
            reported_crossing: false,
            reported_solid: false,
        }
    }

    /// After a step (`step`, ending at `time_s`): the counts at positions
    /// `x`, with `inside` the particles inside a solid then
    /// ([`crate::Simulation::particles_inside`]), and the first event of
    /// each kind, once per run.
    pub fn after_step(
        &mut self,
        model: &ClothModel,
        x: &[Vec3],
        inside: &[Inside],
        (step, time_s): (u64, f64),
    ) -> (TangleCounts, Vec<TangleEvent>) {
        let mut events = Vec::new();
        let crossings = self.check.find(model, x);
        // Carry each crossing's start over from the last step (both sorted).
        self.next.clear();
        let mut k = 0;
        for &c in crossings {
            while k < self.open.len() && self.open[k].0 < c {
                k += 1;
            }
            let since = match self.open.get(k) {
                Some(&(o, since)) if o == c => since,
                _ => (step, time_s),
            };
            self.next.push((c, since));
        }
        std::mem::swap(&mut self.open, &mut self.next);
        if !self.reported_crossing
            && let Some(&((edge, t), since)) = self.open.iter().find(|(_, since)| step - since.0 + 1 >= LASTING_STEPS)
        {
            self.reported_crossing = true;
            let triangle = model.triangles()[t as usize];
            events.push(TangleEvent::LastingCrossing {
                since,
                at: (step, time_s),
                edge,
                triangle,
                crossings: self.open.len(),
            });
        }
        let thickness_m = model.contact_thickness();
        // A particle allowed to start inside counts once it is out of the
        // deep (within the thickness, or outside).
        self.depth.fill(0.0);
        for i in inside {
            self.depth[i.particle] = i.depth_m;
        }
        for (started, &depth) in self.started_inside.iter_mut().zip(&self.depth) {
            *started &= depth > thickness_m;
        }
        let counted = || inside.iter().filter(|i| !self.started_inside[i.particle]);
        let deepest_in_solid_m = counted().map(|i| i.depth_m).fold(0.0, f64::max);
        let deep: Vec<&Inside> = counted().filter(|i| i.depth_m > thickness_m).collect();
        if !self.reported_solid && !deep.is_empty() {
            self.reported_solid = true;
            let deepest = deep.iter().max_by(|a, b| a.depth_m.total_cmp(&b.depth_m)).expect("not empty");
            events.push(TangleEvent::ThroughSolid {
                at: (step, time_s),
                particles: deep.iter().take(LISTED).map(|i| i.particle).collect(),
                count: deep.len(),
                solid: deepest.solid,
                depth_m: deepest.depth_m,
                thickness_m,
            });
        }
        (TangleCounts { self_crossings: self.open.len(), deep_in_solids: deep.len(), deepest_in_solid_m }, events)
    }
}

impl TangleEvent {
    /// The event in words, `solid_name` naming the model's solids.
    pub fn describe(&self, solid_name: impl Fn(usize) -> String) -> String {
        match self {
            TangleEvent::LastingCrossing { since, at, edge, triangle, crossings } => format!(
                "the cloth passes through itself from t = {:.4} s (step {}) and still at t = {:.4} s (step {}): \
                 edge {}-{} through triangle ({}, {}, {}); {crossings} crossing(s) then",
                since.1, since.0, at.1, at.0, edge[0], edge[1], triangle[0], triangle[1], triangle[2]
            ),
            TangleEvent::ThroughSolid { at, particles, count, solid, depth_m, thickness_m } => {
                let listed: Vec<String> = particles.iter().map(usize::to_string).collect();
                let more = if *count > particles.len() {
                    format!(" and {} more", count - particles.len())
                } else {
                    String::new()
                };
                format!(
                    "cloth pushed through a solid at t = {:.4} s (step {}): particle(s) {}{more} deeper inside than \
                     the {:.1} mm contact thickness, the deepest {:.1} mm inside {}",
                    at.1,
                    at.0,
                    listed.join(", "),
                    thickness_m * 1e3,
                    depth_m * 1e3,
                    solid_name(*solid)
                )
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Edge, GridPanel, ModelSpec};

    /// Two 5 x 5 sheets of 0.2 m, one flat at `z = 0`, one upright through
    /// its middle: their edges pierce each other's triangles.
    fn crossed_sheets() -> ClothModel {
        let sheet = |origin_m: [f64; 3], v_axis: [f64; 3]| GridPanel {
            particles: [5, 5],
            size_m: [0.2, 0.2],
            origin_m,
            u_axis: [1.0, 0.0, 0.0],
            v_axis,
            wrap_u: false,
        };
        ClothModel::build(&ModelSpec {
            panels: vec![sheet([0.0, 0.0, 0.0], [0.0, 1.0, 0.0]), sheet([0.013, 0.11, -0.087], [0.0, 0.0, 1.0])],
            ..ModelSpec::default()
        })
        .unwrap()
    }

    /// A crossing is reported once it has lasted `LASTING_STEPS` steps, with
    /// the step it began; a crossing that comes and goes is not.
    #[test]
    fn a_crossing_is_reported_when_it_lasts() {
        let model = crossed_sheets();
        let crossed = model.rest_positions().to_vec();
        let mut apart = crossed.clone();
        for p in &mut apart[25..] {
            p.z += 0.5;
        }
        let mut watch = TangleWatch::new(&model, &[]);
        let h = 0.01;
        let mut reported = Vec::new();
        // Crossed, apart, then crossed for good from step 3.
        for step in 1..=10u64 {
            let x = if step == 2 { &apart } else { &crossed };
            let (counts, events) = watch.after_step(&model, x, &[], (step, step as f64 * h));
            assert_eq!(counts.self_crossings > 0, step != 2, "step {step}: {counts:?}");
            assert_eq!(counts.deep_in_solids, 0);
            reported.extend(events.into_iter().map(|e| (step, e)));
        }
        assert_eq!(reported.len(), 1, "{reported:?}");
        let (step, TangleEvent::LastingCrossing { since, at, edge, triangle, crossings }) = &reported[0] else {
            panic!("{reported:?}")
        };
        assert_eq!((*step, since.0, at.0), (3 + LASTING_STEPS - 1, 3, 3 + LASTING_STEPS - 1));
        assert!(*crossings > 0);
        // The edge belongs to one sheet, the triangle to the other.
        assert_ne!(edge[0] < 25, triangle[0] < 25, "{edge:?} {triangle:?}");
        let words = reported[0].1.describe(|k| format!("solid {k}"));
        assert!(words.contains("from t = 0.0300 s (step 3)"), "{words}");
    }

    /// Particles deeper inside a solid than the contact thickness are
    /// reported at once, the deepest named; those a scene let start inside
    /// count only once they have come out of the deep.
    #[test]
    fn cloth_through_a_solid_is_reported_but_not_a_start_inside() {
        let model = ClothModel::build(&ModelSpec {
            panels: vec![GridPanel {
                particles: [3, 3],
                size_m: [0.1, 0.1],
                origin_m: [0.0; 3],
                u_axis: [1.0, 0.0, 0.0],
                v_axis: [0.0, 1.0, 0.0],
                wrap_u: false,
            }],
            pins: vec![crate::PinSpec { edge: Some(Edge::JMax), ..Default::default() }],
            ..ModelSpec::default()
        })
        .unwrap();
        let x = model.rest_positions().to_vec();
        let thickness = model.contact_thickness();
        let inside = |p: usize, depth_m: f64| Inside { particle: p, solid: 1, depth_m };
        let mut watch = TangleWatch::new(&model, &[inside(0, 0.02)]);
        // Particle 0 started deep inside: not counted; particle 4 within the thickness: not counted.
        let (counts, events) = watch.after_step(&model, &x, &[inside(0, 0.02), inside(4, thickness * 0.5)], (1, 0.01));
        assert_eq!((counts.deep_in_solids, events.len()), (0, 0));
        // Particle 0 comes out of the deep, then goes back in: now it counts.
        watch.after_step(&model, &x, &[inside(0, thickness * 0.5)], (2, 0.02));
        let (counts, events) =
            watch.after_step(&model, &x, &[inside(0, 0.03), inside(5, 0.04), inside(6, 0.001)], (3, 0.03));
        assert_eq!(counts.deep_in_solids, 2);
        let [TangleEvent::ThroughSolid { at, particles, count, solid, depth_m, .. }] = &events[..] else {
            panic!("{events:?}")
        };
        assert_eq!((at.0, particles.as_slice(), *count, *solid, *depth_m), (3, &[0, 5][..], 2, 1, 0.04));
        // Reported once a run.
        let (counts, events) = watch.after_step(&model, &x, &[inside(5, 0.04)], (4, 0.04));
        assert_eq!((counts.deep_in_solids, events.len()), (1, 0));
    }
}
