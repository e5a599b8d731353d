//! What the cloth touches: solids ([`colliders`]: scene descriptions and
//! their built form) and the detection and response of cloth-solid and
//! cloth-cloth contacts ([`contacts`]).

pub mod colliders;
pub mod contacts;
