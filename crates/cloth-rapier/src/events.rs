//! rapier's events of a coupled step, delivered once: a step that is
//! repeated (the iterated master, a monolithic step whose bodies rapier
//! moved) steps rapier several times, and only the accepted pass's
//! events may reach the user's `EventHandler`.

use rapier3d_f64::prelude::{
    ColliderHandle, ColliderSet, CollisionEvent, ContactPair, EventHandler, PhysicsWorld, RigidBodySet, SoftBodySet,
    SoftBodyTearEvent,
};
use std::sync::Mutex;

/// What one rapier step reported, in the order rapier reported it.
#[derive(Debug, Default)]
pub(crate) struct RecordedEvents {
    collisions: Mutex<Vec<CollisionEvent>>,
    /// `(collider1, collider2, total force magnitude in N)`.
    forces: Mutex<Vec<(ColliderHandle, ColliderHandle, f64)>>,
    tears: Mutex<Vec<SoftBodyTearEvent>>,
}

impl EventHandler for RecordedEvents {
    fn handle_collision_event(
        &self,
        _: &RigidBodySet,
        _: &ColliderSet,
        event: CollisionEvent,
        _: Option<&ContactPair>,
    ) {
        self.collisions.lock().expect("event buffer poisoned").push(event);
    }

    fn handle_contact_force_event(
        &self,
        _: f64,
        _: &RigidBodySet,
        _: &ColliderSet,
        pair: &ContactPair,
        total_force_magnitude: f64,
    ) {
        let entry = (pair.collider1, pair.collider2, total_force_magnitude);
        self.forces.lock().expect("event buffer poisoned").push(entry);
    }

    fn handle_soft_body_tear_event(&self, _: &SoftBodySet, event: &SoftBodyTearEvent) {
        self.tears.lock().expect("event buffer poisoned").push(event.clone());
    }
}

/// A buffer's contents, even if a handler panicked while holding it.
fn take<T>(m: Mutex<Vec<T>>) -> Vec<T> {
    m.into_inner().unwrap_or_else(|e| e.into_inner())
}

impl RecordedEvents {
    /// Hands the recorded events to `to`, with the world as the accepted
    /// step left it (contact pairs looked up in its narrow phase).
    pub(crate) fn deliver(self, world: &PhysicsWorld, to: &dyn EventHandler) {
        let (bodies, colliders, pairs) = (&world.bodies, &world.colliders, &world.narrow_phase);
        for event in take(self.collisions) {
            let pair = pairs.contact_pair(event.collider1(), event.collider2());
            to.handle_collision_event(bodies, colliders, event, pair);
        }
        for (c1, c2, magnitude) in take(self.forces) {
            if let Some(pair) = pairs.contact_pair(c1, c2) {
                to.handle_contact_force_event(world.integration_parameters.dt, bodies, colliders, pair, magnitude);
            }
        }
        for tear in take(self.tears) {
            to.handle_soft_body_tear_event(&world.soft_bodies, &tear);
        }
    }
}
