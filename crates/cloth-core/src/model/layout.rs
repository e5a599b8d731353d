//! Where each panel's particles live in a model: grid panels' ranges, and
//! mesh panels' ranges with their edges and outlines.

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
