//! One subdomain's share of the outputs: its `.vtu` files, written where it runs, and the
//! typed rows it sends the first subdomain for the gathered files (`summary`).

use super::summary::RankStats;
use super::{file_ranges, vtu_bytes, write_atomic, ContactRow, Piece, SubPiece, Written};
use crate::case::Case;
use crate::contact::Outcome;
use crate::dd::split::SubProblem;
use crate::error::{Error, Result};
use crate::fem::{self, Materials};
use crate::mesh::Mesh;
use crate::problem::NO_PART;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// What each subdomain sends the first one for the gathered files.
#[derive(Serialize, Deserialize)]
pub struct PieceRows {
    pub contact: Vec<ContactRow>,
    pub stats: RankStats,
    /// The subdomain's own files.
    pub written: Written,
}

/// One subdomain's solution: what its outputs are made of.
pub struct SubdomainSolution<'a> {
    pub subdomain: usize,
    pub case: &'a Case,
    pub sub: &'a SubProblem,
    /// Displacement of every node of the subdomain.
    pub u: &'a [[f64; 2]],
    pub outcome: &'a Outcome,
}

/// The `k`-th `.vtu` file of subdomain `subdomain`'s piece.
pub fn vtu_file_name(subdomain: usize, k: usize) -> String {
    format!("solution_{subdomain}_{k}.vtu")
}

/// Creates the output directory, with a message saying what to do should that fail.
pub fn create_output_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| {
        Error::Output(format!(
            "cannot create the output directory {}: {e}; choose another with --out",
            dir.display()
        ))
    })
}

/// Element stresses (sxx, syy, sxy, szz) and von Mises, in parallel.
pub fn element_stresses(
    materials: Materials<'_>,
    mesh: &Mesh,
    u: &[[f64; 2]],
) -> (Vec<[f64; 4]>, Vec<f64>) {
    let d: Vec<_> = materials
        .table()
        .iter()
        .map(fem::elasticity_matrix)
        .collect();
    let stress: Vec<[f64; 4]> = mesh
        .triangles
        .par_iter()
        .enumerate()
        .map(|(e, t)| {
            let (d, m) = (&d[materials.index(e)], materials.of(e));
            let p = [mesh.nodes[t[0]], mesh.nodes[t[1]], mesh.nodes[t[2]]];
            let ue = [
                u[t[0]][0], u[t[0]][1], u[t[1]][0], u[t[1]][1], u[t[2]][0], u[t[2]][1],
            ];
            let [sxx, syy, sxy] = fem::element_stress(&p, d, &ue);
            [sxx, syy, sxy, fem::stress_zz(m, sxx, syy)]
        })
        .collect();
    let vm = stress.par_iter().map(fem::von_mises).collect();
    (stress, vm)
}

impl SubdomainSolution<'_> {
    /// Writes the subdomain's `.vtu` files into `dir`; returns how many, and their bytes.
    pub fn write_vtu(&self, dir: &Path) -> Result<Written> {
        let (sub, o) = (self.sub, self.outcome);
        // Ghost master nodes (the tail of the nodes) belong to another piece.
        let n = sub.nodes.len() - sub.ghosts;
        let mesh = Mesh {
            nodes: sub.nodes[..n].to_vec(),
            triangles: sub.triangles.clone(),
            ..Default::default()
        };
        let table = self.case.material_table();
        let materials = Materials::PerElement {
            table: &table,
            body: &sub.body,
        };
        let (stress, vm) = element_stresses(materials, &mesh, self.u);
        let body: Vec<i32> = sub.body.iter().map(|&b| b as i32).collect();
        let mut pressure = vec![0.0; n];
        let mut traction = vec![0.0; n];
        let mut status = vec![-1i32; n];
        for (k, &node) in sub.contact_nodes.iter().enumerate() {
            pressure[node] = o.lambda[k];
            traction[node] = -o.mu[k] + 0.0;
            status[node] = o.status[k] as i32;
        }
        let rank_field = vec![self.subdomain as i32; sub.triangles.len()];
        let piece = Piece {
            nodes: &sub.nodes[..n],
            triangles: &sub.triangles,
            displacement: &self.u[..n],
            stress: &stress,
            von_mises: &vm,
            rank: &rank_field,
            body: &body,
            contact_pressure: &pressure,
            tangential_traction: &traction,
            contact_status: &status,
        };
        let ranges = file_ranges(&piece)?;
        // The files are independent: a rank with several threads encodes and writes
        // several files at once (each file's encoding and fsync run on one thread).
        let written: Vec<Written> = ranges
            .par_iter()
            .enumerate()
            .map(|(k, range)| {
                let part = SubPiece::new(&piece, range.clone());
                let bytes = vtu_bytes(&part.piece())?;
                write_atomic(&dir.join(vtu_file_name(self.subdomain, k)), &bytes)?;
                Ok(Written::file(bytes.len()))
            })
            .collect::<Result<_>>()?;
        Ok(written.into_iter().sum())
    }

    /// The rows of the subdomain's own contact nodes.
    pub fn contact_rows(&self) -> Vec<ContactRow> {
        let (sub, o) = (self.sub, self.outcome);
        sub.contact_nodes
            .iter()
            .enumerate()
            .map(|(k, &node)| {
                let x = sub.nodes[node];
                ContactRow {
                    x: x[0],
                    y: x[1],
                    u_n: o.un[k],
                    u_t: o.ut[k],
                    p_n: o.lambda[k],
                    p_t: -o.mu[k] + 0.0,
                    gap: sub.contact.g[k],
                    status: o.status[k],
                    w: sub.contact.w[k],
                    pair: sub.contact.pair[k],
                    s: sub.contact.s[k],
                    normal: sub.contact.normal[k],
                    to_master: (sub.contact_masters.get(k))
                        .map_or(0.0, |m| m.iter().map(|e| e.1).sum()),
                    part: (sub.contact.part.get(k)).map_or([NO_PART; 2], |&p| p),
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::Status;

    #[test]
    fn contact_rows_travel_with_their_status() {
        let rows: Vec<ContactRow> = [Status::Free, Status::Stick, Status::Slip]
            .into_iter()
            .map(|status| ContactRow {
                x: 1.0,
                y: -0.0,
                u_n: 2.0,
                u_t: 3.0,
                p_n: 4.0,
                p_t: 5.0,
                gap: 6.0,
                status,
                w: 0.5,
                pair: 2,
                s: -1.5,
                normal: [0.6, -0.8],
                to_master: 0.0,
                part: [1, NO_PART],
            })
            .collect();
        let bytes = crate::dd::comm::encode(&rows).unwrap();
        let back: Vec<ContactRow> = crate::dd::comm::decode(&bytes).unwrap();
        assert_eq!(back, rows);
        // A status byte (after the seven f64) past Slip is refused.
        let mut bad = crate::dd::comm::encode(&rows[0]).unwrap();
        bad[7 * 8] = 7;
        assert!(crate::dd::comm::decode::<ContactRow>(&bad).is_err());
    }
}
