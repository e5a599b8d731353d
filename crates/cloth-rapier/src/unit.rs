//! placeholder
/// placeholder
pub struct RapierUnit;
