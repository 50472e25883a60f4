"""Frictionless or Tresca contact as a convex program solved by an interior-point method, on
contact-par's case files: how many iterations a method that does not find the contact zone
by exchanging statuses needs on a case, beside the loop's sweeps and the exact active-set
Newton method's steps (run-scripts/pdas_friction.py; issue 24's yardsticks).

    python3 -m venv venv && venv/bin/pip install numpy scipy gmsh clarabel
    venv/bin/python run-scripts/interior_point.py CASE.toml [--csv FILE]

The problem is the one contact-par and pdas_friction.py solve (P1 plane elasticity, one
rigid obstacle, the stiffness, loads, prescribed dofs, normals and gaps of
run-scripts/plain_alg2.py): the displacements minimise 1/2 u'Ku - f'u, plus
sum_i w_i s |u_t,i| under Tresca friction (threshold s), subject to u_n,i <= g_i at every
contact node. The |u_t| terms are bounds on auxiliary variables, so it is a quadratic
program; Clarabel (an interior-point solver for conic programs, PyPI) solves it, its
unknowns scaled to the gaps and its objective to the stiffness, at tolerances 1e-13. Each
iteration factors a new matrix (the barrier changes the contact rows' weights), where the
loop's sweep reuses one factor. Coulomb friction is not a convex program and is refused.

It prints one JSON line: case, nodes, iterations, status; `--csv` writes the contact
nodes' answer in the columns of contact-par's contact.csv (x,y,u_n,u_t,p_n,p_t,gap,contact,
sorted by x then y; p_t the force on the body, against the slip).
"""

import argparse
import json
import os
import sys

import numpy as np
import scipy.sparse as sp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from plain_alg2 import one_body_problem, write_contact_csv  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("case")
    ap.add_argument("--csv")
    ap.add_argument("--max-iterations", type=int, default=500)
    args = ap.parse_args()
    try:
        import clarabel
    except ImportError:
        sys.exit("interior_point.py: Clarabel is missing: pip install clarabel")
    prob = one_body_problem(args.case, "interior_point.py")
    nodes, k, f, fixed, con = prob.nodes, prob.k, prob.f, prob.fixed, prob.con
    law = con.get("friction", "none")
    if law not in ("none", "tresca"):
        sys.exit(f"interior_point.py: {args.case}: friction \"{law}\" is not a convex program; "
                 "use friction = \"none\" or \"tresca\"")
    threshold = con.get("threshold", 0.0)
    cn, w, _, g, nmat, tmat = prob.foundation
    nc = len(cn)

    free = np.isnan(fixed)
    ub = np.where(free, 0.0, fixed)
    kff = k[free][:, free].tocsc()
    rhs = (f - k @ ub)[free]
    nf, tf = nmat[:, free].tocsc(), tmat[:, free].tocsc()
    nb, tb = nmat @ ub, tmat @ ub
    nfree = kff.shape[0]
    # Unknowns in units of the largest gap or prescribed displacement (a millionth of the
    # mesh's size without either), the objective in units of the mean stiffness diagonal
    # times that length squared: the solver's tolerances are then relative.
    length = max(np.abs(g - nb).max(), np.abs(ub).max())
    if length == 0:
        length = 1e-6 * np.linalg.norm(nodes.max(axis=0) - nodes.min(axis=0))
    force = kff.diagonal().mean() * length
    p = kff / kff.diagonal().mean()
    q = -rhs / force
    a = nf
    b = (g - nb) / length
    rows = nc
    if law == "tresca":
        eye = sp.identity(nc, format="csc")
        p = sp.block_diag([p, sp.csc_matrix((nc, nc))], format="csc")
        q = np.concatenate([q, w * threshold / force])
        empty = sp.csc_matrix((nc, nc))
        a = sp.vstack([sp.hstack([nf, empty]), sp.hstack([tf, -eye]), sp.hstack([-tf, -eye])])
        b = np.concatenate([b, -tb / length, tb / length])
        rows = 3 * nc
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.max_iter = args.max_iterations
    settings.tol_gap_abs = 1e-14
    settings.tol_gap_rel = 1e-13
    settings.tol_feas = 1e-13
    settings.tol_ktratio = 1e-10
    cones = [clarabel.NonnegativeConeT(rows)]
    sol = clarabel.DefaultSolver(sp.csc_matrix(p), q, sp.csc_matrix(a), b, cones, settings).solve()
    out = {"case": args.case, "nodes": len(nodes), "iterations": sol.iterations, "status": str(sol.status)}
    print(json.dumps(out))
    if args.csv:
        u = np.array(sol.x[:nfree]) * length
        z = np.array(sol.z) * force
        un, ut = nf @ u + nb, tf @ u + tb
        lam = z[:nc] / w
        # The multipliers of t >= u_t and t >= -u_t: the tangential force on the body
        # opposes the slip.
        pt = -(z[nc:2 * nc] - z[2 * nc:]) / w if law == "tresca" else np.zeros(nc)
        write_contact_csv(args.csv, nodes[cn], un, ut, lam, pt, g)
    if "Solved" not in str(sol.status):
        sys.exit(1)


if __name__ == "__main__":
    main()
