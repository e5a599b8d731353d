//! What the cloth touches: solids ([`colliders`]: scene descriptions and
//! their built form) and the detection and response of cloth-solid and
//! cloth-cloth contacts ([`contacts`]).

pub(crate) mod colliders;
pub(crate) mod contacts;

mod active_set;
pub mod contact_laws;
mod crossings;
mod detect;
mod impact_zones;
mod penalty;
mod projection;
mod response;
mod scratch;
mod self_collision;
mod stage;
mod surroundings;
mod tangles;
mod types;
