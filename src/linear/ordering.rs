//! Fill-reducing orderings of a subdomain's interior, computed on its node graph:
//! geometric nested dissection (`dissection.rs`), approximate minimum degree (faer) or
//! METIS nested dissection (`partition`).

use crate::error::{Error, Result};
use crate::fem::DofMap;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::SparseColMatRef;

use super::dissection::geometric_nested_dissection;

/// Fill-reducing ordering of a subdomain's interior.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum Ordering {
    /// Geometric nested dissection wherever the nodes' positions are known (every run),
    /// else the rule of the time before it: METIS nested dissection from
    /// [`ND_MIN_INTERIOR_DOFS`] interior dofs, minimum degree below. The default.
    ///
    /// On a 2D mesh of n nodes, nested dissection orders for O(n log n) fill and
    /// O(n^1.5) flops, the optimum (George): separators of O(sqrt n) nodes split the
    /// mesh recursively, and only the separators fill. Minimum degree is greedy and
    /// local; its factor is larger by a factor that grows with n, and with the
    /// boundary dofs held last its work doubles (an unstructured 101k-node block on one
    /// subdomain: 15.1 Gflop against 6.8 for METIS's nested dissection). METIS_NodeND
    /// costs several times minimum degree's ordering (0.69 s against 0.10 s there, 4.1
    /// s against 1.1 s for the geometric one on 520k-node subdomains), so it paid only
    /// on the largest subdomains. The geometric dissection orders as fast as minimum
    /// degree and fills within 0-15% of METIS (docs/performance.md, "Orderings").
    #[default]
    Auto,
    /// Approximate minimum degree (faer).
    Amd,
    /// METIS nested dissection on the node graph: the least fill, the slowest ordering.
    NestedDissection,
    /// Nested dissection from the nodes' positions ([`geometric_nested_dissection`]):
    /// straight cuts with the smallest separators, in a few linear passes per level.
    Geometric,
}

/// Interior dofs from which [`Ordering::Auto`] chooses METIS's nested dissection when
/// the nodes' positions are not known (see there).
pub const ND_MIN_INTERIOR_DOFS: usize = 1_000_000;

impl Ordering {
    /// The name of the `--ordering` option.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Amd => "amd",
            Self::NestedDissection => "nd",
            Self::Geometric => "gnd",
        }
    }

    /// The ordering actually used on a subdomain of `n_interior` interior dofs, its
    /// nodes' positions known (`placed`) or not.
    pub(crate) fn resolve(self, n_interior: usize, placed: bool) -> Self {
        match self {
            Self::Auto if placed => Self::Geometric,
            Self::Geometric if !placed => Self::Auto.resolve(n_interior, false),
            Self::Auto if n_interior >= ND_MIN_INTERIOR_DOFS => Self::NestedDissection,
            Self::Auto => Self::Amd,
            other => other,
        }
    }

    /// The permutation of the `n` equations of the LOWER triangle `a` (`perm[new] = old`)
    /// and its inverse that orders the first `n_interior` equations, the interior, by
    /// this ordering on their node graph (`groups`: see [`NodeGraph::new`]) and keeps
    /// the boundary equations last, in place. `positions[node]` places the nodes of
    /// `groups` for [`Ordering::Geometric`] (a resolved ordering: see
    /// [`Ordering::resolve`]). AMD is also the fallback should METIS fail.
    pub(crate) fn boundary_last(
        self,
        a: SparseColMatRef<'_, usize, f64>,
        n_interior: usize,
        groups: &[usize],
        positions: &[[f64; 2]],
    ) -> Result<(Vec<usize>, Vec<usize>)> {
        let mut graph = NodeGraph::new(a, n_interior, groups);
        let ng = graph.first_eq.len() - 1;
        let node_perm = match self {
            Ordering::Geometric => {
                let xy: Vec<[f64; 2]> = (0..ng)
                    .map(|g| positions[groups[graph.first_eq[g]]])
                    .collect();
                geometric_nested_dissection(&graph.xadj, &graph.adjncy, &xy)
            }
            Ordering::NestedDissection => {
                match partition::nested_dissection(&graph.xadj, &graph.adjncy) {
                    Ok(p) => p,
                    Err(_) => amd_node_order(&mut graph)?,
                }
            }
            _ => amd_node_order(&mut graph)?,
        };
        Ok(graph.boundary_last(&node_perm, a.nrows()))
    }
}

/// The graph between the nodes of the interior block of a matrix (in CSR form), the
/// input of the fill-reducing orderings.
pub struct NodeGraph {
    pub xadj: Vec<usize>,
    pub adjncy: Vec<usize>,
    /// First equation of each node (and the end), equations of a node consecutive.
    first_eq: Vec<usize>,
}

impl NodeGraph {
    /// From the LOWER triangle `a`, its first `n_interior` equations and `groups[eq]`,
    /// the node of each equation. A pair of nodes shows up in the columns of the node
    /// with the smaller equations; a marker per node skips repeats without sorting (two
    /// passes: count, then fill).
    pub fn new(a: SparseColMatRef<'_, usize, f64>, n_interior: usize, groups: &[usize]) -> Self {
        let mut group_of = vec![0usize; n_interior];
        let mut first_eq = Vec::new();
        for i in 0..n_interior {
            if i == 0 || groups[i] != groups[i - 1] {
                first_eq.push(i);
            }
            group_of[i] = first_eq.len() - 1;
        }
        let ng = first_eq.len();
        first_eq.push(n_interior);
        let mut marker = vec![usize::MAX; ng];
        let mut for_each_pair = |visit: &mut dyn FnMut(usize, usize)| {
            marker.fill(usize::MAX);
            for u in 0..ng {
                for j in first_eq[u]..first_eq[u + 1] {
                    for i in a.symbolic().row_idx_of_col(j) {
                        if i >= n_interior {
                            continue;
                        }
                        let v = group_of[i];
                        if v != u && marker[v] != u {
                            marker[v] = u;
                            visit(u, v);
                        }
                    }
                }
            }
        };
        let mut xadj = vec![0usize; ng + 1];
        for_each_pair(&mut |u, v| {
            xadj[u + 1] += 1;
            xadj[v + 1] += 1;
        });
        for v in 0..ng {
            xadj[v + 1] += xadj[v];
        }
        let mut next = xadj[..ng].to_vec();
        let mut adjncy = vec![0usize; xadj[ng]];
        for_each_pair(&mut |u, v| {
            adjncy[next[u]] = v;
            next[u] += 1;
            adjncy[next[v]] = u;
            next[v] += 1;
        });
        NodeGraph {
            xadj,
            adjncy,
            first_eq,
        }
    }

    /// Equation permutation (`perm[new] = old`) from a node permutation.
    pub fn expand(&self, node_perm: &[usize]) -> Vec<usize> {
        node_perm
            .iter()
            .flat_map(|&g| self.first_eq[g]..self.first_eq[g + 1])
            .collect()
    }

    /// The permutation of all `n` equations and its inverse: the interior in the order of
    /// `node_perm`, then the boundary equations (from the last interior one on) in place.
    fn boundary_last(&self, node_perm: &[usize], n: usize) -> (Vec<usize>, Vec<usize>) {
        let n_interior = self.first_eq[self.first_eq.len() - 1];
        let mut fwd = self.expand(node_perm);
        fwd.extend(n_interior..n);
        let mut inv = vec![0usize; n];
        for (new, &old) in fwd.iter().enumerate() {
            inv[old] = new;
        }
        (fwd, inv)
    }
}

/// Minimum degree (AMD) of a node graph (its rows sorted in place, as faer requires).
/// On the node graph rather than the dof graph: a quarter of the entries, and AMD finds
/// the dofs of a node indistinguishable anyway. Measured against the dof graph: factors
/// within 3% of the same size either way, the ordering 40-60% faster up to level 4
/// (hertz level 4, one rank: 0.46-0.72 s to 0.24-0.28 s), about as fast at level 5.
fn amd_node_order(graph: &mut NodeGraph) -> Result<Vec<usize>> {
    use faer::sparse::linalg::amd;
    use faer::sparse::SymbolicSparseColMatRef;
    let ng = graph.first_eq.len() - 1;
    for v in 0..ng {
        graph.adjncy[graph.xadj[v]..graph.xadj[v + 1]].sort_unstable();
    }
    let mut node_fwd = vec![0usize; ng];
    let mut node_inv = vec![0usize; ng];
    if ng > 0 {
        let pattern =
            SymbolicSparseColMatRef::new_checked(ng, ng, &graph.xadj, None, &graph.adjncy);
        let mut mem = MemBuffer::new(amd::order_scratch::<usize>(ng, graph.adjncy.len()));
        amd::order(
            &mut node_fwd,
            &mut node_inv,
            pattern,
            amd::Control::default(),
            MemStack::new(&mut mem),
        )
        .map_err(|e| Error::Numerical(format!("AMD ordering failed: {e:?}")))?;
    }
    Ok(node_fwd)
}

/// The node of each interior equation of a [`DofMap`] built by `DofMap::with_last`
/// (equations below `n_free - n_last`), for
/// [`LocalFactor::new`](crate::dd::local_factor::LocalFactor::new).
pub fn interior_groups(dofs: &DofMap) -> Vec<usize> {
    let mut groups = vec![usize::MAX; dofs.n_free];
    for (dof, eq) in dofs.eq.iter().enumerate() {
        if let Some(e) = eq {
            groups[*e] = dof / 2;
        }
    }
    groups
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_ordering_is_geometric_where_the_nodes_are_placed() {
        assert_eq!(Ordering::default(), Ordering::Auto);
        assert_eq!(Ordering::Auto.resolve(1000, true), Ordering::Geometric);
        assert_eq!(Ordering::Auto.resolve(1000, false), Ordering::Amd);
        assert_eq!(
            Ordering::Auto.resolve(ND_MIN_INTERIOR_DOFS, false),
            Ordering::NestedDissection
        );
        assert_eq!(Ordering::Geometric.resolve(1000, false), Ordering::Amd);
        assert_eq!(Ordering::Amd.resolve(usize::MAX, true), Ordering::Amd);
        assert_eq!(
            Ordering::NestedDissection.resolve(0, true),
            Ordering::NestedDissection
        );
    }

    #[test]
    fn subdomains_of_one_rank_order_at_the_same_time() {
        // A binary of this crate binds libmetis's rand/srand to the partition crate's
        // per-thread generators; without them the orderings of a rank's subdomains
        // would queue on one lock.
        assert!(partition::metis_runs_concurrently());
    }
}
