//! The system matrix's sparsity pattern, built once per model from the
//! links, the elements and the pairs outside terms couple, and the tables
//! that index it: each particle's links with their slots in its row, the
//! elements' slots, each row's diagonal slot.

use super::links::{BendLink, Incidence, StretchLink};
use crate::elements::ElementSet;
use crate::seams::Stitch;
use cloth_linalg::BlockPattern;

/// The pattern and its per-row tables.
pub(crate) struct Sparsity {
    pub(crate) pattern: BlockPattern,
    /// `inc[inc_ptr[i]..inc_ptr[i + 1]]`: particle `i`'s links, in link order.
    pub(crate) inc_ptr: Vec<usize>,
    pub(crate) inc: Vec<Incidence>,
    /// Each row's diagonal block, by its position in the row.
    pub(crate) diag_local: Vec<u32>,
}

/// The particle pairs of the links, in link order: stretch links, bend
/// links, stitches.
pub(crate) fn link_pairs(stretch: &[StretchLink], bend: &[BendLink], stitches: &[Stitch]) -> Vec<(usize, usize)> {
    let stretch = stretch.iter().map(|l| (l.i as usize, l.j as usize));
    let bend = bend.iter().map(|l| (l.i as usize, l.j as usize));
    stretch.chain(bend).chain(stitches.iter().map(|s| (s.i as usize, s.j as usize))).collect()
}

impl Sparsity {
    /// The pattern of `n` particles coupled by `links` (in link order),
    /// `elements` (whose slot tables it fills) and `extra` pairs.
    pub(crate) fn of(n: usize, links: &[(usize, usize)], elements: &mut ElementSet, extra: &[[usize; 2]]) -> Self {
        let extra = extra.iter().map(|&[i, j]| (i, j));
        let pairs = links.iter().copied().chain(elements.pairs()).chain(extra);
        let pattern = BlockPattern::from_pairs(n, pairs).expect("links index existing particles");
        elements.index(n, &pattern);
        let mut counts = vec![0usize; n + 1];
        for &(i, j) in links {
            counts[i + 1] += 1;
            counts[j + 1] += 1;
        }
        for k in 0..n {
            counts[k + 1] += counts[k];
        }
        let inc_ptr = counts.clone();
        let mut fill = counts;
        let mut inc = vec![Incidence { link: 0, other: 0, first: true, slot: 0 }; inc_ptr[n]];
        for (link, &(i, j)) in links.iter().enumerate() {
            for (row, other, first) in [(i, j, true), (j, i, false)] {
                let slot = pattern.slot(row, other).expect("pair is in the pattern") - pattern.row_range(row).start;
                inc[fill[row]] = Incidence { link: link as u32, other: other as u32, first, slot: slot as u32 };
                fill[row] += 1;
            }
        }
        let diag_local = (0..n).map(|i| (pattern.diag_slot(i) - pattern.row_range(i).start) as u32).collect();
        Self { pattern, inc_ptr, inc, diag_local }
    }
}
