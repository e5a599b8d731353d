//! Seams: panels sewn together along their edges, as garment patterns are.
//!
//! A seam pairs the nodes of a run along one panel edge with those of a
//! run along another (or the same panel's other edge), node for node, and
//! joins each pair by a stitch ([`crate::laws::stitch`]): a thread of zero
//! rest length beside a dashpot `c (v_j - v_i)`. Panels laid out apart (a
//! strap above a shoulder, a skirt wider than the bodice it hangs from)
//! are drawn together during a settling phase, the way a garment tool
//! sews: while a stitch is open its pull is capped at a gentle `sewing`,
//! and against the dashpot it closes at about `sewing / c` (a constant
//! pull alone would fling the seam's light edge particles through each
//! other: in the linearised step an open stitch has no stiffness along
//! itself). A stitch is closed once its gap is within `pull / k` (a tenth
//! of the spacing by default), and stays closed
//! ([`crate::ClothState::stitches_closed`]): it catches, its pull rising
//! from `sewing` to `k d`, and its cap is the seam's strength `pull`, so
//! it opens again only under a load that would double the length of the
//! cloth's links; its dashpot grows with its cap
//! ([`Stitch::dashpot`]). (Closing only within the sewing law's own linear
//! range, `sewing / k`, left a strap's last stitches open for a second:
//! their load exceeded the sewing pull.) One cap for both
//! did not serve: at the seam's strength the one-piece's skirt, drawn
//! over the pelvis while it was sewn, stretched the bodice's lower rows to
//! 2.45 times their length; at a tenth of it the waist seam tore where the
//! walking hips caught it and the skirt tangled. A run of more nodes sewn
//! to a shorter edge gathers the cloth, as a gathered skirt is.
//!
//! A seam carries no bending: the cloth hinges freely along it (a real
//! seam's allowance stiffens it instead; documented in `docs/garments.md`).

use crate::Edge;
use crate::GridPanel;
use serde::{Deserialize, Serialize};

/// One side of a seam: the nodes along an edge of a panel between two
/// fractions of the edge's length.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SeamSide {
    /// Panel index.
    pub panel: usize,
    /// The edge the run lies on.
    pub edge: Edge,
    /// Part of the edge, `[from, to]` as fractions of its length (node `i`
    /// of an open edge of `n` nodes sits at `i / (n - 1)`, of a wrapped one
    /// at `i / n`); the run takes the nodes with `from <= f <= to` (to
    /// 1e-9), in increasing `f`. On a wrapped edge `from > to` runs across
    /// node 0: `f >= from`, then `f <= to`. Default `[0, 1]`: the whole edge.
    #[serde(default = "whole_edge")]
    pub range: [f64; 2],
}

fn whole_edge() -> [f64; 2] {
    [0.0, 1.0]
}

/// Two runs of nodes sewn together node for node.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SeamSpec {
    /// The first run.
    pub a: SeamSide,
    /// The second run (as many nodes as `a`).
    pub b: SeamSide,
    /// Pair `a`'s first node with `b`'s last (default false).
    #[serde(default)]
    pub reverse: bool,
    /// Stiffness of each closed stitch, N/m. Default: 10 x the material's
    /// `tensile_stiffness_n_m`.
    #[serde(default)]
    pub stiffness_n_m: Option<f64>,
    /// Strength of a closed stitch, N: the most it holds before it opens
    /// again. Default `E s`, the pull that doubles the length of a strip
    /// of spacing `s`, the finer of the two runs' spacings: a seam holds
    /// what the cloth can.
    #[serde(default)]
    pub pull_n: Option<f64>,
    /// Pull of a stitch while it is open, N (at most `pull_n`). Default a
    /// quarter of `pull_n` (at a third and at half of it the one-piece at
    /// Table-1 resolution tangled on the thigh and blew up; at all of it
    /// the bodice stretched to 2.45 while sewn).
    #[serde(default)]
    pub sewing_pull_n: Option<f64>,
    /// Speed at which an open stitch closes, m/s (its dashpot is
    /// `sewing_pull_n / speed` while open, `pull_n / speed` once closed).
    /// Default 0.5.
    #[serde(default)]
    pub closing_speed_m_s: Option<f64>,
}

/// One stitch of a resolved seam.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stitch {
    /// First particle (global index).
    pub i: u32,
    /// Second particle.
    pub j: u32,
    /// Stiffness once closed, N/m.
    pub k: f64,
    /// Strength once closed, N.
    pub pull: f64,
    /// Pull while open, N.
    pub sewing: f64,
    /// Speed at which it closes while open, m/s.
    pub closing_speed_m_s: f64,
}

impl Stitch {
    /// The cap of its pull, N: the seam's strength once closed, the
    /// sewing pull while open.
    pub fn cap(&self, closed: bool) -> f64 {
        if closed { self.pull } else { self.sewing }
    }

    /// Its dashpot on the pair's relative velocity, N s/m: the cap over the
    /// closing speed, so an open stitch closes at that speed and a closed
    /// one damps as strongly as it holds (with the sewing pull's dashpot
    /// alone the sewn garments' straps stretched further as they walked).
    pub fn dashpot(&self, closed: bool) -> f64 {
        self.cap(closed) / self.closing_speed_m_s
    }
}

/// Why a seam is invalid: the field (below `seams[k]`) and the reason.
pub(crate) type SeamError = (&'static str, String);

/// Resolves `seam` over `panels` (with their first particles' global
/// indices `offsets`) into stitches. `tensile` is the material's tensile
/// stiffness, N/m.
pub(crate) fn stitches(
    seam: &SeamSpec,
    panels: &[GridPanel],
    offsets: &[usize],
    tensile: f64,
) -> Result<Vec<Stitch>, SeamError> {
    let (a, spacing_a) = run(&seam.a, ["a.panel", "a.edge", "a.range"], panels, offsets)?;
    let (mut b, spacing_b) = run(&seam.b, ["b.panel", "b.edge", "b.range"], panels, offsets)?;
    if a.len() != b.len() {
        return Err(("b.range", format!("runs {} nodes, a runs {}: a seam sews node to node", b.len(), a.len())));
    }
    if seam.reverse {
        b.reverse();
    }
    let k = seam.stiffness_n_m.unwrap_or(10.0 * tensile);
    if !(k.is_finite() && k > 0.0) {
        return Err(("stiffness_n_m", format!("must be finite and > 0, got {k}")));
    }
    let pull = seam.pull_n.unwrap_or(tensile * spacing_a.min(spacing_b));
    if !(pull.is_finite() && pull > 0.0) {
        return Err(("pull_n", format!("must be finite and > 0, got {pull}")));
    }
    let sewing = seam.sewing_pull_n.unwrap_or(pull / 4.0);
    if !(sewing.is_finite() && sewing > 0.0 && sewing <= pull) {
        return Err(("sewing_pull_n", format!("must be finite, > 0 and at most pull_n ({pull} N), got {sewing}")));
    }
    let speed = seam.closing_speed_m_s.unwrap_or(0.5);
    if !(speed.is_finite() && speed > 0.0) {
        return Err(("closing_speed_m_s", format!("must be finite and > 0, got {speed}")));
    }
    let mut out = Vec::with_capacity(a.len());
    for (&i, &j) in a.iter().zip(&b) {
        if i == j {
            return Err(("b", format!("sews particle {i} to itself")));
        }
        out.push(Stitch { i, j, k, pull, sewing, closing_speed_m_s: speed });
    }
    Ok(out)
}

/// The run's global particle indices and the spacing along it, m; errors
/// name `fields` (the side's panel, edge and range keys).
fn run(
    side: &SeamSide,
    [panel_field, edge_field, range_field]: [&'static str; 3],
    panels: &[GridPanel],
    offsets: &[usize],
) -> Result<(Vec<u32>, f64), SeamError> {
    let panel = panels
        .get(side.panel)
        .ok_or_else(|| (panel_field, format!("no panel {} (the scene has {})", side.panel, panels.len())))?;
    let [from, to] = side.range;
    if !(from.is_finite() && to.is_finite() && (0.0..=1.0).contains(&from) && (0.0..=1.0).contains(&to)) {
        return Err((range_field, format!("must be two fractions in [0, 1], got {:?}", side.range)));
    }
    let [nx, ny] = panel.particles;
    let (dx, dy) = panel.spacing();
    let along_u = matches!(side.edge, Edge::JMin | Edge::JMax);
    if panel.wrap_u && !along_u {
        return Err((edge_field, "a wrapped panel has no i edges: its columns close into a cylinder".into()));
    }
    let wrapped = panel.wrap_u;
    if from > to && !wrapped {
        return Err((
            range_field,
            format!("{:?}: from > to runs across node 0, which only a wrapped edge has", side.range),
        ));
    }
    // Nodes along the edge, and the node count the edge's length spans
    // (a wrapped edge closes back onto node 0).
    let (count, span) = if along_u { (nx, if wrapped { nx } else { nx - 1 }) } else { (ny, ny - 1) };
    let fraction = |k: usize| k as f64 / span as f64;
    let node = |k: usize| -> u32 {
        let (i, j) = match side.edge {
            Edge::JMin => (k, 0),
            Edge::JMax => (k, ny - 1),
            Edge::IMin => (0, k),
            Edge::IMax => (nx - 1, k),
        };
        (offsets[side.panel] + panel.index(i, j)) as u32
    };
    const TOL: f64 = 1e-9;
    let inside = |f: f64, lo: f64, hi: f64| f >= lo - TOL && f <= hi + TOL;
    let nodes: Vec<u32> = if from <= to {
        (0..count).filter(|&k| inside(fraction(k), from, to)).map(node).collect()
    } else {
        let tail = (0..count).filter(|&k| inside(fraction(k), from, 1.0));
        tail.chain((0..count).filter(|&k| inside(fraction(k), 0.0, to))).map(node).collect()
    };
    if nodes.is_empty() {
        return Err((range_field, format!("{:?} holds no node of the edge ({count} nodes)", side.range)));
    }
    Ok((nodes, if along_u { dx } else { dy }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::topology::tests::panel;

    fn side(panel: usize, edge: Edge, range: [f64; 2]) -> SeamSide {
        SeamSide { panel, edge, range }
    }

    fn seam(a: SeamSide, b: SeamSide) -> SeamSpec {
        SeamSpec {
            a,
            b,
            reverse: false,
            stiffness_n_m: None,
            pull_n: None,
            sewing_pull_n: None,
            closing_speed_m_s: None,
        }
    }

    #[test]
    fn runs_pair_node_for_node_in_order() {
        let panels = [panel(5, 3, false), panel(10, 4, true)];
        let offsets = [0, 15];
        // Panel 0's top edge (j = 2: nodes 10..14) to the cylinder's bottom nodes 8, 9, 0, 1, 2
        // (fractions 0.8, 0.9, 0, 0.1, 0.2: across node 0).
        let s = seam(side(0, Edge::JMax, [0.0, 1.0]), side(1, Edge::JMin, [0.8, 0.2]));
        let st = stitches(&s, &panels, &offsets, 200.0).unwrap();
        let pairs: Vec<(u32, u32)> = st.iter().map(|s| (s.i, s.j)).collect();
        assert_eq!(pairs, vec![(10, 23), (11, 24), (12, 15), (13, 16), (14, 17)]);
        assert_eq!(st[0].k, 2000.0);
        // E s with the finer spacing along the runs: the cylinder's 0.1 m
        // (panel 0's is 0.25 m); sewing at a quarter of it.
        assert!((st[0].pull - 200.0 * 0.1).abs() < 1e-13);
        assert_eq!(st[0].sewing, st[0].pull / 4.0);
        let r = SeamSpec { reverse: true, ..s };
        assert_eq!(stitches(&r, &panels, &offsets, 200.0).unwrap()[0].j, 17);
        // An i edge, part of it.
        let s = seam(side(0, Edge::IMax, [0.5, 1.0]), side(0, Edge::IMin, [0.5, 1.0]));
        let pairs: Vec<(u32, u32)> = stitches(&s, &panels, &offsets, 1.0).unwrap().iter().map(|s| (s.i, s.j)).collect();
        assert_eq!(pairs, vec![(9, 5), (14, 10)]);
    }

    #[test]
    fn bad_seams_name_the_field() {
        let panels = [panel(5, 3, false), panel(10, 4, true)];
        let offsets = [0, 15];
        let check = |s: SeamSpec, field: &str| {
            let e = stitches(&s, &panels, &offsets, 200.0).unwrap_err();
            assert_eq!(e.0, field, "{e:?}");
        };
        check(seam(side(0, Edge::JMax, [0.0, 1.0]), side(1, Edge::JMin, [0.0, 1.0])), "b.range");
        check(seam(side(2, Edge::JMax, [0.0, 1.0]), side(1, Edge::JMin, [0.0, 1.0])), "a.panel");
        check(seam(side(0, Edge::JMax, [0.7, 0.2]), side(1, Edge::JMin, [0.0, 1.0])), "a.range");
        check(seam(side(0, Edge::JMax, [0.0, f64::NAN]), side(1, Edge::JMin, [0.0, 1.0])), "a.range");
        check(seam(side(0, Edge::JMax, [0.3, 0.4]), side(1, Edge::JMin, [0.0, 1.0])), "a.range");
        check(seam(side(0, Edge::IMin, [0.0, 1.0]), side(1, Edge::IMin, [0.0, 1.0])), "b.edge");
        check(seam(side(0, Edge::IMin, [0.0, 1.0]), side(0, Edge::IMin, [0.0, 1.0])), "b");
        let s = seam(side(0, Edge::IMin, [0.0, 1.0]), side(0, Edge::IMax, [0.0, 1.0]));
        check(SeamSpec { stiffness_n_m: Some(-1.0), ..s }, "stiffness_n_m");
        check(SeamSpec { pull_n: Some(f64::INFINITY), ..s }, "pull_n");
        check(SeamSpec { closing_speed_m_s: Some(0.0), ..s }, "closing_speed_m_s");
        check(SeamSpec { sewing_pull_n: Some(0.0), ..s }, "sewing_pull_n");
        check(SeamSpec { pull_n: Some(1.0), sewing_pull_n: Some(1.5), ..s }, "sewing_pull_n");
    }
}
