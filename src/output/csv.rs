//! Plain CSV tables. Every f64 is printed with `{}`, Rust's shortest text that parses back to
//! the same bits: users join these tables with others on node coordinates, so a rounded
//! coordinate would silently break the match.

use std::fmt::Write;

use crate::contact::{Status, Sweep};
use serde::{Deserialize, Serialize};

/// One node of the contact boundary: its row of `contact.csv` (the first seven fields),
/// and what the summary counts of it. Each subdomain sends its rows to the first one.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ContactRow {
    pub x: f64,
    pub y: f64,
    /// Normal displacement.
    pub u_n: f64,
    /// Tangential displacement.
    pub u_t: f64,
    /// Normal contact pressure.
    pub p_n: f64,
    /// Tangential traction.
    pub p_t: f64,
    pub gap: f64,
    #[serde(with = "status_code")]
    pub status: Status,
    /// The node's contact weight (its share of the boundary's length).
    pub w: f64,
    /// Its contact (the case's `[[contact]]` entry, from 0: contact.csv's last column)
    /// and its position along that contact's obstacle (for the pictures).
    pub pair: u32,
    pub s: f64,
    /// The node's unit normal (obstacle -> body).
    pub normal: [f64; 2],
    /// The share of the node's contact force that its master nodes take back (the sum
    /// of its mortar row's coefficients, `contact::mortar`: one); 0 against an obstacle.
    pub to_master: f64,
    /// The node's separate part of the mesh and its master nodes' part
    /// (`problem::NO_PART` against an obstacle, or both where not known).
    pub part: [u32; 2],
}

/// A contact status as one byte on the wire.
mod status_code {
    use crate::contact::Status;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(s: &Status, ser: S) -> Result<S::Ok, S::Error> {
        (*s as u8).serialize(ser)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(de: D) -> Result<Status, D::Error> {
        match u8::deserialize(de)? {
            0 => Ok(Status::Free),
            1 => Ok(Status::Stick),
            2 => Ok(Status::Slip),
            3 => Ok(Status::Contact),
            k => Err(serde::de::Error::custom(format!("no contact status {k}"))),
        }
    }
}

/// `contact.csv`: header `x,y,u_n,u_t,p_n,p_t,gap,contact`, rows sorted by x then y;
/// `contact` is the index of the node's contact (the case's `[[contact]]` entry, from 0).
///
/// The order is fixed by the coordinates, not by node numbering or rank, so the file is the
/// same whatever the partition and two runs can be diffed line by line. `f64::total_cmp`
/// gives a total order even for -0.0 (before 0.0) and NaN (last).
pub fn contact_csv(rows: &[ContactRow]) -> String {
    let mut sorted: Vec<&ContactRow> = rows.iter().collect();
    sorted.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    let mut out = String::with_capacity(64 * (rows.len() + 1));
    out.push_str("x,y,u_n,u_t,p_n,p_t,gap,contact\n");
    for r in sorted {
        // Writing into a String cannot fail.
        let _ = writeln!(
            out,
            "{},{},{},{},{},{},{},{}",
            r.x, r.y, r.u_n, r.u_t, r.p_n, r.p_t, r.gap, r.pair
        );
    }
    out
}

/// Node coordinates and displacements: header `x,y,ux,uy`, one row per node in the given
/// order (the caller's numbering is the row number).
///
/// # Panics
/// If `nodes` and `u` differ in length: that is a bug in the caller, not a user error.
pub fn nodes_csv(nodes: &[[f64; 2]], u: &[[f64; 2]]) -> String {
    assert_eq!(
        nodes.len(),
        u.len(),
        "nodes_csv: {} nodes but {} displacements",
        nodes.len(),
        u.len()
    );
    let mut out = String::with_capacity(48 * (nodes.len() + 1));
    out.push_str(NODES_HEADER);
    push_node_rows(&mut out, nodes, u);
    out
}

/// The first line of `nodes.csv`.
pub const NODES_HEADER: &str = "x,y,ux,uy\n";

/// Appends the rows of `nodes.csv` for `nodes` and their displacements `u`.
pub fn push_node_rows(out: &mut String, nodes: &[[f64; 2]], u: &[[f64; 2]]) {
    for (p, d) in nodes.iter().zip(u) {
        let _ = writeln!(out, "{},{},{},{}", p[0], p[1], d[0], d[1]);
    }
}

/// The header of `history.csv`.
pub const HISTORY_HEADER: &str = "iteration,error_estimate,pressure_change,traction_change,displacement_change,contraction,active_nodes,slip_nodes,changed_nodes,uncertain_nodes,stiff_directions,soft_directions,retunes,refused_accelerations,roundoff_floor";

/// `history.csv`: `HISTORY_HEADER`, one row per sweep in the given order (the other
/// fields of [`Sweep`] are not written).
pub fn history_csv(rows: &[Sweep]) -> String {
    let mut out = String::with_capacity(96 * (rows.len() + 1));
    out.push_str(HISTORY_HEADER);
    out.push('\n');
    for r in rows {
        let _ = writeln!(
            out,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            r.iter,
            r.error,
            r.pressure,
            r.traction,
            r.displacement,
            r.contraction,
            r.active,
            r.slip,
            r.changed,
            r.uncertain,
            r.stiff,
            r.soft,
            r.retunes,
            r.refused,
            r.roundoff
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(x: f64, y: f64, v: f64) -> ContactRow {
        ContactRow {
            x,
            y,
            u_n: v,
            u_t: v,
            p_n: v,
            p_t: v,
            gap: v,
            status: Status::Free,
            w: 0.0,
            pair: 0,
            s: x,
            normal: [0.0, 1.0],
            to_master: 0.0,
            part: [0, crate::problem::NO_PART],
        }
    }

    fn parse_table(csv: &str) -> (String, Vec<Vec<f64>>) {
        let mut lines = csv.lines();
        let header = lines.next().unwrap().to_string();
        let rows = lines
            .map(|l| l.split(',').map(|f| f.parse::<f64>().unwrap()).collect())
            .collect();
        (header, rows)
    }

    #[test]
    fn contact_header_is_exact() {
        assert_eq!(contact_csv(&[]), "x,y,u_n,u_t,p_n,p_t,gap,contact\n");
    }

    #[test]
    fn contact_rows_are_sorted_by_x_then_y() {
        let rows = [
            row(2.0, 0.0, 1.0),
            row(1.0, 5.0, 2.0),
            row(1.0, -3.0, 3.0),
            row(0.0, 0.0, 4.0),
            row(-0.0, 0.0, 5.0),
            row(1.0, 0.5, 6.0),
        ];
        let (_, parsed) = parse_table(&contact_csv(&rows));
        let keys: Vec<(f64, f64, f64)> = parsed.iter().map(|r| (r[0], r[1], r[2])).collect();
        assert_eq!(
            keys,
            vec![
                (-0.0, 0.0, 5.0),
                (0.0, 0.0, 4.0),
                (1.0, -3.0, 3.0),
                (1.0, 0.5, 6.0),
                (1.0, 5.0, 2.0),
                (2.0, 0.0, 1.0),
            ]
        );
        // The signed zero must survive: -0.0 sorts first and is printed as such.
        assert!(parsed[0][0].is_sign_negative());
        assert!(parsed[1][0].is_sign_positive());
    }

    #[test]
    fn contact_values_round_trip_exactly() {
        #[allow(clippy::excessive_precision)]
        let awkward = [
            0.1 + 0.2,
            1e-300,
            -0.0,
            123456789.123456789,
            5e-324,
            -1.7e308,
        ];
        // Every column, coordinates included, carries the awkward values.
        let mut rows: Vec<ContactRow> = awkward
            .iter()
            .enumerate()
            .map(|(i, &v)| ContactRow {
                x: v,
                y: -v,
                u_n: awkward[(i + 1) % awkward.len()],
                u_t: awkward[(i + 2) % awkward.len()],
                p_n: awkward[(i + 3) % awkward.len()],
                p_t: awkward[(i + 4) % awkward.len()],
                gap: awkward[(i + 5) % awkward.len()],
                status: Status::Slip,
                w: 1.0,
                ..row(0.0, 0.0, 0.0)
            })
            .collect();
        let (header, parsed) = parse_table(&contact_csv(&rows));
        assert_eq!(header, "x,y,u_n,u_t,p_n,p_t,gap,contact");
        rows.sort_by(|a, b| a.x.total_cmp(&b.x));
        assert_eq!(parsed.len(), rows.len());
        for (r, p) in rows.iter().zip(&parsed) {
            let want = [r.x, r.y, r.u_n, r.u_t, r.p_n, r.p_t, r.gap, r.pair as f64];
            let want: Vec<u64> = want.iter().map(|v| v.to_bits()).collect();
            let got: Vec<u64> = p.iter().map(|v| v.to_bits()).collect();
            assert_eq!(got, want);
        }
    }

    #[test]
    fn nodes_keep_the_given_order() {
        let nodes = [[1.0, 0.0], [0.0, 0.1 + 0.2]];
        let u = [[-0.0, 1e-300], [2.5, -3.0]];
        let csv = nodes_csv(&nodes, &u);
        let (header, parsed) = parse_table(&csv);
        assert_eq!(header, "x,y,ux,uy");
        let got: Vec<Vec<u64>> = parsed
            .iter()
            .map(|r| r.iter().map(|v| v.to_bits()).collect())
            .collect();
        let want: Vec<Vec<u64>> = nodes
            .iter()
            .zip(&u)
            .map(|(p, d)| {
                [p[0], p[1], d[0], d[1]]
                    .iter()
                    .map(|v| v.to_bits())
                    .collect()
            })
            .collect();
        assert_eq!(got, want);
    }

    #[test]
    #[should_panic(expected = "2 nodes but 1 displacements")]
    fn nodes_length_mismatch_panics() {
        nodes_csv(&[[0.0, 0.0], [1.0, 0.0]], &[[0.0, 0.0]]);
    }

    #[test]
    fn history_text_is_exact() {
        let rows = [
            Sweep {
                iter: 1,
                error: 0.5,
                pressure: 0.25,
                traction: 1e-300,
                displacement: 0.0,
                contraction: 0.0,
                active: 10,
                slip: 0,
                changed: 4,
                stiff: 0,
                soft: 0,
                mistuned: 7,
                mistuned_n: 2,
                unsettled: 0,
                uncertain: 3,
                pattern: 0,
                retunes: 0,
                refused: 0,
                roundoff: 0.0,
            },
            Sweep {
                iter: 2,
                error: 0.1 + 0.2,
                pressure: 0.1,
                traction: 0.0,
                displacement: 2.0,
                contraction: 0.5,
                active: 12,
                slip: 3,
                changed: 0,
                stiff: 12,
                soft: 5,
                mistuned: 0,
                mistuned_n: 0,
                unsettled: 0,
                uncertain: 0,
                pattern: 0,
                retunes: 1,
                refused: 2,
                roundoff: 3.1e-9,
            },
        ];
        let csv = history_csv(&rows);
        let mut lines = csv.lines();
        assert_eq!(lines.next(), Some(HISTORY_HEADER));
        assert_eq!(
            lines.next(),
            Some(format!("1,0.5,0.25,{},0,0,10,0,4,3,0,0,0,0,0", 1e-300).as_str())
        );
        assert_eq!(
            lines.next(),
            Some("2,0.30000000000000004,0.1,0,2,0.5,12,3,0,0,12,5,1,2,0.0000000031")
        );
        assert_eq!(lines.next(), None);
        assert!(csv.ends_with('\n'));
    }
}
