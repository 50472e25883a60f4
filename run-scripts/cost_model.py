#!/usr/bin/env python3
"""The cost model of docs/cost-model.md, fitted to the summary.json files of scaling
studies (run-scripts/scale_study.sh writes them as OUT/summary-P.json), then used to
predict a run of another size.

    python3 run-scripts/cost_model.py DIR1/summary-*.json DIR2/summary-*.json \\
        [--dofs 1e8 --ranks 512 --contact-nodes N --sweeps S \\
         --flops F --bandwidth B --latency L --net-bandwidth W --mumps-efficiency E \\
         --start DIR3 --node-cores K]

The laws are fitted on the runs with at least --min-ranks subdomains (the regime they
describe: subdomains with interface all round, the interface factored by MUMPS), and
printed with the ratio model / measured on every run. Only work, sizes, bytes and
memory are fitted: they are the same on an oversubscribed machine as on a cluster.
Times follow from them and a node's parameters, which are arguments.

With --start (the directory of run-scripts/start_study.py's CSV files), the start from
one mesh file is predicted too: what the first rank does alone while every other rank
waits (the mesh read, the problem, the partition and split, the scatter), each piece's
seconds per node on one core and the part of it that runs on the threads of the first
rank's node (--node-cores), and the first rank's memory per node; against the run's
other phases, its share of the whole run, and against a start from a split directory
(`contact-par split` once, then `--mesh-split`).
"""
import argparse
import csv
import json
import math
import os
import statistics
import sys


def fit_power(rows):
    """y = a * prod(x_k ^ g_k): least squares in logs; rows are ([x_k], y)."""
    k = len(rows[0][0])
    X = [[1.0] + [math.log(x) for x in xs] for xs, _ in rows]
    Y = [math.log(y) for _, y in rows]
    # Normal equations, (k+1) x (k+1), by Gaussian elimination.
    A = [[sum(r[i] * r[j] for r in X) for j in range(k + 1)] for i in range(k + 1)]
    b = [sum(r[i] * y for r, y in zip(X, Y)) for i in range(k + 1)]
    for i in range(k + 1):
        p = A[i][i]
        for j in range(i + 1, k + 1):
            f = A[j][i] / p
            A[j] = [a - f * c for a, c in zip(A[j], A[i])]
            b[j] -= f * b[i]
    c = [0.0] * (k + 1)
    for i in reversed(range(k + 1)):
        c[i] = (b[i] - sum(A[i][j] * c[j] for j in range(i + 1, k + 1))) / A[i][i]
    return math.exp(c[0]), c[1:]


def fit_scale(rows):
    """y = a * x: the geometric mean of y / x."""
    return math.exp(statistics.mean(math.log(y / x) for x, y in rows))


def fit_linear(rows):
    """y = a + b x by least squares."""
    xs, ys = [x for x, _ in rows], [y for _, y in rows]
    mx, my = statistics.mean(xs), statistics.mean(ys)
    b = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)
    return my - b * mx, b


def figures(s):
    """What the model needs from one summary.json."""
    per = s["per_subdomain"]
    peaks = s["peak_memory_bytes_per_rank"]
    return dict(
        n=s["dofs"], P=s["subdomains"], n_G=s["interface_dofs"], sweeps=s["iterations"],
        contact=s["contact_nodes"],
        # Contact dofs: both components with friction, the normal's without.
        C=s["contact_nodes"] * (2 if s["friction"] != "none" else 1),
        F_max=max(q["factor_gflop"] for q in per) * 1e9,
        F_one=per[0]["factor_gflop"] * 1e9,
        factor_s=per[0]["factor_s"],
        b_max=max(q["boundary_dofs"] for q in per),
        F_G=s["interface_gflop"] * 1e9, mumps=s.get("interface_factor") == "mumps",
        E_G=s.get("interface_factor_entries", 0.0),
        share_max=max(q["interface_gflop"] for q in per) * 1e9,
        crit=max(q["factor_gflop"] + q["interface_gflop"] for q in per) * 1e9,
        mem0=peaks[0], mem_med=statistics.median(peaks), mem_max=max(peaks),
        sent_med=statistics.median(q["sent_bytes_per_sweep"] for q in per),
        sent_max=max(q["sent_bytes_per_sweep"] for q in per),
    )


class Model:
    """Per rank of a run of n dofs on P ranks (one subdomain each), 2D:
      n_G   = a_G sqrt(n P)                the interface dofs
      b     = a_b sqrt(n / P) + C / P      the largest subdomain's dense block: its
                                           interface dofs and its share of the C
                                           contact dofs (the partition spreads them)
      F_s   = a_f (n / P)^1.5              the largest subdomain's factor (flops; one
                                           rank's whole factor: a_1 n^1.5)
      F_G   = a_I n^1.5 P^beta             MUMPS's interface factorization (flops)
      share = k_I F_G / P                  the largest rank's share of it
      E_G   = kappa F_G^(2/3)              the interface factor's entries
      M     = M_0 + m_n n / P + 8 E_G / P  a rank's peak memory (bytes; rank 0 r_0 x)
    """

    def __init__(self, runs, min_ranks):
        fit = [r for r in runs if r["P"] >= min_ranks]
        if len(fit) < 2:
            sys.exit(f"cost_model.py: at least two runs with {min_ranks} or more subdomains needed")
        # E_G / F_G^(2/3) from MUMPS's INFOG(29) and RINFOG(3) (summary.json
        # interface_factor_entries and interface_gflop).
        sized = [r for r in fit if r["mumps"] and r["E_G"] > 0]
        self.KAPPA = fit_scale([(r["F_G"] ** (2 / 3), r["E_G"]) for r in sized]) if sized else 1.6
        self.kappa_runs = len(sized)
        self.a_G = fit_scale([(math.sqrt(r["n"] * r["P"]), r["n_G"]) for r in fit])
        self.a_b = fit_scale(
            [(math.sqrt(r["n"] / r["P"]), max(r["b_max"] - r["C"] / r["P"], 1.0)) for r in fit]
        )
        self.a_f = fit_scale([((r["n"] / r["P"]) ** 1.5, r["F_max"]) for r in fit])
        mumps = [r for r in fit if r["mumps"]]
        sizes = {r["n"] for r in mumps}
        if len(sizes) >= 2:
            self.a_I, (g_n, self.beta) = fit_power([([r["n"], r["P"]], r["F_G"]) for r in mumps])
            self.g_n = g_n
        else:
            # One mesh size: the exponent of n is the theory's (the top separator of the
            # interface graph has about sqrt(n) dofs, its front costs n^1.5).
            self.g_n = 1.5
            self.a_I, (self.beta,) = fit_power([([r["P"]], r["F_G"] / r["n"] ** 1.5) for r in mumps])
        self.k_I = statistics.median(r["share_max"] / (r["F_G"] / r["P"]) for r in mumps)
        self.M_0, self.m_n = fit_linear(
            [(r["n"] / r["P"], r["mem_med"] - 8 * self.entries(r["F_G"]) / r["P"]) for r in fit]
        )
        # The one-rank factorization, against which the critical path is measured.
        ones = [r for r in runs if r["P"] == 1]
        self.a_1 = fit_scale([(r["n"] ** 1.5, r["F_max"]) for r in ones]) if ones else self.a_f
        self.r_0 = max(r["mem0"] / r["mem_med"] for r in fit)
        self.r_max = max(r["mem_max"] / r["mem_med"] for r in fit)

    def entries(self, F_G):
        return self.KAPPA * F_G ** (2 / 3)

    def predict(self, n, P, C):
        F_G = self.a_I * n**self.g_n * P**self.beta if P > 1 else 0.0
        E_G = self.entries(F_G)
        return dict(
            n_G=self.a_G * math.sqrt(n * P) if P > 1 else 0.0,
            b=self.a_b * math.sqrt(n / P) + C / P if P > 1 else C,
            F_s=self.a_f * (n / P) ** 1.5,
            F_G=F_G, share=self.k_I * F_G / P, E_G=E_G,
            M=self.M_0 + self.m_n * n / P + 8 * E_G / P,
        )

    def describe(self):
        return "\n".join([
            f"  n_G   = {self.a_G:.3f} sqrt(n P)",
            f"  b     = {self.a_b:.3f} sqrt(n / P) + C / P",
            f"  F_s   = {self.a_f:.1f} (n / P)^1.5  (one rank: {self.a_1:.1f} n^1.5)",
            f"  F_G   = {self.a_I:.4g} n^{self.g_n:.2f} P^{self.beta:.2f};  share = {self.k_I:.2f} F_G / P",
            f"  E_G   = {self.KAPPA:.2f} F_G^(2/3)  ({self.kappa_runs} runs; without any, 1.6 from hertz level 4 on 16 ranks)",
            f"  M     = {self.M_0 / 1e6:.0f} MB + {self.m_n:.0f} B x n / P + 8 E_G / P;"
            f"  rank 0 at most {self.r_0:.2f} x, the largest rank {self.r_max:.2f} x the median",
        ])


START_PIECES = ("mesh", "problem", "partition", "scatter")


class Start:
    """The first rank's work alone from one mesh file, per piece p:
      T_p(N, c) = t_p N (1 - f_p + f_p / c)   seconds, N nodes, c cores of its node
    t_p from the runs where the first rank has one core (`--bind-to core`), f_p from
    those where it has its node's k cores (`--bind-to none`): T_k / T_1 = 1 - f + f / k. Those runs have
    2 parts; the partition's growth with the parts and the first rank's peak memory
    come from `contact-par split` on one core (split.csv): its seconds per node over
    those at 2 parts, interpolated in log P, and its peak bytes per node."""

    def __init__(self, directory):
        with open(os.path.join(directory, "start.csv")) as fh:
            rows = list(csv.DictReader(fh))
        with open(os.path.join(directory, "split.csv")) as fh:
            splits = list(csv.DictReader(fh))
        one = [r for r in rows if r["bind"] == "core"]
        many = [r for r in rows if r["bind"] == "none"]
        if not one or not many or not splits:
            sys.exit("cost_model.py: --start needs runs on one core, on the node's cores, and splits")
        k = int(many[0]["cores"])
        self.t, self.f = {}, {}
        for p in START_PIECES:
            key = p + "_s"
            self.t[p] = fit_scale([(float(r["nodes"]), max(float(r[key]), 1e-6)) for r in one])
            t1 = sum(float(r[key]) for r in one)
            tk = sum(float(r[key]) for r in many)
            threaded = (t1 - tk) / (t1 * (1 - 1 / k)) if t1 > 0 and k > 1 else 0.0
            self.f[p] = min(max(threaded, 0.0), 1.0)
        # The largest mesh's splits: seconds per node against the parts.
        big = max(int(r["nodes"]) for r in splits)
        own = sorted((int(r["parts"]), float(r["seconds"]) / big) for r in splits
                     if int(r["nodes"]) == big)
        self.split_per_node = own
        # Peak bytes per node: the slope over the meshes (a process's own fixed tens of
        # MB apart), or over the one mesh there is.
        peaks = [(float(r["nodes"]), float(r["peak_bytes"])) for r in splits]
        if len({n for n, _ in peaks}) >= 2:
            self.m_0 = fit_linear(peaks)[1]
        else:
            self.m_0 = max(b / n for n, b in peaks)

    def split_at(self, parts):
        """`contact-par split`'s seconds per node into `parts` on one core: linear in
        log P between the measured counts, the nearest segment extended beyond them."""
        pts = [(math.log(p), s) for p, s in self.split_per_node]
        if len(pts) < 2:
            return pts[0][1]
        x = math.log(parts)
        i = max(min(sum(px <= x for px, _ in pts) - 1, len(pts) - 2), 0)
        (x0, y0), (x1, y1) = pts[i], pts[i + 1]
        return max(y0 + (y1 - y0) * (x - x0) / (x1 - x0), min(y for _, y in pts))

    def partition_extra(self, parts):
        """Seconds per node the partition into `parts` costs over 2 parts (one core)."""
        return max(self.split_at(parts) - self.split_at(2), 0.0)

    def seconds(self, nodes, cores, parts):
        """Each piece's seconds on `cores` cores, the partition's into `parts`."""
        per_node = dict(self.t)
        per_node["partition"] += self.partition_extra(parts)
        return {p: per_node[p] * nodes * (1 - self.f[p] + self.f[p] / cores) for p in START_PIECES}

    def describe(self):
        pieces = ", ".join(f"{p} {self.t[p] * 1e6:.3f} us/node ({self.f[p]:.0%} threaded)"
                           for p in START_PIECES)
        splits = ", ".join(f"{p} parts {s * 1e6:.2f}" for p, s in self.split_per_node)
        return (f"  start at 2 parts: {pieces}\n  contact-par split, one core, us/node: {splits};"
                f" its peak {self.m_0:.0f} B per node")


def times(pr, P, sweeps, a):
    """Seconds on the critical path: factorization, one sweep, the loop."""
    factor = pr["F_s"] / a.flops + pr["share"] / (a.mumps_efficiency * a.flops)
    # A sweep: the dense block of the largest subdomain read twice (forward and
    # backward, memory-bound), the rank's share of the interface factor read twice,
    # one all-reduce (log2 P steps) and the interface solve's tree (2 log2 P), the
    # interface values of the subdomain sent and received.
    local = 2 * 8 * pr["b"] ** 2 / a.bandwidth
    itf = 2 * 8 * pr["E_G"] / P / a.bandwidth if P > 1 else 0.0
    steps = 3 * math.ceil(math.log2(P)) if P > 1 else 0
    volume = 2 * 8 * pr["b"] / a.net_bandwidth if P > 1 else 0.0
    sweep = local + itf + steps * a.latency + volume
    return factor, sweep, sweeps * sweep


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("summaries", nargs="+")
    ap.add_argument("--min-ranks", type=int, default=16)
    ap.add_argument("--dofs", type=float, default=1e8)
    ap.add_argument("--ranks", type=int, default=512)
    ap.add_argument("--contact-nodes", type=float, default=None,
                    help="default: the study's largest run's, scaled like a boundary (sqrt of the dofs)")
    ap.add_argument("--sweeps", type=float, default=None,
                    help="default: those of the study's largest run (the count depends on the case, not on P)")
    ap.add_argument("--flops", type=float, default=None,
                    help="flop/s of one core in a factorization (default: the one-rank run's, else 10e9)")
    ap.add_argument("--bandwidth", type=float, default=10e9, help="memory bytes/s of one core")
    ap.add_argument("--latency", type=float, default=2e-6, help="network latency, s")
    ap.add_argument("--net-bandwidth", type=float, default=10e9, help="network bytes/s per rank")
    ap.add_argument("--mumps-efficiency", type=float, default=0.3,
                    help="MUMPS's flop rate in the interface factorization over --flops")
    ap.add_argument("--start", help="start_study.py's output directory (start.csv, split.csv): "
                    "predict the start from one mesh file")
    ap.add_argument("--node-cores", type=int, default=64,
                    help="cores of the first rank's node, which it borrows for the start")
    a = ap.parse_args()
    runs = sorted((figures(json.load(open(p))) for p in a.summaries), key=lambda r: (r["n"], r["P"]))
    m = Model(runs, a.min_ranks)
    ones = [r for r in runs if r["P"] == 1]
    if a.flops is None:
        a.flops = ones[-1]["F_one"] / ones[-1]["factor_s"] if ones else 10e9
    big = max(runs, key=lambda r: r["n"])
    sweeps = a.sweeps if a.sweeps is not None else big["sweeps"]
    per_node = big["C"] / big["contact"]
    contact = a.contact_nodes if a.contact_nodes is not None else big["contact"] * math.sqrt(a.dofs / big["n"])
    C = contact * per_node
    print(f"fitted on {sum(r['P'] >= a.min_ranks for r in runs)} runs with {a.min_ranks} or more subdomains:")
    print(m.describe())
    print(f"node: {a.flops / 1e9:.1f} Gflop/s per core, {a.bandwidth / 1e9:.0f} GB/s, latency "
          f"{a.latency * 1e6:.1f} us, network {a.net_bandwidth / 1e9:.0f} GB/s, MUMPS at {a.mumps_efficiency:.0%}")
    print()
    print("model / measured on every run (G = Gflop, MB):")
    print(f"{'dofs':>9} {'P':>4} {'n_G':>13} {'F_s max G':>13} {'F_G G':>13} {'share G':>11} {'median MB':>11}")
    ratio = lambda x, y: f"{x:.3g}/{y:.3g}"
    for r in runs:
        pr = m.predict(r["n"], r["P"], r["C"])
        print(f"{r['n']:>9} {r['P']:>4} {ratio(pr['n_G'], r['n_G']):>13} {ratio(pr['F_s'] / 1e9, r['F_max'] / 1e9):>13} "
              f"{ratio(pr['F_G'] / 1e9, r['F_G'] / 1e9):>13} {ratio(pr['share'] / 1e9, r['share_max'] / 1e9):>11} "
              f"{ratio(pr['M'] / 1e6, r['mem_med'] / 1e6):>11}")
    print()
    one = m.a_1 * a.dofs**1.5
    print(f"prediction for {a.dofs:.3g} dofs, {contact:.0f} contact nodes, {sweeps:.0f} sweeps "
          f"(one rank's factor: {one / 1e9:.3g} Gflop):")
    print(f"{'P':>5} {'n/P':>9} {'b':>6} {'n_G':>8} {'F_s G':>8} {'share G':>8} {'crit/one':>9} "
          f"{'median GiB':>10} {'rank0 GiB':>9} {'factor s':>9} {'sweep ms':>9} {'loop s':>7}")
    for P in sorted({64, 128, 256, a.ranks}):
        pr = m.predict(a.dofs, P, C)
        f, sw, loop = times(pr, P, sweeps, a)
        print(f"{P:>5} {a.dofs / P:>9.3g} {pr['b']:>6.0f} {pr['n_G']:>8.0f} {pr['F_s'] / 1e9:>8.1f} "
              f"{pr['share'] / 1e9:>8.2f} {(pr['F_s'] + pr['share']) / one:>9.5f} "
              f"{pr['M'] / 2**30:>10.2f} {m.r_0 * pr['M'] / 2**30:>9.2f} {f:>9.1f} {sw * 1e3:>9.2f} {loop:>7.1f}")
    if a.start:
        start(a, Start(a.start), m, C, sweeps)


def start(a, st, m, C, sweeps):
    """The start from one mesh file against the run, and the way round it."""
    nodes = a.dofs / 2
    print()
    print(f"the start from one mesh file ({nodes:.3g} nodes): the first rank alone, on its node's "
          f"{a.node_cores} cores, while the other ranks wait; fitted on {a.start}:")
    print(st.describe())
    peak = st.m_0 * nodes / 2**30
    print(f"  its peak memory: {peak:.1f} GiB (the whole mesh and problem)")
    print(f"{'P':>5} {'mesh':>6} {'problem':>8} {'partition':>10} {'scatter':>8} "
          f"{'alone s':>8} {'factor + loop s':>15} {'serial share':>12}")
    share = {}
    for P in sorted({64, 128, 256, a.ranks}):
        secs = st.seconds(nodes, a.node_cores, P)
        alone = sum(secs.values())
        f, _, loop = times(m.predict(a.dofs, P, C), P, sweeps, a)
        share[P] = (alone, alone / (alone + f + loop))
        print(f"{P:>5} " + " ".join(f"{secs[p]:>{w}.1f}" for p, w in zip(START_PIECES, (6, 8, 10, 8)))
              + f" {alone:>8.1f} {f + loop:>15.1f} {share[P][1]:>12.1%}")
    alone, part = share[a.ranks]
    split = st.split_at(a.ranks) * nodes
    print(f"at {a.ranks} ranks a run from one file spends {alone:.0f} s ({part:.1%} of the run) on "
          f"the first rank alone, which holds {peak:.1f} GiB: split once instead "
          f"(`contact-par split --parts {a.ranks}`, about {split:.0f} s on one core, the same "
          f"peak), then run with --mesh-split, where each rank reads its own part and no rank "
          f"holds the mesh.")


if __name__ == "__main__":
    sys.exit(main())
