//! The condensed linear step of one subdomain: its matrix assembled and factored with
//! the boundary dofs last, its contact dofs eliminated, the interface system summed and
//! factored on the first rank or across the ranks by MUMPS (`--interface`, see
//! [`crate::dd::interface_mumps`]), then per sweep one solve on the boundary system and,
//! after the loop, the interior recovered. Collective calls go through [`Mpi`].

use crate::contact::operators::{contact_blocks, mortar_blocks, ContactRowsGeometry};
use crate::contact::{LinearStep, Reduce};
use crate::dd::comm::Mpi;
use crate::dd::condense::{boundary_entries, ContactRows, InterfaceSystem, LocalResponse};
use crate::dd::interface_mumps::{self, MumpsInterface};
use crate::dd::local_factor::{InteriorForward, LocalFactor, SchurChange};
use crate::dd::split::SubProblem;
use crate::error::Result;
use crate::fem::{
    assemble_in_frames, from_frame, to_frame, AssemblyFigures, DofMap, Material, Materials,
};
use crate::host;
use crate::linear::{interior_groups, Ordering};
use crate::timer::{Phase, Timer};
use faer::Mat;

/// What every subdomain's step shares, from the set-up of the run.
#[derive(Clone, Copy)]
pub struct StepSetup<'a> {
    /// Each body's material (a subdomain's triangles carry their body).
    pub materials: &'a [Material],
    /// The augmentation every contact direction is assembled with.
    pub r: f64,
    /// Shift of the interface block of every local matrix (see `LocalFactor`).
    pub alpha: f64,
    pub frictional: bool,
    /// Interface dofs of the whole mesh (0: a single subdomain).
    pub n_interface: usize,
    pub ordering: Ordering,
    /// The interface system factored across the ranks by MUMPS (see
    /// [`crate::dd::interface_mumps`]), not on the first rank.
    pub interface_mumps: bool,
}

/// This subdomain's factored matrix, boundary dofs last.
pub struct LocalSystem {
    dofs: DofMap,
    pub factor: LocalFactor,
    /// Load + lifting of the prescribed dofs, per local equation.
    base: Vec<f64>,
}

impl LocalSystem {
    /// Assembles A_s = K_s + r N'WN (+ r T'WT) with the interface block shifted by alpha,
    /// then factors it (timed as [`Phase::Assemble`] and [`Phase::Factor`]); tells
    /// `assembled_figures` the matrix's size as soon as it is assembled.
    pub fn new(
        s: &StepSetup,
        sub: &SubProblem,
        timer: &Timer,
        assembled_figures: &dyn Fn(AssemblyFigures),
    ) -> Result<Self> {
        let assembled = timer.time(Phase::Assemble, || {
            let dofs = DofMap::with_last(&sub.fixed, &sub.boundary_dofs);
            let rr = vec![s.r; sub.contact_nodes.len()];
            let mut blocks = contact_blocks(
                &sub.contact_nodes,
                &obstacle_weights(sub),
                &rr,
                &rr,
                &sub.step_normals(),
                s.frictional,
            );
            let normals = sub.step_normals();
            let (same, cross) = mortar_blocks(&contact_rows(sub, &normals, s.frictional), &rr, &rr);
            blocks.extend(same);
            let mut g_nodes: Vec<usize> = sub.boundary_dofs[sub.n_contact_dofs..]
                .iter()
                .map(|d| d / 2)
                .collect();
            g_nodes.dedup();
            blocks.extend(
                g_nodes
                    .iter()
                    .map(|&v| (v, [[s.alpha, 0.0], [0.0, s.alpha]])),
            );
            let frames = sub.node_frames();
            let assembled = assemble_in_frames(
                &sub.nodes,
                &sub.triangles,
                Materials::PerElement {
                    table: s.materials,
                    body: &sub.body,
                },
                &dofs,
                &blocks,
                &frames,
            )?;
            let figures = assembled.figures();
            let mut base = assembled.lifting;
            let (coupling, lifting) = pair_entries(&cross, &sub.fixed);
            for (dof, v) in lifting {
                if let Some(i) = dofs.eq[dof] {
                    base[i] += v;
                }
            }
            let mut load = sub.load.clone();
            for &(v, m) in &sub.frames {
                [load[2 * v], load[2 * v + 1]] = to_frame(m, [load[2 * v], load[2 * v + 1]]);
            }
            for (dof, eq) in dofs.eq.iter().enumerate() {
                if let Some(i) = eq {
                    base[*i] += load[dof];
                }
            }
            let matrix = with_pair_entries(assembled.matrix, &dofs, &coupling)?;
            Ok((dofs, matrix, base, figures))
        });
        let (dofs, matrix, base, figures) = assembled?;
        assembled_figures(figures);
        let factor = timer.time(Phase::Factor, || {
            let a = matrix.as_ref();
            let groups = interior_groups(&dofs);
            let n_b = sub.boundary_dofs.len();
            let ordered = timer.time(Phase::Ordering, || {
                LocalFactor::order(a, n_b, &groups, &sub.nodes, s.ordering)
            })?;
            LocalFactor::with_order(a, sub.n_contact_dofs, s.alpha, ordered)
        })?;
        Ok(LocalSystem { dofs, factor, base })
    }
}

/// The linear step on the condensed boundary system: each rank eliminates its own
/// contact dofs, the first rank solves the interface system (one MPI_Gatherv of the
/// ranks' interface right-hand sides, one MPI_Scatterv of the interface values), each
/// rank back-substitutes and reads (Nu, Tu) on its own contact nodes. No communication
/// without an interface.
pub struct CondensedStep<'a> {
    mpi: &'a Mpi,
    setup: StepSetup<'a>,
    sub: &'a SubProblem,
    local: LocalSystem,
    /// The interior's forward solve of the load, for the recovery.
    interior_forward: InteriorForward,
    response: LocalResponse,
    /// The interface system, on the first rank only.
    interface: Option<InterfaceSystem>,
    /// The interface system factored by MUMPS, on each rank's team leader.
    mumps: Option<MumpsInterface>,
    /// "dense", "sparse" or "mumps", its factorization's flops (this rank's share with
    /// MUMPS) and the whole factor's entries (on the first subdomain), as first built.
    interface_figures: (Option<&'static str>, f64, f64),
    interface_counts: Vec<usize>,
    /// The interface system is factored dense on the first subdomain (known on all): a
    /// retune may then update it in place (see [`CondensedStep::set_r`]).
    interface_dense: bool,
    /// Scratch: the packed own forces of the sweep being solved.
    forces: Vec<f64>,
    gathered: Vec<f64>,
    solved: Vec<f64>,
    x_g: Vec<f64>,
    out: Vec<f64>,
}

impl<'a> CondensedStep<'a> {
    /// Condenses the factored subdomain onto its boundary and builds the interface
    /// system (collective). Times [`Phase::Schur`] and the forward half of
    /// [`Phase::OneSolve`].
    pub fn condense(
        mpi: &'a Mpi,
        setup: StepSetup<'a>,
        sub: &'a SubProblem,
        mut local: LocalSystem,
        timer: &Timer,
    ) -> Result<Self> {
        let schur = timer.phase(Phase::Schur);
        let (g_local, interior_forward) =
            timer.time(Phase::OneSolve, || local.factor.condensed_rhs(&local.base));
        let s_local = local.factor.interface_schur();
        let step_normals = sub.step_normals();
        let rows = mpi.agree(ContactRows::new(
            &contact_rows(sub, &step_normals, setup.frictional),
            &sub.fixed,
            &sub.boundary_dofs,
        ))?;
        drop(schur);

        let mut mumps = None;
        let (interface, interface_figures) =
            factor_interface(mpi, (setup, sub), s_local, &mut mumps)?;
        let has_interface = setup.n_interface > 0;
        let interface_counts = interface_counts(mpi, sub, has_interface && !setup.interface_mumps);
        let interface_dense = mpi.broadcast(
            mpi.is_root()
                .then_some(interface_figures.0 == Some("dense")),
        )?;
        Ok(CondensedStep {
            mpi,
            setup,
            sub,
            local,
            interior_forward,
            response: LocalResponse::new(rows, g_local),
            interface,
            mumps,
            interface_figures,
            interface_counts,
            interface_dense,
            forces: Vec::new(),
            gathered: Vec::new(),
            solved: Vec::new(),
            x_g: Vec::new(),
            out: Vec::new(),
        })
    }

    /// The subdomain's factor (for its figures).
    pub fn factor(&self) -> &LocalFactor {
        &self.local.factor
    }

    /// "dense" or "sparse" on the subdomain that factored the interface system, as
    /// first built (`None` on the others).
    pub fn interface_factor(&self) -> Option<&'static str> {
        self.interface_figures.0
    }

    /// That first factorization's floating-point operations (0 on the others).
    pub fn interface_flops(&self) -> f64 {
        self.interface_figures.1
    }

    /// Entries of the interface factor, on the first subdomain (0 on the others).
    pub fn interface_entries(&self) -> f64 {
        self.interface_figures.2
    }

    /// Hands the first subdomain each subdomain's low-rank change of its interface
    /// complement, which it adds to the dense interface factor in place (collective).
    /// False when that failed (an update lost positive definiteness): the factor must
    /// then be built again.
    fn update_interface(&mut self, change: SchurChange) -> Result<bool> {
        let (w, alpha) = match change {
            SchurChange::LowRank { w, alpha } => {
                let flat = (0..w.ncols())
                    .flat_map(|c| (0..w.nrows()).map(move |i| (i, c)))
                    .map(|(i, c)| w[(i, c)])
                    .collect();
                (flat, alpha)
            }
            _ => (Vec::new(), Vec::new()),
        };
        let parts = self
            .mpi
            .gather_parts((self.sub.interface_global.clone(), w, alpha))?;
        let ok = parts.map(|parts| {
            self.interface
                .as_mut()
                .is_some_and(|interface| interface.update(&parts))
        });
        self.mpi.broadcast(ok)
    }

    /// The factored subdomain, for its owner to free when it chooses: at millions of
    /// dofs, handing a gigabyte back to the system takes tens of milliseconds.
    pub fn into_local(self) -> LocalSystem {
        self.local
    }

    /// The displacement of every node of the subdomain, from the boundary values of the
    /// last sweep, which every rank holds: the backward half of a sparse solve for the
    /// interior (timed as the rest of [`Phase::OneSolve`]). `iterations`: the loop's.
    pub fn recover(&mut self, iterations: usize, timer: &Timer) -> Result<Vec<[f64; 2]>> {
        if iterations == 0 {
            // A loop that never solved: the boundary values of zero forces.
            let zero = vec![0.0; self.sub.contact_nodes.len()];
            let (mut un, mut ut) = (zero.clone(), zero.clone());
            self.solve(&zero, &zero, &mut un, &mut ut)?;
        }
        let x_b = self.response.boundary_values();
        // Free the interface system before the solve, as its last use has been (MUMPS's
        // on every leader at once: its end is collective).
        drop(self.interface.take());
        drop(self.mumps.take());
        let u_free = timer.time(Phase::OneSolve, || {
            self.local.factor.recover(&self.interior_forward, &x_b)
        });
        let mut u: Vec<[f64; 2]> = (self.local.dofs.expand(&u_free).chunks_exact(2))
            .map(|c| [c[0], c[1]])
            .collect();
        for &(v, m) in &self.sub.frames {
            u[v] = from_frame(m, u[v]);
        }
        Ok(u)
    }
}

impl LinearStep for CondensedStep<'_> {
    /// Each rank refactors the dense trailing block of its factor with the new
    /// augmentation on its contact dofs; the first rank rebuilds the interface system.
    fn set_r(&mut self, r_n: &[f64], r_t: &[f64]) -> Result<bool> {
        let shift = |r: &[f64]| r.iter().map(|r| r - self.setup.r).collect::<Vec<f64>>();
        let normals = self.sub.step_normals();
        let mut blocks = contact_blocks(
            &self.sub.contact_nodes,
            &obstacle_weights(self.sub),
            &shift(r_n),
            &shift(r_t),
            &normals,
            self.setup.frictional,
        );
        // A mortar row's blocks were assembled with the first r, like the others.
        let (same, cross) = mortar_blocks(
            &contact_rows(self.sub, &normals, self.setup.frictional),
            &shift(r_n),
            &shift(r_t),
        );
        blocks.extend(same);
        let updated = boundary_entries(&blocks, &self.sub.fixed, &self.sub.boundary_dofs).and_then(
            |mut delta| {
                let (coupling, _) = pair_entries(&cross, &self.sub.fixed);
                delta.extend(at_boundary_positions(&coupling, &self.sub.boundary_dofs)?);
                self.local.factor.update_boundary(&delta)
            },
        );
        let change = self.mpi.agree(updated)?;
        if self.setup.n_interface > 0 && !self.setup.interface_mumps && self.interface_dense {
            // Every subdomain's complement changed by a low-rank term (or not at all):
            // the first one updates the dense factor in place instead of summing and
            // factoring again (hertz level 4, 2 subdomains: about 20 ms a retune).
            let mut full = [f64::from(u8::from(matches!(change, SchurChange::Full)))];
            self.mpi.sum_in_place(&mut full);
            if full[0] == 0.0 && self.update_interface(change)? {
                return Ok(true);
            }
        }
        if self.setup.n_interface > 0 && self.setup.interface_mumps {
            // The old factor ends on every leader before the new one starts.
            drop(self.mumps.take());
            interface_mumps::build(
                self.mpi,
                self.setup.n_interface,
                self.sub.interface_global.clone(),
                self.local.factor.interface_schur(),
                &mut self.mumps,
            )?;
        } else if self.setup.n_interface > 0 {
            self.interface = build_interface(
                self.mpi,
                self.sub,
                self.local.factor.interface_schur(),
                self.setup.n_interface,
            )?;
        }
        Ok(true)
    }

    fn solve(
        &mut self,
        force_n: &[f64],
        force_t: &[f64],
        un: &mut [f64],
        ut: &mut [f64],
    ) -> Result<()> {
        let frictional = self.setup.frictional;
        self.forces.clear();
        self.forces.extend_from_slice(force_n);
        if frictional {
            self.forces.extend_from_slice(force_t);
        }
        let z = self.response.forward(&self.local.factor, &self.forces);
        self.x_g.resize(z.len(), 0.0);
        if self.setup.n_interface > 0 && self.setup.interface_mumps {
            let x = interface_mumps::solve(self.mpi, z, &mut self.mumps)?;
            self.x_g.copy_from_slice(&x);
        } else if self.setup.n_interface > 0 {
            self.mpi
                .gather_to_root(z, &self.interface_counts, &mut self.gathered);
            if let Some(sys) = self.interface.as_mut() {
                sys.solve_packed(&self.gathered, &mut self.solved);
            }
            self.mpi
                .scatter_from_root(&self.solved, &self.interface_counts, &mut self.x_g);
        }
        self.out.resize(self.forces.len(), 0.0);
        self.response
            .backward(&self.local.factor, &self.x_g, &mut self.out);
        let n_own = force_n.len();
        un.copy_from_slice(&self.out[..n_own]);
        if frictional {
            ut.copy_from_slice(&self.out[n_own..]);
        } else {
            ut.fill(0.0);
        }
        Ok(())
    }
}

/// The subdomain's contact rows for `mortar_blocks`, with the normals the step sees.
fn contact_rows<'a>(
    sub: &'a SubProblem,
    step_normals: &'a [[f64; 2]],
    frictional: bool,
) -> ContactRowsGeometry<'a> {
    ContactRowsGeometry {
        nodes: &sub.contact_nodes,
        masters: &sub.contact_masters,
        w: &sub.contact.w,
        normals: &sub.contact.normal,
        step_normals,
        frictional,
    }
}

/// Each own contact node's weight in the node-wise augmentation blocks: its own for a
/// node against an obstacle, zero for a mortar row (whose blocks are `mortar_blocks`').
fn obstacle_weights(sub: &SubProblem) -> Vec<f64> {
    (sub.contact.w.iter().enumerate())
        .map(|(k, &w)| {
            if sub.contact_masters.get(k).is_some_and(|m| !m.is_empty()) {
                0.0
            } else {
                w
            }
        })
        .collect()
}

/// Blocks between two different nodes as entries (dof, dof, v) between free local dofs,
/// each pair once (the matrix holds v at both (i, j) and (j, i)), and the lifting they
/// give a free dof where the other is prescribed: (local dof, value to add to the
/// right-hand side).
#[allow(clippy::type_complexity)]
fn pair_entries(
    cross: &[(usize, usize, [[f64; 2]; 2])],
    fixed: &[Option<f64>],
) -> (Vec<(usize, usize, f64)>, Vec<(usize, f64)>) {
    let (mut entries, mut lifting) = (Vec::new(), Vec::new());
    for &(p, q, blk) in cross {
        for (i, row) in blk.iter().enumerate() {
            for (j, &v) in row.iter().enumerate() {
                if v == 0.0 {
                    continue;
                }
                let (dp, dq) = (2 * p + i, 2 * q + j);
                match (fixed[dp], fixed[dq]) {
                    (None, None) => entries.push((dp, dq, v)),
                    (None, Some(u)) => lifting.push((dp, -v * u)),
                    (Some(u), None) => lifting.push((dq, -v * u)),
                    (Some(_), Some(_)) => {}
                }
            }
        }
    }
    (entries, lifting)
}

/// Entries between local dofs at their B positions (for `LocalFactor::update_boundary`).
fn at_boundary_positions(
    entries: &[(usize, usize, f64)],
    boundary_dofs: &[usize],
) -> Result<Vec<(usize, usize, f64)>> {
    let position: std::collections::HashMap<usize, usize> = (boundary_dofs.iter().enumerate())
        .map(|(k, &d)| (d, k))
        .collect();
    (entries.iter())
        .map(|&(a, b, v)| match (position.get(&a), position.get(&b)) {
            (Some(&i), Some(&j)) => Ok((i, j, v)),
            _ => Err(crate::error::Error::Numerical(format!(
                "internal: a mortar row's dof {a} or {b} is not a boundary dof"
            ))),
        })
        .collect()
}

/// `matrix` (lower triangle, by equation) with `entries` between dofs added: a mortar
/// row couples nodes no triangle joins, so its entries are not in the assembled
/// pattern, and the factor's pattern (its trailing block too, which retunes rewrite in
/// place) must hold them and their fill.
fn with_pair_entries(
    matrix: faer::sparse::SparseColMat<usize, f64>,
    dofs: &DofMap,
    entries: &[(usize, usize, f64)],
) -> Result<faer::sparse::SparseColMat<usize, f64>> {
    use faer::sparse::{SparseColMat, Triplet};
    if entries.is_empty() {
        return Ok(matrix);
    }
    let n = matrix.nrows();
    let a = matrix.as_ref();
    let mut triplets: Vec<Triplet<usize, usize, f64>> =
        Vec::with_capacity(a.compute_nnz() + entries.len());
    for j in 0..n {
        for (i, &v) in a.row_idx_of_col(j).zip(a.val_of_col(j)) {
            triplets.push(Triplet::new(i, j, v));
        }
    }
    for &(p, q, v) in entries {
        let (Some(i), Some(j)) = (dofs.eq[p], dofs.eq[q]) else {
            continue;
        };
        triplets.push(Triplet::new(i.max(j), i.min(j), v));
    }
    SparseColMat::try_new_from_triplets(n, n, &triplets).map_err(|e| {
        crate::error::Error::Numerical(format!("cannot assemble the mortar coupling: {e:?}"))
    })
}

/// The interface system, summed and factored once: on the first rank, or across the
/// ranks by MUMPS (into `mumps`, on each rank's team leader); with its figures (see
/// `CondensedStep::interface_figures`).
#[allow(clippy::type_complexity)]
fn factor_interface(
    mpi: &Mpi,
    (setup, sub): (StepSetup, &SubProblem),
    s_local: Mat<f64>,
    mumps: &mut Option<MumpsInterface>,
) -> Result<(Option<InterfaceSystem>, (Option<&'static str>, f64, f64))> {
    let n = setup.n_interface;
    if n > 0 && setup.interface_mumps {
        let index = sub.interface_global.clone();
        let (flops, entries) = interface_mumps::build(mpi, n, index, s_local, mumps)?;
        // A rank's MUMPS work is its leader subdomain's; the factor's size is reported
        // once.
        let flops = if mumps.is_some() { flops } else { 0.0 };
        let entries = if mpi.rank == 0 { entries } else { 0.0 };
        return Ok((None, (Some("mumps"), flops, entries)));
    }
    let interface = match n > 0 {
        true => build_interface(mpi, sub, s_local, n)?,
        false => None,
    };
    let figures = match &interface {
        Some(i) => (
            Some(if i.is_sparse() { "sparse" } else { "dense" }),
            i.factor_flops(),
            i.factor_entries(),
        ),
        None => (None, 0.0, 0.0),
    };
    Ok((interface, figures))
}

/// Every subdomain's number of interface dofs (collective; zeros without an interface).
fn interface_counts(mpi: &Mpi, sub: &SubProblem, has_interface: bool) -> Vec<usize> {
    if !has_interface {
        return vec![0; mpi.size];
    }
    let mut counts = Vec::new();
    mpi.all_gather(
        &[sub.interface_global.len() as f64],
        &vec![1; mpi.size],
        &mut counts,
    );
    counts.iter().map(|&c| c as usize).collect()
}

/// The interface system, summed from every rank's part and factored on the first rank
/// (collective; `None` on the other ranks).
fn build_interface(
    mpi: &Mpi,
    sub: &SubProblem,
    s_local: Mat<f64>,
    n_interface: usize,
) -> Result<Option<InterfaceSystem>> {
    let n = s_local.nrows();
    let flat: Vec<f64> = (0..n * n).map(|k| s_local[(k % n, k / n)]).collect();
    drop(s_local);
    let gathered = mpi.gather_parts((sub.interface_global.clone(), flat));
    let interface = match gathered {
        Ok(Some(parts)) => {
            let pieces = parts.into_iter().map(|(index, flat)| {
                let n = index.len();
                (index, Mat::<f64>::from_fn(n, n, |i, j| flat[i + n * j]))
            });
            // The other subdomains sleep meanwhile (below): see host::interface_threads.
            let threads = host::interface_threads(n_interface);
            Some(InterfaceSystem::new(n_interface, pieces, threads))
        }
        Ok(None) => None,
        Err(e) => Some(Err(e)),
    };
    mpi.barrier_sleeping();
    mpi.agree(interface.transpose())
}
