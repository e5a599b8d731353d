//! placeholder
pub struct ClothUnit;
