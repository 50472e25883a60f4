//! Domain decomposition over MPI ranks: an exact, factor-once substructuring solver.
//!
//! `split` and `condense` are pure (testable without MPI); `comm` is the only module
//! that calls MPI.
//!
//! ## Scheme
//! Rank 0 partitions the mesh (straight cuts, METIS where they leave a part in pieces:
//! `setup::from_file`) into P = ranks x K subdomains and sends each rank its K, or each
//! subdomain reads its own from a split directory (`setup::split_dir`); K =
//! `--subdomains-per-rank`, one per thread by default (`host::subdomains_per_rank`); a
//! rank runs each of its subdomains on a thread of its
//! own, and `comm` makes every collective one over subdomains. Below, "rank" stands for
//! "subdomain". The boundary dofs B_s of a rank are its contact dofs c_s (own contact
//! nodes that no other part touches) followed by its interface dofs g_s. Each rank
//! assembles A_s = K_s + r N'WN (+ r T'WT) on its own elements and contact nodes, shifts
//! the interface block by alpha I (floating subdomains), orders the interior by a
//! fill-reducing ordering and B_s last, and factors once. The dense trailing block of
//! the factor, L_BB = [L_cc 0; L_gc L_gg], is all the condensation needs
//! (`LocalFactor`): L_cc L_cc' = S_cc (the contact block of the subdomain's Schur
//! complement), L_gc L_cc' = S_gc, and L_gg L_gg' - alpha I is the subdomain's part of the
//! interface system once its contact dofs are eliminated. Rank 0 sums those parts into
//! the interface system S' (n_G interface dofs) and factors it: dense Cholesky, or a
//! sparse one (AMD ordering) when that needs at most half the work. With two
//! subdomains each part covers all of S', which is then dense; with many, each part
//! covers the interfaces of one subdomain only, and S' is a sum of overlapping dense
//! blocks whose sparse factor is cheaper. With `--interface mumps` the interface
//! system is instead assembled where its parts are and factored across the ranks
//! (`interface_mumps`).
//!
//! A contact dof belongs to one subdomain, so the contact dofs are eliminated rank by
//! rank, in parallel, and rank 0's dense work depends on the interface only. One sweep
//! (`dd::condense`): each rank forms b_s = g_s + C_s' f_s and runs a forward
//! elimination (a triangular solve with L_cc and a product with L_gc); rank 0 gathers
//! and sums the interface tails, solves with S' and scatters the interface values; each
//! rank back-substitutes and reads (Nu, Tu) on its own contact nodes. After convergence
//! every rank holds its boundary values and recovers its interior with one sparse
//! solve. Everything is a direct method: the iterates are those of the one-rank solver
//! up to round-off, whatever the rank count.
//!
//! ## Cost model (rank s: n_s dofs, c_s contact and g_s interface dofs, b_s = c_s + g_s,
//! nnz(L_s) factor entries; n_G = distinct interface dofs; m = Anderson memory)
//!
//! | phase | flops | memory | messages |
//! | --- | --- | --- | --- |
//! | partition + scatter (rank 0) | O(n log n) | the mesh | one point-to-point per rank |
//! | assemble (each rank) | ~160 per element (a stiffness row per vertex) | the matrix only (~8 lower entries per dof) | - |
//! | factor (each rank) | sparse Cholesky, O(n_s^1.5) in 2D with a good ordering, + b_s^3 / 3 for the dense trailing block | nnz(L_s) + b_s^2 | - |
//! | condensed loads (each rank) | the forward half of a sparse solve, 2 nnz(L_s), + b_s^2 | n_s | - |
//! | interface part L_gg L_gg' (each rank) | g_s^3 / 3 | g_s^2 | one message of g_s^2 doubles to rank 0 |
//! | interface factor (rank 0, on every core of its node's ranks while they sleep) | n_G^3 / 3 dense, or the sparse factor's (`interface_gflop` in summary.json) when at most half that | n_G^2, or nnz(L_G) | - |
//! | one sweep | each rank: 2 c_s^2 + 4 c_s g_s + O(own contact nodes); rank 0: 2 n_G^2, or 4 nnz(L_G) | - | MPI_Gatherv + MPI_Scatterv of the interface values (sum g_s values), and the loop's one MPI_Allreduce (its size: `contact::uzawa`, "Communication per sweep"); with one rank, no interface and only the allreduce |
//! | recovery | each rank: the backward half of a sparse solve, 2 nnz(L_s), + b_s^2 (the forward half is kept from the condensed loads) | - | - |
//!
//! The sweep is independent of the mesh size beyond the contact boundary and the
//! interface: against one sparse forward+backward solve (4 nnz(L) flops, nnz(L) ~ 50-150
//! per dof in 2D) it is cheaper by about 4 nnz(L) / (2 c^2 + 4 c g). Measured figures
//! are in summary.json (`sweep_s` against `one_solve_s`).
//!
//! Limits: with `--interface rank0` the interface system is held and factored by rank 0
//! (n_G^2 doubles dense, less sparse): fine for tens of ranks (n_G = 20 000 is 3.2 GB
//! dense); beyond, `--interface mumps` (the default from 16 subdomains) factors it
//! across the ranks (docs/cost-model.md).

pub mod comm;
pub mod condense;
pub mod full;
pub mod interface_mumps;
pub mod local_factor;
pub mod split;
pub mod step;
