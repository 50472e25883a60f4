//! Criterion benchmarks of the solver's kernels, on the built-in `block` case (Coulomb
//! friction, so both normal and tangential terms run):
//!
//! * `element/stiffness`: one P1 element stiffness matrix.
//! * `assemble/level{2,4}`: A = K + r N'WN + r T'WT on the free dofs (rayon).
//! * `factor/amd/level{2,4}`: sparse Cholesky with AMD (the `--linear full` factor).
//! * `factor/boundary_last/level{2,4}`: `LocalFactor::new`, the interior ordered by
//!   approximate minimum degree and the contact dofs last (the one-rank
//!   subdomain of the default path): ordering, symbolic and numeric factorization, and
//!   the dense trailing block.
//! * `factor/nd_graph/level{2,4}`, `factor/nd_metis/level{2,4}`: the nested-dissection ordering (`--ordering nd`) alone in
//!   its two steps, the node graph from the matrix pattern and METIS_NodeND (through
//!   `partition::nested_dissection`); `factor/nd_numeric/level{2,4}`:
//!   `SparseCholesky::factor` with it precomputed. Together they separate the ordering
//!   from the numeric work.
//! * `condense/level{2,4}`: what the one-rank path adds to the factor before the loop:
//!   the condensed right-hand side (one sparse solve) and the contact rows.
//! * `sweep/full/level{2,4}`: one Uzawa sweep with a sparse forward+backward solve.
//! * `sweep/condensed/level{2,4}`: one Uzawa sweep as the program does it, two dense
//!   triangular solves of the contact size with the trailing block of the sparse factor
//!   (`LocalResponse::forward` / `backward`), then the node kernels.
//! * `sweep/h_matvec/level{2,4}`: the same sweep with an explicit H = C S^-1 C' (formed
//!   once here): one dense matrix-vector product instead of the two solves.
//! * `node_kernels/n{641,2561}`: the node-wise steps 2 and 3 alone (projection,
//!   shrinkage, multipliers, Coulomb threshold) on the contact node counts of block
//!   levels 4 and 6.
//! * `plots/contact/n{878,3505}`, `plots/convergence/sweeps{20,330}`: `contact.png`
//!   and `convergence.png` drawn and encoded in memory (no file), for the contact nodes
//!   of hertz levels 4 and 6 (a Hertz-like profile, with p_t) and for histories of 20
//!   sweeps (hertz level 4) and 330 (block level 2 with `--coulomb outer`).
//!
//! * `problem/level{2,4}`: `problem::build` (the mesh checks, groups, contact geometry,
//!   held check, the locality renumbering; the mesh cloned outside the timing).
//!
//! A sweep is `contact_par::contact::solve` with a budget of one plain (unaccelerated)
//! sweep, through the public `LinearStep` trait, so it is the loop body the program
//! runs, residual norms included.
//!
//! Threads: 1 by default (rayon pool and faer), so the numbers are per core and do not
//! depend on what else runs on the machine; `CONTACT_PAR_BENCH_THREADS=N` changes it.
//! The whole run takes about 90 s on a 2-core machine: `cargo bench --bench kernels`
//! (`cargo bench --bench kernels -- sweep/` runs one group).

use contact_par::case::{self, Case};
use contact_par::contact::kernels::{coulomb_threshold, normal_from_state, tangential_from_state};
use contact_par::contact::operators::{contact_blocks, ContactDofs, ContactRowsGeometry};
use contact_par::contact::Acceleration;
use contact_par::contact::{self, LinearStep, NoComm, Params};
use contact_par::dd::condense::{ContactRows, LocalResponse};
use contact_par::dd::full::{DirectStep, DirectSystem};
use contact_par::dd::local_factor::LocalFactor;
use contact_par::error::Result;
use contact_par::fem::{self, assemble, Assembled, DofMap, Materials};
use contact_par::linear::{interior_groups, NodeGraph, SparseCholesky};
use contact_par::problem::{self, Problem};
use contact_par::setup::load_mesh;
use contact_par::timer::Timer;
use criterion::{black_box, criterion_group, criterion_main, BatchSize, Criterion, SamplingMode};
use faer::sparse::linalg::cholesky::SymmetricOrdering;
use std::time::Duration;

/// The small and the large mesh of every size-dependent benchmark (block levels 2 and 4:
/// 6 601 and 103 201 nodes).
const LEVELS: [u32; 2] = [2, 4];

/// Seconds per iteration at the levels of [`LEVELS`], one thread, as measured on the
/// development machine (for the sample budgets only).
const ASSEMBLE_S: [f64; 2] = [0.01, 0.3];
const AMD_S: [f64; 2] = [0.03, 0.45];
const ND_GRAPH_S: [f64; 2] = [0.004, 0.1];
const ND_METIS_S: [f64; 2] = [0.015, 0.35];
const ND_NUMERIC_S: [f64; 2] = [0.015, 0.45];
const LOCAL_FACTOR_S: [f64; 2] = [0.035, 1.0];
const CONDENSE_S: [f64; 2] = [0.01, 0.25];

/// The built-in block case at one level, with everything the kernels need.
struct Fixture {
    level: u32,
    case: Case,
    prob: Problem,
    r: f64,
    frictional: bool,
}

impl Fixture {
    fn new(level: u32) -> Self {
        let case = case::builtin_case("block", level).expect("built-in case");
        let (mesh, name) = load_mesh(&case).expect("built-in mesh");
        let prob = problem::build(&case, mesh, &name).expect("problem");
        let r = case.solver.r.unwrap_or_else(|| prob.default_r(&case));
        let frictional = Problem::is_frictional(&case);
        Fixture {
            level,
            case,
            prob,
            r,
            frictional,
        }
    }

    fn blocks(&self) -> Vec<(usize, [[f64; 2]; 2])> {
        let r = vec![self.r; self.prob.contact_nodes.len()];
        contact_blocks(
            &self.prob.contact_nodes,
            &self.prob.contact.w,
            &r,
            &r,
            &self.prob.contact.normal,
            self.frictional,
        )
    }

    /// The matrix of the `--linear full` path (free dofs in dof order).
    fn assemble_plain(&self, dofs: &DofMap) -> Assembled {
        let m = &self.prob.mesh;
        assemble(
            &m.nodes,
            &m.triangles,
            Materials::One(&self.case.materials[0].material),
            dofs,
            &self.blocks(),
        )
        .expect("assembly")
    }

    /// Shift of the boundary block, as the program chooses it.
    fn alpha(&self) -> f64 {
        let m = &self.case.materials[0].material;
        m.young / (1.0 - m.poisson * m.poisson)
    }

    /// The free dofs of the contact nodes: the boundary of the one-rank subdomain.
    fn boundary_dofs(&self) -> Vec<usize> {
        self.prob
            .contact_nodes
            .iter()
            .flat_map(|&v| [2 * v, 2 * v + 1])
            .filter(|&d| self.prob.fixed[d].is_none())
            .collect()
    }

    /// The one-rank matrix with the boundary dofs last, and its right-hand side.
    fn assemble_boundary_last(&self) -> (DofMap, Assembled, Vec<f64>, usize) {
        let last = self.boundary_dofs();
        let dofs = DofMap::with_last(&self.prob.fixed, &last);
        // One rank: every boundary dof is a contact dof, none is shifted.
        let blocks = self.blocks();
        let m = &self.prob.mesh;
        let a = assemble(
            &m.nodes,
            &m.triangles,
            Materials::One(&self.case.materials[0].material),
            &dofs,
            &blocks,
        )
        .expect("assembly");
        let mut base = a.lifting.clone();
        for (dof, eq) in dofs.eq.iter().enumerate() {
            if let Some(i) = eq {
                base[*i] += self.prob.load[dof];
            }
        }
        (dofs, a, base, last.len())
    }

    fn contact_dofs(&self) -> ContactDofs<'_> {
        ContactDofs {
            nodes: &self.prob.contact_nodes,
            w: &self.prob.contact.w,
            normals: &self.prob.contact.normal,
            frictional: self.frictional,
        }
    }

    fn direct_step(&self) -> DirectStep {
        let m = &self.prob.mesh;
        let system = DirectSystem {
            nodes: &m.nodes,
            triangles: &m.triangles,
            materials: Materials::One(&self.case.materials[0].material),
            fixed: &self.prob.fixed,
            load: &self.prob.load,
            contact: self.contact_dofs(),
            r: self.r,
        };
        DirectStep::new(&system, &Timer::start(), &|_| ()).expect("direct step")
    }

    /// The condensed contact response of the one-rank path: the condensed loads and the
    /// contact rows against the trailing block of the factor.
    fn condensed(&self, factor: &mut LocalFactor, base: &[f64]) -> LocalResponse {
        let (g, _) = factor.condensed_rhs(base);
        let geometry = ContactRowsGeometry {
            nodes: &self.prob.contact_nodes,
            masters: &self.prob.contact_masters,
            w: &self.prob.contact.w,
            normals: &self.prob.contact.normal,
            step_normals: &self.prob.contact.normal,
            frictional: self.frictional,
        };
        let rows = ContactRows::new(&geometry, &self.prob.fixed, &self.boundary_dofs())
            .expect("contact rows");
        LocalResponse::new(rows, g)
    }

    /// Parameters for exactly one sweep.
    fn one_sweep(&self) -> Params {
        Params {
            r: self.r,
            tol: 0.0,
            max_iter: 1,
            friction: self.case.friction(),
            coulomb: self.case.solver.coulomb,
            acceleration: Acceleration::None,
            adaptive: None,
            mesh_stiffness: f64::NAN,
        }
    }

    fn label(&self) -> String {
        format!("level{}", self.level)
    }
}

/// Packs the forces as the program's gather does on one rank: normal values, then
/// (with friction) tangential ones.
fn pack(f: &mut Vec<f64>, fnn: &[f64], ft: &[f64], frictional: bool) {
    f.clear();
    f.extend_from_slice(fnn);
    if frictional {
        f.extend_from_slice(ft);
    }
}

/// Unpacks (Nu, Tu).
fn unpack(y: &[f64], n: usize, frictional: bool, un: &mut [f64], ut: &mut [f64]) {
    un.copy_from_slice(&y[..n]);
    if frictional {
        ut.copy_from_slice(&y[n..]);
    } else {
        ut.fill(0.0);
    }
}

/// Step 1 condensed onto the contact dofs, as the program does it on one rank:
/// (Nu, Tu) = C S^-1 (g + C' f) + c0 by two triangular solves with the trailing block
/// of the sparse factor (no interface).
struct CondensedStep<'a> {
    factor: &'a LocalFactor,
    response: LocalResponse,
    n: usize,
    frictional: bool,
    f: Vec<f64>,
    y: Vec<f64>,
}

impl<'a> CondensedStep<'a> {
    fn new(factor: &'a LocalFactor, response: LocalResponse, n: usize, frictional: bool) -> Self {
        let ncd = if frictional { 2 * n } else { n };
        CondensedStep {
            factor,
            response,
            n,
            frictional,
            f: Vec::with_capacity(ncd),
            y: vec![0.0; ncd],
        }
    }

    fn respond(&mut self, f: &[f64], out: &mut [f64]) {
        self.response.forward(self.factor, f);
        self.response.backward(self.factor, &[], out);
    }
}

impl LinearStep for CondensedStep<'_> {
    fn solve(&mut self, fnn: &[f64], ft: &[f64], un: &mut [f64], ut: &mut [f64]) -> Result<()> {
        pack(&mut self.f, fnn, ft, self.frictional);
        let f = std::mem::take(&mut self.f);
        let mut y = std::mem::take(&mut self.y);
        self.respond(&f, &mut y);
        (self.f, self.y) = (f, y);
        unpack(&self.y, self.n, self.frictional, un, ut);
        Ok(())
    }
}

/// The same step with H = C S^-1 C' formed explicitly (dense, row-major, one row per
/// contact value): (Nu, Tu) = u0 + H f, rows in parallel with rayon.
struct HStep {
    rows: Vec<f64>,
    u0: Vec<f64>,
    n: usize,
    frictional: bool,
    f: Vec<f64>,
    y: Vec<f64>,
}

impl HStep {
    /// H column by column from the program's contact response (n_H solves, once).
    fn new(cond: &mut CondensedStep, n: usize, frictional: bool) -> Self {
        let ncd = if frictional { 2 * n } else { n };
        let mut u0 = vec![0.0; ncd];
        let mut rows = vec![0.0; ncd * ncd];
        let (mut e, mut col) = (vec![0.0; ncd], vec![0.0; ncd]);
        cond.respond(&e, &mut u0);
        for j in 0..ncd {
            e[j] = 1.0;
            cond.respond(&e, &mut col);
            e[j] = 0.0;
            for i in 0..ncd {
                rows[i * ncd + j] = col[i] - u0[i];
            }
        }
        HStep {
            rows,
            u0,
            n,
            frictional,
            f: Vec::with_capacity(ncd),
            y: vec![0.0; ncd],
        }
    }
}

impl LinearStep for HStep {
    fn solve(&mut self, fnn: &[f64], ft: &[f64], un: &mut [f64], ut: &mut [f64]) -> Result<()> {
        use rayon::prelude::*;
        pack(&mut self.f, fnn, ft, self.frictional);
        let (f, ncd) = (&self.f, self.f.len());
        self.y
            .par_iter_mut()
            .zip(self.rows.par_chunks(ncd))
            .zip(&self.u0)
            .for_each(|((y, row), u0)| {
                *y = u0 + row.iter().zip(f).map(|(h, f)| h * f).sum::<f64>()
            });
        unpack(&self.y, self.n, self.frictional, un, ut);
        Ok(())
    }
}

/// Nested dissection of the node graph expanded to the equations: (perm[new] = old,
/// its inverse).
fn nd_permutation(graph: &NodeGraph) -> (Vec<usize>, Vec<usize>) {
    let node_perm = partition::nested_dissection(&graph.xadj, &graph.adjncy).expect("METIS_NodeND");
    let fwd = graph.expand(&node_perm);
    let mut inv = vec![0usize; fwd.len()];
    for (new, &old) in fwd.iter().enumerate() {
        inv[old] = new;
    }
    (fwd, inv)
}

fn threads() -> usize {
    std::env::var("CONTACT_PAR_BENCH_THREADS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1)
        .max(1)
}

fn set_threads() {
    let n = threads();
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build_global();
    faer::set_global_parallelism(if n == 1 {
        faer::Par::Seq
    } else {
        faer::Par::rayon(n)
    });
}

type Group<'a> = criterion::BenchmarkGroup<'a, criterion::measurement::WallTime>;

/// A group for cases whose one iteration takes about `secs` seconds: the minimum of 10
/// samples, flat sampling, and no longer than needed.
fn heavy<'a>(c: &'a mut Criterion, name: &str, secs: f64) -> Group<'a> {
    let mut g = c.benchmark_group(name);
    g.sample_size(10).sampling_mode(SamplingMode::Flat);
    budget(&mut g, secs);
    g
}

/// Sets the time budget of the next benchmarks of a group to about 12 iterations.
fn budget(g: &mut Group<'_>, secs: f64) {
    g.warm_up_time(Duration::from_secs_f64(secs.clamp(0.1, 1.0)))
        .measurement_time(Duration::from_secs_f64((12.0 * secs).clamp(0.5, 20.0)));
}

const PROBLEM_S: [f64; 2] = [0.01, 0.2];

fn problems(c: &mut Criterion) {
    set_threads();
    for (k, level) in LEVELS.into_iter().enumerate() {
        let case = case::builtin_case("block", level).expect("built-in case");
        let (mesh, name) = load_mesh(&case).expect("built-in mesh");
        let mut g = heavy(c, "problem", PROBLEM_S[k]);
        g.bench_function(format!("level{level}"), |b| {
            b.iter_batched(
                || mesh.clone(),
                |m| problem::build(&case, m, &name).expect("problem"),
                BatchSize::LargeInput,
            )
        });
        g.finish();
    }
}

fn element(c: &mut Criterion) {
    set_threads();
    let d = fem::elasticity_matrix(&case::builtin_case("block", 0).unwrap().materials[0].material);
    let p = [[0.0, 0.0], [0.125, 0.0], [0.0, 0.125]];
    let mut g = c.benchmark_group("element");
    g.warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    g.bench_function("stiffness", |b| {
        b.iter(|| fem::element_stiffness(black_box(&p), black_box(&d)))
    });
    g.finish();
}

fn assembly(c: &mut Criterion) {
    for (k, level) in LEVELS.into_iter().enumerate() {
        let fx = Fixture::new(level);
        let dofs = DofMap::new(&fx.prob.fixed);
        let mut g = heavy(c, "assemble", ASSEMBLE_S[k]);
        g.bench_function(fx.label(), |b| {
            b.iter(|| fx.assemble_plain(black_box(&dofs)))
        });
        g.finish();
    }
}

fn factorization(c: &mut Criterion) {
    for (k, level) in LEVELS.into_iter().enumerate() {
        let fx = Fixture::new(level);
        let a = fx.assemble_plain(&DofMap::new(&fx.prob.fixed)).matrix;
        let mut g = heavy(c, "factor", AMD_S[k]);
        g.bench_function(format!("amd/{}", fx.label()), |b| {
            b.iter(|| SparseCholesky::factor(a.as_ref(), SymmetricOrdering::Amd).unwrap())
        });
        let plain_groups = interior_groups(&DofMap::new(&fx.prob.fixed));
        budget(&mut g, ND_GRAPH_S[k]);
        g.bench_function(format!("nd_graph/{}", fx.label()), |b| {
            b.iter(|| NodeGraph::new(a.as_ref(), a.nrows(), &plain_groups))
        });
        let graph = NodeGraph::new(a.as_ref(), a.nrows(), &plain_groups);
        budget(&mut g, ND_METIS_S[k]);
        g.bench_function(format!("nd_metis/{}", fx.label()), |b| {
            b.iter(|| nd_permutation(&graph))
        });
        let (fwd, inv) = nd_permutation(&graph);
        let n = a.nrows();
        budget(&mut g, ND_NUMERIC_S[k]);
        g.bench_function(format!("nd_numeric/{}", fx.label()), |b| {
            b.iter(|| {
                let perm = faer::perm::PermRef::new_checked(&fwd, &inv, n);
                SparseCholesky::factor(a.as_ref(), SymmetricOrdering::Custom(perm)).unwrap()
            })
        });
        let (dofs, shifted, base, nb) = fx.assemble_boundary_last();
        let groups = interior_groups(&dofs);
        budget(&mut g, LOCAL_FACTOR_S[k]);
        g.bench_function(format!("boundary_last/{}", fx.label()), |b| {
            b.iter(|| {
                LocalFactor::new(shifted.matrix.as_ref(), nb, nb, fx.alpha(), &groups).unwrap()
            })
        });
        g.finish();
        let mut factor =
            LocalFactor::new(shifted.matrix.as_ref(), nb, nb, fx.alpha(), &groups).unwrap();
        let mut g = heavy(c, "condense", CONDENSE_S[k]);
        g.bench_function(fx.label(), |b| b.iter(|| fx.condensed(&mut factor, &base)));
        g.finish();
    }
}

fn sweeps(c: &mut Criterion) {
    for level in LEVELS {
        let fx = Fixture::new(level);
        let nodes = &fx.prob.contact;
        let params = fx.one_sweep();
        let mut g = c.benchmark_group("sweep");
        g.sample_size(20)
            .warm_up_time(Duration::from_millis(300))
            .measurement_time(Duration::from_secs(2));
        let mut full = fx.direct_step();
        g.bench_function(format!("full/{}", fx.label()), |b| {
            b.iter(|| contact::solve(&mut full, &NoComm, nodes, &params, &mut |_| {}).unwrap())
        });
        let (dofs, shifted, base, nb) = fx.assemble_boundary_last();
        let groups = interior_groups(&dofs);
        let mut factor =
            LocalFactor::new(shifted.matrix.as_ref(), nb, nb, fx.alpha(), &groups).unwrap();
        let cond = fx.condensed(&mut factor, &base);
        let n = fx.prob.contact_nodes.len();
        let mut step = CondensedStep::new(&factor, cond, n, fx.frictional);
        g.bench_function(format!("condensed/{}", fx.label()), |b| {
            b.iter(|| contact::solve(&mut step, &NoComm, nodes, &params, &mut |_| {}).unwrap())
        });
        let mut h_step = HStep::new(&mut step, n, fx.frictional);
        g.bench_function(format!("h_matvec/{}", fx.label()), |b| {
            b.iter(|| contact::solve(&mut h_step, &NoComm, nodes, &params, &mut |_| {}).unwrap())
        });
        g.finish();
    }
}

/// Steps 2 and 3 of ALG2 (Coulomb, inner mode) on `n` nodes, without the linear solve,
/// in the state form the loop uses: from s = Nu + lambda / r and z = Tu + mu / r to the
/// auxiliary variables and multipliers, with the residual sums.
fn node_kernels(c: &mut Criterion) {
    let (r, coef) = (7.0e4, 0.3);
    let mut g = c.benchmark_group("node_kernels");
    g.warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1));
    // The contact node counts of block levels 4 and 6.
    for n in [641usize, 2561] {
        let x = |i: usize, a: f64| (a * i as f64).sin();
        let gap: Vec<f64> = (0..n).map(|i| 1e-3 * x(i, 0.7).abs()).collect();
        let w: Vec<f64> = vec![40.0 / n as f64; n];
        let un: Vec<f64> = (0..n).map(|i| 2e-3 * x(i, 1.3)).collect();
        let ut: Vec<f64> = (0..n).map(|i| 1e-3 * x(i, 0.3)).collect();
        let (mut lambda, mut mu) = (vec![10.0; n], vec![1.0; n]);
        let (mut p, mut q) = (vec![0.0; n], vec![0.0; n]);
        g.bench_function(format!("n{n}"), |b| {
            b.iter(|| {
                let mut sums = [0.0f64; 4];
                for i in 0..n {
                    let threshold = coulomb_threshold(coef, lambda[i]);
                    let (pi, li) = normal_from_state(un[i] + lambda[i] / r, gap[i], r);
                    let (qi, mi) = tangential_from_state(ut[i] + mu[i] / r, threshold, r);
                    sums[0] += w[i] * ((li - lambda[i]).powi(2) + (mi - mu[i]).powi(2));
                    sums[1] += w[i] * ((pi - p[i]).powi(2) + (qi - q[i]).powi(2));
                    sums[2] += w[i] * (li * li + mi * mi);
                    sums[3] += w[i] * (un[i] * un[i] + ut[i] * ut[i]);
                    (p[i], lambda[i], q[i], mu[i]) = (pi, li.min(100.0), qi, mi);
                }
                black_box(sums)
            })
        });
    }
    g.finish();
}

fn plots(c: &mut Criterion) {
    use contact_par::contact::Sweep;
    use contact_par::output::plot::{contact_png, convergence_png, convergence_series, PairSeries};
    set_threads();
    let mut g = c.benchmark_group("plots");
    for n in [878, 3505] {
        let s: Vec<f64> = (0..n).map(|i| 50.0 * i as f64 / n as f64).collect();
        let p_n: Vec<f64> = s
            .iter()
            .map(|x| 7700.0 * (1.0 - x * x / 11.0).max(0.0).sqrt())
            .collect();
        let pair = PairSeries {
            name: "contact".into(),
            p_t: Some(p_n.iter().map(|p| -0.3 * p).collect()),
            u_n: s.iter().map(|x| 0.4 * (1.0 - (-x / 10.0).exp())).collect(),
            gap: s.iter().map(|x| 50.0 - (2500.0 - x * x).sqrt()).collect(),
            p_n,
            s,
        };
        g.bench_function(format!("contact/n{n}"), |b| {
            b.iter(|| contact_png(["what", "case"], "x", std::slice::from_ref(&pair)).unwrap())
        });
    }
    for sweeps in [20, 330] {
        let history: Vec<Sweep> = (1..=sweeps)
            .map(|k| {
                let e = 0.7f64.powi(k as i32 % 40);
                Sweep {
                    iter: k,
                    pressure: e / 3.0,
                    traction: e / 2.0,
                    displacement: e / 1.5,
                    contraction: 0.3,
                    error: e,
                    active: 100,
                    slip: 20,
                    changed: 0,
                    stiff: 0,
                    soft: 0,
                    mistuned: 0,
                    mistuned_n: 0,
                    unsettled: 0,
                    uncertain: 0,
                    pattern: 0,
                    retunes: (k / 8).min(4),
                    refused: k / 100,
                    roundoff: 0.0,
                }
            })
            .collect();
        let series = convergence_series(&history, true, 1e-8);
        g.bench_function(format!("convergence/sweeps{sweeps}"), |b| {
            b.iter(|| convergence_png(["what", "case"], &series).unwrap())
        });
    }
    g.finish();
}

criterion_group!(
    benches,
    element,
    assembly,
    factorization,
    sweeps,
    node_kernels,
    plots,
    problems
);
criterion_main!(benches);
