//! Domain decomposition over MPI ranks: an exact, factor-once substructuring solver.
//!
//! `split` and `condense` are pure (testable without MPI); `comm` is the only module
//! that calls MPI.
//!
//! ## Scheme
//! Rank 0 partitions the mesh (METIS on the dual graph) and sends each rank its
//! subdomain. The boundary dofs B of a rank are its interface dofs and the dofs of the
//! contact nodes it owns. Each rank assembles A_s = K_s + r N'WN (+ r T'WT) on its own
//! elements and contact nodes, orders the interior by nested dissection and B last, and
//! factors once: the trailing block of the factor gives its Schur complement
//! S_s = L_BB L_BB' (`LocalFactor`), with no solve per boundary dof. Rank 0 sums the S_s
//! into the condensed matrix S on all of B, orders the contact dofs last and factors it
//! (dense Cholesky). A sweep needs (Nu, Tu) on the contact nodes only, and the contact
//! forces enter only on contact dofs, so one sweep is two triangular solves with the
//! trailing contact block of that factor (`Condensed::contact_response`). After
//! convergence, rank 0 solves for all of B once and every rank recovers its interior
//! with one sparse solve. Everything is a direct method: the iterates are those of the
//! one-rank solver up to round-off, whatever the rank count.
//!
//! ## Cost model (rank s: n_s dofs, b_s boundary dofs, nnz(L_s) factor entries;
//! n_B = sum of distinct boundary dofs, n_c = contact dofs (x and y), m = Anderson memory)
//!
//! | phase | flops | memory | messages |
//! | --- | --- | --- | --- |
//! | partition + scatter (rank 0) | O(n log n) | the mesh | one point-to-point per rank |
//! | assemble (each rank) | 42 per element entry | ~21 triplets per element | - |
//! | factor (each rank) | ND sparse Cholesky, O(n_s^1.5) in 2D, + b_s^3 / 3 for the dense trailing block | nnz(L_s) + b_s^2 | - |
//! | Schur S_s = L_BB L_BB' | b_s^3 | b_s^2 | one message of b_s^2 doubles to rank 0 |
//! | condensed factor (rank 0) | n_B^3 / 3 | n_B^2 | - |
//! | one sweep | rank 0: 2 n_c^2 (two triangular solves); each rank: O(own contact nodes) | - | MPI_Gatherv + MPI_Scatterv of the contact forces / displacements (n_c values in all), one MPI_Allreduce of 11 + m(m+1)/2 + m doubles |
//! | recovery | rank 0: 2 n_B^2; each rank: two sparse solves, 8 nnz(L_s) | - | one broadcast of n_B doubles |
//!
//! The sweep is independent of the mesh size beyond the contact boundary: against one
//! sparse forward+backward solve (4 nnz(L) flops, nnz(L) ~ 50-100 per dof in 2D) it is
//! cheaper by the ratio 4 nnz(L) / 2 n_c^2, e.g. 1.2M-node Hertz: n_c = 3.5k dofs,
//! nnz(L) ~ 2.5e8 -> 1e9 vs 2.5e7 flops. Measured figures are in summary.json
//! (`sweep_s` against `one_solve_s`) and in the notes of the performance issue.
//!
//! Limits: the condensed matrix S is dense and held by rank 0 (n_B^2 doubles): fine for
//! the few thousand boundary dofs of meshes of a few million nodes on tens of ranks; for
//! hundreds of ranks the interface part of S would need a distributed (or iterative,
//! BDDC-preconditioned) solve, which is not built.

pub mod comm;
pub mod condense;
pub mod split;
