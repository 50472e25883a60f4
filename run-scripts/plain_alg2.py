"""A plain Python implementation of the method contact-par runs, for side-by-side timings
and an independent check of its answer (issue 27's "plain Python/CHOLMOD" comparison).

    apt-get install libsuitesparse-dev        # Debian 12: SuiteSparse 5
    python3 -m venv venv && venv/bin/pip install 'numpy<2' 'scipy<1.14' gmsh 'cython<3' setuptools wheel
    venv/bin/pip install --no-build-isolation scikit-sparse==0.4.12   # the last for SuiteSparse 5
    venv/bin/python run-scripts/plain_alg2.py CASE.toml --out DIR [--tol 1e-8] [--acceleration none]

What it does, as a user would write it with NumPy and CHOLMOD: read the Gmsh mesh (gmsh's
Python API), assemble the P1 stiffness (vectorised), eliminate the prescribed dofs,
factor A = K + r N'WN + r T'WT once (CHOLMOD through scikit-sparse, AMD ordering; SciPy's
SuperLU when scikit-sparse is missing), then run ALG2 in its state form with one full
sparse forward and backward solve per sweep, accelerated by Anderson mixing (memory 10,
with the same residual safeguard) unless `--acceleration none`. r is contact-par's
automatic r (E_eff / sqrt(h L)); the loop stops when the relative changes of p_n, p_t and
the contact displacement over one sweep are all below tol. No retune of r per direction,
no subdomains, no contraction estimate: the textbook loop.

It reads the case files contact-par reads, for the subset it needs: [mesh] file, one
[material], [[dirichlet]], [[traction]], [body_force], one contact against a rigid
obstacle ([contact], or one [[contact]] with a line, circle or polyline) and friction
none, tresca or coulomb (inner). It writes DIR/contact.csv in
contact-par's columns (x,y,u_n,u_t,p_n,p_t,gap,contact, sorted by x then y; one contact) and DIR/plain.json
(sweeps, converged, seconds per phase).
"""

import argparse
import json
import math
import os
import sys
import time
import tomllib
import types

import numpy as np
import scipy.sparse as sp


def read_mesh(path):
    import gmsh

    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.open(path)
    tags, xyz, _ = gmsh.model.mesh.getNodes()
    index = {int(t): k for k, t in enumerate(tags)}
    nodes = xyz.reshape(-1, 3)[:, :2].copy()
    tri = []
    types, _, enodes = gmsh.model.mesh.getElements(2)
    for t, en in zip(types, enodes):
        if t == 2:
            tri.append(np.array([index[int(v)] for v in en]).reshape(-1, 3))
    tri = np.vstack(tri)
    groups = {}
    for dim, ptag in gmsh.model.getPhysicalGroups():
        name = gmsh.model.getPhysicalName(dim, ptag)
        if dim == 1:
            segs = []
            for ent in gmsh.model.getEntitiesForPhysicalGroup(dim, ptag):
                types, _, enodes = gmsh.model.mesh.getElements(1, ent)
                for t, en in zip(types, enodes):
                    if t == 1:
                        segs.append(np.array([index[int(v)] for v in en]).reshape(-1, 2))
            groups[name] = ("lines", np.vstack(segs))
        elif dim == 0:
            pts = []
            for ent in gmsh.model.getEntitiesForPhysicalGroup(dim, ptag):
                nt, _, _ = gmsh.model.mesh.getNodes(0, ent, includeBoundary=True)
                pts.extend(index[int(v)] for v in nt)
            groups[name] = ("points", np.array(pts))
    gmsh.finalize()
    # Counter-clockwise triangles.
    p = nodes[tri]
    det = (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) - (p[:, 2, 0] - p[:, 0, 0]) * (
        p[:, 1, 1] - p[:, 0, 1]
    )
    flip = det < 0
    tri[flip] = tri[flip][:, [0, 2, 1]]
    return nodes, tri, groups


def group_nodes(groups, name):
    kind, data = groups[name]
    return np.unique(data.ravel())


def stiffness(nodes, tri, young, poisson, hypothesis):
    if hypothesis == "plane_stress":
        c = young / (1 - poisson**2)
        d = c * np.array([[1, poisson, 0], [poisson, 1, 0], [0, 0, (1 - poisson) / 2]])
    else:
        c = young / ((1 + poisson) * (1 - 2 * poisson))
        d = c * np.array([[1 - poisson, poisson, 0], [poisson, 1 - poisson, 0], [0, 0, (1 - 2 * poisson) / 2]])
    p = nodes[tri]
    x, y = p[:, :, 0], p[:, :, 1]
    b = np.stack([y[:, 1] - y[:, 2], y[:, 2] - y[:, 0], y[:, 0] - y[:, 1]], axis=1)
    cc = np.stack([x[:, 2] - x[:, 1], x[:, 0] - x[:, 2], x[:, 1] - x[:, 0]], axis=1)
    area = 0.5 * (b[:, 0] * cc[:, 1] - b[:, 1] * cc[:, 0])
    bm = np.zeros((len(tri), 3, 6))
    bm[:, 0, 0::2] = b
    bm[:, 1, 1::2] = cc
    bm[:, 2, 0::2] = cc
    bm[:, 2, 1::2] = b
    bm /= (2 * area)[:, None, None]
    ke = np.einsum("eki,kl,elj->eij", bm, d, bm) * area[:, None, None]
    dofs = np.stack([2 * tri[:, 0], 2 * tri[:, 0] + 1, 2 * tri[:, 1], 2 * tri[:, 1] + 1, 2 * tri[:, 2], 2 * tri[:, 2] + 1], axis=1)
    rows = np.repeat(dofs, 6, axis=1).ravel()
    cols = np.tile(dofs, (1, 6)).ravel()
    n = 2 * len(nodes)
    return sp.csc_matrix((ke.ravel(), (rows, cols)), shape=(n, n)), area


def loads_and_prescribed(case, nodes, tri, groups, area):
    """The load vector (body force, tractions) and the prescribed dofs (NaN where free)."""
    n = 2 * len(nodes)
    f = np.zeros(n)
    bf = case.get("body_force", {}).get("f", [0.0, 0.0])
    for c in range(2):
        np.add.at(f, 2 * tri.ravel() + c, np.repeat(area / 3 * bf[c], 3))
    for tr in case.get("traction", []):
        segs = groups[tr["group"]][1]
        length = np.linalg.norm(nodes[segs[:, 1]] - nodes[segs[:, 0]], axis=1)
        for c in range(2):
            np.add.at(f, 2 * segs.ravel() + c, np.repeat(length / 2 * tr["t"][c], 2))
    fixed = np.full(n, np.nan)
    for d in case.get("dirichlet", []):
        v = group_nodes(groups, d["group"])
        if "ux" in d:
            fixed[2 * v] = d["ux"]
        if "uy" in d:
            fixed[2 * v + 1] = d["uy"]
    return f, fixed


def one_material(case, script):
    """The case's one [material]; several bodies ([[material]]) end the script with one line."""
    mat = case.get("material")
    if not isinstance(mat, dict):
        sys.exit(f"{script}: the case has {len(mat) if isinstance(mat, list) else 0} [[material]] "
                 "bodies; this script solves one body with one [material]")
    return mat


def one_contact(case, script):
    """The case's one contact against a rigid obstacle, as a dict with its group, its law's
    keys and its obstacle ({type, ...} as [[contact]] gives it): the single-foundation
    [contact] table or a lone [[contact]] entry. Anything else ends the script with one line."""
    con = case.get("contact")
    if isinstance(con, list) and len(con) == 1 and "obstacle" in con[0]:
        return dict(con[0], group=con[0]["slave"])
    if isinstance(con, dict):
        line = {"type": "line", "point": con["obstacle_point"], "normal": con["obstacle_normal"]}
        return dict(con, obstacle=line)
    kinds = [("obstacle" if "obstacle" in c else "master") for c in con] if isinstance(con, list) else []
    sys.exit(f"{script}: the case's contacts ({', '.join(kinds) or 'none'}) are not one contact against "
             "a rigid obstacle ([contact], or one [[contact]] with an obstacle), which is all this script solves")


def read_case(path):
    """The case file at `path` and its mesh: the case table, nodes, triangles, groups."""
    case = tomllib.load(open(path, "rb"))
    here = os.path.dirname(os.path.abspath(path))
    return (case, *read_mesh(os.path.join(here, case["mesh"]["file"])))


def one_body(case, nodes, tri, groups, script):
    """A case read by `read_case` as the reference scripts solve it: its one material and
    hypothesis, stiffness K, loads f and prescribed dofs (NaN where free), and its one
    contact against a rigid obstacle with that contact's foundation (node numbers,
    weights, segment lengths, gaps, rows N and T)."""
    mat = one_material(case, script)
    hyp = mat.get("hypothesis", "plane_strain")
    k, area = stiffness(nodes, tri, mat["young"], mat["poisson"], hyp)
    f, fixed = loads_and_prescribed(case, nodes, tri, groups, area)
    con = one_contact(case, script)
    return types.SimpleNamespace(case=case, nodes=nodes, mat=mat, hyp=hyp, k=k, f=f,
                                 fixed=fixed, con=con, foundation=foundation(con, nodes, groups))


def one_body_problem(path, script):
    """`one_body` of the case file at `path`."""
    return one_body(*read_case(path), script)


def write_contact_csv(path, pts, u_n, u_t, p_n, p_t, g):
    """The contact nodes' answer in the columns of contact-par's contact.csv, sorted by x
    then y, every number as repr prints it (round trip)."""
    with open(path, "w") as fh:
        fh.write("x,y,u_n,u_t,p_n,p_t,gap,contact\n")
        for i in np.lexsort((pts[:, 1], pts[:, 0])):
            vals = (pts[i, 0], pts[i, 1], u_n[i], u_t[i], p_n[i], p_t[i], g[i])
            fh.write(",".join(repr(float(v)) for v in vals) + ",0\n")


def frames(obstacle, pts):
    """Each point's unit normal m (obstacle -> body) and signed gap g from the closest
    point of the obstacle, as contact-par's README defines them: a line's normal; a
    circle's radius through the point (outwards, or inwards for a body inside the hole);
    a polyline's (end segments run on as half-lines, the body on the left walking from the
    first point, or on the right) segment normal, or at a corner the direction from the
    corner to the point, on the side of the two normals' sum."""
    kind = obstacle["type"]
    if kind == "line":
        m = np.array(obstacle["normal"], dtype=float)
        return np.tile(m, (len(pts), 1)), (pts - np.array(obstacle["point"])) @ m
    if kind == "circle":
        d = pts - np.array(obstacle["centre"], dtype=float)
        dist = np.linalg.norm(d, axis=1)
        radial = d / dist[:, None]
        if obstacle.get("body", "outside") == "inside":
            return -radial, obstacle["radius"] - dist
        return radial, dist - obstacle["radius"]
    if kind != "polyline":
        sys.exit(f"plain_alg2.py: unknown obstacle type {kind!r} (line, circle or polyline)")
    v = np.array(obstacle["points"], dtype=float)
    if obstacle.get("body", "left") == "right":
        v = v[::-1]
    ms, gs = [], []
    for x in pts:
        best = None
        for k in range(len(v) - 1):
            a, b = v[k], v[k + 1]
            u = (b - a) / np.linalg.norm(b - a)
            tau = (x - a) @ u
            lo = -np.inf if k == 0 else 0.0
            hi = np.inf if k == len(v) - 2 else np.linalg.norm(b - a)
            t = min(max(tau, lo), hi)
            corner = k if t == 0.0 and k > 0 else k + 1 if t == hi and k < len(v) - 2 else None
            dist = np.linalg.norm(x - (a + t * u))
            if best is None or dist < best[0]:
                best = (dist, np.array([-u[1], u[0]]), a, corner)
        dist, n, a, corner = best
        if corner is None:
            ms.append(n)
            gs.append((x - a) @ n)
            continue
        c = v[corner]
        n1, n2 = (np.array([-(q - p)[1], (q - p)[0]]) / np.linalg.norm(q - p)
                  for p, q in ((v[corner - 1], c), (c, v[corner + 1])))
        sign = 1.0 if (x - c) @ (n1 + n2) >= 0 else -1.0
        ms.append(sign * (x - c) / dist)
        gs.append(sign * dist)
    return np.array(ms), np.array(gs)


def foundation(con, nodes, groups):
    """A contact's nodes (`con` from one_contact): their node numbers, weights (half the
    lengths of their segments), the segments' lengths, the gaps g, and the rows N and T
    (contact nodes x dofs) of u_n = N u = -m.u (towards the obstacle, at most g) and
    u_t = T u, t = (m_y, -m_x), with each node's own normal m."""
    segs = groups[con["group"]][1]
    cn = np.unique(segs.ravel())
    where = {v: i for i, v in enumerate(cn)}
    length = np.linalg.norm(nodes[segs[:, 1]] - nodes[segs[:, 0]], axis=1)
    w = np.zeros(len(cn))
    np.add.at(w, [where[v] for v in segs[:, 0]], length / 2)
    np.add.at(w, [where[v] for v in segs[:, 1]], length / 2)
    m, g = frames(con["obstacle"], nodes[cn])
    m = m / np.linalg.norm(m, axis=1)[:, None]
    tv = np.stack([m[:, 1], -m[:, 0]], axis=1)
    n = 2 * len(nodes)
    rows = np.repeat(np.arange(len(cn)), 2)
    cols = np.stack([2 * cn, 2 * cn + 1], axis=1).ravel()
    nmat = sp.csr_matrix(((-m).ravel(), (rows, cols)), shape=(len(cn), n))
    tmat = sp.csr_matrix((tv.ravel(), (rows, cols)), shape=(len(cn), n))
    return cn, w, length, g, nmat, tmat


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("case")
    ap.add_argument("--out", default="plain-out")
    ap.add_argument("--tol", type=float, default=None)
    ap.add_argument("--max-iter", type=int, default=100000)
    ap.add_argument("--acceleration", choices=["anderson", "none"], default="anderson")
    args = ap.parse_args()
    t0 = time.perf_counter()
    times = {}
    read = read_case(args.case)
    times["read"] = time.perf_counter() - t0

    t = time.perf_counter()
    prob = one_body(*read, "plain_alg2.py")
    case, nodes, mat, hyp, k, f, fixed, con = (prob.case, prob.nodes, prob.mat, prob.hyp, prob.k,
                                               prob.f, prob.fixed, prob.con)
    cn, w, length, g, nmat, tmat = prob.foundation
    law = con.get("friction", "none")
    frictional = law != "none"
    # contact-par's automatic r: E_eff / sqrt(h L).
    e_eff = mat["young"] / (1 - mat["poisson"] ** 2) if hyp == "plane_strain" else mat["young"]
    h = length.mean()
    span = nodes.max(axis=0) - nodes.min(axis=0)
    r = case.get("solver", {}).get("r", e_eff / math.sqrt(h * span.min()))
    tol = args.tol if args.tol is not None else case.get("solver", {}).get("tol", 1e-8)
    wd = sp.diags(w)
    a = k + r * (nmat.T @ wd @ nmat)
    if frictional:
        a = a + r * (tmat.T @ wd @ tmat)
    free = np.isnan(fixed)
    ub = np.where(free, 0.0, fixed)
    rhs0 = f - k @ ub
    af = sp.csc_matrix(a[free][:, free])
    nf, tf = nmat[:, free], tmat[:, free]
    nb, tb = nmat @ ub, tmat @ ub
    times["assemble"] = time.perf_counter() - t

    t = time.perf_counter()
    try:
        from sksparse.cholmod import cholesky

        solve = cholesky(af, ordering_method="amd")
        solver = "cholmod"
    except ImportError:
        from scipy.sparse.linalg import splu

        lu = splu(af)
        solve = lu.solve
        solver = "superlu"
    times["factor"] = time.perf_counter() - t

    t = time.perf_counter()
    nc = len(cn)
    thresh = con.get("threshold", 0.0)
    coef = con.get("coefficient", 0.0)

    def derived(x):
        s = x[:nc]
        p = np.minimum(g, s)
        lam = r * (s - p)
        if frictional:
            z = x[nc:]
            sf = np.full(nc, thresh) if law == "tresca" else coef * np.maximum(lam, 0.0)
            q = np.sign(z) * np.maximum(np.abs(z) - sf / r, 0.0)
            mu = r * (z - q)
        else:
            q = mu = np.zeros(nc)
        return p, lam, q, mu

    def sweep(x):
        p, lam, q, mu = derived(x)
        b = rhs0[free] + nf.T @ (w * (r * p - lam))
        if frictional:
            b = b + tf.T @ (w * (r * q - mu))
        u = solve(b)
        un = nf @ u + nb
        ut = tf @ u + tb
        gx = un + lam / r
        if frictional:
            gx = np.concatenate([gx, ut + mu / r])
        return gx, (un, ut, u)

    def wnorm(v):
        ww = np.concatenate([w, w]) if len(v) == 2 * nc else w
        return math.sqrt(np.sum(ww * v * v))

    x = np.minimum(g, 0.0)
    if frictional:
        x = np.concatenate([x, np.zeros(nc)])
    memory = 10 if args.acceleration == "anderson" else 0
    dfs, dgs, last = [], [], None
    gx, out = sweep(x)
    sweeps, converged = 1, False
    while sweeps < args.max_iter:
        fx = gx - x
        _, lam0, _, mu0 = derived(x)
        _, lam1, _, mu1 = derived(gx)
        un, ut, _ = out
        size_u = wnorm(un) + wnorm(ut)
        dp = wnorm(lam1 - lam0) / max(wnorm(lam1), 1e-300)
        dt = wnorm(mu1 - mu0) / max(wnorm(mu1), 1e-300) if frictional and wnorm(mu1) > 0 else 0.0
        du = wnorm(fx) / max(size_u, 1e-300)
        if max(dp, dt, du) <= tol:
            converged = True
            break
        y = gx
        if memory:
            if last is not None:
                dfs.append(fx - last[0])
                dgs.append(gx - last[1])
                if len(dfs) > memory:
                    dfs.pop(0)
                    dgs.pop(0)
            last = (fx, gx)
            if dfs:
                dfm, dgm = np.array(dfs).T, np.array(dgs).T
                gamma, *_ = np.linalg.lstsq(dfm, fx, rcond=1e-10)
                y = gx - dgm @ gamma
        gy, outy = sweep(y)
        sweeps += 1
        if memory and y is not gx and np.linalg.norm(gy - y) > np.linalg.norm(fx):
            # Safeguard: the plain step from the last accepted point.
            dfs, dgs, last = [], [], None
            y = gx
            gy, outy = sweep(y)
            sweeps += 1
        x, gx, out = y, gy, outy
    times["loop"] = time.perf_counter() - t

    t = time.perf_counter()
    un, ut, u = out
    _, lam, _, mu = derived(gx)
    os.makedirs(args.out, exist_ok=True)
    write_contact_csv(os.path.join(args.out, "contact.csv"), nodes[cn], un, ut, lam, -mu, g)
    times["output"] = time.perf_counter() - t
    times["total"] = time.perf_counter() - t0
    json.dump({"sweeps": sweeps, "converged": converged, "solver": solver, "r": r,
               "nodes": len(nodes), "timings_s": times}, open(os.path.join(args.out, "plain.json"), "w"), indent=1)
    print(json.dumps({"sweeps": sweeps, "converged": converged, "solver": solver, "timings_s": times}))


if __name__ == "__main__":
    main()
