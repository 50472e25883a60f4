//! Output files: ParaView (`.vtu` pieces and a `.pvtu` index), CSV tables, the pictures
//! (`plot`), and the atomic writer that puts any of them on disk.
//!
//! The formatters are pure functions from data to bytes: they know neither MPI nor physics,
//! so each rank formats its own piece and the caller decides who writes what. Only
//! [`write_atomic`] and [`SharedFile`] touch the file system.
//!
//! ```no_run
//! # use contact_par::contact::Status;
//! # use contact_par::output::{contact_csv, write_atomic, ContactRow};
//! # use std::path::Path;
//! let rows = [ContactRow { x: 0.5, y: 0.0, u_n: -1e-3, u_t: 2e-4, p_n: 12.5, p_t: -0.3, gap: 0.0,
//!                    status: Status::Slip, w: 0.1 }];
//! write_atomic(Path::new("out/contact.csv"), contact_csv(&rows).as_bytes())?;
//! # Ok::<(), contact_par::error::Error>(())
//! ```

mod atomic;
pub mod blocks;
mod csv;
mod piece;
pub mod plot;
mod summary;
mod vtk;

pub use atomic::{write_atomic, SharedFile, Written};
pub use csv::{contact_csv, history_csv, nodes_csv, ContactRow};
pub use piece::{create_output_dir, element_stresses, vtu_file_name, PieceRows, SubdomainSolution};
pub use summary::{BodySummary, Gathered, PlotFacts, RankStats, RunFacts, PLOT_FILES};
pub use vtk::{file_ranges, pvtu_bytes, vtu_bytes, Piece, SubPiece, MAX_TRIANGLES_PER_FILE};
