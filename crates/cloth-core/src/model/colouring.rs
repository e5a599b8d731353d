//! The particles in colours for a vertex solver (Vertex Block Descent;
//! Chen, Macklin et al. 2024): no two particles of one colour share a
//! link, a stitch or an element, so the local steps of one colour do not
//! read each other's positions and run in parallel with the same result in
//! any order.

use crate::ClothModel;

/// A colour per particle, and the particles of each colour.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Colouring {
    colour: Vec<u32>,
    groups: Vec<Vec<u32>>,
}

impl Colouring {
    /// Greedy colouring of the model's coupling graph, the system
    /// matrix's pattern (two particles are coupled when a link, a stitch or
    /// an element joins them): in particle order, each particle takes the
    /// smallest colour that no coupled particle before it has. The same
    /// model always gets the same colours.
    pub(crate) fn of(model: &ClothModel) -> Self {
        let pattern = model.pattern();
        let n = pattern.n();
        let mut colour = vec![u32::MAX; n];
        // `taken[c] == i` marks colour c as used by a neighbour of i.
        let mut taken: Vec<usize> = Vec::new();
        for i in 0..n {
            for &j in pattern.row_cols(i) {
                let c = colour[j as usize];
                if c != u32::MAX {
                    if taken.len() <= c as usize {
                        taken.resize(c as usize + 1, usize::MAX);
                    }
                    taken[c as usize] = i;
                }
            }
            let free = taken.iter().position(|&t| t != i).unwrap_or(taken.len());
            colour[i] = free as u32;
        }
        let count = colour.iter().map(|&c| c as usize + 1).max().unwrap_or(0);
        let mut groups = vec![Vec::new(); count];
        for (i, &c) in colour.iter().enumerate() {
            groups[c as usize].push(i as u32);
        }
        Self { colour, groups }
    }

    /// The particles of each colour, ascending.
    pub(crate) fn groups(&self) -> &[Vec<u32>] {
        &self.groups
    }

    /// Particle `i`'s colour.
    #[cfg(test)]
    pub fn colour(&self, i: usize) -> u32 {
        self.colour[i]
    }

    /// Number of colours.
    pub(crate) fn len(&self) -> usize {
        self.groups.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Edge, GridPanel, ModelKind, SeamSide, SeamSpec};

    /// Whether no stored block of the pattern joins two particles of one
    /// colour, and the groups hold every particle once.
    fn valid(model: &ClothModel, c: &Colouring) -> bool {
        let pattern = model.pattern();
        let separated = (0..pattern.n())
            .all(|i| pattern.row_cols(i).iter().all(|&j| j as usize == i || c.colour(i) != c.colour(j as usize)));
        let mut seen: Vec<u32> = c.groups().iter().flatten().copied().collect();
        seen.sort_unstable();
        separated && seen == (0..pattern.n() as u32).collect::<Vec<_>>()
    }

    #[test]
    fn no_two_particles_of_a_colour_share_a_link_or_element() {
        for kind in [ModelKind::ChoiKo, ModelKind::Provot, ModelKind::Volino] {
            let model = ClothModel::builder().grid([21, 21], [1.0, 1.0]).kind(kind).bending().build().unwrap();
            let c = Colouring::of(&model);
            println!("{kind:?}: {} colours, {} blocks", c.len(), model.pattern().nnz_blocks());
            assert!(valid(&model, &c), "{kind:?}");
            // Measured 7 (Provot), 9 (Choi & Ko's triples and Volino's
            // bending triangles reach two particles away).
            assert!(c.len() <= 9, "{kind:?}: {} colours", c.len());
            assert_eq!(Colouring::of(&model), c, "the same colours every time");
        }
    }

    #[test]
    fn sewn_panels_are_coloured_across_their_seam() {
        let seam = |panel| SeamSide::grid(panel, Edge::IMax);
        let model = ClothModel::builder()
            .grid([5, 5], [0.2, 0.2])
            .panel(GridPanel::flat([5, 5], [0.2, 0.2]).origin([0.0, 0.0, 0.01]))
            .seam(SeamSpec {
                a: seam(0),
                b: seam(1),
                reverse: false,
                stiffness_n_m: None,
                pull_n: None,
                sewing_pull_n: None,
                closing_speed_m_s: None,
            })
            .build()
            .unwrap();
        let c = Colouring::of(&model);
        assert!(valid(&model, &c));
        assert_ne!(c.colour(4), c.colour(25 + 4), "the seam's first stitch joins two particles of one colour");
    }

    #[test]
    fn a_colouring_that_puts_neighbours_together_is_caught() {
        let model = ClothModel::builder().grid([4, 4], [0.3, 0.3]).build().unwrap();
        let one = Colouring { colour: vec![0; 16], groups: vec![(0..16).collect()] };
        assert!(!valid(&model, &one));
    }
}
