//! Aggregates for the multigrid on an unstructured graph (a triangle
//! mesh's edges), as the grid's `2 x 2` blocks are on a grid.

use crate::Buckets;

/// One level's aggregates of a graph and the graph of the aggregates.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GraphAggregation {
    /// Aggregate of each node, in `0..n_coarse`.
    pub coarse_of: Vec<u32>,
    /// Number of aggregates.
    pub n_coarse: usize,
    /// Pairs of aggregates joined by an edge, each once (smaller first).
    pub coarse_edges: Vec<[u32; 2]>,
}

/// Greedy aggregation of the `n` nodes joined by `edges`, in node order:
/// a node not yet taken starts an aggregate and takes its free neighbours,
/// nearest-numbered first, up to `size` nodes; a node left with no free
/// neighbour joins its smallest neighbouring aggregate (or stays alone
/// when it has no neighbour). Deterministic: the same graph gives the
/// same aggregates. Edges naming a node `>= n` are ignored by the caller's
/// contract (they never occur: the graph comes from a checked mesh).
pub fn graph_aggregation(n: usize, edges: &[[u32; 2]], size: usize) -> GraphAggregation {
    let size = size.max(2);
    // Neighbour lists, each sorted.
    let mut adj = Buckets::default();
    adj.rebuild(n, || edges.iter().flat_map(|&[a, b]| [(a as usize, b), (b as usize, a)]));
    adj.sort_each();
    const FREE: u32 = u32::MAX;
    let mut coarse_of = vec![FREE; n];
    let mut members: Vec<usize> = Vec::new();
    let mut lonely = Vec::new();
    for i in 0..n {
        if coarse_of[i] != FREE {
            continue;
        }
        let free: Vec<u32> = adj.of(i).iter().copied().filter(|&q| coarse_of[q as usize] == FREE).collect();
        if free.is_empty() && !adj.of(i).is_empty() {
            lonely.push(i);
            continue;
        }
        let a = members.len() as u32;
        coarse_of[i] = a;
        for &q in free.iter().take(size - 1) {
            coarse_of[q as usize] = a;
        }
        members.push(1 + free.len().min(size - 1));
    }
    for i in lonely {
        let to = adj
            .of(i)
            .iter()
            .map(|&q| coarse_of[q as usize])
            .filter(|&a| a != FREE)
            .min_by_key(|&a| (members[a as usize], a));
        let a = to.unwrap_or_else(|| {
            members.push(0);
            members.len() as u32 - 1
        });
        coarse_of[i] = a;
        members[a as usize] += 1;
    }
    let mut coarse_edges: Vec<[u32; 2]> = edges
        .iter()
        .map(|&[a, b]| (coarse_of[a as usize], coarse_of[b as usize]))
        .filter(|(a, b)| a != b)
        .map(|(a, b)| [a.min(b), a.max(b)])
        .collect();
    coarse_edges.sort_unstable();
    coarse_edges.dedup();
    GraphAggregation { coarse_of, n_coarse: members.len(), coarse_edges }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A strip of triangles: nodes 0..2k along two rows, zig-zag edges.
    fn strip(k: u32) -> Vec<[u32; 2]> {
        let mut e = Vec::new();
        for i in 0..k {
            let (a, b) = (2 * i, 2 * i + 1);
            e.push([a, b]);
            if i + 1 < k {
                e.extend([[a, a + 2], [b, b + 2], [b, a + 2]]);
            }
        }
        e
    }

    #[test]
    fn every_node_is_in_one_aggregate_of_at_most_a_few_neighbours() {
        let edges = strip(50);
        let g = graph_aggregation(100, &edges, 4);
        let mut count = vec![0; g.n_coarse];
        g.coarse_of.iter().for_each(|&a| count[a as usize] += 1);
        assert!(count.iter().all(|&c| (1..=5).contains(&c)), "{count:?}");
        // A coarse edge joins two different aggregates that touch.
        for &[a, b] in &g.coarse_edges {
            assert!(
                a < b
                    && edges.iter().any(|&[p, q]| {
                        let (x, y) = (g.coarse_of[p as usize], g.coarse_of[q as usize]);
                        (x, y) == (a, b) || (y, x) == (a, b)
                    })
            );
        }
        assert!(g.n_coarse <= 100 / 3, "{} aggregates of 100", g.n_coarse);
        assert_eq!(graph_aggregation(100, &edges, 4), g, "deterministic");
    }

    #[test]
    fn isolated_nodes_stay_alone() {
        let g = graph_aggregation(3, &[[0, 1]], 4);
        assert_eq!((g.coarse_of, g.n_coarse), (vec![0, 0, 1], 2));
    }
}
