//! `nodes.csv` written by the ranks that hold its rows, no rank holding the whole mesh:
//! rank q is given the rows of the global node ids in `[block_start(q), block_start(q +
//! 1))`, formats them (the header too on the first rank), and writes the text at the sum
//! of the lengths of the blocks before its own. The file is the one a single writer
//! makes of all rows in id order, byte for byte.

use super::csv::{push_node_rows, NODES_HEADER};
use std::ops::Range;

/// The first id of rank `q`'s block among `n` ids split over `ranks` ranks.
pub fn block_start(q: usize, n: usize, ranks: usize) -> usize {
    ((q as u128 * n as u128) / ranks as u128) as usize
}

/// The ids of rank `q`'s block.
pub fn block(q: usize, n: usize, ranks: usize) -> Range<usize> {
    block_start(q, n, ranks)..block_start(q + 1, n, ranks)
}

/// The rank whose block holds `id`.
pub fn block_of(id: usize, n: usize, ranks: usize) -> usize {
    // The estimate is the block or its neighbour (the blocks' starts are floors).
    let mut q = ((id as u128 * ranks as u128) / n.max(1) as u128) as usize;
    q = q.min(ranks - 1);
    while q + 1 < ranks && block_start(q + 1, n, ranks) <= id {
        q += 1;
    }
    while q > 0 && block_start(q, n, ranks) > id {
        q -= 1;
    }
    q
}

/// The text of rank `q`'s block, given its rows (global id, x, y, ux, uy) in any order.
/// Every id of the block must come exactly once; the error names the first that does
/// not (an internal error of the caller).
pub fn block_text(
    q: usize,
    n: usize,
    ranks: usize,
    rows: impl IntoIterator<Item = (usize, [f64; 4])>,
) -> Result<String, String> {
    let ids = block(q, n, ranks);
    let mut xy = vec![[f64::NAN; 2]; ids.len()];
    let mut u = vec![[f64::NAN; 2]; ids.len()];
    let mut seen = vec![false; ids.len()];
    for (id, [x, y, ux, uy]) in rows {
        if !ids.contains(&id) {
            return Err(format!("node {id} sent to the block {ids:?}"));
        }
        let k = id - ids.start;
        if std::mem::replace(&mut seen[k], true) {
            return Err(format!("node {id} written twice"));
        }
        xy[k] = [x, y];
        u[k] = [ux, uy];
    }
    if let Some(k) = seen.iter().position(|s| !s) {
        return Err(format!("node {} written by no subdomain", ids.start + k));
    }
    let mut out = String::with_capacity(48 * (ids.len() + 1));
    if q == 0 {
        out.push_str(NODES_HEADER);
    }
    push_node_rows(&mut out, &xy, &u);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::nodes_csv;

    #[test]
    fn every_id_has_one_block_and_the_blocks_tile_the_ids() {
        for n in [0, 1, 5, 17, 1000] {
            for ranks in 1..=9 {
                let mut next = 0;
                for q in 0..ranks {
                    let b = block(q, n, ranks);
                    assert_eq!(b.start, next);
                    next = b.end;
                    for id in b {
                        assert_eq!(block_of(id, n, ranks), q, "id {id} of {n} on {ranks}");
                    }
                }
                assert_eq!(next, n);
            }
        }
    }

    #[test]
    fn the_blocks_put_together_are_the_single_writers_file() {
        let n = 23;
        let xy: Vec<[f64; 2]> = (0..n)
            .map(|i| [i as f64 * 0.1, 1.0 / (i as f64 + 3.0)])
            .collect();
        let u: Vec<[f64; 2]> = (0..n).map(|i| [-1e-7 * i as f64, 2.5e-3]).collect();
        let whole = nodes_csv(&xy, &u);
        for ranks in [1, 2, 3, 7, 30] {
            // Rows reach their block in no particular order.
            let rows: Vec<(usize, [f64; 4])> = (0..n)
                .rev()
                .map(|i| (i, [xy[i][0], xy[i][1], u[i][0], u[i][1]]))
                .collect();
            let text: String = (0..ranks)
                .map(|q| {
                    let mine = rows
                        .iter()
                        .copied()
                        .filter(|r| block_of(r.0, n, ranks) == q);
                    block_text(q, n, ranks, mine).unwrap()
                })
                .collect();
            assert_eq!(text, whole, "{ranks} ranks");
        }
    }

    #[test]
    fn a_missing_or_doubled_row_is_an_error() {
        let row = |i: usize| (i, [0.0; 4]);
        assert!(block_text(0, 3, 1, [row(0), row(2)])
            .unwrap_err()
            .contains("node 1"));
        assert!(block_text(0, 2, 1, [row(0), row(0), row(1)])
            .unwrap_err()
            .contains("twice"));
        assert!(block_text(0, 4, 2, [row(0), row(3)])
            .unwrap_err()
            .contains("node 3"));
    }
}
