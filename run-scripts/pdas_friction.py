"""Contact with friction as an exact semismooth Newton method solves it, on contact-par's
case files: how many steps an established active-set method needs on a case, to set
beside the loop's sweeps (issue 24's yardstick: are a case's extra sweeps the loop's, or
the problem's own?).

    apt-get install python3-scipy python3-gmsh    # Debian (or pip install numpy scipy gmsh)
    python3 run-scripts/pdas_friction.py CASE.toml [--start active] [--ct 0.01] [--csv FILE]

The problem is the one contact-par solves: P1 plane elasticity (the stiffness, loads and
prescribed dofs of run-scripts/plain_alg2.py), one rigid obstacle (a line of any
inclination, a circle or a polyline; each node's normal and gap as contact-par's README
defines them), frictionless, Tresca or Coulomb friction (the slip threshold is the
coefficient times the normal force, one load step, u_t the slip). The method is the
primal-dual active-set form of semismooth Newton (Hintermueller, Ito and Kunisch 2002;
with friction, Hueber, Stadler and Wohlmuth 2008), in 2D: each contact node is open,
pressed and sticking, or pressed and slipping in a direction s; a step solves the
linear system those sets give, exactly (SciPy's sparse LU on the whole saddle-point
system, its constraint rows scaled to the stiffness rows, two steps of refinement):

- open: lambda = 0 (and mu = 0 under Coulomb);
- pressed: u_n = g;
- sticking: u_t = 0;
- slipping: mu = F lambda s (Coulomb), mu = threshold s (Tresca, open nodes too).

The next sets come from xi = lambda + c (u_n - g) (pressed where xi > 0) and
sigma = mu + c_t u_t (sticking where |sigma| <= F xi, or the Tresca threshold; s the sign
of sigma elsewhere), with c = E_eff / h and c_t = ct c. It stops when a step's sets come
back (the exact stop of the method: the answer of the last solve is the discrete
answer), or reports the cycle when sets recur. The normal test does not depend on c
once lambda and u_n are a step's; the tangential one does, through c_t: with c_t = c,
slipping nodes flip their direction back and forth on the cases measured, so ct 0.01 by
default, and `--ct` to try others. `--start active` starts with every contact node
pressed and sticking, for a body that only its contact holds (whose first solve is
singular otherwise). Contact nodes whose normal or tangent a Dirichlet condition holds
are never pressed or sticking here, nor sticking where a Dirichlet condition holds one of
their two dofs: their reaction is the support's.

It prints one JSON line: case, nodes, steps (linear solves), converged, active and slip
counts (or the step where a cycle began). `--trace` prints each step's counts; `--csv`
writes the contact nodes' answer in the columns of contact-par's contact.csv (x,y,u_n,u_t,
p_n,p_t,gap,contact, sorted by x then y; p_t the force on the body, against the slip):
tests/tolerance.rs compares contact-par's answers with it.
"""

import argparse
import json
import os
import sys

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from plain_alg2 import one_body_problem, write_contact_csv  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("case")
    ap.add_argument("--start", choices=["active", "inactive"], default="inactive",
                    help="every contact node pressed and sticking (active) or open (inactive) at first")
    ap.add_argument("--ct", type=float, default=0.01, help="c_t over c in the stick/slip test")
    ap.add_argument("--max-steps", type=int, default=400)
    ap.add_argument("--trace", action="store_true")
    ap.add_argument("--csv")
    args = ap.parse_args()
    prob = one_body_problem(args.case, "pdas_friction.py")
    nodes, mat, hyp, k, f, fixed, con = prob.nodes, prob.mat, prob.hyp, prob.k, prob.f, prob.fixed, prob.con
    law = con.get("friction", "none")
    coef = con.get("coefficient", 0.0)
    threshold = con.get("threshold", 0.0)
    cn, w, length, g, nmat, tmat = prob.foundation
    nc = len(cn)
    e_eff = mat["young"] / (1 - mat["poisson"] ** 2) if hyp == "plane_strain" else mat["young"]
    c = e_eff / length.mean()

    free = np.isnan(fixed)
    ub = np.where(free, 0.0, fixed)
    rhs0 = (f - k @ ub)[free]
    kff = k[free][:, free].tocsr()
    nf, tf = nmat[:, free].tocsr(), tmat[:, free].tocsr()
    nb, tb = nmat @ ub, tmat @ ub
    nfree = kff.shape[0]
    held_n = np.asarray(abs(nf).sum(axis=1)).ravel() == 0
    held_t = np.asarray(abs(tf).sum(axis=1)).ravel() == 0
    # A node with one free dof (the other held): pressed, its normal row fixes that dof,
    # and a sticking row would constrain it twice (a singular system); its tangential
    # reaction is the support's.
    held_t |= np.asarray((abs(nf) + abs(tf) > 0).sum(axis=1)).ravel() < 2
    frictional = law != "none"
    # The unknowns are lambda / c and mu / c (displacement units), so that the blocks
    # coupling them to u are of the stiffness' size.
    wc = sp.diags(w * c)
    zero = sp.csr_matrix((nc, nc))
    diag = lambda v: sp.diags(v.astype(float))  # noqa: E731
    # The equilibrium rows do not depend on the sets.
    top = [kff, nf.T @ wc] + ([tf.T @ wc] if frictional else [])

    def singular(step, detail=""):
        sys.exit(f"pdas_friction.py: step {step}: the linear system is singular{detail}: a body "
                 "that only its contact holds needs --start active")

    start = args.start == "active"
    act = np.full(nc, start) & ~held_n
    stick = (np.full(nc, start) & ~held_t) if frictional else np.zeros(nc, bool)
    sgn = np.zeros(nc)
    seen = {}
    for step in range(1, args.max_steps + 1):
        key = (act.tobytes(), stick.tobytes(), sgn.tobytes())
        lam_rows = [diag(act) @ nf, diag(~act)] + ([zero] if frictional else [])
        blocks = [top, lam_rows]
        rhs = [rhs0, np.where(act, g - nb, 0.0)]
        if frictional:
            # Under Tresca every node sticks or slips, open or pressed; under Coulomb an
            # open node carries no tangential force.
            on = act if law == "coulomb" else np.ones(nc, bool)
            st, sl = stick & on, ~stick & on
            if law == "coulomb":
                blocks.append([diag(st) @ tf, -coef * sp.diags(sgn * sl), diag(sl | ~on)])
                rhs.append(np.where(st, -tb, 0.0))
            else:
                blocks.append([diag(st) @ tf, zero, diag(sl)])
                rhs.append(np.where(st, -tb, np.where(sl, threshold * sgn / c, 0.0)))
        scale = sp.diags(np.concatenate([np.ones(nfree)] + [c * w] * (len(blocks) - 1)))
        mat_ = (scale @ sp.vstack([sp.hstack(b) for b in blocks])).tocsc()
        b = np.concatenate([rhs[0]] + [c * w * r for r in rhs[1:]])
        try:
            lu = splu(mat_, permc_spec="COLAMD", diag_pivot_thresh=1.0)
        except RuntimeError:
            singular(step)
        x = lu.solve(b)
        for _ in range(2):
            x += lu.solve(b - mat_ @ x)
        residual = np.linalg.norm(b - mat_ @ x) / np.linalg.norm(b)
        if not residual < 1e-6:
            singular(step, f" (relative residual {residual:.1e})")
        u = x[:nfree]
        lam = c * x[nfree:nfree + nc]
        mu = c * x[nfree + nc:] if frictional else np.zeros(nc)
        un = nf @ u + nb
        ut = tf @ u + tb
        xi = lam + c * (un - g)
        new_act = (xi > 0) & ~held_n
        if frictional:
            sigma = mu + args.ct * c * ut
            bound = coef * np.maximum(xi, 0.0) if law == "coulomb" else np.full(nc, threshold)
            new_stick = (np.abs(sigma) <= bound) & ~held_t
            if law == "coulomb":
                new_stick &= new_act
            new_sgn = np.where(new_stick, 0.0, np.sign(sigma))
        else:
            new_stick, new_sgn = stick, sgn
        if args.trace:
            slipping = int((new_act & ~new_stick).sum()) if frictional else 0
            print(f"step {step}: pressed {int(new_act.sum())}, slipping {slipping}, "
                  f"changed {int((new_act != act).sum() + (new_stick != stick).sum())}", flush=True)
        new_key = (new_act.tobytes(), new_stick.tobytes(), new_sgn.tobytes())
        out = {"case": args.case, "nodes": len(nodes), "steps": step}
        if new_key == key:
            out.update(converged=True, active=int(act.sum()),
                       slip=int((act & ~stick).sum()) if frictional else 0)
            print(json.dumps(out))
            if args.csv:
                write_contact_csv(args.csv, nodes[cn], un, ut, lam, -mu, g)
            return
        if new_key in seen:
            out.update(converged=False, cycle_from=seen[new_key])
            print(json.dumps(out))
            return
        seen[key] = step
        act, stick, sgn = new_act, new_stick, new_sgn
    print(json.dumps({"case": args.case, "nodes": len(nodes), "steps": args.max_steps, "converged": False}))


if __name__ == "__main__":
    main()
