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
//! of the spacing by default) or half the contact thickness, whichever is
//! wider ([`crate::ClothModel::stitch_closing_gap`]), and stays closed
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
use crate::FieldError;
use crate::GridPanel;
use serde::{Deserialize, Serialize};

/// One side of a seam: the nodes along an edge of a grid panel, or the
/// vertices along an outline edge of a pattern mesh, between two fractions
/// of the edge's length.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SeamSide {
    /// Grid panel index (default 0).
    #[serde(default)]
    pub panel: usize,
    /// The grid panel's edge the run lies on.
    #[serde(default)]
    pub edge: Option<Edge>,
    /// A pattern mesh (`[[meshes]]` index) instead of a grid panel.
    #[serde(default)]
    pub mesh: Option<usize>,
    /// The pattern's outline edge the run lies on (from outline corner `k`
    /// to the next). Two whole outline edges sewn together are split
    /// into as many pieces, the more of either's; an outline edge sewn
    /// whole to a grid edge takes the grid run's count.
    #[serde(default)]
    pub outline_edge: Option<usize>,
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

/// Where the particles of the panels and meshes a seam may name live:
/// the grid panels with their first particles' global indices, and the
/// mesh panels (their outline edges).
pub(crate) struct SeamTargets<'a> {
    pub panels: &'a [GridPanel],
    pub offsets: &'a [usize],
    pub meshes: &'a [crate::MeshRange],
}

impl SeamSide {
    /// A grid panel's edge, whole.
    pub fn grid(panel: usize, edge: Edge) -> Self {
        Self { panel, edge: Some(edge), mesh: None, outline_edge: None, range: whole_edge() }
    }

    /// A pattern mesh's outline edge, whole.
    pub fn outline(mesh: usize, outline_edge: usize) -> Self {
        Self { panel: 0, edge: None, mesh: Some(mesh), outline_edge: Some(outline_edge), range: whole_edge() }
    }
}

/// Resolves `seam` over `targets` into stitches. `tensile` is the
/// material's tensile stiffness, N/m.
pub(crate) fn stitches(seam: &SeamSpec, targets: &SeamTargets<'_>, tensile: f64) -> Result<Vec<Stitch>, FieldError> {
    let (a, spacing_a) = side_run(&seam.a, ["a.panel", "a.edge", "a.range", "a.mesh", "a.outline_edge"], targets)?;
    let (mut b, spacing_b) = side_run(&seam.b, ["b.panel", "b.edge", "b.range", "b.mesh", "b.outline_edge"], targets)?;
    if a.len() != b.len() {
        return Err(FieldError::new(
            "b.range",
            format!("runs {} nodes, a runs {}: a seam sews node to node", b.len(), a.len()),
        ));
    }
    if seam.reverse {
        b.reverse();
    }
    let k = seam.stiffness_n_m.unwrap_or(10.0 * tensile);
    if !(k.is_finite() && k > 0.0) {
        return Err(FieldError::new("stiffness_n_m", format!("must be finite and > 0, got {k}")));
    }
    let pull = seam.pull_n.unwrap_or(tensile * spacing_a.min(spacing_b));
    if !(pull.is_finite() && pull > 0.0) {
        return Err(FieldError::new("pull_n", format!("must be finite and > 0, got {pull}")));
    }
    let sewing = seam.sewing_pull_n.unwrap_or(pull / 4.0);
    if !(sewing.is_finite() && sewing > 0.0 && sewing <= pull) {
        return Err(FieldError::new(
            "sewing_pull_n",
            format!("must be finite, > 0 and at most pull_n ({pull} N), got {sewing}"),
        ));
    }
    let speed = seam.closing_speed_m_s.unwrap_or(0.5);
    if !(speed.is_finite() && speed > 0.0) {
        return Err(FieldError::new("closing_speed_m_s", format!("must be finite and > 0, got {speed}")));
    }
    let mut out = Vec::with_capacity(a.len());
    for (&i, &j) in a.iter().zip(&b) {
        if i == j {
            return Err(FieldError::new("b", format!("sews particle {i} to itself")));
        }
        out.push(Stitch { i, j, k, pull, sewing, closing_speed_m_s: speed });
    }
    Ok(out)
}

/// How many pieces each pattern mesh's outline edges must be split into
/// for the seams to sew node to node (`None`: the piece's own split): an
/// outline edge sewn whole to another takes the more pieces of the two,
/// one sewn whole to a grid run (any part of its edge) the run's. Sides
/// naming what does not exist are left to [`stitches`] to report.
pub(crate) fn outline_pieces(
    seams: &[SeamSpec],
    panels: &[GridPanel],
    offsets: &[usize],
    meshes: &[crate::MeshPanel],
) -> Vec<Vec<Option<usize>>> {
    let mut forced: Vec<Vec<Option<usize>>> =
        meshes.iter().map(|m| vec![None; m.pattern.as_ref().map_or(0, |p| p.outline_m.len())]).collect();
    let whole = |side: &SeamSide| side.range == whole_edge();
    // A side's mesh outline edge and its natural pieces, when it is one.
    let outline = |side: &SeamSide| {
        let (mesh, k) = (side.mesh?, side.outline_edge?);
        let pieces = meshes.get(mesh)?.pattern.as_ref()?.natural_pieces(k)?;
        Some((mesh, k, pieces))
    };
    let targets = SeamTargets { panels, offsets, meshes: &[] };
    let grid_pieces = |side: &SeamSide| {
        let fields = ["", "", "", "", ""];
        side.mesh.is_none().then(|| side_run(side, fields, &targets).ok().map(|(run, _)| run.len() - 1)).flatten()
    };
    for seam in seams {
        // Only whole outline edges are split to fit; a grid run may be any part of its edge.
        let (a, b) = (outline(&seam.a).filter(|_| whole(&seam.a)), outline(&seam.b).filter(|_| whole(&seam.b)));
        let pieces = match (a, b) {
            (Some(a), Some(b)) => Some(a.2.max(b.2)),
            (Some(_), None) => grid_pieces(&seam.b),
            (None, Some(_)) => grid_pieces(&seam.a),
            (None, None) => None,
        };
        for (mesh, k, _) in [a, b].into_iter().flatten() {
            let slot = &mut forced[mesh][k];
            *slot = (*slot).max(pieces);
        }
    }
    forced
}

/// The run of a grid or mesh side: its global particle indices and the
/// spacing along it, m; errors name `fields` (the side's panel, edge,
/// range, mesh and outline-edge keys).
fn side_run(
    side: &SeamSide,
    fields: [&'static str; 5],
    targets: &SeamTargets<'_>,
) -> Result<(Vec<u32>, f64), FieldError> {
    let [panel_field, edge_field, range_field, mesh_field, outline_field] = fields;
    let [from, to] = side.range;
    if !(from.is_finite() && to.is_finite() && (0.0..=1.0).contains(&from) && (0.0..=1.0).contains(&to)) {
        return Err(FieldError::new(range_field, format!("must be two fractions in [0, 1], got {:?}", side.range)));
    }
    let Some(mesh) = side.mesh else {
        if side.outline_edge.is_some() {
            return Err(FieldError::new(outline_field, "is a pattern mesh's: give `mesh` too"));
        }
        let edge = side.edge.ok_or(FieldError::new(edge_field, "a grid panel's side needs its `edge`".to_string()))?;
        return run(side, edge, [panel_field, edge_field, range_field], targets.panels, targets.offsets);
    };
    if side.edge.is_some() || side.panel != 0 {
        return Err(FieldError::new(mesh_field, "a mesh's side takes `outline_edge`, not a grid's `panel` and `edge`"));
    }
    let range = targets.meshes.get(mesh).ok_or_else(|| {
        FieldError::new(mesh_field, format!("no mesh {mesh} (the scene has {})", targets.meshes.len()))
    })?;
    let k = side
        .outline_edge
        .ok_or(FieldError::new(outline_field, "a mesh's side needs its `outline_edge`".to_string()))?;
    let edges = &range.outline_edges;
    let (vertices, length) = edges.get(k).zip(range.outline_lengths.get(k)).ok_or_else(|| {
        FieldError::new(
            outline_field,
            format!("mesh {mesh} has {} outline edges (only pattern pieces have them)", edges.len()),
        )
    })?;
    if from > to {
        return Err(FieldError::new(
            range_field,
            format!("{:?}: from > to, which only a wrapped grid edge has", side.range),
        ));
    }
    // Outline vertices are evenly spaced along the edge (unless a line ends on it).
    let pieces = vertices.len() - 1;
    const TOL: f64 = 1e-9;
    let run: Vec<u32> = (0..=pieces)
        .filter(|&j| {
            let f = j as f64 / pieces as f64;
            f >= from - TOL && f <= to + TOL
        })
        .map(|j| vertices[j] + range.offset as u32)
        .collect();
    if run.is_empty() {
        return Err(FieldError::new(
            range_field,
            format!("{:?} holds no vertex of the edge ({} vertices)", side.range, pieces + 1),
        ));
    }
    Ok((run, length / pieces as f64))
}

/// A grid side's run: its nodes' global indices and the spacing, m.
fn run(
    side: &SeamSide,
    edge: Edge,
    [panel_field, edge_field, range_field]: [&'static str; 3],
    panels: &[GridPanel],
    offsets: &[usize],
) -> Result<(Vec<u32>, f64), FieldError> {
    let panel = panels.get(side.panel).ok_or_else(|| {
        FieldError::new(panel_field, format!("no panel {} (the scene has {})", side.panel, panels.len()))
    })?;
    let [from, to] = side.range;
    let [nx, ny] = panel.particles;
    let (dx, dy) = panel.spacing();
    let along_u = matches!(edge, Edge::JMin | Edge::JMax);
    if panel.wrap_u && !along_u {
        return Err(FieldError::new(edge_field, "a wrapped panel has no i edges: its columns close into a cylinder"));
    }
    let wrapped = panel.wrap_u;
    if from > to && !wrapped {
        return Err(FieldError::new(
            range_field,
            format!("{:?}: from > to runs across node 0, which only a wrapped edge has", side.range),
        ));
    }
    // Nodes along the edge, and the node count the edge's length spans
    // (a wrapped edge closes back onto node 0).
    let (count, span) = if along_u { (nx, if wrapped { nx } else { nx - 1 }) } else { (ny, ny - 1) };
    let fraction = |k: usize| k as f64 / span as f64;
    let node = |k: usize| -> u32 {
        let (i, j) = match edge {
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
        return Err(FieldError::new(
            range_field,
            format!("{:?} holds no node of the edge ({count} nodes)", side.range),
        ));
    }
    Ok((nodes, if along_u { dx } else { dy }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::topology::tests::panel;

    fn side(panel: usize, edge: Edge, range: [f64; 2]) -> SeamSide {
        SeamSide { range, ..SeamSide::grid(panel, edge) }
    }

    fn stitches(
        s: &SeamSpec,
        panels: &[GridPanel],
        offsets: &[usize],
        tensile: f64,
    ) -> Result<Vec<Stitch>, FieldError> {
        super::stitches(s, &SeamTargets { panels, offsets, meshes: &[] }, tensile)
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
            assert_eq!(e.path, field, "{e:?}");
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
