"""Frictionless contact as PETSc's semismooth Newton solves it, on contact-par's case files:
the yardstick of issue 27's side-by-side timing against an established solver.

    apt-get install python3-petsc4py python3-scipy python3-numpy   # Debian 12: PETSc 3.18
    /usr/bin/python3 -m venv --system-site-packages venvp && venvp/bin/pip install gmsh
    export PETSC_DIR=/usr/lib/petscdir/petsc3.18/x86_64-linux-gnu-real   # where Debian puts it
    mpirun -n 2 -x PETSC_DIR venvp/bin/python run-scripts/petsc_ssn.py CASE.toml --out DIR

The problem is the one contact-par solves: P1 plane elasticity (the stiffness, loads and
prescribed dofs of run-scripts/plain_alg2.py), a frictionless straight foundation whose
normal is a coordinate axis, so that non-penetration is a bound on one displacement
component of each contact node, m.u_i >= -g_i. The matrix is distributed by rows over
the ranks in node pairs, with the rigid-body modes as GAMG's near null space (every rank
assembles the whole matrix with NumPy and keeps its rows: the set-up is not what is
compared; prescribed dofs are identity rows). Two semismooth Newton methods:

- `--method pdas` (default): the primal-dual active-set form of semismooth Newton
  (Hintermueller, Ito and Kunisch 2002) on the full space, each step one CG + GAMG solve
  (rtol 1e-10, started from the last step's displacement) with the active dofs held on
  the foundation as symmetric prescribed rows and columns, which keeps the node pairs
  and the rigid-body modes that GAMG needs. It stops when a step's active set comes
  back: the exact stop of the method.
- `--method rsls`: SNES's reduced-space `vinewtonrsls`, CG + GAMG on the inactive set.
  The reduced matrix loses the node pairs and the near null space, and GAMG then needs
  hundreds of CG iterations per step (105k nodes, 2 ranks: 4330 in 7 steps, 50 s,
  against 170 in 9 steps, 8 s, for pdas).

`--pc mumps` uses MUMPS's LU in place of CG + GAMG. The contact pressure is the
residual of the active rows, divided by the node's lumped weight. It writes
DIR/contact.csv in contact-par's columns and DIR/petsc.json (Newton steps, KSP
iterations, seconds per phase); rank 0 prints the same JSON. `--trace` prints each
pdas step's active set sizes and CG iterations.
"""

import argparse
import json
import os
import sys
import time
import tomllib

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI  # noqa: F401  (petsc4py needs MPI initialised through it)
from petsc4py import PETSc

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from plain_alg2 import foundation, loads_and_prescribed, one_contact, one_material, read_mesh, stiffness  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("case")
    ap.add_argument("--out", default="petsc-out")
    ap.add_argument("--rtol", type=float, default=1e-10, help="SNES relative tolerance")
    ap.add_argument("--pc", choices=["gamg", "mumps"], default="gamg",
                    help="each Newton step's linear solve: CG + GAMG, or MUMPS's LU")
    ap.add_argument("--method", choices=["pdas", "rsls"], default="pdas",
                    help="pdas: semismooth Newton as a primal-dual active-set loop on the full "
                    "space (default); rsls: SNES vinewtonrsls on the reduced space")
    ap.add_argument("--trace", action="store_true", help="print each pdas step")
    ap.add_argument("--start-active", action="store_true",
                    help="pdas: start with every contact dof on the foundation (for a body "
                    "that only its contact holds) instead of none")
    args = ap.parse_args()
    comm = PETSc.COMM_WORLD
    rank = comm.getRank()
    t0 = time.perf_counter()
    times = {}
    case = tomllib.load(open(args.case, "rb"))
    here = os.path.dirname(os.path.abspath(args.case))
    nodes, tri, groups = read_mesh(os.path.join(here, case["mesh"]["file"]))
    times["read"] = time.perf_counter() - t0

    t = time.perf_counter()
    mat = one_material(case, "petsc_ssn.py")
    k, area = stiffness(nodes, tri, mat["young"], mat["poisson"], mat.get("hypothesis", "plane_strain"))
    n = 2 * len(nodes)
    f, fixed = loads_and_prescribed(case, nodes, tri, groups, area)
    con = one_contact(case, "petsc_ssn.py")
    if con.get("friction", "none") != "none" or con["obstacle"]["type"] != "line":
        sys.exit("petsc_ssn.py: frictionless contact with a line only")
    m = np.array(con["obstacle"]["normal"], dtype=float)
    axis = int(np.argmax(np.abs(m)))
    if abs(abs(m[axis]) - 1.0) > 1e-12:
        sys.exit("petsc_ssn.py: the foundation's normal must be a coordinate axis")
    sign = m[axis]
    cn, w, _, g, _, _ = foundation(con, nodes, groups)

    # Prescribed dofs kept as rows of the identity (their columns moved to the right-hand
    # side), so that the dofs stay in pairs and GAMG can be given the rigid-body modes.
    free = np.isnan(fixed)
    ub = np.where(free, 0.0, fixed)
    b = f - k @ ub
    keep = sp.diags(free.astype(float))
    kb = (keep @ k @ keep + sp.diags((~free).astype(float))).tocsr()
    b[~free] = ub[~free]
    lower = np.full(n, PETSc.NINFINITY)
    upper = np.full(n, PETSc.INFINITY)
    # Bounds: sign * u_axis >= -g at each contact node.
    cdof = 2 * cn + axis
    if sign > 0:
        lower[cdof] = -g
    else:
        upper[cdof] = g

    layout = PETSc.Vec().createMPI((None, n), bsize=2, comm=comm)
    lo, hi = layout.getOwnershipRange()
    rows = kb[lo:hi]
    a = PETSc.Mat().createAIJ(size=((hi - lo, n), (hi - lo, n)), bsize=2, csr=(rows.indptr, rows.indices, rows.data), comm=comm)
    a.assemble()
    coords = PETSc.Vec().createMPI((hi - lo, n), bsize=2, comm=comm)
    coords.setArray(nodes.ravel()[lo:hi])
    a.setNearNullSpace(PETSc.NullSpace().createRigidBody(coords))
    rhs = a.createVecLeft()
    rhs.setArray(b[lo:hi])
    xl, xu = a.createVecLeft(), a.createVecLeft()
    xl.setArray(lower[lo:hi])
    xu.setArray(upper[lo:hi])
    times["assemble"] = time.perf_counter() - t

    t = time.perf_counter()
    if args.method == "pdas":
        x, res, newton, linear, reason = pdas(comm, a, rhs, kb, cdof, sign, g, lo, hi, args)
    else:
        x, res, newton, linear, reason = rsls(comm, a, rhs, xl, xu, ub, lo, hi, args)
    times["solve"] = time.perf_counter() - t

    t = time.perf_counter()
    a.mult(x, res)
    res.axpy(-1.0, rhs)
    u = np.concatenate(comm.tompi4py().allgather(x.getArray()))
    r_full = np.concatenate(comm.tompi4py().allgather(res.getArray()))
    times["output"] = time.perf_counter() - t
    times["total"] = time.perf_counter() - t0
    if rank == 0:
        os.makedirs(args.out, exist_ok=True)
        # The reaction of an active row, K u - f, is the contact force along m.
        force = sign * r_full[cdof]
        p_n = np.where(np.abs(force) > 0, force, 0.0) / w
        # contact-par's signs: u_n = -m.u (positive into the obstacle), u_t = t.u with
        # t = (m_y, -m_x).
        un = -sign * u[2 * cn + axis]
        ut = m[1] * u[2 * cn] - m[0] * u[2 * cn + 1]
        order = np.lexsort((nodes[cn, 1], nodes[cn, 0]))
        with open(os.path.join(args.out, "contact.csv"), "w") as fh:
            fh.write("x,y,u_n,u_t,p_n,p_t,gap,contact\n")
            for i in order:
                row = [nodes[cn[i], 0], nodes[cn[i], 1], un[i], ut[i], p_n[i], 0.0, g[i]]
                fh.write(",".join(repr(float(v)) for v in row) + ",0\n")
        out = {
            "method": args.method,
            "pc": args.pc,
            "newton_steps": newton,
            "ksp_iterations": linear,
            "converged_reason": reason,
            "ranks": comm.getSize(),
            "dofs": int(free.sum()),
            "total_normal_force": float(np.sum(force)),
            "timings_s": times,
        }
        json.dump(out, open(os.path.join(args.out, "petsc.json"), "w"), indent=1)
        print(json.dumps(out))


def linear_solver(comm, a, args):
    ksp = PETSc.KSP().create(comm=comm)
    ksp.setOperators(a)
    pc = ksp.getPC()
    if args.pc == "gamg":
        ksp.setType("cg")
        ksp.setTolerances(rtol=1e-10, max_it=10000)
        pc.setType("gamg")
    else:
        ksp.setType("preonly")
        pc.setType("lu")
        pc.setFactorSolverType("mumps")
    ksp.setFromOptions()
    return ksp


def pdas(comm, a, rhs, kb, cdof, sign, g, lo, hi, args):
    """Semismooth Newton on the complementarity function min(lambda, c d) of each contact
    dof, d = sign u + g its distance to the foundation and lambda its force: a
    primal-dual active-set loop (Hintermueller, Ito and Kunisch 2002). Each step solves
    the full system with the active dofs held on the foundation as prescribed rows and
    columns (MatZeroRowsColumns: the matrix stays symmetric, in node pairs, with the
    rigid-body modes as GAMG's near null space); the force of an active dof is its
    row's residual. It stops when the active set repeats."""
    mine = (cdof >= lo) & (cdof < hi)
    c = float(np.mean(kb.diagonal()[cdof]))
    active = np.full(len(cdof), args.start_active)
    x = a.createVecRight()
    res = a.createVecLeft()
    b = a.createVecLeft()
    linear = 0
    ksp = None
    for step in range(1, 201):
        am = a.copy()
        b.setArray(rhs.getArray())
        rows = cdof[active & mine].astype(PETSc.IntType)
        xd = a.createVecRight()
        xd.setValues(cdof[active & mine].astype(PETSc.IntType), (-sign * g[active & mine]).astype(float))
        xd.assemble()
        am.zeroRowsColumns(rows, 1.0, xd, b)
        am.setNearNullSpace(a.getNearNullSpace())
        if ksp is None:
            ksp = linear_solver(comm, am, args)
            # Each step starts from the last one's displacement.
            ksp.setInitialGuessNonzero(args.pc == "gamg")
        else:
            ksp.setOperators(am)
        ksp.solve(b, x)
        linear += ksp.getIterationNumber()
        # Forces of the active dofs: their rows' residuals in the unconstrained system.
        a.mult(x, res)
        res.axpy(-1.0, rhs)
        u = np.concatenate(comm.tompi4py().allgather(x.getArray()))
        r_full = np.concatenate(comm.tompi4py().allgather(res.getArray()))
        lam = np.where(active, sign * r_full[cdof], 0.0)
        d = sign * u[cdof] + g
        new = lam - c * d > 0
        if args.trace and comm.getRank() == 0:
            print(step, int(active.sum()), int(new.sum()), int((new != active).sum()), float(d.min()), float(lam.min()), ksp.getIterationNumber(), flush=True)
        # The classical stop: the step's own active set comes back (its dofs then lie
        # on the foundation, to the linear solve's tolerance, with forces >= 0, and the
        # others off it).
        if np.array_equal(new, active):
            return x, res, step, linear, 1
        active = new
    return x, res, step, linear, -1


def rsls(comm, a, rhs, xl, xu, ub, lo, hi, args):
    snes = PETSc.SNES().create(comm=comm)
    snes.setType("vinewtonrsls")
    res = a.createVecLeft()

    def residual(snes, x, r):
        a.mult(x, r)
        r.axpy(-1.0, rhs)

    snes.setFunction(residual, res)
    snes.setJacobian(lambda snes, x, j, p: None, a, a)
    snes.setVariableBounds(xl, xu)
    snes.setTolerances(rtol=args.rtol, atol=1e-50, max_it=200)
    ksp = snes.getKSP()
    if args.pc == "gamg":
        ksp.setType("cg")
        ksp.setTolerances(rtol=1e-10)
    else:
        ksp.setType("preonly")

    # The reduced space changes size when the active set does, and PETSc 3.18's
    # preconditioners refuse to set up again on other sizes: built anew before every
    # Newton step.
    def fresh_pc(snes, step):
        pc = snes.getKSP().getPC()
        pc.setType("jacobi")
        if args.pc == "gamg":
            pc.setType("gamg")
        else:
            pc.setType("lu")
            pc.setFactorSolverType("mumps")

    fresh_pc(snes, 0)
    snes.setUpdate(fresh_pc)
    snes.setFromOptions()
    x = a.createVecRight()
    x.setArray(ub[lo:hi])
    x.pointwiseMax(x, xl)
    x.pointwiseMin(x, xu)
    snes.solve(None, x)
    return x, res, snes.getIterationNumber(), snes.getLinearSolveIterations(), snes.getConvergedReason()


if __name__ == "__main__":
    main()
