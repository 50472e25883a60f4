//! The interface system factored by MUMPS across the ranks (`--interface mumps`): each
//! rank hands MUMPS its subdomains' parts of the system (their condensed Schur blocks,
//! with global interface indices; MUMPS sums the parts), and per sweep their parts of the
//! right-hand side (summed likewise). MUMPS leaves each rank some entries of the
//! solution; a plan built once moves them to the ranks whose subdomains need them (one
//! all-to-all per sweep). No rank holds the whole system, right-hand side or solution.
//!
//! Only a team's leader calls MUMPS ([`Mpi::on_leader`]); the state below lives on it.

use crate::dd::comm::{Leader, Mpi};
use crate::error::{Error, Result};
use faer::Mat;
use std::collections::HashMap;

/// The rank that brokers interface dof `d` of `n` among `p` ranks: contiguous blocks.
fn directory(d: usize, n: usize, p: usize) -> usize {
    ((d as u128 * p as u128) / n.max(1) as u128).min(p as u128 - 1) as usize
}

/// Upper-triangle entries (global interface indices) of one subdomain's dense part.
pub fn upper_entries(index: &[usize], s: &Mat<f64>) -> Vec<(usize, usize, f64)> {
    let n = index.len();
    let mut out = Vec::with_capacity(n * (n + 1) / 2);
    for j in 0..n {
        for i in 0..n {
            let (gi, gj) = (index[i], index[j]);
            if gi <= gj {
                out.push((gi, gj, s[(i, j)]));
            }
        }
    }
    out
}

/// Where the solution entries go: built once per factor.
struct Plan {
    /// Per destination rank, positions in this rank's part of the MUMPS solution.
    send: Vec<Vec<usize>>,
    /// Per source rank, positions in `needs` of the values it sends.
    recv: Vec<Vec<usize>>,
}

/// The leader's state: the factor, its subdomains' interface dofs, the plan.
pub struct MumpsInterface {
    factor: mumps::SpdFactor,
    n: usize,
    /// Each member subdomain's global interface dofs, in its own order.
    members: Vec<Vec<usize>>,
    /// Their concatenation: the rows of the right-hand side this rank hands MUMPS.
    rows: Vec<usize>,
    /// The distinct dofs this rank's subdomains need, increasing.
    needs: Vec<usize>,
    plan: Option<Plan>,
}

impl MumpsInterface {
    /// Sums and factors the interface system (collective over the ranks, on leaders):
    /// `parts` are the members' (global interface dofs, dense condensed block).
    fn new(leader: &Leader, n: usize, parts: Vec<(Vec<usize>, Mat<f64>)>) -> Result<Self> {
        let mut entries = Vec::new();
        for (index, s) in &parts {
            entries.extend(upper_entries(index, s));
        }
        let factor = mumps::SpdFactor::new(leader.fortran_comm(), n, &entries)
            .map_err(|e| Error::Numerical(format!("interface system: {e}")))?;
        drop(entries);
        let members: Vec<Vec<usize>> = parts.into_iter().map(|(index, _)| index).collect();
        let rows = members.concat();
        let mut needs = rows.clone();
        needs.sort_unstable();
        needs.dedup();
        Ok(MumpsInterface {
            factor,
            n,
            members,
            rows,
            needs,
            plan: None,
        })
    }

    /// This rank's floating-point operations in the factorization.
    pub fn local_flops(&self) -> f64 {
        self.factor.local_flops()
    }

    /// Entries of the whole factor, over all ranks (INFOG(29)).
    pub fn factor_entries(&self) -> f64 {
        self.factor.factor_entries()
    }

    /// Solves with the members' right-hand sides `z` (each aligned with its interface
    /// dofs); returns each member's interface values (collective, on leaders).
    fn solve(&mut self, leader: &Leader, z: Vec<Vec<f64>>) -> Result<Vec<Vec<f64>>> {
        let values = z.concat();
        let (sol_rows, sol) = self
            .factor
            .solve(&self.rows, &values)
            .map_err(|e| Error::Numerical(format!("interface system: {e}")))?;
        let sol = sol.to_vec();
        if self.plan.is_none() {
            self.plan = Some(self.plan_for(leader, &sol_rows));
        }
        let plan = self.plan.as_ref().expect("built above");
        let send: Vec<Vec<f64>> = plan
            .send
            .iter()
            .map(|pos| pos.iter().map(|&k| sol[k]).collect())
            .collect();
        let received = leader.exchange(send);
        let mut at_needs = vec![0.0; self.needs.len()];
        for (from, vals) in received.iter().enumerate() {
            for (&k, &v) in plan.recv[from].iter().zip(vals) {
                at_needs[k] = v;
            }
        }
        Ok(self
            .members
            .iter()
            .map(|index| {
                index
                    .iter()
                    .map(|d| at_needs[self.needs.binary_search(d).expect("a needed dof")])
                    .collect()
            })
            .collect())
    }

    /// Which rank sends which solution entry to which (collective, on leaders): each
    /// rank tells the directory of each dof that it needs it, and the directory of each
    /// dof it holds that it holds it; the directories pair them up.
    fn plan_for(&self, leader: &Leader, held: &[usize]) -> Plan {
        let (p, n) = (leader.ranks(), self.n);
        let by_directory = |dofs: &[usize]| {
            let mut out = vec![Vec::new(); p];
            for &d in dofs {
                out[directory(d, n, p)].push(d as u64);
            }
            out
        };
        let needed_by = leader.exchange(by_directory(&self.needs));
        let held_by = leader.exchange(by_directory(held));
        // This rank as a directory: who holds each of its dofs.
        let mut holder: HashMap<u64, usize> = HashMap::new();
        for (h, dofs) in held_by.iter().enumerate() {
            for &d in dofs {
                holder.insert(d, h);
            }
        }
        let mut to_holder = vec![Vec::new(); p];
        let mut to_needer = vec![Vec::new(); p];
        for (q, dofs) in needed_by.iter().enumerate() {
            for &d in dofs {
                let h = holder[&d];
                to_holder[h].extend([d, q as u64]);
                to_needer[q].extend([d, h as u64]);
            }
        }
        let asked = leader.exchange(to_holder);
        let told = leader.exchange(to_needer);
        // As a holder: per needer, the positions of its dofs, in increasing dof order.
        let position: HashMap<u64, usize> = held
            .iter()
            .enumerate()
            .map(|(k, &d)| (d as u64, k))
            .collect();
        let mut send: Vec<Vec<(u64, usize)>> = vec![Vec::new(); p];
        for pairs in &asked {
            for pair in pairs.chunks_exact(2) {
                send[pair[1] as usize].push((pair[0], position[&pair[0]]));
            }
        }
        // As a needer: per holder, the dofs it will send, in the same order.
        let mut recv: Vec<Vec<u64>> = vec![Vec::new(); p];
        for pairs in &told {
            for pair in pairs.chunks_exact(2) {
                recv[pair[1] as usize].push(pair[0]);
            }
        }
        Plan {
            send: send
                .into_iter()
                .map(|mut v| {
                    v.sort_unstable();
                    v.into_iter().map(|(_, k)| k).collect()
                })
                .collect(),
            recv: recv
                .into_iter()
                .map(|mut v| {
                    v.sort_unstable();
                    v.into_iter()
                        .map(|d| {
                            self.needs
                                .binary_search(&(d as usize))
                                .expect("a needed dof")
                        })
                        .collect()
                })
                .collect(),
        }
    }
}

/// Builds the distributed interface factor (collective over subdomains): every
/// subdomain hands its interface dofs and condensed block; the leaders factor. Returns
/// the leader's state (`None` on members), this rank's factorization flops and the
/// whole factor's entries.
pub fn build(
    mpi: &Mpi,
    n: usize,
    index: Vec<usize>,
    s_local: Mat<f64>,
    slot: &mut Option<MumpsInterface>,
) -> Result<(f64, f64)> {
    let mut built: Option<Result<MumpsInterface>> = None;
    let flops = mpi.on_leader((index, s_local), |leader, parts| {
        let state = MumpsInterface::new(leader, n, parts);
        let flops = state
            .as_ref()
            .map_or(Err(()), |s| Ok((s.local_flops(), s.factor_entries())));
        let message = state.as_ref().err().map(|e| e.to_string());
        built = Some(state);
        (flops.ok(), message)
    });
    if let Some(state) = built {
        *slot = state.ok();
    }
    let result = match flops {
        (Some(f), _) => Ok(f),
        (None, message) => Err(Error::Numerical(
            message.unwrap_or_else(|| "interface system: MUMPS failed".into()),
        )),
    };
    // A MUMPS failure is every rank's (INFOG is global); one line says it.
    mpi.agree(result)
}

/// One solve (collective over subdomains): `z` is this subdomain's part of the
/// right-hand side; returns its interface values.
pub fn solve(mpi: &Mpi, z: &[f64], slot: &mut Option<MumpsInterface>) -> Result<Vec<f64>> {
    let me = mpi.rank % mpi.per_rank();
    let result = mpi.on_leader(z.to_vec(), |leader, parts| {
        let state = slot
            .as_mut()
            .expect("the leader holds the interface factor");
        state.solve(leader, parts).map_err(|e| e.to_string())
    });
    match result {
        Ok(mut all) => Ok(std::mem::take(&mut all[me])),
        // MUMPS fails on every rank at once (INFOG is global): the first says it, and
        // no extra reduction per sweep is needed to agree.
        Err(message) if mpi.rank == 0 => Err(Error::Numerical(message)),
        Err(_) => Err(Error::Silent(Error::Numerical(String::new()).exit_code())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directories_cover_every_rank_in_blocks() {
        let (n, p) = (10, 3);
        let dirs: Vec<usize> = (0..n).map(|d| directory(d, n, p)).collect();
        assert_eq!(dirs, vec![0, 0, 0, 0, 1, 1, 1, 2, 2, 2]);
        assert!(dirs.windows(2).all(|w| w[0] <= w[1]));
        assert_eq!(directory(0, 1, 4), 0);
    }

    #[test]
    fn upper_entries_keep_one_triangle_by_global_index() {
        // Local order 0, 1 is global 7, 3: the global upper triangle is (3, 7).
        let s = Mat::from_fn(2, 2, |i, j| [[4.0, 1.0], [1.0, 5.0]][i][j]);
        let mut e = upper_entries(&[7, 3], &s);
        e.sort_by_key(|a| (a.0, a.1));
        assert_eq!(e, vec![(3, 3, 5.0), (3, 7, 1.0), (7, 7, 4.0)]);
    }
}
